"""After a burst of Bad measurement, a controller in closed loop returns to its undisturbed
trajectory (issue 11: "the block returns to its undisturbed trajectory"): a controller on a
first-order process, the same run with and without a burst of NaN / ±inf / 1e308 / Bad-status
PV in the middle; long after the burst (many closed-loop time constants), PV and OUT of the two
runs agree. While the burst lasts the controller holds its output (its Bad-input rule), so the
process drifts only as far as a held output lets it.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import loopworks
from loopworks.sim.module import Module

#: controller kind -> (parameters, setpoint) for a loop on a 0..100 % process
CONTROLLERS: dict[str, tuple[dict[str, Any], float]] = {
    "pid": ({"k": 1.0, "ti": 5.0}, 60.0),
    "deltav.pid": ({"gain": 1.0, "reset": 5.0}, 60.0),
    # reverse sense for a positive-gain process (spec 3.3), no minimum accumulated error (3.5)
    "e2.pid": ({"kp": 1.0, "ki": 0.2, "throttling_range": 100.0,
                "error_sign": "setpoint_minus_input", "update_interval": 0.5,
                "min_accumulated_error": 0.0}, 60.0),
}

BURST = [math.nan, math.inf, -math.inf, 1e308, -1e308]


def _run(kind: str, burst: list[tuple[float, int]], start: int) -> tuple[np.ndarray, np.ndarray]:
    params, sp = CONTROLLERS[kind]
    ctl = loopworks.create_block(kind, **params)
    proc = loopworks.create_block("process.first_order", gain=1.0, time_constant=5.0, y0=40.0)
    mod = Module({"proc": proc, "ctl": ctl}, wires={"proc.u": "ctl.out"},
                 inputs={"ctl": {"sp": sp}})
    pv, out = [], []
    dt = 0.5
    for k in range(400):
        y = float(proc.y[0])
        value, status = burst[k - start] if start <= k < start + len(burst) else (y, 128)
        ctl.set_inputs({"pv": (value, status)})
        mod.scan(dt)
        pv.append(float(proc.y[0]))
        out.append(float(ctl.y[0]))
    return np.array(pv), np.array(out)


@pytest.mark.parametrize("kind", sorted(CONTROLLERS))
@settings(max_examples=25)
@given(data=st.data())
def test_controller_returns_to_its_undisturbed_trajectory(kind: str, data: st.DataObject) -> None:
    start = data.draw(st.integers(40, 120))
    n = data.draw(st.integers(1, 8))
    burst = [(data.draw(st.sampled_from([*BURST, 50.0])),
              data.draw(st.sampled_from([128, 0, 0x18, 0x44]))) for _ in range(n)]
    # a finite good value in the burst is a real measurement; make every sample unusable
    burst = [(v, s) if not (math.isfinite(v) and abs(v) < 1e300 and s & 0xC0) else (v, 0)
             for v, s in burst]
    ref_pv, ref_out = _run(kind, [], 10**9)
    pv, out = _run(kind, burst, start)
    assert np.isfinite(pv).all() and np.isfinite(out).all()
    assert abs(ref_pv[-1] - 60.0) < 1e-3  # the undisturbed loop has settled
    np.testing.assert_allclose(pv[-40:], ref_pv[-40:], atol=1e-3)
    np.testing.assert_allclose(out[-40:], ref_out[-40:], atol=1e-3)
