"""Process models (blocks with input ``u`` and output ``y``).

``process.first_order``: a first-order lag, the plant of the built-in closed loop::

    T·dy/dt = K·u - y      →   y_k = y_{k-1} + (1 - e^(-dt/T))·(K·u_k - y_{k-1})

(exact for an input held over the scan; Åström & Wittenmark, *Computer-Controlled Systems*,
ch. 2). The output is the state after the scan, so a controller that runs after the process
in the same scan sees this scan's value. A non-finite input freezes the state and marks ``y``
Bad (no input, no trustworthy output).
"""

from __future__ import annotations

import math
from typing import ClassVar

from loopworks.blocks.block import Block
from loopworks.blocks.kernel import FloatArray, IntArray
from loopworks.blocks.params import Param, Port
from loopworks.blocks.primitives import lag_step
from loopworks.blocks.registry import register
from loopworks.blocks.status import BAD, BAD_NON_SPECIFIC, GOOD_NC

GAIN, TAU, Y0 = range(3)


def first_order_kernel(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                       y: FloatArray, ys: IntArray) -> None:
    """One scan of T·dy/dt = K·u - y (module docstring)."""
    if math.isnan(u[0]) or math.isinf(u[0]) or (us[0] & 0xC0) == BAD:
        ys[0] = BAD_NON_SPECIFIC
    else:
        x[0] = lag_step(x[0], p[GAIN] * u[0], dt, p[TAU])
        ys[0] = GOOD_NC
    y[0] = x[0]


@register
class FirstOrder(Block):
    """First-order lag process: T·dy/dt = K·u - y."""

    kind = "process.first_order"
    kernel = staticmethod(first_order_kernel)
    PARAMS: ClassVar[tuple[Param, ...]] = (
        Param("gain", 1.0, "y/u", "steady-state gain K", lo=-math.inf),
        Param("time_constant", 10.0, "s", "time constant T; 0 = no lag", lo=0.0,
              lo_open=False),
        Param("y0", 0.0, "y", "initial output"),
    )
    INPUTS: ClassVar[tuple[Port, ...]] = (Port("u", 0.0, "u", "process input", status=True),)
    OUTPUTS: ClassVar[tuple[Port, ...]] = (Port("y", 0.0, "y", "process output", status=True),)
    STATES: ClassVar[tuple[str, ...]] = ("y",)

    def coefficients(self) -> list[float]:
        return [float(self.params["gain"]), float(self.params["time_constant"]),
                float(self.params["y0"])]

    def initial_state(self) -> list[float]:
        return [self.p[Y0]]

    def reset(self) -> None:
        super().reset()
        self.y[0] = self.p[Y0]
