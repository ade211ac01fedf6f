"""The generic ``pid`` block against its specification (the docstring of
``loopworks.blocks.pid``).

Every expected value is computed independently: by hand arithmetic written out in the test, or
by :class:`ReferencePID`, a small textbook implementation written here from the equations of the
docstring (Åström & Hägglund, *Advanced PID Control*, 2006, ch. 3). No expected value is taken
from a run of the block.

Most behaviour tests run twice, through the ``make`` fixture: with the compiled (numba) kernel
and with the interpreted kernel.
"""

from __future__ import annotations

import csv
import io
import math
import random
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
from tests.csvfiles import write_csv
from tests.properties.test_controller_properties import raw_step

NAN = math.nan
INF = math.inf

# Status bytes, written out from the Fieldbus encoding (quality << 6 | substatus << 2 | limits).
GOOD = 0x80  # 128 Good non-cascade, not limited
GOOD_LOW = 0x81  # 129 low limited
GOOD_HIGH = 0x82  # 130 high limited
GOOD_CONST = 0x83  # 131 constant (MAN, tracking)
UNC = 0x40  # Uncertain non-specific
UNC_LUV_CONST = 0x47  # Uncertain, last usable value, constant
UNC_SUBST_CONST = 0x4B  # Uncertain, substitute, constant

Make = Callable[..., Block]


def approx(x: float) -> Any:
    return pytest.approx(x, abs=1e-12, rel=1e-12)


@pytest.fixture(params=[True, False], ids=["compiled", "interpreted"])
def make(request: pytest.FixtureRequest) -> Make:
    """``make(**params)``: a pid block with the compiled or the interpreted kernel."""
    jit = request.param

    def _make(**params: Any) -> Block:
        return loopworks.create_block("pid", jit=jit, **params)

    return _make


def out(block: Block, dt: float, **inputs: Any) -> float:
    return float(block.step(dt, **inputs)["out"].value)


def terms(block: Block, dt: float, **inputs: Any) -> tuple[float, float, float, float, int]:
    """(out, p_term, i_term, d_term, out status) of one scan."""
    r = block.step(dt, **inputs)
    return (float(r["out"].value), float(r["p_term"].value), float(r["i_term"].value),
            float(r["d_term"].value), int(r["out"].status))


# ----------------------------------------------------------------------------------------------
# An independent textbook reference, written from the docstring equations (AUTO, good inputs)
# ----------------------------------------------------------------------------------------------
class ReferencePID:
    """Discrete PID from the docstring:

        P_k = s·kp·(b·SP_k - PV_k)
        D_k = (Tf·D_{k-1} + s·kd·(d_k - d_{k-1})) / (Tf + dt),  d = c·SP - PV
        ΔI_k = s·ki·dt·(SP_k - PV_k)  [+ min(dt/Tt, 1)·(u_{k-1} - v_{k-1}) with back-calculation]
        positional: I_k = I_{k-1} + ΔI_k;  v_k = P_k + I_k + D_k + ff_k + bias
        velocity:   v_k = A_{k-1} + ΔP + ΔI + ΔD + Δff;  A_k = u_k (clamping) or v_k (none)
        u_k = ratelimit(clamp(v_k, lo, hi), u_{k-1}, rate·dt)   (no rate limit on scan 0)

    Positional ``clamping`` is deliberately not modelled here (the hand-computed tests pin it).
    """

    def __init__(self, *, kp: float, ki: float, kd: float, tf: float, s: float = 1.0,
                 b: float = 1.0, c: float = 0.0, velocity: bool = False,
                 antiwindup: str = "none", tt: float = INF, lo: float = -1e9, hi: float = 1e9,
                 rate: float = INF, bias: float = 0.0) -> None:
        if antiwindup == "clamping" and not velocity:
            raise ValueError("positional clamping is pinned by hand-computed tests instead")
        self.kp, self.ki, self.kd, self.tf, self.s, self.b, self.c = kp, ki, kd, tf, s, b, c
        self.velocity, self.aw, self.tt = velocity, antiwindup, tt
        self.lo, self.hi, self.rate, self.bias = lo, hi, rate, bias
        self.started = False
        self.i = 0.0
        self.d_filt = 0.0
        self.d_prev = 0.0
        self.u = min(max(bias, lo), hi)
        self.v = self.u
        self.acc = bias
        self.p_prev = 0.0
        self.dout_prev = 0.0
        self.ff_prev = 0.0

    def step(self, dt: float, sp: float, pv: float, ff: float = 0.0) -> float:
        s = self.s
        p = s * self.kp * (self.b * sp - pv)
        d = self.c * sp - pv
        if not self.started:
            self.d_prev = d
        dterm = (self.tf * self.d_filt + s * self.kd * (d - self.d_prev)) / (self.tf + dt)
        di = s * self.ki * dt * (sp - pv)
        if self.aw == "back_calculation":
            di += min(dt / self.tt, 1.0) * (self.u - self.v)
        if self.velocity:
            v = (self.acc + (p - self.p_prev) + di + (dterm - self.dout_prev)
                 + (ff - self.ff_prev))
        else:
            v = p + self.i + di + dterm + ff + self.bias
        u = min(max(v, self.lo), self.hi)
        if self.started:
            u = min(max(u, self.u - self.rate * dt), self.u + self.rate * dt)
        if self.velocity:
            self.acc = u if self.aw == "clamping" else v
        else:
            self.i += di
        self.d_filt, self.d_prev = dterm, d
        self.p_prev, self.dout_prev, self.ff_prev = p, dterm, ff
        self.u, self.v = u, v
        self.started = True
        return u


def random_scans(seed: int, n: int = 200) -> list[tuple[float, float, float, float]]:
    """(dt, sp, pv, ff) for n scans: setpoint steps, a wandering pv, a varying feedforward."""
    rng = random.Random(seed)
    scans = []
    sp, pv, ff = 50.0, 45.0, 0.0
    for _ in range(n):
        if rng.random() < 0.1:
            sp = rng.uniform(20.0, 80.0)
        pv += rng.uniform(-3.0, 3.0)
        if rng.random() < 0.2:
            ff = rng.uniform(-5.0, 5.0)
        scans.append((rng.uniform(0.05, 0.5), sp, pv, ff))
    return scans


def test_reference_implementation_self_check() -> None:
    """The reference itself reproduces a hand-computed PI first and second scan."""
    ref = ReferencePID(kp=2.0, ki=0.2, kd=0.0, tf=0.0)
    assert ref.step(0.1, 50.0, 40.0) == approx(2.0 * 10 + 0.2 * 0.1 * 10)
    assert ref.step(0.1, 50.0, 40.0) == approx(2.0 * 10 + 2 * 0.2 * 0.1 * 10)


# ----------------------------------------------------------------------------------------------
# Forms: ideal, parallel, series; defaults; mixing parameter sets
# ----------------------------------------------------------------------------------------------
def test_ideal_form_pid_three_scans(make: Make) -> None:
    """Ideal: kp = K, ki = K/Ti, kd = K·Td, Tf = Td/10 (n default); all three terms by hand."""
    blk = make(k=2.0, ti=10.0, td=1.0, out_lo=-100.0)  # kp 2, ki 0.2, kd 2, Tf 0.1
    # scan 0: P = 2·(50-40) = 20, I = 0.2·0.1·10 = 0.2, D = 0 (d_{-1} = d_0)
    assert terms(blk, 0.1, sp=50.0, pv=40.0) == (approx(20.2), approx(20.0), approx(0.2),
                                                 approx(0.0), GOOD)
    # scan 1: pv 42: P = 16, I = 0.2 + 0.2·0.1·8 = 0.36, D = (0.1·0 + 2·(-42+40))/(0.1+0.1) = -20
    assert terms(blk, 0.1, pv=42.0) == (approx(16.0 + 0.36 - 20.0), approx(16.0), approx(0.36),
                                        approx(-20.0), GOOD)
    # scan 2: pv unchanged: I = 0.52, D = (0.1·(-20) + 0)/0.2 = -10
    assert terms(blk, 0.1, pv=42.0) == (approx(16.0 + 0.52 - 10.0), approx(16.0), approx(0.52),
                                        approx(-10.0), GOOD)


def test_parallel_form(make: Make) -> None:
    """Parallel: kp, ki, kd used directly; Tf = (kd/kp)/n."""
    blk = make(form="parallel", kp=4.0, ki=0.5, kd=1.0, n=5.0)  # Td = 0.25, Tf = 0.05
    assert blk.gains() == (approx(4.0), approx(0.5), approx(1.0))  # type: ignore[attr-defined]
    # scan 0: P = 4·6 = 24, I = 0.5·0.1·6 = 0.3
    assert out(blk, 0.1, sp=10.0, pv=4.0) == approx(24.3)
    # scan 1: P = 4·5 = 20, I = 0.3 + 0.5·0.1·5 = 0.55, D = (0.05·0 + 1·(-5+4))/(0.05+0.1)
    r = terms(blk, 0.1, pv=5.0)
    assert r[0] == approx(20.0 + 0.55 - 1.0 / 0.15)
    assert r[1:4] == (approx(20.0), approx(0.55), approx(-1.0 / 0.15))


