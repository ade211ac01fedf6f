"""``loopworks serve``: the controller side of a scenario run live, a small soft DCS controller.

Each scan (absolute deadlines, :mod:`loopworks.live.schedule`):

1. read the device's outputs over Modbus (:mod:`loopworks.live.modbus_io`), or from an
   OPC UA server (:mod:`loopworks.live.opcua_io`: an ``[io]`` table with
   ``protocol = "opcua"``, or ``--device opc.tcp://...``); a failed read makes them Bad, no
   communication, holding the last value; with a ``poll_period`` in the map, the device is
   read every that many seconds only and the last values (and statuses) held in between;
2. hand them to the controller blocks' inputs with their statuses and run one scan of the
   controller module (the same blocks, kernels and events as ``loopworks simulate``): the
   blocks do what their vendor does with a Bad PV (the DeltaV PID's actual mode goes to MAN
   and OUT is held; it returns to its target mode when the PV is Good again);
3. write the controller outputs to the device (read back and compared next scan);
4. publish every loop's PV, SP, OUT, MODE, tuning and scan statistics on the OPC UA server
   (:mod:`loopworks.live.opcua`), whose operators' writes come back through
   :meth:`LiveController.write`, validated and logged; SP is the setpoint the controller
   works to (:meth:`LiveController.working_sp`), MODE and MODE_ACTUAL the block's modes
   translated by name to the server's codes (``MODES``) and back (:func:`mode_names`);
5. every ``checkpoint_every`` scans, after every accepted operator write and on shutdown,
   save the controller state (``Module.state_dict``) to the checkpoint file; a controller
   started on an existing checkpoint of the same module resumes from it, so OUT continues
   without a bump (parameters the checkpoint holds at other values than the scenario file
   are kept, and named in one warning line).

A loop is a controller block (a kind that declares its roles, :mod:`loopworks.blocks.controller`),
named after the block. A loop whose output feeds a block of the controller side that is not
a controller (a stiction compensator, ``compensator.signal_in = pid.out``) shows that block's
state as read-only ``COMP_<PORT>`` variables: its outputs (COMP_SIGNAL_OUT,
COMP_DITHER_DELT, COMP_KICKER_DELT ...) and its unwired inputs (COMP_START ...), for the faceplate.
"""

from __future__ import annotations

import asyncio
import contextlib
import hashlib
import json
import logging
import math
import os
import re
import tempfile
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from loopworks.blocks import status as st
from loopworks.blocks.block import Block, _same
from loopworks.blocks.controller import Controller
from loopworks.errors import InputError, LoopworksError
from loopworks.live.opcua import MODES, Variable, WriteRefused
from loopworks.live.registers import RegisterMap
from loopworks.live.schedule import ScanStats, Scheduler
from loopworks.live.split import Split
from loopworks.live.tasks import cancel_and_wait
from loopworks.sim.module import Module

log = logging.getLogger("loopworks.serve")

#: modes an operator may not request (FF: IMan and LO are set by the block itself)
NOT_REQUESTABLE = ("IMAN", "LO")
#: scans between checkpoints (default)
CHECKPOINT_EVERY = 10
#: a scale or span parameter (pv_scale_eu_0, out_scale_eu_100, ...): it sets what PV, SP and
#: OUT mean, so it is written in OOS only (Fieldbus; spec vendor-blocks 4.1, 4.9)
_SCALE = re.compile(r"(^|_)(scale|span)(_|$)")


@dataclass
class Loop:
    """One controller block seen as a loop: its block and the ports of its roles."""

    name: str
    block: Block
    pv: str
    sp: str
    out: str
    mode: str | None
    man_out: str | None
    tuning: list[str] = field(default_factory=list)
    #: the block fed by the loop's output (a compensator), and its ports shown as COMP_<PORT>
    compensator: str | None = None
    comp_ports: list[tuple[str, bool]] = field(default_factory=list)  # (port, is an output)
    #: the names of the mode input's codes (index = the block's code): ``mode_names``
    modes: tuple[str, ...] = ()


def _compensator(module: Module, loop: str, out: str) -> tuple[str | None,
                                                             list[tuple[str, bool]]]:
    """The first block (in scan order) wired from ``loop.out`` that is not a controller, and
    its ports to show: every output, then every input no wire feeds."""
    fed = {dest.split(".", 1)[0] for dest, src in module.wires.items()
           if src == f"{loop}.{out}"}
    for name in module.order:
        block = module.blocks[name]
        if name not in fed or isinstance(block, Controller):
            continue
        ports = [(p.name, True) for p in block.OUTPUTS]
        seen = {p for p, _ in ports}
        ports += [(p.name, False) for p in block.INPUTS
                  if f"{name}.{p.name}" not in module.wires and p.name not in seen]
        return name, ports
    return None, []


def _comp_name(port: str) -> str:
    """The variable of a compensator's port: COMP_SIGNAL_OUT, COMP_START (comp_start)."""
    return "COMP_" + port.upper().removeprefix("COMP_")


def is_scale(param: str) -> bool:
    """True for a scale or span parameter (``pv_scale_eu_100``, ``out_span``): it sets what
    PV, SP and OUT mean, so an operator writes it in OOS only."""
    return _SCALE.search(param.lower()) is not None


