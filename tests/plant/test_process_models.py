"""Process models with dead time: ``process.fopdt``, ``process.sopdt``, ``process.ipdt`` and
``process.tf`` (plant-and-tuning 6.3: exact ZOH discretisation with dead time; 2.8: start at
steady state; 3.2: the relay oracles on the reference plants).

Expected values are closed-form continuous-time responses written in the tests (sampled at the
scan ends), hand-written difference equations, or an independent implementation
(``scipy.signal.lsim``); none is pasted from a run of the block. Timing convention (module
docstring): scan k covers (t_{k-1}, t_k], its input is held over it, y_k = y(t_k). Behaviour
tests run twice through the ``make`` fixture: compiled (numba) and interpreted.
"""

from __future__ import annotations

import csv
import io
import itertools
import json
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

import loopworks
from loopworks.blocks.block import Block
from loopworks.cli import app
from loopworks.errors import InputError, ParameterError
from loopworks.sim.module import Module
from tests.csvfiles import write_csv
from tests.plant.numeric import kernel_scan, unsound

NAN = math.nan
INF = math.inf
GOOD = 0x80  # Good non-cascade
BAD_NS = 0x00  # Bad, non-specific
BAD_CONFIG = 0x04  # Bad, configuration error
UNCERTAIN = 0x40

Make = Callable[..., Block]


@pytest.fixture(params=[True, False], ids=["compiled", "interpreted"])
def make(request: pytest.FixtureRequest) -> Make:
    """``make(kind, **params)``: a block with the compiled or the interpreted kernel."""
    jit = request.param

    def _make(kind: str, **params: Any) -> Block:
        return loopworks.create_block(kind, jit=jit, **params)

    return _make


def run(block: Block, dts: Sequence[float], us: Sequence[Any]) -> tuple[list[float], list[int]]:
    """Step ``block`` through (dt, u) pairs; the outputs' values and statuses."""
    values, statuses = [], []
    for dt, u in zip(dts, us, strict=True):
        out = block.step(dt, u=u)["y"]
        values.append(out.value)
        statuses.append(out.status)
    return values, statuses


def scan_ends(dts: Sequence[float]) -> list[float]:
    """t_k = dt_1 + ... + dt_k."""
    return list(np.cumsum(dts))


# Closed-form unit-step responses (input step at t = 0, dead time θ, s = t - θ).

def fopdt_step(t: float, k: float, tau: float, theta: float) -> float:
    """K·(1 - e^(-(t - θ)/T)) for t ≥ θ, else 0."""
    s = t - theta
    return 0.0 if s <= 0.0 else k * (1.0 - math.exp(-s / tau))


def sopdt_step(t: float, k: float, t1: float, t2: float, theta: float) -> float:
    """K·(1 - (T1·e^(-s/T1) - T2·e^(-s/T2))/(T1 - T2)); T1 = T2: K·(1 - (1 + s/T)·e^(-s/T))."""
    s = t - theta
    if s <= 0.0:
        return 0.0
    if t1 == t2:
        return k * (1.0 - (1.0 + s / t1) * math.exp(-s / t1))
    return k * (1.0 - (t1 * math.exp(-s / t1) - t2 * math.exp(-s / t2)) / (t1 - t2))


# ---------------------------------------------------------------------------------------------
# process.fopdt


@pytest.mark.parametrize(("dt", "theta"), [(0.2, 2.0), (0.2, 2.05), (0.1, 0.7), (0.5, 0.0)])
def test_fopdt_step_response_is_the_sampled_closed_form(make: Make, dt: float,
                                                        theta: float) -> None:
    """y(t) = y0 + K·Δu·(1 - e^(-(t-θ)/T)) for t ≥ θ, whether θ is a whole number of scans
    (2.0 = 10 scans, 0.7 = 7 scans of 0.1 with rounding in the sums) or not (2.05)."""
    # spec 6.3 (exact ZOH + dead time), spec 2.8 (the K = 1, T = 10 s, L = 2 s plant family)
    proc = make("process.fopdt", gain=1.5, time_constant=10.0, dead_time=theta, u0=2.0)
    n = 150
    ys, sts = run(proc, [dt] * n, [6.0] * n)
    for t, y in zip(scan_ends([dt] * n), ys, strict=True):
        assert y == pytest.approx(1.5 * 2.0 + 1.5 * 4.0 * (1.0 - math.exp(-(t - theta) / 10.0))
                                  if t > theta else 3.0, abs=1e-12)
    assert set(sts) == {GOOD}


def test_fopdt_with_varying_dt_is_exact_at_every_scan_end(make: Make) -> None:
    """A replay's dt may vary: the line records each scan's duration, so the response is the
    exact continuous one at whatever times the scans end."""
    # spec 6.3 (exact discretisation), issue 5 (replay may vary dt)
    rng = np.random.default_rng(5)
    dts = list(rng.uniform(0.03, 0.4, size=300))
    proc = make("process.fopdt", gain=2.0, time_constant=3.0, dead_time=1.3)
    ys, _ = run(proc, dts, [1.0] * len(dts))
    for t, y in zip(scan_ends(dts), ys, strict=True):
        assert y == pytest.approx(fopdt_step(t, 2.0, 3.0, 1.3), abs=1e-12)


@pytest.mark.parametrize("kind", ["process.fopdt", "process.sopdt", "process.ipdt"])
def test_a_change_of_dt_stays_exact(make: Make, kind: str) -> None:
    """60 scans of 0.1 s, then 0.25 s, then 0.1 s again: the line is walked while the window
    still holds scans of the old length and read directly once the new length fills it; the
    step response stays the closed form throughout (θ = 1.3 s: 13 scans, then 5.2 scans)."""
    # spec 6.3, issue 5 (replay may vary dt), module docstring (fast path and walk)
    dts = [0.1] * 60 + [0.25] * 40 + [0.1] * 60
    proc = make(kind, gain=0.5, dead_time=1.3, **({} if kind == "process.ipdt" else {
        "time_constant_1": 4.0, "time_constant_2": 1.5} if kind == "process.sopdt" else {
        "time_constant": 4.0}))
    ys, _ = run(proc, dts, [2.0] * len(dts))
    for t, y in zip(scan_ends(dts), ys, strict=True):
        if kind == "process.fopdt":
            exact = fopdt_step(t, 1.0, 4.0, 1.3)
        elif kind == "process.sopdt":
            exact = sopdt_step(t, 1.0, 4.0, 1.5, 1.3)
        else:
            exact = 0.5 * 2.0 * max(0.0, t - 1.3)
        assert y == pytest.approx(exact, abs=1e-12)


