r"""GE PACSystems built-in PID: ``ge.pid_ind`` (PID_IND) and ``ge.pid_isa`` (PID_ISA).

The PID of the PACSystems RX7i / RX3i / RSTi-EP CPUs (also VersaMax and Series 90-30), as
specified in spec vendor-blocks section 1 (sources: GFK-2950C chapter 7 and seed 003). The
block works on a 40-word reference array of signed 16-bit words; this emulation takes the user
words (3-13) as parameters in engineering units, keeps the internal words (14-27) as its state,
and by default reproduces the controller's integer arithmetic in counts.

Parameters and their words (spec 1.2, 1.5)
-------------------------------------------

    word    parameter                            raw scaling (native arithmetic rounds to it)
    3       sample_period (s)                    10 ms per count, 0..655.35 s; >= 10 ms is used
    4, 5    deadband_pos, deadband_neg           PV counts
    6       kp (IND) / kc (ISA)                  0.01 per count: word 6 = 450 is gain 4.50
    7       kd (IND) / td (ISA), s               0.01 s per count
    8       ki (IND), repeats/s                  0.001 repeats/s per count
    8       ti (ISA), s                          word 8 holds 1/Ti in 0.001 repeats/s:
                                                 Ti = 1000/word8
    9       bias                                 CV counts
    10, 11  upper_clamp, lower_clamp             CV counts
    12      min_slew_time (s)                    seconds for a full 32000-count travel, 0 = off
    13      Config Word                          config_word, or the flags below

Config Word bits (spec 1.3): bit 0 ``direct_acting`` (e = PV - SP; GE calls e = SP - PV
"reverse acting", the default), bit 1 ``invert_output`` (CV = -Output after the clamp), bit 2
``derivative_on_pv``, bit 3 ``deadband_subtract``, bit 4 ``arw_hold``, bit 5
``derivative_filter``. Give the flags, or one ``config_word`` integer, not both.
``from_reference_array(words, kind=...)`` builds a block from the raw 40 words.

In ``native`` arithmetic every engineering value is rounded to its word (half away from zero);
a non-zero gain, time or slew time that would round to word 0 (and so silently switch its action
off) is a ``ParameterError``. ``block.parameter_words()`` shows the
words in use. ``arithmetic = "float"`` uses the values as given.

Equations (spec 1.5, 1.6, 1.7)
------------------------------

Timing is the controller clock (spec 1.7 step 3): the block solves only when
``now - t_last >= max(sample_period, 10 ms)``, with ``now`` in 100 µs ticks; then
``dt = now - t_last`` and ``t_last = now``. ``now`` is the ``clock`` input (s, rounded to the
nearest 100 µs tick): a module and ``loopworks replay`` fill it with the scan time / the ``t``
column. When ``clock`` is NaN (its default, e.g. ``step(dt)`` from Python) the block advances
its own clock by ``dt`` before each sweep, so successive steps read dt, 2·dt, ... A clock that
goes backwards makes the block wait until it passes ``t_last`` again. A module's first scan is
at t = 0, the initial time of last solution, so there the first solution comes one sample
period (at least 10 ms) later.

Per solution, with ``e = SP - PV`` (``direct_acting``: ``PV - SP``), SP and PV the INT
operands (native: rounded to whole counts, halves away from zero; one that is not a 16-bit
word is Bad input, see below)::

    dead band (spec 1.7 step 6, strict edges):
        e_db = 0                    if DB- < e < DB+
             = e                    otherwise, bit 3 = 0
             = e - DB+ or e - DB-   otherwise, bit 3 = 1 (the edge is subtracted)
    derivative change Δ (seed 003 table, raw SP/PV: the dead band does not touch it):
        bit0=0 bit2=0: ΔSP - ΔPV    bit0=1 bit2=0: ΔPV - ΔSP
        bit0=0 bit2=1: -ΔPV         bit0=1 bit2=1: +ΔPV

    native, PID_IND (dt_ticks = dt / 100 µs):
        P   = w6·e_db / 100
        ΔI  = w8·e_db·dt_ticks / 10^7           (carried below one count, see below)
        D   = w7·Δ·100 / dt_ticks
    native, PID_ISA (Kc outside; isa_division = "combined"):
        P   = w6·e_db / 100                     (= Kc·e)
        ΔI  = w6·w8·e_db·dt_ticks / 10^9        (= Kc·e·dt/Ti)
        D   = w6·w7·Δ / dt_ticks                (= Kc·Td·Δ/dt)
    float: P = Kp·e_db,  ΔI = Ki·e_db·dt,  D = Kd·Δ/dt   (ISA: Kp = Kc, Ki = Kc/Ti, Kd = Kc·Td)

P and D are whole counts: each division is rounded per ``rounding``. The integral is kept in
units of ``integral_resolution`` (0.001 count): ΔI is rounded to the nearest unit (halves away
from zero) and added to the 32-bit integral (words 21-22, saturated) plus remainder (word 27,
state ``int_remainder`` in those units), so the part below one count is carried to the next
solution; the integral counts in the sum are its whole part. With the default resolution an
increment below half a thousandth of a count is lost every solution: the integral stops (the
vendor's warning against too short a sample period, spec 1.8). ``integral_resolution = 0``
carries the exact remainder, in units of 10^-7 count (IND) or 10^-9 count (ISA), the
denominators of ΔI, so every ΔI is a whole number of units (exact in float64 while the
integral stays below about 9·10^8 counts for IND, 9·10^6 for ISA).

Then (spec 1.7 steps 9-13)::

    Auto:    Output = P + I + D + Bias              (I = integral after this ΔI)
    Manual:  target = word 14 ± 1 count for UP / DN (this solution); the integral is set so
             that P + I + D + Bias = target (bumpless return to Auto)
    slew:    |Output - Output_prev| <= 32000·dt / min_slew_time; when it acts, the integral is
             set so that P + I + D + Bias equals the limited output
    clamp:   lower_clamp <= Output <= upper_clamp; at a clamp the integral is set so that the
             sum equals the clamp (bit 4 = 0, back-calculation) or keeps its value from the
             previous solution (bit 4 = 1, hold)
    word 19 = Output;  CV = -Output if bit 1 else Output
    Auto:    word 14 (Manual Command) = Output (tracking)

Words 16-18 mirror SP, CV and PV and word 15 reports the MAN/enable/UP/DN inputs (bits 1-4)
on each solution while Override (word 15 bit 0) is off. A back-calculated integral is a whole
count (remainder 0).

Inputs
------

``sp``, ``pv`` (counts); ``man``, ``up``, ``dn``, ``enable`` (booleans as 0/1, true above
0.5; ``enable`` is the power flow in, default 1); ``clock`` (s, see Timing). Writes of the
program or HMI into the array, applied each sweep before the block runs when they are 16-bit
words (NaN = no write, the word keeps its value; so does a value that no word can hold: ±inf,
or beyond -32768..32767, 0..65535 for word 15): ``manual_command`` (word 14, counts),
``control_word`` (word 15), ``internal_sp`` / ``internal_pv`` (words 16 / 18, used under
Override). A program that writes word 14 every sweep overrides UP/DN and the Auto tracking, as
on the PLC: set it to NaN to stop writing.

Outputs: ``cv`` (counts, after polarity), ``output`` (word 19, before polarity), ``ok``
(power flow out, 1/0). GE has no status bytes: the outputs are always Good (128), and always
finite whole words (native) inside the clamps; ``ok`` is the only sign of trouble.

Before its first sweep the block shows its start value (issue 11 point 8): word 19 =
clamp(Bias, lower_clamp, upper_clamp), the output a first solution gives at zero error with the
empty integral; CV, word 17 and word 14 hold the same (CV after polarity), and ``ok`` = 0. A
fresh reference array holds 0 in these words; the start value differs from it only when the
bias is not 0 or 0 is outside the clamps, and it is where the output stays until the first
solution (sweeps before the sample period has elapsed hold it). With a parameter error
(``on_parameter_error = "ok_off"``) the block never solves and CV stays at the fresh 0.

Vendor behaviour reproduced
---------------------------

* Not powered (``enable`` off): nothing runs, CV holds, ``ok`` = 0 (spec 1.7 step 1).
* Sweeps between solutions leave CV unchanged with ``ok`` = 1 (an execution without a
  parameter error, spec 1.1).
* Parameter errors (spec 1.7 step 2: a dead band that is not "both 0, or DB+ > 0 and DB- < 0";
  ``upper_clamp <= lower_clamp``): raised as ParameterError at construction, or with
  ``on_parameter_error = "ok_off"`` the PLC behaviour: every powered sweep gives ``ok`` = 0 and
  a frozen CV (spec 1.10).
* Sample period 0 still solves at most every 10 ms: 9 ms sweeps solve every second sweep with
  dt = 18 ms (spec 1.9 G14); overshoot does not accumulate (30 ms sweeps, 100 ms period: every
  120 ms).
* First solution / long gap (spec 1.7): words 24-26 (time of last solution) start at
  ``initial_last_solution`` (0 s), so a first solution at a large clock time has a huge dt and
  the integral steps by Ki·e·dt (saturated at 32 bits). ``load_clock_at_start = true`` loads the
  clock instead as power flow comes on (the first enabled sweep, and each return of power flow
  after an unpowered sweep), as the vendor's SVC_REQ 16/51 remedy does "before re-enabling a
  long-stopped loop" (spec 1.2 words 24-26). The other
  internal words also start at 0 (a fresh reference array): word 20 (the previous error, or
  PV with bit 2) is 0, so the first solution's derivative sees a change from 0: a full kick
  Kd·(-PV)/dt even with ``derivative_on_pv``, which a clamp can turn into a lasting offset
  (the integral is back-calculated to the clamped output). ``prime_derivative = true`` loads
  word 20 with the first solution's PV (bit 2) or error instead, so that derivative is 0.
* UP/DN act once per solution, not per sweep, and stay subject to the slew limit and clamps.
  Word 14 itself is not clamped in Manual (spec 1.7 step 13 writes it in Auto only): UP beyond
  the clamp raises word 14 but not CV.
* When the slew limit or a clamp acts the integral is recomputed from the limited output
  (spec 1.7 steps 10-11, read literally). So a proportional step larger than the rate limit is
  absorbed into the integral: with Ki = 0 the output stays where the limiter left it, and with
  Ki > 0 it ramps at the slower of the slew rate and the integral's own rate. Likewise with
  Ki = 0 the integral of a P-only loop acts as a frozen manual reset after Manual or a clamp.
* The rate limit is 32000 counts per ``min_slew_time`` whatever the CV span.
* PID_ISA uses the same words with the ISA maths; nothing is converted silently.
* Bad measurement (spec silent, an [A]): an ``sp``/``pv`` that is no INT operand (NaN, ±inf,
  or beyond -32768..32767 once rounded: a PLC word cannot hold it, so it is not saturated into
  a plausible full-scale value), or a Bad status (``sp.ST``/``pv.ST``), on a sweep where a
  solution is due makes the block skip that solution as if unpowered: CV holds, ``ok`` = 0, no
  state changes (the time of the last solution too, so the next good solution integrates over
  the whole gap). A NaN or infinite ``man``/``up``/``dn`` (no BOOL) does the same; a NaN
  ``enable`` is no power flow. The block never raises at run time.

Retuning in Auto
----------------

A parameter change between sweeps (``set_params``: a scenario event, ``tune``, an operator)
keeps the state and takes effect at the next solution. The law is positional with an
accumulated integral (spec 1.6, 1.7 steps 8-9), so the vendor's own behaviour is what that law
gives: a change of Kp/Kc (word 6), of the action (Config bit 0) or of the dead band steps the
output by the change of P = w6·e_db/100; Ki/Ti and Kd/Td act on increments (ΔI, Δ/dt) and do
not step it. The integral (words 21-22, 27) is stored in CV counts, with Kc applied to each
increment in PID_ISA (ΔI = Kc·e·dt/Ti, spec 1.5 [D]; the back-calculations of spec 1.7 steps
9-11 set it in counts, the same words for both instructions), so a Kc change does not rescale
the past integral: a PID_ISA Kc step moves the output by ΔKc·e_db (and later increments by
ΔKc·e·dt/Ti), not by ΔKc·I/Kc. Neither the spec (1.6-1.10, 8) nor seed 003 says that the block
compensates a retune, so ``retune = "vendor"`` is the default.

``retune = "bumpless"``: while the block is in Auto (powered, solved before, no parameter error,
and Manual off for the next solution: the MAN input, or word 15 bit 1 under Override), a change
of word 6, Config bit 0 or the dead band moves the integral by P_old - P_new, both at the SP and
PV the next solution reads from the latched inputs (DiscretePIDs.jl ``set_K!``; Åström &
Hägglund 2006, sec. 3.5). In native arithmetic P is a whole count under either tuning, so the
correction is a whole count added to words 21-22, word 27 (the remainder) untouched: the stored
integral moves by exactly P_old - P_new (unless it saturates at the 32-bit limit). The next
solution's output at the same SP and PV then equals the old tuning's exactly with
``rounding = "floor"``, and within one count with ``"truncate"``: the whole part of the integral
is truncated toward zero, and trunc(I + n) = trunc(I) + n - 1 or + 1 when the correction n
carries an integral with a remainder across zero. In float arithmetic the correction is exact
to float64 rounding. In Manual the integral is back-calculated every solution (spec 1.7 step
9), so nothing is done.

Options for the spec's [A]/[?] points
-------------------------------------

* ``rounding`` = ``"truncate"`` (toward zero) or ``"floor"``: direction of the integer divisions
  of P, D and the slew step, and of the integral's whole part [?, spec 1.5]. Differs by one
  count for negative operands only.
* ``integral_resolution`` = 0.001 counts: resolution of the carried integral remainder (word 27)
  [A, spec 1.5]; 0 = exact carry. Must be 0 or 1/n for a whole n.
* ``isa_division`` = ``"combined"``: PID_ISA integer division points [?, spec 1.5]. "combined"
  forms each term as one product divided once (above); "staged" rounds the bracket term first
  (e·dt/Ti to the integral resolution, Td·Δ/dt to a count) and then multiplies by Kc and rounds
  again.
* ``saturate_sum`` = false: whether P + I + D + Bias saturates at 16 bits before the slew limit
  and clamps [?, spec 1.5; the spec's choice is one clamp]. Only the slew remainder can tell.
* ``slew_remainder`` = true: the slew allowance below one count is carried to the next solution
  (word 23, "slew term storage") so a slow ramp still moves; false = truncated every solution
  [A, spec 1.2 word 23 / 1.7 step 10].
* ``derivative_filter`` (Config bit 5) = false, ``derivative_filter_time`` = kd/10 (IND) or
  td/10 (ISA), s: the filter law is unknown [?, spec 1.3]; this is a first-order lag on the D
  term, D_f += (1 - exp(-dt/Tf))·(D - D_f).
* ``arw_hold`` (Config bit 4): "hold" = the integral keeps its previous value while the output
  is clamped in Auto [third-party source only, spec 1.3 / 8]; in Manual the integral is set to
  reproduce the (clamped) Manual Command (spec 1.7 step 9 [V]), so the return to Auto is
  bumpless.
* ``override_sp_pv`` = true: with Override (word 15 bit 0) set, words 16/18 replace the SP/PV
  operands, besides word-15 bits 1/3/4 replacing MAN/UP/DN [A, spec 1.4]; false = only the
  discrete inputs are replaced.
* ``manual_tracking`` = ``"output"``: in Auto, word 14 tracks word 19 (before polarity) [A, spec
  1.7 step 13]; ``"cv"`` tracks CV (after polarity).
* ``initial_last_solution`` = 0 s and ``load_clock_at_start`` = false: the first-solution
  behaviour (words 24-26) [spec 1.7, the emulator must reproduce the step by default].
* ``on_parameter_error`` = ``"raise"`` or ``"ok_off"`` (the PLC's silent ok = 0) [spec 1.7 step 2,
  1.10].
* ``bad_input`` = ``"hold"``: NaN/inf/beyond-16-bit or Bad-status SP/PV skip the solution
  (above) [A, spec silent]; ``"ignore_status"`` uses the value whatever its status (the PLC has
  no status), and still holds on a value that is not a 16-bit word.
* ``prime_derivative`` = false: word 20 starts at 0 (a fresh array: the first solution's
  derivative kicks, literal); true loads it from the first solution's PV or error (no kick)
  [spec 1.2 word 20 / 1.7: the internal words of a fresh array].
* The dead band's bit-3 wording in the manual can be read against the table of spec 1.3;
  ``deadband_subtract`` follows the table (the edge is subtracted outside the band) [?, spec 1.7
  step 6].
* ``retune`` = ``"vendor"``: a change of word 6, Config bit 0 or the dead band in Auto steps the
  output as the law gives; ``"bumpless"`` moves the integral by P_old - P_new (above) [A, spec
  silent; spec 1.6].

Worked example
--------------

The vendor's example array (GFK-2950C section 7.7, spec 1.9 G12): Manual at 8000, then Auto
with SP 10000 and PV 9000 fixed::

    import loopworks
    from loopworks.vendors.ge_pacsystems import from_reference_array

    words = [0] * 40
    words[2:13] = [10, 5, -5, 400, 0, 1500, 0, 20000, 4000, 0, 0]   # words 3..13
    pid = from_reference_array(words, kind="ge.pid_ind")
    # equivalently: loopworks.create_block("ge.pid_ind", kp=4.0, ki=1.5, sample_period=0.1,
    #     deadband_pos=5, deadband_neg=-5, upper_clamp=20000, lower_clamp=4000)
    for k in range(1, 4):       # Manual, Manual Command 8000: CV = 8000
        pid.step(0.1, clock=0.1 * k, sp=10000.0, pv=9000.0, man=1.0, manual_command=8000.0)
    pid.step(0.1, clock=0.4, man=0.0, manual_command=float("nan"))["cv"].value   # 8150.0
    pid.step(0.1, clock=0.5)["cv"].value                                          # 8300.0

The same with ``loopworks replay ge.pid_ind run.csv -p kp=4 -p ki=1.5 -p sample_period=0.1
-p upper_clamp=20000 -p lower_clamp=4000`` on ``run.csv``::

    t,sp,pv,man,manual_command
    0.1,10000,9000,1,8000
    0.2,10000,9000,1,8000
    0.3,10000,9000,0,nan
    0.4,10000,9000,0,nan

gives ``cv`` = 8000, 8000, 8150, 8300 (the ``t`` column is the controller clock).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any, ClassVar

from loopworks.blocks.block import Block
from loopworks.blocks.controller import Action, Controller, Handover, Roles
from loopworks.blocks.forms import ideal_to_parallel, parallel_to_ideal
from loopworks.blocks.kernel import FloatArray, IntArray, primitive
from loopworks.blocks.law import (
    TOL,
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
from loopworks.blocks.primitives import clamp, finite, lag_step
from loopworks.blocks.registry import register
from loopworks.blocks.status import BAD, GOOD_NC
from loopworks.errors import ParameterError

INPUTS: tuple[Port, ...] = (
    Port("sp", 0.0, "counts", "SP operand: setpoint, same scaling as PV (spec 1.1)",
         status=True),
    Port("pv", 0.0, "counts", "PV operand: process variable (spec 1.1)", status=True),
    Port("man", 0.0, "", "MAN: 1 = Manual mode (spec 1.1)"),
    Port("up", 0.0, "", "UP: in Manual raise CV 1 count per solution (spec 1.1)"),
    Port("dn", 0.0, "", "DN: in Manual lower CV 1 count per solution (spec 1.1)"),
    Port("enable", 1.0, "", "power flow in: the block runs only while 1 (spec 1.1)"),
    Port("clock", math.nan, "s", "controller clock (module time / replay t); NaN = advance an "
         "own clock by dt (spec 1.7 step 3)"),
    Port("manual_command", math.nan, "counts", "program write into word 14 (Manual Command) "
         "each sweep; NaN = no write (spec 1.2)"),
    Port("control_word", math.nan, "", "HMI write into word 15 (bit 0 Override, 1 Manual, "
         "3 UP, 4 DN); NaN = no write (spec 1.4)"),
    Port("internal_sp", math.nan, "counts", "write into word 16, the SP used under Override; "
         "NaN = no write (spec 1.4)"),
    Port("internal_pv", math.nan, "counts", "write into word 18, the PV used under Override; "
         "NaN = no write (spec 1.4)"),
)
OUTPUTS: tuple[Port, ...] = (
    Port("cv", 0.0, "counts", "CV: the output after polarity (spec 1.1)"),
    Port("output", 0.0, "counts", "word 19: the output before the polarity inversion "
         "(spec 1.2)"),
    Port("ok", 0.0, "", "ok power flow out: 1 = executed without a parameter error "
         "(spec 1.1)"),
)
#: the coefficient array p (coefficients()): the words 3-13 as the kernel uses them, and the
#: switches of the options
COEFFS: tuple[str, ...] = (
    "isa", "native", "period", "db_pos", "db_neg", "g6", "g7", "g8", "bias", "upper", "lower",
    "slew", "direct", "invert", "d_on_pv", "db_sub", "arw_hold", "d_filt", "tf", "units",
    "unit_mul", "unit_div", "quant", "floor", "staged", "ovr_sppv", "track_cv", "last0",
    "load_clock", "param_err", "ignore_status", "slew_carry", "sat_sum", "prime_d")
#: the state array x, named after the reference-array words they hold (words 14-27) and the
#: block's own memories
STATES: tuple[str, ...] = (
    "manual_command", "control_word", "internal_sp", "internal_cv", "internal_pv", "output",
    "diff_storage", "integral", "int_remainder", "slew_storage", "last_solution", "clock",
    "d_filter", "powered", "cv", "solved")
P, X, U, Y = index(COEFFS, "P"), index(STATES, "X"), index(INPUTS, "U"), index(OUTPUTS, "Y")

TICKS_PER_S = 10_000.0  # the controller clock has 100 µs resolution (spec 1.5)
#: the finest integral_resolution is 1/MAX_UNITS of a count
MAX_UNITS = 1e9
MIN_PERIOD_TICKS = 100.0  # at least 10 ms between solutions (spec 1.2 word 3)
CLOCK_MAX_S = (2.0 ** 48 - 1.0) / TICKS_PER_S  # words 24-26: a 48-bit clock
INT32_MAX = 2147483647.0  # words 21-22
WORD_MIN, WORD_MAX = -32768.0, 32767.0
_EXACT = 4.0e15  # above this every float64 is a whole number: nothing to round


@primitive
def _round_away(x: float) -> float:
    """Nearest whole number, halves away from zero (a float; huge values pass unchanged)."""
    if not (x < _EXACT and x > -_EXACT):
        return x
    if x >= 0.0:
        return float(math.floor(x + 0.5))
    return -float(math.floor(-x + 0.5))


@primitive
def _div(num: float, den: float, floor_mode: float) -> float:
    """Integer division num/den of whole numbers: toward zero, or toward -inf when
    ``floor_mode`` (spec 1.5 [?]). num and den are exact in float64, so the float quotient
    truncates to the exact integer quotient."""
    q = num / den
    if not (q < _EXACT and q > -_EXACT):
        return q
    if floor_mode != 0.0:
        return float(math.floor(q))
    return float(math.trunc(q))


@primitive
def _word(x: float, native: float) -> float:
    """An INT operand: saturated to 16 bits, and in native arithmetic a whole count."""
    x = clamp(x, WORD_MIN, WORD_MAX)
    if native != 0.0:
        return _round_away(x)
    return x


@primitive
def _is_word(x: float, lo: float, hi: float, native: float) -> bool:
    """True when x can be written into a word of range lo..hi: finite and, rounded to a whole
    count in native arithmetic (halves away from zero), inside the range."""
    if not finite(x):
        return False
    if native != 0.0:
        x = _round_away(x)
    return lo <= x and x <= hi


@primitive
def _bit(word: float, weight: float) -> bool:
    """Bit of value ``weight`` (1, 2, 4, ...) of a whole number 0..65535."""
    q = math.floor(word / weight)
    return q - 2 * math.floor(q / 2) != 0


@primitive
def _hold(x: FloatArray, y: FloatArray, ok: float) -> None:
    """No solution this sweep: CV and word 19 keep their values."""
    y[Y.cv] = x[X.cv]
    y[Y.output] = x[X.output]
    y[Y.ok] = ok


@primitive
def _error(p: FloatArray, sp: float, pv: float) -> float:
    """e = SP - PV ("reverse acting"), or PV - SP with Config bit 0 (spec 1.7 step 5)."""
    return pv - sp if p[P.direct] != 0.0 else sp - pv


@primitive
def _dead_band(p: FloatArray, e: float) -> float:
    """The error after the dead band (spec 1.7 step 6): 0 strictly inside DB-..DB+, else e,
    or with Config bit 3 e less the edge it passed."""
    db_pos: float = p[P.db_pos]
    db_neg: float = p[P.db_neg]
    if db_neg < e and e < db_pos:
        return 0.0
    if p[P.db_sub] == 0.0:
        return e
    if e >= db_pos:
        return e - db_pos
    return e - db_neg


@primitive
def _p_term(p: FloatArray, e_db: float) -> float:
    """P = Kp·e_db (ISA: Kc·e_db): native w6·e_db/100 divided per ``rounding``, a whole count
    (spec 1.5); float Kp·e_db."""
    gain: float = p[P.g6]
    if p[P.native] != 0.0:
        return _div(gain * e_db, 100.0, p[P.floor])
    return gain * e_db


def ge_pid_kernel(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                  y: FloatArray, ys: IntArray) -> None:
    """One PLC sweep of the GE PID (spec 1.7; equations in the module docstring)."""
    ys[Y.cv] = GOOD_NC
    ys[Y.output] = GOOD_NC
    ys[Y.ok] = GOOD_NC
    native = p[P.native]
    floor_mode = p[P.floor]
    # Writes of the program / HMI into the array (every sweep, before the block runs). A value
    # that is not a 16-bit word (NaN: no write; inf, out of range) never reaches the array.
    if _is_word(u[U.manual_command], WORD_MIN, WORD_MAX, native):
        x[X.manual_command] = _word(u[U.manual_command], native)
    if _is_word(u[U.control_word], WORD_MIN, 65535.0, 1.0):
        cw = _round_away(u[U.control_word])
        x[X.control_word] = cw + 65536.0 if cw < 0.0 else cw
    if _is_word(u[U.internal_sp], WORD_MIN, WORD_MAX, native):
        x[X.internal_sp] = _word(u[U.internal_sp], native)
    if _is_word(u[U.internal_pv], WORD_MIN, WORD_MAX, native):
        x[X.internal_pv] = _word(u[U.internal_pv], native)
    # The controller clock (spec 1.7 step 3): the clock input, else the block's own clock.
    clock = u[U.clock]
    clock = clamp(clock, 0.0, CLOCK_MAX_S) if finite(clock) else min(x[X.clock] + dt,
                                                                     CLOCK_MAX_S)
    x[X.clock] = clock
    now = float(math.floor(clock * TICKS_PER_S + 0.5))
    # 1. power flow; 2. parameter check (spec 1.7)
    enabled = u[U.enable] > 0.5
    if enabled and x[X.powered] == 0.0 and p[P.load_clock] != 0.0:
        x[X.last_solution] = now  # SVC_REQ 16/51 as power flow returns: no first-dt step
    x[X.powered] = 1.0 if enabled else 0.0
    if not enabled or p[P.param_err] != 0.0:
        _hold(x, y, 0.0)
        return
    # 3. timing: solve only when max(sample period, 10 ms) has elapsed
    elapsed = now - x[X.last_solution]
    if elapsed < p[P.period]:
        _hold(x, y, 1.0)
        return
    dt_ticks = elapsed
    # 4. inputs: MAN/UP/DN from the operands, or from word 15 under Override (spec 1.4)
    override = _bit(x[X.control_word], 1.0)
    if override:
        man = _bit(x[X.control_word], 2.0)
        up = _bit(x[X.control_word], 8.0)
        dn = _bit(x[X.control_word], 16.0)
    else:
        if not (finite(u[U.man]) and finite(u[U.up]) and finite(u[U.dn])):  # no BOOL: Bad input
            _hold(x, y, 0.0)
            return
        man = u[U.man] > 0.5
        up = u[U.up] > 0.5
        dn = u[U.dn] > 0.5
    if override and p[P.ovr_sppv] != 0.0:
        sp = x[X.internal_sp]
        pv = x[X.internal_pv]
    else:
        sp = u[U.sp]
        pv = u[U.pv]
        # an SP or PV that is no INT operand (NaN, inf, beyond 16 bits) is Bad input
        bad = (not _is_word(sp, WORD_MIN, WORD_MAX, native)
               or not _is_word(pv, WORD_MIN, WORD_MAX, native))
        if p[P.ignore_status] == 0.0 and ((us[U.sp] & 0xC0) == BAD or (us[U.pv] & 0xC0) == BAD):
            bad = True
        if bad:  # [A] skip the solution as if unpowered
            _hold(x, y, 0.0)
            return
        sp = _word(sp, native)
        pv = _word(pv, native)
    x[X.last_solution] = now
    if not override:
        x[X.internal_sp] = sp
        x[X.internal_pv] = pv
        x[X.control_word] = ((2.0 if man else 0.0) + 4.0 + (8.0 if up else 0.0)
                             + (16.0 if dn else 0.0))
    # 5. error and 6. dead band
    e = _error(p, sp, pv)
    e_db = _dead_band(p, e)
    # 7. derivative change (seed 003 table); word 20 keeps the previous error or PV. A fresh
    # array holds 0 there; prime_derivative loads it at the first solution (no kick).
    if x[X.solved] == 0.0 and p[P.prime_d] != 0.0:
        x[X.diff_storage] = pv if p[P.d_on_pv] != 0.0 else e
    x[X.solved] = 1.0
    if p[P.d_on_pv] != 0.0:
        delta = pv - x[X.diff_storage] if p[P.direct] != 0.0 else x[X.diff_storage] - pv
        x[X.diff_storage] = pv
    else:
        delta = e - x[X.diff_storage]
        x[X.diff_storage] = e
    # 8. terms
    units = p[P.units]  # integral units per count (1 in float arithmetic)
    if native != 0.0:  # ΔI in units = numerator·unit_mul/unit_div
        pterm = _p_term(p, e_db)
        if p[P.isa] == 0.0:
            inc = p[P.g8] * e_db * dt_ticks / p[P.unit_div]
            draw = _div(p[P.g7] * delta * 100.0, dt_ticks, floor_mode)
        elif p[P.staged] == 0.0:
            inc = p[P.g6] * p[P.g8] * e_db * dt_ticks / p[P.unit_div]
            draw = _div(p[P.g6] * p[P.g7] * delta, dt_ticks, floor_mode)
        else:  # bracket term first (e·dt/Ti, Td·Δ/dt), then Kc
            inner = p[P.g8] * e_db * dt_ticks * p[P.unit_mul] / p[P.unit_div]
            if p[P.quant] != 0.0:
                inner = _round_away(inner)
            inc = p[P.g6] * inner / 100.0
            draw = _div(p[P.g6] * _div(p[P.g7] * delta * 100.0, dt_ticks, floor_mode), 100.0,
                        floor_mode)
        if p[P.quant] != 0.0:  # ΔI to the nearest unit of integral_resolution
            inc = _round_away(inc)
    else:
        dt_s = dt_ticks / TICKS_PER_S
        pterm = _p_term(p, e_db)
        inc = p[P.g8] * e_db * dt_s
        draw = p[P.g7] * delta / dt_s
    if p[P.d_filt] != 0.0:
        x[X.d_filter] = lag_step(x[X.d_filter], draw, dt_ticks / TICKS_PER_S, p[P.tf])
        dterm = _div(x[X.d_filter], 1.0, floor_mode) if native != 0.0 else x[X.d_filter]
    else:
        dterm = draw
    bias = p[P.bias]
    imax = INT32_MAX * units
    total_prev = x[X.integral] * units + x[X.int_remainder]
    # 9. mode
    if man:
        target = x[X.manual_command]
        if up:
            target += 1.0
        if dn:
            target -= 1.0
        target = clamp(target, WORD_MIN, WORD_MAX)
        x[X.manual_command] = target
        total = clamp(target - pterm - dterm - bias, -INT32_MAX, INT32_MAX) * units
    else:
        total = clamp(total_prev + inc, -imax, imax)
    icounts = _div(total, units, floor_mode) if native != 0.0 else total  # whole counts
    out = pterm + icounts + dterm + bias
    if man:  # word 14 is the CV source in Manual (spec 1.2), also when the integral that
        out = target  # would give it saturates at 32 bits (a derivative kick beyond 2^31)
    if p[P.sat_sum] != 0.0:
        out = clamp(out, WORD_MIN, WORD_MAX)
    # 10. slew limit; the integral follows the limited output
    prev = x[X.output]
    if p[P.slew] > 0.0:
        if native != 0.0:
            allow_num = 32000.0 * dt_ticks + x[X.slew_storage]
            den = p[P.slew] * TICKS_PER_S
            step = _div(allow_num, den, 0.0)
        else:
            step = 32000.0 * (dt_ticks / TICKS_PER_S) / p[P.slew]
            allow_num = 0.0
            den = 1.0
        if out > prev + step or out < prev - step:
            out = prev + step if out > prev else prev - step
            if native != 0.0 and p[P.slew_carry] != 0.0:
                x[X.slew_storage] = allow_num - step * den
            total = clamp(out - pterm - dterm - bias, -INT32_MAX, INT32_MAX) * units
        else:
            x[X.slew_storage] = 0.0
    # 11. clamps and anti-windup (Config bit 4)
    if out > p[P.upper] or out < p[P.lower]:
        out = p[P.upper] if out > p[P.upper] else p[P.lower]
        if p[P.arw_hold] != 0.0 and not man:  # in Manual the integral is set (step 9), not
            total = total_prev                # accumulated: bit 4 has nothing to hold
        else:
            total = clamp(out - pterm - dterm - bias, -INT32_MAX, INT32_MAX) * units
    # store the integral as words 21-22 (whole counts) and 27 (remainder)
    if native != 0.0:
        whole = _div(total, units, floor_mode)
        x[X.integral] = whole
        x[X.int_remainder] = total - whole * units
    else:
        x[X.integral] = total
        x[X.int_remainder] = 0.0
    # 12. word 19 and polarity; 13. Manual Command tracking; 14. ok
    cv = -out if p[P.invert] != 0.0 else out
    x[X.output] = out
    x[X.cv] = cv
    if not override:
        x[X.internal_cv] = cv
    if not man:
        x[X.manual_command] = cv if p[P.track_cv] != 0.0 else out
    y[Y.cv] = cv
    y[Y.output] = out
    y[Y.ok] = 1.0


# ----------------------------------------------------------------------------------------------
# Parameters
# ----------------------------------------------------------------------------------------------
CONFIG_FLAGS: tuple[str, ...] = ("direct_acting", "invert_output", "derivative_on_pv",
                                 "deadband_subtract", "arw_hold", "derivative_filter")


def _common_params() -> tuple[Param, ...]:
    return (
        Param("sample_period", 0.0, "s", "Sample Period (word 3, 10 ms steps; 0 = every sweep, "
              "at least 10 ms between solutions), spec 1.2", lo=0.0, hi=655.35, lo_open=False,
              hi_open=False),
        Param("deadband_pos", 0.0, "PV counts", "Dead Band + (word 4): upper edge of the error "
              "dead band; both edges 0, or DB+ > 0 and DB- < 0, spec 1.2/1.7", lo=0.0,
              hi=32767.0, lo_open=False, hi_open=False),
        Param("deadband_neg", 0.0, "PV counts", "Dead Band - (word 5): lower edge of the error "
              "dead band, spec 1.2/1.7", lo=-32768.0, hi=0.0, lo_open=False, hi_open=False),
        Param("bias", 0.0, "CV counts", "CV Bias (word 9), added to the PID sum, spec 1.2",
              lo=-32000.0, hi=32000.0, lo_open=False, hi_open=False),
        Param("upper_clamp", 32000.0, "CV counts", "CV Upper Clamp (word 10): highest output, "
              "> lower_clamp, before polarity, spec 1.2", lo=-32000.0, hi=32000.0, lo_open=False,
              hi_open=False),
        Param("lower_clamp", 0.0, "CV counts", "CV Lower Clamp (word 11): lowest output, "
              "before polarity, spec 1.2", lo=-32000.0, hi=32000.0, lo_open=False, hi_open=False),
        Param("min_slew_time", 0.0, "s", "Minimum Slew Time (word 12): seconds for a full "
              "32000-count travel; 0 = no rate limit, spec 1.2/1.7 step 10", lo=0.0,
              hi=32000.0, lo_open=False, hi_open=False),
        Param("direct_acting", False, "", "Config Word bit 0: e = PV - SP (direct); off: "
              "e = SP - PV (GE's 'reverse acting'), spec 1.3", "bool"),
        Param("invert_output", False, "", "Config Word bit 1: CV = -Output after the clamp, "
              "spec 1.3", "bool"),
        Param("derivative_on_pv", False, "", "Config Word bit 2: derivative on PV only "
              "(ΔSP treated as 0), spec 1.3", "bool"),
        Param("deadband_subtract", False, "", "Config Word bit 3: outside the dead band the "
              "band edge is subtracted from the error, spec 1.3", "bool"),
        Param("arw_hold", False, "", "Config Word bit 4: at a clamp hold the integral; off: "
              "back-calculate it so the output equals the clamp, spec 1.3", "bool"),
        Param("derivative_filter", False, "", "Config Word bit 5: first-order filter on the D "
              "term (law [?]), spec 1.3", "bool"),
        Param("config_word", None, "", "Config Word (word 13) as one integer instead of the "
              "six flags (bits 0-5), spec 1.3", "int", lo=0.0, hi=65535.0, lo_open=False,
              hi_open=False, default_text="from the flags"),
        Param("arithmetic", "native", "", "native: 16-bit counts with the integral remainder "
              "carried (spec 1.5); float: the same equations in floating point", "choice",
              choices=("native", "float")),
        Param("integral_resolution", 0.001, "counts", "resolution of the carried integral "
              "remainder (word 27), 0 = exact carry; 0 or 1/n (n ≤ 10^9), [A] spec 1.5", lo=0.0,
              hi=1.0,
              lo_open=False, hi_open=False),
        Param("rounding", "truncate", "", "integer division direction for P, D and the slew "
              "step, [?] spec 1.5", "choice", choices=("truncate", "floor")),
        Param("saturate_sum", False, "", "saturate P + I + D + Bias at 16 bits before the slew "
              "limit and clamps, [?] spec 1.5", "bool"),
        Param("slew_remainder", True, "", "carry the slew allowance below one count to the "
              "next solution (word 23), [A] spec 1.2/1.7 step 10", "bool"),
        Param("derivative_filter_time", None, "s", "time constant of the Config bit 5 filter; "
              "0 = none, [?] spec 1.3", lo=0.0, lo_open=False, default_text="kd/10 or td/10"),
        Param("override_sp_pv", True, "", "under Override (word 15 bit 0) words 16/18 replace "
              "the SP/PV operands, [A] spec 1.4", "bool"),
        Param("manual_tracking", "output", "", "in Auto, word 14 tracks word 19 (output, before "
              "polarity) or cv, [A] spec 1.7 step 13", "choice", choices=("output", "cv")),
        Param("initial_last_solution", 0.0, "s", "time of last solution (words 24-26) at "
              "start: a first solution at a later clock integrates over the gap, spec 1.7",
              lo=0.0, hi=CLOCK_MAX_S, lo_open=False, hi_open=False),
        Param("load_clock_at_start", False, "", "load the clock into words 24-26 as power "
              "flow comes on: the first enabled sweep and each re-enabling (the SVC_REQ "
              "16/51 remedy), spec 1.2/1.7", "bool"),
        Param("on_parameter_error", "raise", "", "bad dead band or clamps: raise, or ok_off "
              "(the PLC: ok = 0 and CV frozen every sweep), spec 1.7 step 2", "choice",
              choices=("raise", "ok_off")),
        Param("bad_input", "hold", "", "NaN/inf/beyond 16 bits or Bad-status sp/pv: hold "
              "(skip the solution, ok = 0) or ignore_status (use a finite word whatever its "
              "status), [A] spec silent", "choice", choices=("hold", "ignore_status")),
        Param("prime_derivative", False, "", "load word 20 (diff term storage) from the first "
              "solution's PV (or error) so the first derivative sees no change; off: word 20 "
              "starts at 0 (a fresh array) and the first solution kicks, spec 1.2/1.7", "bool"),
        Param("retune", "vendor", "", "a change of the P term (kp or kc, direct_acting, the "
              "dead band) in Auto: vendor = the law as it is, the output steps by the change "
              "of P (spec 1.6); bumpless = words 21-22 move by P_old - P_new at the latched "
              "SP and PV, so the next solution does not step [A, spec silent]", "choice",
              choices=("vendor", "bumpless")),
    )


_GAIN_MAX = 327.67


def _word_of(value: float, scale: float) -> int:
    """The raw word of an engineering value: value·scale rounded half away from zero."""
    return int(math.copysign(math.floor(abs(value) * scale + 0.5), value))


def config_bits(kind: str, params: Mapping[str, Any], given: Iterable[str]) -> dict[str, bool]:
    """The Config Word (word 13) bits by flag name (spec 1.3), from validated ``params``: the
    bits of ``config_word`` when it is given, else the flags; ``given``: the parameter names
    the user gave (a flag given beside ``config_word`` is a ParameterError)."""
    if params["config_word"] is not None:
        cw = int(params["config_word"])
        both = sorted(set(given) & set(CONFIG_FLAGS))
        if both:
            raise ParameterError(f"{kind}: give either 'config_word' or the flags, not both: "
                                 f"'config_word' = {cw} and '{both[0]}' were given")
        return {name: bool(cw >> bit & 1) for bit, name in enumerate(CONFIG_FLAGS)}
    return {name: bool(params[name]) for name in CONFIG_FLAGS}


class GEPIDBlock(Controller, Block):
    """Shared machinery of PID_IND and PID_ISA (one kernel, ``p[P.isa]`` selects the maths)."""

    #: the integral's remainder (word 27) is kept in these units
    FIXED_PARAMS: ClassVar[dict[str, str]] = {
        "integral_resolution": "gives the units the integral remainder (word 27) is kept in"}

    kernel = staticmethod(ge_pid_kernel)
    INPUTS: ClassVar[tuple[Port, ...]] = INPUTS
    OUTPUTS: ClassVar[tuple[Port, ...]] = OUTPUTS
    COEFFS: ClassVar[tuple[str, ...]] = COEFFS
    STATES: ClassVar[tuple[str, ...]] = STATES
    IS_ISA: ClassVar[bool] = False
    # the controller interface (loopworks.blocks.controller): MAN and Manual Command, spec 1.1
    ROLES: ClassVar[Roles] = Roles(sp="sp", pv="pv", out="cv", mode="man",
                                   man_out="manual_command")
    AUTOMATIC: ClassVar[dict[str, Any]] = {"man": 0.0}
    MANUAL: ClassVar[dict[str, Any]] = {"man": 1.0}
    #: every word is a signed 16-bit integer, the SP operand too (spec 1.1)
    SP_WORD: ClassVar[tuple[int, int] | None] = (-32768, 32767)
    ACTION: ClassVar[Action] = Action("direct_acting", "=", True)  # Config Word bit 0, spec 1.3
    #: a relay test puts the block in Manual with the relay's output as Manual Command; the
    #: integral tracks the output in Manual, so Auto continues from it (spec 1.7)
    HANDOVER: ClassVar[Handover] = Handover((("man", "active"), ("manual_command", "out")))

    @classmethod
    def output_range(cls, params: Mapping[str, Any]) -> tuple[float, float]:
        """CV Lower Clamp..CV Upper Clamp (words 11, 10), counts, before the polarity
        inversion (``invert_output`` is not applied)."""
        return float(params["lower_clamp"]), float(params["upper_clamp"])

    def _fail(self, message: str) -> ParameterError:
        return ParameterError(f"{self.kind}: {message}")

    def _gains(self, native: bool) -> tuple[float, float, float, dict[int, int]]:
        """(g6, g7, g8) for the kernel (words, or float gains) and the words 6-8."""
        raise NotImplementedError  # pragma: no cover - abstract

    def _nonzero_word(self, name: str, value: float, scale: float, resolution: str) -> int:
        """The word of ``value``; in native arithmetic a non-zero value may not round to 0."""
        word = _word_of(value, scale)
        if value != 0.0 and word == 0 and self.params["arithmetic"] == "native":
            raise self._fail(f"parameter '{name}' = {value:g} is below the resolution of its "
                             f"word ({resolution}): it would round to 0 and switch the action "
                             "off; give 0 or a larger value")
        return word

    def set_params(self, **changes: Any) -> None:
        """Change parameters between sweeps (see :meth:`Block.set_params`). With
        ``retune = "bumpless"``, while the block is in Auto (powered, solved before, no
        parameter error, the latched MAN off), a change of the P term's coefficients (word 6,
        Config bit 0, the dead band) moves the integral (words 21-22) by

            P_old - P_new,  P = w6·e_db/100 at the SP and PV the next solution reads

        so that solution's output does not step (DiscretePIDs.jl ``set_K!``; Åström &
        Hägglund 2006, sec. 3.5). P is a whole count in native arithmetic, so the correction
        is a whole count and word 27 (the remainder) is untouched: the stored integral moves
        by exactly P_old - P_new (saturated at the 32-bit limit, as the block's own
        integral). The integral and the derivative act on increments (the integral is stored
        in CV counts, Kc applied per increment for PID_ISA, spec 1.5), so Ki, Ti, Kd, Td need
        no correction, and a Kc change does not rescale the past integral."""
        old = self.p.copy()
        super().set_params(**changes)
        if self.params["retune"] != "bumpless":
            return
        new, x = self.p, self.x
        if (x[X.solved] == 0.0 or old[P.param_err] != 0.0 or new[P.param_err] != 0.0
                or old[P.native] != new[P.native] or not self.u[U.enable] > 0.5):
            return
        operands = self._next_operands()
        if operands is None or operands[0]:  # Bad input, or Manual: back-calculated anyway
            return
        _, sp, pv = operands
        delta = (_p_term(old, _dead_band(old, _error(old, sp, pv)))
                 - _p_term(new, _dead_band(new, _error(new, sp, pv))))
        whole = x[X.integral] + delta
        if not -INT32_MAX <= whole <= INT32_MAX:  # the 32-bit words saturate
            whole = max(-INT32_MAX, min(INT32_MAX, whole))
            x[X.int_remainder] = 0.0
        x[X.integral] = whole

    def _next_operands(self) -> tuple[bool, float, float] | None:
        """(manual, SP, PV) of the next solution with the inputs as latched, None when that
        would be Bad input: the kernel's steps 4-5, after the sweep's writes of words 15, 16
        and 18 (spec 1.4, 1.7 step 4)."""
        p, x, u, us = self.p, self.x, self.u, self.us
        native = p[P.native]
        cw = x[X.control_word]
        if _is_word(u[U.control_word], WORD_MIN, 65535.0, 1.0):
            cw = _round_away(u[U.control_word])
            cw = cw + 65536.0 if cw < 0.0 else cw
        override = _bit(cw, 1.0)
        if override:
            man = _bit(cw, 2.0)
        elif not (finite(u[U.man]) and finite(u[U.up]) and finite(u[U.dn])):
            return None
        else:
            man = u[U.man] > 0.5
        if override and p[P.ovr_sppv] != 0.0:
            sp, pv = x[X.internal_sp], x[X.internal_pv]
            if _is_word(u[U.internal_sp], WORD_MIN, WORD_MAX, native):
                sp = _word(u[U.internal_sp], native)
            if _is_word(u[U.internal_pv], WORD_MIN, WORD_MAX, native):
                pv = _word(u[U.internal_pv], native)
            return man, sp, pv
        sp, pv = u[U.sp], u[U.pv]
        bad_status = (us[U.sp] & 0xC0) == BAD or (us[U.pv] & 0xC0) == BAD
        if (not _is_word(sp, WORD_MIN, WORD_MAX, native)
                or not _is_word(pv, WORD_MIN, WORD_MAX, native)
                or (bad_status and p[P.ignore_status] == 0.0)):
            return None
        return man, _word(sp, native), _word(pv, native)

    def config_bits(self) -> dict[str, bool]:
        """The Config Word (word 13) bits by flag name."""
        return config_bits(self.kind, self.params, self.given)

    @classmethod
    def direct_acting(cls, params: Mapping[str, Any]) -> bool:
        """Config Word bit 0 (spec 1.3): ``direct_acting``, or bit 0 of ``config_word``."""
        return config_bits(cls.kind, params, ())["direct_acting"]

    # -- the discrete law (loopworks.blocks.law), both ways ---------------------------------
    LAW_CONTEXT: ClassVar[tuple[str, ...]] = ("pv_span", "cv_span", "word6", "word7", "word8")
    #: the parameters the law reads besides the gains (each form adds its three)
    LAW_PARAMS: ClassVar[tuple[str, ...]] = (
        "direct_acting", "invert_output", "derivative_on_pv", "derivative_filter",
        "derivative_filter_time", "config_word", "sample_period", "arithmetic", "deadband_pos",
        "deadband_neg")

    #: context ``pv_span``, ``cv_span``: counts of 100 % (default 32000, 32000)
    SPANS: ClassVar[tuple[tuple[str, float], tuple[str, float]]] = (
        ("pv_span", 32000.0), ("cv_span", 32000.0))

    @classmethod
    def law(cls, params: Mapping[str, Any], dt: float | None,
            context: Mapping[str, Any]) -> DiscreteLaw:
        """Spec 1.2, 1.5, 1.6: P = Kp·e, ΔI = Ki·e·dt, D = Kd·Δ/dt (no filter), so Kc = Kp,
        Ti = Kp/Ki, Td = Kd/Kp; ISA: Kp = Kc, Ki = Kc/Ti, Kd = Kc·Td. Words: word6 = 100·Kp
        (Kc), word7 = 100·Kd (Td, s), word8 = 1000·Ki (IND) or 1000/Ti (ISA), given in the
        context instead of the values if wanted. The generic pid's law with Tf = 0;
        ``derivative_on_pv`` is c = 0; the derivative filter (bit 5) an exponential lag
        (``derivative = "exp"``). Native arithmetic runs the rounded words (the law does too);
        ``arithmetic = "float"`` the values. Spans: ``pv_span``, ``cv_span`` counts."""
        kind = cls.kind
        given = {str(k).lower() for k in params}
        prm: dict[str, Any] = validate(kind, cls.PARAMS, dict(params))
        pv_span, cv_span = cls.spans(context)
        isa = cls.IS_ISA
        names = ("kc", "td", "ti") if isa else ("kp", "kd", "ki")
        scales = {6: 100.0, 7: 100.0, 8: 1000.0}
        words: dict[int, int] = {}
        for n, name in zip((6, 7, 8), names, strict=True):
            wname = f"word{n}"
            if wname in context:
                w = number(wname, context[wname], 0.0, lo_open=False, kind=kind)
                if w != int(w) or w > 32767:
                    raise ParameterError(f"{kind}: parameter '{wname}' = {context[wname]!r} is "
                                         "out of range: allowed 0..32767 (integer)")
                if name in given:  # both (a conversion's output): they must agree
                    v = float(prm[name])
                    want = ((0 if v == math.inf else _word_of(1000.0 / v, 1.0))
                            if (isa and n == 8) else _word_of(v, scales[n]))
                    if want != int(w):
                        raise ParameterError(f"{kind}: parameter '{wname}' = {int(w)} does "
                                             f"not match '{name}' = {v:g} (word {want}): give "
                                             "one")
                    continue
                words[n] = int(w)
        native = prm["arithmetic"] == "native"
        notes: list[str] = []

        def value(n: int, name: str) -> float:
            scale = scales[n]
            if n in words:
                return words[n] / scale
            v = float(prm[name])
            if native and math.isfinite(v):
                w = _word_of(v, scale)
                if abs(w / scale - v) > TOL * abs(v):
                    notes.append(f"Native arithmetic runs {name} = {v:g} as word {n} = {w} "
                                 f"({w / scale:g}); the conversion uses the word.")
                return w / scale
            return v

        if isa:
            kc = value(6, "kc")
            td = value(7, "td")
            if 8 in words:
                ti = math.inf if words[8] == 0 else 1000.0 / words[8]
            else:
                ti = float(prm["ti"])
                if native and math.isfinite(ti):
                    w8 = _word_of(1000.0 / ti, 1.0)
                    if w8 == 0:
                        raise ParameterError(f"{kind}: parameter 'ti' = {ti:g} s is out of "
                                             "range: word 8 = 1000/ti would round to 0")
                    if abs(1000.0 / w8 - ti) > TOL * ti:
                        notes.append(f"Native arithmetic runs ti = {ti:g} s as word 8 = {w8} "
                                     f"(Ti = {1000.0 / w8:g} s); the conversion uses the word.")
                    ti = 1000.0 / w8
            if not kc > 0.0:
                raise no_ideal(kind, "kc", kc)
            kp = kc
        else:
            kp = value(6, "kp")
            kd = value(7, "kd")
            ki = value(8, "ki")
            if not kp > 0.0:
                raise no_ideal(kind, "kp", kp)
            _, ti, td = parallel_to_ideal(kp, ki, kd)
        bits = config_bits(kind, prm, given)
        derivative = "backward"
        tf = 0.0
        if bits["derivative_filter"] and td > 0.0:
            derivative = "exp"
            tf = (float(prm["derivative_filter_time"])
                  if prm["derivative_filter_time"] is not None
                  else (td if isa else kp * td) / 10.0)
            if tf == 0.0:
                derivative = "backward"
        flags: list[str] = []
        if float(prm["deadband_pos"]) != 0.0 or float(prm["deadband_neg"]) != 0.0:
            flags.append("The GE error dead band (words 4, 5) is a non-linearity the target "
                         "does not have (not converted).")
        period = float(prm["sample_period"])
        law_dt = max(period, 0.01) if period > 0.0 else dt
        if dt is not None and 0.0 < period <= dt:
            # a Sample Period no longer than the scan: the block runs every scan, on the
            # measured dt (spec 1.7 step 3), the same law as the loop's sample time gives
            law_dt = dt
        direct = bits["direct_acting"]
        if bits["invert_output"]:
            # CV = -Output after the clamp (spec 1.3, bit 1): from error to CV the law acts
            # the other way (it was read as not converted, and the target's output had the
            # opposite sign while the conversion was called exact; found by an outside audit)
            direct = not direct
            notes.append("invert_output (Config Word bit 1): CV = -Output after the clamp, "
                         "so from error to CV the law is "
                         + ("direct" if direct else "reverse") + " acting, and is converted "
                         "so; the clamps and CV_Bias act before the inversion (not converted).")
        ideal = Ideal(kp * pv_span / cv_span, ti, td, tf, direct)
        return DiscreteLaw(ideal, b=1.0, c=0.0 if bits["derivative_on_pv"] else 1.0,
                           dt=law_dt, derivative=derivative, words=native, flags=tuple(flags),
                           notes=tuple(notes))

    @classmethod
    def from_law(cls, law: DiscreteLaw, dt: float | None,
                 context: Mapping[str, Any]) -> Realisation:
        """Words 6-8 rounded half up (and the values they stand for, in native arithmetic;
        the unrounded values with context ``arithmetic = "float"``), the action, derivative
        on PV for c = 0, and ``sample_period`` = the context's or ``dt`` (a context's 0, the
        block's default "every sweep", stays 0: the law runs at the scan ``dt``)."""
        kind = cls.kind
        ideal = law.ideal
        every_sweep = False
        if "sample_period" in context:
            period = number("sample_period", context["sample_period"], lo_open=False,
                            kind=kind)
            every_sweep = period == 0.0
            dt = dt if every_sweep else period
        pv_span, cv_span = cls.spans(context)
        k = ideal.kc * cv_span / pv_span
        arithmetic = str(context.get("arithmetic", "native")).lower()
        if arithmetic not in ("native", "float"):
            raise ParameterError(f"{kind}: parameter 'arithmetic' = {arithmetic!r} is not "
                                 "allowed: expected one of native, float")
        native = arithmetic == "native"
        out: dict[str, ParamValue] = {}
        def gain_word(name: str, gain: float) -> int:
            """Word 6 = 100·gain rounded half up; a gain it rounds to 0 (no proportional
            action, which the block refuses) is a ParameterError with the given gain."""
            w = word("word6", gain * 100.0, kind)
            if w == 0 and native:
                raise ParameterError(
                    f"{kind}: parameter '{name}' = {gain:.4g} is out of range: allowed 0.005 "
                    "and above (word 6 = 100·gain rounds to 0: no proportional action; or "
                    "arithmetic = float)")
            return w

        if cls.IS_ISA:
            w6 = gain_word("kc", k)
            w7 = word("word7", ideal.td * 100.0, kind)
            w8 = 0 if ideal.ti == math.inf else word("word8", 1000.0 / ideal.ti, kind)
            if ideal.ti != math.inf and w8 == 0:
                raise ParameterError(f"{kind}: parameter 'ti' = {ideal.ti:g} s is out of "
                                     "range: allowed up to 2000 s (word 8 = 1000/ti rounds "
                                     "to at least 1: 1000/ti >= 0.5) or inf")
            if native:
                out.update(kc=w6 / 100.0, ti=math.inf if w8 == 0 else 1000.0 / w8,
                           td=w7 / 100.0)
            else:
                out.update(kc=k, ti=ideal.ti, td=ideal.td)
        else:
            kp, ki, kd = ideal_to_parallel(k, ideal.ti, ideal.td)
            w6 = gain_word("kp", kp)
            w7 = word("word7", kd * 100.0, kind)
            w8 = word("word8", ki * 1000.0, kind)
            if ideal.ti != math.inf and w8 == 0:
                raise ParameterError(
                    f"{kind}: parameter 'ti' = {ideal.ti:g} s is out of range: allowed up to "
                    f"{2000.0 * kp:g} s (word 8 = 1000·Kp/Ti >= 0.5, so the integral is not "
                    "rounded away) or inf")
            if native:
                out.update(kp=w6 / 100.0, ki=w8 / 1000.0, kd=w7 / 100.0)
            else:
                out.update(kp=kp, ki=ki, kd=kd)
        out.update(word6=w6, word7=w7, word8=w8, direct_acting=ideal.direct,
                   derivative_on_pv=law.c == 0.0 and ideal.td > 0.0)
        if not native:
            out["arithmetic"] = "float"
        if every_sweep:
            out["sample_period"] = 0.0
        elif dt is not None:
            out["sample_period"] = dt
        return Realisation(out, dt)

    def coefficients(self) -> dict[str, Any]:
        prm: dict[str, Any] = self.params
        native = prm["arithmetic"] == "native"
        bits = self.config_bits()
        g6, g7, g8, gain_words = self._gains(native)
        words: dict[int, int] = {3: _word_of(float(prm["sample_period"]), 100.0)}
        words.update(gain_words)
        slew = float(prm["min_slew_time"])
        for n, name in ((4, "deadband_pos"), (5, "deadband_neg"), (9, "bias"),
                        (10, "upper_clamp"), (11, "lower_clamp")):
            words[n] = _word_of(float(prm[name]), 1.0)
        words[12] = self._nonzero_word("min_slew_time", slew, 1.0, "1 s")
        words[13] = sum(1 << bit for bit, name in enumerate(CONFIG_FLAGS) if bits[name])
        self._words = words
        if native:
            db_pos, db_neg = float(words[4]), float(words[5])
            bias, upper, lower = float(words[9]), float(words[10]), float(words[11])
            slew = float(words[12])
            for n, name in ((4, "deadband_pos"), (5, "deadband_neg")):
                if words[n] == 0 and float(prm[name]) != 0.0:  # as a gain that rounds to 0
                    raise self._fail(
                        f"parameter '{name}' = {float(prm[name]):g} PV counts is out of "
                        f"range: native arithmetic holds word {n} in whole counts and this "
                        "rounds to 0, which turns the dead band off; allowed 0 or at least "
                        "0.5 counts in size (spec 1.2)")
        else:
            db_pos, db_neg = float(prm["deadband_pos"]), float(prm["deadband_neg"])
            bias, upper, lower = (float(prm["bias"]), float(prm["upper_clamp"]),
                                  float(prm["lower_clamp"]))
        # the PLC's own parameter check (spec 1.7 step 2)
        problem = ""
        def given(name: str, value: float, n: int) -> str:  # the value, and its word
            v = float(prm[name])
            return f"{v:g}" + (f" (word {n} = {value:g})" if native and v != value else "")

        if not (db_pos == 0.0 and db_neg == 0.0) and not (db_pos > 0.0 and db_neg < 0.0):
            problem = (f"parameters 'deadband_pos' = {given('deadband_pos', db_pos, 4)} and "
                       f"'deadband_neg' = {given('deadband_neg', db_neg, 5)} are not allowed: "
                       "both must be 0, or deadband_pos > 0 and deadband_neg < 0 (spec 1.7 "
                       "step 2)")
        elif not upper > lower:
            problem = (f"parameter 'upper_clamp' = {given('upper_clamp', upper, 10)} must be "
                       f"greater than 'lower_clamp' = {given('lower_clamp', lower, 11)} (spec "
                       "1.7 step 2)")
        if problem and prm["on_parameter_error"] == "raise":
            raise self._fail(problem + "; on_parameter_error = 'ok_off' gives the PLC's "
                             "ok = 0 instead")
        # Integral units: 1/integral_resolution per count; for the exact carry the natural
        # denominators of ΔI (10^-7 count for IND, 10^-9 for ISA), so that every ΔI is a whole
        # number of units. ΔI [units] = numerator·unit_mul/unit_div, where the numerator over
        # 10^7 (IND, ISA staged bracket) or 10^9 (ISA combined) is ΔI in counts.
        res = float(prm["integral_resolution"])
        isa_staged = self.IS_ISA and prm["isa_division"] == "staged"
        base = 1e9 if self.IS_ISA and not isa_staged else 1e7
        unit_mul = 1.0
        if res > 0.0:
            inverse = 1.0 / res
            units = float(round(inverse)) if math.isfinite(inverse) else math.inf
            # n ≤ MAX_UNITS: the integral limit INT32_MAX·n and every sum stay finite (1/2.2e-308
            # made it inf); 10^9 units per count is the exact carry's finest denominator
            if not math.isfinite(units) or units > MAX_UNITS or abs(units * res - 1.0) > 1e-9:
                raise self._fail(f"parameter 'integral_resolution' = {res:g} is not allowed: "
                                 f"it must be 0 or 1/n for a whole n from 1 to {MAX_UNITS:.0e} "
                                 "(e.g. 0.001)")
            unit_div = base / units
        else:
            units = 1e9 if self.IS_ISA else 1e7
            unit_div = 1.0
            unit_mul = 100.0 if isa_staged else 1.0
        if not native:
            units, unit_mul, unit_div = 1.0, 1.0, 1.0
        quant = native and res > 0.0
        if prm["derivative_filter_time"] is not None:
            tf = float(prm["derivative_filter_time"])
        else:
            tf = (words[7] / 100.0 if native else float(prm["td" if self.IS_ISA else "kd"])) / 10
        flags = {"direct": "direct_acting", "invert": "invert_output",
                 "d_on_pv": "derivative_on_pv", "db_sub": "deadband_subtract",
                 "arw_hold": "arw_hold", "d_filt": "derivative_filter"}
        return {
            "isa": 1.0 if self.IS_ISA else 0.0,
            "native": 1.0 if native else 0.0,
            "period": max(words[3] * 100.0, MIN_PERIOD_TICKS),
            "db_pos": db_pos, "db_neg": db_neg,
            "g6": g6, "g7": g7, "g8": g8,
            "bias": bias, "upper": upper, "lower": lower, "slew": slew,
            **{key: 1.0 if bits[flag] else 0.0 for key, flag in flags.items()},
            "tf": tf,
            "units": units, "unit_mul": unit_mul, "unit_div": unit_div,
            "quant": 1.0 if quant else 0.0,
            "floor": 1.0 if prm["rounding"] == "floor" else 0.0,
            "staged": 1.0 if prm.get("isa_division") == "staged" else 0.0,
            "ovr_sppv": 1.0 if prm["override_sp_pv"] else 0.0,
            "track_cv": 1.0 if prm["manual_tracking"] == "cv" else 0.0,
            "last0": math.floor(float(prm["initial_last_solution"]) * TICKS_PER_S + 0.5),
            "load_clock": 1.0 if prm["load_clock_at_start"] else 0.0,
            "param_err": 1.0 if problem else 0.0,
            "ignore_status": 1.0 if prm["bad_input"] == "ignore_status" else 0.0,
            "slew_carry": 1.0 if prm["slew_remainder"] else 0.0,
            "sat_sum": 1.0 if prm["saturate_sum"] else 0.0,
            "prime_d": 1.0 if prm["prime_derivative"] else 0.0,
        }

    def initial_state(self) -> list[float]:
        """A fresh reference array: internal words 0, words 24-26 = initial_last_solution;
        except that the output words start at the start value (:meth:`start_output`)."""
        x = [0.0] * self.n_x
        x[X.last_solution] = self.p[P.last0]
        out = self.start_output()
        cv = -out if self.p[P.invert] != 0.0 else out
        x[X.output] = out
        x[X.cv] = cv
        x[X.internal_cv] = cv
        x[X.manual_command] = cv if self.p[P.track_cv] != 0.0 else out
        return x

    def start_output(self) -> float:
        """Word 19 before the first solution: the Bias limited to the clamps, the output a
        first solution gives at zero error with the empty integral (issue 11 point 8); 0 (the
        fresh array) when the clamps are a parameter error, as the block never solves then."""
        if self.p[P.param_err] != 0.0:
            return 0.0
        return float(min(max(self.p[P.bias], self.p[P.lower]), self.p[P.upper]))

    def initial_outputs(self) -> list[float]:
        """CV and word 19 at their start values, ok = 0 (the block has not run)."""
        return [float(self.x[X.cv]), float(self.x[X.output]), 0.0]

    def parameter_words(self) -> dict[int, int]:
        """The user words 3-13 of the reference array this block runs with (spec 1.2)."""
        return dict(self._words)

    def stored_params(self) -> dict[str, Any]:
        """The parameters as the words hold them (:func:`word_params` of
        :meth:`parameter_words`): Kp 4.505 runs as word 6 = 451, 4.51."""
        w = self._words

        def signed(n: int) -> int:
            x = w[n] & 0xFFFF
            return x - 65536 if x >= 32768 else x

        return word_params(self.kind, signed, lambda n: w[n] & 0xFFFF)


