"""One PID step called from Python: loopworks ``pid`` against simple-pid, in one process.

    python benchmarks/bench_pid_step.py [--calls N] [--repeats R]

Both controllers are PI with the same tuning and no output limits in play; each call feeds a new
measurement and the scan time explicitly (simple-pid with ``dt=``, so no clock is read). The
two are timed interleaved, R rounds of N calls each, and the median per-call time of each is
compared. Absolute times on a shared machine are noise; the ratio is the figure.
"""

from __future__ import annotations

import argparse
import statistics
import timeit

from simple_pid import PID as SimplePID

import loopworks


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--calls", type=int, default=200_000)
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args()

    kp, ti, dt = 2.0, 10.0, 0.1
    ours = loopworks.create_block("pid", k=kp, ti=ti, out_lo=-1e9, out_hi=1e9)
    theirs = SimplePID(kp, kp / ti, 0.0, setpoint=50.0, sample_time=None)

    # Same answers first: simple-pid integrates ki·e·dt before computing the output, as we do.
    for pv in (40.0, 41.0, 42.5):
        a = ours.step(dt, sp=50.0, pv=pv)["out"].value
        b = theirs(pv, dt=dt)
        assert abs(a - b) < 1e-9, (a, b)

    def loopworks_step() -> None:
        ours.step(dt, sp=50.0, pv=42.0)

    def loopworks_step_pv() -> None:
        ours.step(dt, pv=42.0)

    def simple_pid_update() -> None:
        theirs(42.0, dt=dt)

    t_ours: list[float] = []
    t_pv: list[float] = []
    t_theirs: list[float] = []
    for _ in range(args.repeats):
        t_ours.append(timeit.timeit(loopworks_step, number=args.calls) / args.calls)
        t_pv.append(timeit.timeit(loopworks_step_pv, number=args.calls) / args.calls)
        t_theirs.append(timeit.timeit(simple_pid_update, number=args.calls) / args.calls)
    a, c, b = (statistics.median(x) for x in (t_ours, t_pv, t_theirs))
    r = args.repeats
    print(f"simple-pid   PID(pv, dt=)                 {b * 1e6:7.3f} us/call (median of {r})")
    print(f"loopworks    pid.step(dt, sp=, pv=)       {a * 1e6:7.3f} us/call  ratio {a / b:5.2f}")
    print(f"loopworks    pid.step(dt, pv=), sp latched {c * 1e6:6.3f} us/call  ratio {c / b:5.2f}")
    print("(ratio = loopworks / simple-pid; <= 1 means no slower. simple-pid's call feeds only the"
          "\n measurement, its setpoint is an attribute: the sp-latched call is the like-for-like"
          " one)")


if __name__ == "__main__":
    main()
