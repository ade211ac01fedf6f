"""The DeltaV CALC block ``deltav.calc`` against spec vendor-blocks 6.1-6.8 and seed 000.

Expected values are the spec's (section 6.8 table and variants) or hand arithmetic written in
the test; float32 values are the float32 roundings of that arithmetic, worked out with numpy's
float32 beside the test. Behaviour tests run with the compiled and the interpreted kernel. The
equivalence tests run the seed's text against the native ``deltav.stick_slip`` on long random
input sequences and require bit-identical outputs.
"""

from __future__ import annotations

import csv
import io
import itertools
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
from loopworks.blocks.kernel import _marked_np, compiled, run_rows
from loopworks.cli import app
from loopworks.errors import ParameterError
from loopworks.sim.module import Module
from loopworks.sim.scenario import parse_scenario
from loopworks.vendors.deltav.calc import Calc
from loopworks.vendors.deltav.expression import SEED_EXPRESSION, ExpressionError
from tests.csvfiles import write_csv

NAN = math.nan
INF = math.inf
GOOD = 0x80  # Good non-cascade, 128
OOS = 0x1C  # Bad: out of service, 28 (spec 6.8 variants)


def f32(v: float) -> float:
    """The float32 rounding of v, as a float."""
    with np.errstate(over="ignore"):  # beyond the float32 range: inf
        return float(np.float32(v))


Make = Callable[..., Block]


@pytest.fixture(params=[True, False], ids=["compiled", "interpreted"])
def make(request: pytest.FixtureRequest) -> Make:
    """``make(**params)``: a deltav.calc block with the compiled or the interpreted kernel."""
    jit = request.param

    def _make(**params: Any) -> Block:
        return loopworks.create_block("deltav.calc", jit=jit, **params)

    return _make


# spec 6.8 setup: RESOLUTION 0.5, DEADBAND 0.2, factors 1, PROCESS_GAIN 2, CNTRL_ACTION -1,
# VALVE_ACTION +1, SP 50, SIGNAL_IN 40, INITIALIZE = KICK_START = 0, KICKER/DITHER_DELT 0.
SETUP: dict[str, Any] = {"resolution": 0.5, "deadband": 0.2, "sp": 50.0, "signal_in": 40.0}

# spec 6.8 table: (COMP_START, PV, DITHER_OUT) -> (KICKER_DELT, DITHER_DELT, SIGNAL_OUT)
TABLE = [
    ((1, 50.0, +0.3), (0.0, -0.3, 39.7)),   # 1 band
    ((1, 50.0, -0.3), (0.0, +0.3, 40.3)),   # 2 band
    ((1, 50.5, +0.3), (-0.3, 0.0, 39.7)),   # 3 high
    ((1, 50.2, +0.3), (-0.3, -0.3, 39.4)),  # 4 band, kick held
    ((1, 49.3, -0.3), (+0.3, 0.0, 40.3)),   # 5 low
    ((1, 49.5, -0.3), (+0.3, +0.3, 40.6)),  # 6 band, kick held
    ((0, 49.5, +0.3), (+0.3, +0.3, 40.0)),  # 7 pass-through, both stale
    ((1, 50.31, -0.3), (-0.3, 0.0, 39.7)),  # 8 high
]


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_spec_6_8_golden_step_through(make: Make, precision: str) -> None:
    """spec 6.8: the 8-scan table (derived DITHER_AMP = KICKER_OUT = 0.3, NOISE_BAND 0.6)."""
    block = make(precision=precision, **SETUP)
    tol = 1e-12 if precision == "float64" else 2e-6  # float32 storage: within 1 float32 ulp
    for (comp, pv, dither), (kick, dith, out) in TABLE:
        r = block.step(1.0, comp_start=float(comp), pv=pv, dither_out=dither)
        assert r["dither_amp"].value == pytest.approx(0.3, abs=tol)
        assert r["kicker_out"].value == pytest.approx(0.3, abs=tol)
        assert r["noise_band"].value == pytest.approx(0.6, abs=tol)
        assert r["kicker_delt"].value == pytest.approx(kick, abs=tol)
        assert r["dither_delt"].value == pytest.approx(dith, abs=tol)
        assert r["signal_out"].value == pytest.approx(out, abs=4 * tol)
        assert r["signal_out"].status == GOOD


def test_spec_6_8_row_1_in_float32_exactly(make: Make) -> None:
    # spec 6.1 [A]: every stored value is a float32. Line 2: (0.5 + 0.5·0.2)·1·0.5 = 0.3 in
    # float64, stored as float32(0.3); line 23: DITHER_DELT = f32(0.3·(-1)·1) = -f32(0.3);
    # line 26: SIGNAL_OUT = f32(40 + 0 - f32(0.3)) = f32(39.69999998807907) = 39.70000076...
    r = make(**SETUP).step(1.0, comp_start=1.0, pv=50.0, dither_out=0.3)
    assert r["dither_amp"].value == f32(0.3) == 0.30000001192092896
    assert r["noise_band"].value == f32(f32(0.3) * 2.0 * 1.0) == 0.6000000238418579
    assert r["dither_delt"].value == -f32(0.3)
    assert r["signal_out"].value == f32(40.0 - f32(0.3)) == 39.70000076293945


