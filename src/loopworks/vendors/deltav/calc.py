r"""The DeltaV CALC block: kind ``deltav.calc``, a block whose behaviour is an expression text.

DeltaV's Calc/Logic block runs a structured-text expression once per module scan
(spec vendor-blocks 6.1; DeltaV Books Online "Expressions" [R49, R50]). This block takes the
text as its ``expression`` parameter and runs it. The default text is the stick-slip
compensator of seed 000, exactly as printed (28 lines, see the end of this page), so

    create_block("deltav.calc")

is the seed's COMPENSATOR (execution #4) and gives bit for bit the outputs of the native
``deltav.stick_slip`` with equal option settings and DITHER_OUT given.

The language subset (tokenizer, parser, compiler: :mod:`loopworks.vendors.deltav.expression`):
``(* comments *)``, ``:=``, ``IF ... THEN ... ELSIF ... ELSE ... END_IF`` (``ENDIF`` too, as the
seed writes it), ``= != <> ~= |= < > <= >=``, ``AND OR NOT``, ``+ - * /``, unary minus,
parentheses, numbers, ``TRUE``/``FALSE``, and module parameter references ``'^/NAME'`` with the
fields ``.CV`` (the value, the default) and ``.ST`` (the status byte). Operator precedence,
tightest first: unary ``- + NOT``; ``* /``; ``+ -``; ``< > <= >=``; ``= !=``; ``AND``; ``OR``.
Anything else (module-relative and external paths, functions, ``MOD``, ``**``, ...) is a
construction error that names its line and column.

Module parameters, ports and parameters
---------------------------------------

Every ``'^/NAME'`` in the text is a module parameter (spec 6.1: ``^/`` is one level up, the
module that contains the CALC block). Its lower-case name is

* an **output** if the expression assigns it anywhere (its value or its .ST). An output keeps
  its value between scans (it is block state: a statement that does not run leaves it as it
  was, like the seed's held KICKER_DELT), and the expression can read it;
* an **input** otherwise: the expression only reads it.

Each module parameter is also a block parameter: its **initial value**, e.g.
``create_block("deltav.calc", cntrl_action=-1, process_gain=2)``. For an output it is the value
before the first scan (default 0). For an input it is the port's default: the value the input
has until it is given (``step(..., sp=50)``, a wire, a replay column).

Which parameters are known (checked at construction, before the first scan). The block runs
in the seed's module, whose parameter table (seed 000, spec 6.2: SIGNAL_IN, SP, PV, DEADBAND,
RESOLUTION, PROCESS_GAIN (2), CNTRL_ACTION (-1), VALVE_ACTION (1), DITHER_AMP, KICKER_OUT,
NOISE_BAND, KICKER_DELT, DITHER_DELT, DITHER_OUT, COMP_START, INITIALIZE, KICK_START and the
three factors (1); defaults 0 unless marked) declares those names with the seed's defaults.
In float32 precision an initial value must round to a finite float32 (below about 3.4e38 in
magnitude), as a stored value must. Any other name the expression **reads** must be assigned
somewhere in the expression, or be
declared by giving it an initial value, as a DeltaV module parameter must exist before an
expression can refer to it. Reading anything else is an error that names the line, the column
and the name, so a misspelt ``'^/SIGNL_IN'`` is caught at construction instead of reading 0 for
ever. An initial value for a name the expression does not reference is a ParameterError that
lists the names it references (RESET_TIME is in the seed's table but not in its expression, so
it is no parameter here). No module parameter may be called like an option of the block
(``expression``, ``precision``, ...) or ``jit``, ``t``, ``dt``, ``kind``, ``self``.

Before the first scan every output shows its initial value, Good (what a block earlier in the
module order reads from it).

In a scenario file every key of the block's table is a parameter (``split_table``), so
``sp = 50.0`` there is SP's initial value, which is what an unwired input then keeps.

Status (``.ST``, spec 6.1: "the status, an integer"): reading ``'^/NAME.ST'`` of an input gives
its status byte (Good non-cascade, 128, unless given: ``step(..., signal_in=(40.0, 0x1C))``;
Bad, 0, while its value is not finite, below); assigning ``'^/NAME.ST'`` sets the status of
output NAME. An output whose .ST the expression never assigns is Good non-cascade (128); an
assigned status holds until assigned again. A value assigned to .ST is made a byte: truncated
toward zero and limited to 0..255, NaN gives 0 (Bad) [A: the vendor text does not say]. Every
output carries a status (it can be Bad, below); inputs whose .ST is read are the inputs listed
with a status (a replay CSV takes ``NAME.ST`` columns for them).

Execution (spec 6.1)
--------------------

Once per scan the statements run top to bottom. Values are floats (float64 arithmetic); a
comparison gives 1 or 0; AND/OR/NOT and IF take any non-zero value as true. Within a statement
NaN and ±inf follow IEEE 754: arithmetic propagates them, ``= < > <= >=`` with a NaN are false
(so 0), ``!=`` is true, and a NaN condition counts as true (non-zero). Division by zero gives
±3.402823466e+38 as DeltaV documents (first operand < 0: minus; otherwise plus) [V: DeltaV
Books Online, Expressions > Syntax rules > Operators, deltav-books-online.dev.platform-apps.io/
gen_config/html/r_operators.html; not in the spec]; NaN/0 stays NaN [A]. The kernel never
raises.

Non-finite values (issue 11 point 1; the reading of the DeltaV rule that a CALC writes the
Bad status on an output it cannot compute [A]):

* an input whose value is NaN or ±inf, or beyond the float32 range in float32 precision
  (``1e308`` reads as ±inf there), is Bad input: the expression reads its value as it is (IEEE,
  above) and its .ST as Bad (0), unless its status is Bad already (then its substatus is kept).
  So the seed's line 28 passes a Bad status on: a NaN SIGNAL_IN arriving Good gives a Bad
  SIGNAL_OUT;
* an assignment whose result is not finite (after the float32 rounding of the store in that
  precision: a result beyond the float32 range is one) does not store it: the module parameter
  keeps its last value and is **held** for the rest of the scan: its status is Bad (0; a Bad
  .ST the expression assigned keeps its substatus) whatever Good .ST the expression assigns,
  and reading its .ST gives that Bad status, unless a later assignment of the scan stores a
  finite value. A later scan that does not assign it shows its .ST again, with the last value
  stored, as for any parameter a scan leaves alone (the seed's held KICKER_DELT).

So no output is ever non-finite, no state is ever non-finite, and the block recovers as soon
as its inputs are good again. In the seed: a NaN or infinite SIGNAL_IN holds SIGNAL_OUT at its
last value, Bad; an infinite PV is above the trigger (line 15 kicks, SIGNAL_OUT stays Good); an
infinite DITHER_OUT holds DITHER_DELT at its last value, Bad, while SIGNAL_OUT adds the held
value and keeps SIGNAL_IN's status.

With ``precision = "float32"`` (default) a module parameter holds a 32-bit float: every value
the expression assigns is rounded to float32 as it is stored, and every module parameter the
expression reads is its float32 value: an output as stored, an input (a module parameter that
someone else writes) rounded when read, so ``pv = 50.3000001`` reads as 50.29999924. The initial
values of outputs are rounded too. Intermediate results within a statement are float64 and
literals are read as float64 (``0.5``, ``0.0`` and ``1`` are exact either way).
``precision = "float64"`` stores and reads float64 values unchanged.

With ``deferred_param_reads = false`` (default, spec 6.1 [A]) a write is seen at once by later
statements of the same scan. With ``true`` every read of a module parameter the expression
writes sees its value at the start of the scan (the cached-reference reading of spec 6.1); the
writes still all happen, and the last one is the parameter's new value. For the seed this
moves every line that reads a parameter the text writes one scan late, not only the two the
spec names: line 8 (NOISE_BAND from last scan's DITHER_AMP), lines 15/19 (last scan's
NOISE_BAND), lines 16/20 (last scan's KICKER_OUT) and line 26 (SIGNAL_OUT from last scan's
KICKER_DELT and DITHER_DELT), as ``deltav.stick_slip`` does.

The kernel is a small stack machine: the text is compiled (at construction) into a flat
program of (opcode, argument) pairs stored in the coefficient array ``p`` (``code``, after a
header: ``precision, deferred, div_ieee, n_out, stack, code_len``), and each scan interprets it
on a value stack sized for the program. Jumps implement IF/ELSIF/ELSE. Outputs live in the
state array (values, then statuses), so they persist between scans and resume from
``state_dict``.
One compiled kernel serves every text (a compiled block steps through the kernel's standard
entry point rather than a wrapper specialised to its array sizes, so a new text costs no numba
compilation); the interpreted and compiled runs are bit-identical.

Options for the spec's [A]/[?] points
-------------------------------------

* ``precision``: ``float32`` (default; spec 6.1 [A]: "module parameters are 32-bit floats")
  or ``float64``.
* ``deferred_param_reads``: ``false`` (default; spec 6.1 [A]: immediate writes, because the
  compensator uses direct ``'^/'`` paths) or ``true`` (reads see the value at the start of the
  scan).
* ``divide_by_zero``: ``deltav`` (default: ±3.402823466e+38 as the DeltaV operator reference
  states; not in the spec) or ``ieee`` (±inf, NaN for 0/0: a result that is then assigned
  holds its parameter, Bad, as any non-finite result does).

The band factors of the native ``deltav.stick_slip`` (``upper_band_factor`` 0.5,
``lower_band_factor`` 1.0, spec 6.4 [A]) are no options here: they are the literals of seed
lines 15 and 19, so a variant is an edited text (``'^/NOISE_BAND'*1.0`` on line 15).

Vendor quirks reproduced (all from the text itself, spec 6.3-6.7)
-----------------------------------------------------------------

The seed's asymmetric band (PV > SP + NB·0.5 kicks down, PV < SP - NB kicks up), the kick held
while PV is inside the band and while COMP_START = 0, DITHER_DELT zeroed in the kick branches,
the exact float ``= 1`` tests on INITIALIZE and KICK_START, no clamp on SIGNAL_OUT, SIGNAL_OUT.ST
= SIGNAL_IN.ST on every scan, and the EU-versus-% comparison of PV with NOISE_BAND: the block
runs the text, so nothing is "fixed".

Example
-------

Python (spec 6.8, scans 1 and 3: DITHER_OUT is the SGGN1 sample, here given)::

    import loopworks
    comp = loopworks.create_block("deltav.calc", resolution=0.5, deadband=0.2,
                                  sp=50.0, signal_in=40.0, comp_start=1)
    comp.step(1.0, pv=50.0, dither_out=0.3)["signal_out"].value   # 39.70000076293945
    comp.step(1.0, pv=50.5, dither_out=0.3)["signal_out"].value   # 39.70000076293945
    # band (dither -0.3), then high (kick -0.3): 39.7 as float32; precision="float64" gives 39.7

A text of your own (inputs are declared by their initial values)::

    ratio = loopworks.create_block(
        "deltav.calc",
        expression="'^/OUT' := '^/A' / '^/B'; '^/OUT.ST' := '^/A.ST';",
        a=0.0, b=1.0)
    ratio.step(1.0, a=6.0, b=3.0)["out"].value                   # 2.0
    ratio.step(1.0, b=0.0)["out"].value                          # 3.4028234663852886e+38

The seed's module: SGGN1 (#3) makes DITHER_OUT from the DITHER_AMP of the previous scan, then
the CALC (#4) runs the text::

    from loopworks import Module, create_block
    m = Module({"sggn1": create_block("deltav.sggn", period=2.0),
                "comp": create_block("deltav.calc", resolution=0.5, deadband=0.2,
                                     comp_start=1, sp=50.0, pv=50.0, signal_in=40.0)},
               wires={"sggn1.amplitude": "comp.dither_amp", "comp.dither_out": "sggn1.out"})
    m.run(10.0, 1.0)["comp.signal_out"]

Replay (``comp.csv``; every parameter, the expression too, can be given with ``-p``)::

    t,pv,dither_out,signal_in,signal_in.ST
    0,50.0,0.3,40.0,128
    1,50.0,-0.3,40.0,128
    2,50.5,0.3,40.0,28

    loopworks replay deltav.calc comp.csv -p resolution=0.5 -p deadband=0.2 -p sp=50 \
        -p comp_start=1 -p precision=float64

gives ``signal_out`` 39.7, 40.3, 39.7 (band, band, high) and ``signal_out.ST`` 128, 128, 28.

The seed's expression (the default of ``expression``)
-----------------------------------------------------

::

    (* COMPUTE DITHER AND KICK AMPLITUDES *)
    '^/DITHER_AMP' := ('^/RESOLUTION' + 0.5*'^/DEADBAND')*'^/DITHER_FACTOR'*0.5;
    '^/KICKER_OUT' := ('^/RESOLUTION' + 0.5*'^/DEADBAND')*'^/KICKER_FACTOR'*0.5;
    (* NOISE BAND *)
    IF ('^/INITIALIZE' = 1 AND '^/KICK_START' = 1 ) THEN
    '^/NOISE_BAND' := 0.0
    ELSE
    '^/NOISE_BAND' := '^/DITHER_AMP'*'^/PROCESS_GAIN'*'^/NOISE_FACTOR';
    ENDIF;
    (* IF LOOP IS IN MANUAL, PASS THROUGH PID OUTPUT WITHOUT COMPENSATION *)
    IF ('^/COMP_START' = 0) THEN
    '^/SIGNAL_OUT' := '^/SIGNAL_IN'
    ELSE
    (* IF OUTSIDE NOISE BAND, KICK THE PV BACK TOWARDS THE SP DITHER OTHERWISE THE OUTPUT *)
      IF ('^/PV' > ('^/SP' + '^/NOISE_BAND'*0.5)) THEN
        '^/KICKER_DELT' := '^/KICKER_OUT'*'^/CNTRL_ACTION'*'^/VALVE_ACTION';
        '^/DITHER_DELT' := 0.0;
      ELSE
        IF ('^/PV' < ('^/SP' - '^/NOISE_BAND')) THEN
          '^/KICKER_DELT' := - '^/KICKER_OUT'*'^/CNTRL_ACTION'*'^/VALVE_ACTION';
          '^/DITHER_DELT' := 0.0;
        ELSE
          '^/DITHER_DELT' := '^/DITHER_OUT'*'^/CNTRL_ACTION'*'^/VALVE_ACTION'
        ENDIF;
      ENDIF;
    '^/SIGNAL_OUT' := '^/SIGNAL_IN' + '^/KICKER_DELT' + '^/DITHER_DELT'
    ENDIF;
    '^/SIGNAL_OUT.ST' := '^/SIGNAL_IN.ST';
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from loopworks.blocks.block import Block
from loopworks.blocks.kernel import FloatArray, IntArray, primitive
from loopworks.blocks.layout import Array, index
from loopworks.blocks.params import Param, Port, validate
from loopworks.blocks.primitives import finite
from loopworks.blocks.registry import register
from loopworks.errors import ParameterError
from loopworks.vendors.deltav.expression import (
    OP_ADD,
    OP_AND,
    OP_CONST,
    OP_DIV,
    OP_EQ,
    OP_GE,
    OP_GT,
    OP_INPUT,
    OP_INPUT_ST,
    OP_JUMP,
    OP_JUMP_IF_FALSE,
    OP_LE,
    OP_LOAD,
    OP_LOAD_ST,
    OP_LT,
    OP_MUL,
    OP_NE,
    OP_NEG,
    OP_NOT,
    OP_OR,
    OP_STORE,
    OP_STORE_ST,
    OP_SUB,
    SEED_EXPRESSION,
    Compiled,
    ExpressionError,
    Program,
    compile_program,
    parse,
)


def _compile(prog: Program) -> Compiled:
    """The stack-machine program of a parsed text: its inputs (the names it only reads) and
    its outputs (the names it assigns) are numbered in the order of their first reference."""
    inputs = [name for name in prog.names if name not in prog.written]
    outputs = [name for name in prog.names if name in prog.written]
    return compile_program(prog, {name: i for i, name in enumerate(inputs)},
                           {name: i for i, name in enumerate(outputs)})


def code_size(prm: Mapping[str, Any]) -> int:
    """The number of floats of the compiled program of the text ``prm["expression"]``."""
    return len(_compile(parse(prm["expression"])).code)


#: the coefficient array p (coefficients()): a header, then the compiled program, whose size
#: follows the text (an instance declares it from the program it compiled, _Layout.coeffs)
HEADER = ("precision", "deferred", "div_ieee", "n_out", "stack", "code_len")
CODE_MEANING = "2 per instruction of the compiled expression: its (opcode, argument) pairs"
COEFFS = (*HEADER, Array("code", code_size, CODE_MEANING))
P = index(COEFFS, "P")

FLOAT32_MAX = 3.4028234663852886e38
"""The largest float32, DeltaV's 3.402823466e+38 (the result of x/0)."""
FLOAT32_OVERFLOW = 3.4028235677973366e38
"""(2 - 2**-24)·2**127: from here on rounding to float32 gives inf (round half to even)."""
GOOD_NC = 128.0