def test_fopdt_pulse_with_a_non_multiple_dead_time(make: Make) -> None:
    """θ = 1.5 scans: a one-scan pulse (u = 1 over (0, 0.5]) reaches the plant over
    (0.75, 1.25]: y rises as K(1 - e^(-(t-0.75)/T)) there and decays afterwards."""
    # spec 6.3; module docstring: two pieces, f·dt of u_{k-n-1} then (1-f)·dt of u_{k-n}
    k, tau, theta, dt = 2.0, 5.0, 0.75, 0.5
    proc = make("process.fopdt", gain=k, time_constant=tau, dead_time=theta)
    ys, _ = run(proc, [dt] * 10, [1.0] + [0.0] * 9)
    peak = k * (1.0 - math.exp(-0.5 / tau))  # y(1.25), the pulse lasted 0.5 s

    def y_exact(t: float) -> float:
        if t <= theta:
            return 0.0
        if t <= 1.25:
            return k * (1.0 - math.exp(-(t - theta) / tau))
        return peak * math.exp(-(t - 1.25) / tau)

    for t, y in zip(scan_ends([dt] * 10), ys, strict=True):
        assert y == pytest.approx(y_exact(t), abs=1e-12)


def test_fopdt_without_dead_time_is_first_order_bit_for_bit(make: Make) -> None:
    """process.fopdt with θ = 0 and y0 = K·u0 calls the same lag step as
    process.first_order (y0 = K·u0): identical floats on random inputs and scan times."""
    # issue 5 (share the primitive), spec 6.3
    rng = np.random.default_rng(11)
    for u0 in (0.0, 3.25):
        fo = make("process.first_order", gain=-1.7, time_constant=4.0, y0=-1.7 * u0)
        fd = make("process.fopdt", gain=-1.7, time_constant=4.0, dead_time=0.0, u0=u0)
        for _ in range(500):
            dt = float(rng.uniform(0.01, 2.0))
            u = float(rng.uniform(-50.0, 150.0))
            assert fd.step(dt, u=u)["y"].value == fo.step(dt, u=u)["y"].value


@pytest.mark.parametrize(("n", "dt"), [(0, 0.1), (1, 0.1), (7, 0.1), (30, 0.2), (3, 0.3)])
def test_delay_line_is_exact(make: Make, n: int, dt: float) -> None:
    """With no lag (T = 0, K = 1) and θ = n·dt, y_k = u_{k-n} exactly (u0 before): the floats
    come out unchanged, although n·dt and the sums of dt round differently."""
    # issue 5: "for dead_time an integer multiple of dt, y_k = model(u_{k-n}) exactly"
    rng = np.random.default_rng(n)
    inputs = [float(v) for v in rng.uniform(-100.0, 100.0, size=120)]
    proc = make("process.fopdt", gain=1.0, time_constant=0.0, dead_time=n * dt, u0=42.5)
    ys, _ = run(proc, [dt] * len(inputs), inputs)
    expected = [42.5] * n + inputs[:len(inputs) - n]
    assert ys == expected


def test_non_multiple_dead_time_shows_the_held_input_at_t_minus_theta(make: Make) -> None:
    """θ = 2.5 scans and no lag: y_k = u_{k-2}, the input held at t_k - θ (ZOH)."""
    # module docstring (non-multiples), issue 5
    inputs = [float(i * i) for i in range(1, 30)]
    proc = make("process.fopdt", gain=1.0, time_constant=0.0, dead_time=0.25)
    ys, _ = run(proc, [0.1] * len(inputs), inputs)
    assert ys == [0.0, 0.0, *inputs[:-2]]


def test_changing_dead_time_between_scans_uses_the_recorded_history(make: Make) -> None:
    """The line keeps times, so a new θ applies at once: y = u(t - θ_new)."""
    # module docstring (set_params)
    proc = make("process.fopdt", gain=1.0, time_constant=0.0, dead_time=0.5)
    inputs = [float(i) for i in range(1, 21)]
    ys, _ = run(proc, [0.1] * 20, inputs)
    assert ys[-1] == inputs[-6]
    proc.set_params(dead_time=0.2)
    assert proc.step(0.1, u=21.0)["y"].value == 19.0  # u at t_21 - 0.2 = t_19
    with pytest.raises(InputError, match="delay_capacity"):
        proc.set_params(delay_capacity=50)


# ---------------------------------------------------------------------------------------------
# process.sopdt


@pytest.mark.parametrize(("t1", "t2", "theta", "dt"),
                         [(10.0, 3.0, 2.0, 0.2), (3.0, 10.0, 1.1, 0.25), (4.0, 4.0, 0.5, 0.1),
                          (8.0, 0.4, 0.0, 0.5)])
def test_sopdt_step_response_is_the_sampled_closed_form(make: Make, t1: float, t2: float,
                                                        theta: float, dt: float) -> None:
    """K·(1 - (T1·e^(-s/T1) - T2·e^(-s/T2))/(T1 - T2)), s = t - θ; T1 = T2 gives
    K·(1 - (1 + s/T)·e^(-s/T))."""
    # spec 6.3 (exact ZOH of SOPDT), spec 3.6 (SOPDT with two time constants)
    proc = make("process.sopdt", gain=0.8, time_constant_1=t1, time_constant_2=t2,
                dead_time=theta)
    n = 200
    ys, _ = run(proc, [dt] * n, [5.0] * n)
    for t, y in zip(scan_ends([dt] * n), ys, strict=True):
        assert y == pytest.approx(sopdt_step(t, 0.8 * 5.0, t1, t2, theta), abs=1e-12)


def test_sopdt_nearly_equal_time_constants_have_no_cancellation(make: Make) -> None:
    """T2 = T1·(1 + 1e-10): the closed form for T1 ≠ T2 cancels catastrophically; the block
    must agree with the T1 = T2 formula (the difference between the plants is ~1e-10)."""
    # module docstring (φ form), spec 6.3
    proc = make("process.sopdt", gain=1.0, time_constant_1=5.0, time_constant_2=5.0 + 5e-10,
                dead_time=0.0)
    ys, _ = run(proc, [0.1] * 300, [1.0] * 300)
    for t, y in zip(scan_ends([0.1] * 300), ys, strict=True):
        assert y == pytest.approx(sopdt_step(t, 1.0, 5.0, 5.0, 0.0), abs=1e-9)


def test_sopdt_with_one_time_constant_zero_is_fopdt(make: Make) -> None:
    """T2 = 0 (or T1 = 0) leaves one lag: the same floats as process.fopdt."""
    # module docstring, spec 6.3
    rng = np.random.default_rng(3)
    fo = make("process.fopdt", gain=2.5, time_constant=6.0, dead_time=0.9, u0=1.0)
    s2 = make("process.sopdt", gain=2.5, time_constant_1=6.0, time_constant_2=0.0,
              dead_time=0.9, u0=1.0)
    s1 = make("process.sopdt", gain=2.5, time_constant_1=0.0, time_constant_2=6.0,
              dead_time=0.9, u0=1.0)
    for _ in range(300):
        dt = float(rng.uniform(0.05, 0.5))
        u = float(rng.uniform(-10.0, 10.0))
        y = fo.step(dt, u=u)["y"].value
        assert s2.step(dt, u=u)["y"].value == y
        assert s1.step(dt, u=u)["y"].value == y


