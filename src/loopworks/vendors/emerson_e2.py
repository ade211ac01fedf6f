r"""The Emerson (formerly CPC) E2 RX/BX/CX controller PID: kind ``e2.pid``.

The E2 runs one shared PID algorithm in many applications (Loop/Sequence Control, suction and
pressure control, EEPR/EEV circuits, the CC-100 case controllers, condenser fans). This block is
its Setpoint Float and PID cells followed by its Filter and Override cells (spec vendor-blocks
section 3; seed 001 =
E2 I&O manual 026-1610 Rev 13, Appendix D). Output stages (Sequencer, PWM) are separate cells and
are not part of this block; :func:`pwm_times` gives the PWM on/off split of spec 3.7.

Equations
---------

Setpoint Float cell (spec 3.7 step 2, before the PID): the setpoint is shifted by a value
between ``low_float`` and ``high_float`` as the ``float_in`` input moves across its range
``float_range_lo``..``float_range_hi``, by linear interpolation [A], clamped at the ends::

    shift = low_float + (high_float - low_float)·clamp((float_in - float_range_lo) /
                                                       (float_range_hi - float_range_lo), 0, 1)
    setpoint = sp + shift                                (output ``working_sp``)

Low and High Float both 0 (the defaults) disable it ("0 disables it"): the setpoint is ``sp``.
A ``float_in`` that is NaN (not wired), ±inf or Bad keeps the last shift (0 until one is
usable) [A].

Every PID update k (spec 3.3, incremental or "velocity" form; gains are per update)::

    e_k    = input - setpoint                           error_sign [A], spec 3.3
    Padj_k = kp · (e_k - e_{k-1}) · 100 % / TR           [V] spec 3.3; TR = throttling_range
    Iadj_k = ki · e_k        if abs(e_k) > MAE           [V as printed] spec 3.3, 3.5
           = 0               if abs(e_k) <= MAE          inclusive; MAE = min_accumulated_error
    Dadj_k = kd · (e_k - 2·e_{k-1} + e_{k-2})                      d_form = second_difference [A]
           = kd · (e_k - 2·e_{k-1}/t_{-1} + e_{k-2}/t_{-2})        d_form = as_printed
    OUT_k  = clamp(OUT_{k-1} + Padj_k + Iadj_k + Dadj_k, output_min, output_max)   spec 3.4

With ``i_tr_normalise`` (``d_tr_normalise``) Iadj (Dadj) is also multiplied by 100 %/TR. In the
``as_printed`` D form, t_{-1} is the time from update k-1 to update k and t_{-2} the time from
update k-2 to update k-1, both in minutes (the manual calls the ratios rates per minute; the
form adds an error to an error per minute, which is not dimensionally consistent [D]). They are
the times the emulation actually measured between updates (whole scans); the first update takes
both as ``update_interval``, the second takes t_{-2} = ``update_interval``.

Filter cell ("valve filtering", spec 3.6), every ``filter_period`` seconds::

    F_n = F_{n-1} + f · (OUT - F_{n-1}),   f = filter_percentage / 100

where OUT is the PID's (unfiltered) output at that moment. ``filter_period = 0`` turns the
filter off: F = OUT. The vendor example holds exactly: F = 50, the PID asks for 58, f = 75 %:
F = 56, then 57.5, 57.875, 57.96875 (spec 3.8 E6).

Override cell (spec 3.7): while the ``override`` input is finite (and its status is not Bad),
``out`` is the override value. The override cell comes after the PID cell, so Output at
Minimum/Maximum do not apply to it; it is limited to 0..100 % (``override_limits``). By default
the PID keeps running underneath and ``out`` returns to the filter output when the override
ends (``override_updates_pid``).

Outputs: ``out`` = override, else F (after the filter); ``pid_out`` = OUT (the PID cell's
stored output, before the filter); ``p_adj``, ``i_adj``, ``d_adj`` = the adjustments of the
latest PID update (held between updates).

Retuning (issue 12 point 4)
---------------------------

The PID cell is incremental (spec 3.3: each update computes three adjustments and adds them to
the previous output; spec 7: velocity form, anti-windup inherent): P acts on the change of the
error since the previous update, I on the current error, D (default form) on its second
difference, and OUT_{k-1} is the stored output. A change of ``kp``, ``ki``, ``kd`` or
``throttling_range`` (``set_params`` between scans) therefore does not bump the output: the next
update adds the adjustments of the new settings to the stored output. At a steady error Padj =
Dadj = 0, so OUT moves by ki_new·e only. This is the vendor's law, bumpless by construction, so
there is no ``retune`` option. ``output_at_setpoint`` only places the start-up output (spec 3.9):
changing it later moves nothing.

Timing: how the update schedules run on arbitrary scans
-------------------------------------------------------

The PID updates every ``update_interval`` seconds and the filter every ``filter_period``
seconds, each on its own timer (spec 3.3, 3.6), whatever the scan time dt of the block:

* The first scan starts both timers at 0 and runs one PID update and one filter update (the
  controller starts computing at once).
* Each later scan adds dt to each timer. A cell updates when its timer >= its interval (with a
  relative tolerance of 1e-9, so that ten scans of 0.1 s make one 1 s interval despite binary
  rounding); it then subtracts the interval from its timer. The cell therefore updates at the
  first scan at or after each multiple of its interval, and a 0.3 s scan with a 1 s interval
  gives updates at t = 0, 1.2, 2.1, 3.0, 4.2, ... s.
* At most one update per cell per scan: if the timer is still due after subtracting (the scan
  was longer than the interval), it is set to 0 and the missed updates are dropped.
* In one scan the cells run in the E2's cell order: PID, then Filter, then Override (spec 3.7).

Start-up (spec 3.9, [?]): the PID's stored output and the filter start at ``initial_output``
(default Output at Setpoint, clamped to the output limits), and the previous errors
e_{k-1} = e_{k-2} = 0, as if the input had been at setpoint with the output at Output at
Setpoint. So the first update places the output at Output at Setpoint + kp·e·100/TR: with TR 10,
kp 1, OAS 50 and SP 29, input 24 gives 0 % and input 34 gives 100 % (spec 3.8 E2).

Bad input (E2 has no Fieldbus status; [A]): a NaN/inf ``pv`` or ``sp``, or one with a Bad
status byte, makes the PID cell skip its update (the due update is lost, not retried), so its
output, error memories and adjustments hold; the filter keeps running on the held PID output.
``out`` carries status 0x47 (Uncertain, last usable value, constant) while the input is bad; with
``bad_input = "failsafe"`` ``out`` is ``failsafe_output`` instead (0x4B, Uncertain, substitute,
constant). When the input returns, the next scheduled update continues from the stored error, so
the P window is not shifted by the gap. A ``pv`` or ``sp`` beyond ±1e12 EU is not a
measurement either: it is bad input like NaN (issue 11 point 1; the limit of the generic
``pid``, far beyond any real measurement, below which the error arithmetic cannot overflow); an
update whose arithmetic is still not finite (extreme gains: kp·Δe·100/TR beyond the float
range) is skipped like a bad input, so no output and no state is ever non-finite and the cell
computes again at the first good input. An ``override`` that is NaN, ±inf or Bad is no
override (NaN is the input's "not given"). Uncertain inputs are used and make
``out`` Uncertain (0x40). Otherwise ``out`` is Good non-cascade (128), with the limit bits
high (130) / low (129) when ``out`` is at ``output_max`` / ``output_min``, and constant (131)
while overridden.

Before the first scan (issue 11 point 8) ``out`` and ``pid_out`` show the start-up output
(``initial_output``, above) and the adjustments 0, so a block that reads the E2 earlier in a
module's order sees where it starts, not 0.

Options for the spec's [A]/[?] points
-------------------------------------

Each is a parameter; the default is the spec's choice.

* ``error_sign``: ``input_minus_setpoint`` (default [A]: the output rises with the input, the
  cooling sense of the vendor examples) or ``setpoint_minus_input``. Spec 3.3, 3.9, 7.
* ``i_tr_normalise``: ``false`` (default, Iadj = ki·e as printed) or ``true``
  (Iadj = ki·e·100/TR) [?]. Spec 3.3.
* ``d_form``: ``second_difference`` (default [A]) or ``as_printed``. Spec 3.3.
* ``d_tr_normalise``: ``false`` (default, D not scaled by 100 %/TR, like I) or ``true`` [?].
  Spec 3.3.
* ``initial_output``: the PID and filter output at start-up; default Output at Setpoint [?].
  Spec 3.9.
* ``startup_errors``: ``zero`` (default [?]: e_{k-1} = e_{k-2} = 0 before the first update, as
  if the input had been at setpoint) or ``current`` (both = the first error: no P or D kick at
  start-up). Spec 3.2 (the meaning of Output at Setpoint), spec 3.9 and spec 3.8 E2.
* ``old_output``: ``unfiltered`` (default [A]: the PID adds to its own unfiltered output) or
  ``filtered`` (OUT_{k-1} = F). Spec 3.6.
* ``override_updates_pid``: ``false`` (default [?]: the PID's stored output is not set from the
  override) or ``true`` (OUT and F take the override value while it is active, so the release
  is bumpless). Spec 3.7.
* ``override_limits``: ``percent`` (default [A]: the override is limited to 0..100 %) or
  ``output_limits`` (output_min..output_max). Spec 3.7.
* Setpoint Float (``low_float``, ``high_float``, ``float_range_lo``, ``float_range_hi``, the
  ``float_in`` input): linear interpolation across the float input's range, clamped at its
  ends (spec 3.7 step 2 [A]; the vendor names the settings, not the curve); a ``float_in`` that
  is NaN, ±inf or Bad holds the last shift [A].
* ``bad_input``: ``hold`` (default [A]) or ``failsafe`` (``out`` = ``failsafe_output``). The
  E2 has no status (spec 7).

The defaults of the settings themselves are [?] (spec 3.2, 3.9: the setting screens were not
retrieved): kp 1.00, ki 0.30, kd 0.00 and min_accumulated_error 0.10 are the EEPR field defaults
[R33]; throttling_range 10, output_at_setpoint 50 % and the 0/100 % clamps follow the manual's
examples; update_interval 2 s is the low end of the typical 2-6 s.

Vendor quirks reproduced
------------------------

* Increments that would push past a clamp are lost (spec 3.4), so saturation slides the
  throttling range window: TR 10, kp 1, SP 29, OAS 50: inputs 34, 36, 35 give 100, 100, 90 %
  (spec 3.8 E7), and an output held at Output at Minimum leaves it as soon as an adjustment
  raises it (spec 3.8 E3).
* The I Mode ignores errors up to and including MAE (spec 3.5, 3.8 E4, E5); P and D keep acting, so
  the loop may settle anywhere within SP ± MAE.
* ki and kd are per update, not per second: changing ``update_interval`` changes the effective
  I and D strength (spec 3.3 [D]).
* The filter is a first-order step towards the PID demand once per filter period, measured from
  the filtered output (spec 3.6; the vendor example rules out differencing two PID samples).

Example
-------

Python (P only, the vendor's throttling-range example)::

    import loopworks
    pid = loopworks.create_block("e2.pid", throttling_range=10.0, kp=1.0, ki=0.0,
                                 output_at_setpoint=50.0, update_interval=1.0)
    for pv in (24.0, 25.0, 26.0):
        print(pid.step(1.0, sp=29.0, pv=pv)["out"].value)   # 0.0, 10.0, 20.0

Replay (``loopworks replay e2.pid e2.csv -p ki=0 -p update_interval=1``), with ``e2.csv``::

    t,sp,pv,override
    0,29,24,nan
    1,29,25,nan
    2,29,26,70
    3,29,27,nan

gives ``out`` 0, 10, 70 (overridden), 30 and ``pid_out`` 0, 10, 20, 30.
"""

