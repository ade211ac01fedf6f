"""The execution plan (issue 12): the compiled plan and the interpreted run give the same
numbers, on random modules of every kind and on every example scenario; the plan's cache is
keyed so that a second process loads instead of compiling, and a cache that cannot be written
falls back to compiling in memory with one warning."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pytest

import loopworks
from loopworks.blocks import plan
from loopworks.blocks.block import Block
from loopworks.blocks.kernel import run_rows
from loopworks.blocks.params import Port
from loopworks.errors import InputError
from loopworks.sim.module import Event, Module
from loopworks.sim.result import SimResult
from loopworks.sim.scenario import load_scenario
from tests.blocks.test_block_model import VARIANTS, random_inputs, scan_time
from tests.plant.test_process_models import VARIANT_SETS as PROCESS_VARIANTS
from tests.vendors.test_siemens_s5 import VARIANTS as S5_VARIANTS

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


#: the parameter sets the vendor and plant tests pin, beside the branch-covering VARIANTS
EXTRA: dict[str, list[dict[str, Any]]] = {
    "s5.pid": S5_VARIANTS,
    **PROCESS_VARIANTS,
    "deltav.stick_slip": [{"resolution": 0.5, "deadband": 0.2, "precision": "float64",
                           "deferred_param_reads": True, "dither_half_period": 2}],
    "deltav.sggn": [{"waveform": w, "period": 2.5} for w in ("square", "sine", "triangle")],
    "deltav.calc": [{"precision": "float64", "deferred_param_reads": True},
                    {"expression": "'^/Y' := '^/A' / '^/B' - NOT '^/A'; '^/Y.ST' := '^/A';",
                     "a": 0.0, "b": 0.0, "divide_by_zero": "ieee"}],
    "deltav.pid": [{"gain": 2.0, "reset": 3.0, "rate": 1.5,
                    "structure": "two_degrees_of_freedom", "beta": 0.6, "gamma": 0.4,
                    "pv_ftime": 1.0, "arw_hi_lim": 80.0}],
    "e2.pid": [{"kd": 1.0, "d_form": "as_printed", "filter_period": 3.0,
                "old_output": "filtered", "i_tr_normalise": True}],
    "sensor.transmitter": [{"noise_std": 1.3, "time_constant": 0.7, "seed": 11},
                           {"noise_std": 0.3, "time_constant": 2.0, "quantum": 0.05,
                            "seed": 9}],
    "disturbance.load": [{"walk_std": 0.5, "sine_amplitude": 1.0, "ramp_rate": 0.1,
                          "seed": 12}],
}


def rows_of(block: Any, inputs: list[dict[str, Any]]) -> tuple[Any, Any, Any, Any]:
    """Inputs as replay rows (value and status arrays), and output arrays whose row 0 holds
    the outputs before the first scan."""
    n, n_u = len(inputs), len(block.INPUTS)
    U, US = np.zeros((n, n_u)), np.full((n, n_u), 128, dtype=np.int64)
    last = {port.name: (port.default, 128) for port in block.INPUTS}
    for k, row in enumerate(inputs):
        for name, value in row.items():
            last[name] = value if isinstance(value, tuple) else (value, 128)
        for i, port in enumerate(block.INPUTS):
            U[k, i], US[k, i] = last[port.name]
    Y = np.zeros((n, len(block.OUTPUTS)))
    YS = np.zeros((n, len(block.OUTPUTS)), dtype=np.int64)
    Y[0], YS[0] = block.y, block.ys
    return U, US, Y, YS


def usable_dt(block: Any, params: dict[str, Any], rng: np.random.Generator) -> float:
    """A random scan time the block accepts (a short delay line takes only long scans)."""
    for dt in [scan_time(params, rng, 0.05, 1.0) for _ in range(20)] + [1.0, 2.0, 5.0, 20.0]:
        try:
            block.check_dt(dt)
        except InputError:
            continue
        return dt
    raise AssertionError(f"{block.kind} {params}: no usable scan time")


@pytest.mark.parametrize("kind", sorted(VARIANTS))
def test_compiled_plan_equals_the_interpreted_run(kind: str) -> None:
    """Issue 12: the one equivalence test per kind, for the three ways a kernel runs, each
    compiled against the interpreted reference, for every parameter variant (the
    branch-covering ones and those the vendor and plant tests pin):

    * a module of the block alone, its inputs changed by events at random scans (the plan
      runs in chunks between them): values to 1e-12, statuses equal;
    * ``Block.step`` with random inputs (NaN, inf, statuses) and random scan times;
    * replay rows (``run_rows``) of the same inputs at one scan time."""
    rng = np.random.default_rng(20261202)
    for params in VARIANTS[kind] + EXTRA.get(kind, []):
        where = f"{kind} {params}"
        probe = loopworks.create_block(kind, jit=False, **params)
        dt = usable_dt(probe, params, rng)
        events = random_events(kind, params, dt, rng)
        runs = [Module({"b": loopworks.create_block(kind, jit=jit, **params)}, events=events)
                .run(SCANS * dt, dt, plan=how)
                for jit, how in ((False, "python"), (True, "compiled"))]
        assert_same(*runs, where=where)

        fast, slow = (loopworks.create_block(kind, jit=jit, **params) for jit in (True, False))
        steps = []
        for _ in range(SCANS):
            step_dt = usable_dt(probe, params, rng)
            inputs = random_inputs(fast, rng)
            steps.append(inputs)
            a, b = fast.step(step_dt, **inputs), slow.step(step_dt, **inputs)
            for name in a:
                assert a[name].status == b[name].status, f"{where}: step {name}"
                assert a[name].value == pytest.approx(b[name].value, rel=1e-12, abs=1e-12,
                                                      nan_ok=True), f"{where}: step {name}"
            np.testing.assert_allclose(fast.x, slow.x, rtol=1e-12, atol=1e-12,
                                       err_msg=f"{where}: step state")

        block = loopworks.create_block(kind, jit=False, **params)
        got = []
        for jit in (True, False):
            U, US, Y, YS = rows_of(block, steps)
            x = block.x.copy()
            run_rows(type(block).kernel, np.full(SCANS, dt), block.p.copy(), x, U, US, Y, YS,
                     jit=jit, full=not block.SOUND_KERNEL)
            got.append((Y, YS, x))
        np.testing.assert_allclose(got[0][0], got[1][0], rtol=1e-12, atol=1e-12,
                                   equal_nan=True, err_msg=f"{where}: rows")
        np.testing.assert_array_equal(got[0][1], got[1][1], err_msg=f"{where}: row statuses")
        np.testing.assert_allclose(got[0][2], got[1][2], rtol=1e-12, atol=1e-12,
                                   err_msg=f"{where}: rows state")


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


def pid_fopdt(*events: Event) -> Module:
    """A pid on a fopdt of 1 s dead time, SP 1, with ``events``."""
    return Module({"pid": loopworks.create_block("pid", k=2.0, ti=5.0),
                   "process": loopworks.create_block("process.fopdt", dead_time=1.0)},
                  wires={"process.u": "pid.out", "pid.pv": "process.y"},
                  inputs={"pid": {"sp": 1.0}}, events=list(events))


def retuned_loop() -> Module:
    """pid_fopdt with a gain change at 3.3 s and an SP step at 7 s."""
    return pid_fopdt(Event(3.3, "pid.k", 1.0), Event(7.0, "pid.sp", 2.0))


def test_a_scan_from_python_is_one_call_of_the_plan(monkeypatch: pytest.MonkeyPatch) -> None:
    """``Module.scan`` of a compiled module runs its plan's scans entry once (no block binds
    an entry of its own), with events and a block's input written between scans, and gives
    the interpreted module's numbers scan by scan."""
    compiled = retuned_loop()
    monkeypatch.setenv("LOOPWORKS_JIT", "0")
    interpreted = retuned_loop()
    assert compiled.compiled and not interpreted.compiled
    for k in range(120):
        if k == 50:  # an operator's output bias, between scans
            for m in (compiled, interpreted):
                m.blocks["pid"].set_inputs({"ff": 0.25})
        for m in (compiled, interpreted):
            m.scan(0.1)
        for name in compiled.order:
            a, b = compiled.blocks[name], interpreted.blocks[name]
            np.testing.assert_array_equal(a.y, b.y, err_msg=f"{name} at scan {k}")
            np.testing.assert_array_equal(a.ys, b.ys, err_msg=f"{name} at scan {k}")
            np.testing.assert_array_equal(a.x, b.x, err_msg=f"{name} at scan {k}")
    assert compiled.t == interpreted.t and compiled.k == interpreted.k == 120
    assert compiled._scans is not None and compiled._scans[0] == "scans"
    assert all(b._run == b._run_first for b in compiled.blocks.values())


