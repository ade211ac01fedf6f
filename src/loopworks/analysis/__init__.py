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

from loopworks.errors import InputError

Verdict = Literal["stiction", "no_stiction", "undetermined"]
LoopType = Literal["self-regulating", "integrating"]
LOOP_TYPES: tuple[LoopType, ...] = ("self-regulating", "integrating")
#: the loop names an engineer (or a historian tag's service) gives, each its loop type
LOOP_NAMES: dict[str, LoopType] = {"flow": "self-regulating", "pressure": "self-regulating",
                                   "temperature": "self-regulating", "level": "integrating"}


def loop_type_of(name: str) -> LoopType:
    """The :data:`LoopType` a user's name stands for: a loop type, or a loop's service from
    :data:`LOOP_NAMES` (``level`` is integrating; ``flow``, ``pressure``, ``temperature``
    self-regulating), in any letter case. Anything else is an InputError naming the choices."""
    key = str(name).strip().lower()
    if key in LOOP_TYPES:
        return "integrating" if key == "integrating" else "self-regulating"
    if key in LOOP_NAMES:
        return LOOP_NAMES[key]
    raise InputError(f"loop type '{name}' is not allowed: expected "
                     + " or ".join(LOOP_TYPES) + " (or the loop's service: "
                     + ", ".join(LOOP_NAMES) + ")")
