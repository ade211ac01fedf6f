"""The DeltaV PID block ``deltav.pid`` against spec vendor-blocks section 4 (and 0, 7).

Every expected value is worked out by hand in the test (the arithmetic is written beside it) or
taken from the spec's worked examples (section 4.8, DV1-DV4); none is pasted from a run of the
block. Behaviour tests run twice through the ``make`` fixture: with the compiled (numba) kernel
and with the interpreted one. Most use ``precision = "float64"`` so that the spec's decimal
numbers can be compared exactly; the float32 default is tested on DV2 separately.
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
from hypothesis import given, settings
from typer.testing import CliRunner

import loopworks
from loopworks.blocks.block import Block
from loopworks.cli import app
from loopworks.errors import ParameterError
from loopworks.vendors.deltav.pid import P, Y, deltav_pid_kernel, series_to_standard
from tests.csvfiles import write_csv
from tests.properties.strategies import Case, cases

NAN = math.nan
INF = math.inf

# Status bytes, written out from the FF encoding (quality << 6 | substatus << 2 | limits), 4.6.
GOOD = 0x80  # 128 Good non-cascade
GOOD_LOW = 0x81  # 129
GOOD_HIGH = 0x82  # 130
GOOD_CONST = 0x83  # 131
GOOD_C = 0xC0  # 192 Good cascade, non-specific
GOOD_C_CONST = 0xC3
GOOD_C_HIGH = 0xC2
GOOD_C_IA_CONST = 0xC7  # IA (0xC4) + constant
GOOD_C_IR = 0xC8
GOOD_C_NI = 0xCC
GOOD_C_LO = 0xD8
GOOD_C_IFS_CONST = 0xE3  # IFS (0xE0) + constant
UNC = 0x40
UNC_LUV = 0x44
BAD = 0x00
BAD_OOS = 0x1C
# Mode codes (module docstring): OOS 0, IMAN 1, LO 2, MAN 3, AUTO 4, CAS 5
OOS, IMAN, LO, MAN, AUTO, CAS = 0.0, 1.0, 2.0, 3.0, 4.0, 5.0

Make = Callable[..., Block]
F64: dict[str, Any] = {"precision": "float64"}


@pytest.fixture(params=[True, False], ids=["compiled", "interpreted"])
def make(request: pytest.FixtureRequest) -> Make:
    """``make(**params)``: a deltav.pid with the compiled or the interpreted kernel."""
    jit = request.param

    def _make(**params: Any) -> Block:
        return loopworks.create_block("deltav.pid", jit=jit, **params)

    return _make


def run(block: Block, dt: float = 1.0, **inputs: Any) -> dict[str, tuple[float, int]]:
    r = block.step(dt, **inputs)
    return {k: (float(r[k].value), int(r[k].status)) for k in r}


def steady(block: Block, out: float = 50.0, sp: float = 50.0, pv: float = 50.0,
           dt: float = 1.0) -> dict[str, tuple[float, int]]:
    """One MAN scan with the operator output ``out``: R = OUT - P - D - FF (spec 4.7 step 10),
    the steady state the DV examples start from (OUT = R = 50 % when SP = PV)."""
    return run(block, dt, mode="MAN", man_out=out, sp=sp, pv=pv)


def values(block: Block, port: str, n: int, dt: float = 1.0, **inputs: Any) -> list[float]:
    return [run(block, dt, **inputs)[port][0] for _ in range(n)]


# ----------------------------------------------------------------------------------------------
# Worked examples, spec 4.8
# ----------------------------------------------------------------------------------------------
def test_DV1_euler_reset_ramps_one_percent_per_second(make: Make) -> None:
    """spec 4.8 DV1: Standard, GAIN 1, RESET 10 s, RATE 0, dt 1 s, reverse; steady OUT = R = 50;
    e steps to +10 %: OUT = 60, 61, 62, 63, 64 (a = dt/RESET = 0.1, Euler, 4.7 step 7)."""
    b = make(gain=1.0, reset=10.0, rate=0.0, **F64)
    assert steady(b)["r_term"][0] == 50.0
    got = [run(b, mode="AUTO", pv=40.0) for _ in range(5)]
    assert [r["out"][0] for r in got] == pytest.approx([60.0, 61.0, 62.0, 63.0, 64.0], abs=1e-12)
    # R_k = R_{k-1} + 0.1·(OUT_{k-1} - R_{k-1}): 50, 50 + 0.1·10 = 51, 52, 53, 54
    assert [r["r_term"][0] for r in got] == pytest.approx([50.0, 51.0, 52.0, 53.0, 54.0],
                                                          abs=1e-12)
    assert all(r["p_term"][0] == 10.0 for r in got)  # P = GAIN·e = 10 %


def test_DV1_exact_reset_discretisation(make: Make) -> None:
    """spec 4.8 DV1 with a = 1 - e^(-0.1): OUT = 60, 60.951626, 61.903252, 62.854877,
    63.806503 (reset_discretisation = exact, 4.7 step 7)."""
    b = make(gain=1.0, reset=10.0, reset_discretisation="exact", **F64)
    steady(b)
    got = values(b, "out", 5, mode="AUTO", pv=40.0)
    assert got == pytest.approx([60.0, 60.951626, 61.903252, 62.854877, 63.806503], abs=1e-6)
    a = 1.0 - math.exp(-0.1)  # F - R = 10 every scan, so R grows by 10·a per scan
    assert got == pytest.approx([60.0 + 10.0 * a * k for k in range(5)], abs=1e-12)


def test_DV1_backward_reset_discretisation(make: Make) -> None:
    """spec 4.7 step 7 alternative a = dt/(RESET + dt) = 1/11: OUT = 60 + 10·k/11."""
    b = make(gain=1.0, reset=10.0, reset_discretisation="backward", **F64)
    steady(b)
    assert values(b, "out", 4, mode="AUTO", pv=40.0) == pytest.approx(
        [60.0, 60.0 + 10 / 11, 60.0 + 20 / 11, 60.0 + 30 / 11], abs=1e-12)


def test_DV2_output_limit_external_reset_exact_numbers(make: Make) -> None:
    """spec 4.8 DV2: DV1 (Euler) with OUT_HI_LIM = 62; e = +10 % for 6 scans, then 0.
    OUT = 60, 61, 62, 62, 62, 62, 55.439, 55.439, 55.439;
    R = 50, 51, 52, 53, 53.9, 54.71, 55.439 (constant)."""
    b = make(gain=1.0, reset=10.0, out_hi_lim=62.0, **F64)
    steady(b)
    got = [run(b, mode="AUTO", pv=pv) for pv in [40.0] * 6 + [50.0] * 3]
    out = [r["out"][0] for r in got]
    r = [r["r_term"][0] for r in got]
    # R: 52 + 0.1·(62 - 52) = 53; 53 + 0.1·(62 - 53) = 53.9; 53.9 + 0.1·8.1 = 54.71;
    # 54.71 + 0.1·(62 - 54.71) = 55.439; then F = OUT = R: constant
    assert out == pytest.approx([60, 61, 62, 62, 62, 62, 55.439, 55.439, 55.439], abs=1e-12)
    assert r == pytest.approx([50, 51, 52, 53, 53.9, 54.71, 55.439, 55.439, 55.439], abs=1e-12)
    # spec 4.4: high-limited bits while at OUT_HI_LIM (62 is the limit already at scan 3);
    # released at 55.439 (6.561 % away >= BKCAL_HYS 0.5 %)
    assert [r["out"][1] for r in got] == [GOOD, GOOD] + [GOOD_HIGH] * 4 + [GOOD] * 3


def test_DV2_with_initial_out_and_a_steady_auto_scan(make: Make) -> None:
    """The documented alternative start (module docstring): initial_out = 50 and one AUTO scan
    at e = 0 give the same steady state, then the DV2 sequence."""
    b = make(gain=1.0, reset=10.0, out_hi_lim=62.0, initial_out=50.0, **F64)
    assert run(b, sp=50.0, pv=50.0)["out"][0] == 50.0  # R_0 = 50 - 0; R_1 = 50 + 0.1·0
    got = [run(b, pv=pv)["out"][0] for pv in [40.0] * 6 + [50.0]]
    assert got == pytest.approx([60, 61, 62, 62, 62, 62, 55.439], abs=1e-12)


def test_DV2_in_float32_default_precision(make: Make) -> None:
    """spec 4.1 [A] float32 (the default): DV2 within float32 rounding, every value a float32."""
    b = make(gain=1.0, reset=10.0, out_hi_lim=62.0)
    steady(b)
    got = [run(b, mode="AUTO", pv=pv) for pv in [40.0] * 6 + [50.0] * 2]
    out = [r["out"][0] for r in got]
    assert out == pytest.approx([60, 61, 62, 62, 62, 62, 55.439, 55.439], abs=1e-4)
    assert all(v == float(np.float32(v)) for v in out)
    assert all(float(np.float32(r["r_term"][0])) == r["r_term"][0] for r in got)


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_out_at_its_limit_is_the_limit_in_eu_not_a_rounding_past_it(
        make: Make, precision: str) -> None:
    """spec 4.4/4.5: OUT stays within OUT_LO_LIM..OUT_HI_LIM in EU. The limits are held in % of
    OUT_SCALE; on -15..100 EU the high limit 110 EU is 108.69565...% and back in float32
    -15 + 108.69565·1.15 rounds to 110.0000076, one float32 step past the limit (found by
    test_kernel_is_sound_by_itself_and_out_within_limits)."""
    b = make(gain=3.0, reset=10.0, out_scale_eu_0=-15.0, out_hi_lim=110.0, out_lo_lim=-10.0,
             precision=precision)
    steady(b, out=50.0)
    high = [run(b, mode="AUTO", sp=90.0, pv=10.0)["out"] for _ in range(3)]
    assert all(out == (110.0, GOOD_HIGH) for out in high)
    low = [run(b, mode="AUTO", sp=10.0, pv=90.0)["out"] for _ in range(3)]
    assert all(out[0] == -10.0 for out in low)
    assert run(b, mode="MAN", man_out=200.0)["out"][0] == 110.0  # Man: limited too


@pytest.mark.parametrize(("hi", "lo", "pv", "bit"), [(12.8, 0.0, 10.0, 0x02),
                                                      (16.0, 3.2, 90.0, 0x01)])
def test_out_at_a_limit_not_exact_in_float32_carries_the_limit_bit(
        make: Make, hi: float, lo: float, pv: float, bit: int) -> None:
    """spec 4.4: OUT at OUT_HI_LIM/OUT_LO_LIM sets the limited bits of OUT.ST and BKCAL_OUT.ST.
    On 0..16 EU the limit 12.8 EU is 80 %, OUT's float32 value 80.0000019 %: compared with
    the double limit it was not at it, and the bits were missing (found by an outside audit;
    about half of the limits of a 4..20 mA scale)."""
    b = make(gain=1.0, reset=10.0, out_scale_eu_0=0.0, out_scale_eu_100=16.0, out_hi_lim=hi,
             out_lo_lim=lo, precision="float32")
    run(b, mode="MAN", man_out=8.0, sp=50.0, pv=50.0)
    got = run(b, mode="AUTO", sp=50.0, pv=pv)
    assert got["out"][0] == pytest.approx(hi if bit == 0x02 else lo, rel=1e-6)
    assert got["out"][1] & 0x03 == bit and got["bkcal_out"][1] & 0x03 == bit


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_leaving_the_low_limit_with_default_arw_limits_is_not_the_fast_reset(
        make: Make, precision: str) -> None:
    """spec 4.4: RESET/16 acts while OUT is beyond the ARW limits, which default to the OUT
    limits ("the 16x rule then never acts"). In float32, OUT held at 7.2 EU of 4..20 (20 %)
    was just below the double ARW limit, so leaving it ran the reset 16 times faster (found
    by an outside audit). GAIN 1, RESET 10 s, dt 1, e = +10 % in Man at the limit: R = 20 - 10
    = 10 %; the first Auto scan moves R by dt/RESET·(F - R) = 0.1·(20 - 10) = 1 (F = OUT_prev
    for the P on error; 16 times faster is capped at the whole step, 10)."""
    b = make(gain=1.0, reset=10.0, out_scale_eu_0=4.0, out_scale_eu_100=20.0, out_lo_lim=7.2,
             precision=precision)
    man = run(b, mode="MAN", man_out=7.2, sp=50.0, pv=40.0)
    auto = run(b, mode="AUTO", sp=50.0, pv=40.0)
    assert man["r_term"][0] == pytest.approx(10.0, rel=1e-6)
    assert auto["r_term"][0] - man["r_term"][0] == pytest.approx(1.0, rel=1e-5)


def test_DV3_series_to_standard_conversion() -> None:
    """spec 4.8 DV3: Series GAIN 2, RESET 10, RATE 2 = Standard Kc 2.4, Ti 12, Td 1.6667:
    Kc = 2·(1 + 2/10), Ti = 10 + 2, Td = 10·2/12 (spec 4.2 [D])."""
    kc, ti, td = series_to_standard(2.0, 10.0, 2.0)
    assert (kc, ti) == pytest.approx((2.4, 12.0), abs=1e-12)
    assert td == pytest.approx(1.6667, abs=1e-4)
    assert series_to_standard(2.0, INF, 2.0) == (2.0, INF, 2.0)


def test_DV3_series_block_first_scans_by_hand(make: Make) -> None:
    """spec 4.2 Series form, lead-lag (1 + RATE·s)/(α·RATE·s + 1) = 1 + (1 - α)·RATE·s/(...):
    GAIN 2, RESET 10, RATE 2, α 0.125, dt 1, e steps 0 -> 5 % from OUT = R = 30."""
    b = make(form="series", structure="pid_action_on_error", gain=2.0, reset=10.0, rate=2.0,
             **F64)
    steady(b, out=30.0)
    first, second = run(b, mode="AUTO", pv=45.0), run(b, mode="AUTO", pv=45.0)
    # D_1 = GAIN·(1-α)·RATE·Δd/(α·RATE + dt) = 2·0.875·2·5/1.25 = 14; P = 10; R_1 = 30
    assert first["d_term"][0] == pytest.approx(14.0, abs=1e-12)
    assert first["out"][0] == pytest.approx(54.0, abs=1e-12)
    # D_2 = 0.25·14/1.25 = 2.8; series keeps D in the reset loop: F = OUT_1 = 54,
    # R_2 = 30 + 0.1·(54 - 30) = 32.4; OUT_2 = 10 + 2.8 + 32.4 = 45.2
    assert second["d_term"][0] == pytest.approx(2.8, abs=1e-12)
    assert second["r_term"][0] == pytest.approx(32.4, abs=1e-12)
    assert second["out"][0] == pytest.approx(45.2, abs=1e-12)


@pytest.mark.parametrize(("series_derivative", "offset"), [
    # R collects a·ΣD: lead-lag ΣD = 14/(1 - 0.2) = 17.5, filtered 16/(1 - 0.2) = 20; the
    # Standard form's extra P is (2.4 - 2)·5 = 2 = a·20. So filtered matches the conversion
    # exactly once D has died out, and the lead-lag differs by a·(17.5 - 20) = -0.25
    # = -α·GAIN'·RATE'/RESET'·e, the filter the conversion ignores.
    ("filtered", 0.0), ("lead_lag", -0.25)])
def test_DV3_series_matches_its_standard_equivalent_after_the_derivative_transient(
        make: Make, series_derivative: str, offset: float) -> None:
    """spec 4.8 DV3, behaviour: the series block and the Standard block with the converted
    settings ramp alike (2 %/s·... both GAIN·e/RESET = 1 %/s here) and end level."""
    kc, ti, td = series_to_standard(2.0, 10.0, 2.0)
    ser = make(form="series", structure="pid_action_on_error", gain=2.0, reset=10.0, rate=2.0,
               series_derivative=series_derivative, **F64)
    std = make(form="standard", structure="pid_action_on_error", gain=kc, reset=ti, rate=td,
               **F64)
    for b in (ser, std):
        steady(b, out=30.0)
    for _ in range(30):
        a, s = run(ser, mode="AUTO", pv=45.0), run(std, mode="AUTO", pv=45.0)
    assert a["out"][0] - s["out"][0] == pytest.approx(offset, abs=1e-9)
    # both ramps: 2·5/10 = 2.4·5/12 = 1 % per 1 s scan
    nxt_a, nxt_s = run(ser, mode="AUTO", pv=45.0), run(std, mode="AUTO", pv=45.0)
    assert nxt_a["out"][0] - a["out"][0] == pytest.approx(1.0, abs=1e-9)
    assert nxt_s["out"][0] - s["out"][0] == pytest.approx(1.0, abs=1e-9)


def test_DV4_pi_on_error_d_on_pv_setpoint_step_has_no_derivative_kick(make: Make) -> None:
    """spec 4.8 DV4: "PI action on error, D action on PV", SP step +5 %, PV constant: D = 0,
    P jumps by 5·GAIN. (RESET = inf keeps R = 50 so the output shows P and D alone.)"""
    b = make(structure="pi_action_on_error_d_action_on_pv", gain=2.0, rate=4.0, **F64)
    steady(b)
    r = run(b, mode="AUTO", sp=55.0)
    assert r["d_term"][0] == 0.0
    assert r["p_term"][0] == pytest.approx(10.0, abs=1e-12)
    assert r["out"][0] == pytest.approx(60.0, abs=1e-12)


def test_DV4_contrast_pid_on_error_kicks(make: Make) -> None:
    """spec 4.3/4.7 step 6: with D on the error the same step gives the filtered kick
    D = GAIN·RATE·Δe/(α·RATE + dt) = 2·4·5/(0.5 + 1) = 26.667, then ·0.5/1.5 each scan."""
    b = make(structure="pid_action_on_error", gain=2.0, rate=4.0, **F64)
    steady(b)
    first, second = run(b, mode="AUTO", sp=55.0), run(b, mode="AUTO")
    assert first["d_term"][0] == pytest.approx(80.0 / 3.0, abs=1e-12)
    assert second["d_term"][0] == pytest.approx(80.0 / 9.0, abs=1e-12)
    # OUT = P + D + R = 10 + 26.667 + 50 (RESET inf: R stays at the Man value 50)
    assert first["out"][0] == pytest.approx(50.0 + 10.0 + 80.0 / 3.0, abs=1e-12)


def test_derivative_exact_discretisation(make: Make) -> None:
    """spec 4.7 step 6 [A] alternative: step invariant D_1 = GAIN·Δe/α = 2·5/0.125 = 80,
    then ·e^(-dt/(α·RATE)) = e^(-2) per scan."""
    b = make(structure="pid_action_on_error", gain=2.0, rate=4.0,
             derivative_discretisation="exact", out_hi_lim=110.0, **F64)
    steady(b, out=0.0)
    first, second = run(b, mode="AUTO", sp=55.0), run(b, mode="AUTO")
    assert first["d_term"][0] == pytest.approx(80.0, abs=1e-12)
    assert second["d_term"][0] == pytest.approx(80.0 * math.exp(-2.0), abs=1e-12)


# ----------------------------------------------------------------------------------------------
# Modes and bumpless transfer, spec 4.5 and 4.7 step 10
# ----------------------------------------------------------------------------------------------
def test_man_to_auto_is_bumpless(make: Make) -> None:
    """spec 4.5: in Man R = OUT - P - D - FF, so the first Auto scan moves only by one scan of
    reset: GAIN 2, RESET 20, e = 5 %: Man R = 30 - 10 = 20; Auto R = 20 + (1/20)·(30 - 20)
    = 20.5, OUT = 10 + 20.5 = 30.5 (not 40, the proportional kick)."""
    b = make(gain=2.0, reset=20.0, **F64)
    man = steady(b, out=30.0, sp=50.0, pv=45.0)
    assert man["out"] == (30.0, GOOD_CONST)  # Man: constant limit bits (module docstring)
    assert man["r_term"][0] == 20.0
    assert man["mode_actual"][0] == MAN
    auto = run(b, mode="AUTO")
    assert auto["out"] == (30.5, GOOD)
    assert auto["mode_actual"][0] == AUTO


def test_auto_to_man_holds_the_output_despite_a_latched_man_out(make: Make) -> None:
    """spec 4.5 Man + operator-write semantics: MAN with the same man_out as before writes
    nothing, so OUT stays where Auto left it; a new value is a write (limited to OUT limits)."""
    b = make(gain=2.0, reset=20.0, **F64)
    steady(b, out=30.0, sp=50.0, pv=45.0)
    auto = [run(b, mode="AUTO")["out"][0] for _ in range(3)]
    held = run(b, mode="MAN", man_out=30.0)
    assert held["out"] == (auto[-1], GOOD_CONST)
    assert run(b, man_out=35.0)["out"][0] == 35.0
    assert run(b, man_out=120.0)["out"][0] == 100.0  # limited in Man


def test_no_out_limits_in_manual(make: Make) -> None:
    """spec 4.5 (CONTROL_OPTS "No OUT limits in Manual"): the operator value is not limited."""
    b = make(no_out_limits_manual=True, **F64)
    assert run(b, mode="MAN", man_out=105.0)["out"] == (105.0, GOOD_CONST)


def test_target_mode_writes_of_iman_and_lo_are_rejected(make: Make) -> None:
    """spec 4.5: IMan and LO are actual modes only; writing them leaves the target."""
    b = make(**F64)
    run(b, mode="MAN", man_out=40.0)
    r = run(b, mode="IMAN")
    assert (r["mode_target"][0], r["mode_actual"][0]) == (MAN, MAN)


def test_tracking_lo_mode_and_bumpless_release(make: Make) -> None:
    """spec 4.5 LO: Track enable + TRK_IN_D -> OUT = TRK_VAL scaled from TRK_SCALE (0..200 EU:
    70 EU = 35 %), R back-initialised; release: OUT = 35 + one scan of reset."""
    b = make(gain=1.0, reset=10.0, track_enable=True, trk_scale_eu_100=200.0, **F64)
    steady(b, out=50.0, sp=50.0, pv=46.0)  # e = 4 %
    lo = run(b, mode="AUTO", trk_in_d=1.0, trk_val=70.0)
    assert lo["mode_actual"][0] == LO
    assert lo["out"] == (35.0, GOOD_CONST)
    assert lo["bkcal_out"][1] == GOOD_C_LO
    assert lo["r_term"][0] == 31.0  # 35 - P(4)
    rel = run(b, trk_in_d=0.0)
    # F = OUT_prev - (P - Pe) = 35; R = 31 + 0.1·(35 - 31) = 31.4; OUT = 4 + 31.4
    assert rel["mode_actual"][0] == AUTO
    assert rel["out"][0] == pytest.approx(35.4, abs=1e-12)


def test_tracking_with_target_man_needs_track_in_manual(make: Make) -> None:
    """spec 4.5: with target Man, TRK_IN_D acts only with "Track in Manual"."""
    plain = make(track_enable=True, **F64)
    inman = make(track_enable=True, track_in_manual=True, **F64)
    for b, mode in ((plain, MAN), (inman, LO)):
        r = run(b, mode="MAN", man_out=20.0, trk_in_d=1.0, trk_val=80.0)
        assert r["mode_actual"][0] == mode
        assert r["out"][0] == (20.0 if mode == MAN else 80.0)
    off = make(**F64)  # Track enable off: TRK_IN_D is ignored
    assert run(off, trk_in_d=1.0, trk_val=80.0)["mode_actual"][0] == AUTO


def test_iman_from_bkcal_in_status_follows_the_downstream(make: Make) -> None:
    """spec 4.5 IMan: BKCAL_IN Good cascade NI or IR -> OUT = BKCAL_IN, R back-initialised;
    IR is answered with IA (module docstring); Good cascade again -> bumpless Auto."""
    b = make(gain=1.0, reset=10.0, **F64)
    steady(b, out=50.0, sp=50.0, pv=45.0)  # e = 5 %
    ni = run(b, mode="AUTO", bkcal_in=(42.0, GOOD_C_NI))
    assert ni["mode_actual"][0] == IMAN
    assert ni["out"] == (42.0, GOOD_C_CONST)
    assert ni["r_term"][0] == 37.0  # 42 - 5
    ir = run(b, bkcal_in=(43.0, GOOD_C_IR))
    assert ir["out"] == (43.0, GOOD_C_IA_CONST)
    bad = run(b, bkcal_in=(10.0, BAD))  # Bad BKCAL_IN: IMan (FF), no value to follow: hold
    assert (bad["mode_actual"][0], bad["out"][0]) == (IMAN, 43.0)
    back = run(b, bkcal_in=(43.0, GOOD_C))
    # IMan back-initialised R = 43 - P(5) = 38 (step 10); Auto: F = OUT_prev = 43,
    # R = 38 + 0.1·(43 - 38) = 38.5, OUT = 5 + 38.5 = 43.5
    assert back["mode_actual"][0] == AUTO
    assert back["out"] == (43.5, GOOD_C)  # a cascade partner on BKCAL_IN: Good cascade


def test_cas_takes_the_setpoint_from_cas_in(make: Make) -> None:
    """spec 4.5 Cas: SP = CAS_IN; BKCAL_OUT = working SP with Good cascade (4.7 step 11);
    Cas -> Auto keeps the last cascade SP (the SP parameter followed CAS_IN)."""
    b = make(gain=1.0, reset=10.0, initial_out=50.0, **F64)
    auto = run(b, mode="AUTO", sp=50.0, pv=50.0)
    assert auto["bkcal_out"] == (50.0, GOOD_C_NI)  # not in Cas: not invited
    cas = run(b, mode="CAS", cas_in=(60.0, GOOD_C))
    assert cas["mode_actual"][0] == CAS
    assert cas["working_sp"][0] == 60.0
    assert cas["bkcal_out"] == (60.0, GOOD_C)
    assert cas["p_term"][0] == 10.0
    again = run(b, mode="AUTO", sp=50.0)  # sp = 50 is not a new write: SP stays 60
    assert again["working_sp"][0] == 60.0
    assert run(b, sp=55.0)["working_sp"][0] == 55.0  # a new operator write


def test_cas_with_bad_cas_in_sheds_to_auto_and_requests_initialisation(make: Make) -> None:
    """spec 4.5/4.6: target Cas, CAS_IN Bad -> actual Auto, BKCAL_OUT.ST IR; with STATUS_OPTS
    "Target to next permitted mode if Bad CAS_IN" the target becomes Auto."""
    b = make(initial_out=50.0, **F64)  # OUT mid-range: no limit bits
    r = run(b, mode="CAS", cas_in=(60.0, BAD), sp=50.0, pv=50.0)
    assert (r["mode_target"][0], r["mode_actual"][0]) == (CAS, AUTO)
    assert r["bkcal_out"][1] == GOOD_C_IR
    b2 = make(target_to_next_if_bad_cas_in=True, ifs_if_bad_cas_in=True, initial_out=50.0,
              **F64)
    r2 = run(b2, mode="CAS", cas_in=(60.0, BAD), sp=50.0, pv=50.0)
    assert (r2["mode_target"][0], r2["mode_actual"][0]) == (AUTO, AUTO)
    assert r2["out"][1] == 0xE0  # IFS if Bad CAS_IN: Good cascade IFS, not limited


def test_obey_sp_limits_in_cas(make: Make) -> None:
    """spec 4.7 step 2: CAS_IN is limited to SP_LO_LIM..SP_HI_LIM only with "Obey SP limits"."""
    free = make(sp_hi_lim=70.0, **F64)
    obey = make(sp_hi_lim=70.0, obey_sp_limits_cas=True, **F64)
    assert run(free, mode="CAS", cas_in=80.0, pv=50.0)["working_sp"][0] == 80.0
    assert run(obey, mode="CAS", cas_in=80.0, pv=50.0)["working_sp"][0] == 70.0
    assert run(free, mode="AUTO", sp=90.0)["working_sp"][0] == 70.0  # operator SP: limited


def test_sp_pv_track_in_man(make: Make) -> None:
    """spec 4.5/4.7 step 2: "SP-PV track in Man": SP = PV (the PV as it stands at step 2, the
    previous scan's), and Man -> Auto keeps it (the SP parameter was written)."""
    b = make(sp_pv_track_man=True, gain=1.0, reset=10.0, **F64)
    run(b, mode="MAN", man_out=50.0, sp=50.0, pv=40.0)  # first scan: PV starts at IN = 40
    r = run(b, pv=42.0)
    assert r["working_sp"][0] == 40.0  # PV_{k-1}
    r = run(b, pv=42.0)
    assert r["working_sp"][0] == 42.0
    auto = run(b, mode="AUTO")
    assert auto["working_sp"][0] == 42.0
    assert auto["out"][0] == 50.0  # e = 0: no bump at all


def test_sp_pv_track_in_lo_or_iman(make: Make) -> None:
    """spec 4.7 step 2 ("SP-PV track in LO or IMan"): in IMan the SP follows PV_{k-1}."""
    b = make(sp_pv_track_lo_iman=True, **F64)
    run(b, mode="AUTO", sp=50.0, pv=44.0)
    r = run(b, bkcal_in=(30.0, GOOD_C_NI))
    assert (r["mode_actual"][0], r["working_sp"][0]) == (IMAN, 44.0)
    plain = make(**F64)
    run(plain, mode="AUTO", sp=50.0, pv=44.0)
    assert run(plain, bkcal_in=(30.0, GOOD_C_NI))["working_sp"][0] == 50.0


def test_sp_track_retained_target_follows_cas_in(make: Make) -> None:
    """CONTROL_OPTS "SP track retained target" (spec 4.1): target Cas, actual IMan: SP =
    CAS_IN, and it takes precedence over SP-PV tracking."""
    b = make(sp_track_retained_target=True, sp_pv_track_lo_iman=True, **F64)
    r = run(b, mode="CAS", cas_in=(65.0, GOOD_C), bkcal_in=(30.0, GOOD_C_NI), sp=50.0, pv=44.0)
    assert (r["mode_target"][0], r["mode_actual"][0]) == (CAS, IMAN)
    assert r["working_sp"][0] == 65.0
    assert r["bkcal_out"] == (65.0, GOOD_C_IR)  # target Cas, not yet in Cas: IR


def test_use_pv_for_bkcal_out_in_cas(make: Make) -> None:
    """spec 4.7 step 11: BKCAL_OUT = PV instead of the working SP once in Cas."""
    b = make(use_pv_for_bkcal_out=True, **F64)
    assert run(b, mode="AUTO", sp=50.0, pv=44.0)["bkcal_out"][0] == 50.0
    assert run(b, mode="CAS", cas_in=(60.0, GOOD_C))["bkcal_out"][0] == 44.0


def test_sp_rate_limits_in_auto_only(make: Make) -> None:
    """spec 4.7 step 2 (4.1 SP_RATE_UP/DN, EU/s): 2 EU/s up, 5 EU/s down, dt 1 s, Auto."""
    b = make(sp_rate_up=2.0, sp_rate_dn=5.0, **F64)
    run(b, mode="AUTO", sp=50.0, pv=50.0)
    assert values(b, "working_sp", 6, sp=60.0) == [52.0, 54.0, 56.0, 58.0, 60.0, 60.0]
    assert values(b, "working_sp", 5, sp=40.0) == [55.0, 50.0, 45.0, 40.0, 40.0]
    run(b, mode="MAN", man_out=50.0)
    assert run(b, sp=70.0)["working_sp"][0] == 70.0  # Man: no ramp


def test_sp_filter(make: Make) -> None:
    """spec 4.7 step 2 SP_FTIME, backward Euler like the PV filter: T 1 s, dt 1 s: a = 0.5."""
    b = make(sp_ftime=1.0, **F64)
    run(b, mode="AUTO", sp=50.0, pv=50.0)
    assert values(b, "working_sp", 3, sp=60.0) == [55.0, 57.5, 58.75]


def test_bad_in_drops_the_actual_mode_to_man_and_recovers_bumplessly(make: Make) -> None:
    """spec 4.5/4.6: Bad (or NaN) IN -> actual Man, target kept; OUT holds; PV.ST follows IN.ST;
    IN back -> Auto, re-initialised from the held OUT (OUT = OUT_prev + a·Pe)."""
    b = make(gain=1.0, reset=10.0, **F64)
    steady(b)
    held = run(b, mode="AUTO", pv=45.0)["out"][0]  # 55
    bad = run(b, pv=(45.0, BAD))
    assert (bad["mode_target"][0], bad["mode_actual"][0]) == (AUTO, MAN)
    assert bad["out"] == (held, GOOD_CONST)
    assert bad["filtered_pv"] == (45.0, BAD)
    nan = run(b, pv=NAN)
    assert nan["mode_actual"][0] == MAN
    assert nan["out"][0] == held
    assert nan["filtered_pv"] == (45.0, BAD)  # holds its value, Bad non-specific
    assert run(b, pv=INF)["out"][0] == held
    back = run(b, pv=45.0)
    assert back["mode_actual"][0] == AUTO
    assert back["out"][0] == pytest.approx(held + 0.1 * 5.0, abs=1e-12)
    assert back["out"][1] == GOOD


def test_target_to_manual_if_bad_in_latches(make: Make) -> None:
    """spec 4.5 (STATUS_OPTS "Target to Manual if Bad IN"): the target goes to Man and stays
    after IN recovers; the operator returns it by writing the mode (MAN, then AUTO)."""
    b = make(target_to_man_if_bad_in=True, **F64)
    run(b, mode="AUTO", sp=50.0, pv=50.0)
    r = run(b, pv=(50.0, BAD))
    assert (r["mode_target"][0], r["mode_actual"][0]) == (MAN, MAN)
    r = run(b, mode="AUTO", pv=50.0)  # the same value as before: not a write
    assert (r["mode_target"][0], r["mode_actual"][0]) == (MAN, MAN)
    run(b, mode="MAN")
    r = run(b, mode="AUTO")
    assert r["mode_actual"][0] == AUTO


def test_uncertain_in_is_bad_unless_use_uncertain_as_good(make: Make) -> None:
    """spec 4.1/4.6 STATUS_OPTS "Use Uncertain as Good"; used as Good, OUT.ST is degraded to
    Uncertain (4.7 step 11)."""
    plain = make(**F64)
    used = make(use_uncertain_as_good=True, **F64)
    assert run(plain, sp=50.0, pv=(50.0, UNC_LUV))["mode_actual"][0] == MAN
    r = run(used, sp=50.0, pv=(50.0, UNC_LUV))
    assert r["mode_actual"][0] == AUTO
    assert r["out"][1] == UNC | 0x01  # Uncertain, low limited (OUT = initial 0 %)
    assert r["filtered_pv"][1] == UNC_LUV  # PV.ST follows IN.ST


def test_ifs_if_bad_in(make: Make) -> None:
    """spec 4.1 STATUS_OPTS "IFS if Bad IN": OUT.ST Good cascade IFS (constant: Man)."""
    b = make(ifs_if_bad_in=True, **F64)
    assert run(b, sp=50.0, pv=(50.0, BAD))["out"][1] == GOOD_C_IFS_CONST


def test_oos_status_and_bumpless_return(make: Make) -> None:
    """spec 4.5/4.6: OOS holds OUT with Bad out-of-service status on OUT and BKCAL_OUT."""
    b = make(gain=1.0, reset=10.0, **F64)
    steady(b)
    r = run(b, mode="OOS", pv=45.0)
    assert r["out"] == (50.0, BAD_OOS)
    assert r["bkcal_out"][1] == BAD_OOS
    back = run(b, mode="AUTO")
    assert back["out"][0] == pytest.approx(50.5, abs=1e-12)  # 50 + 0.1·5


# ----------------------------------------------------------------------------------------------
# Reset, anti-windup, dead band, feedforward: spec 4.4, 4.7 steps 7-9
# ----------------------------------------------------------------------------------------------
def test_arw_16x_reset_on_the_way_back(make: Make) -> None:
    """spec 4.4 (R42): OUT beyond ARW_HI_LIM and R moving back -> RESET/16.
    GAIN 1, RESET 32, dt 1, ARW_HI_LIM 70; from OUT = R = 90, e = -10 %:
    scan 1: F = 90 = R -> R 90, OUT 80; scan 2: OUT_prev 80 > 70, F = 80 < R:
    a = 16/32 = 0.5, R = 90 - 5 = 85, OUT 75; scan 3: R = 85 + 0.5·(75 - 85) = 80, OUT 70;
    scan 4: OUT_prev = 70 is not beyond 70: a = 1/32, R = 80 - 10/32, OUT = 69.6875."""
    b = make(gain=1.0, reset=32.0, arw_hi_lim=70.0, **F64)
    steady(b, out=90.0)
    got = values(b, "out", 4, mode="AUTO", pv=60.0)
    assert got == pytest.approx([80.0, 75.0, 70.0, 69.6875], abs=1e-12)
    plain = make(gain=1.0, reset=32.0, **F64)  # no ARW window: 90 - 10/32 = 89.6875 -> 79.6875
    steady(plain, out=90.0)
    assert values(plain, "out", 2, mode="AUTO", pv=60.0)[1] == pytest.approx(79.6875)


def test_arw_does_not_act_when_the_reset_moves_away(make: Make) -> None:
    """spec 4.4: beyond ARW_HI_LIM but R rising: normal RESET: 90 + (95 - 90)/32."""
    b = make(gain=1.0, reset=32.0, arw_hi_lim=70.0, **F64)
    steady(b, out=90.0)
    got = values(b, "out", 2, mode="AUTO", pv=45.0)
    assert got[1] == pytest.approx(5.0 + 90.0 + 5.0 / 32.0, abs=1e-12)


def test_arw_limits_in_out_eu(make: Make) -> None:
    """arw_units = out_eu (R42: ARW limits in OUT units): OUT_SCALE 0..200 EU, ARW_HI 140 EU =
    70 %: the same sequence as in percent."""
    b = make(gain=1.0, reset=32.0, arw_hi_lim=140.0, arw_units="out_eu",
             out_scale_eu_100=200.0, **F64)
    steady(b, out=180.0)
    got = values(b, "out", 3, mode="AUTO", pv=60.0)
    assert got == pytest.approx([160.0, 150.0, 140.0], abs=1e-12)


def test_ideadband_freezes_the_reset(make: Make) -> None:
    """spec 4.4: no reset action while abs(SP - PV) < IDEADBAND (EU, strict): GAIN 1,
    RESET 10, IDEADBAND 2: e = 1 -> R stays 50, OUT 51; e = 2 (not inside) -> integrates."""
    b = make(gain=1.0, reset=10.0, ideadband=2.0, **F64)
    steady(b)
    assert values(b, "out", 3, mode="AUTO", pv=49.0) == [51.0, 51.0, 51.0]
    # F = OUT_prev = 51, R = 50 + 0.1·(51 - 50) = 50.1; P = 2 -> 52.1
    assert run(b, pv=48.0)["out"][0] == pytest.approx(52.1, abs=1e-12)


def test_bkcal_in_limit_bits_stop_the_reset_in_that_direction(make: Make) -> None:
    """spec 4.4: a high-limited BKCAL_IN stops the upstream reset rising (falling is free)."""
    b = make(gain=1.0, reset=10.0, **F64)
    steady(b)
    # e = +10 %: F = OUT_prev = 60 > R = 50 would raise R; the high-limited bits forbid it
    up = values(b, "r_term", 3, mode="AUTO", pv=40.0, bkcal_in=(50.0, GOOD_C_HIGH))
    assert up == [50.0, 50.0, 50.0]
    steady(b, out=70.0, pv=50.0)  # R = 70; e = -10 %: OUT = 60, then R falls freely
    assert run(b, mode="AUTO", pv=60.0)["out"][0] == 60.0
    assert run(b)["r_term"][0] == pytest.approx(69.0, abs=1e-12)  # 70 + 0.1·(60 - 70)


def test_dynamic_reset_limit_feeds_back_bkcal_in(make: Make) -> None:
    """spec 4.4: with dynamic reset limiting F = BKCAL_IN%: R = 50 + 0.1·(45 - 50) = 49.5."""
    b = make(gain=1.0, reset=10.0, dynamic_reset_limit=True, **F64)
    steady(b)
    r = run(b, mode="AUTO", pv=40.0, bkcal_in=(45.0, GOOD_C))
    assert r["r_term"][0] == pytest.approx(49.5, abs=1e-12)
    assert r["out"][0] == pytest.approx(59.5, abs=1e-12)


def test_feedforward_is_added_and_not_integrated(make: Make) -> None:
    """spec 4.7 steps 7-8: FF = FF_GAIN·FF_VAL = 0.5·20 = 10 %; F = OUT - FF keeps R at 50
    (ff_in_reset_feedback = false [A]); with true the reset integrates it: 50 + 0.1·10."""
    b = make(gain=1.0, reset=10.0, ff_gain=0.5, **F64)
    steady(b, sp=50.0, pv=50.0)
    assert values(b, "out", 3, mode="AUTO", ff_val=20.0) == [60.0, 60.0, 60.0]
    ffi = make(gain=1.0, reset=10.0, ff_gain=0.5, ff_in_reset_feedback=True, **F64)
    steady(ffi)
    assert values(ffi, "out", 2, mode="AUTO", ff_val=20.0) == pytest.approx([60.0, 61.0])


def test_feedforward_conversion_order_and_bad_ff_holds(make: Make) -> None:
    """spec 4.7 step 8 [A]: FF_SCALE 20..120, FF_GAIN 0.5, FF_VAL 60:
    gain_then_scale (0.5·60 - 20)·100/100 = 10 %; scale_then_gain 0.5·(60 - 20) = 20 %."""
    for order, ff in (("gain_then_scale", 10.0), ("scale_then_gain", 20.0)):
        b = make(ff_gain=0.5, ff_scale_eu_0=20.0, ff_scale_eu_100=120.0, ff_conversion=order,
                 **F64)
        assert run(b, ff_val=60.0)["ff_term"][0] == pytest.approx(ff, abs=1e-12)
        assert run(b, ff_val=NAN)["ff_term"][0] == pytest.approx(ff, abs=1e-12)  # held
        assert run(b, ff_val=(90.0, BAD))["ff_term"][0] == pytest.approx(ff, abs=1e-12)


def test_no_reset_structure_bias(make: Make) -> None:
    """spec 4.3 [?]: without I, R is the bias: bumpless (frozen at the Man value 50), or fixed
    (bias 40 EU, bal_time 2 s: R = 50 + (1 - e^(-1/2))·(40 - 50) after one 1 s scan)."""
    bumpless = make(structure="pd_action_on_error", gain=1.0, reset=10.0, **F64)
    steady(bumpless)
    assert values(bumpless, "r_term", 2, mode="AUTO", pv=45.0) == [50.0, 50.0]
    fixed = make(structure="pd_action_on_error", no_reset_bias="fixed", bias=40.0,
                 bal_time=2.0, **F64)
    steady(fixed)
    assert run(fixed, mode="AUTO")["r_term"][0] == pytest.approx(
        50.0 - 10.0 * (1.0 - math.exp(-0.5)), abs=1e-12)
    at_once = make(structure="p_action_on_error_d_action_on_pv", no_reset_bias="fixed",
                   bias=40.0, **F64)
    steady(at_once)
    assert run(at_once, mode="AUTO", pv=45.0)["out"][0] == 45.0  # P 5 + bias 40


def test_reset_feedback_error_integrates_the_error_with_p_on_pv(make: Make) -> None:
    """spec 4.2 vs 4.7 step 7: "I action on error, PD action on PV" (β = 0), GAIN 1, RESET 10,
    SP = PV = 50, OUT 50: P = -PV% = -50, R = 100. SP -> 60 (e = 10):
    error:  F = OUT - (P - Pe): 50 - (-50 - 0) = 100 -> R 100, OUT 50 (no P kick);
            then F = 50 - (-50 - 10) = 110 -> R 101, OUT 51 (integral of e: +1 %/s)
    output: F = OUT = 50 -> R = 100 + 0.1·(50 - 100) = 95, OUT 45 (the literal law drifts)."""
    b = make(structure="i_action_on_error_pd_action_on_pv", gain=1.0, reset=10.0, **F64)
    assert steady(b)["r_term"][0] == 100.0
    assert values(b, "out", 2, mode="AUTO", sp=60.0) == pytest.approx([50.0, 51.0], abs=1e-12)
    lit = make(structure="i_action_on_error_pd_action_on_pv", gain=1.0, reset=10.0,
               reset_feedback="output", **F64)
    steady(lit)
    assert values(lit, "out", 1, mode="AUTO", sp=60.0) == pytest.approx([45.0], abs=1e-12)


def test_id_structure_has_no_p_and_integrates_the_error(make: Make) -> None:
    """spec 4.3 "ID action on error" (no P): OUT = R + D; R ramps by a·GAIN·e = 0.1·2·5."""
    b = make(structure="id_action_on_error", gain=2.0, reset=10.0, **F64)
    steady(b)
    got = [run(b, mode="AUTO", pv=45.0) for _ in range(3)]
    assert [r["p_term"][0] for r in got] == [0.0, 0.0, 0.0]
    assert [r["out"][0] for r in got] == pytest.approx([50.0, 51.0, 52.0], abs=1e-12)


def test_reset_inf_is_proportional_only(make: Make) -> None:
    """spec 4.1: RESET = inf (the [?] default, R58) disables I: OUT = P + bias, constant."""
    b = make(gain=1.0, **F64)
    steady(b)
    assert values(b, "out", 3, mode="AUTO", pv=45.0) == [55.0, 55.0, 55.0]


def test_limit_bits_released_with_bkcal_hys(make: Make) -> None:
    """spec 4.4: high/low limited at the OUT limits, released only BKCAL_HYS (0.5 %) away.
    P only (RESET inf) around R = 50: OUT = 50 + e."""
    b = make(gain=1.0, **F64)
    steady(b)
    stat = [run(b, mode="AUTO", pv=pv)["out"][1] for pv in (0.0, 0.4, 0.5, 100.0, 99.7, 99.0)]
    # 100 -> 130; 99.6 (0.4 away) -> 130; 99.5 -> 128; 0 -> 129; 0.3 -> 129; 1 -> 128
    assert stat == [GOOD_HIGH, GOOD_HIGH, GOOD, GOOD_LOW, GOOD_LOW, GOOD]


# ----------------------------------------------------------------------------------------------
# Filter, scales and action: spec 4.2, 4.7 steps 3-4, 4.9
# ----------------------------------------------------------------------------------------------
def test_pv_filter_backward_euler_and_exact(make: Make) -> None:
    """spec 4.7 step 3: PV_FTIME 4 s, dt 1 s, IN 50 -> 60: backward a = 1/5: 52, 53.6, 54.88;
    exact a = 1 - e^(-1/4)."""
    b = make(pv_ftime=4.0, **F64)
    run(b, pv=50.0)  # the filter starts at the first usable IN
    assert values(b, "filtered_pv", 3, pv=60.0) == pytest.approx([52.0, 53.6, 54.88], abs=1e-12)
    ex = make(pv_ftime=4.0, filter_discretisation="exact", **F64)
    run(ex, pv=50.0)
    a = 1.0 - math.exp(-0.25)
    assert values(ex, "filtered_pv", 2, pv=60.0) == pytest.approx(
        [50 + 10 * a, 50 + 10 * a + (10 - 10 * a) * a], abs=1e-12)


def test_gain_acts_on_percent_of_span(make: Make) -> None:
    """spec 4.2/4.9: PV_SCALE 0..200, OUT_SCALE 0..50 EU, GAIN 1: e = 20 EU = 10 % of the PV
    span -> P = 10 % of the OUT span = 5 EU: OUT 25 -> 30 EU (0..100 scales: 25 + 20 = 45)."""
    b = make(gain=1.0, pv_scale_eu_100=200.0, out_scale_eu_100=50.0, **F64)
    steady(b, out=25.0, sp=100.0, pv=100.0)
    r = run(b, mode="AUTO", pv=80.0)
    assert r["p_term"][0] == pytest.approx(10.0, abs=1e-12)
    assert r["out"][0] == pytest.approx(30.0, abs=1e-12)
    plain = make(gain=1.0, **F64)
    steady(plain, out=25.0, sp=100.0, pv=100.0)
    assert run(plain, mode="AUTO", pv=80.0)["out"][0] == pytest.approx(45.0, abs=1e-12)


def test_direct_acting_reverses_the_sign(make: Make) -> None:
    """spec 4.2/4.9 CONTROL_OPTS Direct acting: s = -1: PV 5 % above SP raises OUT 50 -> 55."""
    direct = make(gain=1.0, direct_acting=True, **F64)
    reverse = make(gain=1.0, **F64)
    for b, expected in ((direct, 55.0), (reverse, 45.0)):
        steady(b)
        assert run(b, mode="AUTO", pv=55.0)["out"][0] == expected


def test_out_status_good_cascade_toward_a_cascade_partner(make: Make) -> None:
    """spec 4.7 step 11: Good cascade toward a cascade partner (BKCAL_IN Good cascade), else
    Good non-cascade (an unconnected BKCAL_IN, 128)."""
    nc = make(initial_out=50.0, **F64)
    assert run(nc, sp=50.0, pv=50.0)["out"] == (50.0, GOOD)
    c = make(initial_out=50.0, **F64)
    assert run(c, sp=50.0, pv=50.0, bkcal_in=(50.0, GOOD_C))["out"] == (50.0, GOOD_C)


# ----------------------------------------------------------------------------------------------
# Parameters, state, replay, documentation
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("params", "needle"), [
    ({"reset": 0.0}, "'reset' = 0"),
    ({"reset": -1.0}, "'reset'"),
    ({"alpha": 0.01}, "'alpha'"),
    ({"out_hi_lim": 120.0}, "'out_hi_lim' = 120"),
    ({"out_lo_lim": 60.0, "out_hi_lim": 50.0}, "'out_hi_lim'"),
    ({"pv_scale_eu_100": 0.0}, "'pv_scale_eu_100'"),
    ({"beta": 0.5}, "'beta'"),
    ({"arw_hi_lim": 105.0}, "'arw_hi_lim'"),
    ({"initial_out": 90.0, "out_hi_lim": 80.0}, "'initial_out'"),
    ({"structure": "pi"}, "'structure'"),
    ({"gain": 1e300}, "'gain'"),
    ({"rate": 1e300}, "'rate'"),  # beyond float32 (precision float32)
    ({"kp": 1.0}, "unknown parameter 'kp'"),
])
def test_bad_parameters_name_the_parameter(params: dict[str, Any], needle: str) -> None:
    with pytest.raises(ParameterError, match=needle):
        loopworks.create_block("deltav.pid", **params)


