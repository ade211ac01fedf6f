r"""Nonlinearity test by squared bicoherence, and apparent stiction from the PV–OP ellipse.

Sources: M. A. A. S. Choudhury, S. L. Shah, N. F. Thornhill, "Diagnosis of poor control-loop
performance using higher-order statistics", Automatica 40(10) (2004) 1719-1728, and the book
Choudhury, Shah & Thornhill, *Diagnosis of Process Nonlinearities and Valve Stiction*
(Springer 2008); summary in plant-and-tuning spec section 4.3 [L]. Bicoherence normalisation:
Y. C. Kim & E. J. Powers, IEEE Trans. Plasma Sci. 7(2) (1979). Ellipse fit: A. Fitzgibbon,
M. Pilu, R. B. Fisher, "Direct least square fitting of ellipses", IEEE TPAMI 21(5) (1999),
in the numerically stable form of R. Halíř & J. Flusser (WSCG 1998). Choices the sources leave
open are marked [ours].

Squared bicoherence (direct, FFT-based, segment-averaged estimate)
------------------------------------------------------------------

1. Remove the mean of the record, cut it into K segments of ``nfft`` samples (default
   ``SEGMENT_LENGTH = 128``) overlapping by ``overlap`` (default ``OVERLAP = 0.5``), remove each
   segment's mean, multiply by a periodic Hann window and take the FFT X_k(f) of each segment.
   No other filtering is done [ours]: the book recommends band-limiting the loop signal to the
   frequencies of interest first (a Wiener filter); a caller who wants that passes filtered
   data (:func:`bandpass` is one way).
2. For every bifrequency of the principal domain, in FFT bins i, j with ``1 ≤ j ≤ i`` and
   ``i + j < nfft/2`` (0 ≤ f2 ≤ f1, f1 + f2 ≤ fs/2 without the DC bins, which the mean removal
   empties, and without the real-valued Nyquist bin) [ours: those two exclusions]::

       b²(f1, f2) = |Σ_k X_k(f1)·X_k(f2)·X_k*(f1+f2)|²
                    / (Σ_k |X_k(f1)·X_k(f2)|² · Σ_k |X_k(f1+f2)|²)

   (Kim & Powers normalisation; 0 ≤ b² ≤ 1 by Cauchy–Schwarz; b² = 0 where the denominator is
   0). No regularising ε is added to the denominator [ours].

Indices and verdicts
--------------------

- Significance: under the Gaussian hypothesis 2K·b² is approximately χ²(2), so b² is
  significant at level α (``ALPHA = 0.05``) when ``b² > c = χ²_{1-α}(2)/(2K)``, i.e. above
  ``-ln(α)/K`` = 2.996/K for α = 0.05 (Choudhury et al. 2004).
- Non-Gaussianity index: ``NGI = mean(b² over the significant bifrequencies) - c`` (NGI = 0
  when none is significant) [ours: that convention]; the signal is non-Gaussian when ``NGI >
  NGI_THRESHOLD = 0.001`` (Choudhury et al.; threshold as commonly cited, spec 4.3).
- Nonlinearity index: ``NLI = |max b² - (mean b² + 2·std b²)|``, the mean and the (population)
  standard deviation over every bifrequency of the principal domain; nonlinear when the signal
  is non-Gaussian *and* ``NLI > NLI_THRESHOLD = 0.01`` (the book's two-step test; spec 4.3).
  [ours] Plain mean and standard deviation, as the project brief states them; descriptions that
  use outlier-trimmed ("robust") estimates give a slightly larger NLI.

Caveat, derived here and checked by the tests: with K segments and no coupling, b² is
distributed roughly as Beta(1, K-1) (a squared coherence of K samples), so the mean of the
values above c is ``c + (1 - c)/K`` and **NGI of Gaussian noise is about (1 - c)/K**, not 0.
The 0.001 threshold therefore only separates Gaussian noise once K ≳ 1000 segments (about
64 000 samples at nfft = 128, 50 % overlap); for fewer segments ``reason`` says so and quotes
the noise floor. Likewise the largest of the ~nfft²/16 values of a noise bicoherence is about
ln(nfft²/16)/K, so NLI of noise is about (ln(nfft²/16) - 3)/K.

Apparent stiction from the PV–OP ellipse (Choudhury et al. 2008, ch. on quantification)
---------------------------------------------------------------------------------------

PV and OP are band-pass filtered around the oscillation frequency f0 = 1/period: a Butterworth
band-pass of ``order`` 2 (as second-order sections) with edges ``[f0/r, f0·r]``, ``r =
BAND_RATIO = 2``, run forwards and backwards (``scipy.signal.sosfiltfilt``: zero phase, gain
|H|² with |H(f0)| = 1, since f0 is the geometric centre of the band) [ours: the filter, its
order and band; the book uses a frequency-domain Wiener filter around f0]. One period is
dropped at each end of the filtered records when at least four periods remain (the filter's
start-up) [ours]. An ellipse is fitted to the (OP, PV) points by the direct least-squares conic
fit of Fitzgibbon et al. (minimise Σ(a x² + b xy + c y² + d x + e y + f)² subject to
4ac - b² = 1), on data centred and scaled per axis for conditioning. With ``m ≥ n`` the
semi-axes and ``α ∈ (-π/2, π/2]`` the angle from the OP axis to the m axis, the ellipse is::

    OP = OP0 + m·cos t·cos α - n·sin t·sin α,   PV = PV0 + m·cos t·sin α + n·sin t·cos α

and its width along the OP axis through the centre (PV = PV0) is the apparent stiction::

    2·m·n / √(m²·sin²α + n²·cos²α)

It is a size in OP units (%), of the order of the stiction band S of spec 1.2 for a sticky valve
in a self-regulating PI loop (Choudhury et al. call it *apparent* stiction: the loop's filtering
and the controller change it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy import signal, stats

__all__ = [
    "ALPHA",
    "BAND_RATIO",
    "NGI_THRESHOLD",
    "NLI_THRESHOLD",
    "OVERLAP",
    "SEGMENT_LENGTH",
    "Bicoherence",
    "Ellipse",
    "NonlinearityTest",
    "apparent_stiction",
    "bandpass",
    "bicoherence_test",
    "ellipse_fit",
    "squared_bicoherence",
]

#: Segment (and FFT) length of the direct estimate (Choudhury et al. use 128).
SEGMENT_LENGTH = 128
#: Fraction of a segment shared with the next one.
OVERLAP = 0.5
#: Significance level of the χ² test of a bicoherence value (Choudhury et al. 2004).
ALPHA = 0.05
#: NGI above which the signal is non-Gaussian (Choudhury et al.; spec 4.3).
NGI_THRESHOLD = 0.001
#: NLI above which a non-Gaussian signal is nonlinear (Choudhury et al.; spec 4.3).
NLI_THRESHOLD = 0.01
#: The band-pass of the ellipse method spans [f0/BAND_RATIO, f0·BAND_RATIO] [ours].
BAND_RATIO = 2.0

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class Bicoherence:
    """Squared bicoherence on the principal domain, one entry per bifrequency.

    ``f1``, ``f2`` (Hz, with ``f2 ≤ f1``) and ``b2`` are 1-D arrays of the same length;
    ``segments`` is K, ``threshold`` the significance level c = χ²_{1-α}(2)/(2K)."""

    f1: FloatArray
    f2: FloatArray
    b2: FloatArray
    segments: int
    threshold: float

    def at(self, f1: float, f2: float) -> float:
        """b² at the bifrequency nearest to (f1, f2), taken in the principal domain."""
        f1, f2 = max(f1, f2), min(f1, f2)
        i = int(np.argmin((self.f1 - f1) ** 2 + (self.f2 - f2) ** 2))
        return float(self.b2[i])


@dataclass(frozen=True)
class NonlinearityTest:
    """Result of :func:`bicoherence_test` (module docstring for the rules)."""

    ngi: float
    nli: float
    non_gaussian: bool
    nonlinear: bool
    segments: int
    reason: str


@dataclass(frozen=True)
class Ellipse:
    """An ellipse in the (OP, PV) plane: ``center`` (OP0, PV0), semi-axes ``m ≥ n``, ``alpha``
    (rad, from the OP axis to the m axis, in (-π/2, π/2]), ``apparent_stiction`` (its width
    along the OP axis through the centre) and ``residual``, the root-mean-square Sampson
    distance |F|/|∇F| of the points from the fitted conic F = 0 (data units)."""

    center: tuple[float, float]
    m: float
    n: float
    alpha: float
    apparent_stiction: float
    residual: float


def _chi2_threshold(segments: int, alpha: float) -> float:
    return float(stats.chi2.ppf(1.0 - alpha, 2)) / (2.0 * segments)


def squared_bicoherence(x: npt.ArrayLike, dt: float = 1.0, nfft: int = SEGMENT_LENGTH,
                        overlap: float = OVERLAP, alpha: float = ALPHA) -> Bicoherence:
    """Direct estimate of b²(f1, f2) on the principal domain (module docstring, steps 1-2)."""
    y = np.asarray(x, dtype=np.float64)
    if y.ndim != 1 or not np.all(np.isfinite(y)):
        raise ValueError("x must be a one-dimensional array of finite numbers")
    if nfft < 8:
        raise ValueError(f"nfft must be >= 8, not {nfft}")
    if not 0.0 <= overlap < 1.0:
        raise ValueError(f"overlap must be in [0, 1), not {overlap}")
    if not 0.0 < dt < math.inf:
        raise ValueError(f"dt = {dt!r} s is out of range: allowed (0, inf)")
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"alpha = {alpha!r} is out of range: allowed (0, 1)")
    hop = max(1, round(nfft * (1.0 - overlap)))
    if y.size < nfft:
        raise ValueError(f"x has {y.size} samples, fewer than one segment of {nfft}")
    y = y - y.mean()
    starts = np.arange(0, y.size - nfft + 1, hop)
    segs = y[starts[:, None] + np.arange(nfft)[None, :]]
    segs = segs - segs.mean(axis=1, keepdims=True)
    segs = segs * signal.get_window("hann", nfft)[None, :]
    spec = np.fft.fft(segs, axis=1)
    half = nfft // 2
    i1, i2 = np.meshgrid(np.arange(1, half), np.arange(1, half), indexing="ij")
    keep = (i2 <= i1) & (i1 + i2 < half)
    i1, i2 = i1[keep], i2[keep]
    x1, x2, x3 = spec[:, i1], spec[:, i2], spec[:, i1 + i2]
    prod = x1 * x2
    num = np.abs(np.sum(prod * np.conj(x3), axis=0)) ** 2
    den = np.sum(np.abs(prod) ** 2, axis=0) * np.sum(np.abs(x3) ** 2, axis=0)
    b2 = np.divide(num, den, out=np.zeros_like(num), where=den > 0.0)
    b2 = np.minimum(b2, 1.0)  # Cauchy–Schwarz bound; clips rounding only
    df = 1.0 / (nfft * dt)
    k = int(starts.size)
    f1: FloatArray = i1.astype(np.float64) * df
    f2: FloatArray = i2.astype(np.float64) * df
    return Bicoherence(f1, f2, b2, k, _chi2_threshold(k, alpha))


def bicoherence_test(x: npt.ArrayLike, dt: float = 1.0, nfft: int = SEGMENT_LENGTH,
                     overlap: float = OVERLAP, alpha: float = ALPHA) -> NonlinearityTest:
    """Choudhury et al. (2004) NGI/NLI test of one loop signal (module docstring)."""
    bic = squared_bicoherence(x, dt, nfft, overlap, alpha)
    b2, c, k = bic.b2, bic.threshold, bic.segments
    sig = b2[b2 > c]
    ngi = float(sig.mean()) - c if sig.size else 0.0
    nli = abs(float(b2.max()) - (float(b2.mean()) + 2.0 * float(b2.std())))
    non_gaussian = ngi > NGI_THRESHOLD
    nonlinear = non_gaussian and nli > NLI_THRESHOLD
    parts = [f"K = {k} segments of {nfft}, {sig.size} of {b2.size} bifrequencies significant "
             f"(b² > {c:.4g}); NGI = {ngi:.4g} "
             f"{'>' if non_gaussian else '<='} {NGI_THRESHOLD}, NLI = {nli:.4g} "
             f"{'>' if nli > NLI_THRESHOLD else '<='} {NLI_THRESHOLD}"]
    if c >= 1.0:  # K <= 2: no b² (at most 1) can pass the threshold, whatever the signal
        parts.append(f"undetermined: with K = {k} segments the threshold is {c:.3g} >= 1, so "
                     "no bifrequency can be significant; a record of at least 3 segments is "
                     "needed")
    else:
        parts.append("nonlinear" if nonlinear else
                     "non-Gaussian but linear" if non_gaussian else "Gaussian (linear)")
    floor = (1.0 - c) / k
    if floor > NGI_THRESHOLD:
        parts.append(f"caution: with K = {k} Gaussian noise alone gives NGI ≈ (1 - c)/K = "
                     f"{floor:.4g} > {NGI_THRESHOLD}; about {int(np.ceil(1.0 / NGI_THRESHOLD))}"
                     " segments are needed for the threshold to separate noise")
    return NonlinearityTest(ngi, nli, non_gaussian, nonlinear, k, "; ".join(parts))


def _conic_to_ellipse(conic: FloatArray, pts: FloatArray) -> Ellipse:
    a, b, c, d, e, f = (float(v) for v in conic)
    if 4.0 * a * c - b * b <= 0.0:
        raise ValueError("the fitted conic is not an ellipse")
    q = np.array([[a, b / 2.0], [b / 2.0, c]])
    center = np.linalg.solve(2.0 * q, [-d, -e])
    f0 = float(center @ q @ center + d * center[0] + e * center[1] + f)
    lam, vec = np.linalg.eigh(q)
    axes2 = -f0 / lam
    if np.any(axes2 <= 0.0):
        raise ValueError("the fitted conic is an imaginary ellipse")
    axes = np.sqrt(axes2)
    i_m = int(np.argmax(axes))  # the longer semi-axis is m
    m, n = float(axes[i_m]), float(axes[1 - i_m])
    direction = vec[:, i_m]
    alpha = float(np.arctan2(direction[1], direction[0]))
    if alpha <= -np.pi / 2.0:
        alpha += np.pi
    elif alpha > np.pi / 2.0:
        alpha -= np.pi
    if np.isclose(m, n, rtol=1e-12, atol=0.0):
        alpha = 0.0
    width = 2.0 * m * n / float(np.sqrt(m**2 * np.sin(alpha) ** 2 + n**2 * np.cos(alpha) ** 2))
    xs, ys = pts[:, 0], pts[:, 1]
    val = a * xs**2 + b * xs * ys + c * ys**2 + d * xs + e * ys + f
    gx, gy = 2.0 * a * xs + b * ys + d, b * xs + 2.0 * c * ys + e
    grad = np.hypot(gx, gy)
    sampson = np.divide(np.abs(val), grad, out=np.zeros_like(val), where=grad > 0.0)
    return Ellipse((float(center[0]), float(center[1])), m, n, alpha, width,
                   float(np.sqrt(np.mean(sampson**2))))


def ellipse_fit(op: npt.ArrayLike, pv: npt.ArrayLike) -> Ellipse:
    """Direct least-squares ellipse (Fitzgibbon, Pilu & Fisher 1999) through the (OP, PV)
    points, solved as Halíř & Flusser (1998) do; parameters as in the module docstring."""
    xo = np.asarray(op, dtype=np.float64)
    yo = np.asarray(pv, dtype=np.float64)
    if xo.shape != yo.shape or xo.ndim != 1 or xo.size < 5:
        raise ValueError("op and pv must be 1-D arrays of the same length, at least 5 points")
    if not (np.all(np.isfinite(xo)) and np.all(np.isfinite(yo))):
        raise ValueError("op and pv must be finite")
    mx, my = float(xo.mean()), float(yo.mean())
    sx, sy = float(xo.std()), float(yo.std())
    if sx == 0.0 or sy == 0.0:
        raise ValueError("op or pv is constant: no ellipse")
    x, y = (xo - mx) / sx, (yo - my) / sy
    d1 = np.column_stack([x * x, x * y, y * y])
    d2 = np.column_stack([x, y, np.ones_like(x)])
    s1, s2, s3 = d1.T @ d1, d1.T @ d2, d2.T @ d2
    try:
        t = -np.linalg.solve(s3, s2.T)
    except np.linalg.LinAlgError:  # the points lie on a straight line
        raise ValueError("op and pv lie on a straight line: no ellipse") from None
    mat = s1 + s2 @ t
    c1_inv = np.array([[0.0, 0.0, 0.5], [0.0, -1.0, 0.0], [0.5, 0.0, 0.0]])
    w, v = np.linalg.eig(c1_inv @ mat)
    v = np.real(v)
    cond = 4.0 * v[0] * v[2] - v[1] ** 2
    ok = np.flatnonzero(cond > 0.0)
    if ok.size == 0:
        raise ValueError("no ellipse fits the points")
    a1 = v[:, ok[int(np.argmin(np.abs(np.real(w[ok]))))]]
    a2 = t @ a1
    # back to the original units: x = (OP - mx)/sx, y = (PV - my)/sy
    a, b, c = a1[0] / sx**2, a1[1] / (sx * sy), a1[2] / sy**2
    dd, ee, ff = a2[0] / sx, a2[1] / sy, a2[2]
    conic = np.array([
        a, b, c,
        -2.0 * a * mx - b * my + dd,
        -2.0 * c * my - b * mx + ee,
        a * mx**2 + b * mx * my + c * my**2 - dd * mx - ee * my + ff,
    ])
    return _conic_to_ellipse(conic, np.column_stack([xo, yo]))


def bandpass(x: npt.ArrayLike, dt: float, period_s: float, ratio: float = BAND_RATIO,
             order: int = 2) -> FloatArray:
    """Zero-phase Butterworth band-pass [f0/ratio, f0·ratio], f0 = 1/period_s, of the
    mean-removed ``x`` (``scipy.signal.butter`` as sections, ``sosfiltfilt``)."""
    if not (dt > 0.0 and period_s > 0.0 and ratio > 1.0):
        raise ValueError("dt and period_s must be > 0 and ratio > 1")
    f0 = 1.0 / period_s
    nyquist = 0.5 / dt
    if f0 * ratio >= nyquist:
        raise ValueError(f"band upper edge {f0 * ratio:.4g} Hz is not below Nyquist "
                         f"{nyquist:.4g} Hz")
    y = np.asarray(x, dtype=np.float64)
    sos = signal.butter(order, [f0 / ratio, f0 * ratio], btype="bandpass", fs=1.0 / dt,
                        output="sos")
    out: FloatArray = signal.sosfiltfilt(sos, y - y.mean())
    return out


def apparent_stiction(op: npt.ArrayLike, pv: npt.ArrayLike, dt: float,
                      period_s: float) -> float:
    """Apparent stiction (% of OP) from the PV–OP ellipse: band-pass both signals around
    1/period_s (:func:`bandpass`), drop one period at each end when four or more remain, fit
    the ellipse (:func:`ellipse_fit`) and return its OP-axis width through the centre."""
    fo = bandpass(op, dt, period_s)
    fp = bandpass(pv, dt, period_s)
    edge = round(period_s / dt)
    if fo.size - 2 * edge >= 4 * edge:
        fo, fp = fo[edge:-edge], fp[edge:-edge]
    return ellipse_fit(fo, fp).apparent_stiction
