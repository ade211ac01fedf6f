"""``s5.pid``: the Siemens S5 OB 251 block against spec vendor-blocks section 2 and seed 002.

Every expected value is hand arithmetic written out here (the spec 2.13 tables, or the seed
002 formulas evaluated step by step in :func:`seed002_increments`), never a pasted run of the
block. Native (16-bit) results differ from the spec's non-integer columns by the rounding of
each product; those are checked against the spec with the spec's tolerance (1 count per step)
and, separately, against the integer arithmetic done by hand. The golden tests run with the
compiled and with the interpreted kernel (``make`` fixture).
"""

from __future__ import annotations

import inspect
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
from loopworks.vendors import siemens_s5
from tests.csvfiles import write_csv

NAN = math.nan
INF = math.inf
Make = Callable[..., Block]

# The spec 2.13 PI case: K = R = 1000, TI = 100, TD = 0, positioning, W 0 -> 100 at k = 1.
PI = {"k": 1000, "r": 1000, "ti": 100}


@pytest.fixture(params=[True, False], ids=["compiled", "interpreted"])
def make(request: pytest.FixtureRequest) -> Make:
    """``make(**params)``: an s5.pid with the compiled or the interpreted kernel."""
    jit = request.param

    def _make(**params: Any) -> Block:
        return loopworks.create_block("s5.pid", jit=jit, **params)

    return _make


def run(block: Block, scans: Sequence[dict[str, Any]]) -> tuple[list[float], list[float]]:
    """Step once per dict of inputs (dt = 1 s, one OB 13 call each); return (y, dy) lists."""
    ys, dys = [], []
    for inputs in scans:
        out = block.step(1.0, **inputs)
        ys.append(out["y"].value)
        dys.append(out["dy"].value)
    return ys, dys


def steps(n: int, **inputs: Any) -> list[dict[str, Any]]:
    return [dict(inputs) for _ in range(n)]


# -- spec 2.13 worked examples ------------------------------------------------------------------

# spec 2.13 PI step table: (dY nominal, Y nominal, dY exact ÷1024, Y exact ÷1024)
TABLE_2_13 = [
    (110, 110, 104.904175, 104.904175),
    (10, 120, 9.536743, 114.440918),
    (10, 130, 9.536743, 123.977661),
    (10, 140, 9.536743, 133.514404),
    (10, 150, 9.536743, 143.051147),
]


@pytest.mark.parametrize("arithmetic", ["native", "float"])
def test_2_13_pi_step_nominal_column_exact(make: Make, arithmetic: str) -> None:
    """spec 2.13 PI step, nominal ÷1000 column: every product is an integer, so native and
    float give the table exactly."""
    block = make(**PI, scale="nominal", arithmetic=arithmetic)
    y, dy = run(block, steps(5, w=100.0, x=0.0))
    assert dy == [row[0] for row in TABLE_2_13]
    assert y == [row[1] for row in TABLE_2_13]


def test_2_13_pi_step_exact_column_in_float(make: Make) -> None:
    """spec 2.13 PI step, exact ÷1024 column, arithmetic = float (table to 6 decimals)."""
    block = make(**PI, arithmetic="float")  # scale exact is the default
    y, dy = run(block, steps(5, w=100.0, x=0.0))
    # by hand: dY_1 = 1000/1024·(1000/1024·100 + 100/1024·100), dY_k = 1000/1024·100/1024·100
    assert dy[0] == pytest.approx(1000 / 1024 * (1000 / 1024 * 100 + 100 / 1024 * 100), abs=1e-12)
    assert dy[1] == pytest.approx(1000 / 1024 * 100 / 1024 * 100, abs=1e-12)
    for k, row in enumerate(TABLE_2_13):
        assert dy[k] == pytest.approx(row[2], abs=5e-7)
        assert y[k] == pytest.approx(row[3], abs=5e-7)


def test_2_13_pi_step_exact_column_native_within_one_count_per_step(make: Make) -> None:
    """spec 2.13 PI step, exact ÷1024 in 16-bit native arithmetic: the spec's tolerance is
    1 count per step (so k counts on Y_k); the integer values are pinned by hand too."""
    block = make(**PI)  # native, exact, rounding nearest_even
    y, dy = run(block, steps(5, w=100.0, x=0.0))
    for k, row in enumerate(TABLE_2_13):
        assert abs(dy[k] - row[2]) <= 1.0
        assert abs(y[k] - row[3]) <= k + 1
    # by hand: R·PW = 1000·100/1024 = 97.65625 -> 98; TI·XW = 100·100/1024 = 9.765625 -> 10;
    # K·108 = 1000·108/1024 = 105.46875 -> 105; then K·10 = 9.765625 -> 10 per sample
    assert dy == [105, 10, 10, 10, 10]
    assert y == [105, 115, 125, 135, 145]


def test_2_13_floor_rounding_misses_the_spec_tolerance(make: Make) -> None:
    """spec 2.13: why floor is not the default. floor(97.65625) + floor(9.765625) = 106,
    floor(1000·106/1024 = 103.515625) = 103: 1.9 counts below 104.904175."""
    block = make(**PI, rounding="floor")
    _y, dy = run(block, steps(2, w=100.0, x=0.0))
    # k = 2: floor(9.765625) = 9, floor(1000·9/1024 = 8.7890625) = 8
    assert dy == [103, 8]
    assert abs(dy[0] - TABLE_2_13[0][2]) > 1.0


# spec 2.13 D-element check (K = 1, R = 1, TI = 0, TD = 2, nominal; XW step of 100 at k = 1)
D_CASE = {"k": 1000, "r": 1000, "ti": 0, "td": 2000, "scale": "nominal"}
LAW_A_TABLE = [  # (dD, dY, Y)
    (100, 200, 200), (-50, -50, 150), (-25, -25, 125), (-12.5, -12.5, 112.5),
    (-6.25, -6.25, 106.25), (-3.125, -3.125, 103.125)]


@pytest.mark.parametrize("arithmetic", ["native", "float"])
def test_2_13_d_element_literal_law(make: Make, arithmetic: str) -> None:
    """spec 2.13 D-element check, literal law (dd_decay 1.0): dY = 300, 0, 0, ...; Y stays
    at 300 (D behaves like extra P of gain TD)."""
    block = make(**D_CASE, dd_decay=1.0, arithmetic=arithmetic)
    y, dy = run(block, steps(6, w=100.0, x=0.0))
    assert dy == [300, 0, 0, 0, 0, 0]
    assert y == [300] * 6


def test_2_13_d_element_law_a_float(make: Make) -> None:
    """spec 2.13 D-element check, law A (dd_decay 0.5), float: the table exactly."""
    block = make(**D_CASE, arithmetic="float")
    for dd, dy, y in LAW_A_TABLE:
        out = block.step(1.0, w=100.0, x=0.0)
        assert block.state()["dd1"] == dd
        assert out["dy"].value == dy
        assert out["y"].value == y