def test_series_form_uses_the_textbook_conversion(make: Make) -> None:
    """Series K'=2, Ti'=8, Td'=2 -> K = 2·(1+2/8) = 2.5, Ti = 10, Td = 8·2/10 = 1.6, Tf = 0.16."""
    blk = make(form="series", k=2.0, ti=8.0, td=2.0, out_lo=-100.0)
    kp, ki, kd = 2.5, 2.5 / 10.0, 2.5 * 1.6
    assert blk.gains() == (approx(kp), approx(ki), approx(kd))  # type: ignore[attr-defined]
    # scan 0: P = 2.5·10 = 25, I = 0.25·0.1·10 = 0.25
    assert out(blk, 0.1, sp=50.0, pv=40.0) == approx(25.25)
    # scan 1: P = 2.5·9 = 22.5, I = 0.25 + 0.025·9 = 0.475, D = (0 + 4·(-1))/(0.16 + 0.1)
    assert out(blk, 0.1, pv=41.0) == approx(22.5 + 0.475 - 4.0 / 0.26)


def test_series_form_without_integral_is_ideal_pd(make: Make) -> None:
    """Series with Ti' = inf: K = K', Td = Td' (no conversion); n = inf: D = K·Td·Δd/dt."""
    blk = make(form="series", k=2.0, td=1.0, n=INF, out_lo=-100.0)
    assert blk.gains() == (approx(2.0), approx(0.0), approx(2.0))  # type: ignore[attr-defined]
    assert out(blk, 0.1, sp=50.0, pv=40.0) == approx(20.0)
    # P = 2·9 = 18, D = 2·1·(-1)/0.1 = -20
    assert out(blk, 0.1, pv=41.0) == approx(18.0 - 20.0)


def test_series_form_without_derivative_equals_ideal(make: Make) -> None:
    """Series with Td' = 0: K = K'(1 + 0) = K', Ti = Ti'."""
    blk = make(form="series", k=2.0, ti=8.0)
    assert blk.gains() == (approx(2.0), approx(0.25), approx(0.0))  # type: ignore[attr-defined]
    assert out(blk, 1.0, sp=50.0, pv=40.0) == approx(2.0 * 10 + 0.25 * 1.0 * 10)


def test_ti_default_inf_means_no_integral(make: Make) -> None:
    """ti defaults to inf: ki = 0, a constant error gives a constant P-only output."""
    blk = make(k=2.0)
    for _ in range(5):
        o, p, i, d, st = terms(blk, 0.1, sp=50.0, pv=40.0)
        assert (o, p, i, d, st) == (approx(20.0), approx(20.0), approx(0.0), approx(0.0), GOOD)


def test_all_defaults_give_unit_proportional(make: Make) -> None:
    """Defaults k = 1, ti = inf, td = 0: out = SP - PV."""
    blk = make()
    assert out(blk, 0.1, sp=30.0, pv=10.0) == approx(20.0)


@pytest.mark.parametrize(("params", "name"), [
    ({"k": 2.0, "ki": 0.1}, "ki"),
    ({"kp": 2.0}, "kp"),
    ({"form": "ideal", "k": 1.0, "kd": 0.5}, "kd"),
    ({"form": "series", "kp": 1.0}, "kp"),
    ({"form": "parallel", "kp": 1.0, "ti": 5.0}, "ti"),
    ({"form": "parallel", "k": 1.0}, "k"),
])
def test_mixing_ideal_and_parallel_sets_is_an_error(params: dict[str, Any], name: str) -> None:
    """Giving a parameter of the other form's set raises ParameterError naming it."""
    with pytest.raises(ParameterError, match=f"'{name}'"):
        loopworks.create_block("pid", **params)


# ----------------------------------------------------------------------------------------------
# Action and setpoint weights
# ----------------------------------------------------------------------------------------------
def test_direct_action_flips_the_sign(make: Make) -> None:
    """Direct: s = -1, e = PV - SP; P = -kp·(b·SP - PV)."""
    direct = make(k=2.0, ti=10.0, action="direct", out_lo=-100.0)
    reverse = make(k=2.0, ti=10.0, action="reverse", out_lo=-100.0)
    # direct: P = -2·(50-60) = 20, I = 0.2·0.1·(60-50) = 0.2
    assert terms(direct, 0.1, sp=50.0, pv=60.0)[:3] == (approx(20.2), approx(20.0), approx(0.2))
    # reverse: P = 2·(50-60) = -20, I = 0.2·0.1·(50-60) = -0.2
    assert terms(reverse, 0.1, sp=50.0, pv=60.0)[:3] == (approx(-20.2), approx(-20.0),
                                                         approx(-0.2))


def test_direct_action_derivative_sign(make: Make) -> None:
    """Direct, n = inf: D = s·kd·Δ(c·SP - PV)/dt = -1·2·(-(62-60))/0.1 = +40 on a pv rise."""
    blk = make(k=2.0, td=1.0, n=INF, action="direct", out_hi=1000.0)
    assert out(blk, 0.1, sp=50.0, pv=60.0) == approx(20.0)
    # P = -2·(50-62) = 24, D = -2·(-62+60)/0.1 = 40
    assert out(blk, 0.1, pv=62.0) == approx(24.0 + 40.0)


def test_setpoint_weight_b(make: Make) -> None:
    """P = kp·(b·SP - PV), while I still integrates the full error SP - PV."""
    blk = make(k=2.0, ti=10.0, b=0.5, out_lo=-100.0)
    # P = 2·(0.5·50 - 40) = -30, I = 0.2·0.1·10 = 0.2
    assert terms(blk, 0.1, sp=50.0, pv=40.0)[:3] == (approx(-29.8), approx(-30.0), approx(0.2))
    # setpoint 60: P = 2·(30 - 40) = -20 (step of K·b·ΔSP = 10), I = 0.2 + 0.2·0.1·20 = 0.6
    assert terms(blk, 0.1, sp=60.0)[:3] == (approx(-19.4), approx(-20.0), approx(0.6))


@pytest.mark.parametrize("c", [0.0, 0.5, 1.0])
def test_derivative_kick_on_setpoint_step_scales_with_c(make: Make, c: float) -> None:
    """n = inf: D = K·Td·Δ(c·SP - PV)/dt; a setpoint step of 10 gives a kick of 100·c."""
    blk = make(k=1.0, td=1.0, n=INF, c=c, out_lo=-1000.0, out_hi=1000.0)
    assert out(blk, 0.1, sp=0.0, pv=0.0) == approx(0.0)
    o, p, _, d, _ = terms(blk, 0.1, sp=10.0)
    assert d == approx(1.0 * 1.0 * c * 10.0 / 0.1)
    assert o == approx(10.0 + 100.0 * c)
    assert p == approx(10.0)
    # the next scan, with no change, the unfiltered derivative is 0 again
    assert out(blk, 0.1) == approx(10.0)


def test_default_c_is_derivative_on_pv(make: Make) -> None:
    """c defaults to 0: no derivative kick on a setpoint step, full derivative on a pv change."""
    blk = make(k=1.0, td=1.0, n=INF, out_lo=-1000.0, out_hi=1000.0)
    out(blk, 0.1, sp=0.0, pv=0.0)
    assert terms(blk, 0.1, sp=10.0)[3] == approx(0.0)
    assert terms(blk, 0.1, pv=1.0)[3] == approx(-1.0 / 0.1)


# ----------------------------------------------------------------------------------------------
# Derivative filter
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("filt", "tf"), [
    ({}, 0.05),  # Tf = Td/10 with Td = 0.5
    ({"n": 5.0}, 0.1),  # Tf = Td/5
    ({"tf": 0.2}, 0.2),  # explicit
    ({"n": INF}, 0.0),  # no filter
    ({"tf": 0.0}, 0.0),  # explicit: no filter
])
def test_derivative_filter_backward_euler_recurrence(make: Make, filt: dict[str, float],
                                                     tf: float) -> None:
    """D_k = (Tf·D_{k-1} + s·kd·(d_k - d_{k-1}))/(Tf + dt), d = -PV, kd = 2·0.5 = 1."""
    blk = make(k=2.0, td=0.5, out_lo=-1000.0, out_hi=1000.0, **filt)
    dt = 0.1
    pvs = [0.0, 1.0, 3.0, 3.0, 2.0]
    d1 = (tf * 0.0 + 1.0 * (-1.0 - 0.0)) / (tf + dt)
    d2 = (tf * d1 + 1.0 * (-3.0 + 1.0)) / (tf + dt)
    d3 = (tf * d2 + 1.0 * (-3.0 + 3.0)) / (tf + dt)
    d4 = (tf * d3 + 1.0 * (-2.0 + 3.0)) / (tf + dt)
    expected_d = [0.0, d1, d2, d3, d4]
    for pv, dk in zip(pvs, expected_d, strict=True):
        o, p, i, d, _ = terms(blk, dt, sp=0.0, pv=pv)
        assert d == approx(dk)
        assert p == approx(-2.0 * pv)
        assert i == approx(0.0)
        assert o == approx(-2.0 * pv + dk)


