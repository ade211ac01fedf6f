"""The Emerson E2 PID block ``e2.pid`` against spec vendor-blocks section 3 and seed 001.

Every expected value is worked out by hand in the test (the arithmetic is written beside it) or
taken from the spec's worked examples (section 3.8, E1-E8); none is pasted from a run of the
block. Behaviour tests run twice through the ``make`` fixture: with the compiled (numba)
kernel and with the interpreted one.
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
from loopworks.blocks.block import Block
from loopworks.cli import app
from loopworks.errors import InputError, ParameterError
from loopworks.vendors.emerson_e2 import pwm_times
from tests.csvfiles import write_csv
from tests.properties.test_controller_properties import raw_step

NAN = math.nan
INF = math.inf

# Status bytes, written out from the Fieldbus encoding (quality << 6 | substatus << 2 | limits).
GOOD = 0x80  # 128
GOOD_LOW = 0x81  # 129, at output_min
GOOD_HIGH = 0x82  # 130, at output_max
GOOD_CONST = 0x83  # 131, overridden
UNC = 0x40  # Uncertain non-specific
UNC_LUV_CONST = 0x47  # Uncertain, last usable value, constant (bad input, hold)
UNC_SUBST_CONST = 0x4B  # Uncertain, substitute, constant (bad input, failsafe)

Make = Callable[..., Block]

# P only, the vendor's throttling-range example (spec 3.3): TR 10, Kp 1, OAS 50, 1 s updates.
P_ONLY: dict[str, Any] = {"throttling_range": 10.0, "kp": 1.0, "ki": 0.0, "kd": 0.0,
                          "output_at_setpoint": 50.0, "update_interval": 1.0}
# I only with MAE 0: every update adds ki·e = 1 % for e = 1, which counts the updates.
COUNTER: dict[str, Any] = {"kp": 0.0, "ki": 1.0, "min_accumulated_error": 0.0,
                           "output_at_setpoint": 50.0, "update_interval": 1.0}


@pytest.fixture(params=[True, False], ids=["compiled", "interpreted"])
def make(request: pytest.FixtureRequest) -> Make:
    """``make(**params)``: an e2.pid block with the compiled or the interpreted kernel."""
    jit = request.param

    def _make(**params: Any) -> Block:
        return loopworks.create_block("e2.pid", jit=jit, **params)

    return _make


def run(block: Block, dt: float, **inputs: Any) -> dict[str, tuple[float, int]]:
    r = block.step(dt, **inputs)
    return {k: (float(r[k].value), int(r[k].status)) for k in r}


def outs(block: Block, dt: float, pvs: list[float], sp: float, port: str = "out") -> list[float]:
    return [run(block, dt, sp=sp, pv=pv)[port][0] for pv in pvs]


# ----------------------------------------------------------------------------------------------
# Worked examples, spec 3.8
# ----------------------------------------------------------------------------------------------
def test_E1_input_rising_1F_per_update_raises_output_10_percent_per_update(make: Make) -> None:
    """spec 3.8 E1 (spec 3.3 P Mode): TR 10, Kp 1, Ki = Kd = 0, +1 °F per update -> +10 %."""
    b = make(**P_ONLY)
    got = outs(b, 1.0, [20.0, 21.0, 22.0, 23.0], sp=20.0)
    # Padj = 1 · 1 · 100/10 = 10 % per update, from Output at Setpoint 50 %
    assert got == [50.0, 60.0, 70.0, 80.0]
    assert run(b, 1.0, sp=20.0, pv=24.0)["p_adj"][0] == 10.0


def test_E2_input_24_to_34_sweeps_output_0_to_100_linearly(make: Make) -> None:
    """spec 3.8 E2: TR 10, Kp 1, OAS 50, SP 29, P only; input 24 -> 34 gives 0 -> 100 %."""
    b = make(**P_ONLY)
    pvs = [24.0 + i for i in range(11)]
    # start-up: OUT_-1 = OAS = 50, e_-1 = 0 (spec 3.9 default), so OUT = 50 + 10·(pv - 29)
    assert outs(b, 1.0, pvs, sp=29.0) == [10.0 * i for i in range(11)]


def test_E3_output_stays_at_minimum_until_an_adjustment_raises_it(make: Make) -> None:
    """spec 3.8 E3 (spec 3.4, seed 001): clamp 20/100 %, demand falls to 15 % -> stays at 20 %."""
    b = make(**P_ONLY, output_min=20.0, output_max=100.0)
    got = outs(b, 1.0, [29.0, 25.5, 25.0, 25.5], sp=29.0)
    # 50; 50 + 10·(-3.5) = 15 -> 20; 20 + 10·(-0.5) = 15 -> 20 (increment lost);
    # 20 + 10·(+0.5) = 25: leaves the clamp at once (a positional law would give 20 here)
    assert got == [50.0, 20.0, 20.0, 25.0]


def test_E4_error_inside_mae_makes_no_i_adjustment(make: Make) -> None:
    """spec 3.8 E4 (spec 3.5): SP 30, MAE 1, input 30.8 -> Iadj = 0."""
    b = make(kp=0.0, ki=0.3, min_accumulated_error=1.0, update_interval=1.0)
    r = run(b, 1.0, sp=30.0, pv=30.8)
    assert r["i_adj"][0] == 0.0
    assert r["pid_out"][0] == 50.0
    r = run(b, 1.0, sp=30.0, pv=31.5)  # outside: Iadj = 0.3 · 1.5 = 0.45
    assert r["i_adj"][0] == pytest.approx(0.45, abs=1e-12)
    assert r["pid_out"][0] == pytest.approx(50.45, abs=1e-12)


def test_E5_error_equal_to_mae_makes_no_i_adjustment_inclusive_edge(make: Make) -> None:
    """spec 3.8 E5 (spec 3.5, "equal to or less than"): SP 30, MAE 1, input 31.0 -> Iadj = 0."""
    b = make(kp=0.0, ki=0.3, min_accumulated_error=1.0, update_interval=1.0)
    assert run(b, 1.0, sp=30.0, pv=31.0)["i_adj"][0] == 0.0
    assert run(b, 1.0, sp=30.0, pv=29.0)["i_adj"][0] == 0.0  # e = -1, the other edge
    assert run(b, 1.0, sp=30.0, pv=31.25)["i_adj"][0] == pytest.approx(0.3 * 1.25, abs=1e-12)
    assert run(b, 1.0, sp=30.0, pv=31.25)["pid_out"][0] == pytest.approx(50.75, abs=1e-12)


def test_E6_filter_6s_75_percent_approaches_the_demand(make: Make) -> None:
    """spec 3.8 E6 (spec 3.6, seed 001 valve filtering): F = 50, demand 58 held ->
    56, 57.5, 57.875, 57.96875, one step per 6 s filter period."""
    # The PID asks for 58 at once and holds it: TR 12.5, Kp 1, e = 1 -> 50 + 1·1·100/12.5 = 58.
    b = make(throttling_range=12.5, kp=1.0, ki=0.0, update_interval=1.0,
             filter_period=6.0, filter_percentage=75.0)
    got = [run(b, 1.0, sp=29.0, pv=30.0) for _ in range(19)]
    assert all(r["pid_out"][0] == 58.0 for r in got)
    out = [r["out"][0] for r in got]
    # F = 50 + 0.75·8 = 56 at t = 0; 56 + 0.75·2 = 57.5 at t = 6; + 0.75·0.5 = 57.875 at
    # t = 12; + 0.75·0.125 = 57.96875 at t = 18; held in between
    assert out == [56.0] * 6 + [57.5] * 6 + [57.875] * 6 + [57.96875]


def test_seed_filter_example_50_56_57_5_holds_exactly(make: Make) -> None:
    """seed 001 "Filtering": 6 s, 75 %: 50 % -> asks 58 % -> 56 %, then 57.5 % (spec 3.6)."""
    b = make(throttling_range=12.5, kp=1.0, ki=0.0, update_interval=6.0,
             filter_period=6.0, filter_percentage=75.0)
    first = run(b, 6.0, sp=29.0, pv=30.0)
    second = run(b, 6.0, sp=29.0, pv=30.0)
    assert (first["out"][0], second["out"][0]) == (56.0, 57.5)


def test_E7_throttling_range_shift(make: Make) -> None:
    """spec 3.8 E7 (spec 3.4 [D]): TR 10, Kp 1, SP 29, OAS 50, max 100: inputs 34, 36, 35
    give 100, 100, 90 (the window slid up by 2 °F)."""
    b = make(**P_ONLY, output_max=100.0)
    # 50 + 10·5 = 100; 100 + 10·2 = 120 -> 100 (lost); 100 - 10 = 90
    assert outs(b, 1.0, [34.0, 36.0, 35.0], sp=29.0) == [100.0, 100.0, 90.0]


def test_E8_pwm_60_percent_of_10s_is_6s_on_4s_off() -> None:
    """spec 3.8 E8 (spec 3.7 PWM output stage): 60 % of a 10 s period = 6 s on, 4 s off."""
    assert pwm_times(60.0, 10.0) == (6.0, 4.0)
    assert pwm_times(0.0, 10.0) == (0.0, 10.0)
    assert pwm_times(150.0, 10.0) == (10.0, 0.0)  # a percentage: limited to 0..100
    with pytest.raises(ParameterError, match="period"):
        pwm_times(50.0, 0.0)
    with pytest.raises(InputError, match="percent"):
        pwm_times(NAN, 10.0)


# ----------------------------------------------------------------------------------------------
# Equations and options, spec 3.3
# ----------------------------------------------------------------------------------------------
def test_i_mode_adds_ki_times_error_per_update_without_time_factor(make: Make) -> None:
    # spec 3.3: Iadj = Ki · e per update, no division by TR and no dt
    b = make(kp=0.0, ki=0.3, min_accumulated_error=0.1, update_interval=5.0)
    assert outs(b, 5.0, [31.0, 31.0], sp=30.0, port="pid_out") == \
        pytest.approx([50.3, 50.6], abs=1e-12)


def test_i_tr_normalise_scales_i_by_100_over_tr(make: Make) -> None:
    # spec 3.3 [?] option i_tr_normalise: Iadj = ki · e · 100/TR = 0.5 · 2 · 8 = 8
    b = make(kp=0.0, ki=0.5, throttling_range=12.5, min_accumulated_error=0.0,
             i_tr_normalise=True)
    assert run(b, 1.0, sp=0.0, pv=2.0)["i_adj"][0] == 8.0
    plain = make(kp=0.0, ki=0.5, throttling_range=12.5, min_accumulated_error=0.0)
    assert run(plain, 1.0, sp=0.0, pv=2.0)["i_adj"][0] == 1.0  # 0.5 · 2, as printed


def test_d_second_difference(make: Make) -> None:
    # spec 3.3 d_form = second_difference [A]: Dadj = kd·(e_k - 2 e_k-1 + e_k-2), kd = 2
    b = make(kp=0.0, ki=0.0, kd=2.0, update_interval=1.0)
    got = [run(b, 1.0, sp=0.0, pv=pv) for pv in (1.0, 3.0, 4.0)]
    # 2·(1 - 0 + 0) = 2; 2·(3 - 2 + 0) = 2; 2·(4 - 6 + 1) = -2
    assert [r["d_adj"][0] for r in got] == [2.0, 2.0, -2.0]
    assert [r["pid_out"][0] for r in got] == [52.0, 54.0, 52.0]


def test_d_tr_normalise_scales_d_by_100_over_tr(make: Make) -> None:
    # spec 3.3 [?]: Dadj = kd·(2 - 0 + 0)·100/12.5 = 16
    b = make(kp=0.0, ki=0.0, kd=1.0, throttling_range=12.5, d_tr_normalise=True)
    assert run(b, 1.0, sp=0.0, pv=2.0)["d_adj"][0] == 16.0


def test_d_as_printed_uses_the_times_between_updates_in_minutes(make: Make) -> None:
    # spec 3.3 d_form = as_printed: Dadj = kd·(e - 2 e_-1/t_-1 + e_-2/t_-2), t in minutes
    b = make(kp=0.0, ki=0.0, kd=1.0, d_form="as_printed", update_interval=30.0)
    r0 = run(b, 1.0, sp=0.0, pv=1.0)  # first update at t = 0: t_-1 = t_-2 = 30 s = 0.5 min
    r1 = run(b, 45.0, sp=0.0, pv=2.0)  # timer 45 >= 30: update at t = 45 (timer left 15)
    r2 = run(b, 15.0, sp=0.0, pv=2.0)  # timer 15 + 15 = 30: update at t = 60
    d0 = 1.0 * (1.0 - 2.0 * 0.0 / 0.5 + 0.0 / 0.5)
    d1 = 1.0 * (2.0 - 2.0 * 1.0 / (45.0 / 60.0) + 0.0 / 0.5)
    d2 = 1.0 * (2.0 - 2.0 * 2.0 / (15.0 / 60.0) + 1.0 / (45.0 / 60.0))
    assert d0 == 1.0 and d1 == pytest.approx(-2.0 / 3.0) and d2 == pytest.approx(-38.0 / 3.0)
    assert [r0["d_adj"][0], r1["d_adj"][0], r2["d_adj"][0]] == \
        pytest.approx([d0, d1, d2], abs=1e-12)
    assert r2["pid_out"][0] == pytest.approx(50.0 + d0 + d1 + d2, abs=1e-12)


def test_error_sign_default_output_rises_with_input_and_option_reverses(make: Make) -> None:
    # spec 3.3 / 7: e = input - setpoint [A]; option setpoint_minus_input
    assert outs(make(**P_ONLY), 1.0, [30.0], sp=29.0) == [60.0]
    assert outs(make(**P_ONLY, error_sign="setpoint_minus_input"), 1.0, [30.0],
                sp=29.0) == [40.0]


def test_startup_initial_output_and_startup_errors_options(make: Make) -> None:
    # spec 3.9 [?]: start-up output = Output at Setpoint; option initial_output
    assert outs(make(**P_ONLY, initial_output=30.0), 1.0, [29.0, 30.0], sp=29.0) == \
        [30.0, 40.0]
    # startup_errors = current: e_-1 = e_-2 = the first error, so no P kick at start-up
    assert outs(make(**P_ONLY, startup_errors="current"), 1.0, [24.0, 25.0], sp=29.0) == \
        [50.0, 60.0]
    # initial output clamped into the limits when it is Output at Setpoint (50 -> 60)
    b = make(**P_ONLY, output_min=60.0)
    assert b.state()["pid_output"] == 60.0 and b.state()["filter_output"] == 60.0


def test_old_output_filtered_option_integrates_the_filter_output(make: Make) -> None:
    # spec 3.6 [A]: the PID integrates its own unfiltered output by default
    common: dict[str, Any] = {"throttling_range": 12.5, "kp": 1.0, "ki": 0.0,
                              "update_interval": 1.0, "filter_period": 1.0,
                              "filter_percentage": 50.0}
    a = make(**common)
    b = make(**common, old_output="filtered")
    # scan 0 (e = 1): OUT = 50 + 8 = 58, F = 50 + 0.5·8 = 54 in both
    # scan 1 (e = 2): unfiltered OUT = 58 + 8 = 66, F = 54 + 0.5·12 = 60
    #                 filtered   OUT = 54 + 8 = 62, F = 54 + 0.5·8 = 58
    assert outs(a, 1.0, [30.0, 31.0], sp=29.0) == [54.0, 60.0]
    assert outs(b, 1.0, [30.0, 31.0], sp=29.0, port="pid_out") == [58.0, 62.0]
    assert b.outputs()["out"].value == 58.0


def test_old_output_filtered_clamps_the_sum_not_the_old_output(make: Make) -> None:
    """Spec 3.3 OUT_k = clamp(OUT_{k-1} + Padj + Iadj + Dadj, OutMin, OutMax) and spec 3.4
    ("the clamp is applied to the stored output"): with old_output = filtered, OUT_{k-1} = F.
    F was clamped before the adjustments were added, so with the filter off (F = OUT) the two
    options differed once the output was outside raised limits (found by an outside audit)."""
    got = {}
    for old in ("unfiltered", "filtered"):
        b = make(kp=1.0, ki=0.0, throttling_range=100.0, update_interval=1.0,
                 output_at_setpoint=10.0, filter_period=0.0, old_output=old)
        b.step(1.0, sp=0.0, pv=0.0)  # OUT = F = 10
        b.set_params(output_min=40.0)
        got[old] = b.step(1.0, sp=0.0, pv=35.0)["pid_out"].value  # Padj = +35
    assert got == {"unfiltered": 45.0, "filtered": 45.0}  # clamp(10 + 35, 40, 100)


# ----------------------------------------------------------------------------------------------
# Retuning (issue 12 point 4): the law is incremental (spec 3.3), so no retune option
# ----------------------------------------------------------------------------------------------
RETUNE: dict[str, Any] = {"throttling_range": 10.0, "kp": 1.0, "ki": 0.3, "kd": 0.0,
                          "min_accumulated_error": 0.1, "output_at_setpoint": 50.0,
                          "update_interval": 1.0}


def test_retune_at_steady_error_moves_the_output_only_by_the_new_increment(make: Make) -> None:
    """spec 3.3: OUT_k = OUT_{k-1} + Padj + Iadj + Dadj, Padj = kp·(e_k - e_{k-1})·100/TR,
    Iadj = ki·e_k, Dadj = kd·(e_k - 2e_{k-1} + e_{k-2}). SP 29, input 30: e = 1. Update 1:
    50 + 1·1·100/10 + 0.3 = 60.3; update 2: + 0.3. At the steady error Padj = Dadj = 0, so
    kp 1 -> 2 adds only Iadj = 0.3 (a positional kp·e·100/TR would jump by 10), TR 10 -> 5
    with kd 0 -> 0.5 adds 0.3 again (a positional P would jump by 2·1·(20 - 10) = 20), and
    ki 0.3 -> 0.6 adds the new Iadj = 0.6."""
    b = make(**RETUNE)
    assert outs(b, 1.0, [30.0, 30.0], sp=29.0, port="pid_out") == \
        pytest.approx([60.3, 60.6], abs=1e-12)
    b.set_params(kp=2.0)
    r = run(b, 1.0)
    assert r["p_adj"][0] == 0.0 and r["d_adj"][0] == 0.0
    assert r["pid_out"][0] == pytest.approx(60.9, abs=1e-12)
    b.set_params(throttling_range=5.0, kd=0.5)
    r = run(b, 1.0)
    assert r["p_adj"][0] == 0.0 and r["d_adj"][0] == 0.0
    assert r["pid_out"][0] == pytest.approx(61.2, abs=1e-12)
    b.set_params(ki=0.6)
    r = run(b, 1.0)
    assert r["i_adj"][0] == pytest.approx(0.6, abs=1e-15)
    assert r["pid_out"][0] == r["out"][0] == pytest.approx(61.8, abs=1e-12)


def test_after_a_retune_the_loop_follows_the_new_tuning(make: Make) -> None:
    """spec 3.3 with kp 2, TR 5, ki 0.6, kd 0.5 set at e = 1 (steady): the input 30 -> 30.5
    gives e = 1.5: Padj = 2·0.5·100/5 = 20, Iadj = 0.6·1.5 = 0.9, Dadj = 0.5·(1.5 - 2 + 1) =
    0.25: 60.6 + 21.15 = 81.75; next (e = 1.5 steady): Padj = 0, Iadj = 0.9, Dadj =
    0.5·(1.5 - 3 + 1) = -0.25: + 0.65 = 82.4."""
    b = make(**RETUNE)
    outs(b, 1.0, [30.0, 30.0], sp=29.0)
    b.set_params(kp=2.0, throttling_range=5.0, ki=0.6, kd=0.5)
    r = run(b, 1.0, pv=30.5)
    assert (r["p_adj"][0], r["i_adj"][0], r["d_adj"][0]) == pytest.approx((20.0, 0.9, 0.25))
    assert r["pid_out"][0] == pytest.approx(81.75, abs=1e-12)
    assert run(b, 1.0)["pid_out"][0] == pytest.approx(82.4, abs=1e-12)


# ----------------------------------------------------------------------------------------------
# Timing: spec 3.3 (fixed update interval), 3.6 (filter period, independent)
# ----------------------------------------------------------------------------------------------
def test_updates_every_interval_at_fast_scans_without_drift(make: Make) -> None:
    # spec 3.3: one update per update_interval; 0.1 s scans, 1 s interval: scans 0, 10, 20, ...
    b = make(**COUNTER)
    got = outs(b, 0.1, [30.0] * 100, sp=29.0, port="pid_out")
    assert got == [51.0 + k // 10 for k in range(100)]


def test_slow_interval_with_0_3s_scans_updates_at_first_scan_past_each_interval(
        make: Make) -> None:
    # timers accumulate dt and subtract the interval: updates at t = 0, 1.2, 2.1, 3.0, 4.2
    b = make(**COUNTER)
    got = outs(b, 0.3, [30.0] * 15, sp=29.0, port="pid_out")
    updates_at = {0, 4, 7, 10, 14}
    expected = []
    n = 0
    for k in range(15):
        n += k in updates_at
        expected.append(50.0 + n)
    assert got == expected


def test_scan_longer_than_interval_updates_once_per_scan(make: Make) -> None:
    # at most one update per scan; missed updates are dropped (module docstring, Timing)
    b = make(**{**COUNTER, "update_interval": 2.0})
    assert outs(b, 5.0, [30.0] * 3, sp=29.0, port="pid_out") == [51.0, 52.0, 53.0]


def test_filter_and_pid_run_on_independent_timers(make: Make) -> None:
    # spec 3.6: the filter runs every filter period, independently of the PID update
    b = make(**{**COUNTER, "update_interval": 4.0}, filter_period=6.0, filter_percentage=50.0)
    got = [run(b, 1.0, sp=29.0, pv=30.0) for _ in range(14)]
    # PID +1 at t = 0, 4, 8, 12; filter at t = 0, 6, 12 (after the PID in the same scan):
    # F = 50 + 0.5·1 = 50.5; 50.5 + 0.5·(52 - 50.5) = 51.25; 51.25 + 0.5·(54 - 51.25) = 52.625
    assert [r["pid_out"][0] for r in got] == [51.0] * 4 + [52.0] * 4 + [53.0] * 4 + [54.0] * 2
    assert [r["out"][0] for r in got] == [50.5] * 6 + [51.25] * 6 + [52.625] * 2


def test_filter_at_fast_scans_steps_exactly_at_each_period(make: Make) -> None:
    # spec 3.6 with 0.1 s scans: 60 scans make one 6 s period despite binary rounding
    b = make(throttling_range=12.5, kp=1.0, ki=0.0, filter_period=6.0, filter_percentage=75.0)
    out = [run(b, 0.1, sp=29.0, pv=30.0)["out"][0] for _ in range(121)]
    assert out == [56.0] * 60 + [57.5] * 60 + [57.875]


# ----------------------------------------------------------------------------------------------
# Override cell, spec 3.7
# ----------------------------------------------------------------------------------------------
def test_override_forces_out_while_the_pid_keeps_running(make: Make) -> None:
    # spec 3.7: Override comes after PID and Filter; the PID's stored output is not updated
    # from it [?] (default), so out returns to the PID's output when the override ends
    b = make(**P_ONLY, output_max=80.0)
    assert run(b, 1.0, sp=29.0, pv=29.0)["out"] == (50.0, GOOD)
    r = run(b, 1.0, sp=29.0, pv=30.0, override=90.0)
    assert r["out"] == (90.0, GOOD_CONST)  # not limited by Output at Maximum (a PID clamp)
    assert r["pid_out"][0] == 60.0
    assert run(b, 1.0, sp=29.0, pv=31.0, override=120.0)["out"] == (100.0, GOOD_CONST)  # 0..100
    assert run(b, 1.0, sp=29.0, pv=31.0, override=NAN)["out"] == (70.0, GOOD)


def test_override_options_updates_pid_and_output_limits(make: Make) -> None:
    # spec 3.7 [?] option: the override sets the PID's stored output (bumpless release)
    b = make(**P_ONLY, override_updates_pid=True)
    run(b, 1.0, sp=29.0, pv=29.0)
    assert run(b, 1.0, sp=29.0, pv=30.0, override=20.0)["pid_out"][0] == 20.0
    assert run(b, 1.0, sp=29.0, pv=31.0, override=NAN)["out"][0] == 30.0  # 20 + 10·1
    # [A] option: override limited to output_min..output_max instead of 0..100 %
    c = make(**P_ONLY, output_max=80.0, override_limits="output_limits")
    assert run(c, 1.0, sp=29.0, pv=29.0, override=90.0)["out"] == (80.0, GOOD_CONST)


def test_override_with_bad_status_is_no_override(make: Make) -> None:
    b = make(**P_ONLY)
    assert run(b, 1.0, sp=29.0, pv=30.0, override=(70.0, 0))["out"] == (60.0, GOOD)
    assert run(b, 1.0, sp=29.0, pv=30.0, override=(70.0, UNC))["out"] == (70.0, GOOD_CONST)


# ----------------------------------------------------------------------------------------------
# Bad and uncertain input, status (module docstring; E2 has no status, [A])
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("bad", [{"pv": NAN}, {"pv": INF}, {"sp": -INF}, {"pv": (31.0, 0)},
                                 {"sp": (29.0, 0x1C)}])
def test_bad_pv_or_sp_holds_the_output(make: Make, bad: dict[str, Any]) -> None:
    b = make(**P_ONLY)
    assert run(b, 1.0, sp=29.0, pv=29.0)["out"] == (50.0, GOOD)
    inputs: dict[str, Any] = {"sp": 29.0, "pv": 31.0, **bad}
    r = run(b, 1.0, **inputs)
    assert r["out"] == (50.0, UNC_LUV_CONST)
    assert r["pid_out"][0] == 50.0 and r["p_adj"][0] == 0.0
    # recovery continues from the last good error (0): 50 + 10·(2 - 0) = 70
    assert run(b, 1.0, sp=29.0, pv=31.0)["out"] == (70.0, GOOD)


def test_bad_input_skips_the_due_update_until_the_next_interval(make: Make) -> None:
    b = make(**{**P_ONLY, "update_interval": 2.0})
    got = [run(b, 1.0, sp=29.0, pv=pv)["out"] for pv in (29.0, 30.0, NAN, 31.0, 31.0)]
    # updates due at t = 0, 2, 4; t = 2 is lost to the bad input, t = 3 is not due
    assert got == [(50.0, GOOD), (50.0, GOOD), (50.0, UNC_LUV_CONST), (50.0, GOOD),
                   (70.0, GOOD)]


def test_bad_input_failsafe_option(make: Make) -> None:
    b = make(**P_ONLY, bad_input="failsafe", failsafe_output=5.0)
    run(b, 1.0, sp=29.0, pv=29.0)
    r = run(b, 1.0, sp=29.0, pv=NAN)
    assert r["out"] == (5.0, UNC_SUBST_CONST) and r["pid_out"][0] == 50.0
    assert run(b, 1.0, sp=29.0, pv=30.0)["out"] == (60.0, GOOD)


def test_status_uncertain_input_and_limit_bits(make: Make) -> None:
    b = make(**P_ONLY)
    assert run(b, 1.0, sp=29.0, pv=(30.0, UNC))["out"] == (60.0, UNC)
    assert run(b, 1.0, sp=29.0, pv=35.0)["out"] == (100.0, GOOD_HIGH)
    assert run(b, 1.0, sp=29.0, pv=25.0)["out"] == (0.0, GOOD_LOW)


def test_extreme_inputs_never_crash_and_stay_in_range(make: Make) -> None:
    rng = np.random.default_rng(3)
    values = [NAN, INF, -INF, 1e308, -1e308, 0.0, 30.0, 1e-300]
    for params in ({}, {"kd": 5.0, "d_form": "as_printed", "update_interval": 0.5},
                   {"kp": 0.0, "kd": 1.0, "filter_period": 1.0, "old_output": "filtered"}):
        b = make(**params, output_min=10.0, output_max=90.0)
        for _ in range(500):
            inputs = {"pv": float(rng.choice(values)), "sp": float(rng.choice(values)),
                      "override": float(rng.choice([NAN, NAN, NAN, 1e308, 50.0]))}
            r = run(b, float(rng.uniform(0.01, 3.0)), **inputs)
            assert 0.0 <= r["out"][0] <= 100.0
            assert 10.0 <= r["pid_out"][0] <= 90.0


@pytest.mark.parametrize("bad", [{"pv": 1e308}, {"pv": -1e308}, {"sp": 3.5e38},
                                 {"pv": 1.0000001e12}, {"sp": -2e12}])
def test_values_beyond_1e12_eu_are_bad_input(make: Make, bad: dict[str, Any]) -> None:
    # issue 11 point 1: beyond ±1e12 EU is not a measurement (it used to saturate there, so
    # pv = 1e308 drove the output to 100 % with a Good status): the PID holds, 0x47
    b = make(**P_ONLY)
    assert run(b, 1.0, sp=29.0, pv=29.0)["out"] == (50.0, GOOD)
    r = run(b, 1.0, **{"sp": 29.0, "pv": 30.0, **bad})
    assert r["out"] == (50.0, UNC_LUV_CONST) and r["pid_out"][0] == 50.0
    assert run(b, 1.0, sp=29.0, pv=30.0)["out"] == (60.0, GOOD)  # recovers at once


def test_an_input_at_1e12_eu_is_used(make: Make) -> None:
    b = make(**P_ONLY)
    assert run(b, 1.0, sp=0.0, pv=1e12)["out"] == (100.0, GOOD_HIGH)


def test_overflowing_adjustment_is_skipped_like_bad_input(make: Make) -> None:
    # kp·Δe·100/TR = 1e300·1·100/1e-10 overflows: the update is skipped (hold, 0x47), no
    # adjustment or state becomes inf; an error change small enough is computed again
    b = make(**{**P_ONLY, "kp": 1e300, "throttling_range": 1e-10})
    assert run(b, 1.0, sp=29.0, pv=29.0)["out"] == (50.0, GOOD)
    r = run(b, 1.0, sp=29.0, pv=30.0)
    assert r["out"] == (50.0, UNC_LUV_CONST)
    assert (r["p_adj"][0], r["pid_out"][0]) == (0.0, 50.0)
    assert all(math.isfinite(v) for v in b.x)
    # Δe = 1e-300 (from the stored e = 0): Padj = 1e300·1e-300·100/1e-10 = 1e12 -> 100 %
    assert run(b, 1.0, sp=0.0, pv=1e-300)["out"] == (100.0, GOOD_HIGH)
    raw = loopworks.create_block("e2.pid", jit=False, **{**P_ONLY, "kp": 1e300,
                                                         "throttling_range": 1e-10})
    raw_step(raw, 1.0, {"sp": 29.0, "pv": 29.0})
    raw_step(raw, 1.0, {"pv": 30.0})  # the kernel by itself, without the guard's fallback
    assert (raw.y[0], raw.ys[0]) == (50.0, UNC_LUV_CONST)
    assert np.isfinite(raw.x).all() and np.isfinite(raw.y).all()


@pytest.mark.parametrize("value", [NAN, INF, -INF])
def test_non_finite_override_is_no_override(make: Make, value: float) -> None:
    # spec 3.7: NaN = no override (the input's default); ±inf is Bad input: no override either;
    # a huge finite override is limited to 0..100 % (override_limits = percent)
    b = make(**P_ONLY)
    assert run(b, 1.0, sp=29.0, pv=30.0, override=value)["out"] == (60.0, GOOD)
    assert run(b, 1.0, sp=29.0, pv=30.0, override=1e308)["out"] == (100.0, GOOD_CONST)
    assert run(b, 1.0, sp=29.0, pv=30.0, override=value)["out"] == (60.0, GOOD)


def test_issue_nan_then_1e308_pv_then_good_pv_controls_again(make: Make) -> None:
    # issue 11 point 1 for e2.pid: after a burst of NaN and 1e308 the next good input
    # continues from the stored error (29 -> e = 0): input 31 gives 50 + 10·2 = 70
    b = make(**P_ONLY)
    assert run(b, 1.0, sp=29.0, pv=29.0)["out"] == (50.0, GOOD)
    for pv in (NAN, 1e308, -INF):
        assert run(b, 1.0, sp=29.0, pv=pv)["out"] == (50.0, UNC_LUV_CONST)
    assert run(b, 1.0, sp=29.0, pv=31.0)["out"] == (70.0, GOOD)


def test_as_printed_d_with_a_tiny_interval_gives_no_nan(make: Make) -> None:
    # d_form = as_printed divides by t/60; written 60·e/t, a zero error is 0 for any t > 0
    # (t/60 = 5e-324/60 underflows to 0, and 0/0 was NaN: the update was lost)
    b = make(kd=1.0, d_form="as_printed", update_interval=5e-324)
    assert run(b, 1.0, sp=29.0, pv=29.0)["out"] == (50.0, GOOD)


# ----------------------------------------------------------------------------------------------
# Start-up output before the first scan (issue 11 point 8; spec 3.9 [?])
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("params", "start"), [({}, 50.0), ({"initial_output": 30.0}, 30.0),
                                               ({"output_min": 60.0}, 60.0)])
def test_publishes_its_start_up_output_before_the_first_scan(make: Make, params: dict[str, Any],
                                                             start: float) -> None:
    # spec 3.9: the PID and the filter start at initial_output (default Output at Setpoint,
    # clamped to the output limits): that is what a block reading it first sees, not 0
    b = make(**params)
    before = b.outputs()
    assert before["out"] == (start, GOOD) and before["pid_out"] == (start, GOOD)
    assert (before["p_adj"].value, before["i_adj"].value, before["d_adj"].value) == (0, 0, 0)
    b.reset()
    assert b.outputs()["out"].value == start


def test_a_block_that_reads_it_first_sees_the_start_up_output() -> None:
    # issue 11 point 8: in module order the process runs first and reads e2.out at t = 0:
    # it sees Output at Setpoint 50 %, so a gain-1, y0 = 50 process stays at 50
    from loopworks.sim.module import Module
    ctl = loopworks.create_block("e2.pid")
    proc = loopworks.create_block("process.first_order", gain=1.0, time_constant=5.0, y0=50.0)
    mod = Module({"proc": proc, "ctl": ctl}, wires={"proc.u": "ctl.out", "ctl.pv": "proc.y"},
                 inputs={"ctl": {"sp": 50.0}})
    mod.scan(0.5)
    assert proc.y[0] == 50.0 and ctl.y[0] == 50.0


# ----------------------------------------------------------------------------------------------
# Parameters
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("params", "needle"), [
    ({"throttling_range": 0.0}, "throttling_range"),
    ({"kp": -1.0}, "kp"),
    ({"output_max": 120.0}, "output_max"),
    ({"output_min": 60.0, "output_max": 40.0}, "output_max"),
    ({"min_accumulated_error": -0.1}, "min_accumulated_error"),
    ({"update_interval": 0.0}, "update_interval"),
    ({"filter_period": -6.0}, "filter_period"),
    ({"filter_percentage": 150.0}, "filter_percentage"),
    ({"d_form": "textbook"}, "d_form"),
    ({"initial_output": 10.0, "output_min": 20.0}, "initial_output"),
    ({"i_tr_normalise": "maybe"}, "i_tr_normalise"),
    ({"throttling_range": NAN}, "throttling_range"),
    ({"throttling_range": 5e-324}, "throttling_range"),  # 100 %/TR overflows
    ({"bogus": 1.0}, "bogus"),
])
def test_bad_parameters_name_the_parameter(params: dict[str, Any], needle: str) -> None:
    with pytest.raises(ParameterError, match=needle):
        loopworks.create_block("e2.pid", **params)


def test_parameter_names_in_any_case() -> None:
    b = loopworks.create_block("e2.pid", THROTTLING_RANGE=5.0, Update_Interval=3.0)
    assert b.params["throttling_range"] == 5.0 and b.params["update_interval"] == 3.0


# ----------------------------------------------------------------------------------------------
# State, jit, replay
# ----------------------------------------------------------------------------------------------
def test_resume_from_saved_state_equals_uninterrupted_run() -> None:
    params: dict[str, Any] = {"kd": 0.5, "d_form": "as_printed", "update_interval": 1.5,
                              "filter_period": 2.5, "filter_percentage": 60.0}
    rng = np.random.default_rng(11)
    seq = [(float(rng.uniform(0.1, 1.0)),
            {"sp": 30.0, "pv": float(rng.uniform(25.0, 35.0)),
             "override": float(rng.choice([NAN] * 9 + [40.0]))}) for _ in range(300)]
    whole = loopworks.create_block("e2.pid", **params)
    expected = [dict(whole.step(dt, **inp)) for dt, inp in seq]
    first = loopworks.create_block("e2.pid", **params)
    for dt, inp in seq[:150]:
        first.step(dt, **inp)
    saved = json.loads(json.dumps(first.state_dict()))
    second = loopworks.create_block("e2.pid", **params)
    second.load_state(saved)
    rest = [dict(second.step(dt, **inp)) for dt, inp in seq[150:]]
    assert rest == expected[150:]


def test_replay_cli_runs_e2_pid(tmp_path: Path) -> None:
    # the module docstring's replay example: P only, 1 s updates; override 70 at t = 2
    path = write_csv(tmp_path / "e2.csv", ["t", "sp", "pv", "override"],
                     [[0, 29, 24, "nan"], [1, 29, 25, "nan"], [2, 29, 26, 70],
                      [3, 29, 27, "nan"]])
    result = CliRunner().invoke(app, ["replay", "e2.pid", str(path), "-p", "ki=0",
                                      "-p", "update_interval=1"])
    assert result.exit_code == 0, result.output
    rows = list(csv.reader(io.StringIO(result.stdout)))
    assert rows[0] == ["t", "out", "pid_out", "p_adj", "i_adj", "d_adj", "working_sp",
                       "out.ST", "working_sp.ST"]
    # 50 + 10·(24 - 29) = 0; +10 each second; the override shows 70 while the PID goes on
    assert [float(r[1]) for r in rows[1:]] == [0.0, 10.0, 70.0, 30.0]
    assert [float(r[2]) for r in rows[1:]] == [0.0, 10.0, 20.0, 30.0]
    assert [float(r[6]) for r in rows[1:]] == [29.0] * 4  # no Setpoint Float
    assert [int(r[7]) for r in rows[1:]] == [GOOD_LOW, GOOD, GOOD_CONST, GOOD]


def test_setpoint_float_shifts_the_setpoint_linearly_across_the_float_range(make: Make) -> None:
    """spec 3.7 step 2: Setpoint Float shifts the setpoint by a value between Low Float and
    High Float as the float input moves across its range; linear interpolation [A], clamped
    at the ends; 0 (both floats) disables it; before the PID cell, so the error is taken
    from the floated setpoint. P only (TR 10, kp 1, 1 s updates), input = SP = 30."""
    b = make(low_float=-2.0, high_float=2.0, float_range_lo=0.0, float_range_hi=100.0,
             ki=0.0, update_interval=1.0)
    got = [b.step(1.0, sp=30.0, pv=30.0, float_in=f) for f in (0.0, 25.0, 100.0, 140.0)]
    assert [r["working_sp"].value for r in got] == [28.0, 29.0, 32.0, 32.0]
    # e = input - setpoint: +2 at the first update: 50 + 10·2 = 70; then -10·Δsp each update
    assert [r["out"].value for r in got] == pytest.approx([70.0, 60.0, 30.0, 30.0])
    assert b.step(1.0, sp=30.0, pv=30.0, float_in=math.nan)["working_sp"].value == 32.0
    bad_sp = b.step(1.0, sp=math.inf, pv=30.0, float_in=50.0)["working_sp"]
    assert (bad_sp.value, bad_sp.status) == (32.0, 0)  # a bad sp: the last one, Bad
    off = make(ki=0.0, update_interval=1.0)  # both floats 0: disabled, float_in ignored
    r = off.step(1.0, sp=30.0, pv=30.0, float_in=75.0)
    assert (r["working_sp"].value, r["out"].value) == (30.0, 50.0)
    with pytest.raises(ParameterError, match="float_range_hi"):
        make(float_range_lo=10.0, float_range_hi=10.0)


def test_a_disabled_setpoint_float_holds_no_shift_for_a_later_enabling(make: Make) -> None:
    """spec 3.7 step 2: 0 disables the float. A shift computed under earlier settings was kept
    while disabled and came back, outside the new [Low Float, High Float], when the float was
    enabled again with no usable float input (found by an outside audit)."""
    b = make(low_float=0.0, high_float=-3.0, ki=0.0)
    assert b.step(1.0, sp=10.0, pv=10.0, float_in=100.0)["working_sp"].value == 7.0
    b.set_params(high_float=0.0)  # both 0: disabled
    assert b.step(1.0, sp=10.0, pv=10.0, float_in=math.nan)["working_sp"].value == 10.0
    b.set_params(low_float=1.0, high_float=2.0)  # enabled, float input not usable: 0 shift
    assert b.step(1.0, sp=10.0, pv=10.0, float_in=math.nan)["working_sp"].value == 10.0
    assert b.step(1.0, sp=10.0, pv=10.0, float_in=100.0)["working_sp"].value == 12.0


@pytest.mark.parametrize(("floats", "fin", "shift"), [
    ({"low_float": -1e308, "high_float": 1e308}, 100.0, 1e308),
    ({"low_float": -1e308, "high_float": 1e308}, 0.0, -1e308),
    ({"low_float": -1e308, "high_float": 1e308}, 50.0, 0.0),
    ({"low_float": 1.0, "high_float": 3.0, "float_range_lo": -1e308,
      "float_range_hi": 1e308}, 0.0, 2.0),
    ({"low_float": 1.0, "high_float": 3.0, "float_range_lo": -1e308,
      "float_range_hi": 1e308}, 5e307, 2.5),
])
def test_the_setpoint_float_is_finite_for_any_finite_settings(
        make: Make, floats: dict[str, float], fin: float, shift: float) -> None:
    """Floats and ranges accept any finite number; the interpolation Low + (High - Low)·r
    overflowed for floats of ±1e308 (shift inf kept in the state) and r for a ±1e308 range
    (found by an outside audit). Midpoints by hand: r = (fin - lo)/(hi - lo)."""
    b = make(**floats, ki=0.0)
    b.step(1.0, sp=0.0, pv=0.0, float_in=fin)
    assert b.state()["float_shift"] == pytest.approx(shift, rel=1e-12, abs=1e-12)


def test_blocks_cli_documents_parameters_with_spec_sections() -> None:
    result = CliRunner().invoke(app, ["blocks", "e2.pid", "--markdown"])
    assert result.exit_code == 0, result.output
    for needle in ("| throttling_range | EU | 10 | (0, inf) |", "spec 3.5", "i_tr_normalise",
                   "Options for the spec's [A]/[?] points"):
        assert needle in result.stdout
