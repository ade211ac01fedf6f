"""Loop metrics (spec plant-and-tuning 4.1) on signals with known answers."""

import math

import numpy as np
import pytest

from loopworks.sim import metrics


def test_error_integrals() -> None:
    t = np.arange(4) * 0.5
    e = np.array([2.0, -1.0, 0.5, 0.0])
    assert metrics.iae(e, 0.5) == pytest.approx((2 + 1 + 0.5) * 0.5)
    assert metrics.ise(e, 0.5) == pytest.approx((4 + 1 + 0.25) * 0.5)
    assert metrics.itae(e, t) == pytest.approx((0 * 2 + 0.5 * 1 + 1.0 * 0.5) * 0.5)


def test_travel() -> None:
    assert metrics.travel(np.array([0.0, 2.0, 1.0, 1.0, 4.0])) == pytest.approx(6.0)


def test_first_order_step_figures() -> None:
    """y = 1 - e^(-t/T): rise 10-90 % = T·ln 9, settling (2 %) = T·ln 50, no overshoot."""
    tau, dt = 10.0, 0.001
    t = np.arange(0.0, 200.0, dt)
    y = 1.0 - np.exp(-t / tau)
    m = metrics.step_metrics(t, y, 1.0)
    assert m.overshoot_pct == 0.0
    assert m.rise_time_s == pytest.approx(tau * math.log(9.0), abs=2 * dt)
    assert m.settling_time_s == pytest.approx(tau * math.log(50.0), abs=2 * dt)


def test_overshoot_of_a_downward_step() -> None:
    t = np.arange(6.0)
    y = np.array([10.0, 6.0, 3.0, 5.0, 5.0, 5.0])     # from 10 to 5, undershoots to 3
    m = metrics.step_metrics(t, y, 5.0)
    assert m.step_size == -5.0
    assert m.overshoot_pct == pytest.approx(40.0)


def test_never_settled_is_nan() -> None:
    t = np.arange(5.0)
    m = metrics.step_metrics(t, np.array([0.0, 0.2, 0.4, 0.6, 0.8]), 1.0)
    assert math.isnan(m.settling_time_s)
    assert math.isnan(m.rise_time_s)