@register
class GEPIDIndependent(GEPIDBlock):
    """GE PACSystems PID_IND: independent (parallel) PID in 16-bit counts."""

    kind = "ge.pid_ind"
    summary = "GE PACSystems PID_IND (independent form, 16-bit counts, spec 1)"
    LAW_PARAMS: ClassVar[tuple[str, ...]] = ("kp", "ki", "kd", *GEPIDBlock.LAW_PARAMS)
    PARAMS: ClassVar[tuple[Param, ...]] = (
        Param("kp", 1.0, "CV counts/PV count", "Kp (word 6, 0.01 steps): P = Kp·e, spec "
              "1.2/1.5", lo=0.0, hi=_GAIN_MAX, lo_open=False, hi_open=False),
        Param("ki", 0.0, "repeats/s", "Ki (word 8, 0.001 repeats/s steps): integral "
              "increment Ki·e·dt, spec 1.2/1.5", lo=0.0, hi=32.767, lo_open=False,
              hi_open=False),
        Param("kd", 0.0, "s", "Kd (word 7, 0.01 s steps): D = Kd·Δ/dt, spec 1.2/1.5", lo=0.0,
              hi=_GAIN_MAX, lo_open=False, hi_open=False),
        *_common_params(),
    )

    def _gains(self, native: bool) -> tuple[float, float, float, dict[int, int]]:
        prm = self.params
        kp, ki, kd = float(prm["kp"]), float(prm["ki"]), float(prm["kd"])
        words = {6: self._nonzero_word("kp", kp, 100.0, "0.01"),
                 7: self._nonzero_word("kd", kd, 100.0, "0.01 s"),
                 8: self._nonzero_word("ki", ki, 1000.0, "0.001 repeats/s")}
        if native:
            return float(words[6]), float(words[7]), float(words[8]), words
        return kp, kd, ki, words


