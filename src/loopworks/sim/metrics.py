"""Loop performance metrics (spec plant-and-tuning 4.1), on sampled signals.

For samples k with scan time Ts and error e = SP - PV::

    IAE  = Σ |e_k|·Ts        ISE = Σ e_k²·Ts        ITAE = Σ t_k·|e_k|·Ts

with t measured from the setpoint step when the window holds exactly one setpoint change
(the samples before it not summed), or from the start of the window otherwise (a regulatory
window, whose disturbance's time is not known; a setpoint that moves, as a cascade
secondary's does every scan, or steps several times). For a setpoint step of size
Δr = r - y_0 (r the setpoint, y_0 the PV at the step) and y_∞ the mean PV over the tail (the
last 5 % of the samples after the step, at least 2)::

    overshoot      = max over the window of (y - y_∞)·sign(Δr) / |Δr| · 100 %
    rise time      = first time y crosses y_0 + 0.9·Δr minus first time it crosses y_0 + 0.1·Δr
    settling time  = last time |y - y_∞| > band·|Δr| (band 2 %), measured from the step
    travel         = Σ |Δu_k|

The response has settled when every tail sample is within band·|Δr| of y_∞, y_∞ is within
band·|Δr| of r, and the PV has stayed inside the band, up to the end of the record, for at
least half as long as it took to get there (``STAY``: a slow oscillation whose last half
period happens to lie inside the band is not settled); overshoot and settling time are figures
of a settled response, NaN otherwise (a response still moving, oscillating, or stalled off the
setpoint has no final value to measure them against).

The controller output's travel is in % of its span (``out_span``: the output's units of 100 %,
:meth:`Controller.out_span <loopworks.blocks.controller.Controller.out_span>`: 32000 counts for
GE, 1000 for S5, OUT_SCALE for DeltaV, 100 otherwise), and its reversals ignore moves of at most
0.05 % of it, so a PID in counts is scored as one in %. A reversal is a turn of the signal's
moves, each move measured from the last point where the signal had moved more than the
threshold (so a slow ramp of tiny steps counts as one move, and noise below the threshold as
none). NaN marks every figure the data cannot support; the report writes it as
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


#: the metrics whose sign is a direction, not a size: the best of them is the one nearest 0
SIGNED = ("final error", "step size")

_NONFINITE = "a sample in the window is NaN or infinite (a Bad value)"
_INTEGRAL = "the run has fewer than 2 scans (no scan period), or " + _NONFINITE
_FROM_T0 = ("the run has fewer than 2 scans (no scan period), or a sample from t₀ on is NaN "
            "or infinite (a Bad value; the samples before t₀ are not in the sum)")

#: every metric of ``loop_metrics``, in table order; the valve rows only for a loop with a valve
METRICS: tuple[MetricInfo, ...] = (
    MetricInfo("IAE", "PV units·s", "integral of absolute error Σ|e|·Ts over the scored window, "
               "e = working SP − PV", _INTEGRAL),
    MetricInfo("ISE", "PV units²·s", "integral of squared error Σe²·Ts", _INTEGRAL),
    MetricInfo("ITAE", "PV units·s²", "integral of time-weighted absolute error "
               "Σ(t − t₀)·|e|·Ts from t₀ on, t₀ the setpoint step when the window holds "
               "exactly one setpoint change (spec 4.1: t from the set-point change), else the "
               "start of the window (regulatory, or a moving setpoint: a cascade secondary's)",
               _FROM_T0),
    MetricInfo("ITSE", "PV units²·s²", "integral of time-weighted squared error "
               "Σ(t − t₀)·e²·Ts from t₀ on, t₀ as for ITAE (spec 4.1)", _FROM_T0),
    MetricInfo("mean |e|", "PV units", "mean absolute error over the window", _NONFINITE),
    MetricInfo("step size", "PV units", "the last setpoint step in the window: SP after it "
               "minus PV at it (Δr)",
               "no setpoint change in the window (a regulatory window; a Bad setpoint "
               "sample is no change), the setpoint ramps (it also changed on the scan before "
               "its last change: a rate limit, a cascade secondary's moving setpoint; no step "
               "from steady state, spec 4.1), the change is on the window's last scan (no "
               "response to measure), or a sample of SP or PV from the change on is NaN or "
               "infinite (a Bad value; one before the change does not touch the response)"),
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
               "oscillating, or noise larger than the band), y∞ is more than 2 % of the "
               "step away from the setpoint (stalled or creeping: read the final error), or "
               "the PV stayed inside the band for less than half the time it took to get "
               "there (the record is too short to show that it stays: a slow oscillation)"),
    MetricInfo("decay ratio", "ratio (1)", "second peak excursion / first peak excursion beyond y∞ "
               "after the step (spec 4.1; 0.25 is quarter decay): the peaks of the first two "
               "lobes above +2 % of |Δr| separated by an undershoot below -2 %",
               "no step, the response has not settled (see settling time), it does not "
               "overshoot y∞ by more than 2 % of |Δr|, or no second peak leaves that band "
               "(the ratio is then below 2 % / the overshoot, more than the band resolves)"),
    MetricInfo("final error", "PV units", "SP − PV at the last scan of the window", _NONFINITE),
    MetricInfo("PV std", "PV units", "standard deviation of the PV over the window",
               "fewer than 2 samples in the window, or " + _NONFINITE),
    MetricInfo("PV peak to peak", "PV units", "largest minus smallest PV in the window",
               "fewer than 2 samples in the window, or " + _NONFINITE),
    MetricInfo("output travel", "% of OUT span", "controller output travel Σ|ΔOUT| over "
               "the window's scans (the move into its first scan included, spec 4.1), in % "
               "of the output's span (GE counts: 32000 = 100 %, S5: 1000, DeltaV: "
               "OUT_SCALE); of a velocity output (S5 velocity = true: OUT is the increment "
               "dY), the travel of the position the increments build, Σ|dY|",
               "fewer than 2 samples in the window, or " + _NONFINITE),
    MetricInfo("output reversals", "count", "sign changes of the controller output's moves, "
               "moves of at most 0.05 % of its span ignored (of a velocity output, of the "
               "position its increments build)",
               "fewer than 2 samples in the window, or " + _NONFINITE),
    MetricInfo("valve travel", "% of stem stroke", "stem travel Σ|Δy| of the valve position "
               "(the valve's wear)", "fewer than 2 samples in the window, or " + _NONFINITE),
    MetricInfo("valve reversals", "count", "sign changes of the stem's moves, moves of at "
               "most 0.05 % of stroke ignored",
               "fewer than 2 samples in the window, or " + _NONFINITE),
    MetricInfo("valve-command travel", "% of span", "travel Σ|Δop| of the valve command: "
               "the signal wired to the valve's op input (what a compensator sends the "
               "positioner)", "fewer than 2 samples in the window, or " + _NONFINITE),
    MetricInfo("valve-command reversals", "count", "sign changes of the valve command's "
               "moves, moves of at most 0.05 % ignored",
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
taken from the last setpoint change in the window to its end (with no `metrics_window` and no
setpoint change, the run's start is that change: the start-up from the initial PV to SP; in a
window without a change, a regulatory one, they are n/a); the response's final value y∞ is
the mean PV over the last 5 % of that stretch (at least 2 samples). The response has *settled*
when every one of those samples lies within ±2 % of the step around y∞, y∞ lies within ±2 %
of the step of the setpoint, and the PV has stayed inside that band to the end for at least
half as long as it took to get there (a record that ends in the quiet half period of a slow
oscillation does not show a settled loop); overshoot and settling time are given only for a
settled response. A window that starts on the scan of a setpoint change holds that step.

Travel is the sum of the absolute moves of a signal over the window. Three travels show what a
stiction compensator costs: the controller output (`output travel`), the valve command sent to
the positioner (`valve-command travel`: the compensator adds its dither and kicks here) and the
stem (`valve travel`, the wear). The controller output's travel is in % of its span, whatever
its units (GE counts: 32000 = 100 %; S5: 1000; DeltaV: OUT_SCALE; the other kinds' outputs
are taken as in %, 1 unit = 1 %, whatever their limits: a generic `pid` whose output runs
-200..200 has its travel in those units, not in % of 400). Reversals count the turns of a
signal's moves, each move measured from the last point where the signal had moved by more than
0.05 % of its span, so that noise below the resolution is not counted and a slow ramp of small
steps is one move.

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
    decay_ratio: float = math.nan


def step_metrics(t: np.ndarray, y: np.ndarray, r: float, band: float = 0.02) -> StepMetrics:
    """Overshoot, 10-90 % rise time and settling time of ``y`` toward setpoint ``r`` (the
    module docstring gives the definitions and when the response counts as settled)."""
    y = np.asarray(y, dtype=np.float64)
    size, over, rise, settle, decay = _step_rows(
        np.asarray(t, dtype=np.float64), y[None, :], np.array([float(r)]),
        np.zeros(1, dtype=np.int64), band)
    return StepMetrics(float(size[0]), float(over[0]), float(rise[0]), float(settle[0]),
                       float(decay[0]))


def _per_row(f: Any, x: np.ndarray) -> np.ndarray:
    """``f`` (a reduction: np.sum, np.mean, np.std) of each row of ``x`` on its own: a row's
    figure must not depend on how many rows are reduced with it, so that an instance's
    metrics are the same in any batch, in any chunk, on any worker. numpy reduces the last
    axis of an array whose rows are contiguous row by row, each as it reduces a 1-D array
    (pairwise); rows laid out column-major would be summed across rows instead, in another
    order. So the rows are made contiguous first, and ``tests/sim/test_metrics.py`` checks
    the figures against each row reduced alone, bit for bit."""
    return np.asarray(f(np.ascontiguousarray(x), axis=1), dtype=np.float64)


def _first(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per row: (whether any element is True, the index of the first True one)."""
    return np.asarray(mask.any(axis=1)), np.asarray(mask.argmax(axis=1))


