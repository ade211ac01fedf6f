"""Choudhury et al. bicoherence test and PV–OP ellipse: golden values computed independently.

Statistics used as oracles (derived in the module docstring): with K segments and no phase
coupling b² is about Beta(1, K-1), so NGI of Gaussian noise ≈ (1 - c)/K with c = χ²_0.95(2)/(2K),
and b² of a perfectly quadratically phase-coupled triple is 1."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from loopworks.analysis.bicoherence import (
    ALPHA,
    NGI_THRESHOLD,
    NLI_THRESHOLD,
    bandpass,
    bicoherence_test,
    ellipse_fit,
    squared_bicoherence,
)

F1, F2 = 12 / 128, 30 / 128  # cycles per sample, on FFT bins of the 128-point segments


def qpc(n: int, rng: np.random.Generator, coupled: bool, noise: float = 0.1) -> np.ndarray:
    """cos(2π f1 k + φ1) + cos(2π f2 k + φ2) + cos(2π (f1+f2) k + φ3) + noise.

    Coupled: φ3 = φ1 + φ2 (quadratic phase coupling), φ1, φ2 random per realisation.
    Uncoupled: φ1, φ2, φ3 drawn afresh for every block of 128 samples (same power spectrum, no
    coupling); analyse it with non-overlapping 128-sample segments."""
    k = np.arange(n)
    if coupled:
        p1, p2 = rng.uniform(0.0, 2.0 * math.pi, 2)
        p3 = np.full(n, p1 + p2)
        p1a, p2a = np.full(n, p1), np.full(n, p2)
    else:
        blocks = n // 128
        p1a, p2a, p3 = (np.repeat(rng.uniform(0.0, 2.0 * math.pi, blocks), 128) for _ in range(3))
    x = (np.cos(2 * math.pi * F1 * k + p1a) + np.cos(2 * math.pi * F2 * k + p2a)
         + np.cos(2 * math.pi * (F1 + F2) * k + p3))
    return np.asarray(x + noise * rng.standard_normal(n))


def test_constants() -> None:
    assert (ALPHA, NGI_THRESHOLD, NLI_THRESHOLD) == (0.05, 0.001, 0.01)


def test_principal_domain_and_threshold() -> None:
    rng = np.random.default_rng(1)
    bic = squared_bicoherence(rng.standard_normal(4096), dt=0.5)
    # 1 ≤ j ≤ i, i + j < 64: Σ_{j=1}^{31} (64 - 2j) = 992 bifrequencies
    assert bic.b2.size == 992
    assert bic.segments == (4096 - 128) // 64 + 1 == 63
    assert np.all(bic.f2 <= bic.f1)
    assert np.all(bic.f2 > 0.0)
    assert np.all(bic.f1 + bic.f2 < 1.0 / (2 * 0.5))  # below Nyquist (1 Hz at dt = 0.5 s)
    assert bic.f1.min() == pytest.approx(1.0 / (128 * 0.5))
    assert np.all((bic.b2 >= 0.0) & (bic.b2 <= 1.0))
    assert bic.threshold == pytest.approx(stats.chi2.ppf(0.95, 2) / (2 * 63))
    assert bic.threshold == pytest.approx(-math.log(0.05) / 63)  # χ²(2) is exponential


def test_long_gaussian_noise_is_gaussian_and_linear() -> None:
    rng = np.random.default_rng(2024)
    res = bicoherence_test(rng.standard_normal(2**18))
    assert res.segments == 4095
    assert res.ngi <= NGI_THRESHOLD
    assert res.nli <= NLI_THRESHOLD
    assert not res.non_gaussian
    assert not res.nonlinear
    assert "caution" not in res.reason


def test_short_gaussian_noise_ngi_sits_at_the_one_over_k_floor() -> None:
    # The documented caveat: NGI of noise is (1 - c)/K, 0.015 for K = 63, above 0.001.
    ngis = []
    for seed in range(8):
        res = bicoherence_test(np.random.default_rng(seed).standard_normal(4096))
        ngis.append(res.ngi)
        assert "caution" in res.reason
    c = -math.log(0.05) / 63
    assert float(np.mean(ngis)) == pytest.approx((1.0 - c) / 63, rel=0.15)


def test_quadratic_phase_coupling_gives_b2_one_and_is_nonlinear() -> None:
    rng = np.random.default_rng(7)
    x = qpc(2**16, rng, coupled=True)
    bic = squared_bicoherence(x)
    assert bic.at(F1, F2) > 0.98
    assert bic.at(F1, F2) == pytest.approx(float(bic.b2.max()))
    res = bicoherence_test(x)
    assert res.non_gaussian
    assert res.nonlinear
    assert res.nli > 0.5


def test_same_spectrum_without_coupling_has_small_b2() -> None:
    rng = np.random.default_rng(8)
    x = qpc(2**16, rng, coupled=False)
    bic = squared_bicoherence(x, overlap=0.0)
    assert bic.segments == 512
    # Beta(1, 511): P(b² > 0.05) = 0.95^511 ≈ 4e-12
    assert bic.at(F1, F2) < 0.05


def test_linear_sine_in_noise_is_not_nonlinear() -> None:
    rng = np.random.default_rng(9)
    k = np.arange(2**18)
    x = np.sin(2 * math.pi * 20 / 128 * k + 0.3) + 0.5 * rng.standard_normal(k.size)
    res = bicoherence_test(x)
    assert not res.nonlinear
    assert res.nli <= NLI_THRESHOLD


def test_too_short_a_record_is_refused() -> None:
    with pytest.raises(ValueError, match="fewer than one segment"):
        bicoherence_test(np.zeros(100))


def parametric(m: float, n: float, alpha: float, center: tuple[float, float],
               t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    op = center[0] + m * np.cos(t) * math.cos(alpha) - n * np.sin(t) * math.sin(alpha)
    pv = center[1] + m * np.cos(t) * math.sin(alpha) + n * np.sin(t) * math.cos(alpha)
    return op, pv


def chord_through_centre(m: float, n: float, alpha: float) -> float:
    """OP-axis width through the centre, solved from the parametric form: PV = PV0 needs
    m·cos t·sin α + n·sin t·cos α = 0, i.e. t* = atan2(-m sin α, n cos α); the chord is twice
    the OP offset at t*."""
    ts = math.atan2(-m * math.sin(alpha), n * math.cos(alpha))
    assert abs(m * math.cos(ts) * math.sin(alpha) + n * math.sin(ts) * math.cos(alpha)) < 1e-12
    return 2.0 * abs(m * math.cos(ts) * math.cos(alpha) - n * math.sin(ts) * math.sin(alpha))


def test_ellipse_fit_recovers_a_known_ellipse() -> None:
    t = np.linspace(0.0, 2.0 * math.pi, 97, endpoint=False)
    op, pv = parametric(3.0, 1.0, 0.4, (50.0, 10.0), t)
    e = ellipse_fit(op, pv)
    assert e.center[0] == pytest.approx(50.0, abs=1e-6)
    assert e.center[1] == pytest.approx(10.0, abs=1e-6)
    assert e.m == pytest.approx(3.0, abs=1e-6)
    assert e.n == pytest.approx(1.0, abs=1e-6)
    assert e.alpha == pytest.approx(0.4, abs=1e-6)
    assert e.residual < 1e-9
    width = chord_through_centre(3.0, 1.0, 0.4)
    assert e.apparent_stiction == pytest.approx(width, abs=1e-6)
    assert width == pytest.approx(4.033142368949, abs=1e-9)  # hand value of 2mn/√(...)


def test_ellipse_fit_on_an_arc_with_swapped_axes() -> None:
    # semi-axis 1 along 0.4 rad and 3 across: m = 3 lies along 0.4 + π/2, reported as 0.4 - π/2
    t = np.linspace(0.3, 0.3 + 1.5 * math.pi, 60)
    op, pv = parametric(1.0, 3.0, 0.4, (-2.0, 7.0), t)
    e = ellipse_fit(op, pv)
    assert (e.m, e.n) == pytest.approx((3.0, 1.0), abs=1e-6)
    assert e.alpha == pytest.approx(0.4 - math.pi / 2.0, abs=1e-6)
    assert e.apparent_stiction == pytest.approx(chord_through_centre(1.0, 3.0, 0.4), abs=1e-6)


def test_ellipse_width_of_two_phase_shifted_sinusoids() -> None:
    # OP = a cos ωt, PV = b cos(ωt - φ): at PV = 0, ωt = φ ± π/2, OP = ∓a sin φ → width 2a|sin φ|
    t = np.linspace(0.0, 2.0 * math.pi, 200, endpoint=False)
    a, b, phi = 1.3, 0.6, 2.08
    e = ellipse_fit(a * np.cos(t), b * np.cos(t - phi))
    assert e.apparent_stiction == pytest.approx(2.0 * a * abs(math.sin(phi)), rel=1e-9)


def test_ellipse_fit_with_noise() -> None:
    rng = np.random.default_rng(3)
    t = rng.uniform(0.0, 2.0 * math.pi, 2000)
    op, pv = parametric(3.0, 1.0, 0.4, (50.0, 10.0), t)
    sigma = 0.02
    e = ellipse_fit(op + sigma * rng.standard_normal(t.size),
                    pv + sigma * rng.standard_normal(t.size))
    assert e.m == pytest.approx(3.0, rel=0.02)
    assert e.n == pytest.approx(1.0, rel=0.02)
    assert e.alpha == pytest.approx(0.4, abs=0.02)
    assert e.residual == pytest.approx(sigma, rel=0.25)  # distance to the curve ≈ noise


def test_ellipse_fit_refuses_a_line() -> None:
    x = np.linspace(0.0, 1.0, 20)
    with pytest.raises(ValueError):
        ellipse_fit(x, 2.0 * x + 1.0)


def test_bandpass_passes_f0_and_attenuates_the_third_harmonic() -> None:
    dt, period = 0.05, 100.0
    t = np.arange(0.0, 4000.0, dt)
    w = 2.0 * math.pi / period
    mid = slice(t.size // 4, 3 * t.size // 4)
    y1 = bandpass(np.sin(w * t), dt, period)
    assert np.max(np.abs(y1[mid] - np.sin(w * t[mid]))) < 1e-3  # |H(f0)| = 1, zero phase
    y3 = bandpass(np.sin(3.0 * w * t), dt, period)
    # analogue prototype: Ω = (9 - 1)/(3·(2 - 1/2)) = 16/9, |H| = 1/√(1 + Ω⁴), applied twice
    omega = 16.0 / 9.0
    assert np.max(np.abs(y3[mid])) == pytest.approx(1.0 / (1.0 + omega**4), rel=0.03)
    with pytest.raises(ValueError, match="Nyquist"):
        bandpass(np.sin(w * t), dt, 0.15)


def test_odd_inputs_are_named_errors_or_undetermined_not_an_answer() -> None:
    """Found by an outside audit: dt = 0 raised ZeroDivisionError, alpha = 2 gave a NaN
    threshold, collinear OP and PV a numpy LinAlgError, and a record of one or two segments
    answered "Gaussian (linear)" though its threshold c = χ²/(2K) (3 and 1.5) is above every
    possible b² (at most 1): it cannot tell."""
    from loopworks.analysis.bicoherence import bicoherence_test, ellipse_fit

    noise = np.random.default_rng(0).normal(size=4000)
    with pytest.raises(ValueError, match=r"dt = 0.0 s is out of range"):
        bicoherence_test(noise, dt=0.0)
    with pytest.raises(ValueError, match=r"alpha = 2.0 is out of range: allowed \(0, 1\)"):
        bicoherence_test(noise, alpha=2.0)
    with pytest.raises(ValueError, match="lie on a straight line"):
        ellipse_fit(np.arange(20.0), 2.0 * np.arange(20.0) + 1.0)
    short = bicoherence_test(noise[:200])  # K = 2 segments of 128
    assert short.segments == 2 and "undetermined" in short.reason
    assert "Gaussian (linear)" not in short.reason
    assert "undetermined" not in bicoherence_test(noise).reason  # K = 61: it answers
