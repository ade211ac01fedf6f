"""The GE PACSystems PID blocks (``ge.pid_ind``, ``ge.pid_isa``) against vendor-blocks.md
section 1 and seed 003.

Every worked example of spec 1.9 (G1-G15) is a test named after its id. Expected values come
from the spec or from hand arithmetic written beside the assertion (the integer rules of spec
1.5: P = w6·e/100, ΔI = w8·e·dt_ticks/10^7 with dt_ticks in 100 µs, D = w7·Δ·100/dt_ticks),
never from a run of the block. Most tests run twice through the ``make`` fixture: with the
compiled (numba) kernel and with the interpreted one.
"""

from __future__ import annotations

import inspect
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

import loopworks
import loopworks.cli
from loopworks.blocks.block import Block
from loopworks.errors import ParameterError
from loopworks.vendors import ge_pacsystems
from loopworks.vendors.ge_pacsystems import from_reference_array
from tests.csvfiles import write_csv

NAN = math.nan
Make = Callable[..., Block]

# A bipolar CV span so that negative outputs are visible (the default clamps are 0..32000).
BIPOLAR = {"upper_clamp": 32000.0, "lower_clamp": -32000.0}


@pytest.fixture(params=[True, False], ids=["compiled", "interpreted"])
def make(request: pytest.FixtureRequest) -> Make:
    """``make(kind, **params)``: a GE block with the compiled or the interpreted kernel."""
    jit = request.param

    def _make(kind: str = "ge.pid_ind", **params: Any) -> Block:
        return loopworks.create_block(kind, jit=jit, **params)

    return _make


def solve(block: Block, clock: float, **inputs: float) -> tuple[float, float, float]:
    """One sweep at controller time ``clock`` (s): (cv, output, ok)."""
    r = block.step(0.01, clock=clock, **{k: float(v) for k, v in inputs.items()})
    return r["cv"].value, r["output"].value, r["ok"].value


def held(block: Block) -> dict[str, float]:
    """The state a skipped solution must leave unchanged: all but the clock reading."""
    return {k: v for k, v in block.state().items() if k != "clock"}


def words_of(block: Block) -> dict[int, int]:
    """The reference-array words 3-13 a GE block runs with."""
    assert isinstance(block, ge_pacsystems.GEPIDBlock)
    return block.parameter_words()


def vendor_array() -> list[int]:
    """The vendor's example array of GFK-2950C section 7.7 (spec 1.2): words 3..13."""
    words = [0] * 40
    words[2:13] = [10, 5, -5, 400, 0, 1500, 0, 20000, 4000, 0, 0]
    return words


# ----------------------------------------------------------------------------------------------
# Spec 1.9 worked examples
# ----------------------------------------------------------------------------------------------
def test_G1_proportional_term(make: Make) -> None:
    """spec 1.9 G1: Kp word 400, e = 10 counts gives P = 400*10/100 = 40 counts."""
    pid = make(kp=4.0, sample_period=0.1, **BIPOLAR)
    assert words_of(pid)[6] == 400
    assert solve(pid, 0.1, sp=10, pv=0) == (40.0, 40.0, 1.0)
    assert solve(pid, 0.2, sp=0, pv=10)[0] == -40.0  # e = -10: -400*10/100


def test_G2_integral_remainder_carried(make: Make) -> None:
    """spec 1.9 G2: Ki word 1500, e = 20, dt = 50 ms (500 ticks): 1500*20*500/10^7 = 1.5
    counts per solution; increments 1,2,1,2,1,2, integral 1,3,4,6,7,9, the remainder alternating
    half a count (500 thousandths) and 0."""
    pid = make(kp=0.0, ki=1.5, sample_period=0.05)
    outs, rems = [], []
    for k in range(1, 7):
        outs.append(solve(pid, 0.05 * k, sp=20, pv=0)[1])
        rems.append(pid.state()["int_remainder"])
    assert outs == [1.0, 3.0, 4.0, 6.0, 7.0, 9.0]
    assert rems == [500.0, 0.0, 500.0, 0.0, 500.0, 0.0]


def test_G3_integral_at_100ms(make: Make) -> None:
    """spec 1.9 G3: as G2 with dt = 100 ms: 1500*20*1000/10^7 = 3 counts each solution."""
    pid = make(kp=0.0, ki=1.5, sample_period=0.1)
    assert [solve(pid, 0.1 * k, sp=20, pv=0)[1] for k in range(1, 5)] == [3.0, 6.0, 9.0, 12.0]
    assert pid.state()["int_remainder"] == 0.0


def test_G4_slew_16_counts_per_50ms(make: Make) -> None:
    """spec 1.9 G4: word 12 = 100 s, dt = 50 ms: 32000*0.05/100 = 16 counts per solution.
    Ki word 10000 keeps pushing (ΔI = 10000*10000*500/10^7 = 5000 per solution)."""
    pid = make(kp=1.0, ki=10.0, min_slew_time=100.0, sample_period=0.05)
    outs = [solve(pid, 0.05 * k, sp=10000, pv=0)[1] for k in range(1, 4)]
    assert outs == [16.0, 32.0, 48.0]
    # spec 1.7 step 10: the integral is adjusted so the sum equals the limited output
    assert pid.state()["integral"] == 48.0 - 10000.0


def test_slew_limited_p_step_is_absorbed_by_the_integral(make: Make) -> None:
    """spec 1.7 step 10 [V], read literally: the integral follows the limited output, so with
    no integral action (Ki = 0) a proportional step beyond the rate limit is lost: the output
    stays at the first limited value, 16 (and the integral at 16 - 10000)."""
    pid = make(kp=1.0, min_slew_time=100.0, sample_period=0.05)
    assert [solve(pid, 0.05 * k, sp=10000, pv=0)[1] for k in range(1, 4)] == [16.0] * 3
    assert pid.state()["integral"] == 16.0 - 10000.0


def test_G5_slew_160_counts_per_2500ms(make: Make) -> None:
    """spec 1.9 G5: word 12 = 500 s, dt = 2.5 s: 32000*2.5/500 = 160 counts."""
    pid = make(kp=1.0, ki=1.0, min_slew_time=500.0, sample_period=2.5)  # ΔI = 25000 each
    assert [solve(pid, 2.5 * k, sp=10000, pv=0)[1] for k in range(1, 4)] == [160.0, 320.0,
                                                                               480.0]


def test_G6_dead_band_strict_edges(make: Make) -> None:
    """spec 1.9 G6: band ±5, bit 3 = 0: e = 4, 5, 8, -8 give e_db = 0, 5, 8, -8 (P with
    Kp = 1.00 is e_db)."""
    pid = make(kp=1.0, deadband_pos=5, deadband_neg=-5, sample_period=0.1, **BIPOLAR)
    got = [solve(pid, 0.1 * (k + 1), sp=e, pv=0)[1] for k, e in enumerate([4, 5, 8, -8])]
    assert got == [0.0, 5.0, 8.0, -8.0]


def test_G7_dead_band_subtract(make: Make) -> None:
    """spec 1.9 G7: band ±5, bit 3 = 1: e = 4, 8, -8 give e_db = 0, 3, -3."""
    pid = make(kp=1.0, deadband_pos=5, deadband_neg=-5, deadband_subtract=True,
               sample_period=0.1, **BIPOLAR)
    got = [solve(pid, 0.1 * (k + 1), sp=e, pv=0)[1] for k, e in enumerate([4, 8, -8])]
    assert got == [0.0, 3.0, -3.0]


def test_G8_derivative_on_error_sp_step(make: Make) -> None:
    """spec 1.9 G8: Kd word 100, SP step +50, PV constant, dt = 0.1 s:
    D = 100*50*100/1000 = 500 on that solution, 0 afterwards."""
    pid = make(kp=0.0, kd=1.0, sample_period=0.1, **BIPOLAR)
    assert solve(pid, 0.1, sp=0, pv=0)[1] == 0.0
    assert solve(pid, 0.2, sp=50, pv=0)[1] == 500.0
    assert solve(pid, 0.3, sp=50, pv=0)[1] == 0.0


def test_G9_derivative_on_pv_ignores_sp_step(make: Make) -> None:
    """spec 1.9 G9: as G8 with bit 2 = 1: D = 0."""
    pid = make(kp=0.0, kd=1.0, derivative_on_pv=True, sample_period=0.1, **BIPOLAR)
    assert solve(pid, 0.1, sp=0, pv=0)[1] == 0.0
    assert solve(pid, 0.2, sp=50, pv=0)[1] == 0.0


