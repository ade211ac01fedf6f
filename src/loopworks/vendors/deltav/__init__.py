"""Emerson DeltaV: the PID block, the SGGN signal generator, the CALC block (with its
expression language) and the seed's stick-slip compensator."""