def test_a_split_compiled_run_equals_one_run() -> None:
    """reset=False continues the plan from the blocks' state (their arrays are views of the
    plan's buffers), and parameter events between chunks take effect at their scan."""
    whole = retuned_loop().run(20.0, 0.1, plan="compiled")
    split = retuned_loop()
    first = split.run(5.0, 0.1, plan="compiled")
    second = split.run(15.0, 0.1, plan="compiled", reset=False)
    reference = retuned_loop().run(20.0, 0.1, plan="python")
    assert_same(whole, reference, where="whole")
    for name in whole.values:
        joined = np.concatenate([first.values[name], second.values[name]])
        np.testing.assert_array_equal(joined, whole.values[name], err_msg=name)


def test_the_fused_plan_equals_the_interpreted_run() -> None:
    """The ``fused`` plan (every kernel inlined, ``plan="fused"``): the same numbers as the
    Python loop, on pid + fopdt with events split over two runs (the second takes the fused
    plan by itself, since it is cached now). The fused plan is the ``scans`` plan's source
    with each kind's guarded kernel inlined (``guarded_scan``) instead of called through the
    kind's ``call`` entry, which inlines the same guarded kernel: every kind's arithmetic
    compiled is checked through ``scans`` (``test_compiled_plan_equals_the_interpreted_run``,
    every example). The default example's variants were checked fused here too until
    2026-12-07: 63 s of compiling on a fresh machine (110 s in a fresh CI's suite) for a plan
    no run takes by itself below 1e9 block-scans."""
    split = retuned_loop()
    first = split.run(5.0, 0.1, plan="fused")
    assert split._scans[0] == "fused"
    second = split.run(15.0, 0.1, plan="compiled", reset=False)
    assert split._scans[0] == "fused"
    reference = retuned_loop().run(20.0, 0.1, plan="python")
    for name in reference.values:
        np.testing.assert_array_equal(np.concatenate([first.values[name], second.values[name]]),
                                      reference.values[name], err_msg=name)
        np.testing.assert_array_equal(np.concatenate([first.status[name], second.status[name]]),
                                      reference.status[name], err_msg=name)



