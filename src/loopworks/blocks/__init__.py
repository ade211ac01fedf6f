"""The block model, status, the generic PID and shared primitives."""
