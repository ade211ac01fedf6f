"""The DeltaV CALC expression subset (spec vendor-blocks 6.1): tokens, syntax, errors, values.

Values are checked by running one-line texts through ``deltav.calc`` (float64 precision, so the
arithmetic is plain IEEE double) and comparing with hand arithmetic written in the test.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest

import loopworks
from loopworks.blocks.status import Signal
from loopworks.errors import LoopworksError, ParameterError
from loopworks.vendors.deltav.expression import (
    OP_ADD,
    OP_CONST,
    OP_INPUT,
    OP_JUMP,
    OP_JUMP_IF_FALSE,
    OP_LOAD,
    OP_STORE,
    SEED_EXPRESSION,
    Assign,
    ExpressionError,
    If,
    compile_program,
    parse,
    tokenize,
)

SEED_FILE = (Path(__file__).resolve().parents[3].parent / "shared" / "seeds"
             / "000_9c27f16fb49d3d3d.txt")  # ../shared beside the checkout
FLT_MAX = 3.402823466e38  # DeltaV's x/0, printed with 10 digits: the float32 maximum


def result(expr: str, jit: bool = False, **inputs: float) -> Signal:
    """``expr`` evaluated once: Y after ``'^/Y' := expr`` in float64 precision (Y starts at 0).
    The inputs named in ``inputs`` are declared (initial value 0) and given for the scan."""
    block = loopworks.create_block("deltav.calc", jit=jit, precision="float64",
                                   expression=f"'^/Y' := {expr};", **dict.fromkeys(inputs, 0.0))
    return block.step(1.0, **inputs)["y"]


def value(expr: str, jit: bool = False, **inputs: float) -> float:
    """The value ``expr`` stores in Y; it must be a Good result."""
    out = result(expr, jit, **inputs)
    assert out.status == 128, (expr, out)
    return out.value


HELD = Signal(0.0, 0)  # issue 11 point 1: a non-finite result is not stored; Y holds 0, Bad


def error(text: str, **params: Any) -> str:
    """The message of the error ``text`` gives at construction."""
    with pytest.raises(ExpressionError) as info:
        loopworks.create_block("deltav.calc", expression=text, **params)
    return str(info.value)


# -- the seed's text ----------------------------------------------------------------------------


def test_default_text_is_the_seed_expression_as_printed() -> None:
    """spec 6.1/6.3: the 28 lines between the seed's fences, line numbers removed."""
    assert SEED_FILE.exists(), f"the seed file is expected beside the checkout: {SEED_FILE}"
    text = SEED_FILE.read_text()
    start = text.index("```") + 3
    body = text[start:text.index("```", start)].split("\n")
    lines = [ln for ln in body if ln.strip()]
    assert len(lines) == 28
    # the printed numbers take 3 columns: "1  " ... "9  ", "10 " ... "28 "
    assert [ln[:3].strip() for ln in lines] == [str(i) for i in range(1, 29)]
    printed = "\n".join(ln[3:] for ln in lines) + "\n"
    assert printed == SEED_EXPRESSION


def test_seed_parses_to_its_statements_and_names() -> None:
    # spec 6.3: lines 2, 3, the IF of lines 5-9, the IF of lines 11-27, line 28
    prog = parse(SEED_EXPRESSION)
    kinds = [type(s).__name__ for s in prog.statements]
    assert kinds == ["Assign", "Assign", "If", "If", "Assign"]
    assert [s.line for s in prog.statements] == [2, 3, 5, 11, 28]
    # spec 6.2: computed (written) parameters, in order of first assignment
    assert prog.written == ["dither_amp", "kicker_out", "noise_band", "signal_out",
                            "kicker_delt", "dither_delt"]
    assert set(prog.read_only) == {"resolution", "deadband", "dither_factor", "kicker_factor",
                                   "initialize", "kick_start", "process_gain", "noise_factor",
                                   "comp_start", "signal_in", "pv", "sp", "cntrl_action",
                                   "valve_action", "dither_out"}
    assert prog.status_read == {"signal_in"}
    assert prog.status_written == {"signal_out"}
    # line 20's unary minus binds to KICKER_OUT: ((-KO)*CA)*VA, the order deltav.stick_slip uses
    inner = prog.statements[3]
    assert isinstance(inner, If)
    nested = inner.orelse[0]
    assert isinstance(nested, If)
    low = nested.orelse[0]
    assert isinstance(low, If)
    line20 = low.branches[0][1][0]
    assert isinstance(line20, Assign) and line20.line == 20
    assert type(line20.value).__name__ == "Binary"
    assert line20.value.left.left.op == "-"  # type: ignore[union-attr]


