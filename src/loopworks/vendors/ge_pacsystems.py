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
  clock at the first sweep instead, as the vendor's SVC_REQ 16/51 remedy does. The other
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
  is clamped [third-party source only, spec 1.3 / 8].
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
from collections.abc import Sequence
from typing import Any, ClassVar

from loopworks.blocks.block import Block
from loopworks.blocks.kernel import FloatArray, IntArray, primitive
from loopworks.blocks.params import Param, Port
from loopworks.blocks.primitives import clamp, finite, lag_step
from loopworks.blocks.registry import block_class, register
from loopworks.blocks.status import BAD, GOOD_NC
from loopworks.errors import ParameterError

# Coefficient layout (p)
(ISA, NATIVE, PERIOD, DB_POS, DB_NEG, G6, G7, G8, BIAS, UPPER, LOWER, SLEW, DIRECT, INVERT,
 D_ON_PV, DB_SUB, ARW_HOLD, D_FILT, TF, UNITS, UNIT_MUL, UNIT_DIV, QUANT, FLOOR, STAGED,
 OVR_SPPV, TRACK_CV, LAST0, LOAD_CLOCK, PARAM_ERR, IGNORE_STATUS, SLEW_CARRY, SAT_SUM,
 PRIME_D) = range(34)
N_COEFFS = 34
# Inputs (u, us)
SP, PV, MAN, UP, DN, ENABLE, CLOCK, MANUAL_COMMAND, CONTROL_WORD, INTERNAL_SP, INTERNAL_PV = \
    range(11)
# Outputs (y, ys)
CV, OUTPUT, OK = range(3)
# State (x), named after the reference-array words they hold
(W14, W15, W16, W17, W18, W19, W20, W21, W27, W23, W24, S_CLOCK, S_DF, S_STARTED, S_CV,
 S_SOLVED) = range(16)

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
    y[CV] = x[S_CV]
    y[OUTPUT] = x[W19]
    y[OK] = ok


