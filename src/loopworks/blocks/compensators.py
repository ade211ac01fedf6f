r"""Generic stiction compensators: kinds ``compensator.knocker``,
``compensator.constant_reinforcement`` and ``compensator.two_move``.

All three sit where the DeltaV compensator (``deltav.stick_slip``) sits: between the controller
and the valve. They add a correction u_c to the controller output before the valve,
x = u_PID + u_c (plant-and-tuning 2.1).

Port convention (the same for the three kinds)
-----------------------------------------------

* input ``op_in`` (%): the controller output, e.g. ``"comp.op_in" = "pid.out"``;
* output ``op_out`` (%): the signal to the valve, ``"valve.op" = "comp.op_out"``. It carries the
  status of ``op_in`` unchanged on every scan (as the DeltaV block's SIGNAL_OUT.ST :=
  SIGNAL_IN.ST, spec 2.1); it is not clamped (the valve clips its input to 0..100 %);
* output ``correction`` (%): u_c = op_out - op_in, for the travel and reversal metrics of
  spec 4.1;
* input ``enable``: > 0.5 compensates (default 1), otherwise ``op_out = op_in`` (a bypass, e.g.
  in manual; a NaN or infinite ``enable`` is not a switch: bypass). While bypassed each block
  keeps watching the controller output, so it resumes with up-to-date memories;
* inputs ``sp`` and ``pv`` where the algorithm needs the control error e = SP - PV (the
  knocker's optional error band, the two-move's cycle measurement and release).

Non-finite values (issue 11 point 1). The status pass-through stays, and a NaN or infinite
``op_in`` counts as Bad (its status is shown as Bad, 0, unless it arrives Bad already): the
block computes nothing on it, its memories skip the scan (the knocker's pulse timing runs on),
and ``op_out`` holds its last value (before the first scan: the pass-through of ``op_in``) with
that Bad status, except that the two-move in move 1 or hold goes on putting out x_1 or x_f;
``correction`` holds. A result that overflows (``op_in`` near the float range plus a correction)
is held the same way, Bad. A finite ``op_in`` is used whatever its status, which is passed on.
An error e = SP - PV that is not finite (a NaN or infinite ``sp`` or ``pv``, or 1e308 -
(-1e308)) is not measured: the knocker's band does not stop the pulses, the two-move counts no
crossing and does not test its release band on that scan. So no output is ever non-finite unless
its status is Bad, no state is, and each block is back at work at the first finite ``op_in``.

The controller does not see the correction (spec 2.1, as in DeltaV). No action factors are
needed, unlike DeltaV's CNTRL_ACTION·VALVE_ACTION (spec 2.3): every correction here is
computed from the controller output itself, so it pushes the valve input the way the
controller is already pushing it, whatever the controller and valve actions.

Time inside the blocks is the sum of the scan times dt; instants are compared with the 1e-9 s
tolerance of module events (so five 0.2 s scans make 1 s).

``compensator.knocker`` (Hägglund 2002; spec 2.4)
--------------------------------------------------

Short pulses of amplitude a and width τ, one every h_k (spec 2.4)::

    u_k(t) = a·sign(u(t) - u(t_p'))   for t_p ≤ t < t_p + τ
    u_k(t) = 0                        for t_p + τ ≤ t < t_p + h_k

t_p is the start of the current pulse (the first at the first scan, then the first scan at
least h_k after the previous start, so h_k is rounded up to whole scans); the
pulse direction follows the net change of the controller output u since the *previous* pulse
start t_p' (spec 2.4: "the pulse direction follows the net change of the PID output since the
previous pulse"; ``direction_reference = "previous_pulse"``); sign(0) = 0 gives no pulse. The
first pulse, which has no previous one, refers to its own start. Sampled at scans t = k·dt,
a pulse is on at the scans with t - t_p < τ: ceil(τ/dt) scans, at least one. This reading
reproduces every knocker row of the table in spec 2.8 (PV σ, mean |e|, travel, reversals; see
the tests) on the loop the table's figures imply: 11 scans of 0.2 s from the controller's
output to the PV it reads. The spec states L = 2 s with an exact hold; ``loopworks simulate``
of the loop as stated (controller, valve, process, L = 2.0 s) gives figures 10-20 % from the
table's (PV σ 0.065 for its 0.074 at a = 1.5) and reproduces them with ``dead_time = 2.2``.
``direction_reference = "pulse_start"`` is the literal sampling of the formula
with u(t_p) of the current pulse: the first scan of every pulse then has sign(0) = 0, so with
τ ≤ dt no pulse ever fires; it is there for pulses several scans wide. u(t_p) is the finite
u at the pulse start; a pulse that starts on a non-finite u takes the last one known, or,
when none is known yet, the first finite u after its start (a NaN on the first scan left
the second pulse with no direction).

Improved knockers stop pulsing inside an error band to save valve wear (Cuadros, Munaro &
Munareto 2012, spec 2.4 [L]): with ``error_band`` > 0 no pulse is applied on a scan with
abs(SP - PV) ≤ error_band (the pulse timing runs on). ``error_band`` = 0, the default, is
Hägglund's knocker.

``compensator.constant_reinforcement`` (Ivan & Lakshminarayanan 2009; spec 2.6)
--------------------------------------------------------------------------------

A constant bias in the direction the controller output moves::

    u_c(k) = α·sign(u(k) - u(k-1)),   the last non-zero sign held while Δu = 0

so every reversal of the controller output comes with an extra 2α step. The sign is 0 until
the output first moves. A non-finite u is skipped (the sign and u(k-1) hold). In S/J terms
(spec 2.6 [V]): α = fd = (S - J)/2 only compensates the lag while moving; α slightly above S/2
makes every reversal an immediate slip; α = fs = (S + J)/2 over-compensates.

``compensator.two_move`` (Srinivasan & Rengaswamy 2005, 2008; spec 2.5)
------------------------------------------------------------------------

Instead of letting the integral hunt, place the valve at the position y* that gives zero error
with two deliberate moves of the valve input, then hold it there. The algebra is the S/J model
of spec 1.2 with fs = (S + J)/2 (static band) and fd = (S - J)/2 (kinetic band), spec 2.5 [I]:

* a slip that ends in direction d leaves the stem at y = x - d·fd, so the last OP must be
  x_f = y* + d·fd;
* move 1 must put the valve into a known state whatever its state before: moving in a known
  direction and stopped at a known point. A stuck valve whose last stop was at x_ss holds
  while the OP stays in [x_ss - S, x_ss + J] (upward motion last) or [x_ss - J, x_ss + S]
  (downward), a band S + J wide, so only a move of more than S + J from the current OP x_0 is
  sure to slip (a moving valve needs less). Move 1 is therefore at least S + J + m;
* move 2 starts from a valve stopped at x_1 after moving in direction d_1, and must slip: more
  than J if it continues (d = d_1), more than S if it reverses (d = -d_1) (spec 2.5). It is at
  least J + m or S + m.

m = ``margin`` > 0 covers the strict inequalities and errors in the S, J estimates. With
``approach = "reverse"`` (default; the published method moves out past the target and comes
back), the final direction is d = -sign(y* - x_0) (d = -1 when y* = x_0): move 1 heads towards
the target and past it, move 2 comes back::

    x_f = y* + d·fd
    x_1 = min(x_0 - (S + J + m), x_f - (S + m))   for d = +1
    x_1 = max(x_0 + (S + J + m), x_f + (S + m))   for d = -1

With ``approach = "auto"`` both moves go towards the target (d = sign(y* - x_0),
x_1 = x_f - d·(J + m)) when that first move is itself at least S + J + m, i.e. when the target
is far enough; otherwise as ``reverse``. If x_1 falls outside [op_lo, op_hi], the other final
direction is tried; if that falls outside too, x_1 and x_f are clamped to the range (the moves
are then not guaranteed). x_0 is the valve input of the previous scan: the last finite ``op_out``
(before any: this scan's ``op_in``), clamped to [op_lo, op_hi] as the valve clips it (keep
op_lo/op_hi at the valve's range).

Target y*. ``target = "cycle_mean"`` (default): the mean controller output over the last
``cycles`` full cycles of the limit cycle (spec 2.5: "from the mean OP over the limit cycle").
Over whole periods of a limit cycle under integral action the mean error is zero, so this mean
is the OP that holds the PV at SP on average. A cycle is measured between crossings of the error
e = SP - PV: e changes sign when it passes from above ``cycle_band`` to below -``cycle_band`` or
back; the mean is Σ u·dt / Σ dt over the scans from one crossing up to the crossing 2·``cycles``
half cycles later, with u as the valve sees it, clamped to [op_lo, op_hi] (a scan with a
non-finite u is left out). ``target = "model"``: y* = (SP - model_bias)/model_gain from a static
process model PV = model_gain·y + model_bias (spec 2.5: "(SP - d)/K with a process model"); the
block still waits for ``cycles`` measured cycles, i.e. for evidence that the loop is cycling,
before it moves. The cycle mean includes whatever transient follows the last disturbance: in the
loop of spec 2.8 (true y* = 51 % after the +1 % set-point step) 1, 2, 4 and 10 cycles give y* =
50.68, 50.74, 50.82 and 50.91 %, and the PV settles that far below SP; the model target lands
the valve exactly when the model is right. Either way the result is only as good as the S, J and
y* estimates (spec 2.5: "sensitive to errors in the stiction estimate").

Sequence (output ``phase``):

* 0, pass: ``op_out = op_in``; the error cycles are measured. When ``cycles`` cycles have been
  measured and ``enable`` > 0.5, the moves start on that scan (a measurement completed while
  disabled is kept, and refreshed by later cycles, until the block is enabled);
* 1, move 1: ``op_out = x_1`` for ``move_time`` seconds (at least one scan);
* 2, hold: ``op_out = x_f``, until released;
* release, back to 0 and a fresh measurement: ``enable`` ≤ 0.5, a change of ``sp`` (any change
  from its value when the moves began: a set-point change wants new moves; a NaN or infinite
  ``sp`` is not the same setpoint either, so it releases too, and no moves start while ``sp`` is
  not finite), or abs(SP - PV) > ``release_band`` (a load disturbance; default inf = off).

Output ``target`` carries a status: Good while y* is known, NaN with status Bad (0) while it is
not (before the first cycles are measured; with ``target = "model"``, while (SP - model_bias)/
model_gain is not a finite number).

While the block holds the valve input the controller's integral keeps running; the release
then puts its output back on the valve with a bump. To make the release bumpless, let the
controller track the compensator: for the generic ``pid``, wire ``"pid.track" = "comp.phase"``
(phase ≥ 1 tracks) and ``"pid.track_value" = "comp.op_out"``.

Options for the spec's [L]/[I] points
-------------------------------------

The compensator sections are [L] (papers not in the corpus) plus the spec's own [I]
derivations; these interpretations are parameters (defaults are the spec's reading):

* knocker ``direction_reference`` = ``previous_pulse``: direction from the change since the
  previous pulse start (spec 2.4 text; reproduces spec 2.8); ``pulse_start`` is the literal
  formula sampled.
* knocker ``error_band`` = 0: Hägglund's knocker; > 0 is the improved knocker's band [L].
* two-move ``approach`` = ``reverse`` (move out past the target, come back) or ``auto``.
* two-move ``target`` = ``cycle_mean`` or ``model``; ``cycles`` = 2, ``cycle_band`` = 0,
  ``margin`` = 0.5 %, ``move_time`` = 0 (one scan), ``release_band`` = inf.

Defaults. The papers' settings depend on the valve; the defaults here are the valve of the
comparison in spec 2.8 (S = 3 %, J = 1 %) and the best row of its table for each method
[V, spec 2.8]: knocker a = 1.5 %, τ = 0.2 s, h_k = 1.0 s; constant reinforcement α = 1.6 %
(just above S/2, "the sweet spot in this model"); two-move S = 3 %, J = 1 %.

Example
-------

Python (constant reinforcement on a controller output that rises, pauses, then falls)::

    import loopworks
    cr = loopworks.create_block("compensator.constant_reinforcement", alpha=1.6)
    for u in (50.0, 51.0, 51.0, 50.5):
        print(cr.step(0.2, op_in=u)["op_out"].value)
    # 50.0  (no move yet), 52.6, 52.6 (sign held), 48.9

Replay (``loopworks replay compensator.knocker kn.csv -p amplitude=1 -p pulse_width=0.2
-p interval=0.6``), with ``kn.csv``::

    t,op_in
    0,50
    0.2,50.5
    0.4,51
    0.6,51.5
    0.8,52
    1.0,52.5
    1.2,52

gives ``op_out`` 50, 50.5, 51, 52.5, 52, 52.5, 53 (pulses start at 0, 0.6 and 1.2 s; the one at
0.6 s pushes up because u rose from 50 to 51.5 since the first pulse, the one at 1.2 s pushes
up because u rose from 51.5 to 52).
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

from loopworks.blocks.block import Block
from loopworks.blocks.kernel import FloatArray, IntArray, primitive
from loopworks.blocks.layout import index
from loopworks.blocks.params import Param, Port
from loopworks.blocks.primitives import clamp, finite, sign
from loopworks.blocks.registry import register
from loopworks.blocks.status import BAD, GOOD_NC
from loopworks.errors import ParameterError

_TOL = 1e-9  # s, the tolerance of module events
_PCT = "%"


_OP_IN = Port("op_in", 0.0, _PCT, "controller output (e.g. pid.out)", status=True)
_ENABLE = Port("enable", 1.0, "", "> 0.5 compensates; otherwise op_out = op_in (bypass)")
_SP = Port("sp", 0.0, "pv", "setpoint, for the error e = sp - pv")
_PV = Port("pv", 0.0, "pv", "process variable, for the error e = sp - pv")
_OP_OUT = Port("op_out", 0.0, _PCT, "to the valve: op_in + correction, status of op_in",
               status=True)
_CORRECTION = Port("correction", 0.0, _PCT, "u_c = op_out - op_in (spec 2.1)")


@primitive
def switched_on(value: float) -> bool:
    """An on/off input (``enable``): on when > 0.5; NaN or infinite is not a switch: off."""
    return finite(value) and value > 0.5


@primitive
def put_out(y: FloatArray, ys: IntArray, i_out: int, i_correction: int, out: float,
            correction: float, status: int) -> None:
    """Write ``op_out`` (at ``y[i_out]``) with the status of ``op_in`` (spec 2.1) and
    ``correction`` (at ``y[i_correction]``); each kernel passes its own output names, as the
    kinds' output layouts differ. A value that is not finite is not written: that output holds
    its last value, and ``op_out`` is then Bad (``status`` if it is Bad already, its substatus
    kept; else Bad non-specific, 0)."""
    if finite(out):
        y[i_out] = out
        ys[i_out] = status
    elif (status & 0xC0) == BAD:
        ys[i_out] = status
    else:
        ys[i_out] = BAD
    if finite(correction):
        y[i_correction] = correction
    ys[i_correction] = GOOD_NC


def pass_through(op_in: float) -> float:
    """``op_out`` before the first scan (issue 11 point 8): ``op_in`` passed through, no
    correction yet (0 if ``op_in`` is not finite)."""
    op = float(op_in)
    return op if math.isfinite(op) else 0.0


# -- compensator.knocker -----------------------------------------------------------------------

KNOCKER_INPUTS = (_OP_IN, _ENABLE, _SP, _PV)
KNOCKER_OUTPUTS = (_OP_OUT, _CORRECTION)
#: the coefficient array p (coefficients()); from_previous: 1 = direction_reference previous_pulse
KNOCKER_COEFFS = ("amplitude", "pulse_width", "interval", "error_band", "from_previous")
#: the state array x
KNOCKER_STATES = ("since_pulse", "u_previous_pulse", "u_pulse", "pulses",
                  "u_previous_pulse_known", "u_pulse_known")
KP, KX = index(KNOCKER_COEFFS, "KP"), index(KNOCKER_STATES, "KX")
KU, KY = index(KNOCKER_INPUTS, "KU"), index(KNOCKER_OUTPUTS, "KY")


def knocker_kernel(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                   y: FloatArray, ys: IntArray) -> None:
    """One scan of the knocker (spec 2.4, module docstring). Array elements are read into
    Python floats (plain IEEE arithmetic when interpreted, free when compiled). The references
    u(t_p), u(t_p') are the finite u at the pulse starts; each has a flag that says it is
    known."""
    op = float(u[KU.op_in])
    usable = finite(op)
    if x[KX.pulses] == 0.0 or x[KX.since_pulse] >= p[KP.interval] - _TOL:  # a new pulse starts
        x[KX.u_previous_pulse] = x[KX.u_pulse]
        x[KX.u_previous_pulse_known] = x[KX.u_pulse_known]
        if usable:  # a non-finite u keeps the last known reference
            x[KX.u_pulse] = op
            x[KX.u_pulse_known] = 1.0
        x[KX.since_pulse] = 0.0
        x[KX.pulses] = min(x[KX.pulses] + 1.0, 2.0)
    elif usable and x[KX.u_pulse_known] == 0.0:  # started on a non-finite u, none known yet:
        x[KX.u_pulse] = op                        # the first finite u after the start
        x[KX.u_pulse_known] = 1.0
    ref = float(x[KX.u_pulse])
    known = x[KX.u_pulse_known] != 0.0
    if p[KP.from_previous] != 0.0 and x[KX.pulses] >= 2.0:
        ref = float(x[KX.u_previous_pulse])
        known = x[KX.u_previous_pulse_known] != 0.0
    kick = 0.0
    if usable and known and (x[KX.since_pulse] < p[KP.pulse_width] - _TOL
                             or x[KX.since_pulse] == 0.0):
        kick = float(p[KP.amplitude]) * sign(op - ref)  # inside the pulse
    if not switched_on(u[KU.enable]):
        kick = 0.0
    if p[KP.error_band] > 0.0 and abs(float(u[KU.sp]) - float(u[KU.pv])) <= p[KP.error_band]:
        kick = 0.0
    x[KX.since_pulse] = x[KX.since_pulse] + dt
    put_out(y, ys, KY.op_out, KY.correction, op + kick, kick if usable else math.nan,
            us[KU.op_in])


@register
class Knocker(Block):
    """Hägglund's knocker: pulses a·sign(Δu) of width τ every h_k (spec 2.4)."""

    kind = "compensator.knocker"
    summary = ("Knocker stiction compensator (Hägglund 2002): pulses of amplitude a, width τ, "
               "every h_k, in the direction the controller output moves (spec 2.4)")
    kernel = staticmethod(knocker_kernel)

    PARAMS: ClassVar[tuple[Param, ...]] = (
        Param("amplitude", 1.5, _PCT, "pulse amplitude a: a pulse adds ±a to op_in, in "
              "the direction op_in moved (spec 2.4; default: best row of spec 2.8)", lo=0.0,
              lo_open=False),
        Param("pulse_width", 0.2, "s", "pulse width τ; at least one scan (spec 2.4)",
              lo=0.0),
        Param("interval", 1.0, "s", "time h_k between pulse starts, > pulse_width (spec 2.4)",
              lo=0.0),
        Param("error_band", 0.0, "pv", "no pulse while abs(sp - pv) <= band; 0 = off "
              "(improved knocker, spec 2.4 [L])", lo=0.0, lo_open=False),
        Param("direction_reference", "previous_pulse", "", "pulse direction from u since the "
              "previous pulse start, or since this pulse's start (literal formula) [I] "
              "(spec 2.4)", "choice", choices=("previous_pulse", "pulse_start")),
    )
    INPUTS: ClassVar[tuple[Port, ...]] = KNOCKER_INPUTS
    OUTPUTS: ClassVar[tuple[Port, ...]] = KNOCKER_OUTPUTS
    COEFFS: ClassVar[tuple[str, ...]] = KNOCKER_COEFFS
    STATES: ClassVar[tuple[str, ...]] = KNOCKER_STATES

    def initial_outputs(self) -> list[float]:
        return [pass_through(self.u[KU.op_in]), 0.0]

    def publish_start(self) -> None:
        """op_in, settled by the module before the first scan, passed through."""
        self.publish_pass_through("op_out", "op_in")

    def coefficients(self) -> dict[str, Any]:
        prm: dict[str, Any] = self.params
        if prm["interval"] <= prm["pulse_width"]:
            raise ParameterError(
                f"{self.kind}: parameter 'interval' = {prm['interval']:g} is out of range: it "
                f"must be above pulse_width = {prm['pulse_width']:g} s")
        return {"amplitude": prm["amplitude"], "pulse_width": prm["pulse_width"],
                "interval": prm["interval"], "error_band": prm["error_band"],
                "from_previous": 1.0 if prm["direction_reference"] == "previous_pulse"
                else 0.0}


# -- compensator.constant_reinforcement --------------------------------------------------------

REINFORCEMENT_INPUTS = (_OP_IN, _ENABLE)
REINFORCEMENT_OUTPUTS = (_OP_OUT, _CORRECTION)
REINFORCEMENT_COEFFS = ("alpha",)
REINFORCEMENT_STATES = ("u_previous", "direction", "started")
CP, CX = index(REINFORCEMENT_COEFFS, "CP"), index(REINFORCEMENT_STATES, "CX")
CU, CY = index(REINFORCEMENT_INPUTS, "CU"), index(REINFORCEMENT_OUTPUTS, "CY")


def reinforcement_kernel(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                         y: FloatArray, ys: IntArray) -> None:
    """One scan of constant reinforcement (spec 2.6, module docstring)."""
    op = float(u[CU.op_in])
    if finite(op):
        if x[CX.started] != 0.0:
            s = sign(op - x[CX.u_previous])
            if s != 0.0:
                x[CX.direction] = s
        x[CX.u_previous] = op
        x[CX.started] = 1.0
    bias = float(p[CP.alpha]) * float(x[CX.direction]) if switched_on(u[CU.enable]) else 0.0
    put_out(y, ys, CY.op_out, CY.correction, op + bias, bias if finite(op) else math.nan,
            us[CU.op_in])


@register
class ConstantReinforcement(Block):
    """Constant reinforcement: u_c = α·sign(Δu), last sign held (spec 2.6)."""

    kind = "compensator.constant_reinforcement"
    summary = ("Constant-reinforcement stiction compensator (Ivan & Lakshminarayanan 2009): "
               "α·sign(Δu), last non-zero sign held (spec 2.6)")
    kernel = staticmethod(reinforcement_kernel)

    PARAMS: ClassVar[tuple[Param, ...]] = (
        Param("alpha", 1.6, _PCT, "bias α in the direction u moves (spec 2.6; default: just "
              "above S/2 for the S = 3 % valve of spec 2.8)", lo=0.0, lo_open=False),
    )
    INPUTS: ClassVar[tuple[Port, ...]] = REINFORCEMENT_INPUTS
    OUTPUTS: ClassVar[tuple[Port, ...]] = REINFORCEMENT_OUTPUTS
    COEFFS: ClassVar[tuple[str, ...]] = REINFORCEMENT_COEFFS
    STATES: ClassVar[tuple[str, ...]] = REINFORCEMENT_STATES

    def initial_outputs(self) -> list[float]:
        return [pass_through(self.u[CU.op_in]), 0.0]

    def publish_start(self) -> None:
        """op_in, settled by the module before the first scan, passed through."""
        self.publish_pass_through("op_out", "op_in")

    def coefficients(self) -> dict[str, Any]:
        return {"alpha": self.params["alpha"]}


# -- compensator.two_move ----------------------------------------------------------------------

TWO_MOVE_INPUTS = (_OP_IN, _ENABLE, _SP, _PV)
TWO_MOVE_OUTPUTS = (
    _OP_OUT, _CORRECTION,
    Port("phase", 0.0, "", "0 pass, 1 move 1, 2 hold (wire to pid.track for a bumpless "
         "release)"),
    Port("target", 0.0, _PCT, "y*: the target of the moves (in pass: the current "
         "estimate; NaN, status Bad, while it is not known)", status=True),
)
#: the coefficient array p (coefficients()); model: 1 = target model, auto: 1 = approach auto
TWO_MOVE_COEFFS = ("s", "j", "margin", "model", "cycles", "cycle_band", "model_gain",
                   "model_bias", "move_time", "release_band", "op_lo", "op_hi", "auto")
#: the state array x
TWO_MOVE_STATES = (
    "phase", "error_sign", "measuring", "half_cycles", "sum_u_dt", "sum_dt", "ready",
    "cycle_mean", "target", "x1", "x_final", "timer", "sp_at_moves", "last_out",
    "cycle_mean_known", "last_out_known")
TP, TX = index(TWO_MOVE_COEFFS, "TP"), index(TWO_MOVE_STATES, "TX")
TU, TY = index(TWO_MOVE_INPUTS, "TU"), index(TWO_MOVE_OUTPUTS, "TY")
PASS, MOVE1, HOLD = 0.0, 1.0, 2.0


@primitive
def first_move(x0: float, xf: float, d: float, s: float, j: float, m: float) -> float:
    """x_1 of the reverse approach for final direction d (module docstring)."""
    if d > 0.0:
        return min(x0 - (s + j + m), xf - (s + m))
    return max(x0 + (s + j + m), xf + (s + m))


@primitive
def model_target(sp: float, bias: float, gain: float) -> float:
    """y* = (SP - model_bias)/model_gain from the static process model (spec 2.5)."""
    return (sp - bias) / gain


def two_move_kernel(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                    y: FloatArray, ys: IntArray) -> None:
    """One scan of the two-move compensator (spec 2.5, module docstring). Array elements are
    read into Python floats (plain IEEE arithmetic when interpreted, free when compiled).
    The cycle mean and the last op_out each have a flag that says they are known."""
    op = float(u[TU.op_in])
    sp = float(u[TU.sp])
    e = sp - float(u[TU.pv])
    measured = finite(e)  # sp and pv finite, and their difference too
    enabled = switched_on(u[TU.enable])
    lo = float(p[TP.op_lo])
    hi = float(p[TP.op_hi])
    phase = x[TX.phase]
    # release? (a non-finite sp is not the setpoint of the moves: it releases too)
    if phase != PASS and (not enabled or not finite(sp) or sp != x[TX.sp_at_moves]
                          or (measured and abs(e) > p[TP.release_band])):
        phase = PASS
        x[TX.error_sign] = 0.0
        x[TX.measuring] = 0.0
        x[TX.ready] = 0.0
    if phase == PASS:
        # measure the error cycles: a crossing is a sign change outside ±cycle_band
        s = 0.0
        if measured and e > p[TP.cycle_band]:
            s = 1.0
        elif measured and e < -p[TP.cycle_band]:
            s = -1.0
        crossing = s != 0.0 and x[TX.error_sign] != 0.0 and s != x[TX.error_sign]
        if s != 0.0:
            x[TX.error_sign] = s
        if crossing:
            if x[TX.measuring] != 0.0:
                x[TX.half_cycles] += 1.0
                if x[TX.half_cycles] >= 2.0 * p[TP.cycles] and x[TX.sum_dt] > 0.0:
                    x[TX.cycle_mean] = float(x[TX.sum_u_dt]) / float(x[TX.sum_dt])
                    x[TX.cycle_mean_known] = 1.0
                    x[TX.ready] = 1.0
                    x[TX.half_cycles] = 0.0
                    x[TX.sum_u_dt] = 0.0
                    x[TX.sum_dt] = 0.0
            else:
                x[TX.measuring] = 1.0
                x[TX.half_cycles] = 0.0
                x[TX.sum_u_dt] = 0.0
                x[TX.sum_dt] = 0.0
        if x[TX.measuring] != 0.0 and finite(op):  # u as the valve sees it
            x[TX.sum_u_dt] = float(x[TX.sum_u_dt]) + clamp(op, lo, hi) * dt
            x[TX.sum_dt] = float(x[TX.sum_dt]) + dt
        target = float(x[TX.cycle_mean])
        known = x[TX.cycle_mean_known] != 0.0
        if p[TP.model] != 0.0:
            target = model_target(sp, float(p[TP.model_bias]), float(p[TP.model_gain]))
            known = finite(target)
        x0 = float(x[TX.last_out]) if x[TX.last_out_known] != 0.0 else op
        if enabled and x[TX.ready] != 0.0 and known and finite(sp) and finite(x0):
            # the moves start
            x0 = clamp(x0, lo, hi)  # what the valve saw (it clips its input)
            s_ = float(p[TP.s])
            j = float(p[TP.j])
            m = float(p[TP.margin])
            fd = 0.5 * (s_ - j)
            d = sign(target - x0)
            xf = target + d * fd
            x1 = xf - d * (j + m)
            if not (p[TP.auto] != 0.0 and d != 0.0 and d * (x1 - x0) >= s_ + j + m
                    and lo <= x1 <= hi and lo <= xf <= hi):
                d = -1.0 if d >= 0.0 else 1.0  # reverse: move 1 heads past the target
                xf = target + d * fd
                x1 = first_move(x0, xf, d, s_, j, m)
                if not (lo <= x1 <= hi):
                    d2 = -d
                    xf2 = target + d2 * fd
                    x12 = first_move(x0, xf2, d2, s_, j, m)
                    if lo <= x12 <= hi:
                        xf = xf2
                        x1 = x12
            x[TX.x1] = clamp(x1, lo, hi)
            x[TX.x_final] = clamp(xf, lo, hi)
            x[TX.target] = target
            x[TX.sp_at_moves] = sp
            x[TX.timer] = 0.0
            phase = MOVE1
    elif phase == MOVE1:
        x[TX.timer] += dt
        if x[TX.timer] >= p[TP.move_time] - _TOL:
            phase = HOLD
    x[TX.phase] = phase
    if phase == PASS:
        out = op
        target = float(x[TX.cycle_mean])
        known = x[TX.cycle_mean_known] != 0.0
        if p[TP.model] != 0.0:
            target = model_target(sp, float(p[TP.model_bias]), float(p[TP.model_gain]))
            known = finite(target)
    else:
        out = float(x[TX.x1]) if phase == MOVE1 else float(x[TX.x_final])
        target = float(x[TX.target])
        known = True
    if finite(out):
        x[TX.last_out] = out
        x[TX.last_out_known] = 1.0
    put_out(y, ys, TY.op_out, TY.correction, out, out - op, us[TU.op_in])
    y[TY.phase] = phase
    ys[TY.phase] = GOOD_NC
    if known:
        y[TY.target] = target
        ys[TY.target] = GOOD_NC
    else:  # not available
        y[TY.target] = math.nan
        ys[TY.target] = BAD


@register
class TwoMove(Block):
    """Two-move compensation: two OP moves land the valve at y*, then hold (spec 2.5)."""

    kind = "compensator.two_move"
    summary = ("Two-move stiction compensator (Srinivasan & Rengaswamy): two OP moves that "
               "land a S/J valve at the target position, then hold (spec 2.5)")
    kernel = staticmethod(two_move_kernel)

    PARAMS: ClassVar[tuple[Param, ...]] = (
        Param("s", 3.0, _PCT, "estimated deadband + stickband S of the valve (spec 1.1, 2.5)",
              lo=0.0, lo_open=False),
        Param("j", 1.0, _PCT, "estimated slip jump J of the valve (spec 1.1, 2.5)",
              lo=0.0, lo_open=False),
        Param("margin", 0.5, _PCT, "m: the moves exceed the slip thresholds by this much "
              "(spec 2.5 [I])", lo=0.0),
        Param("target", "cycle_mean", "", "y*: mean controller output over the measured "
              "cycles, or (sp - model_bias)/model_gain (spec 2.5)", "choice",
              choices=("cycle_mean", "model")),
        Param("cycles", 2, "", "full error cycles measured before the moves (spec 2.5 [I])",
              "int", lo=1.0, hi=1e6, lo_open=False, hi_open=False),
        Param("cycle_band", 0.0, "pv", "hysteresis of the error crossings that delimit cycles",
              lo=0.0, lo_open=False),
        Param("model_gain", 1.0, "pv/%", "static process gain K for target = model"),
        Param("model_bias", 0.0, "pv", "PV at valve position 0 for target = model: "
              "PV = K·y + bias"),
        Param("move_time", 0.0, "s", "how long move 1 is held (at least one scan)",
              lo=0.0, lo_open=False),
        Param("release_band", math.inf, "pv", "release the hold when abs(sp - pv) exceeds "
              "this; inf = only on a setpoint change or enable = 0", lo=0.0, hi=math.inf,
              hi_open=False),
        Param("op_lo", 0.0, _PCT, "lowest valve input the moves may use"),
        Param("op_hi", 100.0, _PCT, "highest valve input the moves may use"),
        Param("approach", "reverse", "", "reverse: move 1 past the target, move 2 back; auto: "
              "both towards the target when it is far enough (spec 2.5 [I])", "choice",
              choices=("reverse", "auto")),
    )
    INPUTS: ClassVar[tuple[Port, ...]] = TWO_MOVE_INPUTS
    OUTPUTS: ClassVar[tuple[Port, ...]] = TWO_MOVE_OUTPUTS
    COEFFS: ClassVar[tuple[str, ...]] = TWO_MOVE_COEFFS
    STATES: ClassVar[tuple[str, ...]] = TWO_MOVE_STATES

    def coefficients(self) -> dict[str, Any]:
        prm: dict[str, Any] = self.params
        if prm["op_lo"] >= prm["op_hi"]:
            raise ParameterError(
                f"{self.kind}: parameter 'op_hi' = {prm['op_hi']:g} is out of range: it must "
                f"be above op_lo = {prm['op_lo']:g}")
        if prm["target"] == "model" and prm["model_gain"] == 0.0:
            raise ParameterError(
                f"{self.kind}: parameter 'model_gain' = 0 is out of range: target = model "
                "divides by it; allowed any non-zero number")
        return {"s": prm["s"], "j": prm["j"], "margin": prm["margin"],
                "model": 1.0 if prm["target"] == "model" else 0.0, "cycles": prm["cycles"],
                "cycle_band": prm["cycle_band"], "model_gain": prm["model_gain"],
                "model_bias": prm["model_bias"], "move_time": prm["move_time"],
                "release_band": prm["release_band"], "op_lo": prm["op_lo"],
                "op_hi": prm["op_hi"], "auto": 1.0 if prm["approach"] == "auto" else 0.0}

    def initial_outputs(self) -> list[float]:
        """Before the first scan: op_in passed through, phase 0 (pass), and y* if it is known
        (target = model: from the initial sp), else NaN (marked Bad by :meth:`reset`)."""
        target = math.nan
        if self.p[TP.model] != 0.0:
            target = model_target(float(self.u[TU.sp]), float(self.p[TP.model_bias]),
                                  float(self.p[TP.model_gain]))
        return [pass_through(self.u[TU.op_in]), 0.0, PASS,
                target if math.isfinite(target) else math.nan]

    def reset(self) -> None:
        super().reset()
        if not math.isfinite(self.y[TY.target]):
            self.ys[TY.target] = BAD

    def publish_start(self) -> None:
        """op_in (and sp), settled by the module before the first scan: passed through."""
        self.publish_pass_through("op_out", "op_in")
        if not math.isfinite(self.y[TY.target]):
            self.ys[TY.target] = BAD
