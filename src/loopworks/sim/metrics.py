"""Loop performance metrics (spec plant-and-tuning 4.1), on sampled signals.

For samples k with scan time Ts and error e = SP - PV::

    IAE  = Σ |e_k|·Ts        ISE = Σ e_k²·Ts        ITAE = Σ t_k·|e_k|·Ts

with t measured from the start of the analysed window. For a setpoint step of size
Δr = r - y_0 (r the setpoint, y_0 the PV at the step) and y_∞ the mean PV over the tail (the
last 5 % of the samples after the step, at least 2)::

    overshoot      = max over the window of (y - y_∞)·sign(Δr) / |Δr| · 100 %
    rise time      = first time y crosses y_0 + 0.9·Δr minus first time it crosses y_0 + 0.1·Δr
    settling time  = last time |y - y_∞| > band·|Δr| (band 2 %), measured from the step
    travel         = Σ |Δu_k|

The response has settled when every tail sample is within band·|Δr| of y_∞ and y_∞ is within
band·|Δr| of r; overshoot and settling time are figures of a settled response, NaN otherwise
(a response still moving, oscillating, or stalled off the setpoint has no final value to
measure them against). NaN marks every figure the data cannot support; the report writes it as
null in JSON and n/a in tables. ``METRICS`` holds each figure's unit, definition and n/a rule
(rendered as docs/metrics.md by ``markdown()``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache
from typing import Any

import numpy as np


@dataclass(frozen=True)
class MetricInfo:
    """One row of the metrics table: its name (the key in ``loop_metrics``), unit, one-line
    definition and when it is n/a (NaN) instead of a figure."""

    name: str
    unit: str
    definition: str
    not_available: str


_NONFINITE = "a sample in the window is NaN or infinite (a Bad value)"
_INTEGRAL = "the run has fewer than 2 scans (no scan period), or " + _NONFINITE

#: every metric of ``loop_metrics``, in table order; the valve rows only for a loop with a valve
METRICS: tuple[MetricInfo, ...] = (
    MetricInfo("IAE", "PV units·s", "integral of absolute error Σ|e|·Ts over the scored window, "
               "e = working SP − PV", _INTEGRAL),
    MetricInfo("ISE", "PV units²·s", "integral of squared error Σe²·Ts", _INTEGRAL),
    MetricInfo("ITAE", "PV units·s²", "integral of time-weighted absolute error "
               "Σ(t − t₀)·|e|·Ts, t₀ the start of the window", _INTEGRAL),
    MetricInfo("mean |e|", "PV units", "mean absolute error over the window", _NONFINITE),
    MetricInfo("step size", "PV units", "the last setpoint step in the window: SP after it "
               "minus PV at it (Δr)",
               "no setpoint change in the window (a regulatory window), or " + _NONFINITE),
    MetricInfo("overshoot %", "% of the step", "how far the PV went beyond its final value "
               "y∞ (the mean of the last 5 % of the response), in % of |Δr|; 0 if never",
               "no step (step size n/a), or the response has not settled (see settling time)"),
    MetricInfo("rise time s", "s", "time from the PV's first crossing of 10 % of the step to "
               "its first crossing of 90 %",
               "no step (step size n/a), or the PV never reached 90 % of it"),
    MetricInfo("settling time s (2 %)", "s", "time from the step until the PV stays within "
               "±2 % of |Δr| of its final value y∞",
               "no step (step size n/a), or the response has not settled: a sample of the "
               "last 5 % of the response is outside the ±2 % band around y∞ (still moving, "
               "oscillating, or noise larger than the band), or y∞ is more than 2 % of the "
               "step away from the setpoint (stalled or creeping: read the final error)"),
    MetricInfo("final error", "PV units", "SP − PV at the last scan of the window", _NONFINITE),
    MetricInfo("PV std", "PV units", "standard deviation of the PV over the window",
               "fewer than 2 samples in the window, or " + _NONFINITE),
    MetricInfo("PV peak to peak", "PV units", "largest minus smallest PV in the window",
               "fewer than 2 samples in the window, or " + _NONFINITE),
    MetricInfo("output travel", "% of OUT span", "controller output travel Σ|ΔOUT|",
               "fewer than 2 samples in the window, or " + _NONFINITE),
    MetricInfo("output reversals", "count", "sign changes of the controller output's moves, "
               "moves of at most 0.05 ignored", "fewer than 2 samples in the window, or "
               + _NONFINITE),
    MetricInfo("valve travel", "% of stem stroke", "stem travel Σ|Δy| of the valve position "
               "(the valve's wear)", "fewer than 2 samples in the window, or " + _NONFINITE),
    MetricInfo("valve reversals", "count", "sign changes of the stem's moves, moves of at "
               "most 0.05 ignored", "fewer than 2 samples in the window, or " + _NONFINITE),
    MetricInfo("valve-command travel", "% of span", "travel Σ|Δop| of the valve command: "
               "the signal wired to the valve's op input (what a compensator sends the "
               "positioner)", "fewer than 2 samples in the window, or " + _NONFINITE),
    MetricInfo("valve-command reversals", "count", "sign changes of the valve command's "
               "moves, moves of at most 0.05 ignored",
               "fewer than 2 samples in the window, or " + _NONFINITE),
)


def metric_info(name: str) -> MetricInfo:
    """The row of ``METRICS`` named ``name``."""
    for m in METRICS:
        if m.name == name:
            return m
    raise KeyError(f"no metric '{name}'; metrics: {', '.join(m.name for m in METRICS)}")


def markdown() -> str:
    """docs/metrics.md: every metric with its unit, definition and n/a rule."""
    def cell(text: str) -> str:
        return text.replace("|", "\\|")  # a literal bar inside a Markdown table cell

    rows = "\n".join("| " + " | ".join(cell(c) for c in (m.name, m.unit, m.definition,
                                                         m.not_available)) + " |"
                     for m in METRICS)
    return f"""# Loop metrics

