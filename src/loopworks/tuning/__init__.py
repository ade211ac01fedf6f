"""Relay experiment, identification, tuning rules and conversion between controllers."""