def test_2_13_d_element_law_a_native(make: Make) -> None:
    """spec 2.13 D-element check, law A, native: rows 1-3 exact, then within 1 count of the
    table. By hand (half to even): dD_4 = round(-12.5) = -12, dD_5 = -6, dD_6 = -3."""
    block = make(**D_CASE)
    y, dy = run(block, steps(12, w=100.0, x=0.0))
    assert dy[:6] == [200, -50, -25, -12, -6, -3]
    assert y[:6] == [200, 150, 125, 113, 107, 104]
    # then dD = round(-1.5) = -2, -1, round(-0.5) = 0: the kick settles at 101, not 100
    assert y[6:] == [102, 101, 101, 101, 101, 101]
    for k, (_, t_dy, t_y) in enumerate(LAW_A_TABLE):
        assert abs(dy[k] - t_dy) <= 1.0
        assert abs(y[k] - t_y) <= 1.0


def test_2_13_ramp_law_a_settles_at_td_times_slope(make: Make) -> None:
    """spec 2.13 ramp check: XW = 10k, R = 0, TI = 0, TD = 2: the D part of the position
    settles at TD·r = 20 (float). Native loses the halves: 10 + 5 + round(2.5) = 2 + 1 +
    round(0.5) = 0 gives 18."""
    params = {**D_CASE, "r": 0}
    scans = [{"w": 10.0 * k, "x": 0.0} for k in range(1, 61)]
    y_float, _ = run(make(**params, arithmetic="float"), scans)
    assert y_float[:4] == [10, 15, 17.5, 18.75]  # 20·(1 - 2^-k)
    assert y_float[-1] == pytest.approx(20.0, abs=1e-9)
    y_native, _ = run(make(**params), scans)
    assert y_native[:5] == [10, 15, 17, 18, 18]
    assert y_native[-1] == 18


def test_2_6_literal_law_on_a_ramp_is_extra_proportional(make: Make) -> None:
    """spec 2.6: with dd_decay = 1 the D contribution telescopes to TD·XW_k (here 2·10k)."""
    y, _ = run(make(**{**D_CASE, "r": 0}, dd_decay=1.0),
               [{"w": 10.0 * k, "x": 0.0} for k in range(1, 6)])
    assert y == [20, 40, 60, 80, 100]


@pytest.mark.parametrize("k", [1000, -3000, 0])
@pytest.mark.parametrize("arithmetic", ["native", "float"])
def test_2_13_feedforward_z_bypasses_k(make: Make, k: int, arithmetic: str) -> None:
    """spec 2.13 feedforward: Z steps +50 with XW = 0 and D 11.5 = 0: dY = +50 once and Y
    rises by 50 for good, whatever K."""
    block = make(k=k, ti=100, arithmetic=arithmetic)
    scans = [{"w": 0.0, "x": 0.0, "z": 0.0}] * 2 + [{"z": 50.0}] * 4
    y, dy = run(block, scans)
    assert dy == [0, 0, 50, 0, 0, 0]
    assert y == [0, 0, 50, 50, 50, 50]


def test_2_5_no_z_ignores_the_disturbance(make: Make) -> None:
    # spec 2.3/2.5: D 11.5 = 1, no feedforward
    y, _ = run(make(no_z=True), [{"z": 0.0}, {"z": 50.0}, {"z": 80.0}])
    assert y == [0, 0, 0]


# -- the four correction-rate variants of seed 002 ----------------------------------------------

ROWS = [  # (w, x, z, xz); multiples of 10 so every nominal product is an integer
    (100, 0, 0, 0), (100, 20, 30, 10), (120, 40, 30, -20), (120, 30, -10, 40),
    (80, 30, -10, 40), (80, 60, 50, 0), (90, 60, 50, 30)]


def seed002_increments(k: float, r: float, ti: float, td: float, xz_on: bool, no_z: bool,
                       rows: Sequence[tuple[float, float, float, float]]) -> list[float]:
    """dY_k exactly as printed in seed 002 (S5-100U page 9-18), histories starting at 0:

    dY_k = K[(XW_k - XW_{k-1})R + TI·XW_k + (TD(D_k - 2D_{k-1} + D_{k-2}) + dD_{k-1})]
           [+ (Z_k - Z_{k-1})],   dD_k = TD(D_k - 2D_{k-1} + D_{k-2}) + dD_{k-1}
    with D = XW (D 11.1 = 0) or XZ (D 11.1 = 1); Z only if D 11.5 = 0.
    """
    xw1 = xw2 = d1 = d2 = z1 = dd1 = 0.0
    out = []
    for w, x, z, xz in rows:
        xw = w - x
        d = xz if xz_on else xw
        dd = td * (d - 2 * d1 + d2) + dd1
        dy = k * ((xw - xw1) * r + ti * xw + dd)
        if not no_z:
            dy += z - z1
        out.append(dy)
        xw2, xw1 = xw1, xw
        d2, d1 = d1, d
        z1 = z
        dd1 = dd
    del xw2
    return out


@pytest.mark.parametrize("xz_on", [False, True], ids=["D11.1=0", "D11.1=1"])
@pytest.mark.parametrize("no_z", [True, False], ids=["D11.5=1", "D11.5=0"])
@pytest.mark.parametrize("arithmetic", ["native", "float"])
def test_seed002_velocity_variants(make: Make, xz_on: bool, no_z: bool,
                                   arithmetic: str) -> None:
    """seed 002 / spec 2.5: the four velocity variants; velocity mode outputs dY_k in DW 48
    (spec 2.3). K = 2, R = 1, TI = 0.1, TD = 0.5 (nominal), literal law (dd_decay 1.0)."""
    expected = seed002_increments(2.0, 1.0, 0.1, 0.5, xz_on, no_z, ROWS)
    # hand check of the reference, row 1: K·(R·100 + TI·100 + TD·(QW = 100 or QZ = 0))
    assert expected[0] == 2.0 * (100 + 10 + (0 if xz_on else 50))
    block = make(k=2000, r=1000, ti=100, td=500, scale="nominal", dd_decay=1.0,
                 velocity=True, xz_on=xz_on, no_z=no_z, arithmetic=arithmetic)
    y, dy = run(block, [{"w": w, "x": x, "z": z, "xz": xz} for w, x, z, xz in ROWS])
    assert y == expected
    assert dy == expected


