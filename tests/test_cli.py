"""The ``loopworks`` command line: replay, blocks and simulate.

In-process tests use ``typer.testing.CliRunner``. In this typer version ``result.output`` mixes
standard output and standard error, while ``result.stdout`` and ``result.stderr`` are separate;
the tests read the two separately. Expected numbers are computed by hand from the pid equations.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from loopworks.blocks.pid import PID
from loopworks.cli import app
from tests.csvfiles import write_csv

OUT_HEADER = ["t", "out", "p_term", "i_term", "d_term", "out.ST"]

SCENARIO = """\
[simulation]
dt = 0.1
duration = 20.0

[blocks.pid]
kind = "pid"
k = 1.0
ti = 20.0
sp = 50.0

[blocks.process]
kind = "process.first_order"
gain = 2.0
time_constant = 20.0

[wires]
"process.u" = "pid.out"
"pid.pv" = "process.y"
"""


def invoke(*args: str, columns: int | None = None):
    env = {"COLUMNS": str(columns)} if columns is not None else None
    return CliRunner().invoke(app, list(args), env=env)


def table(text: str) -> tuple[list[str], list[list[str]]]:
    rows = list(csv.reader(io.StringIO(text)))
    return rows[0], rows[1:]


def column(header: list[str], rows: list[list[str]], name: str) -> list[float]:
    i = header.index(name)
    return [float(r[i]) for r in rows]


def assert_user_error(result, *needles: str) -> str:
    """Exit code 2, exactly one ``error:`` line on stderr, no traceback; return the line."""
    assert result.exit_code == 2, (result.exit_code, result.output)
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("error: ")
    assert "Traceback" not in result.output
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


@pytest.fixture
def simple_csv(tmp_path: Path) -> Path:
    return write_csv(tmp_path / "in.csv", ["t", "sp", "pv"],
                     [[0.0, 50, 40], [0.1, 50, 40], [0.2, 50, 41]])


# -- replay: results ---------------------------------------------------------------------------


def test_replay_to_stdout_matches_hand_computed_values(simple_csv: Path) -> None:
    result = invoke("replay", "pid", str(simple_csv), "-p", "k=2", "-p", "ti=10")
    assert result.exit_code == 0, result.output
    header, rows = table(result.stdout)
    assert header == OUT_HEADER
    dt = 0.1
    i0 = (2 / 10) * dt * 10
    i1 = i0 + (2 / 10) * dt * 10
    i2 = i1 + (2 / 10) * dt * 9
    assert column(header, rows, "out") == pytest.approx([20 + i0, 20 + i1, 18 + i2], abs=1e-12)
    assert column(header, rows, "out")[0] == pytest.approx(2 * (50 - 40) + (2 / 10) * dt * 10)
    assert column(header, rows, "p_term") == pytest.approx([20.0, 20.0, 18.0])
    assert column(header, rows, "t") == [0.0, 0.1, 0.2]
    assert [r[-1] for r in rows] == ["128"] * 3


def test_replay_to_a_file(simple_csv: Path, tmp_path: Path) -> None:
    out = tmp_path / "out.csv"
    result = invoke("replay", "pid", str(simple_csv), "-p", "k=2", "-p", "ti=10", "-o", str(out))
    assert result.exit_code == 0, result.output
    assert result.stdout == ""  # the data goes to the file, the summary to stderr
    assert "3 rows" in result.stderr
    header, rows = table(out.read_text(encoding="utf-8"))
    assert header == OUT_HEADER
    assert column(header, rows, "out") == pytest.approx([20.2, 20.4, 18.58])


def test_replay_column_names_in_any_case(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "in.csv", ["T", "Sp", "PV"], [[0, 50, 40], [1, 50, 42]])
    result = invoke("replay", "pid", str(path), "-p", "k=2", "-p", "ti=10")
    assert result.exit_code == 0, result.output
    header, rows = table(result.stdout)
    # 2·10 + 0.2·1·10 = 22; 2·8 + 2 + 0.2·1·8 = 19.6
    assert column(header, rows, "out") == pytest.approx([22.0, 19.6])


def test_replay_status_column_bad_pv_holds(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "in.csv", ["t", "sp", "pv", "pv.ST"],
                     [[0, 50, 40, 128], [1, 50, 45, 0], [2, 50, 45, 128]])
    result = invoke("replay", "pid", str(path), "-p", "k=2", "-p", "ti=10")
    assert result.exit_code == 0, result.output
    header, rows = table(result.stdout)
    assert column(header, rows, "out") == pytest.approx([22.0, 22.0, 23.0])
    assert [int(r[header.index("out.ST")]) for r in rows] == [128, 71, 128]


def test_replay_mode_names(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "in.csv", ["t", "sp", "pv", "Mode", "man_out"],
                     [[0, 50, 40, "AUTO", "nan"], [1, 50, 40, "MAN", 30],
                      [2, 50, 40, "AUTO", "nan"]])
    result = invoke("replay", "pid", str(path), "-p", "k=2", "-p", "ti=10")
    assert result.exit_code == 0, result.output
    header, rows = table(result.stdout)
    # AUTO: 22; MAN: 30 (Constant, 131); AUTO again: 20 + (30 - 20) + 0.2·1·10 = 32
    assert column(header, rows, "out") == pytest.approx([22.0, 30.0, 32.0])
    assert [int(r[-1]) for r in rows] == [128, 131, 128]


def test_replay_timing_from_dt_column(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "in.csv", ["dt", "sp", "pv"], [[0.5, 50, 40], [0.25, 50, 40]])
    result = invoke("replay", "pid", str(path), "-p", "k=2", "-p", "ti=10")
    assert result.exit_code == 0, result.output
    header, rows = table(result.stdout)
    assert column(header, rows, "t") == pytest.approx([0.0, 0.25])
    # ΔI = 0.2·dt·10 = 2·dt: 1.0, then 0.5
    assert column(header, rows, "out") == pytest.approx([21.0, 21.5])


def test_replay_timing_from_dt_option(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "in.csv", ["sp", "pv"], [[50, 40], [50, 40], [50, 40]])
    result = invoke("replay", "pid", str(path), "-p", "k=2", "-p", "ti=10", "--dt", "0.5")
    assert result.exit_code == 0, result.output
    header, rows = table(result.stdout)
    assert column(header, rows, "t") == pytest.approx([0.0, 0.5, 1.0])
    assert column(header, rows, "out") == pytest.approx([21.0, 22.0, 23.0])


def test_replay_dt_option_with_t_column_is_timing_twice(simple_csv: Path) -> None:
    result = invoke("replay", "pid", str(simple_csv), "--dt", "0.1")
    assert_user_error(result, "timing given twice")


def test_replay_dt_option_must_be_positive(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "in.csv", ["sp", "pv"], [[50, 40], [50, 40]])
    result = invoke("replay", "pid", str(path), "--dt", "0")
    assert_user_error(result, "dt must be > 0")


def test_replay_params_file_and_p_override(tmp_path: Path, simple_csv: Path) -> None:
    params = tmp_path / "pid.toml"
    params.write_text('kind = "pid"\nk = 2.0\nti = 10.0\nout_hi = 30.0\n', encoding="utf-8")
    result = invoke("replay", "pid", str(simple_csv), "--params", str(params))
    assert result.exit_code == 0, result.output
    header, rows = table(result.stdout)
    assert column(header, rows, "out") == pytest.approx([20.2, 20.4, 18.58])

    # -p overrides the file: k = 4 gives 40 + 0.4·0.1·10 = 40.4, clamped at out_hi = 30
    result = invoke("replay", "pid", str(simple_csv), "--params", str(params), "-p", "k=4",
                    "-p", "out_hi=100")
    assert result.exit_code == 0, result.output
    header, rows = table(result.stdout)
    assert column(header, rows, "out")[0] == pytest.approx(40.4)
    assert column(header, rows, "p_term")[0] == pytest.approx(40.0)

    result = invoke("replay", "pid", str(simple_csv), "--params", str(params), "-p", "k=4")
    header, rows = table(result.stdout)
    assert column(header, rows, "out")[0] == 30.0  # out_hi from the file still applies
    assert int(rows[0][-1]) == 130
    # in any letter case (-p K=4 beside the file's k was refused as a parameter given twice)
    result = invoke("replay", "pid", str(simple_csv), "--params", str(params), "-p", "K=4",
                    "-p", "OUT_HI=100")
    assert result.exit_code == 0, result.output
    assert column(*table(result.stdout), "out")[0] == pytest.approx(40.4)


def test_replay_params_file_unknown_parameter(tmp_path: Path, simple_csv: Path) -> None:
    params = tmp_path / "pid.toml"
    params.write_text("k = 2.0\ngain = 3.0\n", encoding="utf-8")
    result = invoke("replay", "pid", str(simple_csv), "--params", str(params))
    line = assert_user_error(result, str(params), "gain")  # the file is named (outside audit)
    for p in PID.PARAMS:
        assert p.name in line
    params.write_text("k = 2.0\nti = -10.0\n", encoding="utf-8")
    result = invoke("replay", "pid", str(simple_csv), "--params", str(params))
    assert_user_error(result, str(params), "'ti' = -10", "(0, inf]")
    result = invoke("replay", "pid", str(simple_csv), "--params", str(params), "-p", "k=3")
    assert_user_error(result, f"{params} (with the -p options)", "'ti' = -10")


def test_replay_params_file_wrong_kind(tmp_path: Path, simple_csv: Path) -> None:
    params = tmp_path / "p.toml"
    params.write_text('kind = "process.first_order"\ngain = 3.0\n', encoding="utf-8")
    result = invoke("replay", "pid", str(simple_csv), "--params", str(params))
    assert_user_error(result, str(params), "kind")


def test_replay_ten_thousand_rows(tmp_path: Path) -> None:
    n = 10_000
    path = tmp_path / "big.csv"
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("t,sp,pv\n")
        fh.writelines(f"{k * 0.1:.1f},{50 + k % 11},{45 + k % 7}\n" for k in range(n))
    out = tmp_path / "out.csv"
    result = invoke("replay", "pid", str(path), "-p", "k=2", "-p", "ti=10", "-o", str(out))
    assert result.exit_code == 0, result.output
    assert f"{n} rows" in result.stderr
    header, rows = table(out.read_text(encoding="utf-8"))
    assert header == OUT_HEADER
    assert len(rows) == n
    values = [[float(c) for c in r] for r in rows]
    assert all(math.isfinite(v) for r in values for v in r)
    assert [r[0] for r in values] == [round(k * 0.1, 1) for k in range(n)]
    # first row by hand: e = 5, dt = 0.1: 2·5 + 0.2·0.1·5
    assert values[0][1] == pytest.approx(10.1)


# -- replay: errors ----------------------------------------------------------------------------


@pytest.mark.parametrize(("text", "needles"), [
    pytest.param("t,sp,pv,foo\n0,1,2,3\n",
                 ["unknown column 'foo'", "t, dt, sp, pv", "pv.ST"], id="unknown-column"),
    pytest.param("t,sp,pv\n0,50,40\n0.1,50,abc\n", ["line 3", "'pv'", "abc"], id="non-numeric"),
    pytest.param("t,sp,pv\n0,50,40\n0.1,,40\n", ["line 3", "'sp'"], id="empty-cell"),
    pytest.param("", ["empty"], id="empty-file"),
    pytest.param("t,sp,pv\n", ["no data rows"], id="header-only"),
    pytest.param("sp,pv\n50,40\n", ["no timing"], id="no-timing"),
    pytest.param("t,dt,sp,pv\n0,1,50,40\n", ["timing given twice"], id="timing-twice"),
    pytest.param("t,sp,pv\n0,50,40\n1,50,40\n1,50,40\n", ["line 4", "does not increase"],
                 id="t-not-increasing"),
    pytest.param("t,sp,pv\n0,50,40\n1,50,40\n0.5,50,40\n", ["line 4", "does not increase"],
                 id="t-decreasing"),
    pytest.param("dt,sp,pv\n0.1,50,40\n0,50,40\n", ["line 3", "dt must be > 0"], id="dt-zero"),
    pytest.param("dt,sp,pv\n-0.1,50,40\n", ["line 2", "dt must be > 0"], id="dt-negative"),
    pytest.param("t,sp,pv,pv.ST\n0,50,40,128\n1,50,40,256\n", ["line 3", "pv.ST", "0..255"],
                 id="status-256"),
    pytest.param("t,sp,pv,pv.ST\n0,50,40,-1\n", ["line 2", "pv.ST", "0..255"],
                 id="status-negative"),
    pytest.param("t,sp,pv,mode\n0,50,40,MANUAL\n", ["line 2", "'mode'", "MAN, AUTO, CAS"],
                 id="bad-mode"),
    pytest.param("t,sp,pv\n0,50,40\n1,50\n", ["line 3", "cells"], id="short-row"),
])
def test_replay_file_errors(tmp_path: Path, text: str, needles: list[str]) -> None:
    path = tmp_path / "in.csv"
    path.write_text(text, encoding="utf-8")
    result = invoke("replay", "pid", str(path))
    assert_user_error(result, "in.csv", *needles)


def test_replay_unknown_parameter_lists_valid_names(simple_csv: Path) -> None:
    line = assert_user_error(invoke("replay", "pid", str(simple_csv), "-p", "gain=2"), "'gain'")
    for p in PID.PARAMS:
        assert p.name in line


def test_replay_parameter_out_of_range(simple_csv: Path) -> None:
    assert_user_error(invoke("replay", "pid", str(simple_csv), "-p", "k=-1"), "'k'")


def test_replay_out_lo_not_below_out_hi(simple_csv: Path) -> None:
    result = invoke("replay", "pid", str(simple_csv), "-p", "out_lo=50", "-p", "out_hi=50")
    assert_user_error(result, "out_hi", "out_lo")


def test_replay_malformed_p_option(simple_csv: Path) -> None:
    assert_user_error(invoke("replay", "pid", str(simple_csv), "-p", "k"), "NAME=VALUE")


def test_replay_unknown_block_kind(simple_csv: Path) -> None:
    assert_user_error(invoke("replay", "nosuch", str(simple_csv)), "nosuch", "pid",
                      "process.first_order")


def test_replay_missing_input_file(tmp_path: Path) -> None:
    missing = tmp_path / "missing.csv"
    assert_user_error(invoke("replay", "pid", str(missing)), "missing.csv")


@pytest.mark.parametrize("bad_row", [1, 9000])
def test_failed_replay_leaves_no_output_file(tmp_path: Path, bad_row: int) -> None:
    path = tmp_path / "in.csv"
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("t,sp,pv\n")
        for k in range(10_000):
            fh.write(f"{k * 0.1:.1f},50,{'x' if k == bad_row else 40}\n")
    out = tmp_path / "out.csv"
    result = invoke("replay", "pid", str(path), "-o", str(out))
    assert_user_error(result, f"line {bad_row + 2}", "'pv'")
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.csv"]


def test_failed_replay_before_reading_rows_leaves_no_output_file(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "in.csv", ["t", "sp", "bogus"], [[0, 1, 2]])
    out = tmp_path / "out.csv"
    assert_user_error(invoke("replay", "pid", str(path), "-o", str(out)), "bogus")
    assert not out.exists()


def test_user_error_in_a_subprocess_is_one_line(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "in.csv", ["t", "sp", "pv", "temperature"], [[0, 1, 2, 3]])
    proc = subprocess.run([sys.executable, "-m", "loopworks", "replay", "pid", str(path)],
                          capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert proc.returncode == 2
    lines = proc.stderr.splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("error:")
    assert "temperature" in lines[0] and "valid columns" in lines[0]
    assert "Traceback" not in proc.stderr


def test_replay_in_a_subprocess(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "in.csv", ["t", "sp", "pv"], [[0, 50, 40], [1, 50, 40]])
    proc = subprocess.run([sys.executable, "-m", "loopworks", "replay", "pid", str(path),
                           "-p", "k=2", "-p", "ti=10"],
                          capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    header, rows = table(proc.stdout)
    assert header == OUT_HEADER
    assert column(header, rows, "out") == pytest.approx([22.0, 24.0])


EXIT_CHILD = """
import atexit, sys, threading, time
from loopworks.cli import _exit
atexit.register(lambda: print("exit handler ran", flush=True))
print("buffered output", end="")  # not flushed yet: _exit must flush it
if sys.argv[1] == "thread":  # a thread still running: the exit waits for it
    threading.Thread(target=lambda: (time.sleep(0.3), print(" thread done"))).start()
