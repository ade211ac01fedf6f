"""Faithful vendor PID blocks, one module per vendor, each readable beside its manual."""
