"""Data-driven valves against plant-and-tuning.md sections 1.1-1.9 ("spec" below).

Expected values are the spec's tables (1.8 worked examples, 1.9 describing-function table) or
hand arithmetic written out in the test (the rules the spec states, evaluated by hand), never a
pasted run of a block. Golden tests run with the compiled and the interpreted kernel (``make``).
"""

from __future__ import annotations

import cmath
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
from loopworks.blocks.kernel import run_rows
from loopworks.cli import app
from loopworks.errors import ParameterError
from loopworks.plant import valve
from tests.csvfiles import write_csv
from tests.plant.numeric import EXTREMES, kernel_scan, unsound

NAN = math.nan
INF = math.inf
Make = Callable[..., Block]
STICTION = ("valve.choudhury", "valve.kano", "valve.he")


@pytest.fixture(params=[True, False], ids=["compiled", "interpreted"])
def make(request: pytest.FixtureRequest) -> Make:
    """``make(kind, **params)`` with the compiled or the interpreted kernel."""
    jit = request.param

    def _make(kind: str, **params: Any) -> Block:
        return loopworks.create_block(kind, jit=jit, **params)

    return _make


def run(block: Block, ops: Sequence[float], dt: float = 1.0) -> list[float]:
    """Step once per op sample; return the positions."""
    return [block.step(dt, op=float(x))["position"].value for x in ops]


def run_fast(kind: str, ops: np.ndarray, **params: Any) -> tuple[Block, np.ndarray]:
    """Many samples through the compiled row runner (dt = 1 s); returns (block, positions)."""
    b = loopworks.create_block(kind, **params)
    u = np.asarray(ops, dtype=float).reshape(-1, 1)
    n = len(u)
    y = np.zeros((n, 2))
    ys = np.zeros((n, 2), dtype=np.int64)
    run_rows(type(b).kernel, np.ones(n), b.p, b.x, u, np.full((n, 1), 128, dtype=np.int64),
             y, ys)
    return b, y[:, 0]


# -- spec 1.8: the ramp 0 -> 10 -> 0 -> 6 % in 0.5 % steps, S = 3, J = 1, at rest at 0 ------------

UP1 = [0.5 * i for i in range(21)]             # 0 .. 10
DOWN = [10.0 - 0.5 * i for i in range(1, 21)]  # 9.5 .. 0
UP2 = [0.5 * i for i in range(1, 13)]          # 0.5 .. 6
RAMP = UP1 + DOWN + UP2


def choudhury_ramp_expected() -> list[float]:
    """spec 1.8, "Reading the Choudhury row": breaks away when x - y > fs = 2 (x = 2.5) and then
    tracks x - fd = x - 1; at the top holds 9 until the OP is more than S = 3 below 10
    (x = 6.5) and then tracks x + 1; at the bottom (y = 1) holds until x - 0 > S (x = 3.5)."""
    return ([0.0 if x <= 2.0 else x - 1.0 for x in UP1]
            + [9.0 if x >= 7.0 else x + 1.0 for x in DOWN]
            + [1.0 if x <= 3.0 else x - 1.0 for x in UP2])


# He by hand: cum = u_r + dx accumulates 0.5 per sample; a slip (|cum| > 2) lands at x -+ 1 and
# leaves u_r = +-1, so the next slip needs three more samples: steps of 1.5 every 3 samples.
HE_UP1 = [0, 0, 0, 0, 0, 1.5, 1.5, 1.5, 3, 3, 3, 4.5, 4.5, 4.5, 6, 6, 6, 7.5, 7.5, 7.5, 9]
# down from u_r = +1: cum = 0.5, 0, -0.5, -1, -1.5, -2 (hold 9), -2.5 at x = 6.5: slip to 7.5
HE_DOWN = [9, 9, 9, 9, 9, 9, 7.5, 7.5, 7.5, 6, 6, 6, 4.5, 4.5, 4.5, 3, 3, 3, 1.5, 1.5]
# up from u_r = -1: cum = -1 .. 2 over x = 0.5 .. 3.5 (hold 1.5), 2.5 at x = 4: slip to 3
HE_UP2 = [1.5, 1.5, 1.5, 1.5, 1.5, 1.5, 1.5, 3, 3, 3, 4.5, 4.5]

# the columns the spec's table prints explicitly: {index into RAMP: y}
SPEC_COLUMNS_CHOUDHURY = {0: 0, 1: 0, 2: 0, 3: 0, 4: 0, 5: 1.5, 6: 2, 20: 9, 21: 9, 22: 9, 23: 9,
                          24: 9, 25: 9, 26: 9, 27: 7.5, 28: 7, 40: 1, 41: 1, 46: 1, 47: 2.5,
                          48: 3}
SPEC_COLUMNS_HE = {0: 0, 1: 0, 2: 0, 3: 0, 4: 0, 5: 1.5, 6: 1.5, 20: 9, 21: 9, 22: 9, 23: 9,
                   24: 9, 25: 9, 26: 9, 27: 7.5, 28: 7.5, 40: 1.5, 41: 1.5, 46: 1.5, 47: 1.5,
                   48: 3}
SPEC_COLUMNS_BACKLASH = {0: 0, 1: 0, 2: 0, 3: 0.5, 4: 1, 5: 1.5, 6: 2, 20: 9, 21: 9, 22: 9,
                         23: 9, 24: 9, 25: 8.5, 26: 8, 27: 7.5, 28: 7, 40: 1, 41: 1, 46: 2,
                         47: 2.5, 48: 3}