#: a response has settled only if the PV stayed inside the band, to the end of the record,
#: for at least STAY times the time it took to get there (its settling time)
STAY = 0.5


def decay_ratio(excursion: np.ndarray, band: float) -> float:
    """Second peak excursion / first peak excursion (spec 4.1) of a step response's
    ``excursion`` beyond its final value, (y - y∞)·sign(Δr) from the step on: the first peak
    is the largest excursion of the first lobe above +``band``, the second that of the next
    lobe above +band after the response went below -band (an undershoot). NaN when there is
    no overshoot beyond the band, or no second peak beyond it (a decay the ±band cannot
    resolve from noise; the ratio is then below band / first peak)."""
    from loopworks.sim.arrays import compiled_arg

    return float(_decay_loop()(compiled_arg(np.asarray(excursion, dtype=np.float64)),
                               float(band)))


def _decay_scan(x: np.ndarray, band: float) -> float:
    """:func:`decay_ratio`'s loop (runs interpreted and compiled): the lobes found by one
    pass each, their peaks as numpy's max takes them (a NaN in a lobe is its peak)."""
    n = len(x)

    def first(k: int, above: bool) -> int:  # the first sample from k beyond +band / -band
        while k < n and not (x[k] > band if above else x[k] < -band):
            k += 1
        return k

    def peak(a: int, b: int) -> float:
        m = x[a]
        for k in range(a + 1, b):
            if x[k] > m or x[k] != x[k]:
                m = x[k]
        return float(m)

    over = first(0, True)
    under = first(over + 1, False) if over < n else n
    again = first(under + 1, True) if under < n else n
    if again >= n:
        return math.nan
    later = first(again + 1, False)
    return peak(again, later) / peak(over, under)


