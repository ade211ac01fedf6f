r"""``s5.pid``: the Siemens SIMATIC S5 integrated PID control block OB 251 (S5-100U, S5-95F,
S5-115U/F), emulated from spec vendor-blocks section 2 and the S5-100U manual page 9-18 (seed
002).

What it is
----------
OB 251 is a firmware block. The user program opens a controller data block (``C DB n``) and
calls ``JU OB 251`` from the time-driven OB 13; the OB 13 interval is the sampling time TA
(spec 2.1). Every value lives in a 16-bit data-block word. The parameters here are those words:
``k`` (DW 1), ``r`` (DW 3), ``ti`` (DW 5), ``td`` (DW 7) as raw words where 1000 ≈ 1.0,
``bgog``/``bgug`` (DW 14/16), the control bits of DR 11 as flags, and the preset of DW 48
(``y0``). The inputs are W (DW 9), X (DW 22), Z (DW 24), XZ (DW 29), YH (DW 12) and the bits
D 11.0 (``auto``) and D 11.2 (``off``), which a user program may change at any scan.

**The block has no clock** (spec 2.5, 2.11). TI = TA/TN and TD = TV/TA are per-sample
coefficients, so each ``step(dt, ...)`` is one OB 13 call whatever ``dt`` is: ``dt`` is checked
(> 0, finite) and otherwise ignored. If the OB 13 interval changes, recompute ``ti`` and ``td``.

Equations (spec 2.4-2.7, seed 002)
----------------------------------
With c the coefficient word divided by the scale (1024 exact, 1000 nominal)::

    XW_k = W_k - X_k                      PW_k = XW_k - XW_{k-1}    QW_k = PW_k - PW_{k-1}
    PZ_k = XZ_k - XZ_{k-1}                QZ_k = PZ_k - PZ_{k-1}    dZ_k = Z_k - Z_{k-1}
    Q_k  = QZ_k if xz_on (D 11.1 = 1) else QW_k
    dPW_k = R·PW_k                        (P element)
    dI_k  = TI·XW_k                       (I element)
    dD_k  = d·(TD·Q_k + dD_{k-1})         (D element and its memory, d = dd_decay; spec 2.6)
    dY_k  = K·(dPW_k + dI_k + dD_k) + dZ_k        (dZ_k = 0 when no_z, D 11.5 = 1)

    positioning (velocity = false, D 11.3 = 0):  Y_k = clamp(Y_{k-1} + dY_k, BGUG, BGOG) → DW 48
    velocity    (velocity = true,  D 11.3 = 1):  DW 48 = clamp(dY_k, BGUG, BGOG)

These are the four correction-rate variants of seed 002 (D 11.1 × D 11.5); with ``dd_decay``
= 1 the D element is the literal printed law dD_k = TD·QW_k + dD_{k-1}. Z is not multiplied
by K. XW = W - X with K > 0 raises the output when X falls (ISA "reverse" action; Siemens
calls K > 0 "direct"); K < 0 inverts the action. XZ is differentiated as given: for a
derivative on the measurement with the usual sign feed xz = -X.

DW 48 is the integrator of the whole controller in positioning mode (spec 2.7): Auto continues
from whatever it holds (bumpless Manual → Auto), ``y0`` presets it, REG_AUS clears it to 0.

Velocity mode (spec 2.8 [V]: "dYA is the limited correcting increment"): DW 48 is dY_k
clamped to [BGUG, BGOG], and that is all. The block holds no integral in this mode (the
actuator integrates), so nothing winds up in it; the I part beyond a limit is what the clamp
cuts off. ``i_suppression`` does not apply: recomputing the increment without dI_k would give
0 for a steady error whose I part alone exceeds the limit, and a motor valve would stall
(issue 11 point 6).

I-action at a limit, positioning mode (spec 2.8, realisation [A]): when the unclamped
Y_k = Y_{k-1} + dY_k is above BGOG and the I element pushes up (K·dI_k > 0), dY_k is
recomputed with dI_k = 0, then clamped; symmetrically at BGUG. The comparison takes the true
sum, before anything limits it (the CPU's fixed-point add reports an overflow, it does not hide
one; only ``overflow = "wrap"``, unchecked two's complement, compares the wrapped sum): a
sum saturated to 16 bits first could never exceed the default BGOG = 32767, and a one-count
change of BGOG would switch the suppression on or off (issue 11 point 6). The
spec's suggested rule says "dI_k > 0"; it is read here as the I element's contribution to
the output, K·dI_k, which is the same thing for K > 0 and the spec's stated intent ("the
direction the I-element would push further") for K < 0. A consequence of this realisation,
kept as the spec's default: when the I element alone would carry Y past the limit (P and D at
rest), the increment is dropped whole and Y stops short of the limit (a test of this reading
of spec 2.8: 120, 140, 140, ... with BGOG = 150); ``i_suppression = "flag"`` lets Y reach the
limit and then holds the I element there.

Manual mode (``auto`` = MAN, D 11.0 = 0; spec 2.9): the algorithm is not computed, but the
histories are kept current (XW_{k-1} and PW_{k-1}; XZ_{k-1} and PZ_{k-1} if xz_on; Z_{k-1} if
not no_z) and dD_{k-1} is set to 0, so the return to Auto is bumpless. The output:

    hold = false, positioning:  Y moves to YH: Y_k = Y_{k-1} + (YH - Y_{k-1})/2 for
                                ``manual_steps`` samples after entering Manual, then Y_k = YH
    hold = false, velocity:     DW 48 = dYH (the yh input)
    hold = true,  positioning:  the last output is held
    hold = true,  velocity:     DW 48 = 0 (no increment, whatever the limits)

BGOG/BGUG stay active in Manual (spec 2.9 [V]): also a held output, and the ``y0`` preset of
DW 48 is limited to [BGUG, BGOG] from the start (a preset outside them is not output).

Controller off (``off`` = OFF, D 11.2 = 1; spec 2.10): DW 18..48 are cleared (the histories,
dD, the X and Z words, the DW 48 accumulator, the limit flags) and the algorithm does not run;
the output is 0. W, YH and the parameters survive. The first call after REG_AUS, like the first
call after construction, starts from the cleared histories, so a step in XW gives P and D kicks
(``first_call``).

Outputs: ``y`` is DW 48; ``dy`` is the change of the output in this scan, Y_k - Y_{k-1}
(positioning; also in Manual and when REG_AUS clears DW 48), or the increment DW 48 itself
(velocity). The S5 has no status: no port carries one, the status bytes of the inputs are
not read, and the outputs are always finite words. Before the first call (issue 11 point 8)
``y`` is DW 48 as the DB holds it: the limited ``y0`` in positioning mode, 0 (no increment)
in velocity mode; ``dy`` is 0. Y lies in [BGUG, BGOG] (positioning) and dY too (velocity),
except the 0 that REG_AUS writes (spec 2.10), a held 0 after it, and the velocity-mode
HANDART 0 (spec 2.9).

Retuning in Auto (issue 12 point 4)
-----------------------------------
The law is a correction-rate (velocity) law (spec 2.5): each call computes an increment dY_k
from the differences PW_k, QW_k and the I element TI·XW_k, and positioning mode only sums the
increments into DW 48 (spec 2.7). The output is never re-evaluated as a gain times the error
(as a positional P + I + D would be), so a new ``k``, ``r``, ``ti`` or ``td`` (``set_params``
between calls) does not bump Y: the next call adds the increment the new coefficients give,
dY_k = K_new·(R_new·PW_k + TI_new·XW_k + dD_k) + dZ_k, to DW 48 as it was, with the histories
as they were. At a steady error (PW = QW = 0) Y moves by K_new·TI_new·XW only (plus what is
left of a decaying dD, which the new K multiplies as the law says). This is the vendor's
behaviour, bumpless by construction, so there is no ``retune`` option. In velocity mode DW 48
is the new increment itself; in Manual a change does nothing until Auto, which continues from
DW 48 (spec 2.9).

Arithmetic
----------
``arithmetic = "native"`` (default) is 16-bit fixed point: every input is rounded to the
nearest integer (half away from zero) and, as a DB word holds 16 bits, a value beyond
-32768..32767 is saturated or wrapped (its low 16 bits) as ``overflow`` says, like every
intermediate: 1e308 gives 32767 (or 0 wrapped). This is how the user program's integer words
reach the DB (an emulator interface choice, not a firmware point; the S5 has no status to
mark such a value). Every
coefficient product c·v is the integer word (coefficient × v)/scale rounded by ``rounding``;
every intermediate (XW, PW, QW, PZ, QZ, dZ, the products, dD, the sums, dY, Y) is a 16-bit word,
saturated or wrapped by ``overflow``. The ×0.001 of the manual is really ÷1024 (spec 2.2):
k = 1000 is gain 0.9765625 with ``scale = "exact"`` (default) and 1.0 with ``"nominal"``.

Rounding loses fractions of a count at every product, so native results differ from the
spec's exact real-number values by about a count per step (spec 2.13), and a decaying D
memory ends a count or two short: the law-A kick of the spec 2.13 D-element check settles at 101
instead of 100, the ramp check at 18 instead of TD·r = 20.

**The native I element has a dead zone** (real S5 behaviour, from the word arithmetic): with
P and D at rest (XW constant) the increment is dY = round(K·dI/1024) with dI =
round(TI·XW/1024). dI is 0 while |XW| <= 512/TI counts (500/TI with ``scale = "nominal"``;
with the default half-to-even rounding an exact half rounds to 0), and for |K| <= 512 a dI of
1 still gives dY = 0: the I element then needs |dI| > 512/|K|. Inside the zone Y stops, so
a loop settles off the setpoint by up to that much:

    TI (DW 5)   1      10     50     100    200    500    above 512
    |XW| <=     512    51     10     5      2      1      0 (no dead zone)     (|K| > 512)

e.g. TI = 100 with K = 500: dI = 1 needs |XW| >= 6 but gives dY = round(0.49) = 0, dI = 2
needs |XW| >= 16, so the zone is |XW| <= 15. ``arithmetic = "float"`` has no dead zone.

``arithmetic = "float"`` runs the same equations in double precision for engineering studies:
no rounding and no word overflow in between; the inputs are still limited to the word range
-32768..32767 (they are DB words), and ``scale`` applies as above.

Options for the spec's [A]/[?] points
-------------------------------------
* ``rounding`` = ``"nearest_even"`` (default) | ``"nearest"`` | ``"floor"`` | ``"truncate"``:
  how each fixed-point product is rounded to a word [?] (spec 2.13; an open question, spec 8
  item 2). ``floor`` is a plain arithmetic shift; ``nearest`` rounds halves away from zero. The
  default is the one that keeps the spec's 2.13 example within its ±1 count per step (floor
  and truncate lose up to 2 counts a step there) and lets the law-A memory decay to zero (with
  ``nearest`` and ``floor``, dD sticks at -1 because ½·(-1) rounds to -1, and a positioning
  controller then ramps by about a count per sample at zero error).
* ``overflow`` = ``"saturate"`` (default) | ``"wrap"``: 16-bit intermediates in native mode
  saturate at -32768/32767 [A] (spec 2.14), or wrap around as unchecked two's complement would.
  The spec's "|K| ≤ 1500 with a D part" is a guard against exactly this overflow, not a check.
* ``dd_decay`` = 0.5 (default, law A: a derivative kick that halves each sample, a ramp of slope
  r gives TD·r) | 1.0 (the literal printed law: D acts as extra P of gain TD) | any value in
  [0, 1] [?] (spec 2.6).
* ``i_suppression`` = ``"recompute"`` (default: the unclamped result beyond a limit with the I
  element pushing further is recomputed with dI = 0, then clamped [A], spec 2.8) | ``"flag"``
  (dI = 0 while the previous scan's output was at that limit, as the CPU 928B's MERK flags,
  spec 2.8/2.12) | ``"none"`` (clamp only). Positioning mode only: in velocity mode the
  increment is clamped whatever this says (above).
* ``manual_steps`` = 3 (default): the manual-mode exponential transition (spec 2.9, law [A]):
  Y halves its distance to YH for this many samples after entering Manual, then equals YH;
  0 jumps to YH at once.
* ``first_call`` = ``"zero"`` (default: the histories start from the DB contents, all zero, so
  the first PW and QW can kick [A], spec 2.10) | ``"inputs"`` (the first active scan, after
  construction or after REG_AUS, takes XW_{k-1} = XW_k, Z_{k-1} = Z_k, XZ_{k-1} = XZ_k and
  PW_{k-1} = PZ_{k-1} = 0: no kick).
* ``bad_input`` = ``"hold"`` (default) | ``"last"``: a NaN or infinite value in an input the scan
  uses (w and x always; z unless no_z; xz if xz_on; yh in Manual with hold = false) [A]. The S5
  has no status (spec 7), so this is the emulator's choice. ``hold`` skips the scan: the
  histories, dD and DW 48 are kept, positioning holds the output and velocity outputs a zero
  increment (the actuator stays). ``last`` runs the scan with the last finite value of that
  input, as the DB word would keep it when the user program writes nothing new. An ``auto``
  or ``off`` bit that is NaN or infinite (no bit) holds the scan in both settings. A finite
  value beyond the word range is not bad input: it is saturated or wrapped (Arithmetic).

Quirks reproduced (spec 2.14)
-----------------------------
TI and TD are dimensionless per-sample coefficients, not times; ×0.001 is ÷1024; K < 0 inverts
the action and K multiplies P, I and D but R only P; Z bypasses K; DW 48 is the integrator
(positioning) or the increment (velocity); limits bound the increment in velocity mode; the
first call after the DB is created or after REG_AUS kicks; large |K| with a D part overflows.
The high byte DL 11 is internal to the firmware and is not modelled. The CPU 928B OB 250/251
(float DB, trapezoidal I, BUMP bit) is a different block and is not emulated (spec 2.12).

Worked example
--------------
The spec 2.13 PI step (K = R = 1000, TI = 100, nominal scaling, W steps 0 → 100 with X = 0)::

    import loopworks

    pid = loopworks.create_block("s5.pid", k=1000, r=1000, ti=100, scale="nominal")
    for _ in range(5):
        print(pid.step(1.0, w=100.0, x=0.0)["y"].value)  # 110, 120, 130, 140, 150

The same through ``loopworks replay s5.pid step.csv -p k=1000 -p ti=100 -p scale=nominal``
with ``step.csv``::

    t,w,x,auto,off
    0,100,0,1,0
    1,100,0,1,0
    2,100,0,1,0
    3,100,0,0,0
    4,100,0,1,0

(rows 0-2 give y = 110, 120, 130; row 3 is Manual with yh = 0: y halves to 65; row 4 is Auto
again and continues from DW 48: 75).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

from loopworks.blocks.block import Block
from loopworks.blocks.controller import Action, Controller, Handover, Roles
from loopworks.blocks.kernel import FloatArray, IntArray, primitive
from loopworks.blocks.law import (
    DiscreteLaw,
    Ideal,
    ParamValue,
    Realisation,
    no_ideal,
    number,
    word,
)
from loopworks.blocks.layout import index
from loopworks.blocks.params import Param, Port, validate
from loopworks.blocks.primitives import clamp, finite
from loopworks.blocks.registry import register
from loopworks.errors import ParameterError

WORD_MIN = -32768.0
WORD_MAX = 32767.0
_WHOLE = 4503599627370496.0  # 2^52: every float64 at least this large is a whole number

ROUND_NEAREST_EVEN, ROUND_NEAREST, ROUND_FLOOR, ROUND_TRUNCATE = 0.0, 1.0, 2.0, 3.0
ISUP_RECOMPUTE, ISUP_FLAG, ISUP_NONE = 0.0, 1.0, 2.0

INPUTS = (
    Port("w", 0.0, "count", "setpoint W (DW 9)"),
    Port("x", 0.0, "count", "actual value X (DW 22)"),
    Port("z", 0.0, "count", "disturbance Z (DW 24), used unless no_z"),
    Port("xz", 0.0, "count", "derivative input XZ (DW 29), used if xz_on"),
    Port("yh", 0.0, "count", "manual value YH (positioning) or manual increment dYH "
         "(velocity) (DW 12)"),
    Port("auto", 1.0, "", "D 11.0: AUTO (1) automatic, MAN (0) manual (spec 2.9)",
         choices=("MAN", "AUTO")),
    Port("off", 0.0, "", "D 11.2 REG_AUS: OFF (1) clears DW 18..48 and suspends the "
         "block, ACTIVE (0) runs it (spec 2.10)", choices=("ACTIVE", "OFF")),
)
OUTPUTS = (
    Port("y", 0.0, "count", "DW 48: the position Y_k (positioning) or the increment dY_k "
         "(velocity)"),
    Port("dy", 0.0, "count", "change of the output this scan: Y_k - Y_{k-1} "
         "(positioning) or dY_k (velocity)"),
)
#: the coefficient array p (coefficients())
COEFFS = ("k", "r", "ti", "td", "bgog", "bgug", "y0", "scale", "native", "rounding", "wrap",
          "dd_decay", "isup", "manual_steps", "first_inputs", "bad_last", "xz_on", "velocity",
          "hold", "no_z")
#: the state array x: DW 48, the history words, the last input words, flags
STATES = ("dw48", "xw1", "pw1", "dd1", "z1", "xz1", "pz1", "w", "x", "yh", "manual_n", "limit",
          "first")
# XS, not X: X is the S5's actual value (DW 22), the input U.x
P, XS, U, Y = index(COEFFS, "P"), index(STATES, "XS"), index(INPUTS, "U"), index(OUTPUTS, "Y")

#: the coefficient words' divisor by ``scale`` (spec 2.2: the manual's ×0.001 is ÷1024)
SCALES: dict[str, float] = {"exact": 1024.0, "nominal": 1000.0}
_ROUNDINGS = ("nearest_even", "nearest", "floor", "truncate")
_ISUPS = ("recompute", "flag", "none")


@primitive
def s5_round(q: float, mode: float) -> float:
    """q rounded to an integer: half to even, half away from zero, floor or toward zero.
    A finite q of 2^52 or more is a whole number already (and would overflow the integer
    that compiled ``math.floor`` returns): it passes unchanged."""
    if not (q < _WHOLE and q > -_WHOLE):
        return q
    f = float(math.floor(q))
    if mode == ROUND_FLOOR:
        return f
    if mode == ROUND_TRUNCATE:
        return f if q >= 0.0 else float(math.ceil(q))
    rest = q - f
    if rest > 0.5:
        return f + 1.0
    if rest < 0.5:
        return f
    if mode == ROUND_NEAREST:
        return f + 1.0 if q > 0.0 else f
    return f if math.floor(f * 0.5) * 2.0 == f else f + 1.0


def integral_dead_zone(k: float, ti: float, scale: float, rounding: str = "nearest_even"
                       ) -> int:
    """The largest steady |XW| (counts) for which the native I element leaves Y still (the
    module docstring's dead zone): dY = round(K·round(TI·XW/scale)/scale) = 0 with P and D at
    rest, as the kernel computes them (``s5_mul``); 0 when TI = 0 or K = 0 (no I element)."""
    mode = float(_ROUNDINGS.index(rounding))
    if ti == 0.0 or k == 0.0:
        return 0
    for xw in range(1, 32768):
        di = s5_round(ti * xw / scale, mode)
        if s5_round(k * di / scale, mode) != 0.0:
            return xw - 1
    return 32767


@primitive
def s5_word(v: float, native: bool, wrap: bool) -> float:
    """A 16-bit intermediate: saturated to -32768..32767 or wrapped (native); float: v."""
    if not native:
        return v
    if wrap:  # two's complement: the low 16 bits (% is exact for a whole v of any size)
        r = v % 65536.0
        return r - 65536.0 if r > WORD_MAX else r
    return clamp(v, WORD_MIN, WORD_MAX)


@primitive
def s5_mul(c: float, v: float, scale: float, native: bool, mode: float, wrap: bool) -> float:
    """The fixed-point product c·v/scale (scale 1024 or 1000), rounded to a word (native)."""
    q = c * v / scale
    if not native:
        return q
    return s5_word(s5_round(q, mode), True, wrap)


@primitive
def s5_input(v: float, native: bool, wrap: bool) -> float:
    """A finite input as the DB word holds it. Native: rounded to an integer (halves away from
    zero), then a value outside -32768..32767 saturated or wrapped as ``overflow`` says (a DB
    word holds 16 bits); float: limited to the word range."""
    if native:
        return s5_word(s5_round(v, ROUND_NEAREST), True, wrap)
    return clamp(v, WORD_MIN, WORD_MAX)


@primitive
def s5_sum(a: float, b: float, native: bool, wrap: bool) -> float:
    """Y_{k-1} + dY_k as the limit comparison sees it: the true sum (the CPU's add flags an
    overflow, it does not hide it), wrapped only with ``overflow = "wrap"`` (native)."""
    if native and wrap:
        return s5_word(a + b, True, True)
    return a + b


@primitive
def _s5_hold(x: FloatArray, y: FloatArray, y_prev: float, velocity: bool) -> None:
    """A skipped scan (bad input): DW 48 is kept in positioning mode; velocity mode outputs
    a zero increment, so the actuator stays."""
    if velocity:
        x[XS.dw48] = 0.0
        y[Y.y] = 0.0
        y[Y.dy] = 0.0
    else:
        y[Y.y] = y_prev
        y[Y.dy] = 0.0


def s5_pid_kernel(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                  y: FloatArray, ys: IntArray) -> None:
    """One OB 251 call (equations in the module docstring). ``dt`` is not used: no clock.
    The S5 has no status: ``us`` is not read (the values alone decide)."""
    native = p[P.native] != 0.0
    wrap = p[P.wrap] != 0.0
    mode = p[P.rounding]
    scale = p[P.scale]
    hi = p[P.bgog]
    lo = p[P.bgug]
    velocity = p[P.velocity] != 0.0
    xz_on = p[P.xz_on] != 0.0
    use_z = p[P.no_z] == 0.0
    y_prev = x[XS.dw48]
    if not finite(u[U.off]) or not finite(u[U.auto]):  # a control bit that is no bit: hold
        _s5_hold(x, y, y_prev, velocity)
        return
    if u[U.off] > 0.5:  # REG_AUS: clear DW 18..48 and do not compute (spec 2.3, 2.10)
        for i in (XS.dw48, XS.xw1, XS.pw1, XS.dd1, XS.z1, XS.xz1, XS.pz1, XS.x, XS.manual_n,
                  XS.limit):
            x[i] = 0.0
        x[XS.first] = 1.0
        y[Y.y] = 0.0
        y[Y.dy] = 0.0 if velocity else -y_prev
        return
    auto = u[U.auto] > 0.5
    manual_follow = not auto and p[P.hold] == 0.0
    last = p[P.bad_last] != 0.0
    # inputs: a non-finite value takes the DB word's last content; the scan is bad when it is
    # one the scan uses and bad_input = hold
    bad = False
    w = u[U.w]
    if not finite(w):
        w = x[XS.w]
        bad = True
    xv = u[U.x]
    if not finite(xv):
        xv = x[XS.x]
        bad = True
    z = u[U.z]
    if not finite(z):
        z = x[XS.z1]
        bad = bad or use_z
    xz = u[U.xz]
    if not finite(xz):
        xz = x[XS.xz1]
        bad = bad or xz_on
    yh = u[U.yh]
    if not finite(yh):
        yh = x[XS.yh]
        bad = bad or manual_follow
    if bad and not last:  # bad_input = hold: skip the scan, keep every history
        _s5_hold(x, y, y_prev, velocity)
        return
    w = s5_input(w, native, wrap)
    xv = s5_input(xv, native, wrap)
    z = s5_input(z, native, wrap)
    xz = s5_input(xz, native, wrap)
    yh = s5_input(yh, native, wrap)
    x[XS.w] = w
    x[XS.x] = xv
    x[XS.yh] = yh
    xw = s5_word(w - xv, native, wrap)
    if x[XS.first] != 0.0 and p[P.first_inputs] != 0.0:  # first_call = inputs: no kick
        x[XS.xw1] = xw
        x[XS.pw1] = 0.0
        x[XS.xz1] = xz
        x[XS.pz1] = 0.0
        x[XS.z1] = z
        x[XS.dd1] = 0.0
    x[XS.first] = 0.0
    pw = s5_word(xw - x[XS.xw1], native, wrap)
    q = s5_word(pw - x[XS.pw1], native, wrap)  # QW
    pz = 0.0
    if xz_on:
        pz = s5_word(xz - x[XS.xz1], native, wrap)
        q = s5_word(pz - x[XS.pz1], native, wrap)  # QZ
    dz = 0.0
    if use_z:
        dz = s5_word(z - x[XS.z1], native, wrap)
    if auto:
        dpw = s5_mul(p[P.r], pw, scale, native, mode, wrap)
        di = s5_mul(p[P.ti], xw, scale, native, mode, wrap)
        tq = s5_mul(p[P.td], q, scale, native, mode, wrap)
        dd = s5_mul(p[P.dd_decay], s5_word(tq + x[XS.dd1], native, wrap), 1.0, native, mode, wrap)
        total = s5_word(s5_word(dpw + di, native, wrap) + dd, native, wrap)
        dy = s5_word(s5_mul(p[P.k], total, scale, native, mode, wrap) + dz, native, wrap)
        if velocity:  # spec 2.8: DW 48 = the limited increment (clamped below)
            v = dy
        else:
            # the unclamped Y_k = Y_{k-1} + dY_k is compared with the limits before anything
            # limits it (spec 2.8): a saturated sum could never exceed BGOG = 32767
            v = s5_sum(y_prev, dy, native, wrap)
            push = p[P.k] * di  # the direction the I element moves the output
            isup = p[P.isup]
            suppress = False
            if isup == ISUP_RECOMPUTE:
                suppress = (v > hi and push > 0.0) or (v < lo and push < 0.0)
            elif isup == ISUP_FLAG:
                suppress = (x[XS.limit] > 0.0 and push > 0.0) or (x[XS.limit] < 0.0 and push < 0.0)
            if suppress:  # spec 2.8: recompute with dI = 0
                total = s5_word(s5_word(dpw, native, wrap) + dd, native, wrap)
                dy = s5_word(s5_mul(p[P.k], total, scale, native, mode, wrap) + dz, native, wrap)
                v = s5_sum(y_prev, dy, native, wrap)
        x[XS.dd1] = dd
        x[XS.manual_n] = 0.0
    else:  # Manual (spec 2.9): no algorithm; dD_{k-1} = 0
        if velocity:
            v = 0.0 if p[P.hold] != 0.0 else yh
        elif p[P.hold] != 0.0:
            v = y_prev
        elif x[XS.manual_n] < p[P.manual_steps]:
            gap = s5_word(yh - y_prev, native, wrap)
            v = s5_word(y_prev + s5_mul(0.5, gap, 1.0, native, mode, wrap), native, wrap)
            x[XS.manual_n] = x[XS.manual_n] + 1.0
        else:
            v = yh
        x[XS.dd1] = 0.0
    # spec 2.8, 2.9: the limits bound Y or dY, in Manual too; HANDART = 1 in velocity mode
    # is dYA = 0 (the actuator stays) whatever the limits
    out = 0.0 if velocity and not auto and p[P.hold] != 0.0 else clamp(v, lo, hi)
    x[XS.limit] = 1.0 if v >= hi else (-1.0 if v <= lo else 0.0)
    x[XS.xw1] = xw
    x[XS.pw1] = pw
    if xz_on:
        x[XS.xz1] = xz
        x[XS.pz1] = pz
    if use_z:
        x[XS.z1] = z
    x[XS.dw48] = out
    y[Y.y] = out
    y[Y.dy] = out if velocity else out - y_prev


def _word_param(name: str, default: int, meaning: str, lo: float = WORD_MIN,
                hi: float = WORD_MAX, unit: str = "×0.001") -> Param:
    return Param(name, default, unit, meaning, "int", lo=lo, hi=hi, lo_open=False,
                 hi_open=False)


@register
class S5PID(Controller, Block):
    """Siemens SIMATIC S5 OB 251 PID (16-bit fixed point, velocity/positioning, DB words)."""

    kind = "s5.pid"
    summary = ("Siemens S5 OB 251 integrated PID: DB words, ÷1024 fixed point, "
               "positioning (DW 48 sum) or velocity algorithm")
    kernel = staticmethod(s5_pid_kernel)

    PARAMS: ClassVar[tuple[Param, ...]] = (
        _word_param("k", 1000, "proportional coefficient K (DW 1): gain = k/1024 (scale exact) "
                    "or k/1000 (nominal); k < 0 inverts the action; |k| ≤ 1500 is safe with a "
                    "D part, beyond it products can overflow (spec 2.2)"),
        _word_param("r", 1000, "weight R of the P element (DW 3), scaled as k; 0 = pure I/ID "
                    "(spec 2.2, 2.5)"),
        _word_param("ti", 0, "integral coefficient TI = TA/TN per sample (DW 5), scaled as k; 0 = "
                    "no I (spec 2.2, 2.5)", lo=0.0, hi=9999.0),
        _word_param("td", 0, "derivative coefficient TD = TV/TA per sample (DW 7), scaled as k; "
                    "range not documented [?], negative values refused (spec 2.2, 2.6)",
                    lo=0.0),
        _word_param("bgog", 32767, "upper limit BGOG (DW 14) of Y (positioning) or of the "
                    "increment dY (velocity) (spec 2.8)", unit="count"),
        _word_param("bgug", -32768, "lower limit BGUG (DW 16), ≤ bgog (spec 2.8)",
                    unit="count"),
        Param("xz_on", False, "", "D 11.1 XZ_EIN: the differentiator takes xz (DW 29) instead "
              "of XW (spec 2.3, 2.5)", "bool"),
        Param("velocity", False, "", "D 11.3 GESCHW: velocity algorithm, y = increment dY; "
              "false = positioning, y = running sum in DW 48 (spec 2.3, 2.7)", "bool"),
        Param("hold", False, "", "D 11.4 HANDART: Manual holds the output (positioning) or "
              "gives dY = 0 (velocity); false = Manual follows yh (spec 2.3, 2.9)", "bool"),
        Param("no_z", False, "", "D 11.5 NO_Z: no feedforward; false = dZ = Z_k - Z_{k-1} is "
              "added to dY, not multiplied by K (spec 2.3, 2.5)", "bool"),
        _word_param("y0", 0, "initial content of DW 48: presets the output in positioning "
                    "mode (spec 2.7)", unit="count"),
        Param("arithmetic", "native", "", "native: 16-bit fixed point words; float: the same "
              "equations in floating point (spec 2.2)", "choice", choices=("native", "float")),
        Param("scale", "exact", "", "coefficient scaling: exact ÷1024 (the firmware) or "
              "nominal ÷1000 (the manual's ×0.001) (spec 2.2)", "choice",
              choices=("exact", "nominal")),
        Param("rounding", "nearest_even", "", "[?] rounding of each fixed-point product in "
              "native mode (spec 2.13)", "choice", choices=_ROUNDINGS),
        Param("overflow", "saturate", "", "[A] 16-bit intermediates in native mode saturate "
              "or wrap (spec 2.14)", "choice", choices=("saturate", "wrap")),
        Param("dd_decay", 0.5, "", "[?] factor d of the D memory dD_k = d·(TD·Q_k + dD_{k-1}): "
              "0.5 = law A, 1.0 = the literal printed law (spec 2.6)", lo=0.0, hi=1.0,
              lo_open=False, hi_open=False),
        Param("i_suppression", "recompute", "", "[A] I-action at a limit: recompute without "
              "dI, the previous scan's limit flag (CPU 928B style), or none (spec 2.8)",
              "choice", choices=_ISUPS),
        Param("manual_steps", 3, "samples", "[A] Manual transition: Y halves its distance to "
              "YH for this many samples, then equals YH (spec 2.9)", "int", lo=0.0, hi=1000.0,
              lo_open=False, hi_open=False),
        Param("first_call", "zero", "", "[A] first call histories: zero (the DB contents; "
              "kicks possible) or inputs (no kick) (spec 2.10)", "choice",
              choices=("zero", "inputs")),
        Param("bad_input", "hold", "", "[A] a NaN/inf input the scan uses: hold (skip the "
              "scan) or last (use the last finite value, as the DB word keeps it) (spec 7: "
              "the S5 has no status)", "choice", choices=("hold", "last")),
    )
    INPUTS: ClassVar[tuple[Port, ...]] = INPUTS
    OUTPUTS: ClassVar[tuple[Port, ...]] = OUTPUTS
    COEFFS: ClassVar[tuple[str, ...]] = COEFFS
    STATES: ClassVar[tuple[str, ...]] = STATES
    # the controller interface (loopworks.blocks.controller); D 11.0 and YH, spec 2.9
    ROLES: ClassVar[Roles] = Roles(sp="w", pv="x", out="y", ff="z", mode="auto", man_out="yh")
    AUTOMATIC: ClassVar[dict[str, Any]] = {"auto": "AUTO"}
    MANUAL: ClassVar[dict[str, Any]] = {"auto": "MAN"}
    #: W is a 16-bit fixed-point data-block word (spec 2.2)
    SP_WORD: ClassVar[tuple[int, int] | None] = (-32768, 32767)
    #: XW = W - X with K > 0 is reverse acting (Siemens calls it "direct"), spec 2.5
    ACTION: ClassVar[Action] = Action("k", "<", 0)
    #: a relay test puts the block in Manual (D 11.0 = 0) following YH; DW 48 keeps the
    #: manual value, so Auto continues from it bumplessly (spec 2.7, 2.9)
    HANDOVER: ClassVar[Handover] = Handover((("auto", "inactive"), ("yh", "out")))

    @classmethod
    def output_range(cls, params: Mapping[str, Any]) -> tuple[float, float]:
        """BGUG..BGOG (DW 16, DW 14), counts: Y's limits (the increment's in velocity mode)."""
        return float(params["bgug"]), float(params["bgog"])

    @classmethod
    def incremental(cls, params: Mapping[str, Any]) -> str | None:
        """The velocity algorithm (D 11.3) outputs the increment dY_k (spec 2.7)."""
        return ("velocity = true: y is the increment dY (the positioning algorithm, "
                "velocity = false, gives the position)" if params["velocity"] else None)

    # -- the discrete law (loopworks.blocks.law), both ways ---------------------------------
    LAW_CONTEXT: ClassVar[tuple[str, ...]] = ("pv_span", "out_span", "sample_time")
    LAW_PARAMS: ClassVar[tuple[str, ...]] = ("k", "r", "ti", "td", "scale", "dd_decay",
                                             "xz_on", "arithmetic")
    PER_SAMPLE: ClassVar[bool] = True

    #: context ``pv_span``, ``out_span``: counts of 100 % (default 1000, 1000)
    SPANS: ClassVar[tuple[tuple[str, float], tuple[str, float]]] = (
        ("pv_span", 1000.0), ("out_span", 1000.0))

    @classmethod
    def law(cls, params: Mapping[str, Any], dt: float | None,
            context: Mapping[str, Any]) -> DiscreteLaw:
        """Spec 2.2, 2.5, 2.6: K = k/scale, R = r/scale, TI = ti/scale, TD = td/scale (scale
        1024 exact, 1000 nominal), TA = the OB 13 interval (context ``sample_time``, else
        ``dt``). The velocity law dY = K[R·PW + TI·XW + dD] summed gives the position
        Y = K·R·XW + K·TI·ΣXW + K·ΣdD, so Kc = |K|·R and Ti = R·TA/TI (= R·TN). Law A,
        dD_k = d(TD·QW_k + dD_{k-1}) with d = dd_decay, sums to
        ΣdD = d·TD(1 - z⁻¹)/(1 - d·z⁻¹)·E: the pid's backward-Euler filtered D with
        Tf = d·TA/(1 - d) and Kc·Td = |K|·d·TD·TA/(1 - d) (for d = 0.5: Tf = TA, Td = TV/R).
        d = 1 (the literal law) is extra P: Kc = |K|(R + TD), no D. K < 0 is direct action
        (spec 2.5: the Siemens "direct" for K > 0 is ISA reverse)."""
        kind = cls.kind
        prm: dict[str, Any] = validate(kind, cls.PARAMS, dict(params))
        ta = context.get("sample_time", dt)
        if ta is None:
            raise ParameterError("s5.pid: parameter 'sample_time' (the OB 13 interval TA, s) "
                                 "is required: allowed (0, inf) s")
        ta = number("sample_time", ta, kind=kind)
        pv_span, out_span = cls.spans(context)
        scale = SCALES[prm["scale"]]
        big_k = prm["k"] / scale
        r, ti_c, td_c = prm["r"] / scale, prm["ti"] / scale, prm["td"] / scale
        d = float(prm["dd_decay"])
        mag = abs(big_k)
        flags: list[str] = []
        if d >= 1.0:  # the literal law: D acts as extra P of gain TD (spec 2.6)
            kc = mag * (r + td_c)
            kd = 0.0
            tf = 0.0
        else:
            kc = mag * r
            kd = mag * d * td_c * ta / (1.0 - d)
            tf = d * ta / (1.0 - d) if kd > 0.0 else 0.0
        if not kc > 0.0:
            raise no_ideal(kind, "k·r" if mag > 0.0 else "k", prm["k"] if mag == 0.0 else
                           f"{prm['k']}·{prm['r']}")
        ti = kc * ta / (mag * ti_c) if ti_c > 0.0 else math.inf
        if prm["xz_on"]:
            flags.append("xz_on: the S5 differentiates the XZ input, not the error (not "
                         "converted; treated as D on the error).")
        notes = [f"S5 at TA = {ta:g} s, scale {prm['scale']} (÷{scale:g}), dd_decay {d:g}."]
        if prm["arithmetic"] == "native":
            notes.append("Native fixed point rounds every product (about a count per scan); "
                         "that is signal rounding, not counted here.")
        ideal = Ideal(kc * pv_span / out_span, ti, kd / kc, tf, big_k < 0.0)
        return DiscreteLaw(ideal, dt=ta, flags=tuple(flags), notes=tuple(notes), words=True)

    @classmethod
    def from_law(cls, law: DiscreteLaw, dt: float | None,
                 context: Mapping[str, Any]) -> Realisation:
        """The words K, R, TI, TD for TA = context ``sample_time``, else ``dt``: R = context
        ``r`` (default the scale: 1.0), K = Kc/R, TI = R·TA/Ti, TD = R·Td·(1 - d)/(d·TA) with
        d = context ``dd_decay`` (default 0.5, law A), rounded half up to words; K < 0 for
        direct action."""
        kind = cls.kind
        ideal = law.ideal
        if "sample_time" in context:
            dt = number("sample_time", context["sample_time"], kind=kind)
        if dt is None:
            raise ParameterError("s5.pid: parameter 'sample_time' (the OB 13 interval TA, s) "
                                 "is required: allowed (0, inf) s")
        pv_span, out_span = cls.spans(context)
        scale_name = str(context.get("scale", "exact")).lower()
        if scale_name not in SCALES:
            raise ParameterError(f"s5.pid: parameter 'scale' = {scale_name!r} is not allowed: "
                                 "expected one of " + ", ".join(SCALES))
        scale = SCALES[scale_name]
        d = number("dd_decay", context.get("dd_decay", 0.5), 0.0, lo_open=False, kind=kind)
        kc = ideal.kc * out_span / pv_span
        r_given = number("r", context["r"], kind=kind) if "r" in context else scale
        r_word = int(r_given)
        if not 0 < r_word <= 32767 or r_word != r_given:
            raise ParameterError(f"s5.pid: parameter 'r' = {r_given:g} is out of range: allowed "
                                 "1..32767 (integer word)")
        r = r_word / scale
        big_k = kc / r
        ti_c = r * dt / ideal.ti if ideal.ti < math.inf else 0.0
        td_c = 0.0
        if ideal.td > 0.0:
            if not 0.0 < d < 1.0:
                raise ParameterError(f"s5.pid: parameter 'dd_decay' = {d:g} is out of range "
                                     "for a derivative: allowed (0, 1) (law A: 0.5)")
            td_c = r * ideal.td * (1.0 - d) / (d * dt)
        # K is a signed word, -32768..+32767 (spec 2.2): a direct-acting K may reach 32768
        k_word = word("k", big_k * scale, kind, 32768.0 if ideal.direct else 32767.0)
        td_word = word("td", td_c * scale, kind)
        if ideal.ti < math.inf and word("ti", ti_c * scale, kind, 9999.0) == 0:
            raise ParameterError(
                f"s5.pid: parameter 'ti' = {ideal.ti:g} s is out of range: allowed up to "
                f"{2.0 * r_word * dt:g} s (TI = R·TA/Ti >= 0.5 word, so the integral is not "
                "rounded away) or inf")
        out: dict[str, ParamValue] = {
            "k": -k_word if ideal.direct else k_word, "r": r_word,
            "ti": word("ti", ti_c * scale, kind, 9999.0), "td": td_word,
            "scale": scale_name, "dd_decay": d}
        notes = [f"S5 words for TA = {dt:g} s."]
        arithmetic = str(context.get("arithmetic", "native")).lower()
        if arithmetic not in ("native", "float"):
            raise ParameterError(f"{kind}: parameter 'arithmetic' = {arithmetic!r} is not "
                                 "allowed: expected one of native, float")
        if arithmetic == "float":
            out["arithmetic"] = "float"
        ti_word = int(out["ti"])
        if arithmetic == "native" and ti_word > 0:
            zone = integral_dead_zone(k_word, ti_word, scale)
            if zone > 0:
                notes.append(
                    f"In native arithmetic (rounding half to even) the I element does not "
                    f"move Y for a steady |XW| "
                    f"of up to {zone} counts ({100.0 * zone / pv_span:.3g} % of the PV span; "
                    "its words round K·TI·XW to 0): the loop can settle that far from the "
                    "setpoint (arithmetic = float has no dead zone; a larger TI word, from "
                    "a larger R or a longer TA, narrows it).")
        if k_word > 1500 and td_word > 0:
            notes.append("|k| > 1500 with a D part can overflow the 16-bit products in native "
                         "arithmetic (spec 2.2).")
        return Realisation(out, dt, {"sample_time": dt}, tuple(notes))

    def coefficients(self) -> dict[str, float]:
        prm: dict[str, Any] = self.params
        if prm["bgug"] > prm["bgog"]:
            raise ParameterError(
                f"s5.pid: parameter 'bgug' = {prm['bgug']} is out of range: allowed "
                f"[-32768, {prm['bgog']}] (at most bgog)")
        return {"k": float(prm["k"]), "r": float(prm["r"]), "ti": float(prm["ti"]),
                "td": float(prm["td"]), "bgog": float(prm["bgog"]), "bgug": float(prm["bgug"]),
                "y0": float(prm["y0"]),
                "scale": SCALES[prm["scale"]],
                "native": 1.0 if prm["arithmetic"] == "native" else 0.0,
                "rounding": float(_ROUNDINGS.index(prm["rounding"])),
                "wrap": 1.0 if prm["overflow"] == "wrap" else 0.0,
                "dd_decay": float(prm["dd_decay"]),
                "isup": float(_ISUPS.index(prm["i_suppression"])),
                "manual_steps": float(prm["manual_steps"]),
                "first_inputs": 1.0 if prm["first_call"] == "inputs" else 0.0,
                "bad_last": 1.0 if prm["bad_input"] == "last" else 0.0,
                "xz_on": 1.0 if prm["xz_on"] else 0.0,
                "velocity": 1.0 if prm["velocity"] else 0.0,
                "hold": 1.0 if prm["hold"] else 0.0,
                "no_z": 1.0 if prm["no_z"] else 0.0}

    def initial_state(self) -> list[float]:
        """The DB before the first call: histories 0 (spec 2.10); DW 48 = the ``y0`` preset,
        limited to [BGUG, BGOG] (the limits are always active, spec 2.9) in positioning mode,
        0 (no increment) in velocity mode."""
        x = [0.0] * self.n_x
        if self.p[P.velocity] == 0.0:
            x[XS.dw48] = min(max(self.p[P.y0], self.p[P.bgug]), self.p[P.bgog])
        x[XS.first] = 1.0
        return x

    def initial_outputs(self) -> list[float]:
        """Before the first call y is DW 48 (the preset Y, or no increment) and dy is 0."""
        return [float(self.x[XS.dw48]), 0.0]