@primitive
def to_float32(v: float) -> float:
    """v rounded to the nearest float32 (half to even), as a float; beyond the float32 range
    it is ±inf, NaN stays NaN."""
    if v >= FLOAT32_OVERFLOW:
        return math.inf
    if v <= -FLOAT32_OVERFLOW:
        return -math.inf
    return float(np.float32(v))


@primitive
def input_status(value: float, status: int) -> int:
    """The status the expression reads for an input whose value reads as ``value`` (after the
    float32 rounding in that precision): a value that is not finite (NaN, ±inf, or beyond the
    float32 range in float32 precision) is Bad input, status 0, unless its status is Bad
    already (then it keeps its substatus)."""
    if not finite(value) and (status & 0xC0) != 0:
        return 0
    return status


@primitive
def shown_status(status: float, held: float) -> int:
    """The status of a written module parameter: its .ST, or Bad (0) when ``held`` (its
    assignment in this scan was not finite, so it kept its value); a Bad .ST keeps its
    substatus."""
    st = int(status)
    if held != 0.0 and (st & 0xC0) != 0:
        return 0
    return st


@primitive
def status_byte(v: float) -> float:
    """A value assigned to a .ST field as a status byte: truncated, limited to 0..255; NaN
    and values <= 0 give 0 (Bad)."""
    if not v > 0.0:
        return 0.0
    if v >= 255.0:
        return 255.0
    return float(math.floor(v))


