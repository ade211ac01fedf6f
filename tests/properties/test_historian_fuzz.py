"""Fuzzing the historian reader and the diagnosis (issue 15 point 1, "located errors for bad
files, as replay gives"; standards: "no wrong answer may look like a right one").

A mutated historian export either reads, and then diagnoses to one of the three verdicts with
a JSON object that holds no NaN or infinity (figures the data cannot support are null), or is
refused with one line that names the file. No other exception, whatever the cells hold."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from loopworks.analysis.diagnosis import diagnose
from loopworks.analysis.loopdata import read_csv
from loopworks.errors import LoopworksError
from tests.properties.csv_mutations import EDITS, mutate


def _base(n: int, stamps: bool) -> list[list[str]]:
    """A loop cycling through a sticky-looking valve: n samples every 5 s."""
    rng = np.random.default_rng(3)
    k = np.arange(n)
    op = 50.0 + 4.0 * np.sign(np.sin(2 * np.pi * k / 40)) + rng.normal(0, 0.2, n)
    pv = 50.0 + np.cumsum(op - op.mean()) * 0.05 + rng.normal(0, 0.05, n)
    rows = [["Time", "SP", "PV", "OP", "Mode"]]
    for i in range(n):
        t = (f"2024-03-01 {12 + i * 5 // 3600:02d}:{i * 5 // 60 % 60:02d}:{i * 5 % 60:02d}"
             if stamps else repr(5.0 * i))
        rows.append([t, "50", repr(float(pv[i])), repr(float(op[i])), "AUTO"])
    return rows


CELLS = ["", " ", "nan", "NaN", "inf", "-inf", "1e308", "-1e999", "x", "auto", "MAN", "7",
         "2024-02-30 12:00:00", "2024-03-01T12:00:05+01:00", "1e-320", '"', '""', "\x00", "é",
         "0", "-5", "1,2"]
#: cells that still read (a value, or missing): the file passes the reader and the methods run
READABLE = ["", "nan", "1e308", "-1e308", "0", "-5", "1e-320", "1e12", "50", "50.000001"]


HEADERS = ["t", "timestamp", "sv", "PV", "mv", "valve", "mode", "", "op", "pv", "x"]


def _mutate(draw: st.DrawFn, rows: list[list[str]]) -> str:
    """Up to six edits; a file drawn ``readable`` only gets edits that keep it readable
    (readable values over stretches of a data column, repeated and dropped rows), so the
    methods run on it."""
    if draw(st.booleans()):
        return mutate(draw, rows, cells=READABLE, headers=HEADERS, stretch=400,
                      first_column=1, edits=("column", "dup_line", "drop_line"))
    return mutate(draw, rows, cells=CELLS, headers=HEADERS, edits=EDITS)


@st.composite
def mutated_export(draw: st.DrawFn, n: int) -> str:
    return _mutate(draw, _base(n, draw(st.booleans())))


def _read_or_refuse(path: Path) -> object:
    try:
        return read_csv(path)
    except LoopworksError as exc:
        message = str(exc).strip()
        assert message and "\n" not in message, message
        assert str(path) in message, message
        return None


def _write(tmp: Path, text: str) -> Path:
    path = tmp / "export.csv"
    path.write_bytes(text.encode("utf-8", "surrogatepass"))
    return path


@given(text=mutated_export(30))
def test_a_mutated_export_reads_or_gives_a_located_error(
        tmp_path_factory: pytest.TempPathFactory, text: str) -> None:
    data = _read_or_refuse(_write(tmp_path_factory.mktemp("csv"), text))
    if data is not None:
        t = data.t  # type: ignore[attr-defined]
        assert np.all(np.isfinite(t)) and np.all(np.diff(t) > 0)


@given(data=st.binary(max_size=300))
def test_random_bytes_after_a_header_give_a_result_or_a_located_error(
        tmp_path_factory: pytest.TempPathFactory, data: bytes) -> None:
    path = tmp_path_factory.mktemp("csv") / "export.csv"
    path.write_bytes(b"t,sp,pv,op\n" + data)
    _read_or_refuse(path)


def _finite_json(value: object) -> bool:
    if isinstance(value, float):
        return math.isfinite(value)
    if isinstance(value, dict):
        return all(_finite_json(v) for v in value.values())
    if isinstance(value, list | tuple):
        return all(_finite_json(v) for v in value)
    return True


#: a quarter of the profile's examples: each runs the whole battery (about 0.1 s)
LONG_EXAMPLES = max(1, int(os.environ.get("LOOPWORKS_EXAMPLES", "100")) // 4)


@settings(max_examples=LONG_EXAMPLES)
@given(text=mutated_export(600), integrating=st.booleans())
def test_a_mutated_long_export_is_diagnosed_or_refused(
        tmp_path_factory: pytest.TempPathFactory, text: str, integrating: bool) -> None:
    """Long enough to pass the quality gate when unharmed (600 samples), so the methods and
    the valve fit run on whatever the mutations left."""
    path = _write(tmp_path_factory.mktemp("csv"), text)
    try:
        result = diagnose(path, "integrating" if integrating else "self-regulating",
                          recommend=False)
    except LoopworksError as exc:
        message = str(exc).strip()
        assert message and "\n" not in message and str(path) in message, message
        return
    assert result.verdict in ("stiction", "no_stiction", "undetermined")
    assert 0.0 <= result.confidence <= 1.0
    obj = result.to_json()
    assert _finite_json(obj), obj
    json.dumps(obj, allow_nan=False)
