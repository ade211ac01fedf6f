r"""Data-driven control-valve models: stiction, backlash, resolution and quantisation.

Kinds (input ``op``, the controller output in % of span; output ``position``, the stem position
in % of travel; a bare "spec" on this page is the plant-and-tuning specification, see Sources):

| kind | model | section |
|---|---|---|
| ``valve.choudhury`` | Choudhury-Shah-Thornhill two-parameter stiction (S, J) | spec 1.2 |
| ``valve.kano`` | Kano et al. stiction (S, J), stop reference kept | spec 1.3 |
| ``valve.he`` | He et al. two-layer stiction (fs, fd) | spec 1.4 |
| ``valve.backlash`` | friction-dominated backlash of total width b | spec 1.5 |
| ``valve.resolution`` | resolution limit / stick-slip with memory (r) | spec 1.5 |
| ``valve.quantiser`` | memoryless quantiser of step q | spec 1.5 |
| ``valve.karnopp`` | physical: spring-diaphragm, Karnopp friction, I/P lag (own page) | spec 1.6 |

Each scan takes one sample ``op`` and gives one ``position``: these are sampled (static
hysteresis) maps, not dynamics, and they are exactly the spec's algorithms. For friction that
depends on time and velocity (dither studies, spec 2.2) use ``valve.karnopp``.

Vocabulary (spec 1.1): S is the total input travel before a stuck valve moves after a reversal
(deadband + stickband), J the slip jump. Derived: static band fs = (S + J)/2 (the largest
offset |op - y| a stuck valve tolerates), kinetic band fd = (S - J)/2 (the offset |op - y|
kept while the stem moves). J = 0 is pure backlash, J = S pure stick-slip, J > S overshoot.

Stiction parameters: one set of three (spec 1.7)
------------------------------------------------

``valve.choudhury``, ``valve.kano`` and ``valve.he`` take the stiction as ONE of

* ``s``, ``j``: Choudhury's S and J (%);
* ``resolution``, ``deadband``: the practitioner's stick-slip (resolution, RES) and backlash
  (deadband, DB) in series, spec 1.7 [I]: J = RES, S = DB + RES (so fs = RES + DB/2, the
  breakaway band and the DeltaV dither rule "resolution + 0.5·deadband");
* ``fs``, ``fd``: He's static and kinetic bands (%): S = fs + fd, J = fs - fd.

Give both parameters of the set; naming parameters of two sets is an error. With none given
the valve has S = 3 %, J = 1 % (the spec 1.8 example). S >= 0 and J >= 0 are required (for
fs, fd: fs >= |fd|). The mapping is in :func:`sj_from_resolution_deadband`,
:func:`resolution_deadband_from_sj`, :func:`bands_from_sj` and :func:`sj_from_bands`.

Per sample, with x = ``op`` clipped to [0, 100] (spec 1.2 step 1; the C++ offset D and travel
rescaling are not modelled) and sign(0) = 0:

``valve.choudhury`` (spec 1.2, following ``sim_choudhury()`` of fellipegm/valve_estimation).
State x_prev, v_prev (previous increment; only its sign is used), y, I (1 = stuck), xss (OP at
which the valve last stopped)::

    v = x - x_prev,  s = sign(v),  s_prev = sign(v_prev)
    if s == s_prev:
        if I == 0:  y = x - s·fd                                    (moving)
        elif sign(x - xss)·sign(xss - y) == +1:                     (resume, same direction)
            if |x - xss| > J:  I = 0, y = x - s·fd
        elif |x - y| > fs:  I = 0, y = x - s·fd                     (reversal)
    else:
        if I == 0:  xss = x_prev            (only a moving valve refreshes the stop point)
        if s == 0:  I = 1                   (a pause of one sample sticks the valve)
        elif |x - y| > fs:  I = 0, y = x - s·fd
        else:  I = 1
    x_prev = x,  v_prev = v

For J <= S this is the same map as Kano's below (spec 1.2 note [V]; they differ only at exact
float ties). For J > S the stem overshoots past the stop point, so sign(xss - y) no longer
tells the side the stem lags on: after a stop, an OP reversal is then taken for a resume and
needs J instead of S (e.g. S = 2, J = 4 at rest at 50: OP 46.5, 46.5, 47.5, 48.6 leaves
Choudhury at 45.5 while Kano reverses to 49.6). The spec's algorithm is reproduced as written;
use ``valve.kano`` for overshooting valves.

``valve.kano`` (spec 1.3, Kano, Maruta, Kugemoto & Shimizu 2004; BDSIM stiction.m)::

    du = x - u_prev
    if du·du_prev <= 0 and stp == 0:  us = u_prev, stp = 1
    if stp == 0:                y = x - d·fd
    elif -d·(x - us) > S:       d = -d, y = x - d·fd, stp = 0
    elif  d·(x - us) > J:       y = x - d·fd, stp = 0
    (else y holds)
    du_prev = du,  u_prev = x

``valve.he`` (spec 1.4, He, Wang, Pottmann & Qin 2007)::

    cum = u_r + (x - u_prev)
    if |cum| > fs:  y = x - sign(cum)·fd,  u_r = sign(cum)·fd       (slip)
    else:           u_r = cum                                        (stick; y holds)
    u_prev = x

The C++ ``sim_he()`` writes sign(cum - fs); for |cum| > fs that is the same number as
sign(cum) (fs >= 0), so there is nothing to choose. He's output depends on the sample time: a
slow monotone ramp gives stick-slip steps of about J (spec 1.4).

``valve.backlash`` (spec 1.5, python-control ``friction_backlash_nonlinearity``)::

    if x - y > b/2:  y = x - b/2
    elif x - y < -b/2:  y = x + b/2

``valve.resolution`` (spec 1.5, resolution limit with memory, the ISA meaning)::

    if |x - y| > r:  y = x

``valve.quantiser`` (spec 1.5, memoryless)::

    y = q·round(x/q),  round(z) = floor(z + 1/2)    (ties upward; x >= 0 after clipping)

(y = x where x/q is beyond 4e15: a step below the float resolution of x, or a q so small
that x/q overflows; :func:`quantise`.)

Initial state (spec 1.2 table, 1.8)
-----------------------------------

``y0`` (%): with ``y0`` given the valve starts at rest at y0 *before* the first sample, with
x_prev = y0 (Choudhury xss = y0, I = 1; Kano stp = 1, d = +1, us = y0 + fd, as spec 1.8
states; He u_r = 0), and the first sample is processed like any other: this is how the spec
1.8 tables start ("valve initially at rest at 0"). Without ``y0`` (the default) the first
sample initialises the state, at rest at that op (the spec 1.2 table: x_prev = y = xss = OP),
and is not processed as a move.

Before its first scan a valve publishes the position it starts at (issue 11 point 8): ``y0``,
or without ``y0`` the outputs its first scan gives for the ``op`` input latched now (0 %
unless given): the valve at rest at that op, Good. So a process that reads ``position``
earlier in a module's order sees the valve's real start, never a placeholder.

Output stage, common to the six kinds
-------------------------------------

``position`` = the model's y clipped to [0, 100] (the model state itself is not clipped, as in
the C++: J > S can overshoot past the travel), then moved towards it by at most
``stroke_rate``·dt per scan (stroking speed of the actuator, %/s; inf = no limit). The limit
acts on the stem, after the friction map: a slip jump is spread over the time the stem needs
to travel it; the friction model's own state is not changed by it [I, loopworks design].

``flow`` = the inherent characteristic of the trim at that position, in % of the full-open flow
coefficient: ``linear`` f = position; ``equal_percentage`` f = 100·R^(position/100 - 1) with
R = ``rangeability`` (the ideal ISA-75.11.01 curve: 100/R % at closed, not 0). Wire ``flow``
to the process when the characteristic matters; ``position`` stays the stem travel (for travel
and reversal metrics, spec 4.1).

Status
------

A Good ``op`` gives Good (128) outputs; an Uncertain ``op`` is used and gives Uncertain (64).
A Bad or non-finite ``op`` (NaN, ±inf: issue 11 point 1, a non-finite value is Bad input
whatever its status) is handled by ``bad_op``:

* ``hold`` (default): the sample is skipped: the valve state and ``position`` are frozen and
  both outputs are Bad (0), like ``process.first_order`` (no input, no trustworthy output).
  Before the first good sample (no ``y0``) the position held is the start value published
  before the first scan.
* ``fail``: the signal is lost and the actuator goes to its fail position: the model is driven
  with ``fail_op`` (default 0 %, air-to-open fails closed) through its friction, and the outputs
  are Uncertain: substitute (72).

Options for the spec's [I] points
---------------------------------

* ``start`` (spec 1.2 implementation note, 1.3, 1.9; stiction kinds and backlash): ``rest``
  (default, spec 1.2 table and 1.8) or ``moving_up`` / ``moving_down``: the valve starts as if
  it had just been moving in that direction (Choudhury I = 0, v_prev = ±1; Kano stp = 0,
  d = du_prev = ±1; He u_r = ±fd, as ``sim_he()`` does for a non-zero direction; backlash
  y on the trailing edge). With ``y0`` the stem is at y0 and x_prev = y0 ± fd; without it, the
  first op is x_prev and y = op ∓ fd. Use it to avoid the extra J that a repeated first sample
  costs (spec 1.2) and to start a describing-function run in the moving state (spec 1.9, 6 item 2).
* ``resolution``/``deadband`` as an alternative to ``s``/``j`` (spec 1.7 [I] mapping).
* ``stroke_rate`` acts on the stem after the friction model (see above) [loopworks design].
* ``bad_op`` (see Status) [practice].

Worked example (spec 1.8, S = 3, J = 1, valve at rest at 0)::

    import loopworks
    v = loopworks.create_block("valve.choudhury", s=3.0, j=1.0, y0=0.0)
    [v.step(1.0, op=x)["position"].value for x in (1, 2, 3, 4, 5, 5, 5, 5.5, 6, 6.5)]
    # [0.0, 0.0, 2.0, 3.0, 4.0, 4.0, 4.0, 4.0, 4.0, 5.5]
    v = loopworks.create_block("valve.he", resolution=1.0, deadband=2.0, y0=0.0)  # fs=2, fd=1

The same as a replay: ``op.csv`` with a header ``t,op`` and rows ``0,1``, ``1,2``, ``2,3``...;
``loopworks replay valve.choudhury op.csv -p s=3 -p j=1 -p y0=0`` writes ``t,position,flow,
position.ST,flow.ST``.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from loopworks.blocks.block import Block
from loopworks.blocks.kernel import FloatArray, IntArray, primitive
from loopworks.blocks.layout import index
from loopworks.blocks.params import Param, Port
from loopworks.blocks.primitives import clamp, finite, sign
from loopworks.blocks.registry import register
from loopworks.blocks.status import (
    BAD,
    BAD_NON_SPECIFIC,
    GOOD_NC,
    UNCERTAIN,
    UNCERTAIN_NON_SPECIFIC,
    UNCERTAIN_SUBSTITUTE,
)
from loopworks.errors import ParameterError

# -- spec 1.7 / 1.1 mappings ----------------------------------------------------------------------


def sj_from_resolution_deadband(resolution: float, deadband: float) -> tuple[float, float]:
    """(S, J) from the practitioner's resolution (stick-slip) and deadband (backlash), spec 1.7:
    J = RES, S = DB + RES."""
    return deadband + resolution, resolution


def resolution_deadband_from_sj(s: float, j: float) -> tuple[float, float]:
    """(resolution, deadband) from (S, J), spec 1.7: RES = J, DB = S - J."""
    return j, s - j


def bands_from_sj(s: float, j: float) -> tuple[float, float]:
    """(fs, fd) from (S, J), spec 1.1: fs = (S + J)/2, fd = (S - J)/2."""
    return (s + j) / 2.0, (s - j) / 2.0


def sj_from_bands(fs: float, fd: float) -> tuple[float, float]:
    """(S, J) from He's bands (fs, fd), spec 1.1/1.4: S = fs + fd, J = fs - fd."""
    return fs + fd, fs - fd