@primitive
def divide(a: float, b: float, ieee: bool) -> float:
    """a / b. For b = 0: DeltaV's ±3.402823466e+38 (minus when a < 0), or IEEE 754's ±inf
    (NaN for 0/0) when ``ieee``; NaN/0 is NaN either way."""
    if b != 0.0:
        return a / b
    if a != a:
        return a
    if ieee:
        if a == 0.0:
            return math.nan
        if (a < 0.0) != (math.copysign(1.0, b) < 0.0):
            return -math.inf
        return math.inf
    if a < 0.0:
        return -FLOAT32_MAX
    return FLOAT32_MAX


def calc_kernel(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                y: FloatArray, ys: IntArray) -> None:
    """One scan: run the compiled expression (module docstring) on a value stack.

    x holds the values of the written module parameters, then their statuses; ``cur`` is
    their working copy during the scan, ``held`` marks those whose assignment in this scan was
    not finite. Immediate reads see ``cur``; deferred reads see x, the values at the start of
    the scan. A value is stored only when it is finite (module docstring, "Non-finite
    values")."""
    n = int(p[P.n_out])
    f32 = p[P.precision] != 0.0
    deferred = p[P.deferred] != 0.0
    ieee = p[P.div_ieee] != 0.0
    cur = x[:2 * n].copy()
    held = np.zeros(n)
    stack = np.empty(int(p[P.stack]))
    top = 0
    pc = 0
    end = int(p[P.code_len])
    while pc < end:
        op = int(p[P.code + pc])
        arg = p[P.code + pc + 1]
        pc += 2
        if op == OP_CONST:
            stack[top] = arg
            top += 1
        elif op == OP_INPUT or op == OP_INPUT_ST:  # a module parameter written by someone else
            i = int(arg)
            v = float(u[i])
            if f32:
                v = to_float32(v)
            stack[top] = v if op == OP_INPUT else float(input_status(v, int(us[i])))
            top += 1
        elif op == OP_LOAD:
            k = int(arg)
            stack[top] = x[k] if deferred else cur[k]
            top += 1
        elif op == OP_LOAD_ST:
            k = int(arg)
            if deferred:
                stack[top] = x[n + k]
            else:
                stack[top] = float(shown_status(cur[n + k], held[k]))
            top += 1
        elif op == OP_STORE:  # a non-finite result is not stored: the value holds, Bad
            top -= 1
            k = int(arg)
            v = float(stack[top])
            if f32:
                v = to_float32(v)
            if finite(v):
                cur[k] = v
                held[k] = 0.0
            else:
                held[k] = 1.0
        elif op == OP_STORE_ST:
            top -= 1
            cur[n + int(arg)] = status_byte(stack[top])
        elif op == OP_JUMP:
            pc = int(arg)
        elif op == OP_JUMP_IF_FALSE:
            top -= 1
            if stack[top] == 0.0:
                pc = int(arg)
        elif op == OP_NEG:
            stack[top - 1] = -stack[top - 1]
        elif op == OP_NOT:
            stack[top - 1] = 1.0 if stack[top - 1] == 0.0 else 0.0
        else:  # a binary operator: a op b
            top -= 1
            b = float(stack[top])  # Python floats when interpreted: IEEE, without warnings
            a = float(stack[top - 1])
            r = 0.0
            if op == OP_ADD:
                r = a + b
            elif op == OP_SUB:
                r = a - b
            elif op == OP_MUL:
                r = a * b
            elif op == OP_DIV:
                r = divide(a, b, ieee)
            elif op == OP_EQ:
                r = 1.0 if a == b else 0.0
            elif op == OP_NE:
                r = 1.0 if a != b else 0.0
            elif op == OP_LT:
                r = 1.0 if a < b else 0.0
            elif op == OP_GT:
                r = 1.0 if a > b else 0.0
            elif op == OP_LE:
                r = 1.0 if a <= b else 0.0
            elif op == OP_GE:
                r = 1.0 if a >= b else 0.0
            elif op == OP_AND:
                r = 1.0 if (a != 0.0 and b != 0.0) else 0.0
            elif op == OP_OR:
                r = 1.0 if (a != 0.0 or b != 0.0) else 0.0
            stack[top - 1] = r
    for k in range(2 * n):
        x[k] = cur[k]
    for k in range(n):
        y[k] = cur[k]
        ys[k] = shown_status(cur[n + k], held[k])