def test_G10_derivative_on_pv_rise(make: Make) -> None:
    """spec 1.9 G10: bit 0 = 0, bit 2 = 1, PV rises 20 in 0.1 s, Kd 1.00: D = -200."""
    pid = make(kp=0.0, kd=1.0, derivative_on_pv=True, sample_period=0.1, **BIPOLAR)
    solve(pid, 0.1, sp=0, pv=0)
    assert solve(pid, 0.2, sp=0, pv=20)[1] == -200.0


@pytest.mark.parametrize(("direct", "on_pv", "expected"), [
    (False, False, 300.0),  # ΔSP - ΔPV = 50 - 20
    (True, False, -300.0),  # ΔPV - ΔSP = 20 - 50
    (False, True, -200.0),  # -ΔPV
    (True, True, 200.0),  # +ΔPV
])
def test_seed003_derivative_table(make: Make, direct: bool, on_pv: bool,
                                  expected: float) -> None:
    """seed 003 / spec 1.3 table: the Δ used for the derivative, by error mode (bit 0) and
    derivative action (bit 2). ΔSP = +50, ΔPV = +20, Kd word 100, dt = 0.1 s, so
    D = 100*Δ*100/1000 = 10·Δ."""
    pid = make(kp=0.0, kd=1.0, direct_acting=direct, derivative_on_pv=on_pv,
               sample_period=0.1, **BIPOLAR)
    solve(pid, 0.1, sp=0, pv=0)
    assert solve(pid, 0.2, sp=50, pv=20)[1] == expected


def test_G11_isa_and_its_ind_equivalent(make: Make) -> None:
    """spec 1.9 G11: ISA Kc 2.00, Ti 10 s, Td 0.5 s is IND Kp 2.00 (word 200), Ki 0.2/s
    (word 200), Kd 1.00 s (word 100); the two run identically."""
    isa = make("ge.pid_isa", kc=2.0, ti=10.0, td=0.5, sample_period=0.1, **BIPOLAR)
    kc, ti, td = 2.0, 10.0, 0.5
    ind = make("ge.pid_ind", kp=kc, ki=kc / ti, kd=kc * td, sample_period=0.1, **BIPOLAR)
    w = words_of(isa)
    assert (w[6], w[7], w[8]) == (200, 50, 100)  # word 8 = 1000/Ti
    w = words_of(ind)
    assert (w[6], w[8], w[7]) == (200, 200, 100)
    # first solution by hand: e = 100, Δ = 100 (word 20 starts at 0), dt = 1000 ticks:
    # P = 200*100/100 = 200, ΔI = 200*100*1000/10^7 = 2, D = 100*100*100/1000 = 1000
    assert solve(isa, 0.1, sp=100, pv=0)[1] == 1202.0
    assert solve(ind, 0.1, sp=100, pv=0)[1] == 1202.0
    for k, (sp, pv) in enumerate([(100, 7), (130, 20), (130, 60), (90, 61), (90, 95)], 2):
        assert solve(isa, 0.1 * k, sp=sp, pv=pv) == solve(ind, 0.1 * k, sp=sp, pv=pv)


def _g12_to_clamp(pid: Block) -> list[float]:
    """Spec 1.9 G12 run: 3 Manual solutions at 8000, then Auto until t = 10 s."""
    for k in range(1, 4):
        assert solve(pid, 0.1 * k, sp=10000, pv=9000, man=1, manual_command=8000)[0] == 8000.0
    # Manual: P = 400*1000/100 = 4000, integral back-calculated to 8000 - 4000 = 4000
    assert pid.state()["integral"] == 4000.0
    return [solve(pid, 0.1 * k, man=0, manual_command=NAN)[0] for k in range(4, 101)]


def test_G12_vendor_array_manual_then_auto(make: Make) -> None:
    """spec 1.9 G12: the vendor array, SP 10000, PV 9000 open loop, Manual at 8000 then Auto:
    CV = 8150, 8300, ... (+150 = 1500*1000*1000/10^7 per 100 ms), the 20000 clamp after 80
    solutions, and with bit 4 = 0 the integral pinned at 20000 - 4000 = 16000."""
    pid = from_reference_array(vendor_array(), kind="ge.pid_ind", jit=make().jit)
    cvs = _g12_to_clamp(pid)
    assert cvs[:7] == [8150.0, 8300.0, 8450.0, 8600.0, 8750.0, 8900.0, 9050.0]
    assert cvs[79] == 20000.0 and cvs[78] == 19850.0  # 8000 + 80*150
    assert all(cv == 20000.0 for cv in cvs[79:])
    assert pid.state()["integral"] == 16000.0


@pytest.mark.parametrize("bit4", [0, 1])
def test_G13_leaving_the_clamp(make: Make, bit4: int) -> None:
    """spec 1.9 G13: at the clamp PV jumps to 11000 (e = -1000, P = -4000):
    Output = -4000 + 16000 - 150 = 11850 with bit 4 = 0 and also with bit 4 = 1 (the integral
    held at 16000, the value when the clamp first engaged)."""
    words = vendor_array()
    words[12] = bit4 << 4
    pid = from_reference_array(words, kind="ge.pid_ind", jit=make().jit)
    _g12_to_clamp(pid)
    assert pid.state()["integral"] == 16000.0
    assert solve(pid, 10.1, pv=11000)[0] == 11850.0
    assert pid.state()["integral"] == 15850.0


def test_G14_sample_period_0_with_9ms_sweeps(make: Make) -> None:
    """spec 1.9 G14: sample period 0 and 9 ms sweeps: a solution every second sweep with
    dt = 18 ms (180 ticks). With Ki word 1000 and e = 100 each solution adds
    1000*100*180/10^7 = 1.8 counts: integral 1.8, 3.6, 5.4, 7.2 (whole parts 1, 3, 5, 7)."""
    pid = make(kp=0.0, ki=1.0)
    outs, last = [], []
    for _ in range(8):
        outs.append(pid.step(0.009, sp=100.0, pv=0.0)["output"].value)  # own clock: 9 ms
        last.append(pid.state()["last_solution"])
    assert outs == [0.0, 1.0, 1.0, 3.0, 3.0, 5.0, 5.0, 7.0]
    assert last == [0.0, 180.0, 180.0, 360.0, 360.0, 540.0, 540.0, 720.0]


def test_G15_output_polarity(make: Make) -> None:
    """spec 1.9 G15: bit 1 = 1 and Output 12000: word 19 = 12000, CV = -12000."""
    pid = make(kp=0.0, bias=12000, invert_output=True, sample_period=0.1, **BIPOLAR)
    assert solve(pid, 0.1, sp=0, pv=0) == (-12000.0, 12000.0, 1.0)


# ----------------------------------------------------------------------------------------------
# Timing (spec 1.7 step 3, first solution / long gap)
# ----------------------------------------------------------------------------------------------
def test_overshoot_does_not_accumulate(make: Make) -> None:
    """spec 1.7 step 3 [D]: 30 ms sweeps and a 100 ms period solve every 120 ms."""
    pid = make(kp=0.0, ki=1.0, sample_period=0.1)
    solved = []
    for k in range(1, 13):
        solve(pid, 0.03 * k, sp=100, pv=0)
        solved.append(pid.state()["last_solution"])
    assert sorted(set(solved) - {0.0}) == [1200.0, 2400.0, 3600.0]


def test_between_solutions_cv_holds_and_ok_is_on(make: Make) -> None:
    """spec 1.7 step 3 and 1.1: a sweep before the period has elapsed changes nothing; the
    block executed without a parameter error, so ok is on."""
    pid = make(kp=1.0, sample_period=0.5)
    assert solve(pid, 0.5, sp=10, pv=0) == (10.0, 10.0, 1.0)
    assert solve(pid, 0.6, sp=20, pv=0) == (10.0, 10.0, 1.0)
    assert solve(pid, 1.0, sp=20, pv=0) == (20.0, 20.0, 1.0)


def test_first_solution_after_a_long_clock_time_steps_the_integral(make: Make) -> None:
    """spec 1.7 "first solution / long gap": words 24-26 start at 0, so a first solution at
    clock 100 s has dt = 10^6 ticks: ΔI = 1000*10*10^6/10^7 = 1000 counts at once."""
    pid = make(kp=0.0, ki=1.0, sample_period=0.1)
    assert solve(pid, 100.0, sp=10, pv=0)[1] == 1000.0