# ---------------------------------------------------------------------------------------------
# process.ipdt


@pytest.mark.parametrize(("dt", "theta"), [(0.1, 2.0), (0.3, 1.0), (0.25, 0.0)])
def test_ipdt_ramps_at_k_times_the_input_change(make: Make, dt: float, theta: float) -> None:
    """dy/dt = K·(u(t-θ) - u0): from y0 = 10 with u0 = 40 (balance), u = 50 gives
    y = 10 + K·10·(t - θ) for t ≥ θ; at u = u0 the level stays put."""
    # spec 3.2 (integrator Kv = 0.1, L = 2), spec 6.3
    proc = make("process.ipdt", gain=0.1, dead_time=theta, u0=40.0, y0=10.0)
    flat, _ = run(proc, [dt] * 20, [40.0] * 20)
    assert flat == [10.0] * 20
    ys, _ = run(proc, [dt] * 100, [50.0] * 100)  # t counted from the step
    for t, y in zip(scan_ends([dt] * 100), ys, strict=True):
        assert y == pytest.approx(10.0 + 0.1 * 10.0 * max(0.0, t - theta), abs=1e-11)


def test_ipdt_with_varying_dt_and_a_non_multiple_dead_time(make: Make) -> None:
    """The ramp is exact for any scan times: y = K·Δu·(t - θ) for t ≥ θ."""
    # spec 6.3, issue 5 (replay may vary dt)
    rng = np.random.default_rng(8)
    dts = list(rng.uniform(0.02, 0.3, size=200))
    proc = make("process.ipdt", gain=-0.25, dead_time=1.234)
    ys, _ = run(proc, dts, [3.0] * len(dts))
    for t, y in zip(scan_ends(dts), ys, strict=True):
        assert y == pytest.approx(-0.25 * 3.0 * max(0.0, t - 1.234), abs=1e-12)


# ---------------------------------------------------------------------------------------------
# Starting at a chosen steady state


def test_blocks_start_and_stay_at_their_steady_state(make: Make) -> None:
    """u0 fills the line and the u input; y0 defaults to the plant's steady state. Left
    alone (u not given) or fed u0, every kind stays at y0."""
    # spec 2.8 ("start at steady state (all at 50 %)"), issue 5
    cases: list[tuple[str, dict[str, Any], float]] = [
        ("process.fopdt", {"gain": 2.0, "u0": 50.0}, 100.0),
        ("process.sopdt", {"gain": 0.5, "u0": 50.0}, 25.0),
        ("process.sopdt", {"gain": 0.5, "u0": 50.0, "y0": 80.0}, 80.0),
        ("process.ipdt", {"u0": 50.0, "y0": 30.0}, 30.0),
        ("process.ipdt", {"u0": 50.0}, 0.0),
        ("process.tf", {"num": "3", "den": "4, 2, 1", "u0": 50.0, "sample_time": 0.1,
                        "dead_time": 0.3}, 150.0),
        ("process.tf", {"num": "1, 0.5", "den": "1, -0.5", "domain": "z", "u0": 50.0,
                        "sample_time": 0.1}, 150.0),  # G(1) = 1.5/0.5 = 3
        ("process.tf", {"num": "0.1", "den": "1, 0", "u0": 50.0, "sample_time": 0.1}, 0.0),
    ]
    for kind, params, y0 in cases:
        proc = make(kind, **params)
        assert proc.outputs()["y"] == (y0, GOOD)
        assert proc.u[0] == 50.0
        for _ in range(30):
            assert proc.step(0.1)["y"].value == pytest.approx(y0, abs=1e-12)
        for _ in range(30):
            assert proc.step(0.1, u=50.0)["y"].value == pytest.approx(y0, abs=1e-12)


def test_a_step_from_the_steady_state_adds_the_step_response(make: Make) -> None:
    """From (u0, y0) = (50, 80) with an output bias, u = 60 gives 80 + K·10·(step response)."""
    # spec 2.8 (start at steady state, then a step), spec 6.3
    proc = make("process.sopdt", gain=0.5, time_constant_1=10.0, time_constant_2=2.0,
                dead_time=2.0, u0=50.0, y0=80.0)
    ys, _ = run(proc, [0.2] * 200, [60.0] * 200)
    for t, y in zip(scan_ends([0.2] * 200), ys, strict=True):
        assert y == pytest.approx(80.0 + sopdt_step(t, 5.0, 10.0, 2.0, 2.0), abs=1e-12)


# ---------------------------------------------------------------------------------------------
# process.tf


def test_first_order_tf_equals_fopdt(make: Make) -> None:
    """G(s) = 2/(10s + 1), discretised by scipy, equals process.fopdt (θ = 0) and, with
    θ = 0.35 s (3.5 scans: the modified z-transform), process.fopdt with that θ."""
    # issue 5 (transfer-function equivalence), spec 6.3
    rng = np.random.default_rng(21)
    inputs = [float(v) for v in rng.uniform(-20.0, 120.0, size=400)]
    for theta in (0.0, 0.35, 0.4):
        tf = make("process.tf", num="2", den="10, 1", sample_time=0.1, dead_time=theta)
        fo = make("process.fopdt", gain=2.0, time_constant=10.0, dead_time=theta)
        a, _ = run(tf, [0.1] * 400, inputs)
        b, _ = run(fo, [0.1] * 400, inputs)
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12)


def test_second_order_tf_equals_sopdt_and_integrator_tf_equals_ipdt(make: Make) -> None:
    """K/((T1 s + 1)(T2 s + 1)) = K/(T1T2 s² + (T1 + T2) s + 1) and 0.1/s."""
    # issue 5 (transfer-function equivalence), spec 6.3
    rng = np.random.default_rng(22)
    inputs = [float(v) for v in rng.uniform(0.0, 100.0, size=300)]
    tf2 = make("process.tf", num="1.5", den="30, 13, 1", sample_time=0.2, dead_time=0.5)
    so = make("process.sopdt", gain=1.5, time_constant_1=10.0, time_constant_2=3.0,
              dead_time=0.5)
    np.testing.assert_allclose(run(tf2, [0.2] * 300, inputs)[0],
                               run(so, [0.2] * 300, inputs)[0], rtol=1e-10, atol=1e-10)
    tfi = make("process.tf", num="0.1", den="1, 0", sample_time=0.2, dead_time=2.0,
               u0=50.0, y0=5.0)
    ip = make("process.ipdt", gain=0.1, dead_time=2.0, u0=50.0, y0=5.0)
    np.testing.assert_allclose(run(tfi, [0.2] * 300, inputs)[0],
                               run(ip, [0.2] * 300, inputs)[0], rtol=1e-10, atol=1e-10)


