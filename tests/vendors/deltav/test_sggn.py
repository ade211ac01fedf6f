"""The DeltaV signal generator ``deltav.sggn`` (the compensator's SGGN1) against spec
vendor-blocks 6.5 (and 6.1 for the execution order in a module).

Expected values are the waveforms worked out by hand at known positions of the cycle; none is
pasted from a run of the block. Behaviour tests run with the compiled and the interpreted
kernel through the ``make`` fixture.
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
from loopworks.blocks.kernel import _marked_np
from loopworks.cli import app
from loopworks.errors import ParameterError
from loopworks.sim.scenario import parse_scenario
from tests.csvfiles import write_csv

NAN = math.nan
S = math.sqrt(0.5)  # sin(45°)

Make = Callable[..., Block]


@pytest.fixture(params=[True, False], ids=["compiled", "interpreted"])
def make(request: pytest.FixtureRequest) -> Make:
    """``make(**params)``: a deltav.sggn block, compiled or interpreted kernel."""
    jit = request.param

    def _make(**params: Any) -> Block:
        return loopworks.create_block("deltav.sggn", jit=jit, **params)

    return _make


def wave(block: Block, n: int, dt: float = 1.0, **inputs: Any) -> list[float]:
    return [float(block.step(dt, **inputs)["out"].value) for _ in range(n)]


# ----------------------------------------------------------------------------------------------
# Waveforms (spec 6.5: square default; sine and triangle alternatives)
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("dt", [1.0, 0.1, 0.5, 0.2])
def test_square_default_alternates_every_scan_starting_plus(make: Make, dt: float) -> None:
    """spec 6.5 [A]: square wave, "half-period = N scans (configurable, default 1 scan, i.e.
    alternating every scan)", starting with +, at any scan time (the default was a period of
    2 s: at dt 0.1 s it held +A for ten scans)."""
    b = make(amplitude=0.3)
    assert wave(b, 6, dt) == [0.3, -0.3, 0.3, -0.3, 0.3, -0.3]
    assert b.step(dt)["out"].status == 0x80
    b = make(amplitude=0.3, half_period_scans=3)
    assert wave(b, 600, dt) == [0.3 if (k // 3) % 2 == 0 else -0.3 for k in range(600)]


def test_a_period_in_seconds_or_in_scans_not_both() -> None:
    with pytest.raises(ParameterError, match=r"give 'period' .* or 'half_period_scans', not"):
        loopworks.create_block("deltav.sggn", period=2.0, half_period_scans=1)
    with pytest.raises(ParameterError, match="half_period_scans"):
        loopworks.create_block("deltav.sggn", half_period_scans=0)


@pytest.mark.parametrize("dt", [1.0, 0.1, 0.3, 0.7, 1.0 / 3.0, 0.01, 0.25])
def test_square_period_two_scans_alternates_every_scan_for_any_dt(make: Make, dt: float) -> None:
    """spec 6.5: period = 2·dt alternates every scan despite binary rounding of dt/period
    (edge tolerance); period = 6·dt alternates every 3 scans (+ + + - - -)."""
    b = make(amplitude=1.0, period=2 * dt)
    assert wave(b, 5000, dt) == [1.0 if k % 2 == 0 else -1.0 for k in range(5000)]
    b = make(amplitude=1.0, period=6 * dt)
    assert wave(b, 5000, dt) == [1.0 if (k // 3) % 2 == 0 else -1.0 for k in range(5000)]


def test_square_amplitude_period_and_bias(make: Make) -> None:
    """spec 6.5: period 4 s at dt 1 s: + + - - ...; bias 50 and amplitude 2: 52, 52, 48, 48."""
    b = make(amplitude=2.0, period=4.0, bias=50.0)
    assert wave(b, 8) == [52.0, 52.0, 48.0, 48.0, 52.0, 52.0, 48.0, 48.0]


def test_sine_at_eighths_of_the_period(make: Make) -> None:
    """sine: A·sin(2π·t/period), period 8 s, dt 1 s: 0, A·√½, A, A·√½, 0, -A·√½, -A, -A·√½."""
    b = make(waveform="sine", amplitude=2.0, period=8.0, bias=1.0)
    expected = [1.0 + 2.0 * v for v in (0.0, S, 1.0, S, 0.0, -S, -1.0, -S, 0.0)]
    assert wave(b, 9) == pytest.approx(expected, abs=1e-12)


def test_triangle_at_eighths_of_the_period(make: Make) -> None:
    """triangle: 0 rising to A at 1/4, -A at 3/4: 0, A/2, A, A/2, 0, -A/2, -A, -A/2, 0."""
    b = make(waveform="triangle", amplitude=4.0, period=8.0)
    assert wave(b, 9) == pytest.approx([0.0, 2.0, 4.0, 2.0, 0.0, -2.0, -4.0, -2.0, 0.0],
                                       abs=1e-12)


def test_phase_shifts_the_wave(make: Make) -> None:
    """phase (degrees, an advance): sine at 90° is a cosine; square at 180° starts with -;
    triangle at 90° starts at the peak."""
    b = make(waveform="sine", period=4.0, phase=90.0)
    assert wave(b, 5) == pytest.approx([1.0, 0.0, -1.0, 0.0, 1.0], abs=1e-12)
    b = make(amplitude=0.5, phase=180.0)
    assert wave(b, 4) == [-0.5, 0.5, -0.5, 0.5]
    b = make(waveform="triangle", period=4.0, phase=90.0)
    assert wave(b, 5) == pytest.approx([1.0, 0.0, -1.0, 0.0, 1.0], abs=1e-12)
    b = make(period=4.0, phase=90.0)  # square, a quarter period ahead: + - - + + - -
    assert wave(b, 7) == [1.0, -1.0, -1.0, 1.0, 1.0, -1.0, -1.0]


def test_position_follows_elapsed_time_with_variable_dt(make: Make) -> None:
    """The first scan is t = 0 (its dt is ignored); later scans advance by their dt: period
    8 s, scans at t = 0, 1, 3, 6 s: sin 0 = 0, sin(2π/8) = √½, sin(6π/8) = √½,
    sin(12π/8) = -1."""
    b = make(waveform="sine", period=8.0)
    got = [b.step(dt)["out"].value for dt in (5.0, 1.0, 2.0, 3.0)]  # first dt is ignored
    assert got == pytest.approx([0.0, S, S, -1.0], abs=1e-12)


# ----------------------------------------------------------------------------------------------
# The amplitude input (spec 6.5: amplitude = DITHER_AMP of the previous scan)
# ----------------------------------------------------------------------------------------------
def test_extreme_values_do_not_raise(make: Make) -> None:
    """A period so short that dt/period overflows restarts the cycle (out = +A)."""
    b = make(period=1e-310)
    assert wave(b, 3) == [1.0, 1.0, 1.0]


@pytest.mark.parametrize("value", [math.inf, -math.inf, 1e308, -1e308, 3.5e38])
def test_issue_11_unusable_amplitude_keeps_the_last_one_and_is_bad(make: Make,
                                                                  value: float) -> None:
    """issue 11 point 1 (this test pinned out = ±inf, and inf·0 = NaN for a sine, before):
    an amplitude input that is ±inf or beyond float32 (a DeltaV parameter) is Bad input: the
    wave goes on with the last usable amplitude and out is Bad (0); the next usable amplitude
    is Good again. Square, period 2 s: +A, -A, +A, ..."""
    b = make(amplitude=1.0)
    got = [b.step(1.0, amplitude=a)["out"] for a in (0.25, value, value, NAN, 0.5)]
    assert got == [(0.25, 128), (-0.25, 0), (0.25, 0), (-1.0, 128), (0.5, 128)]
    b = make(waveform="sine", period=8.0)
    assert b.step(1.0, amplitude=value)["out"] == (0.0, 0)  # sin(0)·(parameter 1)
    assert np.isfinite(b.x).all()


def test_issue_11_the_kernel_is_sound_by_itself() -> None:
    """issue 11 point 1: the kernel alone, without the numeric guard's undo-and-rerun, leaves
    no state and no output non-finite on random extreme amplitudes, scan times and parameters
    at the float32 limit (out beyond float32 is Bad)."""
    rng = np.random.default_rng(12)
    specials = [NAN, math.inf, -math.inf, 1e308, -1e308, 3.5e38, 3.4e38, -3.4e38, 0.0]
    for params in ({}, {"waveform": "sine", "period": 1e-300}, {"waveform": "triangle",
                   "amplitude": 3.4e38, "bias": 3.4e38, "phase": 359.0}):
        b = loopworks.create_block("deltav.sggn", jit=False, **params)
        for _ in range(2000):
            b.u[0] = float(rng.choice(specials)) if rng.random() < 0.5 else \
                float(rng.uniform(-10, 10))
            b.us[0] = int(rng.choice([128, 0, 0x1C]))
            dt = float(rng.choice([1e-300, 0.1, 1.0, 1e300]))
            with np.errstate(all="ignore"):
                b.kernel(dt, b.p, b.x, b.u, _marked_np(b.u, b.us), b.y, b.ys)
            assert np.isfinite(b.x).all() and np.isfinite(b.y).all()
            if abs(b.y[0]) >= 3.4028235677973366e38:
                assert b.ys[0] == 0


def test_issue_11_point_8_initial_output_is_the_first_scans_value(make: Make) -> None:
    """issue 11 point 8: before the first scan out shows bias + A·wave(phase) for the
    amplitude parameter (not 0): square +A, sine at 90° (a cosine) +A, triangle at 0° the
    bias; the first scan gives the same."""
    for params, start in (({"amplitude": 0.3, "bias": 50.0}, 50.3),
                          ({"waveform": "sine", "amplitude": 2.0, "phase": 90.0}, 2.0),
                          ({"waveform": "triangle", "amplitude": 2.0, "bias": 1.0}, 1.0),
                          ({"amplitude": 0.5, "phase": 180.0}, -0.5)):
        b = make(**params)
        assert b.outputs()["out"] == (pytest.approx(start), 128), params
        assert b.step(1.0)["out"].value == pytest.approx(start), params


def test_amplitude_input_overrides_the_parameter_and_nan_restores_it(make: Make) -> None:
    b = make(amplitude=1.0)
    assert wave(b, 2, amplitude=0.25) == [0.25, -0.25]
    assert wave(b, 2, amplitude=NAN) == [1.0, -1.0]
    assert wave(b, 1, amplitude=-2.0) == [-2.0]  # a negative amplitude inverts the wave
    assert wave(b, 1, amplitude=0.0) == [0.0]


def test_module_sggn1_first_reads_last_scans_dither_amp() -> None:
    """spec 6.1, 6.5: SGGN1 (#3) runs before the CALC (#4), so with
    "sggn1.amplitude" = "comp.dither_amp" it uses the DITHER_AMP of the previous scan: 0 (the
    seed default) at the first scan, then ±DITHER_AMP. DITHER_AMP = (0.5 + 0.1)·1·0.5 = 0.3."""
    module = Module({"sggn1": create_block("deltav.sggn", period=2.0),
                     "comp": create_block("deltav.stick_slip", resolution=0.5, deadband=0.2,
                                          precision="float64")},
                    wires={"sggn1.amplitude": "comp.dither_amp", "comp.dither_out": "sggn1.out"},
                    inputs={"comp": {"signal_in": 40.0, "sp": 50.0, "pv": 50.0,
                                     "comp_start": 1.0}})
    r = module.run(5.0, 1.0)
    assert list(r.values["sggn1.out"]) == pytest.approx([0.0, -0.3, 0.3, -0.3, 0.3])
    # band: DITHER_DELT = DITHER_OUT·-1·1, SIGNAL_OUT = 40 + 0 + DITHER_DELT
    assert list(r.values["comp.signal_out"]) == pytest.approx([40.0, 40.3, 39.7, 40.3, 39.7])


def test_scenario_table_amplitude_is_the_parameter_even_when_the_input_is_wired() -> None:
    """In a scenario file ``amplitude`` is the parameter, so it can sit beside the wire; the
    wired input (DITHER_AMP = (0.5 + 0)·1·0.5 = 0.25) overrides it."""
    scenario = parse_scenario("""
[simulation]
dt = 1.0
duration = 3.0

[blocks.sggn1]
kind = "deltav.sggn"
amplitude = 5.0

[blocks.comp]
kind = "deltav.stick_slip"
resolution = 0.5
precision = "float64"
comp_start = 1.0

[wires]
"sggn1.amplitude" = "comp.dither_amp"
"comp.dither_out" = "sggn1.out"
""")
    sggn = scenario.module.blocks["sggn1"]
    assert sggn.params["amplitude"] == 5.0
    r = scenario.module.run(3.0, 1.0)
    assert list(r.values["sggn1.out"]) == [0.0, -0.25, 0.25]


# ----------------------------------------------------------------------------------------------
# Parameters, state, jit, replay
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("name", "value"), [
    ("period", 0.0), ("period", -1.0), ("period", math.inf), ("phase", 360.0), ("phase", -1.0),
    ("waveform", "sawtooth"), ("amplitude", math.inf), ("bias", NAN),
    ("amplitude", 1e39), ("bias", -3.5e38)])  # a DeltaV parameter is a float32
def test_bad_parameters_name_the_parameter(name: str, value: Any) -> None:
    with pytest.raises(ParameterError, match=name):
        loopworks.create_block("deltav.sggn", **{name: value})


def test_resume_from_saved_state_equals_uninterrupted_run() -> None:
    rng = np.random.default_rng(4)
    seq = [(float(rng.uniform(0.1, 1.0)), float(rng.choice([NAN, 0.3, 0.6])))
           for _ in range(200)]
    params = {"waveform": "triangle", "period": 3.7, "phase": 45.0, "bias": 1.0}
    whole = loopworks.create_block("deltav.sggn", **params)
    expected = [whole.step(dt, amplitude=a)["out"].value for dt, a in seq]
    first = loopworks.create_block("deltav.sggn", **params)
    for dt, a in seq[:100]:
        first.step(dt, amplitude=a)
    saved = json.loads(json.dumps(first.state_dict()))
    second = loopworks.create_block("deltav.sggn", **params)
    second.load_state(saved)
    assert [second.step(dt, amplitude=a)["out"].value for dt, a in seq[100:]] == expected[100:]


def test_replay_cli_runs_the_docstring_example(tmp_path: Path) -> None:
    """Triangle, period 4 s: positions 0, 1/4, 1/2, 3/4 give 0, A, 0, -A; A = 2 from the
    input, then the parameter 1."""
    path = write_csv(tmp_path / "gen.csv", ["t", "amplitude"],
                     [[0, 2], [1, 2], [2, "nan"], [3, "nan"]])
    result = CliRunner().invoke(app, ["replay", "deltav.sggn", str(path), "-p",
                                      "waveform=triangle", "-p", "period=4"])
    assert result.exit_code == 0, result.output
    rows = list(csv.reader(io.StringIO(result.stdout)))
    assert rows[0] == ["t", "out", "out.ST"]
    assert [float(r[1]) for r in rows[1:]] == pytest.approx([0.0, 2.0, 0.0, -1.0], abs=1e-12)
    assert [int(r[2]) for r in rows[1:]] == [128] * 4


def test_blocks_cli_documents_the_generator() -> None:
    result = CliRunner().invoke(app, ["blocks", "deltav.sggn", "--markdown"])
    assert result.exit_code == 0, result.output
    for needle in ("| half_period_scans | scans | 1 |", "spec 6.5",
                   "Options for the spec's [A]/[?] points"):
        assert needle in result.stdout
