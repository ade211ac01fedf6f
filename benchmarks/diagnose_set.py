"""The stiction detector's test set (issue 15): generate it, show its composition and time.

    python benchmarks/diagnose_set.py [--n N] [--seed S] [--oracle | --diagnose]

Generates :func:`loopworks.analysis.synthetic.make_set` and prints the loops per group, loop
type, valve and controller, and how long generation took (the first run on a machine also
compiles each module layout's plan, cached afterwards). :func:`evaluate` scores a detector on
the set: give it ``diagnose(data, loop_type) -> {"verdict": "stiction" | "no_stiction",
"s": ..., "j": ...}`` (s and j optional). ``--oracle`` runs it with a detector that reads the
truth, to show the table's form; ``--diagnose`` scores ``loopworks.diagnose`` (without the
recommendation's simulations) on the records as a historian keeps them, without the valve
position, the first table of docs/diagnose.md; ``--position`` keeps the recorded stem
position (a digital positioner's travel feedback), the second.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time
from collections import Counter
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from loopworks.analysis.loopdata import LoopData
from loopworks.analysis.synthetic import SimulatedLoop, make_set

Diagnose = Callable[[LoopData, str], Mapping[str, Any]]
#: bands of S / (transmitter noise std) the sticky loops are also scored in
SIGNAL_TO_NOISE = ((0.0, 10.0), (10.0, 30.0), (30.0, 100.0), (100.0, math.inf))


def group_of(loop: SimulatedLoop) -> str:
    """The case group: the valve for sticky loops, else clean / aggressive / external."""
    if loop.label == "stiction":
        return loop.valve
    if "aggressive" in loop.case:
        return "aggressive"
    if "external" in loop.case:
        return "external"
    return "clean"


def composition(loops: list[SimulatedLoop]) -> str:
    """A text table of the set: counts per group, loop type, valve and controller."""
    lines = []
    for title, key in (("group", group_of), ("loop type", lambda x: x.loop_type),
                       ("valve", lambda x: x.valve), ("controller", lambda x: x.controller),
                       ("label", lambda x: x.label)):
        counts = Counter(key(x) for x in loops)
        lines.append(f"{title}:")
        lines += [f"  {name:<18} {n:4d}" for name, n in sorted(counts.items())]
    rows = Counter((group_of(x), x.loop_type, x.controller) for x in loops)
    lines.append("group x loop type x controller:")
    lines += [f"  {g:<11} {lt:<16} {c:<11} {n:3d}" for (g, lt, c), n in sorted(rows.items())]
    sticky = [x for x in loops if x.label == "stiction"]
    if sticky:
        s = np.array([x.s_nominal for x in sticky])
        j = np.array([x.j for x in sticky])
        lines.append(f"sticky: nominal S {s.min():.2f}..{s.max():.2f} %, "
                     f"J {j.min():.2f}..{j.max():.2f} %, J = 0 in {int((j == 0).sum())}")
    return "\n".join(lines)


def evaluate(loops: list[SimulatedLoop], diagnose: Diagnose) -> str:
    """Score ``diagnose`` on ``loops``: sensitivity (sticky loops called sticky), specificity
    (clean loops called clean) and balanced accuracy, and how many sticky loops were called
    no_stiction (a wrong answer, not an abstention), overall and per group and loop type;
    the median and 90th-percentile relative errors of S and J on the sticky loops the
    detector called sticky and gave an estimate for (J's only where the true J > 0), and the
    share of those S estimates within 30 % of the truth."""
    verdicts: list[tuple[SimulatedLoop, Mapping[str, Any]]] = [
        (x, diagnose(x.data, x.loop_type)) for x in loops]

    def rates(items: list[tuple[SimulatedLoop, Mapping[str, Any]]]) -> str:
        pos = [v["verdict"] == "stiction" for x, v in items if x.label == "stiction"]
        neg = [v["verdict"] != "stiction" for x, v in items if x.label != "stiction"]
        sens = float(np.mean(pos)) if pos else float("nan")
        spec = float(np.mean(neg)) if neg else float("nan")
        bal = float(np.nanmean([sens, spec])) if pos or neg else float("nan")
        # sticky loops called no_stiction: the wrong answers among the misses (the others
        # are undetermined)
        wrong = sum(v["verdict"] == "no_stiction" for x, v in items if x.label == "stiction")
        undetermined = sum(v["verdict"] == "undetermined" for x, v in items)
        text = (f"n {len(items):4d}  sens {sens:6.3f}  spec {spec:6.3f}  bal.acc {bal:6.3f}  "
                f"sticky->no {wrong:3d}  undet {undetermined:3d}")
        for name in ("s", "j"):
            errs = [abs(float(v[name]) - getattr(x, name)) / getattr(x, name)
                    for x, v in items if x.label == "stiction" and v["verdict"] == "stiction"
                    and v.get(name) is not None and getattr(x, name) > 0.0]
            if errs:
                text += (f"  {name.upper()} rel.err median {np.median(errs):.2f} "
                         f"p90 {np.percentile(errs, 90):.2f}")
                if name == "s":
                    text += (f" within 30 % {np.mean(np.array(errs) <= 0.3):.2f} "
                             f"(n {len(errs)})")
        return text

    lines = [f"{'all':<34} {rates(verdicts)}"]
    for key in sorted({(group_of(x), x.loop_type) for x in loops}):
        part = [(x, v) for x, v in verdicts if (group_of(x), x.loop_type) == key]
        lines.append(f"{key[0] + ', ' + key[1]:<34} {rates(part)}")
    # the sticky loops by how far the stick band stands above the transmitter noise
    for lo, hi in SIGNAL_TO_NOISE:
        part = [(x, v) for x, v in verdicts if x.label == "stiction"
                and lo <= x.s / max(x.noise, 1e-12) < hi]
        name = f"sticky, {lo:g} <= S/noise < {hi:g}" if math.isfinite(hi) else (
            f"sticky, S/noise >= {lo:g}")
        if part:
            lines.append(f"{name:<34} {rates(part)}")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=240)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--oracle", action="store_true",
                        help="evaluate a detector that reads the truth (shows the table)")
    parser.add_argument("--diagnose", action="store_true",
                        help="evaluate loopworks.diagnose on the set")
    parser.add_argument("--position", action="store_true",
                        help="give diagnose the recorded valve position too")
    args = parser.parse_args()
    t0 = time.perf_counter()
    loops = make_set(n=args.n, seed=args.seed)
    seconds = time.perf_counter() - t0
    print(composition(loops))
    samples = [len(x.data) for x in loops]
    print(f"{len(loops)} loops, {min(samples)}..{max(samples)} samples each, generated in "
          f"{seconds:.1f} s")
    if args.oracle:
        truth = {id(x.data): x for x in loops}

        def oracle(data: LoopData, loop_type: str) -> dict[str, Any]:
            x = truth[id(data)]
            return {"verdict": x.label, "s": x.s, "j": x.j}

        print(evaluate(loops, oracle))
    if args.diagnose:
        from loopworks.analysis.diagnosis import diagnose

        def detector(data: LoopData, loop_type: str) -> dict[str, Any]:
            if not args.position:  # a historian rarely has the stem position
                data = dataclasses.replace(data, position=None)
            d = diagnose(data, loop_type, recommend=False)
            st = d.stiction or {}
            return {"verdict": d.verdict, "s": st.get("s"), "j": st.get("j")}

        t0 = time.perf_counter()
        table = evaluate(loops, detector)
        print(table)
        print(f"diagnosed in {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