def test_unfiltered_derivative_by_hand(make: Make) -> None:
    """n = inf: D = K·Td·Δd/dt = 2·0.5·(-Δpv)/0.1: -10, -20, 0, +10 for pv 0, 1, 3, 3, 2."""
    blk = make(k=2.0, td=0.5, n=INF, out_lo=-1000.0, out_hi=1000.0)
    out(blk, 0.1, pv=0.0)
    assert [terms(blk, 0.1, pv=pv)[3] for pv in (1.0, 3.0, 3.0, 2.0)] == [
        approx(-10.0), approx(-20.0), approx(0.0), approx(10.0)]


def test_n_and_tf_together_is_an_error() -> None:
    """The filter is given by n or by tf, not both."""
    with pytest.raises(ParameterError, match=r"'n'.*'tf'"):
        loopworks.create_block("pid", k=1.0, td=1.0, n=8.0, tf=0.1)


def test_parallel_pure_id_needs_tf() -> None:
    """kp = 0 with kd > 0: Td = kd/kp is undefined, so Tf = Td/n is refused; tf works."""
    with pytest.raises(ParameterError, match="'tf'"):
        loopworks.create_block("pid", form="parallel", kp=0.0, ki=0.5, kd=1.0)
    blk = loopworks.create_block("pid", form="parallel", kp=0.0, kd=1.0, tf=0.1,
                                 out_lo=-100.0)
    out(blk, 0.1, sp=0.0, pv=0.0)
    assert out(blk, 0.1, pv=1.0) == approx((0.1 * 0.0 + 1.0 * -1.0) / (0.1 + 0.1))


# ----------------------------------------------------------------------------------------------
# Integral discretisation
# ----------------------------------------------------------------------------------------------
def test_integral_is_backward_euler(make: Make) -> None:
    """I_k = I_{k-1} + ki·dt_k·e_k with the current error and the current dt."""
    blk = make(k=2.0, ti=10.0)  # ki = 0.2
    # scan 0 already integrates: I = 0.2·0.1·10
    assert terms(blk, 0.1, sp=50.0, pv=40.0)[2] == approx(0.2)
    # dt 0.5, e = 5: I = 0.2 + 0.2·0.5·5 = 0.7 (forward Euler would give 0.2 + 0.2·0.5·10)
    o, p, i, _, _ = terms(blk, 0.5, pv=45.0)
    assert (o, p, i) == (approx(10.7), approx(10.0), approx(0.7))
    # dt 0.25: I = 0.7 + 0.2·0.25·5 = 0.95
    assert out(blk, 0.25) == approx(10.0 + 0.95)


# ----------------------------------------------------------------------------------------------
# Positional vs velocity algorithm
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", [1, 2, 3])
@pytest.mark.parametrize("action", ["reverse", "direct"])
def test_positional_and_velocity_agree_while_unlimited(make: Make, seed: int,
                                                       action: str) -> None:
    """Without limits both algorithms give the textbook output of the reference, scan by scan."""
    params = dict(k=1.5, ti=4.0, td=0.8, n=8.0, b=0.7, c=0.3, bias=5.0, action=action,
                  out_lo=-1e6, out_hi=1e6)
    pos = make(algorithm="positional", **params)
    vel = make(algorithm="velocity", **params)
    ref = ReferencePID(kp=1.5, ki=1.5 / 4.0, kd=1.5 * 0.8, tf=0.8 / 8.0, b=0.7, c=0.3,
                       bias=5.0, s=1.0 if action == "reverse" else -1.0)
    for dt, sp, pv, ff in random_scans(seed):
        expected = ref.step(dt, sp, pv, ff)
        o_pos = out(pos, dt, sp=sp, pv=pv, ff=ff)
        o_vel = out(vel, dt, sp=sp, pv=pv, ff=ff)
        assert o_pos == pytest.approx(expected, rel=1e-9, abs=1e-9)
        assert o_vel == pytest.approx(expected, rel=1e-9, abs=1e-9)


@pytest.mark.parametrize(("algorithm", "antiwindup"), [
    ("positional", "none"),
    ("positional", "back_calculation"),
    ("velocity", "none"),
    ("velocity", "clamping"),
])
def test_limited_outputs_follow_the_reference(make: Make, algorithm: str,
                                              antiwindup: str) -> None:
    """With output and rate limits active, the block follows the docstring equations."""
    kw: dict[str, Any] = {"tt": 1.5} if antiwindup == "back_calculation" else {}
    blk = make(k=3.0, ti=2.0, td=0.3, algorithm=algorithm, antiwindup=antiwindup,
               out_lo=0.0, out_hi=60.0, rate_limit=40.0, **kw)
    ref = ReferencePID(kp=3.0, ki=1.5, kd=0.9, tf=0.03, velocity=algorithm == "velocity",
                       antiwindup=antiwindup, tt=1.5, lo=0.0, hi=60.0, rate=40.0)
    limited = 0
    for k, (dt, sp, pv, ff) in enumerate(random_scans(7)):
        expected = ref.step(dt, sp, pv, ff)
        limited += expected in (0.0, 60.0)
        got = out(blk, dt, sp=sp, pv=pv, ff=ff)
        assert got == pytest.approx(expected, rel=1e-9, abs=1e-9), f"scan {k}"
    assert limited > 10  # the run does exercise the limits


# ----------------------------------------------------------------------------------------------
# Anti-windup
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("algorithm", ["positional", "velocity"])
def test_clamping_vs_none_at_the_high_limit(make: Make, algorithm: str) -> None:
    """K = 2, Ti = 8 (ki 0.25), dt 1, e = 10: P = 20, ΔI = 2.5 per scan, out_hi = 30.

    Clamping: I stops at 10 once the output sits at 30, so a setpoint drop leaves the limit at
    once. None: I (or the velocity accumulator) keeps winding up by 2.5 per scan.
    """
    clamp = make(k=2.0, ti=8.0, out_hi=30.0, out_lo=-100.0, algorithm=algorithm)
    none = make(k=2.0, ti=8.0, out_hi=30.0, out_lo=-100.0, algorithm=algorithm,
                antiwindup="none")
    for blk in (clamp, none):
        assert [terms(blk, 1.0, sp=50.0, pv=40.0)[0::2] for _ in range(4)] == [
            (approx(22.5), approx(2.5), GOOD), (approx(25.0), approx(5.0), GOOD),
            (approx(27.5), approx(7.5), GOOD), (approx(30.0), approx(10.0), GOOD_HIGH)]
    for k in range(4, 10):
        o_c, _, i_c, _, st_c = terms(clamp, 1.0)
        o_n, _, i_n, _, st_n = terms(none, 1.0)
        assert (o_c, i_c, st_c) == (approx(30.0), approx(10.0), GOOD_HIGH)
        assert (o_n, i_n, st_n) == (approx(30.0), approx(10.0 + 2.5 * (k - 3)), GOOD_HIGH)
    # setpoint 35: e = -5, P = -10, ΔI = -1.25
    assert terms(clamp, 1.0, sp=35.0)[0::2] == (approx(-10.0 + 8.75), approx(8.75), GOOD)
    assert terms(none, 1.0, sp=35.0)[0::2] == (approx(-10.0 + 23.75), approx(23.75), GOOD)


@pytest.mark.parametrize("algorithm", ["positional", "velocity"])
def test_clamping_lets_a_persistent_error_reach_the_limit(make: Make, algorithm: str) -> None:
    """Conditional integration stops integrating once the output is AT the limit; it must not
    stop the output short of it. K = 2, Ti = 8, e = 10, out_hi = 31: 22.5, 25, 27.5, 30, then
    v = 32.5 -> u = 31 (high limited) and it stays there (velocity: A_k = u_k = 31)."""
    blk = make(k=2.0, ti=8.0, out_hi=31.0, algorithm=algorithm)
    got = [tuple(blk.step(1.0, sp=50.0, pv=40.0)["out"]) for _ in range(8)]
    assert got == [(approx(22.5), GOOD), (approx(25.0), GOOD), (approx(27.5), GOOD),
                   (approx(30.0), GOOD)] + [(approx(31.0), GOOD_HIGH)] * 4


@pytest.mark.parametrize("algorithm", ["positional", "velocity"])
def test_clamping_first_scan_beyond_the_limit(make: Make, algorithm: str) -> None:
    """Scan 0 with P = 60, ΔI = ki·dt·e = 60 gives v = 120: u = out_hi = 100 (130), for both
    algorithms (the output is the limited v; it must not fall back to P = 60 with status 128).
    Velocity/clamping: A_0 = u_0 = 100, so on a reversal (pv 70: ΔP = -70, ΔI = -10)
    v = 100 - 70 - 10 = 20."""
    blk = make(k=1.0, ti=1.0, algorithm=algorithm)
    assert tuple(blk.step(1.0, sp=60.0, pv=0.0)["out"]) == (approx(100.0), GOOD_HIGH)
    if algorithm == "velocity":
        assert out(blk, 1.0, pv=70.0) == approx(100.0 - 70.0 - 10.0)


