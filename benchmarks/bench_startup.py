"""Start-up figures of issue 12, each command in a fresh process (warm cache: every command
is run once first so its compiled code is in the plan cache).

    python benchmarks/bench_startup.py [--repeats R]

1. warm ``loopworks simulate`` (built-in scenario) / the same with ``LOOPWORKS_JIT=0``;
2. a 3-row ``loopworks replay s5.pid`` / ``python -c "import numpy, numba"``.

Median wall time of R runs each; the ratios are the figures.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

BIN = Path(sys.executable).parent


def wall(cmd: list[str], env: dict[str, str], cwd: str) -> float:
    start = time.perf_counter()
    subprocess.run(cmd, env={**os.environ, **env}, cwd=cwd, check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


def median(cmd: list[str], env: dict[str, str], cwd: str, repeats: int) -> float:
    wall(cmd, env, cwd)  # warm the cache (and the OS file cache)
    return statistics.median(wall(cmd, env, cwd) for _ in range(repeats))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    r = args.repeats
    with tempfile.TemporaryDirectory() as tmp:
        csv = Path(tmp) / "s5.csv"
        csv.write_text("t,w,x\n0,50,40\n1,50,41\n2,50,42\n", encoding="utf-8")
        loopworks = str(BIN / "loopworks")
        sim = [loopworks, "simulate", "-q", "-o", str(Path(tmp) / "report")]
        warm = median(sim, {}, tmp, r)
        interp = median(sim, {"LOOPWORKS_JIT": "0"}, tmp, r)
        replay = median([loopworks, "replay", "s5.pid", str(csv), "-o",
                         str(Path(tmp) / "out.csv")], {}, tmp, r)
        imports = median([sys.executable, "-c", "import numpy, numba"], {}, tmp, r)
    print(f"warm loopworks simulate            {warm:7.2f} s (median of {r})")
    print(f"loopworks simulate, LOOPWORKS_JIT=0 {interp:6.2f} s  ratio {warm / interp:5.2f} "
          "(target <= 0.5)")
    print(f"3-row loopworks replay s5.pid      {replay:7.2f} s")
    print(f"python -c 'import numpy, numba'    {imports:7.2f} s  ratio {replay / imports:5.2f} "
          "(target <= 2.5)")


if __name__ == "__main__":
    main()
