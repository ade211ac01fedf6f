r"""Stiction measured on a recorded valve position (issue 15: "optional valve position").

A digital positioner reports the stem's travel; when the record has it, stiction need not be
inferred through the process: the valve's input (OP) and output (position) are both seen, and
the OP-position plot shows the stick band directly (Choudhury, Jain & Shah, *Stiction -
definition, modelling, detection and quantification*, J. Process Control 18 (2008) 232-243,
who read stiction off the OP-MV plot when the valve position is measured). A linear
valve's position follows the OP on a line; a sticky one stays put after each reversal
until the OP has moved S, then jumps J.

The measurement fits loopworks' own ``valve.choudhury`` block (plant-and-tuning 1.2) driven by
the recorded OP to the recorded position::

    position_k ≈ α·x_k(S, J) + β,   x = valve.choudhury(S, J) over the OP

α and β by linear least squares (a position reported in another span or with an offset), S
and J by the grid and pattern search of the joint fit
(:func:`loopworks.analysis.valve_fit.search_sj`). R² = 1 − SSE/SST of the position;
``r2_linear`` is the same with S = J = 0 (α·OP + β, a linear valve).

Both valves may sit behind a first-order positioner lag of τ ≥ 0, fitted with them (the
best of :data:`LAG_TAUS` record periods, for each S and J)::

    l_k = l_{k-1} + (1 − e^{−Δ/τ})·(x_k − l_{k-1}),   position_k ≈ α·l_k + β

A slow positioner's lag shows a healthy valve's position behind the OP on every reversal, as
a dead band would, and against an unlagged linear valve was read as stiction (a 10 s lag at
a 5 s record: S 0.3-0.5 %); a sticky valve's band still explains what the lag leaves.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from loopworks.analysis.loopdata import LoopData, hold_last
from loopworks.analysis.valve_fit import (
    MIN_OP_RANGE,
    MIN_SAMPLES,
    MIN_SWINGS,
    count_swings,
    search_sj,
    valve_position,
)

FloatArray = npt.NDArray[np.float64]

#: the fitted valve must explain at least this share of the position variance [ours: a
#: positioner's travel feedback is a direct measurement; a fit below this is of a position
#: that is not this OP's valve (another loop's, a mis-mapped column)]
MIN_R2 = 0.25
#: ... and at least this share of its moves must go toward the OP (:func:`_toward`) [ours: a
#: valve, sticky or not, moves toward its input, but a historian's sample sees the OP up to
#: a period after the move (0.75-1.0, median 0.998, on the simulated set's 120 sticky valves,
#: docs/diagnose.md); an unrelated signal does half the time (0.52-0.54 for random walks)]
MIN_TOWARD = 0.65
#: the positioner lags τ tried behind either valve, in record periods Δ (0: none) [ours: a
#: slow positioner's 10-20 s at historian periods of 1-10 s; shorter lags also fit the
#: sampled travel of sticky valves (docs/diagnose.md: from a quarter period, sensitivity
#: 0.75 on the simulated set, against 0.79 from two periods)]
LAG_TAUS = (0.0, 2.0, 4.0, 8.0, 16.0)


def lagged(op: FloatArray, tau: float) -> FloatArray:
    """``op`` through a first-order lag of ``tau`` record periods (module docstring), from
    rest at its first value; ``op`` itself for tau = 0."""
    if tau <= 0.0:
        return op
    from scipy.signal import lfilter

    a = 1.0 - math.exp(-1.0 / tau)  # l_k = (1 - a)·l_{k-1} + a·OP_k, l_{-1} = OP_0
    out, _ = lfilter([a], [1.0, a - 1.0], op, zi=[(1.0 - a) * float(op[0])])
    return np.asarray(out, dtype=np.float64)


@dataclass(frozen=True)
class TravelFit:
    """S and J (% of OP) measured on the recorded position (module docstring): ``r2`` of the
    position, ``r2_linear`` for a linear valve, ``ok`` False (S, J NaN) when the record does
    not support a measurement, ``reason`` why or a summary."""

    s: float
    j: float
    r2: float
    r2_linear: float
    ok: bool
    reason: str


def _sse(x: FloatArray, pos: FloatArray) -> float:
    """SSE of pos ≈ α·x + β, α and β by least squares."""
    xc, pc = x - x.mean(), pos - pos.mean()
    xx = float(xc @ xc)
    if xx <= 0.0:
        return float(pc @ pc)
    return max(float(pc @ pc) - float(xc @ pc) ** 2 / xx, 0.0)


def _toward(op: FloatArray, x: FloatArray, pos: FloatArray) -> float:
    """The share of the recorded position's moves that go toward the OP: the position taken
    to OP units through the fitted valve (pos ≈ α·x + β, x the model's stem, α and β by least
    squares: x_rec = (pos − β)/α), a move is a change larger than the median absolute change
    (noise and creep left out), and it goes toward the OP when its sign is that of
    OP_k − x_rec,k−1, as every move of a valve (sticky or not) does. NaN when α ≤ 0 or
    nothing moves."""
    xc, pc = x - x.mean(), pos - pos.mean()
    xx = float(xc @ xc)
    alpha = float(xc @ pc) / xx if xx > 0.0 else 0.0
    if not alpha > 0.0:
        return math.nan
    rec = (pos - (pos.mean() - alpha * x.mean())) / alpha
    step = np.diff(rec)
    gap = op[1:] - rec[:-1]
    moves = np.abs(step) > np.median(np.abs(step))
    if not moves.any():
        return math.nan
    return float(np.mean(np.sign(step[moves]) == np.sign(gap[moves])))


def fit_travel(data: LoopData) -> TravelFit | None:
    """Measure S and J on ``data.position`` (module docstring); None when the record has no
    position column. Samples where OP or position is not finite are left out of the fit (the
    valve model runs over the OP held at its last finite value)."""
    if data.position is None:
        return None
    op = np.asarray(data.op, dtype=np.float64)
    pos = np.asarray(data.position, dtype=np.float64)
    use = np.isfinite(op) & np.isfinite(pos)
    nan = math.nan
    if int(use.sum()) < MIN_SAMPLES:
        return TravelFit(nan, nan, nan, nan, False, f"{int(use.sum())} samples with a finite "
                         f"OP and position: at least {MIN_SAMPLES} are needed.")
    op_held = hold_last(op)  # a Bad OP held at its last finite value
    op_range = float(op[use].max() - op[use].min())
    if op_range < MIN_OP_RANGE:
        return TravelFit(nan, nan, nan, nan, False, f"OP moves over {op_range:.3g} % only: a "
                         "valve that is not driven shows no stiction to measure.")
    swings = count_swings(op[use], op_range / 4.0)
    if swings < MIN_SWINGS:
        return TravelFit(nan, nan, nan, nan, False, f"OP changes direction {swings} times by a "
                         f"quarter of its range: at least {MIN_SWINGS} are needed.")
    p = pos[use]
    sst = float(((p - p.mean()) ** 2).sum())
    if not sst > 0.0:
        return TravelFit(nan, nan, nan, nan, False, "the valve position never moves while the "
                         "OP does (a seized valve, or a position that is not this valve's).")

    def cost(s: float, j: float) -> float:  # behind the best positioner lag
        x = valve_position(op_held, s, j)
        return min(_sse(lagged(x, tau)[use], p) for tau in LAG_TAUS)

    r2_lin = 1.0 - cost(0.0, 0.0) / sst
    s, j = search_sj(cost, op_range)
    r2 = 1.0 - cost(s, j) / sst
    toward = _toward(op[use], valve_position(op_held, s, j)[use], p)
    if math.isnan(toward):
        return TravelFit(nan, nan, r2, r2_lin, False, "the position moves against the fitted "
                         "valve, or not at all: is it this OP's valve?")
    if toward < MIN_TOWARD:
        return TravelFit(nan, nan, r2, r2_lin, False, f"{toward:.0%} of the position's moves "
                         f"go toward the OP, below {MIN_TOWARD:.0%}: is it this OP's valve?")
    if r2 < MIN_R2:
        return TravelFit(nan, nan, r2, r2_lin, False, f"the valve model explains R² = {r2:.2f} "
                         f"of the recorded position, below {MIN_R2:g}: is it this OP's valve?")
    return TravelFit(s, j, r2, r2_lin, True, f"on the recorded position: S = {s:.3g} %, J = "
                     f"{j:.3g} % (deadband {s - j:.3g} %, resolution {j:.3g} %); R² "
                     f"{r2:.3f} of the position against {r2_lin:.3f} for a linear valve "
                     "(each behind its best positioner lag).")


def model_position(data: LoopData, fit: TravelFit) -> FloatArray:
    """The position the fitted valve gives for the recorded OP, in the position's units
    (α·x(S, J) + β, module docstring); NaN where OP or position is not finite, or everywhere
    when ``fit.ok`` is False or the record has no position."""
    out = np.full(len(data), math.nan)
    if data.position is None or not fit.ok:
        return out
    op = np.asarray(data.op, dtype=np.float64)
    pos = np.asarray(data.position, dtype=np.float64)
    use = np.isfinite(op) & np.isfinite(pos)
    full = valve_position(hold_last(op), fit.s, fit.j)
    x = min((lagged(full, tau)[use] for tau in LAG_TAUS),
            key=lambda xs: _sse(xs, pos[use]))  # behind its best positioner lag
    A = np.column_stack([x, np.ones(len(x))])
    theta, *_ = np.linalg.lstsq(A, pos[use], rcond=None)
    out[use] = A @ theta
    return out
