"""Converted controllers give matching closed-loop responses (issue 6 point 4).

Loop: process.fopdt K = 1, T = 30 s, L = 3 s, dt = sample time = 1 s, u0 = 50 %, PV in %;
setpoint step 50 -> 55 % at t = 10 s. Each controller sees the PV in its own port units (GE
counts 0..32000, S5 counts 0..1000, E2 and DeltaV EU 0..100) and starts at 50 % output.
GE and S5 run arithmetic = "float", DeltaV precision float64.

Bound for inexact pairs: with ΔC = C_t - C_s and the loop P(z) (zero-order hold, exact for
this plant: y_{k+1} = a·y_k + (1 - a)·K·u_{k-3}, a = e^(-Δ/T)), the setpoint-to-PV difference
is ΔT = P·ΔC/((1 + P·C_s)(1 + P·C_t)); both loops have integral action, so ΔT(1) = 0 and the
step response difference obeys |e_k| ≤ (r/π)·∫_0^π |ΔT(e^{jθ})|/|1 - e^{-jθ}| dθ. The
controllers' z-transforms are written here independently of loopworks.tuning.convert.
"""

from __future__ import annotations

import cmath
import math
from typing import Any

import numpy as np
import pytest

from loopworks.catalog import create_block
from loopworks.tuning.convert import convert

DT = 1.0
N = 240
STEP_AT = 10
SP0, SP1 = 50.0, 55.0  # small enough that no output limit acts (a linear comparison)
K, T, L = 1.0, 30.0, 3.0


def simulate(kind: str, params: dict[str, Any]) -> np.ndarray:
    """PV (%) of the loop under a ``kind`` controller with ``params``."""
    prm = {k: v for k, v in params.items() if not k.startswith("word")}
    proc = create_block("process.fopdt", jit=False, gain=K, time_constant=T, dead_time=L,
                        u0=50.0)
    if kind == "pid":
        ctl = create_block("pid", jit=False, bias=50.0, **prm)
    elif kind.startswith("ge."):
        prm["arithmetic"] = "float"
        ctl = create_block(kind, jit=False, bias=16000.0, **prm)
    elif kind == "s5.pid":
        ctl = create_block(kind, jit=False, arithmetic="float", y0=500, bgog=1000, bgug=0,
                           **prm)
    elif kind == "e2.pid":
        ctl = create_block(kind, jit=False, output_at_setpoint=50.0, **prm)
    else:
        ctl = create_block(kind, jit=False, precision="float64", initial_out=50.0, **prm)
    y = 50.0
    pv = np.empty(N)
    for k in range(N):
        sp = SP1 if k >= STEP_AT else SP0
        pv[k] = y
        if kind == "pid":
            u = ctl.step(DT, sp=sp, pv=y)["out"].value
        elif kind.startswith("ge."):
            u = ctl.step(DT, sp=sp * 320.0, pv=y * 320.0, clock=(k + 1) * DT)["cv"].value / 320
        elif kind == "s5.pid":
            u = ctl.step(DT, w=sp * 10.0, x=y * 10.0)["y"].value / 10.0
        elif kind == "e2.pid":
            u = ctl.step(DT, sp=sp, pv=y)["out"].value
        else:
            u = ctl.step(DT, sp=sp, pv=y, mode="AUTO")["out"].value
        y = proc.step(DT, u=u)["y"].value
    return pv


# -- independent z-domain models for the bound ---------------------------------------------------
def c_backward(kc: float, ti: float, td: float, tf: float, z: complex) -> complex:
    """P + backward-Euler I + backward-Euler filtered D (the pid, GE, S5 law A, E2)."""
    zi = 1.0 / z
    i = kc * DT / ti / (1.0 - zi) if ti < math.inf else 0.0
    return kc + i + kc * td * (1.0 - zi) / (tf + DT - tf * zi)


def c_deltav(kc: float, ti: float, td: float, alpha: float, z: complex) -> complex:
    """DeltaV standard: the reset integrates the previous error (spec 4.7 step 7, Euler)."""
    zi = 1.0 / z
    tf = alpha * td
    return kc + kc * DT / ti * zi / (1.0 - zi) + kc * td * (1.0 - zi) / (tf + DT - tf * zi)