def test_spec_6_8_variant_initialize_and_kick_start(make: Make) -> None:
    """spec 6.8 variant: INITIALIZE = KICK_START = 1 gives NOISE_BAND 0: PV 50.1 high (39.7),
    49.9 low (40.3), exactly 50.0 the band (40 + held kick + dither)."""
    block = make(precision="float64", kick_start=1.0, initialize=1.0, comp_start=1.0, **SETUP)
    r = block.step(1.0, pv=50.1, dither_out=0.3)
    assert r["noise_band"].value == 0.0
    assert r["signal_out"].value == pytest.approx(39.7)
    assert block.step(1.0, pv=49.9, dither_out=0.3)["signal_out"].value == pytest.approx(40.3)
    r = block.step(1.0, pv=50.0, dither_out=-0.3)
    # 40 + 0.3 (kick of the low branch, held) + (-0.3)·(-1)·1
    assert r["kicker_delt"].value == pytest.approx(0.3)
    assert r["signal_out"].value == pytest.approx(40.6)


def test_spec_6_8_variant_parameter_list_defaults_pass_through(make: Make) -> None:
    """spec 6.8 variant: RESOLUTION = DEADBAND = 0: every amplitude is 0 and SIGNAL_OUT =
    SIGNAL_IN in every branch."""
    block = make(comp_start=1.0, sp=50.0)
    for pv, dither in ((50.0, 0.0), (55.0, 0.0), (45.0, 0.0), (50.0, 0.0)):
        r = block.step(1.0, pv=pv, signal_in=37.25, dither_out=dither)
        assert r["signal_out"].value == 37.25
        assert r["dither_amp"].value == r["kicker_out"].value == r["noise_band"].value == 0.0


@pytest.mark.parametrize("status", [GOOD, OOS, 0x40, 0xC0, 130, 0])
def test_spec_6_8_status_is_copied_in_every_row(make: Make, status: int) -> None:
    # spec 6.3 line 28, 6.8: SIGNAL_OUT.ST = SIGNAL_IN.ST in both branches; others Good (128)
    block = make(**SETUP)
    for (comp, pv, dither), _ in TABLE:
        r = block.step(1.0, comp_start=float(comp), pv=pv, dither_out=dither,
                       signal_in=(40.0, status))
        assert r["signal_out"].status == status
        assert {r[n].status for n in r if n != "signal_out"} == {GOOD}


def test_deferred_param_reads_move_lines_8_and_26_by_one_scan(make: Make) -> None:
    """spec 6.1 [A] switch: reads see the start-of-scan values. Hand, float64, SETUP, PV 50:
    scan 1: DITHER_AMP := 0.3, NOISE_BAND := (old DITHER_AMP 0)·2 = 0; PV 50 is not > 50 + 0
    and not < 50 - 0 (old NOISE_BAND 0): band, DITHER_DELT := 0.3·(-1) = -0.3; SIGNAL_OUT :=
    40 + old KICKER_DELT 0 + old DITHER_DELT 0 = 40. scan 2 (DITHER_OUT -0.3): NOISE_BAND :=
    0.6, DITHER_DELT := +0.3, SIGNAL_OUT := 40 + 0 + (-0.3) = 39.7. The immediate reading gives
    39.7 then 40.3."""
    late = make(precision="float64", deferred_param_reads=True, comp_start=1.0, **SETUP)
    now = make(precision="float64", comp_start=1.0, **SETUP)
    r1 = late.step(1.0, pv=50.0, dither_out=0.3)
    assert r1["noise_band"].value == 0.0
    assert r1["dither_delt"].value == pytest.approx(-0.3)
    assert r1["signal_out"].value == 40.0
    r2 = late.step(1.0, pv=50.0, dither_out=-0.3)
    assert r2["noise_band"].value == pytest.approx(0.6)
    assert r2["signal_out"].value == pytest.approx(39.7)
    assert now.step(1.0, pv=50.0, dither_out=0.3)["signal_out"].value == pytest.approx(39.7)
    assert now.step(1.0, pv=50.0, dither_out=-0.3)["signal_out"].value == pytest.approx(40.3)


def test_inputs_are_read_as_float32_module_parameters(make: Make) -> None:
    # spec 6.1 [A]: PV is a float32 module parameter. The upper trigger (line 15) is
    # 50 + f32(0.6)·0.5 = 50.30000001192093 in float32 mode, 50 + 0.6·0.5 = 50.3 in float64.
    # PV = 50.3000001 reads as f32(50.3000001) = 50.29999923706055 (below: band, no kick); in
    # float64 it is above 50.3 (high: kick -0.3). Hand: f32 spacing at 50 is 2**-18·8 = 3.8e-6.
    assert f32(50.3000001) == 50.29999923706055
    single = make(comp_start=1.0, **SETUP)
    double = make(precision="float64", comp_start=1.0, **SETUP)
    assert single.step(1.0, pv=50.3000001, dither_out=0.3)["kicker_delt"].value == 0.0
    assert double.step(1.0, pv=50.3000001, dither_out=0.3)["kicker_delt"].value == \
        pytest.approx(-0.3)


def test_held_kick_and_stale_dither_while_comp_start_is_0(make: Make) -> None:
    # spec 6.3 lines 11-12: KICKER_DELT and DITHER_DELT keep their values in pass-through and
    # come back on re-enable; inside the band KICKER_DELT is held (line 23)
    block = make(precision="float64", **SETUP)
    block.step(1.0, comp_start=1.0, pv=51.0, dither_out=0.3)  # high: kick -0.3
    for pv in (40.0, 60.0, 50.0):
        r = block.step(1.0, comp_start=0.0, pv=pv, dither_out=0.3)
        assert r["signal_out"].value == 40.0
        assert r["kicker_delt"].value == pytest.approx(-0.3)
        assert r["dither_delt"].value == 0.0
    r = block.step(1.0, comp_start=1.0, pv=50.0, dither_out=0.3)  # band: held kick + dither
    assert r["signal_out"].value == pytest.approx(40.0 - 0.3 - 0.3)