@pytest.mark.parametrize("xz_on", [False, True])
@pytest.mark.parametrize("no_z", [True, False])
def test_2_7_positioning_outputs_the_running_sum(make: Make, xz_on: bool, no_z: bool) -> None:
    """spec 2.7: positioning (D 11.3 = 0) puts the sum of all increments in DW 48."""
    incs = seed002_increments(2.0, 1.0, 0.1, 0.5, xz_on, no_z, ROWS)
    block = make(k=2000, r=1000, ti=100, td=500, scale="nominal", dd_decay=1.0,
                 xz_on=xz_on, no_z=no_z)
    y, dy = run(block, [{"w": w, "x": x, "z": z, "xz": xz} for w, x, z, xz in ROWS])
    assert dy == incs
    assert y == list(np.cumsum(incs))


def test_2_5_xz_is_differentiated_as_given(make: Make) -> None:
    # spec 2.5: XZ = X inverts the D action; XZ = -X gives derivative on the measurement
    params = {"k": 1000, "r": 0, "td": 1000, "scale": "nominal", "dd_decay": 1.0,
              "xz_on": True}
    y_plus, _ = run(make(**params), [{"x": 10.0, "xz": 10.0}])
    y_minus, _ = run(make(**params), [{"x": 10.0, "xz": -10.0}])
    assert y_plus == [10]  # TD·QZ = 1·10, although X rose
    assert y_minus == [-10]


# -- scaling, sign, words (spec 2.2) --------------------------------------------------------------


def test_2_2_k_1000_is_gain_0_9765625_exact_and_1_nominal(make: Make) -> None:
    # spec 2.2: the ×0.001 is really ÷1024
    exact, _ = run(make(k=1000, r=1024, arithmetic="float"), [{"w": 100.0}])
    nominal, _ = run(make(k=1000, r=1000, arithmetic="float", scale="nominal"), [{"w": 100.0}])
    assert exact == [97.65625]  # 1000/1024 · (1024/1024 · 100)
    assert nominal == [100.0]


def test_2_2_negative_k_inverts_the_action(make: Make) -> None:
    # spec 2.2: K < 0 inverts; XW = W - X
    y, _ = run(make(**{**PI, "k": -1000}, scale="nominal"), steps(2, w=100.0, x=0.0))
    assert y == [-110, -120]
    y, _ = run(make(**PI, scale="nominal"), steps(2, w=0.0, x=100.0))
    assert y == [-110, -120]  # X above W lowers the output for K > 0


def test_2_2_r_weights_only_p(make: Make) -> None:
    # spec 2.5: R = 0 gives pure I: dY = K·TI·XW = 10 per sample
    y, _ = run(make(**{**PI, "r": 0}, scale="nominal"), steps(3, w=100.0))
    assert y == [10, 20, 30]


def test_native_inputs_are_rounded_and_limited_words(make: Make) -> None:
    # the DB holds integer words: nearest (halves away from zero), limited to the word range
    p = {"k": 1000, "r": 1000, "scale": "nominal"}
    assert run(make(**p), [{"w": 100.4}])[0] == [100]
    assert run(make(**p), [{"w": 100.5}])[0] == [101]
    assert run(make(**p), [{"w": -100.5}])[0] == [-101]
    assert run(make(**p), [{"w": 1e9}])[0] == [32767]
    assert run(make(**p, arithmetic="float"), [{"w": 100.4}])[0] == [pytest.approx(100.4)]


@pytest.mark.parametrize(("rounding", "minus_half", "plus_half", "minus_1_5"), [
    ("nearest_even", 0, 0, -2), ("nearest", -1, 1, -2), ("floor", -1, 0, -2),
    ("truncate", 0, 0, -1)])
def test_rounding_options(make: Make, rounding: str, minus_half: int, plus_half: int,
                          minus_1_5: int) -> None:
    # spec 2.13 [?]: TI·XW = 100·(∓5)/1000 = ∓0.5 and 100·(-15)/1000 = -1.5; K = 1 (nominal)
    p = {"k": 1000, "r": 0, "ti": 100, "scale": "nominal", "rounding": rounding}
    assert run(make(**p), [{"w": -5.0}])[0] == [minus_half]
    assert run(make(**p), [{"w": 5.0}])[0] == [plus_half]
    assert run(make(**p), [{"w": -15.0}])[0] == [minus_1_5]


def test_2_6_nearest_rounding_leaves_dd_stuck_at_minus_one(make: Make) -> None:
    """Why nearest_even is the default (spec 2.6/2.13): with halves rounded away from zero,
    dD_k = round(½·dD_{k-1}) stays at -1 (½·-1 = -0.5 -> -1) and a pure D controller ramps
    down a count per sample at constant error; half to even lets dD reach 0."""
    p = {**D_CASE, "r": 0}
    # nearest by hand: dD = 100, -50, -25, -13, -7, -4, -2, -1, -1, -1, ...
    y, _ = run(make(**p, rounding="nearest"), steps(30, w=100.0))
    assert y[:10] == [100, 50, 25, 12, 5, 1, -1, -2, -3, -4]
    assert y[29] == -24
    # nearest_even by hand: dD = 100, -50, -25, -12, -6, -3, -2, -1, 0, 0, ...
    y, _ = run(make(**p), steps(30, w=100.0))
    assert y[:10] == [100, 50, 25, 13, 7, 4, 2, 1, 1, 1]
    assert y[29] == 1


def test_2_14_overflow_saturates_or_wraps(make: Make) -> None:
    # spec 2.14 [A]: XW = 20000 - (-20000) = 40000 does not fit a word
    p = {"k": 1000, "r": 1000, "scale": "nominal"}
    assert run(make(**p), [{"w": 20000.0, "x": -20000.0}])[0] == [32767]
    assert run(make(**p, overflow="wrap"), [{"w": 20000.0, "x": -20000.0}])[0] == [
        40000 - 65536]
    # K = 0.5: float keeps 40000·0.5; native saturates XW to 32767, ½·32767 = 16383.5 -> 16384
    half = {"k": 500, "r": 1000, "scale": "nominal"}
    assert run(make(**half, arithmetic="float"), [{"w": 20000.0, "x": -20000.0}])[0] == [20000]
    assert run(make(**half), [{"w": 20000.0, "x": -20000.0}])[0] == [16384]


# -- limits and I suppression (spec 2.8) ----------------------------------------------------------

LIM = {"k": 1000, "r": 1000, "ti": 200, "scale": "nominal", "bgog": 150}
LIM_SCANS = [{"w": 100.0, "x": 0.0}] * 4 + [{"x": 10.0}]


@pytest.mark.parametrize(("option", "expected"), [
    # by hand: dY = 120, then dI = 20 each sample; at k = 5, XW = 90: dP = -10, dI = 18
    ("recompute", [120, 140, 140, 140, 148]),  # 160 > 150 with dI > 0: dY = 0, stays at 140
    ("flag", [120, 140, 150, 150, 140]),  # clamps at 150; then dI = 0 while at the limit
    ("none", [120, 140, 150, 150, 150]),  # clamp only
])
def test_2_8_positioning_limit_and_i_suppression(make: Make, option: str,
                                                 expected: list[int]) -> None:
    # spec 2.8: Y limited to [BGUG, BGOG]; I suppressed at a limit (realisation [A])
    y, _ = run(make(**LIM, i_suppression=option), LIM_SCANS)
    assert y == expected