The table `loopworks simulate` prints, `metrics.json` and `report.html` hold these figures for
each loop (a block with `sp` and `pv` inputs and an `out` output), over the scenario's
`metrics_window` (the whole run without one). The valve rows are there when the loop drives a
valve (a block with a `position` output, followed along the wires through compensators). Source:
loop-performance definitions of the plant-and-tuning spec, section 4.1.

A figure the data cannot support is **n/a** in tables and `null` in `metrics.json`, never a
number: the last column says when. The step figures (overshoot, rise and settling time) are
taken from the last setpoint change in the window to its end; the response's final value y∞ is
the mean PV over the last 5 % of that stretch (at least 2 samples). The response has *settled*
when every one of those samples lies within ±2 % of the step around y∞ and y∞ lies within ±2 %
of the step of the setpoint; overshoot and settling time are given only for a settled response.

Travel is the sum of the absolute moves of a signal over the window. Three travels show what a
stiction compensator costs: the controller output (`output travel`), the valve command sent to
the positioner (`valve-command travel`: the compensator adds its dither and kicks here) and the
stem (`valve travel`, the wear). Reversals count the sign changes of a signal's moves, ignoring
moves of at most 0.05 so that noise below the resolution is not counted.

| metric | unit | definition | n/a when |
|---|---|---|---|
{rows}

PV units are the engineering units of the loop's PV (% of span in the built-in scenario).
"""

def iae(e: np.ndarray, ts: float) -> float:
    """Integral of absolute error, Σ|e|·Ts."""
    return float(np.sum(np.abs(e)) * ts)


def ise(e: np.ndarray, ts: float) -> float:
    """Integral of squared error, Σe²·Ts."""
    return float(np.sum(e * e) * ts)


def itae(e: np.ndarray, t: np.ndarray, ts: float | None = None) -> float:
    """Integral of time-weighted absolute error, Σ(t - t_0)·|e|·Ts; Ts from the t spacing
    unless given."""
    if ts is None:
        ts = float(t[1] - t[0]) if len(t) > 1 else 0.0
    return float(np.sum((t - t[0]) * np.abs(e)) * ts)


def travel(u: np.ndarray) -> float:
    """Total output travel Σ|Δu|."""
    return float(np.sum(np.abs(np.diff(u))))


@dataclass(frozen=True)
class StepMetrics:
    """Step-response figures; NaN where the data cannot support one (``METRICS``)."""

    step_size: float
    overshoot_pct: float
    rise_time_s: float
    settling_time_s: float


def step_metrics(t: np.ndarray, y: np.ndarray, r: float, band: float = 0.02) -> StepMetrics:
    """Overshoot, 10-90 % rise time and settling time of ``y`` toward setpoint ``r`` (the
    module docstring gives the definitions and when the response counts as settled)."""
    nan = math.nan
    if len(y) < 2 or not (math.isfinite(r) and np.all(np.isfinite(y))):
        return StepMetrics(nan, nan, nan, nan)
    y0 = float(y[0])
    dr = r - y0
    if dr == 0.0:
        return StepMetrics(dr, nan, nan, nan)
    sgn = 1.0 if dr > 0 else -1.0
    tol = band * abs(dr)
    frac = (y - y0) * sgn / abs(dr)  # 0 at start, 1 at the setpoint
    i10 = np.flatnonzero(frac >= 0.1)
    i90 = np.flatnonzero(frac >= 0.9)
    rise = float(t[i90[0]] - t[i10[0]]) if len(i90) else nan
    tail = y[-max(2, len(y) // 20):]
    yinf = float(np.mean(tail))
    settled = bool(np.all(np.abs(tail - yinf) <= tol)) and abs(r - yinf) <= tol
    if not settled:
        return StepMetrics(dr, nan, rise, nan)
    overshoot = max(0.0, float(np.max((y - yinf) * sgn)) / abs(dr) * 100.0)
    outside = np.flatnonzero(np.abs(y - yinf) > tol)
    settle = float(t[outside[-1] + 1] - t[0]) if len(outside) else 0.0
    return StepMetrics(dr, overshoot, rise, settle)


def _count_reversals(y: np.ndarray, threshold: float) -> int:
    """:func:`reversals`' loop (runs interpreted and compiled)."""
    count = 0
    last = y[0] if len(y) else 0.0
    direction = 0
    for k in range(1, len(y)):
        move = y[k] - last
        if abs(move) > threshold:
            d = 1 if move > 0 else -1
            if direction != 0 and d != direction:
                count += 1
            direction = d
            last = y[k]
    return count


