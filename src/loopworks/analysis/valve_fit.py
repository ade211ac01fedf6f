r"""How sticky is the valve: S and J of the Choudhury model fitted to a loop's record, with
the process identified jointly (issue 15, point 4), and the PI controller identified from the
same record.

Model (a Hammerstein system, the structure of Jelali 2008 and Choudhury et al. 2008)::

    OP ──► valve.choudhury (S, J) ──► x ──► process ──► PV (+ offset)

* The valve is loopworks' own ``valve.choudhury`` block (plant-and-tuning 1.2; Choudhury,
  Thornhill & Shah, *Modelling valve stiction*, Control Eng. Practice 13 (2005) 641-658),
  run over the recorded OP by its compiled kernel (:func:`loopworks.blocks.kernel.run_rows`),
  started at rest at the first OP: no second copy of its equations lives here.
* The process is identified in discrete time with a dead time of d samples:

  - self-regulating (FOPDT):   y_k = a·y_{k-1} + b·x_{k-d} + c,
  - integrating:               y_k - y_{k-1} = b·x_{k-d} + c.

  A FOPDT K·e^{-Ls}/(Ts + 1) under a zero-order hold with L = m·dt gives a = e^{-dt/T},
  b = K·(1 - a) and d = m + 1 (one sample of the hold): the gain is K = b/(1 - a), the time
  constant T = -dt/ln a and the dead time L = (d - 1)·dt. An integrating process
  dy/dt = K·u(t - L) gives b = K·dt, so K = b/dt (PV units per % per second).

Cost. The fit minimises the *output error* (simulation error): the PV the identified process
produces when driven by the valve position alone, from its own past outputs, never from the
measured PV. A one-step-ahead (equation-error, ARX) fit regresses on the noisy measured PV and
is biased by noise (Ljung, *System Identification*, 2nd ed. 1999, sec. 7.3); the output error is
not. For fixed (S, J, d, a) the simulated PV is linear in the remaining parameters::

    ŷ_k = b·r_k + c' + e0·p_k,   r = x filtered by 1/(1 - a·q⁻¹) and delayed d samples,
                                 p_k = a^k (self-regulating) or k (integrating, a = 1)

(e0·p_k carries the unknown initial state, the constant c' the offset and the filtered c), so
the problem is *separable* (Golub & Pereyra 1973): b, c', e0 come from linear least squares
and only (S, J, d, a) are searched. This is the separable least-squares and global-search
method of Jelali, *Estimation of valve stiction in control loops using separable
least-squares and global search algorithms*, J. Process Control 18 (2008) 632-642, with a
grid and pattern search in place of his genetic algorithm and with the output error as the
cost: d is searched over every sample 0..``max_dead_time`` for every a, a on a logarithmic
grid of time constants refined by a bounded scalar search; (S, J) on a coarse grid over
0 ≤ J ≤ S ≤ 1.25·(OP peak-to-peak), refined by a compass (pattern) search that halves its
step (Hooke & Jeeves 1961) down to :data:`S_STEP_FLOOR` of the OP range.

Level loops. A level integrates its load, and in closed loop the valve answers that load, so
the output error of a level is biased by it (closed-loop identification: the valve position
is correlated with the disturbance). An integrating loop's record (both PV and valve
position, after the high-pass) is first whitened by (1 - q⁻¹)/(1 - c·q⁻¹), c from the
linear fit's residual (:func:`_level_whitening`), and its increments are fitted with a dead
time between two samples (two taps), the prediction-error method with the noise model of a
walking level under white noise (Ljung 1999, sec. 7.2 and 13.4); when the noise dominates
(c > :data:`MAX_WHITENING`) or that fit explains too little (:data:`MIN_R2_INTEGRATING`),
the level itself is fitted as above.

Fit quality: R² = 1 - SSE/SST of the PV (SST about its mean). ``r2_linear`` is the same fit
with S = J = 0 (a linear valve): the gain r2 - r2_linear says how much the valve nonlinearity
explains. Practitioner terms (plant-and-tuning 1.7): resolution (stick-slip) = J, deadband
(backlash) = S - J.

The controller (:func:`fit_controller`) is identified from the velocity form of the PI law
(Åström & Hägglund, *Advanced PID Control*, ISA 2006, sec. 3.4; backward-Euler integral as in
loopworks' ``pid``)::

    ΔOP_k = Kc·(Δe_k + (dt/Ti)·e_k),   e = SP - PV (reverse acting)

by linear least squares in θ1 = Kc, θ2 = Kc·dt/Ti. A negative Kc means direct action
(e = PV - SP). A derivative term is not modelled: a PID's D action (and its filter) appears as
misfit and lowers R².
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.optimize import minimize_scalar
from scipy.signal import lfilter

from loopworks.analysis import LOOP_TYPES as _LOOP_TYPES
from loopworks.analysis.loopdata import LoopData
from loopworks.sim.arrays import compiled_arg

FloatArray = npt.NDArray[np.float64]

#: the high-pass window (:func:`_high_pass`) as a fraction of the record, and its least
#: number of samples [ours: 5 % of a 2000-sample record is 100 samples, several times a
#: stiction cycle and shorter than a slow load's drift]
HP_FRACTION = 0.05
HP_MIN_SAMPLES = 25
#: Below this output-error R² of the best fit the record does not support an estimate [ours:
#: on the simulated set (docs/diagnose.md) the sticky flow loops whose stiction the fit finds
#: explain 0.40-0.97 of the PV; 0.5, the first choice, refused three of them, and no clean loop
#: whose fit explains more than 0.35 gains from stiction].
MIN_R2 = 0.35
#: The same for an integrating loop whose fit is of the PV's whitened increments (module
#: docstring, "Level loops"): with c = 0 the record and the valve position are differenced,
#: y_k - y_{k-1} = b·x_{k-d} (the level's flow balance), which whitens the load, a slow walk
#: that the process integrates: the prediction-error method with the noise model
#: (1 - c·q⁻¹)/(1 - q⁻¹) (Ljung 1999, sec. 7.2 and 13.4: consistent in closed loop when the
#: noise model is right, where an output-error fit is biased by the load the controller
#: answers). Increments are
#: noisier than levels, so less of their variance is explained [ours: on the simulated set
#: (docs/diagnose.md) the sticky level loops whose stiction the fit finds explain 0.2-0.95].
MIN_R2_INTEGRATING = 0.2
#: The largest c of the integrating loop's whitening prefilter (:func:`_level_whitening`);
#: above it the measurement noise dominates the PV's increments, the load walks little from
#: one sample to the next, and the level itself is fitted (high-passed, one tap, at least
#: :data:`MIN_R2`), as for a fast-scanned level loop [ours: with c = 0.81, a level loop
#: sampled at 0.5 s (tests/analysis/test_valve_fit.py) gets its process gain twice too high
#: from the whitened fit and right from the level; at a historian's 5 s most of the simulated
#: set's level loops have c < 0.5]
MAX_WHITENING = 0.5
#: Fewest samples of a usable record (the longest run where OP and PV are finite) [ours].
MIN_SAMPLES = 50
#: Fewest OP swings (direction changes by at least a quarter of the OP range) [ours: the valve
#: must be seen to move both ways at least twice before S, which is about reversals, can be
#: estimated].
MIN_SWINGS = 2
#: Smallest OP range, % of span, that counts as the OP moving at all [ours].
MIN_OP_RANGE = 0.05
#: Upper end of the S grid, as a multiple of the OP peak-to-peak [ours: a valve with S above
#: the OP range never reverses, so larger values all fit alike].
S_RANGE_FACTOR = 1.25
#: Coarse grid: S values (0 included) and J/S fractions.
S_GRID = 13
J_FRACTIONS = (0.0, 1.0 / 6.0, 1.0 / 3.0, 0.5, 2.0 / 3.0, 5.0 / 6.0, 1.0)
#: The pattern search stops when its step is below this fraction of the OP peak-to-peak.
S_STEP_FLOOR = 0.005
#: Time constants of the a-grid, as (smallest, largest) multiples of (dt, record length).
T_GRID = 12
#: Default largest dead time searched, as a fraction of the record (capped by MAX_DEAD_SAMPLES).
DEAD_FRACTION = 0.1
MAX_DEAD_SAMPLES = 200
#: Increment span m, samples, of the integrating search cost (:func:`_fit_increments`) [ours:
#: long enough to average PV noise, short against a limit cycle].
INCREMENT_SAMPLES = 10
#: Most rounds of the (a, d) coordinate descent that refines the process.
D_ROUNDS = 6
#: Below this R² the controller identification is not trusted [ours].
MIN_CONTROLLER_R2 = 0.5
#: Fewest usable samples (automatic, unsaturated) for the controller fit [ours].
MIN_CONTROLLER_SAMPLES = 20


@dataclass(frozen=True)
class ValveFit:
    """The fitted stiction of one loop's valve (module docstring).

    ``s`` and ``j`` are Choudhury's S and J, % of valve span; ``resolution`` = J and
    ``deadband`` = S - J (plant-and-tuning 1.7). ``process``: ``model`` ("fopdt" or
    "integrating"), ``gain`` (PV per % of valve; per % per second when integrating),
    ``time_constant_s`` (None when integrating), ``dead_time_s``. ``r2``: output-error R² of
    the PV; ``r2_linear``: the same with S = J = 0. ``ok`` is False, and S, J NaN, when the
    record does not support an estimate; ``reason`` says why or summarises the fit."""

    s: float
    j: float
    resolution: float
    deadband: float
    process: dict[str, Any]
    r2: float
    r2_linear: float
    reason: str
    ok: bool
    #: c of an integrating loop's whitening prefilter (:func:`_level_whitening`) when its
    #: increments were fitted (``r2`` is then of the whitened increments), else NaN
    whitening: float = math.nan


@dataclass(frozen=True)
class ControllerFit:
    """The PI controller identified from a record: ``kc`` (> 0, %OP per PV unit), ``ti_s``
    (inf when no integral action is found), ``action`` ("reverse": e = SP - PV, or
    "direct"), ``r2`` of ΔOP, ``ok`` and ``reason``."""

    kc: float
    ti_s: float
    r2: float
    ok: bool
    reason: str
    action: str = "reverse"


@dataclass(frozen=True)
class _Process:
    """The best process for one valve output: output-error SSE, a, b, d (samples) and the
    extra lag of a two-tap fit (a fraction of a sample, :func:`_sse_all_d`)."""

    sse: float
    a: float
    b: float
    d: int
    lag: float = 0.0


# ----------------------------------------------------------------------------- valve

def valve_position(op: FloatArray, s: float, j: float) -> FloatArray:
    """The stem position of loopworks' ``valve.choudhury`` block with these S, J (%) driven by
    ``op`` (one value per scan), started at rest at the first OP (its ``y0``): the block's own
    compiled kernel run over the rows (:func:`loopworks.blocks.kernel.run_rows`). The model is
    rate-independent (spec 1.2), so the scan time does not matter; 1 s is passed."""
    from loopworks import create_block
    from loopworks.blocks.kernel import run_rows

    block = create_block("valve.choudhury", s=float(s), j=float(j),
                         y0=float(min(max(op[0], 0.0), 100.0)))
    n = len(op)
    names = [p.name for p in block.OUTPUTS]
    U = np.ascontiguousarray(np.asarray(op, dtype=np.float64).reshape(n, 1))
    US = np.full((n, 1), 128, dtype=np.int64)  # Good
    Y = np.empty((n, len(names)))
    YS = np.empty((n, len(names)), dtype=np.int64)
    Y[0] = block.y
    YS[0] = block.ys
    run_rows(type(block).kernel, np.ones(n), block.p, block.x, U, US, Y, YS)
    return Y[:, names.index("position")].copy()



def search_sj(cost: Callable[[float, float], float], op_range: float) -> tuple[float, float]:
    """The (S, J) that minimise ``cost(S, J)``: a coarse grid over 0 ≤ J ≤ S ≤
    :data:`S_RANGE_FACTOR`·``op_range`` (:data:`S_GRID` values of S, :data:`J_FRACTIONS` of
    each), then a compass (pattern) search from the grid's best over its 8 neighbours at step
    h, moving to the best and halving h when none is better, down to :data:`S_STEP_FLOOR`·
    ``op_range`` (Hooke & Jeeves 1961). (0, 0), the linear valve, is a candidate."""
    s_hi = S_RANGE_FACTOR * op_range
    best_sj, best = (0.0, 0.0), cost(0.0, 0.0)
    for s in np.linspace(0.0, s_hi, S_GRID)[1:]:
        for f in J_FRACTIONS:
            c = cost(float(s), float(f * s))
            if c < best:
                best_sj, best = (float(s), float(f * s)), c
    h = s_hi / (S_GRID - 1)
    while h >= S_STEP_FLOOR * op_range:
        moved = False
        s0, j0 = best_sj
        for ds, dj in ((1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (-1, -1), (1, -1), (-1, 1)):
            s, j = s0 + ds * h, j0 + dj * h
            if s < 0.0 or j < 0.0 or j > s or s > 2.0 * s_hi:
                continue
            c = cost(s, j)
            if c < best:
                best_sj, best, moved = (s, j), c, True
        if not moved:
            h /= 2.0
    return best_sj


# ----------------------------------------------------------------------------- process

def _high_pass(x: FloatArray, width: int) -> FloatArray:
    """x minus its centred moving average over ``width`` samples (ends held): the slow part
    of the record (a load that drifts, the OP that follows it) taken out of both the PV and
    the valve position before the process is fitted. The filter is linear and time
    invariant, so it commutes with the process: HP(PV) = G·HP(x) + HP(load), and HP(load)
    is small for a load slower than the window [ours]."""
    from scipy.ndimage import uniform_filter1d

    return np.asarray(x - uniform_filter1d(np.asarray(x, dtype=np.float64), width,
                                           mode="nearest"), dtype=np.float64)



def _x_corr_y(x: FloatArray, y: FloatArray, dmax: int, taps: int = 1) -> FloatArray:
    """X(s) = Σ_i xp[s + i]·y[i], s = 0..pad, pad = dmax + taps - 1, where xp is x with pad
    copies of x[0] before it (the valve at rest before the record): what :func:`_sse_all_d`
    needs from x and y at every a (so a caller fitting many a computes it once)."""
    xp = np.concatenate([np.full(dmax + taps - 1, x[0]), x])
    return np.asarray(np.correlate(xp, y, "valid"), dtype=np.float64)


def _sse_all_d(x: FloatArray, y: FloatArray, a: float, dmax: int, yy: float,
               only: int | None = None, taps: int = 1,
               xy: FloatArray | None = None) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Output-error SSE, gain b and extra lag of ŷ = b₀·r_d (+ b₁·r_{d+1}) + c' + e0·p for every
    dead time d = 0..dmax (or the one d ``only``) at this a (a = 1: integrating). x is centred;
    ``yy`` = y·y; ``xy`` is :func:`_x_corr_y` of x and y, when the caller has it. ``taps`` = 2
    adds the second delayed regressor r_{d+1}: a dead time between d and d + 1 samples (a
    fractional delay under the zero-order hold: Åström & Wittenmark, *Computer-Controlled
    Systems*, 3rd ed. 1997, sec. 2.3), the gain is b = b₀ + b₁ and the extra lag b₁/b (a
    fraction of a sample); with one tap the lag is 0. The arithmetic is :func:`_regress`,
    compiled unless ``LOOPWORKS_JIT=0``."""
    count = dmax + 1 if only is None else 1
    sse, b, lag = np.empty(count), np.empty(count), np.empty(count)
    if only is None and xy is None:
        xy = _x_corr_y(x, y, dmax, taps)
    _regress_fn()(compiled_arg(x), compiled_arg(y), float(a), int(dmax), float(yy),
                  -1 if only is None else int(only), int(taps),
                  np.zeros(1) if xy is None else compiled_arg(xy), sse, b, lag)
    return sse, b, lag