def test_loading_the_clock_avoids_the_step(make: Make) -> None:
    """spec 1.7: the SVC_REQ remedy (load_clock_at_start) or a loaded time of last solution
    give a first dt of one period: ΔI = 1000*10*1000/10^7 = 1 count."""
    pid = make(kp=0.0, ki=1.0, sample_period=0.1, load_clock_at_start=True)
    assert solve(pid, 100.0, sp=10, pv=0) == (0.0, 0.0, 1.0)  # the clock is loaded: no solve
    assert solve(pid, 100.1, sp=10, pv=0)[1] == 1.0
    pid = make(kp=0.0, ki=1.0, sample_period=0.1, initial_last_solution=99.9)
    assert solve(pid, 100.0, sp=10, pv=0)[1] == 1.0


def test_the_clock_is_loaded_as_power_flow_comes_on_not_at_an_unpowered_first_sweep(
        make: Make) -> None:
    """spec 1.2 words 24-26: load the clock "before re-enabling a long-stopped loop, to avoid
    a huge first dt". It was loaded at the first sweep, powered or not, so a block first
    enabled at 1000 s still took the Ki·e·1000 s step (found by an outside audit). Now as
    power flow comes on, and again at each re-enabling: ΔI of one period = 1 count."""
    pid = make(kp=0.0, ki=1.0, sample_period=0.1, load_clock_at_start=True)
    assert solve(pid, 0.1, sp=10, pv=0, enable=0)[2] == 0.0  # not powered
    assert solve(pid, 1000.0, sp=10, pv=0, enable=1) == (0.0, 0.0, 1.0)  # loaded: no solve
    assert solve(pid, 1000.1, sp=10, pv=0, enable=1)[1] == 1.0
    assert solve(pid, 1000.2, sp=10, pv=0, enable=0)[2] == 0.0  # a long stop
    assert solve(pid, 5000.0, sp=10, pv=0, enable=1)[1] == 1.0  # re-enabled: loaded, held
    assert solve(pid, 5000.1, sp=10, pv=0, enable=1)[1] == 2.0


def test_manual_cv_is_the_manual_command_when_the_integral_saturates(make: Make) -> None:
    """spec 1.2 word 14 ("in Manual it is the CV source") and 1.7 step 9: the integral is
    back-calculated so that P + I + D + Bias is word 14; a derivative kick beyond 2^31
    counts (Kc 20, Td 100 s, 10 ms, SP 0 -> 20000) saturated that integral at 32 bits and
    the CV was recomputed from it: 32000 for one solution (found by an outside audit)."""
    pid = make(kind="ge.pid_isa", kc=20.0, td=100.0, sample_period=0.01,
               lower_clamp=-32000, upper_clamp=32000)
    cvs = [solve(pid, 0.01 * k, sp=sp, pv=0, man=1, manual_command=5000)[0]
           for k, sp in enumerate((0, 0, 20000, 20000), start=1)]
    assert cvs == [5000.0] * 4
    assert abs(pid.state()["integral"]) <= 2**31 - 1


def test_isa_ti_at_the_word_8_bound_is_refused() -> None:
    """spec 1.2: word 8 (1000/Ti) is 0..32767. Ti = 1000/32767.5 rounds (half away from zero)
    to 32768; it was accepted as the closed lower bound (found by an outside audit)."""
    with pytest.raises(ParameterError, match=r"'ti' = 0.030518043793392843 is out of range: "
                                             r"allowed \(0.030518, inf\] s"):
        loopworks.create_block("ge.pid_isa", ti=1000.0 / 32767.5)
    assert words_of(loopworks.create_block("ge.pid_isa", ti=1000.0 / 32767.4))[8] == 32767
    # the upper bound: 1000/Ti rounds to word 1 up to Ti = 2000 s; convert's refusal said
    # "word 8 = 1000/ti >= 1", which 2000 s does not meet (found by an outside audit)
    from loopworks.tuning.convert import convert

    assert words_of(loopworks.create_block("ge.pid_isa", ti=2000.0))[8] == 1
    assert convert("pid", {"k": 2.0, "ti": 2000.0}, "ge.pid_isa").params["word8"] == 1
    with pytest.raises(ParameterError) as info:
        convert("pid", {"k": 2.0, "ti": 2001.0}, "ge.pid_isa")
    assert ("'ti' = 2001 s is out of range: allowed up to 2000 s (word 8 = 1000/ti rounds to "
            "at least 1: 1000/ti >= 0.5) or inf") in str(info.value)


def test_a_dead_band_that_rounds_to_no_dead_band_is_refused_and_messages_give_the_value(
        ) -> None:
    """spec 1.2 words 4/5 hold whole counts in native arithmetic: ±0.4 rounded to 0/0 and
    silently switched the dead band off (a gain that rounds to 0 is refused: so is this),
    and the parameter check named the rounded words ("'upper_clamp' = 100 must be greater
    than 'lower_clamp' = 100" for 100.4; found by an outside audit)."""
    with pytest.raises(ParameterError, match=r"'deadband_pos' = 0.4 PV counts is out of "
                                             r"range: .* rounds to 0"):
        loopworks.create_block("ge.pid_ind", deadband_pos=0.4, deadband_neg=-0.4)
    with pytest.raises(ParameterError, match=r"'upper_clamp' = 100.4 \(word 10 = 100\) must "
                                             r"be greater than 'lower_clamp' = 100 "):
        loopworks.create_block("ge.pid_ind", upper_clamp=100.4, lower_clamp=100.0)
    float_mode = loopworks.create_block("ge.pid_ind", deadband_pos=0.4, deadband_neg=-0.4,
                                        arithmetic="float")  # float arithmetic keeps it
    assert float_mode.params["deadband_pos"] == 0.4


def test_a_derivative_filter_at_full_gain_gives_the_integer_derivative(make: Make) -> None:
    """Config bit 5: with dt far above the filter's time constant its gain 1 - exp(-dt/Tf)
    is 1.0 and the filtered D is the D term: Kd·Δe/dt = 0.01·(-159 - 1)/0.1 = -16 counts
    (IND, word 7 in 0.01 s). The lag left -15.999999999999998, which the integer
    truncation made -15 (found by an outside audit)."""
    pid = make(kp=0.0, kd=0.01, sample_period=0.0, derivative_filter=True,
               lower_clamp=-32000, upper_clamp=32000)  # Tf default kd/10 = 1 ms
    for clock, pv in ((0.01, 0), (0.02, -1)):
        solve(pid, clock, sp=0, pv=pv)
    assert solve(pid, 0.12, sp=0, pv=159)[0] == -16.0


def test_own_clock_advances_by_dt(make: Make) -> None:
    """Without a clock input the block's clock reads dt, 2·dt, ...: with 0.1 s steps and a
    0.1 s period every step solves with dt = 1000 ticks (ΔI = 1 count)."""
    pid = make(kp=0.0, ki=1.0, sample_period=0.1)
    assert [pid.step(0.1, sp=10.0, pv=0.0)["output"].value for _ in range(3)] == [1.0, 2.0, 3.0]


def test_not_powered_holds_cv_and_the_gap_is_integrated(make: Make) -> None:
    """spec 1.7 step 1: enable off: CV keeps its value and ok is off. The time of last solution
    is not updated, so the next solution's dt spans the gap (0.1 -> 1.0 s: 9000 ticks,
    ΔI = 1000*10*9000/10^7 = 9 counts)."""
    pid = make(kp=0.0, ki=1.0, sample_period=0.1)
    assert solve(pid, 0.1, sp=10, pv=0) == (1.0, 1.0, 1.0)
    for k in range(2, 10):
        assert solve(pid, 0.1 * k, enable=0) == (1.0, 1.0, 0.0)
    assert solve(pid, 1.0, enable=1) == (10.0, 10.0, 1.0)


# ----------------------------------------------------------------------------------------------
# Modes (spec 1.7 steps 9 and 13, 1.4)
# ----------------------------------------------------------------------------------------------
def test_up_dn_one_count_per_solution_not_per_sweep(make: Make) -> None:
    """spec 1.7 UP/DN: ±1 count per solution. 50 ms sweeps, 100 ms period: UP held over 6
    sweeps (3 solutions) raises CV by 3."""
    pid = make(kp=0.0, sample_period=0.1)
    assert solve(pid, 0.1, man=1, manual_command=500)[0] == 500.0
    for k in range(3, 9):
        cv = solve(pid, 0.05 * k, man=1, up=1, manual_command=NAN)[0]
    assert cv == 503.0
    assert solve(pid, 0.5, man=1, up=0, dn=1)[0] == 502.0