def test_reset_zero_disables_option() -> None:
    """spec 4.1 [?]: RESET = 0 disables I with reset_zero_disables (P only)."""
    b = loopworks.create_block("deltav.pid", reset=0.0, reset_zero_disables=True, **F64)
    steady(b)
    assert values(b, "out", 2, mode="AUTO", pv=45.0) == [55.0, 55.0]


def test_beta_gamma_with_two_degrees_of_freedom(make: Make) -> None:
    """spec 4.3 Two degrees of freedom: P on BETA·SP - PV: SP +10 %, BETA 0.3 -> P + 3."""
    base = make(structure="two_degrees_of_freedom", beta=0.3, gamma=0.0, gain=1.0, rate=2.0,
                **F64)
    p0 = steady(base)["p_term"][0]  # P = β·SP% - PV% = 15 - 50 = -35; R = 50 + 35 = 85
    p1 = run(base, mode="AUTO", sp=60.0)  # P = 18 - 50 = -32: +3 (no reset: RESET inf)
    assert p0 == pytest.approx(0.3 * 50.0 - 50.0, abs=1e-12)
    assert p1["p_term"][0] - p0 == pytest.approx(3.0, abs=1e-12)
    assert p1["d_term"][0] == 0.0  # γ = 0: no kick
    assert p1["out"][0] == pytest.approx(53.0, abs=1e-12)


