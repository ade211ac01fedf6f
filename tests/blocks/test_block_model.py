"""The block model: registry, validation, inputs, state save/resume, and kernels under numba."""

from __future__ import annotations

import json
import math
import zlib

import numpy as np
import pytest

import loopworks
from loopworks.blocks import status as st
from loopworks.blocks.block import Block
from loopworks.errors import InputError, ParameterError, UnknownKindError

# Every operator of the CALC subset; A, B, C are random inputs (deltav.calc variants).
CALC_TEXT = """(* every operator of the subset; A, B, C are random inputs *)
'^/R' := '^/A' / '^/B';
'^/Q' := - '^/A' / ('^/B' - '^/B') + 1;
IF NOT ('^/A' > 50) OR '^/B' != 3 AND '^/C' <> 0 THEN
  '^/N' := '^/N' + 1;
ELSIF '^/A' <= '^/B' THEN
  '^/N' := - '^/N';
ELSE
  '^/N' := 0
END_IF;
'^/R.ST' := '^/A.ST' + '^/R';
'^/S.ST' := '^/R.ST' - 1;
'^/S' := ('^/A' >= '^/B') AND ('^/C' < 100) OR FALSE;
"""

CHOUDHURY_VARIANTS: list[dict[str, object]] = [
    {},
    {"s": 3.0, "j": 1.0, "y0": 50.0, "start": "moving_up", "stroke_rate": 2.0},
    {"resolution": 0.5, "deadband": 0.2, "bad_op": "fail", "fail_op": 10.0,
     "characteristic": "equal_percentage", "rangeability": 30.0},
    {"s": 1.0, "j": 4.0, "start": "moving_down"},
    {"fs": 5.0, "fd": 0.0, "y0": 0.0},
]