def breakaway_band(resolution: float, deadband: float) -> float:
    """fs = RES + DB/2 (spec 1.7): the offset at which a stuck valve breaks away, and the
    peak-to-peak of the DeltaV dither rule "resolution + 0.5·deadband" (spec 2.2)."""
    return resolution + 0.5 * deadband


_PCT = "%"


# -- coefficient and state layout -----------------------------------------------------------------

CHAR_LINEAR, CHAR_EQUAL = 0.0, 1.0  # values of the coefficient char

INPUTS = (
    Port("op", 0.0, _PCT, "valve input: controller output, % of span (clipped to 0..100)",
         status=True),
)
OUTPUTS = (
    Port("position", 0.0, _PCT, "stem position, % of travel", status=True),
    Port("flow", 0.0, _PCT, "relative flow coefficient from the inherent characteristic, % of "
         "full open", status=True),
)
U, Y = index(INPUTS, "U"), index(OUTPUTS, "Y")

#: every valve kind's coefficients begin with these (valve.karnopp's too): stroke rate,
#: characteristic, ln(rangeability), bad_op = fail, fail_op, start direction, y0 (NaN: none)
COMMON_COEFFS = ("rate", "char", "lnr", "bad_fail", "fail_op", "start", "y0")
#: every valve kind's states begin with these: initialised flag, stem position
COMMON_STATES = ("init", "position")
# The shared primitives below read only these names, through the layouts the calling kernel
# passes (arguments P and X: its own kind's, as every kernel indexes only its kind's layouts);
# Python code that serves every kind reads them through PC and XC.
PC, XC = index(COMMON_COEFFS, "PC"), index(COMMON_STATES, "XC")

