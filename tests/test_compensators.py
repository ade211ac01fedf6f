"""The generic stiction compensators against plant-and-tuning sections 2.1 and 2.4-2.8.

Golden values: the comparison table of spec 2.8 (reproduced with an independent closed loop
written here: exact-ZOH FOPDT with an integer-sample delay, backward-Euler PI, and the
Choudhury S/J valve of spec 1.2), and hand arithmetic written in the tests for every scan-level
behaviour. Behaviour tests run twice through the ``make`` fixture: compiled and interpreted.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

import loopworks
from loopworks import create_block
from loopworks.blocks.block import Block
from loopworks.cli import app
from loopworks.errors import ParameterError
from tests.csvfiles import write_csv
from tests.properties.test_controller_properties import raw_step

NAN = math.nan
INF = math.inf
BAD = 0x00
GOOD = 0x80
OOS = 0x1C
KNOCKER = "compensator.knocker"
CR = "compensator.constant_reinforcement"
TWO_MOVE = "compensator.two_move"

Make = Callable[..., Block]


@pytest.fixture(params=[True, False], ids=["compiled", "interpreted"])
def make(request: pytest.FixtureRequest) -> Make:
    """``make(kind, **params)`` with the compiled or the interpreted kernel."""
    jit = request.param

    def _make(kind: str, **params: Any) -> Block:
        return create_block(kind, jit=jit, **params)

    return _make


# -- an independent loop: spec 2.8 setup --------------------------------------------------------

def sgn(v: float) -> int:
    return (v > 0) - (v < 0)


class ChoudhuryValve:
    """The S/J stiction model, step by step as spec 1.2 writes it (initially at rest)."""

    def __init__(self, s: float, j: float, x0: float) -> None:
        self.s, self.j = s, j
        self.x_prev, self.v_prev, self.y, self.stuck, self.xss = x0, 0.0, x0, True, x0

    def step(self, x: float) -> float:
        s_, j = self.s, self.j
        fd, fs = (s_ - j) / 2, (s_ + j) / 2
        x = min(max(x, 0.0), 100.0)                                   # 1. saturation
        v = x - self.x_prev                                           # 2.
        s, s_prev = sgn(v), sgn(self.v_prev)
        if s == s_prev:                                               # 3. same sign
            if not self.stuck:
                self.y = x - s * fd
            else:
                if sgn(x - self.xss) * sgn(self.xss - self.y) == 1:   # resume, old direction
                    slip = abs(x - self.xss) > j
                else:                                                 # reversal
                    slip = abs(x - self.y) > fs
                if slip:
                    self.stuck = False
                    self.y = x - s * fd
        else:                                                         # 4. sign changed
            if not self.stuck:
                self.xss = self.x_prev
            if s == 0:
                self.stuck = True
            elif abs(x - self.y) > fs:
                self.stuck = False
                self.y = x - s * fd
            else:
                self.stuck = True
        self.x_prev, self.v_prev = x, v                               # 5.
        return self.y


def loop_28(comp: Block | None, duration: float = 6000.0,
            model_step: Callable[[float], float] | None = None) -> dict[str, Any]:
    """Spec 2.8: FOPDT K = 1, T = 10 s, L = 2 s (exact ZOH: pv_k = a·pv_{k-1} + (1 - a)·
    y_{k-11}, the 10-sample dead time and the hold's one sample; an auditor's loop with a
    10-sample recurrence matched the table at L = 2.2 s, the same thing), ideal PI
    Kc = 1, Ti = 10 s, e = SP - PV, Ts = 0.2 s, valve S = 3 %, J = 1 %, all at 50 %, SP + 1 % at
    t = 20 s; metrics on the second half: PV σ, mean |e|, valve travel Σ|Δy|, reversals."""
    ts, kc, ti = 0.2, 1.0, 10.0
    a = math.exp(-ts / 10.0)
    delay = [50.0] * 11
    pv, integral = 50.0, 50.0
    valve = ChoudhuryValve(3.0, 1.0, 50.0)
    n = round(duration / ts)
    pvs, errs, ys, phases = [], [], [], []
    for k in range(n):
        t = k * ts
        sp = 51.0 if t >= 20.0 - 1e-9 else 50.0
        e = sp - pv
        integral += kc * ts / ti * e                                  # backward Euler
        u = kc * e + integral
        x = u
        if comp is not None:
            error = {"sp": sp, "pv": pv} if any(p.name == "sp" for p in comp.INPUTS) else {}
            r = comp.step(ts, op_in=u, **error)
            x = r["op_out"].value
            phases.append(r["phase"].value if "phase" in r else 0.0)
        y = valve.step(x)
        delay.append(y)
        pv = a * pv + (1.0 - a) * 1.0 * delay.pop(0)
        pvs.append(pv)
        errs.append(e)
        ys.append(y)
    half = n // 2
    pv_h, e_h, y_h = np.array(pvs[half:]), np.array(errs[half:]), np.array(ys[half:])
    dy = np.diff(y_h)
    moves = dy[dy != 0.0]
    return {"pv_std": float(pv_h.std()), "mean_abs_e": float(np.abs(e_h).mean()),
            "travel": float(np.abs(dy).sum()),
            "reversals": int(np.sum(np.sign(moves[1:]) != np.sign(moves[:-1]))),
            "pv": np.array(pvs), "y": np.array(ys), "phase": np.array(phases)}


def assert_row(m: dict[str, Any], pv_std: float, mean_e: float, travel: float,
               reversals: int) -> None:
    """Within one unit of the table's last printed digit; reversals exactly."""
    assert abs(m["pv_std"] - pv_std) <= 0.001
    assert abs(m["mean_abs_e"] - mean_e) <= 0.001
    assert abs(m["travel"] - travel) <= 1.0
    assert m["reversals"] == reversals