def test_no_clamp_on_signal_out(make: Make) -> None:
    # spec 6.3 line 26: SIGNAL_OUT may leave 0..100 %
    block = make(precision="float64", resolution=0.5, deadband=0.2, sp=50.0, comp_start=1.0)
    assert block.step(1.0, signal_in=100.0, pv=49.0, dither_out=0.3)["signal_out"].value == \
        pytest.approx(100.3)
    assert block.step(1.0, signal_in=0.0, pv=51.0, dither_out=0.3)["signal_out"].value == \
        pytest.approx(-0.3)


def test_nan_and_inf_inputs_follow_ieee_and_non_finite_results_hold_bad(make: Make) -> None:
    # spec 6.1: float values; NaN compares false: NaN PV is neither high nor low (band);
    # a NaN COMP_START is not 0 (compensate); NaN INITIALIZE is not 1 (band computed)
    block = make(precision="float64", comp_start=1.0, **SETUP)
    block.step(1.0, pv=51.0, dither_out=0.3)  # kick -0.3
    r = block.step(1.0, pv=NAN, dither_out=-0.3)
    assert r["kicker_delt"].value == pytest.approx(-0.3)  # held
    assert r["dither_delt"].value == pytest.approx(0.3)   # band
    r = block.step(1.0, pv=50.0, comp_start=NAN, initialize=NAN, dither_out=0.3)
    assert r["noise_band"].value == pytest.approx(0.6)
    assert r["signal_out"].value == pytest.approx(40.0 - 0.3 - 0.3)
    r = block.step(1.0, pv=INF, comp_start=1.0, initialize=0.0)
    assert r["kicker_delt"].value == pytest.approx(-0.3)  # inf > trigger: high
    assert r["signal_out"] == (pytest.approx(39.7), GOOD)
    # issue 11 point 1 (this test pinned a NaN / inf SIGNAL_OUT with Good status before): a
    # non-finite result is not stored; SIGNAL_OUT holds its last value, 39.7, with status Bad,
    # since SIGNAL_IN.ST reads Bad while SIGNAL_IN is not finite (line 28 passes it on)
    r = block.step(1.0, signal_in=NAN)
    assert (r["signal_out"].value, r["signal_out"].status) == (pytest.approx(39.7), 0)
    r = block.step(1.0, signal_in=INF, pv=49.0)  # low: kick +0.3; 40 + inf: held, Bad
    assert (r["signal_out"].value, r["signal_out"].status) == (pytest.approx(39.7), 0)
    assert r["kicker_delt"] == (pytest.approx(0.3), GOOD)
    r = block.step(1.0, signal_in=40.0, pv=49.0)  # good again: 40 + 0.3 + 0
    assert r["signal_out"] == (pytest.approx(40.3), GOOD)


@pytest.mark.parametrize("value", [NAN, INF, -INF, 1e308, -1e308, 3.5e38])
def test_issue_11_non_finite_or_float32_overflow_signal_in_is_bad(make: Make,
                                                                   value: float) -> None:
    # issue 11 point 1: NaN, ±inf and values beyond float32 (1e308, 3.5e38 read as ±inf in
    # float32 precision, spec 6.1 [A]) are Bad input. Line 12 (COMP_START 0) and line 26 give a
    # non-finite result: SIGNAL_OUT holds f32(40 - 0.3) = 39.70000076 (scan 1, band, dither
    # +0.3·-1), Bad; line 28 copies SIGNAL_IN.ST, which reads Bad (0) unless it arrives Bad
    # with a substatus (0x1C out of service is kept). No state is non-finite; good input again
    # gives the good answer at once.
    block = make(comp_start=1.0, **SETUP)
    held = block.step(1.0, pv=50.0, dither_out=0.3)["signal_out"].value
    assert held == f32(40.0 - f32(0.3))
    for comp in (1.0, 0.0):
        r = block.step(1.0, pv=50.0, dither_out=0.3, comp_start=comp, signal_in=value)
        assert r["signal_out"] == (held, 0)
        assert np.isfinite(block.x).all()
        r = block.step(1.0, pv=50.0, dither_out=0.3, comp_start=comp,
                       signal_in=(value, OOS))
        assert r["signal_out"] == (held, OOS)
    r = block.step(1.0, pv=50.0, dither_out=-0.3, comp_start=1.0, signal_in=40.0)
    assert r["signal_out"] == (f32(40.0 + f32(0.3)), GOOD)


@pytest.mark.parametrize("value", [INF, -INF, 1e308, 3.5e38])
def test_issue_11_extreme_dither_out_holds_dither_delt_bad(make: Make, value: float) -> None:
    # issue 11 point 1: line 23 DITHER_DELT := DITHER_OUT·-1·1 is not finite (float32: 1e308
    # and 3.5e38 read as ±inf): DITHER_DELT holds f32(-0.3·-1)... = its last value, Bad; line
    # 26 adds the held value (40 + 0 + f32(0.3)) and SIGNAL_OUT keeps SIGNAL_IN's status Good;
    # the next finite DITHER_OUT stores again (Good).
    block = make(comp_start=1.0, **SETUP)
    block.step(1.0, pv=50.0, dither_out=-0.3)  # DITHER_DELT = +f32(0.3)
    r = block.step(1.0, pv=50.0, dither_out=value)
    assert r["dither_delt"] == (f32(0.3), 0)
    assert r["signal_out"] == (f32(40.0 + f32(0.3)), GOOD)
    r = block.step(1.0, pv=50.0, dither_out=0.3)
    assert r["dither_delt"] == (-f32(0.3), GOOD)