#: Choudhury, Kano and He: the stiction as S, J and as He's bands fs, fd
STICTION_COEFFS = (*COMMON_COEFFS, "s", "j", "fs", "fd")
CHOUDHURY_STATES = (*COMMON_STATES, "x_prev", "v_prev", "y", "stuck", "xss")
KANO_STATES = (*COMMON_STATES, "u_prev", "du_prev", "stp", "d", "us", "y")
HE_STATES = (*COMMON_STATES, "u_prev", "u_r", "y")
#: backlash (half width b/2), resolution (r) and quantiser (q)
BACKLASH_COEFFS = (*COMMON_COEFFS, "half_width")
RESOLUTION_COEFFS = (*COMMON_COEFFS, "r")
QUANTISER_COEFFS = (*COMMON_COEFFS, "q")
MODEL_STATES = (*COMMON_STATES, "y")  # y: the model's output before the stroke limit
PS, PB, PR, PQ = (index(STICTION_COEFFS, "PS"), index(BACKLASH_COEFFS, "PB"),
                  index(RESOLUTION_COEFFS, "PR"), index(QUANTISER_COEFFS, "PQ"))
XCH, XKA, XHE, XM = (index(CHOUDHURY_STATES, "XCH"), index(KANO_STATES, "XKA"),
                     index(HE_STATES, "XHE"), index(MODEL_STATES, "XM"))


# -- shared primitives ----------------------------------------------------------------------------


