"""Batches (issue 14 point 1): N instances of a module in one compiled call give, instance by
instance, the numbers of building that instance's module and running it."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from loopworks.errors import InputError, LoopworksError
from loopworks.sim.batch import Batch, InstanceError, fixed_names
from loopworks.sim.scenario import load_scenario, parse_scenario
from loopworks.sim.sweep import Job, run_jobs

EXAMPLES = sorted(Path(__file__).resolve().parents[2].joinpath("examples").glob("*.toml"))


def _scaled_changes(sc, variant: str, rng: np.random.Generator) -> dict[str, float]:
    """Up to three float parameters of the variant's blocks scaled by 0.8..1.2, each change
    kept only when the scenario builds with it (a cross-parameter check may refuse one)."""
    module = sc.template(variant)
    options = []
    for name, block in module.blocks.items():
        for p in block.PARAMS:
            value = block.params[p.name]
            if (p.type == "float" and p.name not in block.FIXED_PARAMS and p.name != "seed"
                    and isinstance(value, float) and math.isfinite(value) and value > 0):
                options.append((f"{name}.{p.name}", value))
    changes: dict[str, float] = {}
    for k in rng.permutation(len(options))[:3]:
        name, value = options[int(k)]
        trial = {**changes, name: float(value * rng.uniform(0.8, 1.2))}
        try:
            sc.build(variant, trial, 1)
        except LoopworksError:
            continue
        changes = trial
    return changes


def _compare(sc, variant: str, instances, seeds, duration: float | None = None) -> None:
    template = sc.template(variant)
    record = template.signals()
    batch = Batch(template, record)
    batch.load(instances, seeds)
    R, RS = batch.run(duration or sc.duration, sc.dt)
    for i, (changes, seed) in enumerate(zip(instances, seeds, strict=True)):
        module = sc.build(variant, changes, seed)
        result = module.run(duration or sc.duration, sc.dt)
        for j, name in enumerate(record):
            np.testing.assert_allclose(R[i, j], result.values[name], rtol=1e-12, atol=1e-12,
                                       err_msg=f"{variant} instance {i} {changes}: {name}")
            np.testing.assert_array_equal(RS[i, j], result.status[name],
                                          err_msg=f"{variant} instance {i}: {name} status")


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_batch_equals_one_module_per_instance(path: Path) -> None:
    sc = load_scenario(path)
    rng = np.random.default_rng(7)
    for variant in sc.variants:
        instances = [_scaled_changes(sc, variant, rng) for _ in range(2)]
        _compare(sc, variant, instances, [11, None], duration=min(sc.duration, 300.0))


PARAM_EVENTS = """
[simulation]
dt = 0.5
duration = 200.0

[blocks.pid]
kind = "deltav.pid"
gain = 0.8
reset = 20.0
sp = 50.0
mode = "AUTO"
retune = "bumpless"

[blocks.pi]
kind = "pid"
k = 1.5
ti = 15.0
sp = 40.0

[blocks.process]
kind = "process.fopdt"
gain = 1.0
time_constant = 20.0
dead_time = 2.0
u0 = 50.0

[blocks.second]
kind = "process.fopdt"
gain = 2.0
time_constant = 10.0
dead_time = 1.0

[blocks.sensor]
kind = "sensor.transmitter"
noise_std = 0.05
seed = 3

[wires]
"process.u" = "pid.out"
"sensor.y" = "process.y"
"pid.pv" = "sensor.pv"
"second.u" = "pi.out"
"pi.pv" = "second.y"

[[events]]
t = 40.0
set = "pid.gain"
value = 1.6

[[events]]
t = 40.0
set = "pi.k"
value = 0.7

[[events]]
t = 80.0
set = "pid.sp"
value = 55.0