def test_up_dn_obey_clamp_and_slew(make: Make) -> None:
    """spec 1.7 UP/DN: still subject to the clamps."""
    pid = make(kp=0.0, sample_period=0.1, upper_clamp=1000)
    assert solve(pid, 0.1, man=1, manual_command=1000)[0] == 1000.0
    assert solve(pid, 0.2, man=1, up=1, manual_command=NAN)[0] == 1000.0


def test_manual_command_tracks_the_output_in_auto(make: Make) -> None:
    """spec 1.7 step 13: in Auto word 14 receives the output before polarity [A]; the option
    manual_tracking = cv takes CV instead."""
    pid = make(kp=1.0, bias=100, invert_output=True, sample_period=0.1, **BIPOLAR)
    solve(pid, 0.1, sp=50, pv=0)
    assert pid.state()["manual_command"] == 150.0
    pid = make(kp=1.0, bias=100, invert_output=True, sample_period=0.1,
               manual_tracking="cv", **BIPOLAR)
    solve(pid, 0.1, sp=50, pv=0)
    assert pid.state()["manual_command"] == -150.0


def test_bumpless_manual_to_auto(make: Make) -> None:
    """spec 1.7 bumpless transfer: the first Auto solution changes CV only by the integral
    increment: ΔI = 1000*10*1000/10^7 = 1."""
    pid = make(kp=2.0, ki=1.0, sample_period=0.1)
    assert solve(pid, 0.1, sp=10, pv=0, man=1, manual_command=700)[0] == 700.0
    assert solve(pid, 0.2, man=0, manual_command=NAN)[0] == 701.0


def test_override_word15_drives_manual_and_words_16_18_replace_sp_pv(make: Make) -> None:
    """spec 1.4 [A]: with Override (word 15 bit 0) the word-15 bits replace MAN/UP/DN and
    words 16/18 replace SP/PV (override_sp_pv)."""
    pid = make(kp=1.0, sample_period=0.1, **BIPOLAR)
    # Override + Manual (bits 0 and 1): Manual although the MAN operand is 0
    assert solve(pid, 0.1, man=0, control_word=3, manual_command=321)[0] == 321.0
    # (words 16/18 were still 0, so P = 0 and the integral was set to 321)
    # Override + Auto: SP/PV from words 16/18 (P = 40 - 10), the operands ignored; the
    # return is bumpless: 30 + 321
    assert solve(pid, 0.2, control_word=1, manual_command=NAN, internal_sp=40,
                 internal_pv=10, sp=999, pv=0)[0] == 351.0
    pid = make(kp=1.0, sample_period=0.1, override_sp_pv=False, **BIPOLAR)
    assert solve(pid, 0.1, control_word=1, internal_sp=40, internal_pv=10, sp=5, pv=0)[0] == 5.0


def test_override_off_reports_the_inputs_in_word15(make: Make) -> None:
    """spec 1.4: Override = 0: word 15 reports MAN (2), Enable (4), UP (8); words 16-18
    mirror SP, CV and PV."""
    pid = make(kp=0.0, sample_period=0.1)
    solve(pid, 0.1, sp=12, pv=34, man=1, up=1, manual_command=50)
    s = pid.state()
    assert s["control_word"] == 2 + 4 + 8
    assert (s["internal_sp"], s["internal_cv"], s["internal_pv"]) == (12.0, 51.0, 34.0)


# ----------------------------------------------------------------------------------------------
# Integer arithmetic (spec 1.5) and options
# ----------------------------------------------------------------------------------------------
def test_tiny_increments_stop_the_integral_at_0001_resolution(make: Make) -> None:
    """spec 1.5 [A] / 1.8: Ki word 1, e = 4, dt = 0.1 s: ΔI = 1*4*1000/10^7 = 0.0004 count,
    below half a thousandth, so the integral never moves; with integral_resolution = 0 (exact
    carry) it reaches 1 count after 2500 solutions (2500*0.0004)."""
    stuck = make(kp=0.0, ki=0.001, sample_period=0.1)
    exact = make(kp=0.0, ki=0.001, sample_period=0.1, integral_resolution=0)
    for k in range(1, 2501):
        stuck.step(0.1, sp=4.0, pv=0.0)
        out = exact.step(0.1, sp=4.0, pv=0.0)["output"].value
        if k == 2499:
            assert out == 0.0
    assert out == 1.0
    assert stuck.state()["integral"] == 0.0 and stuck.state()["int_remainder"] == 0.0


@pytest.mark.parametrize(("rounding", "expected"), [("truncate", -4.0), ("floor", -5.0)])
def test_rounding_direction_of_p(make: Make, rounding: str, expected: float) -> None:
    """spec 1.5 [?]: Kp word 150, e = -3: P = -450/100 = -4.5, -4 toward zero, -5 floor."""
    pid = make(kp=1.5, rounding=rounding, sample_period=0.1, **BIPOLAR)
    assert solve(pid, 0.1, sp=0, pv=3)[1] == expected


def test_inputs_round_to_counts(make: Make) -> None:
    """spec 1.5: SP/PV are INT operands: 2.5 rounds to 3 (halves away from zero), and the
    word range ends are words: 32767.4 -> 32767, -32768.4 -> -32768."""
    pid = make(kp=1.0, sample_period=0.1, **BIPOLAR)
    assert solve(pid, 0.1, sp=10, pv=2.5)[1] == 7.0
    pid = make(kp=0.01, sample_period=0.1, **BIPOLAR)
    assert solve(pid, 0.1, sp=32767.4, pv=0)[1] == 327.0  # 1*32767/100 toward zero
    pid = make(kp=0.01, sample_period=0.1, **BIPOLAR)
    assert solve(pid, 0.1, sp=0, pv=-32768.4)[1] == 327.0


@pytest.mark.parametrize("value", [1e6, -1e6, 1e308, -1e308, 32767.5, -32768.5, math.inf,
                                   -math.inf, NAN])
@pytest.mark.parametrize("name", ["sp", "pv"])
def test_an_sp_or_pv_beyond_a_word_is_bad_input(make: Make, name: str, value: float) -> None:
    """issue 11 point 1: an SP/PV that no INT operand can hold (beyond -32768..32767 once
    rounded, or not finite) is Bad input, not a plausible full-scale 32767: the solution is
    skipped, CV holds with ok = 0 and no state changes; the next good solution integrates over
    the gap (ΔI = 1000*10*2000/10^7 = 2). Before, 10^6 was saturated to 32767 and solved."""
    for kind, gains in (("ge.pid_ind", {"kp": 0.0, "ki": 1.0}), ("ge.pid_isa", {"kc": 1.0})):
        pid = make(kind, sample_period=0.1, **gains, **BIPOLAR)
        if kind == "ge.pid_isa":  # kc = 1, no integral: P = e
            assert solve(pid, 0.1, sp=10, pv=0) == (10.0, 10.0, 1.0)
            before = held(pid)
            assert solve(pid, 0.2, **{name: value}) == (10.0, 10.0, 0.0)
            assert held(pid) == before
            continue
        assert solve(pid, 0.1, sp=10, pv=0) == (1.0, 1.0, 1.0)
        before = held(pid)
        assert solve(pid, 0.2, **{name: value}) == (1.0, 1.0, 0.0)
        assert held(pid) == before
        assert solve(pid, 0.3, sp=10, pv=0) == (3.0, 3.0, 1.0)
    pid = make(kp=1.0, sample_period=0.1, bad_input="ignore_status", **BIPOLAR)
    assert solve(pid, 0.1, sp=10, pv=0)[2] == 1.0
    assert solve(pid, 0.2, **{name: value})[2] == 0.0  # no word whatever the status