# Parameter sets that exercise the branches of each kind's kernel.
VARIANTS: dict[str, list[dict[str, object]]] = {
    "pid": [
        {},
        {"k": 2.0, "ti": 5.0, "td": 1.0, "c": 1.0, "b": 0.5},
        {"form": "parallel", "kp": 1.5, "ki": 0.3, "kd": 0.2, "tf": 0.05,
         "antiwindup": "back_calculation", "rate_limit": 20.0},
        {"form": "series", "k": 0.8, "ti": 8.0, "td": 2.0, "algorithm": "velocity",
         "i_deadband": 1.0, "bad_pv": "safe", "safe_out": 10.0},
        {"k": 1.0, "ti": 3.0, "algorithm": "velocity", "antiwindup": "none", "e_deadband": 2.0,
         "action": "direct", "bias": 30.0, "out_lo": -50.0, "out_hi": 50.0},
        {"k": 3.0, "ti": 2.0, "antiwindup": "none", "n": math.inf, "td": 0.5},
    ],
    "process.first_order": [{}, {"gain": -2.0, "time_constant": 3.0, "y0": 5.0},
                            {"time_constant": 0.0}],
    "process.fopdt": [
        {},
        {"gain": -2.0, "time_constant": 0.0, "dead_time": 0.35, "u0": 10.0,
         "bad_input": "freeze"},
        {"time_constant": 3.0, "dead_time": 1.3, "y0": 5.0, "delay_capacity": 200},
    ],
    "process.sopdt": [
        {},
        {"time_constant_1": 4.0, "time_constant_2": 4.0, "dead_time": 0.0},
        {"time_constant_1": 0.0, "time_constant_2": 1.5, "u0": 50.0, "y0": 20.0,
         "bad_input": "freeze"},
    ],
    "process.ipdt": [
        {},
        {"gain": -0.05, "dead_time": 0.0, "u0": 50.0, "y0": 10.0},
        {"dead_time": 0.77, "bad_input": "freeze"},
    ],
    "process.tf": [
        {"sample_time": 0.1},
        {"num": "1, 0.5, 2", "den": "2, 3, 1.5", "sample_time": 0.25, "dead_time": 0.6,
         "u0": 20.0},
        {"num": "0.2, 0.1", "den": "1, -1.2, 0.5", "domain": "z", "sample_time": 0.5,
         "dead_time": 1.0, "bad_input": "freeze"},
    ],
    "ge.pid_ind": [
        {},
        {"kp": 4.0, "ki": 1.5, "kd": 0.5, "sample_period": 0.1, "deadband_pos": 5,
         "deadband_neg": -5, "upper_clamp": 100, "lower_clamp": -100, "min_slew_time": 3,
         "config_word": 63, "rounding": "floor", "saturate_sum": True},
        {"kp": 1.0, "ki": 0.25, "kd": 2.0, "arithmetic": "float", "min_slew_time": 0.7,
         "direct_acting": True, "derivative_filter": True, "derivative_filter_time": 0.3,
         "bad_input": "ignore_status", "manual_tracking": "cv", "upper_clamp": 50,
         "lower_clamp": 10},
        {"kp": 2.0, "ki": 3.0, "integral_resolution": 0, "deadband_pos": 3, "deadband_neg": -2,
         "deadband_subtract": True, "arw_hold": True, "override_sp_pv": False,
         "load_clock_at_start": True, "slew_remainder": False, "min_slew_time": 10},
        {"upper_clamp": 0, "lower_clamp": 10, "on_parameter_error": "ok_off",
         "initial_last_solution": 5.0},
    ],
    "ge.pid_isa": [
        {},
        {"kc": 2.0, "ti": 10.0, "td": 0.5, "isa_division": "staged", "sample_period": 0.05,
         "invert_output": True, "derivative_on_pv": True, "upper_clamp": 80,
         "lower_clamp": -80, "min_slew_time": 7},
        {"kc": 0.7, "ti": 0.5, "td": 1.3, "arithmetic": "float", "arw_hold": True,
         "integral_resolution": 0.01, "derivative_filter": True},
    ],
    "s5.pid": [
        {},
        {"k": 1200, "r": 1000, "ti": 50, "td": 800, "bgog": 100, "bgug": -20,
         "i_suppression": "flag", "first_call": "inputs"},
        {"k": -3000, "ti": 300, "td": 3000, "velocity": True, "xz_on": True, "bgog": 40,
         "bgug": -40, "overflow": "wrap", "rounding": "floor", "bad_input": "last"},
        {"k": 20000, "r": 500, "ti": 9999, "td": 20000, "hold": True, "no_z": True,
         "scale": "nominal", "rounding": "nearest", "dd_decay": 1.0, "manual_steps": 0},
        {"k": 900, "ti": 100, "td": 1500, "arithmetic": "float", "scale": "nominal",
         "xz_on": True, "bgog": 60, "bgug": 0, "y0": 80, "i_suppression": "none"},
        {"k": 1000, "ti": 200, "velocity": True, "hold": True, "arithmetic": "float",
         "rounding": "truncate", "dd_decay": 0.3, "bad_input": "last", "manual_steps": 5},
    ],
    "deltav.stick_slip": [
        {},
        {"resolution": 0.5, "deadband": 0.2},
        {"resolution": 0.5, "deadband": 0.2, "precision": "float64",
         "deferred_param_reads": True, "dither_half_period": 3, "upper_band_factor": 1.0,
         "lower_band_factor": 0.5},
        {"resolution": 2.0, "deadband": 1.0, "kick_start": 1.0, "cntrl_action": 1.0,
         "valve_action": -1.0, "process_gain": 20.0, "noise_factor": 0.5,
         "dither_factor": 3.0, "kicker_factor": 0.25},
        {"resolution": 1e38, "deadband": 3e38, "process_gain": 1e30, "dither_half_period": 2,
         "deferred_param_reads": True},
    ],
    "deltav.pid": [
        {},
        {"gain": 2.0, "reset": 5.0, "rate": 1.0, "structure": "pid_action_on_error",
         "pv_ftime": 0.5, "sp_ftime": 0.3, "sp_rate_up": 2.0, "sp_rate_dn": 5.0,
         "out_hi_lim": 90.0, "out_lo_lim": 5.0, "arw_hi_lim": 80.0, "arw_lo_lim": 10.0,
         "ideadband": 1.0, "ff_gain": 0.5, "dynamic_reset_limit": True, "precision": "float64"},
        {"form": "series", "gain": 1.5, "reset": 3.0, "rate": 2.0, "alpha": 0.2,
         "structure": "two_degrees_of_freedom", "beta": 0.5, "gamma": 0.3,
         "direct_acting": True, "reset_discretisation": "exact",
         "filter_discretisation": "exact", "derivative_discretisation": "exact",
         "pv_ftime": 1.0, "track_enable": True, "track_in_manual": True,
         "use_uncertain_as_good": True, "ifs_if_bad_in": True, "ifs_if_bad_cas_in": True,
         "pv_scale_eu_0": -50.0, "pv_scale_eu_100": 250.0, "out_scale_eu_0": 4.0,
         "out_scale_eu_100": 20.0, "trk_scale_eu_100": 50.0},
        {"structure": "pd_action_on_error", "gain": 0.7, "rate": 3.0,
         "no_reset_bias": "fixed", "bias": 40.0, "bal_time": 2.0, "sp_pv_track_man": True,
         "sp_pv_track_lo_iman": True, "target_to_man_if_bad_in": True,
         "no_out_limits_manual": True, "use_pv_for_bkcal_out": True,
         "obey_sp_limits_cas": True, "sp_hi_lim": 80.0, "sp_lo_lim": 20.0,
         "ff_conversion": "scale_then_gain", "ff_gain": -1.0, "ff_scale_eu_0": 10.0,
         "ff_scale_eu_100": 60.0},
        {"structure": "i_action_on_error_d_action_on_pv", "reset": 0.05, "rate": 0.5,
         "reset_feedback": "output", "ff_in_reset_feedback": True,
         "series_derivative": "filtered", "form": "series", "reset_discretisation": "backward",
         "sp_track_retained_target": True, "target_to_next_if_bad_cas_in": True,
         "arw_units": "out_eu", "arw_hi_lim": 95.0, "arw_lo_lim": 2.0, "initial_out": 30.0,
         "bkcal_hys": 5.0, "gain": 1e6},
        {"structure": "id_action_on_error", "reset": 0.0, "reset_zero_disables": True,
         "rate": 1e30, "gain": 3.0, "out_hi_lim": 110.0, "out_lo_lim": -10.0},
    ],
    "deltav.calc": [
        {},
        {"resolution": 0.5, "deadband": 0.2, "kick_start": 1.0, "process_gain": 0.01},
        {"resolution": 0.5, "deadband": 0.2, "precision": "float64",
         "deferred_param_reads": True, "cntrl_action": 1.0},
        {"expression": CALC_TEXT, "a": 0.0, "b": 0.0, "c": 0.0},
        {"expression": CALC_TEXT, "a": 0.0, "b": 0.0, "c": 0.0, "n": 1e30,
         "divide_by_zero": "ieee", "precision": "float64", "deferred_param_reads": True},
    ],
    "deltav.sggn": [
        {},
        {"waveform": "sine", "amplitude": 2.5, "period": 0.7, "bias": 50.0, "phase": 30.0},
        {"waveform": "triangle", "amplitude": -1.0, "period": 3.3, "phase": 270.0},
        {"waveform": "square", "amplitude": 0.3, "period": 0.05, "phase": 180.0},
    ],
    "valve.choudhury": CHOUDHURY_VARIANTS,
    "valve.kano": CHOUDHURY_VARIANTS,
    "valve.he": [
        {},
        {"fs": 2.0, "fd": 1.0, "y0": 50.0, "start": "moving_up", "stroke_rate": 2.0},
        {"resolution": 0.5, "deadband": 0.2, "bad_op": "fail", "fail_op": 10.0,
         "characteristic": "equal_percentage"},
        {"s": 1.0, "j": 4.0, "start": "moving_down"},
    ],
    "valve.backlash": [
        {},
        {"b": 5.0, "y0": 20.0, "stroke_rate": 1.5, "start": "moving_up"},
        {"b": 0.0, "bad_op": "fail", "fail_op": 100.0, "characteristic": "equal_percentage"},
        {"b": 3.0, "start": "moving_down"},
    ],
    "valve.resolution": [
        {},
        {"r": 3.0, "y0": 100.0, "stroke_rate": 5.0},
        {"r": 0.0, "bad_op": "fail", "characteristic": "equal_percentage"},
    ],
    "valve.quantiser": [
        {},
        {"q": 40.0, "y0": 50.0, "stroke_rate": 10.0, "characteristic": "equal_percentage"},
        {"q": 1.0, "bad_op": "fail", "fail_op": 37.3},
    ],
    "valve.karnopp": [  # coarse substeps: the interpreted kernel runs them all
        {"substep": 0.01},
        {"tau_ip": 0.05, "substep": 0.005, "y0": 50.0, "bad_op": "fail",
         "characteristic": "equal_percentage"},
        {"f_v": 0.0, "v_s": 0.0, "tau_ip": 0.0, "substep": 0.01, "max_substeps": 50},
        {"s": 3.0, "j": 1.0, "sj_mapping": "valve_estimation", "f_init": 1840.8, "k": 0.0,
         "dv": 0.0, "substep": 0.002, "y0": 10.0},
        {"resolution": 1.0, "deadband": 2.0, "m": 50.0, "f_v": 500.0, "tau_ip": 0.5,
         "substep": 0.01, "fail_op": 100.0, "bad_op": "fail"},
    ],
    "sensor.transmitter": [
        {},
        {"gain": 2.0, "offset": -5.0, "time_constant": 3.0, "noise_std": 0.5, "seed": 11,
         "quantum": 0.1, "pv_lo": 0.0, "pv_hi": 100.0},
        {"noise_std": 1.0, "seed": 3, "failure": "stuck", "failure_start": 20.0,
         "failure_end": 60.0, "range_status": "good", "pv_lo": -10.0, "pv_hi": 110.0},
        {"time_constant": 0.5, "failure": "bad", "failure_start": 5.0, "quantum": 1e-300},
        {"failure": "nan", "failure_start": 0.0, "failure_end": 50.0, "failure_status": 16,
         "noise_std": 1e300, "quantum": 1e-3},
    ],
    "disturbance.load": [
        {},
        {"bias": 1.0, "step_size": 5.0, "step_time": 30.0, "ramp_rate": 0.1,
         "ramp_start": 10.0, "ramp_end": 200.0, "sine_amplitude": 2.0, "sine_period": 7.0,
         "sine_phase": 45.0, "sine_start": 3.0},
        {"walk_std": 0.5, "seed": 4, "walk_start": 10.0},
        {"walk_std": 2.0, "walk_time_constant": 15.0, "seed": 99, "ramp_rate": -1e300},
    ],
    "relay": [
        {},
        {"amplitude": 2.0, "amplitude_down": 1.0, "hysteresis": 0.5, "biased_stage": True,
         "stable_cycles": 1, "tolerance": 10.0, "discard_cycles": 0, "action": "direct",
         "u0": 40.0, "max_deviation": 50.0, "timeout": 30.0, "max_half_period": 5.0},
        {"amplitude": 1.0, "hysteresis": 0.1, "stable_cycles": 5, "tolerance": 0.5,
         "max_cycles": 8, "out_lo": -10.0, "out_hi": 10.0},
        {"amplitude": 3.0, "hysteresis": 0.2, "biased_stage": True, "offset": -1.5,
         "stable_cycles": 1, "tolerance": 10.0, "discard_cycles": 0},
    ],
    "compensator.knocker": [
        {},
        {"amplitude": 3.0, "pulse_width": 0.5, "interval": 2.0, "error_band": 20.0},
        {"direction_reference": "pulse_start", "pulse_width": 1.5, "interval": 1.6},
    ],
    "compensator.constant_reinforcement": [{}, {"alpha": 0.0}, {"alpha": 1e300}],
    "compensator.two_move": [
        {},
        {"cycles": 1, "approach": "auto", "move_time": 1.5, "release_band": 50.0,
         "cycle_band": 5.0},
        {"cycles": 1, "target": "model", "model_gain": -2.0, "model_bias": 30.0, "op_lo": 10.0,
         "op_hi": 90.0, "margin": 2.0},
        {"cycles": 3, "s": 0.0, "j": 0.0, "margin": 1e-9, "target": "model",
         "model_gain": 1e-300},
    ],
    "e2.pid": [
        {},
        {"kd": 1.0, "d_form": "as_printed", "update_interval": 0.5, "filter_period": 1.5,
         "filter_percentage": 60.0},
        {"error_sign": "setpoint_minus_input", "i_tr_normalise": True, "d_tr_normalise": True,
         "kd": 0.5, "old_output": "filtered", "filter_period": 0.7, "filter_percentage": 75.0,
         "min_accumulated_error": 5.0},
        {"startup_errors": "current", "initial_output": 30.0, "override_updates_pid": True,
         "override_limits": "output_limits", "output_min": 20.0, "output_max": 80.0,
         "update_interval": 3.0},
        {"bad_input": "failsafe", "failsafe_output": 10.0, "throttling_range": 4.0, "kp": 2.0,
         "ki": 1.0, "update_interval": 0.05},
    ],
}


