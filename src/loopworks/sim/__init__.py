"""Module execution, scenarios, replay and metrics."""