def test_1_8_ramp_indices_are_the_spec_columns() -> None:
    """spec 1.8: the explicit columns sit where the test looks for them."""
    assert (RAMP[5], RAMP[20], RAMP[27], RAMP[40], RAMP[46], RAMP[47], RAMP[48]) == \
        (2.5, 10.0, 6.5, 0.0, 3.0, 3.5, 4.0)


@pytest.mark.parametrize("kind", ["valve.choudhury", "valve.kano"])
def test_1_8_ramp_choudhury_kano_row(make: Make, kind: str) -> None:
    """spec 1.8 ramp, Choudhury/Kano row (S = 3, J = 1, at rest at 0; Kano resting with d = +1,
    us = y0 + fd)."""
    got = run(make(kind, s=3.0, j=1.0, y0=0.0), RAMP)
    assert got == pytest.approx(choudhury_ramp_expected(), abs=1e-12)
    for i, yv in SPEC_COLUMNS_CHOUDHURY.items():
        assert got[i] == pytest.approx(yv, abs=1e-12), i


def test_1_8_ramp_he_row(make: Make) -> None:
    """spec 1.8 ramp, He row (fs = 2, fd = 1, u_r = 0)."""
    got = run(make("valve.he", fs=2.0, fd=1.0, y0=0.0), RAMP)
    assert got == pytest.approx(HE_UP1 + HE_DOWN + HE_UP2, abs=1e-12)
    for i, yv in SPEC_COLUMNS_HE.items():
        assert got[i] == pytest.approx(yv, abs=1e-12), i


def test_1_8_ramp_backlash_row(make: Make) -> None:
    """spec 1.8 ramp, backlash b = 2: y = max(y, x - 1) up, min(y, x + 1) down (spec 1.5)."""
    got = run(make("valve.backlash", b=2.0, y0=0.0), RAMP)
    expected = ([max(0.0, x - 1.0) for x in UP1] + [min(9.0, x + 1.0) for x in DOWN]
                + [max(1.0, x - 1.0) for x in UP2])
    assert got == pytest.approx(expected, abs=1e-12)
    for i, yv in SPEC_COLUMNS_BACKLASH.items():
        assert got[i] == pytest.approx(yv, abs=1e-12), i


# -- spec 1.8: the three short sequences (S = 3, J = 1, start at x = 0 at rest) -------------------

PAUSE = [1, 2, 3, 4, 5, 5, 5, 5.5, 6, 6.5, 7, 7.5]
DIP = [1, 2, 3, 4, 5, 4, 3.5, 4, 5, 6, 7, 8]
REVERSAL = [1, 2, 3, 4, 5, 6, 5, 4, 3, 2.5, 2, 1]


@pytest.mark.parametrize("kind", ["valve.choudhury", "valve.kano"])
def test_1_8_pause_then_resume_choudhury_kano(make: Make, kind: str) -> None:
    """spec 1.8 "pause then resume": needs > J beyond the stop at 5 (5.5 at x = 6.5)."""
    got = run(make(kind, s=3.0, j=1.0, y0=0.0), PAUSE)
    assert got == [0, 0, 2, 3, 4, 4, 4, 4, 4, 5.5, 6, 6.5]


def test_1_8_pause_then_resume_he(make: Make) -> None:
    """spec 1.8 "pause then resume", He column."""
    got = run(make("valve.he", s=3.0, j=1.0, y0=0.0), PAUSE)
    assert got == [0, 0, 2, 2, 4, 4, 4, 4, 4, 5.5, 5.5, 5.5]


@pytest.mark.parametrize("kind", ["valve.choudhury", "valve.kano"])
def test_1_8_dip_inside_the_band_choudhury_kano(make: Make, kind: str) -> None:
    """spec 1.8 "1.5 % dip inside the band": the stop reference stays 5 (6 at x = 7)."""
    got = run(make(kind, s=3.0, j=1.0, y0=0.0), DIP)
    assert got == [0, 0, 2, 3, 4, 4, 4, 4, 4, 4, 6, 7]


def test_1_8_dip_inside_the_band_he(make: Make) -> None:
    """spec 1.8 "1.5 % dip inside the band", He column."""
    got = run(make("valve.he", s=3.0, j=1.0, y0=0.0), DIP)
    assert got == [0, 0, 2, 2, 4, 4, 4, 4, 4, 4, 6, 6]


@pytest.mark.parametrize("kind", ["valve.choudhury", "valve.kano"])
def test_1_8_full_reversal_choudhury_kano(make: Make, kind: str) -> None:
    """spec 1.8 "full reversal": moves again only > S below the stop at 6 (3.5 at x = 2.5)."""
    got = run(make(kind, s=3.0, j=1.0, y0=0.0), REVERSAL)
    assert got == [0, 0, 2, 3, 4, 5, 5, 5, 5, 3.5, 3, 2]


def test_1_8_full_reversal_he(make: Make) -> None:
    """spec 1.8 "full reversal", He column."""
    got = run(make("valve.he", s=3.0, j=1.0, y0=0.0), REVERSAL)
    assert got == [0, 0, 2, 2, 4, 4, 4, 4, 4, 4, 4, 2]


# -- spec 1.2: invariants, the initial state, Choudhury = Kano ------------------------------------


def random_walk(seed: int, n: int, sigma: float = 0.6) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.clip(50.0 + np.cumsum(rng.normal(0.0, sigma, n)), 0.0, 100.0)