def test_resume_from_saved_state_equals_uninterrupted_run() -> None:
    params = {"gain": 1.5, "reset": 4.0, "rate": 1.0, "structure": "pid_action_on_error",
              "pv_ftime": 2.0, "sp_rate_up": 1.0}
    whole = loopworks.create_block("deltav.pid", **params)
    first = loopworks.create_block("deltav.pid", **params)
    seq = [{"mode": "MAN", "man_out": 40.0, "sp": 50.0, "pv": 48.0}] + [
        {"mode": "AUTO", "sp": 50.0 + (k % 7), "pv": 45.0 + 0.3 * k} for k in range(40)]
    expected = [dict(whole.step(0.5, **s)) for s in seq]
    for s in seq[:20]:
        first.step(0.5, **s)
    saved = json.loads(json.dumps(first.state_dict()))
    resumed = loopworks.create_block(saved["kind"], **saved["params"])
    resumed.load_state(saved)
    got = [dict(resumed.step(0.5, **s)) for s in seq[20:]]
    assert got == expected[20:]


def test_replay_cli_runs_deltav_pid(tmp_path: Path) -> None:
    # the module docstring's replay example: DV2 start, float32 default
    path = write_csv(tmp_path / "dv.csv", ["t", "mode", "man_out", "sp", "pv"],
                     [[0, "MAN", 50, 50, 50], [1, "AUTO", 50, 50, 40],
                      [2, "AUTO", 50, 50, 40], [3, "AUTO", 50, 50, 40]])
    result = CliRunner().invoke(app, ["replay", "deltav.pid", str(path), "-p", "reset=10",
                                      "-p", "out_hi_lim=62"])
    assert result.exit_code == 0, result.output
    rows = list(csv.reader(io.StringIO(result.stdout)))
    head = rows[0]
    assert head[:2] == ["t", "out"]
    out = [float(r[head.index("out")]) for r in rows[1:]]
    st = [int(r[head.index("out.ST")]) for r in rows[1:]]
    assert out == [50.0, 60.0, 61.0, 62.0]
    assert st == [GOOD_CONST, GOOD, GOOD, GOOD_HIGH]


