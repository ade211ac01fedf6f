"""Historian replay of large files (issue 12): the bulk reader and the compiled formatter.

A file of at least ``BULK_MIN_BYTES`` is read in bulk (pyarrow) and written by the compiled
formatter of ``loopworks.sim.floatfmt``; smaller ones row by row by the csv module. The two
must not be told apart: the same output text (floats as ``repr`` writes them, so every value
reads back exactly), the same summary, the same located errors. Most tests here run a file
both ways (``BULK_MIN_BYTES`` set to 0, or out of reach) and compare; the expected line numbers
of errors are counted by hand from how the file was written.
"""

from __future__ import annotations

import csv
import io
import math
import random
from pathlib import Path

import numpy as np
import pytest

from loopworks import create_block
from loopworks.blocks.block import Block
from loopworks.errors import FileFormatError, LoopworksError
from loopworks.sim import bulkcsv
from loopworks.sim import replay as replay_module
from loopworks.sim.floatfmt import float_text, format_rows
from loopworks.sim.replay import replay

Outcome = tuple[object, ...]


def pid() -> Block:
    return create_block("pid", k=2.0, ti=10.0, td=1.0)


def run(path: Path, bulk: bool, monkeypatch: pytest.MonkeyPatch, **kwargs: object) -> Outcome:
    """Replay ``path`` in bulk or row by row into a string: ("ok", text, rows, t_start,
    t_end, progress ticks) or ("error", type, message)."""
    monkeypatch.setattr(replay_module, "BULK_MIN_BYTES", 0 if bulk else 1 << 62)
    buf = io.StringIO()
    ticks: list[int] = []
    try:
        s = replay(pid(), path, buf, progress=ticks.append, **kwargs)
    except LoopworksError as exc:
        return ("error", type(exc).__name__, str(exc))
    return ("ok", buf.getvalue(), s.rows, s.t_start, s.t_end, ticks)


def both_ways(path: Path, monkeypatch: pytest.MonkeyPatch, **kwargs: object) -> Outcome:
    """The outcome, after checking that bulk and row by row agree on it exactly."""
    slow = run(path, False, monkeypatch, **kwargs)
    fast = run(path, True, monkeypatch, **kwargs)
    assert fast[:3] == slow[:3]
    assert fast == slow
    return fast


def write_rows(path: Path, n: int, seed: int = 3, mode: bool = False) -> Path:
    """n rows of t, sp, pv (with some nan), pv.ST (and mode by name or code)."""
    rng = random.Random(seed)
    with open(path, "w", encoding="utf-8", newline="") as fh:
        fh.write("t,sp,pv,pv.ST" + (",mode,man_out\n" if mode else "\n"))
        for k in range(n):
            pv = "nan" if rng.random() < 0.01 else f"{40 + 20 * rng.random():.6f}"
            st = rng.choice(["128", "128", "128", "0", "64", "192"])
            fh.write(f"{k * 0.1:.1f},{50 + rng.random():.4f},{pv},{st}")
            if mode:
                fh.write("," + rng.choice(["AUTO", "AUTO", "auto", "1", "MAN", "0", " Man "])
                         + f",{rng.uniform(0, 100):.3f}")
            fh.write("\n")
    return path


# -- the formatter: repr's text, exactly ---------------------------------------------------------


def test_written_floats_are_repr_and_read_back_exactly() -> None:
    rng = np.random.default_rng(12)
    values = np.concatenate([
        rng.integers(0, 2**64, size=200_000, dtype=np.uint64).view(np.float64),  # any bits
        rng.normal(size=50_000) * 10.0 ** rng.integers(-30, 30, size=50_000),
        *(np.round(rng.uniform(-1e4, 1e4, size=10_000), d) for d in range(8)),
        rng.integers(-2**60, 2**60, size=20_000).astype(np.float64),
        np.array([2.0**e for e in range(-1074, 1024)] + [10.0**e for e in range(-323, 309)]),
        np.array([0.0, -0.0, 0.1, 1e16, 1e15, 1e-5, 1e-4, 5e-324, 2.2250738585072014e-308,
                  1.7976931348623157e308, 9007199254740993.0, 123456789012345680.0, 1e23,
                  math.nan, -math.nan, math.inf, -math.inf]),
    ])
    texts = float_text(values)
    assert texts == [repr(v) for v in values.tolist()]
    for text, v in zip(texts, values.tolist(), strict=True):
        if math.isnan(v):
            assert text == "nan"
        else:
            assert float(text) == v and math.copysign(1.0, float(text)) == math.copysign(1.0, v)


