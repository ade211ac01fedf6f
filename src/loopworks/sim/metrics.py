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


def loop_metrics(t: np.ndarray, sp: np.ndarray, pv: np.ndarray,
                 out: np.ndarray) -> dict[str, float]:
    """The metrics table of one loop: error integrals over the run, step figures over the
    window from the last setpoint change to the end, and output travel."""
    ts = float(t[1] - t[0]) if len(t) > 1 else 0.0
    e = sp - pv
    changes = np.flatnonzero(np.diff(sp) != 0.0)
    start = int(changes[-1]) + 1 if len(changes) else 0
    sm = step_metrics(t[start:], pv[start:], float(sp[-1]))
    return {
        "IAE": iae(e, ts),
        "ISE": ise(e, ts),
        "ITAE": itae(e, t),
        "step size": sm.step_size,
        "overshoot %": sm.overshoot_pct,
        "rise time s": sm.rise_time_s,
        "settling time s (2 %)": sm.settling_time_s,
        "final error": float(e[-1]),
        "output travel": travel(out),
    }