@pytest.mark.parametrize(("s", "j"), [(3.0, 1.0), (3.0, 0.0), (2.0, 2.0), (5.0, 2.0)])
def test_1_2_invariants_on_a_random_op(s: float, j: float) -> None:
    """spec 1.2 invariants: moving |x - y| = fd; stuck |x - y| <= fs; every slip ends with
    |x - y| = fd; from rest the first move needs |x - y| > fs; after a stop, a reversal needs
    OP travel > S from the stop point xss, a resume in the same direction > J."""
    fs, fd = (s + j) / 2.0, (s - j) / 2.0
    b = loopworks.create_block("valve.choudhury", s=s, j=j)
    slips = {"rest": 0, "resume": 0, "reversal": 0}
    y_prev = math.nan
    stuck_prev = 1.0
    old_dir = 0.0
    for k, x in enumerate(random_walk(3, 4000)):
        xss = b.state()["xss"]
        yk = b.step(1.0, op=float(x))["position"].value
        if b.state()["stuck"] == 0.0:
            assert abs(abs(x - yk) - fd) < 1e-9, k
        else:
            assert abs(x - yk) <= fs + 1e-9, k
        if k > 0 and yk != y_prev:
            new_dir = math.copysign(1.0, yk - y_prev)
            if stuck_prev == 1.0:  # a slip
                assert abs(abs(x - yk) - fd) < 1e-9, k
                if old_dir == 0.0:
                    assert abs(x - y_prev) > fs, k
                    slips["rest"] += 1
                elif new_dir == old_dir:
                    assert old_dir * (x - xss) > j, k
                    slips["resume"] += 1
                else:
                    assert old_dir * (xss - x) > s, k
                    slips["reversal"] += 1
            old_dir = new_dir
        y_prev, stuck_prev = yk, b.state()["stuck"]
    assert slips["rest"] == 1 and slips["reversal"] > 20


def test_1_2_first_sample_sets_the_state_at_rest(make: Make) -> None:
    """spec 1.2 table: without y0 the first OP gives x_prev = y = xss = OP, I = 1, v_prev = 0."""
    b = make("valve.choudhury", s=3.0, j=1.0)
    assert b.step(1.0, op=42.0)["position"].value == 42.0
    assert b.state() == {"init": 1.0, "position": 42.0, "x_prev": 42.0, "v_prev": 0.0,
                         "y": 42.0, "stuck": 1.0, "xss": 42.0}
    # from rest it breaks away only beyond fs = 2: 44 holds, 44.5 slips to 43.5
    assert run(b, [44.0, 44.5]) == [42.0, 43.5]


def test_1_2_repeated_first_sample_never_moves_a_pure_stick_slip_valve() -> None:
    """spec 1.2 note [V]: a sinusoid whose first two samples were equal never moved a valve
    with S = J = 3, A = 3 (|x - y| never exceeds fs = 3); seeded as moving it cycles."""
    theta = 2.0 * math.pi * np.arange(400) / 100.0
    ops = 50.0 + 3.0 * np.sin(theta)
    ops = np.concatenate([[ops[0]], ops])           # the first sample repeated
    _, rest = run_fast("valve.choudhury", ops, s=3.0, j=3.0)
    assert (rest == 50.0).all()
    _, seeded = run_fast("valve.choudhury", ops, s=3.0, j=3.0, y0=50.0, start="moving_up")
    assert (seeded == 50.0).all()                   # the pause sticks a moving valve too
    # seeded as moving and no repeated sample: fd = 0, it tracks up to 53, holds, slips once
    # x < 53 - S = 50, tracks down to 47, ...
    _, moving = run_fast("valve.choudhury", ops[2:], s=3.0, j=3.0, y0=50.0, start="moving_up")
    assert moving.max() == 53.0 and moving.min() == 47.0
    assert moving[100:200].max() - moving[100:200].min() == pytest.approx(6.0)


@pytest.mark.parametrize(("s", "j"), [(3.0, 1.0), (3.0, 0.0), (3.0, 3.0), (5.0, 2.0),
                                      (1.0, 0.5)])
def test_1_2_choudhury_equals_kano_on_a_random_walk(s: float, j: float) -> None:
    """spec 1.2 note [V]: with the xss rule the two models are algebraically the same; on a
    continuous random walk (no exact threshold ties) every sample agrees, and on one rounded to
    0.1 % they differ only at rare float ties (spec: 0-1 % of samples)."""
    ops = random_walk(11, 20000)
    _, a = run_fast("valve.choudhury", ops, s=s, j=j)
    _, b = run_fast("valve.kano", ops, s=s, j=j)
    assert np.array_equal(a, b)
    rounded = np.round(ops, 1)
    _, c = run_fast("valve.choudhury", rounded, s=s, j=j)
    _, d = run_fast("valve.kano", rounded, s=s, j=j)
    assert np.mean(np.abs(c - d) > 1e-9) <= 0.01


def test_1_2_choudhury_and_kano_differ_when_j_exceeds_s() -> None:
    """Beyond the spec's [V] check (J <= S): with J > S the stem overshoots past the stop
    point, so Choudhury's resume test sign(x - xss)·sign(xss - y) = +1 takes a reversal for a
    resume and asks for J instead of S; Kano keeps the direction d. Hand case S = 2, J = 4
    (fs = 3, fd = -1) from rest at 50: 46.5 slips down to 45.5 (1 below the OP), the pause stops
    it with xss = 46.5, 47.5 holds (|47.5 - 45.5| = 2 <= fs), 48.6 is 2.1 > S above the stop:
    Kano reverses (d = +1, y = 48.6 + 1 = 49.6), Choudhury sees sign(2.1)·sign(1) = +1, asks
    2.1 > J = 4 and holds. (With J <= S, y lags behind xss and the test is right.)"""
    ops = np.array([46.5, 46.5, 47.5, 48.6])
    _, a = run_fast("valve.choudhury", ops, s=2.0, j=4.0, y0=50.0)
    _, b = run_fast("valve.kano", ops, s=2.0, j=4.0, y0=50.0)
    assert list(a) == pytest.approx([45.5, 45.5, 45.5, 45.5])
    assert list(b) == pytest.approx([45.5, 45.5, 45.5, 49.6])


