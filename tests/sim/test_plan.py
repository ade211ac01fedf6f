"""The execution plan (issue 12): the compiled plan and the interpreted run give the same
numbers, on random modules of every kind and on every example scenario; the plan's cache is
keyed so that a second process loads instead of compiling, and a cache that cannot be written
falls back to compiling in memory with one warning."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import loopworks
from loopworks.blocks import plan
from loopworks.errors import InputError
from loopworks.sim.module import Event, Module
from loopworks.sim.result import SimResult
from loopworks.sim.scenario import load_scenario
from tests.blocks.test_block_model import VARIANTS, random_inputs, scan_time

EXAMPLES = sorted((Path(__file__).parents[2] / "examples").glob("*.toml"))
SCANS = 400


def assert_same(a: SimResult, b: SimResult, where: str) -> None:
    """Every recorded value equal to 1e-12 (NaN where NaN) and every status byte equal."""
    assert a.values.keys() == b.values.keys()
    np.testing.assert_array_equal(a.t, b.t)
    for name in a.values:
        np.testing.assert_allclose(a.values[name], b.values[name], rtol=1e-12, atol=1e-12,
                                   equal_nan=True, err_msg=f"{where}: {name}")
        np.testing.assert_array_equal(a.status[name], b.status[name],
                                      err_msg=f"{where}: {name} status")


def random_events(kind: str, params: dict[str, Any], dt: float,
                  rng: np.random.Generator) -> list[Event]:
    """New random inputs (NaN, inf and non-Good statuses included) every few scans."""
    probe = loopworks.create_block(kind, jit=False, **params)
    events = []
    for k in range(0, SCANS, int(rng.integers(1, 9))):
        for name, value in random_inputs(probe, rng).items():
            if name != "clock":  # the module's clock drives it
                events.append(Event(t=k * dt, target=f"b.{name}", value=value))
    return events


@pytest.mark.parametrize("kind", sorted(VARIANTS))
def test_compiled_plan_equals_the_interpreted_run(kind: str) -> None:
    """Issue 12: one equivalence test per kind. A module of the block alone, its inputs
    changed by events at random scans (the plan runs in chunks between them), run as the
    compiled plan and as the interpreted reference, for every parameter variant."""
    rng = np.random.default_rng(20261202)
    for params in VARIANTS[kind]:
        dt = scan_time(params, rng, 0.05, 1.0)
        events = random_events(kind, params, dt, rng)
        runs = [Module({"b": loopworks.create_block(kind, jit=jit, **params)}, events=events)
                .run(SCANS * dt, dt, plan=how)
                for jit, how in ((False, "python"), (True, "compiled"))]
        assert_same(*runs, where=f"{kind} {params}")


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_every_example_runs_the_same_compiled_and_interpreted(
        path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Every example scenario, each variant: the first 1500 scans (or all) as the compiled
    plan and interpreted (LOOPWORKS_JIT=0 when the scenario is loaded)."""
    compiled = load_scenario(path)
    monkeypatch.setenv("LOOPWORKS_JIT", "0")
    interpreted = load_scenario(path)
    assert compiled.variants.keys() == interpreted.variants.keys()
    duration = min(compiled.duration, 1500 * compiled.dt)
    for name, module in compiled.variants.items():
        assert module.compiled and not interpreted.variants[name].compiled
        a = module.run(duration, compiled.dt, plan="compiled")
        b = interpreted.variants[name].run(duration, compiled.dt, plan="python")
        assert_same(a, b, where=f"{path.name} [{name}]")


def test_a_split_compiled_run_equals_one_run() -> None:
    """reset=False continues the plan from the blocks' state (their arrays are views of the
    plan's buffers), and parameter events between chunks take effect at their scan."""
    def make() -> Module:
        return Module({"pid": loopworks.create_block("pid", k=2.0, ti=5.0),
                       "process": loopworks.create_block("process.fopdt", dead_time=1.0)},
                      wires={"process.u": "pid.out", "pid.pv": "process.y"},
                      inputs={"pid": {"sp": 1.0}},
                      events=[Event(3.3, "pid.k", 1.0), Event(7.0, "pid.sp", 2.0)])
    whole = make().run(20.0, 0.1, plan="compiled")
    split = make()
    first = split.run(5.0, 0.1, plan="compiled")
    second = split.run(15.0, 0.1, plan="compiled", reset=False)
    reference = make().run(20.0, 0.1, plan="python")
    assert_same(whole, reference, where="whole")
    for name in whole.values:
        joined = np.concatenate([first.values[name], second.values[name]])
        np.testing.assert_array_equal(joined, whole.values[name], err_msg=name)