def test_2_8_recompute_leaves_the_limit_on_a_falling_p(make: Make) -> None:
    # spec 2.8: from DW 48 = 150 = BGOG: 150 + 20 > 150 -> dY = 0; then 150 - 10 + 18 = 158
    # > 150 -> recompute without dI: 150 - 10 = 140 (the clamp-only variant stays at 150)
    p = {**LIM, "y0": 150, "first_call": "inputs"}
    assert run(make(**p), [{"w": 100.0}, {"x": 10.0}])[0] == [150, 140]
    assert run(make(**p, i_suppression="none"), [{"w": 100.0}, {"x": 10.0}])[0] == [150, 150]


def test_2_8_negative_k_suppresses_at_the_low_limit(make: Make) -> None:
    # spec 2.8: the direction the I element pushes is that of K·dI
    y, _ = run(make(**{**LIM, "k": -1000, "bgog": 32767, "bgug": -150}), LIM_SCANS[:4])
    assert y == [-120, -140, -140, -140]


@pytest.mark.parametrize("option", ["recompute", "flag", "none"])
def test_2_8_velocity_limits_bound_the_increment(make: Make, option: str) -> None:
    """spec 2.8 [V]: in velocity mode DW 48 is "the limited correcting increment": BGOG/BGUG
    clamp dY, whatever i_suppression says (issue 11 point 6: recomputing without dI gave
    0, -10 here). first_call inputs: no P kick at k = 1. By hand: dY = 62 -> 30; -10 + 60
    = 50 -> 30; -100 + 40 = -60 -> -30."""
    block = make(**{**LIM, "bgog": 30, "bgug": -30}, velocity=True, first_call="inputs",
                 i_suppression=option)
    y, dy = run(block, [{"w": 310.0}, {"w": 300.0}, {"w": 200.0}])
    assert y == [30, 30, -30]
    assert dy == [30, 30, -30]


def test_2_8_velocity_steady_large_error_keeps_the_limited_increment(make: Make) -> None:
    """spec 2.8 [V], issue 11 point 6: a steady large error in velocity mode gives BGOG every
    sample, not BGOG, 0, 0, 0. k = 1000, r = 1000, ti = 100 (÷1024), XW = 1000 held: by hand
    dY = round(1000·(977 + 98)/1024) = 1050, then round(1000·98/1024) = 96, both above 10."""
    block = make(k=1000, r=1000, ti=100, bgog=10, bgug=-10, velocity=True)
    y, dy = run(block, steps(5, w=1000.0, x=0.0))
    assert y == [10, 10, 10, 10, 10]
    assert dy == y
    y, _ = run(make(k=1000, r=1000, ti=100, bgog=10, bgug=-10, velocity=True),
               steps(3, w=-1000.0, x=0.0))
    assert y == [-10, -10, -10]


def test_2_8_velocity_loop_through_a_motor_valve_does_not_stall(make: Make) -> None:
    """issue 11 point 6: velocity mode driving an integrating actuator (a motor valve:
    position += dY each sample, travel 0..2000 counts) on a first-order process (a lag of 5
    samples, X += (position - X)/5) reaches W = 1000. Before the fix the loop stopped at
    X = 5: the first P kick moved the valve by BGOG, then every increment was recomputed
    without its I part and came out 0. The loop settles inside the native I dead zone
    (|XW| <= 512/TI = 5.12 counts for TI = 100, see the block's docs)."""
    block = make(k=1000, r=1000, ti=100, bgog=10, bgug=-10, velocity=True)
    position, x = 0.0, 0.0
    trace = []
    for _ in range(800):
        dy = block.step(1.0, w=1000.0, x=x)["y"].value
        assert -10 <= dy <= 10  # spec 2.8: the increment is limited
        position = min(max(position + dy, 0.0), 2000.0)
        x += (position - x) / 5.0
        trace.append(x)
    assert trace[99] > 500.0  # moving at up to 10 counts a sample, not stalled at 5
    assert abs(1000.0 - round(trace[-1])) <= 5
    assert abs(trace[-1] - trace[-50]) < 1.0  # settled


def test_2_8_recompute_fires_at_the_default_limits(make: Make) -> None:
    """issue 11 point 6 / spec 2.8: the unclamped Y_k = Y_{k-1} + dY_k is compared with the
    limits before anything limits it. At the default BGOG = 32767 a 16-bit saturated sum
    could never exceed it, so the I suppression never fired there. Nominal K = R = TI = 1,
    first_call inputs (PW = 0), XW = 100: dY = dI = 100; 32700 + 100 > 32767 with dI > 0 ->
    recomputed without dI: Y stays 32700 (the spec 2.8 quirk of stopping short)."""
    p = {"k": 1000, "r": 1000, "ti": 1000, "scale": "nominal", "first_call": "inputs"}
    assert run(make(**p, y0=32700), steps(2, w=100.0))[0] == [32700, 32700]
    assert run(make(**p, y0=-32700), steps(2, w=-100.0))[0] == [-32700, -32700]
    assert run(make(**p, y0=32700, i_suppression="none"), steps(2, w=100.0))[0] == [
        32767, 32767]
    # flag: no flag before the first scan, so it reaches the limit, then dI = 0 holds it
    assert run(make(**p, y0=32700, i_suppression="flag"), steps(2, w=100.0))[0] == [
        32767, 32767]


def test_2_8_one_count_of_bgog_moves_the_output_by_at_most_one_count(make: Make) -> None:
    """issue 11 point 6: with the comparison after a saturating sum, BGOG = 32767 and 32766
    gave outputs 32769 counts apart on this sequence (the suppression fired at 32766 only).
    The limit is now a continuous parameter."""
    scans = steps(5, w=30000.0, x=0.0) + steps(3, w=30000.0, x=20000.0)
    p = {"k": 2000, "r": 1000, "ti": 3000}
    top, _ = run(make(**p, bgog=32767), scans)
    below, _ = run(make(**p, bgog=32766), scans)
    assert all(abs(a - b) <= 1 for a, b in zip(top, below, strict=True)), (top, below)
    # by hand at k = 6 (Y = 32767 or 32766): XW 30000 -> 10000, dP = round(-20000·1000/1024)
    # = -19531, dI = round(3000·10000/1024) = 29297, dY = round(2000·9766/1024) = 19074 > 0:
    # beyond BGOG with dI > 0 -> without dI dY = round(2000·-19531/1024) = -38146, a word:
    # -32768, so Y = 32767 - 32768 = -1 (and -2 from 32766)
    assert (top[5], below[5]) == (-1, -2)


