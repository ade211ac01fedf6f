"""ACF, Thornhill's regularity and Miao & Seborg's decay ratio (spec 4.2).

Golden values come from closed forms: a sine's period, the Box-Jenkins ACF of a sine, the
Yule-Walker ACF of an AR(2) process."""

from __future__ import annotations

import math

import numpy as np
import pytest

from loopworks.analysis.oscillation import (
    DECAY_RATIO_THRESHOLD,
    REGULARITY_THRESHOLD,
    acf,
    acf_band,
    decay_ratio,
    regularity,
    zero_crossings,
)

DT = 0.1


def sine(period: float, t_end: float = 2000.0, phase: float = 0.0) -> np.ndarray:
    t = np.arange(0.0, t_end, DT)
    return np.asarray(np.sin(2.0 * np.pi * t / period + phase))


def test_zero_crossings_interpolated_and_zero_runs() -> None:
    # 1 -> -1 crosses at 0.5; -1 -> 3 crosses a quarter of the way: 2.25
    assert np.allclose(zero_crossings(np.array([1.0, -1.0, -1.0, 3.0])), [0.5, 2.25])
    # a run of exact zeros between opposite signs: its middle
    assert np.allclose(zero_crossings(np.array([1.0, 0.0, 0.0, -1.0])), [1.5])
    # touching zero and returning is no crossing
    assert len(zero_crossings(np.array([1.0, 0.0, 1.0]))) == 0


def test_acf_of_sine_matches_the_biased_estimate() -> None:
    # 40 whole periods of 500 samples: Σ_t sin(ωt)·sin(ω(t+k)) over N − k samples is
    # (N − k)/2·cos(ωk) − ½·Σ cos(ω(2t + k)), the last sum bounded by 1/(2·|sin ω|) ≈ 39.8;
    # with Σ sin² = N/2 = 10⁴, ρ(k) = (1 − k/N)·cos(ωk) within 0.004 (plus the detrending)
    x = sine(50.0)
    n = len(x)
    k = np.arange(1001)
    expected = (1.0 - k / n) * np.cos(2.0 * np.pi * k / 500.0)
    r = acf(x, 1000)
    assert r[0] == pytest.approx(1.0)
    assert np.max(np.abs(r - expected)) < 5e-3


def test_acf_removes_mean_and_linear_trend_exactly() -> None:
    x = np.random.default_rng(3).standard_normal(800)
    k = np.arange(800)
    assert np.allclose(acf(x + 7.0 + 0.05 * k, 100), acf(x, 100), atol=1e-12)


def test_acf_rejects_constant_and_bad_lag() -> None:
    with pytest.raises(ValueError, match="constant"):
        acf(np.full(50, 3.0), 10)
    with pytest.raises(ValueError, match="max_lag"):
        acf(np.arange(10.0) ** 2, 10)


@pytest.mark.parametrize("period", [50.0, 37.3, 123.0])
def test_regularity_of_a_pure_sine(period: float) -> None:
    osc = regularity(sine(period, phase=0.4), DT)
    assert osc.detected
    assert osc.period_s == pytest.approx(period, rel=0.01)
    assert osc.regularity > 100.0
    assert osc.crossings == 11


def test_regularity_ignores_a_ramp_under_the_sine() -> None:
    x = sine(50.0) + 0.02 * np.arange(20000)
    osc = regularity(x, DT)
    assert osc.detected
    assert osc.period_s == pytest.approx(50.0, rel=0.01)


def test_white_noise_is_not_a_regular_oscillation() -> None:
    x = np.random.default_rng(12345).standard_normal(5000)
    osc = regularity(x, 1.0)
    assert not osc.detected
    assert not osc.regularity > REGULARITY_THRESHOLD  # r <= 1 or NaN


def test_white_noise_rarely_detected() -> None:
    # the white-noise band keeps the false-alarm rate low (the plain rule flags ~25 %)
    hits = sum(regularity(np.random.default_rng(s).standard_normal(3000), 1.0).detected
               for s in range(60))
    assert hits <= 6


def test_the_noise_band_is_bartletts_standard_error() -> None:
    """se = √((1 + 2·Σ_{k<=q} r_k²)/n) over the ACF's first lobe (Box & Jenkins eq. 2.1.13):
    1/√n for white noise; for the theoretical AR(1) ACF φ^k, which never changes sign, the
    whole sum, φ²/(1 - φ²) for a long record."""
    n = 2000
    white = np.r_[1.0, np.zeros(50)]
    assert acf_band(white, n) == pytest.approx(1.0 / math.sqrt(n), rel=1e-12)
    phi = 0.9
    ar1 = phi ** np.arange(400)
    assert acf_band(ar1, n) == pytest.approx(
        math.sqrt((1.0 + 2.0 * phi**2 / (1.0 - phi**2)) / n), rel=1e-9)
    lobe = np.array([1.0, 0.5, 0.2, -0.3, 0.4])  # the lobe ends before the sign change
    assert acf_band(lobe, 100) == pytest.approx(math.sqrt((1.0 + 2.0 * 0.29) / 100), rel=1e-12)


@pytest.mark.parametrize("phi", [0.9, 0.95, 0.98])
def test_slowly_decaying_noise_is_not_a_regular_oscillation(phi: float) -> None:
    """AR(1) noise (a slow load) has no oscillation; under the white-noise band ±3/√N its
    sample ACF's wandering lobes read as a regular oscillation in 37 (φ 0.9), 65 (0.95) and
    46 (0.98, 751 samples) of 200 records. Under the Bartlett band: none of 100."""
    from scipy.signal import lfilter

    n = 751 if phi == 0.98 else 2000
    hits = sum(regularity(lfilter([1.0], [1.0, -phi],
                                  np.random.default_rng(s).standard_normal(n)), 1.0).detected
               for s in range(100))
    assert hits == 0