def scan_time(params: dict[str, object], rng: np.random.Generator, lo: float,
              hi: float) -> float:
    """A random scan time, or the block's own sample_time when it has one (process.tf)."""
    if "sample_time" in params:
        return float(params["sample_time"])  # type: ignore[arg-type]
    return float(rng.uniform(lo, hi))


def random_inputs(block: Block, rng: np.random.Generator) -> dict[str, object]:
    """Random values for every input: occasional NaN/inf and non-Good statuses."""
    inputs: dict[str, object] = {}
    for port in block.INPUTS:
        if port.choices:
            value = float(rng.integers(0, len(port.choices)))
        elif port.name in ("track", "trk_in_d"):
            value = float(rng.random() < 0.1)
        else:
            value = float(rng.uniform(-20.0, 120.0))
            r = rng.random()
            if r < 0.03:
                value = math.nan
            elif r < 0.04:
                value = math.inf
        if port.status:
            status = int(rng.choice([128, 128, 128, 128, 0, 0x40, 0x44, 0xC0, 130]))
            inputs[port.name] = (value, status)
        else:
            inputs[port.name] = value
    return inputs


def test_every_registered_kind_has_variants_here() -> None:
    assert set(loopworks.kinds()) <= set(VARIANTS), "add parameter variants for new kinds"