_exit({"int": 3, "none": None, "text": "a message", "thread": 4}[sys.argv[1]])
print("never")
"""


@pytest.mark.parametrize(("case", "status", "out", "err"), [
    ("int", 3, "buffered outputexit handler ran\n", ""),
    ("none", 0, "buffered outputexit handler ran\n", ""),
    ("text", 1, "buffered outputexit handler ran\n", "a message\n"),
    ("thread", 4, "buffered output thread done\nexit handler ran\n", ""),
])
def test_the_console_script_exits_as_sys_exit_does(case: str, status: int, out: str,
                                                   err: str) -> None:
    """main() ends the process without the interpreter's finalization (cli._exit): the
    status sys.exit gives, the exit handlers run, buffered output flushed, and a thread
    still running is waited for (the normal exit then)."""
    proc = subprocess.run([sys.executable, "-c", EXIT_CHILD, case], capture_output=True,
                          text=True, timeout=120)
    assert (proc.returncode, proc.stdout, proc.stderr) == (status, out, err)


# -- blocks ------------------------------------------------------------------------------------


def test_blocks_lists_kinds() -> None:
    result = invoke("blocks")
    assert result.exit_code == 0, result.output
    assert "pid" in result.stdout.split()
    assert "process.first_order" in result.stdout


def parse_tables(text: str) -> dict[str, dict[str, list[str]]]:
    """Rich tables (title line, then │-separated rows, wrapped cells continued on lines with an
    empty first cell) as {title: {name: [cell, ...]}} with wrapped fragments joined."""
    tables: dict[str, dict[str, list[str]]] = {}
    current: dict[str, list[str]] | None = None
    name = ""
    for line in text.splitlines():
        stripped = line.strip()
        if stripped in ("parameters", "inputs", "outputs"):
            current = tables.setdefault(stripped, {})
            continue
        if current is None or not stripped.startswith("│"):
            continue
        cells = [c.strip() for c in stripped.strip("│").split("│")]
        if cells[0]:
            name = cells[0]
            current[name] = cells
        else:
            current[name] = [(a + " " + b).strip() for a, b in zip(current[name], cells,
                                                                   strict=True)]
    return tables


def check_pid_description(text: str, folded: bool = False) -> None:
    """Every parameter with its unit and range, every input and output. ``folded``: the cells
    may be folded across lines (compare without whitespace), but nothing may be cut off."""
    def same(a: str, b: str) -> bool:
        return "".join(a.split()) == "".join(b.split()) if folded else a == b

    tables = parse_tables(text)
    params = tables["parameters"]
    assert list(params) == [p.name for p in PID.PARAMS]
    for p in PID.PARAMS:
        _name, unit, _default, rng, _meaning = params[p.name]
        assert same(unit, p.unit), (p.name, unit)
        assert same(rng, p.range_text()), (p.name, rng)
    assert list(tables["inputs"]) == [port.name for port in PID.INPUTS]
    assert list(tables["outputs"]) == [port.name for port in PID.OUTPUTS]
    assert tables["outputs"]["out"][2] == "yes"  # out carries status


def test_blocks_pid_describes_every_parameter_wide_terminal() -> None:
    result = invoke("blocks", "pid", columns=250)
    assert result.exit_code == 0, result.output
    check_pid_description(result.stdout)


def test_blocks_pid_describes_every_parameter_80_columns() -> None:
    """At the standard 80 columns (also what a pipe or a file gets), nothing is cut off."""
    result = invoke("blocks", "pid", columns=80)
    assert result.exit_code == 0, result.output
    assert "…" not in result.stdout
    check_pid_description(result.stdout, folded=True)


def test_blocks_any_letter_case() -> None:
    result = invoke("blocks", "PID", columns=250)
    assert result.exit_code == 0, result.output
    check_pid_description(result.stdout)


def test_blocks_first_order() -> None:
    result = invoke("blocks", "process.first_order", columns=250)
    assert result.exit_code == 0, result.output
    tables = parse_tables(result.stdout)
    assert list(tables["parameters"]) == ["gain", "time_constant", "y0"]
    assert list(tables["inputs"]) == ["u"]
    assert list(tables["outputs"]) == ["y"]


def squeeze(text: str) -> str:
    return "".join(text.split())


def test_blocks_prints_bracketed_text_as_written() -> None:
    """Rich markup once swallowed "[output: its initial value]" (deltav.calc) and other
    bracketed text; every kind's every meaning now reads as declared."""
    from loopworks.blocks import reference
    from loopworks.catalog import block_class, kinds

    calc = invoke("blocks", "deltav.calc", columns=250)
    assert calc.exit_code == 0, calc.output
    assert "dither amplitude (line 2) [output: its initial value]" in calc.stdout
    for kind in kinds():
        cls = block_class(kind)
        result = invoke("blocks", kind, columns=250)
        assert result.exit_code == 0, (kind, result.output)
        tables = parse_tables(result.stdout)
        for title, rows in (("parameters", reference.parameter_rows(cls)),
                            ("inputs", reference.input_rows(cls)),
                            ("outputs", reference.output_rows(cls))):
            for row in rows:
                shown = tables[title][row[0]]
                assert [squeeze(c) for c in shown] == [squeeze(c) for c in row], (kind, row[0])
    listing = squeeze(invoke("blocks", columns=400).stdout)
    for kind in kinds():
        assert squeeze(block_class(kind).describe()) in listing, kind