def _regress(x: FloatArray, y: FloatArray, a: float, dmax: int, yy: float, only: int,
             taps: int, xy: FloatArray, sse: FloatArray, b: FloatArray,
             lag: FloatArray) -> None:
    """:func:`_sse_all_d` into ``sse``, ``b``, ``lag`` (one entry per d; ``only`` = -1: every
    d = 0..dmax, else that d; ``xy``: X of :func:`_x_corr_y`, read only for every d).

    The regressors r_k (k = 0..pad, pad = dmax + taps - 1) are f[pad - k : pad - k + n] with
    f_j = a·f_{j-1} + xp_j (xp: x at rest before the record; a = 1 a running sum, a = 0 xp
    itself), and p_i = a^i (i when a = 1, the impulse at 0 when a = 0), the initial state's
    free response. Per d the normal equations G·θ = h of the columns (the taps, a constant,
    p) need Σr_k, Σr_k², Σr_k·p, Σr_k·y and, with two taps, Σr_d·r_{d+1}: the first two and
    the last as differences of running sums; in shift s = pad - k, Σr·y and Σr·p follow
    f's own recursion, R(s) = a·R(s - 1) + Σ_i xp_{s+i}·q_i (R(0) by its dot product), and
    for p = a^i the drive Q(s) = Σ_i xp_{s+i}·a^i runs backwards, Q(s) = xp_s + a·Q(s + 1) -
    a^n·xp_{s+n} [ours]. G is scaled to a unit diagonal with a 1e-10 ridge (so a constant r
    or p is harmless), solved by Gaussian elimination with partial pivoting; SSE = y·y - θ·h.
    """
    n = len(y)
    pad = dmax + taps - 1
    big = n + pad
    f = np.empty(big)
    c1 = np.zeros(big + 1)
    c2 = np.zeros(big + 1)
    cg = np.zeros(big)  # cg[j] = Σ_{i<j} f[i + 1]·f[i]
    prev = 0.0
    for j in range(big):
        v = x[0] if j < pad else x[j - pad]
        prev = a * prev + v
        f[j] = prev
        c1[j + 1] = c1[j] + prev
        c2[j + 1] = c2[j] + prev * prev
        if j > 0:
            cg[j] = cg[j - 1] + prev * f[j - 1]
    p = np.empty(n)
    power = 1.0
    for i in range(n):
        p[i] = float(i) if a == 1.0 else power
        power *= a  # a = 0: the impulse
    sp, pp, sy, py = 0.0, 0.0, 0.0, 0.0
    for i in range(n):
        sp += p[i]
        pp += p[i] * p[i]
        sy += y[i]
        py += p[i] * y[i]
    ry = np.zeros(pad + 1)  # by k
    rp = np.zeros(pad + 1)
    if only >= 0:
        for k in range(only, only + taps):
            s = pad - k
            acc_y, acc_p = 0.0, 0.0
            for i in range(n):
                acc_y += f[s + i] * y[i]
                acc_p += f[s + i] * p[i]
            ry[k], rp[k] = acc_y, acc_p
    else:
        r_y, r_p = 0.0, 0.0
        for i in range(n):
            r_y += f[i] * y[i]
        if a == 1.0:
            for s in range(pad + 1):
                acc = 0.0
                for i in range(n):
                    acc += f[s + i] * p[i]
                rp[pad - s] = acc
        elif a == 0.0:
            for s in range(pad + 1):
                rp[pad - s] = f[s]
        else:
            q = np.empty(pad + 1)
            acc = 0.0
            for i in range(n):
                acc += x[i] * p[i]  # xp[pad + i] = x[i]
            q[pad] = acc
            an = power  # a^n
            for s in range(pad - 1, -1, -1):
                xs = x[0] if s < pad else x[s - pad]
                xsn = x[0] if s + n < pad else x[s + n - pad]
                q[s] = xs + a * q[s + 1] - an * xsn
            for i in range(n):
                r_p += f[i] * p[i]
            rp[pad] = r_p
            for s in range(1, pad + 1):
                r_p = a * r_p + q[s]
                rp[pad - s] = r_p
        ry[pad] = r_y
        for s in range(1, pad + 1):
            r_y = a * r_y + xy[s]
            ry[pad - s] = r_y
    m = taps + 2
    G = np.empty((m, m))
    h = np.empty(m)
    sc = np.empty(m)
    count = len(sse)
    for idx in range(count):
        d = idx if only < 0 else only
        G[:, :] = 0.0
        for t in range(taps):
            k = d + t
            s = pad - k
            G[t, t] = c2[s + n] - c2[s]
            G[t, taps] = G[taps, t] = c1[s + n] - c1[s]
            G[t, taps + 1] = G[taps + 1, t] = rp[k]
            h[t] = ry[k]
        if taps == 2:
            start = pad - d - 1  # r_d·r_{d+1} = Σ_i f[start + 1 + i]·f[start + i]
            G[0, 1] = G[1, 0] = cg[start + n] - cg[start]
        G[taps, taps] = n
        G[taps, taps + 1] = G[taps + 1, taps] = sp
        G[taps + 1, taps + 1] = pp
        h[taps] = sy
        h[taps + 1] = py
        for i in range(m):
            sc[i] = 1.0 / math.sqrt(max(G[i, i], 1e-300))
        A = np.empty((m, m + 1))
        for i in range(m):
            for j in range(m):
                A[i, j] = G[i, j] * sc[i] * sc[j] + (1e-10 if i == j else 0.0)
            A[i, m] = h[i] * sc[i]
        for col in range(m):  # Gaussian elimination, partial pivoting
            piv = col
            for r in range(col + 1, m):
                if abs(A[r, col]) > abs(A[piv, col]):
                    piv = r
            if piv != col:
                for j in range(m + 1):
                    A[col, j], A[piv, j] = A[piv, j], A[col, j]
            for r in range(col + 1, m):
                factor = A[r, col] / A[col, col]
                for j in range(col, m + 1):
                    A[r, j] -= factor * A[col, j]
        theta = np.empty(m)
        for i in range(m - 1, -1, -1):
            acc = A[i, m]
            for j in range(i + 1, m):
                acc -= A[i, j] * theta[j]
            theta[i] = acc / A[i, i]
        fit = 0.0
        for i in range(m):
            theta[i] *= sc[i]
            fit += theta[i] * h[i]
        sse[idx] = max(yy - fit, 0.0)
        gain = 0.0
        for t in range(taps):
            gain += theta[t]
        b[idx] = gain
        lag[idx] = theta[1] / (gain if gain != 0.0 else 1.0) if taps == 2 else 0.0