@pytest.mark.parametrize("value", [1e308, -1e308, 40000.0, math.inf, NAN])
def test_a_write_that_is_no_word_leaves_the_word(make: Make, value: float) -> None:
    """issue 11 point 1: a write into word 14 (or 15, 16, 18) that no 16-bit word can hold
    is no write, as NaN is: Manual stays at 500 (before, 1e308 became 32767, CV 32000)."""
    pid = make(kp=0.0, sample_period=0.1)
    assert solve(pid, 0.1, man=1, manual_command=500)[0] == 500.0
    assert solve(pid, 0.2, man=1, manual_command=value)[0] == 500.0
    assert pid.state()["manual_command"] == 500.0
    pid = make(kp=1.0, sample_period=0.1, **BIPOLAR)
    solve(pid, 0.1, control_word=1, internal_sp=40, internal_pv=10, sp=0, pv=0)
    state = pid.state()
    cw = 70000.0 if value == 40000.0 else value  # 40000 is a word 15 value (0..65535)
    solve(pid, 0.2, control_word=cw, internal_sp=value, internal_pv=value)
    assert [pid.state()[n] for n in ("control_word", "internal_sp", "internal_pv")] == [
        state[n] for n in ("control_word", "internal_sp", "internal_pv")]


@pytest.mark.parametrize("name", ["man", "up", "dn"])
def test_a_non_finite_discrete_input_is_bad_input(make: Make, name: str) -> None:
    """issue 11 point 1: MAN/UP/DN that is no BOOL (NaN, inf) skips the solution like a bad
    PV (ok = 0, CV holds); before, NaN MAN read as Auto. A NaN enable is no power flow."""
    pid = make(kp=1.0, sample_period=0.1, **BIPOLAR)
    assert solve(pid, 0.1, sp=10, pv=0) == (10.0, 10.0, 1.0)
    before = held(pid)
    assert solve(pid, 0.2, sp=20, **{name: NAN}) == (10.0, 10.0, 0.0)
    assert held(pid) == before
    assert solve(pid, 0.3, **{name: 0.0}) == (20.0, 20.0, 1.0)
    assert solve(pid, 0.4, enable=NAN) == (20.0, 20.0, 0.0)


# ----------------------------------------------------------------------------------------------
# Start-up (issue 11 points 7 and 8)
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("params", "cv", "output"), [
    ({}, 0.0, 0.0),  # Bias 0 inside 0..32000
    ({"bias": 5000}, 5000.0, 5000.0),
    ({"upper_clamp": 20000, "lower_clamp": 4000}, 4000.0, 4000.0),  # the vendor array
    ({"bias": 5000, "upper_clamp": 3000, "lower_clamp": -3000, "invert_output": True},
     -3000.0, 3000.0),
])
def test_start_value_before_the_first_solution(make: Make, params: dict[str, Any], cv: float,
                                               output: float) -> None:
    """issue 11 point 8: before its first solution the block shows word 19 =
    clamp(Bias, Lower, Upper), the output of a first solution at zero error with the empty
    integral (CV after polarity), not 0 outside the clamps; sweeps before the first sample
    period has elapsed hold it, and word 14 starts there (a Manual start does not jump)."""
    pid = make(sample_period=1.0, **params)
    out = pid.outputs()
    assert (out["cv"].value, out["output"].value, out["ok"].value) == (cv, output, 0.0)
    assert solve(pid, 0.0) == (cv, output, 1.0)  # a module's first scan at t = 0: no solution
    assert solve(pid, 0.5, man=1) == (cv, output, 1.0)
    assert solve(pid, 1.0, man=1)[:2] == (cv, output)  # Manual from word 14: no jump


def test_first_solution_derivative_kick_and_prime_derivative(make: Make) -> None:
    """issue 11 point 7, spec 1.7: word 20 of a fresh array is 0, so the first solution with
    derivative on PV (bit 2) sees ΔPV = 1000 - 0: D = -100*1000*100/1000 = -10000 (Kd 1.00 s,
    dt 0.1 s), clamped to 0 with the integral back-calculated to 10000 (bit 4 = 0): with
    Ki = 0 that is a lasting offset, CV 10000 at zero error. prime_derivative loads word 20
    from the first PV: D = 0, CV stays 0."""
    p = {"kp": 1.0, "kd": 1.0, "derivative_on_pv": True, "sample_period": 0.1}
    pid = make(**p)
    assert [solve(pid, 0.1 * k, sp=1000, pv=1000)[0] for k in (1, 2, 3)] == [
        0.0, 10000.0, 10000.0]
    pid = make(**p, prime_derivative=True)
    assert [solve(pid, 0.1 * k, sp=1000, pv=1000)[0] for k in (1, 2, 3)] == [0.0, 0.0, 0.0]
    # derivative on the error: word 20 primed with the first error, e = 1000: P only
    pid = make(kp=1.0, kd=1.0, sample_period=0.1, prime_derivative=True)
    assert solve(pid, 0.1, sp=1000, pv=0)[0] == 1000.0
    pid = make(kp=1.0, kd=1.0, sample_period=0.1)  # literal: D = 100*1000*100/1000 = 10000
    assert solve(pid, 0.1, sp=1000, pv=0)[0] == 11000.0
    # only the first solution is primed: PV 1000 -> 1020 then gives D = -100*20*100/1000
    pid = make(**p, prime_derivative=True, **BIPOLAR)
    solve(pid, 0.1, sp=1000, pv=1000)
    assert solve(pid, 0.2, sp=1000, pv=1020)[1] == -20.0 - 200.0


def test_float_arithmetic_runs_the_same_equations(make: Make) -> None:
    """spec 1.5 / the issue: arithmetic = float: G2 without integer rounding gives
    1.5, 3.0, 4.5; Kp 4.005 is used as given (4.005*10 = 40.05)."""
    pid = make(kp=0.0, ki=1.5, sample_period=0.05, arithmetic="float")
    assert [solve(pid, 0.05 * k, sp=20, pv=0)[1] for k in (1, 2, 3)] == pytest.approx(
        [1.5, 3.0, 4.5], abs=1e-12)
    pid = make(kp=4.005, sample_period=0.1, arithmetic="float")
    assert solve(pid, 0.1, sp=10, pv=0)[1] == pytest.approx(40.05, abs=1e-12)


def test_isa_division_points(make: Make) -> None:
    """spec 1.5 [?]: Kc word 150, Td word 33, first solution e = Δ = 3, dt = 1000 ticks.
    P = 150*3/100 = 4.5 -> 4. combined: D = 150*33*3/1000 = 14.85 -> 14, Output 18;
    staged: Td·Δ/dt = 33*3*100/1000 = 9.9 -> 9, then 150*9/100 = 13.5 -> 13, Output 17."""
    combined = make("ge.pid_isa", kc=1.5, td=0.33, sample_period=0.1)
    staged = make("ge.pid_isa", kc=1.5, td=0.33, sample_period=0.1, isa_division="staged")
    assert solve(combined, 0.1, sp=3, pv=0)[1] == 18.0
    assert solve(staged, 0.1, sp=3, pv=0)[1] == 17.0


def test_isa_integral_uses_word8_as_one_over_ti(make: Make) -> None:
    """spec 1.2: word 8 holds 1/Ti in 0.001 repeats/s: Ti = 10 s is word 100. Kc 2.00, e = 100,
    dt = 1000 ticks: ΔI = 200*100*100*1000/10^9 = 2 counts (= 2*100*0.1/10)."""
    pid = make("ge.pid_isa", kc=2.0, ti=10.0, sample_period=0.1)
    assert words_of(pid)[8] == 100
    solve(pid, 0.1, sp=100, pv=0)
    assert pid.state()["integral"] == 2.0


def test_arw_bit4_back_calculation_versus_hold(make: Make) -> None:
    """spec 1.3 bit 4: P = 400*4000/100 = 16000 and ΔI = 1500*4000*1000/10^7 = 600 per
    solution: the sums are 16600, ..., 19600, then 20200 > 20000 on the 7th. Back-calculation
    sets the integral to 20000 - 16000 = 4000; hold keeps 3600. With e = 0 the outputs are
    then 4000 and 3600."""
    results = []
    for hold in (False, True):
        pid = make(kp=4.0, ki=1.5, sample_period=0.1, upper_clamp=20000, arw_hold=hold)
        cvs = [solve(pid, 0.1 * k, sp=4000, pv=0)[0] for k in range(1, 8)]
        assert cvs == [16600.0, 17200.0, 17800.0, 18400.0, 19000.0, 19600.0, 20000.0]
        results.append(solve(pid, 0.8, sp=0, pv=0)[0])
    assert results == [4000.0, 3600.0]