@pytest.mark.parametrize("kind", sorted(VARIANTS))
def test_resume_from_saved_state_equals_uninterrupted_run(kind: str) -> None:
    """Save mid-run (through JSON), restore into a fresh block, continue: identical outputs."""
    for params in VARIANTS[kind]:
        rng = np.random.default_rng(99)
        steps = [(scan_time(params, rng, 0.05, 1.0), None) for _ in range(400)]
        whole = loopworks.create_block(kind, **params)
        first = loopworks.create_block(kind, **params)
        seq = []
        for dt, _ in steps:
            seq.append((dt, random_inputs(whole, rng)))
        expected = [dict(whole.step(dt, **inp)) for dt, inp in seq]
        for dt, inp in seq[:200]:
            first.step(dt, **inp)
        saved = json.loads(json.dumps(first.state_dict()))
        resumed = loopworks.create_block(saved["kind"], **saved["params"])
        resumed.load_state(saved)
        assert resumed.state().keys() == first.state().keys()
        # flat: approx compares no nested lists (an Array entry's value)
        assert resumed.x == pytest.approx(first.x, nan_ok=True)
        got = [dict(resumed.step(dt, **inp)) for dt, inp in seq[200:]]
        for e, g in zip(expected[200:], got, strict=True):
            for name in e:
                assert g[name].status == e[name].status
                assert g[name].value == e[name].value or (math.isnan(g[name].value)
                                                          and math.isnan(e[name].value))


