"""Historian replay through the Python API (``loopworks.sim.replay.replay``).

Expected values are computed by hand from the pid equations in ``loopworks.blocks.pid``
(ideal form, positional, k = 2, ti = 10: P = k·(sp - pv), ΔI = (k/ti)·dt·(sp - pv)), or by
stepping a second block row by row with ``block.step``; never copied from replay's output.
"""

from __future__ import annotations

import csv
import io
import itertools
import math
import random
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from loopworks import create_block
from loopworks.errors import FileFormatError, InputError
from loopworks.sim.replay import replay
from tests.csvfiles import write_csv

OUT_HEADER = ["t", "out", "p_term", "i_term", "d_term", "out.ST"]


def run(block, path: Path, **kwargs) -> tuple[list[str], list[list[str]], object]:
    """Replay into a string buffer; return (header, rows, summary)."""
    buf = io.StringIO()
    summary = replay(block, path, buf, **kwargs)
    rows = list(csv.reader(io.StringIO(buf.getvalue())))
    return rows[0], rows[1:], summary


def col(header: list[str], rows: list[list[str]], name: str) -> list[float]:
    i = header.index(name)
    return [float(r[i]) for r in rows]


def pid(**params):
    base = {"k": 2.0, "ti": 10.0}
    base.update(params)
    return create_block("pid", **base)


# -- correctness against hand-computed values ------------------------------------------------


def test_pid_replay_matches_hand_computed_values(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "in.csv", ["t", "sp", "pv"],
                     [[0.0, 50, 40], [0.1, 50, 40], [0.2, 50, 41]])
    header, rows, summary = run(pid(), path)
    assert header == OUT_HEADER
    assert len(rows) == 3
    # row 0: dt = t1 - t0 = 0.1; e = 10
    p0, i0 = 2 * 10, (2 / 10) * 0.1 * 10
    # row 1: e = 10
    p1, i1 = 2 * 10, i0 + (2 / 10) * 0.1 * 10
    # row 2: e = 9
    p2, i2 = 2 * 9, i1 + (2 / 10) * 0.1 * 9
    assert col(header, rows, "out") == pytest.approx([p0 + i0, p1 + i1, p2 + i2], abs=1e-12)
    assert col(header, rows, "p_term") == pytest.approx([p0, p1, p2], abs=1e-12)
    assert col(header, rows, "i_term") == pytest.approx([i0, i1, i2], abs=1e-12)
    assert col(header, rows, "d_term") == [0.0, 0.0, 0.0]
    assert [r[-1] for r in rows] == ["128", "128", "128"]  # integer status bytes
    assert col(header, rows, "t") == [0.0, 0.1, 0.2]
    assert summary.rows == 3
    assert summary.t_start == 0.0
    assert summary.t_end == pytest.approx(0.2)


