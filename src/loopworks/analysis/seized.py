"""A valve that does not move at all: the controller drives its output across a large part of
the span, the error keeps its sign, and the PV holds one value throughout (issue 15).

The quality gate (:mod:`loopworks.analysis.quality`) refuses a record whose PV is frozen: most
of it carries no information about how the valve moves. One frozen record does carry that
information: when the loop is in automatic, the error SP - PV keeps one sign, and the OP walks
steadily across at least :data:`MIN_OP_TRAVEL` % of its span while the PV does not change by a
single count, the controller's integral action is winding up against a valve that does not
answer. Its stiction is larger than the whole travel the OP made (Choudhury's S above that
travel: the valve never broke away, spec plant-and-tuning 1.2). This is the "stuck valve"
practitioners know, the extreme of stiction. The same
record is made by a closed block (isolation) valve upstream or downstream, or by a transmitter
that is dead yet reads a plausible value: the data cannot tell these apart, so the finding says
to check them in the field, and its confidence is :data:`CONFIDENCE`, not 1.

Rule [ours, each threshold engineering judgement]: over the longest run of samples in which the
PV holds exactly one value, of at least :data:`MIN_RUN_FRACTION` of the record, in automatic
(mode 1, or no mode column):

* the OP travels (maximum - minimum) at least :data:`MIN_OP_TRAVEL` % of span;
* it moves one way: its net move is at least :data:`MIN_MONOTONE` of that travel (a
  controller winding up, not noise around a held output);
* the error SP - PV is non-zero and of one sign at every sample of the run;
* a recorded valve position, if any, does not move with the OP (correlation below 0.9): a
  valve seen moving is not seized, whatever the PV does.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from loopworks.analysis.loopdata import LoopData
from loopworks.analysis.quality import longest_run_span

#: least OP travel (max - min over the frozen run), % of span
MIN_OP_TRAVEL = 10.0
#: least share of the record the frozen run must cover
MIN_RUN_FRACTION = 0.25
#: least net OP move over the run, as a fraction of its travel
MIN_MONOTONE = 0.8
#: the confidence of a seized-valve finding: the data cannot tell it from a closed block valve
#: or a dead transmitter
CONFIDENCE = 0.5


@dataclass(frozen=True)
class Seized:
    """A seized valve found in a record: the frozen run (``start``, ``stop`` sample indices),
    the PV value it holds, the OP's travel over it (% of span, a lower bound on S) and a
    sentence with the figures."""

    start: int
    stop: int
    pv: float
    op_travel: float
    reason: str


#: a recorded position whose correlation with the OP over the run is at least this follows it
FOLLOWS_CORRELATION = 0.9


def _position_follows(data: LoopData, run: slice, op: np.ndarray) -> bool:
    """A recorded valve position (any span, offset or sense: air-to-close reads 100 - OP)
    that moves with the OP over the run (|correlation| at least
    :data:`FOLLOWS_CORRELATION`): that valve is not seized (a stuck transmitter over a moving
    valve was called seized, found by an engineer)."""
    if data.position is None:
        return False
    pos = np.asarray(data.position[run], dtype=np.float64)
    if not np.isfinite(pos).all() or np.ptp(pos) == 0.0 or np.ptp(op) == 0.0:
        return False
    return bool(abs(np.corrcoef(pos, op)[0, 1]) >= FOLLOWS_CORRELATION)  # either sense


def seized_valve(data: LoopData) -> Seized | None:
    """The seized valve in ``data`` by the module's rule, or None."""
    n = len(data)
    if n == 0:
        return None
    start, stop = longest_run_span(np.asarray(data.pv, dtype=np.float64))
    length = stop - start
    if length < MIN_RUN_FRACTION * n or length < 2:
        return None
    run = slice(start, stop)
    op = np.asarray(data.op[run], dtype=np.float64)
    sp = np.asarray(data.sp[run], dtype=np.float64)
    pv = float(data.pv[start])
    if not (np.isfinite(op).all() and np.isfinite(sp).all() and np.isfinite(pv)):
        return None
    if data.mode is not None and not np.all(np.asarray(data.mode[run]) == 1.0):
        return None
    travel = float(op.max() - op.min())
    net = abs(float(op[-1] - op[0]))
    error = sp - pv
    if travel < MIN_OP_TRAVEL or net < MIN_MONOTONE * travel:
        return None
    if not (np.all(error > 0.0) or np.all(error < 0.0)):
        return None
    if _position_follows(data, run, op):
        return None  # the valve moves: the PV's transmitter or a block valve, not stiction
    seconds = float(data.t[stop - 1] - data.t[start])
    way = "up" if op[-1] > op[0] else "down"
    reason = (f"the valve does not move: for {length} samples ({seconds:.0f} s, "
              f"{length / n:.0%} of the record) in automatic the OP walks {way} from "
              f"{op[0]:.3g} to {op[-1]:.3g} % (a travel of {travel:.3g} % of span) while the "
              f"PV holds {pv:.6g} and the error SP - PV keeps its sign: the controller winds up "
              f"against a valve that does not answer. A seized valve (stiction S above "
              f"{travel:.3g} %), or a closed block valve or a dead transmitter: check them in "
              f"the field")
    return Seized(start, stop, pv, travel, reason)