# -- spec 1.4: He's rate dependence ---------------------------------------------------------------


def test_1_4_he_slow_ramp_gives_stick_slip_steps_and_a_fast_ramp_tracks(make: Make) -> None:
    """spec 1.4 [V]: on a monotone ramp He slips only if the increment exceeds J; slower ramps
    give repeated steps. fs = 2, fd = 1 from u_r = 0: increments 0.25 slip at cum = 2.25
    (9 samples), then every 5 samples (1 + 5·0.25 = 2.25 > 2), landing at x - 1; increments
    1.5 > J: the first slip at cum = 3, then every sample (1 + 1.5 > 2), tracking x - 1.
    Choudhury tracks the slow ramp smoothly once it has broken away (x - 50 > fs)."""
    slow = [50.0 + 0.25 * k for k in range(1, 20)]
    got = run(make("valve.he", fs=2.0, fd=1.0, y0=50.0), slow)
    expected = [50.0] * 8 + [51.25] * 5 + [52.5] * 5 + [53.75]
    assert got == pytest.approx(expected)
    fast = [50.0 + 1.5 * k for k in range(1, 6)]
    assert run(make("valve.he", fs=2.0, fd=1.0, y0=50.0), fast) == \
        pytest.approx([50.0, 52.0, 53.5, 55.0, 56.5])
    got_c = run(make("valve.choudhury", s=3.0, j=1.0, y0=50.0), slow)
    assert got_c[8:] == pytest.approx([x - 1.0 for x in slow[8:]])


def test_1_4_he_sign_of_the_cpp_code_is_the_same_number() -> None:
    """spec 1.4: the C++ writes sign(cum - fs); for |cum| > fs (fs >= 0) it equals sign(cum)."""
    rng = np.random.default_rng(5)
    for _ in range(1000):
        fs = float(rng.uniform(0.0, 5.0))
        cum = float(rng.uniform(-20.0, 20.0))
        if abs(cum) > fs:
            assert valve.sign(cum - fs) == valve.sign(cum)


# -- spec 1.5: backlash, resolution, quantiser ----------------------------------------------------


def test_1_5_backlash_equals_choudhury_with_j_zero_without_pauses() -> None:
    """spec 1.5: backlash of width b is the Choudhury model with S = b, J = 0 except for the
    velocity-zero sticking rule (a continuous random walk never pauses)."""
    ops = random_walk(8, 5000)
    _, a = run_fast("valve.backlash", ops, b=3.0)
    _, c = run_fast("valve.choudhury", ops, s=3.0, j=0.0)
    assert np.allclose(a, c, atol=1e-12)
    # a pause sticks the Choudhury valve, which then needs > J = 0 more: the same here
    # (52.1 - 50 > b/2 = 1.5 moves the backlash to 50.6; Choudhury resumes 52.1 > xss = 52)
    pause = np.array([50, 52, 52, 52.1])
    _, a2 = run_fast("valve.backlash", pause, b=3.0)
    assert list(a2) == pytest.approx([50.0, 50.5, 50.5, 50.6])
    _, c2 = run_fast("valve.choudhury", pause, s=3.0, j=0.0)
    assert list(c2) == pytest.approx(list(a2))


def test_1_5_resolution_snaps_to_the_op(make: Make) -> None:
    """spec 1.5: if |x - y| > r: y = x (r = 7 as in the stick-band simulator)."""
    got = run(make("valve.resolution", r=7.0, y0=0.0), [3, 6, 7, 7.5, 10, 14, 15, 9, 7.9])
    # 7 is not > 7; 7.5 snaps; 14 - 7.5 = 6.5 holds; 15 snaps; 15 - 9 = 6 holds; 7.1 snaps
    assert got == [0, 0, 0, 7.5, 7.5, 7.5, 15, 15, 7.9]


def test_1_5_quantiser_rounds_to_the_step(make: Make) -> None:
    """spec 1.5: y = q·round(x/q), ties upward; the position stays in 0..100."""
    assert run(make("valve.quantiser", q=0.5), [1.2, 1.25, 1.3, 99.9, 0.2]) == \
        pytest.approx([1.0, 1.5, 1.5, 100.0, 0.0])
    # q = 40: 19.99 -> 0, 20 -> 40 (tie up), 100 -> 120 clipped to 100
    assert run(make("valve.quantiser", q=40.0), [19.99, 20.0, 100.0]) == [0.0, 40.0, 100.0]


# -- spec 1.7: the practitioner's terms -----------------------------------------------------------


