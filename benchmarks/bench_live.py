"""Many live loops on one core: scan lateness and overruns (issue 16).

    python benchmarks/bench_live.py [--loops 100] [--hz 10] [--seconds 60] [--cores 1]

Runs ``--loops`` copies of the built-in scenario's controller side (the DeltaV PID, the
signal generator and the stick-slip compensator) as live controllers, each on its own
absolute-deadline scheduler (:mod:`loopworks.live.schedule`) at ``--hz`` scans per second of
wall time (plant time runs at dt·hz, the scenario's dt being 0.5 s), all in one process on
one event loop, pinned to ``--cores`` cores. Each controller's device is its own plant side
in memory (:mod:`loopworks.live.loopback`): the plant's scan is done inside the controller's
scan, so the figure is conservative (a real device computes its plant elsewhere), and no
network time is in it. Prints, over all loops, the lateness of the scans' starts (min, mean,
p99, max), the overruns and skipped releases, and the share of the core the scans used.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import time

import numpy as np

from loopworks.live.loopback import LoopbackIO
from loopworks.live.registers import default_map
from loopworks.live.schedule import Scheduler
from loopworks.live.serve import LiveController
from loopworks.live.split import split_scenario
from loopworks.sim.scenario import load_scenario


async def main_async(loops: int, hz: float, seconds: float) -> None:
    sc = load_scenario(None)
    controllers = []
    for _ in range(loops):
        split = split_scenario(sc, "compensation_on")
        controllers.append(LiveController(split, default_map(split), LoopbackIO(split)))
    for c in controllers:  # warm up: load the compiled kernels, settle the first scans
        await c.scan()
    stop = asyncio.Event()
    scheds = [Scheduler(1.0 / hz) for _ in controllers]

    async def run(c: LiveController, s: Scheduler) -> None:
        async def one(k: int) -> None:
            await c.scan(k)
            c.snapshot()  # what an OPC UA server would publish
        await s.run(one, stop, max_scans=round(seconds * hz))

    cpu0, wall0 = time.process_time(), time.perf_counter()
    await asyncio.gather(*(run(c, s) for c, s in zip(controllers, scheds, strict=True)))
    cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
    late = np.concatenate([np.fromiter(s.stats.recent, float) for s in scheds]) * 1e3
    scans = sum(s.stats.scans for s in scheds)
    overruns = sum(s.stats.overruns for s in scheds)
    skipped = sum(s.stats.skipped for s in scheds)
    run_ms = np.array([s.stats.run_sum / max(s.stats.scans, 1) for s in scheds]) * 1e3
    print(f"{loops} loops at {hz:g} Hz for {seconds:g} s on {len(os.sched_getaffinity(0))} "
          f"core(s): {scans} scans in {wall:.1f} s")
    print(f"  lateness ms: min {late.min():.3f}  mean {late.mean():.3f}  "
          f"p99 {np.percentile(late, 99):.3f}  max {late.max():.3f}")
    print(f"  overruns {overruns}, releases skipped {skipped}; one scan (controller + its "
          f"in-memory plant) {run_ms.mean():.3f} ms on average")
    print(f"  CPU {cpu / wall:.0%} of one core")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--loops", type=int, default=100)
    ap.add_argument("--hz", type=float, default=10.0)
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--cores", type=int, default=1)
    args = ap.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, set(sorted(os.sched_getaffinity(0))[:args.cores]))
    asyncio.run(main_async(args.loops, args.hz, args.seconds))


if __name__ == "__main__":
    main()
