r"""Emerson DeltaV standard PID function block: kind ``deltav.pid``.

The DeltaV PID is the Foundation Fieldbus PID model, extended (spec vendor-blocks section 4;
sources R40-R47 DeltaV Books Online, R53-R58). This block emulates the part of it the spec
covers: Standard and Series forms, the eight STRUCTURE options with BETA and GAMMA, reset by
external positive feedback (optionally from BKCAL_IN: dynamic reset limiting), the ARW window
with its 16x reset, IDEADBAND, the PV and SP filters, SP limits and SP rate limits, feedforward,
the modes OOS, IMan, LO, Man, Auto and Cas with bumpless transfer, PV_SCALE / OUT_SCALE
normalisation and the Fieldbus status handling of spec 4.5-4.6. Not emulated: RCas/ROut (and
SHED_OPT), BYPASS, NL_GAIN_MOD, the fault-state (FSA) logic and alarms.

Signals and units
-----------------

Inputs are in engineering units (EU): ``pv`` (IN), ``sp``, ``cas_in`` in PV_SCALE EU;
``bkcal_in``, ``man_out`` and the output limits in OUT_SCALE EU; ``ff_val`` in FF_SCALE EU;
``trk_val`` in TRK_SCALE EU. The algorithm works in percent of span (spec 4.2, 4.9: GAIN is
dimensionless on %/% signals, so changing a span changes the effective gain)::

    x% = (x - EU@0%) · 100/(EU@100% - EU@0%)        EU = EU@0% + x%·(EU@100% - EU@0%)/100

Each scan, in the order of spec 4.7 (k = this scan, s = +1 reverse acting, -1 with
``direct_acting``; dt = the ``step`` time, the fixed module period, never 0)::

    1  actual mode from the target, IN, CAS_IN, BKCAL_IN, TRK_IN_D and STATUS_OPTS (below)
    2  SP: operator SP (Auto/Man), CAS_IN (Cas; limited with obey_sp_limits_cas), limited to
       SP_LO_LIM..SP_HI_LIM when written; ramped in Auto at SP_RATE_UP/SP_RATE_DN (EU/s,
       0 = no limit); then the SP_FTIME filter; SP = PV with the SP-PV track options
    3  PV_k = PV_{k-1} + dt/(PV_FTIME + dt)·(IN_k - PV_{k-1})                [A] backward Euler
    4  SP%, PV% on PV_SCALE
    5  P_k = s·GAIN·(β·SP% - PV%)            (0 in the structures without P)
    6  D_k = (α·RATE·D_{k-1} + s·GAIN·c·RATE·(d_k - d_{k-1}))/(α·RATE + dt),  d = γ·SP% - PV%
                                                                            [A] backward Euler
    7  R_k = R_{k-1} + a·(F_{k-1} - R_{k-1}),  a = dt/RESET                 [A] Euler (a <= 1)
       (RESET/16 under the ARW rule; frozen while abs(SP - PV) < IDEADBAND (EU); frozen in
       the structures without I)
    8  FF_k = FF_GAIN·FF_VAL converted from FF_SCALE to %                   [A] order
    9  OUT%_k = P_k + D_k + R_k + FF_k, limited to OUT_LO_LIM..OUT_HI_LIM; limit bits with
       BKCAL_HYS hysteresis
    10 Man/LO/IMan/OOS: OUT% = operator value / TRK_VAL / BKCAL_IN / held, then
       R_k = OUT%_k - P_k - D_k - FF_k (back-initialisation: the next Auto scan is bumpless)
    11 BKCAL_OUT = working SP (PV in Cas with use_pv_for_bkcal_out); statuses

STRUCTURE (spec 4.3) sets β, γ and whether P and I act: ``pid_action_on_error`` β = γ = 1;
``pi_action_on_error_d_action_on_pv`` β = 1, γ = 0; ``i_action_on_error_pd_action_on_pv``
β = γ = 0; ``pd_action_on_error`` β = γ = 1, no I; ``p_action_on_error_d_action_on_pv`` β = 1,
γ = 0, no I; ``id_action_on_error`` no P, γ = 1; ``i_action_on_error_d_action_on_pv`` no P,
γ = 0; ``two_degrees_of_freedom`` β = ``beta``, γ = ``gamma``. RESET = inf also means no I.

The reset is external positive feedback (spec 4.2, 4.4): R is a first-order lag of time
constant RESET driven by F, which is built from the previous *limited* output (or from
BKCAL_IN% with ``dynamic_reset_limit``, when BKCAL_IN is usable)::

    reset_feedback = "error":   F = OUT%_{k-1} - FF_{k-1} - (P_{k-1} - Pe_{k-1}) [- D_{k-1}]
    reset_feedback = "output":  F = OUT%_{k-1} - FF_{k-1}     (spec 4.7 step 7 as written)

with Pe = s·GAIN·(SP% - PV%) (proportional action on the error) and D removed in the
Standard form only. While nothing limits the output, "error" makes the block exactly the
equations of spec 4.2: Standard OUT = s·GAIN·[(β·SP - PV) + 1/(RESET·s)·(SP - PV) +
RATE·s/(α·RATE·s + 1)·(γ·SP - PV)] + FF, and Series OUT = s·GAIN·(1 + 1/(RESET·s))·
(1 + RATE·s)/(α·RATE·s + 1)·E + FF (the series D, with c = 1 - α, stays inside the reset loop,
which makes the two factors multiply). At a limit, R runs toward the limited output, so it can
never pass the limit, and it is not pinned there either: when the error vanishes OUT drops to
R (spec 4.8 DV2). With RATE = 0 and β = 1 the two settings are the same.

ARW (spec 4.4, R42): when OUT%_{k-1} > ARW_HI_LIM and R is moving down (F < R), or
OUT%_{k-1} < ARW_LO_LIM and R is moving up, the scan uses RESET/16. A BKCAL_IN with Good
quality and high (low) limit bits stops R from rising (falling): the upstream block stops
integrating in the direction the downstream one cannot follow (spec 4.4; constant = both).

Modes (spec 4.5)
----------------

Codes (the ``mode`` input and the ``mode_actual`` / ``mode_target`` outputs): OOS 0, IMAN 1,
LO 2, MAN 3, AUTO 4, CAS 5. The target is OOS, MAN, AUTO or CAS (IMan and LO are actual modes
only: a write of them is rejected, the target stays). The actual mode, highest priority first:

* OOS: target OOS. OUT holds (operator writes accepted); status Bad: out of service (0x1C).
* IMan: BKCAL_IN is Bad, or Good cascade with substatus IR, NI, LO or FSA (the downstream block
  is not in cascade; FF rule, spec 4.5). OUT = BKCAL_IN (not limited; held when BKCAL_IN has no
  value).
* LO: ``track_enable`` and TRK_IN_D true (> 0.5, not Bad) while the target is not Man (or is
  Man with ``track_in_manual``). OUT = TRK_VAL converted from TRK_SCALE, limited to the OUT
  limits (held while TRK_VAL is NaN or Bad).
* Man: target Man, or IN Bad. OUT is the operator's ``man_out``, limited unless
  ``no_out_limits_manual`` (with target and actual Man).
* Cas: target Cas and CAS_IN usable (finite, not Bad): SP = CAS_IN; the SP parameter follows
  it, so Cas -> Auto keeps the last cascade SP.
* Auto: target Auto, or target Cas with an unusable CAS_IN (the block sheds to Auto).

In Man, LO, IMan and OOS, R is back-initialised each scan (step 10), so the return to Auto or
Cas is bumpless; after a scan without a usable PV (Bad IN, or the very first scan) the first
scan with one re-initialises R, D and the previous terms from the current P, D and FF, as if
the scan before had been a Man scan with those values.

Operator writes. ``sp``, ``man_out`` and ``mode`` are the operator's writes to the SP, OUT and
MODE.TARGET parameters: a value is written when it differs from the value the input had on the
scan before (the inputs latch, as a DCS parameter does). A repeated value therefore writes
nothing, so what the block itself sets is kept: the SP set by Cas or by SP-PV tracking, the
output held on Auto -> Man, and the target set to Man by "Target to Manual if Bad IN" (to
return, give another mode and then AUTO). A value that is not storable (below) writes nothing,
and the next storable value is a write even if it equals the last one (the input had no value
in between). SP writes are rejected in Cas, OUT writes
outside Man and OOS. The first scan writes whatever the inputs hold.

Start. The block starts with OUT = ``initial_out`` (default the OUT_SCALE 0 % value) and R
back-initialised at the first scan, as if it had been in Man there: the first Auto scan gives
OUT_1 = initial_out + a·Pe_1. To start from a steady state (spec 4.8 DV1/DV2: OUT = R = 50 %,
e = 0), run one scan with SP = PV (in MAN with ``man_out`` = 50, or in AUTO with
``initial_out`` = 50), then step the error. Before the first scan the block already publishes
its start values (what a block earlier in a module's order reads from it): OUT =
``initial_out``, BKCAL_OUT = working SP = the initial SP (0 limited to SP_LO_LIM..SP_HI_LIM),
mode Man (the target until the first scan writes ``mode``), R = OUT%, and 0 for the PV (IN's
default), P, D and FF; their status is the project's start status, Good non-cascade.

Status (spec 4.6; FF encoding, ``loopworks.blocks.status``)
----------------------------------------------------------

* Storable values. All analogue values are 32-bit floats [A] (spec 4.1): an input value that
  is NaN, infinite or beyond the float32 range (abs > 3.4028235e38, e.g. 1e308: a DeltaV float
  parameter cannot hold it) is Bad input, whatever status it arrives with, with either
  ``precision`` (float64 changes the rounding, not the parameter range).
* IN: not storable, or Bad = Bad; Uncertain = Bad unless ``use_uncertain_as_good``. Bad IN
  makes the actual mode Man (``target_to_man_if_bad_in``: the target too, so the loop stays
  in Man after IN recovers). ``filtered_pv`` carries IN.ST (Bad non-specific for a value that
  is not storable) and holds its last value while IN has no usable value.
* OUT.ST quality: Good cascade when BKCAL_IN comes from a cascade partner (any BKCAL_IN status
  except Good non-cascade: an AO or a secondary PID), else Good non-cascade. BKCAL_IN's
  default, NaN, means not connected: a NaN that arrives Good (every non-finite input is
  seen as Bad non-specific), Bad non-specific or Bad not connected (0x08) is no
  BKCAL_IN at all (no IMan, Good non-cascade); a NaN with another Bad substatus, and an
  infinite or unstorable value with any status, is a Bad BKCAL_IN (IMan, OUT held). In
  Auto/Cas the limit bits come from the BKCAL_HYS hysteresis (set at OUT_HI_LIM/OUT_LO_LIM,
  released when OUT% is BKCAL_HYS % away), and an Uncertain IN used as Good degrades OUT.ST
  to Uncertain (0x40). Man, LO and IMan give the constant bits (3); IMan answering an IR
  request gives Good cascade IA (0xC7). OOS: 0x1C. ``ifs_if_bad_in`` / ``ifs_if_bad_cas_in``
  (CAS_IN unusable while the target is Cas) give Good cascade IFS (0xE0) with the same limit
  bits.
* BKCAL_OUT.ST: Good cascade (0xC0) in Cas, LO (0xD8) in LO, IR (0xC8) while the target is Cas
  but the actual mode is not, NI (0xCC) otherwise, each with the hysteresis limit bits of OUT;
  Bad: out of service in OOS. A primary ``deltav.pid`` wired to it goes to IMan on IR/NI/LO.
* FF_VAL not storable or Bad: the last usable FF contribution is held. CAS_IN, BKCAL_IN,
  TRK_VAL and TRK_IN_D are usable when storable and not Bad (CAS_IN unusable: Cas sheds to
  Auto; TRK_VAL unusable in LO: OUT holds; TRK_IN_D unusable: no tracking).

Percent values (SP%, PV%, FF%, BKCAL_IN%, an operator OUT) saturate at ±1e15 % of span, far
beyond any real signal, so that no storable input can overflow the arithmetic (GAIN and FF_GAIN
are bounded to 1e6 for the same reason): every state and every output stays finite, and the
block never raises at run time.

Options for the spec's [A]/[?] points
-------------------------------------

Each is a parameter whose default is the spec's choice:

* ``reset_discretisation`` = ``euler`` (a = dt/RESET, capped at 1 so that R never passes F in
  one scan) | ``backward`` (a = dt/(RESET + dt)) | ``exact`` (a = 1 - exp(-dt/RESET)).
  Spec 4.7 step 7 [A]. With RESET/16: 16·dt replaces dt.
* ``filter_discretisation`` = ``backward`` (dt/(T + dt)) | ``exact`` (1 - exp(-dt/T)), for
  PV_FTIME and SP_FTIME. Spec 4.7 step 3 [A].
* ``derivative_discretisation`` = ``backward`` (step 6 above) | ``exact`` (step invariant:
  D_k = e^(-dt/(α·RATE))·D_{k-1} + s·GAIN·c/α·(d_k - d_{k-1})). Spec 4.7 step 6 [A].
* ``ff_in_reset_feedback`` = false (FF removed from F, so FF is not integrated) | true.
  Spec 4.7 step 7 [A].
* ``reset_feedback`` = ``error`` | ``output`` (see above). Spec 4.2 vs 4.7 step 7 [A]: the
  literal step 7 integrates D and the setpoint weighting too, which contradicts the spec
  4.2 statement that the unconstrained block equals the ideal equations (and gives the no-P
  structures no integral action at all); ``error`` honours spec 4.2 and equals step 7 whenever
  RATE = 0 and β = 1.
* ``series_derivative`` = ``lead_lag`` ((1 + RATE·s)/(α·RATE·s + 1), the spec 4.2 equation,
  c = 1 - α) | ``filtered`` (1 + RATE·s/(α·RATE·s + 1), "derivative filter applied only to
  derivative action" in R40's words, c = 1). Spec 4.2 [A].
* ``no_reset_bias`` = ``bumpless`` (in the structures without I, R is the bias frozen at the
  value that made the last mode change bumpless) | ``fixed`` (in Auto/Cas R returns to ``bias``
  (OUT EU) with the time constant ``bal_time``, s; 0 = at once). Spec 4.3 [?], 4.1 BAL_TIME [?].
* ``reset_zero_disables`` = false (RESET = 0 is a ParameterError; RESET = inf disables I, the FF
  convention of R58) | true (RESET = 0 also disables I). Spec 4.1 [?].
* ``ff_conversion`` = ``gain_then_scale`` (FF% = (FF_GAIN·FF_VAL - FF@0%)·100/span, the spec's
  wording; note the offset when FF_SCALE does not start at 0) | ``scale_then_gain``
  (FF% = FF_GAIN·(FF_VAL - FF@0%)·100/span). Spec 4.7 step 8 [A].
* ``arw_units`` = ``percent`` (ARW limits in % of OUT span, spec 4.1) | ``out_eu`` (OUT_SCALE EU,
  as the DeltaV parameter table R42 lists them). Spec 4.1.
* ``precision`` = ``float32`` (parameters, inputs and every stored or output value (PV, SP, P,
  D, R, FF, OUT) are rounded to IEEE single precision, the DeltaV float; the arithmetic inside
  one formula is double) | ``float64``. Spec 4.1 [A].
* ``initial_out``: the output before the first scan (OUT EU; default OUT_SCALE 0 %).
* ``retune`` = ``vendor`` (a tuning change in Auto/Cas, ``set_params``, acts on the law as it
  is: OUT jumps by the P term's change; the spec says nothing of retuning [A]) | ``bumpless``
  (R moves by P_old - P_new at the latched SP and PV, so the next scan gives the output the
  old tuning would have; DiscretePIDs.jl ``set_K!``). Spec 4.2, 4.7 steps 5, 7, 9; see
  ``DeltaVPID.set_params``.
* Defaults [?] (spec 4.1): GAIN 1 and RESET inf (the Emerson FF PID defaults, R58); STRUCTURE
  ``pi_action_on_error_d_action_on_pv``; BETA = GAMMA = 1; SP limits and OUT limits = the
  scale ends; ARW limits = the OUT limits (the 16x rule then never acts); FF_GAIN 0.

Vendor quirks reproduced
------------------------

* RESET is seconds per repeat: larger RESET, less integral action (spec 4.9).
* Gains act on % of span: changing PV_SCALE or OUT_SCALE changes the effective gain.
* External reset gives inherent anti-windup: R runs toward the limited output, never past it,
  and OUT drops to R when the error vanishes (DV2: 62, 62, then 55.439).
* The ARW window makes the reset 16x faster on the way back into it.
* Direct/reverse is the ``direct_acting`` CONTROL_OPTS bit, not a sign on GAIN.
* The derivative filter is ALPHA·RATE (0.125 by default) and, in the "D on PV" structures, an
  SP step gives no derivative kick (DV4).
* Bad IN drops the actual mode to Man; the status encoding follows FF.

Example
-------

Python (spec 4.8 DV2: GAIN 1, RESET 10 s, OUT_HI_LIM 62, 1 s scans)::

    import loopworks
    pid = loopworks.create_block("deltav.pid", gain=1.0, reset=10.0, rate=0.0,
                                 out_hi_lim=62.0, precision="float64")
    pid.step(1.0, mode="MAN", man_out=50.0, sp=50.0, pv=50.0)   # steady state: OUT = R = 50
    for pv in (40.0,) * 6 + (50.0,) * 3:
        r = pid.step(1.0, mode="AUTO", pv=pv)
        print(round(r["out"].value, 6), r["out"].status)
    # 60.0 128, 61.0 128, 62.0 130, 62.0 130, 62.0 130, 62.0 130, 55.439 128, 55.439 128, ...

Replay (``loopworks replay deltav.pid dv.csv -p reset=10 -p out_hi_lim=62``), with
``dv.csv``::

    t,mode,man_out,sp,pv
    0,MAN,50,50,50
    1,AUTO,50,50,40
    2,AUTO,50,50,40
    3,AUTO,50,50,40

gives ``out`` 50, 60, 61, 62 (float32 values) and ``out.ST`` 131 (Man: constant), 128, 128,
130 (high limited).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from loopworks.blocks.block import Block
from loopworks.blocks.controller import Action, Controller, Handover, Roles
from loopworks.blocks.forms import ideal_to_series, series_to_ideal
from loopworks.blocks.kernel import FloatArray, IntArray, primitive
from loopworks.blocks.law import DiscreteLaw, Ideal, ParamValue, Realisation, number
from loopworks.blocks.layout import index
from loopworks.blocks.params import Param, Port, validate
from loopworks.blocks.primitives import clamp, finite, lag_step
from loopworks.blocks.registry import register
from loopworks.blocks.status import (
    BAD,
    BAD_NON_SPECIFIC,
    BAD_NOT_CONNECTED,
    BAD_OUT_OF_SERVICE,
    CONSTANT,
    GOOD_C_FSA,
    GOOD_C_IA,
    GOOD_C_IFS,
    GOOD_C_IR,
    GOOD_C_LO,
    GOOD_C_NI,
    GOOD_C_NON_SPECIFIC,
    GOOD_CASCADE,
    GOOD_NC,
    HIGH_LIMITED,
    LOW_LIMITED,
    NOT_LIMITED,
    UNCERTAIN,
    UNCERTAIN_NON_SPECIFIC,
)
from loopworks.errors import ParameterError

EULER, BACKWARD, EXACT = 0.0, 1.0, 2.0
FEEDBACK_ERROR, FEEDBACK_OUTPUT = 0.0, 1.0
GAIN_THEN_SCALE, SCALE_THEN_GAIN = 0.0, 1.0
BIAS_BUMPLESS, BIAS_FIXED = 0.0, 1.0
# Mode codes (inputs and outputs)
MODES = ("OOS", "IMAN", "LO", "MAN", "AUTO", "CAS")
OOS, IMAN, LO, MAN, AUTO, CAS = 0.0, 1.0, 2.0, 3.0, 4.0, 5.0
_PCT = "%"

INPUTS = (
    Port("pv", 0.0, "EU", "IN: the process input, PV_SCALE EU", status=True),
    Port("sp", 0.0, "EU", "operator SP write (a new value is written; NaN = none)"),
    Port("cas_in", math.nan, "EU", "CAS_IN: cascade setpoint (Cas)", status=True),
    Port("bkcal_in", math.nan, "EU", "BKCAL_IN: downstream BKCAL_OUT (OUT_SCALE EU); its "
         "status drives IMan", status=True),
    Port("ff_val", 0.0, "EU", "FF_VAL: feedforward input, FF_SCALE EU", status=True),
    Port("trk_in_d", 0.0, "", "TRK_IN_D: track switch (> 0.5 = track)", status=True),
    Port("trk_val", math.nan, "EU", "TRK_VAL: output in LO, TRK_SCALE EU", status=True),
    Port("man_out", math.nan, "EU", "operator OUT write in Man/OOS (a new value is "
         "written; NaN = none)"),
    Port("mode", AUTO, "", "MODE.TARGET write: OOS, MAN, AUTO or CAS (IMAN/LO rejected)",
         choices=MODES),
)
OUTPUTS = (
    Port("out", 0.0, "EU", "OUT, OUT_SCALE EU", status=True),
    Port("bkcal_out", 0.0, "EU", "BKCAL_OUT: working SP (or PV), PV_SCALE EU", status=True),
    Port("filtered_pv", 0.0, "EU", "PV: IN after PV_FTIME; status follows IN", status=True),
    Port("working_sp", 0.0, "EU", "working SP after limits, ramp and SP_FTIME"),
    Port("mode_actual", 0.0, "", "MODE.ACTUAL code: OOS 0, IMAN 1, LO 2, MAN 3, AUTO 4, "
         "CAS 5", choices=MODES),
    Port("mode_target", 0.0, "", "MODE.TARGET code (same codes)", choices=MODES),
    Port("p_term", 0.0, _PCT, "P contribution, % of OUT span"),
    Port("d_term", 0.0, _PCT, "D contribution, % of OUT span"),
    Port("r_term", 0.0, _PCT, "reset contribution R (external reset state), %"),
    Port("ff_term", 0.0, _PCT, "FF contribution, %"),
)
#: the CONTROL_OPTS and STATUS_OPTS flags, each a coefficient under its parameter's name
FLAGS = ("track_enable", "track_in_manual", "sp_pv_track_man", "sp_pv_track_lo_iman",
         "sp_track_retained_target", "use_pv_for_bkcal_out", "obey_sp_limits_cas",
         "no_out_limits_manual", "dynamic_reset_limit", "ifs_if_bad_in", "ifs_if_bad_cas_in",
         "use_uncertain_as_good", "target_to_man_if_bad_in", "target_to_next_if_bad_cas_in")
#: the coefficient array p (coefficients()): % of span values (and the OUT limits in EU, as
#: given), the law switches, the flags
COEFFS = ("gain", "reset", "rate", "alpha", "beta", "gamma", "has_p", "has_i", "series",
          "d_factor", "sign", "pv_eu0", "pv_k", "out_eu0", "out_k", "out_eu_per_pct", "ff_eu0",
          "ff_k", "trk_eu0", "trk_k", "sp_lo", "sp_hi", "sp_rate_up", "sp_rate_dn", "sp_ftime",
          "pv_ftime", "out_lo", "out_hi", "out_lo_eu", "out_hi_eu", "arw_lo", "arw_hi",
          "bkcal_hys", "ideadband",
          "ff_gain", "ff_order", "reset_law", "filter_law", "deriv_law", "feedback",
          "ff_in_feedback", "bias_mode", "bias", "bal_time", "single", *FLAGS)
#: the state array x
STATES = (
    "target", "mode_seen", "sp_param", "sp_seen", "man_seen", "sp_ramp", "sp_filtered",
    "pv", "pv_ok", "out_pct", "r", "p", "pe", "d", "d_signal", "ff", "ff_hold",
    "limit", "init", "first", "mode_seen_ok", "sp_seen_ok", "man_seen_ok")
P, X, U, Y = index(COEFFS, "P"), index(STATES, "X"), index(INPUTS, "U"), index(OUTPUTS, "Y")

SIGNAL_LIMIT = 1e15  # % signals saturate here: an overflow guard, not a vendor limit
GAIN_LIMIT = 1e6
FLOAT32_MAX = float(np.finfo(np.float32).max)

STRUCTURES: dict[str, tuple[bool, float, float, bool]] = {
    # name: (P acts, beta, gamma, I acts)  - spec 4.3
    "pid_action_on_error": (True, 1.0, 1.0, True),
    "pi_action_on_error_d_action_on_pv": (True, 1.0, 0.0, True),
    "i_action_on_error_pd_action_on_pv": (True, 0.0, 0.0, True),
    "pd_action_on_error": (True, 1.0, 1.0, False),
    "p_action_on_error_d_action_on_pv": (True, 1.0, 0.0, False),
    "id_action_on_error": (False, 0.0, 1.0, True),
    "i_action_on_error_d_action_on_pv": (False, 0.0, 0.0, True),
    "two_degrees_of_freedom": (True, math.nan, math.nan, True),
}


@primitive
def rnd(x: float, single: bool) -> float:
    """``x`` rounded to IEEE single precision (nearest, ties to even) when ``single``: a value
    stored in a 32-bit DeltaV float parameter (spec 4.1 [A])."""
    if single:
        return float(np.float32(x))
    return x


@primitive
def storable(v: float) -> bool:
    """True when ``v`` fits a DeltaV float parameter: finite and ``abs(v) <= 3.4028235e38``,
    the float32 range (spec 4.1 [A]). Any other input value is Bad input."""
    return finite(v) and abs(v) <= FLOAT32_MAX


@primitive
def written(x: FloatArray, seen: int, seen_ok: int, v: float) -> bool:
    """True when the input value ``v`` is an operator write: storable, and different from the
    input's value on the scan before (``x[seen]``) or the input had none then (``x[seen_ok]``
    = 0). Records ``v`` as the value seen."""
    write = storable(v) and (x[seen_ok] == 0.0 or v != x[seen])
    x[seen_ok] = 1.0 if storable(v) else 0.0
    if storable(v):
        x[seen] = v
    return write


@primitive
def to_pct(x: float, eu0: float, k: float) -> float:
    """Percent of span: (x - EU@0%)·k with k = 100/span (spec 4.2), saturated at ±1e15."""
    return clamp((x - eu0) * k, -SIGNAL_LIMIT, SIGNAL_LIMIT)


@primitive
def p_term(p: FloatArray, sp_pct: float, pv_pct: float, single: bool) -> float:
    """The proportional term in % of span, P = sign·GAIN·(BETA·SP% - PV%), 0 in the
    structures without P (spec 4.2, 4.3, 4.7 step 5), stored as the kernel stores it."""
    if p[P.has_p] == 0.0:
        return 0.0
    return rnd(p[P.sign] * p[P.gain] * (p[P.beta] * sp_pct - pv_pct), single)


@primitive
def first_order(y: float, target: float, dt: float, t: float, law: float) -> float:
    """PV/SP filter step (spec 4.7 step 3): y + dt/(T + dt)·(target - y) (backward Euler, [A])
    or y + (1 - e^(-dt/T))·(target - y) (exact); T = 0 passes the target through."""
    if t <= 0.0:
        return target
    if law == EXACT:
        return y + (1.0 - math.exp(-dt / t)) * (target - y)
    return y + dt / (t + dt) * (target - y)


def _reset(kind: str, reset: float, zero_disables: bool) -> float:
    """RESET (s/repeat) as the block runs it: inf disables I; 0 is a ParameterError unless
    ``reset_zero_disables`` (then inf)."""
    if reset == 0.0:
        if not zero_disables:
            raise ParameterError(
                f"{kind}: parameter 'reset' = 0 is out of range: allowed (0, inf] s/repeat "
                "(inf = no integral action; reset_zero_disables = true accepts 0)")
        return math.inf
    return reset


def _rel_differs(a: float, b: float) -> bool:
    """True when ``a`` and ``b`` differ by more than rounding (1e-12 relative)."""
    return abs(a - b) > 1e-12 * max(abs(a), abs(b))


@primitive
def reset_gain(dt: float, reset: float, law: float) -> float:
    """The a of R_k = R_{k-1} + a·(F - R_{k-1}) (spec 4.7 step 7): dt/RESET (Euler [A], capped
    at 1), dt/(RESET + dt) (backward) or 1 - e^(-dt/RESET) (exact)."""
    if law == EXACT:
        return 1.0 - math.exp(-dt / reset)
    if law == BACKWARD:
        return dt / (reset + dt)
    return min(dt / reset, 1.0)


@primitive
def ramp(current: float, target: float, up: float, down: float) -> float:
    """Move ``current`` toward ``target`` by at most ``up`` (rising) or ``down`` (falling) per
    scan; 0 or inf = no limit (FF SP_RATE_UP/DN: "0 = the SP is used immediately")."""
    if target > current and up > 0.0 and current + up < target:
        return current + up
    if target < current and down > 0.0 and current - down > target:
        return current - down
    return target


def deltav_pid_kernel(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                      y: FloatArray, ys: IntArray) -> None:
    """One scan of the DeltaV PID, in the order of spec 4.7 (see the module docstring)."""
    single = p[P.single] != 0.0
    first = x[X.first] != 0.0
    lo = p[P.out_lo]
    hi = p[P.out_hi]
    out_prev = x[X.out_pct]
    # -- input qualities (spec 4.5, 4.6) ------------------------------------------------------
    v_in = u[U.pv]
    q_in = us[U.pv] & 0xC0
    in_finite = storable(v_in)  # NaN, inf or beyond float32: Bad IN
    in_bad = (not in_finite or q_in == BAD
              or (q_in == UNCERTAIN and p[P.use_uncertain_as_good] == 0.0))
    in_uncertain = q_in == UNCERTAIN and not in_bad
    sample = in_finite and q_in != BAD  # a value the PV filter takes
    if in_finite:
        v_in = rnd(v_in, single)
    fresh = False
    if sample and x[X.pv_ok] == 0.0:  # the PV filter starts at the first usable IN
        x[X.pv] = v_in
        x[X.pv_ok] = 1.0
        fresh = True
    cas = u[U.cas_in]
    cas_ok = storable(cas) and (us[U.cas_in] & 0xC0) != BAD
    if cas_ok:
        cas = rnd(cas, single)
        if p[P.obey_sp_limits_cas] != 0.0:
            cas = clamp(cas, p[P.sp_lo], p[P.sp_hi])
    bk = u[U.bkcal_in]
    st_bk = us[U.bkcal_in]
    if math.isnan(bk) and (st_bk == BAD_NON_SPECIFIC or st_bk == BAD_NOT_CONNECTED):
        st_bk = GOOD_NC  # no value, no status: BKCAL_IN is not connected (its default)
    elif not storable(bk):
        st_bk = BAD_NON_SPECIFIC  # inf or beyond float32 (or NaN with a status): Bad
    q_bk = st_bk & 0xC0
    sub_bk = st_bk & 0xFC
    bk_ok = storable(bk) and q_bk != BAD
    bk_pct = 0.0
    if bk_ok:
        bk_pct = rnd(to_pct(rnd(bk, single), p[P.out_eu0], p[P.out_k]), single)
    downstream_not_cas = (q_bk == BAD or sub_bk == GOOD_C_IR or sub_bk == GOOD_C_NI
                          or sub_bk == GOOD_C_LO or sub_bk == GOOD_C_FSA)
    trk = u[U.trk_val]
    trk_ok = storable(trk) and (us[U.trk_val] & 0xC0) != BAD
    # -- step 8 (a pure function of the inputs, needed earlier by the re-initialisation) ------
    ff_val = u[U.ff_val]
    if storable(ff_val) and (us[U.ff_val] & 0xC0) != BAD:
        ff_val = rnd(ff_val, single)
        if p[P.ff_order] == SCALE_THEN_GAIN:
            ff = p[P.ff_gain] * to_pct(ff_val, p[P.ff_eu0], p[P.ff_k])
        else:
            ff = to_pct(p[P.ff_gain] * ff_val, p[P.ff_eu0], p[P.ff_k])
        ff = rnd(clamp(ff, -SIGNAL_LIMIT, SIGNAL_LIMIT), single)
        x[X.ff_hold] = ff
    else:  # NaN, inf, beyond float32 or Bad FF_VAL: the last usable contribution holds
        ff = x[X.ff_hold]
    # -- step 1: target and actual mode ---------------------------------------------------------
    m = u[U.mode]
    # an operator write of MODE.TARGET (always recorded: ``written`` comes first)
    if written(x, X.mode_seen, X.mode_seen_ok, m) and (m == OOS or m == MAN or m == AUTO
                                                        or m == CAS):
        x[X.target] = m
    if in_bad and p[P.target_to_man_if_bad_in] != 0.0 and x[X.target] != OOS:
        x[X.target] = MAN
    ifs_cas = p[P.ifs_if_bad_cas_in] != 0.0 and x[X.target] == CAS and not cas_ok
    if x[X.target] == CAS and not cas_ok and p[P.target_to_next_if_bad_cas_in] != 0.0:
        x[X.target] = AUTO
    target = x[X.target]
    trk_d = u[U.trk_in_d]
    tracking = (p[P.track_enable] != 0.0 and storable(trk_d) and trk_d > 0.5
                and (us[U.trk_in_d] & 0xC0) != BAD
                and (target != MAN or p[P.track_in_manual] != 0.0))
    if target == OOS:
        actual = OOS
    elif downstream_not_cas:
        actual = IMAN
    elif tracking:
        actual = LO
    elif target == MAN or in_bad:
        actual = MAN
    elif target == CAS and cas_ok:
        actual = CAS
    else:
        actual = AUTO
    computing = actual == AUTO or actual == CAS
    # -- step 2: setpoint -------------------------------------------------------------------------
    sp_in = u[U.sp]
    if written(x, X.sp_seen, X.sp_seen_ok, sp_in) and actual != CAS:  # an operator write
        x[X.sp_param] = rnd(clamp(sp_in, p[P.sp_lo], p[P.sp_hi]), single)
    tracked = False
    if actual == CAS:
        x[X.sp_param] = cas
        spw = cas
    else:
        if (p[P.sp_track_retained_target] != 0.0 and target == CAS and cas_ok
                and (actual == MAN or actual == LO or actual == IMAN)):
            x[X.sp_param] = cas
            tracked = True
        elif x[X.pv_ok] != 0.0 and (
                (p[P.sp_pv_track_man] != 0.0 and target == MAN and actual != OOS)
                or (p[P.sp_pv_track_lo_iman] != 0.0 and (actual == LO or actual == IMAN))):
            x[X.sp_param] = x[X.pv]  # SP = PV as it stands at step 2 (PV_{k-1})
            tracked = True
        if actual == AUTO and not tracked and not first:
            spw = ramp(x[X.sp_ramp], x[X.sp_param], p[P.sp_rate_up] * dt, p[P.sp_rate_dn] * dt)
        else:
            spw = x[X.sp_param]
    spw = rnd(spw, single)
    x[X.sp_ramp] = spw
    if tracked or first:
        spf = spw
    else:
        spf = rnd(first_order(x[X.sp_filtered], spw, dt, p[P.sp_ftime], p[P.filter_law]), single)
    x[X.sp_filtered] = spf
    # -- step 3: PV ------------------------------------------------------------------------------
    if sample and not fresh:
        x[X.pv] = rnd(first_order(x[X.pv], v_in, dt, p[P.pv_ftime], p[P.filter_law]), single)
    pv = x[X.pv]
    # -- steps 4-7 ---------------------------------------------------------------------------------
    valid = not in_bad  # implies a PV: a non-Bad IN has started the filter
    init = x[X.init] != 0.0
    s = p[P.sign]
    g = p[P.gain]
    pterm = 0.0
    dterm = 0.0
    pe = 0.0
    dsig = 0.0
    r = x[X.r]
    if valid:
        sp_pct = to_pct(spf, p[P.pv_eu0], p[P.pv_k])  # step 4
        pv_pct = to_pct(pv, p[P.pv_eu0], p[P.pv_k])
        pe = rnd(s * g * (sp_pct - pv_pct), single)
        pterm = p_term(p, sp_pct, pv_pct, single)  # step 5
        dsig = p[P.gamma] * sp_pct - pv_pct  # step 6
        d_prev = x[X.d]
        dsig_prev = x[X.d_signal]
        if init:
            d_prev = 0.0
            dsig_prev = dsig
        rate = p[P.rate]
        if rate > 0.0:
            tf = p[P.alpha] * rate
            kd = s * g * p[P.d_factor]
            if p[P.deriv_law] == EXACT:
                dterm = math.exp(-dt / tf) * d_prev + kd / p[P.alpha] * (dsig - dsig_prev)
            else:  # (α·RATE·D + kd·RATE·Δd)/(α·RATE + dt), written so nothing overflows
                dterm = (d_prev * (tf / (tf + dt))
                         + kd * (dsig - dsig_prev) / (p[P.alpha] + dt / rate))
            dterm = rnd(dterm, single)
        p_prev = x[X.p]
        pe_prev = x[X.pe]
        ff_prev = x[X.ff]
        r_prev = x[X.r]
        if init:  # (re)start: as if the scan before had been Man with these P, D, FF
            r_prev = rnd(out_prev - pterm - dterm - ff, single)
            p_prev = pterm
            pe_prev = pe
            d_prev = dterm
            ff_prev = ff
        r = r_prev
        if computing:  # step 7
            if p[P.has_i] == 0.0:
                if p[P.bias_mode] == BIAS_FIXED:
                    r = lag_step(r_prev, p[P.bias], dt, p[P.bal_time])
            elif not abs(spf - pv) < p[P.ideadband]:
                fb = out_prev
                if p[P.dynamic_reset_limit] != 0.0 and bk_ok:
                    fb = bk_pct
                if p[P.ff_in_feedback] == 0.0:
                    fb = fb - ff_prev
                if p[P.feedback] == FEEDBACK_ERROR:
                    fb = fb - (p_prev - pe_prev)
                    if p[P.series] == 0.0:
                        fb = fb - d_prev
                k = 1.0
                if (out_prev > p[P.arw_hi] and fb < r_prev) or (out_prev < p[P.arw_lo]
                                                             and fb > r_prev):
                    k = 16.0  # ARW: RESET/16 on the way back (spec 4.4)
                r = r_prev + reset_gain(dt * k, p[P.reset], p[P.reset_law]) * (fb - r_prev)
                if (q_bk & 0x80) != 0:  # Good BKCAL_IN limit bits (spec 4.4)
                    bits = st_bk & 3
                    if (bits == HIGH_LIMITED or bits == CONSTANT) and r > r_prev:
                        r = r_prev
                    if (bits == LOW_LIMITED or bits == CONSTANT) and r < r_prev:
                        r = r_prev
            r = rnd(r, single)
    # -- step 9: output ----------------------------------------------------------------------------
    man = u[U.man_out]
    man_write = written(x, X.man_seen, X.man_seen_ok, man)
    limited = True  # OUT held within OUT_LO_LIM..OUT_HI_LIM this scan (spec 4.4, 4.5)
    if computing:
        out_pct = clamp(rnd(pterm + dterm + r + ff, single), lo, hi)
    elif actual == MAN or actual == OOS:  # -- step 10: overrides
        out_pct = out_prev
        if man_write:
            out_pct = to_pct(rnd(man, single), p[P.out_eu0], p[P.out_k])
        limited = actual == MAN and not (p[P.no_out_limits_manual] != 0.0 and target == MAN)
        if limited:
            out_pct = clamp(out_pct, lo, hi)
    elif actual == LO:
        out_pct = out_prev
        limited = trk_ok
        if trk_ok:
            trk = rnd(trk, single)
            out_pct = clamp(to_pct(trk, p[P.trk_eu0], p[P.trk_k]), lo, hi)
    else:  # IMan: OUT follows the downstream block
        limited = False
        out_pct = out_prev
        if bk_ok:
            out_pct = bk_pct
    out_pct = rnd(out_pct, single)
    if valid:
        if not computing:  # back-initialisation: the next Auto/Cas scan is bumpless
            r = rnd(out_pct - pterm - dterm - ff, single)
        x[X.p] = pterm
        x[X.pe] = pe
        x[X.d] = dterm
        x[X.d_signal] = dsig
        x[X.r] = r
    x[X.ff] = ff
    x[X.out_pct] = out_pct
    x[X.init] = 0.0 if valid and actual != OOS else 1.0
    x[X.first] = 0.0
    # limit bits with BKCAL_HYS hysteresis (spec 4.4)
    if out_pct >= hi:
        x[X.limit] = 2.0
    elif out_pct <= lo:
        x[X.limit] = 1.0
    elif (x[X.limit] == 2.0 and hi - out_pct >= p[P.bkcal_hys]) or (
            x[X.limit] == 1.0 and out_pct - lo >= p[P.bkcal_hys]):
        x[X.limit] = 0.0
    bits = NOT_LIMITED
    if x[X.limit] == 2.0:
        bits = HIGH_LIMITED
    elif x[X.limit] == 1.0:
        bits = LOW_LIMITED
    # -- step 11: BKCAL_OUT and statuses -------------------------------------------------------
    base = GOOD_NC if q_bk == GOOD_NC else GOOD_CASCADE
    if actual == OOS:
        st_out = BAD_OUT_OF_SERVICE
        st_bkcal = BAD_OUT_OF_SERVICE
    else:
        if computing:
            st_out = (UNCERTAIN_NON_SPECIFIC if in_uncertain else base) | bits
        elif actual == IMAN and sub_bk == GOOD_C_IR:
            st_out = GOOD_C_IA | CONSTANT
        else:
            st_out = base | CONSTANT
        if (in_bad and p[P.ifs_if_bad_in] != 0.0) or ifs_cas:
            st_out = GOOD_C_IFS | (st_out & 3)
        if actual == CAS:
            st_bkcal = GOOD_C_NON_SPECIFIC | bits
        elif actual == LO:
            st_bkcal = GOOD_C_LO | bits
        elif target == CAS:
            st_bkcal = GOOD_C_IR | bits
        else:
            st_bkcal = GOOD_C_NI | bits
    out = rnd(p[P.out_eu0] + out_pct * p[P.out_eu_per_pct], single)
    if limited:  # the limits in EU as given: % and back may round one float32 step past them
        out = clamp(out, p[P.out_lo_eu], p[P.out_hi_eu])
    y[Y.out] = out
    ys[Y.out] = st_out
    y[Y.bkcal_out] = pv if actual == CAS and p[P.use_pv_for_bkcal_out] != 0.0 else spf
    ys[Y.bkcal_out] = st_bkcal
    y[Y.filtered_pv] = pv
    ys[Y.filtered_pv] = us[U.pv] if in_finite else BAD_NON_SPECIFIC
    y[Y.working_sp] = spf
    y[Y.mode_actual] = actual
    y[Y.mode_target] = target
    y[Y.p_term] = pterm
    y[Y.d_term] = dterm
    y[Y.r_term] = r
    y[Y.ff_term] = ff


def series_to_standard(gain: float, reset: float, rate: float) -> tuple[float, float, float]:
    """Series (GAIN', RESET', RATE') to the Standard equivalent, ignoring the derivative filter
    (spec 4.2 [D], textbook; the equations live in ``loopworks.blocks.forms``)."""
    return series_to_ideal(gain, reset, rate)


_OPT = "CONTROL_OPTS"
_STO = "STATUS_OPTS"


def _flag(name: str, meaning: str) -> Param:
    return Param(name, False, "", meaning, "bool")


def _eu(name: str, default: float | None, unit: str, meaning: str, text: str = "") -> Param:
    return Param(name, default, unit, meaning, lo=-SIGNAL_LIMIT, hi=SIGNAL_LIMIT,
                 lo_open=False, hi_open=False, default_text=text)


@register
class DeltaVPID(Controller, Block):
    """Emerson DeltaV standard PID function block (spec vendor-blocks 4)."""

    kind = "deltav.pid"
    summary = ("Emerson DeltaV PID: Standard/Series, STRUCTURE, external reset, ARW, modes, "
               "Fieldbus status")
    kernel = staticmethod(deltav_pid_kernel)
    # not sound by itself (the property test finds non-finite states from extreme inputs): the
    # full guard undoes such a scan and reruns it as Bad input
    SOUND_KERNEL = False

    PARAMS: ClassVar[tuple[Param, ...]] = (
        Param("form", "standard", "", "FORM: standard (ISA, non-interacting) or series "
              "(interacting) (spec 4.2)", "choice", choices=("standard", "series")),
        Param("structure", "pi_action_on_error_d_action_on_pv", "",
              "STRUCTURE: which terms act on the error and which on PV (spec 4.3); default [?]",
              "choice", choices=tuple(STRUCTURES)),
        Param("gain", 1.0, "%/%", "GAIN on normalised signals (spec 4.1, 4.2); default [?] "
              "(R58)", lo=0.0, hi=GAIN_LIMIT, hi_open=False),
        Param("reset", math.inf, "s/repeat", "RESET, seconds per repeat; inf = no integral "
              "action (spec 4.1; default [?], R58)", lo=0.0, lo_open=False, hi_open=False),
        Param("rate", 0.0, "s", "RATE, derivative time; 0 = no D (spec 4.1)", lo=0.0,
              lo_open=False),
        Param("alpha", 0.125, "", "ALPHA: derivative filter time constant = ALPHA·RATE "
              "(spec 4.1, R42)", lo=0.05, hi=1.0, lo_open=False, hi_open=False),
        Param("beta", 1.0, "", "BETA: setpoint weight of P, structure two_degrees_of_freedom "
              "only (spec 4.3)", lo=0.0, hi=1.0, lo_open=False, hi_open=False),
        Param("gamma", 1.0, "", "GAMMA: setpoint weight of D, structure two_degrees_of_freedom "
              "only (spec 4.3)", lo=0.0, hi=1.0, lo_open=False, hi_open=False),
        Param("ideadband", 0.0, "EU", "IDEADBAND: no reset action while abs(SP - PV) < "
              "IDEADBAND (spec 4.4)", lo=0.0, lo_open=False),
        _eu("pv_scale_eu_0", 0.0, "EU", "PV_SCALE: the IN/SP value that is 0 % of the PV span; "
            "the algorithm works on % of this span (spec 4.1, 4.2)"),
        _eu("pv_scale_eu_100", 100.0, "EU", "PV_SCALE: the IN/SP value that is 100 % of the PV "
            "span, > the 0 % value (spec 4.1)"),
        _eu("out_scale_eu_0", 0.0, "EU", "OUT_SCALE: the OUT value that is 0 % of the output "
            "span; OUT% is converted to EU on it (spec 4.1, 4.2)"),
        _eu("out_scale_eu_100", 100.0, "EU", "OUT_SCALE: the OUT value that is 100 % of the "
            "output span, > the 0 % value (spec 4.1)"),
        _eu("ff_scale_eu_0", 0.0, "EU", "FF_SCALE: the feedforward value that is 0 % of its "
            "span, for the conversion of FF to % (spec 4.1, 4.7 step 8)"),
        _eu("ff_scale_eu_100", 100.0, "EU", "FF_SCALE: the feedforward value that is 100 % of its "
            "span (spec 4.1)"),
        _eu("trk_scale_eu_0", 0.0, "EU", "TRK_SCALE: the TRK_VAL value that is 0 % of its span; "
            "TRK_VAL is converted through % to OUT_SCALE in LO (spec 4.1, 4.5)"),
        _eu("trk_scale_eu_100", 100.0, "EU", "TRK_SCALE: the TRK_VAL value that is 100 % of its "
            "span (spec 4.1)"),
        _eu("sp_hi_lim", None, "EU", "SP_HI_LIM: highest operator/limited SP (spec 4.1, 4.7 "
            "step 2)", "pv_scale_eu_100"),
        _eu("sp_lo_lim", None, "EU", "SP_LO_LIM: lowest operator/limited SP (spec 4.1)",
            "pv_scale_eu_0"),
        Param("sp_rate_up", 0.0, "EU/s", "SP_RATE_UP: SP ramp rate up in Auto; 0 or inf = "
              "none (spec 4.1, 4.7 step 2)", lo=0.0, lo_open=False, hi_open=False),
        Param("sp_rate_dn", 0.0, "EU/s", "SP_RATE_DN: SP ramp rate down in Auto; 0 or inf = "
              "none (spec 4.1)", lo=0.0, lo_open=False, hi_open=False),
        Param("sp_ftime", 0.0, "s", "SP_FTIME: setpoint filter time constant (spec 4.1, "
              "4.7 step 2)", lo=0.0, lo_open=False),
        Param("pv_ftime", 0.0, "s", "PV_FTIME: PV filter time constant (spec 4.1, 4.7 "
              "step 3)", lo=0.0, lo_open=False),
        _eu("out_hi_lim", None, "EU", "OUT_HI_LIM (OUT_SCALE EU), -10..110 % of span (spec "
            "4.1, 4.4)", "out_scale_eu_100"),
        _eu("out_lo_lim", None, "EU", "OUT_LO_LIM (OUT_SCALE EU), -10..110 % of span, < "
            "OUT_HI_LIM (spec 4.1)", "out_scale_eu_0"),
        _eu("arw_hi_lim", None, "% or EU", "ARW_HI_LIM: while OUT is above it and the reset "
            "moves down, the reset runs at RESET/16 (spec 4.4); unit per arw_units",
            "the OUT high limit"),
        _eu("arw_lo_lim", None, "% or EU", "ARW_LO_LIM: while OUT is below it and the reset "
            "moves up, the reset runs at RESET/16 (spec 4.4); unit per arw_units",
            "the OUT low limit"),
        Param("bkcal_hys", 0.5, _PCT, "BKCAL_HYS: limit status released when OUT is this far "
              "from the limit (spec 4.1, 4.4)", lo=0.0, hi=50.0, lo_open=False, hi_open=False),
        Param("ff_gain", 0.0, "", "FF_GAIN: feedforward gain, FF = FF_GAIN·FF_VAL converted to "
              "% of OUT span and added to OUT; 0 = no feedforward (spec 4.1, 4.7 step 8)",
              lo=-GAIN_LIMIT,
              hi=GAIN_LIMIT, lo_open=False, hi_open=False),
        _flag("direct_acting", f"{_OPT} Direct acting: e = PV - SP (s = -1), OUT rises with PV; "
              "off: reverse acting, e = SP - PV (spec 4.2, 4.9)"),
        _flag("track_enable", f"{_OPT} Track enable: TRK_IN_D puts the block in LO "
              "(spec 4.5)"),
        _flag("track_in_manual", f"{_OPT} Track in Manual: tracking also with target Man "
              "(spec 4.5)"),
        _flag("sp_pv_track_man", f"{_OPT} SP-PV track in Man: SP = PV while the target is "
              "Man (spec 4.5, 4.7 step 2)"),
        _flag("sp_pv_track_lo_iman", f"{_OPT} SP-PV track in LO or IMan: SP = PV while the "
              "actual mode is LO or IMan (spec 4.7 step 2)"),
        _flag("sp_track_retained_target", f"{_OPT} SP track retained target: SP = CAS_IN in "
              "Man/LO/IMan while the target is Cas (precedes SP-PV track) (spec 4.1)"),
        _flag("use_pv_for_bkcal_out", f"{_OPT} Use PV for BKCAL_OUT: in Cas BKCAL_OUT is the PV "
              "instead of the working SP (spec 4.7 step 11)"),
        _flag("obey_sp_limits_cas", f"{_OPT} Obey SP limits in Cas: CAS_IN limited to "
              "SP_LO_LIM..SP_HI_LIM (spec 4.7 step 2)"),
        _flag("no_out_limits_manual", f"{_OPT} No OUT limits in Manual: the operator's OUT is "
              "not limited to OUT_LO_LIM..OUT_HI_LIM in Man (spec 4.5)"),
        _flag("dynamic_reset_limit", f"{_OPT} dynamic reset limit: reset feedback from "
              "BKCAL_IN (spec 4.4)"),
        _flag("ifs_if_bad_in", f"{_STO} IFS if Bad IN: OUT.ST is Good cascade IFS (initiate "
              "fault state downstream) while IN is Bad (spec 4.1)"),
        _flag("ifs_if_bad_cas_in", f"{_STO} IFS if Bad CAS_IN: OUT.ST is Good cascade IFS while "
              "the target is Cas and CAS_IN is unusable (spec 4.1)"),
        _flag("use_uncertain_as_good", f"{_STO} Use Uncertain as Good: an Uncertain IN is "
              "not Bad (spec 4.1, 4.6)"),
        _flag("target_to_man_if_bad_in", f"{_STO} Target to Manual if Bad IN (spec 4.5)"),
        _flag("target_to_next_if_bad_cas_in", f"{_STO} Target to next permitted mode if Bad "
              "CAS_IN: the target changes from Cas to Auto while CAS_IN is unusable (spec 4.1)"),
        Param("reset_discretisation", "euler", "", "R update a = dt/RESET (euler [A]), "
              "dt/(RESET + dt) or 1 - exp(-dt/RESET) (spec 4.7 step 7)", "choice",
              choices=("euler", "backward", "exact")),
        Param("filter_discretisation", "backward", "", "PV_FTIME/SP_FTIME filter: backward "
              "Euler [A] or exact (spec 4.7 step 3)", "choice", choices=("backward", "exact")),
        Param("derivative_discretisation", "backward", "", "D filter: backward Euler [A] or "
              "exact step invariant (spec 4.7 step 6)", "choice",
              choices=("backward", "exact")),
        Param("reset_feedback", "error", "", "reset feedback F = limited OUT less FF and what "
              "the spec 4.2 equations do not integrate (error), or less FF only (output, spec "
              "4.7 step 7 literally) [A]", "choice", choices=("error", "output")),
        Param("ff_in_reset_feedback", False, "", "keep FF in the reset feedback (FF is "
              "integrated) [A] (spec 4.7 step 7)", "bool"),
        Param("series_derivative", "lead_lag", "", "Series D: (1 + RATE·s)/(α·RATE·s + 1) "
              "(spec 4.2 [A]) or filtered (1 + RATE·s/(α·RATE·s + 1), R40)", "choice",
              choices=("lead_lag", "filtered")),
        Param("no_reset_bias", "bumpless", "", "bias of the structures without I: frozen at "
              "the bumpless value, or fixed (bias, bal_time) [?] (spec 4.3)", "choice",
              choices=("bumpless", "fixed")),
        _eu("bias", None, "EU", "bias (OUT EU) for no_reset_bias = fixed (spec 4.3 [?])",
            "out_scale_eu_0"),
        Param("bal_time", 0.0, "s", "BAL_TIME: time constant of the return to bias, "
              "no_reset_bias = fixed (spec 4.1 [?])", lo=0.0, lo_open=False),
        Param("reset_zero_disables", False, "", "RESET = 0 also disables I (else an error) "
              "[?] (spec 4.1)", "bool"),
        Param("ff_conversion", "gain_then_scale", "", "FF_GAIN·FF_VAL then FF_SCALE to %, or "
              "the reverse [A] (spec 4.7 step 8)", "choice",
              choices=("gain_then_scale", "scale_then_gain")),
        Param("arw_units", "percent", "", "ARW limits in % of OUT span (spec 4.1) or in "
              "OUT_SCALE EU (R42)", "choice", choices=("percent", "out_eu")),
        Param("precision", "float32", "", "float32: values stored as 32-bit floats [A], or "
              "float64 (spec 4.1)", "choice", choices=("float32", "float64")),
        _eu("initial_out", None, "EU", "OUT before the first scan (OUT EU, within the OUT "
            "limits); R is back-initialised from it", "out_scale_eu_0 (clamped to the limits)"),
        Param("retune", "vendor", "", "a tuning change (set_params) after an Auto/Cas scan: "
              "vendor applies the new GAIN, BETA, STRUCTURE, action or PV_SCALE to the law as "
              "it is (P jumps; the spec says nothing of retuning, [A]); bumpless moves R by "
              "P_old - P_new so OUT does not jump (spec 4.2, 4.7 steps 5, 7, 9)", "choice",
              choices=("vendor", "bumpless")),
    )
    INPUTS: ClassVar[tuple[Port, ...]] = INPUTS
    OUTPUTS: ClassVar[tuple[Port, ...]] = OUTPUTS
    COEFFS: ClassVar[tuple[str, ...]] = COEFFS
    STATES: ClassVar[tuple[str, ...]] = STATES
    # the controller interface (loopworks.blocks.controller); modes spec 4.5
    ROLES: ClassVar[Roles] = Roles(sp="sp", pv="pv", out="out", ff="ff_val", mode="mode",
                                   man_out="man_out", track="trk_in_d", track_value="trk_val",
                                   working_sp="working_sp")
    AUTOMATIC: ClassVar[dict[str, Any]] = {"mode": "AUTO"}
    MANUAL: ClassVar[dict[str, Any]] = {"mode": "MAN"}
    ACTION: ClassVar[Action] = Action("direct_acting", "=", True)  # spec 4.2, 4.9
    #: a relay test holds the block in LO through TRK_IN_D/TRK_VAL (spec 4.5), which needs the
    #: Track enable option; the reset is back-calculated, so the return to Auto is bumpless
    HANDOVER: ClassVar[Handover] = Handover((("trk_in_d", "active"), ("trk_val", "out")),
                                            {"track_enable": True})

    @classmethod
    def pv_range(cls, params: Mapping[str, Any]) -> tuple[float, float] | None:
        """PV_SCALE, 0..100 % of the PV span in EU (spec 4.1)."""
        a = float(params.get("pv_scale_eu_0", 0.0))
        b = float(params.get("pv_scale_eu_100", 100.0))
        return (min(a, b), max(a, b))

    @classmethod
    def output_range(cls, params: Mapping[str, Any]) -> tuple[float, float]:
        """OUT_LO_LIM..OUT_HI_LIM when both are given, else the OUT_SCALE span (OUT EU)."""
        if params["out_lo_lim"] is not None and params["out_hi_lim"] is not None:
            return float(params["out_lo_lim"]), float(params["out_hi_lim"])
        return float(params["out_scale_eu_0"]), float(params["out_scale_eu_100"])

    #: the scale each EU port is in (vendor-blocks 4.1); the others are on PV_SCALE
    PORT_SCALES: ClassVar[dict[str, str]] = {
        "out": "out_scale", "bkcal_in": "out_scale", "man_out": "out_scale",
        "ff_val": "ff_scale", "trk_val": "trk_scale"}

    def port_unit(self, port: str, direction: str) -> str:
        """An EU port is in % when its scale (``PORT_SCALES``) is 0..100, else in "EU"."""
        unit = super().port_unit(port, direction)
        if unit != "eu":
            return unit
        scale = self.PORT_SCALES.get(port, "pv_scale")
        lo, hi = self.params[f"{scale}_eu_0"], self.params[f"{scale}_eu_100"]
        return "%" if (float(lo), float(hi)) == (0.0, 100.0) else "EU"

    @classmethod
    def out_span(cls, params: Mapping[str, Any]) -> float:
        """OUT_SCALE's span |EU at 100 % − EU at 0 %| (OUT is in OUT_SCALE's EU)."""
        return abs(float(params["out_scale_eu_100"]) - float(params["out_scale_eu_0"]))

    # -- the discrete law (loopworks.blocks.law), both ways ---------------------------------
    LAW_PARAMS: ClassVar[tuple[str, ...]] = (
        "form", "structure", "gain", "reset", "rate", "alpha", "beta", "gamma",
        "direct_acting", "series_derivative", "reset_discretisation",
        "derivative_discretisation", "reset_feedback", "ideadband", "pv_scale_eu_0",
        "pv_scale_eu_100", "out_scale_eu_0", "out_scale_eu_100", "reset_zero_disables")

    @classmethod
    def spans(cls, context: Mapping[str, Any]) -> tuple[float, float]:
        """The PV_SCALE and OUT_SCALE spans (EU of 100 %; default 100, 100), spec 4.1."""
        spans = []
        for scale in ("pv_scale", "out_scale"):
            e0 = number(f"{scale}_eu_0", context.get(f"{scale}_eu_0", 0.0), -math.inf,
                        kind=cls.kind)
            e100 = number(f"{scale}_eu_100", context.get(f"{scale}_eu_100", 100.0), -math.inf,
                          kind=cls.kind)
            if not e100 > e0:
                raise ParameterError(f"{cls.kind}: parameter '{scale}_eu_100' = {e100:g} must "
                                     f"be greater than {scale}_eu_0 = {e0:g}")
            spans.append(e100 - e0)
        return spans[0], spans[1]

    @classmethod
    def law(cls, params: Mapping[str, Any], dt: float | None,
            context: Mapping[str, Any]) -> DiscreteLaw:
        """Spec 4.1, 4.2, 4.7: GAIN %/% on PV_SCALE/OUT_SCALE, RESET s/repeat (inf or 0 = no
        I), RATE s, filter ALPHA·RATE. Standard: D as the pid's with Tf = α·RATE; the reset
        R_k = R_{k-1} + (Δ/RESET)·Kc·e_{k-1} integrates the *previous* error (forward Euler:
        the Euler reset law with reset_feedback error). Series (lead_lag): (P + D)·(1 + I)
        with D of gain K'(1 - α)RATE', i.e. K'(1 + 1/(RESET's))(1 + RATE's)/(α·RATE's + 1);
        its Ideal is ``series_to_ideal`` ignoring the filter. STRUCTURE gives b = BETA,
        c = GAMMA (spec 4.3)."""
        kind = cls.kind
        prm: dict[str, Any] = validate(kind, cls.PARAMS, dict(params))
        structure = prm["structure"]
        has_p, beta, gamma, has_i = STRUCTURES[structure]
        if not has_p:
            raise ParameterError(f"deltav.pid: parameter 'structure' = '{structure}' has no "
                                 "ideal form (no P action): allowed a structure with P")
        if structure == "two_degrees_of_freedom":
            beta, gamma = float(prm["beta"]), float(prm["gamma"])
        gain, rate = float(prm["gain"]), float(prm["rate"])
        reset = _reset(kind, float(prm["reset"]), bool(prm["reset_zero_disables"]))
        if not has_i:
            reset = math.inf
        alpha = float(prm["alpha"])
        direct = bool(prm["direct_acting"])
        flags: list[str] = []
        notes: list[str] = []
        law_code = {"euler": EULER, "backward": BACKWARD, "exact": EXACT}[
            prm["reset_discretisation"]]
        if reset < math.inf and dt is not None:
            # the reset's gain per scan a (reset_gain: Euler capped at 1, backward, exact) is
            # the Euler law's Δ/RESET of RESET_eff = Δ/a: the law is that one exactly
            effective = dt / reset_gain(dt, reset, law_code)
            if _rel_differs(effective, reset):
                notes.append(f"RESET = {reset:g} s with reset_discretisation = "
                             f"{prm['reset_discretisation']} at Δ = {dt:g} s moves the reset "
                             f"by a = {dt / effective:.6g} of the way per scan, as the Euler "
                             f"reset of RESET = {effective:.6g} s does (converted so)"
                             + (": the Euler gain Δ/RESET is capped at 1." if law_code == EULER
                                else "."))
                reset = effective
        elif prm["reset_discretisation"] != "euler" and reset < math.inf:
            flags.append(f"DeltaV reset_discretisation = {prm['reset_discretisation']} "
                         "changes the integral gain per scan (converted as RESET; give the "
                         "sample time for the exact equivalent).")
        if prm["derivative_discretisation"] != "backward" and rate > 0.0:
            flags.append("DeltaV derivative_discretisation = exact (step invariant) is not the "
                         "backward-Euler filter (converted as α·RATE).")
        if (prm["reset_feedback"] == "output" and (rate > 0.0 or beta != 1.0)
                and reset < math.inf):
            flags.append("DeltaV reset_feedback = output integrates D and the setpoint "
                         "weighting too (converted as the spec 4.2 equations).")
        if float(prm["ideadband"]) > 0.0 and reset < math.inf:
            flags.append("DeltaV IDEADBAND freezes the reset near the setpoint (not "
                         "converted).")
        cls.spans(prm)  # checks the scales
        filt = alpha * rate if rate > 0.0 else 0.0
        if prm["form"] == "series":
            k, ti, td = series_to_ideal(gain, reset, rate)
            d_factor = 1.0 - alpha if prm["series_derivative"] == "lead_lag" else 1.0
            return DiscreteLaw(Ideal(k, ti, td, filt, direct), b=beta, c=gamma, dt=dt,
                               integral="forward", series=(gain, reset, rate, d_factor, filt),
                               flags=tuple(flags), notes=tuple(notes))
        return DiscreteLaw(Ideal(gain, reset, rate, filt, direct), b=beta, c=gamma, dt=dt,
                           integral="forward", flags=tuple(flags), notes=tuple(notes))

    @classmethod
    def from_law(cls, law: DiscreteLaw, dt: float | None,
                 context: Mapping[str, Any]) -> Realisation:
        """GAIN, RESET, RATE in the context's ``form`` (standard by default, or series),
        ALPHA = context ``alpha``, else Tf/Td (within 0.05..1), else 0.125; the STRUCTURE
        with the law's setpoint weights (two_degrees_of_freedom with BETA, GAMMA when no
        other has them); the context's ``series_derivative`` and scales carried over."""
        ideal, b, c = law.ideal, law.b, law.c
        form = str(context.get("form", "standard")).lower()
        if "alpha" in context:
            alpha = number("alpha", context["alpha"], kind=cls.kind)
        elif ideal.td > 0.0 and ideal.tf > 0.0:
            alpha = min(max(ideal.tf / ideal.td, 0.05), 1.0)
        else:
            alpha = 0.125
        out: dict[str, ParamValue] = {"form": form}
        if form == "series":
            gain, reset, rate = ideal_to_series(ideal.kc, ideal.ti, ideal.td)
        elif form == "standard":
            gain, reset, rate = ideal.kc, ideal.ti, ideal.td
        else:
            raise ParameterError(f"deltav.pid: parameter 'form' = {form!r} is not allowed: "
                                 "expected one of standard, series")
        weights = (b, c if ideal.td > 0.0 else 0.0)
        structure = next((name for name, (has_p, beta, gamma, has_i) in STRUCTURES.items()
                          if has_p and has_i and (beta, gamma) == weights),
                         "two_degrees_of_freedom")
        if ideal.td == 0.0 and b == 1.0:
            structure = "pi_action_on_error_d_action_on_pv"
        out.update(structure=structure, gain=gain, reset=reset, rate=rate, alpha=alpha,
                   direct_acting=ideal.direct)
        if structure == "two_degrees_of_freedom":
            out.update(beta=b, gamma=c)
        for name in ("series_derivative", "pv_scale_eu_0", "pv_scale_eu_100", "out_scale_eu_0",
                     "out_scale_eu_100"):
            if name in context:
                out[name] = context[name]
        return Realisation(out, dt)

    def set_params(self, **changes: Any) -> None:
        """Change parameters between scans (see :meth:`Block.set_params`).

        The DeltaV text says nothing about changing the tuning in Auto (spec 4.1-4.9, 8 item
        4), so ``retune = "vendor"`` (the default, [A]) applies the new coefficients to the law
        as it is: OUT% = P + D + R + FF (spec 4.2, 4.7 step 9), where R_k is built from the
        previous scan's terms (step 7), so the next scan's OUT% moves by the P term's change
        P_new - P_old at once (plus what the scan brings anyway).

        ``retune = "bumpless"``: if the last scan computed the output (actual mode Auto or
        Cas, no re-initialisation pending), a change of the coefficients of P (GAIN, BETA,
        STRUCTURE, direct acting, PV_SCALE) moves the reset the other way, in % of span, at
        the latched working SP and PV (the filtered values the last scan used)::

            P_new = s·GAIN·(β·SP% - PV%)  with the new coefficients (0 without P), float32
                                          rounded as the kernel stores it
            R_{k-1} += P_{k-1} - P_new,   P_{k-1} := P_new,   d_{k-1} := γ·SP% - PV%

        Pe_{k-1} is kept: R_k integrates the last scan's error with the gain that scan had,
        as DiscretePIDs.jl ``set_K!`` keeps the integral's last increment (Åström & Hägglund
        2006, sec. 3.5). With ``reset_feedback = "error"`` F_{k-1} - R_{k-1} of step 7 is then
        unchanged, so at an unchanged SP and PV the next scan gives the output the old tuning
        would have, and the scans after it follow the new tuning. The stored R and P are
        rounded as the kernel stores them, so "the same" is within 2 float32 steps (float64:
        a few double steps) of the largest of abs(P), abs(R), abs(OUT%). With
        ``reset_feedback = "output"`` F = OUT% - FF carries P itself, so the next scan's
        reset step is already the new tuning's (it integrates P_new): OUT differs from the
        old tuning's by a·(P_new - P_old), a = dt/RESET (16·dt/RESET under the ARW rule, as
        long as the rule does not switch). Re-basing d_{k-1} to the new γ and PV_SCALE spares
        D a kick; D and R act on increments, so RATE, ALPHA and RESET changes need no
        correction. In the structures without I the frozen bias moves the same way (with
        ``no_reset_bias = "fixed"`` it then returns to the bias over BAL_TIME, as it does).

        After a Man, LO, IMan or OOS scan nothing is corrected (with either choice): each such
        scan back-initialises R from the P it computes (step 10), so the return to Auto is
        bumpless once one of them has run with the new tuning (a change made between the last
        Man scan and the first Auto scan moves OUT by P_new - P_old, as the law gives)."""
        old = self.p.copy()
        super().set_params(**changes)
        p, x = self.p, self.x
        if (self.params["retune"] != "bumpless" or x[X.init] != 0.0 or x[X.first] != 0.0
                or self.y[Y.mode_actual] not in (AUTO, CAS)):
            return
        terms = (P.gain, P.sign, P.has_p, P.beta, P.gamma, P.pv_eu0, P.pv_k)  # of P and d
        if all(old[i] == p[i] for i in terms):
            return
        sp_pct = to_pct(x[X.sp_filtered], p[P.pv_eu0], p[P.pv_k])
        pv_pct = to_pct(x[X.pv], p[P.pv_eu0], p[P.pv_k])
        p_new = p_term(p, sp_pct, pv_pct, p[P.single] != 0.0)
        x[X.r] = rnd(x[X.r] + (x[X.p] - p_new), p[P.single] != 0.0)
        x[X.p] = p_new
        x[X.d_signal] = p[P.gamma] * sp_pct - pv_pct

    def coefficients(self) -> dict[str, Any]:
        prm: dict[str, Any] = self.params
        kind = self.kind
        single = prm["precision"] == "float32"

        def num(name: str, value: Any = None) -> float:
            v = float(prm[name] if value is None else value)
            if not single:
                return v
            if math.isfinite(v) and abs(v) > FLOAT32_MAX:
                raise ParameterError(
                    f"{kind}: parameter '{name}' = {v:g} is out of range for a 32-bit float "
                    f"(precision = float32): allowed magnitude up to {FLOAT32_MAX:g}")
            return float(np.float32(v))

        def scale(name: str) -> tuple[float, float]:
            e0, e100 = num(f"{name}_eu_0"), num(f"{name}_eu_100")
            if not e100 > e0:
                raise ParameterError(
                    f"{kind}: parameter '{name}_eu_100' = {e100:g} must be greater than "
                    f"{name}_eu_0 = {e0:g}")
            return e0, e100 - e0

        pv0, pv_span = scale("pv_scale")
        out0, out_span = scale("out_scale")
        ff0, ff_span = scale("ff_scale")
        trk0, trk_span = scale("trk_scale")
        structure = prm["structure"]
        has_p, beta, gamma, has_i = STRUCTURES[structure]
        if structure == "two_degrees_of_freedom":
            beta, gamma = num("beta"), num("gamma")
        else:
            for name in ("beta", "gamma"):
                if name in self.given:
                    raise ParameterError(
                        f"{kind}: parameter '{name}' is used only with structure "
                        f"'two_degrees_of_freedom', not '{structure}'")
        reset = _reset(kind, num("reset"), bool(prm["reset_zero_disables"]))
        if math.isinf(reset):
            has_i = False
        # output limits, in % of the OUT span
        hi_eu = num("out_hi_lim", out0 + out_span if prm["out_hi_lim"] is None else None)
        lo_eu = num("out_lo_lim", out0 if prm["out_lo_lim"] is None else None)
        hi, lo = (hi_eu - out0) * 100.0 / out_span, (lo_eu - out0) * 100.0 / out_span
        # -10..110 % (spec 4.1), less the rounding of the EU values (21.6 of 4..20 is
        # 110.00000000000001 %; -1.6 of 0..16 as a float32 -10.00000015 %)
        tol = 1e-5 if single else 1e-9
        for name, pct in (("out_hi_lim", hi), ("out_lo_lim", lo)):
            if not -10.0 - tol <= pct <= 110.0 + tol:
                raise ParameterError(
                    f"{kind}: parameter '{name}' = {hi_eu if name == 'out_hi_lim' else lo_eu:g}"
                    f" is out of range: allowed -10..110 % of OUT_SCALE "
                    f"[{out0 - 0.1 * out_span:g}, {out0 + 1.1 * out_span:g}] EU")
        hi, lo = min(max(hi, -10.0), 110.0), min(max(lo, -10.0), 110.0)
        if single:  # the limits as the float32 values OUT is compared with (spec 4.1 [A])
            hi, lo = float(np.float32(hi)), float(np.float32(lo))
        if not hi > lo:
            raise ParameterError(f"{kind}: parameter 'out_hi_lim' = {hi_eu:g} must be greater "
                                 f"than out_lo_lim = {lo_eu:g}")
        arw: list[float] = []
        for name, default in (("arw_hi_lim", hi), ("arw_lo_lim", lo)):
            if prm[name] is None:
                arw.append(default)
                continue
            v = num(name)
            pct = v if prm["arw_units"] == "percent" else (v - out0) * 100.0 / out_span
            if single:
                pct = float(np.float32(pct))
            if lo - tol <= pct <= hi + tol:  # an OUT limit in EU, rounded
                pct = min(max(pct, lo), hi)
            if not lo <= pct <= hi:
                raise ParameterError(
                    f"{kind}: parameter '{name}' = {v:g} is out of range: allowed between the "
                    f"OUT limits ({lo:g}..{hi:g} % of OUT span; arw_units = {prm['arw_units']})")
            arw.append(pct)
        if arw[1] > arw[0]:
            raise ParameterError(
                f"{kind}: parameter 'arw_lo_lim' = {prm['arw_lo_lim']} must not exceed "
                f"arw_hi_lim = {prm['arw_hi_lim']} (arw_units = {prm['arw_units']})")
        sp_hi = num("sp_hi_lim", pv0 + pv_span if prm["sp_hi_lim"] is None else None)
        sp_lo = num("sp_lo_lim", pv0 if prm["sp_lo_lim"] is None else None)
        if sp_lo > sp_hi:
            raise ParameterError(f"{kind}: parameter 'sp_hi_lim' = {sp_hi:g} must not be below "
                                 f"sp_lo_lim = {sp_lo:g}")
        init = out0 if prm["initial_out"] is None else num("initial_out")
        init_pct = (init - out0) * 100.0 / out_span
        if prm["initial_out"] is None:
            init_pct = min(max(init_pct, lo), hi)
        elif not lo <= init_pct <= hi:
            raise ParameterError(f"{kind}: parameter 'initial_out' = {init:g} is out of range: "
                                 f"allowed [{lo_eu:g}, {hi_eu:g}] EU (the OUT limits)")
        self._initial_pct = float(np.float32(init_pct)) if single else init_pct
        self._initial_sp = min(max(0.0, sp_lo), sp_hi)
        alpha = num("alpha")
        series = prm["form"] == "series"
        d_factor = 1.0
        if series and prm["series_derivative"] == "lead_lag":
            d_factor = 1.0 - alpha
        bias = out0 if prm["bias"] is None else num("bias")
        laws = {"euler": EULER, "backward": BACKWARD, "exact": EXACT}
        return {
            "gain": num("gain"), "reset": reset, "rate": num("rate"), "alpha": alpha,
            "beta": beta, "gamma": gamma, "has_p": float(has_p), "has_i": float(has_i),
            "series": float(series), "d_factor": d_factor,
            "sign": -1.0 if prm["direct_acting"] else 1.0,
            "pv_eu0": pv0, "pv_k": 100.0 / pv_span,
            "out_eu0": out0, "out_k": 100.0 / out_span, "out_eu_per_pct": out_span / 100.0,
            "ff_eu0": ff0, "ff_k": 100.0 / ff_span, "trk_eu0": trk0, "trk_k": 100.0 / trk_span,
            "sp_lo": sp_lo, "sp_hi": sp_hi,
            "sp_rate_up": num("sp_rate_up"), "sp_rate_dn": num("sp_rate_dn"),
            "sp_ftime": num("sp_ftime"), "pv_ftime": num("pv_ftime"),
            "out_lo": lo, "out_hi": hi, "out_lo_eu": lo_eu, "out_hi_eu": hi_eu,
            "arw_lo": arw[1], "arw_hi": arw[0],
            "bkcal_hys": num("bkcal_hys"), "ideadband": num("ideadband"),
            "ff_gain": num("ff_gain"),
            "ff_order": SCALE_THEN_GAIN if prm["ff_conversion"] == "scale_then_gain"
            else GAIN_THEN_SCALE,
            "reset_law": laws[prm["reset_discretisation"]],
            "filter_law": laws[prm["filter_discretisation"]],
            "deriv_law": laws[prm["derivative_discretisation"]],
            "feedback": FEEDBACK_OUTPUT if prm["reset_feedback"] == "output"
            else FEEDBACK_ERROR,
            "ff_in_feedback": float(bool(prm["ff_in_reset_feedback"])),
            "bias_mode": BIAS_FIXED if prm["no_reset_bias"] == "fixed" else BIAS_BUMPLESS,
            "bias": (bias - out0) * 100.0 / out_span,
            "bal_time": num("bal_time"),
            "single": float(single),
            **{name: float(bool(prm[name])) for name in FLAGS},
        }

    def initial_state(self) -> list[float]:
        """Target Man until the first scan writes the ``mode`` input; OUT = initial_out; the
        PV filter and the reset wait for the first usable IN (re-initialisation pending)."""
        x = [0.0] * self.n_x
        x[X.target] = MAN
        x[X.sp_param] = self._initial_sp
        x[X.sp_ramp] = self._initial_sp
        x[X.sp_filtered] = self._initial_sp
        x[X.out_pct] = self._initial_pct
        x[X.r] = self._initial_pct
        x[X.limit] = 2.0 if self._initial_pct >= self.p[P.out_hi] else (
            1.0 if self._initial_pct <= self.p[P.out_lo] else 0.0)
        x[X.init] = 1.0
        x[X.first] = 1.0
        return x

    def initial_outputs(self) -> list[float]:
        """Before the first scan (what blocks earlier in a module's order read): OUT =
        ``initial_out``, the start value; BKCAL_OUT and the working SP = the initial SP
        (SP_LO_LIM..SP_HI_LIM nearest 0); mode Man (the target until the first scan writes
        ``mode``); R = OUT%; PV, P, D and FF 0 (no IN yet; IN's default is 0)."""
        x = self.x
        p = self.p
        y = [0.0] * len(self.OUTPUTS)
        out = rnd(p[P.out_eu0] + x[X.out_pct] * p[P.out_eu_per_pct], p[P.single] != 0.0)
        y[Y.out] = min(max(out, p[P.out_lo_eu]), p[P.out_hi_eu])  # initial_out is within them
        y[Y.bkcal_out] = y[Y.working_sp] = x[X.sp_filtered]
        y[Y.mode_actual] = y[Y.mode_target] = x[X.target]
        y[Y.r_term] = x[X.r]
        return y
