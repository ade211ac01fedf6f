"""A block kind's reference, generated from its declarations: for ``loopworks blocks KIND``
and for the pages in ``docs/blocks/`` (``loopworks blocks KIND --markdown``)."""

from __future__ import annotations

import inspect
import math
from typing import Any

from loopworks.blocks.block import Block


def show(value: Any) -> str:
    """A default value as a user would write it."""
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return f"{value:g}"
    return "" if value is None else str(value)


def parameter_rows(cls: type[Block]) -> list[tuple[str, str, str, str, str]]:
    """(name, unit, default, range, meaning) for every parameter."""
    return [(p.name, p.unit, p.default_text or show(p.default), p.range_text(), p.meaning)
            for p in cls.PARAMS]


def input_rows(cls: type[Block]) -> list[tuple[str, str, str, str]]:
    """(name, unit, default, meaning) for every input; enumerated defaults by name."""
    rows = []
    for port in cls.INPUTS:
        default = port.choices[int(port.default)] if port.choices else show(port.default)
        meaning = port.meaning + (" (has .ST status)" if port.status else "")
        rows.append((port.name, port.unit, default, meaning))
    return rows


def output_rows(cls: type[Block]) -> list[tuple[str, str, str, str]]:
    """(name, unit, status, meaning) for every output."""
    return [(p.name, p.unit, "yes" if p.status else "", p.meaning) for p in cls.OUTPUTS]


def _table(header: tuple[str, ...], rows: list[tuple[str, ...]]) -> str:
    def cell(text: str) -> str:
        return text.replace("|", "\\|")

    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(cell(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


NUMERIC_CONTRACT = """\
An input value that is NaN or infinite is Bad input, whatever status it arrives with: the block
sees it as Bad and does what is written above for Bad input. If a scan's arithmetic overflows
(a state, or an output whose status is not Bad, would become NaN or infinite), the scan is
undone and run again as if every input were Bad; a kind with no rule for Bad input then holds
its state and outputs, with the outputs' status Bad. So no output is NaN or infinite unless its
status is Bad, and the block recovers as soon as its inputs are good again."""


def markdown(cls: type[Block]) -> str:
    """The reference page of a block kind, in Markdown."""
    module_doc = inspect.getdoc(inspect.getmodule(cls)) or ""
    parts = [
        f"# `{cls.kind}`: {cls.describe()}",
        "",
        f"Generated from the code by `loopworks blocks {cls.kind} --markdown`; do not edit.",
        "",
        "## Parameters",
        "",
        _table(("name", "unit", "default", "range", "meaning"), list(parameter_rows(cls))),
        "",
        "## Inputs",
        "",
        _table(("name", "unit", "default", "meaning"), list(input_rows(cls))),
        "",
        "## Outputs",
        "",
        _table(("name", "unit", "status", "meaning"), list(output_rows(cls))),
        "",
        "## Behaviour",
        "",
        module_doc,
        "",
        "## Non-finite values (every kind)",
        "",
        NUMERIC_CONTRACT,
        "",
    ]
    return "\n".join(parts)
