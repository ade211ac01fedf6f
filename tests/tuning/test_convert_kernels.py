"""Conversions tied to the kernels (issue 13 point 3): what ``convert`` says of a pair of
controllers is what the two blocks do when they run.

* Exact pairs: the source block and its converted target are driven with the same random SP/PV
  sequence (each in its own port units: % of its spans) and their outputs, in % of output span,
  move identically scan by scan (to 1e-9 %). Both start in manual at mid-range and switch to
  automatic (their ``MANUAL``/``AUTOMATIC`` input values, the ``man_out`` role); the first
  scans after the switch are the documented start-up difference (a derivative or an integral
  history that one block seeds and the other does not) and are not compared.
* Inexact pairs: the conversion states the relative frequency-response error of the whole
  controller, |C_t(jω) - C_s(jω)|/|C_s(jω)|, at ω = 1/Ti and 1/Td. Both blocks are driven with
  a PV sinusoid at each stated ω; their steady-state responses, fitted from the outputs, give
  the measured error, which must equal the stated one (to 0.1 % of it). The closed-loop
  step-response bounds for representative inexact pairs are in test_convert_closed_loop.py.

Vendor integer arithmetic rounds signals, not parameters, so these runs use each block's float
arithmetic (GE and S5 ``arithmetic = "float"``, DeltaV ``precision = "float64"``): the
conversions' exactness rule is about the law, not about counts.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from loopworks.blocks.controller import Controller
from loopworks.catalog import block_class, controller_kinds
from loopworks.tuning.convert import Conversion, convert, from_ideal
from loopworks.tuning.settings import Ideal

KINDS = controller_kinds()
#: each block's float arithmetic (block options, not tuning parameters)
FLOAT: dict[str, dict[str, Any]] = {"ge.pid_ind": {"arithmetic": "float"},
                                    "ge.pid_isa": {"arithmetic": "float"},
                                    "s5.pid": {"arithmetic": "float"},
                                    "deltav.pid": {"precision": "float64"}}
#: the conversions' target context for float arithmetic
TARGET: dict[str, dict[str, Any]] = {"ge.pid_ind": {"arithmetic": "float"},
                                     "ge.pid_isa": {"arithmetic": "float"}}
WARM = 5  # manual scans at mid-range before the switch to automatic
SKIP = 3  # start-up scans after the switch that are not compared


def controller(kind: str) -> type[Controller]:
    cls = block_class(kind)
    assert issubclass(cls, Controller)
    return cls


def run(kind: str, params: dict[str, Any], sp_pct: np.ndarray, pv_pct: np.ndarray,
        dt: float) -> np.ndarray:
    """The block's output in % of its output span for SP and PV given in % of its PV span:
    WARM scans in manual at mid-range, then automatic."""
    cls = controller(kind)
    prm = {k: v for k, v in params.items() if k not in cls.LAW_CONTEXT}
    block = block_class(kind)(jit=False, **{**prm, **FLOAT.get(kind, {}),
                                            **cls.HANDOVER.params})
    pv_span, out_span = cls.spans(block.params)
    lo, hi = cls.output_range(block.params)
    mid = 0.5 * (lo + hi)
    roles = cls.ROLES
    assert roles.man_out is not None
    out = np.empty(len(sp_pct))
    for k, (sp, pv) in enumerate(zip(sp_pct, pv_pct, strict=True)):
        inputs: dict[str, Any] = {roles.sp: float(sp * pv_span / 100.0),
                                  roles.pv: float(pv * pv_span / 100.0)}
        if k < WARM:
            inputs.update(cls.MANUAL)
            inputs[roles.man_out] = mid
        else:
            inputs.update(cls.AUTOMATIC)
        value = block.step(dt, **inputs)[roles.out].value
        assert lo < value < hi, f"{kind}: the output reached a limit ({value})"
        out[k] = value * 100.0 / out_span
    return out


def random_law(rng: np.random.Generator, dt: float, derivative: bool) -> Ideal:
    """A PI or PID in %/% whose ω = 1/Ti and 1/Td are well below the Nyquist frequency."""
    kc = float(rng.uniform(0.3, 2.5))
    ti = float(rng.uniform(8.0, 40.0)) * dt
    td = float(rng.uniform(2.0, 6.0)) * dt if derivative else 0.0
    return Ideal(kc, ti, td, td / 8.0 if derivative else 0.0, bool(rng.integers(2)))


def source_params(kind: str, ideal: Ideal, dt: float) -> dict[str, Any]:
    """Parameters of a ``kind`` block for ``ideal`` (realised by its own from_law)."""
    return from_ideal(kind, ideal, sample_time=dt, context=TARGET.get(kind, {})).params


def random_walk(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """SP in % with a few steps, PV in % wandering around it (|e| within a few %)."""
    sp = 50.0 + np.repeat(rng.uniform(-3.0, 3.0, n // 40 + 1), 40)[:n]
    noise = np.zeros(n)
    for k in range(1, n):
        noise[k] = 0.8 * noise[k - 1] + rng.normal(0.0, 0.4)
    return sp, sp + np.clip(noise, -4.0, 4.0)


def pairs() -> list[tuple[str, str]]:
    return [(a, b) for a in KINDS for b in KINDS]


# -- exact pairs: identical moves, scan by scan ---------------------------------------------------
@pytest.mark.parametrize(("src", "tgt"), pairs())
@pytest.mark.parametrize("derivative", [False, True], ids=["PI", "PID"])
def test_an_exact_conversion_moves_identically(src: str, tgt: str, derivative: bool) -> None:
    rng = np.random.default_rng([KINDS.index(src), KINDS.index(tgt), derivative])
    dt = float(rng.choice([0.5, 1.0, 2.0]))
    params = source_params(src, random_law(rng, dt, derivative), dt)
    conv = convert(src, params, tgt, sample_time=dt, target=TARGET.get(tgt, {}))
    sp, pv = random_walk(rng, 300)
    a = run(src, params, sp, pv, dt)
    b = run(tgt, conv.params, sp, pv, dt)
    moves_a, moves_b = np.diff(a[WARM + SKIP:]), np.diff(b[WARM + SKIP:])
    assert np.abs(moves_a).max() > 1e-3  # the controllers do move
    diff = moves_a - moves_b
    worst = float(np.abs(diff).max())
    if conv.exact:
        # the start-up difference: a derivative filter state seeded differently at the switch
        # decays as the filter's free response, ρ^k with ρ = Tf/(Tf + Δ), and nothing else
        tf = conv.ideal.tf
        rho = tf / (tf + dt)
        assert np.abs(diff[1:] - rho * diff[:-1]).max() <= 1e-9, (conv.note, worst)
        settled = math.ceil(math.log(1e-13) / math.log(rho)) if rho > 0.0 else 0
        assert np.abs(diff[settled:]).max() <= 1e-9, (conv.note, worst)
    else:  # an inexact conversion is not secretly exact (and its note says so)
        assert conv.note.startswith("Not exact.")
        assert conv.response_errors or "setpoint path" in conv.note or "action" in conv.note


# Which pairs are exact in float arithmetic (convert's exactness rule, and each law's
# docstring): DeltaV's reset integrates the previous error, so DeltaV is exact only onto itself;
# S5's integer words round any other law, so S5 is exact as a target only of itself. Among the
# pid, GE and E2 (and S5 as a source) the PI laws are the same. With D: the pid realises any
# derivative filter (tf), GE and E2 have none (a PID realised on them has Tf = 0), S5's law A
# filters with Tf = TA, and the source pid's filter here is Td/8: a filtered D is exact only
# onto the pid.
def expected_exact(src: str, tgt: str, derivative: bool) -> bool:
    if src == tgt:
        return True
    if "deltav.pid" in (src, tgt) or tgt == "s5.pid":
        return False
    filtered = src in ("pid", "s5.pid")
    return not derivative or tgt == "pid" or not filtered


@pytest.mark.parametrize("derivative", [False, True], ids=["PI", "PID"])
def test_which_pairs_are_exact(derivative: bool) -> None:
    got: dict[tuple[str, str], bool] = {}
    for src, tgt in pairs():
        rng = np.random.default_rng([KINDS.index(src), KINDS.index(tgt), derivative])
        dt = float(rng.choice([0.5, 1.0, 2.0]))
        params = source_params(src, random_law(rng, dt, derivative), dt)
        got[src, tgt] = convert(src, params, tgt, sample_time=dt,
                                target=TARGET.get(tgt, {})).exact
    want = {(s, t): expected_exact(s, t, derivative) for s, t in pairs()}
    assert got == want


# -- inexact pairs: the stated frequency-response error is the kernels' ---------------------------
def response(out: np.ndarray, e: np.ndarray, w: float, dt: float, tail: int) -> complex:
    """C(jω) from a steady-state stretch: the output's and the error's phasors at ω, fitted by
    least squares (sin, cos and a constant) over the last ``tail`` scans."""
    t = np.arange(len(out))[-tail:] * dt
    basis = np.column_stack([np.sin(w * t), np.cos(w * t), np.ones_like(t)])
    (os_, oc, _), *_ = np.linalg.lstsq(basis, out[-tail:], rcond=None)
    (es, ec, _), *_ = np.linalg.lstsq(basis, e[-tail:], rcond=None)
    return complex(os_, oc) / complex(es, ec)


INEXACT = [("deltav.pid", "pid", False), ("pid", "deltav.pid", True),
           ("s5.pid", "ge.pid_ind", True), ("pid", "s5.pid", False), ("pid", "ge.pid_isa", True),
           ("deltav.pid", "e2.pid", True), ("e2.pid", "deltav.pid", False),
           ("ge.pid_ind", "s5.pid", True)]


@pytest.mark.parametrize(("src", "tgt", "derivative"), INEXACT)
def test_an_inexact_conversion_states_the_kernels_error(src: str, tgt: str,
                                                        derivative: bool) -> None:
    rng = np.random.default_rng([KINDS.index(src), KINDS.index(tgt), 7])
    dt = 1.0
    law = random_law(rng, dt, derivative)
    params = source_params(src, law, dt)
    conv: Conversion = convert(src, params, tgt, sample_time=dt, target=TARGET.get(tgt, {}))
    assert not conv.exact and conv.response_errors, conv.note
    sign = -1.0 if law.direct else 1.0  # e = SP - PV (reverse), PV - SP (direct)
    for w, stated in conv.response_errors:
        periods = max(6, math.ceil(600.0 * w * dt / (2.0 * math.pi)))
        n = WARM + int(periods * 2.0 * math.pi / (w * dt)) + 1
        tail = int(4 * 2.0 * math.pi / (w * dt))
        k = np.arange(n)
        sp = np.full(n, 50.0)
        pv = 50.0 + 2.0 * np.sin(w * k * dt)
        e = sign * (sp - pv)
        cs = response(run(src, params, sp, pv, dt), e, w, dt, tail)
        ct = response(run(tgt, conv.params, sp, pv, dt), e, w, dt, tail)
        measured = abs(ct - cs) / abs(cs)
        assert measured == pytest.approx(stated, rel=1e-3), (w, conv.note)
        assert measured > 1e-4  # the error is real, not a rounding residue


@pytest.mark.parametrize("tgt", KINDS)
def test_an_inverted_ge_output_is_converted_with_its_sign(tgt: str) -> None:
    """Spec vendor-blocks 1.3, Config Word bit 1: CV = -Output after the clamp. From error
    to CV that is the other action, and the conversion takes it so: the target moves as the
    inverted GE block does (identically where the pair is exact). It was read as a setting
    "not converted", the pair still called exact, and the target's moves had the opposite
    sign (found by an outside audit)."""
    rng = np.random.default_rng(13)
    dt = 1.0
    law = Ideal(1.2, 20.0, 0.0, 0.0, False)
    params = {**source_params("ge.pid_ind", law, dt), "invert_output": True,
              "lower_clamp": -32000, "upper_clamp": 32000}
    conv = convert("ge.pid_ind", params, tgt, sample_time=dt, target=TARGET.get(tgt, {}))
    assert conv.ideal.direct  # reverse acting, inverted: direct from error to CV
    sp, pv = random_walk(rng, 300)
    a = run("ge.pid_ind", params, sp, pv, dt)
    b = run(tgt, conv.params, sp, pv, dt)
    moves_a, moves_b = np.diff(a[WARM + SKIP:]), np.diff(b[WARM + SKIP:])
    assert float(np.dot(moves_a, moves_b)) > 0.9 * float(np.dot(moves_a, moves_a))
    if conv.exact:
        assert np.abs(moves_a - moves_b).max() <= 1e-9, conv.note