[[events]]
t = 120.0
set = "process.dead_time"
value = 4.0
"""


def test_parameter_events_apply_to_each_instance() -> None:
    # a retune in Auto corrects each instance's integral from its own state (deltav.pid's
    # retune = "bumpless", pid's set_params); a dead-time change keeps each instance's own
    # varied gain: both only if the event is applied row by row with the row's parameters
    sc = parse_scenario(PARAM_EVENTS)
    instances = [{"pid.reset": r, "pi.ti": ti, "process.gain": g}
                 for r, ti, g in ((10.0, 5.0, 0.5), (20.0, 15.0, 1.0), (40.0, 30.0, 2.0))]
    _compare(sc, "base", instances, [1, 2, 3])


def test_state_sizing_parameters_make_groups() -> None:
    sc = parse_scenario(PARAM_EVENTS)
    template = sc.template("base")
    assert fixed_names(template, ["process.delay_capacity", "pid.gain"]) == [
        "process.delay_capacity"]
    jobs = [Job(i, "base", {"process.delay_capacity": cap, "pid.gain": g}, 100 + i)
            for i, (cap, g) in enumerate(((10, 0.5), (500, 0.5), (10, 1.2), (500, 2.0)))]
    rows = run_jobs(sc.text, sc.source, jobs)
    for job, row in zip(jobs, rows, strict=True):
        result = sc.build("base", job.changes, job.seed).run(sc.duration, sc.dt)
        expected = result.metrics("pid")
        got = {k.split(": ", 1)[1]: v for k, v in row.items() if k.startswith("pid: ")}
        assert got.keys() == expected.keys()
        for name, value in expected.items():
            assert got[name] == pytest.approx(value, rel=1e-12, abs=1e-12, nan_ok=True), name


def test_a_refused_instance_is_named() -> None:
    sc = parse_scenario(PARAM_EVENTS)
    batch = Batch(sc.template("base"), ["pid.out"])
    with pytest.raises(InstanceError) as info:
        batch.load([{"pid.gain": 1.0}, {"pid.reset": -5.0}], [1, 2])
    assert info.value.index == 1
    assert "reset" in str(info.value)
    jobs = [Job(0, "base", {"pi.k": 1.0}, 1), Job(4, "base", {"pi.k": -3.0}, 2)]
    with pytest.raises(InputError, match=r"instance 4 \(base; pi\.k = -3\.0\)"):
        run_jobs(sc.text, sc.source, jobs)


def test_an_unknown_signal_is_refused() -> None:
    sc = parse_scenario(PARAM_EVENTS)
    with pytest.raises(InputError, match=r"no signal 'pid\.nothing'"):
        Batch(sc.template("base"), ["pid.nothing"])


def test_rows_are_independent_of_the_batch_they_run_in() -> None:
    # instance order and batch size do not change an instance's numbers (no shared state
    # between the parallel rows)
    sc = parse_scenario(PARAM_EVENTS)
    template = sc.template("base")
    batch = Batch(template, ["pid.out", "pi.out", "sensor.pv"])
    instances = [{"pid.gain": 0.5 + 0.1 * i} for i in range(9)]
    batch.load(instances, list(range(9)))
    whole, whole_status = batch.run(sc.duration, sc.dt)
    batch.load(instances[::-1][:4], list(range(9))[::-1][:4])
    part, part_status = batch.run(sc.duration, sc.dt)
    np.testing.assert_array_equal(part, whole[::-1][:4])
    np.testing.assert_array_equal(part_status, whole_status[::-1][:4])


def test_a_bad_measurement_is_na_in_a_sweep_as_in_one_run() -> None:
    """A transmitter failed "bad" holds a finite value with Bad status; one run's metrics read
    those samples as no measurement (PV figures n/a, docs/metrics.md). The batch recorded
    values only, so a sweep scored the held value as measured (a finite IAE where `simulate`
    of the same values says n/a): it now records the statuses too."""
    from loopworks.sim.scenario import parse_scenario

    text = PARAM_EVENTS.replace('seed = 3\n', 'seed = 3\nfailure = "bad"\n'
                                'failure_start = 100.0\nfailure_end = 110.0\n')
    sc = parse_scenario(text)
    jobs = [Job(i, "base", {"pid.gain": g}, 5 + i) for i, g in enumerate((0.5, 1.0))]
    rows = run_jobs(sc.text, sc.source, jobs)
    for job, row in zip(jobs, rows, strict=True):
        expected = sc.build("base", job.changes, job.seed).run(sc.duration, sc.dt).metrics("pid")
        assert math.isnan(expected["IAE"]) and math.isfinite(expected["output travel"])
        got = {k.split(": ", 1)[1]: v for k, v in row.items() if k.startswith("pid: ")}
        for name, value in expected.items():
            assert got[name] == pytest.approx(value, rel=1e-12, abs=1e-12, nan_ok=True), name


def test_every_instance_is_checked_at_the_scan_time() -> None:
    """`--vary process.dead_time=600,1` at dt 0.5 s with a delay line of 1000 scans: the
    batch checked only the last instance loaded (1 s) against dt, and the 600 s one ran with
    its dead time cut to the line's length, metrics and all (found by a user; in the other
    order the error came, but named no instance). Each instance is checked as it is loaded."""
    sc = parse_scenario(PARAM_EVENTS)
    jobs = [Job(0, "base", {"process.dead_time": 600.0}, 1),
            Job(1, "base", {"process.dead_time": 1.0}, 2)]
    with pytest.raises(InputError, match=r"instance 0 \(base; process\.dead_time = 600\.0\):"
                                         r" .*delay_capacity"):
        run_jobs(sc.text, sc.source, jobs)


FUSED_LOOP = """
[simulation]
dt = 0.5
duration = 100.0