# -- tokens ---------------------------------------------------------------------------------------


def test_tokens_carry_line_and_column_and_comments_vanish() -> None:
    # spec 6.1: comments (* ... *), also over several lines
    toks = tokenize("(* a\ncomment *) '^/Y' :=\n\t.5 ; (**)")
    assert [(t.kind, t.text, t.line, t.column) for t in toks] == [
        ("ref", "'^/Y'", 2, 12), ("op", ":=", 2, 18), ("number", ".5", 3, 2),
        ("op", ";", 3, 5), ("end", "", 3, 11)]


@pytest.mark.parametrize("spelling", ["!=", "|=", "<>", "~="])
def test_every_not_equal_spelling(spelling: str) -> None:
    # spec 6.1: the palette's |= is the OCR rendering of !=; DeltaV also takes <> and ~=
    assert value(f"2 {spelling} 3") == 1.0
    assert value(f"2 {spelling} 2") == 0.0


def test_keywords_in_any_letter_case_and_both_end_if_spellings() -> None:
    # spec 6.1: END_IF (syntax topic) and ENDIF (the seed) both close an IF
    text = ("if '^/A' > 1 then '^/Y' := 1 else '^/Y' := 2 end_if;\n"
            "If '^/A' > 5 Then '^/Z' := 1 Else '^/Z' := 2 EndIf")
    block = loopworks.create_block("deltav.calc", expression=text, a=3.0)
    out = block.step(1.0)
    assert (out["y"].value, out["z"].value) == (1.0, 2.0)


def test_semicolons_may_be_left_out_before_else_and_end_and_doubled() -> None:
    # seed lines 6, 12, 23, 26 have no ';' before ELSE/ENDIF; empty statements are harmless
    text = ";; '^/Y' := 1;; IF 1 THEN '^/Z' := 2 ELSE '^/Z' := 3; ; END_IF '^/W' := 4"
    with pytest.raises(ExpressionError, match=r"line 1, column 64: expected ';' but found "
                                              r"'\^/W'"):
        loopworks.create_block("deltav.calc", expression=text)
    out = loopworks.create_block("deltav.calc", expression=text.replace("END_IF", "END_IF;"),
                                 ).step(1.0)
    assert [out[n].value for n in ("y", "z", "w")] == [1.0, 2.0, 4.0]


# -- precedence and values -----------------------------------------------------------------------


@pytest.mark.parametrize(("expr", "expected"), [
    ("1 + 2 * 3", 7.0),            # * before +
    ("(1 + 2) * 3", 9.0),          # parentheses
    ("2 - 3 - 4", -5.0),           # left to right: (2 - 3) - 4
    ("8 / 4 / 2", 1.0),            # (8 / 4) / 2
    ("- 2 * 3", -6.0),             # unary minus
    ("- - 2", 2.0),
    ("+ 2", 2.0),
    ("2 * - 3", -6.0),
    ("NOT 0 + 1", 2.0),            # NOT binds tighter than +: (NOT 0) + 1
    ("! 3", 0.0),                  # ! is NOT
    ("0 = 1 > 2", 1.0),            # < > <= >= before = : 0 = (1 > 2) = 0 = 0
    ("1 OR 1 AND 0", 1.0),         # AND before OR: 1 OR (1 AND 0)
    ("1 + 1 = 2 AND 3 > 2", 1.0),  # arithmetic, then comparisons, then AND
    ("2 AND 3", 1.0),              # logic gives 1/0; non-zero is true
    ("0 OR -1", 1.0),
    ("0 AND 5", 0.0),
    ("1 < 2", 1.0),
    ("2 <= 2", 1.0),
    ("2 >= 3", 0.0),
    ("TRUE + TRUE + FALSE", 2.0),
    (".5 + 1e2 + 2.5E-1 + 3.", 103.75),
])
def test_operators_and_precedence(expr: str, expected: float) -> None:
    # spec 6.1: comparisons yield 1/0, floats, AND/OR/NOT (DeltaV "Operators" page)
    assert value(expr) == expected