def test_reset_returns_to_the_state_after_construction() -> None:
    pid = loopworks.create_block("pid", k=2.0, ti=10.0)
    fresh = pid.state_dict()
    pid.step(0.1, sp=50.0, pv=40.0, mode="MAN", man_out=30.0)
    assert pid.state_dict() != fresh
    pid.reset()
    assert json.dumps(pid.state_dict()) == json.dumps(fresh)  # NaN-safe comparison


def test_load_state_of_another_kind_is_an_error() -> None:
    pid = loopworks.create_block("pid")
    proc = loopworks.create_block("process.first_order")
    with pytest.raises(InputError, match=r"process\.first_order"):
        pid.load_state(proc.state_dict())


@pytest.mark.parametrize("kind", ["s5.pid", "pid", "process.fopdt"])
@pytest.mark.parametrize("value", [math.nan, math.inf])
def test_a_saved_state_that_is_not_finite_is_refused(kind: str, value: float) -> None:
    """Every kernel keeps its state finite; load_state took any number, and an s5.pid whose
    DW 48 was loaded as NaN gave y = NaN with a Good status for ever (found by an outside
    audit). Now an error naming the state; the block is unchanged."""
    block = loopworks.create_block(kind)
    saved = block.state_dict()
    name = next(iter(saved["state"]))
    state = saved["state"][name]
    saved["state"][name] = [value, *state[1:]] if isinstance(state, list) else value
    before = block.state_dict()
    with pytest.raises(InputError, match=rf"{kind}: saved state '{name}(\[0\])?' = "
                                         rf"{value!r} is not allowed"):
        block.load_state(saved)
    assert json.dumps(block.state_dict()) == json.dumps(before)


