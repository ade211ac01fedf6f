"""The simulate report (issue 11): the variants overlaid with the scored window shaded, the
stiction signature, a headline per variant, units and definitions, and strict JSON."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Any

import matplotlib
import numpy as np
import pytest

from loopworks.sim import report
from loopworks.sim.metrics import METRICS, markdown
from loopworks.sim.result import SimResult

matplotlib.use("Agg")

DT = 0.5
WINDOW = (200.0, 400.0)


def loop_result(pv_amp: float, stem_rate: float, dither: float) -> SimResult:
    """A pid -> comp -> valve loop written out by hand: PV = 50 ± pv_amp alternating each
    scan, the stem ramping at stem_rate % per scan, the valve command the stem plus a dither
    of ±dither (or the stem itself without one)."""
    t = np.arange(0.0, 400.0 + DT / 2, DT)
    k = np.arange(len(t))
    sign = (-1.0) ** k
    position = 50.0 + stem_rate * k
    command = position + dither * sign if dither else position.copy()
    out = position.copy()
    values = {"pid.sp": np.full(len(t), 50.0), "pid.pv": 50.0 + pv_amp * sign,
              "pid.out": out, "comp.signal_in": out, "comp.signal_out": command,
              "valve.op": command, "valve.position": position}
    return SimResult(t=t, values=values, status={n: np.full(len(t), 128) for n in values},
                     kinds={"pid": "pid", "comp": "compensator.constant_reinforcement",
                            "valve": "valve.resolution"},
                     wires={"comp.signal_in": "pid.out", "valve.op": "comp.signal_out"})


def two_variants() -> dict[str, SimResult]:
    # over the window (401 scans, and 401 moves with the one into its first scan, spec 4.1:
    # Σ|Δy_k| over k0..k1): PV std 2 -> 1 (-50 %), stem travel 0.01·401 = 4.01 ->
    # 0.015·401 = 6.015 (+50 %), command travel 4.01 -> 400·2·0.055 + 0.125 = 44.125 (the
    # dither's moves alternate 0.015 ± 0.11; the one into scan 400 is +0.125)
    return {"off": loop_result(2.0, 0.01, 0.0), "on": loop_result(1.0, 0.015, 0.055)}


def strict_json(path: Path) -> Any:
    """Parse as RFC 8259 JSON: NaN, Infinity and -Infinity are not JSON."""
    def refuse(name: str) -> None:
        raise ValueError(f"{path.name}: {name} is not JSON")
    return json.loads(path.read_text(encoding="utf-8"), parse_constant=refuse)


def write(tmp_path: Path, results: dict[str, SimResult],
          window: tuple[float, float] | None = WINDOW,
          autotune: dict[str, Any] | None = None) -> dict[str, dict[str, float]]:
    metrics = {v: r.metrics(window=window) for v, r in results.items()}
    report.write_report(tmp_path, "test loop", "[simulation]\n", results, metrics,
                        autotune, window=window)
    return metrics


def test_metrics_include_the_valve_command() -> None:
    """The table's valve-command rows are the valve's op input as wired (the compensated
    signal), not the controller output."""
    m = two_variants()["on"].metrics(window=WINDOW)
    assert m["valve-command travel"] == pytest.approx(400 * 0.11 + 0.125)
    assert m["valve-command reversals"] == 400.0
    assert m["valve travel"] == pytest.approx(401 * 0.015)
    assert m["output travel"] == pytest.approx(401 * 0.015)


def test_headline_against_the_first_variant(tmp_path: Path) -> None:
    write(tmp_path, two_variants())
    page = (tmp_path / "report.html").read_text(encoding="utf-8")
    assert "<b>on</b> against off: PV std -50 %, stem travel +50 %, " \
           "valve-command travel +1000 %" in page


def test_headline_with_a_zero_base_is_na() -> None:
    """A change against 0 travel has no percentage: n/a, not inf or a division error."""
    base = {"PV std": 1.0, "valve travel": 0.0, "valve-command travel": math.nan}
    other = {"PV std": 1.5, "valve travel": 3.0, "valve-command travel": 7.0}
    assert report.headline(base, other) == \
        "PV std +50 %, stem travel n/a, valve-command travel n/a"
    # no valve: the controller output's travel is the cost
    assert report.headline({"PV std": 2.0, "output travel": 4.0},
                           {"PV std": 1.0, "output travel": 5.0}) == \
        "PV std -50 %, output travel +25 %"


def test_table_has_units_and_every_metric_is_defined(tmp_path: Path) -> None:
    write(tmp_path, two_variants())
    page = (tmp_path / "report.html").read_text(encoding="utf-8")
    assert '<a href="metrics.md">' in page
    assert (tmp_path / "metrics.md").read_text(encoding="utf-8") == markdown()
    row = re.search(r'<tr><th><a href="#(m-[^"]+)">valve-command travel</a></th>'
                    r"<td class=u>([^<]+)</td><td>([^<]+)</td><td>([^<]+)</td></tr>", page)
    assert row is not None
    assert row.group(2) == "% of span"
    assert float(row.group(3)) == pytest.approx(4.01) and float(row.group(4)) == 44.12
    linked = set(re.findall(r'<a href="#(m-[^"]+)">', page))
    defined = set(re.findall(r'<tr id="(m-[^"]+)">', page))
    assert linked and linked <= defined
    assert len(defined) == len(METRICS)
    # a figure the data cannot support: no setpoint step in the window
    assert re.search(r">settling time s \(2 %\)</a></th><td class=u>s</td><td>n/a</td>", page)


def test_every_json_file_is_strict_json(tmp_path: Path) -> None:
    """issue 11 point 5: a non-finite figure is null, never NaN or Infinity."""
    results = {"base": loop_result(2.0, 0.01, 0.0)}
    metrics = {"base": {"IAE": math.inf, "PV std": math.nan, "valve travel": 3.0}}
    autotune = {"loop": "pid", "outcome": "converged", "ku": math.inf,
                "pu": np.float64(math.nan), "cycles": [{"amplitude": -math.inf}, 1.5],
                "n": np.int64(3)}
    report.write_report(tmp_path, "t", "", results, metrics, autotune, window=WINDOW)
    assert strict_json(tmp_path / "metrics.json") == {
        "base": {"IAE": None, "PV std": None, "valve travel": 3.0}}
    assert strict_json(tmp_path / "autotune.json") == {
        "loop": "pid", "outcome": "converged", "ku": None, "pu": None,
        "cycles": [{"amplitude": None}, 1.5], "n": 3}


def test_json_text_refuses_nothing_and_writes_no_constant() -> None:
    text = report.json_text({"a": [math.nan, (math.inf, 1.0)], "b": np.array([2.0, -np.inf])})
    assert "NaN" not in text and "Infinity" not in text
    assert json.loads(text) == {"a": [None, [None, 1.0]], "b": [2.0, None]}


def window_pixels(png: Path) -> int:
    """How many pixels have the scored window's shading colour."""
    import matplotlib.image

    rgb = (matplotlib.image.imread(png)[:, :, :3] * 255).round().astype(int)
    shade = np.array([int(report._WINDOW_COLOUR[i:i + 2], 16) for i in (1, 3, 5)])
    return int(np.sum(np.all(rgb == shade, axis=2)))