@functools.cache
def _regress_fn() -> Callable[..., None]:
    """:func:`_regress`, compiled (cached on disk) unless ``LOOPWORKS_JIT=0``."""
    from loopworks.blocks.kernel import jit_enabled

    if not jit_enabled():
        return _regress
    import numba

    return numba.njit(cache=True, nogil=True)(_regress)


def _admissible(sse: FloatArray, b: FloatArray, sign: float) -> FloatArray:
    """``sse`` with the physically impossible fits ruled out (inf): d = 0 (no sample of delay:
    under a zero-order hold a process answers one sample late at the earliest, and in a closed
    loop a d = 0 fit finds the controller's own PV → OP relation, inverted), and a gain of the
    wrong sign (``sign`` +1 for a reverse-acting controller's process, −1 for a direct-acting
    one's, 0: either) [ours]."""
    out = np.array(sse, dtype=np.float64)
    out[0] = math.inf
    if sign != 0.0:
        out[sign * np.asarray(b) <= 0.0] = math.inf
    return out


def _fit_process(x: FloatArray, y: FloatArray, integrating: bool, dmax: int,
                 sign: float = 0.0, taps: int = 1) -> _Process:
    """The output-error best process for valve position ``x`` (module docstring): every d,
    a on a log grid of time constants, then a bounded scalar search of ln T at the best d
    (``taps``: :func:`_sse_all_d`)."""
    xc = x - x.mean()
    yy = float(y @ y)
    xy = _x_corr_y(xc, y, dmax, taps)
    if integrating:
        sse, b, lag = _sse_all_d(xc, y, 1.0, dmax, yy, taps=taps, xy=xy)
        sse = _admissible(sse, b, sign)
        d = int(np.argmin(sse))
        return _Process(float(sse[d]), 1.0, float(b[d]), d, float(lag[d]))
    n = len(y)
    taus = np.geomspace(0.25, float(n), T_GRID)  # in samples
    best = _Process(math.inf, 0.0, 0.0, 0)
    best_i = -1
    for i, a in enumerate([0.0, *np.exp(-1.0 / taus)]):
        sse, b, lag = _sse_all_d(xc, y, float(a), dmax, yy, taps=taps, xy=xy)
        sse = _admissible(sse, b, sign)
        d = int(np.argmin(sse))
        if sse[d] < best.sse:
            best, best_i = _Process(float(sse[d]), float(a), float(b[d]), d, float(lag[d])), i
    # a and d trade against each other along a valley: coordinate descent from the grid's
    # best, ln T refined at the current d (bounded, between the grid's second neighbours of the
    # best a), then every d at that a, until d stays
    lt = np.log(taus)
    lo = lt[0] - 2.0 if best_i <= 2 else lt[best_i - 3]
    hi = lt[-1] + 1.0 if best_i >= len(taus) - 1 else lt[best_i + 1]

    def cost(log_tau: float, d: int) -> float:
        s, _, _ = _sse_all_d(xc, y, math.exp(-math.exp(-log_tau)), dmax, yy, only=d,
                             taps=taps)
        return float(s[0])

    for _ in range(D_ROUNDS):
        res = minimize_scalar(cost, bounds=(lo, hi), args=(best.d,), method="bounded",
                              options={"xatol": 0.005})
        a = math.exp(-math.exp(-float(res.x)))
        sse, b, lag = _sse_all_d(xc, y, a, dmax, yy, taps=taps, xy=xy)
        sse = _admissible(sse, b, sign)
        d = int(np.argmin(sse))
        if not sse[d] < best.sse:
            break
        moved = d != best.d
        best = _Process(float(sse[d]), a, float(b[d]), d, float(lag[d]))
        if not moved:
            break
    return best