def test_a_value_is_given_in_full_when_its_short_form_would_be_another_number() -> None:
    """"'dither_half_period' = 1e+09 is out of range: allowed [1, 1e+09]" read as a bound
    refused: 1000000001.0 printed with 6 digits (found by an outside audit)."""
    with pytest.raises(ParameterError, match=r"'dither_half_period' = 1000000001.0 is out of "
                                             r"range: allowed \[1, 1e\+09\] integer scans"):
        loopworks.create_block("deltav.stick_slip", dither_half_period=1000000001.0)
    with pytest.raises(ParameterError, match=r"'dither_half_period' = 1.5 must be an integer: "
                                             r"allowed \[1, 1e\+09\] integer scans$"):
        loopworks.create_block("deltav.stick_slip", dither_half_period=1.5)
    with pytest.raises(ParameterError, match=r"'resolution' = 3.4028236e\+38 is out of range"):
        loopworks.create_block("deltav.stick_slip", resolution=3.4028236e38)
    with pytest.raises(ParameterError, match=r"'ti' = -1 is out of range"):  # short when exact
        loopworks.create_block("pid", ti=-1.0)


def test_a_saved_output_that_is_not_finite_must_be_bad() -> None:
    pid = loopworks.create_block("pid")
    saved = pid.state_dict()
    saved["outputs"]["out"] = [math.nan, st.GOOD_NC]
    with pytest.raises(InputError, match=r"saved output 'out' = nan with status 128"):
        pid.load_state(saved)
    saved["outputs"]["out"] = [math.nan, st.BAD]
    pid.load_state(saved)
    assert math.isnan(pid.outputs()["out"].value) and pid.outputs()["out"].status == st.BAD


def _enumerated_inputs() -> list[tuple[str, str]]:
    from loopworks.catalog import block_class, kinds

    return [(kind, port.name) for kind in kinds() for port in block_class(kind).INPUTS
            if port.choices]


@pytest.mark.parametrize(("kind", "port"), _enumerated_inputs())
@pytest.mark.parametrize("value", [math.nan, math.inf])
def test_an_enumerated_input_that_is_not_a_number_is_no_value(kind: str, port: str,
                                                              value: float) -> None:
    """An enumerated input (a mode, an auto or off bit) given NaN or inf as a plain float was
    refused ("expected one of MAN, AUTO ..."), while the same value as a Signal reached the
    block, which treats it as a Bad input (s5.pid's page: "an auto or off bit that is NaN
    ... holds the scan"; found by an outside audit). Both now give the same outputs."""
    required = {"process.tf": {"sample_time": 1.0}}.get(kind, {})
    plain = loopworks.create_block(kind, **required)
    signal = loopworks.create_block(kind, **required)
    for _ in range(2):
        plain.step(1.0)
        signal.step(1.0)
    a = plain.step(1.0, **{port: value})
    b = signal.step(1.0, **{port: loopworks.Signal(value, st.GOOD_NC)})
    assert json.dumps({k: (v.value, v.status) for k, v in a.items()}) == \
        json.dumps({k: (v.value, v.status) for k, v in b.items()})


def test_inputs_latch_until_given_again() -> None:
    """An input keeps its last value: a second step without sp/pv repeats the error."""
    pid = loopworks.create_block("pid", k=1.0, ti=10.0)
    first = pid.step(1.0, sp=10.0, pv=4.0)["out"].value
    second = pid.step(1.0)["out"].value
    assert first == pytest.approx(6.0 + 0.6)
    assert second == pytest.approx(6.0 + 1.2)


def test_input_names_in_any_letter_case_and_signal_pairs() -> None:
    pid = loopworks.create_block("PID", K=1.0)
    out = pid.step(1.0, SP=10.0, Pv=loopworks.Signal(4.0, st.GOOD_NC))
    assert out["out"].value == pytest.approx(6.0)


def test_unknown_input_lists_the_valid_ones() -> None:
    pid = loopworks.create_block("pid")
    with pytest.raises(InputError, match=r"unknown input 'spp'.*sp, pv, ff, mode"):
        pid.step(1.0, spp=1.0)


def test_bad_input_value_names_the_input() -> None:
    pid = loopworks.create_block("pid")
    with pytest.raises(InputError, match="mode"):
        pid.step(1.0, mode="SEMIAUTO")
    for code in (5, 1.5, -1.0):  # NaN is no value, not a wrong one (a Bad input, below)
        with pytest.raises(InputError, match=r"'mode' = .*codes 0\.\.2"):
            pid.step(1.0, mode=code)
    with pytest.raises(InputError, match="status"):
        pid.step(1.0, pv=(1.0, 300))