from __future__ import annotations

import math
import sys
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
    flag,
    no_ideal,
    number,
    span,
)
from loopworks.blocks.layout import index
from loopworks.blocks.params import Param, Port, validate
from loopworks.blocks.pid import measured
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
from loopworks.errors import InputError, ParameterError

D_SECOND_DIFFERENCE, D_AS_PRINTED = 0.0, 1.0
STARTUP_ZERO, STARTUP_CURRENT = 0.0, 1.0
OLD_UNFILTERED, OLD_FILTERED = 0.0, 1.0
BAD_HOLD, BAD_FAILSAFE = 0.0, 1.0
_PCT = "%"

INPUTS = (
    Port("pv", 0.0, "EU", "control input (process variable)", status=True),
    Port("sp", 0.0, "EU", "setpoint", status=True),
    Port("override", math.nan, _PCT, "forced output; NaN = no override (spec 3.7)",
         status=True),
    Port("float_in", math.nan, "float units", "Setpoint Float input, across float_range_lo.."
         "float_range_hi; NaN = not wired (spec 3.7 step 2)", status=True),
)
OUTPUTS = (
    Port("out", 0.0, _PCT, "output after the Filter and Override cells", status=True),
    Port("pid_out", 0.0, _PCT, "PID cell output OUT (before the filter)"),
    Port("p_adj", 0.0, _PCT, "P adjustment of the latest update"),
    Port("i_adj", 0.0, _PCT, "I adjustment of the latest update"),
    Port("d_adj", 0.0, _PCT, "D adjustment of the latest update"),
    Port("working_sp", 0.0, "EU", "the setpoint the PID works to: sp + the Setpoint Float "
         "shift (spec 3.7 step 2); while sp is bad the last usable one, status Bad",
         status=True),
)
#: the coefficient array p (coefficients())
COEFFS = ("tr", "kp", "ki", "kd", "lo", "hi", "mae", "update", "fperiod", "ffrac", "sign",
          "i_norm", "d_form", "d_norm", "startup", "old_out", "ovr_updates", "ovr_lo", "ovr_hi",
          "bad_input", "failsafe", "float_on", "low_float", "high_float", "frange_lo",
          "frange_hi")
