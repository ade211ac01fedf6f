"""Closed-loop check: a PI loop with a Choudhury stick-slip valve, seen by both methods.

Loop (plant-and-tuning 5.1, first row): FOPDT K = 1, T = 10 s, dead time 2 s; ideal PI Kc = 1,
Ti = 10 s, e = SP - PV; valve S = 3 %, J = 1 % (loopworks' valve.choudhury, spec 1.2); dt =
0.05 s; SP 50 → 51 % at t = 10 s (the ``spec_cycle`` fixture, tests/analysis/conftest.py).
The spec reports OP amplitude 1.560, PV amplitude 0.556 and
period 112.0 s for this loop (second half of a 4000 s run); the simulation below must reproduce
them before the detectors are judged on it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from loopworks.analysis.bicoherence import apparent_stiction
from loopworks.analysis.curve_fit import curve_fit_index
from tests.analysis.conftest import SPEC_DT

DT = SPEC_DT
S, J = 3.0, 1.0


@pytest.fixture(scope="module")
def cycle(spec_cycle: tuple[np.ndarray, np.ndarray, np.ndarray]
          ) -> tuple[np.ndarray, np.ndarray, float]:
    _, pv, op = spec_cycle  # the settled limit cycle (loopworks' own blocks)
    oc = op - op.mean()
    ups = np.flatnonzero((oc[:-1] < 0.0) & (oc[1:] >= 0.0))
    return op, pv, float(np.diff(ups).mean() * DT)


def test_simulation_reproduces_the_spec_limit_cycle(
        cycle: tuple[np.ndarray, np.ndarray, float]) -> None:
    op, pv, period = cycle
    assert (op.max() - op.min()) / 2.0 == pytest.approx(1.560, rel=0.01)
    assert (pv.max() - pv.min()) / 2.0 == pytest.approx(0.556, rel=0.01)
    assert period == pytest.approx(112.0, rel=0.01)


def test_apparent_stiction_is_of_the_order_of_s(
        cycle: tuple[np.ndarray, np.ndarray, float]) -> None:
    op, pv, period = cycle
    width = apparent_stiction(op, pv, DT, period)
    # Independent value: the ellipse of the fundamentals alone. With OP1 = a cos ωt and
    # PV1 = b cos(ωt - φ) its OP-axis width is 2a|sin φ|; a and φ from a DFT over whole periods.
    n = round(math.floor(op.size * DT / period) * period / DT)
    z = np.exp(-2j * math.pi * np.arange(n) * DT / period)
    c_op = 2.0 * np.mean((op[:n] - op[:n].mean()) * z)
    c_pv = 2.0 * np.mean((pv[:n] - pv[:n].mean()) * z)
    fundamental = 2.0 * abs(c_op) * abs(math.sin(np.angle(c_pv / c_op)))
    assert width == pytest.approx(fundamental, rel=0.05)  # filter + fit add ~1 % here
    # Choudhury et al. quote the apparent stiction as an estimate of S, not an equality: the
    # fundamental of OP's triangle is 8/π² ≈ 0.81 of its amplitude and OP and PV are not
    # exactly 90° apart, so it reads low (2.23 here, 26 % under S = 3). Tolerance: ±35 %.
    assert width == pytest.approx(S, rel=0.35)
    assert width < S  # and it reads low, for the reasons above


def test_he_index_says_stiction_on_op(cycle: tuple[np.ndarray, np.ndarray, float]) -> None:
    op, _, _ = cycle
    fit = curve_fit_index(op, DT, "self-regulating")
    assert fit.verdict == "stiction"
    assert fit.si > 0.95
    assert fit.half_cycles >= 20