def test_plan_choice_is_checked() -> None:
    m = Module({"p": loopworks.create_block("pid", jit=False)})
    with pytest.raises(InputError, match="plan = 'fast' is not allowed"):
        m.run(1.0, 0.1, plan="fast")
    with pytest.raises(InputError, match="needs every block compiled"):
        m.run(1.0, 0.1, plan="compiled")


def test_a_block_object_is_in_a_module_once() -> None:
    b = loopworks.create_block("pid")
    with pytest.raises(InputError, match="a block object can be in a module once"):
        Module({"a": b, "b": b})


def test_the_block_reads_the_plans_buffers() -> None:
    """After a compiled run the block's own view (state(), outputs()) is the plan's."""
    pid = loopworks.create_block("pid", k=1.0, ti=1.0)
    m = Module({"pid": pid}, inputs={"pid": {"sp": 1.0, "pv": 0.0}})
    r = m.run(1.0, 0.1, plan="compiled")
    assert pid.outputs()["out"].value == r.values["pid.out"][-1]
    assert pid.state()["i"] == pytest.approx(1.0)  # ki·dt·e = 0.1 per scan, ten scans


def test_cache_directory_follows_the_environment(monkeypatch: pytest.MonkeyPatch,
                                                 tmp_path: Path) -> None:
    monkeypatch.setenv("LOOPWORKS_CACHE_DIR", str(tmp_path / "here"))
    assert plan.cache_dir() == tmp_path / "here"
    monkeypatch.delenv("LOOPWORKS_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    if sys.platform.startswith("linux"):
        assert plan.cache_dir() == tmp_path / "xdg" / "loopworks"


RUN = """
import loopworks
from loopworks.sim.module import Module
m = Module({"pid": loopworks.create_block("pid", k=1.5, ti=4.0),
            "p": loopworks.create_block("process.first_order", time_constant=3.0)},
           wires={"p.u": "pid.out", "pid.pv": "p.y"}, inputs={"pid": {"sp": 1.0}})
print(repr(float(m.run(30.0, 0.1, plan="compiled").values["p.y"][-1])))
"""


def run_fresh(env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", RUN], capture_output=True, text=True,
                          env={**os.environ, **env}, timeout=600, check=True)


def test_a_second_process_loads_the_plan(tmp_path: Path) -> None:
    """The first process writes the plan's source and machine code to the cache directory;
    a second one loads them (numba's cache index is there) and gets the same numbers."""
    env = {"LOOPWORKS_CACHE_DIR": str(tmp_path)}
    first = run_fresh(env)
    made = sorted(p.name for p in (tmp_path / "plans" / "__pycache__").iterdir())
    assert any(".scans-" in n and n.endswith(".nbi") for n in made), made
    second = run_fresh(env)
    assert second.stdout == first.stdout
    assert sorted(p.name for p in (tmp_path / "plans" / "__pycache__").iterdir()) == made


def test_an_unwritable_cache_compiles_in_memory_with_one_warning(tmp_path: Path) -> None:
    """A cache directory that cannot be made (here: under a plain file, which even root
    cannot write into) gives one warning line, and the run still gives the same numbers."""
    blocker = tmp_path / "a-file"
    blocker.write_text("not a directory")
    run = run_fresh({"LOOPWORKS_CACHE_DIR": str(blocker / "cache")})
    assert run.stderr.count("cannot be written") == 1, run.stderr
    assert float(run.stdout) == float(run_fresh({"LOOPWORKS_CACHE_DIR": str(tmp_path / "ok")})
                                      .stdout)


def doubling_kernel(dt: float, p: Any, x: Any, u: Any, us: Any, y: Any, ys: Any) -> None:
    """A tiny kernel for the cache tests: y = 2·u, x counts the scans."""
    x[0] += 1.0
    y[0] = 2.0 * u[0]
    ys[0] = 128


def test_the_first_compilation_is_announced_once(monkeypatch: pytest.MonkeyPatch,
                                                 tmp_path: Path) -> None:
    """Issue 12 point 5: a plan that must be compiled (not in the cache) says so on one line,
    once per process, before compiling; what is cached is loaded silently."""
    heard: list[str] = []
    monkeypatch.setenv("LOOPWORKS_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(plan, "announce", heard.append)
    monkeypatch.setattr(plan, "_announced", False)
    for n_u in (1, 2):  # two shapes: two compilations, one line
        slots = plan.layout([(doubling_kernel, 0, 1, n_u, 1, True)])
        step = plan.entry(slots, "step", plan.STEP_SIGNATURE)
        F, S = np.zeros(1 + n_u + 1), np.full(n_u + 1, 128, dtype=np.int64)
        F[1] = 3.0
        step(0.1, F, S)
        assert (F[0], F[-1]) == (1.0, 6.0)
        assert plan.is_cached(slots, "step")
    assert len(heard) == 1 and "once for this machine" in heard[0], heard
    assert str(tmp_path) in heard[0]
