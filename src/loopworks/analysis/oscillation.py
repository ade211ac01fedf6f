"""Oscillation detection from the autocorrelation function (spec plant-and-tuning 4.2).

Pure functions on a uniformly sampled signal x (sample period dt in s):

- :func:`acf`: the autocorrelation of the mean-centred, linearly detrended signal;
- :func:`regularity`: period and regularity of an oscillation from the ACF's zero crossings
  (Thornhill, Huang & Zhang 2003);
- :func:`decay_ratio`: the ACF decay ratio (Miao & Seborg 1999).

Hägglund's (1995) IAE load-disturbance detector is :func:`loopworks.sim.metrics.
oscillation_detector`; it is not repeated here.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage, signal

#: Thornhill, Huang & Zhang (2003): an oscillation is regular when r = Tp/(3·σ_Tp) > 1
REGULARITY_THRESHOLD = 1.0
#: zero crossings of the ACF needed for a period: two intervals, Tp = 2·mean(interval)
MIN_CROSSINGS_PERIOD = 3
#: zero crossings needed for the regularity: three intervals give two period estimates
#: (pairs of successive intervals), the fewest with a standard deviation
MIN_CROSSINGS_REGULARITY = 4
#: zero crossings of the ACF used at most (ten intervals). Assumption: the ACF of a finite
#: record decays with the lag, so only its first crossings are well placed; the number is
#: this module's choice, not a figure verified in the paper.
MAX_CROSSINGS = 11
#: noise guard (this module's addition, not in the papers): an ACF lobe counts only when it
#: leaves the band ±NOISE_BAND_SIGMAS·se, se the standard error of the sample ACF beyond its
#: first lobe by Bartlett's formula (:func:`acf_band`): 1/√N for white noise, wider for a
#: signal whose ACF decays slowly, so crossings inside the band are noise.
NOISE_BAND_SIGMAS = 3.0
#: Miao & Seborg (1999): an ACF decay ratio above 0.5 indicates excessive oscillation
DECAY_RATIO_THRESHOLD = 0.5


def detrend(x: np.ndarray) -> np.ndarray:
    """x minus its least-squares straight line (which also removes its mean)."""
    y = np.asarray(x, dtype=np.float64)
    if y.ndim != 1:
        raise ValueError(f"expected a 1-D signal, got shape {y.shape}")
    if not np.all(np.isfinite(y)):
        raise ValueError("the signal holds a NaN or infinite sample")
    n = len(y)
    if n < 2:
        return y - y.mean() if n else y
    k = np.arange(n, dtype=np.float64)
    slope, intercept = np.polyfit(k, y, 1)
    return np.asarray(y - (slope * k + intercept), dtype=np.float64)


def is_flat(y: np.ndarray) -> bool:
    """True when a detrended signal has no variation left (a constant or a straight line)."""
    return bool(np.sum(y * y) <= 1e-24 * max(1.0, len(y)))


def acf(x: np.ndarray, max_lag: int) -> np.ndarray:
    """Autocorrelation of ``x`` at lags 0 … max_lag (samples), normalised to 1 at lag 0.

    With y the mean-centred, linearly detrended x (its least-squares line removed) and N
    samples, the biased estimate::

        ρ(k) = Σ_{t=0}^{N-1-k} y_t·y_{t+k} / Σ_{t=0}^{N-1} y_t²,   k = 0 … max_lag

    (Box & Jenkins' estimator: it is a positive semi-definite sequence and tapers towards 0 as
    k approaches N). Computed by FFT. A constant or straight-line signal has no ACF: raises
    ``ValueError``.
    """
    y = detrend(x)
    n = len(y)
    if not 0 <= max_lag < n:
        raise ValueError(f"max_lag must be in 0 … {n - 1} (the signal has {n} samples), "
                         f"got {max_lag}")
    if is_flat(y):
        raise ValueError("the signal is constant (or a straight line): no autocorrelation")
    full = signal.correlate(y, y, mode="full", method="fft")
    r = np.asarray(full[n - 1:n + max_lag], dtype=np.float64)
    return np.asarray(r / r[0], dtype=np.float64)


def zero_crossings(y: np.ndarray) -> np.ndarray:
    """Positions (in samples, fractional) where ``y`` changes sign.

    Between successive non-zero samples i < j of opposite sign: when j = i + 1 the crossing is
    interpolated linearly, ``i + y_i/(y_i − y_j)``; when exact zeros lie between them, it is
    the middle of the run of zeros, (i + j)/2. A signal that touches 0 and returns to the same
    side does not cross.
    """
    y = np.asarray(y, dtype=np.float64)
    idx = np.flatnonzero(y != 0.0)
    if len(idx) < 2:
        return np.empty(0)
    s = np.sign(y[idx])
    ch = np.flatnonzero(s[:-1] != s[1:])
    i, j = idx[ch], idx[ch + 1]
    yi, yj = y[i], y[j]
    adjacent = j == i + 1
    with np.errstate(divide="ignore", invalid="ignore"):
        interp = i + yi / (yi - yj)
    return np.where(adjacent, interp, 0.5 * (i + j)).astype(np.float64)


def band_crossings(y: np.ndarray, band: float) -> np.ndarray:
    """Zero crossings (samples, fractional) of ``y`` that separate lobes leaving ±band.

    A sample is significant when |y_k| > band. Between two successive significant samples of
    opposite sign the crossing is the last sign change of y before the second
    (:func:`zero_crossings`); excursions that stay inside ±band, and the crossings they make,
    are ignored (hysteresis). ``band`` = 0 keeps every sign change.
    """
    y = np.asarray(y, dtype=np.float64)
    idx = np.flatnonzero(np.abs(y) > band)
    if len(idx) < 2:
        return np.empty(0)
    s = np.sign(y[idx])
    second = idx[np.flatnonzero(s[:-1] != s[1:]) + 1]
    z = zero_crossings(y)
    return np.asarray(z[np.searchsorted(z, second, side="right") - 1], dtype=np.float64)


#: a half cycle's crossings are found on the signal smoothed over this share of the period
CYCLE_SMOOTHING = 1.0 / 6.0
#: ... between lobes that leave this many standard deviations of the noise left in it
CYCLE_BAND_SIGMAS = 3.0


def cycle_crossings(y: np.ndarray, period: float) -> np.ndarray:
    """Zero crossings (samples, fractional) of the oscillation of ``period`` samples in the
    (centred) signal ``y``: the half cycles the half-cycle methods (area ratio, curve
    fitting) measure, not the sign changes of the noise on it.

    y is smoothed by a centred moving average of w = max(1, round(:data:`CYCLE_SMOOTHING` ·
    period)) samples, made odd (a sixth of a period passes the fundamental at sinc(π/6) = 0.95 and
    keeps the crossings of a symmetric wave where they are), and the crossings are those of
    the smoothed signal between lobes that leave ±:data:`CYCLE_BAND_SIGMAS` times the noise
    left in it, σ/√w with σ the standard deviation of y about its smoothed self
    (:func:`band_crossings`). This module's addition, not the papers': they assume clean half
    cycles, and on a noisy record every sign change of the noise started a "half cycle" (a
    stiction cycle of 57 s half cycles read as 751 half cycles of noise, area ratio 1.06)."""
    y = np.asarray(y, dtype=np.float64)
    smooth, w = cycle_smoothed(y, period)
    if w == 1:
        return zero_crossings(y)
    noise = float(np.std(y - smooth)) / math.sqrt(w)
    return band_crossings(smooth, CYCLE_BAND_SIGMAS * noise)


def cycle_smoothed(y: np.ndarray, period: float) -> tuple[np.ndarray, int]:
    """``y`` smoothed by the centred moving average of :func:`cycle_crossings` (w =
    max(1, round(:data:`CYCLE_SMOOTHING` · period)) samples, made odd: an even window has no
    centre sample, and its average lags half a sample, which moved every crossing of a clean
    sine by +0.5 sample and gave it a curve-fit index of 0.3-0.5 instead of 0 at periods of
    9-15, 21-27, ... samples (found by an outside audit); the ends hold their nearest value),
    and w (1: ``y`` itself)."""
    y = np.asarray(y, dtype=np.float64)
    w = max(1, round(CYCLE_SMOOTHING * period)) if math.isfinite(period) else 1
    w += 1 - w % 2  # odd
    if w == 1 or len(y) < w:
        return y, 1
    return np.asarray(ndimage.uniform_filter1d(y, w, mode="nearest"), dtype=np.float64), w


#: the share of the half cycles an oscillation's period implies (2N/P in N samples) that
#: must stand above the noise for the half-cycle methods to measure them [ours]
MIN_CYCLE_SHARE = 1.0 / 3.0


def cycle_half_cycles(y: np.ndarray, period: float) -> tuple[list[tuple[float, float]], str]:
    """The half cycles of the oscillation of ``period`` samples in ``y``, as (start, end)
    crossings in samples (successive :func:`cycle_crossings`), and ``""``; or no half cycles
    and the reason, when fewer than :data:`MIN_CYCLE_SHARE` of the 2N/P half cycles the
    period implies stand above the noise: the oscillation the error's ACF found is not
    visible in this signal, and the few lobes that are (or several merged into one) say
    nothing of its shape (a linear loop under a slow external sine read "late peaks", R = 2.0,
    on 5 such lobes of 66)."""
    z = cycle_crossings(y, period)
    pairs = [(float(a), float(b)) for a, b in itertools.pairwise(z)]
    expected = 2.0 * len(y) / period
    if len(pairs) < MIN_CYCLE_SHARE * expected:
        return [], (f"{len(pairs)} half cycle(s) stand above the noise, of the "
                    f"{expected:.0f} its period ({period:.3g} samples) implies: fewer than "
                    f"{MIN_CYCLE_SHARE:.0%}")
    return pairs, ""


def acf_band(r: np.ndarray, n: int) -> float:
    """The standard error of an n-sample ACF ``r`` (r[0] = 1) at the lags beyond its first
    lobe, by Bartlett's formula with the lobe's lags q = 1 .. (the last lag before the first
    sign change) taken as the ACF's memory::

        se = √((1 + 2·Σ_{k=1..q} r_k²) / n)

    (M. S. Bartlett, "On the theoretical specification and sampling properties of
    autocorrelated time-series", J. R. Stat. Soc. B 8 (1946) 27-41; Box & Jenkins, *Time
    Series Analysis*, 1976, eq. 2.1.13: the large-lag variance of the sample ACF of a
    process whose ACF is zero beyond q). For white noise se = 1/√n. A slowly decaying ACF
    (an AR(1) load, φ = 0.9-0.98) has a long first lobe, and the lobes its sample ACF
    wanders into beyond it are noise of this size; under the white-noise band 1/√n they
    read as a regular oscillation in 37-65 of 200 records [tests/analysis/
    test_oscillation.py], and a linear loop under such a load was called sticky (7 of 60
    seeds)."""
    r = np.asarray(r, dtype=np.float64)
    change = np.flatnonzero(np.sign(r[1:]) != np.sign(r[:-1]))
    q = int(change[0]) + 1 if len(change) else len(r)
    return math.sqrt((1.0 + 2.0 * float(np.sum(r[1:q] ** 2))) / n)


def acf_crossings(r: np.ndarray, n: int, noise_sigmas: float = NOISE_BAND_SIGMAS
                  ) -> np.ndarray:
    """Zero crossings (lags, fractional) of an ACF ``r`` of an n-sample signal between lobes
    that leave the noise band ±noise_sigmas·:func:`acf_band` (:func:`band_crossings`)."""
    return band_crossings(r, noise_sigmas * acf_band(r, n) if noise_sigmas > 0 else 0.0)


@dataclass(frozen=True)
class Oscillation:
    """Result of :func:`regularity`.

    ``detected``: a regular oscillation (r > 1); ``period_s``: Tp in s (NaN when fewer than
    ``MIN_CROSSINGS_PERIOD`` crossings); ``regularity``: r (NaN when it cannot be computed,
    ``inf`` for period estimates that agree exactly); ``crossings``: ACF zero crossings used;
    ``reason``: one line saying why.
    """

    detected: bool
    period_s: float
    regularity: float
    crossings: int
    reason: str


def _regularity_of(intervals: np.ndarray) -> float:
    """r = Tp/(3·σ_Tp) of successive ACF crossing intervals (:func:`regularity`); inf when
    the period estimates agree exactly."""
    tp = float(2.0 * intervals.mean())
    sigma = float(np.std(intervals[:-1] + intervals[1:], ddof=1))
    return math.inf if sigma == 0.0 else tp / (3.0 * sigma)


def regularity(x: np.ndarray, dt: float, max_lag: int | None = None,
               max_crossings: int = MAX_CROSSINGS,
               noise_sigmas: float = NOISE_BAND_SIGMAS) -> Oscillation:
    """Period and regularity of the oscillation in ``x`` from its ACF (spec 4.2).

    Source: N. F. Thornhill, B. Huang and H. Zhang (2003), "Detection of multiple oscillations
    in control loops", Journal of Process Control 13, 91-100.

    With ρ = :func:`acf` (x, max_lag) (default max_lag = N − 1) and its zero crossings
    t_1 < t_2 < … (lags interpolated linearly between samples, in s; at most
    ``max_crossings`` of them; only those between lobes that leave the noise band
    ±noise_sigmas·se, se = :func:`acf_band`, 1/√N for white noise: :func:`acf_crossings`)::

        Δt_i   = t_{i+1} − t_i                        intervals between successive crossings
        Tp     = 2·mean(Δt_i)                         the period
        Tp_i   = Δt_i + Δt_{i+1}                      period estimates from pairs of intervals
        σ_Tp   = std(Tp_i)  (sample standard deviation, ddof = 1)
        r      = Tp / (3·σ_Tp)                        regular when r > REGULARITY_THRESHOLD = 1

    The interval from lag 0 to the first crossing is a quarter period, not an interval between
    crossings, and is not used. Fewer than ``MIN_CROSSINGS_PERIOD`` (3) crossings: not
    oscillating, period NaN. Exactly 3: the period is given but the regularity needs two period
    estimates (4 crossings), so r is NaN and nothing is detected ("undetermined" in the
    reason). Period estimates that agree exactly (σ_Tp = 0) give r = inf. A constant or
    straight-line signal is not oscillating.

    The noise band is this module's addition (an assumption, not in the paper, which band-pass
    filters the signal instead): the raw ACF of white noise crosses zero every few lags at
    irregular intervals, and with ten intervals r exceeds 1 for a quarter of white-noise
    records (50 of 200 seeded records of 5000 samples); with the ±3/√N band most such records
    have fewer than 4 crossings and 3 of the 200 are flagged. The band is widened by the
    ACF's own first lobe (Bartlett, :func:`acf_band`): under ±3/√N the slowly decaying ACF
    of an AR(1) load kept a few wandering lobes whose crossings looked regular (37-65 of 200
    records), under the Bartlett band none do, and sines in unit noise are found as before
    (SNR 0.3-1, 20-300 samples a period). ``noise_sigmas=0`` gives the plain rule.
    """
    if dt <= 0 or not math.isfinite(dt):
        raise ValueError(f"dt must be a positive sample period in s, got {dt}")
    if max_crossings < MIN_CROSSINGS_PERIOD:
        raise ValueError(f"max_crossings must be at least {MIN_CROSSINGS_PERIOD}")
    y = detrend(x)
    n = len(y)
    if n < 2 or is_flat(y):
        return Oscillation(False, math.nan, math.nan, 0,
                           "not oscillating: the signal is constant (or a straight line)")
    lag = n - 1 if max_lag is None else max_lag
    t = acf_crossings(acf(y, lag), n, noise_sigmas)[:max_crossings] * dt
    c = len(t)
    if c < MIN_CROSSINGS_PERIOD:
        return Oscillation(False, math.nan, math.nan, c,
                           f"not oscillating: the ACF has {c} zero crossing(s) up to lag "
                           f"{lag * dt:g} s, a period needs {MIN_CROSSINGS_PERIOD}")
    intervals = np.diff(t)
    tp = float(2.0 * intervals.mean())
    if c < MIN_CROSSINGS_REGULARITY:
        return Oscillation(False, tp, math.nan, c,
                           f"undetermined: {c} ACF zero crossings give a period but the "
                           f"regularity needs {MIN_CROSSINGS_REGULARITY}")
    r = _regularity_of(intervals)
    if r > REGULARITY_THRESHOLD:
        return Oscillation(True, tp, r, c, f"regular oscillation: r = {r:.3g} > "
                           f"{REGULARITY_THRESHOLD:g}, period {tp:.4g} s")
    return Oscillation(False, tp, r, c, f"not a regular oscillation: r = {r:.3g} <= "
                       f"{REGULARITY_THRESHOLD:g}")


def decay_ratio(x: np.ndarray, max_lag: int | None = None,
                noise_sigmas: float = NOISE_BAND_SIGMAS) -> float:
    """Decay ratio of the ACF of ``x`` (spec 4.2): first peak after lag 0 / |first trough|.

    Source: R. Miao and D. E. Seborg (1999), "Automatic detection of excessively oscillatory
    feedback control loops", Proc. IEEE International Conference on Control Applications,
    Kohala Coast, HI, 359-364. The simple form of the spec is implemented: with ρ =
    :func:`acf` (x, max_lag) (default N − 1) and its zero crossings z_1 < z_2 < z_3 (lags,
    those between lobes outside the noise band, :func:`acf_crossings`)::

        trough = min ρ(k) over z_1 < k < z_2          (the first negative lobe)
        peak   = max ρ(k) over z_2 < k < z_3          (the first positive lobe after lag 0)
        R      = peak / |trough|

    (z_3 = max_lag when the ACF does not cross a third time.) R > DECAY_RATIO_THRESHOLD (0.5)
    indicates excessive oscillation. For a damped oscillation the ACF decays by a constant
    factor per half period, so R estimates the damping per half period. Taking the extrema
    within the lobes between crossings, rather than the first local extrema, keeps small
    ripples (noise) from being read as the peak or trough. NaN when the ACF has no complete
    negative lobe followed by a positive one (fewer than 2 crossings, or no sample inside a
    lobe), or for a constant signal. The paper was not available to check whether it measures
    the extrema from zero or from lines joining neighbouring extrema; this is the spec's form.
    """
    y = detrend(x)
    n = len(y)
    if n < 2 or is_flat(y):
        return math.nan
    lag = n - 1 if max_lag is None else max_lag
    r = acf(y, lag)
    z = acf_crossings(r, n, noise_sigmas)
    if len(z) < 2:
        return math.nan
    k = np.arange(len(r))
    end = z[2] if len(z) > 2 else float(lag) + 1.0
    neg = r[(k > z[0]) & (k < z[1])]
    pos = r[(k > z[1]) & (k < end)]
    if len(neg) == 0 or len(pos) == 0:
        return math.nan
    return float(pos.max() / abs(neg.min()))