def test_blocks_cli_documents_parameters_and_options() -> None:
    result = CliRunner().invoke(app, ["blocks", "deltav.pid", "--markdown"])
    assert result.exit_code == 0, result.output
    for needle in ("| alpha |  | 0.125 | [0.05, 1] |", "spec 4.4", "reset_discretisation",
                   "Options for the spec's [A]/[?] points", "| mode |  | AUTO |"):
        assert needle in result.stdout


def test_docstring_python_example_runs() -> None:
    """The module docstring's Python example prints the DV2 sequence."""
    pid = loopworks.create_block("deltav.pid", gain=1.0, reset=10.0, rate=0.0,
                                 out_hi_lim=62.0, precision="float64")
    pid.step(1.0, mode="MAN", man_out=50.0, sp=50.0, pv=50.0)
    got = [pid.step(1.0, mode="AUTO", pv=pv) for pv in (40.0,) * 6 + (50.0,) * 3]
    assert [round(r["out"].value, 6) for r in got] == [60.0, 61.0, 62.0, 62.0, 62.0, 62.0,
                                                       55.439, 55.439, 55.439]
    assert [r["out"].status for r in got] == [128, 128, 130, 130, 130, 130, 128, 128, 128]


# ----------------------------------------------------------------------------------------------
# Non-finite and overflowing inputs, start-up output: issue 11 points 1 and 8
# ----------------------------------------------------------------------------------------------
F32_MAX = 3.4028234663852886e38  # the largest IEEE single (a DeltaV float parameter, spec 4.1)
BROKEN = [NAN, INF, -INF, 1e308, -1e308, 3.5e38]  # none fits a float32


