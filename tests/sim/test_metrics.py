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


def test_reversals_ignore_moves_below_the_threshold() -> None:
    # spec 4.1: up, down, up (2 reversals); the 0.01 wiggles are noise below 0.05
    assert metrics.reversals(np.array([0.0, 1.0, 1.01, 1.0, 0.5, 0.51, 2.0]), 0.05) == 2
    wiggle = np.array([0.0, 1.0, 0.99, 1.0, 0.99, 1.0, 2.0])
    assert metrics.reversals(wiggle, 0.05) == 0
    assert metrics.reversals(wiggle, 0.0) == 4


def test_hagglund_detector_flags_large_half_periods() -> None:
    """spec 4.2: a sine of amplitude A at ωu has 2A/ωu of |e| per half period; with a = 1 the
    limit is 2/ωu, so A = 2 flags every half period and A = 0.5 none."""
    wu = 2 * np.pi / 20.0
    t = np.arange(0.0, 2000.0, 0.01)
    big = metrics.oscillation_detector(t, 2.0 * np.sin(wu * t + 0.1), a=1.0, wu=wu)
    small = metrics.oscillation_detector(t, 0.5 * np.sin(wu * t + 0.1), a=1.0, wu=wu)
    assert big.iae_limit == pytest.approx(2.0 / wu)
    half_periods = 2000.0 / 10.0
    assert big.large_half_periods >= half_periods - 2
    assert big.alarm
    assert small.large_half_periods == 0 and not small.alarm
    # the Ti form: IAE_lim = a·Ti/π
    assert metrics.oscillation_detector(t, np.sin(t), ti=30.0).iae_limit == pytest.approx(
        30.0 / np.pi)


def test_loop_metrics_window_and_valve() -> None:
    t = np.arange(10.0)
    sp = np.full(10, 5.0)
    pv = np.array([0.0, 1, 2, 3, 4, 5, 6, 5, 4, 5])
    out = np.array([0.0, 1, 0, 1, 0, 1, 0, 1, 0, 1])
    pos = np.array([0.0, 0, 0, 1, 1, 1, 1, 0, 0, 0])
    m = metrics.loop_metrics(t, sp, pv, out, position=pos, window=(5.0, 9.0))
    assert m["IAE"] == pytest.approx(0 + 1 + 0 + 1 + 0)
    assert m["PV peak to peak"] == pytest.approx(2.0)
    assert m["output travel"] == pytest.approx(4.0)
    assert m["valve travel"] == pytest.approx(1.0)
    assert m["output reversals"] == 3.0
    with pytest.raises(ValueError, match="window"):
        metrics.loop_metrics(t, sp, pv, out, window=(20.0, 30.0))