def adapting_kernel(dt: float, p: Any, x: Any, u: Any, us: Any, y: Any, ys: Any) -> None:
    """y = p[0]·u, then p[0] doubles (a kernel that writes its coefficients: no vendor's,
    but a kind may)."""
    y[0] = p[0] * u[0]
    ys[0] = 128
    p[0] = 2.0 * p[0]


class Adapting(Block):
    kind = "test.adapting"
    kernel = staticmethod(adapting_kernel)
    INPUTS: ClassVar[tuple[Port, ...]] = (Port("u", 1.0, status=True),)
    OUTPUTS: ClassVar[tuple[Port, ...]] = (Port("y", 0.0, status=True),)
    COEFFS: ClassVar[tuple[str, ...]] = ("gain",)

    def coefficients(self) -> dict[str, float]:
        return {"gain": 1.0}


def test_a_fused_plan_reads_coefficients_as_a_tuple_and_falls_back_for_a_kernel_that_writes_them(
        ) -> None:
    """A fused plan hands each kernel its coefficients as a tuple read before the scan loop
    (``plan._coefficients``: a quarter less time per scan of pid + fopdt, 2026-12-08); a
    kernel that writes them does not compile so, and the plan is compiled with slices of the
    buffer instead: the same numbers as the compiled plan (y doubles every scan)."""
    m = retuned_loop()
    text = plan.source(m._slots, ["fused", "batch_fused"])[0]
    for i in range(len(m._slots)):
        assert text.count(f"P{i} = (F[") == 2 and f"(dt, P{i}, F[" in text
    assert "P0 = (F[" not in plan.source(m._slots, ["scans", "batch"])[0]
    got = Module({"a": Adapting()}).run(0.5, 0.1, plan="fused")
    assert got.values["a.y"].tolist() == [1.0, 2.0, 4.0, 8.0, 16.0]
    reference = Module({"a": Adapting()}).run(0.5, 0.1, plan="compiled")
    np.testing.assert_array_equal(got.values["a.y"], reference.values["a.y"])