#: the state array x
STATES = ("pid_output", "filter_output", "e1", "e2", "p_adj", "i_adj", "d_adj", "pid_timer",
          "filter_timer", "since_update", "t1", "updated", "started", "float_shift",
          "working_sp")
P, X, U, Y = index(COEFFS, "P"), index(STATES, "X"), index(INPUTS, "U"), index(OUTPUTS, "Y")

DUE_TOLERANCE = 1e-9  # relative: a timer within 1e-9·interval of the interval is due


@primitive
def timer_due(elapsed: float, interval: float) -> bool:
    """True when ``elapsed`` has reached ``interval`` (relative tolerance 1e-9, so that binary
    rounding of accumulated scan times, e.g. ten scans of 0.1 s, does not delay an update)."""
    return elapsed >= interval * (1.0 - DUE_TOLERANCE)


@primitive
def advance_timer(elapsed: float, dt: float, interval: float) -> float:
    """The timer after a scan of ``dt``: ``elapsed + dt``, less one ``interval`` if that made it
    due, and 0 if it is still due after that (at most one update per scan; missed ones are
    dropped). The caller tests :func:`timer_due` on ``elapsed + dt`` for the update itself."""
    t = elapsed + dt
    if timer_due(t, interval):
        t -= interval
        if timer_due(t, interval):
            t = 0.0
    return t