# The seed's module parameter table (seed 000: "Parameter / Default" and the labels; spec 6.2):
# name -> (default, unit, meaning).
SEED_PARAMETERS: dict[str, tuple[float, str, str]] = {
    "signal_in": (0.0, "%", "PID OUT (%): the PID output feeding the compensator"),
    "signal_out": (0.0, "%", "AO CAS_IN (%): the compensated signal (lines 12, 26)"),
    "sp": (0.0, "eu", "PID set point (eu)"),
    "pv": (0.0, "eu", "PID process variable (eu)"),
    "deadband": (0.0, "%", "Backlash (%): the valve deadband, not a PID dead band"),
    "resolution": (0.0, "%", "Stick-Slip (%): the valve resolution"),
    "process_gain": (2.0, "%/%", "identified process gain"),
    "cntrl_action": (-1.0, "", "controller action: reverse = -1, direct = +1"),
    "valve_action": (1.0, "", "valve action: inc-close = -1, inc-open = +1"),
    "dither_amp": (0.0, "%", "(RESOLUTION + DEADBAND/2)·DITHER_FACTOR/2, the dither "
                   "amplitude (line 2)"),
    "kicker_out": (0.0, "%", "(RESOLUTION + DEADBAND/2)·KICKER_FACTOR/2, the kick "
                   "amplitude (line 3)"),
    "noise_band": (0.0, "%", "DITHER_AMP·PROCESS_GAIN·NOISE_FACTOR (0 while INITIALIZE = "
                   "KICK_START = 1), the PV noise band (lines 5-9)"),
    "kicker_delt": (0.0, "%", "kick currently applied; held inside the band (lines 16, 20)"),
    "dither_delt": (0.0, "%", "dither currently applied (lines 17, 21, 23)"),
    "dither_out": (0.0, "%", "dither waveform sample, the SGGN1 output (spec 6.5)"),
    "comp_start": (0.0, "", "1 = compensate; 0 = pass SIGNAL_IN through (line 11)"),
    "initialize": (0.0, "", "with KICK_START = 1 forces NOISE_BAND = 0 (line 5)"),
    "kick_start": (0.0, "", "1 = kick-start: NOISE_BAND = 0 while INITIALIZE = 1 (line 5)"),
    "noise_factor": (1.0, "", "advanced tuning: scales NOISE_BAND (line 8)"),
    "dither_factor": (1.0, "", "advanced tuning: scales DITHER_AMP (line 2)"),
    "kicker_factor": (1.0, "", "advanced tuning: scales KICKER_OUT (line 3)"),
}