def test_velocity_clamping_keeps_the_integral_step_at_a_partial_limit(make: Make) -> None:
    """Velocity, clamping: v_k = A_{k-1} + ΔP + ΔI, u_k = clamp(v_k), A_k = u_k.
    K = 2, Ti = 8, dt 1, out_hi = 30: scans 22.5, 25, 27.5, 30; then pv 40 -> 41 (e = 9):
    ΔP = -2, ΔI = 2.25, v = 30 - 2 + 2.25 = 30.25 -> u = 30 (high limited)."""
    blk = make(k=2.0, ti=8.0, out_hi=30.0, algorithm="velocity")
    for _ in range(4):
        blk.step(1.0, sp=50.0, pv=40.0)
    assert tuple(blk.step(1.0, pv=41.0)["out"]) == (approx(30.0), GOOD_HIGH)


def test_back_calculation_by_hand(make: Make) -> None:
    """I_k = I_{k-1} + ki·dt·e_k + dt/Tt·(u_{k-1} - v_{k-1}); K 2, Ti 8, Tt 2, out_hi 30."""
    blk = make(k=2.0, ti=8.0, antiwindup="back_calculation", tt=2.0, out_hi=30.0,
               out_lo=-100.0)
    seq = [terms(blk, 1.0, sp=50.0, pv=40.0) for _ in range(8)]
    i_hand = [2.5, 5.0, 7.5, 10.0,  # v 22.5 .. 30, u = v
              10.0 + 2.5 + 0.5 * (30.0 - 30.0),  # 12.5, v 32.5
              12.5 + 2.5 + 0.5 * (30.0 - 32.5),  # 13.75
              13.75 + 2.5 + 0.5 * (30.0 - 33.75),  # 14.375
              14.375 + 2.5 + 0.5 * (30.0 - 34.375)]  # 14.6875
    assert [r[2] for r in seq] == [approx(i) for i in i_hand]
    assert [r[0] for r in seq] == [approx(min(20.0 + i, 30.0)) for i in i_hand]
    assert [r[4] for r in seq] == [GOOD] * 3 + [GOOD_HIGH] * 5
    # setpoint 35: P = -10, I = 14.6875 - 1.25 + 0.5·(30 - 34.6875)
    i9 = 14.6875 - 1.25 + 0.5 * (30.0 - 34.6875)
    assert terms(blk, 1.0, sp=35.0)[0::2] == (approx(-10.0 + i9), approx(i9), GOOD)


def test_back_calculation_gain_is_capped_at_one(make: Make) -> None:
    """dt > Tt: forward Euler of dI/dt = (u - v)/Tt would overshoot (gain dt/Tt = 4 here, and
    diverge beyond 2); the tracking gain is capped at 1, so v is realigned to u in one scan.
    K 2, Ti 8, Tt 0.25, dt 1, out_hi 30, e = 10: P = 20, ki·dt·e = 2.5."""
    blk = make(k=2.0, ti=8.0, antiwindup="back_calculation", tt=0.25, out_hi=30.0,
               out_lo=-100.0)
    seq = [terms(blk, 1.0, sp=50.0, pv=40.0) for _ in range(7)]
    # I 2.5 .. 10 (u = v), then 12.5 (v 32.5), then 12.5 + 2.5 + 1·(30 - 32.5) = 12.5 for good
    i_hand = [2.5, 5.0, 7.5, 10.0, 12.5, 12.5, 12.5]
    assert [r[2] for r in seq] == [approx(i) for i in i_hand]
    assert [r[0] for r in seq] == [approx(min(20.0 + i, 30.0)) for i in i_hand]


def test_back_calculation_tiny_tt_keeps_a_transfer_bumpless(make: Make) -> None:
    """Regression (found by the property test of tracking -> AUTO): tt = 6e-56 s made
    dt/Tt = 1.6e55, so the rounding residue of u - v after the bumpless re-initialisation
    (about 1e-17) became an output jump to the rate limit. PD only (ki 0), b 0, kd 0.2."""
    blk = make(form="parallel", kp=1.5, ki=0.0, kd=0.2, tf=0.05, b=0.0, rate_limit=20.0,
               antiwindup="back_calculation", tt=6.175991220068118e-56)
    blk.step(1.0, track=1.0, track_value=0.0, pv=0.0)
    outs = [blk.step(1.0, track=0.0, sp=1.0, pv=1.0, ff=0.01)["out"].value for _ in range(5)]
    assert outs == [approx(0.0)] * 5


@pytest.mark.parametrize(("params", "tt"), [
    ({"k": 2.0, "ti": 8.0, "td": 2.0}, math.sqrt(8.0 * 2.0)),  # Td > 0: sqrt(Ti·Td) = 4
    ({"k": 2.0, "ti": 8.0}, 8.0),  # Td = 0: Ti
    ({"form": "parallel", "kp": 2.0, "ki": 0.25, "kd": 4.0}, 4.0),  # Ti = 8, Td = 2
])
def test_back_calculation_default_tracking_time(make: Make, params: dict[str, Any],
                                                tt: float) -> None:
    """Default Tt = sqrt(Ti·Td) if Td > 0 else Ti. Constant pv, so D = 0 throughout."""
    blk = make(antiwindup="back_calculation", out_hi=30.0, **params)
    for _ in range(5):  # I: 2.5, 5, 7.5, 10, 12.5 (u_{k-1} = v_{k-1} until scan 4)
        blk.step(1.0, sp=50.0, pv=40.0)
    i5 = 12.5 + 2.5 + (30.0 - 32.5) / tt
    i6 = i5 + 2.5 + (30.0 - (20.0 + i5)) / tt
    assert terms(blk, 1.0)[2] == approx(i5)
    assert terms(blk, 1.0)[2] == approx(i6)


def test_pure_integral_parallel_with_back_calculation_is_handled() -> None:
    """Parallel kp = 0, ki = 0.5 (pure I) with back_calculation and no tt: Ti = kp/ki = 0, so
    the default rule gives Tt = 0. The block must pick a usable Tt or raise ParameterError
    (naming tt), never a bare arithmetic exception. Scan 0 is then ki·dt·e = 0.5·1·2 = 1."""
    try:
        blk = loopworks.create_block("pid", form="parallel", kp=0.0, ki=0.5,
                                     antiwindup="back_calculation")
    except ParameterError as exc:
        assert "tt" in str(exc)
        return
    assert out(blk, 1.0, sp=10.0, pv=8.0) == approx(1.0)


def test_velocity_with_back_calculation_is_an_error() -> None:
    """The velocity algorithm supports clamping and none only."""
    with pytest.raises(ParameterError, match="antiwindup"):
        loopworks.create_block("pid", k=1.0, ti=5.0, algorithm="velocity",
                               antiwindup="back_calculation")


# ----------------------------------------------------------------------------------------------
# Output limits, status bits, rate limit
# ----------------------------------------------------------------------------------------------
def test_output_clamp_and_limit_status_bits(make: Make) -> None:
    """u = clamp(v, out_lo, out_hi); 130 at out_hi, 129 at out_lo, 128 in between."""
    blk = make(k=1.0, out_lo=-10.0, out_hi=10.0)
    assert tuple(blk.step(0.1, sp=20.0, pv=0.0)["out"]) == (approx(10.0), GOOD_HIGH)
    assert tuple(blk.step(0.1, sp=-20.0)["out"]) == (approx(-10.0), GOOD_LOW)
    assert tuple(blk.step(0.1, sp=5.0)["out"]) == (approx(5.0), GOOD)
    assert tuple(blk.step(0.1, sp=10.0)["out"]) == (approx(10.0), GOOD_HIGH)  # exactly at hi
    assert tuple(blk.step(0.1, sp=-10.0)["out"]) == (approx(-10.0), GOOD_LOW)


def test_default_limits_are_0_and_100(make: Make) -> None:
    """out_lo = 0, out_hi = 100 by default."""
    blk = make(k=1.0)
    assert tuple(blk.step(0.1, sp=150.0, pv=0.0)["out"]) == (approx(100.0), GOOD_HIGH)
    assert tuple(blk.step(0.1, sp=-5.0)["out"]) == (approx(0.0), GOOD_LOW)


@pytest.mark.parametrize(("lo", "hi"), [(5.0, 5.0), (10.0, 0.0)])
def test_out_lo_not_below_out_hi_is_an_error(lo: float, hi: float) -> None:
    """out_lo >= out_hi raises ParameterError naming out_hi."""
    with pytest.raises(ParameterError, match="'out_hi'"):
        loopworks.create_block("pid", out_lo=lo, out_hi=hi)


