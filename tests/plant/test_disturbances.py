"""``disturbance.load``: y = u + d with step, ramp, seeded random walk and sinusoid.

Golden values are hand arithmetic written in the tests. Statistical checks of the random walk
use fixed seeds and tolerances of five standard errors for the sample size. Load disturbances
are the scenario events of plant-and-tuning 2.8 and 3.4 item 6; the generator is the one of
``sensor.transmitter`` (tested in test_sensors.py).
"""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

import loopworks
from loopworks import Module, create_block
from loopworks.blocks.block import Block
from loopworks.cli import app
from loopworks.errors import ParameterError
from loopworks.plant.sensor import STREAM_DISTURBANCE, rng_normal, rng_seed_state
from tests.csvfiles import write_csv
from tests.plant.numeric import EXTREMES, kernel_scan, unsound

GOOD = 0x80
OOS = 0x1C
KIND = "disturbance.load"

Make = Callable[..., Block]


@pytest.fixture(params=[True, False], ids=["compiled", "interpreted"])
def make(request: pytest.FixtureRequest) -> Make:
    jit = request.param

    def _make(**params: Any) -> Block:
        return create_block(KIND, jit=jit, **params)

    return _make


def d_series(block: Block, n: int, dt: float = 1.0, u: float = 0.0) -> list[float]:
    return [block.step(dt, u=u)["d"].value for _ in range(n)]


def test_defaults_pass_u_and_its_status_through(make: Make) -> None:
    load = make()
    r = load.step(1.0, u=(42.0, OOS))
    assert r["y"] == (42.0, OOS)        # the status of u, unchanged
    assert r["d"] == (0.0, GOOD)


def test_non_finite_u_passes_on_as_bad(make: Make) -> None:
    """Issue 11 point 1: the pass-through stays (seed 000 line 28), but a non-finite u is Bad
    input first: NaN or inf with a Good status gives y with status Bad non-specific (it used
    to keep Good); a Bad status that arrives is kept with its substatus. A sum that overflows
    is Bad too. d stays Good."""
    load = make(bias=1.0)
    for value in (math.nan, math.inf, -math.inf):
        r = load.step(1.0, u=value)
        assert not math.isfinite(r["y"].value) and r["y"].status == 0x00
        assert r["d"] == (1.0, GOOD)
    assert load.step(1.0, u=(math.nan, OOS))["y"].status == OOS
    big = make(bias=1e308)
    r = big.step(1.0, u=1e308)
    assert r["y"].value == math.inf and r["y"].status == 0x00 and r["d"] == (1e308, GOOD)
    assert big.step(1.0, u=-1e308)["y"] == (0.0, GOOD)
    bare = create_block(KIND, jit=False, bias=1e308)  # the kernel itself, without the guard
    kernel_scan(bare, 1.0, u=1e308)
    assert unsound(bare) == [] and bare.ys[0] == 0x00


def test_unwired_u_makes_y_the_disturbance(make: Make) -> None:
    load = make(bias=2.5)
    assert load.step(1.0)["y"].value == 2.5


def test_step_at_its_time(make: Make) -> None:
    load = make(step_size=-4.0, step_time=3.0)
    assert d_series(load, 6) == [0.0, 0.0, 0.0, -4.0, -4.0, -4.0]   # t = 0..5 s


def test_step_time_tolerates_summed_scan_times(make: Make) -> None:
    """200 scans of 0.1 s sum to 19.999999999999996: the step at 20 s lands on scan 200."""
    load = make(step_size=1.0, step_time=20.0)
    d = d_series(load, 202, dt=0.1)
    assert d[199] == 0.0 and d[200] == 1.0


def test_ramp_starts_stops_and_holds(make: Make) -> None:
    # d = rate·(min(t, end) - start) for t ≥ start: 0.5·(t - 2) from 2 s to 5 s, then 1.5
    load = make(ramp_rate=0.5, ramp_start=2.0, ramp_end=5.0)
    assert d_series(load, 8) == [0.0, 0.0, 0.0, 0.5, 1.0, 1.5, 1.5, 1.5]