@pytest.mark.parametrize("hold", [False, True])
def test_manual_below_the_clamp_returns_to_auto_without_a_bump(make: Make, hold: bool) -> None:
    """spec 1.7 step 9 [V]: in Manual the integral is set so the block reproduces the Manual
    Command, and the first Auto solution changes CV only by the new integral increment plus any
    change of P or D. Kp 1 (P = SP - PV = 1000), Ki 0, clamps 4000..20000: Manual 8000 sets
    I = 7000; Manual 1000 asks I = 0, CV clamped to 4000, and I = 3000 reproduces it. Back in
    Auto nothing changed: CV 4000. With bit 4 (hold) the clamp in Manual kept I = 7000, and
    Auto jumped to 8000 (found by an independent reference; bit 4 holds an Auto integral)."""
    pid = make(kp=1.0, ki=0.0, lower_clamp=4000, upper_clamp=20000, sample_period=0.1,
               arw_hold=hold)
    assert solve(pid, 0.1, sp=1000, pv=0, man=1, manual_command=8000)[0] == 8000.0
    assert solve(pid, 0.2, sp=1000, pv=0, man=1, manual_command=1000)[0] == 4000.0
    assert [solve(pid, 0.1 * k, sp=1000, pv=0, man=0)[0] for k in (3, 4)] == [4000.0, 4000.0]


def test_derivative_filter_bit5(make: Make) -> None:
    """spec 1.3 bit 5 [?]: a first-order lag on D. Kd 1.00, SP step 50, dt 0.1 s, Tf 0.1 s:
    raw D = 500, filtered 500*(1 - e^-1) = 316.06 -> 316; then 316.06*e^-1 = 116.27 -> 116."""
    pid = make(kp=0.0, kd=1.0, derivative_filter=True, derivative_filter_time=0.1,
               sample_period=0.1)
    solve(pid, 0.1, sp=0, pv=0)
    first = 500.0 * (1.0 - math.exp(-1.0))
    assert solve(pid, 0.2, sp=50, pv=0)[1] == math.trunc(first)
    assert solve(pid, 0.3, sp=50, pv=0)[1] == math.trunc(first * math.exp(-1.0))
    assert make(derivative_filter=True, kd=2.0).p[ge_pacsystems.P.tf] == pytest.approx(0.2)


def test_slew_remainder_carries_below_one_count(make: Make) -> None:
    """spec 1.7 step 10 / word 23 [A]: word 12 = 32000 s, dt = 0.1 s: 0.1 count per solution
    (ΔI = 1000*100*1000/10^7 = 10 counts keeps the limiter acting). Carried, the output moves
    1 count on the 10th solution; truncated it never moves."""
    carry = make(kp=1.0, ki=1.0, min_slew_time=32000, sample_period=0.1)
    cut = make(kp=1.0, ki=1.0, min_slew_time=32000, sample_period=0.1, slew_remainder=False)
    a = [solve(carry, 0.1 * k, sp=100, pv=0)[1] for k in range(1, 11)]
    b = [solve(cut, 0.1 * k, sp=100, pv=0)[1] for k in range(1, 11)]
    assert a == [0.0] * 9 + [1.0]
    assert b == [0.0] * 10


def test_saturate_sum_changes_only_the_slew_remainder(make: Make) -> None:
    """spec 1.5 [?]: word 12 = 3 s, dt = 0.1 s: an allowance of 32000*1000 = 3.2e7 per
    solution in units of 1/30000 count (1066.67 counts). At the 32000 clamp (P = 4*10000 =
    40000, integral back-calculated to -8000, ΔI = 2000*10000*1000/10^7 = 2000) the raw sum
    34000 is 2000 above the last output, so the limiter acts: its remainder cycles
    3.2e7 - 1066*3e4 = 20000, 3.202e7 - 1067*3e4 = 10000, 3.201e7 - 1067*3e4 = 0. Saturated
    at 32767 the sum is only 767 <= 1066 above it: the limiter never acts there (remainder 0)."""
    remainders = []
    for saturate in (False, True):
        pid = make(kp=4.0, ki=2.0, min_slew_time=3, sample_period=0.1, saturate_sum=saturate)
        for k in range(1, 41):
            cv = solve(pid, 0.1 * k, sp=10000, pv=0)[0]
        assert cv == 32000.0
        seen = []
        for k in range(41, 44):
            assert solve(pid, 0.1 * k, sp=10000, pv=0)[0] == 32000.0
            seen.append(pid.state()["slew_storage"])
        remainders.append(sorted(seen))
    assert remainders == [[0.0, 10000.0, 20000.0], [0.0, 0.0, 0.0]]


# ----------------------------------------------------------------------------------------------
# Bad measurements (an [A]: the spec is silent) and parameter errors (spec 1.7 step 2)
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("bad", [(NAN, 128), (math.inf, 128), (-math.inf, 128), (50.0, 0)])
def test_bad_pv_holds_cv_with_ok_off(make: Make, bad: tuple[float, int]) -> None:
    """[A]: NaN/inf or a Bad-status PV skips the solution: CV holds, ok = 0; the next good
    solution integrates over the whole gap (0.1 -> 0.3 s: ΔI = 1000*10*2000/10^7 = 2)."""
    pid = make(kp=0.0, ki=1.0, sample_period=0.1)
    assert solve(pid, 0.1, sp=10, pv=0) == (1.0, 1.0, 1.0)
    r = pid.step(0.1, clock=0.2, pv=bad)
    assert (r["cv"].value, r["ok"].value) == (1.0, 0.0)
    assert solve(pid, 0.3, pv=0) == (3.0, 3.0, 1.0)


def test_ignore_status_uses_a_bad_status_value(make: Make) -> None:
    """bad_input = ignore_status [A]: the PLC has no status; the value 4 is used (P = 6)."""
    pid = make(kp=1.0, sample_period=0.1, bad_input="ignore_status")
    assert pid.step(0.1, clock=0.1, sp=10.0, pv=(4.0, 0))["cv"].value == 6.0


def test_parameter_errors_name_the_parameter() -> None:
    """spec 1.7 step 2 and the parameter ranges: ParameterError naming what is wrong."""
    cases: list[tuple[dict[str, Any], str]] = [
        ({"upper_clamp": 100, "lower_clamp": 100}, "upper_clamp"),
        ({"deadband_pos": 5, "deadband_neg": 0}, "deadband_neg"),
        ({"deadband_pos": 0.3, "deadband_neg": -5}, "deadband_pos"),  # word 4 rounds to 0
        ({"kp": 400.0}, "kp"),
        ({"ki": 0.0004}, "ki"),  # below 0.001 repeats/s: would round to word 0
        ({"sample_period": 700}, "sample_period"),
        ({"config_word": 4, "derivative_on_pv": True}, "config_word"),
        ({"integral_resolution": 0.3}, "integral_resolution"),
        ({"rounding": "nearest"}, "rounding"),
    ]
    for params, name in cases:
        with pytest.raises(ParameterError, match=name):
            loopworks.create_block("ge.pid_ind", **params)
    with pytest.raises(ParameterError, match="'ti'"):
        loopworks.create_block("ge.pid_isa", ti=5000.0)  # 1000/5000 rounds to word 0


def test_parameter_error_ok_off_is_the_plc_behaviour(make: Make) -> None:
    """spec 1.7 step 2 / 1.10: on_parameter_error = ok_off: the block is made, and every
    sweep leaves CV frozen with ok = 0."""
    pid = make(upper_clamp=100, lower_clamp=200, on_parameter_error="ok_off", kp=1.0)
    for k in range(1, 4):
        assert solve(pid, 0.1 * k, sp=50, pv=0) == (0.0, 0.0, 0.0)


def test_config_word_equals_the_flags(make: Make) -> None:
    """spec 1.3: config_word = 0b011111 is the five flags (bits 0-4)."""
    flags = make(direct_acting=True, invert_output=True, derivative_on_pv=True,
                 deadband_subtract=True, arw_hold=True, **BIPOLAR)
    word = make(config_word=0b11111, **BIPOLAR)
    assert words_of(flags)[13] == 31
    assert list(flags.p) == list(word.p)