@pytest.mark.parametrize("algorithm", ["positional", "velocity"])
def test_rate_limit_p_only(make: Make, algorithm: str) -> None:
    """rate_limit 2 /s, dt 0.5: at most 1 per scan after the first scan (which is free)."""
    blk = make(k=1.0, rate_limit=2.0, algorithm=algorithm, antiwindup="none")
    assert out(blk, 0.5, sp=10.0, pv=0.0) == approx(10.0)  # first scan: 0 -> 10 allowed
    assert out(blk, 0.5, sp=20.0) == approx(11.0)
    assert out(blk, 0.5) == approx(12.0)
    assert out(blk, 0.5, sp=11.5) == approx(11.5)  # within one step: not limited
    assert out(blk, 0.5, sp=0.0) == approx(10.5)
    assert out(blk, 1.5) == approx(7.5)  # dt 1.5: step 3


@pytest.mark.parametrize("antiwindup", ["clamping", "none"])
@pytest.mark.parametrize("algorithm", ["positional", "velocity"])
def test_rate_limited_pi_ramps_at_the_rate(make: Make, algorithm: str, antiwindup: str) -> None:
    """K 1, Ti 1, dt 1, rate 1/s, e = 10: scan 0 gives P + I = 10 + 10 = 20 (no rate limit);
    the wanted output then keeps rising by 10/scan, so the output ramps by exactly 1 per scan:
    21, 22, 23, 24 (conditional integration may stop I, but not the ramp)."""
    blk = make(k=1.0, ti=1.0, rate_limit=1.0, algorithm=algorithm, antiwindup=antiwindup)
    assert [out(blk, 1.0, sp=10.0, pv=0.0) for _ in range(5)] == [
        approx(20.0), approx(21.0), approx(22.0), approx(23.0), approx(24.0)]


def test_rate_limit_does_not_act_in_man(make: Make) -> None:
    """Rate limiting acts in AUTO and CAS only: MAN jumps at once."""
    blk = make(k=1.0, rate_limit=1.0)
    out(blk, 1.0, sp=5.0, pv=0.0)
    assert out(blk, 1.0, mode="MAN", man_out=80.0) == approx(80.0)


# ----------------------------------------------------------------------------------------------
# Dead bands, bias, feedforward
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("algorithm", ["positional", "velocity"])
def test_integral_deadband(make: Make, algorithm: str) -> None:
    """ΔI = 0 while abs(e) < i_deadband (2); K 1, Ti 1, dt 1; P still acts."""
    blk = make(k=1.0, ti=1.0, i_deadband=2.0, out_lo=-100.0, algorithm=algorithm)
    assert out(blk, 1.0, sp=10.0, pv=9.0) == approx(1.0)  # e 1: P 1, I 0
    assert out(blk, 1.0) == approx(1.0)  # frozen
    assert out(blk, 1.0, pv=7.0) == approx(3.0 + 3.0)  # e 3: I = 3
    assert out(blk, 1.0, pv=8.5) == approx(1.5 + 3.0)  # e 1.5: frozen
    assert out(blk, 1.0, pv=8.0) == approx(2.0 + 5.0)  # e = 2 is not < 2: I = 5
    assert out(blk, 1.0, pv=11.0) == approx(-1.0 + 5.0)  # e -1: frozen


def test_integral_deadband_also_freezes_back_calculation(make: Make) -> None:
    """"i_deadband freezes the integral": with back_calculation too. K 1, Ti 1, Tt 1, dt 1,
    out_hi 10, e = 1 < i_deadband 5, ff 20 saturates: v = 1 + 0 + 20 = 21, u = 10. The integral
    stays 0, so when ff goes back to 0 the output is P + I = 1."""
    blk = make(k=1.0, ti=1.0, antiwindup="back_calculation", tt=1.0, i_deadband=5.0,
               out_hi=10.0)
    assert tuple(blk.step(1.0, sp=10.0, pv=9.0, ff=20.0)["out"]) == (approx(10.0), GOOD_HIGH)
    assert terms(blk, 1.0)[0::2] == (approx(10.0), approx(0.0), GOOD_HIGH)
    assert out(blk, 1.0, ff=0.0) == approx(1.0)


@pytest.mark.parametrize("algorithm", ["positional", "velocity"])
def test_error_deadband_holds_then_resumes_bumplessly(make: Make, algorithm: str) -> None:
    """Output held while abs(e) < e_deadband (1); the first scan outside the band gives
    held output + ki·dt·e. K 2, Ti 4 (ki 0.5), dt 1."""
    blk = make(k=2.0, ti=4.0, e_deadband=1.0, out_lo=-100.0, algorithm=algorithm)
    assert out(blk, 1.0, sp=10.0, pv=5.0) == approx(10.0 + 2.5)  # P 10, I 2.5
    assert out(blk, 1.0, pv=9.5) == approx(12.5)  # e 0.5: held
    assert out(blk, 1.0, pv=10.8) == approx(12.5)  # e -0.8: held
    o, p, i, _, st = terms(blk, 1.0, pv=8.0)  # e 2: 12.5 + 0.5·1·2
    assert (o, p, i, st) == (approx(13.5), approx(4.0), approx(13.5 - 4.0), GOOD)
    assert out(blk, 1.0) == approx(4.0 + 9.5 + 1.0)  # normal again: I 10.5
    assert out(blk, 1.0, pv=12.0) == approx(-4.0 + 10.5 - 1.0)  # e -2: P -4, I 9.5


@pytest.mark.parametrize("algorithm", ["positional", "velocity"])
def test_bias_adds_to_the_output(make: Make, algorithm: str) -> None:
    """v = P + I + D + ff + bias; bias is not part of p_term or i_term."""
    blk = make(k=1.0, bias=10.0, algorithm=algorithm)
    o, p, i, _, _ = terms(blk, 0.1, sp=5.0, pv=3.0)
    assert (o, p, i) == (approx(12.0), approx(2.0), approx(0.0))
    assert out(blk, 0.1, pv=4.0) == approx(11.0)


@pytest.mark.parametrize("algorithm", ["positional", "velocity"])
def test_feedforward_adds_to_the_output(make: Make, algorithm: str) -> None:
    """u = P + ff (P-only): ff 7 -> 9, ff 10 -> 12, ff -4 -> -2 clamped to out_lo 0 (129).
    Then ff 1: positional P + ff = 3; velocity/clamping A = u = 0, so v = 0 + Δff = 0 + 5."""
    blk = make(k=1.0, algorithm=algorithm)
    assert out(blk, 0.1, sp=5.0, pv=3.0, ff=7.0) == approx(9.0)
    assert out(blk, 0.1, ff=10.0) == approx(12.0)
    assert tuple(blk.step(0.1, ff=-4.0)["out"]) == (approx(0.0), GOOD_LOW)
    expected = 2.0 + 1.0 if algorithm == "positional" else 0.0 + (1.0 - -4.0)
    assert out(blk, 0.1, ff=1.0) == approx(expected)


# ----------------------------------------------------------------------------------------------
# Modes and tracking
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("man", ["MAN", "man", 0])
def test_manual_mode(make: Make, man: Any) -> None:
    """MAN: out = clamp(man_out, out_lo, out_hi), status 131; NaN man_out holds."""
    blk = make(k=2.0, ti=10.0)
    assert tuple(blk.step(0.1, mode=man, man_out=42.0, sp=50.0, pv=40.0)["out"]) == (
        approx(42.0), GOOD_CONST)
    assert tuple(blk.step(0.1, man_out=150.0)["out"]) == (approx(100.0), GOOD_CONST)
    assert tuple(blk.step(0.1, man_out=NAN)["out"]) == (approx(100.0), GOOD_CONST)
    assert tuple(blk.step(0.1, man_out=-5.0)["out"]) == (approx(0.0), GOOD_CONST)
    assert tuple(blk.step(0.1, man_out=33.0)["out"]) == (approx(33.0), GOOD_CONST)
    assert tuple(blk.step(0.1, man_out=(70.0, 0))["out"]) == (approx(33.0), GOOD_CONST)


@pytest.mark.parametrize("algorithm", ["positional", "velocity"])
@pytest.mark.parametrize(("man", "auto"), [("MAN", "AUTO"), (0, 1)])
def test_man_to_auto_is_bumpless(make: Make, algorithm: str, man: Any, auto: Any) -> None:
    """First AUTO scan: out = last MAN output + ki·dt·e (no P bump, D restarts from 0).
    K 2, Ti 10, Td 1 (Tf 0.1), dt 0.1."""
    blk = make(k=2.0, ti=10.0, td=1.0, out_lo=-100.0, algorithm=algorithm)
    for _ in range(3):
        assert out(blk, 0.1, mode=man, man_out=30.0, sp=50.0, pv=40.0) == approx(30.0)
    o, p, i, d, st = terms(blk, 0.1, mode=auto)
    assert (o, p, i, d, st) == (approx(30.0 + 0.2 * 0.1 * 10), approx(20.0), approx(10.2),
                                approx(0.0), GOOD)
    # pv 41: P 18, I = 10.2 + 0.02·9, D = (0.1·0 + 2·(-1))/0.2 = -10
    assert terms(blk, 0.1, pv=41.0)[:4] == (approx(18.0 + 10.38 - 10.0), approx(18.0),
                                            approx(10.38), approx(-10.0))