def test_issue_11_an_overflowing_result_holds_bad_for_its_scan(make: Make) -> None:
    # issue 11 point 1: 3e38 + 3e38 = 6e38 is beyond float32 (spec 6.1 [A]): not stored, Y
    # holds 1, Bad (the assigned Good .ST does not hide it), and reading Y.ST in that scan gives
    # the Bad status (Z := Y.ST); a later scan whose IF does not assign Y shows its last value
    # with its .ST, as any parameter a scan leaves alone; the next finite result stores again.
    text = ("IF '^/A' > -1 THEN '^/Y' := '^/A' + '^/A' END_IF; '^/Y.ST' := 130; "
            "'^/Z' := '^/Y.ST';")
    block = make(expression=text, a=0.0)
    assert block.step(1.0, a=0.5)["y"] == (1.0, 130)
    r = block.step(1.0, a=3e38)
    assert r["y"] == (1.0, 0) and r["z"] == (0.0, GOOD)
    r = block.step(1.0, a=-5.0)  # Y not assigned
    assert r["y"] == (1.0, 130) and r["z"] == (130.0, GOOD)
    r = block.step(1.0, a=2.0)
    assert r["y"] == (4.0, 130)
    # a later finite assignment in the same scan stores (not held any more)
    again = make(expression="'^/Y' := '^/A' * 2; '^/Y' := 7; '^/Z' := '^/Y.ST';", a=0.0)
    assert again.step(1.0, a=3e38)["y"] == (7.0, GOOD)
    assert again.step(1.0, a=3e38)["z"] == (GOOD, GOOD)
    # float64 precision: 6e38 is a double, stored
    double = make(expression=text, a=0.0, precision="float64")
    assert double.step(1.0, a=3e38)["y"] == (6e38, 130)


def test_issue_11_an_input_beyond_float32_reads_bad_status(make: Make) -> None:
    # issue 11 point 1: in float32 precision 1e39 reads as inf (spec 6.1 [A]) and its .ST as
    # Bad (0); a Bad status that arrives keeps its substatus; in float64 it is a usable value
    text = "'^/S' := '^/A.ST'; '^/V' := '^/A' > 1;"
    block = make(expression=text, a=0.0)
    assert block.step(1.0, a=1e39)["s"].value == 0.0
    assert block.step(1.0, a=1e39)["v"] == (1.0, GOOD)  # inf > 1 (IEEE)
    assert block.step(1.0, a=(1e39, OOS))["s"].value == OOS
    assert block.step(1.0, a=3e38)["s"].value == GOOD
    double = make(expression=text, a=0.0, precision="float64")
    assert double.step(1.0, a=1e39)["s"].value == GOOD


def test_issue_11_point_8_outputs_show_their_initial_values_before_the_first_scan(
        make: Make) -> None:
    # issue 11 point 8: before the first scan an output shows its initial value (float32 as
    # stored), Good, not 0
    block = make(expression="'^/N' := '^/N' + '^/A';", n=10.1, a=1.0)
    assert block.outputs()["n"] == (f32(10.1), GOOD)
    block.step(1.0)
    block.reset()
    assert block.outputs()["n"] == (f32(10.1), GOOD)
    seed = make(signal_out=40.0, kicker_delt=-0.3, precision="float64")
    assert seed.outputs()["signal_out"] == (40.0, GOOD)
    assert seed.outputs()["kicker_delt"] == (-0.3, GOOD)


@pytest.mark.parametrize("name", ["n", "a"])
def test_initial_values_beyond_float32_are_refused(name: str) -> None:
    # spec 6.1 [A]: a float32 module parameter cannot hold 1e39 (it would read as inf)
    with pytest.raises(ParameterError, match=rf"parameter '{name}' = 1e\+39 is out of range"):
        loopworks.create_block("deltav.calc", expression="'^/N' := '^/A';",
                               **{"n": 0.0, "a": 0.0, name: 1e39})
    block = loopworks.create_block("deltav.calc", expression="'^/N' := '^/A';",
                                   precision="float64", **{"n": 0.0, "a": 0.0, name: 1e39})
    assert block.outputs()["n"].value == (1e39 if name == "n" else 0.0)
    assert block.step(1.0)["n"].value == (0.0 if name == "n" else 1e39)


def test_status_fields_of_a_custom_text(make: Make) -> None:
    # spec 6.1: .ST is the status, an integer; an assigned value becomes a byte (truncated,
    # 0..255, NaN -> 0) [A]; an unassigned output status is Good (128); an assignment holds
    text = """IF '^/A' > -100 THEN '^/Y.ST' := '^/A' END_IF;
'^/Y' := '^/Y.ST' + '^/B.ST';
'^/Z' := 1;"""
    block = make(expression=text, a=0.0, b=0.0)
    y_port = next(p for p in block.OUTPUTS if p.name == "y")
    b_port = next(p for p in block.INPUTS if p.name == "b")
    assert y_port.status and b_port.status
    for a, st in ((12.7, 12), (300.0, 255), (-1.0, 0), (NAN, 0), (0x1C, 0x1C), (-500.0, 0x1C)):
        r = block.step(1.0, a=a, b=(0.0, 0x40))
        assert r["y"].status == st
        assert r["y"].value == st + 0x40  # reads see the stored status
        assert r["z"].status == GOOD


def test_outputs_persist_and_take_initial_values(make: Make) -> None:
    # an assigned parameter keeps its value between scans (module parameter), starting from
    # its initial value; in float32 precision the initial value is stored as a float32
    block = make(expression="'^/N' := '^/N' + 1;", n=10.0)
    assert [block.step(1.0)["n"].value for _ in range(3)] == [11.0, 12.0, 13.0]
    block = make(expression="'^/N' := '^/N' + 1;", n=0.1)
    assert block.step(1.0)["n"].value == f32(f32(0.1) + 1.0) == 1.100000023841858
    block = make(expression="'^/N' := '^/N' + 1;", n=0.1, precision="float64")
    assert block.step(1.0)["n"].value == 0.1 + 1.0


