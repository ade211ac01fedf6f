"""Wall-clock tests on a shared machine: a measurement is taken up to three times.

A live test that asserts real time (a scan of 5 ms never overruns its 20 ms period, 40 scans
take 0.78 s and not the 1.0 s of a drifting loop) measures the machine as much as the code: a
third process that takes the core for 20 ms makes one run overrun. :func:`wall_clock` runs
such a test again when an assertion fails, up to ``attempts`` times, and reports the last
failure. A wrong scheduler (a ``sleep(period)`` loop, a burst after an overrun) fails every
attempt, so the test still fails for the bug it pins; only a one-off stall is forgiven.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import ParamSpec, TypeVar

P = ParamSpec("P")
R = TypeVar("R")

ATTEMPTS = 3


def wall_clock(test: Callable[P, R]) -> Callable[P, R]:
    """Run ``test`` up to :data:`ATTEMPTS` times until its assertions hold (module docstring)."""

    @functools.wraps(test)
    def run(*args: P.args, **kwargs: P.kwargs) -> R:
        for attempt in range(1, ATTEMPTS + 1):
            try:
                return test(*args, **kwargs)
            except AssertionError:
                if attempt == ATTEMPTS:
                    raise
        raise AssertionError("unreachable")  # pragma: no cover

    return run