def plant(z: complex) -> complex:
    a = math.exp(-DT / T)
    return K * (1.0 - a) * z ** -(1 + round(L / DT)) / (1.0 - a / z)


def step_bound(cs: Any, ct: Any, r: float) -> float:
    theta = np.linspace(1e-4, math.pi, 20001)
    vals = []
    for th in theta:
        z = cmath.exp(1j * th)
        p, a, b = plant(z), cs(z), ct(z)
        d_t = p * (b - a) / ((1 + p * a) * (1 + p * b))
        vals.append(abs(d_t) / abs(1.0 - 1.0 / z))
    return float(r / math.pi * np.trapezoid(vals, theta))


# -- the source: an ideal PID on the error, no filter (exact onto GE, E2; PI onto S5) ----------
KC, TI, TD = 2.0, 16.0, 2.0
SOURCE = {"k": KC, "ti": TI, "td": TD, "tf": 0.0, "c": 1.0}


@pytest.fixture(scope="module")
def source_pv() -> np.ndarray:
    return simulate("pid", SOURCE)


@pytest.mark.parametrize("kind", ["ge.pid_ind", "ge.pid_isa", "e2.pid", "pid"])
def test_exact_conversions_match(kind: str, source_pv: np.ndarray) -> None:
    conv = convert("pid", SOURCE, kind, sample_time=DT, target={"arithmetic": "float"}
                   if kind.startswith("ge.") else {"form": "parallel"} if kind == "pid" else {})
    assert conv.exact, conv.note
    pv = simulate(kind, conv.params)
    assert np.max(np.abs(pv - source_pv)) < 1e-6
    assert np.max(pv) > 55.2  # the step was answered (overshoot), not a flat line


def test_s5_exact_with_its_derivative_law() -> None:
    # S5 law A is the backward-Euler filter with Tf = TA (spec 2.6): a pid with tf = 1 s
    source = {"k": KC, "ti": TI, "td": TD, "tf": DT, "c": 1.0}
    conv = convert("pid", source, "s5.pid", sample_time=DT)
    assert conv.exact, conv.note
    assert (conv.params["k"], conv.params["ti"], conv.params["td"]) == (2048, 64, 2048)
    pv_s5 = simulate("s5.pid", conv.params)
    pv_pid = simulate("pid", source)
    assert np.max(np.abs(pv_s5 - pv_pid)) < 1e-6


def test_deltav_within_bound(source_pv: np.ndarray) -> None:
    src = {"k": KC, "ti": TI, "td": TD, "tf": 0.0, "c": 1.0}
    conv = convert("pid", src, "deltav.pid", sample_time=DT)
    assert not conv.exact and "Δ/Ti" in conv.note
    alpha = float(conv.params["alpha"])
    pv = simulate("deltav.pid", conv.params)
    dev = float(np.max(np.abs(pv - source_pv)))
    bound = step_bound(lambda z: c_backward(KC, TI, TD, 0.0, z),
                       lambda z: c_deltav(KC, TI, TD, alpha, z), SP1 - SP0)
    assert 1e-4 < dev <= bound  # inexact, but within the frequency-domain bound


def test_filtered_s5_onto_ge_within_bound() -> None:
    source = {"k": 1024, "r": 1024, "ti": 64, "td": 1024}  # Kc 1, Ti 16 s, Td 1 s, Tf = TA
    conv = convert("s5.pid", source, "ge.pid_isa", sample_time=DT,
                   target={"arithmetic": "float"})
    assert not conv.exact and "Derivative filter" in conv.note
    pv_s5 = simulate("s5.pid", source)
    pv_ge = simulate("ge.pid_isa", conv.params)
    dev = float(np.max(np.abs(pv_ge - pv_s5)))
    bound = step_bound(lambda z: c_backward(1.0, 16.0, 1.0, 1.0, z),
                       lambda z: c_backward(1.0, 16.0, 1.0, 0.0, z), SP1 - SP0)
    assert 1e-4 < dev <= bound
