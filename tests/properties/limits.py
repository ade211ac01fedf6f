"""The documented limits of each kind's limited outputs, read from its parameters."""

from __future__ import annotations

import math
from collections.abc import Callable

from loopworks.blocks.block import Block


def _params(lo: str, hi: str) -> Callable[[Block], tuple[float, float]]:
    return lambda b: (float(b.params[lo]), float(b.params[hi]))


def _valve(b: Block) -> tuple[float, float]:
    return (0.0, 100.0)


def _s5(b: Block) -> tuple[float, float]:
    """s5.pid y: BGUG..BGOG bound Y (positioning) and dY (velocity), spec 2.8/2.9; REG_AUS
    writes 0 into DW 48 (spec 2.10) and velocity HANDART gives dY = 0 (spec 2.9) whatever they
    say, so 0 is always possible."""
    return (min(float(b.params["bgug"]), 0.0), max(float(b.params["bgog"]), 0.0))


def _ge(after_polarity: bool) -> Callable[[Block], tuple[float, float]]:
    """ge.pid_*: word 19 within the clamps, CV too (negated by bit 1, spec 1.7 steps 11-12);
    with clamps the PLC refuses (ok_off) there are none."""
    from loopworks.vendors import ge_pacsystems as ge

    def limits(b: Block) -> tuple[float, float]:
        lo, hi = float(b.p[ge.P.lower]), float(b.p[ge.P.upper])
        if b.p[ge.P.param_err] != 0.0:
            return (-math.inf, math.inf)
        return (-hi, -lo) if after_polarity and b.p[ge.P.invert] != 0.0 else (lo, hi)
    return limits


#: kind -> {output: limits from the block}
LIMITS: dict[str, dict[str, Callable[[Block], tuple[float, float]]]] = {
    "pid": {"out": _params("out_lo", "out_hi")},
    # deltav.pid OUT is limited in Auto/Cas/LO only (IMan follows BKCAL_IN, OOS and "No OUT
    # limits in Manual" are unlimited, spec 4.5): pinned in tests/vendors/deltav/test_pid.py
    "deltav.pid": {"mode_actual": lambda b: (0.0, 5.0), "mode_target": lambda b: (0.0, 5.0)},
    "relay": {"out": _params("out_lo", "out_hi")},
    "e2.pid": {"pid_out": _params("output_min", "output_max"), "out": _valve},  # 0..100 %
    "s5.pid": {"y": _s5},
    "ge.pid_ind": {"cv": _ge(True), "output": _ge(False)},
    "ge.pid_isa": {"cv": _ge(True), "output": _ge(False)},
    "compensator.two_move": {"phase": lambda b: (0.0, 2.0)},  # pass, move 1, hold
    # no limited outputs: the seed's SIGNAL_OUT has no clamp (spec 6.3 line 26), a CALC output
    # is what its text assigns, the SGGN output follows its amplitude input (spec 6.5)
    "deltav.stick_slip": {},
    "deltav.calc": {},
    "deltav.sggn": {},
    "valve.choudhury": {"position": _valve, "flow": _valve},
    "valve.kano": {"position": _valve, "flow": _valve},
    "valve.he": {"position": _valve, "flow": _valve},
    "valve.backlash": {"position": _valve, "flow": _valve},
    "valve.resolution": {"position": _valve, "flow": _valve},
    "valve.quantiser": {"position": _valve, "flow": _valve},
    "valve.karnopp": {"position": _valve, "flow": _valve},
    "sensor.transmitter": {"pv": _params("pv_lo", "pv_hi")},
}


def output_limits(block: Block) -> dict[str, tuple[float, float]]:
    """{output name: (lo, hi)} for the outputs of ``block`` that have limits."""
    found = {}
    for name, limits in LIMITS.get(block.kind, {}).items():
        lo, hi = limits(block)
        if math.isfinite(lo) or math.isfinite(hi):
            found[name] = (min(lo, hi), max(lo, hi))
    return found