def test_seed_line_5_condition() -> None:
    # spec 6.3 lines 5-9: "=" binds tighter than AND, and only exactly 1.0 counts
    expr = "('^/I' = 1 AND '^/K' = 1 )"
    assert value(expr, i=1.0, k=1.0) == 1.0
    assert value(expr, i=1.0, k=0.0) == 0.0
    assert value(expr, i=1.0000001, k=1.0) == 0.0


def test_nan_follows_ieee_within_a_statement() -> None:
    # NaN: comparisons false, != true, arithmetic propagates; NaN is non-zero, so true
    nan = math.nan
    for op in ("=", "<", ">", "<=", ">="):
        assert value(f"'^/A' {op} 1", a=nan) == 0.0
    assert value("'^/A' != '^/A'", a=nan) == 1.0
    assert value("'^/A' AND 1", a=nan) == 1.0
    assert value("NOT '^/A'", a=nan) == 0.0
    assert value("('^/A' + 1) != ('^/A' + 1)", a=nan) == 1.0  # the sum is NaN
    assert value("'^/A' * 0 > -1", a=math.inf) == 0.0  # inf·0 = NaN
    block = loopworks.create_block(
        "deltav.calc", expression="IF '^/A' THEN '^/Y' := 1 ELSE '^/Y' := 2 END_IF", a=0.0)
    assert block.step(1.0, a=nan)["y"].value == 1.0


def test_issue_11_a_non_finite_result_is_not_stored() -> None:
    # issue 11 point 1 (this test pinned "NaN + 1 gives NaN" with Good status before): a NaN
    # or infinite result is not stored; Y keeps its value (0) with status Bad
    nan = math.nan
    assert result("'^/A' + 1", a=nan) == HELD
    assert result("'^/A' - '^/A'", a=math.inf) == HELD
    assert result("'^/A' * 10", a=1e308) == HELD  # 1e309 overflows float64
    assert result("'^/A'", a=-math.inf) == HELD


@pytest.mark.parametrize("jit", [False, True], ids=["interpreted", "compiled"])
def test_division_by_zero_gives_deltavs_float32_maximum(jit: bool) -> None:
    # DeltaV Books Online, Expressions > Syntax rules > Operators, "/": first operand < 0 gives
    # -3.402823466e+38, >= 0 gives +3.402823466e+38
    assert value("1 / 0", jit) == pytest.approx(FLT_MAX, rel=1e-9)
    assert value("-7 / 0", jit) == pytest.approx(-FLT_MAX, rel=1e-9)
    assert value("0 / 0", jit) == pytest.approx(FLT_MAX, rel=1e-9)
    assert value("1 / -0", jit) == pytest.approx(FLT_MAX, rel=1e-9)
    assert value("'^/A' / 0", jit, a=math.inf) == pytest.approx(FLT_MAX, rel=1e-9)
    assert value("1 / 4", jit) == 0.25
    # [A]: NaN / 0 stays NaN, so the result is not stored (issue 11 point 1: Y holds, Bad)
    assert result("'^/A' / 0", jit, a=math.nan) == HELD


@pytest.mark.parametrize("jit", [False, True], ids=["interpreted", "compiled"])
def test_division_by_zero_ieee_option(jit: bool) -> None:
    def ieee(expr: str, **inputs: float) -> Signal:
        block = loopworks.create_block("deltav.calc", jit=jit, precision="float64",
                                       divide_by_zero="ieee", expression=f"'^/Y' := {expr};",
                                       **dict.fromkeys(inputs, 0.0))
        return block.step(1.0, **inputs)["y"]

    # IEEE 754 inside the statement: 1/0 = +inf, -1/0 = -inf, 1/-0 = -inf, -1/-0 = +inf,
    # 0/0 = NaN (the signs shown by comparisons, whose results are finite)
    assert ieee("1 / 0 > 1e308") == (1.0, 128)
    assert ieee("-1 / 0 < -1e308") == (1.0, 128)
    assert ieee("1 / -0 < -1e308") == (1.0, 128)
    assert ieee("-1 / -0 > 1e308") == (1.0, 128)
    assert ieee("0 / 0 = 0 / 0") == (0.0, 128)  # NaN != NaN; deltav: FLT_MAX = FLT_MAX
    assert value("0 / 0 = 0 / 0") == 1.0
    # issue 11 point 1 (this test pinned Y = ±inf / NaN before): an infinite or NaN result
    # is not stored; Y holds 0, Bad
    for expr in ("1 / 0", "-1 / 0", "0 / 0"):
        assert ieee(expr) == HELD, expr
    assert ieee("'^/A' / 0", a=math.nan) == HELD