def test_1_7_mapping_of_the_seed_numbers() -> None:
    """spec 1.7: RES = 0.5 %, DB = 0.2 % give S = 0.7 %, J = 0.5 %, fs = 0.6 %, fd = 0.1 %;
    fs = RES + DB/2 is the dither rule "resolution + 0.5·deadband"."""
    s, j = valve.sj_from_resolution_deadband(0.5, 0.2)
    assert (s, j) == pytest.approx((0.7, 0.5))
    assert valve.bands_from_sj(s, j) == pytest.approx((0.6, 0.1))
    assert valve.breakaway_band(0.5, 0.2) == pytest.approx(0.6)
    assert valve.resolution_deadband_from_sj(0.7, 0.5) == pytest.approx((0.5, 0.2))
    assert valve.sj_from_bands(0.6, 0.1) == pytest.approx((0.7, 0.5))
    # spec 1.1: S = fs + fd, J = fs - fd for the 1.8 example
    assert valve.sj_from_bands(2.0, 1.0) == (3.0, 1.0)
    assert valve.bands_from_sj(3.0, 1.0) == (2.0, 1.0)


@pytest.mark.parametrize("kind", STICTION)
def test_1_7_blocks_accept_any_one_parameter_set(kind: str) -> None:
    """spec 1.7 / 1.4: s, j or resolution, deadband or fs, fd give the same valve."""
    a = loopworks.create_block(kind, s=3.0, j=1.0)
    b = loopworks.create_block(kind, resolution=1.0, deadband=2.0)
    c = loopworks.create_block(kind, fs=2.0, fd=1.0)
    d = loopworks.create_block(kind)                      # the default is the 1.8 valve
    for other in (b, c, d):
        assert np.array_equal(a.p, other.p, equal_nan=True)
    ops = [1, 2, 3, 4, 5, 6, 5, 4, 3, 2.5, 2, 1]
    assert run(loopworks.create_block(kind, resolution=1.0, deadband=2.0, y0=0.0), ops) == \
        run(loopworks.create_block(kind, s=3.0, j=1.0, y0=0.0), ops)


@pytest.mark.parametrize("kind", STICTION)
@pytest.mark.parametrize(("params", "got"), [
    ({"s": 3.0, "deadband": 2.0}, "got s, deadband"),
    ({"s": 3.0, "j": 1.0, "fs": 2.0}, "got s, j, fs"),
    ({"resolution": 1.0, "fd": 1.0}, "got resolution, fd"),
])
def test_1_7_two_parameter_sets_are_an_error(kind: str, params: dict[str, float],
                                             got: str) -> None:
    """spec 1.7: giving the stiction both ways is an error naming the parameters."""
    with pytest.raises(ParameterError, match="not parameters of two sets") as info:
        loopworks.create_block(kind, **params)
    assert kind in str(info.value) and got in str(info.value)


@pytest.mark.parametrize("kind", STICTION)
def test_1_7_incomplete_or_invalid_sets_are_errors(kind: str) -> None:
    with pytest.raises(ParameterError, match="'j' is missing"):
        loopworks.create_block(kind, s=3.0)
    with pytest.raises(ParameterError, match="'resolution' is missing"):
        loopworks.create_block(kind, deadband=0.2)
    with pytest.raises(ParameterError, match=r"'fd' = 3 is out of range: allowed \[-fs, fs\]"):
        loopworks.create_block(kind, fs=2.0, fd=3.0)
    with pytest.raises(ParameterError, match=r"'s' = -1 is out of range: allowed \[0, inf\)"):
        loopworks.create_block(kind, s=-1.0, j=1.0)
    with pytest.raises(ParameterError, match=r"'deadband' = -0.2 is out of range"):
        loopworks.create_block(kind, resolution=0.5, deadband=-0.2)


@pytest.mark.parametrize(("params", "derived"), [
    ({"fs": 1e308, "fd": -1e308}, "J = inf"),
    ({"fs": 1.7e308, "fd": 1e308}, "S = inf"),
    ({"resolution": 1e308, "deadband": 1e308}, "S = inf"),
])
@pytest.mark.parametrize("kind", STICTION)
def test_1_7_a_set_whose_s_or_j_overflows_is_an_error(kind: str, params: dict[str, float],
                                                      derived: str) -> None:
    """spec 1.7: S = fs + fd, J = fs - fd, S = DB + RES. Each parameter finite, the derived S
    or J can overflow: the valve then output NaN with a Good status (found by an outside
    audit); now an error naming the set and the derived value."""
    with pytest.raises(ParameterError, match=f"give {derived}: out of range") as info:
        loopworks.create_block(kind, **params)
    assert kind in str(info.value) and next(iter(params)) in str(info.value)


# -- spec 1.9: describing function of the S/J model -----------------------------------------------


def df_formula(s: float, j: float, a: float) -> complex:
    """spec 1.9 N(A), written out by hand: phi = asin((A - S)/A),
    Re = [pi·A/2 + A·phi - (A/2)·sin 2phi + 2(A - S + J)cos phi]/(pi·A),
    Im = -[A(1 - sin phi)² + 2(S - J) sin phi]/(pi·A)."""
    phi = math.asin((a - s) / a)
    re = (math.pi * a / 2 + a * phi - a / 2 * math.sin(2 * phi)
          + 2 * (a - s + j) * math.cos(phi)) / (math.pi * a)
    im = -(a * (1 - math.sin(phi)) ** 2 + 2 * (s - j) * math.sin(phi)) / (math.pi * a)
    return complex(re, im)


def df_simulated(kind: str, s: float, j: float, a: float, n: int = 20000,
                 cycles: int = 4) -> complex:
    """First harmonic of y for x = 50 + A sin(theta), n points per cycle, started in the moving
    state (spec 6 item 2), the first cycle discarded: N = (b1 + j·a1)/A."""
    fd = (s - j) / 2.0
    theta = 2.0 * np.pi * np.arange(1, n * cycles + 1) / n
    _, y = run_fast(kind, 50.0 + a * np.sin(theta), s=s, j=j, y0=50.0 - fd, start="moving_up")
    yc, t = y[n:] - 50.0, theta[n:]
    return complex(2.0 * np.mean(yc * np.sin(t)), 2.0 * np.mean(yc * np.cos(t))) / a


