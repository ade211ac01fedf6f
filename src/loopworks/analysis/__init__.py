"""Analysis of one loop's data, plant or simulated time series (SP, PV, OP): their quality,
oscillation and valve-stiction indices, the valve's S and J, and what to do (issue 15). The
data need no module; the valve fit runs loopworks' own ``valve.choudhury`` block over the
recorded OP, and the recommendation simulates the fitted loop as a scenario.

The words every method answers in: a :data:`Verdict` ("stiction", "no_stiction" or
"undetermined": the data cannot say) for a loop of a :data:`LoopType` ("self-regulating": a
flow, pressure or temperature loop whose PV settles for a constant OP; "integrating": a level
loop, whose PV ramps for any OP off balance)."""

from __future__ import annotations

from typing import Literal

Verdict = Literal["stiction", "no_stiction", "undetermined"]
LoopType = Literal["self-regulating", "integrating"]
LOOP_TYPES: tuple[LoopType, ...] = ("self-regulating", "integrating")
