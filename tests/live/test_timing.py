"""The wall-clock retry of the live timing tests (tests/live/timing.py): a failure that
repeats is reported, a one-off is forgiven, anything but an assertion is not retried."""

from __future__ import annotations

import pytest

from tests.live.timing import ATTEMPTS, wall_clock


def test_a_failure_every_attempt_is_reported_after_all_attempts() -> None:
    calls: list[int] = []

    @wall_clock
    def drifts() -> None:
        calls.append(1)
        assert len(calls) < 0, "drifted"

    with pytest.raises(AssertionError, match="drifted"):
        drifts()
    assert len(calls) == ATTEMPTS == 3


def test_a_one_off_stall_passes_on_the_next_attempt() -> None:
    calls: list[int] = []

    @wall_clock
    def stalls_once(x: int) -> int:
        calls.append(x)
        assert len(calls) > 1
        return x

    assert stalls_once(7) == 7 and calls == [7, 7]


def test_an_error_is_not_retried() -> None:
    calls: list[int] = []

    @wall_clock
    def broken() -> None:
        calls.append(1)
        raise ValueError("a bug, not a stall")

    with pytest.raises(ValueError):
        broken()
    assert calls == [1]
