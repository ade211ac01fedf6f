"""A valve that does not move (issue 15; loopworks.analysis.seized): the rule's each condition
on made-up records, and the real plant record that shows it (plant05: a flow loop labelled
sticky whose flow stays at zero while its OP ramps from 5 to 78 %)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from loopworks.analysis.diagnosis import diagnose
from loopworks.analysis.loopdata import LoopData
from loopworks.analysis.seized import MIN_OP_TRAVEL, MIN_RUN_FRACTION, seized_valve
from loopworks.cli import app

PLANT = Path(__file__).resolve().parents[1] / "data" / "plant-loops"
N = 400


def _record(op: np.ndarray, pv: np.ndarray, sp: float = 2.5,
            mode: np.ndarray | None = None) -> LoopData:
    return LoopData(t=np.arange(len(op)) * 10.0, sp=np.full(len(op), sp), pv=pv, op=op,
                    mode=np.ones(len(op)) if mode is None else mode)


def _stuck(travel: float = 40.0) -> tuple[np.ndarray, np.ndarray]:
    # a working first quarter (PV noisy around SP), then the PV held at 0 while the OP winds
    # up by `travel` % over the remaining three quarters
    rng = np.random.default_rng(2)
    q = N // 4
    op = np.concatenate([20.0 + rng.normal(0.0, 0.5, q), np.linspace(20.0, 20.0 + travel, N - q)])
    pv = np.concatenate([2.5 + rng.normal(0.0, 0.05, q), np.zeros(N - q)])
    return op, pv


def test_a_valve_that_does_not_move_is_found() -> None:
    op, pv = _stuck()
    found = seized_valve(_record(op, pv))
    assert found is not None
    assert (found.start, found.stop) == (N // 4, N)
    assert found.op_travel == pytest.approx(40.0)
    assert found.pv == 0.0
    d = diagnose(_record(op, pv), recommend=False)
    assert d.verdict == "stiction" and d.confidence == pytest.approx(0.5)
    assert [e.key for e in d.evidence] == ["seized"]
    assert d.stiction is None  # no S and J from a valve that never moved
    assert "block valve" in d.reason and "transmitter" in d.reason


def test_a_recorded_position_that_moves_with_the_op_is_no_seized_valve() -> None:
    """A stuck transmitter over a valve that moves: the rule called it seized although the
    recorded position went from 50 to 100 % (found by an engineer); the position, in any span,
    says the valve answers. A position that stays put keeps the finding."""
    op, pv = _stuck()
    record = _record(op, pv)
    moving = LoopData(t=record.t, sp=record.sp, pv=pv, op=op, mode=record.mode,
                      position=0.5 + op / 200.0)  # another span and offset
    assert seized_valve(moving) is None
    reverse = LoopData(t=record.t, sp=record.sp, pv=pv, op=op, mode=record.mode,
                       position=100.0 - op)  # air to close: the other sense
    assert seized_valve(reverse) is None
    assert diagnose(moving, recommend=False).verdict == "undetermined"  # the PV is frozen
    still = LoopData(t=record.t, sp=record.sp, pv=pv, op=op, mode=record.mode,
                     position=np.full(len(op), 30.0))
    assert seized_valve(still) is not None


def test_each_condition_of_the_rule() -> None:
    op, pv = _stuck()
    # the OP travels less than MIN_OP_TRAVEL
    small_op, small_pv = _stuck(travel=0.9 * MIN_OP_TRAVEL)
    assert seized_valve(_record(small_op, small_pv)) is None
    # the OP swings both ways instead of winding up
    swing = 20.0 + 20.0 * np.sin(np.linspace(0.0, 6.0 * np.pi, N))
    assert seized_valve(_record(swing, pv)) is None
    # the error changes sign: SP = 0, the PV held at 0 (nothing to wind up against)
    assert seized_valve(_record(op, pv, sp=0.0)) is None
    # not in automatic during the run
    manual = np.ones(N)
    manual[N // 2] = 0.0
    assert seized_valve(_record(op, pv, mode=manual)) is None
    # a frozen run shorter than MIN_RUN_FRACTION of the record
    short = int(0.9 * MIN_RUN_FRACTION * N)
    rng = np.random.default_rng(4)
    live = 2.5 + rng.normal(0.0, 0.05, N)
    live[-short:] = 0.0
    assert seized_valve(_record(op, live)) is None
    # a PV that moves (a working valve) is never seized
    assert seized_valve(_record(op, live + np.linspace(0.0, 1.0, N))) is None


@pytest.mark.parametrize(("name", "verdict"), [("plant05.csv", "stiction"),
                                                ("plant07.csv", "undetermined")])
def test_the_plant_records(name: str, verdict: str) -> None:
    # plant05: flow held at 1.2e-16 for 441 samples while the OP ramps 35 -> 78 %; plant07:
    # its PV is constant too, but its OP moves 0.1 % (nothing winds up): the gate's refusal
    run = CliRunner().invoke(app, ["diagnose", str(PLANT / name), "--json"])
    assert run.exit_code == 0, run.output
    doc = json.loads(run.stdout)
    assert doc["verdict"] == verdict, doc["reason"]
    assert not doc["quality"]["passed"]
    if verdict == "stiction":
        assert doc["indices"]["seized"] == pytest.approx(78.415 - 35.5, abs=0.1)
        assert doc["stiction"] is None and "repair" in doc["recommendation"]["summary"]