@primitive
def op_in(p: FloatArray, op: float, status: int, P: Any) -> float:
    """The op sample the model acts on: clipped to [0, 100] (spec 1.2 step 1); for a Bad or
    non-finite op ``fail_op`` (bad_op = fail) or NaN (hold: skip the sample). ``P``: the
    calling kind's coefficient layout (it begins with COMMON_COEFFS)."""
    if not finite(op) or (status & 0xC0) == BAD:
        if p[P.bad_fail] != 0.0:
            return float(p[P.fail_op])
        return math.nan
    return clamp(op, 0.0, 100.0)


@primitive
def quantise(v: float, q: float) -> float:
    """q·floor(v/q + 1/2) (spec 1.5, halves rounded up), for q > 0; v itself where |v/q| is
    beyond 4e15 (a double there is already a whole number: the step is below the resolution
    of v, or q is so small that v/q overflows)."""
    w = v / q + 0.5
    if abs(w) < 4.0e15:
        return q * float(math.floor(w))
    return v


@primitive
def op_status(op: float, status: int) -> int:
    """Output status for a scan that ran: Good, Uncertain (Uncertain op) or Uncertain:
    substitute (bad op, fail action)."""
    if not finite(op) or (status & 0xC0) == BAD:
        return UNCERTAIN_SUBSTITUTE
    if (status & 0xC0) == UNCERTAIN:
        return UNCERTAIN_NON_SPECIFIC
    return GOOD_NC


@primitive
def flow_of(p: FloatArray, position: float, P: Any) -> float:
    """Inherent characteristic: linear f = position; equal percentage f = 100·R^(l - 1),
    l = position/100, R the rangeability (ISA-75.11.01 ideal curve). ``P``: the calling
    kind's coefficient layout."""
    if p[P.char] == CHAR_EQUAL:
        return 100.0 * math.exp((position / 100.0 - 1.0) * p[P.lnr])
    return position


@primitive
def hold(p: FloatArray, x: FloatArray, y: FloatArray, ys: IntArray, P: Any, X: Any) -> None:
    """bad_op = hold: outputs frozen at the last position, status Bad. Before the first good
    sample (no y0) that is the start value published before the first scan. ``P``, ``X``: the
    calling kind's layouts (they begin with COMMON_COEFFS, COMMON_STATES)."""
    pos = x[X.position] if x[X.init] != 0.0 else y[Y.position]
    y[Y.position] = pos
    y[Y.flow] = flow_of(p, pos, P)
    ys[Y.position] = BAD_NON_SPECIFIC
    ys[Y.flow] = BAD_NON_SPECIFIC


@primitive
def finish(dt: float, p: FloatArray, x: FloatArray, y: FloatArray, ys: IntArray, ym: float,
           status: int, first: bool, P: Any, X: Any) -> None:
    """Output stage: clip the model's y to [0, 100], stroke towards it at most stroke_rate·dt,
    then the characteristic. ``first``: the sample that initialised the valve (no y0) sets the
    stem there (no stroke from nowhere). ``P``, ``X``: the calling kind's layouts."""
    target = clamp(ym, 0.0, 100.0)
    pos = x[X.position]
    if first:
        pos = target
    else:
        step = p[P.rate] * dt
        if abs(target - pos) <= step:
            pos = target
        elif target > pos:
            pos = pos + step
        else:
            pos = pos - step
    x[X.position] = pos
    y[Y.position] = pos
    y[Y.flow] = flow_of(p, pos, P)
    ys[Y.position] = status
    ys[Y.flow] = status


# -- Choudhury (spec 1.2) -------------------------------------------------------------------------



@primitive
def choudhury_init(p: FloatArray, x: FloatArray, x_prev: float, y: float) -> None:
    """Start state: at rest (I = 1, v_prev = 0, xss = x_prev) or moving in direction
    ``start`` (I = 0, v_prev = ±1)."""
    d = p[PS.start]
    x[XCH.x_prev] = x_prev
    x[XCH.y] = y
    x[XCH.xss] = x_prev
    x[XCH.v_prev] = d
    x[XCH.stuck] = 1.0 if d == 0.0 else 0.0
    x[XCH.init] = 1.0


@primitive
def choudhury_step(p: FloatArray, x: FloatArray, xk: float) -> float:
    """One sample of spec 1.2 steps 2-5 (module docstring); returns y."""
    fs = p[PS.fs]
    fd = p[PS.fd]
    x_prev = x[XCH.x_prev]
    v = xk - x_prev
    s = sign(v)
    s_prev = sign(x[XCH.v_prev])
    y: float = x[XCH.y]
    stuck = x[XCH.stuck] != 0.0
    if s == s_prev:
        if not stuck:
            y = xk - s * fd
        else:
            xss = x[XCH.xss]
            if sign(xk - xss) * sign(xss - y) == 1.0:  # resume in the old direction
                if abs(xk - xss) > p[PS.j]:
                    stuck = False
                    y = xk - s * fd
            elif abs(xk - y) > fs:  # a reversal
                stuck = False
                y = xk - s * fd
    else:
        if not stuck:
            x[XCH.xss] = x_prev
        if s == 0.0:
            stuck = True
        elif abs(xk - y) > fs:
            stuck = False
            y = xk - s * fd
        else:
            stuck = True
    x[XCH.x_prev] = xk
    x[XCH.v_prev] = v
    x[XCH.y] = y
    x[XCH.stuck] = 1.0 if stuck else 0.0
    return y