def test_output_to_a_path_and_summary(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "in.csv", ["t", "sp", "pv"], [[5.0, 50, 40], [6.0, 50, 40]])
    out = tmp_path / "out.csv"
    summary = replay(pid(), path, out)
    with open(out, newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == OUT_HEADER
    # dt = 1 s on both rows: out = 20 + 0.2·1·10 = 22, then 20 + 4 = 24
    assert [float(r[1]) for r in rows[1:]] == pytest.approx([22.0, 24.0])
    assert [float(r[0]) for r in rows[1:]] == [5.0, 6.0]  # t repeated from the input
    assert summary.rows == 2
    assert (summary.t_start, summary.t_end) == (5.0, 6.0)
    assert summary.output == str(out)
    assert not (tmp_path / "out.csv.partial").exists()


def test_first_row_takes_t1_minus_t0_with_irregular_t(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "in.csv", ["t", "sp", "pv"],
                     [[0.0, 50, 40], [0.5, 50, 40], [0.6, 50, 40]])
    header, rows, _ = run(pid(), path)
    # dt = 0.5, 0.5, 0.1; ΔI = 0.2·dt·10 = 2·dt
    assert col(header, rows, "i_term") == pytest.approx([1.0, 2.0, 2.2])
    assert col(header, rows, "out") == pytest.approx([21.0, 22.0, 22.2])


def test_timing_from_a_dt_column(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "in.csv", ["sp", "pv", "dt"],
                     [[50, 40, 0.1], [50, 40, 0.2], [50, 40, 0.1]])
    header, rows, summary = run(pid(), path)
    # t_0 = 0, t_k = t_{k-1} + dt_k
    assert col(header, rows, "t") == pytest.approx([0.0, 0.2, 0.3])
    assert col(header, rows, "i_term") == pytest.approx([0.2, 0.6, 0.8])
    assert col(header, rows, "out") == pytest.approx([20.2, 20.6, 20.8])
    assert summary.t_end == pytest.approx(0.3)


def test_timing_from_the_dt_argument(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "in.csv", ["sp", "pv"], [[50, 40], [50, 40], [50, 45]])
    header, rows, _ = run(pid(), path, dt=0.5)
    assert col(header, rows, "t") == pytest.approx([0.0, 0.5, 1.0])
    # ΔI = 0.2·0.5·e = 0.1·e: 1, 1, 0.5
    assert col(header, rows, "i_term") == pytest.approx([1.0, 2.0, 2.5])
    assert col(header, rows, "out") == pytest.approx([21.0, 22.0, 12.5])


def test_column_names_in_any_letter_case(tmp_path: Path) -> None:
    lower = write_csv(tmp_path / "lower.csv", ["t", "sp", "pv"], [[0, 50, 40], [1, 50, 42]])
    mixed = write_csv(tmp_path / "mixed.csv", ["T", "Sp", "PV"], [[0, 50, 40], [1, 50, 42]])
    h1, r1, _ = run(pid(), lower)
    h2, r2, _ = run(pid(), mixed)
    assert h1 == h2 == OUT_HEADER
    assert r1 == r2
    # and the values really come from the columns: 20 + 2, then 16 + 2 + 1.6
    assert col(h2, r2, "out") == pytest.approx([22.0, 19.6])


def test_bad_pv_status_holds_the_output(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "in.csv", ["t", "sp", "pv", "pv.ST"],
                     [[0, 50, 40, 128], [1, 50, 45, 0], [2, 50, 45, 128]])
    header, rows, _ = run(pid(), path)
    out = col(header, rows, "out")
    st = [int(r[header.index("out.ST")]) for r in rows]
    assert out[0] == pytest.approx(22.0)  # 20 + 0.2·1·10
    assert out[1] == pytest.approx(22.0)  # Bad pv: held
    assert st == [128, 71, 128]  # 71 = 0x47, Uncertain: last usable value, constant
    # bumpless return: I = 22 - 2·5 = 12, + 0.2·1·5 = 13; out = 10 + 13
    assert out[2] == pytest.approx(23.0)


def test_nan_value_is_a_missing_measurement(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "in.csv", ["t", "sp", "pv"],
                     [[0, 50, 40], [1, 50, "nan"], [2, 50, 40]])
    header, rows, _ = run(pid(), path)
    assert col(header, rows, "out")[:2] == pytest.approx([22.0, 22.0])
    assert int(rows[1][-1]) == 71


def test_status_column_defaults_to_good_when_absent(tmp_path: Path) -> None:
    with_st = write_csv(tmp_path / "a.csv", ["t", "sp", "pv", "pv.ST", "sp.ST"],
                        [[0, 50, 40, 128, 128], [1, 50, 41, 128, 128]])
    without = write_csv(tmp_path / "b.csv", ["t", "sp", "pv"], [[0, 50, 40], [1, 50, 41]])
    assert run(pid(), with_st)[1] == run(pid(), without)[1]


def test_mode_column_with_names(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "in.csv", ["t", "sp", "pv", "mode", "man_out"],
                     [[0, 50, 40, "AUTO", "nan"],
                      [1, 50, 40, "MAN", 30],
                      [2, 50, 40, "man", "nan"],
                      [3, 50, 40, "Auto", "nan"]])
    header, rows, _ = run(pid(), path)
    out = col(header, rows, "out")
    st = [int(r[-1]) for r in rows]
    assert out[0] == pytest.approx(22.0)
    assert out[1] == 30.0 and st[1] == 131  # MAN: operator output, Good + Constant
    assert out[2] == 30.0 and st[2] == 131  # MAN, man_out NaN: output holds
    # back to AUTO, bumpless: I = 30 - 20 = 10, + 0.2·1·10 = 12; out = 20 + 12
    assert out[3] == pytest.approx(32.0) and st[3] == 128


def test_mode_column_with_numbers_equals_names(tmp_path: Path) -> None:
    names = write_csv(tmp_path / "a.csv", ["t", "sp", "pv", "mode", "man_out"],
                      [[0, 50, 40, "AUTO", 0], [1, 50, 40, "MAN", 30], [2, 50, 40, "AUTO", 0]])
    nums = write_csv(tmp_path / "b.csv", ["t", "sp", "pv", "mode", "man_out"],
                     [[0, 50, 40, 1, 0], [1, 50, 40, 0, 30], [2, 50, 40, 1, 0]])
    assert run(pid(), names)[1] == run(pid(), nums)[1]


def test_output_limits_set_limited_status(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "in.csv", ["t", "sp", "pv"],
                     [[0, 100, 0], [1, 0, 100], [2, 50, 50]])
    header, rows, _ = run(pid(out_lo=0, out_hi=100), path)
    out = col(header, rows, "out")
    st = [int(r[-1]) for r in rows]
    assert out[:2] == [100.0, 0.0]
    assert st[:2] == [130, 129]  # high limited, low limited


# -- replay equals stepping the block ---------------------------------------------------------


def random_rows(n: int, seed: int) -> list[list[object]]:
    rng = random.Random(seed)
    rows: list[list[object]] = []
    t = 100.0
    for _ in range(n):
        t += rng.choice([0.1, 0.2, 0.25, 1.0])
        mode = rng.choices(["AUTO", "MAN"], weights=[5, 1])[0]
        pv = "nan" if rng.random() < 0.03 else round(rng.uniform(0, 100), 4)
        rows.append([round(t, 6), round(rng.uniform(20, 80), 4), pv,
                     rng.choice([0, 64, 71, 128, 128, 128, 192]),
                     round(rng.uniform(-5, 5), 4), mode, round(rng.uniform(0, 100), 3)])
    return rows


@pytest.mark.parametrize("chunk", [64, 65536])
def test_replay_equals_stepping_row_by_row(tmp_path: Path, chunk: int) -> None:
    header = ["t", "sp", "pv", "pv.ST", "ff", "mode", "man_out"]
    data = random_rows(400, seed=7)
    path = write_csv(tmp_path / "in.csv", header, data)
    params = {"k": 1.5, "ti": 12.0, "td": 2.0, "out_lo": -10, "out_hi": 90}

    _, rows, summary = run(create_block("pid", **params), path, chunk=chunk)
    assert summary.rows == len(data) == len(rows)

    ref = create_block("pid", **params)
    ts = [float(r[0]) for r in data]
    dts = [ts[1] - ts[0]] + [b - a for a, b in itertools.pairwise(ts)]
    expected = []
    for dt, (t, sp, pv, pv_st, ff, mode, man) in zip(dts, data, strict=True):
        y = ref.step(dt, sp=float(sp), pv=(float(pv), pv_st), ff=float(ff), mode=mode,
                     man_out=float(man))
        expected.append([t, y["out"].value, y["p_term"].value, y["i_term"].value,
                         y["d_term"].value, y["out"].status])
    got = np.array([[float(c) for c in r] for r in rows])
    want = np.array(expected, dtype=float)
    np.testing.assert_allclose(got[:, :5], want[:, :5], rtol=1e-12, atol=1e-12)
    assert got[:, 5].astype(int).tolist() == want[:, 5].astype(int).tolist()
    # the mix really exercised several paths
    assert {71, 128, 131} <= set(got[:, 5].astype(int).tolist())


@pytest.mark.parametrize("chunk", [1, 2, 3, 1000])
def test_chunk_size_does_not_change_the_result(tmp_path: Path, chunk: int) -> None:
    path = write_csv(tmp_path / "in.csv", ["t", "sp", "pv"],
                     [[0.1 * k, 50, 40 + (k % 7)] for k in range(25)])
    _, ref_rows, _ = run(pid(), path, chunk=65536)
    _, rows, summary = run(pid(), path, chunk=chunk)
    assert summary.rows == 25
    assert rows == ref_rows


def test_replay_continues_from_block_state(tmp_path: Path) -> None:
    """Replaying two halves through the same block equals replaying the whole file."""
    data = [[0.1 * k, 50, 40 + (k % 5)] for k in range(20)]
    whole = write_csv(tmp_path / "whole.csv", ["dt", "sp", "pv"],
                      [[0.1, r[1], r[2]] for r in data])
    first = write_csv(tmp_path / "a.csv", ["dt", "sp", "pv"],
                      [[0.1, r[1], r[2]] for r in data[:10]])
    second = write_csv(tmp_path / "b.csv", ["dt", "sp", "pv"],
                       [[0.1, r[1], r[2]] for r in data[10:]])
    _, ref, _ = run(pid(), whole)
    blk = pid()
    _, r1, _ = run(blk, first)
    _, r2, _ = run(blk, second)
    got = [r[1:] for r in r1 + r2]
    assert got == [r[1:] for r in ref]


# -- errors of the API ------------------------------------------------------------------------


@pytest.mark.parametrize(("text", "needle"), [
    ("", "empty"),
    ("t,sp,pv\n", "no data rows"),
    ("sp,pv\n1,2\n", "no timing"),
    ("t,dt,sp,pv\n0,1,1,2\n1,1,1,2\n", "timing given twice"),
    ("t,sp,pv,foo\n0,1,2,3\n", "unknown column 'foo'"),
    ("t,sp,pv\n0,1,2\n1,1,x\n", "line 3, column 'pv'"),
    ("t,sp,pv\n0,1,2\n1,,2\n", "line 3, column 'sp'"),
    ("t,sp,pv\n0,1,2\n0,1,2\n", "does not increase"),
    ("dt,sp,pv\n0.1,1,2\n-0.1,1,2\n", "dt must be > 0"),
    ("t,sp,pv,pv.ST\n0,1,2,128\n1,1,2,300\n", "status byte"),
    # a quote never closed: named where it opens (it was "line 4: 2 cells"; an audit)
    ("t,sp,pv\n0,1,2\n1,\"1,2\n2,1,2\n", "line 3, column 'sp': a quote (\") opens there and "
     "is never closed (the cell runs on to line 4)"),
    # a status without its value would run the block on a value the file does not give
    ("t,sp,pv.ST\n0,1,128\n1,1,128\n", "no column 'pv' for its value"),
    # a mode code out of range: what is allowed, not "not a number" (found by an audit)
    ("t,sp,pv,mode\n0,1,2,3\n", "line 2, column 'mode': '3' is not one of MAN, AUTO, CAS "
     "or their codes 0..2"),
])
def test_api_errors_are_file_format_errors(tmp_path: Path, text: str, needle: str) -> None:
    path = tmp_path / "bad.csv"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(FileFormatError) as info:
        replay(pid(), path, io.StringIO())
    message = str(info.value)
    assert message.startswith(str(path))  # names the file
    assert needle in message.replace(str(path), "<file>")


def test_timing_twice_with_t_column_and_dt_argument(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "in.csv", ["t", "sp", "pv"], [[0, 1, 2], [1, 1, 2]])
    with pytest.raises(FileFormatError, match="timing given twice"):
        replay(pid(), path, io.StringIO(), dt=0.1)


@pytest.mark.parametrize("dt", [0.0, -1.0, math.inf, math.nan])
def test_dt_argument_must_be_positive_and_finite(tmp_path: Path, dt: float) -> None:
    path = write_csv(tmp_path / "in.csv", ["sp", "pv"], [[1, 2]])
    with pytest.raises(InputError, match="dt must be > 0"):
        replay(pid(), path, io.StringIO(), dt=dt)


def test_failed_replay_leaves_no_output_file(tmp_path: Path) -> None:
    rows: list[list[object]] = [[0.1 * k, 50, 40] for k in range(500)]
    rows[350][2] = "oops"  # well after several chunks have been written
    path = write_csv(tmp_path / "in.csv", ["t", "sp", "pv"], rows)
    out = tmp_path / "out.csv"
    with pytest.raises(FileFormatError, match="line 352, column 'pv'"):
        replay(pid(), path, out, chunk=50)
    assert not out.exists()
    assert list(tmp_path.iterdir()) == [path]  # no partial file either


# -- size and streaming -----------------------------------------------------------------------


def write_big(path: Path, n: int, seed: int = 1) -> Path:
    rng = random.Random(seed)
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("t,sp,pv\n")
        for k in range(n):
            fh.write(f"{k * 0.1:.1f},{50 + rng.random():.6f},{40 + 20 * rng.random():.6f}\n")
    return path


def test_ten_thousand_rows(tmp_path: Path) -> None:
    n = 10_000
    path = write_big(tmp_path / "in.csv", n)
    out = tmp_path / "out.csv"
    summary = replay(pid(), path, out)
    data = np.loadtxt(out, delimiter=",", skiprows=1)
    with open(out, encoding="utf-8") as fh:
        assert fh.readline().strip().split(",") == OUT_HEADER
    assert data.shape == (n, 6)
    assert summary.rows == n
    assert np.all(np.isfinite(data))
    np.testing.assert_allclose(data[:, 0], np.round(np.arange(n) * 0.1, 1), atol=1e-9)
    assert summary.t_end == pytest.approx((n - 1) * 0.1)
    assert np.all((data[:, 1] >= 0.0) & (data[:, 1] <= 100.0))


def test_ten_thousand_rows_with_dt_argument_time_column(tmp_path: Path) -> None:
    n = 10_000
    path = tmp_path / "in.csv"
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("sp,pv\n")
        fh.writelines(f"50,{40 + k % 13}\n" for k in range(n))
    header, rows, summary = run(pid(), path, dt=0.25)
    t = np.array(col(header, rows, "t"))
    assert len(t) == n == summary.rows
    np.testing.assert_allclose(t, np.arange(n) * 0.25, rtol=0, atol=1e-9)


def _traced_peak(path: Path, out: Path, chunk: int) -> int:
    block = pid()
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        summary = replay(block, path, out, chunk=chunk)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert out.exists() and summary.rows > 0
    return peak


def test_replay_memory_does_not_grow_with_the_file(tmp_path: Path) -> None:
    # 40,000 vs 4,000 rows (10x): reading the big file into memory would take ~10 MB, far more
    # than a chunk of 500 rows; sizes are kept small because tracemalloc slows parsing ~10x.
    small = write_big(tmp_path / "small.csv", 4_000)
    large = write_big(tmp_path / "large.csv", 40_000)
    out = tmp_path / "out.csv"
    replay(pid(), small, out, chunk=500)  # warm up: imports, compiled kernels
    peak_small = _traced_peak(small, out, 500)
    peak_large = _traced_peak(large, out, 500)
    with open(out, encoding="utf-8") as fh:
        assert sum(1 for _ in fh) == 40_001
    assert peak_large < 1.5 * peak_small, (peak_small, peak_large)


# -- files that used to end in a traceback (issue 11) -------------------------------------------


def test_bytes_that_are_not_utf8_are_a_located_error(tmp_path: Path) -> None:
    path = tmp_path / "latin1.csv"
    path.write_bytes(b"t,sp,pv\n0,50,40\n1,50,40\n2,50,4\xb0\n")
    with pytest.raises(FileFormatError, match=r"latin1\.csv, line 4, column 'pv': .* is not a "
                                              r"number .*the file is not UTF-8 text"):
        run(pid(), path)


def test_a_utf16_file_is_named_as_not_utf8(tmp_path: Path) -> None:
    path = tmp_path / "u16.csv"
    path.write_bytes("t,sp,pv\n0,50,40\n".encode("utf-16"))
    with pytest.raises(FileFormatError, match=r"u16\.csv, line 1: unknown column .*not UTF-8"):
        run(pid(), path)


def test_an_oversized_field_is_a_located_error(tmp_path: Path) -> None:
    path = tmp_path / "big.csv"
    path.write_text("t,sp,pv\n0,50,40\n1,50,\"" + "4" * 200_000 + "\"\n", encoding="utf-8")
    with pytest.raises(FileFormatError, match=r"big\.csv, line \d+: field larger than field "
                                              r"limit"):
        run(pid(), path)


def test_an_output_that_is_a_directory_is_refused_before_writing(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "in.csv", ["t", "sp", "pv"], [[0, 50, 40], [1, 50, 40]])
    target = tmp_path / "out"
    target.mkdir()
    with pytest.raises(FileFormatError, match=r"out: is a directory"):
        replay(pid(), path, target)
    assert sorted(tmp_path.iterdir()) == sorted([path, target])  # no partial file left
    assert list(target.iterdir()) == []


def test_an_accumulated_time_that_overflows_is_refused(tmp_path: Path) -> None:
    """t_0 = 0, t_1 = 1e308, t_2 = 2e308 = inf: the output's t column would not be a time."""
    path = write_csv(tmp_path / "in.csv", ["dt", "sp", "pv"],
                     [[1e308, 50, 40], [1e308, 50, 40], [1e308, 50, 40]])
    with pytest.raises(FileFormatError, match=r"in\.csv, line 4: the accumulated time overflows"):
        run(pid(), path)


def test_an_unclosed_quote_in_the_header_is_one_located_line(tmp_path: Path) -> None:
    """A header quote that is never closed swallows the rows into one column name: the error
    is one line naming the file, line 1 and the column (found by the parser fuzz)."""
    from loopworks import create_block
    from loopworks.errors import FileFormatError
    from loopworks.sim.replay import replay

    path = tmp_path / "in.csv"
    path.write_text('t,"sp,pv\n0,50,40\n1,50,41\n', encoding="utf-8")
    block = create_block("pid", k=2.0, ti=10.0, jit=False)
    with pytest.raises(FileFormatError) as err:
        replay(block, path, io.StringIO())
    message = str(err.value)
    assert "\n" not in message
    assert f"{path}, line 1: column 2 ('sp,pv...') opens a quote" in message


def test_a_scan_time_the_block_cannot_run_is_located_before_any_output(tmp_path: Path) -> None:
    """A file's scan time that the block refuses (a dead time longer than its delay line at
    1 ms) names the file, the data row and its time, and nothing is written: the message
    named neither, after the output's header had gone out (found by an outside audit)."""
    text = "t,u\n0,1\n0.1,1\n0.2,1\n0.3,1\n0.4,1\n0.5,1\n0.501,1\n0.6,1\n"
    path = tmp_path / "short_dt.csv"
    path.write_text(text, encoding="utf-8")
    out = io.StringIO()
    fopdt = create_block("process.fopdt", gain=1.0, time_constant=5.0, dead_time=2.0,
                         delay_capacity=1000)
    with pytest.raises(FileFormatError) as info:
        replay(fopdt, path, out)
    assert str(info.value).startswith(f"{path}, data row 7 (t = 0.501 s, a scan of 0.001 s)")
    assert "delay_capacity" in str(info.value)
    assert out.getvalue() == ""


def test_an_error_after_rows_went_to_stdout_says_the_output_is_incomplete(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A stream cannot be taken back: a bad cell found after the first rows went to standard
    output (a file of more than one chunk) says how many were written and that the output is
    incomplete. Before, the rows written ended on a line that looked like a whole file's
    last, and only the exit status told (found by an outside audit)."""
    rows = ["t,sp,pv"] + [f"{i * 0.1:.1f},50,{40 + (i % 7)}" for i in range(100_000)]
    rows[70_001] = rows[70_001].replace(",50,", ",bogus,")
    path = tmp_path / "partial.csv"
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    with pytest.raises(FileFormatError) as info:
        replay(pid(), path, None)
    written = capsys.readouterr().out.splitlines()
    message = str(info.value)
    assert message.startswith(f"{path}, line 70002, column 'sp': 'bogus' is not a number")
    assert f"({len(written) - 1} rows were already written to standard output: that output " \
           "is incomplete)" in message
    assert len(written) > 1  # the case this is about: rows had gone out


@pytest.mark.parametrize("rows", [12, 12_000])  # row by row, and in bulk (64 KiB and more)
def test_a_dt_argument_puts_row_k_at_k_dt(tmp_path: Path, rows: int) -> None:
    """README, "Replay CSV": with --dt row k is at t = k·dt, as a module's scans are. A
    running sum wrote 0.7999999999999999 for the 9th row at 0.1 s and drifted further on
    (3.900000000000002; found by an outside audit)."""
    path = write_csv(tmp_path / "in.csv", ["sp", "pv"], [[1, 0.5]] * rows)
    out = io.StringIO()
    replay(pid(), path, out, dt=0.1)
    ts = [line.split(",")[0] for line in out.getvalue().splitlines()[1:]]
    assert ts == [repr(k * 0.1) for k in range(rows)]
    assert ts[8] == "0.8"


def test_the_first_row_at_a_refused_scan_time_is_the_one_named(tmp_path: Path) -> None:
    """Of several scan times the block refuses, the file's first such row is named: the
    smallest refused scan time was, wherever it lay (a process.tf at sample_time 0.5 s with
    a 0.8 s interval on data row 4 and 0.3 s intervals later was named at a later row;
    found by an outside audit)."""
    t = [0.0, 0.5, 1.0, 1.8, 2.3, 2.6, 3.1, 3.4]  # intervals 0.5 0.5 0.8 0.5 0.3 0.5 0.3
    path = write_csv(tmp_path / "tf.csv", ["t", "u"], [[x, 1.0] for x in t])
    tf = create_block("process.tf", num=[1.0], den=[5.0, 1.0], sample_time=0.5)
    with pytest.raises(FileFormatError) as info:
        replay(tf, path, io.StringIO())
    assert str(info.value).startswith(f"{path}, data row 4 (t = 1.8 s, a scan of 0.8 s)")
