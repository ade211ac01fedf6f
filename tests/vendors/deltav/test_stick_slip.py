"""The DeltaV stick-slip compensator ``deltav.stick_slip`` against spec vendor-blocks section 6
(6.1-6.8) and seed 000 (the 28-line CALC expression).

Expected values come from the spec's golden step-through (6.8) and from hand arithmetic written
in the tests; float32 values are worked out with ``f32`` (numpy's IEEE float32 rounding) on
the hand formula, never pasted from a run of the block. Behaviour tests run twice through the
``make`` fixture: with the compiled (numba) kernel and with the interpreted one.
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
from tests.csvfiles import write_csv

NAN = math.nan
INF = math.inf
GOOD = 0x80  # 128, Good non-cascade
OOS = 0x1C  # 28, Bad out of service

Make = Callable[..., Block]

# spec 6.8 setup: RESOLUTION 0.5, DEADBAND 0.2, factors 1, PROCESS_GAIN 2, CNTRL_ACTION -1,
# VALVE_ACTION +1 (the last four are the seed's defaults)
SEED_68: dict[str, Any] = {"resolution": 0.5, "deadband": 0.2}
IN_68: dict[str, float] = {"signal_in": 40.0, "sp": 50.0, "initialize": 0.0}


def f32(v: float) -> float:
    """IEEE float32 rounding (nearest, ties to even), for the hand calculations."""
    with np.errstate(over="ignore"):  # beyond the float32 range: inf
        return float(np.float32(v))


# float32 hand arithmetic of lines 2, 3 and 8 for the 6.8 setup:
# DITHER_AMP = f32((f32(0.5) + 0.5·f32(0.2))·1·0.5) = f32(0.30000000074505806)
A32 = f32((0.5 + 0.5 * f32(0.2)) * 1.0 * 0.5)
NB32 = f32(A32 * 2.0 * 1.0)  # NOISE_BAND: an exact doubling of A32


@pytest.fixture(params=[True, False], ids=["compiled", "interpreted"])
def make(request: pytest.FixtureRequest) -> Make:
    """``make(**params)``: a deltav.stick_slip block, compiled or interpreted kernel."""
    jit = request.param

    def _make(**params: Any) -> Block:
        return loopworks.create_block("deltav.stick_slip", jit=jit, **params)

    return _make


def run(block: Block, **inputs: Any) -> dict[str, tuple[float, int]]:
    r = block.step(1.0, **inputs)
    return {k: (float(r[k].value), int(r[k].status)) for k in r}


def values(block: Block, **inputs: Any) -> dict[str, float]:
    return {k: v for k, (v, _) in run(block, **inputs).items()}


# ----------------------------------------------------------------------------------------------
# spec 6.8: golden step-through and its variants
# ----------------------------------------------------------------------------------------------
# (COMP_START, PV, DITHER_OUT, KICKER_DELT, DITHER_DELT, SIGNAL_OUT), spec 6.8 table rows 1-8
TABLE_68 = [
    (1.0, 50.0, +0.3, 0.0, -0.3, 39.7),   # band
    (1.0, 50.0, -0.3, 0.0, +0.3, 40.3),   # band
    (1.0, 50.5, +0.3, -0.3, 0.0, 39.7),   # high
    (1.0, 50.2, +0.3, -0.3, -0.3, 39.4),  # band, kick held
    (1.0, 49.3, -0.3, +0.3, 0.0, 40.3),   # low
    (1.0, 49.5, -0.3, +0.3, +0.3, 40.6),  # band, kick held
    (0.0, 49.5, +0.3, +0.3, +0.3, 40.0),  # pass-through, both stale
    (1.0, 50.31, -0.3, -0.3, 0.0, 39.7),  # high
]


def test_6_8_golden_step_through_float64(make: Make) -> None:
    """spec 6.8 table, rows 1-8, with float64 module parameters (the spec's float arithmetic)."""
    b = make(precision="float64", **SEED_68)
    for scan, (comp, pv, dither, kick, dith, out) in enumerate(TABLE_68, start=1):
        r = values(b, comp_start=comp, pv=pv, dither_out=dither, **IN_68)
        # derived constants (spec 6.8): DITHER_AMP = KICKER_OUT = 0.3, NOISE_BAND = 0.6
        assert r["dither_amp"] == pytest.approx(0.3, abs=1e-15), scan
        assert r["kicker_out"] == pytest.approx(0.3, abs=1e-15), scan
        assert r["noise_band"] == pytest.approx(0.6, abs=1e-15), scan
        assert r["kicker_delt"] == pytest.approx(kick, abs=1e-12), scan
        assert r["dither_delt"] == pytest.approx(dith, abs=1e-12), scan
        assert r["signal_out"] == pytest.approx(out, abs=1e-12), scan


def test_6_8_golden_step_through_float32_default(make: Make) -> None:
    """spec 6.8 table with the default float32 module parameters (spec 6.1 [A]): within a few
    float32 ulps of the table, and exactly the float32 hand arithmetic."""
    b = make(**SEED_68)
    for scan, (comp, pv, dither, kick, dith, out) in enumerate(TABLE_68, start=1):
        r = values(b, comp_start=comp, pv=pv, dither_out=dither, **IN_68)
        assert r["dither_amp"] == A32 == 0.30000001192092896
        assert r["kicker_out"] == A32
        assert r["noise_band"] == NB32 == 0.6000000238418579
        assert r["kicker_delt"] == pytest.approx(kick, abs=1e-6), scan
        assert r["dither_delt"] == pytest.approx(dith, abs=1e-6), scan
        assert r["signal_out"] == pytest.approx(out, abs=1e-5), scan
        # exact: each stored value is one float32 rounding of the float64 line result; the
        # kick and dither are ±A32 (f32(±0.3)·-1·1 = ∓A32 exactly), so line 26 is
        # f32(40 + kick + dither) with kick, dither in {-A32, 0, A32}
        assert abs(r["kicker_delt"]) in (0.0, A32) and abs(r["dither_delt"]) in (0.0, A32)
        if comp == 1.0:
            assert r["signal_out"] == f32(40.0 + r["kicker_delt"] + r["dither_delt"]), scan
        else:
            assert r["signal_out"] == 40.0, scan


def test_6_8_row4_signal_out_exact_float32(make: Make) -> None:
    """spec 6.8 row 4 by hand in float32: f32(40 - A32 - A32) = f32(39.39999997615814)."""
    b = make(**SEED_68)
    values(b, comp_start=1.0, pv=50.5, dither_out=0.3, **IN_68)  # high: kick -A32
    r = values(b, comp_start=1.0, pv=50.2, dither_out=0.3, **IN_68)  # band: dither -f32(0.3)
    assert r["signal_out"] == f32((40.0 - A32) - A32) == 39.400001525878906


def test_6_8_variant_initialize_and_kick_start_zero_the_band(make: Make) -> None:
    """spec 6.8 variant (spec 6.3 lines 5-6, 6.6): INITIALIZE = KICK_START = 1 gives
    NOISE_BAND = 0: PV 50.1 high (39.7), PV 49.9 low (40.3), PV 50.0 band (40 + held kick +
    dither)."""
    b = make(precision="float64", kick_start=1.0, **SEED_68)
    inputs = {**IN_68, "initialize": 1.0, "comp_start": 1.0, "dither_out": 0.3}
    r = values(b, pv=50.1, **inputs)
    assert r["noise_band"] == 0.0
    assert r["signal_out"] == pytest.approx(39.7, abs=1e-12)
    r = values(b, pv=49.9, **inputs)
    assert r["signal_out"] == pytest.approx(40.3, abs=1e-12)
    r = values(b, pv=50.0, **inputs)  # band: held kick +0.3, dither 0.3·-1·1 = -0.3
    assert r["kicker_delt"] == pytest.approx(0.3, abs=1e-12)
    assert r["signal_out"] == pytest.approx(40.0 + 0.3 - 0.3, abs=1e-12)
    # the same band scan after a high kick: 40 - 0.3 - 0.3
    values(b, pv=50.1, **inputs)
    r = values(b, pv=50.0, **inputs)
    assert r["signal_out"] == pytest.approx(39.4, abs=1e-12)


def test_6_8_variant_band_zero_needs_both_flags_exactly_1(make: Make) -> None:
    """spec 6.3 lines 5-9: both INITIALIZE and KICK_START must equal 1 exactly (float =)."""
    for kick_start, initialize in ((1.0, 0.0), (0.0, 1.0), (1.0, 0.999), (1.0, 2.0),
                                   (0.5, 1.0)):
        b = make(precision="float64", kick_start=kick_start, **SEED_68)
        r = values(b, pv=50.0, comp_start=1.0, dither_out=0.3,
                   **{**IN_68, "initialize": initialize})
        assert r["noise_band"] == pytest.approx(0.6, abs=1e-15), (kick_start, initialize)
    b = make(precision="float64", kick_start=1.0, **SEED_68)
    assert values(b, **{**IN_68, "initialize": 1.0})["noise_band"] == 0.0


def test_6_8_variant_parameter_defaults_pass_through(make: Make) -> None:
    """spec 6.8 variant: with the parameter-list defaults (RESOLUTION = DEADBAND = 0) every
    amplitude is 0 and SIGNAL_OUT = SIGNAL_IN whatever the branch. DITHER_OUT is the SGGN1
    output of amplitude DITHER_AMP = 0 (spec 6.5): the internal dither (NaN) or a wired 0."""
    b = make()
    rng = np.random.default_rng(3)
    for _ in range(200):
        si = f32(float(rng.uniform(0.0, 100.0)))  # a float32 value: stored unchanged
        pv = float(rng.choice([45.0, 50.0, 55.0]))
        r = values(b, signal_in=si, sp=50.0, pv=pv, comp_start=float(rng.integers(0, 2)),
                   dither_out=float(rng.choice([NAN, 0.0])))
        assert r["dither_amp"] == r["kicker_out"] == r["noise_band"] == 0.0
        assert r["kicker_delt"] == 0.0 and r["dither_delt"] == 0.0
        assert r["signal_out"] == si
    # line 23 is literal: a DITHER_OUT not scaled by DITHER_AMP still reaches SIGNAL_OUT
    r = values(b, signal_in=40.0, sp=50.0, pv=50.0, comp_start=1.0, dither_out=0.5)
    assert r["signal_out"] == 40.0 - 0.5


@pytest.mark.parametrize("status", [0x80, 0x1C, 0x00, 0x47, 0xC2, 0x99])
def test_6_8_variant_signal_out_status_is_signal_in_status(make: Make, status: int) -> None:
    """spec 6.8 variant, spec 6.3 line 28: SIGNAL_OUT.ST = SIGNAL_IN.ST on every row, both
    branches (0x80 in gives 0x80 out; 0x1C out of service in gives 0x1C out); the other
    outputs are Good non-cascade."""
    b = make(**SEED_68)
    for comp, pv, dither, _, _, _ in TABLE_68:
        r = run(b, signal_in=(40.0, status), sp=50.0, pv=pv, comp_start=comp, dither_out=dither)
        assert r["signal_out"][1] == status
        for name in ("dither_amp", "kicker_out", "noise_band", "kicker_delt", "dither_delt"):
            assert r[name][1] == GOOD
        # the status does not change the value (spec 6.3: status is copied, never acted on)
    assert r["signal_out"][0] == pytest.approx(39.7, abs=1e-5)


# ----------------------------------------------------------------------------------------------
# spec 6.3: branches, held values, no clamp, action product
# ----------------------------------------------------------------------------------------------
def test_kicker_delt_held_in_band_and_in_pass_through_then_reused(make: Make) -> None:
    """spec 6.3 lines 11-12 and 22-23: KICKER_DELT keeps its value inside the band and while
    COMP_START = 0; on resuming inside the band the stale kick comes back into effect."""
    b = make(precision="float64", **SEED_68)
    values(b, comp_start=1.0, pv=49.0, dither_out=0.3, **IN_68)  # low: kick +0.3
    r = values(b, comp_start=0.0, pv=55.0, dither_out=0.3, **IN_68)  # pass-through
    assert r["signal_out"] == 40.0
    assert r["kicker_delt"] == pytest.approx(0.3, abs=1e-15)
    assert r["dither_delt"] == 0.0
    r = values(b, comp_start=1.0, pv=50.0, dither_out=-0.3, **IN_68)  # band, stale kick
    # 40 + 0.3 + (-0.3·-1·1) = 40.6
    assert r["signal_out"] == pytest.approx(40.6, abs=1e-12)


def test_kick_in_band_reset_option_dithers_only_in_band(make: Make) -> None:
    """plant-and-tuning 2.3 item 2 [I] (architecture: "the held kick", a quirk with an option
    for the corrected behaviour): kick_in_band = reset zeroes KICKER_DELT inside the band,
    "dither only in band"; the default keeps the seed's held kick."""
    b = make(precision="float64", kick_in_band="reset", **SEED_68)
    assert values(b, comp_start=1.0, pv=49.0, dither_out=0.3, **IN_68)["kicker_delt"] == \
        pytest.approx(0.3)  # low: kick +0.3, as held
    r = values(b, comp_start=1.0, pv=50.0, dither_out=-0.3, **IN_68)  # band: no kick
    assert r["kicker_delt"] == 0.0
    assert r["signal_out"] == pytest.approx(40.3, abs=1e-12)  # 40 + 0 + (-0.3·-1·1)
    held = make(precision="float64", **SEED_68)
    values(held, comp_start=1.0, pv=49.0, dither_out=0.3, **IN_68)
    assert values(held, comp_start=1.0, pv=50.0, dither_out=-0.3, **IN_68)["kicker_delt"] == \
        pytest.approx(0.3)  # the default: the kick persists while dithering


def test_asymmetric_band_edges(make: Make) -> None:
    """spec 6.4: high above SP + NB/2 = 50.3, low below SP - NB = 49.4 (band 1.5·NB wide);
    the tests are strict. PVs kept 1e-3 away from the triggers (spec 6.8 note)."""
    cases = [(50.301, "high"), (50.299, "band"), (49.401, "band"), (49.399, "low"),
             (49.5, "band"), (50.0, "band")]
    for pv, branch in cases:
        b = make(**SEED_68)
        r = values(b, comp_start=1.0, pv=pv, dither_out=0.3, **IN_68)
        kick = {"high": -A32, "low": A32, "band": 0.0}[branch]
        assert r["kicker_delt"] == kick, pv
        assert r["dither_delt"] == (-A32 if branch == "band" else 0.0), pv


def test_band_factor_options(make: Make) -> None:
    """spec 6.4 [A]: upper_band_factor/lower_band_factor replace 0.5 (line 15) and 1 (line 19).
    NB = 0.6: symmetric 0.5/0.5 gives low below 49.7; 1/1 gives high above 50.6."""
    b = make(precision="float64", lower_band_factor=0.5, **SEED_68)
    assert values(b, comp_start=1.0, pv=49.6, dither_out=0.3, **IN_68)["kicker_delt"] == \
        pytest.approx(0.3)
    b = make(precision="float64", **SEED_68)  # literal: 49.6 is inside the band
    assert values(b, comp_start=1.0, pv=49.6, dither_out=0.3, **IN_68)["kicker_delt"] == 0.0
    b = make(precision="float64", upper_band_factor=1.0, **SEED_68)
    assert values(b, comp_start=1.0, pv=50.5, dither_out=0.3, **IN_68)["kicker_delt"] == 0.0
    assert values(b, comp_start=1.0, pv=50.7, dither_out=0.3, **IN_68)["kicker_delt"] == \
        pytest.approx(-0.3)


def test_no_clamp_on_signal_out(make: Make) -> None:
    """spec 6.3 line 26: no clamp; 99.9 + kick 0.3 + nothing = 100.2, -0.1 - 0.3 = -0.4."""
    b = make(precision="float64", **SEED_68)
    r = values(b, signal_in=99.9, sp=50.0, pv=40.0, comp_start=1.0, dither_out=0.3)
    assert r["signal_out"] == pytest.approx(100.2, abs=1e-12)
    r = values(b, signal_in=-0.1, sp=50.0, pv=60.0, comp_start=1.0, dither_out=0.3)
    assert r["signal_out"] == pytest.approx(-0.4, abs=1e-12)


@pytest.mark.parametrize(("ca", "va", "high_kick"), [(-1.0, 1.0, -0.3), (1.0, 1.0, 0.3),
                                                     (1.0, -1.0, -0.3), (-1.0, -1.0, 0.3)])
def test_kick_sign_is_the_literal_action_product(make: Make, ca: float, va: float,
                                                 high_kick: float) -> None:
    """spec 6.3 lines 16, 20, 23 and 6.7: the literal product CNTRL_ACTION·VALVE_ACTION."""
    b = make(precision="float64", cntrl_action=ca, valve_action=va, **SEED_68)
    assert values(b, comp_start=1.0, pv=51.0, dither_out=0.3, **IN_68)["kicker_delt"] == \
        pytest.approx(high_kick)
    assert values(b, comp_start=1.0, pv=49.0, dither_out=0.3, **IN_68)["kicker_delt"] == \
        pytest.approx(-high_kick)
    assert values(b, comp_start=1.0, pv=50.0, dither_out=0.3, **IN_68)["dither_delt"] == \
        pytest.approx(0.3 * ca * va)


def test_factors_scale_their_amplitudes(make: Make) -> None:
    """spec 6.3 lines 2, 3, 8: DITHER_AMP = (0.5 + 0.1)·2·0.5 = 0.6, KICKER_OUT =
    0.6·3·0.5 = 0.9, NOISE_BAND = 0.6·4·0.25 = 0.6."""
    b = make(precision="float64", dither_factor=2.0, kicker_factor=3.0, process_gain=4.0,
             noise_factor=0.25, **SEED_68)
    r = values(b, **IN_68)
    assert r["dither_amp"] == pytest.approx(0.6, abs=1e-15)
    assert r["kicker_out"] == pytest.approx(0.9, abs=1e-15)
    assert r["noise_band"] == pytest.approx(0.6, abs=1e-15)


def test_reset_time_is_unused(make: Make) -> None:
    """spec 6.2: RESET_TIME is read but unused by the expression."""
    a, b = make(reset_time=8.0, **SEED_68), make(reset_time=1234.5, **SEED_68)
    for comp, pv, dither, _, _, _ in TABLE_68:
        inputs = {"comp_start": comp, "pv": pv, "dither_out": dither, **IN_68}
        assert run(a, **inputs) == run(b, **inputs)


# ----------------------------------------------------------------------------------------------
# spec 6.1: float32 module parameters and deferred reads
# ----------------------------------------------------------------------------------------------
def test_float32_reads_move_a_pv_just_above_the_trigger_into_the_band(make: Make) -> None:
    """spec 6.1 [A], 6.8 note: PV 50.3000001 is above the float64 trigger 50.3 but reads as
    f32(50.3000001) = 50.29999924 < 50 + 0.30000001 in float32 precision."""
    assert f32(50.3000001) < 50.0 + A32 < 50.3000001
    b = make(**SEED_68)
    assert values(b, comp_start=1.0, pv=50.3000001, dither_out=0.3, **IN_68)["kicker_delt"] \
        == 0.0
    b = make(precision="float64", **SEED_68)
    assert values(b, comp_start=1.0, pv=50.3000001, dither_out=0.3, **IN_68)["kicker_delt"] \
        == pytest.approx(-0.3)


def test_float32_parameters_and_stored_values(make: Make) -> None:
    """spec 6.1 [A]: parameters are stored as float32 (kick_start 1.00000001 is exactly 1 in
    float32, not in float64); signal_out is stored as float32."""
    b = make(kick_start=1.00000001, **SEED_68)
    assert values(b, **{**IN_68, "initialize": 1.0})["noise_band"] == 0.0
    b = make(kick_start=1.00000001, precision="float64", **SEED_68)
    assert values(b, **{**IN_68, "initialize": 1.0})["noise_band"] == pytest.approx(0.6)
    b = make()
    r = values(b, signal_in=0.1, comp_start=0.0)
    assert r["signal_out"] == f32(0.1) == 0.10000000149011612
    b = make(precision="float64")
    assert values(b, signal_in=0.1, comp_start=0.0)["signal_out"] == 0.1


def test_float32_overflow_is_not_stored(make: Make) -> None:
    """spec 6.1 [A]: a value beyond the float32 range rounds to ±inf; issue 11 point 1 (this
    test pinned signal_out = inf before): it is not stored, the parameter holds its last value
    and is Bad, until a finite value is stored again."""
    b = make(**SEED_68)
    r = run(b, signal_in=1e39, sp=50.0, pv=50.0, comp_start=0.0)
    assert r["signal_out"] == (0.0, 0)  # held at the seed default 0, Bad
    r = run(b, signal_in=3e38, sp=50.0, pv=50.0, comp_start=1.0, dither_out=-3e38)
    # hand: DITHER_DELT = f32(f32(-3e38)·-1·1) = f32(3e38) (finite);
    # line 26: f32(f32(3e38) + 0 + f32(3e38)) = f32(6e38) = inf: SIGNAL_OUT held (0), Bad
    assert r["dither_delt"] == (f32(3e38), GOOD)
    assert r["signal_out"] == (0.0, 0)
    r = run(b, signal_in=40.0, sp=50.0, pv=50.0, comp_start=1.0, dither_out=-0.3)
    assert r["signal_out"] == (f32(40.0 + A32), GOOD)
    b = make(precision="float64", **SEED_68)
    r = run(b, signal_in=3e38, sp=50.0, pv=50.0, comp_start=1.0, dither_out=-3e38)
    assert r["signal_out"] == (6e38, GOOD)


def test_amplitudes_beyond_float32_hold_bad(make: Make) -> None:
    """spec 6.1 [A], issue 11 point 1: RESOLUTION 3e38 and DEADBAND 2e38 are float32 values,
    but line 2 gives (3e38 + 1e38)·2·0.5 = 4e38, beyond float32: DITHER_AMP is not stored,
    holds its start value 0 and is Bad on every scan (so NOISE_BAND = 0·2·1 = 0 is Good);
    KICKER_OUT = (4e38)·1·0.5 = 2e38 is finite. In float64 every value is stored."""
    b = make(resolution=3e38, deadband=2e38, dither_factor=2.0)
    for _ in range(3):
        r = run(b, **IN_68, pv=50.0, comp_start=1.0, dither_out=0.3)
        assert r["dither_amp"] == (0.0, 0)
        assert r["kicker_out"] == (f32((f32(3e38) + 0.5 * f32(2e38)) * 0.5), GOOD)
        assert r["noise_band"] == (0.0, GOOD)
    r = run(make(resolution=3e38, deadband=2e38, dither_factor=2.0, precision="float64"),
            **IN_68)
    assert r["dither_amp"] == (4e38, GOOD)


def test_deferred_reads_lag_lines_8_15_16_and_26_by_one_scan(make: Make) -> None:
    """spec 6.1 [A] deferred_param_reads: reads of parameters written by the expression see
    last scan's values (initially the seed defaults 0).
    scan 1, PV 50.2: NOISE_BAND := DITHER_AMP(prev 0)·2·1 = 0, the high test uses NB(prev 0):
      50.2 > 50 + 0 -> high; KICKER_DELT := KICKER_OUT(prev 0)·-1·1 = 0;
      SIGNAL_OUT := 40 + KICKER_DELT(prev 0) + DITHER_DELT(prev 0) = 40.
    scan 2, PV 50.2: NB := 0.3·2 = 0.6, but the test reads NB(prev 0): high;
      KICKER_DELT := 0.3·-1 = -0.3; SIGNAL_OUT := 40 + 0 + 0 = 40.
    scan 3, PV 50.2: band (NB prev 0.6: 50.2 <= 50.3); DITHER_DELT := 0.3·-1 = -0.3;
      SIGNAL_OUT := 40 + (-0.3) + 0 = 39.7 (last scan's kick and dither).
    scan 4, same: SIGNAL_OUT := 40 - 0.3 - 0.3 = 39.4."""
    b = make(precision="float64", deferred_param_reads=True, **SEED_68)
    got = [values(b, comp_start=1.0, pv=50.2, dither_out=0.3, **IN_68) for _ in range(4)]
    assert [g["noise_band"] for g in got] == pytest.approx([0.0, 0.6, 0.6, 0.6])
    assert [g["kicker_delt"] for g in got] == pytest.approx([0.0, -0.3, -0.3, -0.3])
    assert [g["dither_delt"] for g in got] == pytest.approx([0.0, 0.0, -0.3, -0.3])
    assert [g["signal_out"] for g in got] == pytest.approx([40.0, 40.0, 39.7, 39.4])
    # immediate writes (the default): band from the first scan, 40 - 0.3
    b = make(precision="float64", **SEED_68)
    r = values(b, comp_start=1.0, pv=50.2, dither_out=0.3, **IN_68)
    assert r["signal_out"] == pytest.approx(39.7) and r["kicker_delt"] == 0.0


# ----------------------------------------------------------------------------------------------
# spec 6.5: the internal dither
# ----------------------------------------------------------------------------------------------
def test_internal_dither_is_previous_dither_amp_alternating_from_plus(make: Make) -> None:
    """spec 6.5 [A]: dither_out NaN -> ±DITHER_AMP of the previous scan, starting with +,
    alternating every scan. Scan 0 uses the seed default DITHER_AMP 0 (one-scan lag); then
    -A, +A, -A: DITHER_DELT = dither·-1·1 = 0, +A, -A, +A."""
    b = make(**SEED_68)
    got = [values(b, comp_start=1.0, pv=50.0, **IN_68) for _ in range(5)]
    assert [g["dither_delt"] for g in got] == [0.0, A32, -A32, A32, -A32]
    assert [g["signal_out"] for g in got] == [40.0, f32(40.0 + A32), f32(40.0 - A32),
                                              f32(40.0 + A32), f32(40.0 - A32)]


def test_internal_dither_half_period(make: Make) -> None:
    """spec 6.5 [A]: dither_half_period N alternates every N scans: + + - - + + for N = 2,
    so DITHER_DELT = -(+0), -(+A), +A, +A, -A, -A."""
    b = make(dither_half_period=2, precision="float64", **SEED_68)
    got = [values(b, comp_start=1.0, pv=50.0, **IN_68)["dither_delt"] for _ in range(6)]
    assert got == pytest.approx([0.0, -0.3, 0.3, 0.3, -0.3, -0.3])


def test_internal_dither_counter_runs_while_dither_out_is_supplied(make: Make) -> None:
    """spec 6.5: SGGN1 runs every scan; after two supplied scans the internal wave is at
    scan 2 (+): DITHER_DELT = 0.3·-1 = -0.3."""
    b = make(precision="float64", **SEED_68)
    values(b, comp_start=1.0, pv=50.0, dither_out=0.3, **IN_68)
    values(b, comp_start=1.0, pv=50.0, dither_out=0.3, **IN_68)
    r = values(b, comp_start=1.0, pv=50.0, dither_out=NAN, **IN_68)
    assert r["dither_delt"] == pytest.approx(-0.3)


def test_module_sggn1_then_compensator_equals_internal_dither() -> None:
    """spec 6.1, 6.5: SGGN1 (#3, square, period 2·dt, amplitude wired from the compensator's
    DITHER_AMP) runs before the CALC (#4) and feeds DITHER_OUT: the module gives exactly the
    outputs of the compensator's internal dither (±last scan's DITHER_AMP, alternating)."""
    dt = 0.5
    n = 400
    rng = np.random.default_rng(21)
    pvs = rng.uniform(49.0, 51.0, n)
    comps = (rng.random(n) < 0.9).astype(float)
    variants: list[dict[str, Any]] = [{}, {"precision": "float64", "deferred_param_reads": True},
                                      {"dither_half_period": 3, "kicker_factor": 2.0}]
    for params in variants:
        half = int(params.get("dither_half_period", 1))
        module = Module(
            {"sggn1": create_block("deltav.sggn", waveform="square", period=2 * half * dt),
             "comp": create_block("deltav.stick_slip", **SEED_68, **params)},
            wires={"sggn1.amplitude": "comp.dither_amp", "comp.dither_out": "sggn1.out"},
            inputs={"comp": {"signal_in": 40.0, "sp": 50.0}})
        alone = create_block("deltav.stick_slip", **SEED_68, **params)
        dithers = []
        for k in range(n):
            module.blocks["comp"].set_inputs({"pv": float(pvs[k]), "comp_start": comps[k]})
            module.scan(dt)
            r = alone.step(dt, signal_in=40.0, sp=50.0, pv=float(pvs[k]), comp_start=comps[k])
            dithers.append(float(module.blocks["sggn1"].y[0]))
            for i, port in enumerate(alone.OUTPUTS):
                assert module.blocks["comp"].y[i] == r[port.name].value, (params, k, port.name)
        # the module's dither: 0 at scan 0 (DITHER_AMP 0 before the first CALC), then ±A
        amp = float(module.blocks["comp"].y[1])
        expected = [0.0] + [amp if (k // half) % 2 == 0 else -amp for k in range(1, n)]
        assert dithers == expected


# ----------------------------------------------------------------------------------------------
# NaN / inf inputs: IEEE semantics of the expression (comparisons with NaN are false)
# ----------------------------------------------------------------------------------------------
def test_nan_comp_start_is_not_0_so_it_compensates(make: Make) -> None:
    """spec 6.3 line 11: NaN = 0 is false -> the compensation branch."""
    b = make(precision="float64", **SEED_68)
    r = values(b, comp_start=NAN, pv=51.0, dither_out=0.3, **IN_68)
    assert r["kicker_delt"] == pytest.approx(-0.3) and r["signal_out"] == pytest.approx(39.7)


def test_nan_initialize_is_not_1(make: Make) -> None:
    """spec 6.3 line 5: NaN = 1 is false -> NOISE_BAND computed."""
    b = make(precision="float64", kick_start=1.0, **SEED_68)
    assert values(b, **{**IN_68, "initialize": NAN})["noise_band"] == pytest.approx(0.6)


@pytest.mark.parametrize("which", ["pv", "sp"])
def test_nan_pv_or_sp_fails_both_band_tests_and_dithers(make: Make, which: str) -> None:
    """spec 6.3 lines 15, 19: both comparisons false -> band branch, the kick is held."""
    b = make(precision="float64", **SEED_68)
    values(b, comp_start=1.0, pv=49.0, dither_out=0.3, **IN_68)  # low: kick +0.3
    inputs = {**IN_68, "comp_start": 1.0, "pv": 50.0, "dither_out": 0.3, which: NAN}
    r = values(b, **inputs)
    assert r["kicker_delt"] == pytest.approx(0.3)
    assert r["dither_delt"] == pytest.approx(-0.3)
    assert r["signal_out"] == pytest.approx(40.0)


def test_nan_signal_in_holds_signal_out_bad_and_recovers(make: Make) -> None:
    """issue 11 point 1 (this test pinned a NaN signal_out before): a NaN signal_in is Bad
    input; line 12 (pass-through) or line 26 gives a NaN result, which is not stored:
    signal_out holds its last value, f32(40 - A32) (band, dither 0.3·-1), Bad. Good input
    again gives the good answer at once."""
    b = make(**SEED_68)
    held = values(b, signal_in=40.0, sp=50.0, pv=50.0, comp_start=1.0, dither_out=0.3)
    assert held["signal_out"] == f32(40.0 - A32)
    for comp in (0.0, 1.0):
        r = run(b, signal_in=NAN, sp=50.0, pv=50.0, comp_start=comp, dither_out=0.3)
        assert r["signal_out"] == (f32(40.0 - A32), 0)
        assert all(math.isfinite(v) for v in b.state().values())
    r = run(b, signal_in=40.0, sp=50.0, pv=50.0, comp_start=1.0, dither_out=-0.3)
    assert r["signal_out"] == (f32(40.0 + A32), GOOD)


@pytest.mark.parametrize("value", [NAN, INF, -INF, 1e308, -1e308, 3.5e38, -3.5e38])
@pytest.mark.parametrize("name", ["signal_in", "sp", "pv", "comp_start", "initialize",
                                  "dither_out"])
def test_issue_11_extreme_value_into_each_input(make: Make, name: str, value: float) -> None:
    """issue 11 point 1: NaN, ±inf and ±1e308 / ±3.5e38 (beyond float32: read as ±inf, spec 6.1
    [A]) into each input, arriving Good: no output is non-finite, an output whose value could
    not be computed is Bad, no state is non-finite, and with good inputs again every output is
    as in a run that never saw the value. Expected per input, by the seed's lines:
    signal_in: lines 12/26 not finite: signal_out held, Bad (line 28 reads SIGNAL_IN.ST Bad);
    sp, pv: band tests are IEEE comparisons (NaN fails both: dither; +inf PV or -inf SP is
    high; the other sign low), every output finite and Good; comp_start, initialize: a
    non-finite value is neither 0 nor 1 (compensate, band computed), Good; dither_out: NaN
    selects the internal dither, any other value line 23 not finite: dither_delt held, Bad,
    signal_out Good (it adds the held dither). Recovery: the same outputs as the undisturbed
    run, except the kick an infinite PV (or SP) took, which the band holds (spec 6.6: the
    relay keeps its last state)."""
    good = {**IN_68, "pv": 50.0, "comp_start": 1.0, "dither_out": 0.3}
    b, ref = make(**SEED_68), make(**SEED_68)
    for block in (b, ref):
        run(block, **{**good, "dither_out": -0.3})
    r = run(b, **{**good, name: value})
    for port in r:
        assert math.isfinite(r[port][0]), port
    assert all(math.isfinite(v) for v in b.state().values())
    bad = {port for port in r if r[port][1] == 0}
    if name == "signal_in":
        assert bad == {"signal_out"} and r["signal_out"][0] == f32(40.0 + A32)
    elif name == "dither_out" and not math.isnan(value):
        assert bad == {"dither_delt"} and r["dither_delt"][0] == A32
        assert r["signal_out"] == (f32(40.0 + A32), GOOD)
    else:
        assert bad == set()
    if name == "pv" and not math.isnan(value):
        assert r["kicker_delt"][0] == (-A32 if value > 0 else A32)  # high / low
    if name == "sp" and not math.isnan(value):
        assert r["kicker_delt"][0] == (A32 if value > 0 else -A32)  # PV below / above
    run(ref, **good)
    kicked = name in ("sp", "pv") and not math.isnan(value)
    for _ in range(3):
        got, want = run(b, **good), run(ref, **good)
        if kicked:
            assert got.pop("kicker_delt") == (r["kicker_delt"][0], GOOD)
            assert got.pop("signal_out") == (f32(want["signal_out"][0] + r["kicker_delt"][0]),
                                             GOOD)
            del want["kicker_delt"], want["signal_out"]
        assert got == want


@pytest.mark.parametrize("status", [0x00, 0x1C, 0x0C, 0x40])
def test_issue_11_bad_status_passes_through_and_a_held_value_keeps_a_bad_substatus(
        make: Make, status: int) -> None:
    """spec 6.3 line 28 pass-through stays: a finite signal_in with a Bad or Uncertain status
    gives that status on signal_out; a non-finite signal_in that arrives Bad (0x1C out of
    service) holds signal_out with that status, substatus kept; Uncertain (0x40) with NaN is
    Bad (0) (issue 11 point 1)."""
    b = make(precision="float64", **SEED_68)
    r = run(b, signal_in=(40.0, status), sp=50.0, pv=50.0, comp_start=1.0, dither_out=0.3)
    assert r["signal_out"] == (pytest.approx(39.7), status)
    r = run(b, signal_in=(NAN, status), sp=50.0, pv=50.0, comp_start=1.0, dither_out=0.3)
    assert r["signal_out"] == (pytest.approx(39.7), 0 if status & 0xC0 else status)


def test_infinite_pv_kicks_and_extreme_values_do_not_raise(make: Make) -> None:
    """IEEE: inf > SP + NB/2 -> high; -inf -> low. issue 11 point 1 (this test pinned
    dither_delt = signal_out = inf and a NaN signal_out, Good, before): an infinite dither
    holds dither_delt, Bad; -inf + A32 + (held dither) is -inf: signal_out holds, Bad."""
    b = make(**SEED_68)
    assert values(b, comp_start=1.0, pv=INF, dither_out=0.3, **IN_68)["kicker_delt"] == -A32
    assert values(b, comp_start=1.0, pv=-INF, dither_out=0.3, **IN_68)["kicker_delt"] == A32
    r = run(b, comp_start=1.0, pv=50.0, dither_out=-INF, **IN_68)
    assert r["dither_delt"] == (0.0, 0)  # held: 0 since the kicks
    assert r["signal_out"] == (f32(40.0 + A32), GOOD)  # 40 + kick A32 + held dither 0
    r = run(b, signal_in=-INF, sp=50.0, pv=50.0, comp_start=1.0, dither_out=-INF)
    assert r["signal_out"] == (f32(40.0 + A32), 0) and r["dither_delt"] == (0.0, 0)


# ----------------------------------------------------------------------------------------------
# The seed's lines, literally: an independent line-by-line reading of the expression
# ----------------------------------------------------------------------------------------------
def literal_scan(mp: dict[str, float], deferred: bool, single: bool) -> None:
    """One CALC scan of seed 000 on the module parameter table ``mp``, written straight from
    the seed text: every assignment stores f32(float64 result) in float32 precision; with
    deferred reads, reads of written parameters come from a snapshot of the scan start.
    Issue 11 point 1 (the rule of deltav.calc): a result that is not finite is not stored, the
    parameter keeps its value and is held in this scan (``mp[NAME + ".held"]``, shown Bad);
    SIGNAL_IN.ST reads Bad (0) while SIGNAL_IN is not finite (unless it is Bad already)."""
    for name in ("DITHER_AMP", "KICKER_OUT", "NOISE_BAND", "KICKER_DELT", "DITHER_DELT",
                 "SIGNAL_OUT"):
        mp[name + ".held"] = 0.0
    start = dict(mp)

    def rd(name: str) -> float:
        return start[name] if deferred else mp[name]

    def assign(name: str, value: float) -> None:
        value = f32(value) if single else value
        if math.isfinite(value):
            mp[name] = value
        mp[name + ".held"] = 0.0 if math.isfinite(value) else 1.0

    assign("DITHER_AMP", (rd("RESOLUTION") + 0.5 * rd("DEADBAND")) * rd("DITHER_FACTOR") * 0.5)
    assign("KICKER_OUT", (rd("RESOLUTION") + 0.5 * rd("DEADBAND")) * rd("KICKER_FACTOR") * 0.5)
    if rd("INITIALIZE") == 1 and rd("KICK_START") == 1:
        assign("NOISE_BAND", 0.0)
    else:
        assign("NOISE_BAND", rd("DITHER_AMP") * rd("PROCESS_GAIN") * rd("NOISE_FACTOR"))
    if rd("COMP_START") == 0:
        assign("SIGNAL_OUT", rd("SIGNAL_IN"))
    else:
        if rd("PV") > (rd("SP") + rd("NOISE_BAND") * 0.5):
            assign("KICKER_DELT", rd("KICKER_OUT") * rd("CNTRL_ACTION") * rd("VALVE_ACTION"))
            assign("DITHER_DELT", 0.0)
        elif rd("PV") < (rd("SP") - rd("NOISE_BAND")):
            assign("KICKER_DELT", -rd("KICKER_OUT") * rd("CNTRL_ACTION") * rd("VALVE_ACTION"))
            assign("DITHER_DELT", 0.0)
        else:
            assign("DITHER_DELT", rd("DITHER_OUT") * rd("CNTRL_ACTION") * rd("VALVE_ACTION"))
        assign("SIGNAL_OUT", rd("SIGNAL_IN") + rd("KICKER_DELT") + rd("DITHER_DELT"))
    status = int(mp["SIGNAL_IN.ST"])
    mp["SIGNAL_OUT.ST"] = status if math.isfinite(mp["SIGNAL_IN"]) or status < 0x40 else 0


def shown(mp: dict[str, float], name: str) -> int:
    """The status of a written parameter: its .ST (128 unless assigned), Bad while held."""
    status = int(mp.get(name + ".ST", GOOD))
    return 0 if mp[name + ".held"] and status >= 0x40 else status


@pytest.mark.parametrize("single", [True, False], ids=["float32", "float64"])
@pytest.mark.parametrize("deferred", [False, True], ids=["immediate", "deferred"])
def test_bit_identical_to_the_literal_expression_on_random_sequences(
        make: Make, single: bool, deferred: bool) -> None:
    """spec 6.1, 6.3: the native block equals the seed's lines executed literally, bit for bit,
    on long random sequences (including values near the triggers, NaN PV/SP/SIGNAL_IN, status
    bytes), with random parameters; the last sequence has extreme inputs (NaN, ±inf, ±1e308,
    beyond float32) and parameters near the float32 limit (issue 11 point 1), statuses
    included."""
    rng = np.random.default_rng(2024 + 2 * single + deferred)
    store = f32 if single else float
    extremes = [NAN, INF, -INF, 1e308, -1e308, 3.5e38, -3.5e38, 3e38, 5e-324]
    for rep in range(4):
        params = {"resolution": float(rng.uniform(0, 2)), "deadband": float(rng.uniform(0, 1)),
                  "process_gain": float(rng.uniform(0.1, 5)),
                  "cntrl_action": float(rng.choice([-1.0, 1.0])),
                  "valve_action": float(rng.choice([-1.0, 1.0])),
                  "dither_factor": float(rng.uniform(0, 2)),
                  "kicker_factor": float(rng.uniform(0, 2)),
                  "noise_factor": float(rng.uniform(0, 2)),
                  "kick_start": float(rng.choice([0.0, 1.0]))}
        extreme = rep == 3
        if extreme:
            params.update(resolution=3e38, deadband=2e38, process_gain=1e30, valve_action=3.0)
        b = make(precision="float32" if single else "float64", deferred_param_reads=deferred,
                 **params)
        mp = {k.upper(): store(v) for k, v in params.items()}
        for name in ("DITHER_AMP", "KICKER_OUT", "NOISE_BAND", "KICKER_DELT", "DITHER_DELT",
                     "SIGNAL_OUT"):
            mp[name] = mp[name + ".held"] = 0.0
        for _k in range(2000):
            inputs = {"signal_in": float(rng.uniform(-10, 110)), "sp": float(rng.uniform(40, 60)),
                      "pv": float(rng.uniform(38, 62)),
                      "comp_start": float(rng.choice([0.0, 1.0, 1.0, 1.0, 0.5])),
                      "initialize": float(rng.choice([0.0, 1.0])),
                      "dither_out": float(rng.uniform(-2, 2))}
            if rng.random() < 0.3:  # near a trigger of the last band
                inputs["pv"] = inputs["sp"] + mp["NOISE_BAND"] * float(rng.choice([0.5, -1.0])) \
                    + float(rng.normal(0.0, 1e-7))
            if rng.random() < 0.02:
                inputs[str(rng.choice(["pv", "sp", "signal_in", "comp_start"]))] = NAN
            if extreme and rng.random() < 0.3:  # dither_out NaN is the internal dither
                inputs[str(rng.choice(list(inputs)))] = float(rng.choice(extremes[1:]))
            status = int(rng.choice([0x80, 0x1C, 0x40, 0xC0]))
            for name, value in inputs.items():
                mp[name.upper()] = store(value)
            # the status the block sees: the numeric guard shows a non-finite value as Bad (0)
            mp["SIGNAL_IN.ST"] = status if math.isfinite(inputs["signal_in"]) or \
                status < 0x40 else 0
            literal_scan(mp, deferred, single)
            r = run(b, **{**inputs, "signal_in": (inputs["signal_in"], status)})
            for name in ("signal_out", "dither_amp", "kicker_out", "noise_band", "kicker_delt",
                         "dither_delt"):
                want = mp[name.upper()]
                got = r[name][0]
                assert got == want, name
                assert r[name][1] == shown(mp, name.upper()), name



# ----------------------------------------------------------------------------------------------
# Parameters, state, jit, replay, docs
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("name", "value"), [
    ("precision", "float16"), ("dither_half_period", 0), ("dither_half_period", 1.5),
    ("upper_band_factor", -0.1), ("lower_band_factor", INF), ("resolution", INF),
    ("deadband", "abc"), ("cntrl_action", NAN), ("deferred_param_reads", "maybe"),
    ("resolution", 1e39)])
def test_bad_parameters_name_the_parameter(name: str, value: Any) -> None:
    with pytest.raises(ParameterError, match=name):
        loopworks.create_block("deltav.stick_slip", **{name: value})


def test_unknown_parameter_lists_the_valid_names() -> None:
    with pytest.raises(ParameterError, match="kicker_factor"):
        loopworks.create_block("deltav.stick_slip", kick_factor=1.0)


def test_parameter_names_in_any_letter_case() -> None:
    b = loopworks.create_block("deltav.stick_slip", KICKER_FACTOR=2.0, Process_Gain=3.0)
    assert b.params["kicker_factor"] == 2.0 and b.params["process_gain"] == 3.0


def test_float64_accepts_values_beyond_the_float32_range() -> None:
    b = loopworks.create_block("deltav.stick_slip", resolution=1e39, precision="float64")
    # (1e39 + 0.5·0)·1·0.5 = 5e38, kept as a double
    assert b.step(1.0)["dither_amp"].value == 5e38


def test_resume_from_saved_state_equals_uninterrupted_run() -> None:
    params: dict[str, Any] = {**SEED_68, "dither_half_period": 3, "deferred_param_reads": True}
    rng = np.random.default_rng(8)
    seq = [{"signal_in": float(rng.uniform(30, 50)), "sp": 50.0,
            "pv": float(rng.uniform(49, 51)), "comp_start": float(rng.random() < 0.9)}
           for _ in range(300)]
    whole = loopworks.create_block("deltav.stick_slip", **params)
    expected = [dict(whole.step(1.0, **inp)) for inp in seq]
    first = loopworks.create_block("deltav.stick_slip", **params)
    for inp in seq[:151]:  # an odd count: the resume lands mid half-period
        first.step(1.0, **inp)
    saved = json.loads(json.dumps(first.state_dict()))
    second = loopworks.create_block("deltav.stick_slip", **params)
    second.load_state(saved)
    assert [dict(second.step(1.0, **inp)) for inp in seq[151:]] == expected[151:]


def test_issue_11_point_8_initial_outputs() -> None:
    """issue 11 point 8: before the first scan signal_out passes signal_in through and the
    other outputs are the seed's defaults (spec 6.2: 0), Good; a module's SGGN1 running first
    reads DITHER_AMP 0 at scan 0 (spec 6.5)."""
    b = loopworks.create_block("deltav.stick_slip", **SEED_68)
    assert dict(b.outputs()) == {name: (0.0, GOOD) for name in b.outputs()}
    b.u[0] = 40.0  # a module that latched SIGNAL_IN before asking (the pass-through)
    assert b.initial_outputs()[0] == 40.0
    b.u[0] = 1e39  # not a float32 value: the start value, 0
    assert b.initial_outputs()[0] == 0.0


def test_resume_after_a_held_parameter_equals_uninterrupted_run() -> None:
    """A run saved after DITHER_DELT was held (Bad) resumes as the uninterrupted run; Bad
    while its assignment is not finite, Good again with the next finite one, and Good (its
    last value) in pass-through, where line 23 does not run."""
    seq = [{"signal_in": 40.0, "sp": 50.0, "pv": 50.0, "comp_start": 1.0, "dither_out": d}
           for d in (0.3, INF, INF, 1e39, -0.3)]
    seq += [{"signal_in": 40.0, "sp": 50.0, "pv": 50.0, "comp_start": 0.0, "dither_out": INF}]
    whole = loopworks.create_block("deltav.stick_slip", **SEED_68)
    expected = [dict(whole.step(1.0, **inp)) for inp in seq]
    first = loopworks.create_block("deltav.stick_slip", **SEED_68)
    for inp in seq[:2]:
        first.step(1.0, **inp)
    saved = json.loads(json.dumps(first.state_dict()))
    second = loopworks.create_block("deltav.stick_slip", **SEED_68)
    second.load_state(saved)
    assert [dict(second.step(1.0, **inp)) for inp in seq[2:]] == expected[2:]
    assert [e["dither_delt"].status for e in expected] == [GOOD, 0, 0, 0, GOOD, GOOD]
    assert [e["dither_delt"].value for e in expected] == [-A32] * 4 + [A32] * 2


def test_the_kernel_is_sound_by_itself_on_extreme_sequences() -> None:
    """issue 11 point 1: the kernel alone, without the numeric guard's undo-and-rerun (it sees
    the statuses the guard shows: a non-finite value is Bad), leaves no state non-finite and
    no output non-finite, on random sequences of NaN, ±inf, ±1e308, float32-overflowing and
    ordinary inputs with every option and parameters near the float32 limit."""
    rng = np.random.default_rng(77)
    specials = [NAN, INF, -INF, 1e308, -1e308, 3.5e38, -3.5e38, 3e38, 0.0, 1.0]
    for params in ({**SEED_68}, {**SEED_68, "precision": "float64", "deferred_param_reads": True},
                   {"resolution": 3e38, "deadband": 3e38, "process_gain": 1e30,
                    "kicker_factor": 3.0, "dither_half_period": 2},
                   {"resolution": 1e300, "precision": "float64", "cntrl_action": 1e10}):
        b = loopworks.create_block("deltav.stick_slip", jit=False, **params)
        for _ in range(3000):
            for i in range(len(b.INPUTS)):
                b.u[i] = float(rng.choice(specials)) if rng.random() < 0.3 else \
                    float(rng.uniform(-100, 200))
                b.us[i] = int(rng.choice([GOOD, 0, OOS, 0x40]))
            with np.errstate(all="ignore"):
                b.kernel(1.0, b.p, b.x, b.u, _marked_np(b.u, b.us), b.y, b.ys)
            assert np.isfinite(b.x).all(), b.state()
            assert np.isfinite(b.y).all(), b.y


def test_replay_cli_runs_the_docstring_example(tmp_path: Path) -> None:
    """The module docstring's replay example (spec 6.8 values, float64; status copy 6.3)."""
    path = write_csv(tmp_path / "comp.csv",
                     ["t", "signal_in", "sp", "pv", "comp_start", "dither_out", "signal_in.ST"],
                     [[0, 40, 50, 50.0, 1, 0.3, 128], [1, 40, 50, 50.5, 1, 0.3, 128],
                      [2, 40, 50, 49.5, 1, -0.3, 28], [3, 40, 50, 49.5, 0, 0.3, 128]])
    result = CliRunner().invoke(app, ["replay", "deltav.stick_slip", str(path),
                                      "-p", "resolution=0.5", "-p", "deadband=0.2",
                                      "-p", "precision=float64"])
    assert result.exit_code == 0, result.output
    rows = list(csv.reader(io.StringIO(result.stdout)))
    assert rows[0] == ["t", "signal_out", "dither_amp", "kicker_out", "noise_band",
                       "kicker_delt", "dither_delt", "signal_out.ST", "dither_amp.ST",
                       "kicker_out.ST", "noise_band.ST", "kicker_delt.ST", "dither_delt.ST"]
    assert {r[i] for r in rows[1:] for i in range(8, 13)} == {"128"}
    # band: 40 - 0.3; high: 40 - 0.3; band, kick held: 40 - 0.3 + 0.3; pass-through: 40
    assert [float(r[1]) for r in rows[1:]] == pytest.approx([39.7, 39.7, 40.0, 40.0])
    assert [float(r[5]) for r in rows[1:]] == pytest.approx([0.0, -0.3, -0.3, -0.3])
    assert [int(r[7]) for r in rows[1:]] == [GOOD, GOOD, OOS, GOOD]


def test_blocks_cli_documents_parameters_and_options() -> None:
    result = CliRunner().invoke(app, ["blocks", "deltav.stick_slip", "--markdown"])
    assert result.exit_code == 0, result.output
    for needle in ("| process_gain | %PV/%OUT | 2 |", "spec 6.4", "deferred_param_reads",
                   "Options for the spec's [A]/[?] points", "| dither_out | % | nan |"):
        assert needle in result.stdout
