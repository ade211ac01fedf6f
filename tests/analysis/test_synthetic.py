"""The simulated-loop generator of the stiction detector's test set (issue 15).

Short runs (minutes of plant time), so the suite stays fast; the spec 5.1 loop runs its
4000 s at dt 0.05 s, as the spec did."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from loopworks.analysis.loopdata import read_csv
from loopworks.analysis.synthetic import (
    CONTROLLERS,
    KARNOPP_PARAMS,
    SimulatedLoop,
    _counts,
    karnopp_reversal_band,
    make_set,
    simc,
    simulate_loop,
    ultimate,
    write_csv,
)

SHORT = {"warmup": 300.0, "duration": 1500.0, "sample_period": 1.0}


def dominant_period(x: np.ndarray, dt: float) -> float:
    """The period of the largest FFT peak of x (mean removed), s."""
    spectrum = np.abs(np.fft.rfft(x - x.mean()))
    freqs = np.fft.rfftfreq(len(x), dt)
    k = int(np.argmax(spectrum[1:])) + 1
    return 1.0 / float(freqs[k])


def test_same_seed_same_data_other_seed_other_noise() -> None:
    kw = dict(valve="choudhury", s=2.0, j=0.5, noise=0.1, walk_std=0.03, **SHORT)
    a, b = simulate_loop(seed=5, **kw), simulate_loop(seed=5, **kw)  # type: ignore[arg-type]
    c = simulate_loop(seed=6, **kw)  # type: ignore[arg-type]
    for name in ("t", "sp", "pv", "op", "position"):
        assert np.array_equal(getattr(a.data, name), getattr(b.data, name)), name
    assert not np.array_equal(a.data.pv, c.data.pv)


def test_make_set_is_deterministic_and_labelled_by_its_valve() -> None:
    first, second = make_set(n=12, seed=3), make_set(n=12, seed=3)
    assert len(first) == 12
    for x, y in zip(first, second, strict=True):
        assert x.case == y.case and x.seed == y.seed
        assert np.array_equal(x.data.pv, y.data.pv)
    assert sum(loop.label == "stiction" for loop in first) == 6
    for loop in first:
        sticky = loop.valve in ("choudhury", "karnopp")
        assert loop.label == ("stiction" if sticky else "no_stiction"), loop.case
        if sticky:
            nominal = loop.s_nominal
            assert 0.5 <= nominal <= 5.0 and 0.0 <= loop.j <= nominal, loop.case
            # a Karnopp valve's S is the band it shows on reversal, S + J (see below)
            assert loop.s == (nominal + loop.j if loop.valve == "karnopp" else nominal)
        else:
            assert loop.s == loop.j == loop.s_nominal == 0.0
            assert loop.data.position is not None
            assert np.allclose(loop.data.position, loop.data.op, atol=1e-9), loop.case
        assert loop.loop_type in ("self-regulating", "integrating")
        assert loop.controller in CONTROLLERS
        assert 1000 <= len(loop.data) <= 3000


def test_composition_of_240() -> None:
    assert dict(_counts(240)) == {"choudhury": 80, "karnopp": 40, "clean": 40,
                                  "aggressive": 40, "external": 40}
    assert sum(c for _, c in _counts(7)) == 7


def test_sticky_valve_sticks_and_jumps_clean_valve_follows_op() -> None:
    kw = dict(noise=0.05, walk_std=0.03, seed=1, **SHORT)
    sticky = simulate_loop(valve="choudhury", s=3.0, j=1.0, **kw)  # type: ignore[arg-type]
    clean = simulate_loop(valve="linear", **kw)  # type: ignore[arg-type]
    assert sticky.label == "stiction" and (sticky.s, sticky.j) == (3.0, 1.0)
    assert clean.label == "no_stiction" and (clean.s, clean.j) == (0.0, 0.0)
    assert sticky.data.position is not None and clean.data.position is not None
    moves = np.abs(np.diff(sticky.data.position))
    assert np.mean(moves == 0.0) > 0.6  # stuck most of the time
    assert moves.max() >= 1.0  # a slip jump of about J
    assert np.array_equal(clean.data.position, clean.data.op)
    assert np.mean(np.diff(clean.data.position) == 0.0) < 0.05


def test_aggressive_tuning_oscillates_on_its_own() -> None:
    lt, k, tau, dead, noise = "self-regulating", 1.0, 20.0, 3.0, 0.05
    kc, ti = simc(lt, k, tau, dead)
    ku, pu = ultimate(lt, k, tau, dead, ti)
    kw = dict(loop_type=lt, valve="linear", gain=k, time_constant=tau, dead_time=dead, ti=ti,
              noise=noise, walk_std=0.03, seed=2, **SHORT)
    wild = simulate_loop(kc=ku / 1.1, **kw)  # type: ignore[arg-type]
    tame = simulate_loop(kc=kc, **kw)  # type: ignore[arg-type]
    half = len(wild.data) // 2
    # lightly damped: it rings at its ultimate period on the noise and the load, well above
    # the noise and the well-tuned loop's spread
    assert np.ptp(wild.data.pv[half:]) > 10.0 * noise
    assert np.std(wild.data.pv[half:]) > 1.3 * np.std(tame.data.pv[half:])
    assert dominant_period(wild.data.pv, wild.data.dt) == pytest.approx(pu, rel=0.15)


@pytest.mark.parametrize("loop_type, period", [("self-regulating", 150.0),
                                                ("integrating", 300.0)])
def test_external_disturbance_sets_the_pv_period(loop_type: str, period: float) -> None:
    loop = simulate_loop(loop_type=loop_type, gain=1.0 if loop_type == "self-regulating"
                         else 0.03, valve="linear", noise=0.1, sine_amplitude=5.0,
                         sine_period=period, seed=4, warmup=300.0, duration=3000.0,
                         sample_period=1.0)
    assert dominant_period(loop.data.pv, loop.data.dt) == pytest.approx(period, rel=0.05)


def test_spec_5_1_limit_cycle_period() -> None:
    """plant-and-tuning 5.1, first row: FOPDT K 1, T 10 s, L 2 s; PI Kc 1, Ti 10 s; S 3, J 1;
    no noise; dt 0.05 s; SP +1 % at 10 s; 4000 s, the second half: period 112 s."""
    loop = simulate_loop(valve="choudhury", s=3.0, j=1.0, noise=0.0, gain=1.0,
                         time_constant=10.0, dead_time=2.0, kc=1.0, ti=10.0, sp_step=1.0,
                         sp_step_time=10.0, dt=0.05, sample_period=0.05, warmup=2000.0,
                         duration=2000.0)
    op = loop.data.op - loop.data.op.mean()
    ups = np.flatnonzero((op[:-1] < 0.0) & (op[1:] >= 0.0))
    assert len(ups) >= 10
    period = float(np.diff(ups).mean()) * loop.data.dt
    assert period == pytest.approx(112.0, rel=0.10)
    assert np.all(loop.data.sp == 51.0)


def test_write_csv_round_trip(tmp_path: Path) -> None:
    loop: SimulatedLoop = simulate_loop(valve="choudhury", s=2.0, j=1.0, noise=0.1, seed=9,
                                        **SHORT)  # type: ignore[arg-type]
    path = tmp_path / "loop.csv"
    write_csv(loop, path)
    header = path.read_text(encoding="utf-8").splitlines()[0]
    assert header == "t,sp,pv,op,mode"
    back = read_csv(path)
    assert back.resampled == ""
    assert back.position is None and back.mode is not None
    for name in ("sp", "pv", "op", "mode"):
        assert np.array_equal(getattr(back, name), getattr(loop.data, name)), name
    assert np.allclose(back.t, loop.data.t, rtol=0.0, atol=1e-9)
    write_csv(loop, path, position=True)
    with_position = read_csv(path)
    assert with_position.position is not None and loop.data.position is not None
    assert np.array_equal(with_position.position, loop.data.position)
    assert math.isclose(back.dt, SHORT["sample_period"])


@pytest.mark.parametrize(("s", "j"), [(1.0, 0.5), (3.0, 0.0), (4.0, 3.0)])
def test_a_karnopp_valve_shows_s_plus_j_on_reversal(s: float, j: float) -> None:
    """The set's Karnopp valve, made from nominal S and J, driven by a slow triangle
    (0.01 %/s, as a loop's integral action drives it) waits for S + J of OP travel after each
    reversal (2·Fs/U with Fs = U·(S + J)/2, spec 1.1, the Stribeck creep of spec 1.6): the S
    the set records (karnopp_reversal_band), not the nominal S."""
    from loopworks import create_block
    from loopworks.plant.valve import resolution_deadband_from_sj

    resolution, deadband = resolution_deadband_from_sj(s, j)
    valve = create_block("valve.karnopp", resolution=resolution, deadband=deadband, y0=50.0,
                         **KARNOPP_PARAMS)
    ramp = np.linspace(45.0, 55.0, 2001)
    op = np.concatenate([ramp, ramp[::-1], ramp, ramp[::-1]])
    pos = np.array([valve.step(0.5, op=float(u))["position"].value for u in op])
    for k0 in (4002, 6003):  # the reversals at the bottom (45 %) and at the top (55 %)
        moved = np.flatnonzero(np.abs(pos[k0:] - pos[k0 - 1]) > 0.01)[0]
        travel = abs(op[k0 + moved] - op[k0 - 1])
        assert travel == pytest.approx(karnopp_reversal_band(s, j), abs=0.05)
        assert karnopp_reversal_band(s, j) == s + j
        if j > 0.0:
            assert travel > s + 0.4 * j  # distinguishable from the nominal S