def ge_pid_kernel(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                  y: FloatArray, ys: IntArray) -> None:
    """One PLC sweep of the GE PID (spec 1.7; equations in the module docstring)."""
    ys[CV] = GOOD_NC
    ys[OUTPUT] = GOOD_NC
    ys[OK] = GOOD_NC
    native = p[NATIVE]
    floor_mode = p[FLOOR]
    # Writes of the program / HMI into the array (every sweep, before the block runs). A value
    # that is not a 16-bit word (NaN: no write; inf, out of range) never reaches the array.
    if _is_word(u[MANUAL_COMMAND], WORD_MIN, WORD_MAX, native):
        x[W14] = _word(u[MANUAL_COMMAND], native)
    if _is_word(u[CONTROL_WORD], WORD_MIN, 65535.0, 1.0):
        cw = _round_away(u[CONTROL_WORD])
        x[W15] = cw + 65536.0 if cw < 0.0 else cw
    if _is_word(u[INTERNAL_SP], WORD_MIN, WORD_MAX, native):
        x[W16] = _word(u[INTERNAL_SP], native)
    if _is_word(u[INTERNAL_PV], WORD_MIN, WORD_MAX, native):
        x[W18] = _word(u[INTERNAL_PV], native)
    # The controller clock (spec 1.7 step 3): the clock input, else the block's own clock.
    clock = u[CLOCK]
    clock = clamp(clock, 0.0, CLOCK_MAX_S) if finite(clock) else min(x[S_CLOCK] + dt,
                                                                     CLOCK_MAX_S)
    x[S_CLOCK] = clock
    now = float(math.floor(clock * TICKS_PER_S + 0.5))
    if x[S_STARTED] == 0.0:
        x[S_STARTED] = 1.0
        if p[LOAD_CLOCK] != 0.0:  # SVC_REQ 16/51 before enabling: no first-solution step
            x[W24] = now
    # 1. power flow; 2. parameter check (spec 1.7)
    enabled = u[ENABLE] > 0.5
    if not enabled or p[PARAM_ERR] != 0.0:
        _hold(x, y, 0.0)
        return
    # 3. timing: solve only when max(sample period, 10 ms) has elapsed
    elapsed = now - x[W24]
    if elapsed < p[PERIOD]:
        _hold(x, y, 1.0)
        return
    dt_ticks = elapsed
    # 4. inputs: MAN/UP/DN from the operands, or from word 15 under Override (spec 1.4)
    override = _bit(x[W15], 1.0)
    if override:
        man = _bit(x[W15], 2.0)
        up = _bit(x[W15], 8.0)
        dn = _bit(x[W15], 16.0)
    else:
        if not (finite(u[MAN]) and finite(u[UP]) and finite(u[DN])):  # no BOOL: Bad input
            _hold(x, y, 0.0)
            return
        man = u[MAN] > 0.5
        up = u[UP] > 0.5
        dn = u[DN] > 0.5
    if override and p[OVR_SPPV] != 0.0:
        sp = x[W16]
        pv = x[W18]
    else:
        sp = u[SP]
        pv = u[PV]
        # an SP or PV that is no INT operand (NaN, inf, beyond 16 bits) is Bad input
        bad = (not _is_word(sp, WORD_MIN, WORD_MAX, native)
               or not _is_word(pv, WORD_MIN, WORD_MAX, native))
        if p[IGNORE_STATUS] == 0.0 and ((us[SP] & 0xC0) == BAD or (us[PV] & 0xC0) == BAD):
            bad = True
        if bad:  # [A] skip the solution as if unpowered
            _hold(x, y, 0.0)
            return
        sp = _word(sp, native)
        pv = _word(pv, native)
    x[W24] = now
    if not override:
        x[W16] = sp
        x[W18] = pv
        x[W15] = ((2.0 if man else 0.0) + 4.0 + (8.0 if up else 0.0)
                  + (16.0 if dn else 0.0))
    # 5. error and 6. dead band
    e = pv - sp if p[DIRECT] != 0.0 else sp - pv
    db_pos = p[DB_POS]
    db_neg = p[DB_NEG]
    if db_neg < e and e < db_pos:
        e_db = 0.0
    elif p[DB_SUB] == 0.0:
        e_db = e
    elif e >= db_pos:
        e_db = e - db_pos
    else:
        e_db = e - db_neg
    # 7. derivative change (seed 003 table); word 20 keeps the previous error or PV. A fresh
    # array holds 0 there; prime_derivative loads it at the first solution (no kick).
    if x[S_SOLVED] == 0.0 and p[PRIME_D] != 0.0:
        x[W20] = pv if p[D_ON_PV] != 0.0 else e
    x[S_SOLVED] = 1.0
    if p[D_ON_PV] != 0.0:
        delta = pv - x[W20] if p[DIRECT] != 0.0 else x[W20] - pv
        x[W20] = pv
    else:
        delta = e - x[W20]
        x[W20] = e
    # 8. terms
    units = p[UNITS]  # integral units per count (1 in float arithmetic)
    if native != 0.0:  # ΔI in units = numerator·UNIT_MUL/UNIT_DIV
        pterm = _div(p[G6] * e_db, 100.0, floor_mode)
        if p[ISA] == 0.0:
            inc = p[G8] * e_db * dt_ticks / p[UNIT_DIV]
            draw = _div(p[G7] * delta * 100.0, dt_ticks, floor_mode)
        elif p[STAGED] == 0.0:
            inc = p[G6] * p[G8] * e_db * dt_ticks / p[UNIT_DIV]
            draw = _div(p[G6] * p[G7] * delta, dt_ticks, floor_mode)
        else:  # bracket term first (e·dt/Ti, Td·Δ/dt), then Kc
            inner = p[G8] * e_db * dt_ticks * p[UNIT_MUL] / p[UNIT_DIV]
            if p[QUANT] != 0.0:
                inner = _round_away(inner)
            inc = p[G6] * inner / 100.0
            draw = _div(p[G6] * _div(p[G7] * delta * 100.0, dt_ticks, floor_mode), 100.0,
                        floor_mode)
        if p[QUANT] != 0.0:  # ΔI to the nearest unit of integral_resolution
            inc = _round_away(inc)
    else:
        dt_s = dt_ticks / TICKS_PER_S
        pterm = p[G6] * e_db
        inc = p[G8] * e_db * dt_s
        draw = p[G7] * delta / dt_s
    if p[D_FILT] != 0.0:
        x[S_DF] = lag_step(x[S_DF], draw, dt_ticks / TICKS_PER_S, p[TF])
        dterm = _div(x[S_DF], 1.0, floor_mode) if native != 0.0 else x[S_DF]
    else:
        dterm = draw
    bias = p[BIAS]
    imax = INT32_MAX * units
    total_prev = x[W21] * units + x[W27]
    # 9. mode
    if man:
        target = x[W14]
        if up:
            target += 1.0
        if dn:
            target -= 1.0
        target = clamp(target, WORD_MIN, WORD_MAX)
        x[W14] = target
        total = clamp(target - pterm - dterm - bias, -INT32_MAX, INT32_MAX) * units
    else:
        total = clamp(total_prev + inc, -imax, imax)
    icounts = _div(total, units, floor_mode) if native != 0.0 else total  # whole counts
    out = pterm + icounts + dterm + bias
    if p[SAT_SUM] != 0.0:
        out = clamp(out, WORD_MIN, WORD_MAX)
    # 10. slew limit; the integral follows the limited output
    prev = x[W19]
    if p[SLEW] > 0.0:
        if native != 0.0:
            allow_num = 32000.0 * dt_ticks + x[W23]
            den = p[SLEW] * TICKS_PER_S
            step = _div(allow_num, den, 0.0)
        else:
            step = 32000.0 * (dt_ticks / TICKS_PER_S) / p[SLEW]
            allow_num = 0.0
            den = 1.0
        if out > prev + step or out < prev - step:
            out = prev + step if out > prev else prev - step
            if native != 0.0 and p[SLEW_CARRY] != 0.0:
                x[W23] = allow_num - step * den
            total = clamp(out - pterm - dterm - bias, -INT32_MAX, INT32_MAX) * units
        else:
            x[W23] = 0.0
    # 11. clamps and anti-windup (Config bit 4)
    if out > p[UPPER] or out < p[LOWER]:
        out = p[UPPER] if out > p[UPPER] else p[LOWER]
        if p[ARW_HOLD] != 0.0:
            total = total_prev
        else:
            total = clamp(out - pterm - dterm - bias, -INT32_MAX, INT32_MAX) * units
    # store the integral as words 21-22 (whole counts) and 27 (remainder)
    if native != 0.0:
        whole = _div(total, units, floor_mode)
        x[W21] = whole
        x[W27] = total - whole * units
    else:
        x[W21] = total
        x[W27] = 0.0
    # 12. word 19 and polarity; 13. Manual Command tracking; 14. ok
    cv = -out if p[INVERT] != 0.0 else out
    x[W19] = out
    x[S_CV] = cv
    if not override:
        x[W17] = cv
    if not man:
        x[W14] = cv if p[TRACK_CV] != 0.0 else out
    y[CV] = cv
    y[OUTPUT] = out
    y[OK] = 1.0


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
        Param("load_clock_at_start", False, "", "load the clock into words 24-26 at the first "
              "sweep (the SVC_REQ 16/51 remedy), spec 1.2/1.7", "bool"),
        Param("on_parameter_error", "raise", "", "bad dead band or clamps: raise, or ok_off "
              "(the PLC: ok = 0 and CV frozen every sweep), spec 1.7 step 2", "choice",
              choices=("raise", "ok_off")),
        Param("bad_input", "hold", "", "NaN/inf/beyond 16 bits or Bad-status sp/pv: hold "
              "(skip the solution, ok = 0) or ignore_status (use a finite word whatever its "
              "status), [A] spec silent", "choice", choices=("hold", "ignore_status")),
        Param("prime_derivative", False, "", "load word 20 (diff term storage) from the first "
              "solution's PV (or error) so the first derivative sees no change; off: word 20 "
              "starts at 0 (a fresh array) and the first solution kicks, spec 1.2/1.7", "bool"),
    )


