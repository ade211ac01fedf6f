"""A block kind's reference, generated from its declarations: for ``loopworks blocks KIND``,
for the pages in ``docs/blocks/`` (``loopworks blocks KIND --markdown``) and, as data, for
``loopworks blocks KIND --json`` (:func:`declaration`, documented in ``docs/blocks-json.md``).

The pages cite the project's specifications ("spec 4.4", "plant-and-tuning 2.3", "R42",
"seed 000", "[A]"), which are not shipped; :func:`citations` finds every such citation on a
page and :func:`sources_section` explains each one from :mod:`loopworks.blocks.sources`.
"""

from __future__ import annotations

import inspect
import math
import re
import textwrap
from dataclasses import dataclass, field
from typing import Any

from loopworks.blocks import sources
from loopworks.blocks.block import Block
from loopworks.blocks.controller import Controller
from loopworks.blocks.params import Param, Port


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


def json_value(value: Any) -> Any:
    """A value for JSON: numbers, text, true/false and null as they are; a non-finite float
    as the text a scenario file or a CSV writes (``"nan"``, ``"inf"``, ``"-inf"``)."""
    if isinstance(value, float) and not math.isfinite(value):
        return show(value)
    return value


def _parameter(p: Param) -> dict[str, Any]:
    numeric = p.type in ("float", "int")
    bounds = {"lo": json_value(p.lo), "lo_open": p.lo_open,
              "hi": json_value(p.hi), "hi_open": p.hi_open} if numeric else None
    return {"name": p.name, "unit": p.unit, "type": p.type, "default": json_value(p.default),
            "default_text": p.default_text, "range": bounds, "range_text": p.range_text(),
            "choices": list(p.choices), "meaning": p.meaning}


def _port(p: Port) -> dict[str, Any]:
    return {"name": p.name, "unit": p.unit, "default": json_value(p.default),
            "status": p.status,
            "choices": [{"code": code, "name": name} for code, name in enumerate(p.choices)],
            "meaning": p.meaning}


def _controller(cls: type[Controller], defaults: dict[str, Any]) -> dict[str, Any]:
    action = cls.ACTION
    return {
        "roles": cls.ROLES.as_dict(),
        "automatic": {k: json_value(v) for k, v in cls.AUTOMATIC.items()},
        "manual": {k: json_value(v) for k, v in cls.MANUAL.items()},
        "action": {"parameter": action.parameter, "op": action.op,
                   "value": json_value(action.value), "rule": action.rule(),
                   "default": "direct" if cls.direct_acting(defaults) else "reverse"},
        "handover": {"inputs": [{"input": name, "from": source}
                                for name, source in cls.HANDOVER.inputs],
                     "params": {k: json_value(v) for k, v in cls.HANDOVER.params.items()}},
    }


def declaration(cls: type[Block]) -> dict[str, Any]:
    """Everything ``cls`` declares, as JSON-ready data (``loopworks blocks KIND --json``; every
    key is described in ``docs/blocks-json.md``): kind, summary, parameters, inputs, outputs,
    and for a controller (:class:`~loopworks.blocks.controller.Controller`) its roles,
    automatic and manual input values, action and handover, else ``controller`` is null."""
    defaults = {p.name: p.default for p in cls.PARAMS}
    return {
        "kind": cls.kind,
        "summary": cls.describe(),
        "parameters": [_parameter(p) for p in cls.PARAMS],
        "inputs": [_port(p) for p in cls.INPUTS],
        "outputs": [_port(p) for p in cls.OUTPUTS],
        "controller": _controller(cls, defaults) if issubclass(cls, Controller) else None,
    }


def layout_rows(entries: tuple[Any, ...]) -> list[tuple[str, ...]]:
    """(index, name, size) for every entry of a layout (COEFFS or STATES); a per-instance
    size is described by the Array's meaning."""
    from loopworks.blocks.layout import Array, offsets

    rows: list[tuple[str, ...]] = []
    for at, entry in zip(offsets(entries), entries, strict=True):
        if isinstance(entry, Array):
            size = str(entry.size) if isinstance(entry.size, int) else entry.meaning
            rows.append((str(at), entry.name, size))
        else:
            rows.append((str(at), entry, "1"))
    return rows


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