# -- manual mode (spec 2.9) ----------------------------------------------------------------------


def test_2_9_positioning_manual_moves_to_yh_then_follows(make: Make) -> None:
    # spec 2.9 [A]: Y halves its distance to YH for 3 samples, then Y = YH
    block = make(y0=128)
    y, dy = run(block, [*steps(5, auto="MAN", yh=0.0), {"yh": 50.0}])
    assert y == [64, 32, 16, 0, 0, 50]
    assert dy == [-64, -32, -16, -16, 0, 50]
    y, _ = run(make(y0=100, arithmetic="float"), steps(4, auto="MAN", yh=0.0))
    assert y == [50, 25, 12.5, 0]
    y, _ = run(make(y0=100, manual_steps=0), steps(2, auto="MAN", yh=40.0))
    assert y == [40, 40]


def test_2_9_velocity_manual_passes_the_manual_increment(make: Make) -> None:
    # spec 2.9: dYH (DW 12) goes straight to dYA; limits stay active
    block = make(velocity=True, bgug=-100)
    y, _ = run(block, [{"auto": 0.0, "yh": 7.0}, {"yh": -200.0}])
    assert y == [7, -100]


def test_2_9_hold_positioning_keeps_the_last_output(make: Make) -> None:
    # spec 2.9: HANDART = 1, GESCHW = 0
    y, dy = run(make(hold=True, y0=77), steps(2, auto="MAN", w=100.0, yh=5.0))
    assert y == [77, 77]
    assert dy == [0, 0]


def test_2_9_hold_velocity_gives_zero_increment(make: Make) -> None:
    # spec 2.9: HANDART = 1, GESCHW = 1
    y, _ = run(make(hold=True, velocity=True), steps(2, auto="MAN", w=100.0, yh=5.0))
    assert y == [0, 0]


def test_2_9_limits_stay_active_in_manual(make: Make) -> None:
    y, _ = run(make(bgog=200, manual_steps=0), [{"auto": "MAN", "yh": 500.0}])
    assert y == [200]


@pytest.mark.parametrize(("y0", "expected"), [(80, 60), (-5, 0)])
def test_2_9_a_y0_preset_outside_the_limits_is_clamped(make: Make, y0: int,
                                                       expected: int) -> None:
    """spec 2.9 [V] "limits stay active in Manual", issue 11 point 6: a DW 48 preset outside
    BGUG..BGOG = 0..60 is limited, before the first call and when Manual holds it."""
    block = make(y0=y0, bgog=60, bgug=0, hold=True)
    assert block.outputs()["y"].value == expected
    assert block.state()["dw48"] == expected
    y, dy = run(block, steps(2, auto="MAN"))
    assert y == [expected, expected]
    assert dy == [0, 0]


def test_2_9_manual_keeps_histories_so_auto_is_bumpless(make: Make) -> None:
    """spec 2.9: Manual updates XW_{k-1}, PW_{k-1} and zeroes dD_{k-1}; Auto continues from
    DW 48 (spec 2.7). K = R = 1, TD = 1, law A, nominal."""
    block = make(k=1000, r=1000, td=1000, scale="nominal")
    y, dy = run(block, [
        {"w": 0.0, "auto": "AUTO"},
        {"w": 100.0, "auto": "MAN", "yh": 40.0},  # Y: 0 + 40/2 = 20
        {"auto": "MAN"},  # 20 + 20/2 = 30
        {"auto": "AUTO"},  # PW = 0, QW = 0, dD = 0: no kick
    ])
    assert y == [0, 20, 30, 30]
    assert dy[3] == 0
    # dD is cleared by one manual scan: Auto step W 0 -> 100 gives dD = ½·TD·QW = 50
    block = make(k=1000, r=1000, td=1000, scale="nominal")
    block.step(1.0, w=100.0)
    assert block.state()["dd1"] == 50
    block.step(1.0, auto="MAN")
    assert block.state()["dd1"] == 0


# -- REG_AUS, first call, DW 48 preset (spec 2.7, 2.10) -------------------------------------------


def test_2_10_off_clears_dw18_to_48_and_the_next_call_kicks(make: Make) -> None:
    block = make(**PI, scale="nominal")
    y, _ = run(block, steps(3, w=105.0, x=5.0))
    assert y == [110, 120, 130]
    out = block.step(1.0, off="OFF")
    assert (out["y"].value, out["dy"].value) == (0, -130)
    state = block.state()
    assert state["w"] == 105  # W (DW 9) survives
    assert state["first"] == 1
    assert all(state[n] == 0 for n in state if n not in ("w", "yh", "first"))
    y, _ = run(block, [{"off": "OFF"}, {"off": "ACTIVE"}, {}])
    assert y == [0, 110, 120]  # from zero histories: the P kick again


def test_2_10_first_call_inputs_has_no_kick(make: Make) -> None:
    # spec 2.10 [A]: first_call = inputs takes the histories from the first inputs
    block = make(**PI, scale="nominal", first_call="inputs")
    y, _ = run(block, [*steps(2, w=100.0), {"off": 1.0}, {"off": 0.0}])
    assert y == [10, 20, 0, 10]
    y, _ = run(make(first_call="inputs"), [{"z": 50.0}, {"z": 60.0}])
    assert y == [0, 10]
    y, _ = run(make(), [{"z": 50.0}])
    assert y == [50]  # default zero: Z_0 = 0, dZ kicks


def test_2_7_y0_presets_dw48(make: Make) -> None:
    # spec 2.7: writing DW 48 presets the output; Auto continues from it
    assert run(make(**PI, scale="nominal", y0=500), [{"w": 0.0}])[0] == [500]
    assert run(make(**PI, scale="nominal", y0=500), [{"w": 100.0}])[0] == [610]


# -- bad input (emulator option, [A]) -------------------------------------------------------------


def test_bad_input_hold_skips_the_scan(make: Make) -> None:
    block = make(**PI, scale="nominal")
    run(block, steps(2, w=100.0, x=0.0))
    before = block.state()
    out = block.step(1.0, x=NAN)
    assert (out["y"].value, out["dy"].value) == (120, 0)
    assert block.state() == before
    out = block.step(1.0, x=0.0, w=INF)
    assert out["y"].value == 120
    assert run(block, [{"w": 100.0}])[0] == [130]  # as if the bad scans never happened


def test_bad_input_hold_in_velocity_gives_zero_increment(make: Make) -> None:
    block = make(**PI, scale="nominal", velocity=True)
    y, _ = run(block, [{"w": 100.0}, {}, {"x": NAN}, {"x": 0.0}])
    assert y == [110, 10, 0, 10]