def mode_names(block: Block, port: str) -> tuple[str, ...]:
    """The names of a mode input's codes, index = code: its choices (``pid``: MAN, AUTO, CAS;
    ``deltav.pid``: OOS, IMAN, LO, MAN, AUTO, CAS), or, for a switch without names (GE's
    MAN input, 1 = Manual), AUTO and MAN at the codes the controller's ``AUTOMATIC`` and
    ``MANUAL`` give it; () when neither says."""
    spec = block.INPUTS[block._in_index[port]]
    if spec.choices:
        return tuple(c.upper() for c in spec.choices)
    cls = type(block)
    named: dict[int, str] = {}
    for mode, table in (("AUTO", getattr(cls, "AUTOMATIC", {})),
                        ("MAN", getattr(cls, "MANUAL", {}))):
        code = table.get(port)
        if (isinstance(code, int | float) and not isinstance(code, bool) and 0 <= code < 8
                and code == int(code)):
            named[int(code)] = mode
    return tuple(named.get(i, "") for i in range(max(named) + 1)) if named else ()


def _loops(module: Module) -> list[Loop]:
    loops = []
    for name in module.order:
        block = module.blocks[name]
        if not isinstance(block, Controller):
            continue
        roles = type(block).ROLES
        modes = mode_names(block, roles.mode) if roles.mode is not None else ()
        tuning = [p for p in type(block).LAW_PARAMS
                  if p in block.params and type(block.params[p]) in (int, float)
                  and ("OOS" in modes or not is_scale(p))]  # a scale: in OOS only
        comp, ports = _compensator(module, name, roles.out)
        loops.append(Loop(name, block, roles.pv, roles.sp, roles.out,
                          roles.mode if modes else None, roles.man_out, tuning, comp, ports,
                          modes))
    return loops


def _published_mode(names: tuple[str, ...], code: float) -> tuple[int, int]:
    """(code of ``MODES``, status byte): how the MODE node publishes a block's mode code
    whose names are ``names``, translated by name (the generic pid's AUTO, its code 1, is
    MODES' 4); a code without a name of MODES is published Bad (configuration error), never
    as another mode."""
    if code == int(code) and 0 <= int(code) < len(names) and names[int(code)] in MODES:
        return MODES.index(names[int(code)]), st.GOOD_NC
    return 0, st.BAD_CONFIGURATION_ERROR


def _input(block: Block, port: str) -> tuple[float, int]:
    i = block._in_index[port]
    return float(block.u[i]), int(block.us[i])


def _output(block: Block, port: str) -> tuple[float, int]:
    i = block._out_index[port]
    return float(block.y[i]), int(block.ys[i])


def layout_key(module: Module) -> str:
    """A hash of a module's shape (block names, kinds, order, wires): a checkpoint loads only
    into the module it was saved from."""
    shape = {"order": module.order, "kinds": {n: b.kind for n, b in module.blocks.items()},
             "wires": module.wires}
    return hashlib.sha256(json.dumps(shape, sort_keys=True).encode()).hexdigest()[:16]


def read_checkpoint(path: Path, module: Module) -> dict[str, Any]:
    """The checkpoint at ``path`` for the controller ``module``; InputError when it is not
    one, or is another module's (``serve`` checks it before its device starts: on a wrong
    checkpoint it ran the built-in device for a hundred scans before the error; found by an
    outside audit)."""
    try:
        saved = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise InputError(f"{path}: not a loopworks checkpoint ({exc})") from None
    key = layout_key(module)
    if not isinstance(saved, dict) or saved.get("layout") != key:
        layout = saved.get("layout") if isinstance(saved, dict) else None
        raise InputError(f"{path}: the checkpoint is of another controller module "
                         f"(layout {layout!r}, this one {key!r}); remove it or give another "
                         "--state-dir")
    return saved


