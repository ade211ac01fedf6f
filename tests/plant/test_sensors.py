"""``sensor.transmitter`` and the seeded generator it shares with ``disturbance.load``.

Golden values come from hand arithmetic written in the tests, from the published reference
outputs of MRG32k3a (L'Ecuyer's RngStream.c, all-12345 state) and SplitMix64 (Vigna's
splitmix64.c, state 0), and from an exact integer re-implementation of MRG32k3a written here.
Statistical checks use fixed seeds and tolerances of five standard errors for the sample size.
The plant-and-tuning spec feeds the loop metrics of section 4 from the PV the sensor gives
(spec 4.1); its quantiser is spec 1.5 and measurement noise is listed in spec 6 item 3.
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
from loopworks.plant import sensor
from loopworks.plant.sensor import rng_normal, rng_seed_state, rng_uniform
from tests.csvfiles import write_csv
from tests.plant.numeric import kernel_scan, unsound

NAN = math.nan
GOOD = 0x80
BAD_SENSOR = 0x10
OOS = 0x1C
UNCERTAIN_RANGE = 0x54
KIND = "sensor.transmitter"

Make = Callable[..., Block]


@pytest.fixture(params=[True, False], ids=["compiled", "interpreted"])
def make(request: pytest.FixtureRequest) -> Make:
    """``make(**params)``: a transmitter with the compiled or the interpreted kernel."""
    jit = request.param

    def _make(**params: Any) -> Block:
        return create_block(KIND, jit=jit, **params)

    return _make


def run(block: Block, ys: list[Any], dt: float = 1.0) -> list[tuple[float, int]]:
    out = []
    for y in ys:
        r = block.step(dt, y=y)["pv"]
        out.append((r.value, r.status))
    return out


# -- the generator -------------------------------------------------------------------------------

def mrg32k3a_exact(seed: list[int], n: int) -> list[float]:
    """MRG32k3a with Python integers (L'Ecuyer 1999, eqs. for the two components)."""
    m1, m2 = 4294967087, 4294944443
    s1, s2 = list(seed[:3]), list(seed[3:])
    out = []
    for _ in range(n):
        p1 = (1403580 * s1[1] - 810728 * s1[0]) % m1
        s1 = [s1[1], s1[2], p1]
        p2 = (527612 * s2[2] - 1370589 * s2[0]) % m2
        s2 = [s2[1], s2[2], p2]
        z = (p1 - p2) % m1
        out.append(float(z if z > 0 else m1) * 2.328306549295727688e-10)  # × 1/(m1 + 1)
    return out


def test_mrg32k3a_reference_outputs() -> None:
    """The first five numbers and the 1000th from the all-12345 state: the published outputs
    of L'Ecuyer's RngStream.c."""
    x = np.full(6, 12345.0)
    first = [rng_uniform(x, 0) for _ in range(5)]
    assert first == [0.12701112204657714, 0.3185275653967945, 0.3091860155832701,
                     0.8258468629271136, 0.2216299157820229]
    for _ in range(994):
        rng_uniform(x, 0)
    assert rng_uniform(x, 0) == 0.98607848680213228


def test_float_mrg32k3a_is_exact_integer_arithmetic() -> None:
    """The double-precision recurrence equals the integer one on 20 000 draws (every product
    below 2^53), from a seeded state and from the all-12345 state."""
    for start in (rng_seed_state(99, 1), [12345.0] * 6):
        x = np.array(start)
        got = [rng_uniform(x, 0) for _ in range(20_000)]
        assert got == mrg32k3a_exact([int(v) for v in start], 20_000)


def test_splitmix64_reference_outputs() -> None:
    """SplitMix64 from state 0: Vigna's published first outputs."""
    state, outs = 0, []
    for _ in range(4):
        state, z = sensor._splitmix64(state)
        outs.append(z)
    assert outs == [0xE220A8397B1DCDAF, 0x6E789E6AA1B965F4, 0x06C45D188009454F,
                    0xF88BB8A8724C81EC]


def test_seed_state_is_splitmix_of_seed_and_stream() -> None:
    """seed 0, stream 0: SplitMix64 from state 0, reduced modulo m1 (first three) and m2."""
    words = [0xE220A8397B1DCDAF, 0x6E789E6AA1B965F4, 0x06C45D188009454F, 0xF88BB8A8724C81EC]
    state = rng_seed_state(0, 0)
    assert state[:3] == [float(w % 4294967087) for w in words[:3]]
    assert state[3] == float(words[3] % 4294944443)
    assert all(0 <= v < 4294967087 and v == int(v) for v in state)
    assert rng_seed_state(5, 1) != rng_seed_state(5, 2) != rng_seed_state(6, 1)


def test_normals_are_box_muller_of_two_uniforms() -> None:
    x, xu = np.array(rng_seed_state(3, 1)), np.array(rng_seed_state(3, 1))
    for _ in range(100):
        u1, u2 = rng_uniform(xu, 0), rng_uniform(xu, 0)
        assert rng_normal(x, 0) == math.sqrt(-2.0 * math.log(u1)) * math.cos(2 * math.pi * u2)


# -- the signal path -----------------------------------------------------------------------------

def test_defaults_pass_the_value_through(make: Make) -> None:
    tt = make()
    assert run(tt, [1.5, -7.25, 1e6]) == [(1.5, GOOD), (-7.25, GOOD), (1e6, GOOD)]


def test_gain_and_offset(make: Make) -> None:
    # m = gain·y + offset: 0..10 bar to 0..100 % with a 0.5 % zero error
    tt = make(gain=10.0, offset=0.5)
    assert [v for v, _ in run(tt, [0.0, 3.0, 10.0])] == [0.5, 30.5, 100.5]


def test_first_order_lag_starts_settled_then_exact_zoh_steps(make: Make) -> None:
    """z_k = z_{k-1} + (1 - e^(-dt/T))(m - z_{k-1}), z_0 = first measurement."""
    tt = make(time_constant=2.0)
    got = [v for v, _ in run(tt, [4.0, 10.0, 10.0, 10.0, 10.0], dt=0.5)]
    a = 1.0 - math.exp(-0.25)
    expected = [4.0]
    for _ in range(4):
        expected.append(expected[-1] + a * (10.0 - expected[-1]))
    assert got[0] == 4.0
    assert got == pytest.approx(expected, abs=1e-12)
    # the closed form 10 - 6·e^(-k·dt/T)
    assert got[4] == pytest.approx(10.0 - 6.0 * math.exp(-4 * 0.5 / 2.0), abs=1e-12)


def test_quantisation_rounds_to_the_nearest_step_halves_up(make: Make) -> None:
    # spec 1.5: y = q·round(x/q); here q·floor(x/q + 1/2)
    tt = make(quantum=0.5)
    got = [v for v, _ in run(tt, [10.1, 10.25, 10.3, -0.25, -0.3, 0.74, 0.76])]
    assert got == [10.0, 10.5, 10.5, 0.0, -0.5, 0.5, 1.0]


def test_noise_is_added_after_the_lag_and_before_the_quantiser(make: Make) -> None:
    """pv = q·floor((z + σ·n)/q + 1/2), n the block's own normals (seed 4, sensor stream)."""
    tt = make(time_constant=3.0, noise_std=0.2, quantum=0.1, seed=4)
    x = np.array(rng_seed_state(4, sensor.STREAM_SENSOR))
    z = 20.0
    for k, yk in enumerate([20.0, 25.0, 25.0, 25.0]):
        if k:
            z = z + (1.0 - math.exp(-1.0 / 3.0)) * (yk - z)
        v = z + 0.2 * rng_normal(x, 0)
        expected = 0.1 * math.floor(v / 0.1 + 0.5)
        assert tt.step(1.0, y=yk)["pv"].value == expected


def test_range_clamps_with_limit_bits_and_uncertain_quality(make: Make) -> None:
    # a saturated output: Uncertain EU range violation (0x54) + high (2) / low (1) limit bits
    tt = make(pv_lo=-2.5, pv_hi=102.5)
    assert run(tt, [110.0, 50.0, -9.0]) == [(102.5, UNCERTAIN_RANGE | 2), (50.0, GOOD),
                                              (-2.5, UNCERTAIN_RANGE | 1)]
    good = make(pv_lo=0.0, pv_hi=100.0, range_status="good")
    assert run(good, [101.0, -1.0]) == [(100.0, GOOD | 2), (0.0, GOOD | 1)]


def test_a_value_beyond_the_range_is_limited_even_when_quantised_onto_its_edge(
        make: Make) -> None:
    """A measured 100.1 on 0..100 is a saturated signal; quantised to 0.5 it is 100.0, which
    the range check after the quantiser let through as Good. The limit bits and the range
    status come from the value before the quantiser as well as after it; a value inside
    the range that the quantiser puts beyond it is limited as before, and one that stays in
    keeps its quantised value."""
    tt = make(pv_lo=0.0, pv_hi=100.0, quantum=0.5)
    assert run(tt, [100.1, -0.2, 99.9, 0.2, 99.7]) == [
        (100.0, UNCERTAIN_RANGE | 2), (0.0, UNCERTAIN_RANGE | 1), (100.0, GOOD),
        (0.0, GOOD), (99.5, GOOD)]
    edge = make(pv_lo=0.0, pv_hi=99.9, quantum=0.5)  # 99.8 rounds up to 100.0, beyond 99.9
    assert run(edge, [99.8, 99.7]) == [(99.9, UNCERTAIN_RANGE | 2), (99.5, GOOD)]


def test_noise_statistics_mean_std_normality_whiteness() -> None:
    """N = 40 000 scans, σ = 0.5: the sample mean within 5σ/√N, the sample std within
    5σ/√(2N), P(|n| < σ) within 5·√(p(1-p)/N) of 0.6827, lag-1 autocorrelation within 5/√N,
    for three seeds."""
    n, sigma = 40_000, 0.5
    for seed in (0, 1, 12345):
        tt = create_block(KIND, noise_std=sigma, seed=seed)
        e = np.array([tt.step(0.1, y=30.0)["pv"].value for _ in range(n)]) - 30.0
        assert abs(e.mean()) < 5 * sigma / math.sqrt(n)
        assert abs(e.std(ddof=1) - sigma) < 5 * sigma / math.sqrt(2 * n)
        p = math.erf(1 / math.sqrt(2))  # 0.682689...
        assert abs(np.mean(np.abs(e) < sigma) - p) < 5 * math.sqrt(p * (1 - p) / n)
        r1 = float(np.corrcoef(e[:-1], e[1:])[0, 1])
        assert abs(r1) < 5 / math.sqrt(n)


def test_same_seed_same_noise_other_seed_other_noise() -> None:
    def noise(seed: int) -> list[float]:
        tt = create_block(KIND, noise_std=1.0, seed=seed)
        return [tt.step(1.0, y=0.0)["pv"].value for _ in range(50)]

    assert noise(8) == noise(8)
    assert noise(8) != noise(9)


def test_noise_of_scan_k_is_the_kth_number_whatever_happens(make: Make) -> None:
    """A Bad input and a failure in the middle do not shift the stream (one draw per scan)."""
    ref = make(noise_std=1.0, seed=21)
    other = make(noise_std=1.0, seed=21, failure="nan", failure_start=5.0, failure_end=8.0)
    for k in range(20):
        y = (7.0, OOS) if k in (2, 3) else 7.0
        a = ref.step(1.0, y=7.0)["pv"].value
        b = other.step(1.0, y=y)["pv"].value
        if k not in (2, 3, 5, 6, 7):
            assert a == b


# -- input status ----------------------------------------------------------------------------------

def test_bad_or_non_finite_input_holds_the_pv(make: Make) -> None:
    tt = make(time_constant=5.0)
    got = run(tt, [10.0, (20.0, OOS), NAN, math.inf, 20.0])
    assert got[1] == (10.0, OOS)            # Bad input: the PV and its status as given
    assert got[2] == (10.0, 0x00)           # NaN with Good status: Bad non-specific
    assert got[3] == (10.0, 0x00)
    # the lag held: the first good scan moves from 10 by one step
    assert got[4] == (pytest.approx(10.0 + (1 - math.exp(-0.2)) * 10.0, abs=1e-12), GOOD)


def test_uncertain_input_gives_uncertain_pv(make: Make) -> None:
    tt = make()
    assert run(tt, [(5.0, 0x47), (5.0, 0x40)]) == [(5.0, 0x44), (5.0, 0x40)]


def test_bad_input_at_the_first_scan_then_settles_on_the_first_good_one(make: Make) -> None:
    tt = make(time_constant=10.0)
    got = run(tt, [(3.0, OOS), 8.0, 8.0])
    assert got[0][1] == OOS
    assert got[1:] == [(8.0, GOOD), (8.0, GOOD)]


# -- failures --------------------------------------------------------------------------------------

def test_stuck_freezes_the_last_pv_with_good_status(make: Make) -> None:
    tt = make(failure="stuck", failure_start=3.0)
    got = run(tt, [1.0, 2.0, 3.0, 4.0, 5.0, 6.0])   # t = 0..5 s
    assert got == [(1.0, GOOD), (2.0, GOOD), (3.0, GOOD), (3.0, GOOD), (3.0, GOOD), (3.0, GOOD)]


def test_stuck_holds_a_noisy_value_without_noise(make: Make) -> None:
    tt = make(failure="stuck", failure_start=10.0, noise_std=2.0, seed=5)
    got = [v for v, _ in run(tt, [0.0] * 30)]
    assert len(set(got[:10])) == 10
    assert set(got[10:]) == {got[9]}


def test_bad_holds_the_last_value_with_bad_sensor_failure(make: Make) -> None:
    tt = make(failure="bad", failure_start=2.0, failure_end=4.0)
    got = run(tt, [1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    assert got == [(1.0, GOOD), (2.0, GOOD), (2.0, BAD_SENSOR), (2.0, BAD_SENSOR),
                   (5.0, GOOD), (6.0, GOOD)]   # recovers at t = 4 s to the current reading


def test_nan_gives_nan_with_bad_status_by_default(make: Make) -> None:
    """Issue 11 point 1: no output is NaN unless its status is Bad, so the injected NaN comes
    with Bad non-specific (0x00); it used to come with Good (128)."""
    tt = make(failure="nan", failure_start=1.0)
    got = run(tt, [1.0, 2.0, 3.0])
    assert got[0] == (1.0, GOOD)
    assert math.isnan(got[1][0]) and got[1][1] == 0x00
    assert math.isnan(got[2][0]) and got[2][1] == 0x00
    assert all(math.isfinite(v) for v in tt.x)


def test_nan_failure_with_a_status_that_is_not_bad_is_refused() -> None:
    """failure = nan with failure_status Good or Uncertain would be a NaN that looks usable
    (issue 11 point 1): a ParameterError naming failure_status."""
    for status in (128, 0x40):
        with pytest.raises(ParameterError, match=rf"'failure_status' = {status} is out of range "
                                                 "for failure = 'nan'"):
            create_block(KIND, failure="nan", failure_status=status)
    create_block(KIND, failure="stuck", failure_status=128)  # a finite value may look Good


def test_failure_status_overrides_the_mode_default(make: Make) -> None:
    tt = make(failure="nan", failure_start=0.0, failure_status=0x10)
    assert tt.step(1.0, y=1.0)["pv"].status == BAD_SENSOR
    stuck = make(failure="stuck", failure_status=0x47)
    assert run(stuck, [4.0, 9.0]) == [(4.0, 0x47), (4.0, 0x47)]  # from the first scan


def test_the_sensing_element_follows_the_process_during_a_failure(make: Make) -> None:
    """The lag keeps running: after the failure the PV is the lag's current value."""
    tt = make(time_constant=4.0, failure="bad", failure_start=1.0, failure_end=6.0)
    got = [v for v, _ in run(tt, [0.0] + [10.0] * 7)]
    assert got[6] == pytest.approx(10.0 * (1.0 - math.exp(-6.0 / 4.0)), abs=1e-12)


def test_failure_time_tolerates_summed_scan_times(make: Make) -> None:
    """200 scans of 0.1 s sum to 19.999999999999996: a failure at 20 s starts at scan 200."""
    tt = make(failure="bad", failure_start=20.0)
    statuses = [s for _, s in run(tt, [1.0] * 202, dt=0.1)]
    assert statuses[199] == GOOD and statuses[200] == BAD_SENSOR


def test_failure_time_follows_the_clock_input(make: Make) -> None:
    tt = make(failure="stuck", failure_start=100.0, failure_status=0x11)
    assert tt.step(1.0, y=1.0, clock=99.0)["pv"] == (1.0, GOOD)
    assert tt.step(1.0, y=2.0, clock=100.0)["pv"] == (1.0, 0x11)


def test_module_feeds_its_time_to_the_failure_window() -> None:
    m = Module({"proc": create_block("process.first_order", time_constant=0.0),
                "tt": create_block(KIND, failure="bad", failure_start=0.75)},
               wires={"tt.y": "proc.y"}, inputs={"proc": {"u": 3.0}})
    r = m.run(duration=1.25, dt=0.25)
    assert list(r.status["tt.pv"]) == [GOOD, GOOD, GOOD, BAD_SENSOR, BAD_SENSOR]
    assert list(r["tt.pv"]) == [3.0] * 5


# -- parameters, save/resume, jit, replay ----------------------------------------------------------

@pytest.mark.parametrize(("params", "name"), [
    ({"pv_lo": 5.0, "pv_hi": 5.0}, "pv_hi"),
    ({"failure_start": 10.0, "failure_end": 5.0}, "failure_end"),
    ({"noise_std": -1.0}, "noise_std"),
    ({"time_constant": -0.1}, "time_constant"),
    ({"quantum": -0.5}, "quantum"),
    ({"failure": "drift"}, "failure"),
    ({"seed": -1}, "seed"),
    ({"seed": 1.5}, "seed"),
    ({"failure_status": 256}, "failure_status"),
])
def test_bad_parameters_name_the_parameter(params: dict[str, Any], name: str) -> None:
    with pytest.raises(ParameterError, match=f"'{name}'"):
        create_block(KIND, **params)


def test_resume_from_saved_state_continues_the_noise_exactly() -> None:
    params = {"noise_std": 0.7, "time_constant": 1.5, "quantum": 0.01, "seed": 3,
              "failure": "bad", "failure_start": 150.0, "failure_end": 170.0}
    whole = create_block(KIND, **params)
    first = create_block(KIND, **params)
    ys = [50.0 + 10.0 * math.sin(k / 20.0) for k in range(300)]
    expected = [whole.step(1.0, y=y)["pv"] for y in ys]
    for y in ys[:120]:
        first.step(1.0, y=y)
    saved = json.loads(json.dumps(first.state_dict()))
    resumed = create_block(saved["kind"], **saved["params"])
    resumed.load_state(saved)
    assert [resumed.step(1.0, y=y)["pv"] for y in ys[120:]] == expected[120:]


def test_replay_cli_runs_the_docstring_example(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "tt.csv", ["t", "y"],
                     [[0, 10.1], [1, 10.3], [2, 11.0], [3, 12.0]])
    result = CliRunner().invoke(app, ["replay", KIND, str(path), "-p", "quantum=0.5",
                                      "-p", "failure=stuck", "-p", "failure_start=2"])
    assert result.exit_code == 0, result.output
    rows = list(csv.reader(io.StringIO(result.stdout)))
    assert rows[0] == ["t", "pv", "pv.ST"]
    # 10.1 -> 10, 10.3 -> 10.5; stuck from t = 2 s at 10.5
    assert [float(r[1]) for r in rows[1:]] == [10.0, 10.5, 10.5, 10.5]
    assert [int(r[2]) for r in rows[1:]] == [GOOD] * 4


def test_docstring_python_example() -> None:
    tt = loopworks.create_block(KIND, time_constant=2.0, noise_std=0.1, quantum=0.05, seed=7,
                                failure="bad", failure_start=10.0)
    results = [tt.step(1.0, y=50.0)["pv"] for _ in range(12)]
    assert results[11] == (results[9].value, BAD_SENSOR)
    assert results[9].status == GOOD


# -- issue 11: numeric contract and start value ----------------------------------------------------


@pytest.mark.parametrize("huge", [1e308, -1e308, 1e200, math.inf, -math.inf, NAN])
def test_extreme_input_holds_like_a_bad_one_and_leaves_no_trace(make: Make, huge: float) -> None:
    """A y the transmitter cannot measure - NaN, ±inf, or a reading gain·y + offset beyond
    ±1e150 (module docstring) - holds the PV and the lag with status Bad, exactly as a Bad
    status does (reference: the same scans fed with an OOS input), and afterwards the PV is
    the reference's bit for bit; noise keeps its stream. A 1e308 used to enter the lag."""
    a = make(time_constant=5.0, noise_std=0.5, seed=2)
    b = make(time_constant=5.0, noise_std=0.5, seed=2)
    for k in range(30):
        burst = 10 <= k < 13
        ra = a.step(1.0, y=(huge, GOOD) if burst else 20.0 + k)["pv"]
        rb = b.step(1.0, y=(0.0, OOS) if burst else 20.0 + k)["pv"]
        assert ra.value == rb.value
        assert ra.status == (0x00 if burst else GOOD)
        assert all(math.isfinite(v) for v in a.x)


def test_noise_that_overflows_is_held_bad_by_the_kernel_itself() -> None:
    """noise_std = 1e308 (finite, so valid): lag + noise overflows on most scans. The bare
    kernel (no guard) holds the PV with status Bad instead of giving inf with status Good;
    the generator still advances one draw per scan."""
    tt = create_block(KIND, jit=False, noise_std=1e308, seed=4)
    for _ in range(20):
        kernel_scan(tt, 1.0, y=1.0)
        assert unsound(tt) == []
    draws = np.array(rng_seed_state(4, sensor.STREAM_SENSOR))
    for _ in range(20):
        rng_normal(draws, 0)
    assert list(tt.x[sensor.X.rng_s10:]) == list(draws)


def test_start_value_is_the_settled_pv_of_the_latched_y() -> None:
    """Issue 11 point 8: before its first scan the transmitter publishes the PV of its settled
    start for the y latched now: gain·y + offset, quantised, limited, no noise. By default
    y = 0 gives the offset; publish_start() (what a module that settles its wires calls)
    re-publishes it for a newly latched y."""
    tt = create_block(KIND, gain=2.0, offset=2.0, quantum=0.5, pv_hi=10.0, noise_std=1.0)
    assert tt.outputs()["pv"] == (2.0, GOOD)
    tt.set_inputs({"y": 3.3})
    tt.publish_start()  # type: ignore[attr-defined]
    assert tt.outputs()["pv"] == (8.5, GOOD)         # 2·3.3 + 2 = 8.6 -> 8.5
    tt.set_inputs({"y": 7.0})
    tt.publish_start()  # type: ignore[attr-defined]
    assert tt.outputs()["pv"] == (10.0, UNCERTAIN_RANGE | 2)   # 16 limited at pv_hi


def test_bad_first_input_holds_the_start_value(make: Make) -> None:
    """Before the first usable scan a Bad y holds the start value published before the first
    scan (the offset for y = 0), not an arbitrary 0."""
    tt = make(offset=5.0)
    assert run(tt, [(3.0, OOS), 8.0]) == [(5.0, OOS), (13.0, GOOD)]