OPTIONS: tuple[Param, ...] = (
    Param("expression", SEED_EXPRESSION, "", "the DeltaV expression text the block runs "
          "(spec 6.1)", "text", default_text="the seed's compensator (end of this page)"),
    Param("precision", "float32", "", "module parameters hold float32 (every stored value is "
          "rounded) or float64 (spec 6.1 [A])", "choice", choices=("float32", "float64")),
    Param("deferred_param_reads", False, "", "reads of written parameters see their value at "
          "the start of the scan (spec 6.1 [A]; default: writes are seen at once)", "bool"),
    Param("divide_by_zero", "deltav", "", "x/0: deltav gives ±3.402823466e+38 (DeltaV operator "
          "reference), ieee gives ±inf or NaN", "choice", choices=("deltav", "ieee")),
)
# "kind" and "self" would collide with create_block's and the constructor's own arguments
_RESERVED = frozenset({p.name for p in OPTIONS} | {"jit", "t", "dt", "kind", "self"})


class _Layout:
    """What a text gives the block: parameters, ports, state names and the program."""

    def __init__(self, prog: Program, given: Mapping[str, Any], kind: str) -> None:
        self.prog = prog
        params: list[Param] = list(OPTIONS)
        labels: dict[str, tuple[str, str]] = {}  # name -> (unit, meaning of the port)
        for name in prog.names:
            output = name in prog.written
            role = ("output: its initial value" if output else
                    "input: its initial value, the input's default")
            if name in SEED_PARAMETERS:
                default, unit, label = SEED_PARAMETERS[name]
                labels[name] = (unit, label)
                params.append(Param(name, default, unit, f"{label} [{role}] (seed 000, spec 6.2)"))
                continue
            labels[name] = ("", f"module parameter {name.upper()}")
            if output:
                params.append(Param(name, 0.0, "", f"module parameter {name.upper()} [{role}]"))
            else:
                params.append(Param(name, None, "", f"module parameter {name.upper()} [{role}]; "
                                    "required: giving it declares the parameter",
                                    default_text="required"))
        self.params = tuple(params)
        values = validate(kind, self.params, dict(given))
        inputs: list[Port] = []
        outputs: list[Port] = []
        for name in prog.names:
            value = values[name]
            default = 0.0 if value is None else float(value)
            unit, label = labels[name]
            if name in prog.written:  # every output can be Bad (a non-finite result)
                outputs.append(Port(name, default, unit, label, status=True))
            else:
                inputs.append(Port(name, default, unit, label, status=name in prog.status_read))
        self.inputs = tuple(inputs)
        self.outputs = tuple(outputs)
        # the output values, then their statuses ("signal_out.st"): the kernel finds them by
        # the program's output numbers, so they are names for state() only, not an index
        self.states = tuple(p.name for p in outputs) + tuple(f"{p.name}.st" for p in outputs)
        self.compiled: Compiled = _compile(prog)
        self.coeffs = (*HEADER, Array("code", len(self.compiled.code), CODE_MEANING))