# Citations -------------------------------------------------------------------------------
#
# A section citation starts with "spec", "spec's", "vendor-blocks" or "plant-and-tuning"
# (optionally "spec vendor-blocks", and "section(s)"), then a chain of section numbers:
# "spec 1.2/1.7 step 10", "spec 2.4-2.7", "spec 1.2 table, 1.8", "Spec 4.2 vs 4.7 step 7".
# Words such as "step 10", "item 5", "lines 26, 28", "table", "[A]" qualify a number and are
# skipped; the chain ends at anything else ("spec 1.8, S = 3" is section 1.8 only).

SECTION_HEADING = "## Sources"

_DOCS = "|".join(re.escape(doc) for doc in sources.DOCUMENTS)
_LEAD = re.compile(
    rf"\b(?:(?i:spec)(?:'s)?(?:\s+(?P<named>{_DOCS}))?|(?P<doc>{_DOCS}))(?:\.md)?(?:``)?"
    r"(?:\s+(?:sections?|§))?\s+(?=\d)")
_NUM = re.compile(r"(\d+)(?:\.(\d+))?(?![\d])(?!\.\d)")
_RANGE = re.compile(r"\s*[-–]\s*")
_QUALIFIER = re.compile(
    r"\s+(?:(?:steps?|items?|lines?|words?|rows?|points?)\s+\d+"
    r"(?:\s*(?:-|–|,|/|and)\s*\d+)*(?![.\d])"
    r"|implementation\s+note|table|note|examples?|mapping|test|text|equations?|statement"
    r"|literally|\[[^\[\]]*\]|[A-Z][A-Z0-9_]*\d+(?:/[A-Z][A-Z0-9_]*\d+)*)")
_SEPARATOR = re.compile(r"\s*,\s*and\s+|\s*,\s*|\s*/\s*|\s+and\s+|\s+vs\.?\s+|\s+or\s+")
_REFERENCE = re.compile(r"\bR(\d{1,2})\b(?:\s*[-–]\s*R(\d{1,2})\b)?")
_SEED = re.compile(r"\bseed\s+(\d{3})\b")
_BRACKET = re.compile(r"\[([^\[\]]+)\]")
_TAG = re.compile(r"(V|D|A|\?|S|L|I)(?=$|[\s:])")


@dataclass
class Citations:
    """What a page cites: sections as (document, number), references, seeds and tags."""

    sections: set[tuple[str, str]] = field(default_factory=set)
    references: set[str] = field(default_factory=set)
    seeds: set[str] = field(default_factory=set)
    tags: set[str] = field(default_factory=set)


def _section_chain(text: str, pos: int) -> tuple[list[str], int]:
    """The section numbers of the chain that starts at ``pos``, and where it ends."""
    numbers: list[str] = []
    while True:
        m = _NUM.match(text, pos)
        if not m:
            break
        major, minor = m.group(1), m.group(2)
        pos = m.end()
        r = _RANGE.match(text, pos)
        m2 = _NUM.match(text, r.end()) if r else None
        if r and m2 and m2.group(1) == major and minor and m2.group(2):
            numbers += [f"{major}.{i}" for i in range(int(minor), int(m2.group(2)) + 1)]
            pos = m2.end()
        else:
            numbers.append(major if minor is None else f"{major}.{minor}")
        while q := _QUALIFIER.match(text, pos):
            pos = q.end()
        sep = _SEPARATOR.match(text, pos)
        if not sep or not _NUM.match(text, sep.end()):
            break
        pos = sep.end()
    return numbers, pos


def citations(text: str, document: str) -> Citations:
    """Every citation in ``text``; a bare "spec X.Y" is a section of ``document``."""
    found = Citations()
    for m in _LEAD.finditer(text):
        doc = m.group("named") or m.group("doc") or document
        numbers, _ = _section_chain(text, m.end())
        found.sections.update((doc, n) for n in numbers)
    for m in _REFERENCE.finditer(text):
        first = int(m.group(1))
        last = int(m.group(2)) if m.group(2) else first
        found.references.update(f"R{i}" for i in range(first, last + 1))
    found.seeds.update(_SEED.findall(text))
    for m in _BRACKET.finditer(text):
        for part in (p.strip() for p in m.group(1).split(",")):
            if part in sources.PROJECT_TAGS:
                found.tags.add(part)
            elif t := _TAG.match(part):
                found.tags.add(t.group(1))
    return found