def test_spec_28_uncompensated_row_validates_the_loop() -> None:
    # spec 2.8 "none": PV σ 0.452, mean |e| 0.424, travel 61, 53 reversals
    assert_row(loop_28(None), 0.452, 0.424, 61, 53)


@pytest.mark.parametrize(("a", "hk", "row"), [
    (1.5, 1.0, (0.074, 0.064, 619, 599)),
    (3.0, 1.0, (0.162, 0.140, 3736, 999)),
    (3.0, 2.0, (0.225, 0.195, 2937, 748)),
])
def test_spec_28_knocker_rows(a: float, hk: float, row: tuple[float, float, float, int]) -> None:
    # spec 2.8 knocker rows (τ = 0.2 s = one scan); spec 2.4 direction since the previous pulse
    comp = create_block(KNOCKER, amplitude=a, pulse_width=0.2, interval=hk)
    assert_row(loop_28(comp), *row)


@pytest.mark.parametrize(("alpha", "row"), [
    (1.0, (0.276, 0.246, 168, 148)),
    (1.6, (0.042, 0.036, 1683, 1250)),
    (2.0, (0.070, 0.060, 2805, 1250)),
])
def test_spec_28_constant_reinforcement_rows(alpha: float,
                                             row: tuple[float, float, float, int]) -> None:
    # spec 2.8 constant-reinforcement rows; spec 2.6 u_c = α·sign(Δu), last sign held
    assert_row(loop_28(create_block(CR, alpha=alpha)), *row)


def test_spec_28_defaults_are_the_best_rows() -> None:
    # knocker a = 1.5, τ = 0.2, h_k = 1.0 and CR α = 1.6 (spec 2.8)
    assert_row(loop_28(create_block(KNOCKER)), 0.074, 0.064, 619, 599)
    assert_row(loop_28(create_block(CR)), 0.042, 0.036, 1683, 1250)


def test_literal_pulse_start_reading_never_fires_one_scan_pulses() -> None:
    # spec 2.4 formula sampled literally: sign(u(t_p) - u(t_p)) = 0 on a one-scan pulse, so the
    # loop is the uncompensated one
    comp = create_block(KNOCKER, direction_reference="pulse_start")
    assert_row(loop_28(comp), 0.452, 0.424, 61, 53)


def test_two_move_with_an_exact_model_lands_the_valve_and_stops_the_cycle() -> None:
    """spec 2.5: two moves put the valve at y* = (SP - 0)/1 = 51 %: the PV settles on SP and
    the valve moves exactly twice after the moves start (no more limit cycle)."""
    comp = create_block(TWO_MOVE, target="model", model_gain=1.0, model_bias=0.0)
    m = loop_28(comp, duration=3000.0)
    phase, y = m["phase"], m["y"]
    k = int(np.argmax(phase > 0))
    assert k > 0 and phase[k] == 1.0 and (phase[k + 1:] == 2.0).all()
    assert y[-1] == pytest.approx(51.0, abs=1e-9)
    after = np.diff(y[k - 1:])
    assert np.count_nonzero(after) == 2
    assert m["pv"][-1] == pytest.approx(51.0, abs=1e-9)


def test_two_move_cycle_mean_target_holds_the_valve_at_the_measured_mean() -> None:
    """spec 2.5 (mean OP over the limit cycle): the valve lands on the estimate, the PV stops
    cycling; the estimate after 2 cycles of the transient after the SP step is 50.74 %."""
    comp = create_block(TWO_MOVE)
    m = loop_28(comp, duration=3000.0)
    k = int(np.argmax(m["phase"] > 0))
    target = comp.outputs()["target"].value
    assert m["y"][-1] == pytest.approx(target, abs=1e-9)
    assert target == pytest.approx(50.74, abs=0.005)
    pv_tail = m["pv"][k + 2000:]   # 400 s after the moves: settled
    assert pv_tail.std() < 1e-6
    assert np.count_nonzero(np.diff(m["y"][k - 1:])) == 2


# -- knocker (spec 2.4) ----------------------------------------------------------------------

def corrections(block: Block, ops: list[float], dt: float, **inputs: Any) -> list[float]:
    return [block.step(dt, op_in=op, **inputs)["correction"].value for op in ops]


