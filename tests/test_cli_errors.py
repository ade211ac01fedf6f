"""Ordinary mistakes on the command line (issue 11): each is one ``error:`` line and exit code 2,
found before the run, never a traceback. One test per path that used to crash, accept a wrong
input, or report late."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.csvfiles import write_csv
from tests.test_cli import SCENARIO, assert_user_error, invoke


def scenario_file(tmp_path: Path, text: str = SCENARIO, name: str = "case.toml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def simulate(tmp_path: Path, text: str, *extra: str):
    """Run ``simulate`` on ``text``; the report directory is tmp_path/report unless given."""
    args = ["simulate", str(scenario_file(tmp_path, text)), "-q"]
    return invoke(*args, *(extra or ("-o", str(tmp_path / "report"))))


def with_simulation(line: str) -> str:
    return SCENARIO.replace("duration = 20.0", f"duration = 20.0\n{line}")


# -- simulate -o --------------------------------------------------------------------------------


def test_report_onto_an_existing_file(tmp_path: Path) -> None:
    target = tmp_path / "report.html"
    target.write_text("keep me", encoding="utf-8")
    result = simulate(tmp_path, SCENARIO, "-o", str(target))
    assert_user_error(result, "report.html", "exists and is not a directory")
    assert result.stdout == ""  # refused before the run
    assert target.read_text(encoding="utf-8") == "keep me"


def test_report_directory_that_cannot_be_created(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("", encoding="utf-8")
    result = simulate(tmp_path, SCENARIO, "-o", str(blocker / "sub" / "report"))
    assert_user_error(result, "cannot create the report directory", f"{blocker} is a file")
    assert result.stdout == ""


def test_report_write_failure_is_one_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import loopworks.sim.report as report

    def full_disk(directory: Path, *args: object) -> None:
        raise OSError(28, "No space left on device", str(directory / "base.csv"))

    monkeypatch.setattr(report, "write_report", full_disk)
    assert_user_error(simulate(tmp_path, SCENARIO), "base.csv: cannot write the report: "
                                                    "No space left on device")


# -- the run's settings -------------------------------------------------------------------------


@pytest.mark.parametrize(("window", "needle"), [
    pytest.param("[10.0, 5.0]", "reversed", id="reversed"),
    pytest.param("[30.0, 40.0]", "outside the run", id="after-the-run"),
    pytest.param("[-5.0, 5.0]", "outside the run", id="before-the-run"),
])
def test_metrics_window(tmp_path: Path, window: str, needle: str) -> None:
    result = simulate(tmp_path, with_simulation(f"metrics_window = {window}"))
    assert_user_error(result, "case.toml: simulation.metrics_window", needle)
    assert not (tmp_path / "report").exists()


def test_a_run_too_long_for_memory_says_how_much_it_needs(tmp_path: Path) -> None:
    text = SCENARIO.replace("duration = 20.0", "duration = 1e9").replace("dt = 0.1", "dt = 1e-3")
    line = assert_user_error(simulate(tmp_path, text), "case.toml: [simulation]",
                             "1e+12 scans", "recording them needs about", "GB of memory")
    assert "shorter duration or a longer dt" in line


def test_a_scan_count_too_large_to_count(tmp_path: Path) -> None:
    text = SCENARIO.replace("duration = 20.0", "duration = 1e300").replace("dt = 0.1",
                                                                          "dt = 1e-300")
    assert_user_error(simulate(tmp_path, text), "more scans than can be counted")


def test_an_event_after_the_run_is_a_warning(tmp_path: Path) -> None:
    text = SCENARIO + '\n[[events]]\nt = 25.0\nset = "pid.sp"\nvalue = 60.0\n'
    result = simulate(tmp_path, text)
    assert result.exit_code == 0, result.output
    assert result.stderr.splitlines() == [
        f"warning: {tmp_path / 'case.toml'}: event at t = 25 s (set = 'pid.sp') is after the "
        "last scan (t = 19.9 s) of the 20 s run: it never happens"]


# -- what the file says -------------------------------------------------------------------------


@pytest.mark.parametrize(("edit", "needles"), [
    pytest.param(("sp = 50.0", "sp = nan"), ["[blocks.pid]: sp = nan", "finite"],
                 id="nan-constant"),
    pytest.param(("sp = 50.0", "sp = inf"), ["[blocks.pid]: sp = inf", "finite"],
                 id="inf-constant"),
    pytest.param(('"pid.pv" = "process.y"', '"pid.pv" = "process.y"\n"pid.mode" = "process.y"'),
                 ["wire 'pid.mode' = 'process.y'", "enumerated input"], id="analog-into-mode"),
])
def test_scenario_mistakes(tmp_path: Path, edit: tuple[str, str], needles: list[str]) -> None:
    text = SCENARIO.replace(*edit, 1)
    assert text != SCENARIO
    assert_user_error(simulate(tmp_path, text), "case.toml", *needles)
    assert not (tmp_path / "report").exists()


@pytest.mark.parametrize(("event", "needles"), [
    pytest.param('set = "pid.sp"\nvalue = inf', ["[[events]] #1", "value = inf", "finite"],
                 id="inf-event"),
    pytest.param('set = "pid.mode"\nvalue = "HIGH"',
                 ["event at t = 5 s, set = 'pid.mode'", "'HIGH'", "MAN, AUTO, CAS"],
                 id="mode-name"),
    pytest.param('set = "pid.k"\nvalue = -1.0', ["event at t = 5 s, set = 'pid.k'", "'k' = -1"],
                 id="parameter-out-of-range"),
    pytest.param('set = "pidx.sp"\nvalue = 1.0', ["event at t = 5 s, set = 'pidx.sp'",
                                                  "unknown block 'pidx'"], id="unknown-block"),
])
def test_event_mistakes_are_found_before_the_run(tmp_path: Path, event: str,
                                                 needles: list[str]) -> None:
    text = SCENARIO + f"\n[[events]]\nt = 5.0\n{event}\n"
    line = assert_user_error(simulate(tmp_path, text), "case.toml", *needles)
    assert "wire" not in line  # an event is not a wire


def test_a_variant_name_that_is_not_a_file_name(tmp_path: Path) -> None:
    text = SCENARIO + '\n[compare."slow/fast"]\n"pid.k" = 2.0\n'
    assert_user_error(simulate(tmp_path, text), "[compare.slow/fast]", "report files")
    assert not (tmp_path / "report").exists()


def test_a_scenario_that_is_not_utf8(tmp_path: Path) -> None:
    path = tmp_path / "latin1.toml"
    path.write_bytes((SCENARIO + "# r\xe9glage\n").encode("latin-1"))
    assert_user_error(invoke("simulate", str(path), "-q", "-o", str(tmp_path / "r")),
                      "latin1.toml: not UTF-8 text")


# -- replay -------------------------------------------------------------------------------------


def test_replay_csv_that_is_not_utf8(tmp_path: Path) -> None:
    path = tmp_path / "latin1.csv"
    path.write_bytes(b"t,sp,pv\n0,50,40\n1,50,4\xb0\n")
    assert_user_error(invoke("replay", "pid", str(path)), "latin1.csv, line 3, column 'pv'",
                      "not UTF-8 text")


def test_replay_csv_with_an_oversized_field(tmp_path: Path) -> None:
    path = tmp_path / "big.csv"
    path.write_text('t,sp,pv\n0,50,"' + "4" * 200_000 + '"\n', encoding="utf-8")
    assert_user_error(invoke("replay", "pid", str(path)), "big.csv, line 2",
                      "field larger than field limit")


def test_replay_output_onto_a_directory(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "in.csv", ["t", "sp", "pv"], [[0, 50, 40], [1, 50, 40]])
    (tmp_path / "out").mkdir()
    assert_user_error(invoke("replay", "pid", str(path), "-o", str(tmp_path / "out")),
                      "is a directory")


def test_replay_params_file_that_is_not_utf8(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "in.csv", ["t", "sp", "pv"], [[0, 50, 40], [1, 50, 40]])
    params = tmp_path / "p.toml"
    params.write_bytes("k = 2.0 # gain \xb0\n".encode("latin-1"))
    assert_user_error(invoke("replay", "pid", str(path), "--params", str(params)),
                      "p.toml: not UTF-8 text")


def test_replay_time_that_overflows(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "in.csv", ["dt", "sp", "pv"],
                     [[1e308, 50, 40], [1e308, 50, 40], [1e308, 50, 40]])
    assert_user_error(invoke("replay", "pid", str(path)), "line 4",
                      "the accumulated time overflows")


def test_replay_refuses_to_write_over_its_input(tmp_path: Path) -> None:
    """`replay pid in.csv -o in.csv` overwrote the record it read (found by a user)."""
    from typer.testing import CliRunner

    from loopworks.cli import app

    path = tmp_path / "in.csv"
    text = "dt,sp,pv\n1,50,40\n1,50,41\n"
    path.write_text(text)
    run = CliRunner().invoke(app, ["replay", "pid", str(path), "-o", str(path)])
    assert run.exit_code == 2 and "is the input file" in run.output, run.output
    assert path.read_text() == text


def test_a_file_with_another_separator_is_named_so(tmp_path: Path) -> None:
    """A semicolon-separated export read as one column named 't;op;pv;sp', and the error
    said only that no time column was found."""
    from loopworks.analysis.loopdata import read_csv
    from loopworks.errors import FileFormatError

    path = tmp_path / "semi.csv"
    path.write_text("t;op;pv;sp\n0;1;2;3\n")
    with pytest.raises(FileFormatError, match=r"line 1: the header 't;op;pv;sp' is one "
                                              r"column: the file seems separated by ';'"):
        read_csv(path)


def test_live_commands_check_duration_and_ports_before_starting() -> None:
    """Found by a user: `serve --duration nan` crash-looped its controller six times and
    exited 0; a port beyond 65535 or in use was a traceback (for serve after the device and
    the controller had started; `serve --faceplate` then ran without its faceplate)."""
    import socket

    from typer.testing import CliRunner

    from loopworks.cli import app

    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        used = busy.getsockname()[1]
        for args, message in (
                (["serve", "--duration", "nan"], "--duration nan: expected plant seconds > 0"),
                (["device", "--duration", "-5"], "--duration -5.0: expected plant seconds"),
                (["serve", "--opcua-port", "70000"], "--opcua-port 70000: allowed 1..65535"),
                (["faceplate", "--port", "70000"], "--port 70000: allowed 1..65535"),
                (["serve", "--opcua-port", str(used)], f"cannot listen on 127.0.0.1:{used}"),
                (["serve", "--faceplate", "--faceplate-port", str(used)],
                 f"--faceplate-port {used}: cannot listen"),
                (["device", "--modbus-port", str(used)], f"--modbus-port {used}: cannot listen"),
                (["faceplate", "--port", str(used)], f"--port {used}: cannot listen"),
                # a host that is no address is the host's error, not the port's (found by an
                # outside audit)
                (["device", "--host", "999.1.1.1", "--modbus-port", "20011"],
                 "--host 999.1.1.1: not an address to listen on")):
            run = CliRunner().invoke(app, args)
            assert run.exit_code == 2, (args, run.output)
            assert run.output.startswith("error: ") and message in run.output, run.output


def test_a_password_that_is_not_utf8_is_one_error_line(tmp_path: Path) -> None:
    """`printf '\\xff\\xfe\\n' | loopworks users add FILE NAME` was a UnicodeEncodeError
    traceback (found by a user); nothing is written."""
    import subprocess
    import sys

    path = tmp_path / "users.toml"
    run = subprocess.run([sys.executable, "-m", "loopworks", "users", "add", str(path), "bin"],
                         input=b"\xff\xfe\n", capture_output=True, timeout=120)
    assert run.returncode == 2, run.stderr
    assert run.stderr.decode().startswith("error: the password read from standard input is "
                                          "not UTF-8 text") and not path.exists()


def test_serve_exits_nonzero_when_it_gave_up_on_its_controller(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """A controller that died six times within a minute made serve log "giving up" and exit
    0 (found by a user with --duration nan, now refused up front): it is an error exit."""
    from typer.testing import CliRunner

    from loopworks.cli import app
    from loopworks.live import supervisor

    async def gave_up(*args: object, **kwargs: object) -> dict[str, object]:
        return {"stats": None, "io": None, "checkpoint": "state/checkpoint.json",
                "gave_up": True}

    monkeypatch.setattr(supervisor, "run", gave_up)
    monkeypatch.setattr(supervisor, "log_to_stderr", lambda: None)
    run = CliRunner().invoke(app, ["serve", "--opcua-port", "0"])
    assert run.exit_code == 2 and "died too often" in run.output, run.output
