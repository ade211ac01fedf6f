"""Singhal & Salsbury's area-ratio stiction index (spec plant-and-tuning 4.3).

Source: A. Singhal and T. I. Salsbury (2005), "A simple method for detecting valve stiction in
oscillating control loops", Journal of Process Control 15, 371-382.

In a self-regulating loop with a sticky valve the control error rises while the process
responds to a slip, then stays nearly flat until the next slip drives it back through zero: the
peak of each half cycle comes late, so the area before the peak exceeds the area after it. A
sinusoidal (linear-loop) oscillation is symmetric about its peak.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from loopworks.analysis import Verdict
from loopworks.analysis.oscillation import band_crossings, cycle_half_cycles

#: R above this -> stiction. The paper's criterion is R > 1 (asymmetric half cycles); a margin
#: above 1 guards against noise and sampling. Assumption: the margin's size was not verified in
#: the paper; 1.2 is this module's default, pass ``threshold`` to change it.
STICTION_THRESHOLD = 1.2
#: complete half cycles needed for a verdict
MIN_HALF_CYCLES = 4



@dataclass(frozen=True)
class AreaRatio:
    """Result of :func:`area_ratio`: the index R (median over the complete half cycles; NaN
    without one), the number of complete half cycles, the verdict and a one-line reason."""

    ratio: float
    half_cycles: int
    verdict: Verdict
    reason: str


def half_cycle_ratios(e: np.ndarray, dt: float, band: float = 0.0,
                      period: float | None = None) -> np.ndarray:
    """A1/A2 of every complete half cycle of the control error ``e`` (sample period dt in s).

    Half cycles lie between successive zero crossings z_i < z_{i+1} of e (interpolated
    linearly; with ``band`` > 0 only crossings between excursions beyond ±band count, so noise
    around zero does not split a half cycle; with ``period``, the oscillation's period in
    samples, the half cycles of that oscillation, :func:`~loopworks.analysis.oscillation.
    cycle_half_cycles`, and ``band`` is not used). The part before the first crossing and after the
    last is incomplete and not used. Within a half cycle, with |e| taken as the straight-line
    interpolant through 0 at the crossings and the samples between them (trapezoids; a
    sample of the other sign than the half cycle's, noise within the band or beside a
    crossing found on the smoothed signal, counts as 0), and t_p the peak's time
    (:func:`peak_time`, between samples)::

        A1 = ∫_{z_i}^{t_p} |e| dt,   A2 = ∫_{t_p}^{z_{i+1}} |e| dt,   R_i = A1/A2

    A half cycle with no sample strictly between its crossings is skipped.
    """
    x = np.asarray(e, dtype=np.float64)
    pairs = (cycle_half_cycles(x, period)[0] if period is not None
             else itertools.pairwise(band_crossings(x, band)))
    out: list[float] = []
    for z0, z1 in pairs:
        k0, k1 = math.floor(z0) + 1, math.ceil(z1) - 1  # samples strictly inside
        if k1 < k0:
            continue
        k = np.arange(k0, k1 + 1)
        lobe = x[k0:k1 + 1]
        sign = 1.0 if lobe.sum() >= 0.0 else -1.0
        v = np.maximum(lobe * sign, 0.0)
        nodes = np.concatenate(([z0], k.astype(np.float64), [z1]))
        values = np.concatenate(([0.0], v, [0.0]))
        tp = peak_time(values, nodes)
        before = nodes < tp
        vp = float(np.interp(tp, nodes, values))
        a1 = float(np.trapezoid(np.append(values[before], vp), np.append(nodes[before], tp)))
        a2 = float(np.trapezoid(np.insert(values[~before], 0, vp),
                                np.insert(nodes[~before], 0, tp)))
        if a2 > 0.0:
            out.append(a1 / a2)
    return np.asarray(out, dtype=np.float64)


def peak_time(values: np.ndarray, nodes: np.ndarray) -> float:
    """The time of a half cycle's peak: the vertex of the parabola through its largest sample
    and the two beside it (samples one apart; at an end, the largest sample itself)::

        t_p = t_k + (v_{k-1} - v_{k+1}) / (2·(v_{k-1} - 2·v_k + v_{k+1}))   within ±½ sample

    [ours: Singhal & Salsbury take the largest sample. On a sampled sine the largest sample
    lies up to half a sample from the true peak, and with a whole number of samples a period
    every half cycle is off the same way, so the median keeps it: a clean sine of 16-25
    samples a period read R up to 1.5, and 35 of 364 clean sines of 8-59 samples a period
    voted stiction (``tests/analysis/test_area_ratio.py``).]"""
    i = int(np.argmax(values))
    if 1 <= i <= len(values) - 2 and nodes[i + 1] - nodes[i] == 1.0 == nodes[i] - nodes[i - 1]:
        curve = values[i - 1] - 2.0 * values[i] + values[i + 1]
        if curve < 0.0:
            return float(nodes[i] + 0.5 * (values[i - 1] - values[i + 1]) / curve)
    return float(nodes[i])


def area_ratio(e: np.ndarray, dt: float, threshold: float = STICTION_THRESHOLD,
               band: float = 0.0, period: float | None = None) -> AreaRatio:
    """Singhal & Salsbury's (2005) area-ratio stiction index of the control error ``e``.

    R_i = A1/A2 per complete half cycle (:func:`half_cycle_ratios`: A1 the area of |e| before
    the half cycle's peak, A2 after it; ``band`` and ``period`` (samples) say which crossings
    bound a half cycle, there). The index is the **median** of the R_i: a half cycle
    whose peak sits on a noise spike near one end gives an A1 or A2 near 0 and an R_i that is
    huge or near 0; a ratio is heavy-tailed, so one such half cycle would move a mean but not
    the median. R ≈ 1 for symmetric (sinusoidal) half cycles, R > 1 for a peak that comes late
    (stiction in a self-regulating loop). Rule::

        fewer than MIN_HALF_CYCLES (4) complete half cycles -> "undetermined"
        R > threshold (default STICTION_THRESHOLD = 1.2)     -> "stiction"
        otherwise                                            -> "no_stiction"

    The paper's criterion is R > 1; the margin 1.2 is an assumption (see the constant). Meant
    for an oscillating, self-regulating loop (pass SP − PV); the sign of e does not matter.
    """
    if dt <= 0 or not math.isfinite(dt):
        raise ValueError(f"dt must be a positive sample period in s, got {dt}")
    if period is not None and not 0.0 < period < math.inf:
        raise ValueError(f"period = {period!r} samples is out of range: allowed (0, inf)")
    if not threshold > 0.0 or not math.isfinite(threshold):
        raise ValueError(f"threshold = {threshold!r} is out of range: allowed (0, inf)")
    x = np.asarray(e, dtype=np.float64)
    if x.ndim != 1 or not np.all(np.isfinite(x)):
        raise ValueError("e must be a 1-D signal of finite samples")
    if period is not None:
        why = cycle_half_cycles(x, period)[1]
        if why:
            return AreaRatio(math.nan, 0, "undetermined", f"e: {why}")
    r = half_cycle_ratios(x, dt, band, period)
    n = len(r)
    ratio = float(np.median(r)) if n else math.nan
    if n < MIN_HALF_CYCLES:
        return AreaRatio(ratio, n, "undetermined",
                         f"{n} complete half cycle(s) of e; a verdict needs {MIN_HALF_CYCLES}")
    if ratio > threshold:
        return AreaRatio(ratio, n, "stiction", f"R = {ratio:.3f} > {threshold:g} over {n} "
                         "half cycles: the peaks come late (stiction-like)")
    return AreaRatio(ratio, n, "no_stiction", f"R = {ratio:.3f} <= {threshold:g} over {n} "
                     "half cycles: no late-peaked half cycles")