def test_sinusoid_with_phase_and_start(make: Make) -> None:
    # d = A·sin(2π(t - t0)/P + φ) for t ≥ t0: A = 2, P = 12 s, φ = 30°, t0 = 1 s
    load = make(sine_amplitude=2.0, sine_period=12.0, sine_phase=30.0, sine_start=1.0)
    got = d_series(load, 5)
    expected = [0.0] + [2.0 * math.sin(2 * math.pi * (t - 1.0) / 12.0 + math.pi / 6)
                        for t in (1.0, 2.0, 3.0, 4.0)]
    assert got == pytest.approx(expected, abs=1e-12)
    assert got[1] == pytest.approx(1.0, abs=1e-12)        # 2·sin 30°
    assert got[3] == pytest.approx(2.0, abs=1e-12)        # 2·sin 90° at t - t0 = 2 s = P/6


def test_components_add_up(make: Make) -> None:
    load = make(bias=1.0, step_size=2.0, step_time=1.0, ramp_rate=0.25,
                sine_amplitude=0.5, sine_period=4.0)
    got = [load.step(1.0, u=10.0)["y"].value for _ in range(3)]
    # t = 0: 10 + 1;  t = 1: 10 + 1 + 2 + 0.25 + 0.5·sin 90°;  t = 2: 10 + 1 + 2 + 0.5 + sin 180°
    assert got == pytest.approx([11.0, 13.75, 13.5], abs=1e-12)


def test_clock_input_sets_the_time(make: Make) -> None:
    load = make(step_size=1.0, step_time=100.0, ramp_rate=1.0, ramp_start=99.0)
    assert load.step(1.0, clock=99.5)["d"].value == 0.5
    assert load.step(1.0, clock=100.0)["d"].value == 2.0
    # NaN clock: the block's own time, which continued from the last clock (100 + 1)
    assert load.step(1.0, clock=math.nan)["d"].value == 3.0


def test_module_time_drives_the_step() -> None:
    m = Module({"load": create_block(KIND, step_size=5.0, step_time=0.5),
                "proc": create_block("process.first_order", time_constant=0.0)},
               wires={"proc.u": "load.y"}, inputs={"load": {"u": 1.0}})
    r = m.run(duration=1.0, dt=0.25)
    assert list(r["proc.y"]) == [1.0, 1.0, 6.0, 6.0]


# -- random walk -----------------------------------------------------------------------------

def test_walk_is_zero_until_it_starts_then_sums_scaled_normals(make: Make) -> None:
    """w(t0) = 0, w(t + dt) = w(t) + σ·√dt·n_k, n_k the block's own normals."""
    load = make(walk_std=0.3, walk_start=2.0, seed=17)
    got = d_series(load, 8, dt=0.5)
    x = np.array(rng_seed_state(17, STREAM_DISTURBANCE))
    w, expected = 0.0, []
    for k in range(8):
        expected.append(w)
        if k * 0.5 >= 2.0:
            w += 0.3 * math.sqrt(0.5) * rng_normal(x, 0)
    assert got == expected
    assert got[:5] == [0.0] * 5 and got[5] != 0.0   # t = 2 s gives w(t0) = 0


def test_walk_increments_are_independent_normals_of_variance_sigma2_dt() -> None:
    """N = 40 000 increments / (σ√dt): mean within 5/√N, std within 5/√(2N) of 1, lag-1
    autocorrelation within 5/√N."""
    n, sigma, dt = 40_000, 0.8, 0.25
    for seed in (0, 77):
        load = create_block(KIND, walk_std=sigma, seed=seed)
        w = np.array(d_series(load, n + 1, dt=dt))
        z = np.diff(w) / (sigma * math.sqrt(dt))
        assert abs(z.mean()) < 5 / math.sqrt(n)
        assert abs(z.std(ddof=1) - 1.0) < 5 / math.sqrt(2 * n)
        assert abs(float(np.corrcoef(z[:-1], z[1:])[0, 1])) < 5 / math.sqrt(n)