def choudhury_kernel(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                     y: FloatArray, ys: IntArray) -> None:
    """One scan of ``valve.choudhury`` (spec 1.2)."""
    xk = op_in(p, u[U.op], us[U.op], PS)
    if math.isnan(xk):
        hold(p, x, y, ys, PS, XCH)
        return
    first = x[XCH.init] == 0.0
    if first:
        choudhury_init(p, x, xk, xk - p[PS.start] * p[PS.fd])
        ym = x[XCH.y]
    else:
        ym = choudhury_step(p, x, xk)
    finish(dt, p, x, y, ys, ym, op_status(u[U.op], us[U.op]), first, PS, XCH)


# -- Kano (spec 1.3) ------------------------------------------------------------------------------



@primitive
def kano_init(p: FloatArray, x: FloatArray, u_prev: float, y: float) -> None:
    """Start state: at rest (stp = 1, d = +1, us = y + fd, du_prev = 0; spec 1.8) or moving in
    direction ``start`` (stp = 0, d = du_prev = ±1, us = u_prev)."""
    d = p[PS.start]
    x[XKA.u_prev] = u_prev
    x[XKA.y] = y
    if d == 0.0:
        x[XKA.stp] = 1.0
        x[XKA.d] = 1.0
        x[XKA.us] = y + p[PS.fd]
        x[XKA.du_prev] = 0.0
    else:
        x[XKA.stp] = 0.0
        x[XKA.d] = d
        x[XKA.us] = u_prev
        x[XKA.du_prev] = d
    x[XKA.init] = 1.0


@primitive
def kano_step(p: FloatArray, x: FloatArray, uk: float) -> float:
    """One sample of the spec 1.3 pseudo-code; returns y."""
    fd = p[PS.fd]
    u_prev = x[XKA.u_prev]
    du = uk - u_prev
    stp = x[XKA.stp]
    d = x[XKA.d]
    y: float = x[XKA.y]
    if du * x[XKA.du_prev] <= 0.0 and stp == 0.0:  # input reversed or paused while moving
        x[XKA.us] = u_prev
        stp = 1.0
    us = x[XKA.us]
    if stp == 0.0:
        y = uk - d * fd
    elif -d * (uk - us) > p[PS.s]:
        d = -d
        y = uk - d * fd
        stp = 0.0
    elif d * (uk - us) > p[PS.j]:
        y = uk - d * fd
        stp = 0.0
    x[XKA.stp] = stp
    x[XKA.d] = d
    x[XKA.y] = y
    x[XKA.du_prev] = du
    x[XKA.u_prev] = uk
    return y


def kano_kernel(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                y: FloatArray, ys: IntArray) -> None:
    """One scan of ``valve.kano`` (spec 1.3)."""
    uk = op_in(p, u[U.op], us[U.op], PS)
    if math.isnan(uk):
        hold(p, x, y, ys, PS, XKA)
        return
    first = x[XKA.init] == 0.0
    if first:
        kano_init(p, x, uk, uk - p[PS.start] * p[PS.fd])
        ym = x[XKA.y]
    else:
        ym = kano_step(p, x, uk)
    finish(dt, p, x, y, ys, ym, op_status(u[U.op], us[U.op]), first, PS, XKA)


# -- He (spec 1.4) --------------------------------------------------------------------------------



@primitive
def he_init(p: FloatArray, x: FloatArray, u_prev: float, y: float) -> None:
    """Start state: u_r = 0 at rest, ±fd moving (``sim_he()`` with a direction)."""
    x[XHE.u_prev] = u_prev
    x[XHE.y] = y
    x[XHE.u_r] = p[PS.start] * p[PS.fd]
    x[XHE.init] = 1.0


@primitive
def he_step(p: FloatArray, x: FloatArray, uk: float) -> float:
    """One sample of the spec 1.4 model; returns y."""
    cum = x[XHE.u_r] + (uk - x[XHE.u_prev])
    y: float = x[XHE.y]
    if abs(cum) > p[PS.fs]:
        sg = sign(cum)
        y = uk - sg * p[PS.fd]
        x[XHE.u_r] = sg * p[PS.fd]
    else:
        x[XHE.u_r] = cum
    x[XHE.y] = y
    x[XHE.u_prev] = uk
    return y


def he_kernel(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
              y: FloatArray, ys: IntArray) -> None:
    """One scan of ``valve.he`` (spec 1.4)."""
    uk = op_in(p, u[U.op], us[U.op], PS)
    if math.isnan(uk):
        hold(p, x, y, ys, PS, XHE)
        return
    first = x[XHE.init] == 0.0
    if first:
        he_init(p, x, uk, uk - p[PS.start] * p[PS.fd])
        ym = x[XHE.y]
    else:
        ym = he_step(p, x, uk)
    finish(dt, p, x, y, ys, ym, op_status(u[U.op], us[U.op]), first, PS, XHE)


# -- backlash, resolution, quantiser (spec 1.5) ---------------------------------------------------



