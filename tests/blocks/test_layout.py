"""Every kind declares its layouts once (issue 12 point 1): its kernel's index names are made
from the declarations, the arrays a block holds follow them, and the generated docs show them."""

from __future__ import annotations

import contextlib
import re
import types
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import loopworks
from loopworks.blocks import layout
from loopworks.blocks.layout import Array
from tests.blocks.test_block_model import VARIANTS

ROOT = Path(__file__).resolve().parents[2]  # the checkout (loopworks may be installed elsewhere)
SRC = ROOT / "src" / "loopworks"
DOCS = ROOT / "docs" / "blocks"


def _referenced(fn: Any, seen: set[int] | None = None) -> Iterator[tuple[str, Any]]:
    """(name, value) of every global a kernel reads, through the primitives it calls."""
    seen = set() if seen is None else seen
    fn = getattr(fn, "py_func", fn)
    if id(fn) in seen or not isinstance(fn, types.FunctionType):
        return
    seen.add(id(fn))
    codes = [fn.__code__]
    names: set[str] = set()
    while codes:
        code = codes.pop()
        names |= set(code.co_names)
        codes += [c for c in code.co_consts if isinstance(c, types.CodeType)]
    for name in sorted(names):
        if name in fn.__globals__:
            value = fn.__globals__[name]
            yield name, value
            if getattr(value, "_lw_primitive", False):
                yield from _referenced(value, seen)


def _declarations(cls: type[loopworks.Block] | loopworks.Block) -> dict[str, tuple[Any, ...]]:
    return {"COEFFS": cls.COEFFS, "STATES": cls.STATES, "INPUTS": cls.INPUTS,
            "OUTPUTS": cls.OUTPUTS}


#: every kind with each parameter set that exercises its branches (tests.blocks.test_block_model)
CASES = [(kind, params) for kind in loopworks.kinds() for params in VARIANTS.get(kind, [{}])]
IDS = [f"{kind}-{i}" for kind in loopworks.kinds() for i in range(len(VARIANTS.get(kind, [{}])))]


@pytest.mark.parametrize(("kind", "params"), CASES, ids=IDS)
def test_the_kernel_indexes_with_names_made_from_the_declarations(
        kind: str, params: dict[str, Any]) -> None:
    """Each layout name tuple the kernel reads is index() of one of the kind's declarations
    (an instance's, for kinds whose ports follow their parameters): no hand-written
    offsets."""
    block = loopworks.create_block(kind, **params)
    declared = {}
    for key, value in _declarations(block).items():
        # names that are not identifiers (deltav.calc's "x.st") make no index
        with contextlib.suppress(ValueError):
            declared[key] = layout.index(value)
    used = {name: value for name, value in _referenced(type(block).kernel)
            if getattr(type(value), "_lw_layout", False)}
    assert used, f"{kind}: the kernel reads no generated layout names"
    for name, names in used.items():
        matches = [key for key, made in declared.items()
                   if made._fields == names._fields and tuple(made) == tuple(names)]
        assert matches, (f"{kind}: the kernel's {name} = {names} is not made from the "
                         f"kind's declarations {sorted(declared)}")


@pytest.mark.parametrize(("kind", "params"), CASES, ids=IDS)
def test_the_arrays_follow_the_declarations(kind: str, params: dict[str, Any]) -> None:
    """coefficients() gives names (packed by COEFFS), the state has the declared size and
    names, and a saved state round-trips by those names."""
    block = loopworks.create_block(kind, **params)
    values = block.coefficients()
    assert isinstance(values, Mapping), f"{kind}: coefficients() must return names and values"
    assert list(values) == list(layout.entries_of(block.COEFFS))
    assert block.p.shape == (layout.size(block.COEFFS, block.params),)
    assert block.x.shape == (layout.size(block.STATES, block.params),)
    state = block.state()
    assert list(state) == list(layout.entries_of(block.STATES))
    for entry in block.STATES:
        if isinstance(entry, Array):
            assert len(state[entry.name]) == entry.length(block.params)
    saved = block.state_dict()
    again = loopworks.create_block(kind, **params)
    again.load_state(saved)
    assert np.array_equal(again.x, block.x, equal_nan=True)


@pytest.mark.parametrize("kind", loopworks.kinds())
def test_the_reference_page_shows_the_layouts(kind: str) -> None:
    """docs/blocks/KIND.md lists the state and coefficient names at their kernel indices."""
    cls = loopworks.block_class(kind)
    page = (DOCS / f"{kind}.md").read_text()
    section = page.split("## Layout\n", 1)[1].split("\n## ", 1)[0]
    state, coeffs = section.split("Coefficients:")
    for text, entries in ((state, cls.STATES), (coeffs, cls.COEFFS)):
        rows = re.findall(r"^\| (\d+) \| (\S+) \|", text, flags=re.M)
        assert [(int(i), n) for i, n in rows] == list(zip(
            layout.offsets(entries), layout.entries_of(entries), strict=True))


LAYOUT_BY_HAND = re.compile(r"^\s*\(?[A-Z][A-Z0-9_]*(\s*,\s*[A-Z][A-Z0-9_]*)+\s*,?\s*\)?"
                            r"\s*=\s*\\?\s*range\(\d+\)", re.M)
SIZED_BY_HAND = re.compile(r"\[0\.0\]\s*\*\s*\d+")


def test_no_layout_is_written_by_hand() -> None:
    """No module numbers its array slots itself (``A, B, C = range(3)``) or sizes an array by
    a literal (``[0.0] * 57``): index() and the declarations do that."""
    found = []
    paths = sorted(SRC.rglob("*.py"))
    assert len(paths) > 40, f"the source is not at {SRC}"
    for path in paths:
        text = path.read_text(encoding="utf-8")
        text = re.sub(r"\\\n", " ", text)
        for pattern in (LAYOUT_BY_HAND, SIZED_BY_HAND):
            found += [f"{path.relative_to(SRC)}: {m.group(0).strip()[:60]}"
                      for m in pattern.finditer(text)]
    assert found == []


def test_index_and_pack() -> None:
    """index() numbers names in order, an Array by its first element; pack() lays values out
    and names what is missing, unknown or wrongly sized."""
    entries = ("a", Array("ring", 3), "b", Array("tail", lambda prm: prm["n"]))
    at = layout.index(entries)
    assert tuple(at) == (0, 1, 4, 5) and at.b == 4
    assert layout.size(entries, {"n": 2}) == 7
    assert layout.names(entries, {"n": 2}) == ("a", "ring[0]", "ring[1]", "ring[2]", "b",
                                               "tail[0]", "tail[1]")
    values = {"a": 1, "ring": [2, 3, 4], "b": 5, "tail": [6, 7]}
    flat = layout.pack(entries, values, "k", {"n": 2})
    assert flat.tolist() == [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]
    assert layout.unpack(entries, flat, {"n": 2}) == values
    with pytest.raises(ValueError, match="k: z not declared, b missing"):
        layout.pack(entries, {"a": 1, "ring": [2, 3, 4], "z": 5, "tail": [6, 7]}, "k")
    with pytest.raises(ValueError, match="'ring' has 2 values, its declaration 3"):
        layout.pack(entries, {**values, "ring": [2, 3]}, "k", {"n": 2})
    with pytest.raises(ValueError, match="declared twice"):
        layout.index(("a", "a"))
    with pytest.raises(ValueError, match="must be the last"):
        layout.index((Array("tail", lambda prm: 1), "a"))