def _fit_increments(x: FloatArray, y: FloatArray, m: int, dmax: int,
                    sign: float = 0.0) -> _Process:
    """The search cost of an integrating loop: least squares of the m-sample PV increments,

        y_k - y_{k-m} = b·(x_{k-d} + ... + x_{k-d-m+1}) + c·m,

    for every d. Its regressors are valve positions only (no measured PV), so, like the output
    error, it is not biased by PV noise; unlike the output error of an integrator, a valve
    mismatch costs where it happens and does not accumulate into a drift, which leaves the
    cost over (S, J) smooth enough to search (an output-error map of a level loop is a needle
    at the true S, J surrounded by plateaus) [ours]."""
    xc = x - x.mean()
    n = len(y)
    c = np.concatenate([[0.0], np.cumsum(np.concatenate([np.full(dmax + m, xc[0]), xc]))])
    f = (c[m:] - c[:-m])[1 + m:]  # f[dmax - d + i] = x_{i+m-d} + ... + x_{i+1-d}
    z = y[m:] - y[:-m]
    nz = n - m
    c1 = np.concatenate([[0.0], np.cumsum(f)])
    c2 = np.concatenate([[0.0], np.cumsum(f * f)])
    r1 = (c1[nz:] - c1[:-nz])[::-1][:dmax + 1]
    rr = (c2[nz:] - c2[:-nz])[::-1][:dmax + 1]
    rz = np.correlate(f, z, "valid")[::-1][:dmax + 1]
    zc = z - z.mean()
    var_r = rr - r1 * r1 / nz
    moves = var_r > 1e-12 * max(float(rr.max()), 1e-300)  # a valve that never moves explains
    var_r = np.where(moves, var_r, 1.0)                    # nothing (b = 0)
    cov = np.where(moves, rz - r1 * z.sum() / nz, 0.0)
    sse = np.maximum(zc @ zc - cov * cov / var_r, 0.0)
    sse = _admissible(sse, cov / var_r, sign)
    d = int(np.argmin(sse))
    return _Process(float(sse[d]), 1.0, float(cov[d] / var_r[d]), d)