_TI_MIN = 1000.0 / 32767.5  # word 8 = 1000/Ti must round to at most 32767: Ti > this


@register
class GEPIDISA(GEPIDBlock):
    """GE PACSystems PID_ISA: ISA (standard) PID, Kc outside the bracket, 16-bit counts."""

    kind = "ge.pid_isa"
    summary = "GE PACSystems PID_ISA (ISA form, 16-bit counts, spec 1)"
    IS_ISA: ClassVar[bool] = True
    LAW_PARAMS: ClassVar[tuple[str, ...]] = ("kc", "ti", "td", *GEPIDBlock.LAW_PARAMS)
    PARAMS: ClassVar[tuple[Param, ...]] = (
        Param("kc", 1.0, "CV counts/PV count", "Kc (word 6, 0.01 steps), multiplies P, I and "
              "D, spec 1.2/1.6", lo=0.0, hi=_GAIN_MAX, lo_open=False, hi_open=False),
        Param("ti", math.inf, "s", "Ti: word 8 holds 1/Ti in 0.001 repeats/s, Ti = 1000/word8 "
              "(at most 2000 s); inf = no integral, spec 1.2", lo=_TI_MIN, lo_open=True,
              hi_open=False),
        Param("td", 0.0, "s", "Td (word 7, 0.01 s steps): derivative time, D = Kc·Td·Δ/dt, "
              "spec 1.2/1.6", lo=0.0, hi=_GAIN_MAX, lo_open=False, hi_open=False),
        *_common_params(),
        Param("isa_division", "combined", "", "integer division points of the ISA terms: "
              "combined (one division per term) or staged, [?] spec 1.5", "choice",
              choices=("combined", "staged")),
    )

    def _gains(self, native: bool) -> tuple[float, float, float, dict[int, int]]:
        prm = self.params
        kc, ti, td = float(prm["kc"]), float(prm["ti"]), float(prm["td"])
        w8 = 0 if ti == math.inf else _word_of(1000.0 / ti, 1.0)
        if ti != math.inf and w8 == 0 and native:
            raise self._fail(f"parameter 'ti' = {ti:g} s is out of range: word 8 = 1000/ti "
                             "would round to 0 (no integral); allowed "
                             f"({_TI_MIN:.6g}, 2000] s or inf")
        words = {6: self._nonzero_word("kc", kc, 100.0, "0.01"),
                 7: self._nonzero_word("td", td, 100.0, "0.01 s"), 8: w8}
        if native:
            return float(words[6]), float(words[7]), float(words[8]), words
        return kc, kc * td, (kc / ti if ti != math.inf else 0.0), words


