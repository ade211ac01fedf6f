"""Stiction measured on a recorded valve position (issue 15: "optional valve position").

The positions are made here, independently of the fit: a stem that stays put after each
reversal until the OP has moved S past the point where it stuck and then jumps to within
J... is loopworks' valve.choudhury, which the fit also uses, so the sticky record is made
instead by a plain backlash (deadband S, J = 0: the stem follows the OP at S/2 behind it,
written out below), whose Choudhury S is the band width; the clean records by a positioner
that follows the OP through a first-order lag, and by an unrelated signal.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.signal import lfilter
from typer.testing import CliRunner

from loopworks.analysis.loopdata import LoopData
from loopworks.analysis.valve_travel import fit_travel
from loopworks.cli import app


def _backlash(op: np.ndarray, band: float) -> np.ndarray:
    """A stem with backlash ``band`` (% of OP): it moves only when the OP pushes it from
    either side of the band, y = clip(y, op - band/2, op + band/2)."""
    y = np.empty_like(op)
    pos = float(op[0])
    for k, u in enumerate(op):
        pos = min(max(pos, u - band / 2.0), u + band / 2.0)
        y[k] = pos
    return y


def _record(op: np.ndarray, position: np.ndarray | None) -> LoopData:
    t = np.arange(len(op), dtype=np.float64)
    return LoopData(t=t, sp=np.full(len(op), 50.0), pv=op.copy(), op=op, position=position)


def _op(n: int = 1500, seed: int = 2) -> np.ndarray:
    """An OP that wanders both ways: a slow sine plus a random walk, ±5 %."""
    rng = np.random.default_rng(seed)
    t = np.arange(n)
    walk = np.cumsum(rng.normal(0.0, 0.1, n))
    return 50.0 + 4.0 * np.sin(2.0 * math.pi * t / 300.0) + walk - walk.mean()


def test_a_backlash_is_measured_as_its_band() -> None:
    op = _op()
    pos = 10.0 + 0.9 * _backlash(op, 2.0)  # another span and an offset: α, β are fitted
    fit = fit_travel(_record(op, pos))
    assert fit is not None and fit.ok, fit
    assert fit.s == pytest.approx(2.0, rel=0.1)  # Choudhury S of a pure backlash: its band
    assert fit.j == pytest.approx(0.0, abs=0.2)
    # the band explains nearly all that the best linear valve (a lag or not) leaves
    assert fit.r2 > 0.99 and (fit.r2 - fit.r2_linear) / (1.0 - fit.r2_linear) > 0.9


def test_a_positioner_lag_is_not_stiction() -> None:
    op = _op()
    a = math.exp(-1.0 / 0.5)  # a 0.5 s positioner sampled every 1 s
    pos = lfilter([1.0 - a], [1.0, -a], op, zi=[a * op[0]])[0]
    fit = fit_travel(_record(op, pos))
    assert fit is not None and fit.ok
    assert fit.s < 0.3  # below the verdict's MIN_S
    assert fit.r2_linear > 0.99


def test_no_position_no_measurement_and_an_unrelated_one_is_refused() -> None:
    op = _op()
    assert fit_travel(_record(op, None)) is None
    other = 50.0 + np.cumsum(np.random.default_rng(9).normal(0.0, 0.3, len(op)))
    fit = fit_travel(_record(op, other))
    assert fit is not None and not fit.ok and math.isnan(fit.s)
    assert "this OP's valve?" in fit.reason
    # a valve that is not driven has nothing to show
    still = fit_travel(_record(np.full(400, 50.0), np.full(400, 50.0)))
    assert still is not None and not still.ok and "OP moves" in still.reason


def test_the_report_draws_the_valve_against_its_recorded_position(tmp_path: Path) -> None:
    # a sticky loop (the spec 5.1 loop, S 3 %, J 1 %) written with its stem position: the
    # command finds the column by name and the report draws it with the fitted valve over it
    from loopworks.analysis.synthetic import simulate_loop, write_csv

    loop = simulate_loop(valve="choudhury", s=3.0, j=1.0, noise=0.02, kc=1.0, ti=10.0,
                         sp_step=1.0, dt=0.5, sample_period=1.0, warmup=300.0,
                         duration=2000.0, seed=4)
    csv = tmp_path / "loop.csv"
    write_csv(loop, csv, position=True)
    run = CliRunner().invoke(app, ["diagnose", str(csv), "--json", "-o", str(tmp_path / "r")])
    assert run.exit_code == 0, run.output
    doc = json.loads(run.stdout)
    assert doc["verdict"] == "stiction" and doc["indices"]["valve_travel"] == pytest.approx(
        3.0, rel=0.3)
    assert (tmp_path / "r" / "valve_travel.png").stat().st_size > 10_000
    assert "valve_travel.png" in (tmp_path / "r" / "report.html").read_text()


@pytest.mark.parametrize("periods", [2.0, 4.0])
def test_a_slow_positioner_is_not_stiction(periods: float) -> None:
    """A healthy valve behind a 10-20 s positioner lag, recorded every 5 s (2-4 periods):
    the lag puts the position behind the OP on every reversal, as a dead band would, and
    against α·OP + β alone the fit voted stiction (S 0.3-0.5 %; found by a user's level
    loops). The linear valve it is measured against may lag (LAG_TAUS): the stick band
    explains nothing beyond it."""
    from loopworks.analysis.diagnosis import _valve_travel_vote

    op = _op()
    a = math.exp(-1.0 / periods)
    pos = lfilter([1.0 - a], [1.0, -a], op, zi=[a * op[0]])[0]
    pos = pos + 0.01 * np.random.default_rng(5).standard_normal(len(op))
    fit = fit_travel(_record(op, pos))
    assert fit is not None and fit.ok and fit.r2_linear > 0.99
    assert _valve_travel_vote(fit).vote != "stiction", fit