def test_man_to_auto_without_integral_freezes_the_manual_reset(make: Make) -> None:
    """ti = inf: the re-initialised integral (30 - P) is a frozen manual reset."""
    blk = make(k=2.0)
    out(blk, 0.1, mode="MAN", man_out=30.0, sp=50.0, pv=40.0)
    assert out(blk, 0.1, mode="AUTO") == approx(30.0)
    assert out(blk, 0.1, pv=41.0) == approx(30.0 - 2.0)  # P 20 -> 18
    assert out(blk, 0.1) == approx(28.0)
    assert out(blk, 0.1, pv=40.0) == approx(30.0)


@pytest.mark.parametrize("cas", ["CAS", 2])
def test_cascade_mode_controls_to_cas_sp(make: Make, cas: Any) -> None:
    """CAS: the working setpoint is cas_sp; sp is ignored (even NaN)."""
    blk = make(k=2.0, ti=10.0)
    assert tuple(blk.step(0.1, mode=cas, cas_sp=50.0, sp=NAN, pv=40.0)["out"]) == (
        approx(20.2), GOOD)
    assert out(blk, 0.1, cas_sp=45.0) == approx(10.0 + 0.2 + 0.1)


def test_cascade_mode_with_bad_cas_sp_holds(make: Make) -> None:
    """CAS with cas_sp unset (NaN) is a bad working setpoint: hold, 0x47."""
    blk = make(k=2.0, ti=10.0)
    assert tuple(blk.step(0.1, sp=50.0, pv=40.0)["out"]) == (approx(20.2), GOOD)
    assert tuple(blk.step(0.1, mode="CAS")["out"]) == (approx(20.2), UNC_LUV_CONST)
    assert tuple(blk.step(0.1, cas_sp=(50.0, 0x10))["out"]) == (approx(20.2), UNC_LUV_CONST)
    # good cas_sp: bumpless resume, 20.2 + 0.2·0.1·5
    assert tuple(blk.step(0.1, cas_sp=45.0)["out"]) == (approx(20.3), GOOD)


@pytest.mark.parametrize("algorithm", ["positional", "velocity"])
def test_tracking_in_auto_and_bumpless_return(make: Make, algorithm: str) -> None:
    """track = 1: out = track_value (131); back to AUTO: track_value + ki·dt·e."""
    blk = make(k=2.0, ti=10.0, algorithm=algorithm)
    assert out(blk, 0.1, sp=50.0, pv=40.0) == approx(20.2)
    assert tuple(blk.step(0.1, track=1.0, track_value=25.0)["out"]) == (approx(25.0),
                                                                        GOOD_CONST)
    assert tuple(blk.step(0.1, track_value=26.0)["out"]) == (approx(26.0), GOOD_CONST)
    assert tuple(blk.step(0.1, track=0.0)["out"]) == (approx(26.0 + 0.2), GOOD)
    assert out(blk, 0.1) == approx(26.4)


def test_tracking_overrides_man(make: Make) -> None:
    """Tracking acts in any mode, MAN included; after it MAN again gives man_out."""
    blk = make(k=2.0, ti=10.0)
    assert out(blk, 0.1, mode="MAN", man_out=40.0) == approx(40.0)
    assert tuple(blk.step(0.1, track=1, track_value=25.0)["out"]) == (approx(25.0),
                                                                      GOOD_CONST)
    assert tuple(blk.step(0.1, track=0)["out"]) == (approx(40.0), GOOD_CONST)


# ----------------------------------------------------------------------------------------------
# Bad and uncertain inputs
# ----------------------------------------------------------------------------------------------
BAD_PVS = [NAN, INF, -INF, (40.0, 0), (40.0, 0x1C), (40.0, 0x10)]
BAD_IDS = ["nan", "+inf", "-inf", "bad-status", "bad-oos", "bad-sensor"]


@pytest.mark.parametrize("algorithm", ["positional", "velocity"])
@pytest.mark.parametrize("bad", BAD_PVS, ids=BAD_IDS)
def test_bad_pv_holds_and_recovers_bumplessly(make: Make, bad: Any, algorithm: str) -> None:
    """bad_pv = hold: output held with 0x47; recovery: held + ki·dt·e (no P bump)."""
    blk = make(k=2.0, ti=10.0, algorithm=algorithm)
    assert out(blk, 0.1, sp=50.0, pv=40.0) == approx(20.2)
    assert tuple(blk.step(0.1, pv=bad)["out"]) == (approx(20.2), UNC_LUV_CONST)
    assert tuple(blk.step(0.1)["out"]) == (approx(20.2), UNC_LUV_CONST)
    assert tuple(blk.step(0.1, pv=45.0)["out"]) == (approx(20.2 + 0.2 * 0.1 * 5), GOOD)
    assert out(blk, 0.1) == approx(20.3 + 0.1)


@pytest.mark.parametrize("bad", BAD_PVS, ids=BAD_IDS)
def test_bad_pv_safe_goes_to_safe_out(make: Make, bad: Any) -> None:
    """bad_pv = safe: out = safe_out (default out_lo) with 0x4B; recovery from safe_out."""
    blk = make(k=2.0, ti=10.0, bad_pv="safe")
    assert out(blk, 0.1, sp=50.0, pv=40.0) == approx(20.2)
    assert tuple(blk.step(0.1, pv=bad)["out"]) == (approx(0.0), UNC_SUBST_CONST)
    blk = make(k=2.0, ti=10.0, bad_pv="safe", safe_out=15.0, out_lo=-5.0)
    assert out(blk, 0.1, sp=50.0, pv=40.0) == approx(20.2)
    assert tuple(blk.step(0.1, pv=bad)["out"]) == (approx(15.0), UNC_SUBST_CONST)
    assert tuple(blk.step(0.1, pv=45.0)["out"]) == (approx(15.0 + 0.1), GOOD)


def test_bad_setpoint_or_feedforward_holds(make: Make) -> None:
    """A non-finite or Bad sp (AUTO) or ff also holds the output (0x47)."""
    blk = make(k=2.0, ti=10.0)
    assert out(blk, 0.1, sp=50.0, pv=40.0) == approx(20.2)
    assert tuple(blk.step(0.1, sp=NAN)["out"]) == (approx(20.2), UNC_LUV_CONST)
    assert tuple(blk.step(0.1, sp=(50.0, 0))["out"]) == (approx(20.2), UNC_LUV_CONST)
    assert tuple(blk.step(0.1, sp=50.0, ff=(0.0, 0))["out"]) == (approx(20.2), UNC_LUV_CONST)
    assert tuple(blk.step(0.1, ff=INF)["out"]) == (approx(20.2), UNC_LUV_CONST)
    assert tuple(blk.step(0.1, ff=0.0)["out"]) == (approx(20.4), GOOD)


@pytest.mark.parametrize("port", ["pv", "sp", "ff"])
@pytest.mark.parametrize("uncertain", [0x40, 0x44, 0x50])
def test_uncertain_input_is_used_and_out_is_uncertain(make: Make, port: str,
                                                      uncertain: int) -> None:
    """Uncertain inputs are used; out status = 0x40 (+ limit bits)."""
    values = {"sp": 50.0, "pv": 40.0, "ff": 0.0}
    inputs: dict[str, Any] = dict(values)
    inputs[port] = (values[port], uncertain)
    blk = make(k=2.0, ti=10.0)
    assert tuple(blk.step(0.1, **inputs)["out"]) == (approx(20.2), UNC)
    hi = make(k=20.0, ti=10.0)  # P 200 -> out_hi
    assert tuple(hi.step(0.1, **inputs)["out"]) == (approx(100.0), UNC | 2)
    inputs["sp"] = (30.0, uncertain) if port == "sp" else 30.0
    lo = make(k=2.0, ti=10.0)  # P -20 -> out_lo
    assert tuple(lo.step(0.1, **inputs)["out"]) == (approx(0.0), UNC | 1)


def test_good_cascade_input_is_good(make: Make) -> None:
    """A Good cascade pv (0xC0) is Good: out 128."""
    blk = make(k=2.0, ti=10.0)
    assert tuple(blk.step(0.1, sp=50.0, pv=(40.0, 0xC0))["out"]) == (approx(20.2), GOOD)


# ----------------------------------------------------------------------------------------------
# Non-finite and overflowing values (issue 11 point 1): Bad input, the kernel sound by itself
# ----------------------------------------------------------------------------------------------
def kernel_scan(block: Block, dt: float, **inputs: Any) -> tuple[float, int]:
    """One scan of the pid kernel itself, without the numeric guard's fallback (a non-finite
    value is shown as Bad, as the guard shows it); asserts the scan is sound by itself."""
    raw_step(block, dt, inputs)
    assert np.isfinite(block.x).all(), block.state()
    assert np.isfinite(block.y).all()  # no output of the pid is ever non-finite
    return float(block.y[0]), int(block.ys[0])


