"""Helpers for the issue 11 point 1 tests of the plant kinds: run a block's own kernel,
interpreted and without the numeric guard of ``loopworks.blocks.kernel.guarded_scan``, and
check that the scan was sound by itself (the guard is a floor; the kernels must not need it)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from loopworks.blocks import layout
from loopworks.blocks.block import Block

#: the values issue 11 point 1 names, and the float32 edge
EXTREMES = (math.nan, math.inf, -math.inf, 1e308, -1e308, 3.5e38, -3.5e38)


def kernel_scan(block: Block, dt: float, **inputs: Any) -> None:
    """Latch ``inputs`` as ``step()`` does and run one scan of the bare kernel on the block's
    own arrays (no guard, no compiled code)."""
    block.set_inputs(inputs)
    with np.errstate(all="ignore"):
        type(block).kernel(dt, block.p, block.x, block.u, block.us, block.y, block.ys)


def unsound(block: Block) -> list[str]:
    """What breaks the numeric contract now: a non-finite state, or a non-finite output whose
    status is not Bad (or that carries no status)."""
    names = layout.names(block.STATES, block.params)  # an Array's elements as name[i]
    found = [f"state {n} = {v}" for n, v in zip(names, block.x, strict=True)
             if not math.isfinite(v)]
    for i, port in enumerate(block.OUTPUTS):
        value, status = float(block.y[i]), int(block.ys[i])
        if not math.isfinite(value) and (not port.status or status & 0xC0 != 0):
            found.append(f"output {port.name} = {value} with status {status}")
    return found