def test_ports_follow_the_expression() -> None:
    block = loopworks.create_block("deltav.calc", expression="'^/Q' := 2 * '^/P';", p=1.5)
    assert [p.name for p in block.INPUTS] == ["p"]
    assert [p.name for p in block.OUTPUTS] == ["q"]
    assert not block.INPUTS[0].status and block.OUTPUTS[0].status  # every output can be Bad
    assert block.step(1.0)["q"].value == 3.0  # the initial value is the input's default
    assert block.step(1.0, p=4.0)["q"].value == 8.0
    # the class keeps the seed's declarations (for the reference page)
    assert [p.name for p in Calc.OUTPUTS] == ["dither_amp", "kicker_out", "noise_band",
                                               "signal_out", "kicker_delt", "dither_delt"]


# -- construction checks ---------------------------------------------------------------------


def test_reading_an_unknown_parameter_is_an_error_before_the_first_scan() -> None:
    # issue: "a reference to an unknown parameter is an error before the first scan"
    lines = SEED_EXPRESSION.split("\n")
    assert lines[11] == "'^/SIGNAL_OUT' := '^/SIGNAL_IN'"
    lines[11] = "'^/SIGNAL_OUT' := '^/SIGNL_IN'"
    with pytest.raises(ExpressionError) as info:
        loopworks.create_block("deltav.calc", expression="\n".join(lines))
    message = str(info.value)
    assert message.startswith("deltav.calc: expression, line 12, column 19: '^/SIGNL_IN' is "
                              "not a known module parameter")
    assert "signl_in=0.0" in message
    assert isinstance(info.value, ParameterError)
    # declared by an initial value, it is an input
    block = loopworks.create_block("deltav.calc", expression="\n".join(lines), signl_in=5.0)
    assert "signl_in" in block._in_index and "signal_in" in block._in_index


def test_an_initial_value_for_an_unreferenced_name_lists_the_referenced_names() -> None:
    with pytest.raises(ParameterError) as info:
        loopworks.create_block("deltav.calc", reset_time=8.0)
    message = str(info.value)
    assert "unknown parameter 'reset_time'" in message
    for name in ("signal_in", "signal_out", "dither_out", "comp_start", "kicker_delt"):
        assert name in message
    with pytest.raises(ParameterError, match=r"references \(y, a\)"):
        loopworks.create_block("deltav.calc", expression="'^/Y' := '^/A'", a=1.0, b=2.0)


@pytest.mark.parametrize("name", ["PRECISION", "expression", "JIT", "t", "DT"])
def test_module_parameters_may_not_take_reserved_names(name: str) -> None:
    with pytest.raises(ExpressionError, match=rf"line 1, column 10: module parameter "
                                              rf"'\^/{name}' has the name"):
        loopworks.create_block("deltav.calc", expression=f"'^/Y' := '^/{name}';")


@pytest.mark.parametrize(("params", "needle"), [
    ({"precision": "float16"}, "'precision' = 'float16' is not allowed"),
    ({"divide_by_zero": "zero"}, "'divide_by_zero' = 'zero' is not allowed"),
    ({"deferred_param_reads": "maybe"}, "'deferred_param_reads' = 'maybe' must be true or"),
    ({"cntrl_action": "reverse"}, "'cntrl_action' = 'reverse' must be a number"),
    ({"sp": NAN}, "'sp' = nan is out of range"),
])
def test_bad_parameters_name_the_parameter(params: dict[str, Any], needle: str) -> None:
    with pytest.raises(ParameterError, match=needle):
        loopworks.create_block("deltav.calc", **params)


def test_parameter_names_in_any_letter_case() -> None:
    block = loopworks.create_block("deltav.calc", RESOLUTION=0.5, Deadband=0.2,
                                   PRECISION="float64")
    assert block.step(1.0)["dither_amp"].value == pytest.approx(0.3)


# -- the native block: bit for bit ------------------------------------------------------------

NATIVE = "deltav.stick_slip"
SEED_NAMES = ("resolution", "deadband", "process_gain", "cntrl_action", "valve_action",
              "dither_factor", "kicker_factor", "noise_factor", "kick_start")
OPTIONS = list(itertools.product(["float32", "float64"], [False, True]))


def random_params(rng: np.random.Generator) -> dict[str, float]:
    """The seed's module parameters, random (exact 0/1 and ±1 where the text compares)."""
    return {
        "resolution": float(rng.choice([0.0, 0.5, rng.uniform(0.0, 2.0)])),
        "deadband": float(rng.choice([0.0, 0.2, rng.uniform(0.0, 1.0)])),
        "process_gain": float(rng.uniform(0.2, 4.0)),
        "cntrl_action": float(rng.choice([-1.0, 1.0])),
        "valve_action": float(rng.choice([-1.0, 1.0])),
        "dither_factor": float(rng.uniform(0.3, 3.0)),
        "kicker_factor": float(rng.uniform(0.3, 3.0)),
        "noise_factor": float(rng.uniform(0.3, 3.0)),
        "kick_start": float(rng.choice([0.0, 1.0])),
    }


EXTREMES = np.array([NAN, INF, -INF, 1e308, -1e308, 3.5e38, -3.5e38, 3e38, -3e38, 5e-324])