def test_figures_are_written_and_the_window_is_shaded(tmp_path: Path) -> None:
    write(tmp_path / "scored", two_variants())
    write(tmp_path / "whole", two_variants(), window=None)
    for name in ("overview.png", "signature.png", "off.png", "on.png"):
        assert (tmp_path / "scored" / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert (tmp_path / "whole" / name).exists()
    page = (tmp_path / "scored" / "report.html").read_text(encoding="utf-8")
    assert 'src="overview.png"' in page and 'src="signature.png"' in page
    assert window_pixels(tmp_path / "scored" / "overview.png") > 10_000
    assert window_pixels(tmp_path / "scored" / "off.png") > 10_000
    assert window_pixels(tmp_path / "whole" / "overview.png") == 0


def test_zoom_is_centred_on_the_largest_command_move() -> None:
    t = np.arange(0.0, 3600.0 + DT / 2, DT)
    command = 50.0 + 0.1 * (-1.0) ** np.arange(len(t))
    command[t >= 2500.0] += 2.0   # a kick at 2500 s
    command[t >= 1000.0] += 9.0   # larger, but before the window
    assert report.zoom_span(t, (1800.0, 3600.0), command) == (2450.0, 2550.0)
    command[t >= 3590.0] += 5.0   # largest in the window, near its end: the zoom stays inside
    assert report.zoom_span(t, (1800.0, 3600.0), command) == (3500.0, 3600.0)
    assert report.zoom_span(t, (1800.0, 3600.0), None) == (2650.0, 2750.0)
    assert report.zoom_span(t, (100.0, 150.0), command) == (100.0, 150.0)


FORKED = """
import os, sys
from pathlib import Path
from loopworks.sim.report import forked

out = Path(sys.argv[1])
parent = os.getpid()

def draw() -> None:
    (out / "drawn").write_text(str(os.getpid()))

wait = forked(draw)
wait()
print("child" if int((out / "drawn").read_text()) != parent else "here")

def fail_in_child() -> None:
    if os.getpid() != parent:
        raise RuntimeError("the child fails")
    (out / "again").write_text("here")

forked(fail_in_child)()
print((out / "again").read_text())

def fail() -> None:
    raise ValueError("a bad figure")

try:
    forked(fail)()
except ValueError as exc:
    print("raised:", exc)
"""


def test_figures_drawn_in_a_forked_child_or_here_on_failure(tmp_path: Path) -> None:
    """``report.forked``: in a one-thread process on Linux the job runs in a child; a job that
    fails there runs again in the caller, so its error is raised where it would have been."""
    import subprocess
    import sys

    run = subprocess.run([sys.executable, "-c", FORKED, str(tmp_path)], capture_output=True,
                         text=True, timeout=120, check=True)
    where, again, raised = run.stdout.split("\n")[:3]
    assert where == ("child" if sys.platform.startswith("linux") else "here"), run.stderr
    assert again == "here"
    assert raised == "raised: a bad figure"


def test_a_loop_driving_no_valve_gets_no_valve_figures() -> None:
    """The valve a loop drives is followed through compensators, not through a process or
    another controller: a loop whose process feeds another loop's feedforward, and a cascade
    primary, got the other loop's valve travel and a signature plot of its valve (found by a
    user of the reports). The cascade's secondary keeps its valve."""
    from loopworks.sim.scenario import load_scenario

    root = Path(__file__).resolve().parents[2]
    sc = load_scenario(root / "examples" / "cascade.toml")
    result = sc.module.run(200.0, sc.dt)
    assert result.valve_of("primary") is None
    assert result.valve_of("secondary") is not None
    assert "valve travel" not in result.metrics("primary")
    assert "valve travel" in result.metrics("secondary")
    sc = load_scenario(root / "examples" / "compensators_side_by_side.toml")
    both = sc.module.run(10.0, sc.dt)
    for loop in both.controllers():  # each through its compensator to its own valve
        valve = both.valve_of(loop)
        assert valve == loop.replace("pid_", "valve_"), (loop, valve)


def test_the_output_axis_is_in_the_controllers_units() -> None:
    """The report's output axis said "controller output (%)" over GE counts of 16000-19500
    and a DeltaV OUT_SCALE of 0..200 EU (found by a user of the reports)."""
    kinds = {"g": "ge.pid_ind", "s": "s5.pid", "d": "deltav.pid", "p": "pid", "e": "e2.pid"}
    result = SimResult(np.arange(3.0), {}, {}, kinds=kinds)
    assert {k: result.out_units(k) for k in kinds} == {
        "g": "counts", "s": "counts", "d": "EU", "p": "%", "e": "%"}


GE_SCALED = """
[simulation]
dt = 0.1
duration = 200.0

[blocks.tt]
kind = "sensor.transmitter"
gain = 320.0

[blocks.ge]
kind = "ge.pid_ind"
kp = 1.0
ki = 0.05
sample_period = 0.1
sp = 16000.0
bias = 16000.0
load_clock_at_start = true

[blocks.scale]
kind = "deltav.calc"
expression = "'^/PCT' := '^/CNT' / 320.0;"
precision = "float64"
cnt = 16000.0
pct = 50.0

[blocks.valve]
kind = "valve.choudhury"
s = 2.0
j = 1.0

[blocks.process]
kind = "process.fopdt"
gain = 1.0
time_constant = 20.0
dead_time = 2.0
u0 = 50.0

[wires]
"tt.y" = "process.y"
"ge.pv" = "tt.pv"
"scale.cnt" = "ge.cv"
"valve.op" = "scale.pct"
"process.u" = "valve.position"

[[events]]
t = 100.0
set = "ge.sp"
value = 17600.0
"""


def test_the_signature_draws_an_output_in_counts_on_its_own_axis(tmp_path: Path) -> None:
    """A GE CV (counts) scaled to the valve's % was drawn on the command's axis labelled
    "ge output, valve command (%)": 16000-20000 "%" beside 50-62 % (found by an engineer)."""
    from loopworks.sim.report import signature_plot
    from loopworks.sim.scenario import parse_scenario

    sc = parse_scenario(GE_SCALED)
    run = sc.module.run(sc.duration, sc.dt)
    import matplotlib.pyplot as plt

    made: list[Any] = []
    real = plt.close
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(plt, "close", lambda fig=None: made.append(fig))
        assert signature_plot({"base": run}, "ge", tmp_path / "sig.png")
    fig = made[0]
    labels = {ax.get_xlabel() for ax in fig.axes}
    assert labels == {"valve command (%)", "ge output (counts)"}, labels
    for ax in fig.axes:  # each axis spans its own signal: counts on one, % on the other
        hi = ax.get_xlim()[1]
        assert (hi > 1000.0) == (ax.get_xlabel() == "ge output (counts)"), (ax.get_xlabel(), hi)
    real(fig)


def test_a_loop_keeps_its_colour_in_every_trend_panel() -> None:
    """The colour cycle ran on across each panel's lines: a loop's PV was green and its OUT
    another loop's colour, and three compensator outputs shared one grey (found by a user of
    the reports). A loop's PV, SP, OUT, compensator output and valve share its colour."""
    from matplotlib.colors import to_hex

    from loopworks.sim.report import _trend_figure
    from loopworks.sim.scenario import load_scenario

    root = Path(__file__).resolve().parents[2]
    sc = load_scenario(root / "examples" / "compensators_side_by_side.toml")
    _, axes = _trend_figure(sc.module.run(20.0, sc.dt), "t", None)
    colour = {line.get_label(): to_hex(line.get_color()) for ax in axes for line in ax.lines}
    for name in ("none", "knocker", "dither_kicker"):
        same = {colour[f"pid_{name} PV"], colour[f"pid_{name} SP"], colour[f"pid_{name} OUT"],
                colour[f"valve_{name} position"]}
        assert len(same) == 1, (name, same)
    assert colour["comp_knocker op_out"] == colour["pid_knocker OUT"]
    assert len({colour[f"pid_{n} OUT"] for n in ("none", "knocker", "dither_kicker")}) == 3


def test_a_reused_directory_loses_the_earlier_reports_files_only(tmp_path: Path) -> None:
    """A report written where another scenario's was kept that one's autotune.json and
    variants beside it (found by an outside audit). The earlier report's files this one
    does not replace are removed; the user's own files, and a directory that holds no
    report, are left alone."""
    write(tmp_path, two_variants(), autotune={"loop": "pid", "process_gain": 1.0})
    (tmp_path / "notes.txt").write_text("mine")
    (tmp_path / "other.csv").write_text("t,x\n0,1\n")
    assert {"off.csv", "on.png", "autotune.json"} <= {p.name for p in tmp_path.iterdir()}
    write(tmp_path, {"base": loop_result(2.0, 0.01, 0.0)})
    names = {p.name for p in tmp_path.iterdir()}
    assert not names & {"off.csv", "off.png", "on.csv", "on.png", "autotune.json"}, names
    assert {"base.csv", "base.png", "notes.txt", "other.csv", "report.html"} <= names
    # no earlier report here (no report.html): a file named as a variant's stays
    fresh = tmp_path / "fresh"
    fresh.mkdir()
    (fresh / "autotune.json").write_text("{}")
    (fresh / "metrics.json").write_text('{"keep": {}}')
    (fresh / "keep.csv").write_text("mine")
    write(fresh, {"base": loop_result(2.0, 0.01, 0.0)})
    assert (fresh / "keep.csv").read_text() == "mine" and (fresh / "autotune.json").exists()
