"""Stiction limit cycles against the reference simulations of spec plant-and-tuning 5.1.

Ideal PI (e = SP - PV), Ts = 0.05 s, the Choudhury valve (spec 1.2) starting stuck at 50 %,
SP +1 % at t = 10 s, 4000 s; amplitudes are half peak-to-peak over the second half, the period
the mean spacing of PV up-crossings of its mean. The loop is built from the project's blocks
(generic pid -> valve.choudhury -> process) in a module.
"""

from __future__ import annotations

import numpy as np
import pytest

from loopworks import Module, create_block
from loopworks.sim.module import Event


def limit_cycle(process: dict[str, object], kc: float, ti: float, s: float,
                j: float) -> tuple[float, float, float]:
    m = Module({"pid": create_block("pid", k=kc, ti=ti, bias=50.0, out_lo=-1e6, out_hi=1e6),
                "valve": create_block("valve.choudhury", s=s, j=j, y0=50.0),
                "process": create_block(**process)},  # type: ignore[arg-type]
               wires={"valve.op": "pid.out", "process.u": "valve.position",
                      "pid.pv": "process.y"},
               inputs={"pid": {"sp": 50.0}}, events=[Event(10.0, "pid.sp", 51.0)])
    r = m.run(4000.0, 0.05)
    half = r.t >= 2000.0
    pv, op, t = r["process.y"][half], r["pid.out"][half], r.t[half]
    up = np.flatnonzero((pv[:-1] < pv.mean()) & (pv[1:] >= pv.mean()))
    period = float(np.mean(np.diff(t[up]))) if len(up) > 1 else float("nan")
    return float(np.ptp(pv)) / 2, float(np.ptp(op)) / 2, period


FOPDT = {"kind": "process.fopdt", "gain": 1.0, "time_constant": 10.0, "dead_time": 2.0,
         "u0": 50.0}
IPDT = {"kind": "process.ipdt", "gain": 0.1, "dead_time": 2.0, "u0": 50.0, "y0": 50.0}


@pytest.mark.parametrize(("process", "kc", "ti", "s", "j", "pv_amp", "op_amp", "period"), [
    (FOPDT, 1.0, 10.0, 3.0, 1.0, 0.556, 1.560, 112.0),
    (FOPDT, 2.5, 10.0, 3.0, 1.0, 0.517, 1.681, 40.7),
    (IPDT, 1.0, 20.0, 3.0, 1.0, 1.644, 1.702, 95.7),
    (IPDT, 1.0, 20.0, 3.0, 0.0, 1.775, 2.148, 122.7),
], ids=["fopdt-pi", "fopdt-simc", "integrator", "integrator-deadband"])
def test_limit_cycle_matches_the_reference_simulation(
        process: dict[str, object], kc: float, ti: float, s: float, j: float, pv_amp: float,
        op_amp: float, period: float) -> None:
    """spec 5.1 table rows: PV and OP amplitude and period within 2 % of the reference."""
    got = limit_cycle(process, kc, ti, s, j)
    assert got == pytest.approx((pv_amp, op_amp, period), rel=0.02)


def test_pure_deadband_does_not_cycle_in_a_self_regulating_loop() -> None:
    """spec 5.1 row 2: S = 3, J = 0 on the FOPDT: no cycle, PV settles on SP."""
    pv_amp, op_amp, _ = limit_cycle(FOPDT, 1.0, 10.0, 3.0, 0.0)
    assert pv_amp < 1e-3 and op_amp < 1e-3