def backlash_kernel(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                    y: FloatArray, ys: IntArray) -> None:
    """One scan of ``valve.backlash`` (spec 1.5)."""
    xk = op_in(p, u[U.op], us[U.op], PB)
    if math.isnan(xk):
        hold(p, x, y, ys, PB, XM)
        return
    half = p[PB.half_width]
    first = x[XM.init] == 0.0
    if first:
        x[XM.y] = xk - p[PB.start] * half
        x[XM.init] = 1.0
    elif xk - x[XM.y] > half:
        x[XM.y] = xk - half
    elif xk - x[XM.y] < -half:
        x[XM.y] = xk + half
    finish(dt, p, x, y, ys, x[XM.y], op_status(u[U.op], us[U.op]), first, PB, XM)


def resolution_kernel(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                      y: FloatArray, ys: IntArray) -> None:
    """One scan of ``valve.resolution`` (spec 1.5)."""
    xk = op_in(p, u[U.op], us[U.op], PR)
    if math.isnan(xk):
        hold(p, x, y, ys, PR, XM)
        return
    first = x[XM.init] == 0.0
    if first or abs(xk - x[XM.y]) > p[PR.r]:
        x[XM.y] = xk
        x[XM.init] = 1.0
    finish(dt, p, x, y, ys, x[XM.y], op_status(u[U.op], us[U.op]), first, PR, XM)


def quantiser_kernel(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                     y: FloatArray, ys: IntArray) -> None:
    """One scan of ``valve.quantiser`` (spec 1.5): y = q·floor(x/q + 1/2)."""
    xk = op_in(p, u[U.op], us[U.op], PQ)
    if math.isnan(xk):
        hold(p, x, y, ys, PQ, XM)
        return
    first = x[XM.init] == 0.0
    x[XM.y] = quantise(xk, p[PQ.q])
    x[XM.init] = 1.0
    finish(dt, p, x, y, ys, x[XM.y], op_status(u[U.op], us[U.op]), first, PQ, XM)


# -- block classes --------------------------------------------------------------------------------

_START = {"rest": 0.0, "moving_up": 1.0, "moving_down": -1.0}

COMMON_PARAMS: tuple[Param, ...] = (
    Param("y0", None, _PCT, "initial stem position, at rest before the first sample (spec 1.2 "
          "table, 1.8); not given: the first op initialises the valve", lo=0.0, hi=100.0,
          lo_open=False, hi_open=False, default_text="first op"),
    Param("stroke_rate", math.inf, "%/s", "stroking speed limit of the stem, applied after the "
          "friction model [loopworks design]; inf = none", lo=0.0, hi_open=False),
    Param("characteristic", "linear", "", "inherent flow characteristic giving the 'flow' "
          "output (ISA-75.11.01)", "choice", choices=("linear", "equal_percentage")),
    Param("rangeability", 50.0, "", "rangeability R of the equal-percentage characteristic",
          lo=1.0),
    Param("bad_op", "hold", "", "Bad or non-finite op: hold (freeze, outputs Bad) or fail "
          "(drive to fail_op, outputs Uncertain: substitute) [practice]", "choice",
          choices=("hold", "fail")),
    Param("fail_op", 0.0, _PCT, "op the actuator fails to when bad_op = fail", lo=0.0,
          hi=100.0, lo_open=False, hi_open=False),
)

START_PARAM = Param("start", "rest", "", "initial friction state: at rest (spec 1.2, 1.8) or as "
                    "if just moving up/down (spec 1.2 note, 1.9) [I]", "choice",
                    choices=("rest", "moving_up", "moving_down"))

STICTION_PARAMS: tuple[Param, ...] = (
    Param("s", None, _PCT, "Choudhury S: deadband + stickband, input travel before a reversal "
          "moves the valve (spec 1.1, 1.2)", lo=0.0, lo_open=False,
          default_text="3.0 (no set given)"),
    Param("j", None, _PCT, "Choudhury J: slip jump, how far the stem jumps when it breaks "
          "free (spec 1.1, 1.2)", lo=0.0, lo_open=False,
          default_text="1.0 (no set given)"),
    Param("resolution", None, _PCT, "practitioner's stick-slip / resolution RES = J, instead "
          "of s, j (spec 1.7)", lo=0.0, lo_open=False, default_text="-"),
    Param("deadband", None, _PCT, "practitioner's backlash / deadband DB = S - J, instead of "
          "s, j (spec 1.7)", lo=0.0, lo_open=False, default_text="-"),
    Param("fs", None, _PCT, "He's static band fs = (S + J)/2, instead of s, j (spec 1.4)",
          lo=0.0, lo_open=False, default_text="-"),
    Param("fd", None, _PCT, "He's kinetic band fd = (S - J)/2, instead of s, j (spec 1.4)",
          default_text="-"),
)

_SETS: tuple[tuple[str, str], ...] = (("s", "j"), ("resolution", "deadband"), ("fs", "fd"))