def test_knocker_pulse_width_interval_and_direction(make: Make) -> None:
    # a = 1, τ = 0.5 s, h_k = 1 s, 0.25 s scans: pulses start at scans 0, 4, 8 and last two
    # scans; the first refers to its own start, later ones to the previous pulse start
    kn = make(KNOCKER, amplitude=1.0, pulse_width=0.5, interval=1.0)
    ops = [50.0 + 0.1 * k for k in range(10)]
    assert corrections(kn, ops, 0.25) == [0, 1, 0, 0, 1, 1, 0, 0, 1, 1]


def test_knocker_pushes_the_way_the_output_moved_since_the_previous_pulse(make: Make) -> None:
    kn = make(KNOCKER, amplitude=2.0, pulse_width=0.1, interval=0.3)
    # pulse starts at scans 0, 3, 6, 9 (0.1 s scans): u at starts 50, 49, 49, 49.5
    ops = [50.0, 50.5, 50.0, 49.0, 49.0, 48.0, 49.0, 50.0, 51.0, 49.5]
    got = corrections(kn, ops, 0.1)
    assert got == [0, 0, 0, -2, 0, 0, 0, 0, 0, 2]   # 49 - 50 < 0, 49 - 49 = 0, 49.5 - 49 > 0


def test_knocker_literal_formula_refers_to_the_current_pulse_start(make: Make) -> None:
    kn = make(KNOCKER, amplitude=1.0, pulse_width=0.5, interval=1.0,
              direction_reference="pulse_start")
    ops = [50.0 + 0.1 * k for k in range(10)]
    assert corrections(kn, ops, 0.25) == [0, 1, 0, 0, 0, 1, 0, 0, 0, 1]


def test_knocker_pulse_lasts_at_least_one_scan(make: Make) -> None:
    # τ = 0.05 s < dt = 0.2 s: one scan per pulse (spec 2.4: τ of the order of one scan)
    kn = make(KNOCKER, amplitude=1.0, pulse_width=0.05, interval=0.4)
    ops = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]
    assert corrections(kn, ops, 0.2) == [0, 0, 1, 0, 1, 0]


def test_knocker_error_band_stops_pulses_inside_it(make: Make) -> None:
    # improved knocker (spec 2.4 [L]): no pulse while |sp - pv| <= band
    kn = make(KNOCKER, amplitude=1.0, pulse_width=0.2, interval=0.4, error_band=0.5)
    got = [kn.step(0.2, op_in=float(k), sp=10.0, pv=pv)["correction"].value
           for k, pv in enumerate([10.0, 10.0, 10.2, 10.2, 11.0, 11.0])]
    assert got == [0, 0, 0, 0, 1, 0]


def test_knocker_enable_bypasses_and_keeps_time(make: Make) -> None:
    kn = make(KNOCKER, amplitude=1.0, pulse_width=0.2, interval=0.4)
    got = [kn.step(0.2, op_in=float(k), enable=en)["op_out"].value
           for k, en in enumerate([1.0, 1.0, 0.0, 0.0, 1.0, 1.0])]
    assert got == [0.0, 1.0, 2.0, 3.0, 5.0, 5.0]   # the pulse at scan 2 is bypassed


# -- constant reinforcement (spec 2.6) ---------------------------------------------------------

def test_constant_reinforcement_follows_the_sign_and_holds_it(make: Make) -> None:
    # u_c = α·sign(u_k - u_{k-1}), last non-zero sign held; 0 before the first move
    cr = make(CR, alpha=0.8)
    ops = [50.0, 50.0, 50.2, 50.2, 50.2, 50.1, 50.1, 50.3]
    assert corrections(cr, ops, 1.0) == [0, 0, 0.8, 0.8, 0.8, -0.8, -0.8, 0.8]


def test_constant_reinforcement_reversal_is_a_step_of_two_alpha(make: Make) -> None:
    cr = make(CR, alpha=1.6)
    outs = [cr.step(0.2, op_in=u)["op_out"].value for u in (50.0, 51.0, 51.0, 50.5)]
    assert outs == pytest.approx([50.0, 52.6, 52.6, 48.9], abs=1e-12)
    assert outs[2] - outs[3] == pytest.approx(0.5 + 2 * 1.6, abs=1e-12)


def test_constant_reinforcement_skips_non_finite_output_and_bypass(make: Make) -> None:
    cr = make(CR, alpha=1.0)
    got = corrections(cr, [10.0, 11.0, NAN, 11.0, 10.0], 1.0)
    assert got == [0, 1, 1, 1, -1]                   # NaN skipped: 11 -> 11 holds +
    # issue 11 point 1 (it was NaN with a Good status): a NaN op_in is Bad, op_out holds its
    # last value (10 - 1 = 9) with status Bad
    assert tuple(cr.step(1.0, op_in=NAN)["op_out"]) == (9.0, BAD)
    assert cr.step(1.0, op_in=12.0, enable=0.0)["op_out"].value == 12.0