def _level_whitening(x: FloatArray, y: FloatArray, dmax: int, sign: float) -> float:
    """The c of the prefilter (1 - q⁻¹)/(1 - c·q⁻¹) that whitens what an integrating loop's
    linear-valve fit leaves unexplained (``x``, ``y``: the high-passed OP and PV). That
    residual is modelled as a level that walks (the load, integrated by the process) plus
    white measurement noise, the local-level model, whose increments are the MA(1) process
    e_k - c·e_{k-1} with lag-1 autocorrelation ρ = -c/(1 + c²) (Harvey, *Forecasting,
    Structural Time Series Models and the Kalman Filter*, 1989, sec. 2.3.2), so
    c = (-1 + √(1 - 4ρ²))/(2ρ) from the residual increments' ρ ∈ [-0.5, 0]: c = 0 (a plain
    difference) when the walk dominates, as it does at a historian's period; c → 1 (little
    filtering) when the noise does, as at a fast scan (:data:`MAX_WHITENING`)."""
    proc = _fit_process(x, y, True, dmax, sign)
    xc = x - x.mean()
    n = len(y)
    xp = np.concatenate([np.full(proc.d, xc[0]), xc])[:n]
    A = np.column_stack([np.cumsum(xp), np.ones(n), np.arange(n, dtype=np.float64)])
    theta, *_ = np.linalg.lstsq(A, y, rcond=None)
    dr = np.diff(y - A @ theta)
    dr = dr - dr.mean()
    denom = float(dr @ dr)
    rho = float(dr[1:] @ dr[:-1]) / denom if denom > 0.0 else 0.0
    rho = min(max(rho, -0.5), 0.0)
    if rho == 0.0:
        return 0.0
    c = (-1.0 + math.sqrt(max(1.0 - 4.0 * rho * rho, 0.0))) / (2.0 * rho)
    return float(min(max(c, 0.0), 1.0))