@pytest.mark.parametrize("dt", [0.0, -0.1, math.nan, math.inf])
def test_non_positive_or_non_finite_dt_is_an_error(dt: float) -> None:
    pid = loopworks.create_block("pid")
    with pytest.raises(InputError, match="dt"):
        pid.step(dt, sp=1.0, pv=0.0)


def test_unknown_kind_lists_the_known_kinds() -> None:
    with pytest.raises(UnknownKindError, match=r"unknown block kind 'pidd'.*pid"):
        loopworks.create_block("pidd")


def test_parameter_errors_name_parameter_value_and_range() -> None:
    with pytest.raises(ParameterError, match=r"'ti' = -1 is out of range: allowed \(0, inf\] s"):
        loopworks.create_block("pid", ti=-1)
    with pytest.raises(ParameterError, match=r"'k' = 'abc' must be a number: allowed \(0, inf\)"):
        loopworks.create_block("pid", k="abc")
    with pytest.raises(ParameterError, match=r"'ti' = True must be a number: allowed \(0, inf\] s"):
        loopworks.create_block("pid", ti=True)
    with pytest.raises(ParameterError, match=r"'form' = 'pi' is not allowed: expected one of"):
        loopworks.create_block("pid", form="pi")
    with pytest.raises(ParameterError, match=r"'time_constant' = nan is out of range"):
        loopworks.create_block("process.first_order", time_constant=math.nan)


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf, "nan", "inf", 1e308])
def test_a_non_finite_or_huge_integer_parameter_names_itself(value: object) -> None:
    """An integer parameter given NaN or infinity (a float, or text as a CLI gives it) is out
    of its range, named, not a ValueError or OverflowError from int() (found by fuzzing)."""
    with pytest.raises(ParameterError, match=r"'delay_capacity' = .* is out of range: "
                                             r"allowed \[1, 1e\+07\] integer"):
        loopworks.create_block("process.fopdt", delay_capacity=value)
    with pytest.raises(ParameterError, match=r"'max_cycles' = .* is out of range"):
        loopworks.create_block("relay", max_cycles=value)


def test_none_is_a_parameter_not_given() -> None:
    """None for a parameter means "not given" (found by fuzzing: a None gain reached the
    coefficients as a TypeError): the declared default, or the derived one."""
    assert (loopworks.create_block("process.fopdt", gain=None, dead_time=None).params
            == loopworks.create_block("process.fopdt").params)
    assert (loopworks.create_block("pid", k=None, ti=None).gains()  # type: ignore[attr-defined]
            == loopworks.create_block("pid").gains())  # type: ignore[attr-defined]


def test_a_dead_time_no_delay_line_holds_is_a_clear_error() -> None:
    """dead_time/dt beyond the largest delay line (delay_capacity ≤ 1e7), or not even a
    finite count (1e308 s in scans of 1e-9 s), says so, instead of an OverflowError."""
    block = loopworks.create_block("process.ipdt", dead_time=1e308, jit=False)
    for dt in (1.0, 1e-9):
        with pytest.raises(InputError, match=r"dead_time = 1e\+308 s .* more than the most a "
                                             r"delay line holds .* longer dt"):
            block.step(dt)
    with pytest.raises(InputError, match=r"needs 10 scans .* give delay_capacity ≥ 10"):
        loopworks.create_block("process.fopdt", dead_time=10.0, delay_capacity=1).step(1.0)


def test_parameters_from_strings_as_a_cli_gives_them() -> None:
    pid = loopworks.create_block("pid", k="2", ti="inf", action="DIRECT", out_hi="1e3")
    assert pid.params["ti"] == math.inf
    assert pid.params["action"] == "direct"
    assert pid.params["out_hi"] == 1000.0


def test_repr_round_trips_the_constructor() -> None:
    pid = loopworks.create_block("pid", k=2.0, ti=10.0)
    assert repr(pid) == "create_block('pid', k=2.0, ti=10.0)"


def test_a_held_result_keeps_the_scan_that_produced_it() -> None:
    """step() returns the scan's outputs even when read after later scans, resets or loads."""
    pid = loopworks.create_block("pid", k=1.0)
    first = pid.step(1.0, sp=10.0, pv=4.0)
    saved = pid.state_dict()
    second = pid.step(1.0, pv=7.0)
    assert first["out"].value == 6.0 and second["out"].value == 3.0
    pid.reset()
    assert second["out"] == (3.0, 128)
    third = pid.step(1.0, sp=10.0, pv=9.0)
    pid.load_state(saved)
    assert third["out"].value == 1.0
    assert dict(first) == {"out": (6.0, 128), "p_term": (6.0, 128), "i_term": (0.0, 128),
                           "d_term": (0.0, 128)}


