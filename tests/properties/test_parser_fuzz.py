"""Fuzzing the file parsers (issue 11): random bytes and structured mutations of valid files give
either a result or a located loopworks error, never a traceback.

* replay CSV: a valid file with cells, rows and header names mutated, or random bytes;
* scenario TOML: the shipped examples with keys, values and lines mutated, or random bytes.

(The CALC parser has its own fuzz test beside the DeltaV tests.)
"""

from __future__ import annotations

import io
import os
import re
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

import loopworks
from loopworks.errors import LoopworksError
from loopworks.sim.replay import replay
from loopworks.sim.scenario import parse_scenario
from tests.properties.csv_mutations import mutate

EXAMPLES = sorted((Path(__file__).parents[2] / "examples").glob("*.toml"))

VALID_CSV = ("t,sp,pv,mode,pv.ST\n0,50,40,AUTO,128\n0.5,50,41,1,128\n1.0,50,nan,1,0\n"
             "1.5,50,45,1,64\n")

CELLS = ["", " ", "nan", "inf", "-inf", "1e308", "-1e999", "x", "AUTO", "MAN", "CAS", "7",
         "-1", "256", "0x80", "1,2", '"', '""', "\x00", "é", "1e-320", "  3  ", "NaN"]


def _located(message: str) -> bool:
    """A located message names the file (and, for cell errors, the line)."""
    return bool(message.strip()) and "\n" not in message.strip()


@st.composite
def mutated_csv(draw: st.DrawFn) -> str:
    return mutate(draw, [line.split(",") for line in VALID_CSV.strip().split("\n")],
                  cells=CELLS, headers=["T", "dt", "SP", "Pv", "pv.st", "mode.ST", "out",
                                        "clock", "", "t", "sp"])


def _replay_text(tmp_path: Path, text: str | bytes) -> None:
    path = tmp_path / "in.csv"
    path.write_bytes(text if isinstance(text, bytes) else text.encode("utf-8", "surrogatepass"))
    block = loopworks.create_block("pid", k=2.0, ti=10.0, jit=False)  # the parser is tested
    try:
        replay(block, path, io.StringIO())
    except LoopworksError as exc:
        assert _located(str(exc)), str(exc)
        assert str(path) in str(exc) or "--dt" in str(exc), str(exc)


@given(text=mutated_csv())
def test_mutated_replay_csv_gives_a_result_or_a_located_error(tmp_path_factory: pytest.
                                                              TempPathFactory,
                                                              text: str) -> None:
    _replay_text(tmp_path_factory.mktemp("csv"), text)


@given(data=st.binary(max_size=300))
def test_random_bytes_as_replay_csv_give_a_located_error(tmp_path_factory: pytest.
                                                          TempPathFactory,
                                                          data: bytes) -> None:
    _replay_text(tmp_path_factory.mktemp("csv"), b"t,sp,pv\n" + data)


VALUES = ['0', '-1', '1e308', 'nan', 'inf', '-inf', '"x"', '"AUTO"', 'true', '[]', '[1, 2]',
          '{}', '"pid.out"', '"nope.out"', '"pid"', '1.5', '100000000000', '"process.y"']

KEYS = ["kind", "dt", "bogus", "MODE", "sp", '"a.b"', '"pid.mode"', "duration", "t"]


@st.composite
def mutated_toml(draw: st.DrawFn) -> str:
    text = draw(st.sampled_from(EXAMPLES)).read_text()
    lines = text.split("\n")
    for _ in range(draw(st.integers(1, 4))):
        op = draw(st.sampled_from(["value", "key", "drop", "dup", "garbage"]))
        assignments = [i for i, line in enumerate(lines) if re.match(r"\s*[\w\".]+\s*=", line)]
        if not assignments:
            break
        i = draw(st.sampled_from(assignments))
        key, _, _ = lines[i].partition("=")
        if op == "value":
            lines[i] = f"{key}= {draw(st.sampled_from(VALUES))}"
        elif op == "key":
            new_key = draw(st.sampled_from(KEYS))
            lines[i] = f"{new_key} = {draw(st.sampled_from(VALUES))}"
        elif op == "drop":
            lines.pop(i)
        elif op == "dup":
            lines.insert(i, lines[i])
        else:
            lines.insert(i, draw(st.sampled_from(["[", "[[events]]", "]]", "= 1", "[blocks.x]",
                                                  "kind = 'pid'", "\"", "[simulation]"])))
    return "\n".join(lines)


def _parse(text: str) -> None:
    jit = os.environ.get("LOOPWORKS_JIT")
    os.environ["LOOPWORKS_JIT"] = "0"  # the parser is tested, not the compiled kernels
    try:
        scenario = parse_scenario(text, "fuzz.toml")
    except LoopworksError as exc:
        assert _located(str(exc)), str(exc)
        assert "fuzz.toml" in str(exc), str(exc)
        return
    finally:
        if jit is None:
            del os.environ["LOOPWORKS_JIT"]
        else:
            os.environ["LOOPWORKS_JIT"] = jit
    assert scenario.module.blocks and scenario.dt > 0


@given(text=mutated_toml())
def test_mutated_scenarios_load_or_give_a_located_error(text: str) -> None:
    _parse(text)


@given(data=st.binary(max_size=300))
def test_random_bytes_as_a_scenario_give_a_located_error(data: bytes) -> None:
    _parse(data.decode("utf-8", "replace"))
