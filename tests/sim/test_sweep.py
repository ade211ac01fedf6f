"""Sweeps (issue 14): the grammar of --vary, the Latin hypercube, a grid equal to separate
``simulate`` runs, reproducible Monte Carlo, located errors before anything runs, the output
files, and a Dask LocalCluster giving the local numbers."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from loopworks.cli import app
from loopworks.errors import InputError
from loopworks.sim.sweep import Axis, design, latin_hypercube, parse_vary, sweep

#: a noisy loop with two variants: a transmitter with noise (seeded), a random-walk load
SCENARIO = """\
[simulation]
dt = 0.5
duration = 120.0
metrics_window = [20.0, 120.0]

[blocks.pid]
kind = "pid"
k = 1.0
ti = 20.0
sp = 50.0
bias = 50.0

[blocks.process]
kind = "process.fopdt"
gain = 1.0
time_constant = 10.0
dead_time = 1.0
u0 = 50.0

[blocks.load]
kind = "disturbance.load"
walk_std = 0.2
seed = 5

[blocks.tx]
kind = "sensor.transmitter"
noise_std = 0.3
seed = 9

[wires]
"process.u" = "pid.out"
"load.u" = "process.y"
"tx.y" = "load.y"
"pid.pv" = "tx.pv"

[compare.base]