def test_set_params_changes_tuning_and_keeps_state() -> None:
    # the textbook law (no bumpless correction, tests/blocks/test_pid.py pins that one)
    pid = loopworks.create_block("pid", k=1.0, ti=10.0, retune="textbook")
    pid.step(1.0, sp=10.0, pv=0.0)            # I = 1.0
    pid.set_params(k=2.0)                     # ki = k/ti = 0.2 now
    out = pid.step(1.0)["out"].value
    assert out == pytest.approx(2.0 * 10.0 + 1.0 + 0.2 * 10.0)
    with pytest.raises(ParameterError, match="'k' = -1"):
        pid.set_params(k=-1.0)
    assert pid.params["k"] == 2.0             # a failed change leaves the block as it was


@pytest.mark.parametrize(("kind", "params", "change"), [
    ("deltav.calc", {}, {"expression": "OUT1 := IN1 * 3;"}),
    ("ge.pid_ind", {}, {"integral_resolution": 0.01}),
    ("process.fopdt", {}, {"delay_capacity": 50}),
])
def test_a_parameter_the_state_depends_on_cannot_change(
        kind: str, params: dict[str, object], change: dict[str, object]) -> None:
    """set_params refuses, naming the parameter and both values, to change what sizes the
    state, gives its units or is the block's program (Block.FIXED_PARAMS): applying it would
    run on a state that means something else (a calc block kept its old program while
    reporting the new text; a GE remainder in thousandths read as ten-millionths)."""
    block = loopworks.create_block(kind, **params)
    block.step(0.1)
    before = (block.p.copy(), block.x.copy(), dict(block.params))
    (name,) = change
    with pytest.raises(InputError, match=rf"{kind}: {name} .* cannot change .*make a new block"):
        block.set_params(**change)
    assert np.array_equal(block.p, before[0]) and np.array_equal(block.x, before[1],
                                                                 equal_nan=True)
    assert block.params == before[2]


@pytest.mark.parametrize("kind", sorted(VARIANTS))
def test_the_keyword_step_equals_the_general_step(kind: str) -> None:
    """A kind's ``step`` made for its ports (``keyword_step``: the ports as keyword-only
    parameters, a fast path for up to two floats) does what :meth:`Block.step` does with the
    same inputs, on a random mix of calls: floats, ints, ``(value, status)`` pairs, codes and
    names of enumerated inputs, one to four inputs at a time, some in upper case."""
    rng = np.random.default_rng(zlib.crc32(kind.encode()))
    params = VARIANTS[kind][-1]
    fast = loopworks.create_block(kind, **params)
    slow = loopworks.create_block(kind, **params)
    assert getattr(type(fast).step, "generated", False) or type(fast).step is not Block.step
    ports = list(fast.INPUTS)
    for _ in range(60):
        chosen = rng.choice(len(ports), size=min(len(ports), int(rng.integers(0, 5))),
                            replace=False)
        inputs: dict[str, object] = {}
        for i in chosen:
            port = ports[int(i)]
            name = port.name.upper() if rng.uniform() < 0.1 else port.name
            if port.choices:
                code = int(rng.integers(0, len(port.choices)))
                inputs[name] = port.choices[code] if rng.uniform() < 0.5 else code
                continue
            base = port.default if math.isfinite(port.default) else 0.0
            value = base + float(rng.normal(0.0, 2.0))
            form = rng.uniform()
            inputs[name] = (value if form < 0.7 else int(value) if form < 0.8
                            else loopworks.Signal(value, st.GOOD_NC if form < 0.9 else 0x40))
        dt = scan_time(params, rng, 0.05, 1.0)
        a = fast.step(dt, **inputs)
        b = Block.step(slow, dt, **inputs)
        assert list(a) == list(b), inputs
        assert np.array_equal([a[k][0] for k in a], [b[k][0] for k in b], equal_nan=True) \
            and [a[k][1] for k in a] == [b[k][1] for k in b], inputs
        for f, g in ((fast.x, slow.x), (fast.u, slow.u), (fast.us, slow.us),
                     (fast.y, slow.y), (fast.ys, slow.ys)):  # what state_dict holds
            assert np.array_equal(f, g, equal_nan=True), inputs
        assert fast.given == slow.given
