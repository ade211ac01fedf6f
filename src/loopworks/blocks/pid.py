r"""The generic ``pid`` block: loopworks' own controller with the modern feature set.

Equations (Åström & Hägglund, *Advanced PID Control*, ISA 2006, ch. 3; Åström & Murray,
*Feedback Systems*, 2nd ed., sec. 11.3), with s = +1 for reverse action (e = SP - PV) and
s = -1 for direct action (e = PV - SP)::

    ideal     u = K·[ (b·SP - PV) + 1/(Ti·p)·e + Td·p/(1 + Tf·p)·(c·SP - PV) ]·s + ff + bias
    parallel  u = [ kp·(b·SP - PV) + ki/p·e + kd·p/(1 + Tf·p)·(c·SP - PV) ]·s + ff + bias
    series    K'(1 + 1/(Ti'·p))(1 + Td'·p), run as the ideal form with the textbook conversion
              K = K'(1 + Td'/Ti'), Ti = Ti' + Td', Td = Ti'·Td'/(Ti' + Td')  (plant-and-tuning 3.5)

Internally every form is kp = K, ki = K/Ti, kd = K·Td. The derivative filter time constant is
``tf`` when given, else Tf = Td/N (``n``, default 10; ``n = inf`` = no filter).

Discretisation, per scan of length dt (k = this scan):

    P_k = s·kp·(b·SP_k - PV_k)
    D_k = (Tf·D_{k-1} + s·kd·(d_k - d_{k-1})) / (Tf + dt),   d = c·SP - PV   (backward Euler)
    ΔI_k = s·ki·dt·(SP_k - PV_k)                                               (backward Euler)

positional:  I_k = I_{k-1} + ΔI_k [+ min(dt/Tt, 1)·(u_{k-1} - v_{k-1}) with back-calculation]
             v_k = P_k + I_k + D_k + ff_k + bias
velocity:    v_k = A_{k-1} + (P_k - P_{k-1}) + ΔI_k + (D_k - D_{k-1}) + (ff_k - ff_{k-1}),
             A_k = u_k (clamping: the accumulator is the limited output) or v_k (none)
both:        u_k = ratelimit(clamp(v_k, out_lo, out_hi), u_{k-1}, rate_limit·dt)

At the first scan the memories are zero, the accumulator is ``bias`` and d_{k-1} = d_k, so the
two algorithms give the same output while nothing limits it. Before its first scan (what a
block earlier in a module's order reads from it on scan 0) ``out`` is ``bias`` limited to
out_lo..out_hi, whatever the mode: a MAN start's ``man_out`` is applied by that first scan.

The effective limits of a scan are [max(out_lo, u_{k-1} - rate_limit·dt),
min(out_hi, u_{k-1} + rate_limit·dt)] (the rate terms from the second scan on); u_k is v_k
clamped to them.

Anti-windup (positional): ``clamping`` integrates conditionally: ΔI is cut so that v_k does not
pass the effective limit in the direction ΔI moves (and is zero when v is already beyond it),
so the output reaches its limit and the integral stops there (Åström & Hägglund 2006,
sec. 3.5, conditional integration); ``back_calculation`` adds the tracking term with time
constant Tt (``tt``; default sqrt(Ti·Td) when Td > 0, else Ti, same source; the tracking gain
dt/Tt is capped at 1, because forward Euler of dI/dt = (u - v)/Tt overshoots for dt > Tt and
diverges for dt > 2·Tt, where a rounding residue of u - v would grow without bound); ``none``
integrates regardless; ``integral_limits`` keeps the integral itself within
out_lo..out_hi, I_k = clamp(I_{k-1} + ΔI_k, out_lo, out_hi), and sums v_k = P_k + I_k + D_k +
ff_k + bias in that order (simple-pid 2.0.1, ``PID.__call__``, "Avoid integral windup": the
rule of :class:`loopworks.compat.PID`). The velocity algorithm supports ``clamping`` (its
accumulator is the limited output) and ``none`` (its accumulator is v, which can wind up).

Dead bands: ``i_deadband`` freezes the integral (tracking term included) while
abs(e) < i_deadband. ``e_deadband`` is a gap: while abs(e) < e_deadband the output is held at
its last value (no P, I or D action; status Good with the Constant limit bits, 131).

Modes (input ``mode``): MAN (0) puts ``man_out`` on the output (limited to out_lo..out_hi; NaN
= no operator write, the output holds); AUTO (1) controls to ``sp``; CAS (2) controls to
``cas_sp``. ``track`` > 0.5 puts ``track_value`` on the output in any mode (a Bad or
non-finite ``track_value`` holds the output, status 0x47; a non-finite ``track`` is not a
switch: no tracking). Rate limiting acts
in AUTO and CAS only. Any scan that does not compute the output (MAN, tracking, bad input, the
error gap) re-initialises the controller at the next computing scan: the integral (or the
velocity accumulator) is set so that the output continues from where it was and d_{k-1} = d_k,
so every return to control is bumpless; with ``antiwindup = "integral_limits"`` only while
that integral, u - P - D - ff - bias, lies within out_lo..out_hi (the rule keeps it there, as
simple-pid's ``set_auto_mode`` does; otherwise the output continues from
P + clamp(integral) + ff + bias). With no integral action (ti = inf, ki = 0) the
re-initialised integral is a frozen manual reset.

Bad input (issue 11 point 1): in AUTO/CAS, a ``pv`` that is not a usable measurement (NaN,
±inf, Bad status, or beyond ±1e12 in its units, ``INPUT_LIMIT``: no real measurement is that
large; e2.pid uses the same limit), and likewise the working
setpoint or ``ff``, makes the block hold its last output (``bad_pv = "hold"``, status
Uncertain: last usable value, 0x47) or go to ``safe_out`` (``bad_pv = "safe"``, status
Uncertain: substitute, 0x4B); the limit bits say Constant. A scan whose arithmetic overflows
(a P, I or D term, or their sum, not finite: extreme gains) is Bad input in the same way. Such
a scan leaves the controller's memories as they were (the state is written only when every
term is finite), and the next usable scan re-initialises bumplessly from the output it gave, so
the controller is back in control at the first good PV, whatever came before: no state and no
output is ever non-finite. Uncertain inputs are used, and ``out`` becomes Uncertain.
The ``out`` status is otherwise Good non-cascade (128), with the high/low limited bits
(130/129) when the output sits at ``out_hi``/``out_lo`` and Constant (131) in MAN or tracking
(Fieldbus convention, spec vendor-blocks 4.6).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Mapping
from typing import Any, ClassVar

from loopworks.blocks.block import Block
from loopworks.blocks.controller import Action, Controller, Handover, Roles
from loopworks.blocks.forms import (
    ideal_to_parallel,
    ideal_to_series,
    parallel_to_ideal,
    series_to_ideal,
)
from loopworks.blocks.kernel import FloatArray, IntArray, primitive, sees_nonfinite
from loopworks.blocks.law import DiscreteLaw, Ideal, ParamValue, Realisation, no_ideal
from loopworks.blocks.layout import index
from loopworks.blocks.params import Param, Port, validate
from loopworks.blocks.primitives import clamp, finite
from loopworks.blocks.registry import register
from loopworks.blocks.status import (
    BAD,
    CONSTANT,
    GOOD_NC,
    HIGH_LIMITED,
    LOW_LIMITED,
    UNCERTAIN,
    UNCERTAIN_LAST_USABLE_VALUE,
    UNCERTAIN_NON_SPECIFIC,
    UNCERTAIN_SUBSTITUTE,
)
from loopworks.errors import ParameterError

AW_NONE, AW_CLAMPING, AW_BACK_CALCULATION, AW_INTEGRAL_LIMITS = 0, 1, 2, 3
BAD_HOLD, BAD_SAFE = 0, 1
MAN, AUTO, CAS = 0, 1, 2  # values of the mode input

INPUTS = (
    Port("sp", 0.0, "pv", "setpoint (AUTO)", status=True),
    Port("pv", 0.0, "pv", "process variable", status=True),
    Port("ff", 0.0, "out", "feedforward, added to the output", status=True),
    Port("mode", float(AUTO), "", "MAN (0), AUTO (1) or CAS (2)",
         choices=("MAN", "AUTO", "CAS")),
    Port("man_out", math.nan, "out", "operator output in MAN (NaN = hold)", status=True),
    Port("cas_sp", math.nan, "pv", "cascade setpoint (CAS)", status=True),
    Port("track", 0.0, "", "output tracking switch (> 0.5 = track)"),
    Port("track_value", math.nan, "out", "output while tracking", status=True),
)
OUTPUTS = (
    Port("out", 0.0, "out", "controller output", status=True),
    Port("p_term", 0.0, "out", "proportional contribution"),
    Port("i_term", 0.0, "out", "integral contribution"),
    Port("d_term", 0.0, "out", "derivative contribution"),
)
#: the coefficient array p (coefficients())
COEFFS = ("kp", "ki", "kd", "tf", "b", "c", "sign", "velocity", "aw", "tt_inv", "lo", "hi",
          "rate", "idb", "edb", "bias", "safe", "badpv")
#: the state array x
STATES = ("i", "d", "d_prev", "u_prev", "v_prev", "acc", "p_prev", "d_out_prev", "ff_prev",
          "first", "init")
P, X, U, Y = index(COEFFS, "P"), index(STATES, "X"), index(INPUTS, "U"), index(OUTPUTS, "Y")


# Inputs beyond this magnitude are not measurements (issue 11 point 1); shared with e2.pid
INPUT_LIMIT = 1e12


@primitive
def measured(value: float, status: int) -> bool:
    """True when an analog input is usable: finite, within ±INPUT_LIMIT (in its own units) and
    its status is not Bad. Anything else is Bad input (issue 11 point 1)."""
    return finite(value) and abs(value) <= INPUT_LIMIT and (status & 0xC0) != BAD


@sees_nonfinite
def pid_kernel(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
               y: FloatArray, ys: IntArray) -> None:
    """One scan of the generic PID (equations in the module docstring). A computing scan
    works on locals and writes the state only once every term is finite, so a scan whose
    arithmetic overflows is Bad input and leaves the state as it was."""
    lo = p[P.lo]
    hi = p[P.hi]
    u_prev = x[X.u_prev]
    mode = u[U.mode]
    out = u_prev
    status = GOOD_NC | CONSTANT
    computed = False
    track = u[U.track]
    if finite(track) and track > 0.5:  # output tracking, any mode
        if finite(u[U.track_value]) and (us[U.track_value] & 0xC0) != BAD:
            out = clamp(u[U.track_value], lo, hi)
        else:
            status = UNCERTAIN_LAST_USABLE_VALUE | CONSTANT
    elif mode == MAN:
        if finite(u[U.man_out]) and (us[U.man_out] & 0xC0) != BAD:
            out = clamp(u[U.man_out], lo, hi)
    else:
        isp = U.cas_sp if mode == CAS else U.sp
        sp = u[isp]
        pv = u[U.pv]
        ff = u[U.ff]
        q_sp = us[isp] & 0xC0
        q_pv = us[U.pv] & 0xC0
        q_ff = us[U.ff] & 0xC0
        usable = ((mode == AUTO or mode == CAS) and measured(sp, us[isp])
                  and measured(pv, us[U.pv]) and measured(ff, us[U.ff]))
        if usable:
            s = p[P.sign]
            bias = p[P.bias]
            e = s * (sp - pv)
            pterm = s * p[P.kp] * (p[P.b] * sp - pv)
            d = s * (p[P.c] * sp - pv)
            init = x[X.init] != 0.0
            first = x[X.first] != 0.0
            d_prev = x[X.d_prev]
            d_filt = x[X.d]
            if init or first:
                d_prev = d
                d_filt = 0.0
            if p[P.kd] == 0.0 and d_filt == 0.0:  # a PI: the same 0, without the division
                dterm = 0.0
            else:
                dterm = (p[P.tf] * d_filt + p[P.kd] * (d - d_prev)) / (p[P.tf] + dt)
            i_prev = x[X.i]
            acc = x[X.acc]
            v_prev = x[X.v_prev]
            p_prev = x[X.p_prev]
            dout_prev = x[X.d_out_prev]
            ff_prev = x[X.ff_prev]
            if init:  # bumpless return: continue from the last output
                i_prev = u_prev - pterm - dterm - ff - bias
                acc = u_prev
                v_prev = u_prev
                p_prev = pterm
                dout_prev = dterm
                ff_prev = ff
            velocity = p[P.velocity] != 0.0
            gap = abs(e) < p[P.edb]  # error gap: hold the output, re-initialise on leaving
            di = 0.0
            if not gap and abs(e) >= p[P.idb]:  # inside the integral dead band I is frozen
                di = p[P.ki] * dt * e
                if p[P.aw] == AW_BACK_CALCULATION:
                    # forward Euler of dI/dt = (u - v)/Tt overshoots for dt > Tt and diverges
                    # for dt > 2·Tt: the gain is capped at 1 (v realigned to u in one scan)
                    di += min(dt * p[P.tt_inv], 1.0) * (u_prev - v_prev)
            if velocity:
                base = acc + (pterm - p_prev) + (dterm - dout_prev) + (ff - ff_prev)
            else:
                base = pterm + i_prev + dterm + ff + bias
            upper = hi
            lower = lo
            if not first:
                upper = min(hi, u_prev + p[P.rate] * dt)
                lower = max(lo, u_prev - p[P.rate] * dt)
            if p[P.aw] == AW_CLAMPING and not velocity:
                # the integral moves only as far as keeps v inside the effective limits
                if di > 0.0 and base + di > upper:
                    di = max(0.0, upper - base)
                elif di < 0.0 and base + di < lower:
                    di = min(0.0, lower - base)
            i_sum = i_prev + di
            if p[P.aw] == AW_INTEGRAL_LIMITS:  # positional only (coefficients() refuses velocity)
                i_sum = clamp(i_sum, lo, hi)
                v = pterm + i_sum + dterm + ff + bias
            else:
                v = base + di
            i_new = i_prev
            if gap:
                out = u_prev
                iterm = out - pterm - dterm - ff - bias
            else:
                out = clamp(v, lower, upper)
                if velocity:
                    acc = out if p[P.aw] == AW_CLAMPING else v
                    iterm = acc - pterm - dterm - ff - bias
                else:
                    i_new = i_sum
                    iterm = i_new
            # overflow is Bad input: a sum of finite numbers is finite unless one of them is
            # not, or the sum overflows (then the terms are beyond any usable scale anyway)
            usable = finite(pterm + dterm + i_new + base + v + acc + iterm)
            if usable:
                computed = True
                x[X.d] = dterm
                x[X.d_prev] = d
                x[X.first] = 0.0
                if gap:
                    x[X.init] = 1.0
                    status = GOOD_NC | CONSTANT
                else:
                    x[X.i] = i_new
                    x[X.acc] = acc
                    x[X.v_prev] = v
                    x[X.p_prev] = pterm
                    x[X.d_out_prev] = dterm
                    x[X.ff_prev] = ff
                    x[X.init] = 0.0
                    status = GOOD_NC
                    if q_sp == UNCERTAIN or q_pv == UNCERTAIN or q_ff == UNCERTAIN:
                        status = UNCERTAIN_NON_SPECIFIC
                    if out >= hi:
                        status |= HIGH_LIMITED
                    elif out <= lo:
                        status |= LOW_LIMITED
                y[Y.p_term] = pterm
                y[Y.i_term] = iterm
                y[Y.d_term] = dterm
        if not usable:
            if p[P.badpv] == BAD_SAFE:
                out = p[P.safe]
                status = UNCERTAIN_SUBSTITUTE | CONSTANT
            else:
                out = u_prev
                status = UNCERTAIN_LAST_USABLE_VALUE | CONSTANT
    if not computed:
        x[X.init] = 1.0
        x[X.first] = 0.0
        x[X.v_prev] = out
        y[Y.p_term] = 0.0
        y[Y.i_term] = 0.0
        y[Y.d_term] = 0.0
    x[X.u_prev] = out
    y[Y.out] = out
    ys[Y.out] = status


_GAINS_IDEAL = ("k", "ti", "td")
_GAINS_PARALLEL = ("kp", "ki", "kd")


def _check_form(form: str, given: set[str]) -> None:
    """ParameterError when ``given`` (the parameter names set) mixes the forms' gains (k, ti,
    td for ideal and series; kp, ki, kd for parallel) or gives both 'n' and 'tf': what the
    block refuses, and so what a conversion from it refuses too."""
    if form == "parallel":
        wrong = given & set(_GAINS_IDEAL)
        if wrong:
            raise ParameterError(
                f"pid: parameter '{sorted(wrong)[0]}' is for the ideal and series forms; "
                "form 'parallel' takes kp, ki, kd")
    else:
        wrong = given & set(_GAINS_PARALLEL)
        if wrong:
            raise ParameterError(
                f"pid: parameter '{sorted(wrong)[0]}' is for the parallel form; "
                f"form '{form}' takes k, ti, td")
    if "n" in given and "tf" in given:
        raise ParameterError("pid: give either 'n' or 'tf' for the derivative filter, not both")


@register
class PID(Controller, Block):
    """Generic PID: ideal, parallel or series form; positional or velocity algorithm."""

    kind = "pid"
    summary = "generic PID (ideal/parallel/series, positional/velocity, anti-windup, modes)"
    kernel = staticmethod(pid_kernel)

    PARAMS: ClassVar[tuple[Param, ...]] = (
        Param("form", "ideal", "", "controller form", "choice",
              choices=("ideal", "parallel", "series")),
        Param("k", None, "out/pv", "gain K (ideal and series forms)", lo=0.0,
              default_text="1.0"),
        Param("ti", None, "s", "integral time (ideal and series); inf = no integral action",
              lo=0.0, hi_open=False, default_text="inf"),
        Param("td", None, "s", "derivative time (ideal and series); 0 = none", lo=0.0,
              lo_open=False, default_text="0.0"),
        Param("kp", None, "out/pv", "proportional gain (parallel form)", lo=0.0, lo_open=False,
              default_text="1.0"),
        Param("ki", None, "out/(pv·s)", "integral gain (parallel form)", lo=0.0, lo_open=False,
              default_text="0.0"),
        Param("kd", None, "out·s/pv", "derivative gain (parallel form)", lo=0.0, lo_open=False,
              default_text="0.0"),
        Param("action", "reverse", "", "reverse: e = sp - pv; direct: e = pv - sp", "choice",
              choices=("reverse", "direct")),
        Param("b", 1.0, "", "setpoint weight in the proportional term", lo=0.0, hi=1.0,
              lo_open=False, hi_open=False),
        Param("c", 0.0, "", "setpoint weight in the derivative term (0 = derivative on PV)",
              lo=0.0, hi=1.0, lo_open=False, hi_open=False),
        Param("n", None, "", "derivative filter: Tf = Td/n; inf = no filter", lo=0.0,
              hi_open=False, default_text="10.0"),
        Param("tf", None, "s", "derivative filter time constant (instead of n); 0 = none",
              lo=0.0, lo_open=False, default_text="Td/n"),
        Param("algorithm", "positional", "", "positional or velocity (incremental)", "choice",
              choices=("positional", "velocity")),
        Param("antiwindup", "clamping", "", "anti-windup strategy", "choice",
              choices=("clamping", "back_calculation", "integral_limits", "none")),
        Param("tt", None, "s", "tracking time constant for back_calculation", lo=0.0,
              default_text="sqrt(Ti·Td) if Td > 0 else Ti"),
        Param("out_lo", 0.0, "out", "output low limit"),
        Param("out_hi", 100.0, "out", "output high limit (> out_lo)"),
        Param("rate_limit", math.inf, "out/s", "output rate limit (AUTO/CAS); inf = none",
              lo=0.0, hi_open=False),
        Param("i_deadband", 0.0, "pv", "integral frozen while abs(e) < i_deadband", lo=0.0,
              lo_open=False),
        Param("e_deadband", 0.0, "pv", "output held while abs(e) < e_deadband", lo=0.0,
              lo_open=False),
        Param("bias", 0.0, "out", "output bias added in the positional sum"),
        Param("bad_pv", "hold", "", "on Bad or non-finite pv: hold the output or go to "
              "safe_out", "choice", choices=("hold", "safe")),
        Param("safe_out", None, "out", "output when bad_pv = safe (in out_lo..out_hi)",
              default_text="out_lo"),
        Param("retune", "bumpless", "", "a parameter change between computing scans (new "
              "tuning in AUTO/CAS): bumpless moves the integral so the output does not jump; "
              "textbook applies the new law as it is", "choice",
              choices=("bumpless", "textbook")),
    )
    INPUTS: ClassVar[tuple[Port, ...]] = INPUTS
    OUTPUTS: ClassVar[tuple[Port, ...]] = OUTPUTS
    COEFFS: ClassVar[tuple[str, ...]] = COEFFS
    STATES: ClassVar[tuple[str, ...]] = STATES
    # the controller interface (loopworks.blocks.controller)
    ROLES: ClassVar[Roles] = Roles(sp="sp", pv="pv", out="out", ff="ff", mode="mode",
                                   man_out="man_out", track="track", track_value="track_value")
    AUTOMATIC: ClassVar[dict[str, Any]] = {"mode": "AUTO"}
    MANUAL: ClassVar[dict[str, Any]] = {"mode": "MAN"}
    ACTION: ClassVar[Action] = Action("action", "=", "direct")
    #: a relay test drives the tracking switch and value (bumpless: the integral follows)
    HANDOVER: ClassVar[Handover] = Handover((("track", "active"), ("track_value", "out")))

    @classmethod
    def setpoint_input(cls, inputs: Mapping[str, float]) -> str:
        """``cas_sp`` in CAS mode (the mode input's value 2), else ``sp``."""
        return "cas_sp" if inputs.get("mode") == CAS else "sp"

    @classmethod
    def output_range(cls, params: Mapping[str, Any]) -> tuple[float, float]:
        """``out_lo``..``out_hi``."""
        return float(params["out_lo"]), float(params["out_hi"])

    # -- the discrete law (loopworks.blocks.law), both ways ---------------------------------
    LAW_CONTEXT: ClassVar[tuple[str, ...]] = ("pv_span", "out_span")
    LAW_PARAMS: ClassVar[tuple[str, ...]] = ("form", "k", "ti", "td", "kp", "ki", "kd", "n",
                                             "tf", "action", "b", "c", "i_deadband",
                                             "e_deadband")

    @classmethod
    def law(cls, params: Mapping[str, Any], dt: float | None,
            context: Mapping[str, Any]) -> DiscreteLaw:
        """The reference law (:mod:`loopworks.blocks.law`): P = Kc·e; ΔI_k = (Kc/Ti)·Δ·e_k;
        D_k = (Tf·D_{k-1} + Kc·Td·Δe_k)/(Tf + Δ), at any Δ. k, ti, td (ideal); kp, ki, kd
        (parallel: Kc = kp, Ti = kp/ki, Td = kd/kp); series k', ti', td' through
        ``series_to_ideal`` (plant-and-tuning 3.5). Tf = ``tf``, else Td/``n`` (n = 10 by
        default: a pid without ``tf`` filters its D). b, c the setpoint weights of P and D.
        Kc (%/%) = k·pv_span/out_span."""
        prm: dict[str, Any] = validate(cls.kind, cls.PARAMS, dict(params))
        pv_span, out_span = cls.spans(context)
        form = prm["form"]
        _check_form(form, {str(k).lower() for k, v in params.items() if v is not None})
        if form == "parallel":
            kp = 1.0 if prm["kp"] is None else float(prm["kp"])
            ki = 0.0 if prm["ki"] is None else float(prm["ki"])
            kd = 0.0 if prm["kd"] is None else float(prm["kd"])
            if not kp > 0.0:
                raise no_ideal(cls.kind, "kp", kp)
            k, ti, td = parallel_to_ideal(kp, ki, kd)
        else:
            k = 1.0 if prm["k"] is None else float(prm["k"])
            ti = math.inf if prm["ti"] is None else float(prm["ti"])
            td = 0.0 if prm["td"] is None else float(prm["td"])
            if form == "series" and td > 0.0:
                k, ti, td = series_to_ideal(k, ti, td)
        if prm["tf"] is not None:
            tf = float(prm["tf"])
        else:
            n = 10.0 if prm["n"] is None else float(prm["n"])
            tf = 0.0 if td == 0.0 or n == math.inf else td / n
        notes: tuple[str, ...] = ()
        if prm["tf"] is None and td > 0.0 and tf > 0.0:
            n_text = "n default 10" if prm["n"] is None else f"n = {float(prm['n']):g}"
            notes = (f"The pid filters its derivative with Tf = Td/n = {tf:g} s "
                     f"({n_text}).",)
        flags: list[str] = []
        if float(prm["i_deadband"]) > 0.0 and ti < math.inf:
            flags.append(f"The pid's i_deadband = {float(prm['i_deadband']):g} freezes the "
                         "integral near the setpoint (not converted).")
        if float(prm["e_deadband"]) > 0.0:
            flags.append(f"The pid's e_deadband = {float(prm['e_deadband']):g} holds the "
                         "output near the setpoint (not converted).")
        ideal = Ideal(k * pv_span / out_span, ti, td, tf if td > 0.0 else 0.0,
                      prm["action"] == "direct")
        return DiscreteLaw(ideal, b=float(prm["b"]), c=float(prm["c"]), dt=dt, notes=notes,
                           flags=tuple(flags))

    @classmethod
    def from_law(cls, law: DiscreteLaw, dt: float | None,
                 context: Mapping[str, Any]) -> Realisation:
        """k, ti, td in the context's ``form`` (ideal by default; parallel, series), tf, the
        action and the setpoint weights b, c: the reference law itself, at any Δ."""
        ideal = law.ideal
        pv_span, out_span = cls.spans(context)
        k = ideal.kc * out_span / pv_span
        form = str(context.get("form", "ideal")).lower()
        out: dict[str, ParamValue] = {"form": form}
        if form == "parallel":
            kp, ki, kd = ideal_to_parallel(k, ideal.ti, ideal.td)
            out.update(kp=kp, ki=ki, kd=kd)
        elif form == "series":
            ks, tis, tds = ideal_to_series(k, ideal.ti, ideal.td)
            out.update(k=ks, ti=tis, td=tds)
        elif form == "ideal":
            out.update(k=k, ti=ideal.ti, td=ideal.td)
        else:
            raise ParameterError(f"pid: parameter 'form' = {form!r} is not allowed: expected "
                                 "one of ideal, parallel, series")
        out.update(tf=ideal.tf if ideal.td > 0.0 else 0.0,
                   action="direct" if ideal.direct else "reverse", b=law.b, c=law.c)
        return Realisation(out, dt)

    def set_params(self, **changes: Any) -> None:
        """Change parameters between scans (see :meth:`Block.set_params`). With
        ``retune = "bumpless"`` (default) and the controller computing (AUTO/CAS, not about to
        re-initialise), a change of the proportional term's coefficients (kp, b, action) does
        not bump the output: at the latched SP and PV,

            P_old = s_old·kp_old·(b_old·SP - PV),  P_new = s_new·kp_new·(b_new·SP - PV)
            positional: I += P_old - P_new;  velocity: P_{k-1} += P_new - P_old

        (the correction of DiscretePIDs.jl ``set_K!``; Åström & Hägglund 2006, sec. 3.5,
        bumpless parameter changes). The integral and derivative gains act on increments, so
        their changes need no correction.

        In any ``retune`` mode, the derivative's memory d_{k-1} = s·(c·SP - PV) is restated
        for a new action or c at the same SP and PV, so the next scan differentiates the signal,
        not the change of its definition (a flip of the action was a kick of
        2·kd·(c·SP - PV)/(Tf + dt), enough to drive the output to a limit; simple-pid keeps
        its last input and last error, and changes its D form without one)."""
        old = self.p.copy()
        super().set_params(**changes)
        if self.x[X.init] != 0.0 or self.x[X.first] != 0.0:
            return
        mode = self.u[U.mode]
        if mode not in (AUTO, CAS):
            return
        sp, pv = self.u[U.cas_sp if mode == CAS else U.sp], self.u[U.pv]
        d_old = old[P.sign] * (old[P.c] * sp - pv)
        d_new = self.p[P.sign] * (self.p[P.c] * sp - pv)
        if math.isfinite(d_old) and math.isfinite(d_new):
            self.x[X.d_prev] += d_new - d_old
        if self.params["retune"] != "bumpless":
            return
        p_old = old[P.sign] * old[P.kp] * (old[P.b] * sp - pv)
        p_new = self.p[P.sign] * self.p[P.kp] * (self.p[P.b] * sp - pv)
        if math.isfinite(p_old) and math.isfinite(p_new):
            self.x[X.i] += p_old - p_new
            self.x[X.p_prev] += p_new - p_old

    def gains(self) -> tuple[float, float, float]:
        """(kp, ki, kd) of the equivalent parallel form."""
        return self.p[P.kp], self.p[P.ki], self.p[P.kd]

    def coefficients(self) -> dict[str, Any]:
        prm: dict[str, Any] = self.params
        given = set(self.given)
        form = prm["form"]
        _check_form(form, given)
        if form == "parallel":
            kp = _or(prm["kp"], 1.0)
            ki = _or(prm["ki"], 0.0)
            kd = _or(prm["kd"], 0.0)
            ti = kp / ki if ki > 0.0 else math.inf
            td = kd / kp if kp > 0.0 else math.inf
        else:
            k = _or(prm["k"], 1.0)
            ti = _or(prm["ti"], math.inf)
            td = _or(prm["td"], 0.0)
            if form == "series" and td > 0.0:
                k, ti, td = series_to_ideal(k, ti, td)
            kp, ki, kd = k, (k / ti if ti < math.inf else 0.0), k * td
        if prm["tf"] is not None:
            tf = float(prm["tf"])
        else:
            n = _or(prm["n"], 10.0)
            if kd > 0.0 and not td < math.inf:
                raise ParameterError("pid: with kp = 0 the filter cannot be Td/n; give 'tf' (s)")
            tf = 0.0 if kd == 0.0 or n == math.inf else td / n
        lo, hi = float(prm["out_lo"]), float(prm["out_hi"])
        if not lo < hi:
            raise ParameterError(
                f"pid: parameter 'out_hi' = {hi:g} must be greater than out_lo = {lo:g}")
        _check_finite(prm, given, kp, ki, kd, tf)
        velocity = prm["algorithm"] == "velocity"
        aw = {"none": AW_NONE, "clamping": AW_CLAMPING, "back_calculation": AW_BACK_CALCULATION,
              "integral_limits": AW_INTEGRAL_LIMITS}[prm["antiwindup"]]
        if velocity and aw in (AW_BACK_CALCULATION, AW_INTEGRAL_LIMITS):
            raise ParameterError(
                f"pid: antiwindup = '{prm['antiwindup']}' needs algorithm = 'positional'; the "
                "velocity algorithm takes 'clamping' (accumulate the limited output) or 'none'")
        tt_inv = 0.0
        if aw == AW_BACK_CALCULATION:
            if prm["tt"] is not None:
                tt = float(prm["tt"])
            elif ki == 0.0:
                tt = math.inf
            else:
                tt = math.sqrt(ti * td) if 0.0 < td < math.inf else ti
                if not tt > 0.0:
                    raise ParameterError(
                        "pid: antiwindup = 'back_calculation' with kp = 0 has no default "
                        "tracking time (Ti = kp/ki = 0): give 'tt' (s)")
            tt_inv = 1.0 / tt
            if not math.isfinite(tt_inv):
                name = ("tt" if prm["tt"] is not None
                        else "kp" if form == "parallel" else "ti")  # tt from Ti (= kp/ki)
                raise ParameterError(
                    f"pid: parameter '{name}' = {float(prm[name]):g} is out of range: it "
                    f"gives the tracking time tt = {tt:g} s, and 1/tt must be a finite number: "
                    f"allowed tt > {1.0 / sys.float_info.max:.3g} s")
        safe = lo if prm["safe_out"] is None else float(prm["safe_out"])
        if not lo <= safe <= hi:
            raise ParameterError(
                f"pid: parameter 'safe_out' = {safe:g} is out of range: allowed "
                f"[{lo:g}, {hi:g}] (out_lo..out_hi)")
        return {"kp": kp, "ki": ki, "kd": kd, "tf": tf, "b": prm["b"], "c": prm["c"],
                "sign": 1.0 if prm["action"] == "reverse" else -1.0,
                "velocity": 1.0 if velocity else 0.0, "aw": aw, "tt_inv": tt_inv,
                "lo": lo, "hi": hi, "rate": prm["rate_limit"], "idb": prm["i_deadband"],
                "edb": prm["e_deadband"], "bias": prm["bias"], "safe": safe,
                "badpv": BAD_SAFE if prm["bad_pv"] == "safe" else BAD_HOLD}

    def initial_outputs(self) -> list[float]:
        """Before its first scan the controller's output is where it starts: bias, limited."""
        return [self.x[X.u_prev], 0.0, 0.0, 0.0]

    def initial_state(self) -> list[float]:
        x = [0.0] * self.n_x
        bias = self.p[P.bias]
        x[X.u_prev] = min(max(bias, self.p[P.lo]), self.p[P.hi])
        x[X.v_prev] = x[X.u_prev]
        x[X.acc] = bias
        x[X.first] = 1.0
        return x


def _check_finite(prm: dict[str, Any], given: set[str], kp: float, ki: float, kd: float,
                  tf: float) -> None:
    """ParameterError unless the derived gains and the filter time are finite numbers (a
    tiny ti makes k/ti, or the series conversion's K'(1 + Td'/Ti'), overflow)."""
    if prm["form"] == "parallel":
        sources = {"kp": "kp", "ki": "ki", "kd": "kd", "tf": "tf" if "tf" in given else "kd"}
    else:
        sources = {"kp": "ti" if prm["form"] == "series" else "k", "ki": "ti", "kd": "td",
                   "tf": "tf" if "tf" in given else "td"}
    for gain, value in (("kp", kp), ("ki", ki), ("kd", kd), ("tf", tf)):
        if not math.isfinite(value):
            name = sources[gain]
            raise ParameterError(
                f"pid: parameter '{name}' = {float(prm[name]):g} is out of range: with the "
                f"other settings it gives {gain} = {value:g}; allowed: values that keep the "
                "gains kp, ki, kd and the filter time tf finite numbers")


def _or(value: Any, default: float) -> float:
    return default if value is None else float(value)