def test_elsif_chain_takes_the_first_true_branch() -> None:
    text = """IF '^/A' < 0 THEN '^/Y' := 1;
ELSIF '^/A' < 10 THEN '^/Y' := 2;
ELSIF '^/A' < 20 THEN '^/Y' := 3;
ELSE '^/Y' := 4;
END_IF;"""
    block = loopworks.create_block("deltav.calc", expression=text, a=0.0)
    assert [block.step(1.0, a=a)["y"].value for a in (-5.0, 5.0, 15.0, 25.0, 5.0)] == \
        [1.0, 2.0, 3.0, 4.0, 2.0]


def test_if_without_else_leaves_the_parameter_unchanged() -> None:
    text = "IF '^/A' > 0 THEN '^/Y' := '^/A' END_IF"
    block = loopworks.create_block("deltav.calc", expression=text, a=0.0)
    assert [block.step(1.0, a=a)["y"].value for a in (3.0, -1.0, 0.0, 7.0)] == \
        [3.0, 3.0, 3.0, 7.0]


# -- the compiled program ----------------------------------------------------------------------


def test_compiled_program_of_an_assignment_and_an_if() -> None:
    prog = parse("'^/Y' := '^/X' + 1; IF '^/Y' THEN '^/Y' := 2 END_IF")
    out = compile_program(prog, {"x": 0}, {"y": 0})
    pairs = list(zip(out.code[::2], out.code[1::2], strict=True))
    assert pairs == [
        (OP_INPUT, 0), (OP_CONST, 1.0), (OP_ADD, 0), (OP_STORE, 0),   # Y := X + 1
        (OP_LOAD, 0), (OP_JUMP_IF_FALSE, 18),                          # IF Y: else skip
        (OP_CONST, 2.0), (OP_STORE, 0), (OP_JUMP, 18),                 # THEN Y := 2
    ]  # jump targets index the flat code: 9 pairs end at 18
    assert out.stack == 2


def test_deep_nesting_is_refused() -> None:
    text = "'^/Y' := " + "(1 + " * 70 + "1" + ")" * 70
    assert "nested too deeply" in error(text)
    # every nesting construct, at the level past the limit (32), not as a RecursionError: the
    # 33rd '(' of "'^/Y' := ((..." is at column 9 + 33, the 33rd '- ' at 9 + 2·32 + 1, the 33rd
    # 'NOT ' at 9 + 4·32 + 1, the 33rd IF on line 33
    assert "line 1, column 42: the expression is nested too deeply (more than 32 levels" in \
        error("'^/Y' := " + "(" * 40 + "1" + ")" * 40)
    assert "line 1, column 74: the expression is nested too deeply" in \
        error("'^/Y' := " + "- " * 40 + "1")
    assert "line 1, column 138: the expression is nested too deeply" in \
        error("'^/Y' := " + "NOT " * 40 + "1")
    assert "line 33, column 1: the expression is nested too deeply" in \
        error("IF 1 THEN\n" * 40 + "'^/Y' := 1" + " END_IF" * 40)
    # 32 levels are fine
    assert value("(" * 32 + "1" + ")" * 32) == 1.0
    assert value("- " * 32 + "1") == 1.0


def test_a_long_chain_of_operators_compiles_without_recursion() -> None:
    # 1 + 1 + ... parses left to right as one deep tree; compiling it must not recurse once
    # per operator (Python's recursion limit is 1000)
    assert value(" + ".join(["1"] * 5000)) == 5000.0
    assert value(" * ".join(["'^/A'"] * 3000), a=1.0) == 1.0
    prog = parse("'^/Y' := " + " - ".join([f"'^/A{i}'" for i in range(2000)]))
    assert prog.names[:3] == ["y", "a0", "a1"] and len(prog.names) == 2001


def test_a_literal_beyond_float64_is_refused() -> None:
    # float("1e999") is inf: a literal must be a finite number
    assert "line 1, column 14: number '1e999' is out of range" in error("'^/Y' := 1 + 1e999")
    assert value("1e308") == 1e308


