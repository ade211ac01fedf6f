"""Loop performance metrics (spec plant-and-tuning 4.1), on sampled signals.

For samples k with scan time Ts and error e = SP - PV::

    IAE  = Σ |e_k|·Ts        ISE = Σ e_k²·Ts        ITAE = Σ t_k·|e_k|·Ts

with t measured from the start of the analysed window. For a setpoint step of size
Δr = r - y_0 (r the setpoint, y_0 the PV at the step):

    overshoot      = max over the window of (y - y_∞)·sign(Δr) / |Δr| · 100 %   (y_∞ = last PV)
    rise time      = first time y crosses y_0 + 0.9·Δr minus first time it crosses y_0 + 0.1·Δr
    settling time  = last time |y - y_∞| > band·|Δr| (band 2 %), measured from the step;
                     NaN unless at least the last 5 % of the window lies inside the band
    travel         = Σ |Δu_k| of the controller output
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


def iae(e: np.ndarray, ts: float) -> float:
    """Integral of absolute error, Σ|e|·Ts."""
    return float(np.sum(np.abs(e)) * ts)


def ise(e: np.ndarray, ts: float) -> float:
    """Integral of squared error, Σe²·Ts."""
    return float(np.sum(e * e) * ts)


def itae(e: np.ndarray, t: np.ndarray) -> float:
    """Integral of time-weighted absolute error, Σ(t - t_0)·|e|·Ts, Ts from the t spacing."""
    ts = float(t[1] - t[0]) if len(t) > 1 else 0.0
    return float(np.sum((t - t[0]) * np.abs(e)) * ts)


def travel(u: np.ndarray) -> float:
    """Total output travel Σ|Δu|."""
    return float(np.sum(np.abs(np.diff(u))))


@dataclass(frozen=True)
class StepMetrics:
    """Step-response figures; NaN where the response never reaches the level."""

    step_size: float
    overshoot_pct: float
    rise_time_s: float
    settling_time_s: float


def step_metrics(t: np.ndarray, y: np.ndarray, r: float, band: float = 0.02) -> StepMetrics:
    """Overshoot, 10-90 % rise time and settling time of ``y`` toward setpoint ``r``."""
    y0 = float(y[0])
    dr = r - y0
    if dr == 0.0 or len(y) < 2:
        return StepMetrics(dr, math.nan, math.nan, math.nan)
    sgn = 1.0 if dr > 0 else -1.0
    yinf = float(y[-1])
    frac = (y - y0) * sgn / abs(dr)  # 0 at start, 1 at the setpoint
    overshoot = max(0.0, float(np.max((y - yinf) * sgn)) / abs(dr) * 100.0)
    i10 = np.flatnonzero(frac >= 0.1)
    i90 = np.flatnonzero(frac >= 0.9)
    rise = float(t[i90[0]] - t[i10[0]]) if len(i10) and len(i90) else math.nan
    outside = np.flatnonzero(np.abs(y - yinf) > band * abs(dr))
    tail = max(2, len(y) // 20)  # settled means the last 5 % of the window stays in the band
    if len(outside) == 0:
        settle = 0.0
    elif outside[-1] >= len(y) - tail:
        settle = math.nan
    else:
        settle = float(t[outside[-1] + 1] - t[0])
    return StepMetrics(dr, overshoot, rise, settle)


def reversals(y: np.ndarray, threshold: float = 0.05) -> int:
    """Sign changes of the moves of ``y``, ignoring moves of at most ``threshold`` (spec 4.1:
    so noise below the resolution is not counted). Moves are taken between the points where y
    has moved more than the threshold since the last counted point."""
    count = 0
    last = float(y[0]) if len(y) else 0.0
    direction = 0
    for v in y[1:]:
        move = float(v) - last
        if abs(move) > threshold:
            d = 1 if move > 0 else -1
            if direction and d != direction:
                count += 1
            direction = d
            last = float(v)
    return count


@dataclass(frozen=True)
class OscillationReport:
    """Hägglund's load-disturbance detector (spec 4.2): the IAE limit used, the number of
    half periods whose IAE exceeded it, the forgetting counter at the end and the alarm."""

    iae_limit: float
    large_half_periods: int
    counter: float
    alarm: bool


def oscillation_detector(t: np.ndarray, e: np.ndarray, a: float = 1.0,
                         wu: float | None = None, ti: float | None = None, n_lim: float = 10.0,
                         t_sup: float | None = None) -> OscillationReport:
    """Hägglund (1995), spec 4.2: integrate |e| between zero crossings of e; a half period is
    "large" when its IAE_i > IAE_lim = 2a/ωu (a in PV units, default 1 % of a 0..100 range;
    ωu from the tuner, or ωu = 2π/Ti, giving IAE_lim = a·Ti/π). The flags are counted with
    exponential forgetting x <- γ·x + flag at each crossing, γ = exp(-Δt/T_sup) over the time
    since the previous crossing, T_sup = 50·Tu (Tu = 2π/ωu); alarm when x > n_lim."""
    if wu is None:
        if ti is None:
            raise ValueError("oscillation_detector needs wu (rad/s) or ti (s)")
        wu = 2.0 * np.pi / ti
    iae_lim = 2.0 * a / wu
    tu = 2.0 * np.pi / wu
    t_sup = 50.0 * tu if t_sup is None else t_sup
    ts = float(t[1] - t[0]) if len(t) > 1 else 0.0
    x = 0.0
    large = 0
    area = 0.0
    t_last = float(t[0]) if len(t) else 0.0
    sign = 0.0
    for k in range(len(e)):
        ek = float(e[k])
        s = float(np.sign(ek))
        if sign and s and s != sign:  # a zero crossing ends the half period
            flag = 1.0 if area > iae_lim else 0.0
            large += int(flag)
            x = float(np.exp(-(float(t[k]) - t_last) / t_sup)) * x + flag
            t_last = float(t[k])
            area = 0.0
        if s:
            sign = s
        area += abs(ek) * ts
    return OscillationReport(iae_lim, large, x, x > n_lim)


def loop_metrics(t: np.ndarray, sp: np.ndarray, pv: np.ndarray, out: np.ndarray,
                 position: np.ndarray | None = None,
                 window: tuple[float, float] | None = None,
                 reversal_threshold: float = 0.05) -> dict[str, float]:
    """The metrics table of one loop (spec 4.1), over ``window`` = (t0, t1) s (default: the
    whole run): error integrals, step figures over the window from the last setpoint change
    (none for a window without a setpoint change in it),
    PV standard deviation and peak to peak, controller output travel and reversals, and the
    valve stem travel and reversals when ``position`` is given."""
    if window is not None:
        keep = (t >= window[0]) & (t <= window[1])
        if not keep.any():
            raise ValueError(f"window {window} s holds no sample of the run "
                             f"({t[0]:g}..{t[-1]:g} s)")
        t, sp, pv, out = t[keep], sp[keep], pv[keep], out[keep]
        position = position[keep] if position is not None else None
    ts = float(t[1] - t[0]) if len(t) > 1 else 0.0
    e = sp - pv
    changes = np.flatnonzero(np.diff(sp) != 0.0)
    if len(changes) or window is None:
        start = int(changes[-1]) + 1 if len(changes) else 0
        sm = step_metrics(t[start:], pv[start:], float(sp[-1]))
    else:  # a regulatory window (no setpoint change in it): no step figures
        sm = StepMetrics(math.nan, math.nan, math.nan, math.nan)
    result = {
        "IAE": iae(e, ts),
        "ISE": ise(e, ts),
        "ITAE": itae(e, t),
        "mean |e|": float(np.mean(np.abs(e))),
        "step size": sm.step_size,
        "overshoot %": sm.overshoot_pct,
        "rise time s": sm.rise_time_s,
        "settling time s (2 %)": sm.settling_time_s,
        "final error": float(e[-1]),
        "PV std": float(np.std(pv)),
        "PV peak to peak": float(np.ptp(pv)),
        "output travel": travel(out),
        "output reversals": float(reversals(out, reversal_threshold)),
    }
    if position is not None:
        result["valve travel"] = travel(position)
        result["valve reversals"] = float(reversals(position, reversal_threshold))
    return result