@pytest.mark.parametrize("precision", ["float32", "float64"])
@pytest.mark.parametrize("value", BROKEN)
def test_broken_in_is_bad_in_man_held_and_recovers(make: Make, precision: str,
                                                   value: float) -> None:
    """issue 11 point 1, spec 4.5/4.6: an IN that is not finite or does not fit a DeltaV
    float32 is Bad IN: actual Man, OUT held (finite, Good constant: the Man status), PV Bad
    holding 45; good again -> Auto from the held OUT: 55 + 0.1·5 (the same numbers as
    test_bad_in_drops_the_actual_mode_to_man_and_recovers_bumplessly)."""
    b = make(gain=1.0, reset=10.0, precision=precision)
    steady(b)
    assert run(b, mode="AUTO", pv=45.0)["out"][0] == 55.0
    for _ in range(3):
        bad = run(b, pv=value)
        assert (bad["mode_target"][0], bad["mode_actual"][0]) == (AUTO, MAN)
        assert bad["out"] == (55.0, GOOD_CONST)
        assert bad["filtered_pv"] == (45.0, BAD)
        assert all(math.isfinite(v) for v in b.x)
    back = run(b, pv=45.0)
    assert back["mode_actual"][0] == AUTO
    assert back["out"] == (pytest.approx(55.5, abs=1e-5), GOOD)


