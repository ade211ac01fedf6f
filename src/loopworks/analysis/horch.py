"""Horch's cross-correlation test for valve stiction (spec plant-and-tuning 4.3).

Source: A. Horch (1999), "A simple method for detection of stiction in control valves",
Control Engineering Practice 7, 1221-1231.

In a self-regulating loop that oscillates, the cross-correlation function (CCF) between the
controller output OP and the process variable PV (or the control error) tells two causes apart:

- stiction: the valve holds while the integral ramps OP, then slips, so PV is a square-like wave
  in step with OP's slope; OP and PV are about 90° apart and the CCF is *odd* (near zero at lag
  0, an extremum on each side);
- aggressive tuning or an external oscillation: OP and PV are about 180° apart (0° for the
  control error) and the CCF is *even* (an extremum at lag 0).

Not valid for integrating (level) loops, whose PV integrates the valve position and so lags it
by 90° without any stiction: :func:`horch_test` answers "undetermined" for them (Horch proposed
a PV-acceleration histogram test for those loops; not implemented here).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import signal

from loopworks.analysis import LoopType, Verdict
from loopworks.analysis.oscillation import detrend, is_flat, zero_crossings

#: the CCF's phase at which an odd CCF begins: at or above it the verdict is stiction.
#: Assumption (this module's choice): the published rule (Horch 1999) reads "odd CCF ->
#: stiction, even CCF -> no stiction" from the phase of the CCF without a number verified here;
#: the 0-90° range is split in thirds, the middle third undetermined.
PHASE_STICTION_DEG = 60.0
#: at or below this phase the CCF is even: no stiction (assumption, as above)
PHASE_NO_STICTION_DEG = 30.0



def cross_correlation(op: np.ndarray, pv: np.ndarray, max_lag: int) -> np.ndarray:
    """Normalised cross-correlation of ``op`` and ``pv`` at lags −max_lag … max_lag (samples;
    2·max_lag + 1 values, lag 0 in the middle).

    With a and b the mean-centred, linearly detrended op and pv (N samples each)::

        r(τ) = Σ_t a_t·b_{t+τ} / √(Σ a_t² · Σ b_t²)       (sum over the overlapping samples)

    so a positive lag τ pairs OP with a later PV (PV lagging OP peaks at τ > 0), |r| <= 1, and
    r(0) is the correlation coefficient of the detrended signals. Computed by FFT. Raises
    ``ValueError`` for signals of different lengths, a max_lag outside 0 … N − 1, or a signal
    without variation.
    """
    a, b = detrend(op), detrend(pv)
    n = len(a)
    if len(b) != n:
        raise ValueError(f"op and pv must have the same length, got {n} and {len(b)}")
    if not 0 <= max_lag < n:
        raise ValueError(f"max_lag must be in 0 … {n - 1} (the signals have {n} samples), "
                         f"got {max_lag}")
    if is_flat(a) or is_flat(b):
        raise ValueError("op or pv is constant (or a straight line): no cross-correlation")
    full = signal.correlate(b, a, mode="full", method="fft")  # index n-1+τ: Σ b_{t+τ}·a_t
    r = np.asarray(full[n - 1 - max_lag:n + max_lag], dtype=np.float64)
    return r / math.sqrt(float(np.sum(a * a)) * float(np.sum(b * b)))


@dataclass(frozen=True)
class HorchResult:
    """Result of :func:`horch_test`: the verdict, the CCF at lag 0, the distances (s) from lag
    0 to the CCF's first zero crossing on the left and on the right (NaN when not found), the
    asymmetry |τ_r − τ_l|/(τ_r + τ_l) in [0, 1] (NaN when not computed) and a one-line
    reason."""

    verdict: Verdict
    ccf0: float
    lag_left_s: float
    lag_right_s: float
    asymmetry: float
    reason: str


def horch_test(op: np.ndarray, pv: np.ndarray, dt: float,
               loop_type: LoopType = "self-regulating",
               max_lag: int | None = None) -> HorchResult:
    """Horch's (1999) stiction test from the CCF of OP and PV (or control error), spec 4.3.

    Numeric form implemented (the spec's "compare the first zero crossings on either side of
    lag 0"): with r = :func:`cross_correlation` (op, pv, max_lag) (default max_lag = N // 2),
    τ_l and τ_r the distances (s) from lag 0 to the CCF's nearest zero crossing on the left and
    on the right (interpolated linearly; a crossing exactly at lag 0 counts on the right)::

        a = |τ_r − τ_l| / (τ_r + τ_l)         in [0, 1]
        φ = 90°·a                             the CCF's phase

    Why: an oscillating CCF near lag 0 is r(τ) ≈ c·cos(ω(τ − τ₀)), an even function shifted
    by τ₀. Its crossings are at τ₀ ± π/(2ω), so τ_l = π/(2ω) + τ₀, τ_r = π/(2ω) − τ₀ and
    ω·|τ₀| = (π/2)·a: a is the CCF's phase away from even, as a fraction of 90°. Even CCF
    (extremum at lag 0; OP and PV 180° apart): a = 0. Odd CCF (zero at lag 0; 90° apart): one
    crossing at lag 0, the other half a period away, a = 1. Rule::

        φ >= PHASE_STICTION_DEG (60°)       -> "stiction"
        φ <= PHASE_NO_STICTION_DEG (30°)    -> "no_stiction"
        otherwise                           -> "undetermined"

    The thresholds are assumptions (see the constants); the sign of the CCF does not matter,
    so PV or the control error may be passed. "undetermined" also when ``loop_type`` is
    "integrating" (the test is not valid for integrating loops), when a signal has no
    variation, or when the CCF has no zero crossing within max_lag on a side (no oscillation
    in the window). The loop should be oscillating (see :mod:`loopworks.analysis.oscillation`).

    Limits seen on simulated loops (FOPDT K = 1, T = 10 s, L = 2 s, Choudhury valve, spec
    5.1): PI Kc = 1, Ti = 10 s, S = 3 %, J = 1 % gives φ ≈ 62° (stiction); the same valve under
    SIMC tuning (Kc = 2.5) gives φ ≈ 34° (undetermined): the process lag delays PV's response
    to each slip, moving an odd CCF towards even when the cycle is short. A slow external
    sinusoidal disturbance on a PI loop (period 120-300 s) gives φ ≈ 62-78°, i.e. a false
    "stiction": the integral action puts OP 90° from PV at frequencies well below the
    crossover. Read the verdict with the period and the loop's tuning in mind.
    """
    if dt <= 0 or not math.isfinite(dt):
        raise ValueError(f"dt must be a positive sample period in s, got {dt}")
    nan = math.nan
    if loop_type == "integrating":
        return HorchResult("undetermined", nan, nan, nan, nan,
                           "not valid for integrating loops: their PV lags the valve by 90° "
                           "without stiction (Horch 1999); use a test for integrating loops")
    if loop_type != "self-regulating":
        raise ValueError(f"loop_type must be 'self-regulating' or 'integrating', "
                         f"got {loop_type!r}")
    n = len(np.asarray(op))
    if n < 3 or is_flat(detrend(op)) or is_flat(detrend(pv)):
        return HorchResult("undetermined", nan, nan, nan, nan,
                           "op or pv has no variation (constant, a straight line or < 3 "
                           "samples)")
    m = n // 2 if max_lag is None else max_lag
    r = cross_correlation(op, pv, m)
    ccf0 = float(r[m])
    z = zero_crossings(r) - m  # in lags relative to lag 0
    right = z[z >= 0.0]
    left = z[z < 0.0]
    if len(right) == 0 or len(left) == 0:
        return HorchResult("undetermined", ccf0, nan, nan, nan,
                           f"the CCF has no zero crossing within ±{m * dt:g} s on the "
                           f"{'right' if len(right) == 0 else 'left'}: no oscillation seen")
    tau_r = float(right.min()) * dt
    tau_l = float(-left.max()) * dt
    a = abs(tau_r - tau_l) / (tau_r + tau_l)
    phase = 90.0 * a
    figures = (f"CCF phase {phase:.1f}° (τ_l = {tau_l:.4g} s, τ_r = {tau_r:.4g} s, "
               f"r(0) = {ccf0:.3f})")
    if phase >= PHASE_STICTION_DEG:
        return HorchResult("stiction", ccf0, tau_l, tau_r, a,
                           f"odd CCF: {figures} >= {PHASE_STICTION_DEG:g}°")
    if phase <= PHASE_NO_STICTION_DEG:
        return HorchResult("no_stiction", ccf0, tau_l, tau_r, a,
                           f"even CCF: {figures} <= {PHASE_NO_STICTION_DEG:g}°")
    return HorchResult("undetermined", ccf0, tau_l, tau_r, a,
                       f"neither odd nor even: {figures} between {PHASE_NO_STICTION_DEG:g}° "
                       f"and {PHASE_STICTION_DEG:g}°")