def test_bad_input_last_uses_the_last_word(make: Make) -> None:
    block = make(**PI, scale="nominal", bad_input="last")
    y, _ = run(block, [{"w": 100.0, "x": 0.0}, {"x": NAN}, {"x": -INF}, {"w": NAN}])
    assert y == [110, 120, 130, 140]


def test_bad_input_only_counts_where_the_scan_uses_it(make: Make) -> None:
    p = {**PI, "scale": "nominal"}
    # z with no_z, yh in Auto, xz without xz_on: not used
    y, _ = run(make(**p, no_z=True), [{"w": 100.0, "z": NAN, "yh": NAN, "xz": INF}])
    assert y == [110]
    # z used (D 11.5 = 0), xz used (D 11.1 = 1), yh used in Manual: the scan is held
    assert run(make(**p), [{"w": 100.0}, {"z": NAN}])[0] == [110, 110]
    assert run(make(**p, xz_on=True), [{"w": 100.0}, {"xz": NAN}])[0] == [110, 110]
    assert run(make(**p), [{"w": 100.0}, {"auto": "MAN", "yh": NAN}])[0] == [110, 110]


@pytest.mark.parametrize("value", [NAN, INF, -INF])
@pytest.mark.parametrize(("name", "params", "inputs"), [
    ("w", {}, {}), ("x", {}, {}), ("z", {}, {}), ("xz", {"xz_on": True}, {}),
    ("yh", {}, {"auto": "MAN"})])
def test_non_finite_input_is_held_and_the_block_recovers(
        make: Make, name: str, params: dict[str, Any], inputs: dict[str, Any],
        value: float) -> None:
    """issue 11 point 1: a non-finite value in an input the scan uses is Bad input: the scan
    is skipped (bad_input = hold), the outputs stay finite, and with good inputs again the
    block continues as if the bad scan never happened."""
    p = {**PI, "scale": "nominal", **params}
    block = make(**p)
    ref = make(**p)
    good = {"w": 100.0, "x": 0.0, "z": 0.0, "xz": 0.0, "yh": 0.0, **inputs}
    run(block, [good, good])
    run(ref, [good, good])
    before = block.state()
    y, dy = run(block, [{**good, name: value}])
    assert (y, dy) == ([block.state()["dw48"]], [0])
    assert block.state() == before
    assert run(block, steps(3, **good)) == run(ref, steps(3, **good))


@pytest.mark.parametrize(("value", "saturated", "wrapped"), [
    (1e308, 32767, 0),  # 1e308 is a multiple of 65536: its low 16 bits are 0
    (-1e308, -32768, 0),
    (70000.0, 32767, 70000 - 65536),
    (-40000.0, -32768, -40000 + 65536),
    (32767.5, 32767, -32768),  # rounds to 32768 first
])
def test_native_input_beyond_a_word_saturates_or_wraps(make: Make, value: float,
                                                       saturated: int, wrapped: int) -> None:
    """issue 11 point 1: a finite input beyond the 16-bit word is what a DB word can hold:
    saturated (overflow = saturate, the default) or its low 16 bits (overflow = wrap),
    exactly as the block's 16-bit intermediates (spec 2.14 [A]). K = R = 1 (nominal),
    first call: Y = dP = XW = W."""
    p = {"k": 1000, "r": 1000, "scale": "nominal"}
    assert run(make(**p), [{"w": value}])[0] == [saturated]
    assert run(make(**p, overflow="wrap"), [{"w": value}])[0] == [wrapped]
    assert run(make(**p, arithmetic="float"), [{"w": value}])[0] == [
        pytest.approx(max(-32768.0, min(32767.0, value)))]


@pytest.mark.parametrize("bit", ["auto", "off"])
def test_a_non_finite_control_bit_holds_the_scan(make: Make, bit: str) -> None:
    """issue 11 point 1: D 11.0 / D 11.2 that is no bit (NaN, inf) is Bad input: the scan is
    held (before, NaN auto read as Manual and Y moved towards YH = 0)."""
    block = make(**PI, scale="nominal")
    run(block, steps(2, w=100.0))
    before = block.state()
    block.set_inputs({bit: (NAN, 128)})
    out = block.step(1.0)
    assert (out["y"].value, out["dy"].value) == (120, 0)
    assert block.state() == before
    block.set_inputs({bit: (INF, 128)})
    assert block.step(1.0)["y"].value == 120
    block.set_inputs({"auto": 1.0, "off": 0.0})
    assert run(block, [{}])[0] == [130]


def test_status_is_not_read(make: Make) -> None:
    """The S5 has no status (spec 7): a finite word with a Bad status byte is used."""
    block = make(**PI, scale="nominal")
    assert block.step(1.0, w=(100.0, 0), x=(0.0, 0x18))["y"].value == 110


@pytest.mark.parametrize(("params", "expected"), [
    ({"y0": 500}, 500), ({"y0": 500, "bgog": 300}, 300), ({}, 0),
    ({"y0": 500, "velocity": True}, 0)])
def test_initial_output_before_the_first_call(params: dict[str, Any], expected: int) -> None:
    """issue 11 point 8: before its first call the block publishes DW 48 as it stands: the
    y0 preset (limited, spec 2.9) in positioning mode, no increment in velocity mode."""
    block = loopworks.create_block("s5.pid", **params)
    out = block.outputs()
    assert (out["y"].value, out["dy"].value) == (expected, 0)


def test_native_integral_dead_zone_is_documented_and_real(make: Make) -> None:
    """The native I element rounds TI·XW/1024 to a whole count, so it is 0 for |XW| <=
    512/TI, and K·dI/1024 rounds to 0 for |K| < 512: a loop settles up to that far off the
    setpoint. Pure I (r = 0): TI = 100: XW = 5 (100·5/1024 = 0.49 -> 0) never moves Y, XW = 6
    (0.59 -> 1) moves it a count per sample with K = 1024; K = 500 needs dI = 2 (500/1024 =
    0.49 -> 0): XW = 15 (1.46 -> 1) stays, XW = 16 (1.56 -> 2, 0.98 -> 1) moves."""
    doc = inspect.getdoc(siemens_s5) or ""
    assert "512/TI" in doc and "512/|K|" in doc
    assert run(make(k=1024, r=0, ti=100), steps(4, w=5.0))[0] == [0, 0, 0, 0]
    assert run(make(k=1024, r=0, ti=100), steps(4, w=6.0))[0] == [1, 2, 3, 4]
    assert run(make(k=1024, r=0, ti=100), steps(2, w=-5.0))[0] == [0, 0]
    assert run(make(k=500, r=0, ti=100), steps(3, w=15.0))[0] == [0, 0, 0]
    assert run(make(k=500, r=0, ti=100), steps(3, w=16.0))[0] == [1, 2, 3]
    assert run(make(k=1024, r=0, ti=100, arithmetic="float"), steps(2, w=5.0))[0] == [
        pytest.approx(100 * 5 / 1024), pytest.approx(2 * 100 * 5 / 1024)]


