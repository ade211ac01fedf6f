"""Sweep throughput (issue 14 point 5): ``loopworks.sweep`` against a numba ``prange`` PI+FOPDT
batch (the near-limit anchor, written here) and against a plain Python loop over
``Module.run``, in one process; and the peak memory of the sweep's process.

    python benchmarks/bench_sweep.py [--instances N] [--scans S] [--builtin-instances M]

Loops: (1) pid + process.fopdt (K = 1, T = 20 s, dead time 2 s, PI Kc = 2, Ti = 10 s, a unit
setpoint, dt = 0.1 s), ``--instances`` instances of ``--scans`` scans, the controller gain
drawn uniform(1, 3) per instance, with the batch that calls each kind's cached kernel
(``plan="compiled"``) and with every kernel inlined (``plan="fused"``, compiled once per
module shape, which ``"auto"`` takes once it is cached); (2) the built-in scenario (7 blocks,
two variants, its own one-hour run), ``--builtin-instances`` Monte Carlo instances of the
valve's resolution (its slip jump). Each figure is instances per second (the sweep's:
``SweepResult.seconds``, the instances' run with its worker processes, not the ``[autotune]``
relay tests, one per point, before it: the Python loop runs none either); the ratios are the
figures (absolute times on shared machines are noise).
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numba
import numpy as np

import loopworks
from loopworks.sim.scenario import load_scenario

K, T, THETA, KC, TI, DT = 1.0, 20.0, 2.0, 2.0, 10.0, 0.1

LOOP = f"""\
[simulation]
dt = {DT}
duration = {{duration}}

[blocks.pid]
kind = "pid"
k = {KC}
ti = {TI}
out_lo = -1e9
out_hi = 1e9
sp = 1.0

[blocks.process]
kind = "process.fopdt"
gain = {K}
time_constant = {T}
dead_time = {THETA}

[wires]
"process.u" = "pid.out"
"pid.pv" = "process.y"
"""


@numba.njit(parallel=True, cache=True)
def numba_batch(kc: np.ndarray, n: int, dt: float) -> np.ndarray:
    """Each instance: PI (gain kc[i]) on the FOPDT with an exact ring buffer, n scans; returns
    each instance's IAE so nothing is optimised away."""
    out = np.empty(kc.size)
    delay = round(THETA / dt)
    a = np.exp(-dt / T)
    for i in numba.prange(kc.size):
        ring = np.zeros(delay)
        y = 0.0
        integral = 0.0
        head = 0
        iae = 0.0
        for _ in range(n):
            e = 1.0 - y
            iae += abs(e) * dt
            integral += kc[i] / TI * dt * e
            u = kc[i] * e + integral
            u_late = ring[head]
            ring[head] = u
            head = (head + 1) % delay
            y = a * y + (1.0 - a) * K * u_late
        out[i] = iae
    return out


# VmHWM, not ru_maxrss: a child's ru_maxrss starts at its parent's peak at the fork
MEMORY_CHILD = """
import re, sys
import loopworks
def peak():
    with open("/proc/self/status") as f:
        return int(re.search(r"VmHWM:\\s+(\\d+) kB", f.read()).group(1)) / 1024
path, n = sys.argv[1], int(sys.argv[2])
loopworks.sweep(path, ["pid.k=uniform(1,3)"], samples=2, workers=1)
before = peak()
loopworks.sweep(path, ["pid.k=uniform(1,3)"], samples=n)
print(before, peak())
"""


def sweep_memory(path: Path, n: int) -> tuple[float, float]:
    """Peak resident memory (MB, Linux: VmHWM) of a fresh process that runs only the sweep of ``n``
    instances: before the instances (warmed on two) and through them. A process of its own,
    so this one's anchor (numba's thread pool) and other runs do not count."""
    out = subprocess.run([sys.executable, "-c", MEMORY_CHILD, str(path), str(n)],
                         capture_output=True, text=True, check=True).stdout.split()
    return float(out[0]), float(out[1])


