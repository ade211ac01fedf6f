"""Layouts: a kind's coefficients and states declared once, the index names its kernel reads
generated from that declaration.

A kind declares its coefficient array ``p`` (``COEFFS``) and its state array ``x``
(``STATES``) as tuples of entries, each a name (one float) or an :class:`Array` (several
floats under one name: a delay line, a program, a table). Its inputs and outputs are its
``INPUTS`` and ``OUTPUTS`` ports. From the four declarations the kind's module makes the
names its kernel indexes with::

    P = index(COEFFS)       # p[P.kicker_factor]
    X = index(STATES)       # x[X.dither_amp]; an Array's name is its first element's index
    U = index(INPUTS)       # u[U.sp], us[U.sp]
    Y = index(OUTPUTS)      # y[Y.out], ys[Y.out]

The result is a named tuple of ints: interpreted, ``P.kp`` is a tuple field read; compiled,
numba freezes a global tuple into the machine code, so ``p[P.kp]`` costs what ``p[3]`` does.
``coefficients()`` returns names and values, which :func:`pack` lays out in the declared
order, refusing a missing or unknown name, so a layout cannot drift from its names.

An Array's size is fixed (an int) or per instance: a function of the validated parameters
(a delay line of ``delay_capacity`` scans). A per-instance Array must be the last entry, so
every name before it has the same index in every instance.
"""

from __future__ import annotations

import contextlib
import functools
from collections import namedtuple
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Array:
    """An array-valued entry of a layout: ``size`` floats under one name. ``size`` is an int,
    or a function of the validated parameters (per instance; last entry only)."""

    name: str
    size: int | Callable[[Mapping[str, Any]], int]
    meaning: str = ""

    def length(self, params: Mapping[str, Any] | None) -> int:
        """The number of floats this entry holds for an instance with ``params``."""
        if isinstance(self.size, int):
            return self.size
        if params is None:
            raise ValueError(f"the size of '{self.name}' depends on the parameters")
        return int(self.size(params))


Entry = Any  # str | Array | a port (anything with a ``name``)


def _name(entry: Entry) -> str:
    return entry if isinstance(entry, str) else str(entry.name)


def _check(entries: Sequence[Entry]) -> None:
    names = [_name(e) for e in entries]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ValueError(f"layout names {dup} are declared twice")
    for entry in entries[:-1]:
        if isinstance(entry, Array) and not isinstance(entry.size, int):
            raise ValueError(f"'{entry.name}' has a per-instance size: it must be the last "
                             "entry of its layout")


def offsets(entries: Sequence[Entry]) -> list[int]:
    """Each entry's index in its array (an Array's: its first element's)."""
    _check(entries)
    out: list[int] = []
    at = 0
    for entry in entries:
        out.append(at)
        if isinstance(entry, Array):
            if isinstance(entry.size, int):
                at += entry.size
        else:
            at += 1
    return out


def index(entries: Sequence[Entry], typename: str = "Layout") -> Any:
    """The named tuple of each entry's index (an Array's: its first element's). The names
    must be Python identifiers (the kernel writes them as ``P.name``)."""
    at = offsets(entries)
    cls = namedtuple(typename, [_name(e) for e in entries])  # type: ignore[misc]
    cls._lw_layout = True  # type: ignore[attr-defined] # made here (the layout test finds a kernel's names by it)
    return cls(*at)


def size(entries: Sequence[Entry], params: Mapping[str, Any] | None = None) -> int:
    """The number of floats the layout holds for an instance with ``params``."""
    return sum(e.length(params) if isinstance(e, Array) else 1 for e in entries)


def names(entries: Sequence[Entry], params: Mapping[str, Any] | None = None) -> tuple[str, ...]:
    """One name per float: an entry's name, an Array's element ``name[i]``."""
    out: list[str] = []
    for entry in entries:
        if isinstance(entry, Array):
            out += [f"{entry.name}[{i}]" for i in range(entry.length(params))]
        else:
            out.append(_name(entry))
    return tuple(out)


@functools.lru_cache(maxsize=256)
def _names_of(entries: tuple[Entry, ...]) -> tuple[str, ...]:
    return tuple(_name(e) for e in entries)


@functools.lru_cache(maxsize=256)
def _scalars_of(entries: tuple[Entry, ...]) -> bool:
    return not any(isinstance(e, Array) for e in entries)


def _scalars(entries: tuple[Entry, ...]) -> bool:
    """True when no entry is an Array (worked out once per layout)."""
    try:
        return _scalars_of(entries)
    except TypeError:  # an entry that cannot be hashed
        return not any(isinstance(e, Array) for e in entries)


def _declared(entries: Sequence[Entry]) -> tuple[str, ...]:
    """The entries' names (a kind's layout is a tuple: its names are worked out once)."""
    if isinstance(entries, tuple):
        with contextlib.suppress(TypeError):  # an entry that cannot be hashed: worked out
            return _names_of(entries)
    return tuple(_name(e) for e in entries)


def pack(entries: Sequence[Entry], values: Mapping[str, Any], what: str,
         params: Mapping[str, Any] | None = None) -> np.ndarray:
    """``values`` (name to a float, or to a sequence for an Array) in the layout's order, as
    one float64 array. A missing, unknown or wrongly sized entry is a ValueError naming it,
    ``what`` naming the values ("pid: coefficients()", "pid: saved state")."""
    declared = _declared(entries)
    if len(values) != len(declared) or not all(n in values for n in declared):
        missing = [n for n in declared if n not in values]
        extra = [n for n in values if n not in declared]
        raise ValueError(f"{what}: {', '.join(sorted(extra)) or 'nothing'} not declared, "
                         f"{', '.join(sorted(missing)) or 'nothing'} missing")
    # the floats in order, an Array's values as one array among them (a scalar layout, the
    # common case, is one conversion of a list)
    if isinstance(entries, tuple) and _scalars(entries):
        return np.array([float(values[name]) for name in declared], dtype=np.float64)
    parts: list[Any] = []
    arrays = False
    for entry, name in zip(entries, declared, strict=True):
        value = values[name]
        if isinstance(entry, Array):
            items = np.asarray(value, dtype=np.float64)
            if items.ndim != 1:
                raise ValueError(f"{what}: '{entry.name}' must be a list of numbers")
            if params is not None and len(items) != entry.length(params):
                raise ValueError(f"{what}: '{entry.name}' has {len(items)} values, its "
                                 f"declaration {entry.length(params)}")
            parts.append(items)
            arrays = True
        else:
            parts.append(float(value))
    if not arrays:
        return np.array(parts, dtype=np.float64)
    return np.concatenate([p if isinstance(p, np.ndarray) else np.array([p]) for p in parts])


def unpack(entries: Sequence[Entry], flat: Any,
           params: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The inverse of :func:`pack`: name to a float, or to a list for an Array."""
    out: dict[str, Any] = {}
    at = 0
    for entry in entries:
        if isinstance(entry, Array):
            n = entry.length(params) if params is not None or isinstance(entry.size, int) \
                else len(flat) - at
            out[entry.name] = [float(v) for v in flat[at:at + n]]
            at += n
        else:
            out[_name(entry)] = float(flat[at])
            at += 1
    return out


def entries_of(declaration: Iterable[Entry]) -> tuple[str, ...]:
    """The declared names, in order (an Array counts once)."""
    return tuple(_name(e) for e in declaration)