def _process_dict(proc: _Process | None, integrating: bool, dt: float) -> dict[str, Any]:
    """The identified process in physical units (module docstring)."""
    model = "integrating" if integrating else "fopdt"
    if proc is None:
        return {"model": model, "gain": math.nan,
                "time_constant_s": None if integrating else math.nan,
                "dead_time_s": math.nan}
    dead = max(proc.d - 1 + min(max(proc.lag, 0.0), 1.0), 0.0) * dt
    if integrating:
        return {"model": model, "gain": proc.b / dt, "time_constant_s": None,
                "dead_time_s": dead}
    tau = 0.0 if proc.a <= 0.0 else -dt / math.log(proc.a)
    return {"model": model, "gain": proc.b / (1.0 - proc.a), "time_constant_s": tau,
            "dead_time_s": dead}


# ----------------------------------------------------------------------------- record checks

def _longest_finite(*arrays: FloatArray) -> slice:
    """The longest run of samples where every array is finite."""
    good = np.logical_and.reduce([np.isfinite(a) for a in arrays])
    edges = np.flatnonzero(np.diff(np.concatenate([[0], good.astype(np.int8), [0]])))
    if len(edges) == 0:
        return slice(0, 0)
    starts, ends = edges[::2], edges[1::2]
    k = int(np.argmax(ends - starts))
    return slice(int(starts[k]), int(ends[k]))


def count_swings(x: FloatArray, hysteresis: float) -> int:
    """Direction changes of ``x`` by at least ``hysteresis`` (a turning point counts once x has
    moved ``hysteresis`` back from the extreme since the last one)."""
    if len(x) == 0 or hysteresis <= 0.0:
        return 0
    swings, direction = 0, 0
    hi = lo = float(x[0])
    for v in x:
        v = float(v)
        hi, lo = max(hi, v), min(lo, v)
        if direction >= 0 and v < hi - hysteresis:
            swings += direction > 0
            direction, lo = -1, v
        elif direction <= 0 and v > lo + hysteresis:
            swings += direction < 0
            direction, hi = 1, v
    return swings


# ----------------------------------------------------------------------------- valve fit

