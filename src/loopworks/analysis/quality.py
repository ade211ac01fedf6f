"""The data-quality gate run before any stiction test: a record that fails it gets no stiction
verdict, only the reasons, each a sentence with its figure. Never a guess.

Rules, their thresholds (module constants) and their sources:

* **Too short** — fewer than :data:`MIN_SAMPLES` (200) samples fails. Engineering judgement:
  the stiction indices (cross-correlation, area ratio, curve fits, bicoherence) need several
  oscillation cycles of some tens of samples each; 200 samples is the least that can hold a
  few. (A minimum number of oscillation periods, about 3, belongs to the oscillation stage,
  not here.)
* **Frozen signal** — a PV or OP that is constant over the record, or that holds one value
  for a run of consecutive samples longer than :data:`FROZEN_RUN_FRACTION` (50 %) of the
  record, fails: a dead transmitter, a controller output not written, or a compressed historian
  tag (swinging door or exception deadband) replayed by zero-order hold, which repeats the last
  stored value until the next. Engineering judgement: when most of the record is one held value,
  most of it carries no information about the valve.
* **Held records** — stretches where SP, PV and OP *all* repeat their previous values exactly
  for at least :data:`HELD_RUN` consecutive samples, covering more than
  :data:`MAX_HELD_FRACTION` (20 %) of the record, fail: in automatic a PI controller's output
  does not stand still while a live measurement moves, so such stretches are gaps in the
  archive replayed by zero-order hold (a historian that lost or compressed the samples
  repeats the last stored row), or a PV quantised to its set point; either way they hold no
  OP → PV dynamics, and a model fitted across them fits the holds (a plateau, then a jump,
  the shape of stick-slip). Fewer is a note. The same idea as the frozen-signal rule, on the
  three signals together; the thresholds are engineering judgement: two repeats in a row
  happen by chance in a slowly moving, coarsely archived record, three across all three
  signals do not.
* **Compressed or quantised PV** — fewer than :data:`MIN_UNIQUE_FRACTION` (20 %) distinct PV
  values (after rounding to :data:`UNIQUE_DECIMALS` = 6 decimals) fails. This is the rule of
  maulanaiskak/valve-stiction-ml (``src/valve_stiction_ml/classic.py``,
  ``is_likely_quantized``; cited in the plant-and-tuning spec, section 4.3): a quantised PV
  makes the same "flat, then jump" shape as stick-slip; that repository found 46-77 % distinct
  PV values in windows tagged as stick-slip and 6 % in one tagged as quantisation. The fraction
  depends on the record's length (a signal with L levels cannot exceed L / n), so it is meant
  for windows of a few hundred to a few thousand samples. The estimated quantisation step is
  reported as a note (:func:`pv_quantum`). A constant PV is reported as frozen, not also as
  quantised. A long record of a finely quantised PV (a PLC's INT counts) passes with a note:
  a step at most :data:`FINE_QUANTUM` of the PV's noise, and the PV repeating its last value
  in at most :data:`MAX_REPEAT_FRACTION` of the samples (a compressing historian holds it).
* **Saturated output** — the OP at a limit for more than :data:`MAX_SATURATED_FRACTION` (10 %)
  of the samples fails: a saturated valve does not move, so the loop is open there. With
  ``op_limits`` given, at a limit is within :data:`SATURATION_TOLERANCE` (0.5 % of their span)
  of one. Without them (``diagnose``, its OP in % of the valve's span), it is within 0.5 % of
  0 % or 100 %, or exactly at the OP's own minimum or maximum over the record (a clamp the
  record does not name, OUT_HI_LIM 90 % say, holds the OP flat there; to within
  :data:`SAME_VALUE` of its size). Not within 0.5 % of those extremes: an OP that settles
  and moves a little about its value (50 ± 0.05 after a start-up ramp from 0) has most of
  its samples near its own maximum without being held by anything (it was called saturated,
  2026-12-07). Engineering judgement.
* **Manual mode** — a mode other than 1 (automatic) for more than :data:`MAX_MANUAL_FRACTION`
  (10 %) of the samples fails: in manual the loop is open and the OP is the operator's.
  Less than that is a note. A record without a mode column gets a note that automatic mode is
  assumed. Engineering judgement.
* **Setpoint changes** — SP moves (sample to sample) larger than :data:`SP_MOVE_FRACTION`
  (1 %) of the PV's span are counted and given as a note, never a failure. Decision: a record
  with SP moves is a servo record or a cascade slave (the slave's SP moves every sample); the
  stiction tests then work on the control error e = SP - PV, as Choudhury's method does for
  cascade loops, so refusing it would refuse most flow loops. Engineering judgement.
* **Bad values** — the fraction of samples with a Bad SP, PV or OP (NaN, infinite, or beyond
  ±1e12 in its units, the rule of a block's input: :func:`loopdata.bad`): above
  :data:`MAX_NAN_FRACTION` (5 %) fails, any is a note: the spectral and shape tests need
  continuous records, and a few gaps can be bridged, many cannot. Engineering judgement.

Every rule is checked on every record; a record that fails lists every reason.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from loopworks.analysis.loopdata import LoopData, bad

FloatArray = npt.NDArray[np.float64]

#: fewest samples a stiction test is run on (engineering judgement: a few cycles of tens of
#: samples each)
MIN_SAMPLES = 200
#: a run of one held value longer than this fraction of the record is a frozen signal
#: (engineering judgement)
FROZEN_RUN_FRACTION = 0.5
#: a stretch of at least this many consecutive samples that repeat the previous SP, PV and OP
#: exactly is a held stretch (engineering judgement)
HELD_RUN = 3
#: more of the samples than this fraction in held stretches fails (engineering judgement)
MAX_HELD_FRACTION = 0.2
#: fewer distinct PV values than this fraction of the samples is a compressed or quantised PV
#: (maulanaiskak/valve-stiction-ml, classic.py, is_likely_quantized)
MIN_UNIQUE_FRACTION = 0.2
#: decimals the PV is rounded to before counting distinct values (as the same source does)
UNIQUE_DECIMALS = 6
#: a quantisation step at most this fraction of the PV's noise cannot make the "flat, then
#: jump" shape, and a PV that repeats its last value in at most MAX_REPEAT_FRACTION of the
#: samples is not held by a compressing historian: its few distinct values are the length of
#: the record (a PLC's INT PV over 12,000 samples: 797 values, 6.6 %), not a loss (ours)
FINE_QUANTUM = 0.25
MAX_REPEAT_FRACTION = 0.1
#: an OP this close to a limit, as a fraction of the limits' span, is at the limit
SATURATION_TOLERANCE = 0.005
#: an OP sample this close to the record's own extreme (relative to its size, at least 1) is
#: at it: a clamp holds the OP at one value (the text of a CSV may round it in its last digits)
SAME_VALUE = 1e-9
#: more of the samples than this fraction at an OP limit is a saturated output
#: (engineering judgement)
MAX_SATURATED_FRACTION = 0.1
#: more of the samples than this fraction out of automatic is a manual record
#: (engineering judgement)
MAX_MANUAL_FRACTION = 0.1
#: an SP move larger than this fraction of the PV's span counts as a setpoint change
SP_MOVE_FRACTION = 0.01
#: more of the samples than this fraction with a Bad (NaN) SP, PV or OP fails
#: (engineering judgement)
MAX_NAN_FRACTION = 0.05
#: a quantum is "common" when at least this fraction of the gaps between adjacent PV levels
#: are whole multiples of it
QUANTUM_COMMON = 0.9
#: how close (as a fraction of the quantum) a gap must be to a whole multiple of it
QUANTUM_TOLERANCE = 0.01


@dataclass(frozen=True)
class Quality:
    """The gate's verdict on one record: ``passed`` is False when ``reasons`` is not empty;
    ``notes`` are warnings that do not fail it. The figures: ``n`` samples, the fraction of
    distinct PV values, of samples with the OP at a limit, out of automatic mode, with a NaN;
    the number of SP moves; the estimated PV quantisation step (0 when none is found); the
    longest held run of the PV or OP as a fraction of the record; the fraction of the record in
    stretches where SP, PV and OP are all held."""

    passed: bool
    reasons: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    n: int = 0
    unique_pv_fraction: float = 0.0
    saturated_fraction: float = 0.0
    manual_fraction: float = 0.0
    sp_changes: int = 0
    nan_fraction: float = 0.0
    pv_quantum: float = 0.0
    frozen_fraction: float = 0.0
    held_fraction: float = 0.0

    def summary(self) -> str:
        """The verdict, the reasons and the notes, one to a line."""
        head = "quality: passed" if self.passed else "quality: failed"
        lines = [head, *(f"  reason: {r}" for r in self.reasons),
                 *(f"  note: {m}" for m in self.notes)]
        return "\n".join(lines)


def check_quality(data: LoopData, *,
                  op_limits: tuple[float, float] | None = None) -> Quality:
    """Run every rule of the module docstring on ``data``; ``op_limits`` are the OP's
    saturation limits (the OP's own extremes when None)."""
    n = len(data)
    reasons: list[str] = []
    # how the reader made the record regular (resampling, repeated time stamps), first
    notes: list[str] = [data.resampled] if data.resampled else []
    if n < MIN_SAMPLES:
        reasons.append(f"the record has {n} samples: at least {MIN_SAMPLES} are needed")
    nan_fraction = _nan_check(data, reasons, notes)
    frozen = max(_frozen_check("PV", data.pv, reasons), _frozen_check("OP", data.op, reasons))
    held = _held_check(data, reasons, notes)
    unique, quantum = _quantisation_check(data.pv, reasons, notes)
    saturated = _saturation_check(data.op, op_limits, reasons)
    manual = _manual_check(data.mode, reasons, notes)
    if data.sp_recorded:
        sp_changes = _sp_check(data.sp, data.pv, notes)
    elif not np.isfinite(data.sp).all():  # no finite PV in automatic to take the mean of
        sp_changes = 0
        reasons.append("the record has no setpoint column, and no finite PV sample in "
                       "automatic to take the SP from (the PV's mean)")
    else:
        sp_changes = 0
        notes.append(f"the record has no setpoint column: the SP is taken as constant at the "
                     f"PV's mean, {data.sp[0]:.6g} (a loop with integral action holds its PV "
                     f"at its SP on average); wrong for a loop whose SP moved (a cascade "
                     f"secondary)")
    return Quality(passed=not reasons, reasons=reasons, notes=notes, n=n,
                   unique_pv_fraction=unique, saturated_fraction=saturated,
                   manual_fraction=manual, sp_changes=sp_changes, nan_fraction=nan_fraction,
                   pv_quantum=quantum, frozen_fraction=frozen, held_fraction=held)


def _pct(x: float) -> str:
    """A fraction as a percentage for a sentence."""
    return f"{100 * x:.3g} %"


def _nan_check(data: LoopData, reasons: list[str], notes: list[str]) -> float:
    """The fraction of samples with a Bad SP, PV or OP (NaN, infinite or beyond ±1e12:
    :func:`~loopworks.analysis.loopdata.bad`); a failure above the limit."""
    # an SP the reader took from the PV (no setpoint column) is Bad only where the PV is
    signals = (("SP", data.sp), ("PV", data.pv), ("OP", data.op))
    flags = [(name, bad(a)) for name, a in signals if data.sp_recorded or name != "SP"]
    count = int(np.logical_or.reduce([b for _, b in flags]).sum())
    fraction = count / len(data)
    if not count:
        return 0.0
    each = ", ".join(f"{name} {int(b.sum())}" for name, b in flags)
    which = "SP, PV or OP" if data.sp_recorded else "PV or OP"
    text = (f"{count} of {len(data)} samples ({_pct(fraction)}) have a Bad {which} (NaN, "
            f"infinite or beyond ±1e12; {each})")
    if fraction > MAX_NAN_FRACTION:
        reasons.append(f"{text}: at most {_pct(MAX_NAN_FRACTION)} is allowed")
    else:
        notes.append(f"{text}: within the {_pct(MAX_NAN_FRACTION)} allowed")
    return fraction


def longest_run_span(x: FloatArray) -> tuple[int, int]:
    """(start, stop) of the longest run of consecutive equal values in ``x`` (NaN ends a
    run); (0, 0) for an empty ``x``."""
    if len(x) == 0:
        return 0, 0
    change = np.flatnonzero(x[1:] != x[:-1]) + 1
    bounds = np.concatenate(([0], change, [len(x)]))
    k = int(np.argmax(np.diff(bounds)))
    return int(bounds[k]), int(bounds[k + 1])


def longest_run(x: FloatArray) -> tuple[int, float]:
    """The longest run of consecutive equal values in ``x`` (NaN ends a run) and its value."""
    if len(x) == 0:
        return 0, float("nan")
    start, stop = longest_run_span(x)
    return stop - start, float(x[start])


def _frozen_check(name: str, x: FloatArray, reasons: list[str]) -> float:
    """A constant signal, or one held for most of the record, fails; the longest run's
    fraction of the record."""
    finite = x[np.isfinite(x)]
    if len(finite) == 0:
        reasons.append(f"the {name} has no valid value (every sample is NaN)")
        return 1.0
    if np.ptp(finite) == 0:
        reasons.append(f"the {name} is constant at {finite[0]:.6g} over all {len(finite)} valid "
                       f"samples (a frozen signal)")
        return 1.0
    run, value = longest_run(x)
    fraction = run / len(x)
    if fraction > FROZEN_RUN_FRACTION:
        reasons.append(f"the {name} holds {value:.6g} for {run} consecutive samples "
                       f"({_pct(fraction)} of the record; a frozen or compressed signal): at "
                       f"most {_pct(FROZEN_RUN_FRACTION)} is allowed")
    return fraction


def held_stretches(data: LoopData, min_run: int = HELD_RUN) -> list[tuple[int, int]]:
    """(start, stop) of each stretch of at least ``min_run`` consecutive samples that repeat
    the previous sample's SP, PV and OP exactly (the sample before the stretch is not in it:
    it is the value being held)."""
    same = ((data.sp[1:] == data.sp[:-1]) & (data.pv[1:] == data.pv[:-1])
            & (data.op[1:] == data.op[:-1]))
    edges = np.flatnonzero(np.diff(np.concatenate(([0], same.astype(np.int8), [0]))))
    return [(int(a) + 1, int(b) + 1) for a, b in zip(edges[::2], edges[1::2], strict=True)
            if b - a >= min_run]


def _held_check(data: LoopData, reasons: list[str], notes: list[str]) -> float:
    """The fraction of the record in held stretches (:func:`held_stretches`); a failure above
    :data:`MAX_HELD_FRACTION`, a note when there are any."""
    stretches = held_stretches(data)
    if not stretches:
        return 0.0
    count = sum(b - a for a, b in stretches)
    fraction = count / len(data)
    text = (f"SP, PV and OP all repeat their previous values in {len(stretches)} stretch"
            f"{'es' * (len(stretches) != 1)} of {HELD_RUN} or more samples, {count} of "
            f"{len(data)} samples ({_pct(fraction)}, the longest "
            f"{max(b - a for a, b in stretches)}): gaps in the archive replayed as holds, or a "
            f"PV quantised at its set point")
    if fraction > MAX_HELD_FRACTION:
        reasons.append(f"{text}: at most {_pct(MAX_HELD_FRACTION)} is allowed (the holds carry "
                       f"no OP to PV dynamics, and their plateaus look like stick-slip)")
    else:
        notes.append(text)
    return fraction


def unique_fraction(pv: FloatArray) -> tuple[int, float]:
    """The distinct valid PV values after rounding to :data:`UNIQUE_DECIMALS` decimals, and
    their fraction of the valid samples (maulanaiskak/valve-stiction-ml's measure)."""
    finite = pv[np.isfinite(pv)]
    if len(finite) == 0:
        return 0, 0.0
    count = len(np.unique(np.round(finite, UNIQUE_DECIMALS)))
    return count, count / len(finite)


def pv_quantum(pv: FloatArray) -> float:
    """The PV's estimated quantisation step: the smallest gap between adjacent distinct
    values, when at least :data:`QUANTUM_COMMON` of all the gaps are whole multiples of it
    (within :data:`QUANTUM_TOLERANCE` of it); else 0 (a continuous signal, whose gaps are
    not multiples of one step). Gaps below 1e-9 of the largest magnitude are floating-point
    noise in the text and are ignored."""
    levels = np.unique(pv[np.isfinite(pv)])
    if len(levels) < 2:
        return 0.0
    gaps = np.diff(levels)
    gaps = gaps[gaps > 1e-9 * float(np.abs(levels).max())]
    if len(gaps) == 0:
        return 0.0
    q = float(gaps.min())
    ratio = gaps / q
    whole = np.abs(ratio - np.round(ratio)) <= QUANTUM_TOLERANCE
    return q if whole.mean() >= QUANTUM_COMMON else 0.0


def _quantisation_check(pv: FloatArray, reasons: list[str],
                        notes: list[str]) -> tuple[float, float]:
    """Fewer than :data:`MIN_UNIQUE_FRACTION` distinct PV values fails (unless the PV is
    constant: that is a frozen signal); the fraction and the estimated quantum."""
    count, fraction = unique_fraction(pv)
    quantum = pv_quantum(pv)
    valid = int(np.isfinite(pv).sum())
    finite = pv[np.isfinite(pv)]
    noise = float(np.std(np.diff(finite, 2)) / np.sqrt(6.0)) if len(finite) > 3 else 0.0
    repeats = float(np.mean(np.diff(finite) == 0.0)) if len(finite) > 1 else 1.0
    fine = 0.0 < quantum <= FINE_QUANTUM * noise and repeats <= MAX_REPEAT_FRACTION
    if count > 1 and fraction < MIN_UNIQUE_FRACTION and fine:
        notes.append(f"the PV takes {count} distinct values over {valid} samples "
                     f"({_pct(fraction)}), in steps of {quantum:.6g}, far below its noise "
                     f"({noise:.3g}), and repeats itself in {_pct(repeats)} of the samples: a "
                     "fine quantisation over a long record, not a compressed or coarsely "
                     "quantised PV")
    elif count > 1 and fraction < MIN_UNIQUE_FRACTION:
        need = int(np.ceil(MIN_UNIQUE_FRACTION * valid))
        reasons.append(f"the PV takes {count} distinct values over {valid} samples "
                       f"({_pct(fraction)}; compressed or quantised): at least {need} "
                       f"({_pct(MIN_UNIQUE_FRACTION)}) are needed "
                       f"(the maulanaiskak/valve-stiction-ml rule)")
    if quantum > 0:
        notes.append(f"the PV moves in steps of {quantum:.6g} (quantised; "
                     f"{count} distinct values)")
    return fraction, quantum


def _saturation_check(op: FloatArray, limits: tuple[float, float] | None,
                      reasons: list[str]) -> float:
    """The fraction of samples with the OP at a limit (module docstring); a failure above the
    allowed one."""
    finite = op[np.isfinite(op)]
    if len(finite) == 0:
        return 0.0
    low, high = (float(finite.min()), float(finite.max())) if limits is None else limits
    if not high > low:
        return 0.0  # a constant OP is reported as frozen
    if limits is not None:
        tol = SATURATION_TOLERANCE * (high - low)
        low_side, high_side = finite <= low + tol, finite >= high - tol
        where = f"{low:.6g} and {high:.6g}, the given limits, within {_pct(SATURATION_TOLERANCE)}"
    else:  # OP in %: the valve's span, or held flat at its own extremes (an unnamed clamp)
        tol = SATURATION_TOLERANCE * 100.0
        same = SAME_VALUE * max(1.0, abs(low), abs(high))
        low_side, high_side = finite <= low + same, finite >= high - same
        # an extreme reached once is no value held there (a 15-sample ramp read 2 of 15
        # samples "at a limit"; found by an outside audit)
        low_side &= int(low_side.sum()) > 1
        high_side &= int(high_side.sum()) > 1
        low_side |= finite <= tol
        high_side |= finite >= 100.0 - tol
        where = (f"{low:.6g} and {high:.6g}, its extremes over the record, held there, or "
                 f"within {_pct(SATURATION_TOLERANCE)} of 0 % or 100 %")
    at_low, at_high = int(low_side.sum()), int(high_side.sum())
    fraction = (at_low + at_high) / len(op)
    if fraction > MAX_SATURATED_FRACTION:
        reasons.append(f"the OP is at a limit for {at_low + at_high} of {len(op)} samples "
                       f"({_pct(fraction)}; {at_low} at the low one, {at_high} at the high one: "
                       f"{where}): at most {_pct(MAX_SATURATED_FRACTION)} is allowed "
                       "(saturated, or held there by a compressed tag: the valve does not "
                       "move)")
    return fraction


def _manual_check(mode: FloatArray | None, reasons: list[str], notes: list[str]) -> float:
    """The fraction of samples out of automatic (mode != 1, or Bad); a failure above the
    allowed one; a note when the record has no mode."""
    if mode is None:
        notes.append("the record has no mode column: automatic mode is assumed throughout")
        return 0.0
    out = int((mode != 1).sum())
    fraction = out / len(mode)
    text = f"the loop is not in automatic for {out} of {len(mode)} samples ({_pct(fraction)})"
    if fraction > MAX_MANUAL_FRACTION:
        reasons.append(f"{text}: at most {_pct(MAX_MANUAL_FRACTION)} is allowed (in manual the "
                       f"loop is open)")
    elif out:
        notes.append(text)
    return fraction


def _sp_moves(sp: FloatArray, pv: FloatArray) -> tuple[npt.NDArray[np.bool_], float]:
    """Which sample-to-sample SP moves count as setpoint changes (larger than
    :data:`SP_MOVE_FRACTION` of the PV's span; a NaN is no move), and that tolerance."""
    finite = pv[np.isfinite(pv)]
    span = float(np.ptp(finite)) if len(finite) else 0.0
    tol = SP_MOVE_FRACTION * span
    return np.abs(np.diff(sp)) > tol, tol


def sp_reversals(data: LoopData) -> int:
    """How many times the setpoint changes (:func:`_sp_moves`) reverse direction: 0 for a
    record whose SP only steps or ramps one way."""
    moved, _ = _sp_moves(data.sp, data.pv)
    signs = np.sign(np.diff(data.sp)[moved])
    return int((signs[1:] != signs[:-1]).sum())


def held_sp_stretches(data: LoopData) -> list[slice]:
    """The stretches of the record between consecutive setpoint changes (:func:`_sp_moves`),
    longest first (in record order among equals)."""
    moved, _ = _sp_moves(data.sp, data.pv)
    edges = [0, *(int(k) + 1 for k in np.flatnonzero(moved)), len(data)]
    spans = [slice(a, b) for a, b in itertools.pairwise(edges) if b > a]
    return sorted(spans, key=lambda s: -(s.stop - s.start))


def _sp_check(sp: FloatArray, pv: FloatArray, notes: list[str]) -> int:
    """The number of SP moves larger than :data:`SP_MOVE_FRACTION` of the PV's span; a note
    when there are any."""
    moved, tol = _sp_moves(sp, pv)
    count = int(moved.sum())
    if count:
        size = (f"by more than {tol:.3g} ({_pct(SP_MOVE_FRACTION)} of the PV's span)" if tol > 0
                else "(the PV does not move, so any SP move counts)")
        times = "once" if count == 1 else f"{count} times"
        notes.append(f"the SP moves {times} {size}: a servo record or a cascade slave; "
                     f"the stiction tests work on the control error SP - PV")
    return count