def batch_alone(sc: object, kc: np.ndarray) -> dict[str, float]:
    """Instances/s of the compiled batch alone, every instance in one call, recording
    nothing, the rows made beforehand and no metrics: the ceiling of what the sweep's
    plumbing could reach with its kernels (``"batch"`` and ``"batch_fused"``)."""
    from loopworks.blocks.plan import BATCH_SIGNATURE, entry
    from loopworks.sim.batch import Batch

    template = sc.template("base")  # type: ignore[attr-defined]
    batch = Batch(template, [])
    batch.load([{"pid.k": float(k)} for k in kc])
    n = round(sc.duration / sc.dt)  # type: ignore[attr-defined]
    empty = np.empty((kc.size, 0, n))
    none = np.empty((kc.size, 0, n), dtype=np.uint8)
    index = np.zeros(0, dtype=np.int64)
    out = {}
    for what in ("batch", "batch_fused"):
        run = entry(template._slots, what, BATCH_SIGNATURE)
        F, S = batch.F.copy(), batch.S.copy()
        start = time.perf_counter()
        run(F, S, DT, 0, n, empty, index, none, index, 0)
        out[what] = kc.size / (time.perf_counter() - start)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--instances", type=int, default=10_000)
    ap.add_argument("--scans", type=int, default=1_000)
    ap.add_argument("--builtin-instances", type=int, default=20)
    ap.add_argument("--python-instances", type=int, default=200,
                    help="instances of the Python Module.run loop (it is the slow anchor)")
    args = ap.parse_args()
    n, scans = args.instances, args.scans
    kc = np.random.default_rng(0).uniform(1.0, 3.0, n)
    numba_batch(kc[:2], 10, DT)
    start = time.perf_counter()
    numba_batch(kc, scans, DT)
    anchor = n / (time.perf_counter() - start)

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "loop.toml"
        path.write_text(LOOP.format(duration=scans * DT), encoding="utf-8")
        loopworks.sweep(path, ["pid.k=uniform(1,3)"], samples=2, workers=1,
                        plan="compiled")  # warm the cache
        result = loopworks.sweep(path, ["pid.k=uniform(1,3)"], samples=n, plan="compiled")
        start = time.perf_counter()  # compiled once per machine (a load when cached)
        loopworks.sweep(path, ["pid.k=uniform(1,3)"], samples=2, workers=1, plan="fused")
        fuse_first = time.perf_counter() - start
        fused = loopworks.sweep(path, ["pid.k=uniform(1,3)"], samples=n, plan="fused")
        ours_fused = len(fused) / fused.seconds
        before, rss = sweep_memory(path, n)
        ours = len(result) / result.seconds  # the instances' run (workers included)
        sc = load_scenario(path)
        alone = batch_alone(sc, kc)
        m = args.python_instances
        start = time.perf_counter()
        for gain in kc[:m]:
            module = sc.build("base", {"pid.k": float(gain)})
            res = module.run(sc.duration, sc.dt)
            res.metrics("pid")
        python_loop = m / (time.perf_counter() - start)
    print(f"pid + fopdt, {n} instances x {scans} scans")
    print(f"  numba prange batch (anchor)      {anchor:12.0f} instances/s")
    print(f"  loopworks.sweep, plan='compiled' {ours:12.0f} instances/s  ratio {ours / anchor:.4f}"
          " (target >= 0.3, goal 0.5)")
    print(f"  loopworks.sweep, plan='fused'    {ours_fused:12.0f} instances/s  ratio "
          f"{ours_fused / anchor:.4f} (its first use took {fuse_first:.1f} s: compiled, or "
          "loaded from the cache)")
    print(f"  Python loop over Module.run      {python_loop:12.0f} instances/s  sweep / loop "
          f"{ours / python_loop:.2f}")
    for what, rate in alone.items():
        print(f"  {what + ' alone':32s} {rate:12.0f} instances/s  ratio {rate / anchor:.4f} "
              "(one call, no rows, record or metrics: the sweep's ceiling)")

    b = args.builtin_instances
    # warm: the same sweep (one point's relay test alone may not converge, which ends a
    # sweep of that one point)
    loopworks.sweep(None, ["valve.resolution=uniform(0.2,0.8)"], samples=b)
    built = loopworks.sweep(None, ["valve.resolution=uniform(0.2,0.8)"], samples=b)
    ours_b = len(built) / built.seconds  # without the points' [autotune] relay tests
    sc = load_scenario(None)
    from loopworks.sim.scenario import run_autotune

    run_autotune(sc)
    start = time.perf_counter()
    for variant in sc.variants:
        module = sc.build(variant, {"valve.resolution": 0.5})
        module.run(sc.duration, sc.dt).metrics(window=sc.metrics_window)
    loop_b = len(sc.variants) / (time.perf_counter() - start)
    print(f"built-in scenario (7 blocks, {sc.duration:g} s at {sc.dt:g} s), {b} points x "
          f"{len(sc.variants)} variants")
    print(f"  loopworks.sweep                  {ours_b:12.2f} runs/s")
    print(f"  Python loop over Module.run      {loop_b:12.2f} runs/s  sweep / loop "
          f"{ours_b / loop_b:.2f} (target >= 100)")
    print(f"peak memory of a process that runs only the pid + fopdt sweep: {rss:.0f} MB, of "
          f"which {before:.0f} MB before the {n} instances (imports, numba, the loaded plans); "
          f"target < 200 MB for {n} instances with metrics only")
    if not math.isfinite(ours):
        raise SystemExit(1)


if __name__ == "__main__":
    main()