def test_in_within_the_float32_range_is_a_value(make: Make) -> None:
    """issue 11 point 1: 3e38 fits a float32 (max 3.4028235e38): a Good IN, used; reverse
    action with PV far above SP drives OUT to OUT_LO_LIM (0 %, low limited)."""
    b = make(gain=1.0, reset=10.0)
    steady(b)
    r = run(b, mode="AUTO", pv=3e38)
    assert r["mode_actual"][0] == AUTO
    assert r["filtered_pv"] == (float(np.float32(3e38)), GOOD)
    assert r["out"] == (0.0, GOOD_LOW)
    assert run(b, pv=-F32_MAX)["out"] == (100.0, GOOD_HIGH)


@pytest.mark.parametrize("value", BROKEN)
def test_broken_operator_writes_write_nothing(make: Make, value: float) -> None:
    """issue 11 point 1 + the operator-write rule (module docstring): a write that is not
    finite or does not fit a float32 writes nothing, and the next good value is a write even
    if it equals the last one (the input had no value in between). GAIN 1, RESET 10, e = 5 %:
    Man 30 (R = 25); Auto: R = 25 + 0.1·(30 - 25), OUT = 5 + 25.5 = 30.5; MAN with broken
    SP and OUT writes: SP 50 and OUT 30.5 held; man_out = 30 again: OUT 30."""
    b = make(gain=1.0, reset=10.0, **F64)
    steady(b, out=30.0, sp=50.0, pv=45.0)
    assert run(b, mode="AUTO")["out"][0] == 30.5
    held = run(b, mode="MAN", sp=value, man_out=value)
    assert (held["working_sp"][0], held["out"][0], held["mode_target"][0]) == (50.0, 30.5, MAN)
    assert all(math.isfinite(v) for v in b.x)
    assert run(b, man_out=30.0)["out"][0] == 30.0
    assert run(b, sp=40.0)["working_sp"][0] == 40.0