[blocks.pi]
kind = "pid"
k = 1.5
ti = 15.0
sp = 40.0

[blocks.process]
kind = "process.fopdt"
gain = 2.0
time_constant = 10.0
dead_time = 1.0

[blocks.sensor]
kind = "sensor.transmitter"
noise_std = 0.05
seed = 3

[wires]
"process.u" = "pi.out"
"sensor.y" = "process.y"
"pi.pv" = "sensor.pv"

[[events]]
t = 40.0
set = "pi.k"
value = 0.7
"""


def test_the_fused_batch_gives_the_batchs_numbers(monkeypatch: pytest.MonkeyPatch) -> None:
    """``plan="fused"`` (every kernel inlined into the batch: ``batch_fused``) gives the
    compiled batch's numbers bit for bit, events and seeded noise included; ``"auto"`` takes
    it when the sweep is long enough (``PLAN_FUSE_BLOCK_SCANS``) or it is cached, else the
    batch; another plan is refused."""
    import loopworks.blocks.plan as plan_mod
    import loopworks.sim.module as module_mod

    sc = parse_scenario(FUSED_LOOP)
    batch = Batch(sc.template("base"), ["pi.out", "sensor.pv", "process.y"])
    instances = [{"pi.k": k, "process.time_constant": tau}
                 for k, tau in ((0.8, 8.0), (1.5, 10.0), (2.5, 14.0))]
    taken: list[str] = []
    entry = plan_mod.entry
    monkeypatch.setattr("loopworks.sim.batch.entry",
                        lambda slots, what, sig: taken.append(what) or entry(slots, what, sig))
    results = {}
    for plan in ("compiled", "fused"):
        batch.load(instances, [4, 5, 6])
        results[plan] = batch.run(sc.duration, sc.dt, plan)
    assert taken == ["batch", "batch_fused"]
    np.testing.assert_array_equal(results["fused"][0], results["compiled"][0])
    np.testing.assert_array_equal(results["fused"][1], results["compiled"][1])
    _compare(sc, "base", instances[:1], [4])  # and both are one module's run
    # "auto": fused when cached, or when the block-scans (3 × 200 scans × 3 blocks, or the
    # whole sweep's ``total`` instances) reach the threshold
    for cached, threshold, total, expected in ((False, 1801, None, "batch"),
                                               (False, 1800, None, "batch_fused"),
                                               (False, 1801, 4, "batch_fused"),
                                               (True, 10**12, None, "batch_fused")):
        monkeypatch.setattr(plan_mod, "is_cached", lambda *a, c=cached, **k: c)
        monkeypatch.setattr(module_mod, "PLAN_FUSE_BLOCK_SCANS", threshold)
        batch.load(instances, [4, 5, 6])
        batch.run(sc.duration, sc.dt, total=total)
        assert taken[-1] == expected, (cached, threshold, total)
    with pytest.raises(InputError, match="plan = 'inline' is not allowed"):
        batch.run(sc.duration, sc.dt, "inline")