# -- two-move (spec 2.5) --------------------------------------------------------------------

# e = sp - pv alternates +1, +1, -1, -1, ...: crossings at scans 2, 4, 6, ...
def cycling_pv(k: int, sp: float = 0.0) -> float:
    return sp - (1.0 if (k // 2) % 2 == 0 else -1.0)


def drive(block: Block, ops: list[float], dt: float = 1.0, sp: float = 0.0,
          enable: list[float] | None = None) -> list[Any]:
    out = []
    for k, op in enumerate(ops):
        en = 1.0 if enable is None else enable[k]
        r = block.step(dt, op_in=op, sp=sp, pv=cycling_pv(k, sp), enable=en)
        out.append((r["op_out"].value, r["phase"].value, r["target"].value))
    return out


def test_two_move_measures_one_cycle_then_moves_reverse(make: Make) -> None:
    """cycles = 1: the mean of u over scans 2..5 (from a crossing to the crossing two half
    cycles later) is (52+53+54+55)/4 = 53.5; x_0 = 55 (last op_out). Reverse, d = +1 (target
    below x_0): x_f = 53.5 + fd = 54.5, x_1 = min(55 - (3+1+0.5), 54.5 - (3+0.5)) = 50.5."""
    tm = make(TWO_MOVE, cycles=1)
    got = drive(tm, [50.0 + k for k in range(10)])
    assert [g[1] for g in got] == [0, 0, 0, 0, 0, 0, 1, 2, 2, 2]
    assert [g[0] for g in got[:6]] == [50.0, 51.0, 52.0, 53.0, 54.0, 55.0]   # pass
    assert got[6][0] == 50.5 and got[7][0] == 54.5 and got[9][0] == 54.5
    assert got[6][2] == 53.5
    assert math.isnan(got[0][2])
    assert tm.outputs()["correction"].value == 54.5 - 59.0


def test_two_move_model_target_reverse_and_auto(make: Make) -> None:
    """y* = (sp - bias)/gain = 20, x_0 = 55. reverse: d = +1, x_f = 21,
    x_1 = min(55 - 4.5, 21 - 3.5) = 17.5. auto: both moves down, d = -1, x_f = 19,
    x_1 = 19 + (1 + 0.5) = 20.5, first move 34.5 >= S + J + m = 4.5."""
    for approach, x1, xf in (("reverse", 17.5, 21.0), ("auto", 20.5, 19.0)):
        tm = make(TWO_MOVE, cycles=1, target="model", model_gain=1.0, approach=approach)
        got = drive(tm, [50.0 + k for k in range(8)], sp=20.0)
        assert (got[6][0], got[7][0]) == (x1, xf)
        assert got[6][2] == 20.0


def test_two_move_auto_falls_back_to_reverse_near_the_target(make: Make) -> None:
    # the target 53.5 is 1.5 below x_0 = 55 < S + 2J + 2m: auto gives the reverse moves
    tm = make(TWO_MOVE, cycles=1, approach="auto")
    got = drive(tm, [50.0 + k for k in range(8)])
    assert (got[6][0], got[7][0]) == (50.5, 54.5)


def test_two_move_flips_direction_at_the_range_end_then_clamps(make: Make) -> None:
    """y* = 1, x_0 = 3: reverse d = +1 gives x_1 = min(3 - 4.5, 2 - 3.5) = -1.5 < 0, so d = -1:
    x_f = 0, x_1 = max(3 + 4.5, 0 + 3.5) = 7.5. With op_hi = 5 both fail: d = +1 clamped:
    x_1 = 0, x_f = 2."""
    ops = [3.0] * 8
    tm = make(TWO_MOVE, cycles=1, target="model", model_bias=-1.0)   # y* = (0 + 1)/1
    got = drive(tm, ops)
    assert (got[6][0], got[7][0]) == (7.5, 0.0)
    tight = make(TWO_MOVE, cycles=1, target="model", model_bias=-1.0, op_hi=5.0)
    got = drive(tight, ops)
    assert (got[6][0], got[7][0]) == (0.0, 2.0)


def test_two_move_move_time_holds_the_first_move(make: Make) -> None:
    # move_time = 1 s with 0.25 s scans: x_1 on 4 scans, then x_f
    tm = make(TWO_MOVE, cycles=1, target="model", model_gain=1.0, move_time=1.0)
    ops = [50.0] * 14
    got = []
    for k, op in enumerate(ops):
        r = tm.step(0.25, op_in=op, sp=0.0, pv=cycling_pv(k))
        got.append(r["phase"].value)
    assert got == [0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 2]


def test_two_move_releases_on_setpoint_change_enable_and_error_band(make: Make) -> None:
    tm = make(TWO_MOVE, cycles=1)
    drive(tm, [50.0] * 9)
    assert tm.outputs()["phase"].value == 2.0
    r = tm.step(1.0, op_in=47.0, sp=0.5, pv=0.5)          # a new setpoint: release
    assert (r["phase"].value, r["op_out"].value, r["correction"].value) == (0.0, 47.0, 0.0)
    # enable = 0 releases; a band release needs |e| > release_band
    for kwargs, released in (({"enable": 0.0}, True), ({"pv": 1.9}, False),
                             ({"pv": 2.1}, True)):
        tm = make(TWO_MOVE, cycles=1, release_band=2.0)
        drive(tm, [50.0] * 9)
        inputs = {"op_in": 47.0, "sp": 0.0, "pv": 0.0, **kwargs}
        assert (tm.step(1.0, **inputs)["phase"].value == 0.0) is released


def test_two_move_measures_while_disabled_and_moves_when_enabled(make: Make) -> None:
    tm = make(TWO_MOVE, cycles=1)
    enable = [0.0] * 8 + [1.0] * 3
    got = drive(tm, [50.0 + k for k in range(11)], enable=enable)
    assert [g[1] for g in got] == [0] * 8 + [1, 2, 2]
    assert got[7][2] == 53.5          # measured at scan 6 while disabled, shown in pass


def test_two_move_cycle_band_ignores_small_crossings(make: Make) -> None:
    tm = make(TWO_MOVE, cycles=1, cycle_band=1.5)   # |e| = 1 never leaves the band
    assert all(g[1] == 0 for g in drive(tm, [50.0] * 20))


def test_two_moves_land_any_valve_state_on_the_target() -> None:
    """spec 2.5 [I]: move 1 of S + J + m puts the valve in a known state whatever it was doing
    (moving, or stuck anywhere in its band), so move 2 lands it on y* exactly: 300 random OP
    histories through the spec 1.2 valve, random targets, both approaches."""
    rng = np.random.default_rng(2005)
    for trial in range(300):
        approach = "auto" if trial % 2 else "reverse"
        target = float(rng.uniform(20.0, 80.0))
        tm = create_block(TWO_MOVE, cycles=1, target="model", model_gain=1.0,
                          approach=approach)
        valve = ChoudhuryValve(3.0, 1.0, 50.0)
        op = 50.0
        n = int(rng.integers(20, 120))
        enable = [0.0] * n + [1.0] * 3
        for k in range(n + 3):
            op += float(rng.normal(0.0, 1.5)) if rng.random() < 0.8 else 0.0
            r = tm.step(1.0, op_in=op, sp=target, pv=cycling_pv(k, target), enable=enable[k])
            valve.step(r["op_out"].value)
        assert tm.outputs()["phase"].value == 2.0
        assert valve.y == pytest.approx(target, abs=1e-9)


def test_a_move_of_s_plus_margin_does_not_always_break_away() -> None:
    """Why move 1 is S + J + m (spec 2.5 [I], stick band of spec 1.2): after an upward stop
    at x_ss the valve holds for OP in [x_ss - S, x_ss + J]; from the low edge an upward move of
    S + 0.5 ends at x_ss + 0.5 < x_ss + J and does not slip."""
    valve = ChoudhuryValve(3.0, 1.0, 50.0)
    for x in (51.0, 52.5, 54.0, 56.0):
        valve.step(x)                       # moving up: y = x - fd
    y_stop = valve.step(56.0)               # pause: stuck, x_ss = 56
    assert y_stop == 55.0
    assert valve.step(53.1) == 55.0         # inside the band (> 56 - 3)
    assert valve.step(53.1 + 3.5) == 55.0   # 56.6 < 56 + J: still stuck
    assert valve.step(57.1) == 56.1         # beyond x_ss + J: slips to x - fd


# -- all three: status, bypass, parameters, replay ------------------------------------------

@pytest.mark.parametrize("kind", [KNOCKER, CR, TWO_MOVE])
def test_op_out_carries_the_status_of_op_in(make: Make, kind: str) -> None:
    # spec 2.1: the compensator passes the controller's status through (DeltaV 6.3 line 28)
    comp = make(kind)
    for status in (OOS, 0x47, GOOD, 0xC0):
        r = comp.step(0.2, op_in=(40.0, status))
        assert r["op_out"].status == status
        assert r["correction"].status == GOOD


@pytest.mark.parametrize("kind", [KNOCKER, CR, TWO_MOVE])
def test_disabled_compensator_passes_the_output_through(make: Make, kind: str) -> None:
    comp = make(kind)
    ops = [50.0, 53.0, 49.0, 55.0, 45.0, 60.0, 40.0, 61.0]
    error = kind != CR   # constant reinforcement has no sp/pv inputs: it needs no error
    got = [comp.step(0.2, op_in=op, enable=0.0,
                     **({"sp": 0.0, "pv": cycling_pv(k)} if error else {}))["op_out"].value
           for k, op in enumerate(ops)]
    assert got == ops


@pytest.mark.parametrize(("kind", "params", "name"), [
    (KNOCKER, {"interval": 0.2, "pulse_width": 0.2}, "interval"),
    (KNOCKER, {"amplitude": -1.0}, "amplitude"),
    (KNOCKER, {"pulse_width": 0.0}, "pulse_width"),
    (KNOCKER, {"direction_reference": "next"}, "direction_reference"),
    (CR, {"alpha": -0.1}, "alpha"),
    (TWO_MOVE, {"op_lo": 50.0, "op_hi": 50.0}, "op_hi"),
    (TWO_MOVE, {"target": "model", "model_gain": 0.0}, "model_gain"),
    (TWO_MOVE, {"cycles": 0}, "cycles"),
    (TWO_MOVE, {"margin": 0.0}, "margin"),
    (TWO_MOVE, {"s": -1.0}, "s"),
    (TWO_MOVE, {"approach": "sideways"}, "approach"),
])
def test_bad_parameters_name_the_parameter(kind: str, params: dict[str, Any],
                                           name: str) -> None:
    with pytest.raises(ParameterError, match=f"'{name}'"):
        create_block(kind, **params)


# -- non-finite values (issue 11 point 1) and the output before the first scan (point 8) --------

SPECIALS = [NAN, INF, -INF, 1e308, -1e308]


def error_inputs(kind: str, sp: float, pv: float) -> dict[str, float]:
    return {} if kind == CR else {"sp": sp, "pv": pv}


PORTS = [(kind, port) for kind in (KNOCKER, CR, TWO_MOVE)
         for port in ("op_in", "enable", "sp", "pv") if kind != CR or port in ("op_in", "enable")]


@pytest.mark.parametrize(("kind", "port"), PORTS)
@pytest.mark.parametrize("value", SPECIALS, ids=["nan", "inf", "-inf", "1e308", "-1e308"])
def test_non_finite_inputs_give_no_non_finite_good_output(make: Make, kind: str, port: str,
                                                          value: float) -> None:
    """Issue 11 point 1: NaN, ±inf or ±1e308 into any input (scans 8-13 of a cycling loop, so
    the two-move measures and moves meanwhile) gives no inf/NaN output unless its status is
    Bad, and no non-finite state, through the block and through its kernel alone (no
    fallback of the guard needed); after it finite inputs give finite Good outputs again."""
    params: dict[str, Any] = {"cycles": 1} if kind == TWO_MOVE else {}
    for comp, scan in ((make(kind, **params), None), (create_block(kind, jit=False, **params),
                                                      raw_step)):
        for k in range(30):
            inputs = {"op_in": 50.0 + (k % 5), "enable": 1.0,
                      **error_inputs(kind, 0.0, cycling_pv(k))}
            if 8 <= k < 14:
                inputs[port] = value
            if scan is None:
                comp.step(0.2, **inputs)
            else:
                scan(comp, 0.2, inputs)
            for i, out in enumerate(comp.OUTPUTS):
                v, st = float(comp.y[i]), int(comp.ys[i])
                assert math.isfinite(v) or (out.status and st & 0xC0 == BAD), (
                    f"scan {k}: {out.name} = {v}, status {st}")
            assert np.isfinite(comp.x).all(), comp.state()
        assert comp.ys[0] == GOOD and math.isfinite(comp.y[0]) and math.isfinite(comp.y[1])


@pytest.mark.parametrize("kind", [KNOCKER, CR, TWO_MOVE])
@pytest.mark.parametrize("value", [NAN, INF, -INF])
def test_non_finite_op_in_holds_op_out_bad_then_recovers(make: Make, kind: str,
                                                         value: float) -> None:
    """A non-finite op_in is Bad: op_out holds its last value with status Bad (0, or the
    Bad status it came with, substatus kept) and correction holds; the next finite op_in
    passes through as before (enable = 0: op_out = op_in)."""
    comp = make(kind)
    err = error_inputs(kind, 0.0, 0.0)
    assert comp.step(0.2, op_in=40.0, enable=0.0, **err)["op_out"] == (40.0, GOOD)
    r = comp.step(0.2, op_in=value)
    assert (tuple(r["op_out"]), r["correction"].value) == ((40.0, BAD), 0.0)
    assert tuple(comp.step(0.2, op_in=(value, OOS))["op_out"]) == (40.0, OOS)
    assert tuple(comp.step(0.2, op_in=41.0)["op_out"]) == (41.0, GOOD)


def test_op_out_holds_bad_when_the_sum_overflows(make: Make) -> None:
    """1.7e308 + α with α = 1e308 overflows: op_out holds (Bad); the sign memory still follows
    u, so u falling to 1 gives 1 - α."""
    cr = make(CR, alpha=1e308)
    assert cr.step(1.0, op_in=0.0)["op_out"] == (0.0, GOOD)
    assert tuple(cr.step(1.0, op_in=1.7e308)["op_out"]) == (0.0, BAD)
    assert cr.step(1.0, op_in=1.0)["op_out"] == (1.0 - 1e308, GOOD)  # u fell: -α


def test_knocker_whose_first_pulse_starts_on_nan_refers_to_the_first_finite_u(
        make: Make) -> None:
    """The pulse direction needs u at the pulse start. A NaN there, with no u known before,
    left the first pulse without a reference, and so the second too (it refers to the
    first's start): no pulse for two intervals (found by an outside audit). The first finite
    u after the start is now the reference (a = 1, τ = 0.5 s, h_k = 1 s, 0.25 s scans)."""
    kn = make(KNOCKER, amplitude=1.0, pulse_width=0.5, interval=1.0)
    ops = [NAN, 50.1, 50.2, 50.3, 50.4, 50.5, 50.6, 50.7, 50.8, 50.9]
    got = corrections(kn, ops, 0.25)
    # scan 0: NaN, correction holds 0; scan 1: 50.1 becomes the first pulse's reference,
    # sign(0) = 0; scan 4 (second pulse): +1 since 50.1; scan 8: +1 since 50.4; as with a
    # finite first u from the second pulse on
    assert got == [0, 0, 0, 0, 1, 1, 0, 0, 1, 1]
    finite = make(KNOCKER, amplitude=1.0, pulse_width=0.5, interval=1.0)
    assert corrections(finite, [50.0, *ops[1:]], 0.25)[4:] == got[4:]
    assert np.isfinite(kn.x).all()


def test_knocker_unmeasured_error_does_not_stop_the_pulses(make: Make) -> None:
    """error_band (spec 2.4 [L]) stops pulses while |e| <= band; a NaN or overflowing error
    (1e308 - -1e308) is not inside the band: the pulses go on."""
    for sp, pv in ((NAN, 0.0), (1e308, -1e308)):
        kn = make(KNOCKER, amplitude=1.0, pulse_width=0.2, interval=0.4, error_band=0.5)
        got = [kn.step(0.2, op_in=float(k), sp=sp, pv=pv)["correction"].value
               for k in range(6)]
        assert got == [0, 0, 1, 0, 1, 0]


def test_two_move_target_is_bad_until_known() -> None:
    """The target port has a status (issue 11): NaN and Bad before the cycle mean is
    measured, Good after; target = model: Bad while (sp - bias)/gain is not finite."""
    tm = create_block(TWO_MOVE, cycles=1)
    assert math.isnan(tm.outputs()["target"].value) and tm.outputs()["target"].status == BAD
    got = [tm.step(1.0, op_in=50.0 + k, sp=0.0, pv=cycling_pv(k))["target"] for k in range(7)]
    assert all(math.isnan(t.value) and t.status == BAD for t in got[:6])
    assert got[6] == (53.5, GOOD)
    model = create_block(TWO_MOVE, target="model", model_gain=1e-300)
    assert model.outputs()["target"] == (0.0, GOOD)   # (0 - 0)/1e-300, from the initial sp
    t = model.step(1.0, op_in=50.0, sp=1e10, pv=0.0)["target"]
    assert math.isnan(t.value) and t.status == BAD  # 1e10/1e-300 = inf
    assert model.step(1.0, sp=1e-290)["target"] == (pytest.approx(1e10), GOOD)


def test_two_move_holds_x_final_through_a_bad_controller_output() -> None:
    """In hold the valve input is x_f whatever op_in is; a NaN op_in passes its Bad status
    on with x_f (correction held); the hold goes on when op_in is finite again."""
    tm = create_block(TWO_MOVE, cycles=1)
    drive(tm, [50.0 + k for k in range(9)])      # as in the first two-move test: x_f = 54.5
    r = tm.step(1.0, op_in=NAN, sp=0.0, pv=1.0)
    assert (tuple(r["op_out"]), r["correction"].value, r["phase"].value) == (
        (54.5, BAD), 54.5 - 58.0, 2.0)
    assert tuple(tm.step(1.0, op_in=47.0)["op_out"]) == (54.5, GOOD)


def test_two_move_non_finite_setpoint_releases_and_blocks_the_moves() -> None:
    """A NaN sp is not the setpoint of the moves: release; with sp NaN no moves start
    (ready as they are), they start at the first finite sp."""
    tm = create_block(TWO_MOVE, cycles=1)
    drive(tm, [50.0] * 9)
    assert tm.step(1.0, op_in=50.0, sp=NAN, pv=0.0)["phase"].value == 0.0
    tm = create_block(TWO_MOVE, cycles=1)
    drive(tm, [50.0] * 7, enable=[0.0] * 7)      # measured, ready
    assert tm.step(1.0, op_in=50.0, enable=1.0, sp=NAN, pv=0.0)["phase"].value == 0.0
    assert tm.step(1.0, op_in=50.0, sp=0.0, pv=1.0)["phase"].value == 1.0


def test_two_move_mean_takes_u_as_the_valve_sees_it() -> None:
    """The cycle mean uses u clamped to [op_lo, op_hi] (the valve clips it): a 1e308 sample
    counts as op_hi = 100 (without the clamp the sum overflowed to inf). cycles = 1, mean over
    scans 2..5 of u = 50, 1e308, 50, 50: (50 + 100 + 50 + 50)/4 = 62.5."""
    tm = create_block(TWO_MOVE, cycles=1)
    ops = [50.0, 50.0, 50.0, 1e308, 50.0, 50.0, 50.0]
    got = drive(tm, ops)
    assert got[6][2] == 62.5
    assert np.isfinite(tm.x).all()


@pytest.mark.parametrize("kind", [KNOCKER, CR, TWO_MOVE])
@pytest.mark.parametrize("enable", [NAN, INF])
def test_non_finite_enable_is_a_bypass(make: Make, kind: str, enable: float) -> None:
    """A NaN or infinite enable is not a switch: bypass, op_out = op_in."""
    comp = make(kind)
    ops = [50.0, 53.0, 49.0, 55.0, 45.0, 60.0]
    got = [comp.step(0.2, op_in=op, enable=enable,
                     **error_inputs(kind, 0.0, cycling_pv(k)))["op_out"].value
           for k, op in enumerate(ops)]
    assert got == ops


@pytest.mark.parametrize("kind", [KNOCKER, CR, TWO_MOVE])
def test_op_out_before_the_first_scan_passes_op_in_through(kind: str) -> None:
    """Issue 11 point 8: before the first scan op_out is op_in passed through (a compensator
    with no correction yet, at steady state), correction 0: 0 % for the input's default, the
    given op_in when the initial outputs are taken from it, 0 for a non-finite one."""
    comp = create_block(kind)
    assert comp.outputs()["op_out"] == (0.0, GOOD)
    assert comp.outputs()["correction"] == (0.0, GOOD)
    comp.set_inputs({"op_in": 42.0})
    assert comp.initial_outputs()[:2] == [42.0, 0.0]
    comp.set_inputs({"op_in": NAN})
    assert comp.initial_outputs()[:2] == [0.0, 0.0]


def test_replay_cli_runs_the_knocker_docstring_example(tmp_path: Path) -> None:
    rows_in = [[0, 50], [0.2, 50.5], [0.4, 51], [0.6, 51.5], [0.8, 52], [1.0, 52.5], [1.2, 52]]
    path = write_csv(tmp_path / "kn.csv", ["t", "op_in"], rows_in)
    result = CliRunner().invoke(app, ["replay", KNOCKER, str(path), "-p", "amplitude=1",
                                      "-p", "pulse_width=0.2", "-p", "interval=0.6"])
    assert result.exit_code == 0, result.output
    rows = list(csv.reader(io.StringIO(result.stdout)))
    assert rows[0] == ["t", "op_out", "correction", "op_out.ST"]
    assert [float(r[1]) for r in rows[1:]] == [50, 50.5, 51, 52.5, 52, 52.5, 53]


def test_docstring_python_example() -> None:
    cr = loopworks.create_block(CR, alpha=1.6)
    outs = [cr.step(0.2, op_in=u)["op_out"].value for u in (50.0, 51.0, 51.0, 50.5)]
    assert outs == pytest.approx([50.0, 52.6, 52.6, 48.9], abs=1e-12)




ORDER_LOOP = """
[simulation]
dt = 0.2
duration = 2.0

[blocks.valve]
kind = "valve.choudhury"
s = 3.0
j = 1.0
y0 = 50.0

[blocks.process]
kind = "process.fopdt"
gain = 1.0
time_constant = 10.0
dead_time = 2.0
u0 = 50.0

[blocks.pid]
kind = "pid"
k = 1.0
ti = 10.0
bias = 50.0
sp = 50.0

[blocks.comp]
kind = "{kind}"
{extra}

[wires]
"valve.op" = "comp.{out_port}"
"comp.{in_port}" = "pid.out"
"process.u" = "valve.position"
"pid.pv" = "process.y"
"""


@pytest.mark.parametrize(("kind", "in_port", "out_port", "extra"), [
    ("compensator.knocker", "op_in", "op_out", ""),
    ("compensator.constant_reinforcement", "op_in", "op_out", ""),
    ("compensator.two_move", "op_in", "op_out", ""),
    ("deltav.stick_slip", "signal_in", "signal_out", "comp_start = 0.0")])
def test_a_compensator_scanned_after_its_valve_passes_the_controller_through_at_start(
        kind: str, in_port: str, out_port: str, extra: str) -> None:
    """spec 2.1: x = u_PID + u_c. With the compensator declared after the valve, the valve's
    first scan read the compensator's placeholder output 0 (its initial pass-through of the
    default op_in): the valve stepped to 1 % and stuck at 49 (found by an independent
    reference). The module's start settling (issue 11 point 8) now lets the compensator pass
    the settled controller output (the pid's bias, 50) through before the first scan."""
    from loopworks.sim.scenario import parse_scenario

    sc = parse_scenario(ORDER_LOOP.format(kind=kind, in_port=in_port, out_port=out_port,
                                          extra=extra))
    result = sc.module.run(sc.duration, sc.dt)
    assert result["valve.op"][0] == 50.0
    assert (result["valve.position"] == 50.0).all()
