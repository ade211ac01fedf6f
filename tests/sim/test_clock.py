"""The controller-clock convention: an input named ``clock`` receives the scan time."""

from __future__ import annotations

import io
import math
from pathlib import Path
from typing import ClassVar

import numpy as np

from loopworks.blocks.block import Block
from loopworks.blocks.kernel import FloatArray, IntArray
from loopworks.blocks.params import Param, Port
from loopworks.sim.module import Module
from loopworks.sim.replay import replay
from tests.csvfiles import write_csv


def probe_kernel(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                 y: FloatArray, ys: IntArray) -> None:
    y[0] = u[0]
    y[1] = dt


class ClockProbe(Block):
    """Echoes its clock input and dt (a test block, not registered)."""

    kind = "test.clock_probe"
    kernel = staticmethod(probe_kernel)
    PARAMS: ClassVar[tuple[Param, ...]] = ()
    INPUTS: ClassVar[tuple[Port, ...]] = (Port("clock", math.nan, "s", "controller clock"),)
    OUTPUTS: ClassVar[tuple[Port, ...]] = (Port("seen", 0.0, "s", "clock seen"),
                                           Port("dt", 0.0, "s", "dt seen"))

    def coefficients(self) -> list[float]:
        return []


def test_module_feeds_the_scan_time() -> None:
    m = Module({"probe": ClockProbe(jit=False)})
    result = m.run(duration=1.0, dt=0.25)
    np.testing.assert_array_equal(result["probe.seen"], [0.0, 0.25, 0.5, 0.75])


def test_a_given_clock_constant_wins() -> None:
    m = Module({"probe": ClockProbe(jit=False)}, inputs={"probe": {"clock": 7.0}})
    assert (m.run(duration=1.0, dt=0.5)["probe.seen"] == 7.0).all()


def test_replay_feeds_the_t_column(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "in.csv", ["t"], [[100.0], [100.5], [101.5]])
    buf = io.StringIO()
    replay(ClockProbe(jit=False), path, buf)
    rows = [line.split(",") for line in buf.getvalue().split()][1:]
    assert [float(r[1]) for r in rows] == [100.0, 100.5, 101.5]
    assert [float(r[2]) for r in rows] == [0.5, 0.5, 1.0]


def test_replay_keeps_a_clock_column(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "in.csv", ["t", "clock"], [[0.0, 5.0], [1.0, 6.0]])
    buf = io.StringIO()
    replay(ClockProbe(jit=False), path, buf)
    rows = [line.split(",") for line in buf.getvalue().split()][1:]
    assert [float(r[1]) for r in rows] == [5.0, 6.0]