def test_formatted_rows_are_what_csv_writer_writes() -> None:
    rng = np.random.default_rng(5)
    t = np.round(np.cumsum(rng.uniform(0.05, 1.0, size=2000)), 3)
    Y = rng.normal(size=(2000, 4)) * np.array([1.0, 1e-7, 1e9, 0.0])
    Y[::97, 1] = math.nan
    S = rng.integers(-(2**63), 2**63 - 1, size=(2000, 2), dtype=np.int64)
    S[:, 0] = rng.integers(0, 256, size=2000)
    out = io.StringIO()
    body = np.concatenate([t[:, None], Y], axis=1).tolist()
    csv.writer(out, lineterminator="\n").writerows(
        b + s for b, s in zip(body, S.tolist(), strict=True))
    assert format_rows(t, Y, S).tobytes().decode("ascii") == out.getvalue()


def test_bulk_numbers_are_pythons_floats() -> None:
    """pyarrow's parser, where it takes a cell, gives the double ``float(cell)`` gives: long
    digit strings, exponents at the ends of the range, and exact halfway cases."""
    rng = random.Random(8)
    cells = []
    for _ in range(20_000):
        digits = "".join(rng.choice("0123456789") for _ in range(rng.randrange(1, 30)))
        point = rng.randrange(len(digits) + 1)
        cells.append(rng.choice(["", "-", "+"]) + digits[:point] + "." + digits[point:]
                     + rng.choice(["", f"e{rng.randrange(-340, 320)}"]))
        m, e = rng.getrandbits(53) | 1 << 52, rng.randrange(-40, 40)  # (2m + 1)·2^(e-1) in full
        cells.append(f"{(2 * m + 1) * 5 ** (1 - e)}e{e - 1}" if e < 1 else
                     str((2 * m + 1) * 2 ** (e - 1)))
    cells = [c for c in cells if c.strip("+-") != "."]
    data = ("\n".join(cells) + "\n").encode()
    table = bulkcsv.read_columns(data, 1, set())
    assert table is not None
    n, (values,) = table
    assert n == len(cells)
    assert [float(c) for c in cells] == np.asarray(values).tolist()


# -- bulk and row by row agree ------------------------------------------------------------------


def test_a_multi_chunk_file_gives_the_same_output_either_way(tmp_path: Path,
                                                             monkeypatch: pytest.MonkeyPatch,
                                                             ) -> None:
    path = write_rows(tmp_path / "in.csv", 30_000)
    outcome = both_ways(path, monkeypatch, chunk=4096)
    assert outcome[0] == "ok" and outcome[2] == 30_000
    assert outcome[5] == [min(4096 * (k + 1), 30_000) for k in range(8)]  # progress, per chunk
    rows = list(csv.reader(io.StringIO(str(outcome[1]))))
    assert rows[0] == ["t", "out", "p_term", "i_term", "d_term", "out.ST"]
    assert {r[-1] for r in rows[1:]} >= {"128", "71"}  # good and held (Bad pv) rows
    for row in rows[1:200]:
        for cell in row[:-1]:
            assert repr(float(cell)) == cell  # the shortest text of the value it reads as