@cache
def _decay_loop() -> Any:
    """:func:`_decay_scan`, compiled (cached on disk) unless ``LOOPWORKS_JIT=0``."""
    from loopworks.blocks.kernel import jit_enabled

    if not jit_enabled():
        return _decay_scan
    import numba

    return numba.njit(cache=True, nogil=True)(_decay_scan)


def _step_rows(t: np.ndarray, y: np.ndarray, r: np.ndarray, start: np.ndarray,
               band: float = 0.02) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                            np.ndarray]:
    """:func:`step_metrics` of each row i of ``y`` from sample ``start[i]`` on (the samples
    before it are not part of the response), toward ``r[i]``: (step size, overshoot %, rise
    time s, settling time s, decay ratio), NaN where the data cannot support a figure."""
    nan = math.nan
    rows, n = y.shape
    k = np.arange(n)
    ok = ((n - start) >= 2) & np.isfinite(r)
    ok &= ~((~np.isfinite(y)) & (k >= start[:, None])).any(axis=1)
    idx = np.arange(rows)
    y0 = y[idx, np.minimum(start, n - 1)] if n else np.zeros(rows)
    dr = np.where(ok, r - y0, nan)
    moves = ok & (dr != 0.0)
    size = dr
    over = np.full(rows, nan)
    rise = np.full(rows, nan)
    settle = np.full(rows, nan)
    decay = np.full(rows, nan)
    if not moves.any():
        return size, over, rise, settle, decay
    sel = np.flatnonzero(moves)
    y, r, start, y0, d = y[sel], r[sel], start[sel], y0[sel], dr[sel]
    m = np.maximum(2, (n - start) // 20)  # the tail: the last 5 % of the response, >= 2
    yinf = np.empty(len(y))
    for mi in np.unique(m):  # the rows whose tails are as long, at once
        same = m == mi
        yinf[same] = _per_row(np.mean, y[same, n - mi:])
    y = np.ascontiguousarray(y)
    figures = np.empty((len(y), 4))
    _step_loop()(np.ascontiguousarray(t, dtype=np.float64), y, np.asarray(r, dtype=np.float64),
                 d, np.asarray(start, dtype=np.int64), y0, yinf, float(band), float(STAY),
                 figures)
    over[sel], rise[sel], settle[sel] = figures[:, 0], figures[:, 1], figures[:, 2]
    for j in np.flatnonzero(figures[:, 3]):  # settled, with an overshoot beyond the band
        sgn = 1.0 if d[j] > 0 else -1.0
        decay[sel[j]] = decay_ratio((y[j, start[j]:] - yinf[j]) * sgn,
                                    float(band * abs(d[j])))
    return size, over, rise, settle, decay


def _step_figures(t: np.ndarray, y: np.ndarray, r: np.ndarray, d: np.ndarray,
                  start: np.ndarray, y0: np.ndarray, yinf: np.ndarray, band: float,
                  stay: float, out: np.ndarray) -> None:
    """:func:`_step_rows`' figures of responses that move (runs interpreted and compiled):
    row i of ``y`` from sample ``start[i]`` on, a step of ``d[i]`` from ``y0[i]`` toward
    ``r[i]``, its final value ``yinf[i]`` (the tail's mean, taken by numpy row by row);
    out[i] = (overshoot %,
    rise time s, settling time s, 1 where the decay ratio is to be worked out). One pass per
    figure over the response, not numpy's temporaries of every row (a sweep's chunk spent
    most of its metrics' time so); each comparison and each expression as the figures'
    definitions give them, so the numbers are the same."""
    nan = math.nan
    n = y.shape[1]
    for i in range(y.shape[0]):
        s = start[i]
        sgn = 1.0 if d[i] > 0 else -1.0
        mag = abs(d[i])
        tol = band * mag
        i10 = -1
        i90 = -1
        for k in range(s, n):  # the first samples 10 % and 90 % of the way
            frac = (y[i, k] - y0[i]) * sgn / mag
            if i10 < 0 and frac >= 0.1:
                i10 = k
            if frac >= 0.9:
                i90 = k
                break
        out[i, 1] = t[i90] - t[i10] if i10 >= 0 and i90 >= 0 else nan
        yi = yinf[i]
        m = max(2, (n - s) // 20)
        settled = abs(r[i] - yi) <= tol  # it ends at the setpoint
        for k in range(n - m, n):  # the tail stays in the band
            if abs(y[i, k] - yi) > tol:
                settled = False
        last = -1
        peak = -math.inf
        for k in range(s, n):
            if abs(y[i, k] - yi) > tol:
                last = k
            v = (y[i, k] - yi) * sgn
            if v > peak:
                peak = v
        t_end = t[min(last + 1, n - 1)]
        if last >= 0:  # stayed in the band to the end for STAY times as long as it took
            settled = settled and t[n - 1] - t_end >= stay * (t_end - t[s])
        out[i, 0] = (peak if peak > 0.0 else 0.0) / mag * 100.0 if settled else nan
        out[i, 2] = (t_end - t[s] if last >= 0 else 0.0) if settled else nan
        out[i, 3] = 1.0 if settled and peak > tol else 0.0


@cache
def _step_loop() -> Any:
    """:func:`_step_figures`, compiled (cached on disk) unless ``LOOPWORKS_JIT=0``."""
    from loopworks.blocks.kernel import jit_enabled

    if not jit_enabled():
        return _step_figures
    import numba

    return numba.njit(cache=True, nogil=True)(_step_figures)


def _count_reversals(y: np.ndarray, threshold: float) -> int:
    """:func:`reversals`' loop (runs interpreted and compiled). A move within 1e-9 of the
    threshold is "at most" it: a GE move of 16 counts is 0.05 % of 32000, and scaled to % it
    came out either side of 0.05 by rounding (0.0750 - 0.0250 counted, 50.05 - 50.00 not)."""
    count = 0
    last = y[0] if len(y) else 0.0
    direction = 0
    limit = threshold * (1.0 + 1e-9)
    for k in range(1, len(y)):
        move = y[k] - last
        if abs(move) > limit:
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
    from loopworks.sim.arrays import compiled_arg

    return int(_reversals_loop()(compiled_arg(y), float(threshold)))


@dataclass(frozen=True)
class OscillationReport:
    """Hägglund's load-disturbance detector (spec 4.2): the IAE limit used, the number of
    half periods whose IAE exceeded it, the forgetting counter at the end, the alarm (the
    counter above n_lim at any crossing of the record) and the counter's largest value."""

    iae_limit: float
    large_half_periods: int
    counter: float
    alarm: bool
    peak_counter: float = 0.0


def oscillation_detector(t: np.ndarray, e: np.ndarray, a: float = 1.0,
                         wu: float | None = None, ti: float | None = None, n_lim: float = 10.0,
                         t_sup: float | None = None) -> OscillationReport:
    """Hägglund (1995), spec 4.2: integrate |e| between zero crossings of e; a half period is
    "large" when its IAE_i > IAE_lim = 2a/ωu (a in PV units, default 1 % of a 0..100 range;
    ωu from the tuner, or ωu = 2π/Ti, giving IAE_lim = a·Ti/π). The flags are counted with
    exponential forgetting x <- γ·x + flag at each crossing, γ = exp(-Δt/T_sup) over the time
    since the previous crossing, T_sup = 50·Tu (Tu = 2π/ωu); an alarm is raised when x >
    n_lim, at any crossing of the record (an oscillation that stopped before the record's end
    was alarmed; judged on the final counter it was not). ValueError names a parameter out
    of range or a time axis that does not match ``e`` or does not increase."""
    def positive(name: str, value: float | None) -> None:
        if value is not None and not 0.0 < value < math.inf:
            raise ValueError(f"oscillation_detector: {name} = {value!r} is out of range: "
                             "allowed (0, inf)")

    for name, value in (("a", a), ("wu", wu), ("ti", ti), ("t_sup", t_sup)):
        positive(name, value)
    if not math.isfinite(n_lim):
        raise ValueError(f"oscillation_detector: n_lim = {n_lim!r} must be finite")
    if len(t) != len(e):
        raise ValueError(f"oscillation_detector: t has {len(t)} samples and e {len(e)}: "
                         "one time per error sample")
    if len(t) > 1 and not bool(np.all(np.diff(t) > 0)):
        raise ValueError("oscillation_detector: t must increase")
    if wu is None:
        if ti is None:
            raise ValueError("oscillation_detector needs wu (rad/s) or ti (s)")
        wu = 2.0 * np.pi / ti
    iae_lim = 2.0 * a / wu
    tu = 2.0 * np.pi / wu
    t_sup = 50.0 * tu if t_sup is None else t_sup
    ts = float(t[1] - t[0]) if len(t) > 1 else 0.0
    x = 0.0
    peak = 0.0
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
            peak = max(peak, x)
            t_last = float(t[k])
            area = 0.0
        if s:
            sign = s
        area += abs(ek) * ts
    return OscillationReport(iae_lim, large, x, peak > n_lim, peak)


def _signal_metrics(u: np.ndarray, threshold: float) -> tuple[np.ndarray, np.ndarray]:
    """(travel, reversals) of each row of ``u`` over the window; NaN for fewer than 2 samples
    or a non-finite sample."""
    rows, n = u.shape
    if n < 2:
        return np.full(rows, math.nan), np.full(rows, math.nan)
    finite = np.isfinite(u).all(axis=1)
    with np.errstate(over="ignore", invalid="ignore"):  # beyond the float range: n/a
        moves = _per_row(np.sum, np.abs(np.diff(u, axis=1)))
    from loopworks.sim.arrays import compiled_arg

    count = _reversals_loop()
    turns = np.array([float(count(compiled_arg(u[i]), float(threshold))) if finite[i]
                      else math.nan for i in range(rows)])
    return np.where(finite, moves, math.nan), turns


#: the tolerance of a window's bounds, in scan periods: scan k runs at t = k·dt, which rounds
#: (0.8999999999999999 for the 4th scan at 0.3 s), and a bound written as 0.9 means that scan;
#: the scenario counts a window's scans by the same rule (``scenario._window``)
WINDOW_TOLERANCE = 1e-9


def in_window(t: np.ndarray, window: tuple[float, float], ts: float) -> np.ndarray:
    """The samples of ``t`` inside ``window`` = (t0, t1) s, both ends included, each end
    widened by :data:`WINDOW_TOLERANCE` of the scan period ``ts`` (none when ``ts`` is not
    finite: a one-sample run) and by the rounding of the bound itself."""
    t0, t1 = (float(w) for w in window)
    tol = (WINDOW_TOLERANCE * ts if math.isfinite(ts) else 0.0) \
        + 4.0 * np.finfo(np.float64).eps * max(abs(t0), abs(t1))
    return np.asarray((t >= t0 - tol) & (t <= t1 + tol))


def loop_metrics(t: np.ndarray, sp: np.ndarray, pv: np.ndarray, out: np.ndarray,
                 position: np.ndarray | None = None,
                 window: tuple[float, float] | None = None,
                 reversal_threshold: float = 0.05,
                 command: np.ndarray | None = None,
                 out_span: float | np.ndarray = 100.0) -> dict[str, Any]:
    """The metrics table of one loop (``METRICS``, spec 4.1), over ``window`` = (t0, t1) s
    (default: the whole run): error integrals, step figures from the last setpoint change in
    the window (none for a window without one; a change on the window's first scan, against
    the scan before it, is one), PV spread, controller output travel and reversals (in % of
    ``out_span``, the output's units of 100 %, or one per instance), the valve stem's when
    ``position`` is given
    and the valve command's (the signal wired to the valve's op input) when ``command`` is
    given; ``reversal_threshold`` in % of span. NaN marks a figure the data cannot support.

    The signals are arrays over ``t``, each figure a float; or N × len(t) arrays, N
    instances of one loop (a sweep's batch), each figure an array of N."""
    one = np.ndim(pv) == 1

    def rows(x: np.ndarray) -> np.ndarray:
        return np.atleast_2d(np.asarray(x, dtype=np.float64))

    sp, pv, out = rows(sp), rows(pv), rows(out)
    position = rows(position) if position is not None else None
    command = rows(command) if command is not None else None
    ts = float(t[1] - t[0]) if len(t) > 1 else math.nan  # the scan period, before windowing
    before = sp[:, :1]  # the setpoint on the scan before the window (none: the first scan's)
    # travel Σ|Δy_k| over k = k0..k1 (spec 4.1) counts the move into the window's first
    # scan, Δy_k0 = y_k0 - y_k0-1: the travel signals keep the scan before the window (a
    # window starting on a setpoint step held the step but lost its proportional kick)
    moving = [out, position, command]
    if window is not None:
        keep = in_window(t, window, ts)
        if not keep.any():
            raise ValueError(f"window {window} s holds no sample of the run "
                             f"({t[0]:g}..{t[-1]:g} s)")
        first = int(np.argmax(keep))
        before = sp[:, first - 1:first] if first > 0 else sp[:, first:first + 1]
        lead = slice(max(first - 1, 0), first + int(keep.sum()))
        moving = [x[:, lead] if x is not None else None for x in moving]
        t, sp, pv = t[keep], sp[:, keep], pv[:, keep]
    n = len(t)
    e = sp - pv
    ae = np.abs(e)
    # changed[:, j]: the setpoint of scan j differs from the scan before it (the window's
    # first scan against the one before the window); a Bad (non-finite) setpoint sample is
    # no change: going Bad and back is not a step
    both = np.concatenate([before, sp], axis=1)
    finite_sp = np.isfinite(both)
    with np.errstate(invalid="ignore"):
        changed = (np.diff(both, axis=1) != 0.0) & finite_sp[:, 1:] & finite_sp[:, :-1]
    has_change = changed.any(axis=1)
    start = np.where(has_change, n - 1 - changed[:, ::-1].argmax(axis=1), 0)
    # the response needs SP and PV from the step on: a Bad setpoint sample there is one too
    size, over, rise, settle, decay = _step_rows(
        t, np.where(np.isfinite(sp), pv, math.nan), sp[:, -1], start)
    # ITAE's t from the setpoint step (spec 4.1) when the window holds one change, else from
    # the window's start (regulatory, or a setpoint that moves: a cascade secondary's changes
    # every scan, and its last change is no step to weigh from)
    t0 = np.where(changed.sum(axis=1) == 1, start, 0)
    since = t[None, :] - t[t0][:, None]
    if window is not None:  # a regulatory window (no setpoint change in it): no step figures
        for fig in (size, over, rise, settle, decay):
            fig[~has_change] = math.nan
    # a setpoint that also changed on the scan before its last change ramps (a rate limit, a
    # cascade secondary's moving SP): its last increment is no step from steady state (spec
    # 4.1; a DeltaV SP ramp from 50 to 60 read as a step of 0.45 with a rise time of 10 s)
    which = np.arange(len(start))
    ramps = has_change & (start >= 1) & changed[which, np.maximum(start - 1, 0)]
    for fig in (size, over, rise, settle, decay):
        fig[ramps] = math.nan
    spread = n >= 2
    with np.errstate(over="ignore", invalid="ignore"):
        result: dict[str, np.ndarray] = {
            "IAE": _per_row(np.sum, ae) * ts,
            "ISE": _per_row(np.sum, e * e) * ts,
            "ITAE": _per_row(np.sum, np.where(since >= 0.0, since * ae, 0.0)) * ts,
            "ITSE": _per_row(np.sum, np.where(since >= 0.0, since * e * e, 0.0)) * ts,
            "mean |e|": _per_row(np.mean, ae),
            "step size": size,
            "overshoot %": over,
            "rise time s": rise,
            "settling time s (2 %)": settle,
            "decay ratio": decay,
            # n/a when a sample of the window is Bad, as the table says (not only the last)
            "final error": np.where(np.isfinite(e).all(axis=1), e[:, -1], math.nan),
            "PV std": _per_row(np.std, pv) if spread else np.full(len(pv), math.nan),
            "PV peak to peak": np.ptp(pv, axis=1) if spread else np.full(len(pv), math.nan),
        }
    out_moves, position_moves, command_moves = moving
    assert out_moves is not None
    result["output travel"], result["output reversals"] = _signal_metrics(
        out_moves * (100.0 / np.reshape(np.asarray(out_span, dtype=np.float64), (-1, 1))),
        reversal_threshold)
    if position_moves is not None:
        result["valve travel"], result["valve reversals"] = _signal_metrics(
            position_moves, reversal_threshold)
    if command_moves is not None:
        result["valve-command travel"], result["valve-command reversals"] = _signal_metrics(
            command_moves, reversal_threshold)
    clean = {k: np.where(np.isfinite(v), v, math.nan) for k, v in result.items()}
    return {k: float(v[0]) for k, v in clean.items()} if one else clean