@pytest.mark.parametrize("name", ["KIND", "self"])
def test_names_of_constructor_arguments_are_reserved(name: str) -> None:
    # 'kind' and 'self' would collide with create_block(kind, ...) and the constructor
    assert f"line 1, column 10: module parameter '^/{name}' has the name of a deltav.calc " \
        "parameter or a reserved name" in error(f"'^/Y' := '^/{name}';")
    assert "a reserved name" in error(f"'^/{name}' := 1;")


# -- errors --------------------------------------------------------------------------------------


def test_parse_error_names_line_column_and_what_was_expected() -> None:
    # the issue's example: the seed with line 15 broken
    lines = SEED_EXPRESSION.split("\n")
    assert lines[14] == "  IF ('^/PV' > ('^/SP' + '^/NOISE_BAND'*0.5)) THEN"
    lines[14] = "  IF ('^/PV' > '^/SP' ; THEN"
    message = error("\n".join(lines))
    assert message == ("deltav.calc: expression, line 15, column 23: expected ')' but found "
                       "';'")


def test_parse_errors_are_parameter_errors() -> None:
    with pytest.raises(ParameterError):
        loopworks.create_block("deltav.calc", expression="'^/Y' := (1")
    assert issubclass(ExpressionError, LoopworksError)


@pytest.mark.parametrize(("text", "message"), [
    ("'^/Y' := (1", "line 1, column 12: expected ')' but found the end of the expression"),
    ("'^/Y' = 1", "line 1, column 7: expected ':=' but found '='"),
    ("'^/Y' := ;", "line 1, column 10: expected an operand (a number, a '^/NAME' reference "
                   "or '(') but found ';'"),
    ("IF 1 '^/Y' := 1; END_IF", "line 1, column 6: expected 'THEN' but found '^/Y'"),
    ("IF 1 THEN\n  '^/Y' := 1;\n", "line 3, column 1: expected 'END_IF' (or 'ENDIF') to close "
                                   "the IF of line 1 but found the end of the expression"),
    ("'^/Y' := 1;\nELSE", "line 2, column 1: expected a statement (an assignment to '^/NAME' "
                          "or an IF) but found 'ELSE'"),
    ("'^/Y' := 1 '^/Z' := 2", "line 1, column 12: expected ';' but found '^/Z'"),
    ("'^/Y' := 1 * * 2", "line 1, column 14: expected an operand"),
    ("'^/Y' := 1;\n\t(* never closed", "line 2, column 2: the comment '(*' is never closed"),
    ("'^/Y' := '^/A;\n", "line 1, column 10: the quoted reference is never closed"),
    ("'^/Y' := '/PID1/OUT';", "line 1, column 10: module-relative reference '/PID1/OUT' is not "
                              "supported"),
    ("'^/Y' := '//MOD1/X';", "line 1, column 10: external reference '//MOD1/X' is not "
                             "supported"),
    ("'^/Y' := 'IN1';", "line 1, column 10: expected a reference of the form '^/NAME'"),
    ("'^/Y' := '^/A.CST';", "line 1, column 10: '^/A.CST': field '.CST' is not supported"),
    ("'^/Y' := '^/A B';", "line 1, column 10: '^/A B': expected a parameter name"),
    ("'^/Y' := IN1;", "line 1, column 10: unquoted name 'IN1'"),
    ("'^/Y' := 7 MOD 2;", "line 1, column 12: the operator 'MOD' is not supported"),
    ("'^/Y' := 2 ** 2;", "line 1, column 12: the power operator '**' is not supported"),
    ("'^/Y' := 1 ? 2 : 3;", "line 1, column 12: the conditional operator '? :' is not"),
    ("'^/Y' := 3 & 1;", "line 1, column 12: the bitwise operator '&' is not supported"),
    ("'^/Y' := 1.2.3;", "line 1, column 10: malformed number '1.2.'"),
    ("'^/Y' := 1 # 2;", "line 1, column 12: unexpected character '#'"),
    ("", "line 1, column 1: the expression assigns no module parameter"),
])
def test_syntax_errors(text: str, message: str) -> None:
    assert message in error(text)


def test_columns_count_characters_from_one_on_each_line() -> None:
    text = "'^/Y' := 1;\n\n    '^/Z' := (2 +;"
    assert "expression, line 3, column 18: expected an operand" in error(text)


def test_bad_expression_type_is_a_parameter_error() -> None:
    with pytest.raises(ParameterError, match="'expression' = 5 must be text"):
        loopworks.create_block("deltav.calc", expression=5)
