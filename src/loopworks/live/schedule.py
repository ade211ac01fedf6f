"""Periodic scans on absolute deadlines, with lateness and overrun statistics and a watchdog.

The scan of period P released at k (k = 0, 1, ...) is due at ``t0 + k·P`` on the monotonic
clock; the scheduler sleeps until then (``sleep(deadline - now)``, never ``sleep(P)``, which
drifts by the scan's own run time every scan: runtime-and-ecosystem.md 3.1). Its lateness is
``start - deadline``. A scan that ends after the next release has *overrun*: by the "Next"
rule of CODESYS task configuration (the default there), the missed releases are skipped, not
run in a burst, and counted; the next scan starts at the next release still ahead. The
watchdog trips after :attr:`Scheduler.watchdog_overruns` consecutive overruns (CODESYS's
sensitivity) and calls ``on_watchdog`` once per trip; a scan on time re-arms it.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import time
from collections import deque
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field

import numpy as np

from loopworks.errors import InputError

#: lateness samples kept for the percentiles (the last this many scans)
LATENESS_WINDOW = 100_000


@dataclass
class ScanStats:
    """What the scheduler measured: scans run, overruns (scans that ended after the next
    release), releases skipped by them, watchdog trips, and the lateness of each scan's start
    after its release, s (min, mean, max over the whole run; p99 over the last
    :data:`LATENESS_WINDOW` scans); ``run_time`` of the scans, s (mean and max)."""

    period: float
    scans: int = 0
    overruns: int = 0
    skipped: int = 0
    watchdog_trips: int = 0
    late_min: float = math.inf
    late_max: float = 0.0
    late_sum: float = 0.0
    run_max: float = 0.0
    run_sum: float = 0.0
    recent: deque[float] = field(default_factory=lambda: deque(maxlen=LATENESS_WINDOW))

    def add(self, lateness: float, run_time: float) -> None:
        self.scans += 1
        self.late_min = min(self.late_min, lateness)
        self.late_max = max(self.late_max, lateness)
        self.late_sum += lateness
        self.run_max = max(self.run_max, run_time)
        self.run_sum += run_time
        self.recent.append(lateness)

    def summary(self) -> dict[str, float | int]:
        """The figures in milliseconds (``*_ms``) and counts, JSON-able."""
        n = max(self.scans, 1)
        p99 = float(np.percentile(np.fromiter(self.recent, float), 99)) if self.recent else 0.0
        return {"period_ms": self.period * 1e3, "scans": self.scans,
                "overruns": self.overruns, "skipped": self.skipped,
                "watchdog_trips": self.watchdog_trips,
                "late_min_ms": (0.0 if self.scans == 0 else self.late_min) * 1e3,
                "late_mean_ms": self.late_sum / n * 1e3, "late_p99_ms": p99 * 1e3,
                "late_max_ms": self.late_max * 1e3,
                "run_mean_ms": self.run_sum / n * 1e3, "run_max_ms": self.run_max * 1e3}


class Scheduler:
    """Runs ``scan(k)`` every ``period`` seconds of wall time (module docstring)."""

    def __init__(self, period: float, *, watchdog_overruns: int = 3,
                 on_watchdog: Callable[[ScanStats], None] | None = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        if not (math.isfinite(period) and period > 0.0):
            raise InputError(f"scan period = {period!r} s is not allowed: it must be > 0 and "
                             "finite")
        if watchdog_overruns < 1:
            raise InputError(f"watchdog_overruns = {watchdog_overruns!r} is not allowed: it "
                             "must be >= 1")
        self.period = period
        self.watchdog_overruns = watchdog_overruns
        self.on_watchdog = on_watchdog
        self.clock = clock
        self.stats = ScanStats(period)

    async def run(self, scan: Callable[[int], Awaitable[None]], stop: asyncio.Event,
                  max_scans: int | None = None) -> ScanStats:
        """Scan until ``stop`` is set (or ``max_scans`` scans ran). ``scan`` gets the release
        number k (its plant time is k·period·speedup to the caller)."""
        period, clock, stats = self.period, self.clock, self.stats
        t0 = clock()
        k = 0
        consecutive = 0
        while not stop.is_set() and (max_scans is None or stats.scans < max_scans):
            deadline = t0 + k * period
            delay = deadline - clock()
            if delay > 0.0:
                with contextlib.suppress(TimeoutError):  # wake at the deadline ...
                    await asyncio.wait_for(stop.wait(), delay)
                    break  # ... or at once when stopped
            start = clock()
            await scan(k)
            end = clock()
            stats.add(max(start - deadline, 0.0), end - start)
            nxt = k + 1
            if end > t0 + nxt * period:  # overran the next release: skip to the next ahead
                ahead = math.floor((end - t0) / period) + 1
                stats.overruns += 1
                stats.skipped += ahead - nxt
                nxt = ahead
                consecutive += 1
                if consecutive == self.watchdog_overruns:
                    stats.watchdog_trips += 1
                    if self.on_watchdog is not None:
                        self.on_watchdog(stats)
            else:
                consecutive = 0
            k = nxt
        return stats
