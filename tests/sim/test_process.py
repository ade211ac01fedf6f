"""The first-order process: exact ZOH step of T·dy/dt = K·u - y."""

import math

import pytest

import loopworks


def test_first_order_step_response_is_exact() -> None:
    """y(t) = K·u·(1 - e^(-t/T)) at the sample times, for a held input."""
    proc = loopworks.create_block("process.first_order", gain=2.0, time_constant=10.0)
    for k in range(1, 51):
        y = proc.step(0.5, u=3.0)["y"].value
        assert y == pytest.approx(6.0 * (1.0 - math.exp(-0.5 * k / 10.0)), abs=1e-12)


def test_initial_output_and_zero_time_constant() -> None:
    proc = loopworks.create_block("process.first_order", gain=1.5, time_constant=0.0, y0=4.0)
    assert proc.outputs()["y"].value == 4.0
    assert proc.step(1.0, u=2.0)["y"].value == 3.0


def test_nan_input_freezes_and_marks_bad() -> None:
    proc = loopworks.create_block("process.first_order", gain=1.0, time_constant=5.0)
    y1 = proc.step(1.0, u=1.0)["y"]
    y2 = proc.step(1.0, u=math.nan)["y"]
    assert y2.value == y1.value
    assert y2.status == 0
    assert proc.step(1.0, u=(1.0, 0x1C))["y"].status == 0   # Bad status input
    assert proc.step(1.0, u=1.0)["y"].status == 128