def _layout(text: Any, given: Mapping[str, Any], kind: str) -> _Layout:
    """Parse and check ``text`` against the given parameters (lower-case names)."""
    if not isinstance(text, str):
        raise ParameterError(f"{kind}: parameter 'expression' = {text!r} must be text")
    try:
        prog = parse(text)
    except ExpressionError as exc:
        raise ExpressionError(exc.line, exc.column, exc.detail, kind) from None
    if not prog.written:
        raise ExpressionError(1, 1, "the expression assigns no module parameter: expected at "
                              "least one assignment '^/NAME' := ...", kind)
    for name in prog.names:
        if name in _RESERVED:
            ref = prog.first_refs[name]
            raise ExpressionError(ref.line, ref.column, f"module parameter {ref.text} has the "
                                  f"name of a {kind} parameter or a reserved name ("
                                  f"{', '.join(sorted(_RESERVED))}); rename it", kind)
    options = {p.name for p in OPTIONS}
    unknown = [k for k in given if k not in options and k not in prog.names]
    if unknown:
        raise ParameterError(
            f"{kind}: unknown parameter '{unknown[0]}': it is neither an option ("
            f"{', '.join(p.name for p in OPTIONS)}) nor a module parameter the expression "
            f"references ({', '.join(prog.names)})")
    for name in prog.read_only:
        if name not in given and name not in SEED_PARAMETERS:
            ref = prog.read_refs[name]
            raise ExpressionError(
                ref.line, ref.column, f"{ref.text} is not a known module parameter: the "
                f"expression reads it but never assigns it, and it has no initial value; "
                f"declare it as an input by giving one (e.g. {name}=0.0)", kind)
    return _Layout(prog, given, kind)


