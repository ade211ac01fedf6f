r"""Valve-stiction detection by curve fitting (He, Wang, Pottmann & Qin 2007).

Source: Q. P. He, J. Wang, M. Pottmann, S. J. Qin, "A curve fitting method for detecting valve
stiction in oscillating control loops", Ind. Eng. Chem. Res. 46(13) (2007) 4549-4560; summary in
plant-and-tuning spec section 4.3 [L].

Idea. In a loop oscillating because of stiction the integral action ramps the controller output
while the valve is stuck, so OP is triangular in a self-regulating loop; in an integrating
(level) loop the process integrates the square-ish valve position, so PV is triangular. A loop
oscillating for other reasons (aggressive tuning, an external sinusoidal disturbance) is close
to sinusoidal. So: fit a sinusoid and a triangle to every half cycle of the right signal and
compare the fit errors.

Procedure as implemented here (choices the paper leaves open are marked [ours]):

1. Take OP for a self-regulating loop, PV for an integrating loop (``loop_type``) and remove
   its mean over the record: ``x ← x - mean(x)``.
2. Zero crossings of the centred signal cut it into half cycles. [ours] A crossing counts only
   once the signal has left a hysteresis band ``±h·std(x)`` on the other side (``h =``
   ``hysteresis``, default 0.1), so measurement noise around zero does not cut spurious half
   cycles; its time is the last sign change before the exit from the band, placed between the
   two samples by linear interpolation: ``t = j + x_j/(x_j - x_{j+1})`` (in samples). Only
   *complete* half cycles (between two crossings) are fitted; the pieces before the first and
   after the last crossing are dropped. [ours] A half cycle with fewer than
   ``MIN_HALF_CYCLE_SAMPLES`` samples strictly inside it is skipped (it cannot tell a peak from
   a ramp) and counted in ``reason``.
3. On a half cycle from crossing t0 to t1, with ``τ = (t - t0)/(t1 - t0) ∈ (0, 1)`` at its
   samples, fit by least squares (both curves are zero at the two crossings):

   - a half sine ``ŝ(τ) = A·sin(πτ)``: ``A = Σ y·sin(πτ) / Σ sin²(πτ)``;
   - a triangle, piecewise linear up then down, with peak at ``τp`` and height ``H``:
     ``g(τ) = τ/τp`` for ``τ ≤ τp``, ``(1 - τ)/(1 - τp)`` after, ``t̂ = H·g(τ)``. For a fixed
     ``τp``, ``H = Σ y·g / Σ g²`` and the residual sum is ``Σ y² - (Σ y·g)²/Σ g²``; ``τp`` (the
     peak position, which He et al. fit as well) minimises it: every sample position is tried,
     then the best one is refined by bounded scalar minimisation between its neighbours.

4. The mean squared errors are pooled over the whole record [the brief's "say exactly"]:
   ``MSE_sin = Σ_h SSE_sin,h / Σ_h n_h`` and ``MSE_tri = Σ_h SSE_tri,h / Σ_h n_h``, sums over
   the fitted half cycles h with n_h samples each. The stiction index is

       SI = MSE_sin / (MSE_sin + MSE_tri)    (He et al. 2007)

   SI → 1 when the triangle fits far better (stiction), SI → 0 when the sine does.
5. Verdict (He et al. 2007 thresholds): ``SI ≥ SI_STICTION = 0.6`` stiction, ``SI ≤
   SI_NO_STICTION = 0.4`` no stiction, in between undetermined. Fewer than ``MIN_HALF_CYCLES =
   4`` complete half cycles [ours: two full periods, the least that shows a repeated shape], or
   a signal fitted exactly by both curves (``MSE_sin + MSE_tri = 0``), give undetermined with
   the reason.

Golden values (continuous limit, derived here, checked by the tests): a triangle of height H
against its best half sine leaves ``MSE = (1/3 - 32/π⁴)·H² ≈ 0.004822·H²`` (``A = 8H/π²``); a
half sine of amplitude A against its best (symmetric) triangle leaves ``(1/2 - 48/π⁴)·A² ≈
0.007233·A²`` (``H = 12A/π²``).

The method assumes the loop oscillates (run an oscillation detector first, spec 4.2); it says
nothing about a loop that does not.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.optimize import minimize_scalar

from loopworks.analysis import LOOP_TYPES, LoopType, Verdict
from loopworks.analysis.oscillation import cycle_half_cycles

__all__ = [
    "MIN_HALF_CYCLES",
    "MIN_HALF_CYCLE_SAMPLES",
    "MIN_PERIOD_HALF_SAMPLES",
    "SI_NO_STICTION",
    "SI_STICTION",
    "CurveFit",
    "LoopType",
    "Verdict",
    "curve_fit_index",
    "curve_fit_loop",
    "half_cycles",
]


#: SI at or above which the loop is declared sticky (He et al. 2007).
SI_STICTION = 0.6
#: SI at or below which the loop is declared free of stiction (He et al. 2007).
SI_NO_STICTION = 0.4
#: Fewest complete half cycles for a verdict [ours: two full periods].
MIN_HALF_CYCLES = 4
#: Fewest samples strictly inside a half cycle for it to be fitted [ours].
MIN_HALF_CYCLE_SAMPLES = 4
#: Fewest samples in the detected oscillation's half period for a "triangular" verdict
#: [ours]: with the triangle's peak position free, a few noisy samples fit a triangle better
#: than a sine. Sines with white noise of 0.1-0.4 of their amplitude, 20 records of 2000
#: samples each: at 3 to 7 samples a half period SI 0.60-0.85, "triangular" in 30-100 % of
#: them; at 8, 10 and 15 samples SI 0.38-0.56, none. The bias is towards the triangle, so
#: below this a "sinusoidal" verdict stands and a "triangular" one is not counted.
MIN_PERIOD_HALF_SAMPLES = 8

FloatArray = npt.NDArray[np.float64]

_SIGNAL = {"self-regulating": "OP", "integrating": "PV"}
_ARTICLE = {"self-regulating": "a", "integrating": "an"}


@dataclass(frozen=True)
class CurveFit:
    """Result of :func:`curve_fit_index`.

    ``si`` is the stiction index (NaN when there was nothing to fit), ``mse_sine`` and
    ``mse_triangle`` the pooled mean squared errors of step 4 (in the signal's units squared),
    ``half_cycles`` the number of half cycles fitted, ``verdict`` one of ``"stiction"``,
    ``"no_stiction"``, ``"undetermined"``, and ``reason`` one sentence saying why."""

    si: float
    mse_sine: float
    mse_triangle: float
    half_cycles: int
    verdict: Verdict
    reason: str


def half_cycles(x: npt.ArrayLike, hysteresis: float = 0.1) -> FloatArray:
    """Crossing times (in samples, fractional) of the mean-centred ``x``: step 2 above.

    Consecutive entries bound the complete half cycles. ``hysteresis`` is the half width of the
    band, as a fraction of the standard deviation, the signal must leave on the far side for a
    crossing to count (0 counts every sign change). :func:`curve_fit_index` with a
    ``period`` fits the oscillation's half cycles instead."""
    y = np.asarray(x, dtype=np.float64)
    y = y - y.mean()
    if hysteresis < 0.0:
        raise ValueError(f"hysteresis must be >= 0, not {hysteresis}")
    band = hysteresis * float(y.std())
    outside = np.flatnonzero(np.abs(y) > band)
    if outside.size < 2:
        return np.empty(0)
    side = np.sign(y[outside])
    exits = np.flatnonzero(side[1:] != side[:-1])  # outside[e] → outside[e + 1] changes side
    times: list[float] = []
    for e in exits:
        p, k = int(outside[e]), int(outside[e + 1])
        seg = y[p : k + 1]
        # last j in [p, k) where the sign flips between y[j] and y[j + 1] (0 counts as a flip)
        flips = np.flatnonzero(np.sign(seg[:-1]) != np.sign(seg[1:]))
        j = p + int(flips[-1])
        if y[j + 1] == 0.0:
            times.append(float(j + 1))
        elif y[j] == 0.0:
            times.append(float(j))
        else:
            times.append(j + float(y[j] / (y[j] - y[j + 1])))
    return np.asarray(times, dtype=np.float64)


def _triangle_sse(tau: FloatArray, y: FloatArray, tp: float) -> float:
    """Residual sum of squares of the best triangle with peak at ``tp`` (height fitted)."""
    g = np.where(tau <= tp, tau / tp, (1.0 - tau) / (1.0 - tp))
    gg = float(g @ g)
    yg = float(y @ g)
    return float(y @ y) - (yg * yg / gg if gg > 0.0 else 0.0)


def _fit_half_cycle(tau: FloatArray, y: FloatArray) -> tuple[float, float]:
    """(SSE of the best half sine, SSE of the best triangle) on one half cycle."""
    s = np.sin(np.pi * tau)
    yy = float(y @ y)
    ys = float(y @ s)
    sse_sin = max(yy - ys * ys / float(s @ s), 0.0)
    candidates = [_triangle_sse(tau, y, float(tp)) for tp in tau]
    i = int(np.argmin(candidates))
    lo = float(tau[i - 1]) if i > 0 else 0.5 * float(tau[0])
    hi = float(tau[i + 1]) if i + 1 < tau.size else 0.5 * (1.0 + float(tau[-1]))
    best = candidates[i]
    if hi > lo:
        res = minimize_scalar(lambda tp: _triangle_sse(tau, y, float(tp)), bounds=(lo, hi),
                              method="bounded", options={"xatol": 1e-10})
        best = min(best, float(res.fun))
    return sse_sin, max(best, 0.0)


def curve_fit_index(x: npt.ArrayLike, dt: float, loop_type: LoopType,
                    hysteresis: float = 0.1, period: float | None = None) -> CurveFit:
    """He et al. (2007) stiction index of one oscillating loop signal (module docstring).

    ``x`` is the signal He et al. fit, uniformly sampled with period ``dt`` (s): the controller
    output OP when ``loop_type`` is ``"self-regulating"``, the process variable PV when it is
    ``"integrating"`` (:func:`curve_fit_loop` picks it from both). The index itself does not
    depend on ``dt``; ``dt`` only sizes the half cycles quoted in ``reason``. ``period``
    (samples): the oscillation's, whose half cycles are fitted
    (:func:`~loopworks.analysis.oscillation.cycle_half_cycles`: on a noisy record the noise
    crossed the 0.1·std band of :func:`half_cycles`, and hundreds of its fragments were
    fitted as half cycles, reading "triangular")."""
    if loop_type not in LOOP_TYPES:
        raise ValueError(f"loop_type must be one of {LOOP_TYPES}, not {loop_type!r}")
    if not dt > 0.0:
        raise ValueError(f"dt must be > 0, not {dt}")
    if period is not None and not 0.0 < period < float("inf"):
        raise ValueError(f"period = {period!r} samples is out of range: allowed (0, inf)")
    y = np.asarray(x, dtype=np.float64)
    if y.ndim != 1 or not np.all(np.isfinite(y)):
        raise ValueError("x must be a one-dimensional array of finite numbers")
    name = f"{_SIGNAL[loop_type]} of {_ARTICLE[loop_type]} {loop_type} loop"
    y = y - y.mean()
    if period is not None:
        pairs, why = cycle_half_cycles(y, period)
        if why:
            return CurveFit(float("nan"), float("nan"), float("nan"), 0, "undetermined",
                            f"{name}: {why}")
    else:
        pairs = list(itertools.pairwise(half_cycles(y, hysteresis)))
    sse_sin = sse_tri = 0.0
    n_samples = 0
    fitted = skipped = 0
    idx = np.arange(y.size, dtype=np.float64)
    for t0, t1 in pairs:
        inside = (idx > t0) & (idx < t1)
        if int(inside.sum()) < MIN_HALF_CYCLE_SAMPLES:
            skipped += 1
            continue
        tau = (idx[inside] - t0) / (t1 - t0)
        a, b = _fit_half_cycle(tau, y[inside])
        sse_sin += a
        sse_tri += b
        n_samples += tau.size
        fitted += 1
    skip_note = (f"; {skipped} half cycle(s) shorter than {MIN_HALF_CYCLE_SAMPLES} samples "
                 "skipped" if skipped else "")
    if fitted < MIN_HALF_CYCLES:
        return CurveFit(float("nan"), float("nan"), float("nan"), fitted, "undetermined",
                        f"{name}: {fitted} complete half cycle(s) fitted, fewer than "
                        f"{MIN_HALF_CYCLES}{skip_note}")
    mse_sin = sse_sin / n_samples
    mse_tri = sse_tri / n_samples
    mean_half = float(np.mean([b - a for a, b in pairs])) * dt
    if mse_sin + mse_tri <= 0.0:
        return CurveFit(float("nan"), mse_sin, mse_tri, fitted, "undetermined",
                        f"{name}: both curves fit exactly (zero error), no shape to compare")
    si = mse_sin / (mse_sin + mse_tri)
    detail = (f"{name}: SI = {si:.3f} over {fitted} half cycles (mean {mean_half:.3g} s)"
              f"{skip_note}")
    if si >= SI_STICTION and period is not None and period < 2 * MIN_PERIOD_HALF_SAMPLES:
        return CurveFit(si, mse_sin, mse_tri, fitted, "undetermined",
                        f"{detail}; triangular, SI >= {SI_STICTION}, but the oscillation's "
                        f"half cycle is {period / 2:.3g} samples, fewer than "
                        f"{MIN_PERIOD_HALF_SAMPLES}, where a noisy sine fits a triangle "
                        "better: not counted")
    if si >= SI_STICTION:
        return CurveFit(si, mse_sin, mse_tri, fitted, "stiction",
                        f"{detail}; triangular, SI >= {SI_STICTION}")
    if si <= SI_NO_STICTION:
        return CurveFit(si, mse_sin, mse_tri, fitted, "no_stiction",
                        f"{detail}; sinusoidal, SI <= {SI_NO_STICTION}")
    return CurveFit(si, mse_sin, mse_tri, fitted, "undetermined",
                    f"{detail}; between {SI_NO_STICTION} and {SI_STICTION}")


def curve_fit_loop(op: npt.ArrayLike, pv: npt.ArrayLike, dt: float, loop_type: LoopType,
                   hysteresis: float = 0.1, period: float | None = None) -> CurveFit:
    """:func:`curve_fit_index` on the signal He et al. prescribe for ``loop_type``: ``op`` for a
    self-regulating loop, ``pv`` for an integrating one."""
    if loop_type not in LOOP_TYPES:
        raise ValueError(f"loop_type must be one of {LOOP_TYPES}, not {loop_type!r}")
    return curve_fit_index(op if loop_type == "self-regulating" else pv, dt, loop_type,
                           hysteresis, period)
