"""Analysis of loop data that needs no blocks: plant or simulated time series of one loop
(SP, PV, OP), their quality, oscillation and valve-stiction indices (issue 15)."""