# ----------------------------------------------------------------------------------------------
# The raw reference array
# ----------------------------------------------------------------------------------------------
def from_reference_array(words: Sequence[int], kind: str | None = None,
                         **options: Any) -> Block:
    """A block from a raw 40-word reference array (``words[0]`` is word 1), spec 1.2/1.5.

    The user words 3-13 become the parameters with the raw scalings: word 3·0.01 s, words 4/5
    and 9-11 in counts, word 6/100, word 7/100 s, word 8/1000 repeats/s (IND) or Ti = 1000/word8
    s (ISA; 0 = no integral), word 12 s, word 13 the Config Word. Words 3, 12 and 13 are read
    unsigned, the others as signed 16-bit. ``kind`` defaults from word 2 (1 = ISA, 2 = IND);
    when given, a word 2 of 1 or 2 must agree with it. Words 14-40 are the block's internal
    state, whose encoding the spec does not give: they are not loaded. ``options`` are further
    parameters (``arithmetic``, ``on_parameter_error``, ...).
    """
    if len(words) != 40:
        raise ParameterError(f"reference array: expected 40 words, got {len(words)}")
    raw: list[int] = []
    for n, w in enumerate(words, start=1):
        if isinstance(w, bool) or not float(w).is_integer() or not -32768 <= w <= 65535:
            raise ParameterError(f"reference array: word {n} = {w!r} is not a 16-bit word "
                                 "(integer -32768..65535)")
        raw.append(int(w))

    def signed(n: int) -> int:
        w = raw[n - 1] & 0xFFFF
        return w - 65536 if w >= 32768 else w

    def unsigned(n: int) -> int:
        return raw[n - 1] & 0xFFFF

    algorithm = signed(2)
    by_word = {1: "ge.pid_isa", 2: "ge.pid_ind"}
    if kind is None:
        if algorithm not in by_word:
            raise ParameterError(f"reference array: word 2 (algorithm) = {algorithm} does not "
                                 "say 1 = ISA or 2 = IND; give kind='ge.pid_ind' or 'ge.pid_isa'")
        kind = by_word[algorithm]
    kind = kind.lower()
    if kind not in by_word.values():
        raise ParameterError(f"reference array: kind '{kind}' is not ge.pid_ind or ge.pid_isa")
    if algorithm in by_word and by_word[algorithm] != kind:
        raise ParameterError(f"reference array: word 2 = {algorithm} says {by_word[algorithm]}, "
                             f"not {kind}")
    params = word_params(kind, signed, unsigned)
    params.update(options)
    cls: type[GEPIDBlock] = GEPIDIndependent if kind == "ge.pid_ind" else GEPIDISA
    return cls(**params)


def word_params(kind: str, signed: Callable[[int], int], unsigned: Callable[[int], int]
                ) -> dict[str, Any]:
    """The parameters user words 3-13 hold (``signed(n)``, ``unsigned(n)``: word n read so),
    with the raw scalings of :func:`from_reference_array` (spec 1.2/1.5)."""
    params: dict[str, Any] = {
        "sample_period": unsigned(3) / 100.0,
        "deadband_pos": float(signed(4)),
        "deadband_neg": float(signed(5)),
        "bias": float(signed(9)),
        "upper_clamp": float(signed(10)),
        "lower_clamp": float(signed(11)),
        "min_slew_time": float(unsigned(12)),
        "config_word": unsigned(13),
    }
    if kind == "ge.pid_ind":
        params.update(kp=signed(6) / 100.0, kd=signed(7) / 100.0, ki=signed(8) / 1000.0)
    else:
        w8 = signed(8)
        if w8 < 0:
            raise ParameterError(f"reference array: word 8 (1/Ti) = {w8} is out of range: "
                                 "allowed 0..32767 (0 = no integral)")
        params.update(kc=signed(6) / 100.0, td=signed(7) / 100.0,
                      ti=math.inf if w8 == 0 else 1000.0 / w8)
    return params
