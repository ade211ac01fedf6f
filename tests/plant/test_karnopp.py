"""``valve.karnopp`` against plant-and-tuning.md 1.1, 1.6, 1.7 and 2.2 ("spec" below).

Expected values are hand calculations written in the tests: static force balances, the exact
solution of the linear second-order stem, the half swing of an undamped stem with Coulomb
friction, the square-wave response of the I/P lag. Golden tests run with the compiled and the
interpreted kernel (``make``).
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
from loopworks.blocks.block import Block
from loopworks.cli import app
from loopworks.errors import ParameterError
from loopworks.plant import karnopp
from tests.csvfiles import write_csv
from tests.plant.numeric import EXTREMES, kernel_scan, unsound

NAN = math.nan
Make = Callable[..., Block]

# the spec 1.6 real valve (run_models.cpp PARAM_VALVULA / PARAM_ATRITO_KARNOPP)
M, K, SA, F0 = 1.6, 210490.0, 0.0445, 2550.0
TRAVEL, P_MIN, P_MAX = 0.029, 41368.0, 180000.0
FC, FS, FV, VS = 700.0, 780.0, 125000.0, 5e-4
DP = P_MAX - P_MIN
U = SA * DP / 100.0           # N of actuator force per % of op: 61.69124


@pytest.fixture(params=[True, False], ids=["compiled", "interpreted"])
def make(request: pytest.FixtureRequest) -> Make:
    jit = request.param

    def _make(**params: Any) -> Block:
        return loopworks.create_block("valve.karnopp", jit=jit, **params)

    return _make


def pos_eq(op: float, f_init: float = F0) -> float:
    """Frictionless equilibrium position (% of travel): k·x = Sa·P - F_init."""
    return 100.0 * ((SA * (P_MIN + DP * op / 100.0) - f_init) / K) / TRAVEL


def pct(force: float) -> float:
    """Stem travel (% of travel) that the spring takes up for ``force`` newtons."""
    return 100.0 * force / K / TRAVEL


def hold_op(block: Block, op: float, seconds: float, dt: float = 0.1) -> float:
    value = NAN
    for _ in range(round(seconds / dt)):
        value = block.step(dt, op=op)["position"].value
    return value


# -- spec 1.6 parameter set, spec 1.1 mappings ----------------------------------------------------


def test_1_6_defaults_are_the_specs_real_valve() -> None:
    """spec 1.6 [S]: m = 1.6 kg, k = 210 490 N/m, Sa = 0.0445 m², F_init = 2550 N, travel
    0-29 mm, P = 41.4-180 kPa, Fc = 700 N, Fs = 780 N, Fv = 125 000 N·s/m, vs = 5e-4 m/s,
    tau_ip = 3.57 s (the source's exact 41368 Pa and 1/0.28 s)."""
    v = loopworks.create_block("valve.karnopp")
    prm = v.params
    assert (prm["m"], prm["k"], prm["sa"], prm["f_init"]) == (M, K, SA, F0)
    assert (prm["x_min"], prm["x_max"], prm["p_max"]) == (0.0, TRAVEL, P_MAX)
    assert prm["p_min"] == pytest.approx(41.4e3, abs=50.0)
    assert (prm["f_v"], prm["v_s"]) == (FV, VS)
    assert prm["tau_ip"] == pytest.approx(3.57, abs=0.005)
    assert (v.p[karnopp.P.f_s], v.p[karnopp.P.f_c]) == (FS, FC)


def test_1_1_valve_estimation_mapping_gives_the_specs_pair() -> None:
    """spec 1.1 [S, arithmetic V]: S = 2·Fs/(Sa·Δp), J = (Fs - Fc)/(Sa·Δp): Fs = 780 N,
    Fc = 700 N give S = 25.287 %, J = 1.2968 % (with Δp = 180 000 - 41 368 Pa)."""
    s, j = karnopp.sj_from_forces(FS, FC, SA, DP, "valve_estimation")
    assert s == pytest.approx(25.287, abs=5e-4)
    assert j == pytest.approx(1.2968, abs=5e-5)
    assert karnopp.forces_from_sj(s, j, SA, DP, "valve_estimation") == pytest.approx((FS, FC))


def test_1_1_force_balance_mapping() -> None:
    """spec 1.1 [I]: S = 100(Fs + Fc)/(Sa·Δp) = 1480/61.69124 = 23.9905 %,
    J = 100(Fs - Fc)/(Sa·Δp) = 80/61.69124 = 1.29678 %; the two mappings differ by
    (Fs - Fc)/U in S only."""
    s, j = karnopp.sj_from_forces(FS, FC, SA, DP)
    assert s == pytest.approx(1480.0 / U) and s == pytest.approx(23.9905, abs=1e-4)
    assert j == pytest.approx(80.0 / U) and j == pytest.approx(1.29678, abs=1e-5)
    s2, _ = karnopp.sj_from_forces(FS, FC, SA, DP, "valve_estimation")
    assert s2 - s == pytest.approx((FS - FC) / U)
    assert karnopp.forces_from_sj(s, j, SA, DP) == pytest.approx((FS, FC))


@pytest.mark.parametrize(("params", "f_s", "f_c"), [
    ({"s": 3.0, "j": 1.0}, 2.0 * U, 1.0 * U),                                   # U·fs, U·fd
    ({"resolution": 1.0, "deadband": 2.0}, 2.0 * U, 1.0 * U),                   # spec 1.7
    ({"s": 3.0, "j": 1.0, "sj_mapping": "valve_estimation"}, 1.5 * U, 0.5 * U),  # U·S/2, -U·J
    ({"f_s": 100.0, "f_c": 100.0}, 100.0, 100.0),
])
def test_1_7_friction_from_any_one_parameter_set(params: dict[str, Any], f_s: float,
                                                 f_c: float) -> None:
    v = loopworks.create_block("valve.karnopp", **params)
    assert v.p[karnopp.P.f_s] == pytest.approx(f_s)
    assert v.p[karnopp.P.f_c] == pytest.approx(f_c)


@pytest.mark.parametrize(("params", "match"), [
    ({"f_s": 780.0, "s": 3.0, "j": 1.0}, "not parameters of two sets: got f_s, s, j"),
    ({"s": 3.0, "resolution": 1.0}, "got s, resolution"),
    ({"s": 3.0}, "'j' is missing"),
    ({"f_c": 10.0}, "'f_s' is missing"),
    ({"f_s": 100.0, "f_c": 200.0}, r"'f_c' = 200 is out of range: allowed \[0, f_s\]"),
    ({"s": 1.0, "j": 2.0}, r"J = 2 % is out of range for sj_mapping = 'force_balance'"),
    ({"s": 3.0, "j": 2.0, "sj_mapping": "valve_estimation"}, r"allowed \[0, S/2\]"),
    ({"x_max": 0.0}, "'x_max' = 0 must be greater than x_min"),
    ({"p_max": 1000.0}, "'p_max' = 1000 must be greater than p_min"),
    ({"m": 0.0}, r"'m' = 0 is out of range: allowed \(0, inf\)"),
    ({"substep": -1e-3}, r"'substep' = -0.001 is out of range"),
    ({"max_substeps": 2.5}, "'max_substeps' = 2.5 must be an integer"),
])
def test_parameter_errors_name_the_parameter(params: dict[str, Any], match: str) -> None:
    with pytest.raises(ParameterError, match=match):
        loopworks.create_block("valve.karnopp", **params)


# -- spec 1.6: statics and dynamics of the stem ---------------------------------------------------


def test_1_6_first_op_sets_the_frictionless_equilibrium(make: Make) -> None:
    """Without y0 the first op puts the stem at rest where k·x = Sa·P_op - F_init: op 50 %,
    P = 41368 + 69316 = 110684 Pa, x = (4925.438 - 2550)/210490 = 11.2853 mm = 38.9147 %."""
    v = make()
    r = v.step(0.1, op=50.0)
    assert r["position"].value == pytest.approx(pos_eq(50.0), abs=1e-12)
    assert r["position"].value == pytest.approx(38.9147, abs=1e-4)
    st = v.state()
    assert (st["v"], st["stuck"], st["friction"]) == (0.0, 1.0, 0.0)
    assert st["p"] == pytest.approx(P_MIN + 0.5 * DP)


def test_1_6_stuck_inside_the_static_band(make: Make) -> None:
    """spec 1.6: the stem stays while |F_r| < Fs: +12 % of op is 12·61.69 = 740.3 N < 780 N,
    so the position does not change at all and the friction force carries 740.3 N once the
    lag has settled; +13 % (802 N) breaks it away."""
    v = make(tau_ip=0.5)
    p0 = v.step(0.1, op=50.0)["position"].value
    assert hold_op(v, 62.0, 20.0) == p0
    assert v.state()["friction"] == pytest.approx(12.0 * U, rel=1e-9)
    assert v.state()["stuck"] == 1.0
    assert hold_op(v, 63.0, 20.0) > p0


def test_1_6_breakaway_creeps_until_the_force_falls_to_fs(make: Make) -> None:
    """spec 1.6 with Stribeck and heavy viscous friction: after breakaway the friction at
    small speed is about Fs + Fv·v, so the stem creeps until F_r = Fs:
    k·x = Sa·P - F_init - Fs, i.e. 12.778 % short of the frictionless position."""
    v = make(tau_ip=0.0)
    v.step(0.1, op=50.0)
    got = hold_op(v, 70.0, 30.0)
    assert got == pytest.approx(pos_eq(70.0) - pct(FS), abs=1e-6)
    assert pct(FS) == pytest.approx(12.778, abs=1e-3)
    assert v.state()["friction"] == pytest.approx(FS, abs=1e-6)


def test_1_6_slip_jump_of_an_undamped_stem() -> None:
    """spec 1.6 with Coulomb friction only (Fv = 0, vs = 0): from rest with F_r0 = 800 N >
    Fs, the stem oscillates about the point where k·Δx = F_r0 - Fc and stops after half a
    period pi·sqrt(m/k) = 8.66 ms at Δx = 2(F_r0 - Fc)/k = 0.950 mm = 3.2764 %, where
    F_r = 2·Fc - F_r0 = 600 N < Fs: it sticks there."""
    v = loopworks.create_block("valve.karnopp", tau_ip=0.0, f_v=0.0, v_s=0.0, substep=1e-5)
    p0 = v.step(0.001, op=50.0)["position"].value
    op = 50.0 + 800.0 / U
    trace = [v.step(0.001, op=op)["position"].value for _ in range(100)]
    jump = 2.0 * (800.0 - FC) / K
    assert trace[-1] - p0 == pytest.approx(100.0 * jump / TRAVEL, rel=2e-4)
    assert v.state()["stuck"] == 1.0
    assert v.state()["friction"] == pytest.approx(2.0 * FC - 800.0, abs=0.1)
    half_period = math.pi * math.sqrt(M / K)
    settled = next(i for i, p in enumerate(trace) if p == trace[-1])
    assert half_period == pytest.approx(0.00866, abs=1e-5)
    assert abs((settled + 1) * 0.001 - half_period) <= 0.001


@pytest.mark.parametrize("substep", [1e-3, 1e-4])
def test_1_6_linear_stem_matches_the_exact_solution(substep: float) -> None:
    """Without friction the stem is m·x'' + Fv·x' + k·x = Sa·P - F_init. A step 50 -> 60 %
    from rest (tau_ip = 0): x(t) = x1 + (x0 - x1)(l2·e^(l1·t) - l1·e^(l2·t))/(l2 - l1),
    l1,2 = (-Fv ± sqrt(Fv² - 4mk))/(2m) = -1.684, -78 123 /s. The error stays below
    3.5·substep % of travel (first-order method) on a 10 % step."""
    v = loopworks.create_block("valve.karnopp", tau_ip=0.0, f_s=0.0, f_c=0.0, substep=substep)
    v.step(0.1, op=50.0)
    disc = math.sqrt(FV * FV - 4.0 * M * K)
    l1, l2 = (-FV + disc) / (2.0 * M), (-FV - disc) / (2.0 * M)
    assert l1 == pytest.approx(-1.68396, abs=1e-5)
    x0, x1 = pos_eq(50.0), pos_eq(60.0)
    for i in range(1, 31):
        got = v.step(0.1, op=60.0)["position"].value
        t = 0.1 * i
        exact = x1 + (x0 - x1) * (l2 * math.exp(l1 * t) - l1 * math.exp(l2 * t)) / (l2 - l1)
        assert got == pytest.approx(exact, abs=3.5 * substep), t


def test_1_6_ip_lag_is_exact(make: Make) -> None:
    """spec 1.6: P follows tau_ip·dP/dt = P_op - P exactly for an op held over the scan, on
    the stuck path (one step per scan) and on the sliding path (substeps)."""
    tau = 0.8
    for params in ({"f_s": 1e7, "f_c": 1e7}, {"f_s": 0.0, "f_c": 0.0}):
        v = make(tau_ip=tau, **params)
        v.step(0.1, op=20.0)
        p0, p1 = P_MIN + 0.2 * DP, P_MIN + 0.9 * DP
        for i in range(1, 11):
            v.step(0.1, op=90.0)
            exact = p1 + (p0 - p1) * math.exp(-0.1 * i / tau)
            assert v.state()["p"] == pytest.approx(exact, rel=1e-12), (params, i)


def test_1_6_travel_limits(make: Make) -> None:
    """spec 1.6: the stem stops at the travel limits. Op 0: Sa·p_min - F_init = -709 N pushes
    it onto the lower stop (0 %); op 5 (-401 N) still pushes it there; with F_init = 0 op 100
    would need 38 mm > 29 mm and stops at 100 % (1906 N > Fs into the stop)."""
    v = make(tau_ip=0.0)
    assert v.step(0.1, op=0.0)["position"].value == 0.0
    assert hold_op(v, 5.0, 5.0) == 0.0
    w = make(tau_ip=0.0, f_init=0.0)
    assert w.step(0.1, op=100.0)["position"].value == 100.0
    w2 = make(tau_ip=0.0, f_init=0.0)
    w2.step(0.1, op=60.0)
    assert hold_op(w2, 100.0, 10.0) == 100.0
    assert w2.state()["v"] == 0.0


def test_1_1_force_balance_sj_on_a_quasi_static_coulomb_valve(make: Make) -> None:
    """spec 1.1 [I]: with Coulomb friction (vs = 0) and the force-balance mapping, a slow ramp
    shows the S/J behaviour: from rest at op 50 the stem breaks away past 50 + fs = 52; it then
    trails the frictionless position by (Fc + Fv·v)/k; after the reversal at 60 it waits until
    the force has changed from its value at the stop (between Fc and Fc + Fv·v: the viscous
    part relaxes as the stem stops) to -Fs, i.e. by S to S + Fv·v/U of op. Ramp 0.01 % per
    0.1 s scan (0.1 %/s): v = (U/k)·0.1 = 2.931e-5 m/s, Fv·v = 3.664 N (0.0594 % of op)."""
    v = make(s=3.0, j=1.0, v_s=0.0, tau_ip=0.0)
    assert v.p[karnopp.P.f_s] == pytest.approx(2.0 * U) and v.p[karnopp.P.f_c] == pytest.approx(U)
    p0 = v.step(0.1, op=50.0)["position"].value
    ops_up = [50.0 + 0.01 * i for i in range(1, 1001)]
    up = [v.step(0.1, op=x)["position"].value for x in ops_up]
    first = next(x for x, p in zip(ops_up, up, strict=True) if p != p0)
    assert first == pytest.approx(52.0, abs=0.011)
    speed = U / K * 0.1            # dx/dt = (U/k m per %)·(0.1 %/s) = 2.931e-5 m/s
    assert speed == pytest.approx(2.931e-5, rel=1e-3)
    lag = U + FV * speed           # Fc = U·fd = U·1 N
    i55 = ops_up.index(min(ops_up, key=lambda x: abs(x - 55.0)))
    assert up[i55] == pytest.approx(pos_eq(ops_up[i55]) - pct(lag), abs=0.01)
    top = up[-1]
    ops_down = [60.0 - 0.01 * i for i in range(1, 601)]
    down = [v.step(0.1, op=x)["position"].value for x in ops_down]
    moved = next(x for x, p in zip(ops_down, down, strict=True) if p < top - 1e-9)
    assert 60.0 - 3.0 - FV * speed / U - 0.01 <= moved < 60.0 - 3.0


# -- spec 2.2: dither on the physical valve -------------------------------------------------------


def dither_run(make: Make, substep: float = 1e-3) -> tuple[float, float, Block]:
    """op 50 (rest, no friction force), then 55 (+308.5 N, stuck), then +-12 % toggled every
    0.1 s scan for 60 s, then 55 held 10 s. Returns (position before, after, block)."""
    v = make(tau_ip=0.05, substep=substep)
    v.step(0.1, op=50.0)
    before = hold_op(v, 55.0, 5.0)
    for k in range(600):
        v.step(0.1, op=55.0 + (12.0 if k % 2 == 0 else -12.0))
    return before, hold_op(v, 55.0, 10.0), v


def test_2_2_dither_moves_a_stuck_valve_until_the_peak_force_is_fs(make: Make) -> None:
    """spec 2.2: dither keeps the stem near breakaway. The lag passes a square wave of half
    period Th = 0.1 s with amplitude A·tanh(Th/(2·tau_ip)) = 740.3 N · tanh(1) = 563.8 N;
    the stem creeps while F_r + 563.8 N > Fs, so the mean force offset falls from 308.5 N to
    about Fs - 563.8 = 216.2 N (a little above: creep under Fv is slow). Without dither it stays
    stuck (test_1_6_stuck_inside_the_static_band)."""
    before, after, v = dither_run(make)
    assert before == pytest.approx(pos_eq(50.0), abs=1e-12)
    peak = 12.0 * U * math.tanh(0.1 / (2.0 * 0.05))
    assert peak == pytest.approx(563.8, abs=0.1)
    offset = v.state()["friction"]
    assert FS - peak <= offset <= FS - peak + 0.03 * peak
    # the stem took up the rest of the 5 % step: 308.5 N - offset
    assert after - before == pytest.approx(pct(5.0 * U - offset), abs=1e-6)


def test_2_2_dither_response_is_converged_in_the_substep() -> None:
    """The honest-response claim (module docstring): the default 1 ms substep gives the
    dither result of a 4 times finer substep to 0.02 % of travel, against a 1.4 % effect."""
    def mk(**p: Any) -> Block:
        return loopworks.create_block("valve.karnopp", **p)

    b1, a1, _ = dither_run(mk, 1e-3)
    _, a2, _ = dither_run(mk, 2.5e-4)
    assert a1 - b1 > 1.0
    assert abs(a1 - a2) < 0.02


def test_long_scans_are_capped_and_stay_stable(make: Make) -> None:
    """max_substeps caps the work per scan; the longer substep (h = 1 s here, h²k > 2m + h·Fv)
    makes the spring implicit: it stays stable and the stem comes to rest with the spring
    force between the kinetic and the static level, Fc <= F_r <= Fs (coarse steps do not
    resolve the final creep, which the 1 ms default gives exactly: F_r = Fs)."""
    v = make(tau_ip=0.0, max_substeps=10)
    v.step(10.0, op=50.0)
    for _ in range(10):
        got = v.step(10.0, op=70.0)["position"].value
    assert v.state()["stuck"] == 1.0
    assert pos_eq(70.0) - pct(FS) <= got <= pos_eq(70.0) - pct(FC)


# -- initial state, status, characteristic --------------------------------------------------------


def test_y0_starts_at_rest_with_the_holding_pressure(make: Make) -> None:
    """With y0 the stem starts at y0 % with P = (k·x + F_init)/Sa: the op that gives this P
    (x = 14.5 mm: P = (3052.105 + 2550)/0.0445 = 125 890 Pa, op = 100·84 522/138 632 =
    60.9686 %) leaves it exactly there."""
    v = make(y0=50.0)
    assert v.outputs()["position"] == (50.0, 128)
    p_hold = (K * 0.0145 + F0) / SA
    assert v.state()["p"] == pytest.approx(p_hold)
    op = 100.0 * (p_hold - P_MIN) / DP
    assert op == pytest.approx(60.9686, abs=1e-4)
    assert hold_op(v, op, 30.0) == pytest.approx(50.0, abs=1e-12)
    assert abs(v.state()["friction"]) < 1e-6


def test_bad_op_hold_freezes_the_state(make: Make) -> None:
    v = make(tau_ip=0.5)
    v.step(0.1, op=50.0)
    hold_op(v, 80.0, 0.5)                    # sliding
    before = v.state()
    r = v.step(0.1, op=NAN)
    assert r["position"].status == 0 and r["flow"].status == 0
    assert r["position"].value == before["position"]
    assert v.state() == before
    assert v.step(0.1, op=(80.0, 0))["position"].status == 0
    assert v.state() == before


def test_bad_op_fail_strokes_towards_fail_op(make: Make) -> None:
    """bad_op = fail, fail_op = 0: P falls to p_min, Sa·p_min - F_init = -709.1 N pushes the
    stem down; it creeps until the spring has taken up all but Fs, and stops
    (780 - 709.1)/k = 0.337 mm = 1.161 % above the stop - friction holds it there."""
    v = make(tau_ip=0.5, bad_op="fail", fail_op=0.0)
    v.step(0.1, op=50.0)
    r = v.step(0.1, op=NAN)
    assert r["position"].status == 0x48
    push = F0 - SA * P_MIN
    assert push == pytest.approx(709.12, abs=0.01)
    assert hold_op(v, NAN, 30.0) == pytest.approx(pct(FS - push), abs=1e-6)
    assert pct(FS - push) == pytest.approx(1.161, abs=1e-3)


def test_uncertain_op_gives_uncertain_outputs(make: Make) -> None:
    v = make()
    r = v.step(0.1, op=(50.0, 0x4C))
    assert r["position"] == (pytest.approx(pos_eq(50.0)), 0x40)


def test_equal_percentage_flow(make: Make) -> None:
    v = make(characteristic="equal_percentage", rangeability=30.0)
    r = v.step(0.1, op=50.0)
    pos = r["position"].value
    assert r["flow"].value == pytest.approx(100.0 * 30.0 ** (pos / 100.0 - 1.0))


# -- replay, state, docs --------------------------------------------------------------------------


def test_replay_cli(tmp_path: Path) -> None:
    """op 50 then 62 (+740 N < Fs): the position stays at the frictionless 38.9147 %."""
    path = write_csv(tmp_path / "op.csv", ["t", "op"],
                     [[0.1 * k, 50.0 if k == 0 else 62.0] for k in range(20)])
    out = tmp_path / "out.csv"
    result = CliRunner().invoke(app, ["replay", "valve.karnopp", str(path), "-p", "tau_ip=0.05",
                                      "-o", str(out)])
    assert result.exit_code == 0, result.output
    lines = out.read_text().splitlines()
    assert lines[0] == "t,position,flow,position.ST,flow.ST"
    positions = [float(line.split(",")[1]) for line in lines[1:]]
    assert positions == pytest.approx([pos_eq(50.0)] * 20, abs=1e-12)


def test_resume_from_saved_state_mid_slide() -> None:
    ops = [50.0] + [50.0 + 30.0 * math.sin(0.05 * k) for k in range(1, 300)]
    whole = loopworks.create_block("valve.karnopp", tau_ip=0.2)
    expected = [whole.step(0.1, op=x)["position"].value for x in ops]
    first = loopworks.create_block("valve.karnopp", tau_ip=0.2)
    for x in ops[:150]:
        first.step(0.1, op=x)
    assert first.state()["stuck"] == 0.0
    saved = json.loads(json.dumps(first.state_dict()))
    resumed = loopworks.create_block("valve.karnopp", **saved["params"])
    resumed.load_state(saved)
    assert [resumed.step(0.1, op=x)["position"].value for x in ops[150:]] == expected[150:]


def test_docstring_example_runs() -> None:
    v = loopworks.create_block("valve.karnopp", tau_ip=0.05)
    assert v.step(0.1, op=50.0)["position"].value == pytest.approx(38.915, abs=1e-3)
    for _ in range(50):
        r = v.step(0.1, op=55.0)
    assert r["position"].value == pytest.approx(38.915, abs=1e-3)
    for k in range(600):
        r = v.step(0.1, op=55.0 + (12.0 if k % 2 == 0 else -12.0))
    assert r["position"].value == pytest.approx(40.30, abs=0.01)


def test_options_are_listed_in_the_docstring() -> None:
    doc = inspect.getdoc(karnopp) or ""
    options = doc.split("Options for the spec's [I] points")[1]
    for name in ("sj_mapping", "dv", "substep", "max_substeps", "bad_op"):
        assert f"``{name}``" in options


# -- issue 11: numeric contract and start value ---------------------------------------------------


def test_start_value_is_the_equilibrium_with_the_latched_op() -> None:
    """Issue 11 point 8: without y0 the position published before the first scan is where
    the first op will set the stem (at rest, frictionless equilibrium, module docstring): op
    0 % gives Sa·p_min - F_init < 0, the bottom stop; a latched op of 50 % re-published (what a
    module that settles its wires calls) gives the force balance (Sa·P - F_init)/k, 38.9 %."""
    v = loopworks.create_block("valve.karnopp")
    assert v.outputs()["position"] == (0.0, 128)
    assert all(math.isfinite(x) for x in v.x)
    v.set_inputs({"op": 50.0})
    v.publish_start()  # type: ignore[attr-defined]
    assert v.outputs()["position"] == (pytest.approx(pos_eq(50.0), abs=1e-12), 128)
    assert pos_eq(50.0) == pytest.approx(38.915, abs=1e-3)


def test_position_at_a_travel_stop_stays_within_0_100(make: Make) -> None:
    """Issue 11 (property: limited outputs stay within limits): a stem on its top stop is at
    100 % exactly, not 100.00000000000003 (x_min + travel·y0/100 rounded back)."""
    v = make(substep=0.01, m=1.0, sa=1.0, y0=100.0)
    for op in (3.96, 71.3, 100.0, 0.0):
        r = v.step(0.5, op=op)
        assert 0.0 <= r["position"].value <= 100.0


def test_area_too_small_for_the_y0_pressure_is_refused() -> None:
    """Sa = 5e-324 m² is inside its range (> 0), but the pressure that holds the stem at y0,
    (k·x + F_init)/Sa, is not finite: refused, naming sa (it used to start with P = inf)."""
    with pytest.raises(ParameterError, match=r"parameter 'sa' = 4.94066e-324 m² is too small"):
        loopworks.create_block("valve.karnopp", sa=5e-324, y0=50.0)


def test_extreme_ops_leave_no_non_finite_value(make: Make) -> None:
    """Issue 11 point 1: NaN, ±inf, ±1e308, ±3.5e38 into op: a finite op is clipped to
    0..100 % and used, a non-finite one is Bad input (hold); positions stay in 0..100 %, every
    state finite, also for the bare kernel without the guard."""
    v = make(tau_ip=0.05)
    bare = loopworks.create_block("valve.karnopp", jit=False, tau_ip=0.05)
    for op in (*EXTREMES, 50.0, *EXTREMES):
        r = v.step(0.1, op=op)
        kernel_scan(bare, 0.1, op=op)
        assert unsound(bare) == []
        assert 0.0 <= r["position"].value <= 100.0
        assert (r["position"].status == 0) == (not math.isfinite(op))
        assert all(math.isfinite(x) for x in v.x)