DF_TABLE = [  # spec 1.9: S, J, A, N(A), -1/N(A)
    (3, 1, 1.6, 0.2186 - 0.4228j, -0.9652 - 1.8662j),
    (3, 1, 2, 0.4712 - 0.3979j, -1.2389 - 1.0462j),
    (3, 1, 3, 0.7122 - 0.3183j, -1.1703 - 0.5231j),
    (3, 1, 5, 0.8644 - 0.2165j, -1.0886 - 0.2726j),
    (3, 1, 10, 0.9514 - 0.1178j, -1.0352 - 0.1281j),
    (3, 0, 2, 0.1955 - 0.2387j, -2.0533 - 2.5073j),
    (3, 0, 3, 0.5000 - 0.3183j, -1.4232 - 0.9060j),
    (3, 0, 5, 0.7477 - 0.2674j, -1.1858 - 0.4241j),
    (5, 2, 5, 0.7546 - 0.3183j, -1.1250 - 0.4745j),
]


@pytest.mark.parametrize(("s", "j", "a", "n_ref", "inv_ref"), DF_TABLE)
def test_1_9_describing_function_table(s: float, j: float, a: float, n_ref: complex,
                                       inv_ref: complex) -> None:
    """spec 1.9 [V]: the formula gives the table, and the first harmonic of the Choudhury and
    Kano blocks (20 000 points per cycle) matches it to 4 decimals."""
    n_formula = df_formula(s, j, a)
    assert abs(n_formula - n_ref) < 1e-4
    assert abs(-1.0 / n_formula - inv_ref) < 2e-4
    for kind in ("valve.choudhury", "valve.kano"):
        assert abs(df_simulated(kind, s, j, a) - n_ref) < 1.5e-4, kind


def test_1_9_describing_function_is_zero_up_to_half_s() -> None:
    """spec 1.9: N = 0 for A <= S/2 (after the first half cycle the valve never moves again);
    just above S/2 it approaches -j·4J/(pi·S)."""
    assert abs(df_simulated("valve.choudhury", 3.0, 1.0, 1.4)) < 1e-12
    near = df_formula(3.0, 1.0, 1.5 + 1e-9)
    assert near.real == pytest.approx(0.0, abs=1e-3)
    assert near.imag == pytest.approx(-4.0 * 1.0 / (math.pi * 3.0), abs=1e-3)
    assert cmath.isclose(df_formula(3.0, 0.0, 3.0), 0.5 - 1j / math.pi, abs_tol=1e-12)


# -- output stage: clipping, stroking rate, characteristic ----------------------------------------


def test_op_is_clipped_to_0_100(make: Make) -> None:
    """spec 1.2 step 1: the OP is clipped before the model (x_prev keeps the clipped value)."""
    b = make("valve.choudhury", s=3.0, j=1.0, y0=98.0)
    assert run(b, [120.0, 130.0]) == [98.0, 98.0]      # 100 - 98 = 2, not > fs
    assert b.state()["x_prev"] == 100.0
    b = make("valve.backlash", b=2.0, y0=5.0)
    assert run(b, [-50.0]) == [1.0]                     # x = 0, y = 0 + 1


def test_overshoot_j_above_s_clips_the_position_not_the_state(make: Make) -> None:
    """spec 1.1: J > S overshoots; the position output stays within the travel while the
    model state keeps y (as the C++ clamps its output only)."""
    b = make("valve.choudhury", s=1.0, j=5.0, y0=95.0)  # fs = 3, fd = -2
    assert run(b, [98.5]) == [100.0]                    # slips to 98.5 + 2 = 100.5
    assert b.state()["y"] == pytest.approx(100.5)


def test_stroke_rate_spreads_a_slip(make: Make) -> None:
    """The stem travels at most stroke_rate·dt per scan (module docstring): a slip from 50 to
    53.5 (S = 3, J = 1: x = 54.5 - fd) with 2 %/s and dt = 0.5 s moves 1 % per scan."""
    b = make("valve.choudhury", s=3.0, j=1.0, y0=50.0, stroke_rate=2.0)
    got = run(b, [54.5, 54.5, 54.5, 54.5, 54.5], dt=0.5)
    assert got == pytest.approx([51.0, 52.0, 53.0, 53.5, 53.5])
    assert b.state()["y"] == 53.5


def test_equal_percentage_characteristic(make: Make) -> None:
    """flow = 100·R^(position/100 - 1) (ISA-75.11.01 ideal curve), R = 50: 50 % open gives
    100/sqrt(50) = 14.142 %, closed 2 %, open 100 %; linear: flow = position."""
    b = make("valve.resolution", r=0.0, characteristic="equal_percentage", rangeability=50.0)
    flows = [b.step(1.0, op=x)["flow"].value for x in (50.0, 0.0, 100.0)]
    assert flows == pytest.approx([100.0 / math.sqrt(50.0), 2.0, 100.0])
    lin = make("valve.resolution", r=0.0)
    assert lin.step(1.0, op=37.5)["flow"].value == 37.5


