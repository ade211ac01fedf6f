"""Horch's cross-correlation stiction test (spec 4.3), on synthetic signals with known phase
and on a simulated PI loop with a Choudhury stick-slip valve (spec 1.2, reference case 5.1)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from loopworks.analysis.area_ratio import area_ratio
from loopworks.analysis.horch import (
    PHASE_NO_STICTION_DEG,
    PHASE_STICTION_DEG,
    cross_correlation,
    horch_test,
)
from loopworks.analysis.oscillation import regularity
from tests.analysis.conftest import SPEC_DT

DT = 0.1
PERIOD = 100.0


def time(t_end: float = 2000.0) -> np.ndarray:
    return np.arange(0.0, t_end, DT)


def test_cross_correlation_lag_convention_and_normalisation() -> None:
    rng = np.random.default_rng(4)
    op = rng.standard_normal(4000)
    pv = np.roll(op, 5)  # PV is OP five samples later (circular: 5 of 4000 samples wrap)
    r = cross_correlation(op, pv, 20)
    assert len(r) == 41
    assert int(np.argmax(r)) == 20 + 5  # the peak at lag +5: PV lags OP
    assert r[25] == pytest.approx(1.0, abs=0.01)
    assert cross_correlation(op, op, 0)[0] == pytest.approx(1.0)
    assert cross_correlation(op, -op, 3)[3] == pytest.approx(-1.0)


def test_cross_correlation_refuses_bad_input() -> None:
    with pytest.raises(ValueError, match="same length"):
        cross_correlation(np.arange(10.0) ** 2, np.arange(11.0) ** 2, 2)
    with pytest.raises(ValueError, match="constant"):
        cross_correlation(np.ones(10), np.arange(10.0) ** 2, 2)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_sticky_valve_triangle_op_square_pv_is_stiction(sign: float) -> None:
    # a sticky valve: the integral ramps OP (a triangle) while the valve holds; each slip
    # moves PV to the other level, so PV is a square wave in step with OP's slope (90° apart)
    t = time()
    phase = (t / PERIOD) % 1.0
    op = np.where(phase < 0.5, 4.0 * phase - 1.0, 3.0 - 4.0 * phase)  # triangle ±1
    pv = sign * np.where(phase < 0.5, 1.0, -1.0)  # + while OP rises
    res = horch_test(op, pv, DT)
    assert res.verdict == "stiction"
    # the CCF of a triangle and a square in quadrature is odd: zero at lag 0, its other
    # crossing half a period away
    assert abs(res.ccf0) < 0.02
    assert res.asymmetry > 0.95
    assert max(res.lag_left_s, res.lag_right_s) == pytest.approx(PERIOD / 2, rel=0.02)


@pytest.mark.parametrize(("lag_deg", "verdict"), [
    (180.0, "no_stiction"),  # OP and PV 180° apart: even CCF
    (170.0, "no_stiction"),
    (135.0, "undetermined"),
    (100.0, "stiction"),
    (90.0, "stiction"),  # quadrature: odd CCF
])
def test_sines_phase_gives_the_ccf_phase(lag_deg: float, verdict: str) -> None:
    # op = sin(ωt), pv = sin(ωt − φ): r(τ) ∝ cos(ωτ − φ), whose extremum nearest lag 0 is
    # at ωτ₀ = φ − 180°; the CCF's phase from even is |180° − φ| and a = |180° − φ|/90°
    t = time()
    w = 2.0 * np.pi / PERIOD
    op = np.sin(w * t)
    pv = np.sin(w * t - math.radians(lag_deg))
    res = horch_test(op, pv, DT)
    assert res.asymmetry == pytest.approx(abs(180.0 - lag_deg) / 90.0, abs=0.01)
    assert res.verdict == verdict


def test_antiphase_sines_have_an_extremum_at_lag_zero() -> None:
    t = time()
    op = np.sin(2.0 * np.pi * t / PERIOD)
    res = horch_test(op, -op, DT)
    assert res.verdict == "no_stiction"
    assert res.ccf0 == pytest.approx(-1.0, abs=1e-6)
    # crossings of −cos(ωτ) at ±a quarter period
    assert res.lag_left_s == pytest.approx(PERIOD / 4, rel=0.01)
    assert res.lag_right_s == pytest.approx(PERIOD / 4, rel=0.01)
    assert res.asymmetry < 0.01


def test_thresholds_are_ordered() -> None:
    assert 0.0 < PHASE_NO_STICTION_DEG < PHASE_STICTION_DEG < 90.0


def test_integrating_loops_are_undetermined() -> None:
    t = time()
    w = 2.0 * np.pi / PERIOD
    res = horch_test(np.sin(w * t), np.cos(w * t), DT, loop_type="integrating")
    assert res.verdict == "undetermined"
    assert "integrating" in res.reason
    with pytest.raises(ValueError, match="loop_type"):
        horch_test(np.sin(w * t), np.cos(w * t), DT, loop_type="level")  # type: ignore[arg-type]


def test_no_variation_or_no_crossing_is_undetermined() -> None:
    t = time(200.0)
    flat = horch_test(np.sin(t), np.full(len(t), 3.0), DT)
    assert flat.verdict == "undetermined"
    # a window of lags shorter than a quarter period: no crossing on either side
    w = 2.0 * np.pi / PERIOD
    short = horch_test(np.sin(w * time()), -np.sin(w * time()), DT, max_lag=100)
    assert short.verdict == "undetermined"
    assert "no zero crossing" in short.reason


def test_closed_loop_with_sticky_valve(
        spec_cycle: tuple[np.ndarray, np.ndarray, np.ndarray]) -> None:
    dt = SPEC_DT
    sp, pv, op = spec_cycle  # the limit cycle, as spec 5.1 measures it (second half)
    # spec 5.1: PV amplitude 0.556, OP amplitude 1.560, period 112.0 s
    assert np.ptp(pv) / 2 == pytest.approx(0.556, rel=0.05)
    assert np.ptp(op) / 2 == pytest.approx(1.560, rel=0.05)
    osc = regularity(pv, dt)
    assert osc.detected
    assert osc.period_s == pytest.approx(112.0, rel=0.2)
    res = horch_test(op, pv, dt)
    assert res.verdict == "stiction", res.reason
    assert horch_test(op, sp - pv, dt).verdict == "stiction"  # control error: sign only
    assert area_ratio(sp - pv, dt).verdict == "stiction"