def test_walk_variance_grows_as_sigma2_t_whatever_the_scan_time() -> None:
    """Over 400 seeds, std of w(20 s) is σ·√20 within 5 standard errors (σ√20/√(2·400)), with
    0.1 s and with 2 s scans."""
    sigma, horizon, runs = 0.5, 20.0, 400
    for dt in (0.1, 2.0):
        n = round(horizon / dt)
        finals = []
        for seed in range(runs):
            load = create_block(KIND, walk_std=sigma, seed=seed)
            finals.append(d_series(load, n + 1, dt=dt)[-1])
        target = sigma * math.sqrt(horizon)
        assert abs(np.std(finals, ddof=1) - target) < 5 * target / math.sqrt(2 * runs)
        assert abs(np.mean(finals)) < 5 * target / math.sqrt(runs)


def test_ornstein_uhlenbeck_steps_are_exact() -> None:
    """w(t+dt) = a·w + σ·√(τ/2·(1 - a²))·n: the normalised innovations are N(0, 1), and the
    long-run std is σ·√(τ/2) (tolerance 5 standard errors with N_eff = N·dt/(2τ))."""
    n, sigma, tau, dt = 60_000, 0.4, 5.0, 0.5
    load = create_block(KIND, walk_std=sigma, walk_time_constant=tau, seed=4)
    w = np.array(d_series(load, n + 1, dt=dt))
    a = math.exp(-dt / tau)
    z = (w[1:] - a * w[:-1]) / (sigma * math.sqrt(tau / 2 * (1 - a * a)))
    assert abs(z.mean()) < 5 / math.sqrt(n)
    assert abs(z.std(ddof=1) - 1.0) < 5 / math.sqrt(2 * n)
    stationary = sigma * math.sqrt(tau / 2)
    n_eff = n * dt / (2 * tau)
    assert abs(w[1000:].std() - stationary) < 5 * stationary / math.sqrt(2 * n_eff)


def test_same_seed_same_walk_other_seed_other_walk() -> None:
    def walk(seed: int) -> list[float]:
        return d_series(create_block(KIND, walk_std=1.0, seed=seed), 30)

    assert walk(2) == walk(2)
    assert walk(2) != walk(3)


def test_sensor_and_disturbance_with_one_seed_draw_different_streams() -> None:
    load = create_block(KIND, walk_std=1.0, seed=5)
    tt = create_block("sensor.transmitter", noise_std=1.0, seed=5)
    steps = np.diff(d_series(load, 11))
    noise = [tt.step(1.0, y=0.0)["pv"].value for _ in range(10)]
    assert not np.allclose(steps, noise)


# -- parameters, save/resume, jit, replay -----------------------------------------------------

@pytest.mark.parametrize(("params", "name"), [
    ({"ramp_start": 10.0, "ramp_end": 5.0}, "ramp_end"),
    ({"sine_period": 0.0}, "sine_period"),
    ({"walk_std": -0.1}, "walk_std"),
    ({"walk_time_constant": 0.0}, "walk_time_constant"),
    ({"seed": -3}, "seed"),
    ({"step_time": math.nan}, "step_time"),
])
def test_bad_parameters_name_the_parameter(params: dict[str, Any], name: str) -> None:
    with pytest.raises(ParameterError, match=f"'{name}'"):
        create_block(KIND, **params)


def test_resume_from_saved_state_continues_the_walk_exactly() -> None:
    params = {"walk_std": 0.2, "walk_time_constant": 30.0, "seed": 8, "sine_amplitude": 1.0,
              "ramp_rate": 0.01, "step_size": 1.0, "step_time": 150.0}
    whole = create_block(KIND, **params)
    first = create_block(KIND, **params)
    expected = [whole.step(0.7, u=3.0)["y"] for _ in range(300)]
    for _ in range(140):
        first.step(0.7, u=3.0)
    saved = json.loads(json.dumps(first.state_dict()))
    resumed = create_block(saved["kind"], **saved["params"])
    resumed.load_state(saved)
    assert [resumed.step(0.7)["y"] for _ in range(160)] == expected[140:]


