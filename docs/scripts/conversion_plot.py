"""Make docs/img/conversion.png and print the deviation table of docs/conversion.md.

One loop (process.fopdt K = 1, T = 30 s, L = 3 s, dt = 1 s, u0 = 50 %) under a generic pid
(Kc 2, Ti 16 s, Td 2 s, no derivative filter, D on the error) and under each controller the
pid converts to with ``loopworks.tuning.convert``; setpoint step 50 -> 55 % at t = 10 s.
Run: python docs/scripts/conversion_plot.py  (a few seconds).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from loopworks import create_block
from loopworks.tuning.convert import convert

DT, N, STEP_AT, SP0, SP1 = 1.0, 240, 10, 50.0, 55.0
SOURCE = {"k": 2.0, "ti": 16.0, "td": 2.0, "tf": 0.0, "c": 1.0}
TARGETS: dict[str, dict[str, Any]] = {
    "ge.pid_ind": {"arithmetic": "float"}, "ge.pid_isa": {"arithmetic": "float"},
    "e2.pid": {}, "s5.pid": {}, "deltav.pid": {}}


def simulate(kind: str, params: dict[str, Any]) -> np.ndarray:
    """PV (%) of the loop; each controller sees PV in its own port units."""
    prm = {k: v for k, v in params.items() if not k.startswith("word")}
    proc = create_block("process.fopdt", jit=False, gain=1.0, time_constant=30.0,
                        dead_time=3.0, u0=50.0)
    extra: dict[str, Any] = {
        "pid": {"bias": 50.0}, "ge.pid_ind": {"bias": 16000.0, "arithmetic": "float"},
        "ge.pid_isa": {"bias": 16000.0, "arithmetic": "float"},
        "s5.pid": {"arithmetic": "float", "y0": 500, "bgog": 1000, "bgug": 0},
        "e2.pid": {"output_at_setpoint": 50.0},
        "deltav.pid": {"precision": "float64", "initial_out": 50.0}}[kind]
    ctl = create_block(kind, jit=False, **{**prm, **extra})
    y, pv = 50.0, np.empty(N)
    for k in range(N):
        sp = SP1 if k >= STEP_AT else SP0
        pv[k] = y
        if kind.startswith("ge."):
            u = ctl.step(DT, sp=sp * 320, pv=y * 320, clock=(k + 1) * DT)["cv"].value / 320
        elif kind == "s5.pid":
            u = ctl.step(DT, w=sp * 10, x=y * 10)["y"].value / 10
        elif kind == "deltav.pid":
            u = ctl.step(DT, sp=sp, pv=y, mode="AUTO")["out"].value
        else:
            u = ctl.step(DT, sp=sp, pv=y)["out"].value
        y = proc.step(DT, u=u)["y"].value
    return pv


def main() -> None:
    t = np.arange(N) * DT
    ref = simulate("pid", SOURCE)
    fig, ax = plt.subplots(figsize=(8, 4.5))
    ax.plot(t, ref, "k", lw=3, alpha=0.35, label="pid (source)")
    print("| target | exact | max abs PV deviation from the source loop (%) |")
    print("|---|---|---|")
    for kind, ctx in TARGETS.items():
        conv = convert("pid", SOURCE, kind, sample_time=DT, target=ctx)
        pv = simulate(kind, conv.params)
        dev = float(np.max(np.abs(pv - ref)))
        print(f"| {kind} | {conv.exact} | {dev:.3g} |")
        ax.plot(t, pv, lw=1.2, ls="-" if conv.exact else "--",
                label=f"{kind} ({'exact' if conv.exact else 'inexact'})")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("PV (%)")
    ax.set_title("Setpoint step 50 → 55 %, FOPDT K=1, T=30 s, L=3 s, Δ = 1 s")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    out = Path(__file__).resolve().parents[1] / "img" / "conversion.png"
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(out, dpi=100)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
