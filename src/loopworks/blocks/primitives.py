"""Shared numeric primitives that kernels call: each equation written once.

All are :func:`~loopworks.blocks.kernel.primitive` functions of plain floats, so they run
interpreted and compile with numba inside a kernel.
"""

from __future__ import annotations

import math

from loopworks.blocks.kernel import primitive


@primitive
def finite(x: float) -> bool:
    """True unless x is NaN or infinite."""
    return not (math.isnan(x) or math.isinf(x))


@primitive
def sign(v: float) -> float:
    """+1, -1 or 0: sign(0) = 0 and sign(NaN) = 0 (used by the valve models, spec
    plant-and-tuning 1.2 step 2, and the compensators, 2.4-2.6)."""
    if v > 0.0:
        return 1.0
    if v < 0.0:
        return -1.0
    return 0.0


@primitive
def clamp(x: float, lo: float, hi: float) -> float:
    """min(max(x, lo), hi)."""
    if x > hi:
        return hi
    if x < lo:
        return lo
    return x


@primitive
def lag_step(y: float, target: float, dt: float, time_constant: float) -> float:
    """Exact (zero-order-hold) step of a first-order lag T·dy/dt = target - y over ``dt``:

        y_k = y_{k-1} + (1 - exp(-dt/T))·(target - y_{k-1})

    (Åström & Wittenmark, Computer-Controlled Systems, ch. 2: ZOH sampling of 1/(Ts+1)),
    computed as target + exp(-dt/T)·(y_{k-1} - target): the same value, and exactly the
    target once exp(-dt/T) is 0 (dt far above T; the other order left a rounding residue,
    -15.999999999999998 for -16, that an integer truncation turned into -15). T = 0 passes
    the target through.
    """
    if time_constant <= 0.0:
        return target
    return target + math.exp(-dt / time_constant) * (y - target)