_SEED = _layout(SEED_EXPRESSION, {}, "deltav.calc")


@register
class Calc(Block):
    """DeltaV CALC block running an expression text (default: the seed's compensator)."""

    kind = "deltav.calc"
    summary = ("DeltaV CALC block: runs a DeltaV expression text (default: the seed's "
               "stick-slip compensator)")
    kernel = staticmethod(calc_kernel)
    FIXED_LAYOUT = False  # array sizes differ from text to text: no per-size step wrapper
    FIXED_PARAMS: ClassVar[dict[str, str]] = {
        "expression": "is the block's program (compiled when the block is made)"}

    # The class declarations are the seed's; an instance sets its own from its expression.
    PARAMS: ClassVar[tuple[Param, ...]] = _SEED.params
    INPUTS: ClassVar[tuple[Port, ...]] = _SEED.inputs
    OUTPUTS: ClassVar[tuple[Port, ...]] = _SEED.outputs
    COEFFS: ClassVar[tuple[Any, ...]] = COEFFS
    STATES: ClassVar[tuple[str, ...]] = _SEED.states

    def __init__(self, *, jit: bool | None = None, **params: Any) -> None:
        given = {k.lower(): v for k, v in params.items()}
        layout = _layout(given.get("expression", SEED_EXPRESSION), given, self.kind)
        self.program: Program = layout.prog
        self._layout = layout
        self.__dict__.update(PARAMS=layout.params, INPUTS=layout.inputs,
                             OUTPUTS=layout.outputs, COEFFS=layout.coeffs,
                             STATES=layout.states)
        super().__init__(jit=jit, **params)

    def coefficients(self) -> dict[str, Any]:
        prm = self.params
        if prm["precision"] == "float32":
            for port in (*self.INPUTS, *self.OUTPUTS):
                if abs(port.default) >= FLOAT32_OVERFLOW:
                    raise ParameterError(
                        f"{self.kind}: parameter '{port.name}' = {port.default!r} is out of "
                        f"range: a float32 module parameter allows (-{FLOAT32_OVERFLOW!r}, "
                        f"{FLOAT32_OVERFLOW!r}), i.e. values that round to a finite float32 "
                        "(precision = float32, spec 6.1)")
        code = self._layout.compiled
        return {"precision": 1.0 if prm["precision"] == "float32" else 0.0,
                "deferred": 1.0 if prm["deferred_param_reads"] else 0.0,
                "div_ieee": 1.0 if prm["divide_by_zero"] == "ieee" else 0.0,
                "n_out": float(len(self.OUTPUTS)), "stack": float(code.stack),
                "code_len": float(len(code.code)), "code": code.code}

    def initial_state(self) -> list[float]:
        """Outputs start at their initial values (stored: rounded to float32 in that
        precision), with status Good non-cascade (128)."""
        f32 = self.params["precision"] == "float32"
        values = [float(self.params[p.name]) for p in self.OUTPUTS]
        if f32:
            values = [to_float32(v) for v in values]
        return values + [GOOD_NC] * len(self.OUTPUTS)

    def initial_outputs(self) -> list[float]:
        """Before the first scan every output shows its initial value (issue 11 point 8: what
        a block earlier in the module order reads), Good non-cascade."""
        return [float(v) for v in self.x[:len(self.OUTPUTS)]]

    @classmethod
    def split_table(cls, table: Mapping[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
        """Every key of a scenario table is a parameter: an option, or the initial value of a
        module parameter, which for an input is also the constant an unwired input keeps."""
        return dict(table), {}