def test_issue_pv_1e308_then_minus_1e308_holds_instead_of_nan(make: Make) -> None:
    """Issue 11 point 1: a PV of 1e308 then -1e308 wrote out = nan with status 128. Both are
    beyond ±1e12 (INPUT_LIMIT): Bad input, the output holds (0x47); the next good PV
    continues bumplessly: held + ki·dt·e = 20.2 + 0.2·0.1·5."""
    blk = make(k=2.0, ti=10.0, td=1.0)
    assert out(blk, 0.1, sp=50.0, pv=40.0) == approx(20.2)
    for pv in (1e308, -1e308):
        assert tuple(blk.step(0.1, pv=pv)["out"]) == (approx(20.2), UNC_LUV_CONST)
    assert tuple(blk.step(0.1, pv=45.0)["out"]) == (approx(20.3), GOOD)
    raw = loopworks.create_block("pid", jit=False, k=2.0, ti=10.0, td=1.0)
    assert kernel_scan(raw, 0.1, sp=50.0, pv=40.0) == (approx(20.2), GOOD)
    for pv in (1e308, -1e308, NAN):
        assert kernel_scan(raw, 0.1, pv=pv) == (approx(20.2), UNC_LUV_CONST)


@pytest.mark.parametrize("algorithm", ["positional", "velocity"])
@pytest.mark.parametrize("burst", [[NAN, 1e308], [1e308], [-1e308, INF, 3.5e38], [NAN, -INF]])
def test_issue_after_a_bad_burst_pv_above_sp_brings_the_output_down(
        make: Make, algorithm: str, burst: list[float]) -> None:
    """Issue 11 point 1: one NaN PV then 1e308 left the integral at +inf (the re-initialised
    I = u_prev - P - D - ff - bias absorbed P = -1e308) and the output at the high limit for
    good. Now the burst holds the output at 50 and the first good PV = 60 re-initialises from
    it: with K 1, Ti 10 (ki 0.1), e = -10: out = 50 - 1·k for k = 1, 2, ... down to out_lo."""
    blk = make(k=1.0, ti=10.0, bias=50.0, algorithm=algorithm)
    assert out(blk, 1.0, sp=50.0, pv=50.0) == approx(50.0)
    for pv in burst:
        assert tuple(blk.step(1.0, pv=pv)["out"]) == (approx(50.0), UNC_LUV_CONST)
    got = [out(blk, 1.0, pv=60.0) for _ in range(120)]  # two minutes of PV above SP
    assert got[:3] == [approx(49.0), approx(48.0), approx(47.0)]
    assert got[49] == approx(0.0) and got[-1] == approx(0.0)
    assert all(math.isfinite(v) for v in blk.x)


@pytest.mark.parametrize("port", ["pv", "sp", "ff"])
@pytest.mark.parametrize("value", [1e308, -1e308, 3.5e38, 1.0000001e12, -2e12])
def test_values_beyond_the_input_limit_are_bad_input(make: Make, port: str,
                                                     value: float) -> None:
    """Beyond ±1e12 (INPUT_LIMIT) a pv, sp or ff is not a measurement: hold, 0x47."""
    blk = make(k=2.0, ti=10.0)
    assert out(blk, 0.1, sp=50.0, pv=40.0, ff=0.0) == approx(20.2)
    assert tuple(blk.step(0.1, **{port: value})["out"]) == (approx(20.2), UNC_LUV_CONST)


def test_a_value_at_the_input_limit_is_used(make: Make) -> None:
    """1e12 itself is a measurement: P = 2·(0 - 1e12) puts the output at out_lo (129)."""
    blk = make(k=2.0, ti=10.0)
    assert tuple(blk.step(0.1, sp=0.0, pv=1e12)["out"]) == (approx(0.0), GOOD_LOW)


def test_cas_sp_beyond_the_limit_is_bad_input(make: Make) -> None:
    blk = make(k=2.0, ti=10.0)
    assert out(blk, 0.1, mode="CAS", cas_sp=50.0, pv=40.0) == approx(20.2)
    assert tuple(blk.step(0.1, cas_sp=-1e308)["out"]) == (approx(20.2), UNC_LUV_CONST)


@pytest.mark.parametrize("algorithm", ["positional", "velocity"])
def test_overflowing_arithmetic_is_bad_input_and_leaves_the_state(make: Make,
                                                                   algorithm: str) -> None:
    """K = 1e307: P = 1e307·(50 - -1000) overflows to inf. The scan is Bad input: the output
    holds at its start (bias 0 -> 0), 0x47, and the state stays finite. A PV that keeps P
    finite (e = 1e-10: P = 1e297) is computed again, re-initialised bumplessly from 0 (129);
    then e = 2e-10 raises P by 1e297: out_hi (130)."""
    blk = make(k=1e307, algorithm=algorithm)
    assert tuple(blk.step(0.1, sp=50.0, pv=-1000.0)["out"]) == (0.0, UNC_LUV_CONST)
    assert all(math.isfinite(v) for v in blk.x)
    assert tuple(blk.step(0.1, pv=50.0 - 1e-10)["out"]) == (0.0, GOOD_LOW)
    assert tuple(blk.step(0.1, pv=50.0 - 2e-10)["out"]) == (100.0, GOOD_HIGH)
    raw = loopworks.create_block("pid", jit=False, k=1e307, algorithm=algorithm)
    assert kernel_scan(raw, 0.1, sp=50.0, pv=-1000.0) == (0.0, UNC_LUV_CONST)


@pytest.mark.parametrize("value", [NAN, INF, -INF])
def test_non_finite_man_out_or_track_value_holds(make: Make, value: float) -> None:
    """MAN: a non-finite man_out is no write (hold, 131); tracking: a non-finite
    track_value holds (0x47). A huge finite man_out is limited (out_hi, 131)."""
    blk = make(k=2.0, ti=10.0)
    assert out(blk, 0.1, mode="MAN", man_out=30.0) == approx(30.0)
    assert tuple(blk.step(0.1, man_out=value)["out"]) == (approx(30.0), GOOD_CONST)
    assert tuple(blk.step(0.1, man_out=1e308)["out"]) == (approx(100.0), GOOD_CONST)
    assert tuple(blk.step(0.1, track=1.0, track_value=value)["out"]) == (
        approx(100.0), UNC_LUV_CONST)


@pytest.mark.parametrize("track", [NAN, INF])
def test_a_non_finite_track_switch_does_not_track(make: Make, track: float) -> None:
    """A NaN or infinite track is not a switch: no tracking, the controller computes."""
    blk = make(k=2.0, ti=10.0)
    assert tuple(blk.step(0.1, sp=50.0, pv=40.0, track=track, track_value=70.0)["out"]) == (
        approx(20.2), GOOD)


def test_issue_pid_replay_of_1e308_writes_no_nan(tmp_path: Path) -> None:
    """Issue 11 point 1 as reported: `loopworks replay pid` with PV 1e308 then -1e308 wrote
    out = nan with status 128; now the output holds, Uncertain (71), never NaN."""
    path = write_csv(tmp_path / "pv.csv", ["t", "sp", "pv"],
                     [[0, 50, 40], [1, 50, 1e308], [2, 50, -1e308], [3, 50, 45]])
    result = CliRunner().invoke(app, ["replay", "pid", str(path), "-p", "k=2", "-p", "ti=10"])
    assert result.exit_code == 0, result.output
    rows = list(csv.reader(io.StringIO(result.stdout)))
    col, st_col = rows[0].index("out"), rows[0].index("out.ST")
    # scan 0: P 20, I 2·1/10·10 = 2; then held; then 22 + 0.2·1·5 = 23
    assert [float(r[col]) for r in rows[1:]] == [approx(22.0), approx(22.0), approx(22.0),
                                                 approx(23.0)]
    assert [int(r[st_col]) for r in rows[1:]] == [GOOD, UNC_LUV_CONST, UNC_LUV_CONST, GOOD]


# ----------------------------------------------------------------------------------------------
# Parameter and input validation
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("params", "name", "value"), [
    ({"k": -1.0}, "k", "-1"),
    ({"ti": 0.0}, "ti", "0"),
    ({"ti": -5.0}, "ti", "-5"),
    ({"td": -1.0}, "td", "-1"),
    ({"b": 1.5}, "b", "1.5"),
    ({"b": -0.1}, "b", "-0.1"),
    ({"c": 2.0}, "c", "2"),
    ({"n": 0.0}, "n", "0"),
    ({"tt": 0.0}, "tt", "0"),
    ({"form": "parallel", "kp": -1.0}, "kp", "-1"),
    ({"form": "parallel", "ki": -0.5}, "ki", "-0.5"),
    ({"rate_limit": -1.0}, "rate_limit", "-1"),
    ({"i_deadband": -1.0}, "i_deadband", "-1"),
    ({"e_deadband": -0.5}, "e_deadband", "-0.5"),
    ({"form": "pi"}, "form", "'pi'"),
    ({"action": "up"}, "action", "'up'"),
    ({"algorithm": "incremental"}, "algorithm", "'incremental'"),
    ({"antiwindup": "conditional"}, "antiwindup", "'conditional'"),
    ({"bad_pv": "zero"}, "bad_pv", "'zero'"),
    ({"safe_out": 200.0}, "safe_out", "200"),
    ({"k": "fast"}, "k", "'fast'"),
    # derived gains that are not finite numbers (k/ti, the series K'(1 + Td'/Ti'), k·td, 1/tt)
    ({"ti": 5e-324}, "ti", "4.94066e-324"),
    ({"form": "series", "k": 0.8, "ti": 5e-324, "td": 2.0}, "ti", "4.94066e-324"),
    ({"k": 1e300, "td": 1e300}, "td", "1e+300"),
    ({"ti": 1.0, "antiwindup": "back_calculation", "tt": 5e-324}, "tt", "4.94066e-324"),
])
def test_bad_parameter_values(params: dict[str, Any], name: str, value: str) -> None:
    """Each raises ParameterError whose message names the parameter and the value."""
    with pytest.raises(ParameterError) as info:
        loopworks.create_block("pid", **params)
    msg = str(info.value)
    assert f"'{name}'" in msg
    assert value in msg