def e2_pid_kernel(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                  y: FloatArray, ys: IntArray) -> None:
    """One scan of the E2 PID, Filter and Override cells (equations in the module docstring)."""
    lo = p[P.lo]
    hi = p[P.hi]
    interval = p[P.update]
    period = p[P.fperiod]
    # -- timers (spec 3.3, 3.6): the first scan runs both cells, later scans when due ---------
    if x[X.started] == 0.0:
        x[X.started] = 1.0
        pid_due = True
        filter_due = True
        x[X.pid_timer] = 0.0
        x[X.filter_timer] = 0.0
    else:
        x[X.since_update] = x[X.since_update] + dt
        pid_due = timer_due(x[X.pid_timer] + dt, interval)
        x[X.pid_timer] = advance_timer(x[X.pid_timer], dt, interval)
        filter_due = False
        if period > 0.0:
            filter_due = timer_due(x[X.filter_timer] + dt, period)
            x[X.filter_timer] = advance_timer(x[X.filter_timer], dt, period)
    # -- input quality (no status in the E2: NaN/inf or a Bad status byte = bad input, [A]) ----
    pv = u[U.pv]
    sp = u[U.sp]
    q_pv = us[U.pv] & 0xC0
    q_sp = us[U.sp] & 0xC0
    bad = not measured(pv, us[U.pv]) or not measured(sp, us[U.sp])  # beyond ±1e12 EU too
    # -- Setpoint Float cell (spec 3.7 step 2): linear across the float input's range [A] ----
    if p[P.float_on] != 0.0:
        fin = u[U.float_in]
        if finite(fin) and (us[U.float_in] & 0xC0) != BAD:  # else the last shift holds
            # r = (fin - lo)/(hi - lo) clamped to 0..1, in halves (no overflow for any finite
            # range); shift = (1 - r)·Low + r·High (within [Low, High] for any finite floats)
            num = 0.5 * fin - 0.5 * p[P.frange_lo]
            den = 0.5 * p[P.frange_hi] - 0.5 * p[P.frange_lo]
            r = 0.0 if num <= 0.0 else (1.0 if num >= den else num / den)
            x[X.float_shift] = (1.0 - r) * p[P.low_float] + r * p[P.high_float]
        sp = sp + x[X.float_shift]
    else:  # disabled: no shift, and none held for a later enabling (it was another setting's)
        x[X.float_shift] = 0.0
    e = 0.0
    if not bad:  # spec 3.3: e = input - setpoint [A]
        e = p[P.sign] * (pv - sp)
    # -- PID cell (spec 3.3-3.5) ----------------------------------------------------------------
    if pid_due and not bad:
        if x[X.updated] == 0.0:  # first update: no measured times yet (spec 3.9 [?])
            if p[P.startup] == STARTUP_CURRENT:
                x[X.e1] = e
                x[X.e2] = e
            t1 = interval
            t2 = interval
        else:
            t1 = x[X.since_update]
            t2 = x[X.t1]
        e1 = x[X.e1]
        e2 = x[X.e2]
        padj = p[P.kp] * (e - e1) * 100.0 / p[P.tr]
        iadj = 0.0
        if abs(e) > p[P.mae]:  # spec 3.5: no I adjustment while abs(e) <= MAE
            iadj = p[P.ki] * e
            if p[P.i_norm] != 0.0:
                iadj = iadj * 100.0 / p[P.tr]
        if p[P.d_form] == D_AS_PRINTED:  # times in minutes, as printed (026-1614 p.D-4):
            # e/(t/60) written 60·e/t, so that a zero error is 0 for any t > 0
            dadj = p[P.kd] * (e - 2.0 * (60.0 * e1 / t1) + 60.0 * e2 / t2)
        else:
            dadj = p[P.kd] * (e - 2.0 * e1 + e2)
        if p[P.d_norm] != 0.0:
            dadj = dadj * 100.0 / p[P.tr]
        old = x[X.pid_output]
        if p[P.old_out] == OLD_FILTERED:  # OUT_{k-1} = F, as it is: the clamp is on the sum
            old = x[X.filter_output]
        v = old + padj + iadj + dadj
        if not finite(padj + iadj + dadj + v):  # overflow (extreme gains): skip, as bad input
            bad = True
        else:
            x[X.pid_output] = clamp(v, lo, hi)  # spec 3.4: increments past a clamp are lost
            x[X.e2] = e1
            x[X.e1] = e
            x[X.t1] = t1
            x[X.since_update] = 0.0
            x[X.updated] = 1.0
            x[X.p_adj] = padj
            x[X.i_adj] = iadj
            x[X.d_adj] = dadj
    # -- Filter cell (spec 3.6) -------------------------------------------------------------------
    if period > 0.0:
        if filter_due:
            x[X.filter_output] = (x[X.filter_output]
                                  + p[P.ffrac] * (x[X.pid_output] - x[X.filter_output]))
    else:
        x[X.filter_output] = x[X.pid_output]
    # -- Override cell (spec 3.7) and status ------------------------------------------------------
    ov = u[U.override]
    if finite(ov) and (us[U.override] & 0xC0) != BAD:
        out = clamp(ov, p[P.ovr_lo], p[P.ovr_hi])
        status = GOOD_NC | CONSTANT
        if p[P.ovr_updates] != 0.0:
            x[X.pid_output] = clamp(ov, lo, hi)
            x[X.filter_output] = out
    elif bad:
        if p[P.bad_input] == BAD_FAILSAFE:
            out = p[P.failsafe]
            status = UNCERTAIN_SUBSTITUTE | CONSTANT
        else:
            out = x[X.filter_output]
            status = UNCERTAIN_LAST_USABLE_VALUE | CONSTANT
    else:
        out = x[X.filter_output]
        status = GOOD_NC
        if q_pv == UNCERTAIN or q_sp == UNCERTAIN:
            status = UNCERTAIN_NON_SPECIFIC
        if out >= hi:
            status = status | HIGH_LIMITED
        elif out <= lo:
            status = status | LOW_LIMITED
    y[Y.out] = out
    ys[Y.out] = status
    y[Y.pid_out] = x[X.pid_output]
    y[Y.p_adj] = x[X.p_adj]
    y[Y.i_adj] = x[X.i_adj]
    y[Y.d_adj] = x[X.d_adj]
    if measured(u[U.sp], us[U.sp]) and finite(sp):
        x[X.working_sp] = sp
        ys[Y.working_sp] = GOOD_NC
    else:  # a bad sp: the last usable working setpoint, Bad
        ys[Y.working_sp] = BAD
    y[Y.working_sp] = x[X.working_sp]