[compare.faster]
"pid.ti" = 10.0
"""


def same_table(a: dict[str, list[object]], b: dict[str, list[object]]) -> None:
    """Equal column by column, NaN equal to NaN (an n/a metric)."""
    assert list(a) == list(b)
    for name in a:
        np.testing.assert_array_equal(np.array(a[name]), np.array(b[name]), err_msg=name)


@pytest.fixture(scope="module")
def scenario(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("sweep") / "loop.toml"
    path.write_text(SCENARIO, encoding="utf-8")
    return path


# -- the grammar -------------------------------------------------------------------------------
def test_specs() -> None:
    assert parse_vary("pid.k=1:2:3") == Axis("pid.k", values=(1.0, 1.5, 2.0))
    assert parse_vary("pid.mode=AUTO,MAN") == Axis("pid.mode", values=("AUTO", "MAN"))
    assert parse_vary("pid.k = 1, 2.5") == Axis("pid.k", values=(1, 2.5))
    u = parse_vary("valve.s=uniform(1,3)")
    assert u.sampled and u.at(0.0) == 1.0 and u.at(0.5) == 2.0
    lg = parse_vary("valve.s=loguniform(1,100)")
    assert lg.at(0.5) == pytest.approx(10.0)
    nm = parse_vary("process.gain=normal(1,0.1)")
    assert nm.at(0.5) == pytest.approx(1.0)
    assert nm.at(0.8413447460685429) == pytest.approx(1.1)  # Φ(1)
    assert parse_vary("pid.k=2:2:1") == Axis("pid.k", values=(2.0,))
    ch = parse_vary("comp.kind=choice(a,b,c)")
    assert [ch.at(u) for u in (0.0, 0.34, 0.99)] == ["a", "b", "c"]


@pytest.mark.parametrize(("text", "message"), [
    ("pid.k", "expected NAME=SPEC"),
    ("k=1,2", "expected NAME=SPEC"),
    ("pid.k=1:2:x", "n = 'x' must be a whole number"),
    ("pid.k=1:b:3", "'b' is not a number"),
    ("pid.k=gauss(1,2)", "unknown distribution 'gauss'"),
    ("pid.k=uniform(2,1)", "needs a < b"),
    ("pid.k=loguniform(0,1)", "needs 0 < a"),
    ("pid.k=normal(1,-1)", "needs s > 0"),
    ("pid.k=uniform(1)", "takes two numbers, got 1"),
    ("pid.k=1,,2", "an empty value"),
    ("pid.k=1:3", "a range is a:b:n, three parts"),
    ("pid.k=1:2:3:4", "a range is a:b:n, three parts"),
    # given values silently dropped (found by a user): an empty choice, b of a:b:1
    ("pid.mode=choice(AUTO,,MAN)", "an empty value in choice()"),
    ("pid.mode=choice(AUTO,MAN,)", "an empty value in choice()"),
    ("pid.k=1:2:1", "a:b:1 is one value, a = 1, and drops b = 2"),
    ("pid.k=0:1:2.5", "n = '2.5' must be a whole number"),
    ("pid.k=0:1:inf", "n = 'inf' must be a whole number"),
    ("pid.k=0:1:0", "n = '0' must be a whole number"),
])
def test_a_bad_spec_is_a_located_error(text: str, message: str) -> None:
    with pytest.raises(InputError, match=re.escape(message)) as err:
        parse_vary(text)
    assert f"--vary {text}" in str(err.value)


def test_latin_hypercube_has_one_point_per_stratum() -> None:
    u = latin_hypercube(50, 3, np.random.default_rng(1))
    assert u.shape == (50, 3) and ((u >= 0.0) & (u < 1.0)).all()
    for j in range(3):
        assert sorted(np.floor(u[:, j] * 50).astype(int)) == list(range(50))


def test_design_is_grid_times_samples() -> None:
    axes = [parse_vary("a.x=1,2"), parse_vary("b.y=1:3:3"), parse_vary("c.z=uniform(0,1)")]
    points = design(axes, 4, seed=3)
    assert len(points) == 2 * 3 * 4
    assert {(p["a.x"], p["b.y"]) for p in points} == {(a, b) for a in (1, 2)
                                                     for b in (1.0, 2.0, 3.0)}
    assert design(axes, 4, seed=3) == points  # seeded
    assert design(axes, 4, seed=4) != points


def test_any_integer_is_a_seed() -> None:
    """A scenario's seed may be negative (simulate takes it, mix_seed works modulo 2**64), so
    a sweep's may be too: it was a ValueError from numpy's generator (found by fuzzing)."""
    axes = [parse_vary("c.z=uniform(0,1)")]
    assert design(axes, 4, seed=-1) == design(axes, 4, seed=2**64 - 1)
    assert design(axes, 4, seed=-1) != design(axes, 4, seed=1)
    assert len(design(axes, 4, seed=2**70)) == 4


# -- against simulate --------------------------------------------------------------------------
def _simulate_metrics(tmp: Path, text: str, values: dict[str, float], seed: int,
                      variant: str) -> dict[str, float]:
    """``loopworks simulate`` of the scenario with ``values`` written into it and
    ``[simulation] seed``: the metrics of ``variant``."""
    lines = text.replace("[simulation]\n", f"[simulation]\nseed = {seed}\n", 1)
    for name, value in values.items():
        block, param = name.split(".")
        lines = re.sub(rf"(\[blocks\.{block}\]\n(?:.+\n)*?){param} = .+\n",
                       rf"\g<1>{param} = {value!r}\n", lines, count=1)
        assert f"{param} = {value!r}" in lines
    path = tmp / f"run_{seed}.toml"
    path.write_text(lines, encoding="utf-8")
    result = CliRunner().invoke(app, ["simulate", str(path), "--json", "-q"])
    assert result.exit_code == 0, result.output
    return dict(json.loads(result.stdout)[variant])


def test_a_grid_equals_separate_simulate_runs(scenario: Path, tmp_path: Path) -> None:
    """Done-when: a 3 × 3 grid gives the metrics of nine ``loopworks simulate`` runs with
    those values (and each row's seed as [simulation] seed), to 1e-9."""
    result = sweep(scenario, {"pid.k": "0.5:1.5:3", "process.gain": "0.8,1.0,1.2"},
                   variant="base", workers=1)
    assert len(result) == 9 and result.design == "grid" and result.grid_shape == (3, 3)
    assert len(set(result.columns["seed"])) == 9  # each point its own noise
    for i in range(9):
        row = {k: col[i] for k, col in result.columns.items()}
        expected = _simulate_metrics(tmp_path, SCENARIO, {"pid.k": row["pid.k"],
                                                          "process.gain": row["process.gain"]},
                                     row["seed"], "base")
        for metric, value in expected.items():
            if value is None or (isinstance(value, float) and math.isnan(value)):
                assert math.isnan(row[metric]), metric
            else:
                assert row[metric] == pytest.approx(value, rel=1e-9, abs=1e-12), metric


def test_monte_carlo_is_reproducible_and_processes_agree(scenario: Path) -> None:
    vary = ["pid.k=uniform(0.5,1.5)", "tx.noise_std=loguniform(0.05,0.5)"]
    one = sweep(scenario, vary, samples=6, seed=11, workers=1)
    two = sweep(scenario, vary, samples=6, seed=11, workers=2)
    same_table(one.columns, two.columns)  # same seed: the same table, in processes too
    assert len(one) == 12 and one.design == "monte carlo"
    other = sweep(scenario, vary, samples=6, seed=12, workers=1)
    assert other.columns["pid.k"] != one.columns["pid.k"]
    # the variants of a point share its values and its noise
    base = [i for i, v in enumerate(one.columns["variant"]) if v == "base"]
    fast = [i for i, v in enumerate(one.columns["variant"]) if v == "faster"]
    assert [one.columns["seed"][i] for i in base] == [one.columns["seed"][i] for i in fast]
    assert [one.columns["pid.k"][i] for i in base] == [one.columns["pid.k"][i] for i in fast]


def test_a_column_has_its_parameters_type_however_its_values_were_typed(
        scenario: Path) -> None:
    """`pid.k=1,2` made an int64 column and `pid.k=1.0,2` a float64 one, so two sweeps of
    one parameter had two Parquet schemas (found by an outside audit): a float parameter's
    values are floats, a numeric input's too."""
    import pyarrow as pa

    types = set()
    for spec in ("1,2", "1.0,2", "choice(1,2)"):
        result = sweep(scenario, [f"pid.k={spec}"], samples=2, seed=1, variant="base",
                       workers=1)
        assert {type(v) for v in result.columns["pid.k"]} == {float}, spec
        types.add(result.to_arrow().schema.field("pid.k").type)
    assert types == {pa.float64()}


def test_a_range_gives_the_decimals_it_stands_for() -> None:
    """1:2:11 is 1.0, 1.1, ..., 2.0 (linspace gave 1.7000000000000002, shown so in the
    results); n may be written 3.0 (it was refused)."""
    assert parse_vary("pid.k=1:2:11").values == tuple(v / 10 for v in range(10, 21))
    assert parse_vary("pid.k=0.1:0.3:3").values == (0.1, 0.2, 0.3)
    assert parse_vary("pid.k=0:1:3.0").values == (0.0, 0.5, 1.0)


@pytest.mark.parametrize(("vary", "message"), [
    (["pid.k=uniform(-1,2)"], "uniform(-1.0, 2.0) reaches a: pid.k = -1.0"),
    (["pid.k=uniform(0,2)"], None),  # k in (0, inf): the end 0 is never drawn
    (["pid.k=choice(1,2,-3)"], "choice() value: pid.k = -3"),
])
@pytest.mark.parametrize("seed", range(4))
def test_a_distribution_reaching_outside_a_range_is_refused_whatever_the_seed(
        scenario: Path, vary: list[str], message: str | None, seed: int) -> None:
    """A distribution's ends and choices are checked before anything is drawn: with one
    sample, uniform(-1, 2) for a gain in (0, inf) drew inside two times in three and ran
    (docs/sweeps.md). An end on a bound the range excludes is
    allowed (uniform(0, ...) never draws the 0); the check runs before the relay tests and
    the instances."""
    if message is None:
        result = sweep(scenario, vary, samples=1, seed=seed, workers=1)
        assert 0.0 < result.columns["pid.k"][0] < 2.0
        return
    with pytest.raises(InputError, match=re.escape(message)):
        sweep(scenario, vary, samples=1, seed=seed, workers=1,
              progress=lambda done, total: pytest.fail("it ran"))


@pytest.mark.parametrize(("vary", "message"), [
    (["valve.s=1,2"], "no block 'valve'"),
    (["pid.gain=1,2"], "'gain' is not a parameter or input of pid (pid)"),
    (["pid.k=-1,1"], "instance 0: pid.k = -1"),
    (["pid.k=1,2", "pid.K=3"], "--vary pid.k is given twice (pid.k=1,2; pid.K=3)"),
    # parameter names: any case; the repeated one named (all the names were listed)
    (["pid.sp=uniform(0,1)", "pid.mode=choice(AUTO,BOGUS)"], "pid.mode = 'BOGUS'"),
    # a wired input: the constant was taken and silently never applied (found by a user)
    (["pid.pv=0,100"], "--vary pid.pv: the input is wired from 'tx.pv' in variant 'base': "
                       "an input takes a wire or a constant, not both"),
])
def test_unknown_names_and_bad_values_fail_before_running(scenario: Path, vary: list[str],
                                                          message: str) -> None:
    with pytest.raises(InputError, match=re.escape(message)):
        sweep(scenario, vary, samples=20, workers=1,
              progress=lambda done, total: pytest.fail("it ran"))


def test_sweep_command_writes_results_and_summary(scenario: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    result = CliRunner().invoke(app, ["sweep", str(scenario), "--vary", "pid.k=0.5:1.5:3",
                                      "--workers", "1", "-o", str(out), "-q", "--json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert (data["instances"], data["runs"]) == (3, 6)
    assert data["design"] == "grid" and data["metric"] == "PV std"
    assert set(data["variants"]) == {"base", "faster"}
    table = pq.read_table(out / "results.parquet")
    assert table.num_rows == 6
    assert table.column_names[:4] == ["variant", "point", "seed", "pid.k"]
    assert "PV std" in table.column_names and "IAE" in table.column_names
    csv_rows = (out / "results.csv").read_text().splitlines()
    assert len(csv_rows) == 7
    page = (out / "summary.html").read_text()
    assert "metrics_vs_parameter.png" in page and (out / "metrics_vs_parameter.png").exists()


def test_monte_carlo_summary_has_histograms_and_pareto(
        scenario: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from loopworks.sim import sweep_report

    titles: dict[str, list[str]] = {}
    save = sweep_report._save

    def keep_titles(fig: Any, path: Path) -> Path:
        titles[path.name] = [ax.get_title() for ax in fig.axes]
        return save(fig, path)

    monkeypatch.setattr(sweep_report, "_save", keep_titles)
    result = sweep(scenario, ["pid.k=uniform(0.5,1.5)"], samples=5, workers=1)
    sweep_report.write_summary(result, tmp_path, "t", "cmd")
    assert (tmp_path / "histograms.png").exists()
    # no valve in this loop: the Pareto plot uses the controller output travel, and says so
    assert (tmp_path / "pareto.png").exists()
    assert titles["pareto.png"][0].startswith("PV variability against output travel;")


def test_pareto_front() -> None:
    from loopworks.sim.sweep_report import pareto

    x = np.array([1.0, 2.0, 3.0, 1.5, 4.0, math.nan])
    y = np.array([5.0, 3.0, 1.0, 6.0, 0.5, 0.1])
    assert pareto(x, y).tolist() == [0, 1, 2, 4]


def test_best_row(scenario: Path) -> None:
    result = sweep(scenario, ["pid.k=0.5:1.5:3"], variant="base", workers=1)
    best = result.best("IAE")
    assert best["IAE"] == min(result.columns["IAE"])
    with pytest.raises(KeyError, match="no metric 'nope'"):
        result.best("nope")


def test_the_best_of_a_signed_metric_is_the_nearest_zero() -> None:
    """"Best instance by final error = -0.5068" was the largest error of the sweep (values
    -0.51 .. +0.37; found by a user of the summaries): a signed metric ranks by its size."""
    from loopworks.sim.sweep import SweepResult
    from loopworks.sim.sweep_report import summary_table

    result = SweepResult({"variant": ["a", "a", "a"], "point": [0, 1, 2], "seed": [1, 2, 3],
                          "pid.k": [1.0, 2.0, 3.0], "final error": [-0.51, 0.37, -0.05],
                          "IAE": [3.0, 1.0, 2.0]}, ["pid.k"], "grid",
                         metrics=["final error", "IAE"])
    assert result.best("final error")["pid.k"] == 3.0
    assert result.best("IAE")["pid.k"] == 2.0
    assert summary_table(result, "final error")[0][4] == -0.05


def test_a_dask_local_cluster_gives_the_local_numbers(scenario: Path) -> None:
    import distributed  # the test extras install it (the cluster extra)

    vary = ["pid.k=uniform(0.5,1.5)"]
    local = sweep(scenario, vary, samples=4, seed=2, workers=1)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, host="127.0.0.1",
                                  processes=True, dashboard_address=None) as cluster:
        remote = sweep(scenario, vary, samples=4, seed=2, scheduler=cluster.scheduler_address)
    same_table(remote.columns, local.columns)


def test_scheduler_without_dask_says_how_to_get_it(scenario: Path,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    import builtins

    real = builtins.__import__

    def no_dask(name: str, *args: object, **kwargs: object) -> object:
        if name == "distributed" or name.startswith("distributed."):
            raise ImportError(name)
        return real(name, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(builtins, "__import__", no_dask)
    with pytest.raises(InputError, match=re.escape('pip install "loopworks[cluster]"')):
        sweep(scenario, ["pid.k=1,2"], scheduler="tcp://127.0.0.1:1")


def test_the_python_api_is_loopworks_sweep() -> None:
    import loopworks

    assert loopworks.sweep is sweep


def test_an_unknown_metric_is_refused_before_the_run(scenario: Path, tmp_path: Path) -> None:
    result = CliRunner().invoke(app, ["sweep", str(scenario), "--vary", "pid.k=1,2",
                                      "--metric", "PV sdt", "-o", str(tmp_path / "o"), "-q"])
    assert result.exit_code == 2
    assert "--metric 'PV sdt': no such metric" in result.output
    assert not (tmp_path / "o" / "results.parquet").exists()


def test_a_metric_this_scenario_lacks_is_refused_before_the_run(
        scenario: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """"valve travel" is a metric, but this scenario has no valve: it was refused only after
    every instance had run, and nothing was written (found by an outside audit). Now before
    the sweep runs, with the scenario's own metrics."""
    import loopworks.sim.sweep as sweep_module

    def never(*args: object, **kwargs: object) -> None:
        raise AssertionError("the sweep ran")

    monkeypatch.setattr(sweep_module, "sweep", never)
    result = CliRunner().invoke(app, ["sweep", str(scenario), "--vary", "pid.k=1,2",
                                      "--metric", "valve travel", "-o", str(tmp_path / "o"),
                                      "-q"])
    assert result.exit_code == 2, result.output
    assert "--metric 'valve travel': this scenario has no such metric; its metrics: IAE" \
        in result.output
    assert "valve" not in result.output.split("its metrics:")[1]


def test_a_reused_output_directory_keeps_no_file_of_an_earlier_sweep(
        scenario: Path, tmp_path: Path) -> None:
    """A second sweep into the same -o directory: the first one's figures of another design
    and its trajectory files are removed (they would read as this sweep's); a file of the
    user's stays."""
    out = tmp_path / "o"
    first = CliRunner().invoke(app, ["sweep", str(scenario), "--vary", "pid.k=0.5:1.5:3",
                                     "--trajectory", "1", "-o", str(out), "-q"])
    assert first.exit_code == 0, first.output
    assert (out / "metrics_vs_parameter.png").exists()
    assert (out / "trajectory_base_1.csv").exists()
    (out / "mine.txt").write_text("the user's", encoding="utf-8")
    second = CliRunner().invoke(app, ["sweep", str(scenario), "--vary",
                                      "pid.k=uniform(0.5,1.5)", "--samples", "4", "-o",
                                      str(out), "-q"])
    assert second.exit_code == 0, second.output
    assert (out / "histograms.png").exists() and (out / "pareto.png").exists()
    assert not (out / "metrics_vs_parameter.png").exists()
    assert not list(out.glob("trajectory_*.csv"))
    assert (out / "mine.txt").read_text(encoding="utf-8") == "the user's"


def test_trajectories_only_for_the_points_asked(scenario: Path) -> None:
    result = sweep(scenario, {"pid.k": "1,2,3"}, trajectories=[2])
    assert set(result.trajectories) == {("base", 2), ("faster", 2)}
    run = result.trajectories[("faster", 2)]
    assert "process.y" in run.values and len(run.t) == 240  # every signal, every scan
    row = next(i for i in range(len(result)) if result.columns["variant"][i] == "faster"
               and result.columns["point"][i] == 2)
    metrics = run.metrics("pid", window=(20.0, 120.0))  # the scenario's metrics_window
    assert result.columns["pid.k"][row] == 3
    for name in ("IAE", "PV std", "output travel"):
        assert result.columns[name][row] == pytest.approx(metrics[name], rel=1e-12), name
    with pytest.raises(InputError, match="--trajectory 3: no such point"):
        sweep(scenario, {"pid.k": "1,2,3"}, trajectories=[3])


def test_a_choice_input_varied_by_name_and_by_code_is_one_column(scenario: Path) -> None:
    """`--vary pid.mode=AUTO,1` (both valid: a name and its code) ran and then crashed in
    pyarrow (a column of str and int) with nothing written; the column is now text."""
    result = sweep(scenario, ["pid.mode=AUTO,1"], variant="base", workers=1)
    assert result.columns["pid.mode"] == ["AUTO", "1"]
    assert result.to_arrow().num_rows == 2


def test_a_metric_with_no_value_is_null_in_json_and_na_in_the_table(scenario: Path,
                                                                     tmp_path: Path) -> None:
    """No setpoint step here, so "overshoot %" is n/a in every run: --json crashed in best()
    (KeyError) and wrote "nan" strings; the table printed nan. Now null, and n/a."""
    args = ["sweep", str(scenario), "--vary", "pid.k=0.5,1", "--workers", "1", "-q",
            "--metric", "overshoot %", "-o", str(tmp_path / "a")]
    done = CliRunner().invoke(app, [*args, "--json"])
    assert done.exit_code == 0, done.output
    data = json.loads(done.stdout)
    assert data["best"] is None
    # each variant's runs with no value are counted (they were left out silently; found by
    # an outside audit)
    assert data["variants"]["base"] == {"median": None, "p5": None, "p95": None, "best": None,
                                        "n_a": 2}
    done = CliRunner().invoke(app, [*args[:-1], str(tmp_path / "b")])
    assert done.exit_code == 0, done.output
    assert "n/a" in done.output and "nan" not in done.output


def test_n_a_is_null_in_the_results_files_and_the_json_counts_points_and_runs(
        scenario: Path, tmp_path: Path) -> None:
    """docs/sweeps.md: an n/a metric is null in results.parquet (it was a NaN value that
    Arrow counted and averaged as data) and an empty CSV field (was "nan"); --json's
    `instances` counts points and `runs` points × variants (`instances` was the runs)."""
    out = tmp_path / "r"
    done = CliRunner().invoke(app, ["sweep", str(scenario), "--vary", "pid.k=0.5,1,2",
                                    "--workers", "1", "-q", "--json", "-o", str(out)])
    assert done.exit_code == 0, done.output
    data = json.loads(done.stdout)
    assert (data["instances"], data["runs"]) == (3, 6)  # two [compare] variants
    table = pq.read_table(out / "results.parquet")
    assert table["overshoot %"].null_count == 6  # no setpoint step: n/a in every run
    assert str(table["overshoot %"].type) == "double"  # not a null-typed column
    assert table["PV std"].null_count == 0
    header, *rows = (out / "results.csv").read_text().splitlines()
    at = header.split(",").index('"overshoot %"')
    assert all(row.split(",")[at] == "" for row in rows) and "nan" not in rows[0]


def test_a_block_named_in_capitals_is_swept_as_simulate_runs_it(tmp_path: Path) -> None:
    """A block keeps its case as in [wires] (parameter names do not): --vary PID.k on
    [blocks.PID] was refused ("no block 'pid'; blocks: PID, ...") or, half-fixed, crashed."""
    text = SCENARIO.replace("[blocks.pid]", "[blocks.PID]").replace('"pid.', '"PID.')
    text = text.replace('= "pid.out"', '= "PID.out"')
    path = tmp_path / "caps.toml"
    path.write_text(text, encoding="utf-8")
    result = sweep(path, {"PID.K": "0.5,1.5"}, variant="base", workers=1)
    assert result.varied == ["PID.k"]
    for i in range(2):
        row = {k: col[i] for k, col in result.columns.items()}
        expected = _simulate_metrics(tmp_path, text, {"PID.k": row["PID.k"]}, row["seed"],
                                     "base")
        assert row["IAE"] == pytest.approx(expected["IAE"], rel=1e-9)
    with pytest.raises(InputError, match="no block 'pid'"):
        sweep(path, {"pid.k": "1,2"}, workers=1)
    figures = result.plot(directory=str(tmp_path / "figs"))  # a str as sweep() takes
    assert figures and all(f.is_file() for f in figures)
    from loopworks.sim.scenario import parse_scenario

    tuned = parse_scenario(text + '\n[autotune]\nloop = "PID"\nprocess_gain = ["PID.K"]\n')
    assert tuned.autotune_test is not None and tuned.autotune_test.loop == "PID"  # was 'pid'


def test_a_wrong_scheduler_address_or_workers_with_it_fail_before_running(
        scenario: Path) -> None:
    """`--scheduler notaurl` was a ValueError traceback from distributed, after the local
    warm-up runs; `--workers 2 --scheduler ...` silently dropped --workers."""
    def ran(done: int, total: int) -> None:
        pytest.fail("it ran")

    import threading

    threads = threading.active_count()
    for address in ("notaurl", "http://127.0.0.1:8786", "tcp://127.0.0.1:99999"):
        with pytest.raises(InputError, match=r"not a scheduler address .* expected "
                                             r"tcp://HOST:PORT"):
            sweep(scenario, ["pid.k=1,2"], scheduler=address, progress=ran)
    # refused before a Client was made: no event-loop thread left behind (one that was
    # left kept a CI test worker from exiting)
    assert threading.active_count() == threads
    with pytest.raises(InputError, match=r"--workers 2 with --scheduler: give one"):
        sweep(scenario, ["pid.k=1,2"], workers=2, scheduler="tcp://127.0.0.1:1", progress=ran)


def test_a_report_directory_that_cannot_be_made_is_refused_before_the_run(
        scenario: Path) -> None:
    """`-o /proc/x` passed the writability check (root may write anywhere, by os.access)
    and failed in mkdir after the run with a traceback; sweep, diagnose and simulate now
    make the directory first."""
    plant = Path(__file__).resolve().parents[1] / "data" / "plant-loops" / "plant03.csv"
    for args in (["sweep", str(scenario), "--vary", "pid.k=1,2"], ["simulate", "-q"],
                 ["diagnose", str(plant)]):
        done = CliRunner().invoke(app, [*args, "-o", "/proc/loopworks-nowhere"])
        assert done.exit_code == 2, (args, done.output)
        assert done.output.startswith("error: -o /proc/loopworks-nowhere: cannot create the "
                                      "report directory"), done.output


def test_the_python_api_takes_one_spec_or_a_list_of_values(scenario: Path) -> None:
    """`sweep(S, "pid.k=1,2")` read the string one character at a time, and
    `vary={"pid.k": [1, 2]}` failed on '[1'; both mean what they say."""
    one = sweep(scenario, "pid.k=1,2", variant="base", workers=1)
    listed = sweep(scenario, {"pid.k": [1, 2]}, variant="base", workers=1)
    assert one.columns["pid.k"] == listed.columns["pid.k"] == [1, 2]
    same_table(one.columns, listed.columns)


def test_a_seed_that_is_not_a_whole_number_is_refused(scenario: Path) -> None:
    """`sweep(..., seed=1.5)` ran as seed 1 (found by a user)."""
    with pytest.raises(InputError, match=r"--seed 1.5: expected a whole number"):
        sweep(scenario, ["pid.k=1,2"], seed=1.5, workers=1)  # type: ignore[arg-type]


def test_a_plan_that_is_not_one_is_refused_before_the_run(scenario: Path) -> None:
    with pytest.raises(InputError, match=r"plan = 'inlined' is not allowed: expected auto, "
                                         r"compiled or fused"):
        sweep(scenario, ["pid.k=1,2"], plan="inlined", workers=1)


def short_default(tmp_path: Path, duration: float, window: tuple[float, float]
                  ) -> tuple[Path, str]:
    """examples/default.toml (the built-in scenario, with [autotune]) run for ``duration`` s
    and scored over ``window``, written to tmp_path: its path and text."""
    root = Path(__file__).resolve().parents[2]
    text = (root / "examples" / "default.toml").read_text(encoding="utf-8")
    text = text.replace("duration = 3600.0", f"duration = {duration!r}").replace(
        "metrics_window = [1800.0, 3600.0]", f"metrics_window = [{window[0]!r}, {window[1]!r}]")
    path = tmp_path / "short.toml"
    path.write_text(text, encoding="utf-8")
    return path, text


def test_each_point_is_relay_tested_as_simulate_would(tmp_path: Path) -> None:
    """A scenario with [autotune]: the sweep ran the relay test once, on the scenario as
    written, and put that gain into every instance, while `simulate` of a row's values runs
    it on those values (pid.gain 1.0: 0.850 against 0.945; found by a user comparing rows
    with simulate). Each point now has its own test, and its gain is a column; varying the
    parameter [autotune] writes is refused (simulate's test would overwrite it)."""
    from loopworks.sim.scenario import parse_scenario, run_autotune

    path, text = short_default(tmp_path, 600.0, (300.0, 600.0))
    result = sweep(path, {"pid.gain": "0.8,1.0"}, variant="compensation_on", workers=1)
    gains = result.columns["compensator.process_gain"]
    assert gains[0] != gains[1]
    for row in range(2):
        value, seed = result.columns["pid.gain"][row], result.columns["seed"][row]
        one = text.replace("gain = 0.8\n", f"gain = {value!r}\n").replace(
            "[simulation]\n", f"[simulation]\nseed = {seed}\n")
        sc = parse_scenario(one, source="row")
        at = run_autotune(sc)
        assert at is not None and gains[row] == pytest.approx(at["process_gain"], rel=1e-12)
        expected = sc.variants["compensation_on"].run(sc.duration, sc.dt).metrics(
            window=sc.metrics_window)
        for name, want in expected.items():
            assert result.columns[name][row] == pytest.approx(want, rel=1e-9, abs=1e-12,
                                                               nan_ok=True), (row, name)
    with pytest.raises(InputError, match=r"--vary compensator.process_gain: \[autotune\] "
                                         "writes this parameter"):
        sweep(path, {"compensator.process_gain": "0.5,1"}, workers=1)


def test_a_point_whose_relay_test_fails_is_n_a_and_the_others_run(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """One point of a Monte Carlo whose [autotune] relay test identifies no gain (the
    built-in scenario's valve.resolution = 0.2637 of uniform(0.2, 0.8) did not converge)
    failed the whole sweep, every other point's test and run lost. Its rows are now n/a with
    the test's error in a column and one warning; the other rows are the sweep's without it.
    When every point fails, the first one's error is raised, as before."""
    import loopworks.sim.scenario as scenario_module
    from loopworks.errors import LoopworksError

    path, _ = short_default(tmp_path, 300.0, (100.0, 300.0))
    vary = {"pid.gain": "0.8,1.0,1.2"}
    whole = sweep(path, vary, variant="compensation_on", workers=1)
    real = scenario_module.autotune_gain

    def failing(sc: object, point: dict[str, object] | None = None, **kw: object) -> object:
        if point and point.get("pid.gain") == 1.0:
            raise LoopworksError("the relay test did not converge (a test's failure)")
        return real(sc, point, **kw)  # type: ignore[arg-type]

    monkeypatch.setattr(scenario_module, "autotune_gain", failing)
    with pytest.warns(UserWarning, match=r"1 of 3 points' \[autotune\] relay tests identified "
                      r"no process gain.*point 1 \(pid.gain = 1.0\): the relay test did not"):
        part = sweep(path, vary, variant="compensation_on", workers=1)
    assert part.columns["autotune_error"] == [
        None, "the relay test did not converge (a test's failure)", None]
    assert math.isnan(part.columns["compensator.process_gain"][1])
    from loopworks.sim import sweep_report

    sweep_report.write_summary(part, tmp_path / "report", "t", "loopworks sweep", None)
    page = (tmp_path / "report" / "summary.html").read_text(encoding="utf-8")
    assert "1 of 3 points did not run" in page and "a test&#x27;s failure" in page
    for name in whole.metrics:
        assert math.isnan(part.columns[name][1]), name
        for row in (0, 2):
            assert part.columns[name][row] == pytest.approx(
                whole.columns[name][row], rel=1e-12, abs=1e-15, nan_ok=True), (row, name)
    monkeypatch.setattr(scenario_module, "autotune_gain", lambda *a, **k: (_ for _ in ()).throw(
        LoopworksError("no gain")))
    with pytest.raises(InputError, match=r"point 0 \(pid.gain = 0.8\): no gain"):
        sweep(path, vary, variant="compensation_on", workers=1)


def test_a_loop_name_missing_from_the_metric_is_refused_before_the_run(tmp_path: Path) -> None:
    """Two loops: metrics are "LOOP: name"; `--metric IAE` was refused only after every
    instance had run, and nothing was written."""
    two = SCENARIO.replace("[wires]", '[blocks.pid2]\nkind = "pid"\nk = 1.0\nti = 10.0\n\n'
                           '[blocks.process2]\nkind = "process.fopdt"\ngain = 1.0\n'
                           'time_constant = 5.0\n\n[wires]\n"process2.u" = "pid2.out"\n'
                           '"pid2.pv" = "process2.y"', 1)
    assert two != SCENARIO
    path = tmp_path / "two.toml"
    path.write_text(two, encoding="utf-8")
    result = CliRunner().invoke(app, ["sweep", str(path), "--vary", "pid.k=1,2", "--metric",
                                      "IAE", "-o", str(tmp_path / "o"), "-q"])
    assert result.exit_code == 2
    assert "2 loops: name one, as 'LOOP: IAE' with LOOP one of pid, pid2" in result.output
    assert not (tmp_path / "o").exists()


def test_an_infinite_varied_value_is_inf_in_json_not_null(scenario: Path,
                                                          tmp_path: Path) -> None:
    """`--vary pid.ti=inf` (allowed: no integral action) printed "pid.ti": null in --json,
    which the docs define as n/a; results.csv says inf. It is the text "inf" now."""
    result = CliRunner().invoke(app, ["sweep", str(scenario), "--vary", "pid.ti=inf",
                                      "--variant", "base", "--workers", "1", "-q", "--json",
                                      "--metric", "PV std", "-o", str(tmp_path / "o")])
    assert result.exit_code == 0, result.output
    best = json.loads(result.stdout)["best"]
    assert best["pid.ti"] == "inf" and isinstance(best["PV std"], float)


def test_a_swept_out_scale_scores_output_travel_in_each_instances_span(
        tmp_path: Path) -> None:
    """A DeltaV PID's OUT is in OUT_SCALE's EU, and output travel is scored in % of that span
    (spec 4.1, docs/metrics.md): a sweep of OUT_SCALE scored every instance against the
    template's span (an OUT_SCALE of 0..200 EU printed twice its travel). Each row now
    equals ``loopworks simulate`` of its point."""
    text = SCENARIO.replace('kind = "pid"\nk = 1.0\nti = 20.0\nsp = 50.0\nbias = 50.0\n',
                            'kind = "deltav.pid"\ngain = 1.0\nreset = 20.0\nsp = 50.0\n'
                            'initial_out = 50.0\nout_scale_eu_100 = 100.0\n'
                            ).replace('"pid.ti" = 10.0', '"pid.reset" = 10.0')
    assert "deltav.pid" in text and "ti" not in text.split("[compare.base]")[1]
    path = tmp_path / "deltav.toml"
    path.write_text(text, encoding="utf-8")
    result = sweep(path, {"pid.out_scale_eu_100": "100,200"}, variant="base", workers=1)
    travel = []
    for i in range(2):
        row = {k: col[i] for k, col in result.columns.items()}
        expected = _simulate_metrics(tmp_path, text, {
            "pid.out_scale_eu_100": row["pid.out_scale_eu_100"]}, row["seed"], "base")
        for name in ("output travel", "output reversals", "IAE"):
            assert row[name] == pytest.approx(expected[name], rel=1e-9), name
        travel.append(row["output travel"])
    assert travel[0] != pytest.approx(travel[1], rel=0.05)  # the runs differ: a real check


def test_sweep_figures_sort_the_grid_and_share_one_colour_scale(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A 1-D grid given as `30,5,15,10` was drawn joined in that order (a zig-zag), heat-map
    axes kept the order given, and each variant's heat map had its own colour scale (one
    yellow was 0.55 in one panel and 0.41 beside it; found by a user of the summaries). The
    points are joined in x order, the axes sorted, one scale spans every variant and the
    best instance is ringed."""
    from loopworks.sim import sweep_report
    from loopworks.sim.sweep import SweepResult

    kept: list[Any] = []
    monkeypatch.setattr(sweep_report, "_save", lambda fig, path: kept.append(fig) or path)
    one = SweepResult({"variant": ["a"] * 4, "point": [0, 1, 2, 3], "seed": [1, 2, 3, 4],
                       "pid.ti": [30.0, 5.0, 15.0, 10.0], "IAE": [4.0, 1.0, 3.0, 2.0]},
                      ["pid.ti"], "grid", grid_shape=(4,), metrics=["IAE"])
    sweep_report.figures(one, tmp_path, "IAE")
    line = kept[0].axes[0].lines[0]
    assert list(line.get_xdata()) == [5.0, 10.0, 15.0, 30.0]
    assert list(line.get_ydata()) == [1.0, 2.0, 3.0, 4.0]
    cols: dict[str, list[Any]] = {"variant": [], "point": [], "seed": [], "x": [], "y": [],
                                  "IAE": []}
    for v, offset in (("a", 0.0), ("b", 10.0)):
        for k, (x, y) in enumerate(((3.0, 1.0), (1.0, 1.0), (3.0, 2.0), (1.0, 2.0))):
            for name, value in zip(cols, (v, k, k, x, y, offset + x + y), strict=True):
                cols[name].append(value)
    two = SweepResult(cols, ["x", "y"], "grid", grid_shape=(2, 2), metrics=["IAE"])
    sweep_report.figures(two, tmp_path, "IAE")
    heat = kept[1]
    images = [ax.images[0] for ax in heat.axes if ax.images]
    assert [im.get_clim() for im in images] == [(2.0, 15.0)] * 2
    assert [t.get_text() for t in heat.axes[0].get_xticklabels()] == ["1", "3"]
    assert images[0].get_array()[0, 0] == 2.0  # x = 1, y = 1: the corner, sorted
    assert any(line.get_label() == "best" for line in heat.axes[0].lines)


S5_LOOP = """\
[simulation]
dt = 1.0
duration = 200.0

[blocks.s5]
kind = "s5.pid"
k = 500
ti = 100
w = 500.0
velocity = false

[blocks.process]
kind = "process.first_order"
gain = 1.0
time_constant = 20.0

[wires]
"process.u" = "s5.y"
"s5.x" = "process.y"

[[events]]
t = 100.0
set = "s5.w"
value = 600.0
"""


def test_a_swept_velocity_scores_each_instances_output_as_it_is(tmp_path: Path) -> None:
    """docs/metrics.md: a velocity output (S5 velocity = true) is scored on the position its
    increments build. A sweep of s5.velocity scored every instance as the scenario file
    had it (the output travel of the velocity instance read 40.9 where simulate gives 769.2;
    found by an outside audit). Each row now equals ``loopworks simulate`` of its point."""
    path = tmp_path / "s5.toml"
    path.write_text(S5_LOOP, encoding="utf-8")
    result = sweep(path, {"s5.velocity": "true,false"}, workers=1)
    travel = []
    for i in range(2):
        row = {k: col[i] for k, col in result.columns.items()}
        assert isinstance(row["s5.velocity"], bool)  # the parameter's type
        text = S5_LOOP.replace("velocity = false",
                               f"velocity = {str(row['s5.velocity']).lower()}")
        one = tmp_path / f"point{i}.toml"
        one.write_text(text.replace("[simulation]\n", f"[simulation]\nseed = {row['seed']}\n"),
                       encoding="utf-8")
        done = CliRunner().invoke(app, ["simulate", str(one), "-o", str(tmp_path / f"r{i}"),
                                        "-q"])
        assert done.exit_code == 0, done.output
        report = json.loads((tmp_path / f"r{i}" / "metrics.json").read_text())
        expected = report[row["variant"]]
        for name in ("output travel", "output reversals", "IAE"):
            assert row[name] == pytest.approx(expected[name], rel=1e-9, nan_ok=True), name
        travel.append(row["output travel"])
    assert travel[0] != pytest.approx(travel[1], rel=0.05)  # the runs differ: a real check


def test_a_whole_number_parameter_refuses_a_continuous_distribution(tmp_path: Path) -> None:
    """docs/sweeps.md: uniform, loguniform and normal draw fractions, and an S5 word is a
    whole number: the sweep is refused before anything runs, saying what to give instead
    (it was refused as "s5.k = 400.0000002 must be an integer"; found by an outside audit)."""
    path = tmp_path / "s5.toml"
    path.write_text(S5_LOOP, encoding="utf-8")
    for spec in ("uniform(400,600)", "loguniform(400,600)", "normal(500,50)"):
        with pytest.raises(InputError, match=r"--vary s5.k: .*draws fractional values, and "
                                             r"s5.k is a whole number .*: give a list"):
            sweep(path, {"s5.k": spec}, samples=4, workers=1)
    assert len(sweep(path, {"s5.k": "400,600"}, workers=1)) == 2
    # a whole float typed for a whole-number parameter is its integer, in the table too
    typed = sweep(path, {"s5.k": "400.0,600"}, workers=1)
    assert typed.columns["s5.k"] == [400, 600]
    assert {type(v) for v in typed.columns["s5.k"]} == {int}


def test_a_combination_a_block_refuses_is_refused_before_anything_runs(
        scenario: Path) -> None:
    """`pid.out_lo=0,10,150` against the scenario's out_hi = 100: refused only when the batch
    of point 2 loaded, after the other instances had run, nothing written; with [autotune]
    taken for a relay test that identified no gain, the sweep ending well (found by an
    outside audit). Every point's values are checked together first."""
    ran: list[int] = []
    with pytest.raises(InputError, match=r"--vary: point 2 \(pid\.out_lo = 150\.0\) in "
                                         r"variant 'base': pid: parameter 'out_hi' = 100 must "
                                         r"be greater than out_lo = 150"):
        sweep(scenario, ["pid.out_lo=0,10,150"], workers=1,
              progress=lambda done, total: ran.append(done))
    assert ran == []
    # [autotune] (the built-in scenario): refused before its relay tests, not n/a rows
    tests: list[int] = []
    with pytest.raises(InputError, match=r"point 1 \(pid\.ff_scale_eu_0 = 200\.0\) .*"
                                         r"'ff_scale_eu_100' = 100 must be greater"):
        sweep(None, ["pid.ff_scale_eu_0=0,200"], workers=1,
              relay_progress=lambda done, total: tests.append(done))
    assert tests == []


def test_text_and_bool_columns_have_their_parameters_type(tmp_path: Path) -> None:
    """A text parameter's numbers are text (`process.num=2,3` was refused: "'num' = 2 must
    be text"), a bool parameter's true/yes/1 are one bool column (they made a string or an
    int64 column by how they were typed; found by an outside audit)."""
    path = tmp_path / "tf.toml"
    path.write_text(SCENARIO.replace('kind = "process.fopdt"\ngain = 1.0\ntime_constant = '
                                     '10.0\ndead_time = 1.0\nu0 = 50.0',
                                     'kind = "process.tf"\nnum = "1"\nden = "10, 1"\nu0 = 50.0\n'
                                     'sample_time = 0.5'
                                     ).replace('[compare.faster]\n"pid.ti" = 10.0\n', ''))
    result = sweep(path, ["process.num=2,3"], workers=1)
    assert result.columns["process.num"] == ["2", "3"]
    path.write_text(S5_LOOP)
    for typed in ("true,false", "1,0", "yes,no"):
        result = sweep(path, [f"s5.velocity={typed}"], workers=1)
        assert result.columns["s5.velocity"] == [True, False], typed


def test_plot_removes_no_file_of_the_users(scenario: Path, tmp_path: Path) -> None:
    """`.plot()` wrote into the current directory and removed every figure name it did not
    draw: a user's own pareto.png and histograms.png there were deleted (found by an outside
    audit). Only a sweep's report directory (-o DIR) is cleaned of an earlier sweep's."""
    theirs = tmp_path / "mine"
    theirs.mkdir()
    for name in ("heatmap.png", "pareto.png", "histograms.png"):
        (theirs / name).write_text("my own figure")
    result = sweep(scenario, ["pid.k=0.5,1,2"], variant="base", workers=1)
    drawn = result.plot(directory=theirs)
    for name in ("heatmap.png", "pareto.png", "histograms.png"):
        path = theirs / name
        assert path.exists(), name
        if path not in drawn:
            assert path.read_text() == "my own figure"


def test_the_summarys_command_is_quoted_for_a_shell() -> None:
    from loopworks.cli import _sweep_command

    argv = ["/venv/bin/loopworks", "sweep", "loop.toml", "--vary", "pid.k=uniform(1,2)",
            "--metric", "PV std"]
    assert _sweep_command(argv) == ("loopworks sweep loop.toml --vary 'pid.k=uniform(1,2)' "
                                    "--metric 'PV std'")


def test_a_range_keeps_its_ends_and_refuses_values_it_cannot_tell_apart() -> None:
    """a:b:n rounded its ends to 15 digits (0.1234567890123456 became 0.123456789012346) and
    1:1.000000000000001:3 made three runs of 1.0 (found by an outside audit)."""
    axis = parse_vary("pid.k=0.1234567890123456:0.2:3")
    assert axis.values[0] == 0.1234567890123456 and axis.values[-1] == 0.2
    assert parse_vary("pid.k=1:2:11").values[7] == 1.7  # the inner values' decimals, as before
    with pytest.raises(InputError, match=r"3 values from 1\.0 to 1\.000000000000001 are not "
                                         r"all different"):
        parse_vary("pid.k=1:1.000000000000001:3")


def test_a_sweep_too_large_or_a_count_of_the_wrong_type_is_refused(scenario: Path) -> None:
    """A grid of 1e20 values or 1e13 samples was a numpy traceback (out of memory);
    samples=2.5, workers=2.0 a bare TypeError; trajectories=[True] point 1 (found by an
    outside audit)."""
    with pytest.raises(InputError, match=r"n = 1e20 values: a sweep runs at most 10,000,000"):
        parse_vary("pid.k=1:2:1e20")
    with pytest.raises(InputError, match=r"would run 20,000,000,000,000 instances"):
        sweep(scenario, ["pid.k=uniform(1,2)"], samples=10**13, workers=1)
    for kwargs, message in (({"samples": 2.5}, "--samples 2.5: expected a whole number"),
                            ({"samples": "3"}, "--samples '3': expected a whole number"),
                            ({"workers": 2.0}, "--workers 2.0: expected a whole number"),
                            ({"trajectories": [True]}, "--trajectory True: no such point")):
        with pytest.raises(InputError, match=re.escape(message)):
            sweep(scenario, ["pid.k=uniform(1,2)"], **{"samples": 2, "workers": 1, **kwargs})


def test_the_cli_runs_a_large_sweep_in_one_process_per_core(
        scenario: Path, monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """One process makes each instance's row and metrics in Python on one core while its
    batch's scans use every core: the CLI's default (``workers="auto"``) runs a sweep of
    ``AUTO_WORKERS_INSTANCES`` or more in one process per core (at most ``AUTO_WORKERS``),
    with the numbers of one process; below that, and from Python by default (a script
    without a ``__main__`` guard cannot start processes), in this one."""
    from concurrent.futures import ProcessPoolExecutor

    from loopworks.sim import sweep as sweep_mod

    started: list[int] = []

    class Counted(ProcessPoolExecutor):
        def __init__(self, n: int, **kwargs: Any) -> None:
            started.append(n)
            super().__init__(n, **kwargs)

    monkeypatch.setattr(sweep_mod, "ProcessPoolExecutor", Counted)
    monkeypatch.setattr(sweep_mod.os, "cpu_count", lambda: 8)
    monkeypatch.setattr(sweep_mod, "AUTO_WORKERS_INSTANCES", 12)
    vary = ["pid.k=uniform(0.5,1.5)"]
    one = sweep(scenario, vary, samples=6, seed=3)  # 12 instances: two variants
    assert started == []
    auto = sweep(scenario, vary, samples=6, seed=3, workers="auto")
    assert started == [sweep_mod.AUTO_WORKERS] == [4]
    same_table(one.columns, auto.columns)
    sweep(scenario, vary, samples=5, seed=3, workers="auto")  # 10 instances: here
    assert started == [4]
    seen: list[Any] = []
    monkeypatch.setattr(sweep_mod, "sweep", lambda *a, **k: seen.append(k["workers"]) or one)
    for args, workers in (([], "auto"), (["--workers", "2"], 2)):
        got = CliRunner().invoke(app, ["sweep", str(scenario), "--vary", vary[0], "-q",
                                       "-o", str(tmp_path / "out"), *args])
        assert got.exit_code == 0, got.output
        assert seen[-1] == workers
    with pytest.raises(InputError, match=r"--workers 'two': expected a whole number"):
        sweep(scenario, vary, workers="two")
