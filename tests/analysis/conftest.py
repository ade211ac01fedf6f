"""Shared loops for the analysis tests."""

from __future__ import annotations

import numpy as np
import pytest

from loopworks.analysis.synthetic import simulate_loop

#: the scan of the spec 5.1 loop
SPEC_DT = 0.05


@pytest.fixture(scope="session")
def spec_cycle() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """SP, PV, OP of plant-and-tuning 5.1's first case, run by loopworks' own blocks (pid,
    valve.choudhury S = 3 %, J = 1 %, process.fopdt K = 1, T = 10 s, L = 2 s; PI Kc = 1,
    Ti = 10 s; no noise; SP 50 -> 51 % at 10 s; dt 0.05 s): the second half of a 4000 s run,
    the settled limit cycle (spec: OP amplitude 1.560, PV amplitude 0.556, period 112.0 s)."""
    loop = simulate_loop(valve="choudhury", s=3.0, j=1.0, noise=0.0, gain=1.0,
                         time_constant=10.0, dead_time=2.0, kc=1.0, ti=10.0, sp_step=1.0,
                         sp_step_time=10.0, dt=SPEC_DT, sample_period=SPEC_DT, warmup=2000.0,
                         duration=2000.0)
    return np.array(loop.data.sp), np.array(loop.data.pv), np.array(loop.data.op)
