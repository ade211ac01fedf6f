"""Many live loops on one core: scan lateness and overruns (issue 16).

    python benchmarks/bench_live.py [--loops 100] [--hz 10] [--seconds 60] [--cores 1]
                                    [--io memory|modbus]

Runs ``--loops`` copies of the built-in scenario's controller side (the DeltaV PID, the
signal generator and the stick-slip compensator) as live controllers, each on its own
absolute-deadline scheduler (:mod:`loopworks.live.schedule`) at ``--hz`` scans per second of
wall time (plant time runs at dt·hz, the scenario's dt being 0.5 s), all in one process on
one event loop, pinned to ``--cores`` cores. ``--io memory`` (default): each controller's
device is its own plant side in memory (:mod:`loopworks.live.loopback`), its plant scanned
inside the controller's scan (conservative: a real device computes its plant elsewhere), no
network. ``--io modbus``: each controller reads and writes its own ``loopworks.live.device``
over Modbus TCP on 127.0.0.1 (:mod:`loopworks.live.modbus_io`, one request to read, one to
write per scan), the devices running in another process on the other cores. Prints, over all
loops, the lateness of the scans' starts (min, mean, p99, max), the overruns and skipped
releases, and the share of the core the controllers used.
"""

from __future__ import annotations

import argparse
import asyncio
import multiprocessing as mp
import os
import time
from typing import Any

import numpy as np

from loopworks.live.loopback import LoopbackIO
from loopworks.live.modbus_io import ModbusIO
from loopworks.live.registers import default_map
from loopworks.live.schedule import Scheduler
from loopworks.live.serve import LiveController
from loopworks.live.split import split_scenario
from loopworks.sim.scenario import load_scenario


def devices_main(loops: int, speedup: float, cores: set[int], conn: Any) -> None:
    """The devices' process: ``loops`` built-in plants, each on its own port."""
    if cores and hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, cores)

    async def run() -> None:
        from loopworks.live.device import Device

        sc = load_scenario(None)
        devices = []
        for _ in range(loops):
            split = split_scenario(sc, "compensation_on")
            devices.append(Device(split, default_map(split), speedup=speedup,
                                  fstate_time=3600.0))
        conn.send([await d.start("127.0.0.1", 0) for d in devices])
        await asyncio.gather(*(d.run() for d in devices))

    asyncio.run(run())


async def main_async(loops: int, hz: float, seconds: float, io: str,
                     other_cores: set[int]) -> None:
    sc = load_scenario(None)
    controllers = []
    ports: list[int] = []
    proc = None
    if io == "modbus":
        ctx = mp.get_context("spawn")
        here, there = ctx.Pipe()
        speedup = hz * sc.dt
        proc = ctx.Process(target=devices_main, args=(loops, speedup, other_cores, there),
                           daemon=True)
        proc.start()
        ports = here.recv()
    for i in range(loops):
        split = split_scenario(sc, "compensation_on")
        regmap = default_map(split)
        dev: Any = (ModbusIO(regmap, "127.0.0.1", ports[i]) if io == "modbus"
                    else LoopbackIO(split))
        controllers.append(LiveController(split, regmap, dev))
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
    what = ("controller + its in-memory plant" if io == "memory"
            else "controller, awaiting its two Modbus requests")
    print(f"  overruns {overruns}, releases skipped {skipped}; one scan ({what}) "
          f"{run_ms.mean():.3f} ms on average")
    print(f"  CPU {cpu / wall:.0%} of one core (the controllers' process; I/O: {io})")
    if proc is not None:
        proc.terminate()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--loops", type=int, default=100)
    ap.add_argument("--hz", type=float, default=10.0)
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--cores", type=int, default=1)
    ap.add_argument("--io", choices=("memory", "modbus"), default="memory")
    args = ap.parse_args()
    other: set[int] = set()
    if hasattr(os, "sched_setaffinity"):
        cores = sorted(os.sched_getaffinity(0))
        os.sched_setaffinity(0, set(cores[:args.cores]))
        other = set(cores[args.cores:])
    asyncio.run(main_async(args.loops, args.hz, args.seconds, args.io, other))


if __name__ == "__main__":
    main()