def test_replay_cli_runs_the_docstring_example(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "load.csv", ["t", "u"], [[0, 10], [1, 10], [2, 10], [3, 10]])
    result = CliRunner().invoke(app, ["replay", KIND, str(path), "-p", "step_size=5",
                                      "-p", "step_time=2", "-p", "sine_amplitude=1",
                                      "-p", "sine_period=4"])
    assert result.exit_code == 0, result.output
    rows = list(csv.reader(io.StringIO(result.stdout)))
    assert rows[0] == ["t", "y", "d", "y.ST", "d.ST"]
    # sin 0, sin 90°, 5 + sin 180°, 5 + sin 270°
    assert [float(r[1]) for r in rows[1:]] == pytest.approx([10.0, 11.0, 15.0, 14.0], abs=1e-12)
    assert [float(r[2]) for r in rows[1:]] == pytest.approx([0.0, 1.0, 5.0, 4.0], abs=1e-12)


def test_docstring_python_example() -> None:
    load = loopworks.create_block(KIND, step_size=2.0, step_time=10.0, ramp_rate=5.0 / 60.0)
    for _ in range(12):
        r = load.step(1.0, u=40.0)
    assert r["y"].value == pytest.approx(40.0 + 2.0 + 11.0 / 12.0, abs=1e-12)


# -- issue 11: numeric contract and start value ----------------------------------------------------


def test_d_beyond_the_float_range_is_nan_bad_and_recovers(make: Make) -> None:
    """A clock near the float range makes ramp_rate·t overflow: d is NaN with status Bad (d
    carries a status since issue 11, so a NaN d cannot pass as a value) and y is Bad with it;
    with the time back in range both are Good again."""
    load = make(ramp_rate=1e10)
    r = load.step(1.0, u=5.0, clock=1e300)
    assert math.isnan(r["d"].value) and r["d"].status == 0x00
    assert math.isnan(r["y"].value) and r["y"].status == 0x00
    r = load.step(1.0, u=5.0, clock=2.0)
    assert r["d"] == (2e10, GOOD) and r["y"] == (5.0 + 2e10, GOOD)


def test_bare_kernel_is_sound_on_extreme_inputs() -> None:
    """The kernel by itself (no guard) never gives a non-finite output with a status that is
    not Bad, nor a non-finite state, for NaN, ±inf, ±1e308 in u and the clock."""
    load = create_block(KIND, jit=False, ramp_rate=3.0, sine_amplitude=2.0, walk_std=1.0,
                        seed=3)
    for u in EXTREMES:
        for clock in (math.nan, 1e308, -1e308, 5.0):
            kernel_scan(load, 0.5, u=u, clock=clock)
            assert unsound(load) == []


def test_start_value_is_u_plus_d_at_t_0() -> None:
    """Issue 11 point 8: before its first scan the block publishes y = u + d(0) and d(0) for
    the u latched now (the bias, a step at t = 0, the sine's phase; the walk is 0), so a
    block that reads y earlier in a module's order sees the signal, not 0; publish_start()
    (what a module that settles its wires calls) re-publishes it for a newly latched u."""
    load = create_block(KIND, bias=2.0, step_size=1.0, sine_amplitude=4.0, sine_phase=30.0,
                        walk_std=1.0)
    d0 = 2.0 + 1.0 + 4.0 * 0.5
    assert load.outputs()["d"] == (pytest.approx(d0), GOOD)
    assert load.outputs()["y"] == (pytest.approx(d0), GOOD)
    load.set_inputs({"u": (40.0, 0x40)})
    load.publish_start()  # type: ignore[attr-defined]
    assert load.outputs()["y"] == (pytest.approx(40.0 + d0), 0x40)
    assert load.step(1.0)["y"].value == pytest.approx(40.0 + d0)  # scan 1 at t = 0
