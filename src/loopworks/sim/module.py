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
``sp = 50.0``), else its port default. An enumerated input (a ``mode``: codes that name
choices, MAN 0, AUTO 1, ...) takes a wire only from an output with the same codes (DeltaV's
``mode_actual``); an analog signal there is refused when the module is made.

Events set an unwired input, or change a parameter (a new tuning, a new disturbance size), at
a given time; both are checked when the module is made. A block with an input named
``clock`` (a controller clock in seconds, as GE's PID measures its own dt) gets the module
time t_k there, unless it is wired or given.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any, ClassVar

import numpy as np

from loopworks.blocks.block import Block
from loopworks.blocks.params import Port
from loopworks.blocks.plan import SCANS_SIGNATURE, Record, Slot, entry, is_cached, layout
from loopworks.errors import InputError, LoopworksError
from loopworks.sim.result import SimResult

#: bytes a run records per signal per scan: a float64 value and a status byte
RECORD_BYTES = 9
#: the most a run may record when the available memory cannot be read (bytes)
RECORD_CAP = 8 * 1024**3
#: a run of at least this many block-scans (scans × blocks) compiles the module's plan when
#: it is not cached yet; a shorter one runs block by block from Python (each block's own
#: compiled step), which costs less than compiling the module would
PLAN_MIN_BLOCK_SCANS = 20_000
#: a run of at least this many block-scans takes the module's ``fused`` plan (every kernel
#: inlined, which reaches each kernel directly instead of through its kind's cached entry),
#: compiling it once for this module's shape when it is not cached yet; a shorter run takes
#: ``scans`` (only its glue to compile) unless the fused plan is already cached or asked for
#: (``plan="fused"``). Fusing saves 20-60 ns per block-scan, and compiling it costs about a
#: second per light kind (pid, fopdt: 2 s) and several for the heavy ones (the built-in
#: scenario's seven blocks, DeltaV PID, Karnopp valve, calc: 22 s, 63 s before the
#: primitives were linked instead of inlined by numba, 2026-12-07; saving 0.4 µs of 2.2 µs a
#: scan): 1e9 block-scans pays for the heaviest compile. It was 1e6, and a 20-hour simulate
#: of the built-in scenario spent a minute compiling to save 0.06 s.
PLAN_FUSE_BLOCK_SCANS = 1_000_000_000
# the record arguments of a one-scan plan call that records nothing (Module.scan)
_T1 = np.empty(1)
_NO_F = np.empty((0, 1))
_NO_S = np.empty((0, 1), dtype=np.uint8)
_NO_I = np.empty(0, dtype=np.int64)


@dataclass(frozen=True)
class Event:
    """At time ``t`` (s), set the unwired input ``target`` ("block.input") to ``value``."""

    t: float
    target: str
    value: Any


def _event(ev: Any) -> Event:
    """An :class:`Event`; also from a mapping with ``t``, ``set`` (or ``target``) and
    ``value`` (a scenario's ``[[events]]`` table) or a ``(t, target, value)`` tuple; anything
    else is an InputError that shows it."""
    if isinstance(ev, Event):
        return ev
    if isinstance(ev, Mapping):
        keys = {str(k).lower(): v for k, v in ev.items()}
        target = keys.get("set", keys.get("target"))
        if set(keys) <= {"t", "set", "target", "value"} and "t" in keys and "value" in keys \
                and isinstance(target, str):
            return Event(float(keys["t"]), target, keys["value"])
    elif isinstance(ev, tuple | list) and len(ev) == 3 and isinstance(ev[1], str):
        return Event(float(ev[0]), ev[1], ev[2])
    raise InputError(f"event {ev!r}: expected Event(t, target, value), a (t, target, value) "
                     "tuple or a {t, set, value} table")


def _split(ref: str, what: str) -> tuple[str, str]:
    if ref.count(".") < 1:
        raise InputError(f"{what} '{ref}' must be written 'block.port'")
    block, port = ref.rsplit(".", 1)
    return block, port


def _codes(choices: tuple[str, ...]) -> str:
    return ", ".join(f"{c} {i}" for i, c in enumerate(choices))


#: the most scans a run can have: 2**53, the largest count a double holds exactly (t = k·dt)
MAX_SCANS = 2**53


def downstream_valves(loop: str, wires: Mapping[str, str], kinds: Mapping[str, str],
                      controllers: set[str], is_valve: Callable[[str], bool]) -> list[str]:
    """Every block with a position output (``is_valve``) downstream of block ``loop`` along
    ``wires`` (dest -> src), nearest first, through the blocks that pass a signal on
    (compensators, calculations, a relay), not through a valve, a process, a sensor, a load
    or a controller: a split range's two valves, for one."""
    stops = ("process.", "sensor.", "disturbance.")
    frontier, seen, found = [loop], {loop}, []
    while frontier:
        block = frontier.pop(0)
        for dest, src in wires.items():
            if src.rsplit(".", 1)[0] == block:
                nxt = dest.rsplit(".", 1)[0]
                if nxt in seen:
                    continue
                seen.add(nxt)
                if is_valve(nxt):
                    found.append(nxt)
                elif nxt not in controllers and not kinds.get(nxt, "").startswith(stops):
                    frontier.append(nxt)
    return found


def downstream_valve(loop: str, wires: Mapping[str, str], kinds: Mapping[str, str],
                     controllers: set[str], is_valve: Callable[[str], bool]) -> str | None:
    """The first of :func:`downstream_valves`, or None."""
    found = downstream_valves(loop, wires, kinds, controllers, is_valve)
    return found[0] if found else None


def _unit_text(block: Block, unit: str, side: int) -> str:
    """``unit`` in words; counts with the block's count of 100 % (``Controller.SPANS``, side
    0 the PV's, 1 the output's)."""
    if unit == "counts":
        spans = getattr(block, "SPANS", None)
        return f"counts ({spans[side][1]:g} = 100 %)" if spans else "counts"
    return {"%": "% of span",
            "EU": "engineering units of a scale other than 0..100"}.get(unit, unit)


def scan_count(duration: float, dt: float, what: str = "duration", least: int = 1) -> int:
    """n = round(duration/dt) scans, at t_k = k·dt; InputError unless dt and duration are
    finite and > 0 and give at least ``least`` scans and at most ``MAX_SCANS``. ``what``
    names the length in the messages (``duration``; a relay test's ``start``)."""
    if not 0.0 < dt < math.inf:
        raise InputError(f"dt = {dt!r} s is not allowed: dt must be > 0 and finite")
    if not 0.0 < duration < math.inf:
        raise InputError(f"{what} = {duration!r} s is not allowed: must be > 0 and finite")
    ratio = duration / dt
    if not ratio <= MAX_SCANS:
        raise InputError(f"{what} = {duration:g} s in scans of dt = {dt:g} s is more scans "
                         f"than can be counted (at most {MAX_SCANS:.4g}: 2**53, where a scan "
                         "number is still exact as a double)")
    n = round(ratio)
    if n < least:
        raise InputError(f"{what} = {duration:g} s is shorter than one scan of dt = {dt:g} s")
    return n


def available_memory() -> int | None:
    """Bytes of memory available to a new allocation (Linux MemAvailable, else free physical
    pages), or None when the system does not say."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (AttributeError, OSError, ValueError):
        return None


def _gb(n: float) -> str:
    return f"{n / 1e9:.3g} GB" if n >= 1e9 else f"{n / 1e6:.3g} MB"


def check_record_size(need: int, duration: float, dt: float, n: int,
                      what: str = "duration") -> None:
    """InputError when a run's record of ``need`` bytes (``n`` scans) would not fit: beyond
    the available memory, or beyond RECORD_CAP when that is unknown. ``what`` names the
    length in the message (``duration``; a relay test's ``start``)."""
    if need <= 2**26:  # 64 MB fits anywhere this runs; skip reading the system's figure
        return
    avail = available_memory()
    limit = RECORD_CAP if avail is None else avail
    if need > limit:
        have = ("the record cap of " + _gb(RECORD_CAP) if avail is None
                else f"{_gb(avail)} is available")
        raise InputError(
            f"{what} = {duration:g} s in scans of dt = {dt:g} s is {n:.4g} scans; recording "
            f"them needs about {_gb(need)} of memory and {have}: use a shorter {what} or a "
            "longer dt")


class Module:
    """Named blocks, wires from destination input to source output, and a run order."""

    #: how many modules were laid out in this process (a block changes module only then)
    _layouts: ClassVar[int] = 0

    def __init__(self, blocks: Mapping[str, Block], wires: Mapping[str, str] | None = None,
                 inputs: Mapping[str, Mapping[str, Any]] | None = None,
                 order: Sequence[str] | None = None,
                 events: Sequence[Event | Mapping[str, Any] | tuple[float, str, Any]] | None
                 = None) -> None:
        self.blocks: dict[str, Block] = dict(blocks)
        # per parameter an event changed since the last reset: its value before the run's
        # first event on it and the value the events left (reset() sets it back)
        self._undo: dict[tuple[str, str], tuple[Any, Any]] = {}
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
            dblock, dport = self._port(dest, "input", "wire")
            sblock, sport = self._port(src, "output", "wire")
            self._check_kind(dest, src, self.blocks[dblock].INPUTS[
                self.blocks[dblock]._in_index[dport]], self.blocks[sblock].OUTPUTS[
                self.blocks[sblock]._out_index[sport]])
            self.wires[dest] = src
            self.blocks[dblock]._all_good = False  # the scan writes its input statuses
            self._links[dblock].append((self.blocks[dblock]._in_index[dport],
                                        self.blocks[sblock], self.blocks[sblock]._out_index[sport]))
        self.constants: dict[str, dict[str, Any]] = {}
        for name, values in (inputs or {}).items():
            for port, value in values.items():
                self._check_unwired(f"{name}.{port}", "constant")
                self.constants.setdefault(name, {})[port.lower()] = value
        # blocks that read the controller clock (an input named "clock", s) get the module time
        self._clocks: dict[str, int] = {
            name: b._in_index["clock"] for name, b in self.blocks.items()
            if "clock" in b._in_index and f"{name}.clock" not in self.wires
            and "clock" not in self.constants.get(name, {})}
        self.events: list[Event] = sorted((_event(e) for e in events or []), key=lambda e: e.t)
        for ev in self.events:
            if not math.isfinite(ev.t) or ev.t < 0.0:
                raise InputError(f"event at t = {ev.t!r} s: t must be finite and >= 0")
        self._check_events()
        self._lay_out()
        self.t = 0.0
        self.k = 0
        self.reset()

    def _lay_out(self) -> None:
        """The execution plan's layout: every block's buffers moved into one float and one int
        buffer (``Block.adopt``), the wires and clocks as offsets, and the record's indices
        (each block's inputs then outputs, in run order). Compiled on the first run."""
        if len({id(b) for b in self.blocks.values()}) != len(self.blocks):
            raise InputError("a block object can be in a module once: make one block per name")
        index = {id(self.blocks[n]): k for k, n in enumerate(self.order)}
        sizes = [(type(b).kernel, len(b.p), len(b.x), len(b.u), len(b.y), not b.SOUND_KERNEL)
                 for b in (self.blocks[n] for n in self.order)]
        slots = []
        for slot, name in zip(layout(sizes), self.order, strict=True):
            links = tuple((i, index[id(src)], j) for i, src, j in self._links[name])
            slots.append(replace(slot, links=links, clock=self._clocks.get(name)))
        self._slots: list[Slot] = slots
        self._F: np.ndarray = np.zeros(slots[-1].f1 if slots else 0)
        self._S: np.ndarray = np.zeros(slots[-1].s1 if slots else 0, dtype=np.int64)
        self._token = object()  # the blocks' buffers are this module's while they hold it
        Module._layouts += 1  # any module laid out since a check may have taken a block
        self._checked_at = -1
        for slot, name in zip(slots, self.order, strict=True):
            self.blocks[name].adopt(self._F[slot.f0:slot.f1], self._S[slot.s0:slot.s1])
            self.blocks[name]._module = self._token
        self._rec_f = np.array([i for sl in slots for i in range(sl.u0, sl.f1)], dtype=np.int64)
        self._rec_s = np.array([i for sl in slots for i in range(sl.s0, sl.s1)], dtype=np.int64)
        self._scans: Any = None

    def __getstate__(self) -> dict[str, Any]:
        """A copy or a pickle: everything but the compiled plan, loaded again on the next run."""
        state = dict(self.__dict__)
        state["_scans"] = None
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        """A copied or unpickled module: its blocks (copied with buffers of their own) take
        views of the module's copied buffers again, as :meth:`_lay_out` gave them, so the
        plan and the blocks work on the same numbers (a deep copy ran its plan on buffers its
        blocks no longer held)."""
        self.__dict__.update(state)
        for slot, name in zip(self._slots, self.order, strict=True):
            block = self.blocks[name]
            block.adopt(self._F[slot.f0:slot.f1], self._S[slot.s0:slot.s1])
            block._module = self._token

    def _check_blocks(self) -> None:
        """InputError when a block of this module was put into another module since: it
        moved its buffers there (a block belongs to one module), and this module would run
        on numbers the blocks no longer hold. One comparison when no module was laid out
        since the last check (a scan loop from Python calls it every scan)."""
        if self._checked_at == Module._layouts:
            return
        for name, block in self.blocks.items():
            if getattr(block, "_module", None) is not self._token:
                raise InputError(f"block '{name}' ({block.kind}) was put into another module "
                                 "after this one was made: a block object belongs to one "
                                 "module; make a block per module (create_block again)")
        self._checked_at = Module._layouts

    @property
    def compiled(self) -> bool:
        """True when runs go through the compiled plan: every block is compiled (``jit``)."""
        return bool(self.blocks) and all(b.jit for b in self.blocks.values())

    def _port(self, ref: str, direction: str, what: str) -> tuple[str, str]:
        """``ref`` split into (block, port), checked; ``what`` ("wire", "constant", "event")
        names the reference in errors."""
        block, port = _split(ref, f"{what} {direction}" if what == "wire" else what)
        if block not in self.blocks:
            raise InputError(f"{what} '{ref}': unknown block '{block}'; blocks: "
                             + ", ".join(self.blocks))
        b = self.blocks[block]
        names = b._in_index if direction == "input" else b._out_index
        if port.lower() not in names:
            raise InputError(f"{what} '{ref}': block '{block}' ({b.kind}) has no {direction} "
                             f"'{port}'; {direction}s: {', '.join(names)}")
        return block, port.lower()

    @staticmethod
    def _check_kind(dest: str, src: str, inp: Port, out: Port) -> None:
        """An enumerated input (a mode: codes that name choices) takes a wire only from an
        output with the same codes; an analog value there would run the block in a mode that
        does not exist (pid mode 37) or in one nobody chose."""
        if not inp.choices or out.choices == inp.choices:
            return
        what = ("an analog output" if not out.choices
                else f"an output with other codes ({_codes(out.choices)})")
        raise InputError(
            f"wire '{dest}' = '{src}': '{dest}' is an enumerated input ({_codes(inp.choices)}) "
            f"and '{src}' is {what}; wire it from an output with the same codes, or set it "
            "with a constant or an event")

    def _check_events(self) -> None:
        """Each event's target and value, checked before any scan: an input event's value
        must parse for its port (a mode by name or code), and a parameter event must leave
        the block's parameters valid (applied in time order, as the run would)."""
        trials: dict[str, Block] = {}  # interpreted copies that take the parameter events
        seen: dict[tuple[float, str, str], int] = {}
        for i, ev in enumerate(self.events):
            where = f"event at t = {ev.t:g} s, set = '{ev.target}'"
            block, name = _split(ev.target, "event")
            first = seen.setdefault((ev.t, block, name.lower()), i)
            if first != i:
                other = self.events[first].target
                raise InputError(f"{where}: another event sets '{other}' at the same time; "
                                 "which one would hold is only the order they are written "
                                 "in: keep one")
            if self._is_parameter(ev.target):
                block, name = _split(ev.target, "event")
                b = self.blocks[block]
                try:
                    if block not in trials:
                        trials[block] = type(b)(jit=False, **b.given)
                    trials[block].set_params(**{name: ev.value})
                except LoopworksError as exc:
                    raise InputError(f"{where}: {exc}") from None
                continue
            block, port = _split(ev.target, "event")
            known = self.blocks.get(block)
            if known is None:
                raise InputError(f"{where}: unknown block '{block}'; blocks: "
                                 + ", ".join(self.blocks))
            if port.lower() not in known._in_index:
                raise InputError(
                    f"{where}: block '{block}' ({known.kind}) has no input or parameter "
                    f"'{port}'; inputs: {', '.join(known._in_index)}; parameters: "
                    + ", ".join(p.name for p in known.PARAMS))
            self._check_unwired(ev.target, "event")
            if isinstance(ev.value, tuple):
                continue  # (value, status): checked by set_inputs when applied
            try:
                known.INPUTS[known._in_index[port.lower()]].parse(ev.value)
            except (TypeError, ValueError) as exc:
                raise InputError(f"{where}: {exc}") from None

    def late_events(self, duration: float, dt: float) -> list[Event]:
        """The events a run of ``duration`` s in scans of ``dt`` s from t = 0 never reaches
        (the last scan executes at t = (n - 1)·dt, n = round(duration/dt))."""
        last = (scan_count(duration, dt) - 1) * dt
        return [ev for ev in self.events if ev.t > last + 1e-9]

    def unit_warnings(self) -> list[str]:
        """Wires whose two ends declare units that cannot hold one quantity unscaled: a % port
        fed from counts (GE's 16-bit words) or from engineering units (DeltaV's scales when
        they are not 0..100), or the reverse; and a velocity controller's increment fed to a
        valve's position command. The run would take one number for the other (a GE CV of
        16000 counts opened a valve to "16000 %", clipped to 100, with every status Good), so
        ``simulate`` says so; a scaling block between them (``deltav.calc``) clears it."""
        from loopworks.blocks.controller import Controller

        out = []
        for dest, src in self.wires.items():
            (db, dp), (sb, sp) = _split(dest, "wire input"), _split(src, "wire output")
            if db not in self.blocks or sb not in self.blocks:
                continue
            d_unit = self.blocks[db].port_unit(dp.lower(), "input")
            s_unit = self.blocks[sb].port_unit(sp.lower(), "output")
            if d_unit != s_unit and {d_unit, s_unit} <= {"%", "counts", "EU"}:
                example = (" (e.g. \"'^/PCT' := '^/CNT' / 320.0;\" for GE counts to %)"
                           if (s_unit, d_unit) == ("counts", "%") else "")
                out.append(f"wire '{dest}' = '{src}': {src} is in "
                           f"{_unit_text(self.blocks[sb], s_unit, 1)}, {dest} in "
                           f"{_unit_text(self.blocks[db], d_unit, 0)}: the value passes unscaled; "
                           f"scale it between them with a deltav.calc{example}")
            source = self.blocks[sb]
            if isinstance(source, Controller) and sp.lower() == source.ROLES.out \
                    and self.blocks[db].kind.startswith("valve.") and dp.lower() == "op":
                why = type(source).incremental(source.params)
                if why is not None:
                    out.append(f"wire '{dest}' = '{src}': {why}, and a valve's op is a "
                               "position: an integrating actuator (a motor drive) takes an "
                               "increment")
        return out

    def signals(self) -> list[str]:
        """Every input and output, ``"block.port"``, in the order a run records them."""
        return [f"{name}.{port.name}" for name in self.order
                for port in (*self.blocks[name].INPUTS, *self.blocks[name].OUTPUTS)]

    def incremental_outputs(self, changes: Mapping[str, Any] | None = None) -> frozenset[str]:
        """The controllers whose output is an increment per scan (``Controller.incremental``:
        S5's velocity algorithm), by name; with ``changes`` (a batch instance's,
        ``"block.parameter"`` = value), those of that instance (a swept ``s5.velocity``: its
        output travel was read as the template's)."""
        from loopworks.blocks.controller import Controller
        from loopworks.blocks.params import validate

        out = set()
        for n, b in self.blocks.items():
            if not isinstance(b, Controller):
                continue
            if type(b).incremental.__func__ is Controller.incremental.__func__:  # type: ignore[attr-defined]
                continue  # a kind whose output is never an increment (no validation per row)
            mine = {k.rpartition(".")[2].lower(): v for k, v in (changes or {}).items()
                    if k.rpartition(".")[0] == n
                    and k.rpartition(".")[2].lower() not in b._in_index}
            params = validate(b.kind, type(b).PARAMS, {**b.given, **mine}) if mine else b.params
            if type(b).incremental(params) is not None:
                out.add(n)
        return frozenset(out)

    def out_spans(self, instances: Sequence[Mapping[str, Any]] = ()
                  ) -> dict[str, float | np.ndarray]:
        """Each controller's output units of 100 % (``Controller.out_span``), by name; with
        ``instances`` (each a batch instance's changes, ``"block.parameter"`` = value), one
        per instance where they differ (a swept OUT_SCALE), an array of them."""
        from loopworks.blocks.controller import Controller

        spans: dict[str, float | np.ndarray] = {}
        for n, b in self.blocks.items():
            if not isinstance(b, Controller):
                continue
            span = type(b).out_span(b.params)
            mine = [{k.rpartition(".")[2].lower(): v for k, v in changes.items()
                     if k.rpartition(".")[0] == n} for changes in instances]
            if any(mine):
                each = np.array([type(b).out_span({**b.params, **m}) if m else span
                                 for m in mine])
                spans[n] = float(each[0]) if (each == each[0]).all() else each
            else:
                spans[n] = span
        return spans

    def metric_signals(self) -> list[str]:
        """What :meth:`SimResult.metrics` reads of every controller: its SP, PV and OUT roles
        (and working or cascade setpoint, mode), and every valve's position and command."""
        from loopworks.blocks.controller import Controller

        wanted: list[str] = []
        for name, block in self.blocks.items():
            if isinstance(block, Controller):
                r = block.ROLES
                wanted += [f"{name}.{p}" for p in (r.sp, r.pv, r.out, r.working_sp, r.mode)
                           if p is not None]
                if "cas_sp" in block._in_index:
                    wanted.append(f"{name}.cas_sp")
            if "position" in block._out_index:
                wanted.append(f"{name}.position")
                if "op" in block._in_index:
                    wanted.append(f"{name}.op")
        return wanted

    def record_bytes(self, n: int) -> int:
        """Memory a run of ``n`` scans records of every signal: a float64 value and a status
        byte (9 bytes) per scan, and one more, of each signal it writes scan by scan
        (:meth:`record_plan`: a constant input or an input wired to an output costs nothing)."""
        rows, _ = self.record_plan(range(len(self.signals())))
        return (n + 1) * len(rows) * RECORD_BYTES

    def _usual_record(self) -> Record:
        """The buffer offsets (values, statuses) of the record of every signal, the usual
        one, which the compiled plan writes at literal offsets (:func:`~loopworks.blocks.plan.
        source`)."""
        rows, _ = self.record_plan(range(len(self.signals())))
        return (tuple(int(i) for i in self._rec_f[rows]),
                tuple(int(i) for i in self._rec_s[rows]))

    def record_plan(self, chosen: Iterable[int]) -> tuple[list[int], list[tuple[str, int]]]:
        """How a run records the signals ``chosen`` (indices into :meth:`signals`): the signals
        it writes scan by scan (``rows``, indices into :meth:`signals`), each into a row of
        n + 1 columns, column 0 its value before the first scan and column k + 1 its value
        after scan k; and, per chosen signal, where its record comes from:

        * ``("row", r)``: columns 1..n of row r;
        * ``("before", r)``: columns 0..n-1 of row r: an input wired from an output of a block
          that runs after it (or of itself) reads, in scan k, that output as scan k - 1 left
          it (module docstring);
        * ``("const", -1)``: an unwired input that no event sets and no clock drives keeps its
          value and status for the whole run (no kernel writes its inputs).

        An input wired from a block that runs before it is ``("row", r)`` of that output: it
        holds the same value and status every scan. So no signal is written twice, and a
        constant not at all."""
        names = self.signals()
        first: dict[str, int] = {}  # each block's first signal (its inputs, then outputs)
        at = 0
        for name in self.order:
            first[name] = at
            at += len(self.blocks[name].INPUTS) + len(self.blocks[name].OUTPUTS)
        place = {name: k for k, name in enumerate(self.order)}
        evented = {(b, p.lower()) for b, p in (_split(ev.target, "event") for ev in self.events)}
        rows: dict[int, int] = {}  # signal index -> row
        how: list[tuple[str, int]] = []
        for i in chosen:
            block, port = names[i].rsplit(".", 1)
            source = self.wires.get(names[i])
            output = i - first[block] >= len(self.blocks[block].INPUTS)
            clock = block in self._clocks and port == "clock"
            if output or clock or (block, port) in evented:
                how.append(("row", rows.setdefault(i, len(rows))))
            elif source is None:
                how.append(("const", -1))
            else:
                sblock, sport = source.rsplit(".", 1)
                j = first[sblock] + len(self.blocks[sblock].INPUTS) \
                    + self.blocks[sblock]._out_index[sport]
                r = rows.setdefault(j, len(rows))
                how.append(("row" if place[sblock] < place[block] else "before", r))
        return list(rows), how

    def _check_unwired(self, ref: str, what: str) -> None:
        block, port = self._port(ref, "input", what)
        if f"{block}.{port}" in self.wires:
            article = "an" if what[0] in "aeiou" else "a"
            raise InputError(f"the {what} for '{ref}' conflicts with its wire from "
                             f"'{self.wires[f'{block}.{port}']}': an input takes a wire or "
                             f"{article} {what}, not both")

    def reset(self) -> None:
        """Every block to its initial state, constant inputs applied, time to 0.

        Then the start is settled: twice over the run order, each wired input is copied from
        its source and a block that derives its published start from its inputs (a
        ``publish_start`` method: sensors, loads, valves) publishes it again, so no block reads
        a placeholder 0 from a source that runs later in the order (issue 11 point 8).

        A parameter an event changed during the last run is set back to its value before
        that run's first event, so every run from the start sees the same parameters; unless
        it was changed since (``set_params`` between runs: a sweep's value, an operator's), then
        that value stays."""
        self._check_blocks()
        for (owner, key), (before, after) in self._undo.items():
            if self.blocks[owner].params[key] == after:
                self.blocks[owner].set_params(**{key: before})
        self._undo.clear()
        for name in self.order:
            block = self.blocks[name]
            block.reset()
            if name in self.constants:
                block.set_inputs(self.constants[name])
            if self._links[name]:
                block._all_good = False  # the scan writes its input statuses
        for _ in range(2):  # twice: a source later in the order settles too
            for name in self.order:
                block = self.blocks[name]
                for i, src, j in self._links[name]:
                    block.u[i] = src.y[j]
                    block.us[i] = src.ys[j]
                publish = getattr(block, "publish_start", None)
                if publish is not None:
                    publish()
        self.t = 0.0
        self.k = 0
        self._next_event = 0

    def check_dt(self, dt: float, events: bool = True) -> None:
        """InputError unless every block can run at scan time ``dt`` (``Block.check_dt``),
        with its parameters now and, with ``events``, after each parameter event still to
        come (a dead time an event lengthens beyond the delay line), applied in time order
        to interpreted copies, each such failure naming its event."""
        for block in self.blocks.values():
            block.check_dt(dt)
        if not events:
            return
        trials: dict[str, Block] = {}
        for ev in self.events[self._next_event:]:
            if not self._is_parameter(ev.target):
                continue
            owner, name = _split(ev.target, "event")
            if owner not in trials:
                b = self.blocks[owner]
                trials[owner] = type(b)(jit=False, **b.given)
            trials[owner].set_params(**{name: ev.value})
            try:
                trials[owner].check_dt(dt)
            except LoopworksError as exc:
                raise InputError(f"event at t = {ev.t:g} s, set = '{ev.target}': {exc}"
                                 ) from None

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
                b, key = self.blocks[block], name.lower()
                before = b.params[key]
                b.set_params(**{name: ev.value})
                first = self._undo.get((block, key))
                self._undo[(block, key)] = (before if first is None else first[0],
                                            b.params[key])
            else:
                self.blocks[block].set_inputs({name: ev.value})
            self._next_event += 1

    def scan(self, dt: float) -> None:
        """Run every block once, in order, at the module's current time; then advance it.

        A compiled module runs the scan as one call of its plan (:meth:`run`'s ``scans``
        entry, recording nothing), so a scan loop from Python (a relay test, a live
        controller) loads one compiled plan instead of one entry per block."""
        self._check_blocks()
        if not self.compiled:
            self._scan_blocks(dt)
            return
        self._apply_events(self.t)
        if self._scans is None:
            self._scans = ("scans", entry(self._slots, "scans", SCANS_SIGNATURE,
                                          self._usual_record()))
        self._scans[1](self._F, self._S, dt, self.t, self.k, 1, _T1, _NO_F, _NO_S, _NO_I,
                       _NO_I, 0)
        self.k += 1
        self.t = self.k * dt

    def _scan_blocks(self, dt: float) -> None:
        """:meth:`scan` block by block from Python (the reference plan): each block
        interpreted or through its own compiled step."""
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
            progress: Callable[[int, int], None] | None = None,
            plan: str = "auto", record: Sequence[str] | None = None) -> SimResult:
        """Run ``duration`` seconds in scans of ``dt``; scan k executes at t = k·dt.

        ``plan``: ``"compiled"`` runs the module's generated plan (compiled once per machine,
        then loaded from the cache, :mod:`loopworks.blocks.plan`); ``"python"`` runs block by
        block from Python (the reference; each block interpreted or through its own compiled
        step); ``"auto"`` (default) takes the compiled plan when every block is compiled
        (``jit``) and the plan is cached or the run has at least ``PLAN_MIN_BLOCK_SCANS``
        block-scans; ``"fused"`` is the compiled plan with every kernel inlined, compiled now
        if it is not cached (seconds to a minute, once per module shape: worth it for a module
        run many times; "compiled" and "auto" take it once it is cached, or for a run of
        ``PLAN_FUSE_BLOCK_SCANS``). All four give the same numbers.

        With ``reset=False`` the run continues from the current state (and time), so a run can
        be split, saved with :meth:`state_dict` and resumed. ``record``: the signals
        (``"block.port"``) the result holds; default every input and output. A run whose
        record (:meth:`record_bytes`) would not fit in memory is refused before its first
        scan.
        """
        self._check_blocks()
        n = scan_count(duration, dt)
        names = self.signals()
        if record is None:
            chosen = list(range(len(names)))
        else:
            where = {name: i for i, name in enumerate(names)}
            unknown = [r for r in record if r not in where]
            if unknown:
                raise InputError(f"record: no signal '{unknown[0]}'; signals: "
                                 + ", ".join(names))
            chosen = sorted({where[r] for r in record})
        rows, how = self.record_plan(chosen)
        check_record_size(len(rows) * (n + 1) * RECORD_BYTES, duration, dt, n)
        if reset:
            self.reset()
        self.check_dt(dt)
        # T[k + 1] is the time of scan k; row r of RF/RS is signal rows[r], column 0 before
        # the first scan and column k + 1 after scan k (record_plan): each signal's record is
        # a contiguous array, handed out as a view
        T = np.empty(n + 1)
        rec_f, rec_s = self._rec_f[rows], self._rec_s[rows]
        RF = np.empty((len(rows), n + 1))
        RS = np.empty((len(rows), n + 1), dtype=np.uint8)
        RF[:, 0] = self._F[rec_f]
        RS[:, 0] = self._S[rec_s]
        if plan not in ("auto", "compiled", "fused", "python"):
            raise InputError(f"plan = {plan!r} is not allowed: expected auto, compiled, fused "
                             f"or python")
        if plan in ("compiled", "fused") and not self.compiled:
            raise InputError(f"plan = {plan!r} needs every block compiled (jit); blocks "
                             + ", ".join(n for n, b in self.blocks.items() if not b.jit)
                             + " are interpreted")
        if plan in ("compiled", "fused") or (plan == "auto" and self.compiled and (
                n * len(self.blocks) >= PLAN_MIN_BLOCK_SCANS
                or is_cached(self._slots, "scans", self._usual_record())
                or is_cached(self._slots, "fused", self._usual_record()))):
            self._run_compiled(n, dt, T, RF, RS, rec_f, rec_s, progress, plan == "fused")
        else:
            self._run_python(n, dt, T, RF, RS, rec_f, rec_s, progress)
        # a record is evidence, and a row may be two signals' record: read-only
        for array in (T, RF, RS):
            array.flags.writeable = False
        values: dict[str, np.ndarray] = {}
        status: dict[str, np.ndarray] = {}
        for i, (what, r) in zip(chosen, how, strict=True):
            if what == "const":
                values[names[i]] = np.broadcast_to(self._F[self._rec_f[i]], (n,))
                status[names[i]] = np.broadcast_to(np.uint8(self._S[self._rec_s[i]]), (n,))
            else:
                cols = slice(1, n + 1) if what == "row" else slice(0, n)
                values[names[i]] = RF[r, cols]
                status[names[i]] = RS[r, cols]
        return SimResult(t=T[1:], values=values, status=status,
                         kinds={n: self.blocks[n].kind for n in self.order},
                         wires=dict(self.wires), out_spans=self.out_spans(),
                         incremental=self.incremental_outputs())

    def _run_python(self, n: int, dt: float, t: np.ndarray, RF: np.ndarray, RS: np.ndarray,
                    rec_f: np.ndarray, rec_s: np.ndarray,
                    progress: Callable[[int, int], None] | None) -> None:
        """The reference: one :meth:`scan` per scan from Python (interpreted blocks); scan k
        recorded in column k + 1 of ``t``, RF and RS."""
        every = max(1, n // 100)
        for k in range(n):
            t[k + 1] = self.t
            self._scan_blocks(dt)
            RF[:, k + 1] = self._F[rec_f]
            RS[:, k + 1] = self._S[rec_s]
            if progress is not None and (k % every == 0 or k == n - 1):
                progress(k + 1, n)

    def _next_event_scan(self, dt: float) -> int | None:
        """The scan count at which the next pending event applies (``_apply_events``'s rule:
        the first scan k with t_k = k·dt >= t_event - 1e-9), or None."""
        if self._next_event >= len(self.events):
            return None
        te = self.events[self._next_event].t
        k = max(self.k, math.ceil((te - 1e-9) / dt))
        while k > self.k and te <= (k - 1) * dt + 1e-9:
            k -= 1
        while te > (self.t if k == self.k else k * dt) + 1e-9:
            k += 1
        return k

    def _run_compiled(self, n: int, dt: float, t: np.ndarray, RF: np.ndarray, RS: np.ndarray,
                      rec_f: np.ndarray, rec_s: np.ndarray,
                      progress: Callable[[int, int], None] | None,
                      fuse: bool = False) -> None:
        """The compiled plan, in chunks: events are applied between chunks (a parameter
        change recomputes the coefficients once), and progress is reported per chunk."""
        usual = self._usual_record()
        what = "fused" if (fuse or n * len(self.blocks) >= PLAN_FUSE_BLOCK_SCANS
                           or is_cached(self._slots, "fused", usual)) else "scans"
        if self._scans is None or self._scans[0] != what:
            self._scans = (what, entry(self._slots, what, SCANS_SIGNATURE, usual))
        scans = self._scans[1]
        every = max(1, n // 100) if progress is not None else n
        done = 0
        while done < n:
            self._apply_events(self.t)
            stop = min(n, done + every)
            k_event = self._next_event_scan(dt)
            if k_event is not None:
                stop = min(stop, done + max(1, k_event - self.k))
            m = stop - done
            scans(self._F, self._S, dt, self.t, self.k, m, t, RF, RS, rec_f, rec_s,
                  done + 1)
            self.k += m
            self.t = self.k * dt
            done = stop
            if progress is not None:
                progress(done, n)

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