@pytest.mark.parametrize("value", BROKEN)
def test_broken_cas_in_sheds_to_auto_and_recovers(make: Make, value: float) -> None:
    """issue 11 point 1, spec 4.5/4.6: CAS_IN not finite or beyond float32 is unusable: target
    Cas sheds to Auto with BKCAL_OUT IR (as a Bad CAS_IN); a good CAS_IN again -> Cas."""
    b = make(initial_out=50.0, **F64)
    assert run(b, mode="CAS", cas_in=(60.0, GOOD_C), pv=50.0)["working_sp"][0] == 60.0
    r = run(b, cas_in=(value, GOOD_C))
    assert (r["mode_target"][0], r["mode_actual"][0]) == (CAS, AUTO)
    assert r["bkcal_out"] == (60.0, GOOD_C_IR)
    assert r["working_sp"][0] == 60.0
    back = run(b, cas_in=(62.0, GOOD_C))
    assert (back["mode_actual"][0], back["working_sp"][0]) == (CAS, 62.0)


@pytest.mark.parametrize("value", [INF, -INF, 1e308, -1e308, 3.5e38])
def test_broken_bkcal_in_is_bad_iman_holds_and_recovers(make: Make, value: float) -> None:
    """issue 11 point 1, spec 4.5: a BKCAL_IN value that is infinite or beyond float32 is a
    Bad BKCAL_IN: IMan with no value to follow, OUT held; Good cascade again -> Auto."""
    b = make(gain=1.0, reset=10.0, **F64)
    steady(b, out=50.0, sp=50.0, pv=45.0)
    assert run(b, mode="AUTO", bkcal_in=(42.0, GOOD_C_NI))["out"] == (42.0, GOOD_C_CONST)
    bad = run(b, bkcal_in=(value, GOOD_C))
    assert (bad["mode_actual"][0], bad["out"][0]) == (IMAN, 42.0)
    back = run(b, bkcal_in=(42.0, GOOD_C))
    # IMan: R = 42 - 5 = 37; Auto: R = 37 + 0.1·(42 - 37) = 37.5, OUT = 5 + 37.5
    assert back["mode_actual"][0] == AUTO
    assert back["out"] == (pytest.approx(42.5, abs=1e-12), GOOD_C)


def test_unconnected_bkcal_in_is_not_a_bad_bkcal_in(make: Make) -> None:
    """issue 11 point 1 ("not given" inputs keep their meaning): BKCAL_IN's default, NaN, is
    an unconnected BKCAL_IN, also when it arrives Bad non-specific or Bad not connected (0x08):
    the block computes (Auto, OUT.ST Good non-cascade), not IMan. A NaN with another Bad
    substatus (downstream out of service, 0x1C) is a Bad BKCAL_IN: IMan."""
    for status in (GOOD, BAD, 0x08):
        b = make(initial_out=50.0, **F64)
        r = run(b, sp=50.0, pv=50.0, bkcal_in=(NAN, status))
        assert (r["mode_actual"][0], r["out"]) == (AUTO, (50.0, GOOD))
    oos = make(initial_out=50.0, **F64)
    assert run(oos, sp=50.0, pv=50.0, bkcal_in=(NAN, BAD_OOS))["mode_actual"][0] == IMAN


@pytest.mark.parametrize("value", BROKEN)
def test_broken_ff_trk_val_and_trk_in_d(make: Make, value: float) -> None:
    """issue 11 point 1: FF_VAL broken -> the last FF contribution holds (as NaN/Bad FF_VAL,
    module docstring); TRK_VAL broken in LO -> OUT holds; TRK_IN_D broken -> no tracking."""
    b = make(ff_gain=0.5, track_enable=True, **F64)
    assert run(b, sp=50.0, pv=50.0, ff_val=20.0)["ff_term"][0] == 10.0
    assert run(b, ff_val=value)["ff_term"][0] == 10.0
    lo = run(b, trk_in_d=1.0, trk_val=70.0)
    assert (lo["mode_actual"][0], lo["out"][0]) == (LO, 70.0)
    assert run(b, trk_val=value)["out"] == (70.0, GOOD_CONST)
    assert run(b, trk_in_d=value)["mode_actual"][0] == AUTO


def test_state_is_finite_from_construction(make: Make) -> None:
    """issue 11 point 1: no NaN sentinels in the state (flags + finite values instead), before
    the first scan and after scans whose inputs are all "not given" (NaN)."""
    b = make()
    assert all(math.isfinite(v) for v in b.x)
    for _ in range(3):
        b.step(1.0, pv=NAN, sp=NAN, man_out=NAN, cas_in=NAN, bkcal_in=NAN, ff_val=NAN,
               trk_val=NAN, trk_in_d=NAN)
        assert all(math.isfinite(v) for v in b.x)
        assert all(math.isfinite(v) for v in b.y)


def test_initial_outputs_are_the_start_values(make: Make) -> None:
    """issue 11 point 8: before its first scan the block publishes OUT = initial_out (module
    docstring "Start"), not 0: OUT_SCALE 0..200 EU, initial_out 80 EU; BKCAL_OUT and the
    working SP = the initial SP (0 limited to SP_LO_LIM 20); mode Man (the initial target);
    R = OUT% = 40."""
    b = make(initial_out=80.0, out_scale_eu_100=200.0, sp_lo_lim=20.0)
    out = b.outputs()
    assert out["out"] == (80.0, GOOD)
    assert out["bkcal_out"].value == out["working_sp"].value == 20.0
    assert (out["mode_actual"].value, out["mode_target"].value) == (MAN, MAN)
    assert out["r_term"].value == 40.0
    assert make().outputs()["out"].value == 0.0  # default initial_out: OUT_SCALE 0 %
    b.step(1.0, sp=20.0, pv=20.0)
    b.reset()
    assert b.outputs()["out"].value == 80.0


def test_a_block_earlier_in_the_order_reads_the_start_output() -> None:
    """issue 11 point 8: in a module whose order runs the valve before the PID, the valve's
    first scan reads initial_out (35 %), not 0."""
    from loopworks.sim.module import Module

    m = Module({"valve": loopworks.create_block("valve.choudhury"),
                "pid": loopworks.create_block("deltav.pid", initial_out=35.0)},
               wires={"valve.op": "pid.out", "pid.pv": "valve.position"}, order=["valve", "pid"])
    result = m.run(2.0, 1.0)
    assert result["valve.op"][0] == 35.0


@settings(max_examples=60, deadline=None)
@given(case=cases("deltav.pid"))
def test_kernel_is_sound_by_itself_and_out_within_limits(case: Case) -> None:
    """issue 11 point 1: the kernel alone (not the guard's undo-and-rerun) leaves every state
    finite and every output finite on random parameters and inputs with NaN, ±inf, ±1e308,
    float32 overflows and every status (statuses shown as the guard shows them: a non-finite
    value Bad). Spec 4.4/4.5: OUT within OUT_LO_LIM..OUT_HI_LIM in Auto and Cas, and in Man
    unless "No OUT limits in Manual" with target Man."""
    b = loopworks.create_block("deltav.pid", jit=False, **case.params)
    single = b.params["precision"] == "float32"
    lo = b.p[P.out_eu0] + b.p[P.out_lo] * b.p[P.out_eu_per_pct]
    hi = b.p[P.out_eu0] + b.p[P.out_hi] * b.p[P.out_eu_per_pct]
    if single:
        lo, hi = float(np.float32(lo)), float(np.float32(hi))
    free_man = bool(b.params["no_out_limits_manual"])
    for k, (dt, inputs) in enumerate(zip(case.dts, case.inputs, strict=True)):
        b.set_inputs(inputs)
        shown = np.where(~np.isfinite(b.u) & ((b.us & 0xC0) != 0), 0, b.us)
        deltav_pid_kernel(dt, b.p, b.x, b.u, shown, b.y, b.ys)
        where = f"scan {k}, params {case.params}, inputs {inputs}"
        assert np.isfinite(b.x).all(), where
        assert np.isfinite(b.y).all(), where
        actual, target = b.y[Y.mode_actual], b.y[Y.mode_target]
        if actual in (AUTO, CAS) or (actual == MAN and not (free_man and target == MAN)):
            assert lo <= b.y[0] <= hi, where