@pytest.mark.parametrize("period", [20, 60, 150, 300])
def test_a_sine_in_noise_is_still_found(period: int) -> None:
    """The Bartlett band widens with the ACF's first lobe, which a sine has too: a sine of
    std 0.5 in unit white noise (2000 samples) is found in every one of 20 records, at 20 to
    300 samples a period, as under ±3/√N."""
    t = np.arange(2000)
    for s in range(20):
        rng = np.random.default_rng(s)
        x = 0.5 * math.sqrt(2.0) * np.sin(2.0 * np.pi * (t + rng.uniform(0, period)) / period)
        assert regularity(x + rng.standard_normal(2000), 1.0).detected, s


def test_few_crossings_give_period_then_nothing() -> None:
    x = sine(50.0)  # ACF crossings at 12.5, 37.5, 62.5, 87.5 s …
    three = regularity(x, DT, max_lag=700)  # lags up to 70 s: 3 crossings
    assert three.crossings == 3
    assert not three.detected
    assert three.period_s == pytest.approx(50.0, rel=0.01)
    assert math.isnan(three.regularity)
    assert "undetermined" in three.reason
    two = regularity(x, DT, max_lag=500)  # up to 50 s: 2 crossings
    assert two.crossings == 2
    assert not two.detected
    assert math.isnan(two.period_s)
    assert "not oscillating" in two.reason


def test_constant_signal_is_not_oscillating() -> None:
    osc = regularity(np.full(1000, 42.0), DT)
    assert not osc.detected
    assert math.isnan(osc.period_s)
    assert osc.crossings == 0


def test_regularity_rejects_bad_dt() -> None:
    with pytest.raises(ValueError, match="dt"):
        regularity(sine(50.0), 0.0)


def ar2_decay_ratio(radius: float, theta: float, lags: int = 400) -> float:
    """First positive-lobe peak / |first negative-lobe trough| of the exact ACF of
    x_t = φ1·x_{t−1} + φ2·x_{t−2} + e_t (Yule-Walker: ρ0 = 1, ρ1 = φ1/(1 − φ2),
    ρk = φ1·ρ_{k−1} + φ2·ρ_{k−2})."""
    phi1, phi2 = 2.0 * radius * math.cos(theta), -radius * radius
    rho = [1.0, phi1 / (1.0 - phi2)]
    for _ in range(lags):
        rho.append(phi1 * rho[-1] + phi2 * rho[-2])
    r = np.array(rho)
    sign = np.sign(r)
    cross = np.flatnonzero(sign[:-1] != sign[1:])  # r[c] and r[c+1] of opposite sign
    trough = r[cross[0] + 1:cross[1] + 1].min()
    peak = r[cross[1] + 1:cross[2] + 1].max()
    return float(peak / abs(trough))


def ar2(radius: float, theta: float, n: int, seed: int) -> np.ndarray:
    from scipy.signal import lfilter

    e = np.random.default_rng(seed).standard_normal(n)
    return np.asarray(lfilter([1.0], [1.0, -2.0 * radius * math.cos(theta), radius ** 2], e))


@pytest.mark.parametrize(("radius", "excessive"), [(0.96, True), (0.85, False)])
def test_decay_ratio_of_ar2_matches_yule_walker(radius: float, excessive: bool) -> None:
    theta = 2.0 * math.pi / 20.0  # 20-sample period
    golden = ar2_decay_ratio(radius, theta)
    # the half-period decay of the ACF's envelope is about radius**10
    assert golden == pytest.approx(radius ** 10, rel=0.15)
    got = decay_ratio(ar2(radius, theta, 400_000, seed=7))
    assert got == pytest.approx(golden, abs=0.03)
    assert (got > DECAY_RATIO_THRESHOLD) is excessive


def test_decay_ratio_of_a_sine_is_one() -> None:
    # ρ(k) ≈ (1 − k/N)·cos(ωk): the peak at one period over the trough at half a period
    x = sine(50.0)
    n = len(x)
    assert decay_ratio(x) == pytest.approx((1 - 500 / n) / (1 - 250 / n), abs=1e-3)


def test_decay_ratio_nan_without_oscillation() -> None:
    assert math.isnan(decay_ratio(np.full(100, 1.0)))
    # lags up to 20 s of a 50 s sine: one crossing (12.5 s), no complete negative lobe
    assert math.isnan(decay_ratio(sine(50.0), max_lag=200))


@pytest.mark.parametrize("period", [20.0, 21.0, 24.0, 27.0, 36.0, 42.0])
def test_half_cycle_crossings_of_a_clean_sine_are_where_it_crosses(period: float) -> None:
    """The half cycles the curve fit and the area ratio measure start where the wave crosses
    zero: sin(2πk/P + φ) crosses at k = (mπ - φ)·P/(2π). The smoothing window round(P/6) was
    even for P = 21-27 and 36, its average lagged half a sample, every crossing moved by
    +0.5 sample and a clean sine's curve-fit index (He et al. 2007: 0 for a sine) read
    0.3-0.5 (found by an outside audit)."""
    from loopworks.analysis.curve_fit import curve_fit_index
    from loopworks.analysis.oscillation import cycle_crossings

    k = np.arange(3000)
    phase = 0.37
    y = np.sin(2.0 * np.pi * k / period + phase)
    z = cycle_crossings(y, period)
    m = np.round((2.0 * np.pi * z / period + phase) / np.pi)  # the nearest true crossing
    true = (m * np.pi - phase) * period / (2.0 * np.pi)
    assert np.max(np.abs(z[1:-1] - true[1:-1])) < 0.01
    assert curve_fit_index(y, 1.0, "self-regulating", period=period).si < 0.02