def test_underdamped_tf_step_response_is_the_closed_form(make: Make) -> None:
    """ωn² /(s² + 2ζωn s + ωn²) written as den 1/ωn², 2ζ/ωn, 1: unit step response
    1 - e^(-ζωn s)·(cos ωd s + ζ/√(1-ζ²)·sin ωd s), ωd = ωn√(1-ζ²), s = t - θ."""
    # module docstring (underdamped plants as process.tf), spec 6.3
    wn, zeta, theta = 0.8, 0.3, 0.6
    wd = wn * math.sqrt(1.0 - zeta * zeta)
    tf = make("process.tf", num="1", den=[1.0 / wn**2, 2.0 * zeta / wn, 1.0], sample_time=0.1,
              dead_time=theta)
    ys, _ = run(tf, [0.1] * 300, [1.0] * 300)
    for t, y in zip(scan_ends([0.1] * 300), ys, strict=True):
        s = t - theta
        exact = 0.0 if s <= 0 else 1.0 - math.exp(-zeta * wn * s) * (
            math.cos(wd * s) + zeta / math.sqrt(1.0 - zeta * zeta) * math.sin(wd * s))
        assert y == pytest.approx(exact, abs=1e-12)


def test_tf_with_zeros_agrees_with_scipy_lsim(make: Make) -> None:
    """A third-order G(s) with zeros and a feed-through term D = 0.25 against
    scipy.signal.lsim with a zero-order-hold input (an independent simulation): lsim's input
    on [t_k, t_{k+1}) is the block's input of scan k + 1, and lsim's y[k] = Cx + D·U[k] takes
    the input that starts at t_k where the block's y_k = y(t_k) takes the one that ended
    there (the held input u_k): y_k = lsim y[k] - D·U[k] + D·u_k."""
    # spec 6.3, issue 5 (exact ZOH via scipy)
    from scipy import signal

    num, den = [0.5, 2.0, 1.0, 0.3], [2.0, 5.0, 4.0, 1.0]
    rng = np.random.default_rng(4)
    u = [float(v) for v in rng.uniform(-5.0, 5.0, size=200)]
    tf = make("process.tf", num=num, den=den, sample_time=0.05)
    ys, _ = run(tf, [0.05] * 200, u)
    t = np.arange(201) * 0.05
    _, y_ref, _ = signal.lsim((num, den), U=[*u, u[-1]], T=t, interp=False)
    d = 0.5 / 2.0
    expected = y_ref[1:] - d * np.array([*u[1:], u[-1]]) + d * np.array(u)
    np.testing.assert_allclose(ys, expected, rtol=1e-9, atol=1e-9)


def test_discrete_tf_is_the_literal_difference_equation(make: Make) -> None:
    """G(z) = 0.5 z⁻¹/(1 - 0.8 z⁻¹): y_k = 0.8 y_{k-1} + 0.5 u_{k-1}; the biproper
    (1 + 0.5 z⁻¹)/(1 - 0.2 z⁻¹): y_k = 0.2 y_{k-1} + u_k + 0.5 u_{k-1}; a 3-sample dead time
    shifts the input by 3 scans."""
    # issue 5 (a discrete TF), module docstring (z domain)
    rng = np.random.default_rng(9)
    u = [float(v) for v in rng.uniform(-10.0, 10.0, size=100)]

    def recur(b0: float, b1: float, a1: float, shift: int) -> list[float]:
        w = [0.0] * shift + u
        out, y_prev, w_prev = [], 0.0, 0.0
        for k in range(len(u)):
            y = -a1 * y_prev + b0 * w[k] + b1 * w_prev
            out.append(y)
            y_prev, w_prev = y, w[k]
        return out

    g1 = make("process.tf", num="0.5", den="1, -0.8", domain="z", sample_time=0.5)
    np.testing.assert_allclose(run(g1, [0.5] * 100, u)[0], recur(0.0, 0.5, -0.8, 0),
                               rtol=1e-12, atol=1e-12)
    g2 = make("process.tf", num="1 0.5", den="[1, -0.2]", domain="z", sample_time=0.5)
    np.testing.assert_allclose(run(g2, [0.5] * 100, u)[0], recur(1.0, 0.5, -0.2, 0),
                               rtol=1e-12, atol=1e-12)
    g3 = make("process.tf", num="1, 0.5", den="1, -0.2", domain="z", sample_time=0.5,
              dead_time=1.5)
    np.testing.assert_allclose(run(g3, [0.5] * 100, u)[0], recur(1.0, 0.5, -0.2, 3),
                               rtol=1e-12, atol=1e-12)


