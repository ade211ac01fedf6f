"""The live scheduler: absolute deadlines (no drift), lateness figures, overruns skipped by the
"Next" rule and counted, the watchdog (runtime-and-ecosystem.md 3.1)."""

from __future__ import annotations

import asyncio
import time

import pytest

from loopworks.errors import InputError
from loopworks.live.schedule import ScanStats, Scheduler
from tests.live.timing import wall_clock


def run(sched: Scheduler, work: float, scans: int,
        slow: set[int] | None = None, slow_work: float = 0.0) -> tuple[ScanStats, float]:
    """Run ``scans`` scans of ``work`` seconds of busy work each; the scans ``slow`` (counted
    as run, 0 the first, not by release index: which releases an overrun skips depends on how
    late the machine let it start) take ``slow_work``."""
    done = [0]

    async def scan(k: int) -> None:
        end = time.monotonic() + (slow_work if slow and done[0] in slow else work)
        done[0] += 1
        while time.monotonic() < end:  # busy work, as a scan's computation is
            pass

    async def main() -> tuple[ScanStats, float]:
        start = time.monotonic()
        stats = await sched.run(scan, asyncio.Event(), max_scans=scans)
        return stats, time.monotonic() - start

    return asyncio.run(main())


@wall_clock
def test_absolute_deadlines_do_not_drift() -> None:
    # 40 scans of 20 ms, each doing 5 ms of work: a sleep(period) loop would take
    # 40 x 25 ms = 1.0 s; on absolute deadlines the last scan starts at 39 x 20 ms
    stats, elapsed = run(Scheduler(0.020), 0.005, 40)
    assert stats.scans == 40
    assert 0.78 + 0.005 <= elapsed < 0.78 + 0.005 + 0.10
    s = stats.summary()
    assert 0.0 <= s["late_min_ms"] <= s["late_mean_ms"] <= s["late_p99_ms"] <= s["late_max_ms"]
    assert s["run_mean_ms"] >= 5.0
    assert s["overruns"] == 0 and s["skipped"] == 0


@wall_clock
def test_overruns_skip_to_the_next_release_and_trip_the_watchdog() -> None:
    trips: list[int] = []
    sched = Scheduler(0.010, watchdog_overruns=3,
                      on_watchdog=lambda st: trips.append(st.scans))
    # the third, fourth and fifth scans run take 25 ms: each ends after two more releases
    # (k+1, k+2 passed), so it overruns, the releases it missed are skipped (not run in a
    # burst), and the third in a row trips the watchdog once
    stats, _ = run(sched, 0.0, 8, slow={2, 3, 4}, slow_work=0.025)
    assert stats.scans == 8
    assert stats.overruns == 3
    assert stats.skipped >= 3  # each 25 ms scan passes at least one more release
    assert stats.watchdog_trips == 1 and len(trips) == 1
    # releases of the slow scans are 2, then >= 5, ... : k jumps past the missed ones


@wall_clock
def test_a_scan_on_time_rearms_the_watchdog() -> None:
    sched = Scheduler(0.010, watchdog_overruns=2)
    stats, _ = run(sched, 0.0, 6, slow={0, 4}, slow_work=0.015)
    assert stats.overruns >= 1
    assert stats.watchdog_trips == 0


@pytest.mark.parametrize("period", [0.0, -1.0, float("nan"), float("inf")])
def test_a_wrong_period_is_named(period: float) -> None:
    with pytest.raises(InputError, match="scan period"):
        Scheduler(period)


@wall_clock
def test_stop_ends_the_run_at_once() -> None:
    async def main() -> tuple[int, float]:
        stop = asyncio.Event()
        sched = Scheduler(0.5)

        async def scan(k: int) -> None:
            if k == 0:
                asyncio.get_running_loop().call_later(0.05, stop.set)

        start = time.monotonic()
        stats = await sched.run(scan, stop)
        return stats.scans, time.monotonic() - start

    scans, elapsed = asyncio.run(main())
    assert scans == 1
    assert elapsed < 0.3  # not the 0.5 s until the next release
