"""The numeric guard every scan runs under (kernel.guarded_scan, issue 11 point 1), on toy
kernels whose behaviour is known by hand: compiled and interpreted alike."""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np
import pytest

from loopworks.blocks.block import Block
from loopworks.blocks.kernel import FloatArray, IntArray, run_rows
from loopworks.blocks.params import Port


def summing_kernel(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                   y: FloatArray, ys: IntArray) -> None:
    """x += a - b while both are not Bad; y = x with Good status; with a Bad input, hold x and
    say Uncertain (0x44)."""
    if (us[0] & 0xC0) == 0 or (us[1] & 0xC0) == 0:
        y[0] = x[0]
        ys[0] = 0x44
        return
    x[0] = x[0] + (u[0] - u[1])
    y[0] = x[0]
    ys[0] = 128


def ignorant_kernel(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                    y: FloatArray, ys: IntArray) -> None:
    """x += a, y = 2x: ignores every status (a kind with no answer for Bad input)."""
    x[0] = x[0] + u[0]
    y[0] = 2.0 * x[0]
    ys[0] = 128


class Summing(Block):
    kind = "test.summing"
    kernel = staticmethod(summing_kernel)
    SOUND_KERNEL = False  # overflows on purpose: the full guard is what is tested here
    INPUTS: ClassVar[tuple[Port, ...]] = (Port("a", 0.0, status=True), Port("b", 0.0,
                                                                              status=True))
    OUTPUTS: ClassVar[tuple[Port, ...]] = (Port("y", 0.0, status=True),)
    STATES: ClassVar[tuple[str, ...]] = ("x",)

    def coefficients(self) -> list[float]:
        return []


class Ignorant(Summing):
    kind = "test.ignorant"
    kernel = staticmethod(ignorant_kernel)


@pytest.fixture(params=[False, True], ids=["interpreted", "compiled"])
def jit(request: pytest.FixtureRequest) -> bool:
    return bool(request.param)


def test_a_non_finite_input_is_bad_input_for_the_kernel(jit: bool) -> None:
    block = Summing(jit=jit)
    assert block.step(1.0, a=3.0, b=1.0)["y"] == (2.0, 128)
    for value in (math.nan, math.inf, -math.inf):
        assert block.step(1.0, a=value)["y"] == (2.0, 0x44)  # held, the kernel saw Bad
    assert block.us[0] == 128  # the latched status is what was given
    assert block.step(1.0, a=2.0)["y"] == (3.0, 128)  # recovers at once


def test_an_overflowing_scan_is_rerun_as_bad_input(jit: bool) -> None:
    block = Summing(jit=jit)
    block.step(1.0, a=1e308, b=0.0)
    assert block.x[0] == 1e308
    out = block.step(1.0, a=1e308, b=-1e308)["y"]  # 1e308 + 2e308 overflows
    assert out == (1e308, 0x44)
    assert block.x[0] == 1e308  # the state is the one before the scan


def test_a_kind_without_an_answer_holds_with_bad_status(jit: bool) -> None:
    block = Ignorant(jit=jit)
    assert block.step(1.0, a=2.0)["y"] == (4.0, 128)
    out = block.step(1.0, a=math.nan)["y"]
    assert out.value == 4.0 and out.status == 0  # held, Bad
    assert block.x[0] == 2.0
    out = block.step(1.0, a=1.0)["y"]
    assert out == (6.0, 128)


def echo_kernel(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                y: FloatArray, ys: IntArray) -> None:
    """y = the status the kernel sees for input a."""
    y[0] = float(us[0])
    ys[0] = 128


class Echo(Summing):
    kind = "test.echo"
    kernel = staticmethod(echo_kernel)


def test_the_kernel_sees_bad_for_non_finite_values_and_a_bad_substatus_is_kept(
        jit: bool) -> None:
    block = Echo(jit=jit)
    assert block.step(1.0, a=(math.nan, 128))["y"].value == 0
    assert block.step(1.0, a=(math.inf, 0x44))["y"].value == 0
    assert block.step(1.0, a=(math.nan, 0x18))["y"].value == 0x18  # Bad NoComm kept
    assert block.step(1.0, a=(5.0, 0x44))["y"].value == 0x44  # finite: as given


def test_replay_rows_run_under_the_guard_and_start_from_the_held_outputs(jit: bool) -> None:
    block = Summing(jit=jit)
    U = np.array([[1.0, 0.0], [math.nan, 0.0], [1e308, -1e308], [2.0, 0.0]])
    US = np.full((4, 2), 128, dtype=np.int64)
    Y = np.empty((4, 1))
    YS = np.empty((4, 1), dtype=np.int64)
    Y[0] = block.y
    YS[0] = block.ys
    run_rows(Summing.kernel, np.ones(4), block.p, block.x, U, US, Y, YS, jit=jit)
    assert Y[:, 0].tolist() == [1.0, 1.0, 1.0, 3.0]
    assert YS[:, 0].tolist() == [128, 0x44, 0x44, 128]