@cache
def _reversals_loop() -> Any:
    """:func:`_count_reversals`, compiled (cached on disk) unless ``LOOPWORKS_JIT=0``."""
    from loopworks.blocks.kernel import jit_enabled

    if not jit_enabled():
        return _count_reversals
    import numba

    return numba.njit(cache=True, nogil=True)(_count_reversals)


def reversals(y: np.ndarray, threshold: float = 0.05) -> int:
    """Sign changes of the moves of ``y``, ignoring moves of at most ``threshold`` (spec 4.1:
    so noise below the resolution is not counted). Moves are taken between the points where y
    has moved more than the threshold since the last counted point."""
    return int(_reversals_loop()(np.ascontiguousarray(y, dtype=np.float64), float(threshold)))


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


def _signal_metrics(u: np.ndarray, threshold: float) -> tuple[float, float]:
    """(travel, reversals) of one signal over the window; NaN for fewer than 2 samples or a
    non-finite sample."""
    if len(u) < 2 or not np.all(np.isfinite(u)):
        return math.nan, math.nan
    with np.errstate(over="ignore"):  # a travel beyond the float range is n/a, not inf
        return travel(u), float(reversals(u, threshold))


def loop_metrics(t: np.ndarray, sp: np.ndarray, pv: np.ndarray, out: np.ndarray,
                 position: np.ndarray | None = None,
                 window: tuple[float, float] | None = None,
                 reversal_threshold: float = 0.05,
                 command: np.ndarray | None = None) -> dict[str, float]:
    """The metrics table of one loop (``METRICS``, spec 4.1), over ``window`` = (t0, t1) s
    (default: the whole run): error integrals, step figures from the last setpoint change in
    the window (none for a window without one), PV spread, controller output travel and
    reversals, the valve stem's when ``position`` is given and the valve command's (the
    signal wired to the valve's op input) when ``command`` is given. NaN marks a figure the
    data cannot support."""
    ts = float(t[1] - t[0]) if len(t) > 1 else math.nan  # the scan period, before windowing
    if window is not None:
        keep = (t >= window[0]) & (t <= window[1])
        if not keep.any():
            raise ValueError(f"window {window} s holds no sample of the run "
                             f"({t[0]:g}..{t[-1]:g} s)")
        t, sp, pv, out = t[keep], sp[keep], pv[keep], out[keep]
        position = position[keep] if position is not None else None
        command = command[keep] if command is not None else None
    e = sp - pv
    changes = np.flatnonzero(np.diff(sp) != 0.0)
    if len(changes) or window is None:
        start = int(changes[-1]) + 1 if len(changes) else 0
        sm = step_metrics(t[start:], pv[start:], float(sp[-1]))
    else:  # a regulatory window (no setpoint change in it): no step figures
        sm = StepMetrics(math.nan, math.nan, math.nan, math.nan)
    spread = len(pv) >= 2
    result = {
        "IAE": iae(e, ts),
        "ISE": ise(e, ts),
        "ITAE": itae(e, t, ts),
        "mean |e|": float(np.mean(np.abs(e))),
        "step size": sm.step_size,
        "overshoot %": sm.overshoot_pct,
        "rise time s": sm.rise_time_s,
        "settling time s (2 %)": sm.settling_time_s,
        "final error": float(e[-1]),
        "PV std": float(np.std(pv)) if spread else math.nan,
        "PV peak to peak": float(np.ptp(pv)) if spread else math.nan,
    }
    result["output travel"], result["output reversals"] = _signal_metrics(
        out, reversal_threshold)
    if position is not None:
        result["valve travel"], result["valve reversals"] = _signal_metrics(
            position, reversal_threshold)
    if command is not None:
        result["valve-command travel"], result["valve-command reversals"] = _signal_metrics(
            command, reversal_threshold)
    return {k: (v if math.isfinite(v) else math.nan) for k, v in result.items()}
