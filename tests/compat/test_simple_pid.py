"""simple-pid 2.0.1's own tests (``tests/test_pid.py``, 20 tests), ported to
``loopworks.compat.PID`` with an explicit ``dt`` (or a fake clock) instead of sleeping.

Each test keeps its original name and assertions; where simple-pid measured time with
``time.sleep``, the port passes the same interval as ``dt`` or advances a fake ``time_fn``.
The golden values are simple-pid's (its tests' literals), and the closed-loop tests also run
simple-pid itself beside the port as the independent reference.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable

import pytest

from loopworks.compat import PID, clamp_limits


class Clock:
    """A fake monotonic clock (the port of simple-pid's ``stime``)."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now

    def tick(self, seconds: float) -> None:
        self.now += seconds


def test_zero() -> None:
    pid = PID(1, 1, 1, setpoint=0)
    assert pid(0, dt=0.01) == 0


def test_P() -> None:
    pid = PID(1, 0, 0, setpoint=10, sample_time=None)
    assert pid(0, dt=0.1) == 10
    assert pid(5, dt=0.1) == 5
    assert pid(-5, dt=0.1) == 15


def test_P_negative_setpoint() -> None:
    pid = PID(1, 0, 0, setpoint=-10, sample_time=None)
    assert pid(0, dt=0.1) == -10
    assert pid(5, dt=0.1) == -15
    assert pid(-5, dt=0.1) == -5
    assert pid(-15, dt=0.1) == 5


def test_I() -> None:
    pid = PID(0, 10, 0, setpoint=10, sample_time=0.1)
    assert round(pid(0, dt=0.1)) == 10.0  # 10·10·0.1
    assert round(pid(0, dt=0.1)) == 20.0


def test_I_negative_setpoint() -> None:
    pid = PID(0, 10, 0, setpoint=-10, sample_time=0.1)
    assert round(pid(0, dt=0.1)) == -10.0
    assert round(pid(0, dt=0.1)) == -20.0


def test_D() -> None:
    pid = PID(0, 0, 0.1, setpoint=10, sample_time=0.1)
    # no derivative when there is no previous input (0 is not assumed as the first input)
    assert pid(0, dt=0.1) == 0
    # the derivative is 0 when the input is the same; the third call comes within sample_time
    assert pid(0, dt=0.1) == 0
    assert pid(0, dt=1e-16) == 0
    assert round(pid(5, dt=0.1)) == -5  # -0.1·5/0.1
    assert round(pid(15, dt=0.1)) == -10


def test_D_negative_setpoint() -> None:
    pid = PID(0, 0, 0.1, setpoint=-10, sample_time=0.1)
    assert pid(0, dt=0.1) == 0
    assert pid(0, dt=0.1) == 0
    assert pid(0, dt=1e-16) == 0
    assert round(pid(5, dt=0.1)) == -5
    assert round(pid(-5, dt=0.1)) == 10
    assert round(pid(-15, dt=0.1)) == 10


def test_desired_state() -> None:
    pid = PID(10, 5, 2, setpoint=10, sample_time=None)
    # no adjustment when the setpoint is reached
    assert pid(10, dt=0.1) == 0


def test_output_limits() -> None:
    pid = PID(100, 20, 40, setpoint=10, output_limits=(0, 100), sample_time=None)
    assert 0 <= pid(0, dt=0.1) <= 100
    assert 0 <= pid(-100, dt=0.1) <= 100


def test_sample_time() -> None:
    pid = PID(setpoint=10, sample_time=10)
    control = pid(0, dt=10.0)
    # within the sample time the last value is returned again
    assert pid(100, dt=1.0) == control


def test_time_fn() -> None:
    pid = PID()
    assert pid.time_fn == time.monotonic  # the default
    i = 0

    def time_function() -> float:
        nonlocal i
        i += 1
        return i

    pid.time_fn = time_function
    for j in range(1, 5):
        pid(0)  # the time function above is used
        assert pid._last_time == j


def test_time_fn_notime() -> None:
    saved = sys.modules["time"]
    sys.modules["time"] = None  # type: ignore[assignment]
    try:
        with pytest.raises(ModuleNotFoundError):
            PID()  # without the time module a time_fn must be given
        PID(time_fn=lambda: 0)
    finally:
        sys.modules["time"] = saved


def test_starting_output() -> None:
    pid = PID(1, 0, 0, setpoint=10, starting_output=25)
    assert pid(10, dt=0.1) == 25


def test_auto_mode() -> None:
    clock = Clock()
    pid = PID(1, 0, 0, setpoint=10, sample_time=None, time_fn=clock)
    assert pid(0, dt=0.1) == 10
    assert pid(5, dt=0.1) == 5
    # no updates in manual
    pid.auto_mode = False
    assert pid(1, dt=0.1) == 5
    assert pid(7, dt=0.1) == 5
    # reactivating resets
    pid.auto_mode = True
    assert pid._last_input is None
    assert pid._integral == 0
    assert pid(8, dt=0.1) == 2
    # the last update time is reset too, so no huge dt follows
    pid.auto_mode = False
    clock.tick(1)
    pid.auto_mode = True
    assert pid._last_time is not None
    assert pid.time_fn() - pid._last_time < 0.01
    # setting the last output
    pid.auto_mode = False
    pid.set_auto_mode(True, last_output=10)
    assert pid._integral == 10


def test_separate_components() -> None:
    pid = PID(1, 0, 1, setpoint=10, sample_time=0.1)
    assert pid(0, dt=0.1) == 10
    assert pid.components == (10, 0, 0)
    assert round(pid(5, dt=0.1)) == -45
    assert tuple(round(term) for term in pid.components) == (5, 0, -50)


def test_clamp() -> None:
    assert clamp_limits(None, (None, None)) is None
    assert clamp_limits(None, (-10, 10)) is None
    # no limits
    assert clamp_limits(0, (None, None)) == 0
    assert clamp_limits(100, (None, None)) == 100
    assert clamp_limits(-100, (None, None)) == -100
    # only a lower limit
    assert clamp_limits(0, (0, None)) == 0
    assert clamp_limits(100, (0, None)) == 100
    assert clamp_limits(-100, (0, None)) == 0
    # only an upper limit
    assert clamp_limits(0, (None, 0)) == 0
    assert clamp_limits(100, (None, 0)) == 0
    assert clamp_limits(-100, (None, 0)) == -100
    # both
    assert clamp_limits(0, (-10, 10)) == 0
    assert clamp_limits(-10, (-10, 10)) == -10
    assert clamp_limits(10, (-10, 10)) == 10
    assert clamp_limits(-100, (-10, 10)) == -10
    assert clamp_limits(100, (-10, 10)) == 10


def test_repr() -> None:
    pid = PID(1, 2, 3, setpoint=10)
    new_pid = eval(repr(pid), {"PID": PID})
    assert new_pid.Kp == 1
    assert new_pid.Ki == 2
    assert new_pid.Kd == 3
    assert new_pid.setpoint == 10


def _converge(make: Callable[..., object], **kw: object) -> list[float]:
    """simple-pid's converge test: an integrator with a constant load, dt = 0.01 s for 120 s
    (the original slept in real time for that long)."""
    pid = make(1, 0.8, 0.04, setpoint=5, output_limits=(-5, 5), **kw)
    pv = 0.0
    trace = []
    for _ in range(12_000):
        c = pid(pv, dt=0.01)  # type: ignore[operator]
        pv = pv + c * 0.01 - 1 * 0.01
        trace.append(pv)
    return trace


@pytest.mark.parametrize("d_on_m", [True, False], ids=["converge_system",
                                                       "converge_diff_on_error"])
def test_converge_system(d_on_m: bool) -> None:
    """test_converge_system and test_converge_diff_on_error; simple-pid beside the port."""
    import simple_pid  # a test dependency (the [test] extra)

    ours = _converge(PID, differential_on_measurement=d_on_m)
    theirs = _converge(simple_pid.PID, differential_on_measurement=d_on_m)
    assert abs(ours[-1] - 5) < 0.1  # converged
    assert max(abs(a - b) for a, b in zip(ours, theirs, strict=True)) < 1e-9


def test_error_map() -> None:
    def pi_clip(angle: float) -> float:
        """The angle in [-pi, pi)."""
        if angle > 0:
            if angle > math.pi:
                return angle - 2 * math.pi
        elif angle < -math.pi:
            return angle + 2 * math.pi
        return angle

    sp, pv = 0.0, 5.0
    pid = PID(1, 0, 0, setpoint=0.0, sample_time=0.1, error_map=pi_clip)
    assert pid(pv, dt=0.1) == pi_clip(sp - pv)  # the error is mapped