# ----------------------------------------------------------------------------------------------
# The reference array loader (spec 1.2 / 1.5)
# ----------------------------------------------------------------------------------------------
def test_from_reference_array_scalings() -> None:
    """spec 1.2/1.5: word 3 x 10 ms, word 6/100, word 7/100 s, word 8/1000 (IND) or
    Ti = 1000/word8 (ISA); the words come back unchanged."""
    words = vendor_array()
    ind = from_reference_array(words, kind="ge.pid_ind")
    assert ind.params["sample_period"] == pytest.approx(0.1)
    assert (ind.params["kp"], ind.params["ki"]) == (pytest.approx(4.0), pytest.approx(1.5))
    assert words_of(ind) == {3: 10, 4: 5, 5: -5, 6: 400, 7: 0, 8: 1500, 9: 0, 10: 20000,
                          11: 4000, 12: 0, 13: 0}
    words[1] = 1  # word 2 = 1: ISA
    isa = from_reference_array(words)
    assert isa.kind == "ge.pid_isa"
    assert isa.params["ti"] == pytest.approx(1000.0 / 1500.0)
    with pytest.raises(ParameterError, match="word 2"):
        from_reference_array(words, kind="ge.pid_ind")
    with pytest.raises(ParameterError, match="40 words"):
        from_reference_array(words[:39])
    words[9], words[10] = 4000, 20000  # upper < lower: the PLC's parameter error
    with pytest.raises(ParameterError, match="upper_clamp"):
        from_reference_array(words)
    assert from_reference_array(words, on_parameter_error="ok_off").kind == "ge.pid_isa"


def test_engineering_values_round_to_their_words() -> None:
    """spec 1.2: Ti = 3 s is word 8 = round(1000/3) = 333; 0.015 s is word 3 = 2 (half away
    from zero)."""
    isa = loopworks.create_block("ge.pid_isa", ti=3.0, sample_period=0.015)
    w = words_of(isa)
    assert (w[8], w[3]) == (333, 2)


# ----------------------------------------------------------------------------------------------
# Retuning in Auto (issue 12 point 4)
# ----------------------------------------------------------------------------------------------
# e = 1000 - 900 = 100 counts; Kp 4 (word 6 = 400), Ki 1.5 (word 8 = 1500), 100 ms solutions:
# P = 400·100/100 = 400, ΔI = 1500·100·1000/10^7 = 15 counts per solution (spec 1.5).
IND_TUNING: dict[str, Any] = {"kp": 4.0, "ki": 1.5, "sample_period": 0.1, **BIPOLAR}
# PID_ISA Kc 2 (word 6 = 200), Ti 10 s (word 8 = 100): P = 200·100/100 = 200,
# ΔI = 200·100·100·1000/10^9 = 2 counts per solution (spec 1.5, isa_division combined).
ISA_TUNING: dict[str, Any] = {"kc": 2.0, "ti": 10.0, "sample_period": 0.1, **BIPOLAR}


def three_solutions(first: Block, *others: Block) -> list[float]:
    """Solutions at 0.1, 0.2, 0.3 s with SP 1000, PV 900 of every block; word 19 of the
    first."""
    outs = []
    for k in (1, 2, 3):
        for block in others:
            solve(block, 0.1 * k, sp=1000, pv=900)
        outs.append(solve(first, 0.1 * k, sp=1000, pv=900)[1])
    return outs


def test_retune_vendor_steps_the_output_by_the_change_of_p(make: Make) -> None:
    """spec 1.6 (Output = Kp·e + Integ + Kd·Δ/dt + Bias, the integral accumulated): 415, 430,
    445; Kp 4 -> 6 (word 6 = 600) makes P = 600·100/100 = 600, so the next solution is
    600 + 4·15 = 660: a step of (600 - 400)·100/100 = 200 over the old law's 460."""
    pid = make(**IND_TUNING)
    assert pid.params["retune"] == "vendor"
    assert three_solutions(pid) == [415.0, 430.0, 445.0]
    pid.set_params(kp=6.0)
    assert solve(pid, 0.4)[1] == 660.0
    assert solve(pid, 0.5)[1] == 675.0


def test_retune_vendor_isa_kc_does_not_rescale_the_past_integral(make: Make) -> None:
    """spec 1.5 (ISA ΔI = Kc·e·dt/Ti, accumulated in CV counts) and 1.6: 202, 204, 206.
    Kc 2 -> 3 (word 6 = 300): P = 300, ΔI = 300·100·100·1000/10^9 = 3, and the integral 6
    is kept as it is: 300 + 6 + 3 = 309 (an integral multiplied by Kc at output time would
    give 300 + 9 + 3 = 312)."""
    pid = make("ge.pid_isa", **ISA_TUNING)
    assert three_solutions(pid) == [202.0, 204.0, 206.0]
    pid.set_params(kc=3.0)
    assert solve(pid, 0.4)[1] == 309.0
    assert pid.state()["integral"] == 9.0


@pytest.mark.parametrize("rounding", ["truncate", "floor"])
def test_retune_bumpless_next_solution_is_the_old_tunings(make: Make, rounding: str) -> None:
    """retune = bumpless, Kp 6 -> 4 at e = 100: the integral moves by P_old - P_new =
    600 - 400 = +200 counts, word 27 untouched, so the next solution equals the old tuning's:
    600 + 4·15 = 660 (spec 1.6). Afterwards the loop follows the new tuning: a block tuned
    Kp 4 from the start (460 at 0.4 s) differs from it by that constant integral offset, 200,
    through SP steps (e 110, 110, 90: P = 4·e, ΔI = 16.5, 16.5, 13.5 with the remainder
    carried)."""
    start = {**IND_TUNING, "kp": 6.0, "rounding": rounding}
    old = make(**start)
    pid = make(**start, retune="bumpless")
    new = make(**{**start, "kp": 4.0})
    assert three_solutions(pid, old, new) == [615.0, 630.0, 645.0]
    integral, remainder = pid.state()["integral"], pid.state()["int_remainder"]
    pid.set_params(kp=4.0)
    assert (pid.state()["integral"], pid.state()["int_remainder"]) == (integral + 200.0,
                                                                       remainder)
    assert solve(pid, 0.4)[1] == solve(old, 0.4)[1] == 660.0
    assert solve(new, 0.4)[1] == 460.0
    for k, sp in ((5, 1010), (6, 1010), (7, 990), (8, 990)):
        assert solve(pid, 0.1 * k, sp=sp)[1] - solve(new, 0.1 * k, sp=sp)[1] == 200.0


def test_retune_bumpless_isa_moves_only_by_the_new_increment(make: Make) -> None:
    """PID_ISA, bumpless, Kc 2 -> 3 after 202, 204, 206: the integral moves by
    P_old - P_new = 200 - 300 = -100 (6 -> -94), so the next solution moves only by the new
    increment ΔI = 3 (spec 1.5): 209, where the old tuning gives 208 (its increment 2)."""
    old = make("ge.pid_isa", **ISA_TUNING)
    pid = make("ge.pid_isa", **ISA_TUNING, retune="bumpless")
    assert three_solutions(pid, old) == [202.0, 204.0, 206.0]
    pid.set_params(kc=3.0)
    assert pid.state()["integral"] == -94.0
    assert solve(pid, 0.4)[1] == 209.0
    assert solve(old, 0.4)[1] == 208.0
    assert solve(pid, 0.5)[1] == 212.0  # the new law: 300 + (-91 + 3)


@pytest.mark.parametrize(("change", "p_new"), [
    ({"kp": 6.0}, 600.0),  # 600·100/100
    ({"direct_acting": True}, -400.0),  # e = PV - SP = -100 (spec 1.7 step 5)
    ({"deadband_pos": 150.0, "deadband_neg": -150.0}, 0.0),  # inside the band (step 6)
    ({"deadband_pos": 50.0, "deadband_neg": -50.0, "deadband_subtract": True},
     200.0),  # e_db = 100 - 50 (step 6, Config bit 3)
])
@pytest.mark.parametrize("retune", ["vendor", "bumpless"])
def test_retune_of_each_p_coefficient(make: Make, change: dict[str, Any], p_new: float,
                                      retune: str) -> None:
    """P only (Ki 0: the integral is a frozen manual reset, 0 here), e = 100: the output is
    P = 400·100/100 = 400. vendor: the next solutions give the new law's P (spec 1.6);
    bumpless: the integral takes P_old - P_new and the output stays at 400."""
    pid = make(kp=4.0, sample_period=0.1, retune=retune, **BIPOLAR)
    assert solve(pid, 0.1, sp=1000, pv=900)[1] == 400.0
    pid.set_params(**change)
    expected = p_new if retune == "vendor" else 400.0
    assert [solve(pid, t)[1] for t in (0.2, 0.3)] == [expected, expected]