def test_unknown_parameter_lists_valid_names() -> None:
    """An unknown name is a ParameterError listing every valid parameter."""
    with pytest.raises(ParameterError) as info:
        loopworks.create_block("pid", kc=1.0)
    msg = str(info.value)
    assert "'kc'" in msg
    for name in ("form", "k", "ti", "td", "kp", "ki", "kd", "action", "b", "c", "n", "tf",
                 "algorithm", "antiwindup", "tt", "out_lo", "out_hi", "rate_limit",
                 "i_deadband", "e_deadband", "bias", "bad_pv", "safe_out"):
        assert name in msg


def test_parameter_names_are_case_insensitive(make: Make) -> None:
    """K = 2 is k = 2."""
    blk = make(K=2.0, Ti=10.0)
    assert out(blk, 0.1, sp=50.0, pv=40.0) == approx(20.2)


@pytest.mark.parametrize("dt", [0.0, -0.1, NAN, INF])
def test_bad_dt_is_an_input_error(make: Make, dt: float) -> None:
    """dt must be > 0 and finite."""
    blk = make(k=1.0)
    with pytest.raises(InputError, match="dt"):
        blk.step(dt, sp=1.0, pv=0.0)


@pytest.mark.parametrize(("inputs", "word"), [
    ({"foo": 1.0}, "foo"),
    ({"mode": "HAND"}, "HAND"),
    ({"pv": (40.0, 300)}, "300"),
])
def test_bad_inputs_are_input_errors(make: Make, inputs: dict[str, Any], word: str) -> None:
    """Unknown port, unknown mode name, a status that is not a byte: InputError."""
    blk = make(k=1.0)
    with pytest.raises(InputError, match=word):
        blk.step(0.1, **inputs)


# ----------------------------------------------------------------------------------------------
# Block API: latched inputs, reset, saved state
# ----------------------------------------------------------------------------------------------
def test_inputs_latch_between_scans(make: Make) -> None:
    """An input keeps its last value: a scan without inputs integrates the same error."""
    blk = make(k=2.0, ti=10.0)
    assert out(blk, 0.1, sp=50.0, pv=40.0) == approx(20.2)
    assert out(blk, 0.1) == approx(20.4)


def test_reset_returns_to_the_first_scan(make: Make) -> None:
    """After reset() the next scan is a first scan again: I = ki·dt·e_0, D = 0 (d_{-1} = d_0)."""
    blk = make(k=2.0, ti=10.0, td=1.0)
    for pv in (40.0, 42.0, 45.0):
        blk.step(0.1, sp=50.0, pv=pv)
    blk.reset()
    assert terms(blk, 0.1, sp=50.0, pv=40.0) == (
        approx(20.0 + 0.2 * 0.1 * 10), approx(20.0), approx(0.2), approx(0.0), GOOD)


def test_reset_restores_input_defaults(make: Make) -> None:
    """After reset() unset inputs take their defaults again: sp = pv = ff = 0, AUTO."""
    blk = make(k=2.0, ti=10.0)
    blk.step(0.1, sp=50.0, pv=40.0, ff=3.0, mode="MAN", man_out=20.0)
    blk.reset()
    assert tuple(blk.step(0.1)["out"]) == (approx(0.0), GOOD_LOW)


def test_saved_state_resumes(make: Make) -> None:
    """state_dict/load_state: a new block continues where the saved one stopped."""
    blk = make(k=2.0, ti=10.0)
    for _ in range(3):  # 20.2, 20.4, 20.6
        blk.step(0.1, sp=50.0, pv=40.0)
    saved = blk.state_dict()
    again = make(k=2.0, ti=10.0)
    again.load_state(saved)
    assert out(again, 0.1) == approx(20.0 + 4 * 0.2)  # latched sp/pv restored too


@pytest.mark.parametrize("algorithm", ["positional", "velocity"])
def test_retuning_in_auto_is_bumpless(make: Make, algorithm: str) -> None:
    """Issue 12 point 4 (DiscretePIDs.jl set_K!): K 2 -> 4 at e = 10 would move P from 20 to
    40; with retune = bumpless the next scan moves only by the new integral increment
    ki_new·dt·e = (4/8)·1·10 = 5."""
    blk = make(k=2.0, ti=8.0, algorithm=algorithm)
    for _ in range(3):
        before = out(blk, 1.0, sp=50.0, pv=40.0)
    blk.set_params(k=4.0)
    assert out(blk, 1.0, sp=50.0, pv=40.0) == approx(before + 5.0)


@pytest.mark.parametrize("algorithm", ["positional", "velocity"])
@pytest.mark.parametrize("change", [{"action": "direct"}, {"c": 0.0}, {"c": 1.0}])
def test_a_new_action_or_derivative_weight_does_not_kick_the_derivative(
        make: Make, algorithm: str, change: dict[str, Any]) -> None:
    """Found by a user: at rest (SP = PV = 50, output 4), set_params(action="direct") or a
    new c drove the output to 100 on the next scan: the derivative memory s·(c·SP - PV)
    kept the old s and c, a step of 50-100 in d, kd·Δd/(Tf + dt) = 2·100/0.2 = 1000. With
    e = 0 nothing should move (P and the integral are bumpless already)."""
    blk = make(k=2.0, ti=10.0, td=1.0, c=0.5, algorithm=algorithm)
    for _ in range(20):
        out(blk, 0.1, sp=50.0, pv=40.0)
    for _ in range(600):
        before = out(blk, 0.1, sp=50.0, pv=50.0)
    blk.set_params(**change)
    assert out(blk, 0.1, sp=50.0, pv=50.0) == pytest.approx(before, abs=1e-9)


def test_retuning_can_bump_when_asked(make: Make) -> None:
    """retune = textbook: the vendor-neutral textbook law, P jumps with K (20 -> 40)."""
    blk = make(k=2.0, ti=8.0, retune="textbook")
    for _ in range(3):
        before = out(blk, 1.0, sp=50.0, pv=40.0)
    blk.set_params(k=4.0)
    assert out(blk, 1.0, sp=50.0, pv=40.0) == approx(before + 20.0 + 5.0)


def test_retuning_in_man_needs_no_correction(make: Make) -> None:
    """In MAN the next AUTO scan re-initialises anyway: the output continues from MAN."""
    blk = make(k=2.0, ti=8.0)
    out(blk, 1.0, mode="MAN", man_out=30.0, sp=50.0, pv=40.0)
    blk.set_params(k=4.0)
    assert out(blk, 1.0, mode="AUTO") == approx(30.0 + 5.0)


# ----------------------------------------------------------------------------------------------
# antiwindup = integral_limits (simple-pid 2.0.1's rule: the integral itself within the limits)
# ----------------------------------------------------------------------------------------------
def test_integral_limits_keeps_the_integral_within_the_output_limits(make: Make) -> None:
    """I_k = clamp(I_{k-1} + ki·dt·e, lo, hi); u = clamp(P + I + D, lo, hi). Hand values:
    kp 2, ki 1, lo 0, hi 10, dt 1, sp 10."""
    blk = make(form="parallel", kp=2.0, ki=1.0, out_lo=0.0, out_hi=10.0,
               antiwindup="integral_limits")
    # pv 0: P 20, I 0 + 10 = 10 (at hi), u = clamp(30) = 10
    assert terms(blk, 1.0, sp=10.0, pv=0.0)[:3] == (10.0, 20.0, 10.0)
    # pv 0 again: I stays at 10 (clamped), not 20 as 'none' would give
    assert terms(blk, 1.0, pv=0.0)[:3] == (10.0, 20.0, 10.0)
    # pv 12: P -4, I 10 - 2 = 8, u = 4: the output leaves the limit at once (no wound-up I;
    # 'clamping' would have kept I at 0, P alone being beyond the limit: u = clamp(-6) = 0)
    assert terms(blk, 1.0, pv=12.0)[:3] == (4.0, -4.0, 8.0)


def test_integral_limits_needs_the_positional_algorithm() -> None:
    with pytest.raises(ParameterError, match=r"integral_limits.*positional"):
        loopworks.create_block("pid", algorithm="velocity", antiwindup="integral_limits")