def test_a_long_run_takes_the_fused_plan_only_when_it_pays_for_its_compilation(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Fusing saves tens of ns per block-scan; compiling it cost 63 s for the built-in
    scenario's module. A run of 1e6 block-scans (a 20-hour simulate of it) compiled it, to
    save 0.06 s: it now takes the scans plan unless the fused one is cached, asked for, or the
    run is PLAN_FUSE_BLOCK_SCANS long. Not cached here: nothing is compiled or loaded."""
    from loopworks.sim import module as module_mod

    monkeypatch.setattr(module_mod, "is_cached", lambda *args: False)
    taken: list[str] = []
    monkeypatch.setattr(module_mod, "entry", lambda slots, what, *args: taken.append(what) or (
        lambda *a: None))
    m = retuned_loop()
    assert module_mod.PLAN_FUSE_BLOCK_SCANS >= 10**9
    m.run(500_000 * 0.1, 0.1, plan="compiled", record=["pid.out"])  # 1e6 block-scans
    m.run(1.0, 0.1, plan="fused")
    monkeypatch.setattr(module_mod, "PLAN_FUSE_BLOCK_SCANS", 20)
    retuned_loop().run(1.0, 0.1, plan="compiled")  # 10 scans of 2 blocks: "long" here
    assert taken == ["scans", "fused", "fused"]
    with pytest.raises(InputError, match="expected auto, compiled, fused or python"):
        m.run(1.0, 0.1, plan="fast")
    monkeypatch.setenv("LOOPWORKS_JIT", "0")
    with pytest.raises(InputError, match="plan = 'fused' needs every block compiled"):
        retuned_loop().run(1.0, 0.1, plan="fused")


@pytest.mark.parametrize("what", ["scans", "fused"])
def test_the_usual_record_and_any_other_give_the_blocks_numbers(
        what: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """A module's plan writes its usual record (every signal) at literal offsets and any
    other record through the index arrays: both hold what the interpreted run holds."""
    from loopworks.sim import module as module_mod

    monkeypatch.setattr(module_mod, "PLAN_FUSE_BLOCK_SCANS", 0 if what == "fused" else 10**12)
    if what == "scans":  # not the fused plan, even when it is cached
        monkeypatch.setattr(module_mod, "is_cached", lambda *args: False)
    compiled = retuned_loop()
    text = plan.source(compiled._slots, [what], compiled._usual_record())[0]
    assert "        if usual:" in text and "RF[0, at + k] = F[" in text
    monkeypatch.setenv("LOOPWORKS_JIT", "0")
    reference = retuned_loop().run(20.0, 0.1, plan="python")
    every = compiled.run(20.0, 0.1, plan="compiled")
    assert compiled._scans[0] == what
    some = ["pid.out", "process.y", "pid.i_term"]
    part = compiled.run(20.0, 0.1, plan="compiled", record=some)
    assert set(part.values) == set(some)
    for result in (every, part):
        for name in result.values:
            np.testing.assert_array_equal(result.values[name], reference.values[name],
                                          err_msg=name)
            np.testing.assert_array_equal(result.status[name], reference.status[name],
                                          err_msg=name)


def test_the_record_holds_status_bytes() -> None:
    """A status is one byte (spec architecture: the Foundation Fieldbus status byte): the
    record keeps it as uint8, compiled and interpreted alike."""
    m = pid_fopdt(Event(1.0, "pid.sp", float("nan")))
    for how in ("compiled", "python"):
        r = m.run(3.0, 0.1, plan=how)
        assert all(s.dtype == np.uint8 for s in r.status.values())
        out = r.status["pid.out"]
        assert out[0] == 0x80 and out[-1] < 0x80  # Good, then not Good from the NaN SP on
        assert out[-1] == m._S[m._rec_s[list(m.signals()).index("pid.out")]]


def scanned(m: Module, n: int, dt: float) -> tuple[np.ndarray, dict[str, np.ndarray],
                                                   dict[str, np.ndarray]]:
    """The record written out by hand: reset, then per scan ``Module.scan`` and every
    block's inputs and outputs read from the block (no record plan involved)."""
    m.reset()
    t = np.empty(n)
    values = {name: np.empty(n) for name in m.signals()}
    status = {name: np.empty(n, dtype=np.int64) for name in m.signals()}
    for k in range(n):
        t[k] = m.t
        m.scan(dt)
        for name in m.order:
            b = m.blocks[name]
            for arr, sarr, ports in ((b.u, b.us, b.INPUTS), (b.y, b.ys, b.OUTPUTS)):
                for i, port in enumerate(ports):
                    values[f"{name}.{port.name}"][k] = arr[i]
                    status[f"{name}.{port.name}"][k] = sarr[i]
    return t, values, status


def feedback_first() -> Module:
    """pid_fopdt run process first: the pid reads this scan's PV, the process last scan's
    output."""
    return Module({"pid": loopworks.create_block("pid", k=2.0, ti=5.0),
                   "process": loopworks.create_block("process.fopdt", dead_time=1.0)},
                  wires={"process.u": "pid.out", "pid.pv": "process.y"},
                  inputs={"pid": {"sp": 1.0}}, order=["process", "pid"],
                  events=[Event(2.0, "pid.sp", 2.0), Event(3.3, "pid.k", 1.0)])


@pytest.mark.parametrize("how", ["compiled", "python"])
def test_the_record_is_what_the_blocks_held(how: str) -> None:
    """A run writes each signal once (record_plan): a constant input is not written, an
    input wired to an output shares that output's record (shifted by a scan when its source
    runs after it). Every signal still reads what its block held after each scan, as a scan
    loop records it by hand; the record is read-only. Both orders of a feedback loop, events
    on a constant input and on a parameter, and every variant of the default example."""
    path = Path(__file__).parents[2] / "examples" / "default.toml"
    variants = list(load_scenario(path).variants)
    # each run on a new module: a parameter event stays applied after a run
    makers = [("pid first", retuned_loop), ("process first", feedback_first),
              *((v, lambda v=v: load_scenario(path).variants[v]) for v in variants)]
    for where, make in makers:
        dt = 0.1 if where.endswith("first") else 0.5
        n = 120
        r = make().run(n * dt, dt, plan=how)
        t, values, status = scanned(make(), n, dt)
        np.testing.assert_array_equal(r.t, t)
        assert r.values.keys() == values.keys()
        for name in values:
            np.testing.assert_array_equal(r.values[name], values[name], err_msg=f"{where}: {name}")
            np.testing.assert_array_equal(r.status[name], status[name],
                                          err_msg=f"{where}: {name} status")
            assert not r.values[name].flags.writeable and not r.status[name].flags.writeable
    m = retuned_loop()
    rows, kinds = m.record_plan(range(len(m.signals())))
    # written: the five outputs; pid.sp has an event; every other input is wired or constant
    assert sorted(m.signals()[i] for i in rows) == sorted(
        ["pid.out", "pid.p_term", "pid.i_term", "pid.d_term", "process.y", "pid.sp"])
    assert kinds[m.signals().index("process.u")] == ("row", rows.index(
        m.signals().index("pid.out")))
    assert kinds[m.signals().index("pid.pv")][0] == "before"
    assert kinds[m.signals().index("pid.ff")] == ("const", -1)


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


RACE = """
import sys, time
from pathlib import Path
from loopworks.blocks import plan
from loopworks.blocks.block import Block
from tests.sim.test_plan import doubling_kernel
slots = plan.layout([(doubling_kernel, 0, 1, 3, 1, True)])
Path(sys.argv[1]).touch()
while not Path(sys.argv[2]).exists():
    time.sleep(0.005)
disp = plan.entry(slots, "step", plan.step_signature(1))
print(sum(disp.stats.cache_misses.values()), sum(disp.stats.cache_hits.values()))
"""


def test_two_processes_needing_one_plan_compile_it_once(tmp_path: Path) -> None:
    """Two processes released at the same instant on an empty cache need the same plan: one
    compiles it (a cache miss) while the other waits on its lock file and loads the machine
    code it wrote (a cache hit), instead of both compiling it."""
    env = {**os.environ, "LOOPWORKS_CACHE_DIR": str(tmp_path / "cache"),
           "PYTHONPATH": str(Path(__file__).resolve().parents[2])}
    go = tmp_path / "go"
    procs = [subprocess.Popen([sys.executable, "-c", RACE, str(tmp_path / f"ready{i}"), str(go)],
                              env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True) for i in range(2)]
    deadline = time.monotonic() + 300
    while not all((tmp_path / f"ready{i}").exists() for i in range(2)):
        assert time.monotonic() < deadline and all(p.poll() is None for p in procs), (
            [p.communicate() for p in procs])
        time.sleep(0.01)
    go.touch()
    outs = [p.communicate(timeout=600) for p in procs]
    assert all(p.returncode == 0 for p in procs), outs
    counts = sorted(tuple(int(v) for v in out.split()) for out, _ in outs)
    assert counts == [(0, 1), (1, 0)], outs  # (misses, hits): one compiled, one loaded


def test_an_unwritable_cache_compiles_in_memory_with_one_warning(tmp_path: Path) -> None:
    """A cache directory that cannot be made (here: under a plain file, which even root
    cannot write into) gives one warning line, and the run still gives the same numbers
    (as the same plan run here, from this process's cache)."""
    blocker = tmp_path / "a-file"
    blocker.write_text("not a directory")
    run = run_fresh({"LOOPWORKS_CACHE_DIR": str(blocker / "cache")})
    assert run.stderr.count("cannot be written") == 1, run.stderr
    here: dict[str, Any] = {}
    exec(RUN.replace("print(", "result = ("), here)
    assert float(run.stdout) == float(here["result"])


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
        step = plan.entry(slots, "step", plan.step_signature(1))
        F, S = np.zeros(1 + n_u + 1), np.full(n_u + 1, 128, dtype=np.int64)
        assert step(0.1, F.ctypes.data, S.ctypes.data, 0, 3.0, -1, 0.0, True) == (6.0, 128)
        assert (F[0], F[1], F[-1]) == (1.0, 3.0, 6.0)
        assert plan.is_cached(slots, "step")
    assert len(heard) == 1 and "once for this machine" in heard[0], heard
    assert str(tmp_path) in heard[0]


THREE_PATHS = """
import numpy as np
import loopworks
from loopworks.blocks.kernel import run_rows
from loopworks.sim.module import Module

block = loopworks.create_block("valve.backlash", b=1.0)
block.step(0.5, op=10.0)
n_y = len(block.OUTPUTS)
run_rows(type(block).kernel, np.array([0.5, 0.5]), block.p.copy(), block.x.copy(),
         np.array([[1.0], [20.0]]), np.full((2, 1), 128, dtype=np.int64), np.zeros((2, n_y)),
         np.full((2, n_y), 128, dtype=np.int64), jit=True, full=not block.SOUND_KERNEL)
module = Module({"v": loopworks.create_block("valve.backlash", b=1.0)},
                inputs={"v": {"op": 5.0}})
module.run(1.0, 0.5, plan="compiled")
"""


def test_each_kernel_is_compiled_into_one_entry_only(tmp_path: Path) -> None:
    """A block's step, a replay's rows and a module's scans all call the kind's one cached
    ``call`` entry: the kernel's arithmetic is compiled once per machine, whichever runs
    first ("never compile the same thing twice"). Run in a fresh process, so nothing is
    loaded already."""
    subprocess.run([sys.executable, "-c", THREE_PATHS], capture_output=True, text=True,
                   env={**os.environ, "LOOPWORKS_CACHE_DIR": str(tmp_path)}, timeout=600,
                   check=True)
    texts = [p.read_text() for p in (tmp_path / "plans").glob("lw_plan_*.py")]
    inlined = [t for t in texts if "= guarded_scan(" in t]
    assert len(texts) == 4 and len(inlined) == 1, texts  # call, and step, rows, scans
    assert "def call(" in inlined[0]
    assert sum("= kernel_call(" in t for t in texts) == 3


def test_the_plan_name_follows_the_kernels_code_not_its_module(tmp_path: Path) -> None:
    """A plan's name hashes what its machine code depends on: the kernel's code and the
    constants and primitives it uses, not the rest of its module (a docstring elsewhere, a
    parameter's meaning), so an edit there costs no compilation, and an edit that changes the
    arithmetic always gives a new name."""
    text = "def k(dt, p, x, u, us, y, ys):\n    y[0] = GAIN * u[0]\n"

    def kernel(source: str, gain: float) -> Any:
        namespace: dict[str, Any] = {"GAIN": gain, "__name__": "tests.fake_kernels"}
        exec(compile(source, "<fake>", "exec"), namespace)
        return namespace["k"]

    base = plan._kernels_hash((kernel(text, 2.0),))
    assert plan._kernels_hash((kernel("\n\n# moved down\n" + text, 2.0),)) == base
    assert plan._kernels_hash((kernel(text, 3.0),)) != base  # a constant numba freezes
    assert plan._kernels_hash((kernel(text.replace("*", "+"), 2.0),)) != base
    # a helper the kernel calls, compiled apart (a primitive) or left a plain function: a
    # decorator moved off it kept the name, and a warm cache served machine code that a fresh
    # machine could not build (deltav.pid's reset_gain, 2026-12-06)
    import numba

    def helper(v: float) -> float:
        return 2.0 * v

    calls = "def k(dt, p, x, u, us, y, ys):\n    y[0] = HELPER(u[0])\n"

    def calling(fn: Any) -> Any:
        namespace: dict[str, Any] = {"HELPER": fn, "__name__": "tests.fake_kernels"}
        exec(compile(calls, "<fake>", "exec"), namespace)
        return namespace["k"]

    assert plan._kernels_hash((calling(helper),)) != plan._kernels_hash(
        (calling(numba.njit(helper)),))


def test_is_cached_finds_machine_code_under_numba_cache_dir(monkeypatch: pytest.MonkeyPatch,
                                                            tmp_path: Path) -> None:
    """With ``NUMBA_CACHE_DIR`` set numba writes a plan's machine code there, not next to its
    source: ``is_cached`` must look where numba does, or every cached plan looks uncached (a
    wrong "compiling ..." line, and ``Module.run`` choosing between plans by the wrong rule)."""
    import numba

    monkeypatch.setenv("LOOPWORKS_CACHE_DIR", str(tmp_path / "lw"))
    monkeypatch.setattr(numba.config, "CACHE_DIR", str(tmp_path / "numba"))
    monkeypatch.setattr(plan, "_loaded", {})  # this test's plans stay its own
    slots = plan.layout([(doubling_kernel, 0, 1, 3, 1, True)])
    assert not plan.is_cached(slots, "step")
    plan.entry(slots, "step", plan.step_signature(1))
    name = plan._name(slots, "step")[0]
    plan._loaded.pop(name)  # as a fresh process sees it: only what is on disk
    assert plan.is_cached(slots, "step")
    on_disk = [p.name for p in (tmp_path / "numba").rglob(f"{name}.step-*.nbi")]
    assert on_disk, "numba wrote no index under NUMBA_CACHE_DIR"
    assert not (tmp_path / "lw" / "plans" / "__pycache__").exists() or not any(
        (tmp_path / "lw" / "plans" / "__pycache__").glob(f"{name}.step-*.nbi"))


STALE = """
import sys
import numpy as np
from loopworks.blocks import plan
from loopworks.blocks.block import Block
from tests.sim.test_plan import doubling_kernel
if sys.argv[1] == "old":  # the kind entries under the names of a source since edited
    made = plan._name
    plan._name = lambda slots, what, usual=None, tuples=True: (
        (lambda n, t, i: (n + "old" if what == "call" else n, t, i))(
            *made(slots, what, usual, tuples)))
slots = plan.layout([(doubling_kernel, 0, 1, 3, 1, True), (doubling_kernel, 0, 1, 3, 1, True)])
scans = plan.entry(slots, "scans", plan.SCANS_SIGNATURE)
F, S = np.zeros(slots[-1].f1), np.zeros(slots[-1].s1, dtype=np.int64)
F[slots[0].u0] = 1.5
T, RF, RS = np.zeros(3), np.zeros((1, 3)), np.zeros((1, 3), dtype=np.uint8)
scans(F, S, 0.1, 0.0, 0, 3, T, RF, RS, np.array([slots[0].y0]), np.array([slots[0].ys0]), 0)
print(RF[0].tolist(), F[slots[1].x0])
"""


def test_machine_code_naming_a_plan_module_no_process_makes_is_compiled_again(
        tmp_path: Path) -> None:
    """A module plan is cached under a name from the sources as one process read them, and
    its machine code names the kind entries it links to. A file edited while a long run
    went on gave its later plans new names and its kind entries the old ones (the files were
    read again for each name); every later process then failed to load that plan
    (ModuleNotFoundError: No module named 'lw_plan_...'), whatever it ran, until the cache was
    deleted (found in this project's own benchmark run). The stale machine code is compiled
    again instead (and a process reads each source once)."""
    env = {**os.environ, "LOOPWORKS_CACHE_DIR": str(tmp_path / "cache"),
           "PYTHONPATH": str(Path(__file__).resolve().parents[2])}

    def run(which: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run([sys.executable, "-c", STALE, which], capture_output=True,
                              text=True, env=env, timeout=600)

    old = run("old")
    assert old.returncode == 0, old.stderr
    assert old.stdout.split()[:3] == ["[3.0,", "3.0,", "3.0]"]
    for _ in range(2):  # compiled again, then loaded
        new = run("new")
        assert new.returncode == 0, new.stderr[-2000:]
        assert new.stdout == old.stdout