# -- retuning in Auto (issue 12 point 4; spec 2.5, 2.7) -----------------------------------------
# The S5 law is a correction-rate law summed into DW 48 (spec 2.5, 2.7): a new tuning adds the
# new increment to DW 48, nothing is re-evaluated from the past, so there is no retune option.


@pytest.mark.parametrize("arithmetic", ["native", "float"])
def test_retune_in_auto_moves_y_only_by_the_new_increment(make: Make, arithmetic: str) -> None:
    """spec 2.5, 2.7: dY_k = K·(R·PW_k + TI·XW_k + dD_k), Y_k = Y_{k-1} + dY_k. The spec 2.13
    PI case (nominal ÷1000) at the steady error XW = 100: Y = 110, 120, 130. Then, with PW = 0:
    k 1000 -> 2000: dY = 2·(0.1·100) = 20 -> 150 (a positional K·(R·XW + I) would also jump
    by (2 - 1)·100 = 100, to 250); ti 100 -> 300: dY = 2·(0.3·100) = 60 -> 210; r 1000 -> 0:
    R weights only PW = 0, dY = 60 again -> 270. Every product is whole, so native = float."""
    block = make(**PI, scale="nominal", arithmetic=arithmetic)
    y, _ = run(block, steps(3, w=100.0))
    assert y == [110, 120, 130]
    block.set_params(k=2000)
    assert run(block, [{}]) == ([150], [20])
    block.set_params(ti=300)
    assert run(block, [{}]) == ([210], [60])
    block.set_params(r=0)
    assert run(block, [{}]) == ([270], [60])


def test_retune_in_auto_native_exact_scaling(make: Make) -> None:
    """spec 2.5 with ÷1024 words (spec 2.2), XW = 100 steady, K = R = 1000, TI = 100. First
    call: dPW = round(1000·100/1024 = 97.66) = 98, dI = round(9.77) = 10, dY = round(1000·108
    /1024 = 105.47) = 105; then dY = round(1000·10/1024 = 9.77) = 10: 105, 115, 125. k -> 2000:
    dY = round(2000·10/1024 = 19.53) = 20 -> 145."""
    block = make(**PI)
    assert run(block, steps(3, w=100.0))[0] == [105, 115, 125]
    block.set_params(k=2000)
    assert run(block, steps(2))[0] == [145, 165]


def test_retune_then_the_loop_follows_the_new_tuning(make: Make) -> None:
    """spec 2.5: after k 1000 -> 2000 and ti 100 -> 300 (nominal) an X step 0 -> 20 gives
    XW = 80, PW = -20: dY = 2·(1·(-20) + 0.3·80) = 2·4 = 8; then PW = 0: dY = 2·24 = 48."""
    block = make(**PI, scale="nominal")
    assert run(block, steps(2, w=100.0))[0] == [110, 120]
    block.set_params(k=2000, ti=300)
    assert run(block, [{"x": 20.0}, {}]) == ([128, 176], [8, 48])


def test_retune_in_velocity_mode_outputs_the_new_increment(make: Make) -> None:
    """spec 2.7, 2.8: in velocity mode DW 48 = dY_k: 110, 10, 10; k -> 2000: 20, 20."""
    block = make(**PI, scale="nominal", velocity=True)
    assert run(block, steps(3, w=100.0))[0] == [110, 10, 10]
    block.set_params(k=2000)
    assert run(block, steps(2))[0] == [20, 20]


def test_retune_in_manual_does_nothing_special(make: Make) -> None:
    """spec 2.9: in Manual the algorithm is not computed (Y follows YH = 130, already there);
    a new k changes nothing there, and Auto continues from DW 48 with the new increment
    (histories kept, PW = 0): 130 + 2·10 = 150."""
    block = make(**PI, scale="nominal")
    assert run(block, steps(3, w=100.0))[0] == [110, 120, 130]
    assert run(block, [{"auto": "MAN", "yh": 130.0}])[0] == [130]
    block.set_params(k=2000)
    assert run(block, [{}, {"auto": "AUTO"}]) == ([130, 150], [0, 20])


# -- the block has no clock (spec 2.5, 2.11) ------------------------------------------------------


def test_2_11_dt_is_ignored(make: Make) -> None:
    a, b = make(**PI, td=500), make(**PI, td=500)
    scans = [{"w": 100.0}, {"x": 7.0}, {"x": 20.0}, {"w": 50.0}]
    for dt, inputs in zip([0.01, 5.0, 600.0, 1e-6], scans, strict=True):
        assert a.step(dt, **inputs)["y"].value == b.step(1.0, **inputs)["y"].value


def test_2_11_dt_is_still_validated() -> None:
    with pytest.raises(InputError, match="dt"):
        loopworks.create_block("s5.pid").step(0.0, w=1.0)


# -- parameters -----------------------------------------------------------------------------------


@pytest.mark.parametrize(("params", "name"), [
    ({"k": 40000}, "k"), ({"k": 1.5}, "k"), ({"r": -40000}, "r"), ({"ti": 10000}, "ti"),
    ({"ti": -1}, "ti"), ({"td": -1}, "td"), ({"bgog": 40000}, "bgog"),
    ({"bgog": 10, "bgug": 20}, "bgug"), ({"y0": 1e6}, "y0"), ({"dd_decay": 1.5}, "dd_decay"),
    ({"rounding": "up"}, "rounding"), ({"scale": "1000"}, "scale"),
    ({"arithmetic": "fixed"}, "arithmetic"), ({"overflow": "clip"}, "overflow"),
    ({"i_suppression": "hold"}, "i_suppression"), ({"manual_steps": -1}, "manual_steps"),
    ({"first_call": "db"}, "first_call"), ({"bad_input": "zero"}, "bad_input"),
    ({"velocity": "maybe"}, "velocity"), ({"kp": 1}, "kp"),
])
def test_bad_parameters_name_the_parameter(params: dict[str, Any], name: str) -> None:
    with pytest.raises(ParameterError, match=f"'{name}'"):
        loopworks.create_block("s5.pid", **params)


def test_parameter_meanings_name_the_spec_section() -> None:
    cls = loopworks.block_class("s5.pid")
    for p in cls.PARAMS:
        assert "spec " in p.meaning, p.name


def test_every_option_is_listed_in_the_docstring() -> None:
    doc = inspect.getdoc(siemens_s5) or ""
    options = doc.split("Options for the spec's [A]/[?] points")[1].split("Quirks")[0]
    for name in ("rounding", "overflow", "dd_decay", "i_suppression", "manual_steps",
                 "first_call", "bad_input"):
        assert f"``{name}``" in options


