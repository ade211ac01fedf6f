"""A big historian replay: ``loopworks replay pid`` against a plain-Python csv copy, in one
process (issue 12, figure 4).

    python benchmarks/bench_replay.py [--rows N] [--repeats R]

Writes an N-row input CSV (``t, sp, pv``: a 0.1 s scan, a setpoint near 50 and a noisy
measurement, six decimals) to a temporary folder, then times, best of R each:

* the baseline: ``csv.reader`` over the file and ``csv.writer`` writing every row to another
  file, the least any Python tool that reads and writes the rows must do;
* ``loopworks.sim.replay.replay`` (the function the CLI calls) writing its output CSV, after
  one warm-up replay of a small file so that compiling is not counted.

The ratio replay / baseline is the figure (target: at most 0.5): both run in this process, so
the machine's speed cancels out. A shared or busy machine still moves it: the replay overlaps
reading, the kernel and writing in worker threads, so it gains when a second core is free; the
replay is also timed with the stages one after the other (``replay.OVERLAP = False``). Last,
the CLI ``loopworks replay pid`` runs on the same file in a fresh subprocess, start-up
included.
"""

from __future__ import annotations

import argparse
import csv
import random
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import loopworks
from loopworks.sim import replay as replay_module
from loopworks.sim.replay import replay


def write_input(path: Path, rows: int, seed: int = 1) -> None:
    """The input CSV: t (s), sp and pv, as a historian export would give them."""
    rng = random.Random(seed)
    with open(path, "w", encoding="utf-8", newline="") as fh:
        fh.write("t,sp,pv\n")
        fh.writelines(f"{k * 0.1:.1f},{50 + rng.random():.6f},{40 + 20 * rng.random():.6f}\n"
                      for k in range(rows))


def csv_copy(src: Path, dst: Path) -> None:
    """The baseline: every row read by csv.reader and written by csv.writer (``writerows``,
    the faster of the two ways to write them: the stricter baseline)."""
    with open(src, newline="", encoding="utf-8") as fin, \
            open(dst, "w", newline="", encoding="utf-8") as fout:
        csv.writer(fout).writerows(csv.reader(fin))


def run_replay(src: Path, dst: Path) -> None:
    """The replay, as the CLI runs it: a pid with k = 2, ti = 10 s, CSV in, CSV out."""
    replay(loopworks.create_block("pid", k=2.0, ti=10.0), src, dst)


def best(fn: Callable[[], None], repeats: int) -> float:
    """The shortest of ``repeats`` timed calls (s)."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=1_000_000)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        src, small = folder / "in.csv", folder / "small.csv"
        write_input(src, args.rows)
        write_input(small, 20_000)  # past the bulk reader's threshold: the same code path
        run_replay(small, folder / "warm.csv")  # warm-up: imports and compiled code
        base = best(lambda: csv_copy(src, folder / "copy.csv"), args.repeats)
        ours = best(lambda: run_replay(src, folder / "out.csv"), args.repeats)
        replay_module.OVERLAP = False
        alone = best(lambda: run_replay(src, folder / "out.csv"), args.repeats)
        replay_module.OVERLAP = True
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "loopworks", "replay", "pid", str(src),
                        "-p", "k=2", "-p", "ti=10", "-o", str(folder / "cli.csv")],
                       check=True, capture_output=True)
        cli = time.perf_counter() - t0
        size = src.stat().st_size / 1e6
    print(f"input: {args.rows} rows, {size:.1f} MB; best of {args.repeats}")
    print(f"plain csv read + write         {base:7.3f} s")
    print(f"loopworks.sim.replay (pid)     {ours:7.3f} s   ratio {ours / base:5.2f} "
          "(target <= 0.5)")
    print(f"  the same, stages not overlapped {alone:6.3f} s   ratio {alone / base:5.2f} "
          "(one core's worth)")
    print(f"CLI loopworks replay pid -o    {cli:7.3f} s   (fresh subprocess, start-up and "
          "cached compiled code included)")


if __name__ == "__main__":
    main()