@pytest.mark.parametrize(("rounding", "residual"), [("floor", 0.0), ("truncate", 1.0)])
def test_retune_bumpless_residual_is_at_most_one_count(make: Make, rounding: str,
                                                       residual: float) -> None:
    """The stated bound: the correction is a whole count, but truncate takes the integral's
    whole part toward zero, so when the correction carries an integral with a remainder
    across zero the next output differs from the old tuning's by one count; floor is exact.
    Kp 0.05 -> 0.10 (word 6 = 5 -> 10) at e = -20: P = 5·(-20)/100 = -1 -> -2, so
    P_old - P_new = +1; Ki word 125: ΔI = 125·(-20)·1000/10^7 = -0.25 per solution.
    truncate: old -1 + trunc(-0.5) = -1, bumpless -2 + trunc(-0.25 + 1 - 0.25) = -2;
    floor: old -1 + floor(-0.5) = -2, bumpless -2 + floor(0.5) = -2 (spec 1.5 [?] rounding)."""
    tuning = {"kp": 0.05, "ki": 0.125, "sample_period": 0.1, "rounding": rounding, **BIPOLAR}
    old = make(**tuning)
    pid = make(**tuning, retune="bumpless")
    assert solve(old, 0.1, sp=0, pv=20)[1] == solve(pid, 0.1, sp=0, pv=20)[1]
    pid.set_params(kp=0.1)
    assert abs(solve(pid, 0.2)[1] - solve(old, 0.2)[1]) == residual


def test_retune_in_manual_does_nothing_special(make: Make) -> None:
    """In Manual the integral is back-calculated every solution (spec 1.7 step 9), so a Kp
    change leaves the bumpless block exactly where the vendor's is: the vendor array (G12),
    Manual at 8000 with e = 1000; Kp 4 -> 6 gives the integral 8000 - 6000 = 2000 at the
    next Manual solution, and the first Auto solution is 6000 + 2000 + 150 = 8150."""
    g12 = {"kp": 4.0, "ki": 1.5, "sample_period": 0.1, "deadband_pos": 5.0,
           "deadband_neg": -5.0, "upper_clamp": 20000.0, "lower_clamp": 4000.0}
    blocks = [make(**g12, retune=retune) for retune in ("vendor", "bumpless")]
    for pid in blocks:
        for k in (1, 2):
            solve(pid, 0.1 * k, sp=10000, pv=9000, man=1, manual_command=8000)
        pid.set_params(kp=6.0)
    assert held(blocks[0]) == held(blocks[1])
    for pid in blocks:
        assert solve(pid, 0.3)[1] == 8000.0
        assert pid.state()["integral"] == 2000.0
        assert solve(pid, 0.4, man=0, manual_command=NAN)[1] == 8150.0


def test_retune_before_the_first_solution_changes_nothing(make: Make) -> None:
    """No solution yet: there is no output to keep, and the integral stays 0."""
    pid = make(kp=4.0, retune="bumpless", **BIPOLAR)
    pid.set_inputs({"sp": 1000.0, "pv": 900.0})
    pid.set_params(kp=6.0)
    assert pid.state()["integral"] == 0.0
    assert solve(pid, 0.1)[1] == 600.0


# ----------------------------------------------------------------------------------------------
# Robustness, state, replay, documentation
# ----------------------------------------------------------------------------------------------
def test_extreme_inputs_never_crash(make: Make) -> None:
    """Any input values, including NaN, inf and huge numbers, give finite outputs."""
    for kind in ("ge.pid_ind", "ge.pid_isa"):
        pid = make(kind, min_slew_time=5, **({"kp": 3.0, "ki": 2.0, "kd": 1.0}
                                             if kind == "ge.pid_ind" else {"td": 1.0}))
        values = [NAN, math.inf, -math.inf, 1e300, -1e300, 0.0, 7.0, 4e15]
        for k, v in enumerate(values * 4):
            r = pid.step(0.05, **{name: v if (i + k) % 3 else 1.0
                                  for i, name in enumerate(pid._in_index)})
            assert all(math.isfinite(r[n].value) for n in r)


def test_resume_from_saved_state(make: Make) -> None:
    """state_dict/load_state (through JSON) continue exactly as an uninterrupted run."""
    params = {"kp": 2.0, "ki": 0.7, "kd": 0.3, "min_slew_time": 20, "sample_period": 0.05}
    whole = make(**params)
    first = make(**params)
    seq = [(0.03 * k, 100.0 + (k % 7) * 50, 80.0 + (k % 5) * 30) for k in range(1, 200)]
    expected = [solve(whole, t, sp=sp, pv=pv) for t, sp, pv in seq]
    for t, sp, pv in seq[:100]:
        solve(first, t, sp=sp, pv=pv)
    saved = json.loads(json.dumps(first.state_dict()))
    resumed = make(saved["kind"], **saved["params"])
    resumed.load_state(saved)
    assert [solve(resumed, t, sp=sp, pv=pv) for t, sp, pv in seq[100:]] == expected[100:]


def test_replay_cli(tmp_path: Path) -> None:
    """``loopworks replay ge.pid_ind``: the t column is the controller clock (G12 start)."""
    path = write_csv(tmp_path / "run.csv", ["t", "sp", "pv", "man", "manual_command"],
                     [[0.1, 10000, 9000, 1, 8000], [0.2, 10000, 9000, 1, 8000],
                      [0.3, 10000, 9000, 0, "nan"], [0.4, 10000, 9000, 0, "nan"],
                      [0.45, 10000, 9000, 0, "nan"]])
    out = tmp_path / "out.csv"
    result = CliRunner().invoke(loopworks.cli.app, [
        "replay", "ge.pid_ind", str(path), "-p", "kp=4", "-p", "ki=1.5", "-p",
        "sample_period=0.1", "-p", "upper_clamp=20000", "-p", "lower_clamp=4000", "-o", str(out)])
    assert result.exit_code == 0, result.output
    lines = out.read_text().split()
    assert lines[0] == "t,cv,output,ok"
    cvs = [float(line.split(",")[1]) for line in lines[1:]]
    assert cvs == [8000.0, 8000.0, 8150.0, 8300.0, 8300.0]  # 0.45 s: the period has not elapsed


def test_docstring_lists_every_option() -> None:
    """The block's docs name every option for the spec's [A]/[?] points."""
    doc = inspect.getdoc(ge_pacsystems) or ""
    section = doc.split("Options for the spec's [A]/[?] points")[1].split("Worked example")[0]
    for name in ("rounding", "integral_resolution", "isa_division", "saturate_sum",
                 "slew_remainder", "derivative_filter", "derivative_filter_time", "arw_hold",
                 "override_sp_pv", "manual_tracking", "initial_last_solution",
                 "load_clock_at_start", "on_parameter_error", "bad_input",
                 "deadband_subtract", "prime_derivative", "retune"):
        assert f"``{name}``" in section, name


@pytest.mark.parametrize("kind", ["ge.pid_ind", "ge.pid_isa"])
def test_a_subnormal_integral_resolution_is_a_parameter_error(kind: str) -> None:
    """Found by the slow property profile: 1/5e-324 overflowed inside the check (issue 11)."""
    with pytest.raises(ParameterError, match="integral_resolution"):
        loopworks.create_block(kind, integral_resolution=5e-324)


@pytest.mark.parametrize("kind", ["ge.pid_ind", "ge.pid_isa"])
def test_an_integral_resolution_finer_than_a_billionth_is_a_parameter_error(kind: str) -> None:
    """Found by the slow property profile (issue 11): integral_resolution = 2.2e-308 (1/n for
    n = 4.5e307) made the integral's limit INT32_MAX·n infinite, and the integral with it.
    1/n is allowed up to n = 10^9 (the exact carry's finest unit), and stays finite there."""
    with pytest.raises(ParameterError, match=r"integral_resolution.*1 to 1e\+09"):
        loopworks.create_block(kind, integral_resolution=2.2250738585072014e-308)
    with pytest.raises(ParameterError, match="integral_resolution"):
        loopworks.create_block(kind, integral_resolution=1e-10)
    fast = {"ki": 30.0} if kind == "ge.pid_ind" else {"ti": 0.05}
    block = loopworks.create_block(kind, **fast, integral_resolution=1e-9)
    for _ in range(2000):
        block.step(0.1, sp=30000.0, pv=-30000.0)
        assert all(math.isfinite(v) for v in [*block.x, *block.y]), block.state()
