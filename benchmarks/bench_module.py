"""``Module.run`` of pid + process.fopdt against a numba PI + FOPDT loop, in one process.

    python benchmarks/bench_module.py [--scans N] [--repeats R]

The anchor is the near-limit reference: the same loop (PI in the ideal form, a first-order lag
with dead time as a ring buffer, unit step of the setpoint) written as one ``numba.njit``
function, with nothing recorded. loopworks runs the same closed loop through its compiled
execution plan, which also applies the numeric guard and records every input and output of
both blocks every scan. Both are warmed up (compiled or loaded from the cache) first; the
figure is the ratio of scans per second, median of R rounds. loopworks runs its ``fused`` plan
(``plan="fused"``: every kernel inlined, compiled once per module shape and cached, what a
module run many times takes; ``Module.run`` takes it by itself once it is cached).

A third line times that record alone: arrays of the shape ``Module.run`` writes (a float64
value and a status byte per scan of each signal it writes scan by scan: the outputs here,
``Module.record_plan``: a constant input is not written, an input wired to an output shares
its record), allocated and written scan by scan with no block run. No ``Module.run`` that
returns every signal can be faster, so its ratio is the ceiling of the figure on the machine
that runs it.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numba
import numpy as np

import loopworks
from loopworks.sim.module import Module

K, T, THETA = 1.0, 20.0, 2.0  # process gain, lag (s), dead time (s)
KC, TI = 2.0, 10.0  # PI gain and integral time (s)
DT = 0.1


@numba.njit(cache=True)
def numba_loop(n: int, dt: float) -> float:
    """PI (ideal form, backward Euler integral, no limits) on a FOPDT with an exact ring
    buffer of round(theta/dt) scans; returns the final PV so nothing is optimised away."""
    delay = round(THETA / dt)
    ring = np.zeros(delay)
    a = np.exp(-dt / T)
    y = 0.0
    integral = 0.0
    head = 0
    for _ in range(n):
        e = 1.0 - y
        integral += KC / TI * dt * e
        u = KC * e + integral
        u_late = ring[head]
        ring[head] = u
        head = (head + 1) % delay
        y = a * y + (1.0 - a) * K * u_late
    return y


@numba.njit(cache=True)
def record_loop(n: int, dt: float, t: np.ndarray, rf: np.ndarray, rs: np.ndarray) -> None:
    """The record of ``Module.run`` without the blocks: per scan, the time and one value and
    one status per signal (the values change every scan, so nothing is hoisted)."""
    v = 0.0
    for k in range(n):
        t[k] = k * dt
        v += 1.0
        for j in range(rf.shape[0]):
            rf[j, k] = v
            rs[j, k] = 128


def record_only(n: int, signals: int, dt: float) -> None:
    """Allocate and fill a record like ``Module.run``'s (see ``record_loop``)."""
    record_loop(n, dt, np.empty(n), np.empty((signals, n)),
                np.empty((signals, n), dtype=np.uint8))


def module() -> Module:
    blocks = {"pid": loopworks.create_block("pid", k=KC, ti=TI, out_lo=-1e9, out_hi=1e9),
              "process": loopworks.create_block("process.fopdt", gain=K, time_constant=T,
                                                dead_time=THETA)}
    return Module(blocks, wires={"process.u": "pid.out", "pid.pv": "process.y"},
                  inputs={"pid": {"sp": 1.0}})


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scans", type=int, default=1_000_000)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    n = args.scans
    m = module()
    m.run(100 * DT, DT, plan="fused")  # compile or load the plan
    numba_loop(10, DT)
    every = len(m.signals())
    signals = len(m.record_plan(range(every))[0])  # written scan by scan
    record_only(10, signals, DT)
    ours: list[float] = []
    theirs: list[float] = []
    record: list[float] = []
    for _ in range(args.repeats):
        start = time.perf_counter()
        m.run(n * DT, DT, plan="fused")
        ours.append(time.perf_counter() - start)
        start = time.perf_counter()
        numba_loop(n, DT)
        theirs.append(time.perf_counter() - start)
        start = time.perf_counter()
        record_only(n, signals, DT)
        record.append(time.perf_counter() - start)
    a, b, c = statistics.median(ours), statistics.median(theirs), statistics.median(record)
    print(f"numba PI+FOPDT loop          {n / b / 1e6:8.2f} M scans/s (median of {args.repeats})")
    print(f"loopworks Module.run         {n / a / 1e6:8.2f} M scans/s  ratio {b / a:5.3f} "
          "(target >= 0.10, goal 0.25; the fused plan)")
    print(f"the record alone ({signals} of {every} signals written) {n / c / 1e6:8.2f} M scans/s  "
          f"ratio {b / c:5.3f} (the ceiling: Module.run writes this record too)")


if __name__ == "__main__":
    main()