def test_parameters_in_any_case_and_from_strings() -> None:
    a = loopworks.create_block("s5.pid", K="1000", TI="100", SCALE="nominal", VELOCITY="true")
    assert run(a, [{"w": 100.0}])[0] == [110]


# -- replay, state, compiled kernel ---------------------------------------------------------------


def test_replay_cli_runs_the_docstring_example(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "step.csv", ["t", "w", "x", "auto", "off"],
                     [[0, 100, 0, 1, 0], [1, 100, 0, 1, 0], [2, 100, 0, 1, 0],
                      [3, 100, 0, 0, 0], [4, 100, 0, 1, 0]])
    out = tmp_path / "out.csv"
    result = CliRunner().invoke(app, ["replay", "s5.pid", str(path), "-p", "k=1000", "-p",
                                      "ti=100", "-p", "scale=nominal", "-o", str(out)])
    assert result.exit_code == 0, result.output
    lines = out.read_text().splitlines()
    assert lines[0] == "t,y,dy"
    rows = [[float(c) for c in line.split(",")] for line in lines[1:]]
    # hand: 110, 120, 130; Manual with yh = 0: 130 - 65 = 65; Auto: dI = 10 -> 75
    assert [r[1] for r in rows] == [110, 120, 130, 65, 75]
    assert [r[2] for r in rows] == [110, 10, 10, -65, 10]


def test_replay_rejects_a_non_binary_auto(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "bad.csv", ["dt", "w", "auto"], [[1, 100, 2]])
    result = CliRunner().invoke(app, ["replay", "s5.pid", str(path)])
    assert result.exit_code != 0
    assert "auto" in result.output


VARIANTS: list[dict[str, Any]] = [
    {},
    {"k": 1200, "r": 1000, "ti": 50, "td": 800, "bgog": 100, "bgug": -20,
     "i_suppression": "flag", "first_call": "inputs"},
    {"k": -3000, "ti": 300, "td": 3000, "velocity": True, "xz_on": True, "bgog": 40,
     "bgug": -40, "overflow": "wrap", "rounding": "floor", "bad_input": "last"},
    {"k": 20000, "r": 500, "ti": 9999, "td": 20000, "hold": True, "no_z": True,
     "scale": "nominal", "rounding": "nearest", "dd_decay": 1.0, "manual_steps": 0},
    {"k": 900, "ti": 100, "td": 1500, "arithmetic": "float", "scale": "nominal", "xz_on": True,
     "bgog": 60, "bgug": 0, "y0": 80, "i_suppression": "none"},
    {"k": 1000, "ti": 200, "velocity": True, "hold": True, "arithmetic": "float",
     "rounding": "truncate", "dd_decay": 0.3, "bad_input": "last", "manual_steps": 5},
]


def random_inputs(rng: np.random.Generator) -> dict[str, Any]:
    """Random words, sometimes far out of range, NaN or inf; random D 11.0 / D 11.2 bits."""
    inputs: dict[str, Any] = {}
    for name in ("w", "x", "z", "xz", "yh"):
        r = rng.random()
        if r < 0.03:
            inputs[name] = NAN
        elif r < 0.05:
            inputs[name] = float(rng.choice([INF, -INF]))
        elif r < 0.15:
            inputs[name] = float(rng.choice([1e300, -1e300, 1e9, -7e4, 32767.5, -32768.5]))
        else:
            inputs[name] = float(rng.uniform(-300.0, 300.0))
    inputs["auto"] = float(rng.random() < 0.8)
    inputs["off"] = float(rng.random() < 0.05)
    return inputs


@pytest.mark.parametrize("params", VARIANTS)
def test_native_states_stay_finite_words(params: dict[str, Any]) -> None:
    """On random inputs the states stay finite, and in native arithmetic whole 16-bit words
    (spec 2.8 [V]). (Compiled against interpreted: tests/sim/test_plan.py, these variants
    included.)"""
    rng = np.random.default_rng(2024)
    py = loopworks.create_block("s5.pid", jit=False, **params)
    for _ in range(1500):
        py.set_inputs(random_inputs(rng))
        type(py).kernel(1.0, py.p, py.x, py.u, py.us, py.y, py.ys)
        assert np.isfinite(py.x).all()
        if params.get("arithmetic", "native") == "native":
            assert (py.x == np.round(py.x)).all()
            assert (np.abs(py.x[:10]) <= 32768).all()


@pytest.mark.parametrize("params", VARIANTS)
def test_resume_from_saved_state_equals_uninterrupted_run(params: dict[str, Any]) -> None:
    rng = np.random.default_rng(5)
    seq = [random_inputs(rng) for _ in range(300)]
    whole = loopworks.create_block("s5.pid", **params)
    first = loopworks.create_block("s5.pid", **params)
    expected = [dict(whole.step(1.0, **inp)) for inp in seq]
    for inp in seq[:150]:
        first.step(1.0, **inp)
    saved = json.loads(json.dumps(first.state_dict()))
    resumed = loopworks.create_block(saved["kind"], **saved["params"])
    resumed.load_state(saved)
    got = [dict(resumed.step(1.0, **inp)) for inp in seq[150:]]
    assert got == expected[150:]


@pytest.mark.parametrize(("k", "ti"), [(1235, 13), (500, 100), (600, 1), (1000, 600)])
def test_the_stated_integral_dead_zone_is_the_blocks(k: int, ti: int) -> None:
    """A tuned S5 loop in native arithmetic settled 0.8 % of a 2 % step short: its I element
    (dY = round(K·round(TI·XW/1024)/1024), spec 2.2/2.13) left Y still for |XW| up to 39
    counts, and tune said nothing (found by an engineer). The zone a conversion now states is
    the one the block shows: Y still at the zone's edge, moving one count beyond it."""
    from loopworks import create_block
    from loopworks.tuning.convert import convert
    from loopworks.vendors.siemens_s5 import integral_dead_zone

    zone = integral_dead_zone(k, ti, 1024.0)
    assert zone == {(1235, 13): 39, (500, 100): 15, (600, 1): 512, (1000, 600): 0}[(k, ti)]
    for xw, moves in ((zone, False), (zone + 1, True)):
        b = create_block("s5.pid", k=k, r=1024, ti=ti, td=0, bgog=32000, bgug=0, y0=1000,
                         no_z=True)
        ys = [b.step(0.1, w=1000 + xw, x=1000, auto="AUTO")["y"].value for _ in range(4)]
        assert (ys[-1] != ys[0]) == moves, (xw, ys)
    c = convert("pid", {"k": 1235 / 1024, "ti": 0.1 * 1024 / 13}, "s5.pid", sample_time=0.1)
    if (k, ti) == (1235, 13):
        assert (c.params["k"], c.params["ti"]) == (1235, 13)
        assert "up to 39 counts (3.9 % of the PV span" in c.note