# -- status ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("bad", [(50.0, 0), (NAN, 128), (INF, 128), (-INF, 128), (NAN, 0x40)])
def test_bad_op_holds_and_marks_the_outputs_bad(make: Make, bad: tuple[float, int]) -> None:
    """bad_op = hold: the sample is skipped (state frozen), outputs Bad; the next good sample
    continues as if the bad one never came."""
    b = make("valve.choudhury", s=3.0, j=1.0, y0=0.0)
    ref = make("valve.choudhury", s=3.0, j=1.0, y0=0.0)
    run(b, [1, 2, 3, 4])
    run(ref, [1, 2, 3, 4])
    before = b.state()
    r = b.step(1.0, op=bad)
    assert r["position"] == (3.0, 0) and r["flow"] == (3.0, 0)
    assert b.state() == before
    assert run(b, [5, 5, 6, 6.5]) == run(ref, [5, 5, 6, 6.5])


def test_bad_first_op_without_y0_holds_the_start_value_bad(make: Make) -> None:
    """Issue 11 point 1: no NaN in the state or in a Good output. Before the first good op
    (no y0) a Bad op holds the start value published before the first scan (0 %: op 0), Bad;
    the first good op then initialises the valve as usual (module docstring)."""
    b = make("valve.he")
    r = b.step(1.0, op=NAN)
    assert r["position"] == (0.0, 0) and r["flow"] == (0.0, 0)
    assert all(math.isfinite(v) for v in b.x)
    assert b.step(1.0, op=30.0)["position"] == (30.0, 128)


def test_bad_op_fail_drives_the_valve_to_fail_op(make: Make) -> None:
    """bad_op = fail: the model gets fail_op (through its friction): from rest at 50 the OP 0
    is 50 > fs = 2 away, so it slips to 0 + fd = 1; status Uncertain: substitute (72)."""
    b = make("valve.choudhury", s=3.0, j=1.0, y0=50.0, bad_op="fail", fail_op=0.0)
    r = b.step(1.0, op=(55.0, 0))
    assert r["position"] == (1.0, 72)
    assert b.step(1.0, op=NAN)["position"] == (1.0, 72)


def test_uncertain_op_is_used_and_uncertain(make: Make) -> None:
    b = make("valve.backlash", b=2.0, y0=50.0)
    assert b.step(1.0, op=(55.0, 0x44))["position"] == (54.0, 0x40)
    assert b.step(1.0, op=(56.0, 0xC0))["position"] == (55.0, 128)


def test_outputs_before_the_first_scan() -> None:
    """Issue 11 point 8: before any scan the outputs show y0 (Good), or without y0 the valve
    at rest at the op latched now (0 % by default), Good, never a NaN placeholder."""
    b = loopworks.create_block("valve.kano", y0=40.0)
    assert b.outputs()["position"] == (40.0, 128)
    c = loopworks.create_block("valve.kano")
    assert c.outputs()["position"] == (0.0, 128)
    assert all(math.isfinite(v) for v in c.x)


@pytest.mark.parametrize(("kind", "params", "start"), [
    ("valve.choudhury", {}, 30.0),
    ("valve.kano", {"s": 4.0, "j": 1.0, "start": "moving_up"}, 28.5),  # op - fd, fd = 1.5
    ("valve.he", {"fs": 2.0, "fd": 1.0, "start": "moving_down"}, 31.0),  # op + fd
    ("valve.backlash", {"b": 2.0, "start": "moving_up"}, 29.0),  # op - b/2
    ("valve.resolution", {}, 30.0),
    ("valve.quantiser", {"q": 4.0}, 32.0),  # 4·floor(30/4 + 1/2) = 4·8
])
def test_start_value_is_the_first_scan_for_the_latched_op(
        kind: str, params: dict[str, Any], start: float) -> None:
    """Issue 11 point 8: without y0 the start value published before the first scan is what
    the first scan gives for the latched op (the valve initialised at rest there, spec 1.2
    table; ``start`` moving: the kinetic offset, spec 1.2 note), with its flow; publish_start()
    (what a module that settles its wires calls) re-publishes it for a newly latched op."""
    b = loopworks.create_block(kind, characteristic="equal_percentage", **params)
    b.set_inputs({"op": 30.0})
    b.publish_start()  # type: ignore[attr-defined]
    flow = 100.0 * 50.0 ** (start / 100.0 - 1.0)
    assert b.outputs()["position"] == (pytest.approx(start), 128)
    assert b.outputs()["flow"].value == pytest.approx(flow)
    assert b.step(1.0, op=30.0)["position"] == (pytest.approx(start), 128)


@pytest.mark.parametrize("kind", [*STICTION, "valve.backlash", "valve.resolution",
                                  "valve.quantiser"])
def test_extreme_ops_leave_no_non_finite_value(make: Make, kind: str) -> None:
    """Issue 11 point 1: NaN, ±inf, ±1e308 and ±3.5e38 into op, from the first scan on (no
    y0: the first good op initialises the valve). A finite op is clipped to 0..100 % (spec 1.2
    step 1) and used; a non-finite one is Bad input (bad_op = hold): the position holds, Bad.
    Every output stays in 0..100 %, every state finite (no NaN "not started" marker), and the
    bare kernel (no guard) is sound by itself."""
    b = make(kind)
    bare = loopworks.create_block(kind, jit=False)
    for op in (*EXTREMES, 50.0, *EXTREMES):
        r = b.step(1.0, op=op)
        kernel_scan(bare, 1.0, op=op)
        assert unsound(bare) == []
        for name in ("position", "flow"):
            assert 0.0 <= r[name].value <= 100.0
        assert (r["position"].status == 0) == (not math.isfinite(op))
        assert all(math.isfinite(v) for v in b.x)
    # a huge finite op is the full-open op (clipped), Good
    assert make(kind, y0=50.0).step(1.0, op=1e308)["position"] == \
        make(kind, y0=50.0).step(1.0, op=100.0)["position"]