def fit_valve(data: LoopData, loop_type: str = "self-regulating", *,
              max_dead_time: float | None = None, gain_sign: float = 0.0,
              whiten: bool | None = None) -> ValveFit:
    """Fit Choudhury's S and J jointly with the process (module docstring).

    An integrating loop's record is whitened (``whiten``, default: when the residual walks,
    :data:`MAX_WHITENING`) and its increments fitted (:data:`MIN_R2_INTEGRATING`); when that
    fit explains too little of them to support an estimate, the level itself is fitted
    instead, as for a fast-scanned level loop.

    ``loop_type``: ``"self-regulating"`` (FOPDT process) or ``"integrating"``.
    ``max_dead_time``: the longest dead time searched, s (default :data:`DEAD_FRACTION` of the
    record, at most :data:`MAX_DEAD_SAMPLES` samples). The record used is the longest run where
    OP and PV are finite. ``ok`` is False, with S and J NaN, when that run is shorter than
    :data:`MIN_SAMPLES`, when OP or PV do not move (OP range below :data:`MIN_OP_RANGE` % or
    fewer than :data:`MIN_SWINGS` swings of a quarter of its range), or when the best fit
    explains less than :data:`MIN_R2` of the PV variance."""
    if loop_type not in _LOOP_TYPES:
        raise ValueError(f"loop_type must be one of {_LOOP_TYPES}, not {loop_type!r}")
    integrating = loop_type == "integrating"
    dt = data.dt
    span = _longest_finite(data.op, data.pv)
    op = np.asarray(data.op[span], dtype=np.float64)
    pv = np.asarray(data.pv[span], dtype=np.float64)
    n = len(op)
    cut = "" if n == len(data) else (f" (the longest finite run, {n} of {len(data)} samples)")

    def refuse(why: str, r2: float = math.nan, r2_lin: float = math.nan,
               proc: _Process | None = None) -> ValveFit:
        return ValveFit(math.nan, math.nan, math.nan, math.nan,
                        _process_dict(proc, integrating, dt), r2, r2_lin, why, False)

    if n < MIN_SAMPLES:
        return refuse(f"{n} usable samples{cut}: at least {MIN_SAMPLES} are needed to fit "
                      f"the valve and the process.")
    op_range = float(op.max() - op.min())
    width = max(HP_MIN_SAMPLES, round(HP_FRACTION * n))

    y = _high_pass(pv, width)
    min_r2 = MIN_R2_INTEGRATING if integrating else MIN_R2
    sst = float((y ** 2).sum())
    if op_range < MIN_OP_RANGE:
        return refuse(f"OP moves over {op_range:.3g} % only{cut} (below {MIN_OP_RANGE:g} %): "
                      f"a valve that is not driven shows no stiction to estimate.")
    if not sst > 0.0:
        return refuse(f"PV is constant{cut}: nothing to fit.")
    swings = count_swings(op, op_range / 4.0)
    if swings < MIN_SWINGS:
        return refuse(f"OP changes direction {swings} time{'s' * (swings != 1)} by a quarter "
                      f"of its {op_range:.3g} % range{cut}: at least {MIN_SWINGS} are needed "
                      f"to see the valve reverse.")
    dmax = (round(max_dead_time / dt) + 1 if max_dead_time is not None
            else int(min(MAX_DEAD_SAMPLES, max(1, round(DEAD_FRACTION * n)))))
    dmax = max(1, min(dmax, n // 2))
    c = (_level_whitening(_high_pass(op, width), y, dmax, gain_sign)
         if integrating and whiten is not False else math.inf)
    auto = whiten is None
    whiten = c <= MAX_WHITENING if whiten is None else whiten and integrating
    taps = 2 if whiten else 1

    def prefilter(v: FloatArray) -> FloatArray:
        """High-pass (:func:`_high_pass`); for an integrating loop whose residual walks, then
        the whitening filter (1 - q⁻¹)/(1 - c·q⁻¹) of :func:`_level_whitening`."""
        z = _high_pass(v, width)
        return np.asarray(lfilter([1.0, -1.0], [1.0, -c], z, zi=[-c * z[0]])[0]
                          if whiten else z, dtype=np.float64)

    if whiten:
        y = prefilter(pv)
        sst = float((y ** 2).sum())
    else:
        min_r2 = MIN_R2
    cache: dict[tuple[float, float], _Process] = {}

    def evaluate(s: float, j: float) -> _Process:
        key = (round(s, 9), round(j, 9))
        if key not in cache:
            x = prefilter(valve_position(op, s, j))
            cache[key] = (_fit_increments(x, y, INCREMENT_SAMPLES, dmax, gain_sign)
                          if integrating else _fit_process(x, y, False, dmax, gain_sign))
        return cache[key]

    def output_error(s: float, j: float) -> _Process:
        return (_fit_process(prefilter(valve_position(op, s, j)), y, True, dmax, gain_sign,
                             taps=taps)
                if integrating
                else evaluate(s, j))

    r2_lin = 1.0 - output_error(0.0, 0.0).sse / sst
    s, j = search_sj(lambda s, j: evaluate(s, j).sse, op_range)
    best = output_error(s, j)
    r2 = 1.0 - best.sse / sst
    process = _process_dict(best, integrating, dt)
    if r2 < min_r2 and whiten and auto:
        return fit_valve(data, loop_type, max_dead_time=max_dead_time, gain_sign=gain_sign,
                         whiten=False)
    if r2 < min_r2:
        what = "the PV increments' variance" if whiten else "the PV variance"
        return refuse(f"the best valve-and-process fit explains R² = {r2:.2f} of {what}"
                      f"{cut}, below {min_r2:g}: the record does not support an "
                      f"estimate of S and J (is the PV driven by the OP at all?).",
                      r2, r2_lin, best)
    of = f" of the PV's increments whitened with c = {c:.2f}" if whiten else ""
    reason = (f"S = {s:.3g} %, J = {j:.3g} % (deadband {s - j:.3g} %, resolution {j:.3g} %) "
              f"with {'an integrating' if integrating else 'a FOPDT'} process of gain "
              f"{process['gain']:.3g}; output-error R² {r2:.3f}{of} against {r2_lin:.3f} for "
              f"a linear valve{cut}.")
    return ValveFit(s, j, j, s - j, process, r2, r2_lin, reason, True,
                    c if whiten else math.nan)


def model_pv(data: LoopData, fit: ValveFit) -> FloatArray:
    """The PV the fitted model (valve S, J and the identified process) gives for the recorded
    OP, over the whole record: the process's dead time and time constant as fitted, its gain,
    offset and initial state by least squares against the recorded PV (module docstring's
    separable form); NaN where OP or PV is not finite, or everywhere when ``fit.ok`` is
    False. An integrating process also integrates the load, which the record does not show,
    so a model level run free drifts away from any record: there the model predicts the
    level m samples ahead of the record, PV̂_k = PV_{k-m} + K·dt·(x_{k-d} + ... +
    x_{k-d-m+1}) + c, with c the mean increment the valve does not explain (the first m
    samples NaN): m = 1 when the fit was of the whitened increments, else
    :data:`INCREMENT_SAMPLES`, as its search cost (:func:`_fit_increments`)."""
    out = np.full(len(data), math.nan)
    if not fit.ok:
        return out
    span = _longest_finite(data.op, data.pv)
    op, pv = np.asarray(data.op[span]), np.asarray(data.pv[span])
    n, dt = len(op), data.dt
    x = valve_position(op, fit.s, fit.j)
    x = x - x.mean()
    proc = fit.process
    d = round(float(proc["dead_time_s"]) / dt) + 1 if proc["dead_time_s"] > 0 else 0
    xp = np.concatenate([np.full(d, x[0]), x])[:n]
    if proc["model"] == "integrating":
        m = min(1 if math.isfinite(fit.whitening) else INCREMENT_SAMPLES, n - 1)
        level = float(proc["gain"]) * dt * np.cumsum(xp)
        ahead = level[m:] - level[:-m]
        offset = float(np.mean(pv[m:] - pv[:-m] - ahead))
        model = np.full(n, math.nan)
        model[m:] = pv[:-m] + ahead + offset
        out[span] = model
        return out
    tau = float(proc["time_constant_s"] or 0.0)
    a = math.exp(-dt / tau) if tau > 0.0 else 0.0
    r = lfilter([1.0], [1.0, -a], xp)
    p = a ** np.arange(n, dtype=np.float64)
    A = np.column_stack([r, np.ones(n), p])
    theta, *_ = np.linalg.lstsq(A, pv, rcond=None)
    out[span] = A @ theta
    return out


# ----------------------------------------------------------------------------- controller

def fit_controller(data: LoopData) -> ControllerFit:
    """Identify the PI controller by linear least squares of its velocity form (module
    docstring): ΔOP_k = θ1·Δe_k + θ2·e_k with e = SP - PV, Kc = |θ1|, Ti = dt·θ1/θ2, direct
    action when the coefficient of the term that moves OP more (|θ1|·σ(Δe) against
    |θ2|·σ(e)) is negative. Scans are used where SP, PV, OP are finite at k and k-1, OP is inside
    (0, 100) % (not saturated) and, when the record has a mode, the loop is automatic
    (mode ≥ 1) at both. A derivative action is ignored (it lowers R²)."""
    dt = data.dt
    e = np.asarray(data.sp - data.pv, dtype=np.float64)
    op = np.asarray(data.op, dtype=np.float64)
    de, dop, ek = np.diff(e), np.diff(op), e[1:]
    use = np.isfinite(de) & np.isfinite(dop)
    inside = (op > 0.0) & (op < 100.0)
    use &= inside[1:] & inside[:-1]
    if data.mode is not None:
        auto = data.mode >= 1.0
        use &= auto[1:] & auto[:-1]
    m = int(use.sum())
    nan = math.nan
    if m < MIN_CONTROLLER_SAMPLES:
        return ControllerFit(nan, nan, nan, False, f"{m} usable scans (automatic, OP inside "
                             f"0..100 %, values finite): at least {MIN_CONTROLLER_SAMPLES} are "
                             f"needed.")
    A = np.stack([de[use], ek[use]], axis=1)
    z = dop[use]
    sst = float(((z - z.mean()) ** 2).sum())
    if not sst > 0.0 or not np.any(A):
        return ControllerFit(nan, nan, nan, False, "OP or the control error does not move: "
                             "no controller to identify.")
    theta, *_ = np.linalg.lstsq(A, z, rcond=None)
    r2 = 1.0 - float(((z - A @ theta) ** 2).sum()) / sst
    th1, th2 = float(theta[0]), float(theta[1])
    # the action is the sign of the term that moves OP most: at a historian's period an
    # integral much faster than the sampling leaves θ1 near 0 and of either sign (a reverse
    # PI with Ti = 1 s read every 5 s was "direct, Ti = inf", and the valve fit's process
    # gain took the wrong sign)
    p_part, i_part = abs(th1) * float(np.std(de[use])), abs(th2) * float(np.std(ek[use]))
    action = "direct" if (th1 if p_part >= i_part else th2) < 0.0 else "reverse"
    kc = abs(th1)
    ti = dt * th1 / th2 if th1 * th2 > 0.0 else math.inf
    integral = (f"Ti = {ti:.4g} s" if math.isfinite(ti)
                else "no integral action identified (Ti = inf)")
    if r2 < MIN_CONTROLLER_R2:
        return ControllerFit(nan, nan, r2, False, f"the velocity PI form explains R² = "
                             f"{r2:.2f} of the OP moves, below {MIN_CONTROLLER_R2:g}: not a PI "
                             f"controller acting on SP - PV at this sampling (derivative "
                             f"action, filtering or a coarser historian period?).", action)
    return ControllerFit(kc, ti, r2, True, f"{action}-acting PI: Kc = {kc:.4g}, {integral}; "
                         f"velocity-form R² {r2:.3f} over {m} scans.", action)