def _atomic_write(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _requested_mode(value: Any) -> str:
    """The name of a mode an operator requested: a code of the OPC UA MODE node (``MODES``:
    0 OOS .. 5 CAS) or a name; WriteRefused(BadOutOfRange) for anything else."""
    if isinstance(value, str) and value.strip().upper() in MODES:
        return value.strip().upper()
    if (isinstance(value, int | float) and not isinstance(value, bool) and value == int(value)
            and 0 <= value < len(MODES)):
        return MODES[int(value)]
    raise WriteRefused("BadOutOfRange", f"mode {value!r}: expected a code 0..{len(MODES) - 1} "
                       f"or a name of {', '.join(MODES)}")


def _units(unit: str) -> str:
    """A block's declared unit as an operator reads it: the generic ``pv`` and ``out`` (the
    PV's and the output's own units) named so, the others as declared."""
    return {"pv": "PV units", "out": "output units", "out/pv": "output units/PV unit"}.get(
        unit, unit)


def _overridden(module: Module, saved: Mapping[str, Any]) -> list[str]:
    """The parameters a checkpoint ``saved`` (``Module.state_dict``) sets to another value
    than ``module``'s (the scenario file's), as ``block.param = saved (file value)``."""
    kept = []
    for name, block in module.blocks.items():
        given = (saved.get("blocks", {}).get(name) or {}).get("params") or {}
        for param, value in given.items():
            file_value = block.given.get(param, block.params.get(param))
            # the file's value, or the block's default where the file gives none (an
            # operator's write of the default overrides nothing)
            if not _same(file_value, value) and not _same(block.params.get(param), value):
                kept.append(f"{name}.{param} = {value!r} (file: "
                            f"{block.params.get(param)!r})")
    return kept


class LiveController:
    """The controller module of ``split`` scanned live (module docstring). ``io`` is the
    device I/O (:class:`~loopworks.live.modbus_io.ModbusIO` or anything with its ``read``,
    ``write`` and ``status``)."""

    def __init__(self, split: Split, regmap: RegisterMap | Sequence[RegisterMap], io: Any, *,
                 checkpoint: Path | None = None,
                 checkpoint_every: int = CHECKPOINT_EVERY) -> None:
        maps = [regmap] if isinstance(regmap, RegisterMap) else list(regmap)
        self.split = split
        self.module = split.controller
        self.dt = split.dt
        self.regmaps = maps
        self.io = io
        self.by_name = {loop.name: loop for loop in _loops(self.module)}
        if not self.by_name:
            raise InputError("the controller side has no controller block to serve")
        # controller input "pid.pv" <- device point "sensor.pv"; device point "valve.op" <-
        # controller output "compensator.signal_out"
        self.reads = [(dest, src) for dest, src in split.to_controller]
        self.writes = [(point, src) for point, src in split.to_plant]
        #: the device points the last scan's write left unwritten (:meth:`out`)
        self.unwritten: set[str] = set()
        names = {p.name for m in maps for p in m.points}
        missing = [n for n in [s for _, s in self.reads] + [p for p, _ in self.writes]
                   if n not in names]
        if missing:
            raise InputError(f"the register map has no point for {', '.join(missing)}; points: "
                             + ", ".join(sorted(names)))
        self.checkpoint = checkpoint
        self.checkpoint_every = checkpoint_every
        #: scans between reads of the device (the map's poll_period, 1: every scan; several
        #: devices are polled each at its own period by their I/O, loopworks.live.devices)
        self.poll_every = (1 if len(maps) != 1 or maps[0].poll_period is None
                           else max(1, round(maps[0].poll_period / self.dt)))
        self._values: dict[str, tuple[float, int]] | None = None
        self.stats = ScanStats(self.dt)
        self.resumed = False
        self.scans = 0
        self.key = layout_key(self.module)
        if checkpoint is not None and checkpoint.exists():
            self._resume(checkpoint)

    # -- checkpoints ---------------------------------------------------------------------

    def _resume(self, path: Path) -> None:
        saved = read_checkpoint(path, self.module)
        kept = _overridden(self.module, saved["module"])
        self.module.load_state(saved["module"])
        if kept:
            log.warning("%s: the checkpoint's parameters differ from the scenario file's and "
                        "are kept (an operator's retuning, or an edited file: remove the "
                        "checkpoint to start from the file): %s", path, "; ".join(kept))
        self.scans = int(saved.get("scans", 0))
        self.resumed = True
        log.info("resumed from checkpoint %s at scan %d (t = %.3f s)", path, self.scans,
                 self.module.t)

    def save(self) -> None:
        """Write the checkpoint now (atomically)."""
        if self.checkpoint is None:
            return
        state = {"layout": self.key, "scans": self.scans, "saved": time.time(),
                 "module": self.module.state_dict()}
        _atomic_write(self.checkpoint, json.dumps(state))

    # -- one scan ------------------------------------------------------------------------

    async def scan(self, k: int = 0) -> None:
        """One live scan (module docstring, 1-5 except publishing)."""
        if self._values is None or self.scans % self.poll_every == 0:
            self._values = await self.io.read()
        values = self._values
        for dest, src in self.reads:
            block, port = dest.split(".", 1)
            self.module.blocks[block].set_inputs({port: self._in_range(block, port,
                                                                       values[src])})
        self.module.scan(self.dt)
        out: dict[str, float] = {}
        for point, src in self.writes:
            block, port = src.split(".", 1)
            out[point] = _output(self.module.blocks[block], port)[0]
        # the points a failed write left unwritten (the I/O's own list where it has one, else
        # all): the loops that feed them publish OUT Bad, no communication
        ok = await self.io.write(out)
        self.unwritten = set() if ok else set(getattr(self.io, "unwritten", out))
        self.scans += 1
        if self.checkpoint is not None and self.scans % self.checkpoint_every == 0:
            self.save()

    def _in_range(self, block: str, port: str, value: tuple[float, int]) -> tuple[float, int]:
        """``value`` for a loop's PV input, Uncertain with the limit bit of its side (EU
        range violation, 0x55/0x56) when a Good reading lies outside the controller's PV
        range (:meth:`Controller.pv_range`; runtime-and-ecosystem 2d): a device sending
        150 on a 0..100 scale, or a word order that makes a huge number of two registers,
        was used and published Good (found by an outside audit)."""
        loop = self.by_name.get(block)
        v, status = value
        if loop is None or port != loop.pv or status & 0xC0 != st.GOOD_NC \
                or not math.isfinite(v):
            return value
        ctrl = loop.block
        assert isinstance(ctrl, Controller)  # a loop is a controller block (_loops)
        span = type(ctrl).pv_range(ctrl.params)
        if span is None or span[0] <= v <= span[1]:
            return value
        return v, st.UNCERTAIN_EU_RANGE_VIOLATION | (st.HIGH_LIMITED if v > span[1]
                                                     else st.LOW_LIMITED)

    # -- what the OPC UA server shows ------------------------------------------------------

    def variables(self, loop: Loop) -> list[Variable]:
        b = loop.block
        # each value in the units its block declares (GE's and S5's counts, DeltaV's EU; the
        # generic pid works in its PV's and output's own units): all were "% of PV span"
        pv_unit = _units(b.INPUTS[b._in_index[loop.pv]].unit)
        out_unit = _units(b.OUTPUTS[b._out_index[loop.out]].unit)
        params = {p.name: p for p in b.PARAMS}
        # OUT is written in MAN: a block without a mode to put in MAN (E2) takes no OUT (it
        # was advertised writable and every write refused)
        manual = loop.mode is not None and loop.man_out is not None
        out: list[Variable] = [
            Variable("PV", _input(b, loop.pv)[0], "double", False, pv_unit,
                     "process variable as the controller reads it"),
            Variable("SP", self.working_sp(loop)[0], "double", True, pv_unit,
                     "working setpoint (writable by an operator, not while it comes from "
                     "a cascade input)"),
            Variable("OUT", _output(b, loop.out)[0], "double", manual, out_unit,
                     "controller output (writable by an operator in MAN)" if manual else
                     "controller output (this block has no manual mode to write it in)"),
        ]
        if loop.mode is not None:
            out.append(Variable("MODE", self.mode(loop)[0], "mode", True, "",
                                "target mode (writable by an operator): "
                                + ", ".join(m for m in loop.modes
                                            if m and m not in NOT_REQUESTABLE)))
        if "mode_actual" in b._out_index:
            out.append(Variable("MODE_ACTUAL", self.mode_actual(loop)[0], "mode", False,
                                "", "actual mode, as the block computed it"))
        for name in loop.tuning:
            out.append(Variable(name.upper(), float(b.params[name]), "double", True,
                                _units(params[name].unit) if name in params else "",
                                f"tuning parameter {name}"
                                + (" (written in OOS only)" if is_scale(name) else "")))
        for name in ("SCANS", "OVERRUNS", "LATE_P99_MS", "LATE_MAX_MS", "COMM_ERRORS",
                     "READBACK_MISMATCHES"):
            out.append(Variable(name, 0.0, "double", False, "", "scan statistics"))
        if loop.compensator is not None:
            cb = self.module.blocks[loop.compensator]
            for port, output in loop.comp_ports:
                spec = (cb.OUTPUTS[cb._out_index[port]] if output
                        else cb.INPUTS[cb._in_index[port]])
                value = (_output(cb, port) if output else _input(cb, port))[0]
                out.append(Variable(_comp_name(port), value, "double", False,
                                    spec.unit, f"compensator {loop.compensator} "
                                    f"({cb.kind}) {'output' if output else 'input'} {port}: "
                                    f"{spec.meaning}"))
        return out

    def loops(self) -> dict[str, list[Variable]]:
        """Every loop's variables (the OPC UA server's ``controller.loops()``)."""
        return {name: self.variables(loop) for name, loop in self.by_name.items()}

    def snapshot(self) -> dict[str, tuple[float, int]]:
        """Every loop variable's value and Fieldbus status byte, keyed ``loop.NAME``."""
        stats = self.stats.summary()
        io = self.io.status()
        snap: dict[str, tuple[float, int]] = {}
        for name, loop in self.by_name.items():
            b = loop.block
            snap[f"{name}.PV"] = _input(b, loop.pv)
            snap[f"{name}.SP"] = self.working_sp(loop)
            snap[f"{name}.OUT"] = self.out(loop)
            if loop.mode is not None:
                snap[f"{name}.MODE"] = self.mode(loop)
            if "mode_actual" in b._out_index:
                snap[f"{name}.MODE_ACTUAL"] = self.mode_actual(loop)
            for p in loop.tuning:
                snap[f"{name}.{p.upper()}"] = (float(b.params[p]), st.GOOD_NC)
            for key, value in (("SCANS", stats["scans"]), ("OVERRUNS", stats["overruns"]),
                               ("LATE_P99_MS", stats["late_p99_ms"]),
                               ("LATE_MAX_MS", stats["late_max_ms"]),
                               ("COMM_ERRORS", io["read_errors"] + io["write_errors"]),
                               ("READBACK_MISMATCHES", io["readback_mismatches"])):
                snap[f"{name}.{key}"] = (float(value), st.GOOD_NC)
            if loop.compensator is not None:
                cb = self.module.blocks[loop.compensator]
                for port, output in loop.comp_ports:
                    spec = (cb.OUTPUTS[cb._out_index[port]] if output
                            else cb.INPUTS[cb._in_index[port]])
                    v, s = _output(cb, port) if output else _input(cb, port)
                    snap[f"{name}.{_comp_name(port)}"] = (v, s if spec.status else st.GOOD_NC)
        return snap

    def out(self, loop: Loop) -> tuple[float, int]:
        """OUT as published: the controller's output and status, the status Bad (no
        communication, last usable value) while a device point the loop feeds (through its
        compensator too) was not written on the last scan: the valve does not get it, and an
        operator must not read it as Good."""
        value, status = _output(loop.block, loop.out)
        feeds = {loop.name, loop.compensator}
        if any(src.split(".", 1)[0] in feeds for point, src in self.writes
               if point in self.unwritten):
            return value, st.BAD_NO_COMM_LUV
        b = loop.block
        if "ok" in b._out_index and _output(b, "ok")[0] < 0.5:
            # GE's ok OFF: the PID is not solving (a parameter pair the PLC refuses, a
            # setpoint beyond its word, power flow off) and CV holds (spec vendor-blocks
            # 1.7 steps 1-2): an operator must not read a held CV as a working loop
            return value, st.BAD_CONFIGURATION_ERROR
        return value, status

    def mode(self, loop: Loop) -> tuple[int, int]:
        """The loop's target mode as the OPC UA MODE node publishes it: (code of ``MODES``,
        status byte), translated from the block's own code by name (``_published_mode``)."""
        assert loop.mode is not None
        return _published_mode(loop.modes, _input(loop.block, loop.mode)[0])

    def mode_actual(self, loop: Loop) -> tuple[int, int]:
        """The block's ``mode_actual`` output as MODE_ACTUAL publishes it (as :meth:`mode`)."""
        b = loop.block
        spec = b.OUTPUTS[b._out_index["mode_actual"]]
        return _published_mode(tuple(c.upper() for c in spec.choices),
                                _output(b, "mode_actual")[0])

    def _mode_name(self, loop: Loop, actual: bool = False) -> str:
        """The name of the loop's target (or actual) mode, "" when it has none."""
        if actual and "mode_actual" in loop.block._out_index:
            code, status = self.mode_actual(loop)
        elif loop.mode is not None:
            code, status = self.mode(loop)
        else:
            return ""
        return MODES[code] if status == st.GOOD_NC else ""

    def working_sp(self, loop: Loop) -> tuple[float, int]:
        """The setpoint the controller works to, as SP publishes it: its ``working_sp`` role
        output where it has one (deltav.pid: after limits, ramp and filter, CAS_IN in Cas),
        else the input its ``setpoint_input`` names for its current inputs (the generic
        pid's ``cas_sp`` in CAS), never an unused local SP."""
        b = loop.block
        assert isinstance(b, Controller)
        roles = type(b).ROLES
        if roles.working_sp is not None:
            return _output(b, roles.working_sp)
        value, status = _input(b, self._setpoint_input(loop))
        if not math.isfinite(value) and status & 0xC0 != st.BAD:
            return value, st.BAD_NOT_CONNECTED  # no value is no Good one
        return value, status

    def _setpoint_input(self, loop: Loop) -> str:
        """The input the loop's controller takes its setpoint from now (``setpoint_input``)."""
        b = loop.block
        assert isinstance(b, Controller)
        values = {p.name: float(b.u[i]) for i, p in enumerate(b.INPUTS)}
        return type(b).setpoint_input(values)

    def _unfed_setpoint(self, loop: Loop, code: float) -> str | None:
        """The input the setpoint would come from in the mode of ``code`` when that is not the
        operator's SP and no wire feeds it (the generic pid's ``cas_sp`` in CAS: it read NaN,
        published as SP with a Good status; found by an outside audit), else None. A block
        with a working setpoint of its own (DeltaV: CAS_IN not connected keeps it in AUTO,
        spec vendor-blocks 4.5) decides that itself."""
        b = loop.block
        assert isinstance(b, Controller)
        if type(b).ROLES.working_sp is not None or loop.mode is None:
            return None
        values = {p.name: float(b.u[i]) for i, p in enumerate(b.INPUTS)}
        values[loop.mode] = code
        port = type(b).setpoint_input(values)
        fed = {dest for dest, _ in self.reads} | set(self.module.wires)
        if port == loop.sp or f"{loop.name}.{port}" in fed:
            return None
        return port

    def _sp_elsewhere(self, loop: Loop) -> str | None:
        """Why an operator's SP would not be used now, None when it would: the setpoint
        comes from another input (the generic pid's ``cas_sp`` in CAS), or the block's actual
        mode is CAS (DeltaV: SP = CAS_IN, an SP write is not taken; spec vendor-blocks 4.5)."""
        port = self._setpoint_input(loop)
        if port != loop.sp:
            return (f"the setpoint comes from input {port} in mode "
                    f"{self._mode_name(loop) or '?'}")
        if self._mode_name(loop, actual=True) == "CAS":
            return "the setpoint comes from the cascade input while the actual mode is CAS"
        return None

    def write(self, user: str | None, role: str | None, loop: str, name: str,
              value: Any) -> None:
        """An operator's write, validated by the block's own rules; raises
        :class:`~loopworks.live.opcua.WriteRefused` with the OPC UA status code when refused.
        Every write is logged, accepted or not. An accepted write is saved in the checkpoint
        at once (when there is one), so a controller restarted from it keeps the change."""
        try:
            self._write(role, loop, name, value)
        except WriteRefused as exc:
            log.warning("write refused: user %s, %s.%s = %r: %s (%s)", user, loop, name, value,
                        exc.message, exc.code)
            raise
        log.info("write accepted: user %s, %s.%s = %r", user, loop, name, value)
        try:
            self.save()
        except OSError as exc:  # the write stands; the operator's log says it is not saved
            log.error("write %s.%s = %r by %s is applied but not saved in the checkpoint %s "
                      "(%s): a restart before the next checkpoint would lose it", loop, name,
                      value, user, self.checkpoint, exc)

    def _write(self, role: str | None, loop_name: str, name: str, value: Any) -> None:
        if role != "operator":
            raise WriteRefused("BadUserAccessDenied",
                               "writes need a logged-in user with the operator role")
        loop = self.by_name.get(loop_name)
        if loop is None:
            raise WriteRefused("BadNodeIdUnknown", f"no loop {loop_name!r}")
        b = loop.block
        name = name.upper()
        if name == "MODE" and loop.mode is not None:
            mode = _requested_mode(value)
            if mode not in loop.modes:
                allowed = [m for m in loop.modes if m and m not in NOT_REQUESTABLE]
                raise WriteRefused("BadOutOfRange", f"mode {mode}: this {b.kind} block has "
                                   f"the modes {', '.join(allowed)}")
            if mode in NOT_REQUESTABLE:
                raise WriteRefused("BadOutOfRange", f"mode {mode} cannot be requested (the "
                                   "block sets it itself)")
            unfed = self._unfed_setpoint(loop, float(loop.modes.index(mode)))
            if unfed is not None:
                raise WriteRefused("BadInvalidState", f"mode {mode}: the setpoint would come "
                                   f"from input {unfed}, which nothing feeds (not wired)")
            b.set_inputs({loop.mode: float(loop.modes.index(mode))})
            if mode != "MAN" and loop.man_out is not None:
                # a manual output written as a program write each scan (GE's Manual Command,
                # NaN = no write) ends with manual: latched, it kept rewriting word 14 in
                # Auto, which no longer tracked CV, and the next Manual jumped to it
                port = next(p for p in b.INPUTS if p.name == loop.man_out)
                if math.isnan(port.default):
                    b.set_inputs({loop.man_out: math.nan})
            return
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise WriteRefused("BadTypeMismatch", f"{name} takes a number, not {value!r}")
        v = float(value)
        # a tuning parameter's own range says whether inf is a value (RESET = inf: no
        # integral action, refused here before; found by an outside audit); NaN never is
        tuning = name.lower() in loop.tuning
        if math.isnan(v) or (math.isinf(v) and not tuning):
            raise WriteRefused("BadOutOfRange", f"{name} = {v!r} is not finite")
        if name == "SP":
            elsewhere = self._sp_elsewhere(loop)
            if elsewhere is not None:
                raise WriteRefused("BadInvalidState", f"SP is not written now: {elsewhere} "
                                   "(set the target mode to AUTO to write SP)")
            word = type(b).SP_WORD if isinstance(b, Controller) else None
            if word is not None and not (v == round(v) and word[0] <= v <= word[1]):
                raise WriteRefused("BadOutOfRange", f"SP = {v!r}: this controller's setpoint "
                                   f"is a 16-bit word, a whole number of counts in "
                                   f"{word[0]}..{word[1]}")
            lo, hi = self._sp_range(b)
            if not lo <= v <= hi:
                raise WriteRefused("BadOutOfRange", f"SP = {v:g} is outside {lo:g}..{hi:g}")
            b.set_inputs({loop.sp: v})
        elif name == "OUT":
            if loop.mode is None or loop.man_out is None:
                raise WriteRefused("BadNotWritable", "this controller has no manual output")
            mode = self._mode_name(loop)
            if mode != "MAN":
                raise WriteRefused("BadInvalidState", f"OUT is written in MAN only; the "
                                   f"loop's target mode is {mode or '?'}")
            lo, hi = self._out_range(b)
            if not lo <= v <= hi:
                raise WriteRefused("BadOutOfRange", f"OUT = {v:g} is outside the output "
                                   f"limits {lo:g}..{hi:g}")
            if (isinstance(b, Controller) and type(b).SP_WORD is not None
                    and b.params.get("arithmetic") == "native" and v != round(v)):
                # GE's word 14 and S5's YH are 16-bit words: 12345.5 ran as 12346 and was
                # answered Good (found by an outside audit), as an SP of 16000.5 is refused
                raise WriteRefused("BadOutOfRange", f"OUT = {v!r}: this controller's manual "
                                   "output is a 16-bit word in native arithmetic, a whole "
                                   "number of counts")
            b.set_inputs({loop.man_out: v})
        elif name.lower() in loop.tuning:
            if is_scale(name) and self._mode_name(loop) != "OOS":
                raise WriteRefused("BadInvalidState", f"{name} is written in OOS only: a "
                                   "scale sets what PV, SP and OUT mean, so changing it in "
                                   "another mode would bump the output; the loop's target "
                                   f"mode is {self._mode_name(loop) or '?'}")
            key = name.lower()
            before = b.given.get(key, b.params.get(key))
            try:
                b.set_params(**{key: v})
            except LoopworksError as exc:
                raise WriteRefused("BadOutOfRange", str(exc)) from None
            stored = b.stored_params().get(key) if isinstance(b, Controller) else None
            if stored is not None and not math.isclose(float(stored), v, rel_tol=1e-9):
                # published as typed, run as the word holds it (TI 1500 s ran as 1000 s)
                b.set_params(**{key: before})
                raise WriteRefused("BadOutOfRange", f"{name} = {v!r} is not a value the "
                                   f"block's word holds: it would run as {stored!r}; write "
                                   "that, or another value on the word's grid")
        else:
            raise WriteRefused("BadNotWritable", f"{loop_name}.{name} is not writable")

    @staticmethod
    def _out_range(b: Block) -> tuple[float, float]:
        """The range an operator's OUT must respect: the controller's output limits
        (``output_range``), any value when the block takes OUT unlimited in manual
        (DeltaV's ``no_out_limits_manual``, spec vendor-blocks 4.5)."""
        assert isinstance(b, Controller)
        if b.params.get("no_out_limits_manual"):
            return -math.inf, math.inf
        lo, hi = type(b).output_range(b.params)
        return min(lo, hi), max(lo, hi)

    @staticmethod
    def _sp_range(b: Block) -> tuple[float, float]:
        """The setpoint limits an operator's SP must respect: the block's own SP limits
        (SP_LO_LIM / SP_HI_LIM where it has them; unset means the PV scale, DeltaV), else
        its PV scale, else any finite value."""
        p = b.params
        lo, hi = p.get("sp_lo_lim"), p.get("sp_hi_lim")
        e0, e1 = p.get("pv_scale_eu_0"), p.get("pv_scale_eu_100")
        if e0 is not None and e1 is not None:
            s0, s1 = min(float(e0), float(e1)), max(float(e0), float(e1))
            lo = s0 if lo is None else lo
            hi = s1 if hi is None else hi
        return (-math.inf if lo is None else float(lo), math.inf if hi is None else float(hi))


async def run_controller(controller: LiveController, *, speedup: float = 1.0,
                         duration: float | None = None, stop: asyncio.Event | None = None,
                         publish: Callable[[dict[str, tuple[float, int]]], Any] | None = None,
                         before: Callable[[], None] | None = None,
                         watchdog_overruns: int = 3) -> ScanStats:
    """Scan ``controller`` every dt/speedup wall seconds until ``stop`` is set or
    ``duration`` seconds of plant time passed; ``before`` runs at the start of each scan
    (an operator's pending writes); publish each scan's snapshot (``publish`` may be a
    coroutine function); save the checkpoint at the end."""
    if not (math.isfinite(speedup) and speedup > 0.0):
        raise InputError(f"speedup = {speedup!r} is not allowed: it must be > 0 and finite")
    stop = stop or asyncio.Event()

    def watchdog(stats: ScanStats) -> None:
        log.error("watchdog: %d consecutive overruns of the %.3g ms scan (trip %d)",
                  sched.watchdog_overruns, stats.period * 1e3, stats.watchdog_trips)

    sched = Scheduler(controller.dt / speedup, watchdog_overruns=watchdog_overruns,
                      on_watchdog=watchdog)
    controller.stats = sched.stats
    max_scans = None if duration is None else max(1, round(duration / controller.dt))

    async def one(k: int) -> None:
        if before is not None:
            before()
            if stop.is_set():
                return
        await controller.scan(k)
        if publish is not None:
            result = publish(controller.snapshot())
            if asyncio.iscoroutine(result):
                await result

    try:
        return await sched.run(one, stop, max_scans=max_scans)
    finally:
        with contextlib.suppress(OSError):
            controller.save()


def describe(stats: Mapping[str, float | int]) -> str:
    """One line of scan statistics for the console."""
    return (f"{stats['scans']} scans of {stats['period_ms']:.4g} ms, {stats['overruns']} "
            f"overruns; lateness mean {stats['late_mean_ms']:.3g} ms, p99 "
            f"{stats['late_p99_ms']:.3g} ms, max {stats['late_max_ms']:.3g} ms")


@dataclass
class Served:
    """What :func:`serve` ran: the controller, its statistics, the OPC UA endpoint and the
    device address it controlled."""

    controller: LiveController
    stats: dict[str, float | int]
    endpoint: str | None
    device: str


def parse_device(url: str) -> tuple[str, str, int]:
    """(protocol, host, port) of ``modbus://HOST:PORT`` ("modbus", port default 502) or
    ``opc.tcp://HOST:PORT/PATH`` ("opcua", port default 4840)."""
    from urllib.parse import urlparse

    from loopworks.live.registers import check_opcua_url

    parsed = urlparse(url)
    if parsed.scheme == "opc.tcp":
        check_opcua_url(url, "--device")
        return "opcua", str(parsed.hostname), parsed.port or 4840
    if parsed.scheme != "modbus" or not parsed.hostname:
        raise InputError(f"--device {url!r} is not allowed: expected modbus://HOST:PORT "
                         "(for example modbus://127.0.0.1:5020) or opc.tcp://HOST:PORT/PATH")
    try:
        port = parsed.port or 502
    except ValueError:
        raise InputError(f"--device {url!r}: the port must be a number 1..65535") from None
    return "modbus", parsed.hostname, port


def device_of(regmap: RegisterMap, device: str | None) -> str | None:
    """The device URL the controller talks to: ``device`` (``--device``: its scheme picks
    the protocol), else the map's ``url`` (an ``[io]`` table with ``protocol = "opcua"``),
    else None (the scenario's own plant is started as the device)."""
    if device is not None:
        parse_device(device)  # an InputError now
        return device
    return regmap.url


def make_io(regmap: RegisterMap, device: str) -> Any:
    """The controller's I/O to the device at URL ``device``: an
    :class:`~loopworks.live.opcua_io.OpcuaIO` for ``opc.tcp://``, else a
    :class:`~loopworks.live.modbus_io.ModbusIO`."""
    protocol, host, port = parse_device(device)
    if protocol == "opcua":
        from loopworks.live.opcua_io import OpcuaIO

        return OpcuaIO(regmap, device)
    from loopworks.live.modbus_io import ModbusIO

    return ModbusIO(regmap, host, port)


async def close_io(io: Any) -> None:
    """Close ``io``: ``await io.aclose()`` when it has one (OPC UA), else ``io.close()``."""
    aclose = getattr(io, "aclose", None)
    if aclose is not None:
        await aclose()
    else:
        io.close()


async def serve(config: str | Path | None = None, *, device: str | None = None,
                host: str = "127.0.0.1", opcua_port: int | None = 4840,
                users: Path | None = None, speedup: float = 1.0,
                duration: float | None = None, variant: str | None = None,
                state_dir: Path | None = None, stop: asyncio.Event | None = None,
                ready: Callable[[Served], Any] | None = None) -> Served:
    """Run the controller side of scenario ``config`` (None: the built-in scenario) live:
    against the Modbus device at ``device`` (``modbus://HOST:PORT``), or, without one, its
    own plant side started in this process as a device on loopback. ``opcua_port`` None: no
    OPC UA server. The device may also be ``opc.tcp://...`` (or come from an ``[io]`` table
    with ``protocol = "opcua"`` and a ``url``); a table with ``protocol = "opcua"`` and no
    url, without ``device``, serves the built-in device's points on OPC UA as well and
    controls it through them. ``state_dir``: where the checkpoint is kept (default
    ``loopworks-state`` in the current directory). ``ready`` is called once everything
    listens, before the first scan. Returns when ``duration`` s of plant time passed or
    ``stop`` is set."""
    from loopworks.live.registers import map_of
    from loopworks.live.split import split_scenario
    from loopworks.sim.scenario import load_scenario

    sc = load_scenario(config)
    split = split_scenario(sc, variant)
    regmap = map_of(sc, split)
    state = state_dir if state_dir is not None else Path("loopworks-state")
    if (state / "checkpoint.json").exists():  # refused before anything starts
        read_checkpoint(state / "checkpoint.json", split.controller)
    local = None
    local_ua = None
    target = device_of(regmap, device)
    device_task: asyncio.Task[Any] | None = None
    if target is None:
        from loopworks.live.device import Device

        local = Device(split_scenario(sc, variant), regmap, speedup=speedup)
        dport = await local.start("127.0.0.1", 0)
        target = f"modbus://127.0.0.1:{dport}"
        if regmap.protocol == "opcua":
            from loopworks.live.device_opcua import DeviceOpcua

            local_ua = DeviceOpcua(local, "127.0.0.1", 0)
            try:
                target = await local_ua.start()
            except BaseException:
                await local.stop()
                raise
        device_task = asyncio.create_task(local.run())
    io = make_io(regmap, target)
    controller = LiveController(split, regmap, io, checkpoint=state / "checkpoint.json")
    server = None
    endpoint = None
    publish = None
    try:
        if opcua_port is not None:
            from loopworks.live.opcua import LoopServer
            from loopworks.live.users import load_users

            server = LoopServer(controller, load_users(users) if users else None, host=host,
                                port=opcua_port, certificate_dir=state / "pki")
            endpoint = await server.start()
            publish = server.publish
        served = Served(controller, controller.stats.summary(), endpoint, target)
        if ready is not None:
            ready(served)
        stats = await run_controller(controller, speedup=speedup, duration=duration,
                                     stop=stop, publish=publish)
        served.stats = stats.summary()
        return served
    finally:
        if server is not None:
            await server.stop()
        await close_io(io)
        if local_ua is not None:
            await local_ua.stop()
        if local is not None:
            await local.stop()
        if device_task is not None:
            with contextlib.suppress(Exception):
                await cancel_and_wait(device_task)
