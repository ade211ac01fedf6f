"""Modules: named blocks plus wires, executed in a fixed declared order.

A module is DeltaV's word for a function-block diagram. Each scan, the blocks run in the
declared order; just before a block runs, each of its wired inputs is copied from its source
output, so an input reads its source's newest value: this scan's if the source already ran,
else the last scan's. Feedback loops need no special case.

Wires go from destination to source, as in a scenario file's ``[wires]`` table::

    Module({"pid": create_block("pid", k=2, ti=20), "process": create_block("process.first_order")},
           wires={"process.u": "pid.out", "pid.pv": "process.y"},
           inputs={"pid": {"sp": 50.0}})

An unwired input takes the constant given for it in ``inputs`` (a scenario block table's
``sp = 50.0``), else its port default. Events set an unwired input, or change a parameter
(a new tuning, a new disturbance size), at a given time. A block
with an input named ``clock`` (a controller clock in seconds, as GE's PID measures its own dt)
gets the module time t_k there, unless it is wired or given.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from loopworks.blocks.block import Block
from loopworks.errors import InputError
from loopworks.sim.result import SimResult


@dataclass(frozen=True)
class Event:
    """At time ``t`` (s), set the unwired input ``target`` ("block.input") to ``value``."""

    t: float
    target: str
    value: Any


def _split(ref: str, what: str) -> tuple[str, str]:
    if ref.count(".") < 1:
        raise InputError(f"{what} '{ref}' must be written 'block.port'")
    block, port = ref.rsplit(".", 1)
    return block, port


class Module:
    """Named blocks, wires from destination input to source output, and a run order."""

    def __init__(self, blocks: Mapping[str, Block], wires: Mapping[str, str] | None = None,
                 inputs: Mapping[str, Mapping[str, Any]] | None = None,
                 order: Sequence[str] | None = None,
                 events: Sequence[Event] | None = None) -> None:
        self.blocks: dict[str, Block] = dict(blocks)
        self.order: list[str] = list(order) if order is not None else list(self.blocks)
        missing = set(self.blocks) - set(self.order)
        unknown = [n for n in self.order if n not in self.blocks]
        if unknown or missing or len(set(self.order)) != len(self.order):
            raise InputError(
                f"order {self.order} must name each block once; blocks: {', '.join(self.blocks)}")
        self.wires: dict[str, str] = {}
        # per block: list of (dest input index, source block, source output index)
        self._links: dict[str, list[tuple[int, Block, int]]] = {n: [] for n in self.blocks}
        for dest, src in (wires or {}).items():
            dblock, dport = self._port(dest, "input")
            sblock, sport = self._port(src, "output")
            self.wires[dest] = src
            self.blocks[dblock]._all_good = False  # the scan writes its input statuses
            self._links[dblock].append((self.blocks[dblock]._in_index[dport],
                                        self.blocks[sblock], self.blocks[sblock]._out_index[sport]))
        self.constants: dict[str, dict[str, Any]] = {}
        for name, values in (inputs or {}).items():
            for port, value in values.items():
                self._check_unwired(f"{name}.{port}", "a constant")
                self.constants.setdefault(name, {})[port.lower()] = value
        # blocks that read the controller clock (an input named "clock", s) get the module time
        self._clocks: dict[str, int] = {
            name: b._in_index["clock"] for name, b in self.blocks.items()
            if "clock" in b._in_index and f"{name}.clock" not in self.wires
            and "clock" not in self.constants.get(name, {})}
        self.events: list[Event] = sorted(events or [], key=lambda e: e.t)
        for ev in self.events:
            if not self._is_parameter(ev.target):
                self._check_unwired(ev.target, "an event")
            if not math.isfinite(ev.t) or ev.t < 0.0:
                raise InputError(f"event at t = {ev.t!r} s: t must be finite and >= 0")
        self.t = 0.0
        self.k = 0
        self.reset()

    def _port(self, ref: str, direction: str) -> tuple[str, str]:
        block, port = _split(ref, f"wire {direction}")
        if block not in self.blocks:
            raise InputError(f"wire '{ref}': unknown block '{block}'; blocks: "
                             + ", ".join(self.blocks))
        b = self.blocks[block]
        names = b._in_index if direction == "input" else b._out_index
        if port.lower() not in names:
            raise InputError(f"wire '{ref}': block '{block}' ({b.kind}) has no {direction} "
                             f"'{port}'; {direction}s: {', '.join(names)}")
        return block, port.lower()

    def _check_unwired(self, ref: str, what: str) -> None:
        block, port = self._port(ref, "input")
        if f"{block}.{port}" in self.wires:
            raise InputError(f"{what} for '{ref}' conflicts with its wire from "
                             f"'{self.wires[f'{block}.{port}']}'")

    def reset(self) -> None:
        """Every block to its initial state, constant inputs applied, time to 0."""
        for name in self.order:
            block = self.blocks[name]
            block.reset()
            if name in self.constants:
                block.set_inputs(self.constants[name])
            if self._links[name]:
                block._all_good = False  # the scan writes its input statuses
        self.t = 0.0
        self.k = 0
        self._next_event = 0

    def _is_parameter(self, ref: str) -> bool:
        """True when ``ref`` ("block.name") names a parameter (not an input) of a block."""
        block, name = _split(ref, "event target")
        b = self.blocks.get(block)
        return (b is not None and name.lower() not in b._in_index
                and name.lower() in {p.name for p in b.PARAMS})

    def _apply_events(self, t: float) -> None:
        while self._next_event < len(self.events) and self.events[self._next_event].t <= t + 1e-9:
            ev = self.events[self._next_event]
            block, name = _split(ev.target, "event target")
            if self._is_parameter(ev.target):
                self.blocks[block].set_params(**{name: ev.value})
            else:
                self.blocks[block].set_inputs({name: ev.value})
            self._next_event += 1

    def scan(self, dt: float) -> None:
        """Run every block once, in order, at the module's current time; then advance it."""
        self._apply_events(self.t)
        for name in self.order:
            block = self.blocks[name]
            u, us = block.u, block.us
            for i, src, j in self._links[name]:
                u[i] = src.y[j]
                us[i] = src.ys[j]
            if name in self._clocks:
                u[self._clocks[name]] = self.t
            block._run(dt, block.p, block.x, u, us, block.y, block.ys)
        self.k += 1
        self.t = self.k * dt

    def run(self, duration: float, dt: float, *, reset: bool = True,
            progress: Callable[[int, int], None] | None = None) -> SimResult:
        """Run ``duration`` seconds in scans of ``dt``; scan k executes at t = k·dt.

        With ``reset=False`` the run continues from the current state (and time), so a run can
        be split, saved with :meth:`state_dict` and resumed.
        """
        if not 0.0 < dt < math.inf:
            raise InputError(f"dt = {dt!r} s is not allowed: dt must be > 0 and finite")
        if not 0.0 < duration < math.inf:
            raise InputError(f"duration = {duration!r} s is not allowed: must be > 0 and finite")
        if reset:
            self.reset()
        for block in self.blocks.values():
            block._release_last()
            block.check_dt(dt)
        n = round(duration / dt)
        if n < 1:
            raise InputError(f"duration = {duration} s is shorter than one scan of dt = {dt} s")
        names: list[str] = []
        recs: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []
        for name in self.order:
            b = self.blocks[name]
            names.append(name)
            recs.append((np.empty((n, len(b.u))), np.empty((n, len(b.u)), dtype=np.int64),
                         np.empty((n, len(b.y))), np.empty((n, len(b.y)), dtype=np.int64)))
        t = np.empty(n)
        every = max(1, n // 100)
        for k in range(n):
            t[k] = self.t
            self.scan(dt)
            for name, (U, US, Y, YS) in zip(names, recs, strict=True):
                b = self.blocks[name]
                U[k] = b.u
                US[k] = b.us
                Y[k] = b.y
                YS[k] = b.ys
            if progress is not None and (k % every == 0 or k == n - 1):
                progress(k + 1, n)
        values: dict[str, np.ndarray] = {}
        status: dict[str, np.ndarray] = {}
        for name, (U, US, Y, YS) in zip(names, recs, strict=True):
            b = self.blocks[name]
            for i, port in enumerate(b.INPUTS):
                values[f"{name}.{port.name}"] = U[:, i].copy()
                status[f"{name}.{port.name}"] = US[:, i].copy()
            for i, port in enumerate(b.OUTPUTS):
                values[f"{name}.{port.name}"] = Y[:, i].copy()
                status[f"{name}.{port.name}"] = YS[:, i].copy()
        return SimResult(t=t, values=values, status=status,
                         kinds={n: self.blocks[n].kind for n in names}, wires=dict(self.wires))

    def state_dict(self) -> dict[str, Any]:
        """Time, scan count and every block's state: enough to resume a run exactly."""
        return {"t": self.t, "k": self.k, "next_event": self._next_event,
                "blocks": {n: b.state_dict() for n, b in self.blocks.items()}}

    def load_state(self, saved: Mapping[str, Any]) -> None:
        """Restore what :meth:`state_dict` saved."""
        if set(saved["blocks"]) != set(self.blocks):
            raise InputError(f"saved module has blocks {sorted(saved['blocks'])}, this one "
                             f"{sorted(self.blocks)}")
        for n, b in self.blocks.items():
            b.load_state(saved["blocks"][n])
        self.t = float(saved["t"])
        self.k = int(saved["k"])
        self._next_event = int(saved["next_event"])