def random_rows(rng: np.random.Generator, n: int, extreme: float = 0.0) -> dict[str,
                                                                              np.ndarray]:
    """Inputs for n scans: PV around SP (often inside the band, sometimes exactly at SP),
    COMP_START and INITIALIZE mostly 0/1, finite DITHER_OUT (the native block's NaN = internal
    dither has no counterpart in the text), occasional NaN/inf, random SIGNAL_IN statuses. With
    ``extreme`` > 0 every input is, with that probability, one of NaN, ±inf, ±1e308, beyond or
    near the float32 range, or subnormal (DITHER_OUT: anything but NaN)."""
    sp = np.where(rng.random(n) < 0.9, 50.0, rng.uniform(0.0, 100.0, n))
    pv = sp + rng.normal(0.0, 1.0, n) * rng.choice([0.3, 1.0, 10.0], n)
    at_sp = rng.random(n) < 0.05
    pv[at_sp] = sp[at_sp]
    pv[rng.random(n) < 0.01] = NAN
    pv[rng.random(n) < 0.005] = INF
    signal_in = rng.uniform(-10.0, 110.0, n)
    signal_in[rng.random(n) < 0.01] = NAN
    signal_in[rng.random(n) < 0.005] = -INF
    comp = rng.choice([0.0, 1.0, 1.0, 1.0, 1.0, 0.5, NAN], n)
    init = rng.choice([0.0, 0.0, 1.0, 1.0, 1.0000001, NAN], n)
    amp = rng.choice([0.3, 0.25, 1.7], n)
    dither = np.where(rng.random(n) < 0.8, amp * rng.choice([-1.0, 1.0], n),
                      rng.uniform(-3.0, 3.0, n))
    rows = {"signal_in": signal_in, "sp": sp, "pv": pv, "comp_start": comp, "initialize": init,
            "dither_out": dither}
    for name, column in rows.items():
        hit = rng.random(n) < extreme
        pool = EXTREMES[1:] if name == "dither_out" else EXTREMES
        column[hit] = rng.choice(pool, int(hit.sum()))
    status = rng.choice([GOOD, GOOD, 0, OOS, 0x40, 0x47, 0xC0, 130, 255], n)
    return rows | {"signal_in.ST": status}