def test_help_prints_bracketed_text_as_written() -> None:
    """"[compare]" and "[autotune]" are TOML tables, not markup: they stay in --help."""
    simulate = invoke("simulate", "--help", columns=120)
    assert "each [compare] variant" in simulate.stdout
    tune = invoke("tune", "--help", columns=200)
    assert squeeze("A scenario with an [autotune] table") in squeeze(tune.stdout)
    assert squeeze("(default: the [autotune] loop)") in squeeze(tune.stdout)


def test_version() -> None:
    from importlib.metadata import version

    import loopworks

    result = invoke("--version")
    assert result.exit_code == 0, result.output
    assert result.stdout == f"loopworks {version('loopworks')}\n"
    assert loopworks.__version__ == version("loopworks")


def test_dir_shows_the_lazy_names_and_import_stays_light() -> None:
    code = ("import sys, loopworks\nnames = dir(loopworks)\n"
            "print('Module' in names, 'Signal' in names, "
            "sorted(m for m in ('numba', 'numpy', 'scipy', 'matplotlib') if m in sys.modules))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=60, check=True)
    assert proc.stdout.split() == ["True", "True", "[]"]


def test_help_of_create_block_names_every_kind() -> None:
    """The kinds are written in loopworks.create_block's docstring (import stays light);
    this keeps that list equal to the registry."""
    import pydoc
    import re

    import loopworks
    from loopworks.catalog import kinds

    shown = pydoc.plain(pydoc.render_doc(loopworks.create_block))  # what help() prints
    kinds_part = shown.split("The kinds")[1].split(">>>")[0]
    listed = re.findall(r"``([a-z0-9_.]+)``", kinds_part)
    assert sorted(listed) == kinds()


def test_blocks_unknown_kind() -> None:
    assert_user_error(invoke("blocks", "nosuch"), "nosuch", "pid", "process.first_order")


# -- simulate ----------------------------------------------------------------------------------


def test_simulate_builtin_scenario(tmp_path: Path) -> None:
    result = invoke("simulate", "-o", str(tmp_path / "report"), columns=120)
    assert result.exit_code == 0, result.output
    assert "IAE" in result.stdout
    assert "overshoot" in result.stdout
    assert result.stderr == ""
    assert (tmp_path / "report" / "report.html").exists()
    # the built-in scenario's [autotune] relay test (issue 6): printed, and in the report
    assert "[autotune] relay test on pid" in result.stdout
    tuned = json.loads((tmp_path / "report" / "autotune.json").read_text())
    assert tuned["outcome"] == "converged" and tuned["loop"] == "pid"
    assert "Relay auto-tune" in (tmp_path / "report" / "report.html").read_text()


def test_the_table_title_gives_the_duration_that_ran(tmp_path: Path) -> None:
    """A duration off the scan grid runs the nearest count of scans (warned); the table's
    title gave the duration as written (20.04 s for a 20 s run)."""
    scenario = tmp_path / "loop.toml"
    scenario.write_text(SCENARIO.replace("duration = 20.0", "duration = 20.04"), "utf-8")
    result = invoke("simulate", str(scenario), "-o", str(tmp_path / "r"), "-q", columns=200)
    assert result.exit_code == 0, result.output
    assert "200 scans (20 s)" in result.stderr
    assert " 20 s in scans of 0.1 s" in result.stdout and "20.04" not in result.stdout


def test_simulate_file_writes_the_report_directory(tmp_path: Path) -> None:
    scenario = tmp_path / "loop.toml"
    scenario.write_text(SCENARIO, encoding="utf-8")
    out = tmp_path / "report"
    result = invoke("simulate", str(scenario), "-o", str(out), "-q", columns=120)
    assert result.exit_code == 0, result.output
    assert "IAE" in result.stdout
    header, rows = table((out / "base.csv").read_text(encoding="utf-8"))
    assert header[0] == "t"
    assert "pid.out" in header and "process.y" in header
    assert len(rows) == 200  # 20 s in scans of 0.1 s
    t = column(header, rows, "t")
    assert t[1] - t[0] == pytest.approx(0.1)
    assert (out / "base.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    import json

    metrics = json.loads((out / "metrics.json").read_text())
    assert list(metrics) == ["base"] and "IAE" in metrics["base"]
    assert (out / "scenario.toml").read_text() == SCENARIO
    page = (out / "report.html").read_text()
    assert 'src="base.png"' in page and "IAE" in page


def test_simulate_json_prints_the_metrics_json_and_writes_no_report_unless_asked(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`simulate --json`: standard output is one JSON object, the report's metrics.json; no
    report directory unless -o is given (then the same file is written too)."""
    import json

    monkeypatch.chdir(tmp_path)
    scenario = tmp_path / "loop.toml"
    scenario.write_text(SCENARIO, encoding="utf-8")
    alone = CliRunner().invoke(app, ["simulate", str(scenario), "--json", "-q"])
    assert alone.exit_code == 0, alone.output
    assert list(tmp_path.iterdir()) == [scenario]  # no loopworks-report/
    printed = json.loads(alone.stdout)
    assert list(printed) == ["base"] and printed["base"]["IAE"] > 0.0
    both = CliRunner().invoke(app, ["simulate", str(scenario), "--json", "-q", "-o", "rep"])
    assert both.exit_code == 0, both.output
    assert json.loads(both.stdout) == printed
    assert (tmp_path / "rep" / "metrics.json").read_text() == both.stdout


@pytest.mark.parametrize(("edit", "needle"), [
    pytest.param(("[simulation]", "[simulation"), "invalid TOML", id="syntax"),
    pytest.param(("k = 1.0", "kk = 1.0"), "kk", id="unknown-parameter"),
    pytest.param(('"pid.out"', '"pid.outt"'), "outt", id="unknown-wire-port"),
    pytest.param(("dt = 0.1", "dt = 0.0"), "dt", id="dt-zero"),
    pytest.param(("dt = 0.1", "dt = -0.1"), "dt", id="dt-negative"),
])
def test_simulate_scenario_errors(tmp_path: Path, edit: tuple[str, str], needle: str) -> None:
    text = SCENARIO.replace(*edit, 1)
    assert text != SCENARIO
    scenario = tmp_path / "broken_scenario.toml"
    scenario.write_text(text, encoding="utf-8")
    out = tmp_path / "report"
    result = invoke("simulate", str(scenario), "-q", "-o", str(out))
    assert_user_error(result, "broken_scenario.toml", needle)
    assert not out.exists()


def test_simulate_missing_scenario_file(tmp_path: Path) -> None:
    assert_user_error(invoke("simulate", str(tmp_path / "nope.toml"), "-q"), "nope.toml")


def test_help_does_not_import_the_heavy_libraries() -> None:
    """`loopworks --help` stays fast: numba, scipy, matplotlib and numpy load only when used."""
    code = ("import sys\nfrom loopworks.cli import app\n"
            "print(sorted(m for m in ('numba', 'scipy', 'matplotlib', 'numpy', 'pandas')"
            " if m in sys.modules))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=60, check=True)
    assert proc.stdout.strip() == "[]"


def test_compile_fills_the_cache_so_later_commands_compile_nothing(tmp_path: Path) -> None:
    """`loopworks compile KIND ... --jobs N` compiles each kind's kernel into the plan cache
    (in N processes); run again it loads them; a later command in a fresh process then
    compiles nothing (no "compiling ..." announcement)."""
    env = {**os.environ, "LOOPWORKS_CACHE_DIR": str(tmp_path / "cache")}

    def run(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run([sys.executable, "-m", "loopworks", *args], capture_output=True,
                              text=True, env=env, timeout=600)

    first = run("compile", "valve.backlash", "sensor.transmitter", "--jobs", "2", "-q")
    assert first.returncode == 0, first.stderr
    assert first.stdout.startswith("2 of 2 kernels compiled, 0 loaded from the cache")
    again = run("compile", "valve.backlash", "sensor.transmitter", "-q")
    assert again.stdout.startswith("0 of 2 kernels compiled, 2 loaded from the cache")
    path = tmp_path / "op.csv"
    path.write_text("t,op\n0,10\n1,20\n2,15\n")
    replay = run("replay", "valve.backlash", str(path), "-p", "b=1")
    assert replay.returncode == 0, replay.stderr
    assert "compiling" not in replay.stderr and replay.stdout.startswith("t,")
    wrong = CliRunner().invoke(app, ["compile", "valve.nope"])  # refused before compiling
    assert wrong.exit_code == 2 and wrong.stderr.count("\n") == 1
    assert "valve.nope" in wrong.stderr and "valve.backlash" in wrong.stderr
    zero = CliRunner().invoke(app, ["compile", "pid", "--jobs", "0"])
    assert zero.exit_code == 2 and "--jobs 0" in zero.stderr


HELPERS_USED = """
import numpy as np
from loopworks.analysis import valve_fit
from loopworks.sim import floatfmt, metrics
ro = np.array([1.5, -2.25, 3.0]); ro.flags.writeable = False  # a pyarrow column's kind
assert floatfmt.float_text(ro) == ["1.5", "-2.25", "3.0"]
assert floatfmt.float_text(np.array([0.1])) == ["0.1"]
assert metrics.reversals(ro, 0.0) == 1 and metrics.reversals(np.array([0.0, 1.0, 0.0])) == 1
x = np.arange(40.0) % 7; y = np.roll(x, 2)  # every d, one d, two taps, read-only, a = 1
for args in ((0.5, 5, 1.0, None, 1), (0.5, 5, 1.0, 2, 1), (1.0, 5, 1.0, None, 2)):
    valve_fit._sse_all_d(x, y, args[0], args[1], args[2], only=args[3], taps=args[4])
valve_fit._sse_all_d(ro, ro, 0.5, 1, 1.0)
for disp in (floatfmt._format_rows, metrics._reversals_loop(), valve_fit._regress_fn()):
    # on disk (numba's cache=True: a later process loads it), one signature for every call
    print(type(disp._cache).__name__ != "NullCache", len(disp.signatures))
"""


def test_compile_without_kinds_also_compiles_the_helpers_once(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """`loopworks compile` (every kind) also compiles the CSV formatter and the metrics'
    reversal loop into numba's on-disk cache, each for the one signature later calls use: a
    read-only array (a pyarrow column) is no second signature to compile (it was: 8 s for the
    formatter, in a fresh install's first replay of a Parquet file). Checked in a fresh
    process, so no earlier call in this one has added a signature."""
    import loopworks.cli as cli

    used = subprocess.run([sys.executable, "-c", "from loopworks.cli import _compile_helpers;"
                           " _compile_helpers()\n" + HELPERS_USED], capture_output=True,
                          text=True, timeout=300)
    assert used.returncode == 0, used.stderr
    lines = used.stdout.splitlines()
    assert len(lines) == 3
    for line in lines:
        cached, signatures = line.split()
        assert (cached, signatures) == ("True", "1"), used.stdout
    calls: list[int] = []
    monkeypatch.setattr(cli, "_compile_helpers", lambda: calls.append(1))
    assert CliRunner().invoke(app, ["compile", "pid", "-q"]).exit_code == 0
    assert calls == []  # named kinds: only their kernels
    run = CliRunner().invoke(app, ["compile", "-q"])
    assert run.exit_code == 0 and calls == [1], run.output


def test_convert_json_gives_the_stated_errors_as_data() -> None:
    """docs/conversion.md: --json has "response_errors", the note's controller
    frequency-response errors at ω = 1/Ti and 1/Td; [] for an exact conversion."""
    args = ["convert", "--from", "pid", "--to", "s5.pid", "-p", "k=2", "-p", "ti=16", "-p",
            "td=2", "-p", "tf=0", "-p", "c=1", "--sample-time", "1", "--json"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert data["exact"] is False
    omegas = [e["omega"] for e in data["response_errors"]]
    assert omegas == [1 / 16, 1 / 2]  # 1/Ti, 1/Td
    for entry in data["response_errors"]:
        assert f"{entry['error']:.3g} at ω" in data["note"]
    assert data["unmodelled"] == []  # the figures hold every difference of the two laws
    exact = CliRunner().invoke(app, ["convert", "--from", "pid", "--to", "ge.pid_isa", "-p",
                                     "k=2", "-p", "ti=16", "-t",
                                     "arithmetic=float", "--json"])
    assert exact.exit_code == 0, exact.output
    assert json.loads(exact.stdout)["response_errors"] == []


TWO_LOOPS_ONE_VALVE = """
[simulation]
dt = 0.5
duration = 100.0

[blocks.a]
kind = "pid"
k = 1.0
ti = 10.0
sp = 50.0

[blocks.pa]
kind = "process.first_order"
gain = 1.0
time_constant = 5.0

[blocks.b]
kind = "pid"
k = 1.0
ti = 10.0
sp = 50.0

[blocks.vb]
kind = "valve.choudhury"
s = 1.0
j = 0.2

[blocks.pb]
kind = "process.first_order"
gain = 1.0
time_constant = 5.0

[wires]
"pa.u" = "a.out"
"a.pv" = "pa.y"
"vb.op" = "b.out"
"pb.u" = "vb.position"
"b.pv" = "pb.y"
"""


def test_simulate_prints_a_later_loops_valve_rows(tmp_path: Path) -> None:
    """Loop a has no valve, loop b drives one: the table took its rows from the first loop
    and dropped b's valve travel (in metrics.json, missing from the printed table; found by a
    user). Every loop's rows are printed, n/a where a loop has none."""
    path = tmp_path / "two.toml"
    path.write_text(TWO_LOOPS_ONE_VALVE, encoding="utf-8")
    result = CliRunner().invoke(app, ["simulate", str(path), "-o", str(tmp_path / "o"), "-q"])
    assert result.exit_code == 0, result.output
    saved = json.loads((tmp_path / "o" / "metrics.json").read_text(encoding="utf-8"))
    travel = saved["base: b"]["valve travel"]
    row = next(line for line in result.output.splitlines() if "valve travel" in line)
    assert "n/a" in row and f"{travel:.4g}" in row


def test_replay_reads_a_pipe(tmp_path: Path) -> None:
    """`loopworks replay pid /dev/stdin` (a pipe: not seekable) was an io.UnsupportedOperation
    traceback (found by a user); a pipe is read into memory first."""
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-m", "loopworks", "replay", "pid", "/dev/stdin"],
                          input="t,sp,pv\n0,1,0\n1,1,0.5\n", capture_output=True, text=True,
                          timeout=300, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines()[1:] == ["0.0,1.0,1.0,0.0,0.0,128",
                                            "1.0,0.5,0.5,0.0,0.0,128"]  # P = k·e, k = 1


def test_replay_takes_a_dash_for_standard_input_and_output(tmp_path: Path) -> None:
    """README, "Replay CSV": `-` reads standard input and `-o -` writes standard output (it
    wrote a file named "-", and `-` as the input was "cannot read the input"); an `-o` name
    of another format (`.parquet`) is refused (CSV text was written into it silently; found
    by an outside audit)."""
    runner = CliRunner()
    text = "t,sp,pv\n0,1,0\n1,1,0.5\n"
    done = runner.invoke(app, ["replay", "pid", "-", "-o", "-"], input=text)
    assert done.exit_code == 0, done.output
    assert done.stdout.splitlines()[1:] == ["0.0,1.0,1.0,0.0,0.0,128",
                                            "1.0,0.5,0.5,0.0,0.0,128"]  # P = k·e, k = 1
    assert not (Path.cwd() / "-").exists()
    path = tmp_path / "in.csv"
    path.write_text(text, encoding="utf-8")
    refused = runner.invoke(app, ["replay", "pid", str(path), "-o", str(tmp_path / "o.parquet")])
    assert refused.exit_code != 0 and "replay writes CSV text" in refused.output
    assert not (tmp_path / "o.parquet").exists()
    (tmp_path / "one.csv").write_text("sp,pv\n1,0\n", encoding="utf-8")
    one = runner.invoke(app, ["replay", "pid", "--dt", "1", str(tmp_path / "one.csv"), "-o",
                              str(tmp_path / "out.csv")])
    assert one.exit_code == 0 and "replayed 1 row " in one.output, one.output


def test_a_warning_is_one_line() -> None:
    """README: a cache that cannot be written gives one warning line; Python's format gave the
    file, line and source line too (found by a user)."""
    from loopworks.cli import _warning_line

    text = _warning_line(RuntimeWarning("loopworks: the plan cache /x cannot be written"),
                         RuntimeWarning, "/some/file.py", 12, "warnings.warn(...)")
    assert text == "warning: the plan cache /x cannot be written\n"


def test_convert_json_keeps_numbers_given_as_text_numbers() -> None:
    """`-p pv_scale_eu_100=200` passed through as the JSON string "200" (found by an outside
    audit): a numeric parameter is a JSON number."""
    import json

    result = invoke("convert", "--from", "deltav.pid", "--to", "deltav.pid", "-p", "gain=2",
                    "-p", "reset=16", "-p", "pv_scale_eu_100=200", "--json")
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert data["pv_scale_eu_100"] == 200 and not isinstance(data["pv_scale_eu_100"], str)
    assert all(not isinstance(data[k], str) for k in ("gain", "reset", "pv_scale_eu_0"))