def test_quantiser_step_below_the_float_resolution(make: Make) -> None:
    """q = 5e-324 (a valid q > 0): op/q overflows, and the quantised value is op itself (the
    step is far below its resolution; module docstring); it used to raise OverflowError."""
    b = make("valve.quantiser", q=5e-324)
    assert run(b, [37.25, 60.5]) == [37.25, 60.5]


@pytest.mark.parametrize("kind", ["valve.choudhury", "valve.kano"])
def test_start_moving_needs_no_breakaway(make: Make, kind: str) -> None:
    """start = moving_up [I] (spec 1.2 note, 1.9): with y0 = 50 the OP is taken to be at
    y0 + fd = 51.5 and the stem moving, so 51.6 continues at once with the kinetic offset
    fd = 1.5 (S = 4, J = 1); from rest the same OPs are inside fs = 2.5."""
    up = make(kind, s=4.0, j=1.0, y0=50.0, start="moving_up")
    assert run(up, [51.6, 52.0]) == pytest.approx([50.1, 50.5])
    rest = make(kind, s=4.0, j=1.0, y0=50.0)
    assert run(rest, [51.6, 52.0]) == [50.0, 50.0]


@pytest.mark.parametrize("kind", [*STICTION, "valve.backlash"])
def test_start_moving_down_from_the_first_op(make: Make, kind: str) -> None:
    """start = moving_down without y0: the first OP 40 puts the stem on the trailing side,
    y = 40 + fd = 41.5 (fd = 1.5: S = 4, J = 1; backlash b/2 = 1.5), and a further 1.5 down
    moves it to 40 (He: cum = -1.5 - 1.5 = -3 beyond fs = 2.5)."""
    params: dict[str, Any] = {"b": 3.0} if kind == "valve.backlash" else {"s": 4.0, "j": 1.0}
    down = make(kind, start="moving_down", **params)
    assert run(down, [40.0, 38.5]) == pytest.approx([41.5, 40.0])
    assert run(make(kind, **params), [40.0]) == [40.0]
    # He with y0: u_r = fd and x_prev = y0 + fd add up to the same cum as at rest
    if kind == "valve.he":
        a = run(make(kind, y0=50.0, start="moving_up", **params), [51.6, 52.7, 53.9])
        assert a == run(make(kind, y0=50.0, **params), [51.6, 52.7, 53.9]) == \
            pytest.approx([50.0, 51.2, 52.4])


# -- replay, state, docs --------------------------------------------------------------------------


def test_replay_cli_runs_the_docstring_example(tmp_path: Path) -> None:
    """The module docstring's replay: spec 1.8 "pause then resume"."""
    path = write_csv(tmp_path / "op.csv", ["t", "op"],
                     [[k, x] for k, x in enumerate(PAUSE)])
    out = tmp_path / "out.csv"
    result = CliRunner().invoke(app, ["replay", "valve.choudhury", str(path), "-p", "s=3",
                                      "-p", "j=1", "-p", "y0=0", "-o", str(out)])
    assert result.exit_code == 0, result.output
    lines = out.read_text().splitlines()
    assert lines[0] == "t,position,flow,position.ST,flow.ST"
    rows = [[float(c) for c in line.split(",")] for line in lines[1:]]
    assert [r[1] for r in rows] == [0, 0, 2, 3, 4, 4, 4, 4, 4, 5.5, 6, 6.5]
    assert {r[3] for r in rows} == {128.0}


def test_docstring_example_runs() -> None:
    v = loopworks.create_block("valve.choudhury", s=3.0, j=1.0, y0=0.0)
    assert run(v, [1, 2, 3, 4, 5, 5, 5, 5.5, 6, 6.5]) == [0, 0, 2, 3, 4, 4, 4, 4, 4, 5.5]


@pytest.mark.parametrize("kind", [*STICTION, "valve.backlash", "valve.resolution",
                                  "valve.quantiser"])
def test_resume_from_saved_state(kind: str) -> None:
    ops = list(random_walk(4, 300, sigma=1.5))
    whole = loopworks.create_block(kind, stroke_rate=3.0)
    expected = run(whole, ops, dt=0.5)
    first = loopworks.create_block(kind, stroke_rate=3.0)
    run(first, ops[:150], dt=0.5)
    saved = json.loads(json.dumps(first.state_dict()))
    resumed = loopworks.create_block(kind, **saved["params"])
    resumed.load_state(saved)
    assert run(resumed, ops[150:], dt=0.5) == expected[150:]


def test_options_are_listed_in_the_docstring() -> None:
    doc = inspect.getdoc(valve) or ""
    options = doc.split("Options for the spec's [I] points")[1]
    for name in ("start", "resolution", "stroke_rate", "bad_op"):
        assert f"``{name}``" in options


@pytest.mark.parametrize("kind", [*STICTION, "valve.backlash", "valve.resolution",
                                  "valve.quantiser"])
def test_parameter_errors_name_the_parameter(kind: str) -> None:
    with pytest.raises(ParameterError, match=r"'rangeability' = 1 is out of range"):
        loopworks.create_block(kind, rangeability=1.0)
    with pytest.raises(ParameterError, match=r"'y0' = 101 is out of range: allowed \[0, 100\]"):
        loopworks.create_block(kind, y0=101.0)
    with pytest.raises(ParameterError, match="unknown parameter 'S_J'"):
        loopworks.create_block(kind, S_J=1.0)
