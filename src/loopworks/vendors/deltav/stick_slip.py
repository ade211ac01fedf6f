r"""The DeltaV stick-slip compensator of seed 000 (dither + kicker): kind ``deltav.stick_slip``.

In the seed, a DeltaV module holds the compensator: a CALC block (COMPENSATOR, execution #4)
runs a 28-line expression on module parameters, and a signal generator (SGGN1, execution #3)
supplies the dither waveform DITHER_OUT. The compensator sits between the PID output and the AO:
``signal_in`` is the PID OUT (%), ``signal_out`` goes to the AO CAS_IN (%). It adds a *dither*
(a small alternating signal that keeps a sticky valve moving) while the PV is inside a noise
band around the setpoint, and a *kick* (a constant bias, "relay auto tuner type correction")
that pushes the PV back towards the setpoint while it is outside the band (spec vendor-blocks
section 6; plant-and-tuning 2.3 describes the same compensator from the plant side).

This block is the seed's expression, implemented natively, line by line in the seed's order,
as one CALC scan executes it. A ``deltav.calc`` block running the seed's text gives the same
outputs bit for bit when the options match.

The expression (seed 000, one scan, top to bottom)
--------------------------------------------------

Names are the seed's module parameters; in this block they are snake_case parameters, inputs
(``signal_in``, ``sp``, ``pv``, ``comp_start``, ``initialize``, ``dither_out``) and outputs::

    line 2      DITHER_AMP := (RESOLUTION + 0.5*DEADBAND)*DITHER_FACTOR*0.5
    line 3      KICKER_OUT := (RESOLUTION + 0.5*DEADBAND)*KICKER_FACTOR*0.5
    lines 5-9   IF (INITIALIZE = 1 AND KICK_START = 1) THEN NOISE_BAND := 0.0
                ELSE NOISE_BAND := DITHER_AMP*PROCESS_GAIN*NOISE_FACTOR
    line 11     IF (COMP_START = 0) THEN
    line 12         SIGNAL_OUT := SIGNAL_IN                                     (pass-through)
                ELSE
    line 15         IF (PV > (SP + NOISE_BAND*0.5)) THEN                        (high: kick)
    line 16             KICKER_DELT := KICKER_OUT*CNTRL_ACTION*VALVE_ACTION
    line 17             DITHER_DELT := 0.0
    line 19         ELSE IF (PV < (SP - NOISE_BAND)) THEN                       (low: kick)
    line 20             KICKER_DELT := - KICKER_OUT*CNTRL_ACTION*VALVE_ACTION
    line 21             DITHER_DELT := 0.0
                    ELSE                                                        (band: dither)
    line 23             DITHER_DELT := DITHER_OUT*CNTRL_ACTION*VALVE_ACTION
    line 26         SIGNAL_OUT := SIGNAL_IN + KICKER_DELT + DITHER_DELT
    line 28     SIGNAL_OUT.ST := SIGNAL_IN.ST

The arithmetic of each line is done in float64 in the order written, left to right
(``a*b*c`` is ``(a*b)*c``, ``a + b + c`` is ``(a + b) + c``, line 20 is ``((-a)*b)*c``), and
the comparisons are IEEE comparisons (strict ``>`` and ``<``; ``=`` is exact float equality, so
only exactly 1.0 (0.0) counts as 1 (0), spec 6.3). The factors 0.5 of line 15 and 1 (implicit)
of line 19 are the options ``upper_band_factor`` and ``lower_band_factor``: line 15 reads
``SP + NOISE_BAND*upper_band_factor`` and line 19 ``SP - NOISE_BAND*lower_band_factor``
(multiplying by 1.0 is exact, so the defaults are the literal text).

Precision (``precision = "float32"``, the default; spec 6.1 [A]): a DeltaV module parameter
holds a 32-bit float. So

* every value assigned to a module parameter (lines 2, 3, 6, 8, 12, 16, 17, 20, 21, 23, 26) is
  rounded once to float32 (round to nearest, ties to even; a value beyond the float32 range
  rounds to ±inf and is not stored, see "Non-finite values") when it is stored; the expression
  on the right is evaluated in float64;
* every parameter and input the expression reads is the float32-rounded value: the
  parameters are rounded when the block is made (``kick_start = 1.00000001`` is then exactly
  1), the inputs when they are read in the scan (``pv = 50.3000001`` reads as 50.29999924).

``precision = "float64"`` stores and reads float64 values unchanged.

Read/write visibility (``deferred_param_reads``, spec 6.1 [A]). With ``false`` (the default)
a line sees the values written by earlier lines of the same scan (immediate writes). With
``true`` every read of a parameter that the expression writes (DITHER_AMP, KICKER_OUT,
NOISE_BAND, KICKER_DELT, DITHER_DELT, SIGNAL_OUT) sees its value as of the start of the scan,
i.e. the value stored by the previous scan (the seed defaults, 0, at the first scan): line 8
uses last scan's DITHER_AMP, lines 15/19 last scan's NOISE_BAND, lines 16/20 last scan's
KICKER_OUT and line 26 last scan's KICKER_DELT and DITHER_DELT. Parameters the expression never
writes (the inputs and the tuning parameters) read their current values in both modes. The
writes themselves are the same in both modes.

DITHER_OUT (spec 6.5). The ``dither_out`` input is the SGGN1 output; wire a ``deltav.sggn`` block
that runs before this one to it (see ``deltav.sggn``). While ``dither_out`` is NaN (its default:
"not supplied") the block uses an internal square wave instead, the spec's default reading of
SGGN1 [A]: at the start of each scan, *before line 2 executes* (SGGN1 is execution #3, the CALC
#4), the sample is::

    DITHER_OUT_k = +DITHER_AMP_{k-1}   if floor(k / dither_half_period) is even   (k = 0, 1, ...)
                 = -DITHER_AMP_{k-1}   otherwise

where DITHER_AMP_{k-1} is the value line 2 stored in the previous scan (0, the seed default, in
the first scan k = 0): a one-scan lag of the amplitude. The wave starts with + and alternates
every ``dither_half_period`` scans; its scan counter k advances on every scan, whether or not
``dither_out`` is supplied. A supplied ``dither_out`` is read as a module parameter
(float32-rounded in float32 precision).

Status (spec 6.3 line 28): ``signal_out`` carries the status byte of ``signal_in`` unchanged
on every scan, in both branches; the compensator neither degrades nor improves it. The other
outputs are Good non-cascade (128). Input statuses are otherwise ignored, as in the expression.

Non-finite values (issue 11 point 1), the rule of ``deltav.calc`` for a CALC block, so the two
stay bit for bit equal:

* an input that is NaN or ±inf, or beyond the float32 range in float32 precision (``1e308``
  reads as ±inf), is Bad input. The expression reads its value as it is, with IEEE
  comparisons (every comparison with NaN is false): a NaN ``comp_start`` is not 0 and selects
  the compensation branch; a NaN ``initialize`` is not 1 (the noise band is computed); a NaN
  ``pv`` or ``sp`` fails both band tests and selects the dither branch (KICKER_DELT held); an
  infinite ``pv`` is above the trigger (high). A NaN ``dither_out`` cannot reach line 23: it
  means "use the internal dither" (above). Line 28 reads SIGNAL_IN.ST as Bad (0) while
  ``signal_in`` is not finite, unless it arrives Bad already (then its substatus is kept);
* an assignment whose result is not finite (after the float32 rounding of the store: a sum
  beyond the float32 range is one) is not stored: the module parameter keeps its last value
  and is **held**, its output Bad (0; SIGNAL_OUT keeps SIGNAL_IN's status if that is Bad) for
  that scan. A later scan that does not assign it (KICKER_DELT inside the band) shows it Good
  with the last value stored, as the expression holds it. So a NaN ``signal_in`` holds
  ``signal_out`` at its last value, Bad; an infinite ``dither_out`` holds ``dither_delt``, Bad,
  while ``signal_out`` adds the held dither and keeps ``signal_in``'s status.

No output and no state is ever non-finite, and the block recovers as soon as its inputs are
good again. Nothing is clamped: there is no limit on
``signal_out`` (spec 6.3 line 26), and the block never raises on a value.

Before the first scan (issue 11 point 8) ``signal_out`` passes ``signal_in`` through (no kick,
no dither yet) and the other outputs show the seed's defaults, 0 (spec 6.2), which is what
SGGN1 reads as DITHER_AMP at the first scan (spec 6.5).

Options for the spec's [A]/[?] points
-------------------------------------

Each is a parameter; the default is the spec's choice.

* ``upper_band_factor`` = 0.5 and ``lower_band_factor`` = 1.0: the factors of NOISE_BAND in the
  high (line 15) and low (line 19) band tests; the defaults are the literal, asymmetric text
  (spec 6.4 [A]). ``upper_band_factor = lower_band_factor`` gives a symmetric band.
* ``deferred_param_reads`` = false: immediate writes; true = reads see last scan's values
  (spec 6.1 [A]).
* ``precision`` = ``float32``: module parameters are 32-bit floats, rounded on every store;
  ``float64`` keeps doubles (spec 6.1 [A]).
* ``kick_in_band`` = ``held``: KICKER_DELT keeps the last kick while the PV is inside the band
  (the seed's text, a quirk reproduced); ``reset`` zeroes it there, "dither only in band",
  the corrected behaviour plant-and-tuning 2.3 item 2 names (architecture: "the held kick").
* ``dither_half_period`` = 1 scan: the internal DITHER_OUT square wave (±last scan's DITHER_AMP,
  starting with +) alternates every this many scans (spec 6.5 [A]; the SGGN1 configuration is
  unknown, spec 8 item 5).

Vendor quirks reproduced
------------------------

* The band is asymmetric: high above SP + NOISE_BAND/2, low below SP - NOISE_BAND, so it is
  1.5·NOISE_BAND wide (SP - 0.6 .. SP + 0.3 for NOISE_BAND 0.6) (spec 6.4).
* KICKER_DELT keeps its last value while the PV is inside the band (the last kick persists
  while dithering: a relay with hysteresis, spec 6.6) and while COMP_START = 0 (spec 6.3).
* DITHER_DELT is zeroed in the kick branches; with COMP_START = 0 both KICKER_DELT and
  DITHER_DELT keep their (stale) values and come back into effect when compensation resumes,
  until overwritten (spec 6.3 lines 11-12).
* DITHER_AMP is half the header's peak-to-peak dither: resolution 0.5 %, deadband 0.2 % give
  DITHER_AMP 0.3 % (spec 6.2).
* INITIALIZE = KICK_START = 1 collapses the band to 0: every PV ≠ SP kicks (pure relay,
  spec 6.6). Nothing in the expression clears INITIALIZE.
* NOISE_BAND (% of PV span) is compared with SP and PV in EU as raw numbers (spec 6.7), and the
  kick direction is the literal product CNTRL_ACTION·VALVE_ACTION (spec 6.7).
* ``reset_time`` is a parameter of the seed's list but the expression does not use it
  (spec 6.2).
* No clamp on ``signal_out``: it can leave 0..100 % by up to KICKER_OUT + DITHER_AMP (spec 6.3).

Example
-------

Python (the golden step-through of spec 6.8, first three scans)::

    import loopworks
    comp = loopworks.create_block("deltav.stick_slip", resolution=0.5, deadband=0.2)
    for pv, dither in ((50.0, 0.3), (50.0, -0.3), (50.5, 0.3)):
        r = comp.step(1.0, signal_in=40.0, sp=50.0, pv=pv, comp_start=1.0, dither_out=dither)
        print(r["signal_out"].value, r["kicker_delt"].value)
    # 39.70000076293945 0.0            (band: dither -0.3)
    # 40.29999923706055 0.0            (band: dither +0.3)
    # 39.70000076293945 -0.30000001192092896   (high: kick -0.3)

(float32 values; ``precision="float64"`` gives 39.7, 40.3, 39.7.)

Replay (``loopworks replay deltav.stick_slip comp.csv -p resolution=0.5 -p deadband=0.2
-p precision=float64``), with ``comp.csv``::

    t,signal_in,sp,pv,comp_start,dither_out,signal_in.ST
    0,40,50,50.0,1,0.3,128
    1,40,50,50.5,1,0.3,128
    2,40,50,49.5,1,-0.3,28
    3,40,50,49.5,0,0.3,128

gives ``signal_out`` 39.7, 39.7 (kick -0.3), 40.0 (kick held, dither +0.3), 40.0
(pass-through) and ``signal_out.ST`` 128, 128, 28, 128 (every output has a ``.ST`` column;
the others are 128 here).
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

from loopworks.blocks.block import Block
from loopworks.blocks.kernel import FloatArray, IntArray, primitive
from loopworks.blocks.layout import index
from loopworks.blocks.params import Param, Port
from loopworks.blocks.primitives import finite
from loopworks.blocks.registry import register
from loopworks.blocks.status import GOOD_NC
from loopworks.errors import ParameterError
from loopworks.vendors.deltav.calc import FLOAT32_OVERFLOW as F32_OVERFLOW
from loopworks.vendors.deltav.calc import input_status, shown_status
from loopworks.vendors.deltav.calc import to_float32 as f32

_PCT = "%"
# the module parameters of the seed's list, in the p layout order
_SEED_PARAMS = ("resolution", "deadband", "process_gain", "cntrl_action", "valve_action",
                "dither_factor", "kicker_factor", "noise_factor", "kick_start", "reset_time")

INPUTS = (
    Port("signal_in", 0.0, _PCT, "SIGNAL_IN, 'PID OUT (%)': the PID output (spec 6.2)",
         status=True),
    Port("sp", 0.0, "EU", "SP, 'PID Set Point (eu)' (spec 6.2)"),
    Port("pv", 0.0, "EU", "PV, 'PID Process Variable (eu)' (spec 6.2)"),
    Port("comp_start", 0.0, "",
         "COMP_START: exactly 0 passes signal_in through; else compensate (spec 6.3)"),
    Port("initialize", 0.0, "",
         "INITIALIZE: exactly 1 with kick_start = 1 sets NOISE_BAND = 0 (spec 6.3)"),
    Port("dither_out", math.nan, _PCT,
         "DITHER_OUT, the SGGN1 output; NaN = internal square wave (spec 6.5)"),
)
OUTPUTS = (
    Port("signal_out", 0.0, _PCT,
         "SIGNAL_OUT, 'AO CAS_IN (%)': signal_in + kick + dither, no clamp; status = "
         "signal_in's (spec 6.3 lines 26, 28)", status=True),
    Port("dither_amp", 0.0, _PCT, "DITHER_AMP: dither amplitude, (RESOLUTION + "
         "DEADBAND/2)·DITHER_FACTOR/2 (spec 6.3 line 2)", status=True),
    Port("kicker_out", 0.0, _PCT, "KICKER_OUT: kick amplitude, (RESOLUTION + "
         "DEADBAND/2)·KICKER_FACTOR/2 (spec 6.3 line 3)", status=True),
    Port("noise_band", 0.0, "% of PV", "NOISE_BAND: PV noise band, DITHER_AMP·"
         "PROCESS_GAIN·NOISE_FACTOR; 0 while INITIALIZE = KICK_START = 1 (spec 6.3 lines "
         "5-9)", status=True),
    Port("kicker_delt", 0.0, _PCT,
         "KICKER_DELT: kick applied; held inside the band (spec 6.3 lines 16, 20)",
         status=True),
    Port("dither_delt", 0.0, _PCT,
         "DITHER_DELT: dither applied; 0 while kicking (spec 6.3 lines 17, 21, 23)",
         status=True),
)
#: the coefficient array p: the module parameters (as stored), then the options
COEFFS = (*_SEED_PARAMS, "upper_band_factor", "lower_band_factor", "deferred", "single",
          "half_period", "reset_kick")
#: the state array x: the module parameters the expression writes, the internal dither's
#: scan counter
STATES = (
    "dither_amp", "kicker_out", "noise_band", "kicker_delt", "dither_delt", "dither_count",
    "signal_out")
P, X, U, Y = index(COEFFS, "P"), index(STATES, "X"), index(INPUTS, "U"), index(OUTPUTS, "Y")


@primitive
def stored(value: float, single: float) -> float:
    """The value a module parameter holds after ``value`` is written: float32-rounded when
    ``single`` (precision float32; beyond the float32 range ±inf), else unchanged. Reads of
    inputs use it too: an input is a module parameter written by someone else."""
    if single != 0.0:
        return f32(value)
    return value


@primitive
def keep(new: float, old: float) -> float:
    """The value a module parameter holds after an assignment of ``new``: ``new`` when it is
    finite, else ``old`` (a non-finite result is not stored; the parameter is held, Bad)."""
    if finite(new):
        return new
    return old


@primitive
def held(new: float) -> float:
    """The held flag of this scan after an assignment of ``new``: 1 when it was not finite."""
    return 0.0 if finite(new) else 1.0


def stick_slip_kernel(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                      y: FloatArray, ys: IntArray) -> None:
    """One module scan: SGGN1 (internal dither), then the seed's lines 2-28 in order.

    Every array element is read once into a local Python float (``float()`` costs nothing
    compiled, and keeps the interpreted run in plain IEEE floats, without numpy warnings).
    Each assignment is ``value = keep(v, old)``, ``flag = held(v)``: a non-finite result keeps
    the old value and marks the parameter held (Bad) for this scan, exactly as ``deltav.calc``
    stores."""
    single = p[P.single]
    deferred = p[P.deferred] != 0.0
    # the tuning parameters, as stored (float32-rounded by coefficients() in float32 precision)
    resolution = float(p[P.resolution])
    deadband = float(p[P.deadband])
    process_gain = float(p[P.process_gain])
    action = float(p[P.cntrl_action])
    valve = float(p[P.valve_action])
    # the parameters the expression writes, as of the start of the scan
    da0 = float(x[X.dither_amp])
    ko0 = float(x[X.kicker_out])
    nb0 = float(x[X.noise_band])
    kicker_delt = float(x[X.kicker_delt])
    dither_delt = float(x[X.dither_delt])
    signal_out = float(x[X.signal_out])
    held_kd = 0.0  # KICKER_DELT, DITHER_DELT: assigned in some branches only
    held_dd = 0.0
    # -- SGGN1 (#3) before the CALC (#4): DITHER_OUT, spec 6.5 ---------------------------------
    count = float(x[X.dither_count])
    positive = count < p[P.half_period]
    count = count + 1.0
    if count >= 2.0 * p[P.half_period]:
        count = 0.0
    x[X.dither_count] = count
    dither = float(u[U.dither_out])
    if not math.isnan(dither):  # supplied (SGGN1 wired): the module parameter as stored
        dither = stored(dither, single)
    elif positive:  # not supplied: the internal square wave, ±DITHER_AMP of the last scan [A]
        dither = da0
    else:
        dither = -da0
    # -- line 2, line 3 -------------------------------------------------------------------------
    v = stored((resolution + 0.5 * deadband) * float(p[P.dither_factor]) * 0.5, single)
    da = keep(v, da0)
    held_da = held(v)
    v = stored((resolution + 0.5 * deadband) * float(p[P.kicker_factor]) * 0.5, single)
    ko = keep(v, ko0)
    held_ko = held(v)
    # -- lines 5-9: NOISE_BAND ------------------------------------------------------------------
    if stored(float(u[U.initialize]), single) == 1.0 and p[P.kick_start] == 1.0:
        v = 0.0
    else:
        v = stored((da0 if deferred else da) * process_gain * float(p[P.noise_factor]), single)
    nb = keep(v, nb0)
    held_nb = held(v)
    # -- lines 11-27 ------------------------------------------------------------------------------
    signal_in = stored(float(u[U.signal_in]), single)
    if stored(float(u[U.comp_start]), single) == 0.0:
        v = signal_in  # line 12: pass-through; KICKER_DELT, DITHER_DELT untouched
    else:
        pv = stored(float(u[U.pv]), single)
        sp = stored(float(u[U.sp]), single)
        band = nb0 if deferred else nb
        kicker = ko0 if deferred else ko
        kd_read = kicker_delt  # line 26 reads these: the start-of-scan values when deferred
        dd_read = dither_delt
        if pv > (sp + band * float(p[P.upper_band_factor])):  # lines 15-17: high
            v = stored(kicker * action * valve, single)
            kicker_delt = keep(v, kicker_delt)
            held_kd = held(v)
            dither_delt = 0.0
            held_dd = 0.0
        elif pv < (sp - band * float(p[P.lower_band_factor])):  # lines 19-21: low
            v = stored(-kicker * action * valve, single)
            kicker_delt = keep(v, kicker_delt)
            held_kd = held(v)
            dither_delt = 0.0
            held_dd = 0.0
        else:  # line 23: inside the band, KICKER_DELT held (kick_in_band = reset: 0)
            v = stored(dither * action * valve, single)
            dither_delt = keep(v, dither_delt)
            held_dd = held(v)
            if p[P.reset_kick] != 0.0:
                kicker_delt = 0.0
                held_kd = 0.0
        if not deferred:
            kd_read = kicker_delt
            dd_read = dither_delt
        v = stored(signal_in + kd_read + dd_read, single)  # line 26, no clamp
    signal_out = keep(v, signal_out)
    held_so = held(v)
    # -- line 28: SIGNAL_OUT.ST := SIGNAL_IN.ST (Bad while SIGNAL_IN is not finite) ------------
    status = input_status(signal_in, int(us[U.signal_in]))
    # -- store and the outputs --------------------------------------------------------------------
    x[X.dither_amp] = da
    x[X.kicker_out] = ko
    x[X.noise_band] = nb
    x[X.kicker_delt] = kicker_delt
    x[X.dither_delt] = dither_delt
    x[X.signal_out] = signal_out
    y[Y.signal_out] = signal_out
    y[Y.dither_amp] = da
    y[Y.kicker_out] = ko
    y[Y.noise_band] = nb
    y[Y.kicker_delt] = kicker_delt
    y[Y.dither_delt] = dither_delt
    ys[Y.signal_out] = shown_status(status, held_so)
    ys[Y.dither_amp] = shown_status(GOOD_NC, held_da)
    ys[Y.kicker_out] = shown_status(GOOD_NC, held_ko)
    ys[Y.noise_band] = shown_status(GOOD_NC, held_nb)
    ys[Y.kicker_delt] = shown_status(GOOD_NC, held_kd)
    ys[Y.dither_delt] = shown_status(GOOD_NC, held_dd)


@register
class StickSlip(Block):
    """DeltaV stick-slip compensator (seed 000): dither inside a noise band, kick outside."""

    kind = "deltav.stick_slip"
    summary = ("DeltaV stick-slip compensator (seed 000 CALC): dither inside the noise band, "
               "relay-type kick outside it")
    kernel = staticmethod(stick_slip_kernel)

    PARAMS: ClassVar[tuple[Param, ...]] = (
        Param("resolution", 0.0, _PCT,
              "RESOLUTION, 'Stick-Slip (%)': valve resolution (spec 6.2, line 2)"),
        Param("deadband", 0.0, _PCT,
              "DEADBAND, 'Backlash (%)': valve deadband, not a PID dead band (spec 6.2)"),
        Param("process_gain", 2.0, "%PV/%OUT",
              "PROCESS_GAIN, 'Identified Process Gain' from the tuner (spec 6.2, line 8)"),
        Param("cntrl_action", -1.0, "",
              "CNTRL_ACTION: Reverse = -1, Direct = +1; used as a factor (spec 6.2, 6.7)"),
        Param("valve_action", 1.0, "",
              "VALVE_ACTION: Inc-close = -1, Inc-open = +1; used as a factor (spec 6.2, 6.7)"),
        Param("dither_factor", 1.0, "", "DITHER_FACTOR: scales DITHER_AMP (spec 6.2, line 2)"),
        Param("kicker_factor", 1.0, "", "KICKER_FACTOR: scales KICKER_OUT (spec 6.2, line 3)"),
        Param("noise_factor", 1.0, "", "NOISE_FACTOR: scales NOISE_BAND (spec 6.2, line 8)"),
        Param("kick_start", 0.0, "",
              "KICK_START: exactly 1 with INITIALIZE = 1 sets NOISE_BAND = 0 (spec 6.2, 6.3)"),
        Param("reset_time", 8.0, "s",
              "RESET_TIME, 'PID Reset Time (sec)': read but unused by the expression "
              "(spec 6.2)"),
        Param("upper_band_factor", 0.5, "",
              "high test PV > SP + NOISE_BAND·factor; literal 0.5 [A] (spec 6.4, line 15)",
              lo=0.0, lo_open=False),
        Param("lower_band_factor", 1.0, "",
              "low test PV < SP - NOISE_BAND·factor; literal 1 [A] (spec 6.4, line 19)",
              lo=0.0, lo_open=False),
        Param("deferred_param_reads", False, "",
              "reads of parameters the expression writes see last scan's values; false = "
              "immediate writes [A] (spec 6.1)", "bool"),
        Param("precision", "float32", "",
              "module parameters are float32, rounded on every store [A], or float64 "
              "(spec 6.1)", "choice", choices=("float32", "float64")),
        Param("kick_in_band", "held", "",
              "KICKER_DELT inside the band: held, the last kick persists while dithering "
              "(the seed's text), or reset to 0, dither only in band (spec plant-and-tuning "
              "2.3 item 2)", "choice", choices=("held", "reset")),
        Param("dither_half_period", 1, "scans",
              "internal dither (dither_out NaN): ±last scan's DITHER_AMP, starting +, "
              "alternating every N scans [A] (spec 6.5)", "int", lo=1.0, hi=1e9,
              lo_open=False, hi_open=False),
    )
    INPUTS: ClassVar[tuple[Port, ...]] = INPUTS
    OUTPUTS: ClassVar[tuple[Port, ...]] = OUTPUTS
    COEFFS: ClassVar[tuple[str, ...]] = COEFFS
    STATES: ClassVar[tuple[str, ...]] = STATES

    def coefficients(self) -> dict[str, Any]:
        prm: dict[str, Any] = self.params
        single = prm["precision"] == "float32"
        coeffs: dict[str, Any] = {}
        for name in _SEED_PARAMS:
            value = float(prm[name])
            if single and abs(value) >= F32_OVERFLOW:
                raise ParameterError(
                    f"{self.kind}: parameter '{name}' = {value!r} is out of range: a float32 "
                    f"module parameter allows (-{F32_OVERFLOW!r}, {F32_OVERFLOW!r}), i.e. "
                    "values that round to a finite float32 (precision = float32, spec 6.1)")
            coeffs[name] = f32(value) if single else value
        coeffs["upper_band_factor"] = float(prm["upper_band_factor"])
        coeffs["lower_band_factor"] = float(prm["lower_band_factor"])
        coeffs["deferred"] = 1.0 if prm["deferred_param_reads"] else 0.0
        coeffs["single"] = 1.0 if single else 0.0
        coeffs["half_period"] = float(prm["dither_half_period"])
        coeffs["reset_kick"] = 1.0 if prm["kick_in_band"] == "reset" else 0.0
        return coeffs

    def initial_state(self) -> list[float]:
        """The written module parameters at the seed's defaults (spec 6.2: all 0); the
        internal dither at its first scan."""
        return [0.0] * self.n_x

    def publish_start(self) -> None:
        """SIGNAL_IN, settled by the module before the first scan, passed through."""
        self.publish_pass_through("signal_out", "signal_in")

    def initial_outputs(self) -> list[float]:
        """Before the first scan (issue 11 point 8): SIGNAL_OUT passes SIGNAL_IN through (no
        kick, no dither yet), the other outputs show the seed's defaults (0; SGGN1 reads
        DITHER_AMP 0 at the first scan, spec 6.5)."""
        x = self.x
        signal_in = stored(float(self.u[U.signal_in]), self.p[P.single])
        y = [0.0] * len(self.OUTPUTS)
        y[Y.signal_out] = signal_in if finite(signal_in) else float(x[X.signal_out])
        y[Y.dither_amp] = float(x[X.dither_amp])
        y[Y.kicker_out] = float(x[X.kicker_out])
        y[Y.noise_band] = float(x[X.noise_band])
        y[Y.kicker_delt] = float(x[X.kicker_delt])
        y[Y.dither_delt] = float(x[X.dither_delt])
        return y