def stiction_sj(kind: str, params: dict[str, Any], given: set[str]) -> tuple[float, float]:
    """(S, J) from whichever one of the three parameter sets was given (module docstring)."""
    named = {n for n in given if params.get(n) is not None}
    used = [(a, b) for a, b in _SETS if a in named or b in named]
    if len(used) > 1:
        names = [n for a, b in used for n in (a, b) if n in named]
        raise ParameterError(
            f"{kind}: give the stiction as one set - s, j or resolution, deadband or fs, fd "
            f"(spec 1.7) - not parameters of two sets: got {', '.join(names)}")
    if not used:
        return 3.0, 1.0
    a, b = used[0]
    missing = [n for n in (a, b) if n not in named]
    if missing:
        raise ParameterError(
            f"{kind}: parameter '{missing[0]}' is missing: give both {a} and {b}")
    va, vb = float(params[a]), float(params[b])
    if a == "s":
        return va, vb
    if a == "resolution":
        s, j = sj_from_resolution_deadband(va, vb)
    else:
        if not abs(vb) <= va:
            raise ParameterError(
                f"{kind}: parameter 'fd' = {vb:g} is out of range: allowed [-fs, fs] = "
                f"[{-va:g}, {va:g}] (fs >= |fd|, i.e. S >= 0 and J >= 0; spec 1.4)")
        s, j = sj_from_bands(va, vb)
    for name, value in (("S", s), ("J", j)):
        if not math.isfinite(value):  # each parameter finite, their sum or difference not
            raise ParameterError(
                f"{kind}: {a} = {va:g}, {b} = {vb:g} give {name} = {value:g}: out of range: "
                f"allowed a finite S and J (spec 1.7)")
    return s, j


class _Valve(Block):
    """Common parameters, ports, initial state and output stage of the data-driven valves."""

    INPUTS: ClassVar[tuple[Port, ...]] = INPUTS
    OUTPUTS: ClassVar[tuple[Port, ...]] = OUTPUTS
    HAS_START: ClassVar[bool] = False

    def common(self) -> dict[str, float]:
        """The coefficients every valve begins with (COMMON_COEFFS)."""
        prm = self.params
        y0 = math.nan if prm["y0"] is None else float(prm["y0"])
        start = _START[str(prm["start"])] if self.HAS_START else 0.0
        return {"rate": float(prm["stroke_rate"]),
                "char": CHAR_EQUAL if prm["characteristic"] == "equal_percentage"
                else CHAR_LINEAR,
                "lnr": math.log(float(prm["rangeability"])),
                "bad_fail": 1.0 if prm["bad_op"] == "fail" else 0.0,
                "fail_op": float(prm["fail_op"]), "start": start, "y0": y0}

    def model_init(self, x: FloatArray, y0: float) -> None:
        """Set the model state for a valve at y0 before the first sample (``y0`` given)."""
        x[XM.y] = y0
        x[XM.init] = 1.0

    def initial_state(self) -> list[float]:
        x = np.zeros(self.n_x)  # no y0: init = 0 until the first op, every state finite
        y0 = self.p[PC.y0]
        if not math.isnan(y0):
            self.model_init(x, y0)
            x[XC.position] = y0
        return [float(v) for v in x]

    def reset(self) -> None:
        super().reset()
        self.publish_start()

    def publish_start(self) -> None:
        """Publish the outputs before the first scan for the op latched now (:func:`publish_start`;
        a module that settles its wires before the first scan calls it again)."""
        publish_start(self)


def publish_start(block: Block) -> None:
    """Before the first scan a valve shows where it starts (module docstring): at rest at y0
    (Good), or without y0 the outputs its first scan gives for the op latched now, computed
    on copies of its arrays (the valve initialised at rest at that op; Bad if that op is Bad
    and bad_op = hold)."""
    y0 = block.p[PC.y0]
    if not math.isnan(y0):
        block.y[Y.position] = y0
        block.y[Y.flow] = flow_of(block.p, y0, PC)
        block.ys[:] = GOOD_NC
        return
    y = np.zeros(len(block.y))
    ys = np.full(len(block.ys), BAD_NON_SPECIFIC, dtype=np.int64)
    with np.errstate(all="ignore"):  # interpreted, as the guard runs it: overflow to inf is
        # handled by the kernel (a clamp, a finiteness check), numpy need not warn
        type(block).kernel(1.0, block.p, block.x.copy(), block.u.copy(), block.us.copy(), y, ys)
    block.y[:] = y
    block.ys[:] = ys


class _StictionValve(_Valve):
    PARAMS: ClassVar[tuple[Param, ...]] = (*STICTION_PARAMS, START_PARAM, *COMMON_PARAMS)
    HAS_START: ClassVar[bool] = True

    COEFFS: ClassVar[tuple[str, ...]] = STICTION_COEFFS

    def nonlinearity(self) -> str | None:
        """The valve's stick-slip in words (S, J in % of span), None without any."""
        s, j = stiction_sj(self.kind, self.params, set(self.given))
        return f"stick-slip S = {s:g} %, J = {j:g} %" if s > 0.0 or j > 0.0 else None

    def coefficients(self) -> dict[str, float]:
        s, j = stiction_sj(self.kind, self.params, set(self.given))
        fs, fd = bands_from_sj(s, j)
        return {**self.common(), "s": s, "j": j, "fs": fs, "fd": fd}