# ----------------------------------------------------------------------------------------------
# Retuning in Auto (issue 12 point 4): the option retune = vendor | bumpless
# ----------------------------------------------------------------------------------------------
# The DV1 loop (spec 4.8): GAIN 1, RESET 10 s, dt 1 s, SP 50, PV 40 (e = +10 %), from OUT = R =
# 50. Two Auto scans give OUT 60, 61 (R 50, 51); the old tuning's third scan gives 62 (R 52).
# Each change, with the P term the spec gives at SP% = 50, PV% = 40 (spec 4.7 step 5,
# P = s·GAIN·(β·SP% - PV%)): old P = 1·1·(50 - 40) = 10.
RETUNES: list[tuple[dict[str, Any], dict[str, Any], float, float]] = [
    # (params, change, P_new, the new tuning's reset step a·Pe_new = 0.1·s·GAIN·(SP% - PV%))
    ({}, {"gain": 2.0}, 2.0 * (50.0 - 40.0), 0.1 * 2.0 * 10.0),
    ({}, {"direct_acting": True}, -1.0 * (50.0 - 40.0), 0.1 * -1.0 * 10.0),
    ({"structure": "two_degrees_of_freedom", "beta": 1.0, "gamma": 0.0}, {"beta": 0.5},
     0.5 * 50.0 - 40.0, 0.1 * 10.0),
]


def dv1_two_scans(block: Block) -> None:
    steady(block)
    assert values(block, "out", 2, mode="AUTO", pv=40.0) == [60.0, 61.0]


@pytest.mark.parametrize(("params", "change", "p_new", "step"), RETUNES)
def test_retune_vendor_jumps_by_the_p_change(make: Make, params: dict[str, Any],
                                             change: dict[str, Any], p_new: float,
                                             step: float) -> None:
    """retune = vendor (default): the new coefficients act on the law as it is (spec 4.2,
    4.7 steps 5, 7, 9: OUT = P + D + R + FF, R_k from the previous scan's terms), so the first
    scan after the change is the old tuning's 62 plus P_new - P_old; then R moves by the new
    tuning's step each scan."""
    b = make(gain=1.0, reset=10.0, **params, **F64)
    assert b.params["retune"] == "vendor"
    dv1_two_scans(b)
    b.set_params(**change)
    got = [run(b) for _ in range(3)]
    # R_3 = R_2 + a·(F_2 - R_2), F_2 = OUT_2 - (P_2 - Pe_2) = 61: 51 + 0.1·10 = 52, as before
    assert got[0]["r_term"][0] == pytest.approx(52.0, abs=1e-12)
    assert got[0]["p_term"][0] == pytest.approx(p_new, abs=1e-12)
    assert got[0]["out"][0] == pytest.approx(62.0 + (p_new - 10.0), abs=1e-12)
    out = [r["out"][0] for r in got]
    assert out[1] - out[0] == pytest.approx(step, abs=1e-12)
    assert out[2] - out[1] == pytest.approx(step, abs=1e-12)


@pytest.mark.parametrize(("params", "change", "p_new", "step"), RETUNES)
def test_retune_bumpless_gives_the_old_output_then_the_new_law(
        make: Make, params: dict[str, Any], change: dict[str, Any], p_new: float,
        step: float) -> None:
    """retune = bumpless (DiscretePIDs.jl set_K!): R moves by P_old - P_new at the latched SP
    and PV, so the first scan gives the old tuning's 62 (R_3 = 52 + 10 - P_new, spec 4.7 step
    7 with F_2 - R_2 unchanged) and the loop then follows the new tuning, 62 + step, ..."""
    b = make(gain=1.0, reset=10.0, retune="bumpless", **params, **F64)
    dv1_two_scans(b)
    b.set_params(**change)
    got = [run(b) for _ in range(3)]
    assert got[0]["p_term"][0] == pytest.approx(p_new, abs=1e-12)
    assert got[0]["r_term"][0] == pytest.approx(52.0 + 10.0 - p_new, abs=1e-12)
    assert [r["out"][0] for r in got] == pytest.approx([62.0, 62.0 + step, 62.0 + 2 * step],
                                                       abs=1e-12)
    assert got[0]["out"][1] == GOOD


@pytest.mark.parametrize("form", ["standard", "series"])
@pytest.mark.parametrize("mode", ["AUTO", "CAS"])
@pytest.mark.parametrize("limited", [False, True])
def test_retune_bumpless_float32_within_the_resolution(make: Make, form: str, mode: str,
                                                       limited: bool) -> None:
    """float32 (spec 4.1 [A]): with retune = bumpless the first scan after a change of GAIN
    and STRUCTURE/BETA gives the output a block kept on the old tuning gives, within 2
    float32 steps of the largest term (R and P are stored rounded); with D, in Auto and Cas,
    and at the output limit with the ARW window (spec 4.4)."""
    params: dict[str, Any] = {
        "form": form, "gain": 1.3, "reset": 7.0, "rate": 1.5,
        "structure": "two_degrees_of_freedom", "beta": 0.8, "gamma": 0.4}
    if limited:
        params |= {"out_hi_lim": 70.0, "arw_hi_lim": 60.0}
    new, old = (make(retune="bumpless", **params) for _ in range(2))
    inputs = {"mode": mode, "sp": 57.3, "cas_in": 57.3, "pv": 41.9}
    for blk in (new, old):
        steady(blk, 55.0, 57.3, 41.9, dt=0.5)
        for _ in range(12):
            run(blk, 0.5, **inputs)
    assert np.array_equal(new.x, old.x)
    if limited:
        assert run(old, 0.5)["out"][1] == GOOD_HIGH and run(new, 0.5)["out"][1] == GOOD_HIGH
    new.set_params(gain=2.7, beta=0.3)
    got, want = run(new, 0.5), run(old, 0.5)
    assert got["p_term"][0] != want["p_term"][0]
    size = max(abs(got[k][0]) for k in ("out", "p_term", "r_term", "d_term"))
    assert abs(got["out"][0] - want["out"][0]) <= 2 * np.spacing(np.float32(size))


def test_retune_bumpless_gamma_change_gives_no_derivative_kick(make: Make) -> None:
    """Two degrees of freedom, RATE 2, e = 0 at SP = PV = 50: GAMMA 1 -> 0.9 makes d = γ·SP% -
    PV% step from 0 to -5. retune = vendor: D = s·GAIN·RATE·Δd/(α·RATE + dt) = 2·(-5)/1.25 =
    -8, OUT 42 (spec 4.7 step 6); bumpless re-bases d_{k-1}: no kick, OUT stays 50."""
    for retune, want in (("vendor", 42.0), ("bumpless", 50.0)):
        b = make(structure="two_degrees_of_freedom", beta=1.0, gamma=1.0, gain=1.0,
                 reset=10.0, rate=2.0, retune=retune, **F64)
        steady(b)
        assert run(b, mode="AUTO")["out"][0] == 50.0
        b.set_params(gamma=0.9)
        r = run(b)
        assert r["out"][0] == pytest.approx(want, abs=1e-12), retune


@pytest.mark.parametrize("retune", ["vendor", "bumpless"])
def test_retune_in_man_does_nothing_special(make: Make, retune: str) -> None:
    """In Man nothing is corrected (spec 4.5, 4.7 step 10): the state is untouched, OUT stays
    the operator's, and the next Man scan back-initialises R = OUT - P_new = 50 - 20 = 30, so
    the first Auto scan gives P + R_1 = 20 + 30 + 0.1·(50 - 30) = 52 = OUT + a·Pe_new."""
    b = make(gain=1.0, reset=10.0, retune=retune, **F64)
    steady(b, 50.0, 50.0, 40.0)
    before = b.x.copy()
    b.set_params(gain=2.0)
    assert np.array_equal(b.x, before)
    r = run(b, mode="MAN")
    assert (r["out"][0], r["r_term"][0]) == (50.0, 30.0)
    assert run(b, mode="AUTO")["out"][0] == pytest.approx(52.0, abs=1e-12)


def test_retune_bumpless_ignores_changes_outside_p(make: Make) -> None:
    """RESET, RATE and the other coefficients outside P act on increments: bumpless leaves
    the state as it is (the next scan is the vendor's)."""
    b = make(gain=1.0, reset=10.0, retune="bumpless", **F64)
    dv1_two_scans(b)
    before = b.x.copy()
    b.set_params(reset=20.0, rate=1.0, out_hi_lim=90.0)
    assert np.array_equal(b.x, before)


def test_a_retune_is_judged_on_its_own_values(make: Make) -> None:
    """BETA applies only with the two-degrees-of-freedom structure (spec 4.3): a live BETA
    write on a one-degree block was accepted (the rule read the names given before the
    change), never applied, and then every later tuning write was refused naming beta
    (found by an operator: the loop's tuning was locked, across restarts). The change itself
    is refused now, and the block keeps taking other changes."""
    b = make(gain=0.5, reset=20.0, **F64)
    with pytest.raises(ParameterError, match="'beta' is used only with structure"):
        b.set_params(beta=0.5)
    assert "beta" not in b.given and b.params["beta"] == 1.0
    b.set_params(gain=1.0)
    assert b.params["gain"] == 1.0
    b.set_params(structure="two_degrees_of_freedom", beta=0.5)  # together: accepted
    assert b.params["beta"] == 0.5
