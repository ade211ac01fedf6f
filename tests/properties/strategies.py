"""Hypothesis strategies shared by the property tests: random blocks of every kind (random
parameters within their documented ranges, starting from the branch-covering variants of
``tests/blocks/test_block_model.py``), random scan times with jitter, and random input
sequences that include NaN, ±inf, ±1e308, subnormals and status bytes of every quality."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from hypothesis import assume
from hypothesis import strategies as st

import loopworks
from loopworks.blocks.block import Block
from loopworks.blocks.params import Param
from loopworks.catalog import block_class
from loopworks.errors import LoopworksError
from tests.blocks.test_block_model import VARIANTS

#: values no kind may turn into a non-finite output with a status that is not Bad
SPECIALS = (math.nan, math.inf, -math.inf, 1e308, -1e308, 5e-324, -5e-324, 2.2250738585072014e-308,
            3.5e38, -3.5e38, 32768.0, -32769.0, 0.0)
#: one status byte of each quality and common substatuses and limit bits
STATUSES = (128, 128, 128, 129, 130, 131, 0xC0, 0xC4, 0xD8, 0x40, 0x44, 0x4B, 0x54, 0x00, 0x04,
            0x08, 0x0C, 0x10, 0x18, 0x1C, 0x03)
#: parameters whose size sets an array length or a work count: keep them small
SIZE_LIMITS = {"delay_capacity": 400, "max_order": 6, "max_substeps": 400, "max_cycles": 30,
               "stable_cycles": 6, "discard_cycles": 4, "cycles": 4, "manual_steps": 8}
#: parameters the property tests leave at the variant's value (text, seeds of expressions)
FIXED = {"expression", "num", "den", "sample_time", "substep"}


@functools.cache
def param_value(prm: Param) -> st.SearchStrategy[Any]:
    """A value of ``prm`` inside its documented range (finite, moderate magnitudes); one
    strategy object per parameter (Hypothesis works out a new strategy's properties on its
    first draw, a tenth of a property test's time when one was made per draw)."""
    if prm.type == "choice":
        return st.sampled_from(prm.choices)
    if prm.type == "bool":
        return st.booleans()
    lo = prm.lo if math.isfinite(prm.lo) else -1e6
    hi = prm.hi if math.isfinite(prm.hi) else 1e6
    lo, hi = max(lo, -1e6), min(hi, 1e6)
    if prm.name in SIZE_LIMITS:
        hi = min(hi, SIZE_LIMITS[prm.name])
    if prm.type == "int":
        ilo, ihi = math.ceil(lo + (1 if prm.lo_open and lo == prm.lo else 0)), math.floor(hi)
        return st.integers(ilo, max(ilo, ihi))
    inner = st.floats(lo, hi, exclude_min=prm.lo_open, exclude_max=prm.hi_open,
                      allow_nan=False, allow_infinity=False)
    edges = [v for v in (prm.lo, prm.hi) if not math.isnan(v)
             and ((v == prm.lo and not prm.lo_open) or (v == prm.hi and not prm.hi_open))]
    return st.one_of(inner, st.sampled_from(edges)) if edges else inner


@functools.cache
def _kind_strategies(kind: str) -> tuple[st.SearchStrategy[Any], st.SearchStrategy[Any] | None]:
    """A variant of ``kind``, and up to three of its free parameters (None: it has none)."""
    free = [p for p in block_class(kind).PARAMS if p.type != "text" and p.name not in FIXED]
    chosen = (st.lists(st.sampled_from(free), max_size=3, unique_by=lambda p: p.name)
              if free else None)
    return st.sampled_from(VARIANTS[kind]), chosen


@st.composite
def blocks(draw: st.DrawFn, kind: str) -> tuple[str, dict[str, Any]]:
    """(kind, params): a variant of ``kind`` with up to three parameters redrawn."""
    variant, chosen = _kind_strategies(kind)
    params = dict(draw(variant))
    if chosen is not None:
        for prm in draw(chosen):
            params[prm.name] = draw(param_value(prm))
    try:
        loopworks.create_block(kind, jit=False, **params)
    except LoopworksError:
        assume(False)
    return kind, params


@dataclass
class Case:
    """A block to build, its scan times and per-scan inputs (``name: (value, status)``)."""

    kind: str
    params: dict[str, Any]
    dts: list[float]
    inputs: list[dict[str, Any]]

    def make(self) -> Block:
        return loopworks.create_block(self.kind, **self.params)


def scan_time(block: Block, params: dict[str, Any]) -> float:
    """A scan time this block accepts: its own sample time, else 0.5 s, 0.1 s, ... (a short
    delay line takes only long scans); a block that takes none is not a case."""
    candidates = [float(params["sample_time"])] if "sample_time" in params else []
    for dt in [*candidates, 0.5, 0.1, 1.0, 0.05, 2.0, 5.0, 20.0, 100.0, 1000.0]:
        try:
            block.check_dt(dt)
        except LoopworksError:
            continue
        return dt
    assume(False)
    raise AssertionError("unreachable")  # pragma: no cover


def _accepts(block: Block, dt: float) -> bool:
    try:
        block.check_dt(dt)
    except LoopworksError:
        return False
    return True


def input_rows(block: Block, n: int, seed: int, special: float, bad: float) -> list[
        dict[str, Any]]:
    """``n`` scans of inputs for ``block`` from a seeded generator (cheap to make, so the slow
    profile can afford 10,000 examples): values mostly in -50..150, with probability
    ``special`` one of :data:`SPECIALS`, statuses from :data:`STATUSES` with probability
    ``bad``; an input keeps its last value with probability 0.4 (as a wired input often does).
    """
    rng = np.random.default_rng(seed)
    rows: list[dict[str, Any]] = []
    for _ in range(n):
        row: dict[str, Any] = {}
        for port in block.INPUTS:
            if rows and rng.random() < 0.4:
                row[port.name] = rows[-1][port.name]
                continue
            if port.choices:
                value = float(rng.integers(0, len(port.choices)))
            elif port.name == "clock":
                value = math.nan  # the block's own time
            elif rng.random() < special:
                value = SPECIALS[int(rng.integers(0, len(SPECIALS)))]
            else:
                value = float(rng.uniform(-50.0, 150.0))
            status = STATUSES[int(rng.integers(0, len(STATUSES)))] if rng.random() < bad else 128
            row[port.name] = (value, status)
        rows.append(row)
    return rows


SEEDS = st.integers(0, 2**32 - 1)
BOOLEANS = st.booleans()


@functools.cache
def _scan_counts(lo: int, hi: int) -> st.SearchStrategy[int]:
    return st.integers(lo, hi)


@st.composite
def cases(draw: st.DrawFn, kind: str, *, special: float = 0.12, bad: float = 0.15,
          scans: tuple[int, int] = (4, 40)) -> Case:
    """A random block of ``kind`` and a random input sequence for it, with dt jitter."""
    kind, params = draw(blocks(kind))
    block = loopworks.create_block(kind, jit=False, **params)
    dt0 = scan_time(block, params)
    n = draw(_scan_counts(*scans))
    seed = draw(SEEDS)
    rng = np.random.default_rng(seed + 1)
    jitter = draw(BOOLEANS) and "sample_time" not in params
    dts = []
    for _ in range(n):
        dt = dt0 * float(rng.uniform(0.8, 1.25)) if jitter else dt0
        dts.append(dt if _accepts(block, dt) else dt0)
    return Case(kind, params, dts, input_rows(block, n, seed, special, bad))