_GAIN_MAX = 327.67
_INPUTS: tuple[Port, ...] = (
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
_OUTPUTS: tuple[Port, ...] = (
    Port("cv", 0.0, "counts", "CV: the output after polarity (spec 1.1)"),
    Port("output", 0.0, "counts", "word 19: the output before the polarity inversion "
         "(spec 1.2)"),
    Port("ok", 0.0, "", "ok power flow out: 1 = executed without a parameter error "
         "(spec 1.1)"),
)
_STATES: tuple[str, ...] = (
    "manual_command", "control_word", "internal_sp", "internal_cv", "internal_pv", "output",
    "diff_storage", "integral", "int_remainder", "slew_storage", "last_solution", "clock",
    "d_filter", "started", "cv", "solved")


def _word_of(value: float, scale: float) -> int:
    """The raw word of an engineering value: value·scale rounded half away from zero."""
    return int(math.copysign(math.floor(abs(value) * scale + 0.5), value))


class GEPIDBlock(Block):
    """Shared machinery of PID_IND and PID_ISA (one kernel, ``p[ISA]`` selects the maths)."""

    kernel = staticmethod(ge_pid_kernel)
    INPUTS: ClassVar[tuple[Port, ...]] = _INPUTS
    OUTPUTS: ClassVar[tuple[Port, ...]] = _OUTPUTS
    STATES: ClassVar[tuple[str, ...]] = _STATES
    IS_ISA: ClassVar[bool] = False

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

    def config_bits(self) -> dict[str, bool]:
        """The Config Word (word 13) bits by flag name."""
        prm = self.params
        if prm["config_word"] is not None:
            cw = int(prm["config_word"])
            given = set(self.given) & set(CONFIG_FLAGS)
            if given:
                raise self._fail(f"give either 'config_word' or the flags, not both: "
                                 f"'config_word' = {cw} and '{sorted(given)[0]}' were given")
            return {name: bool(cw >> bit & 1) for bit, name in enumerate(CONFIG_FLAGS)}
        return {name: bool(prm[name]) for name in CONFIG_FLAGS}

    def coefficients(self) -> list[float]:
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
        else:
            db_pos, db_neg = float(prm["deadband_pos"]), float(prm["deadband_neg"])
            bias, upper, lower = (float(prm["bias"]), float(prm["upper_clamp"]),
                                  float(prm["lower_clamp"]))
        # the PLC's own parameter check (spec 1.7 step 2)
        problem = ""
        if not (db_pos == 0.0 and db_neg == 0.0) and not (db_pos > 0.0 and db_neg < 0.0):
            problem = (f"parameters 'deadband_pos' = {db_pos:g} and 'deadband_neg' = "
                       f"{db_neg:g} are not allowed: both must be 0, or deadband_pos > 0 and "
                       "deadband_neg < 0 (spec 1.7 step 2)")
        elif not upper > lower:
            problem = (f"parameter 'upper_clamp' = {upper:g} must be greater than "
                       f"'lower_clamp' = {lower:g} (spec 1.7 step 2)")
        if problem and prm["on_parameter_error"] == "raise":
            raise self._fail(problem + "; on_parameter_error = 'ok_off' gives the PLC's "
                             "ok = 0 instead")
        # Integral units: 1/integral_resolution per count; for the exact carry the natural
        # denominators of ΔI (10^-7 count for IND, 10^-9 for ISA), so that every ΔI is a whole
        # number of units. ΔI [units] = numerator·UNIT_MUL/UNIT_DIV, where the numerator over
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
        c = [0.0] * N_COEFFS
        c[ISA] = 1.0 if self.IS_ISA else 0.0
        c[NATIVE] = 1.0 if native else 0.0
        c[PERIOD] = max(words[3] * 100.0, MIN_PERIOD_TICKS)
        c[DB_POS], c[DB_NEG] = db_pos, db_neg
        c[G6], c[G7], c[G8] = g6, g7, g8
        c[BIAS], c[UPPER], c[LOWER], c[SLEW] = bias, upper, lower, slew
        for index, name in ((DIRECT, "direct_acting"), (INVERT, "invert_output"),
                            (D_ON_PV, "derivative_on_pv"), (DB_SUB, "deadband_subtract"),
                            (ARW_HOLD, "arw_hold"), (D_FILT, "derivative_filter")):
            c[index] = 1.0 if bits[name] else 0.0
        c[TF] = tf
        c[UNITS] = units
        c[UNIT_MUL] = unit_mul
        c[UNIT_DIV] = unit_div
        c[QUANT] = 1.0 if quant else 0.0
        c[FLOOR] = 1.0 if prm["rounding"] == "floor" else 0.0
        c[STAGED] = 1.0 if prm.get("isa_division") == "staged" else 0.0
        c[OVR_SPPV] = 1.0 if prm["override_sp_pv"] else 0.0
        c[TRACK_CV] = 1.0 if prm["manual_tracking"] == "cv" else 0.0
        c[LAST0] = math.floor(float(prm["initial_last_solution"]) * TICKS_PER_S + 0.5)
        c[LOAD_CLOCK] = 1.0 if prm["load_clock_at_start"] else 0.0
        c[PARAM_ERR] = 1.0 if problem else 0.0
        c[IGNORE_STATUS] = 1.0 if prm["bad_input"] == "ignore_status" else 0.0
        c[SLEW_CARRY] = 1.0 if prm["slew_remainder"] else 0.0
        c[SAT_SUM] = 1.0 if prm["saturate_sum"] else 0.0
        c[PRIME_D] = 1.0 if prm["prime_derivative"] else 0.0
        return c

    def initial_state(self) -> list[float]:
        """A fresh reference array: internal words 0, words 24-26 = initial_last_solution;
        except that the output words start at the start value (:meth:`start_output`)."""
        x = [0.0] * len(self.STATES)
        x[W24] = self.p[LAST0]
        out = self.start_output()
        cv = -out if self.p[INVERT] != 0.0 else out
        x[W19] = out
        x[S_CV] = cv
        x[W17] = cv
        x[W14] = cv if self.p[TRACK_CV] != 0.0 else out
        return x

    def start_output(self) -> float:
        """Word 19 before the first solution: the Bias limited to the clamps, the output a
        first solution gives at zero error with the empty integral (issue 11 point 8); 0 (the
        fresh array) when the clamps are a parameter error, as the block never solves then."""
        if self.p[PARAM_ERR] != 0.0:
            return 0.0
        return float(min(max(self.p[BIAS], self.p[LOWER]), self.p[UPPER]))

    def initial_outputs(self) -> list[float]:
        """CV and word 19 at their start values, ok = 0 (the block has not run)."""
        return [float(self.x[S_CV]), float(self.x[W19]), 0.0]

    def parameter_words(self) -> dict[int, int]:
        """The user words 3-13 of the reference array this block runs with (spec 1.2)."""
        return dict(self._words)


@register
class GEPIDIndependent(GEPIDBlock):
    """GE PACSystems PID_IND: independent (parallel) PID in 16-bit counts."""

    kind = "ge.pid_ind"
    summary = "GE PACSystems PID_IND (independent form, 16-bit counts, spec 1)"
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


_TI_MIN = 1000.0 / 32767.5  # word 8 = 1000/Ti must round to at most 32767


@register
class GEPIDISA(GEPIDBlock):
    """GE PACSystems PID_ISA: ISA (standard) PID, Kc outside the bracket, 16-bit counts."""

    kind = "ge.pid_isa"
    summary = "GE PACSystems PID_ISA (ISA form, 16-bit counts, spec 1)"
    IS_ISA: ClassVar[bool] = True
    PARAMS: ClassVar[tuple[Param, ...]] = (
        Param("kc", 1.0, "CV counts/PV count", "Kc (word 6, 0.01 steps), multiplies P, I and "
              "D, spec 1.2/1.6", lo=0.0, hi=_GAIN_MAX, lo_open=False, hi_open=False),
        Param("ti", math.inf, "s", "Ti: word 8 holds 1/Ti in 0.001 repeats/s, Ti = 1000/word8 "
              "(at most 2000 s); inf = no integral, spec 1.2", lo=_TI_MIN, lo_open=False,
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
                             f"[{_TI_MIN:.4g}, 2000] s or inf")
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
    params.update(options)
    return block_class(kind)(**params)