def test_a_big_file_is_read_in_bulk_by_default(tmp_path: Path,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    path = write_rows(tmp_path / "in.csv", 20_000)
    assert path.stat().st_size >= replay_module.BULK_MIN_BYTES
    out = tmp_path / "out.csv"
    replay(pid(), path, out)
    fast = out.read_text(encoding="utf-8")
    monkeypatch.setattr(replay_module, "BULK_MIN_BYTES", 1 << 62)
    replay(pid(), path, out)
    assert fast == out.read_text(encoding="utf-8")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.csv", "out.csv"]


def test_enumerated_inputs_by_name_and_code_in_a_big_file(tmp_path: Path,
                                                          monkeypatch: pytest.MonkeyPatch,
                                                          ) -> None:
    path = write_rows(tmp_path / "in.csv", 6000, mode=True)
    outcome = both_ways(path, monkeypatch, chunk=1000)
    assert outcome[0] == "ok"
    statuses = {r.rsplit(",", 1)[1] for r in str(outcome[1]).splitlines()[1:]}
    assert "131" in statuses  # MAN: the operator's output, Good + Constant


def test_standard_output_gets_the_same_text(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    path = write_rows(tmp_path / "in.csv", 3000)
    texts = []
    for bulk in (False, True):
        monkeypatch.setattr(replay_module, "BULK_MIN_BYTES", 0 if bulk else 1 << 62)
        replay(pid(), path, None, chunk=700)
        texts.append(capsys.readouterr().out)
    assert texts[0] == texts[1] and texts[0].count("\n") == 3001


EDGE_FILES = {
    "crlf": b"t,sp,pv\r\n0,50,40\r\n\r\n1,50,41\r\n2,50,42\r\n",
    "bom and blank lines first": b"\xef\xbb\xbf\n\nt,sp,pv\n0,50,40\n1,50,41\n",
    "quoted everywhere": b'"t","sp","pv"\n"0","50","40"\n"1","50",""\n',
    "quoted, doubled quote": b't,sp,pv\n0,50,40\n1,"5""0",40\n',
    "quote inside a field": b't,sp,pv\n0,50,40\n1,5"0,40\n2,"50",40\n',
    "quoted line break": b't,sp,pv\n0,50,40\n1,"5\n0",40\n2,50,x\n',
    "lone carriage returns": b"t,sp,pv\r0,50,40\r1,50,41\r2,50,x\r",
    "padded cells": b"t,sp,pv\n0, 50 ,40\n1,\t50,41\n2,50 ,x\n",
    "blank, whitespace and comma lines": b"t,sp,pv\n0,50,40\n\n  \n,,\n1,50,41\n,,\n2,5,y\n",
    "nan(...) and names": b"t,sp,pv\n0,50,40\n1,nan(1),40\n",
    "underscores and unicode digits": "t,sp,pv\n0,5_0,40\n1,\u0665\u0660,40\n".encode(),
    "not UTF-8": b"t,sp,pv\n0,50,40\n1,50,4\xb0\n",
    "short and long rows": b"t,sp,pv\n0,50,40\n1,50\n",
    "oversized field": b't,sp,pv\n0,50,40\n1,50,"' + b"4" * 200_000 + b'"\n',
    "t not increasing": b"t,sp,pv\n0,50,40\n1,50,40\n1,50,40\n",
    "t not finite": b"t,sp,pv\n0,50,40\ninf,50,40\n",
    "last line without a line feed": b"t,sp,pv\n0,50,40\n1,50,41",
    "only a header": b"t,sp,pv\n\n\n",
    "status bytes": b"t,sp,pv,pv.ST\n0,50,40,128\n1,50,40, 64\n2,50,40,128.0\n",
    "dt column": b"dt,sp,pv\n0.1,50,40\n0.2,50,40\n0,50,40\n",
    "accumulated time overflows": b"dt,sp,pv\n1e308,50,40\n1e308,50,40\n1e308,50,40\n",
    "one row": b"t,sp,pv\n0,50,40\n",
    "enumerated name unknown": b"t,sp,pv,mode\n0,50,40,AUTO\n1,50,40,Manual\n",
}


@pytest.mark.parametrize("name", list(EDGE_FILES))
@pytest.mark.parametrize("chunk", [1, 2, 65536])
def test_edge_files_are_read_alike(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, name: str,
                                   chunk: int) -> None:
    path = tmp_path / "edge.csv"
    path.write_bytes(EDGE_FILES[name])
    both_ways(path, monkeypatch, chunk=chunk)


@pytest.mark.parametrize("text", [b"mode,sp,pv\nAUTO,50,40\nMAN,50,40\n1,50,41\n",
                                  b"pv.ST,pv\n128,40\n0,41\n64,x\n"])
def test_timing_from_the_dt_argument_with_text_columns(tmp_path: Path,
                                                       monkeypatch: pytest.MonkeyPatch,
                                                       text: bytes) -> None:
    path = tmp_path / "in.csv"
    path.write_bytes(text)
    both_ways(path, monkeypatch, dt=0.5)


CELLS = ["", " ", "nan", "inf", "-inf", "1e308", "x", "AUTO", "MAN", "man", "7", "-1", "256",
         '"1,2"', '"', '""', '"5"', 'a"b', "\x00", "\xe9", "1e-320", "  3  ", "nan(1)", "1_0",
         "+5", ".5", "128", " 128", "128.0", "0.1", "\t7"]


def random_file(rng: random.Random) -> bytes:
    """A small valid file, mutated: bad cells, blank lines, odd quoting and line ends."""
    cols = rng.choice([["t", "sp", "pv"], ["dt", "sp", "pv", "pv.ST"],
                       ["t", "sp", "pv", "mode", "man_out"], ["T", "PV", "pv.st", "mode"]])
    lines = [",".join(cols)]
    t = 0.0
    for _ in range(rng.choice([1, 2, 5, 40, 300])):
        t += rng.choice([0.1, 0.25, 1.0])
        cells = []
        for c in cols:
            low = c.lower()
            cells.append(repr(round(t, 3)) if low == "t" else
                         rng.choice(["0.1", "1", "0.05"]) if low == "dt" else
                         rng.choice(["AUTO", "MAN", "1", "0", "auto"]) if low == "mode" else
                         rng.choice(["128", "0", "64", "192"]) if low.endswith(".st") else
                         rng.choice([repr(rng.uniform(-100, 100)), "nan", "50"]))
        lines.append(",".join(cells))
    for _ in range(rng.choice([0, 1, 3])):
        i = rng.randrange(1, len(lines)) if len(lines) > 1 else 0
        op = rng.choice(["cell", "blank", "spaces", "commas", "short", "quote", "cr"])
        if op == "cell":
            cells = lines[i].split(",")
            cells[rng.randrange(len(cells))] = rng.choice(CELLS)
            lines[i] = ",".join(cells)
        elif op in ("blank", "spaces", "commas"):
            lines.insert(i, {"blank": "", "spaces": "  ", "commas": ",,"}[op])
        elif op == "short":
            lines[i] = lines[i].rsplit(",", 1)[0]
        elif op == "quote":
            lines[i] = ",".join(f'"{c}"' for c in lines[i].split(","))
        else:
            lines[i] += "\r"
    return ("\n".join(lines) + rng.choice(["\n", ""])).encode("utf-8", "surrogatepass")


def test_random_files_are_read_alike(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    rng = random.Random(20)
    for case in range(150):
        path = tmp_path / f"r{case % 5}.csv"
        path.write_bytes(random_file(rng))
        both_ways(path, monkeypatch, chunk=rng.choice([1, 3, 64, 65536]),
                  dt=0.5 if rng.random() < 0.1 else None)


# -- located errors deep inside big files --------------------------------------------------------


def test_a_malformed_cell_deep_inside_a_big_file(tmp_path: Path) -> None:
    """Blank lines and a quoted line break before the bad cell: the line is still the file's."""
    path = tmp_path / "big.csv"
    n, bad = 200_000, 150_000
    with open(path, "w", encoding="utf-8", newline="") as fh:
        fh.write("t,sp,pv\n")  # line 1
        line = 1
        for k in range(n):
            if k in (10, 70_000):
                fh.write("\n")  # a blank line
                line += 1
            if k == 90_000:
                fh.write('\n"",\t,\n')  # a blank line, and a row of blank cells (skipped)
                line += 2
            line += 1
            if k == bad:
                fh.write(f"{k * 0.1:.1f},50,4O.5\n")  # letter O for a zero
                bad_line = line
            elif k == 149_000:
                fh.write(f'"{k * 0.1:.1f}","50\n",40\n')  # a quoted cell across two lines
                line += 1
            else:
                fh.write(f"{k * 0.1:.1f},50,{40 + k % 17}\n")
    out = tmp_path / "out.csv"
    with pytest.raises(FileFormatError) as info:
        replay(pid(), path, out)
    assert str(info.value) == (f"{path}, line {bad_line}, column 'pv': '4O.5' is not a number")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["big.csv"]  # no output, no partial


def test_a_non_increasing_t_deep_inside_a_big_file(tmp_path: Path) -> None:
    path = tmp_path / "big.csv"
    with open(path, "w", encoding="utf-8", newline="") as fh:
        fh.write("t,sp,pv\n")
        fh.writelines(f"{k * 0.1 if k != 77_777 else 1.0:.1f},50,40\n" for k in range(100_000))
    with pytest.raises(FileFormatError, match=rf"big\.csv, line {77_777 + 2}: t = 1 s does not "
                                              r"increase \(previous row t = 7777\.6 s\)"):
        replay(pid(), path, io.StringIO())