def pwm_times(percent: float, period: float) -> tuple[float, float]:
    """The E2 PWM output stage (spec 3.7, E8): (on, off) seconds of one ``period`` for a PID
    output of ``percent`` %: on = period·percent/100, off = period - on; the percentage is
    limited to 0..100. 60 % of a 10 s period gives 6 s on and 4 s off.

    The PWM cell is an output stage after the Override cell, not part of the PID block."""
    if not period > 0.0 or not math.isfinite(period):
        raise ParameterError(f"e2 pwm: period = {period!r} s is out of range: allowed (0, inf) s")
    if math.isnan(percent):
        raise InputError("e2 pwm: percent = nan is not a number")
    on = period * min(max(percent, 0.0), 100.0) / 100.0
    return on, period - on


@register
class E2PID(Controller, Block):
    """Emerson E2 PID cell with its Filter and Override cells (spec vendor-blocks 3)."""

    kind = "e2.pid"
    summary = "Emerson E2 RX/BX/CX PID: incremental, throttling range, MAE, valve filter, override"
    kernel = staticmethod(e2_pid_kernel)

    PARAMS: ClassVar[tuple[Param, ...]] = (
        Param("throttling_range", 10.0, "EU",
              "Throttling Range TR: input span that sweeps the output 0-100 % at kp = 1 "
              "(spec 3.2, 3.3)", lo=0.0),
        Param("kp", 1.0, "", "P Mode gain: Padj = kp·Δe·100/TR per update (spec 3.2, 3.3)",
              lo=0.0, lo_open=False),
        Param("ki", 0.3, "%/EU per update",
              "I Mode gain: Iadj = ki·e per update, no time factor (spec 3.2, 3.3)",
              lo=0.0, lo_open=False),
        Param("kd", 0.0, "%/EU per update",
              "D Mode gain: Dadj = kd·(second difference of e) per update (spec 3.2, 3.3)",
              lo=0.0, lo_open=False),
        Param("output_at_setpoint", 50.0, _PCT,
              "Output at Setpoint: the output when input = setpoint; start-up output "
              "(spec 3.2, 3.9)", lo=0.0, hi=100.0, lo_open=False, hi_open=False),
        Param("output_min", 0.0, _PCT, "Output at Minimum: low clamp of the PID output "
              "(spec 3.2, 3.4)", lo=0.0, hi=100.0, lo_open=False, hi_open=False),
        Param("output_max", 100.0, _PCT, "Output at Maximum: high clamp of the PID output, "
              "> output_min (spec 3.2, 3.4)", lo=0.0, hi=100.0, lo_open=False, hi_open=False),
        Param("min_accumulated_error", 0.1, "EU",
              "Minimum Accumulated Error: no I adjustment while abs(e) <= MAE, inclusive edge "
              "(spec 3.5)", lo=0.0, lo_open=False),
        Param("update_interval", 2.0, "s", "time between PID updates; kp, ki and kd act once "
              "per update (spec 3.2, 3.3)", lo=0.0),
        Param("filter_period", 0.0, "s", "time between filter updates, each a step of the "
              "output towards the PID output; 0 = filter off (spec 3.6)",
              lo=0.0, lo_open=False),
        Param("filter_percentage", 100.0, _PCT,
              "filter percentage f: F += f·(OUT - F) each filter period (spec 3.6)",
              lo=0.0, hi=100.0, lo_open=False, hi_open=False),
        Param("error_sign", "input_minus_setpoint", "",
              "e = input - setpoint (output rises with the input) [A], or the reverse "
              "(spec 3.3, 3.9)", "choice",
              choices=("input_minus_setpoint", "setpoint_minus_input")),
        Param("i_tr_normalise", False, "", "also scale Iadj by 100 %/TR [?] (spec 3.3)",
              "bool"),
        Param("d_form", "second_difference", "",
              "D Mode: kd·(e - 2e₋₁ + e₋₂) [A] or the printed form with times between "
              "updates in minutes (spec 3.3)", "choice",
              choices=("second_difference", "as_printed")),
        Param("d_tr_normalise", False, "", "also scale Dadj by 100 %/TR [?] (spec 3.3)",
              "bool"),
        Param("initial_output", None, _PCT,
              "PID and filter output at start-up [?], in output_min..output_max (spec 3.9)",
              lo=0.0, hi=100.0, lo_open=False, hi_open=False,
              default_text="output_at_setpoint (clamped)"),
        Param("startup_errors", "zero", "",
              "previous errors before the first update: zero (as if at setpoint) [?] or "
              "current (no P/D kick) (spec 3.2, 3.9)", "choice", choices=("zero", "current")),
        Param("old_output", "unfiltered", "",
              "OUT_{k-1} the PID adds to: its own unfiltered output [A] or the filter output "
              "(spec 3.6)", "choice", choices=("unfiltered", "filtered")),
        Param("override_updates_pid", False, "",
              "while overridden, set the PID's stored output and the filter to the override "
              "value [?] (spec 3.7)", "bool"),
        Param("override_limits", "percent", "",
              "override limited to 0..100 % [A] or to output_min..output_max (spec 3.7)",
              "choice", choices=("percent", "output_limits")),
        Param("bad_input", "hold", "",
              "NaN/inf or Bad pv/sp: the PID holds [A], or out goes to failsafe_output "
              "(the E2 has no status, spec 7)", "choice", choices=("hold", "failsafe")),
        Param("low_float", 0.0, "EU", "Setpoint Float: the shift at the low end of the float "
              "input's range; low and high both 0 disable it (spec 3.7 step 2)"),
        Param("high_float", 0.0, "EU", "Setpoint Float: the shift at the high end of the float "
              "input's range (spec 3.7 step 2)"),
        Param("float_range_lo", 0.0, "float units", "Setpoint Float: the float input's value "
              "giving low_float (its Output Range, spec 3.7 step 2)"),
        Param("float_range_hi", 100.0, "float units", "Setpoint Float: the float input's value "
              "giving high_float, > float_range_lo; linear between [A] (spec 3.7 step 2)"),
        Param("failsafe_output", 0.0, _PCT,
              "out while pv/sp is bad and bad_input = failsafe [A] (the E2 has no status, spec 7)",
              lo=0.0, hi=100.0, lo_open=False, hi_open=False),
    )
    INPUTS: ClassVar[tuple[Port, ...]] = INPUTS
    OUTPUTS: ClassVar[tuple[Port, ...]] = OUTPUTS
    COEFFS: ClassVar[tuple[str, ...]] = COEFFS
    STATES: ClassVar[tuple[str, ...]] = STATES
    # the controller interface (loopworks.blocks.controller): the E2 has no mode input; the
    # Override cell is its manual (spec 3.7): a finite override is the output, NaN releases it
    ROLES: ClassVar[Roles] = Roles(sp="sp", pv="pv", out="out", man_out="override",
                                   working_sp="working_sp")
    AUTOMATIC: ClassVar[dict[str, Any]] = {"override": math.nan}
    MANUAL: ClassVar[dict[str, Any]] = {}
    ACTION: ClassVar[Action] = Action("error_sign", "=", "input_minus_setpoint")  # spec 3.3
    #: a relay test overrides the output; the PID's stored output follows the override
    #: (override_updates_pid), so the PID continues from it when the override ends
    HANDOVER: ClassVar[Handover] = Handover((("override", "override"),),
                                            {"override_updates_pid": True})

    @classmethod
    def output_range(cls, params: Mapping[str, Any]) -> tuple[float, float]:
        """Output at Minimum..Output at Maximum, % (spec 3.4)."""
        return float(params["output_min"]), float(params["output_max"])

    # -- the discrete law (loopworks.blocks.law), both ways ---------------------------------
    LAW_CONTEXT: ClassVar[tuple[str, ...]] = ("pv_span",)
    LAW_PARAMS: ClassVar[tuple[str, ...]] = (
        "throttling_range", "kp", "ki", "kd", "update_interval", "error_sign",
        "i_tr_normalise", "d_tr_normalise", "d_form", "min_accumulated_error", "filter_period")
    PER_SAMPLE: ClassVar[bool] = True

    @classmethod
    def spans(cls, context: Mapping[str, Any]) -> tuple[float, float]:
        """Context ``pv_span`` EU (default 100); the output is in % (span 100)."""
        return span(context, "pv_span", 100.0, cls.kind), 100.0

    @classmethod
    def law(cls, params: Mapping[str, Any], dt: float | None,
            context: Mapping[str, Any]) -> DiscreteLaw:
        """Spec 3.2, 3.3: per update Δ (``update_interval``; ``dt`` when that is not given):
        Padj = kp·Δe·100/TR, Iadj = ki·e, Dadj = kd·(e - 2e₋₁ + e₋₂); summed: P gain
        kp·100/TR %/EU, I gain ki/Δ %/(EU·s), D gain kd·Δ %·s/EU, an unfiltered backward
        difference: the pid's law with Tf = 0 (``i_tr_normalise`` / ``d_tr_normalise``
        multiply ki / kd by 100/TR). e = input - setpoint is direct action."""
        kind = cls.kind
        given = {str(k).lower() for k in params}
        prm: dict[str, Any] = validate(kind, cls.PARAMS, dict(params))
        pv_span, _ = cls.spans(context)
        notes: list[str] = []
        if "update_interval" in given or dt is None:
            step = float(prm["update_interval"])
            if "update_interval" not in given:
                notes.append(f"E2 update_interval not given: the block default {step:g} s.")
        else:
            step = dt
        if prm["d_form"] == "as_printed":
            raise ParameterError("e2.pid: parameter 'd_form' = 'as_printed' has no continuous "
                                 "equivalent (it adds an error to an error per minute): "
                                 "allowed second_difference")
        tr = float(prm["throttling_range"])
        kp = float(prm["kp"])
        if not kp > 0.0:
            raise no_ideal(kind, "kp", kp)
        kc_port = kp * 100.0 / tr  # %/EU
        ki = float(prm["ki"]) * (100.0 / tr if prm["i_tr_normalise"] else 1.0) / step
        kd = float(prm["kd"]) * (100.0 / tr if prm["d_tr_normalise"] else 1.0) * step
        flags: list[str] = []
        mae = float(prm["min_accumulated_error"])
        if mae > 0.0 and ki > 0.0:
            flags.append(f"E2 min_accumulated_error = {mae:g} EU stops the I action while "
                         "abs(e) <= MAE (a dead band the target does not have; set it to 0).")
        if float(prm["filter_period"]) > 0.0:
            flags.append("The E2 filter cell (filter_period > 0) lags the output (not "
                         "converted).")
        ideal = Ideal(kc_port * pv_span / 100.0, kc_port / ki if ki > 0.0 else math.inf,
                      kd / kc_port, 0.0, prm["error_sign"] == "input_minus_setpoint")
        return DiscreteLaw(ideal, dt=step, flags=tuple(flags), notes=tuple(notes))

    @classmethod
    def from_law(cls, law: DiscreteLaw, dt: float | None,
                 context: Mapping[str, Any]) -> Realisation:
        """Per-update gains for Δ = context ``update_interval``, else ``dt``: kp = 1 and
        TR = 100/Kc (or TR = context ``throttling_range`` and kp chosen), ki = Kc·Δ/Ti,
        kd = Kc·Td/Δ (times TR/100 with the normalise options); MAE 0."""
        kind = cls.kind
        ideal = law.ideal
        step = context.get("update_interval", dt)
        if step is None:
            raise ParameterError("e2.pid: parameter 'update_interval' (s) is required for the "
                                 "per-update gains: give sample_time; allowed (0, inf) s")
        step = number("update_interval", step, kind=kind)
        pv_span, _ = cls.spans(context)
        kc_port = ideal.kc * 100.0 / pv_span  # %/EU
        if "throttling_range" in context:
            tr = number("throttling_range", context["throttling_range"], kind=kind)
            kp = kc_port * tr / 100.0
        else:
            kp = 1.0
            tr = 100.0 / kc_port
        i_norm = flag("i_tr_normalise", context.get("i_tr_normalise", False), kind)
        d_norm = flag("d_tr_normalise", context.get("d_tr_normalise", False), kind)
        ki = kc_port / ideal.ti * step if ideal.ti < math.inf else 0.0
        kd = kc_port * ideal.td / step
        if i_norm:
            ki *= tr / 100.0
        if d_norm:
            kd *= tr / 100.0
        out: dict[str, ParamValue] = {
            "throttling_range": tr, "kp": kp, "ki": ki, "kd": kd, "update_interval": step,
            "error_sign": "input_minus_setpoint" if ideal.direct else "setpoint_minus_input",
            "min_accumulated_error": 0.0}
        if i_norm:
            out["i_tr_normalise"] = True
        if d_norm:
            out["d_tr_normalise"] = True
        return Realisation(out, step)

    def coefficients(self) -> dict[str, float]:
        prm: dict[str, Any] = self.params
        lo, hi = float(prm["output_min"]), float(prm["output_max"])
        if not lo < hi:
            raise ParameterError(
                f"e2.pid: parameter 'output_max' = {hi:g} must be greater than "
                f"output_min = {lo:g}")
        tr = float(prm["throttling_range"])
        if not math.isfinite(100.0 / tr):
            raise ParameterError(
                f"e2.pid: parameter 'throttling_range' = {tr:g} is out of range: the P "
                f"adjustment's 100 %/TR must be a finite number: allowed "
                f"({100.0 / sys.float_info.max:.3g}, inf) EU")
        init = prm["initial_output"]
        if init is not None and not lo <= float(init) <= hi:
            raise ParameterError(
                f"e2.pid: parameter 'initial_output' = {float(init):g} is out of range: "
                f"allowed [{lo:g}, {hi:g}] % (output_min..output_max)")
        ovr_lo, ovr_hi = (lo, hi) if prm["override_limits"] == "output_limits" \
            else (0.0, 100.0)
        f_lo, f_hi = float(prm["float_range_lo"]), float(prm["float_range_hi"])
        if not (f_hi > f_lo and math.isfinite(1.0 / (f_hi - f_lo))):
            raise ParameterError(
                f"e2.pid: parameter 'float_range_hi' = {f_hi:g} must be greater than "
                f"float_range_lo = {f_lo:g} (the Setpoint Float input's range)")
        low_float, high_float = float(prm["low_float"]), float(prm["high_float"])
        return {"tr": float(prm["throttling_range"]),
                "kp": float(prm["kp"]), "ki": float(prm["ki"]), "kd": float(prm["kd"]),
                "lo": lo, "hi": hi,
                "mae": float(prm["min_accumulated_error"]),
                "update": float(prm["update_interval"]),
                "fperiod": float(prm["filter_period"]),
                "ffrac": float(prm["filter_percentage"]) / 100.0,
                "sign": 1.0 if prm["error_sign"] == "input_minus_setpoint" else -1.0,
                "i_norm": 1.0 if prm["i_tr_normalise"] else 0.0,
                "d_form": D_AS_PRINTED if prm["d_form"] == "as_printed"
                else D_SECOND_DIFFERENCE,
                "d_norm": 1.0 if prm["d_tr_normalise"] else 0.0,
                "startup": STARTUP_CURRENT if prm["startup_errors"] == "current"
                else STARTUP_ZERO,
                "old_out": OLD_FILTERED if prm["old_output"] == "filtered" else OLD_UNFILTERED,
                "ovr_updates": 1.0 if prm["override_updates_pid"] else 0.0,
                "ovr_lo": ovr_lo, "ovr_hi": ovr_hi,
                "bad_input": BAD_FAILSAFE if prm["bad_input"] == "failsafe" else BAD_HOLD,
                "failsafe": float(prm["failsafe_output"]),
                "float_on": 0.0 if low_float == high_float == 0.0 else 1.0,
                "low_float": low_float, "high_float": high_float,
                "frange_lo": f_lo, "frange_hi": f_hi}

    def initial_state(self) -> list[float]:
        """OUT = F = initial_output (default Output at Setpoint, clamped); e₋₁ = e₋₂ = 0."""
        x = [0.0] * self.n_x
        init = self.params["initial_output"]
        start = float(self.params["output_at_setpoint"]) if init is None else float(init)
        start = min(max(start, self.p[P.lo]), self.p[P.hi])
        x[X.pid_output] = start
        x[X.filter_output] = start
        x[X.t1] = self.p[P.update]
        x[X.working_sp] = float(self.u[U.sp]) if math.isfinite(self.u[U.sp]) else 0.0
        return x

    def initial_outputs(self) -> list[float]:
        """Before the first scan: out = pid_out = the start-up output, no adjustments; the
        working setpoint is sp (no float shift yet)."""
        return [float(self.x[X.filter_output]), float(self.x[X.pid_output]), 0.0, 0.0, 0.0,
                float(self.x[X.working_sp])]