@register
class Choudhury(_StictionValve):
    """Choudhury-Shah-Thornhill two-parameter stiction model (spec 1.2)."""

    kind = "valve.choudhury"
    summary = "valve stiction, Choudhury-Shah-Thornhill S/J model (plant-and-tuning 1.2)"
    kernel = staticmethod(choudhury_kernel)
    STATES: ClassVar[tuple[str, ...]] = CHOUDHURY_STATES

    def model_init(self, x: FloatArray, y0: float) -> None:
        choudhury_init(self.p, x, y0 + self.p[PS.start] * self.p[PS.fd], y0)


@register
class Kano(_StictionValve):
    """Kano et al. stiction model (spec 1.3)."""

    kind = "valve.kano"
    summary = "valve stiction, Kano et al. model (plant-and-tuning 1.3)"
    kernel = staticmethod(kano_kernel)
    STATES: ClassVar[tuple[str, ...]] = KANO_STATES

    def model_init(self, x: FloatArray, y0: float) -> None:
        kano_init(self.p, x, y0 + self.p[PS.start] * self.p[PS.fd], y0)


@register
class He(_StictionValve):
    """He et al. two-layer stiction model (spec 1.4)."""

    kind = "valve.he"
    summary = "valve stiction, He et al. fs/fd model (plant-and-tuning 1.4)"
    kernel = staticmethod(he_kernel)
    STATES: ClassVar[tuple[str, ...]] = HE_STATES

    def model_init(self, x: FloatArray, y0: float) -> None:
        he_init(self.p, x, y0 + self.p[PS.start] * self.p[PS.fd], y0)


@register
class Backlash(_Valve):
    """Friction-dominated backlash of total width b (spec 1.5)."""

    kind = "valve.backlash"
    summary = "valve backlash (deadband) of total width b (plant-and-tuning 1.5)"
    kernel = staticmethod(backlash_kernel)
    HAS_START: ClassVar[bool] = True

    def nonlinearity(self) -> str | None:
        """The backlash in words, None when b = 0."""
        b = float(self.params["b"])
        return f"a backlash of {b:g} %" if b > 0.0 else None
    PARAMS: ClassVar[tuple[Param, ...]] = (
        Param("b", 2.0, _PCT, "total backlash width b (spec 1.5; = Choudhury S with J = 0)",
              lo=0.0, lo_open=False),
        Param("start", "rest", "", "without y0: the first op is the stem position (rest) or the "
              "stem trails it by b/2 (moving_up/moving_down) [I]", "choice",
              choices=("rest", "moving_up", "moving_down")),
        *COMMON_PARAMS,
    )
    COEFFS: ClassVar[tuple[str, ...]] = BACKLASH_COEFFS
    STATES: ClassVar[tuple[str, ...]] = MODEL_STATES

    def coefficients(self) -> dict[str, float]:
        return {**self.common(), "half_width": float(self.params["b"]) / 2.0}


@register
class Resolution(_Valve):
    """Resolution limit with memory: y snaps to the op once they differ by more than r
    (spec 1.5)."""

    kind = "valve.resolution"
    summary = "valve resolution limit with memory (stick-slip snap, plant-and-tuning 1.5)"
    kernel = staticmethod(resolution_kernel)

    def nonlinearity(self) -> str | None:
        """The resolution in words, None when r = 0."""
        r = float(self.params["r"])
        return f"a resolution of {r:g} %" if r > 0.0 else None
    PARAMS: ClassVar[tuple[Param, ...]] = (
        Param("r", 1.0, _PCT, "resolution r: the position snaps to the op when |op - y| > r "
              "(spec 1.5; = Choudhury S = J = r without the tracking branch)", lo=0.0,
              lo_open=False),
        *COMMON_PARAMS,
    )
    COEFFS: ClassVar[tuple[str, ...]] = RESOLUTION_COEFFS
    STATES: ClassVar[tuple[str, ...]] = MODEL_STATES

    def coefficients(self) -> dict[str, float]:
        return {**self.common(), "r": float(self.params["r"])}


@register
class Quantiser(_Valve):
    """Memoryless quantiser y = q·round(op/q) (spec 1.5)."""

    kind = "valve.quantiser"
    summary = "valve position quantiser y = q*round(op/q) (plant-and-tuning 1.5)"
    kernel = staticmethod(quantiser_kernel)

    def nonlinearity(self) -> str | None:
        """The quantisation in words (q = 2 % read K 0.23 and T 4.9 s for 1 and 20 s)."""
        return f"a quantisation step of {float(self.params['q']):g} %"
    PARAMS: ClassVar[tuple[Param, ...]] = (
        Param("q", 0.1, _PCT, "quantisation step q (DAC, stepper or bus resolution; spec 1.5)",
              lo=0.0),
        *COMMON_PARAMS,
    )
    COEFFS: ClassVar[tuple[str, ...]] = QUANTISER_COEFFS
    STATES: ClassVar[tuple[str, ...]] = MODEL_STATES

    def coefficients(self) -> dict[str, float]:
        return {**self.common(), "q": float(self.params["q"])}

    def model_init(self, x: FloatArray, y0: float) -> None:
        x[XM.y] = y0  # the quantiser has no memory: y0 is only the start of the stroke
        x[XM.init] = 1.0