def test_discrete_zoh_equivalent_matches_fopdt(make: Make) -> None:
    """With a = e^(-dt/T): (1-a)·z/(z - a) is the block's fopdt (θ = 0); the textbook ZOH
    equivalent (1-a)/(z - a) carries one sample of delay: fopdt with θ = dt."""
    # issue 5 (a discrete TF), module docstring (z domain)
    dt, tau, k = 0.5, 4.0, 3.0
    a = math.exp(-dt / tau)
    rng = np.random.default_rng(12)
    u = [float(v) for v in rng.uniform(0.0, 10.0, size=100)]
    z0 = make("process.tf", num=[k * (1 - a), 0.0], den=[1.0, -a], domain="z", sample_time=dt)
    z1 = make("process.tf", num=[k * (1 - a)], den=[1.0, -a], domain="z", sample_time=dt)
    f0 = make("process.fopdt", gain=k, time_constant=tau, dead_time=0.0)
    f1 = make("process.fopdt", gain=k, time_constant=tau, dead_time=dt)
    np.testing.assert_allclose(run(z0, [dt] * 100, u)[0], run(f0, [dt] * 100, u)[0],
                               rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(run(z1, [dt] * 100, u)[0], run(f1, [dt] * 100, u)[0],
                               rtol=1e-12, atol=1e-12)


def test_tf_pure_gain_and_leading_zeros(make: Make) -> None:
    """num '0, 0, 2' is 2; den '4' makes a pure gain 0.5·num."""
    # module docstring (coefficient lists)
    g = make("process.tf", num="2", den="4", sample_time=1.0, dead_time=2.0)
    assert run(g, [1.0] * 4, [10.0, 20.0, 30.0, 40.0])[0] == [0.0, 0.0, 5.0, 10.0]
    a = make("process.tf", num="0, 0, 2", den="10, 1", sample_time=0.1)
    b = make("process.tf", num="2", den="10, 1", sample_time=0.1)
    assert run(a, [0.1] * 20, [1.0] * 20) == run(b, [0.1] * 20, [1.0] * 20)


def test_tf_set_params_keeps_the_state_and_its_layout(make: Make) -> None:
    """set_params re-discretises and keeps ξ (the deviation from the steady state at u0):
    with y0 given, the block continues exactly as a fresh block with the new coefficients
    would from that state; with y0 left at its default G(0)·u0, the output moves at once to
    the new G(0)·u0 (4 = 4·1). max_order sizes the state and cannot change."""
    # module docstring (set_params)
    tf = make("process.tf", num="2", den="10, 1", sample_time=0.5, u0=1.0, y0=2.0)
    ref = make("process.tf", num="4", den="10, 1", sample_time=0.5, u0=1.0, y0=2.0)
    tf.set_params(num="4")
    for u in (1.0, 3.0, -2.0, 5.0):
        assert tf.step(0.5, u=u)["y"].value == pytest.approx(ref.step(0.5, u=u)["y"].value,
                                                             abs=1e-12)
    free = make("process.tf", num="2", den="10, 1", sample_time=0.5, u0=1.0)
    assert free.step(0.5)["y"].value == pytest.approx(2.0, abs=1e-15)
    free.set_params(num="4")
    assert free.step(0.5)["y"].value == pytest.approx(4.0, abs=1e-15)
    with pytest.raises(InputError, match=r"max_order sizes the block's state"):
        tf.set_params(max_order=3)


def test_closed_loop_in_a_module_fopdt_equals_tf(make: Make) -> None:
    """A PI loop (module: the kernels run directly, fixed dt) on fopdt and on the same plant
    as process.tf, θ = 2.1 s = 10.5 scans: the same trajectory."""
    # spec 2.8 (PI on FOPDT K = 1, T = 10, L ≈ 2 started at steady state), spec 6.3
    def loop(plant: Block) -> np.ndarray:
        pid = make("pid", k=1.0, ti=10.0, bias=50.0)
        mod = Module({"pid": pid, "proc": plant}, {"proc.u": "pid.out", "pid.pv": "proc.y"},
                     inputs={"pid": {"sp": 51.0}})
        return mod.run(100.0, 0.2)["proc.y"]

    a = loop(make("process.fopdt", dead_time=2.1, u0=50.0))
    b = loop(make("process.tf", num="1", den="10, 1", sample_time=0.2, dead_time=2.1,
                  u0=50.0))
    assert a[0] == 50.0 and a[-1] == pytest.approx(51.0, abs=0.05)
    np.testing.assert_allclose(a, b, rtol=1e-11, atol=1e-11)


def test_tf_runs_only_at_its_sample_time(make: Make, tmp_path: Path) -> None:
    """step() at another dt is an InputError naming sample_time; so is a replay row with
    another dt (Block.check_dt, before any row runs); the kernel itself, reached some other
    way, skips such scans with status Bad: configuration error."""
    # module docstring (process.tf and dt)
    tf = make("process.tf", num="1", den="10, 1", sample_time=0.1)
    assert tf.step(0.1 * (1 + 1e-9), u=1.0)["y"].status == GOOD  # within the tolerance
    with pytest.raises(InputError, match=r"dt = 0\.2 s is not allowed.*sample_time = 0\.1"):
        tf.step(0.2, u=1.0)
    path = write_csv(tmp_path / "in.csv", ["dt", "u"], [[0.1, 1.0], [0.2, 1.0], [0.1, 1.0]])
    y_first = 1.0 - math.exp(-0.01)
    result = CliRunner().invoke(app, ["replay", "process.tf", str(path), "-p", "num=1",
                                      "-p", "den=10, 1", "-p", "sample_time=0.1"])
    assert result.exit_code == 2
    assert "sample_time" in result.output
    direct = make("process.tf", num="1", den="10, 1", sample_time=0.1)
    kernel = type(direct).kernel
    outs = []
    for dt in (0.1, 0.2, 0.1):
        direct.u[0] = 1.0
        kernel(dt, direct.p, direct.x, direct.u, direct.us, direct.y, direct.ys)
        outs.append((float(direct.y[0]), int(direct.ys[0])))
    assert outs[0][0] == pytest.approx(y_first, abs=1e-12)
    assert outs[1] == (pytest.approx(y_first, abs=1e-12), BAD_CONFIG)  # held
    assert outs[2] == (pytest.approx(1.0 - math.exp(-0.02), abs=1e-12), GOOD)


# ---------------------------------------------------------------------------------------------
# Delay capacity


def test_delay_capacity_error_names_the_parameter(make: Make) -> None:
    """θ = 2 s needs 10 scans at 0.2 s (fits a capacity of 10, rounding included) and 20
    at 0.1 s (does not)."""
    # issue 5 (an error naming the capacity)
    ok = make("process.fopdt", dead_time=2.0, delay_capacity=10, time_constant=0.0)
    ys, _ = run(ok, [0.2] * 30, [float(i) for i in range(30)])
    assert ys == [0.0] * 10 + [float(i) for i in range(20)]
    bad = make("process.fopdt", dead_time=2.0, delay_capacity=10)
    with pytest.raises(InputError, match=r"needs 20 scans.*delay_capacity = 10.*≥ 20"):
        bad.step(0.1, u=1.0)
    with pytest.raises(ParameterError, match=r"'delay_capacity' = 0 is out of range"):
        make("process.fopdt", delay_capacity=0)
    with pytest.raises(ParameterError, match=r"'delay_capacity' = 3 is too small.*≥ 4"):
        make("process.tf", sample_time=0.5, dead_time=1.75, delay_capacity=3)
    make("process.tf", sample_time=0.5, dead_time=1.5, delay_capacity=3)  # exactly 3 scans


def test_delay_capacity_overflow_in_a_module_is_an_error(make: Make) -> None:
    """A module checks every block's scan time before it runs (Block.check_dt): a dead time
    longer than the kept history is an error naming delay_capacity."""
    # module docstring (delay_capacity)
    proc = make("process.fopdt", dead_time=2.0, delay_capacity=10, time_constant=0.0,
                u0=5.0)
    mod = Module({"proc": proc}, inputs={"proc": {"u": 7.0}})
    with pytest.raises(InputError, match="delay_capacity"):
        mod.run(2.0, 0.1)


# ---------------------------------------------------------------------------------------------
# Bad input


@pytest.mark.parametrize("kind", ["process.fopdt", "process.sopdt", "process.ipdt",
                                  "process.tf"])
def test_bad_input_holds_the_last_input_and_marks_y_bad(make: Make, kind: str) -> None:
    """NaN, ±inf and a Bad status: y is Bad (0) and the plant runs on the last good input,
    as a run fed that input is; Uncertain inputs are used and y stays Good."""
    # issue 5 ("hold the last input and mark y Bad")
    extra = {"sample_time": 0.1, "dead_time": 0.3} if kind == "process.tf" else {}
    a = make(kind, **extra)
    b = make(kind, **extra)
    bad_inputs: list[Any] = [NAN, INF, -INF, (60.0, BAD_NS), (70.0, 0x1C)]
    for _ in range(10):
        a.step(0.1, u=40.0)
        b.step(0.1, u=40.0)
    for bad in bad_inputs:
        ya = a.step(0.1, u=bad)["y"]
        yb = b.step(0.1, u=40.0)["y"]
        assert ya.status == BAD_NS
        assert ya.value == yb.value
    ya = a.step(0.1, u=(45.0, UNCERTAIN))["y"]
    yb = b.step(0.1, u=45.0)["y"]
    assert ya == yb and ya.status == GOOD


@pytest.mark.parametrize("kind", ["process.fopdt", "process.tf"])
def test_bad_input_freeze_skips_the_scan(make: Make, kind: str) -> None:
    """bad_input = freeze (process.first_order's way): y holds, the line does not move, and
    afterwards the block continues as if the bad scans had not happened."""
    # module docstring (bad_input option)
    extra = {"sample_time": 0.1} if kind == "process.tf" else {}
    a = make(kind, bad_input="freeze", dead_time=0.3, **extra)
    b = make(kind, bad_input="freeze", dead_time=0.3, **extra)
    rng = np.random.default_rng(1)
    for i in range(40):
        u = float(rng.uniform(0.0, 100.0))
        ya = a.step(0.1, u=u)["y"]
        assert ya == b.step(0.1, u=u)["y"]
        if i % 7 == 3:
            held = a.step(0.1, u=NAN)["y"]
            assert held == (ya.value, BAD_NS)


# ---------------------------------------------------------------------------------------------
# Parameters


@pytest.mark.parametrize(("kind", "params", "pattern"), [
    ("process.fopdt", {"time_constant": -1.0}, r"'time_constant' = -1 is out of range"),
    ("process.fopdt", {"dead_time": -0.5}, r"'dead_time' = -0.5 is out of range"),
    ("process.fopdt", {"bad_input": "ignore"}, r"'bad_input' = 'ignore' is not allowed"),
    ("process.sopdt", {"time_constant_2": math.nan}, r"'time_constant_2' = nan"),
    ("process.ipdt", {"gain": "fast"}, r"'gain' = 'fast' must be a number"),
    ("process.tf", {}, r"'sample_time' is required"),
    ("process.tf", {"sample_time": 0.0}, r"'sample_time' = 0 is out of range"),
    ("process.tf", {"sample_time": 1, "num": "1, x"}, r"'num' = '1, x' is not allowed"),
    ("process.tf", {"sample_time": 1, "den": ""}, r"'den' = '' is not allowed"),
    ("process.tf", {"sample_time": 1, "den": "0, 1"}, r"'den'.*leading coefficient"),
    ("process.tf", {"sample_time": 1, "num": "1, 2, 3"}, r"must be proper"),
    ("process.tf", {"sample_time": 1, "num": "1, inf"}, r"'num' = '1, inf'"),
    ("process.tf", {"sample_time": 1, "den": [1] * 10}, r"'max_order' = 8 is too small.*9"),
    ("process.tf", {"sample_time": 1, "domain": "w"}, r"'domain' = 'w' is not allowed"),
    ("process.tf", {"sample_time": 1, "domain": "z", "dead_time": 2.5},
     r"'dead_time' = 2.5 s is not allowed.*whole number"),
])
def test_bad_parameters_name_the_parameter(kind: str, params: dict[str, Any],
                                           pattern: str) -> None:
    # issue 5 / project rule: ParameterError naming parameter, value and range
    with pytest.raises(ParameterError, match=pattern):
        loopworks.create_block(kind, **params)


def test_coefficient_lists_as_text_or_lists_give_the_same_block() -> None:
    """num/den as text ('1, 2', '1 2', '[1, 2]') or as a list; the block remembers text."""
    # module docstring (coefficient lists)
    a = loopworks.create_block("process.tf", num=[1, 2], den=(1, 3, 2), sample_time=0.1)
    b = loopworks.create_block("process.tf", num="[1 2]", den="1; 3; 2", sample_time=0.1)
    np.testing.assert_array_equal(a.p, b.p)
    assert a.given["num"] == "1.0, 2.0"
    assert json.loads(json.dumps(a.state_dict()))["params"]["den"] == "1.0, 3.0, 2.0"


# ---------------------------------------------------------------------------------------------
# Replay, save/resume, compiled = interpreted


def test_replay_with_a_t_column_is_exact(tmp_path: Path) -> None:
    """loopworks replay process.fopdt on uneven times: y = closed form at each row's t (the
    first row's scan takes its dt from the second row, so the input starts at t0 - dt1)."""
    # issue 5 (replay), spec 6.3
    ts = [0.0, 0.3, 0.5, 1.1, 1.2, 2.0, 2.35, 3.0, 4.5, 6.0]
    path = write_csv(tmp_path / "in.csv", ["t", "u"], [[t, 2.0] for t in ts])
    result = CliRunner().invoke(app, ["replay", "process.fopdt", str(path), "-p", "gain=1.5",
                                      "-p", "time_constant=2", "-p", "dead_time=0.7"])
    assert result.exit_code == 0, result.output
    rows = list(csv.reader(io.StringIO(result.stdout)))
    assert rows[0] == ["t", "y", "y.ST"]
    start = -0.3  # the first scan covers (-0.3, 0]
    for t, row in zip(ts, rows[1:], strict=True):
        assert float(row[0]) == t
        assert float(row[1]) == pytest.approx(fopdt_step(t - start, 3.0, 2.0, 0.7), abs=1e-12)


def test_replay_worked_example_of_the_docs(tmp_path: Path) -> None:
    """The ipdt replay example of the reference page: y = 0, 0, 0.05, 0.1, 0.15."""
    # module docstring (worked example), spec 3.2 (integrator)
    path = write_csv(tmp_path / "ramp.csv", ["t", "u"],
                     [[0, 1], [0.5, 1], [1.0, 1], [1.5, 1], [2.0, 1]])
    result = CliRunner().invoke(app, ["replay", "process.ipdt", str(path), "-p", "gain=0.1",
                                      "-p", "dead_time=1"])
    assert result.exit_code == 0, result.output
    ys = [float(r[1]) for r in list(csv.reader(io.StringIO(result.stdout)))[1:]]
    # the input starts at t = -0.5 and reaches the integrator at t = 0.5: y = 0.1·(t - 0.5)
    assert ys == pytest.approx([0.0, 0.0, 0.05, 0.1, 0.15], abs=1e-15)


def test_worked_python_example_of_the_docs(make: Make) -> None:
    # module docstring (worked example), spec 2.8 plant
    p = make("process.fopdt", gain=1.0, time_constant=10.0, dead_time=2.0)
    ys = [p.step(0.5, u=1.0)["y"].value for _ in range(8)]
    assert ys == pytest.approx([0, 0, 0, 0, 0.0487706, 0.0951626, 0.139292, 0.181269],
                               abs=5e-7)
    tf = make("process.tf", num="1", den="10, 1", sample_time=0.5)
    assert tf.step(0.5, u=1.0)["y"].value == pytest.approx(1.0 - math.exp(-0.05), abs=1e-15)


VARIANT_SETS: dict[str, list[dict[str, Any]]] = {
    "process.fopdt": [{}, {"gain": -2.0, "time_constant": 0.0, "dead_time": 0.35, "u0": 10.0,
                           "bad_input": "freeze"},
                      {"time_constant": 3.0, "dead_time": 2.0, "delay_capacity": 3, "y0": 5.0}],
    "process.sopdt": [{}, {"time_constant_1": 4.0, "time_constant_2": 4.0, "dead_time": 0.0},
                      {"time_constant_1": 0.0, "time_constant_2": 1.5, "u0": 50.0, "y0": 20.0,
                       "bad_input": "freeze"}],
    "process.ipdt": [{}, {"gain": -0.05, "dead_time": 0.0, "u0": 50.0, "y0": 10.0},
                     {"dead_time": 5.0, "delay_capacity": 4, "bad_input": "freeze"}],
    "process.tf": [{"sample_time": 0.1}, {"num": "1, 0.5, 2", "den": "2, 3, 1.5",
                                          "sample_time": 0.25, "dead_time": 0.6, "u0": 20.0},
                   {"num": "0.2, 0.1", "den": "1, -1.2, 0.5", "domain": "z",
                    "sample_time": 0.5, "dead_time": 1.0, "bad_input": "freeze"},
                   {"num": "0.1", "den": "1, 0", "sample_time": 1.0, "max_order": 2,
                    "delay_capacity": 3}],
}


@pytest.mark.parametrize("kind", sorted(VARIANT_SETS))
def test_resume_from_saved_state_equals_one_run(kind: str) -> None:
    """Save mid-run through JSON, restore into a new block, continue: identical outputs."""
    # issue 5 (save/resume)
    for params in VARIANT_SETS[kind]:
        rng = np.random.default_rng(77)
        ts = params.get("sample_time")
        cap = params.get("delay_capacity", 1000)
        theta = params.get("dead_time", 2.0 if kind != "process.tf" else 0.0)
        lo = max(0.05, theta / cap * 1.01)
        dts = [float(ts) if ts is not None else float(rng.uniform(lo, lo + 1.0))
               for _ in range(300)]
        us: list[Any] = [float(v) for v in rng.uniform(0.0, 100.0, size=300)]
        us[50] = NAN
        us[220] = (3.0, BAD_NS)
        whole = loopworks.create_block(kind, **params)
        first = loopworks.create_block(kind, **params)
        expected = run(whole, dts, us)
        run(first, dts[:150], us[:150])
        saved = json.loads(json.dumps(first.state_dict()))
        resumed = loopworks.create_block(saved["kind"], **saved["params"])
        resumed.load_state(saved)
        got = run(resumed, dts[150:], us[150:])
        assert got[0] == expected[0][150:]
        assert got[1] == expected[1][150:]


@pytest.mark.parametrize("kind", sorted(VARIANT_SETS))
def test_the_line_is_one_state_entry(kind: str) -> None:
    """The delay line (and process.tf's ξ) is one list in the state, sized by delay_capacity
    (and max_order): the state of a run round-trips into a fresh block through JSON, and a
    state saved with the earlier separate names (line_head, line_u_0, ...) is refused with an
    InputError that names the state's entries."""
    for params in VARIANT_SETS[kind]:
        block = loopworks.create_block(kind, **params)
        cap = int(block.params["delay_capacity"])
        name = "xi_line" if kind == "process.tf" else "line"
        extra = 2 * int(block.params["max_order"]) if kind == "process.tf" else 0
        ts = params.get("sample_time", 2.0)  # within every variant's delay_capacity
        run(block, [float(ts)] * 7, [float(k) for k in range(7)])
        state = block.state()
        assert list(state)[-1] == name and len(state[name]) == extra + 4 + 2 * cap
        saved = json.loads(json.dumps(block.state_dict()))
        fresh = loopworks.create_block(kind, **params)
        fresh.load_state(saved)
        assert np.array_equal(fresh.x, block.x)
        line = state[name][extra:]
        old = {k: v for k, v in state.items() if k != name}
        old.update(zip(("line_head", "line_count", "line_run_dt", "line_run_len"), line,
                       strict=False))
        old.update({f"line_u_{i}": line[4 + i] for i in range(cap)})
        old.update({f"line_dt_{i}": line[4 + cap + i] for i in range(cap)})
        with pytest.raises(InputError, match=f"line_u_0.*one entry.*u_held, {name}"):
            fresh.load_state({**saved, "state": old})
        assert np.array_equal(fresh.x, block.x)  # the refused state changed nothing


# ---------------------------------------------------------------------------------------------
# The relay oracles of spec 3.2 on the reference plants


def relay_cycle(proc: Block, d: float, eps: float, dt: float, duration: float
                ) -> tuple[float, float, float]:
    """A symmetric relay ±d with hysteresis ε around SP = 0 (e = -PV): returns the PV
    amplitude a (half peak-to-peak), the period P and the mean time from a switch to the
    next PV extremum, over the second half of the run."""
    n = round(duration / dt)
    u = d
    y = 0.0
    ys = np.empty(n)
    switches: list[int] = []
    for k in range(n):
        e = -y
        if e > eps and u < 0.0:
            u = d
            switches.append(k)
        elif e < -eps and u > 0.0:
            u = -d
            switches.append(k)
        y = proc.step(dt, u=u)["y"].value
        ys[k] = y
    half = n // 2
    tail = ys[half:]
    amplitude = (tail.max() - tail.min()) / 2.0
    late = [s for s in switches if s > half]
    period = 2.0 * float(np.mean(np.diff(late))) * dt
    lags = []
    for s0, s1 in itertools.pairwise(late):
        seg = ys[s0:s1]
        k_ext = int(np.argmax(seg) if ys[s0] > 0 else np.argmin(seg))
        lags.append(k_ext * dt)
    return float(amplitude), period, float(np.mean(lags))


@pytest.mark.parametrize(("kind", "params", "eps", "a", "period"), [
    ("process.fopdt", {"gain": 1.0, "time_constant": 10.0}, 0.0, 0.18127, 7.332),
    ("process.fopdt", {"gain": 1.0, "time_constant": 10.0}, 0.05, 0.22221, 9.039),
    ("process.fopdt", {"gain": 1.0, "time_constant": 10.0}, 0.10, 0.26314, 10.779),
    ("process.ipdt", {"gain": 0.1}, 0.0, 0.2000, 8.000),
    ("process.ipdt", {"gain": 0.1}, 0.05, 0.2500, 10.000),
])
def test_relay_limit_cycle_matches_spec_3_2(kind: str, params: dict[str, Any], eps: float,
                                            a: float, period: float) -> None:
    """spec 3.2 table (fine-step simulation at dt = 1 ms agrees to 4-5 digits): a and P of
    the relay cycle on FOPDT K=1, T=10, L=2 and on the integrator Kv=0.1, L=2; and spec 3.3:
    the PV keeps moving for L after each switch. The relay acts one scan after the PV
    crosses, which costs about dt here."""
    # spec 3.2, spec 3.3 (switch to extremum = L)
    proc = loopworks.create_block(kind, dead_time=2.0, delay_capacity=2000, **params)
    amp, per, lag = relay_cycle(proc, 1.0, eps, 0.001, 80.0)
    assert amp == pytest.approx(a, abs=1e-4)
    assert per == pytest.approx(period, abs=0.005)
    assert lag == pytest.approx(2.0, abs=0.002)


# ---------------------------------------------------------------------------------------------
# Issue 11 point 1: values the float arithmetic cannot carry


@pytest.mark.parametrize("kind", ["process.fopdt", "process.sopdt", "process.ipdt",
                                  "process.tf"])
@pytest.mark.parametrize("huge", [1e308, -1e308, 3.5e38 * 1e120])
def test_input_beyond_the_model_range_is_bad_and_leaves_no_trace(
        make: Make, kind: str, huge: float) -> None:
    """A Good-status u whose contribution K·(u - u0) exceeds MODEL_RANGE = 1e150 (module
    docstring, Bad input) is Bad input: y Bad, the plant runs on the last good input, and
    once the inputs are good again the output is exactly the undisturbed run's. Before, 1e308
    entered the delay line and overflowed the plant θ later (ipdt then stayed Bad for good)."""
    extra = {"sample_time": 0.1} if kind == "process.tf" else {}
    a = make(kind, dead_time=0.3, **extra)
    b = make(kind, dead_time=0.3, **extra)
    for k in range(60):
        u_b = 40.0 + k
        u_a: Any = (huge, GOOD) if 10 <= k < 13 else u_b
        if 10 <= k < 13:
            u_b = 49.0  # the last good input, which the plant holds
        ya, yb = a.step(0.1, u=u_a)["y"], b.step(0.1, u=u_b)["y"]
        assert ya.value == yb.value
        assert ya.status == (BAD_NS if 10 <= k < 13 else GOOD)
        assert all(math.isfinite(v) for v in a.x)


def test_input_at_the_model_range_is_used(make: Make) -> None:
    """The boundary: |K·(u - u0)| = 1e150 is used (a pure gain passes it), beyond is Bad."""
    p = make("process.fopdt", time_constant=0.0, dead_time=0.0, gain=2.0, u0=1.0)
    assert p.step(0.1, u=1.0 + 0.5e150)["y"] == (pytest.approx(1e150, rel=1e-15), GOOD)
    assert p.step(0.1, u=1.0 + 0.6e150)["y"].status == BAD_NS


def test_first_order_refuses_an_input_beyond_the_model_range(make: Make) -> None:
    """process.first_order: |K·u| > 1e150 is Bad input and freezes the state (module
    docstring); 1e308 used to be taken as a Good input (y jumped to ~1e307, status Good)."""
    p = make("process.first_order", gain=2.0, time_constant=5.0)
    p.step(1.0, u=10.0)
    before = p.outputs()["y"].value
    assert p.step(1.0, u=1e308)["y"] == (before, BAD_NS)
    assert p.step(1.0, u=(1e200, 0x40))["y"] == (before, BAD_NS)
    assert p.step(1.0, u=10.0)["y"].status == GOOD


def test_an_integrator_past_the_float_range_skips_the_scan() -> None:
    """ipdt: K·(u - u0)·dt beyond ±1.8e308 (u = 1e150, dt = 1e160 s) would make y infinite:
    the bare kernel (no guard) skips the scan, y holds with status Bad, the state stays
    finite; a scan that fits runs again."""
    p = loopworks.create_block("process.ipdt", jit=False, gain=1.0, dead_time=0.0)
    kernel_scan(p, 1e160, u=1e150)
    assert unsound(p) == [] and (p.y[0], p.ys[0]) == (0.0, BAD_NS)
    kernel_scan(p, 1.0, u=1e150)
    assert (p.y[0], p.ys[0]) == (1e150, GOOD)


def test_an_unstable_transfer_function_that_runs_away_holds_bad() -> None:
    """G(z) = 1/(z - 2) doubles every sample: after about 1024 samples it would overflow. The
    bare kernel (no guard) skips such scans: y holds its last finite value, status Bad; no
    state is ever non-finite."""
    p = loopworks.create_block("process.tf", jit=False, num="1", den="1, -2", domain="z",
                               sample_time=1.0)
    statuses = []
    for _ in range(1100):
        kernel_scan(p, 1.0, u=1.0)
        assert unsound(p) == []
        statuses.append(int(p.ys[0]))
    first_bad = statuses.index(BAD_NS)
    assert 1000 < first_bad < 1030 and set(statuses[first_bad:]) == {BAD_NS}
    assert math.isfinite(p.y[0]) and p.y[0] > 1e307


@pytest.mark.parametrize("den", ["1, -1", "1, -1.3, 0.3", "1, -1.1, 0.1", "1, -1.9, 0.9"])
def test_a_z_domain_integrator_written_in_decimals_starts_at_zero(den: str) -> None:
    """process.tf page: y0 left out is G(1)·u0 (z), "0 if integrating". (z - 1)(z - 0.3)
    typed as 1, -1.3, 0.3 sums to -5.6e-17 in floats, not 0, and y0 came out as -9e16 with
    a Good status (found by an outside audit): D(1) within the rounding of its terms is a
    pole at z = 1. Held at u0, the plant stays at 0."""
    tf = loopworks.create_block("process.tf", num="0.5", den=den, domain="z",
                                sample_time=1.0, u0=10.0)
    for _ in range(5):
        out = tf.step(1.0, u=10.0)["y"]
        assert (out.value, out.status) == (0.0, 0x80)


def test_tf_messages_give_the_value_that_was_given() -> None:
    """"dt = 0.1 s is not allowed: ... runs at sample_time = 0.1 s" for a dt of 0.1000002, and
    "'dead_time' = 3 s ... must be a whole number of samples" for 3.0000001: the value
    shown was the allowed one (found by an outside audit)."""
    tf = loopworks.create_block("process.tf", num="1", den="10, 1", sample_time=0.1)
    with pytest.raises(InputError, match=r"dt = 0.1000002 s is not allowed.*"
                                       r"\(give sample_time = 0.1000002 "):
        tf.step(0.1000002, u=1.0)
    with pytest.raises(ParameterError, match=r"'dead_time' = 3.0000001 s"):
        loopworks.create_block("process.tf", num="1", den="1, -0.5", domain="z",
                               sample_time=1.0, dead_time=3.0000001)