def _arrays(block: Block, rows: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    n = len(rows["pv"])
    U = np.empty((n, len(block.INPUTS)))
    US = np.full((n, len(block.INPUTS)), GOOD, dtype=np.int64)
    for i, port in enumerate(block.INPUTS):
        U[:, i] = rows.get(port.name, port.default)
        if port.name + ".ST" in rows:
            US[:, i] = rows[port.name + ".ST"]
    return U, US


def run_kernel(block: Block, rows: dict[str, np.ndarray], jit: bool) -> tuple[np.ndarray,
                                                                            np.ndarray]:
    """Run the rows through the block's kernel (the replay path); outputs by port order."""
    U, US = _arrays(block, rows)
    n = len(U)
    Y = np.empty((n, len(block.OUTPUTS)))
    YS = np.empty((n, len(block.OUTPUTS)), dtype=np.int64)
    Y[0], YS[0] = block.y, block.ys
    run_rows(type(block).kernel, np.ones(n), block.p, block.x, U, US, Y, YS, jit=jit)
    return Y, YS


def run_alone(block: Block, rows: dict[str, np.ndarray], jit: bool) -> tuple[np.ndarray,
                                                                           np.ndarray]:
    """The same rows through the bare kernel, without the numeric guard's undo-and-rerun
    (issue 11 point 1: kernels are sound by themselves): the kernel sees the statuses the
    guard shows it (a non-finite value is Bad), and every scan must leave every state finite
    and every output finite or Bad. Works on copies: ``block`` is not changed."""
    kernel = compiled(type(block).kernel) if jit else type(block).kernel
    U, US = _arrays(block, rows)
    x, y, ys = block.x.copy(), block.y.copy(), block.ys.copy()
    Y = np.empty((len(U), len(y)))
    YS = np.empty((len(U), len(y)), dtype=np.int64)
    with np.errstate(all="ignore"):
        for k in range(len(U)):
            kernel(1.0, block.p, x, U[k], _marked_np(U[k], US[k]), y, ys)
            assert np.isfinite(x).all(), (k, dict(zip(block.STATES, x, strict=True)))
            assert (np.isfinite(y) | (ys & 0xC0 == 0)).all(), (k, y, ys)
            Y[k], YS[k] = y, ys
    return Y, YS


def assert_identical(a: Block, ya: tuple[np.ndarray, np.ndarray], b: Block,
                     yb: tuple[np.ndarray, np.ndarray]) -> None:
    """Every output of ``a`` equals the same-named output of ``b`` bit for bit (any NaN
    equals any NaN), status included."""
    names = [p.name for p in a.OUTPUTS]
    assert sorted(names) == sorted(p.name for p in b.OUTPUTS)
    for i, name in enumerate(names):
        j = b._out_index[name]
        va, vb = ya[0][:, i], yb[0][:, j]
        same = (va.view(np.int64) == vb.view(np.int64)) | (np.isnan(va) & np.isnan(vb))
        bad = np.flatnonzero(~same)
        assert bad.size == 0, (f"{name}: first difference at scan {bad[0]}: "
                               f"{va[bad[0]]!r} vs {vb[bad[0]]!r}")
        np.testing.assert_array_equal(ya[1][:, i], yb[1][:, j], err_msg=f"{name}.ST")


@pytest.mark.parametrize(("precision", "deferred"), OPTIONS)
def test_seed_text_equals_native_stick_slip_bit_for_bit(precision: str, deferred: bool) -> None:
    """The seed's 28 lines run as text give exactly the outputs of deltav.stick_slip
    (deltav_common interface; spec 6.1-6.3), on 200,000 random scans per option setting, a
    quarter of them with extreme inputs (NaN, ±inf, ±1e308, beyond float32: issue 11 point 1,
    the same rule in both). Both kernels are sound by themselves: on the extreme sequence they
    give the same outputs without the numeric guard."""
    rng = np.random.default_rng(2024 + 2 * OPTIONS.index((precision, deferred)))
    single = precision == "float32"
    for extreme in (0.0, 0.0, 0.0, 0.05):
        params = random_params(rng)
        opts = {"precision": precision, "deferred_param_reads": deferred}
        native = loopworks.create_block(NATIVE, **params, **opts)
        text = loopworks.create_block("deltav.calc", **params, **opts)
        rows = random_rows(rng, 50_000, extreme)
        alone = (run_alone(text, rows, jit=True), run_alone(native, rows, jit=True)) \
            if extreme else None
        got = run_kernel(text, rows, jit=True)
        assert_identical(text, got, native, run_kernel(native, rows, jit=True))
        if alone is not None:
            assert_identical(text, got, text, alone[0])
            assert_identical(native, alone[1], text, got)
        # every branch ran: kicks both ways, dither, pass-through
        kick = got[0][:, text._out_index["kicker_delt"]]
        dither = got[0][:, text._out_index["dither_delt"]]
        if params["resolution"] + params["deadband"] > 0.0:
            assert (kick > 0).any() and (kick < 0).any() and (dither != 0).any()
        with np.errstate(over="ignore"):
            stored = rows["signal_in"].astype(np.float32).astype(float) if single else \
                rows["signal_in"]
        assert (got[0][:, text._out_index["signal_out"]] == stored).any()
        # issue 11 point 1: non-finite values came in, none came out (held outputs are Bad)
        assert np.isfinite(got[0]).all()
        assert (got[1][:, text._out_index["signal_out"]] == 0).any()


@pytest.mark.parametrize(("precision", "deferred"), OPTIONS)
def test_seed_text_equals_native_with_parameters_near_the_float32_limit(
        precision: str, deferred: bool) -> None:
    """Parameters near the float32 maximum make lines 2, 3, 8, 16, 20, 23 and 26 overflow the
    float32 store (spec 6.1 [A]): the text and the native block hold the same parameters, Bad,
    bit for bit, and stay sound without the guard (issue 11 point 1)."""
    rng = np.random.default_rng(99 + OPTIONS.index((precision, deferred)))
    for _ in range(3):
        params = random_params(rng) | {
            "resolution": float(rng.choice([3e38, 1e38, 0.5])),
            "deadband": float(rng.choice([3e38, 0.2])),
            "process_gain": float(rng.choice([1e30, 2.0])),
            "cntrl_action": float(rng.choice([-1.0, 3e38])),
            "dither_factor": float(rng.choice([1.0, 2.5])),
        }
        opts = {"precision": precision, "deferred_param_reads": deferred}
        native = loopworks.create_block(NATIVE, **params, **opts)
        text = loopworks.create_block("deltav.calc", **params, **opts)
        rows = random_rows(rng, 20_000, 0.05)
        alone = run_alone(text, rows, jit=True)
        got = run_kernel(text, rows, jit=True)
        assert_identical(text, got, native, run_kernel(native, rows, jit=True))
        assert_identical(text, got, text, alone)
        assert np.isfinite(got[0]).all()


@pytest.mark.parametrize(("precision", "deferred"), OPTIONS)
def test_seed_text_equals_native_through_the_block_api(precision: str, deferred: bool) -> None:
    """The same through step(), with the interpreted text kernel and random statuses."""
    rng = np.random.default_rng(7 + OPTIONS.index((precision, deferred)))
    params = random_params(rng) | {"resolution": 0.5, "deadband": 0.2}
    opts = {"precision": precision, "deferred_param_reads": deferred}
    native = loopworks.create_block(NATIVE, **params, **opts)
    text = loopworks.create_block("deltav.calc", jit=False, **params, **opts)
    rows = random_rows(rng, 3000)
    for k in range(3000):
        inputs: dict[str, Any] = {n: float(v[k]) for n, v in rows.items() if "." not in n}
        inputs["signal_in"] = (inputs["signal_in"], int(rows["signal_in.ST"][k]))
        ra, rb = text.step(1.0, **inputs), native.step(1.0, **inputs)
        for name in ra:
            va, vb = ra[name].value, rb[name].value
            assert va == vb or (math.isnan(va) and math.isnan(vb)), (k, name, va, vb)
            assert math.copysign(1.0, va) == math.copysign(1.0, vb) or math.isnan(va)
            assert ra[name].status == rb[name].status, (k, name)


@pytest.mark.parametrize(("upper", "lower"), [(1.0, 1.0), (0.5, 0.5), (0.25, 2.0)])
def test_edited_band_factors_equal_the_native_options(upper: float, lower: float) -> None:
    """spec 6.4 [A]: the native upper/lower_band_factor options are the literals of lines 15
    and 19; an edited text gives the same outputs. An edited text declares its own inputs."""
    lines = SEED_EXPRESSION.split("\n")
    lines[14] = lines[14].replace("'^/NOISE_BAND'*0.5", f"'^/NOISE_BAND'*{upper}")
    lines[18] = lines[18].replace("'^/NOISE_BAND'", f"'^/NOISE_BAND'*{lower}")
    assert f"*{upper}))" in lines[14] and f"*{lower}))" in lines[18]
    rng = np.random.default_rng(11)
    params = random_params(rng)
    native = loopworks.create_block(NATIVE, upper_band_factor=upper, lower_band_factor=lower,
                                    **params)
    text = loopworks.create_block("deltav.calc", expression="\n".join(lines), **params)
    rows = random_rows(rng, 50_000)
    assert_identical(text, run_kernel(text, rows, jit=True),
                     native, run_kernel(native, rows, jit=True))


def test_seed_module_sggn1_then_calc_equals_the_native_internal_dither() -> None:
    """spec 6.5 [A]: SGGN1 (#3) square wave of last scan's DITHER_AMP, alternating every
    scan, then the CALC (#4); the native block's internal dither (dither_out NaN) is the same
    reading, so the outputs agree (as values: the sign of a zero dither may differ)."""
    params = {"resolution": 0.5, "deadband": 0.2}
    module = Module({"sggn1": loopworks.create_block("deltav.sggn", period=2.0),
                     "comp": loopworks.create_block("deltav.calc", **params)},
                    wires={"sggn1.amplitude": "comp.dither_amp", "comp.dither_out": "sggn1.out"})
    native = loopworks.create_block(NATIVE, **params)
    rng = np.random.default_rng(5)
    for _ in range(2000):
        inputs = {"signal_in": float(rng.uniform(0, 100)), "sp": 50.0,
                  "pv": float(50.0 + rng.normal(0.0, 0.5)), "comp_start": 1.0,
                  "initialize": float(rng.random() < 0.1)}
        module.blocks["comp"].set_inputs(inputs)
        module.scan(1.0)
        expected = native.step(1.0, **inputs)
        comp = module.blocks["comp"]
        for name in expected:
            assert comp.y[comp._out_index[name]] == expected[name].value, name


# -- compiled and interpreted, resume, replay, scenario, docs ----------------------------------


def test_resume_from_saved_state_equals_uninterrupted_run(make: Make) -> None:
    text = "'^/N' := '^/N' + '^/A'; IF '^/N' > 5 THEN '^/N.ST' := 28 END_IF;"
    whole = make(expression=text, a=1.0)
    first = make(expression=text, a=1.0)
    steps = [float(a) for a in (1, 2, 0.5, 3, -1, 2, 2, 0.25)]
    expected = [dict(whole.step(1.0, a=a)) for a in steps]
    for a in steps[:4]:
        first.step(1.0, a=a)
    saved = json.loads(json.dumps(first.state_dict()))
    resumed = loopworks.create_block(saved["kind"], **saved["params"])
    resumed.load_state(saved)
    got = [dict(resumed.step(1.0, a=a)) for a in steps[4:]]
    assert got == expected[4:]
    assert expected[-1]["n"].value == 9.75 and expected[-1]["n"].status == 28


def test_replay_cli_runs_the_seed_text(tmp_path: Path) -> None:
    # the module docstring's example; spec 6.8 rows 1-3 in float64, statuses copied (6.3)
    path = write_csv(tmp_path / "comp.csv", ["t", "pv", "dither_out", "signal_in",
                                             "signal_in.ST"],
                     [[0, 50.0, 0.3, 40.0, 128], [1, 50.0, -0.3, 40.0, 128],
                      [2, 50.5, 0.3, 40.0, 28]])
    result = CliRunner().invoke(app, ["replay", "deltav.calc", str(path), "-p", "resolution=0.5",
                                      "-p", "deadband=0.2", "-p", "sp=50", "-p", "comp_start=1",
                                      "-p", "precision=float64"])
    assert result.exit_code == 0, result.output
    rows = list(csv.DictReader(io.StringIO(result.stdout)))
    assert [float(r["signal_out"]) for r in rows] == pytest.approx([39.7, 40.3, 39.7])
    assert [float(r["kicker_delt"]) for r in rows] == pytest.approx([0.0, 0.0, -0.3])
    assert [int(r["signal_out.ST"]) for r in rows] == [128, 128, 28]


def test_replay_cli_with_an_expression_parameter(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "in.csv", ["t", "A"], [[0, 1.0], [1, 4.0]])
    result = CliRunner().invoke(app, ["replay", "deltav.calc", str(path), "-p",
                                      "expression='^/Y' := '^/A' * '^/A' + '^/K';", "-p", "a=0",
                                      "-p", "k=0.5"])
    assert result.exit_code == 0, result.output
    assert result.stdout.splitlines() == ["t,y,y.ST", "0.0,1.5,128", "1.0,16.5,128"]
    bad = CliRunner().invoke(app, ["replay", "deltav.calc", str(path), "-p",
                                   "expression='^/Y' := ('^/A';", "-p", "a=0"])
    assert bad.exit_code == 2
    assert "expression, line 1, column 16: expected ')' but found ';'" in bad.output


def test_scenario_table_keys_are_parameters() -> None:
    # split_table: initial values of inputs are parameters, so a wired input may be declared
    assert Calc.split_table({"sp": 50.0, "precision": "float64"}) == \
        ({"sp": 50.0, "precision": "float64"}, {})
    text = '''
[simulation]
dt = 1.0
duration = 3.0

[blocks.src]
kind = "process.first_order"
time_constant = 0.0

[blocks.calc]
kind = "deltav.calc"
expression = "'^/OUT' := 2 * '^/X' + '^/OFFSET';"
x = 0.0
offset = 1.5

[wires]
"calc.x" = "src.y"
'''
    sc = parse_scenario(text)
    sc.module.blocks["src"].set_inputs({"u": 3.0})
    result = sc.module.run(sc.duration, sc.dt, reset=False)
    assert result["calc.out"][-1] == 2 * 3.0 + 1.5


def test_reference_page_names_the_options_and_sources() -> None:
    result = CliRunner().invoke(app, ["blocks", "deltav.calc", "--markdown"])
    assert result.exit_code == 0, result.output
    for needle in ("Options for the spec's [A]/[?] points", "deferred_param_reads",
                   "| precision |", "| cntrl_action |", "spec 6.1", "3.402823466e+38",
                   "'^/SIGNAL_OUT.ST' := '^/SIGNAL_IN.ST';"):
        assert needle in result.stdout
