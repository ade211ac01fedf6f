"""Fuzzing the CALC expression parser (issue 11, "fuzz the CSV, TOML and CALC parsers"): random
text, random bytes and structured mutations of the seed's text (spec vendor-blocks 6.1, seed
000) give either a block that runs or an :class:`ExpressionError` that names a line and a column
inside the text, never another exception. A block that builds is then run on inputs with NaN,
±inf and ±1e308: its scans are sound by themselves (issue 11 point 1).
"""

from __future__ import annotations

import math
import re
from typing import Any

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

import loopworks
from loopworks.blocks.block import Block
from loopworks.blocks.kernel import _marked_np
from loopworks.vendors.deltav.calc import SEED_PARAMETERS
from loopworks.vendors.deltav.expression import SEED_EXPRESSION, ExpressionError, parse

#: pieces of the language (and of what it refuses), for texts that get past the tokenizer
TOKENS = ["'^/A'", "'^/B.ST'", "'^/Y'", "'^/Y.ST'", "'^/Z.CV'", "'^/PV'", "'^/SIGNAL_IN.ST'",
          ":=", ";", "IF", "THEN", "ELSIF", "ELSE", "END_IF", "ENDIF", "AND", "OR", "NOT", "!",
          "TRUE", "FALSE", "(", ")", "+", "-", "*", "/", "=", "!=", "<>", "~=", "|=", "<", ">",
          "<=", ">=", "0", "1", "0.5", ".5", "1e38", "3.5e38", "1e308", "1e999", "2E-400",
          "(* c *)", "(*", "*)", "'", "'^/'", "'/X'", "'//M/X'", "'^/A.CST'", "MOD", "**", "?",
          "&", "x", "\n", "\t", "é", "\x00"]
#: what a mutation may insert: tokens, and runs of the nesting constructs (deep nesting must be
#: a located error, not a RecursionError)
INSERTS = [*TOKENS, "(" * 300, "- " * 300, "NOT " * 300, "IF 1 THEN " * 120, "1 + " * 3000,
           "'^/A' * " * 3000, "(1 + " * 80]
SPECIALS = [math.nan, math.inf, -math.inf, 1e308, -1e308, 3.5e38, -3.5e38, 0.0, -0.0, 5e-324,
            1.0, 50.0]
_RESERVED = {"expression", "precision", "deferred_param_reads", "divide_by_zero", "jit", "t",
             "dt", "kind", "self"}


def located(exc: ExpressionError, text: str) -> None:
    """The error names a line and a column of ``text`` (the end of the text included)."""
    lines = text.split("\n")
    assert 1 <= exc.line <= len(lines), (exc.line, len(lines), str(exc))
    assert 1 <= exc.column <= len(lines[exc.line - 1]) + 1, (exc.column, str(exc))
    assert re.search(rf"expression, line {exc.line}, column {exc.column}: \S", str(exc))
    assert "\n" not in str(exc).strip()


def sound(block: Block) -> None:
    """No output is non-finite unless its status is Bad; no state is non-finite."""
    for i, port in enumerate(block.OUTPUTS):
        if not math.isfinite(block.y[i]):
            assert port.status and block.ys[i] & 0xC0 == 0, (port.name, block.y[i], block.ys[i])
    assert np.isfinite(block.x).all(), dict(zip(block.STATES, block.x, strict=True))


def raw_step(block: Block, dt: float, **inputs: Any) -> None:
    """One scan through the block's kernel alone, without the numeric guard's fallback: the
    kernel sees the statuses the guard shows it (a non-finite value is Bad), nothing more, so
    a scan that is not sound by itself is caught here (issue 11 point 1)."""
    block.set_inputs(inputs)
    with np.errstate(all="ignore"):
        type(block).kernel(dt, block.p, block.x, block.u, _marked_np(block.u, block.us),
                           block.y, block.ys)


def check(text: str, seed: int = 0) -> None:
    """``text`` builds a deltav.calc block (its unknown inputs declared) that runs soundly, or
    it raises a located ExpressionError; nothing else."""
    try:
        prog = parse(text)
    except ExpressionError as exc:
        located(exc, text)
        return
    declare = {n: 0.0 for n in prog.read_only
               if n not in SEED_PARAMETERS and n not in _RESERVED}
    rng = np.random.default_rng(seed)
    for precision in ("float32", "float64"):
        try:
            block = loopworks.create_block("deltav.calc", jit=False, expression=text,
                                           precision=precision, **declare)
        except ExpressionError as exc:
            located(exc, text)
            return
        sound(block)  # the outputs before the first scan (issue 11 point 8)
        for _ in range(6):
            inputs: dict[str, Any] = {}
            for port in block.INPUTS:
                value = float(rng.choice(SPECIALS)) if rng.random() < 0.4 else \
                    float(rng.uniform(-100.0, 100.0))
                inputs[port.name] = (value, int(rng.choice([128, 0, 0x1C, 0x40, 0xC0])))
            raw_step(block, 1.0, **inputs)
            sound(block)


@st.composite
def mutated_seed(draw: st.DrawFn) -> str:
    """The seed's text with 1-6 edits: a span deleted, a piece inserted, a span duplicated,
    two lines swapped, or a line dropped."""
    text = SEED_EXPRESSION
    for _ in range(draw(st.integers(1, 6))):
        op = draw(st.sampled_from(["delete", "insert", "insert", "duplicate", "swap", "drop"]))
        n = len(text)
        at = draw(st.integers(0, n))
        if op == "delete" and n:
            text = text[:at] + text[at + draw(st.integers(1, 12)):]
        elif op == "insert":
            text = text[:at] + draw(st.sampled_from(INSERTS) | st.text(max_size=4)) + text[at:]
        elif op == "duplicate":
            end = min(n, at + draw(st.integers(1, 80)))
            text = text[:end] + text[at:end] + text[end:]
        else:
            lines = text.split("\n")
            i = draw(st.integers(0, len(lines) - 1))
            j = draw(st.integers(0, len(lines) - 1))
            if op == "swap":
                lines[i], lines[j] = lines[j], lines[i]
            else:
                del lines[i]
            text = "\n".join(lines)
    return text


@given(st.text(max_size=200))
def test_random_text(text: str) -> None:
    check(text)


@given(st.binary(max_size=200), st.sampled_from(["utf-8", "latin-1"]))
def test_random_bytes(data: bytes, encoding: str) -> None:
    check(data.decode(encoding, errors="replace"))


@given(st.lists(st.sampled_from(TOKENS), max_size=40).map(" ".join))
def test_random_token_sequences(text: str) -> None:
    check(text)


@given(mutated_seed(), st.integers(0, 2**32 - 1))
def test_mutations_of_the_seed_text(text: str, seed: int) -> None:
    check(text, seed)


def test_the_seed_text_and_deep_nesting_examples() -> None:
    """Fixed cases the strategies found or must cover: the seed itself builds and runs; deep
    nesting of each construct and a long operator chain are located errors or results."""
    check(SEED_EXPRESSION)
    for text in ["'^/Y' := " + "(" * 500 + "1" + ")" * 500,
                 "'^/Y' := " + "- " * 2000 + "1",
                 "'^/Y' := " + "NOT " * 2000 + "1",
                 "IF 1 THEN " * 500 + "'^/Y' := 1" + " END_IF" * 500,
                 "'^/Y' := " + " + ".join(["1"] * 5000),
                 "'^/Y' := 1e999", "'^/Y' := '^/A' + 1e400", "'^/KIND' := 1; '^/Y' := '^/SELF'"]:
        check(text)