def _order(number: str) -> tuple[int, ...]:
    return tuple(int(x) for x in number.split("."))


def unresolved(found: Citations, document: str) -> list[str]:
    """The citations that :mod:`loopworks.blocks.sources` does not explain (should be none)."""
    missing = [f"spec {n} ({doc})" for doc, n in sorted(found.sections)
               if n not in sources.SECTIONS.get(doc, {})]
    missing += [r for r in sorted(found.references) if r not in sources.REFERENCES]
    missing += [f"seed {s}" for s in sorted(found.seeds) if s not in sources.SEEDS]
    missing += [f"[{t}]" for t in sorted(found.tags)
                if t not in sources.TAGS[document] and t not in sources.PROJECT_TAGS]
    return missing


def sources_section(found: Citations, document: str) -> str:
    """The "Sources" section of a page: every citation in ``found`` in plain words."""
    unknown = "(not in loopworks.blocks.sources)"
    intro = ("The citations on this page point into the two specifications loopworks is "
             "implemented from. They are internal documents, not shipped with loopworks, so "
             'each citation is explained here: "spec X.Y" is section X.Y of a specification '
             f"(of {document} unless another is named), an R number is an entry of the "
             "reference list of vendor-blocks, a seed is a vendor excerpt the specifications "
             "were written from, and a tag in brackets says how sure a statement is.")
    lines = [SECTION_HEADING, "", textwrap.fill(intro, 96)]
    docs = sorted({doc for doc, _ in found.sections} | {document},
                  key=list(sources.DOCUMENTS).index)
    lines += ["", "Specifications:", ""]
    lines += [f"* {doc}: {sources.DOCUMENTS[doc]}" for doc in docs]
    if found.sections:
        lines += ["", "Sections cited:", ""]
        for doc, number in sorted(found.sections,
                                  key=lambda c: (docs.index(c[0]), _order(c[1]))):
            title = sources.SECTIONS.get(doc, {}).get(number, unknown)
            lines.append(f"* spec {number} ({doc}): {title}")
    if found.references or found.seeds:
        lines += ["", "References cited (the reference list of vendor-blocks):", ""]
        lines += [f"* {r}: {sources.REFERENCES.get(r, unknown)}"
                  for r in sorted(found.references, key=lambda r: int(r[1:]))]
        lines += [f"* seed {s}: {sources.SEEDS.get(s, unknown)}" for s in sorted(found.seeds)]
    if found.tags:
        lines += ["", "Tags:", ""]
        lines += [f"* [{tag}] ({document}) {meaning}"
                  for tag, meaning in sources.TAGS[document].items() if tag in found.tags]
        lines += [f"* [{tag}] (loopworks) {meaning}"
                  for tag, meaning in sources.PROJECT_TAGS.items() if tag in found.tags]
        known = {*sources.TAGS[document], *sources.PROJECT_TAGS}
        lines += [f"* [{tag}] {unknown}" for tag in sorted(found.tags - known)]
    return "\n".join(lines)


def markdown(cls: type[Block]) -> str:
    """The reference page of a block kind, in Markdown, ending with its Sources section."""
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
        "## Layout",
        "",
        "What the kernel keeps from scan to scan (the state, `state()`), and the coefficients "
        "it reads, derived from the parameters; each name is an index of the kernel "
        "(`x[X.name]`, `p[P.name]`).",
        "",
        "State:",
        "",
        _table(("index", "name", "size"), layout_rows(cls.STATES)),
        "",
        "Coefficients:",
        "",
        _table(("index", "name", "size"), layout_rows(cls.COEFFS)),
        "",
        "## Non-finite values (every kind)",
        "",
        NUMERIC_CONTRACT,
        "",
    ]
    document = sources.kind_document(cls.__module__)
    body = "\n".join(parts)
    return body + "\n" + sources_section(citations(body, document), document) + "\n"
