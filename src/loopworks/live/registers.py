"""Modbus register maps: which holding registers carry which plant signal, and how.

Modbus has 16-bit registers and no types: a float32 takes two registers, and devices differ
in the order of its four bytes A B C D (A the most significant byte of the IEEE-754 single,
runtime-and-ecosystem 2c):

========  ==================  ===============================================
order     registers           where it is used
========  ==================  ===============================================
abcd      [AB, CD]            the Modbus standard: big-endian, high word first
cdab      [CD, AB]            "word-swapped" (many PLCs; pymodbus ``little``)
badc      [BA, DC]            bytes swapped in each word
dcba      [DC, BA]            both swapped (the little-endian float's bytes)
========  ==================  ===============================================

123456.0 is 0x47F12000: abcd gives [0x47F1, 0x2000], cdab [0x2000, 0x47F1].

A :class:`RegisterMap` lists the points (``"block.port"``, a 0-based holding-register
address, a direction, a type, a word order) plus two uint16 registers of the device's own:
a **heartbeat** (the device's scan counter, wrapping at 65536, so a client sees the device is
alive and scanning) and the **fault bits** (bit i set while device input i, in map order, is
in its fault state: see :mod:`loopworks.live.device`). Its TOML form is the ``[io]`` table a
controller configuration uses::

    [io]
    device_id = 1
    heartbeat_address = 4   # uint16, device scan counter
    fault_bits_address = 5  # uint16, bit i: input i in fault state

    [io.points."sensor.pv"]
    address = 0
    direction = "output"    # read by the controller
    type = "float32"
    word_order = "abcd"

**OPC UA.** ``protocol = "opcua"`` (default ``"modbus"``) makes the controller reach the
device's points on an OPC UA server instead (:mod:`loopworks.live.opcua_io`): ``url`` is the
server's endpoint (``--device opc.tcp://...`` overrides it), and each point may name its
``node`` (``"ns=2;s=sensor.pv"`` or ``"nsu=urn:loopworks:device;s=sensor.pv"``; default
``nsu=urn:loopworks:device;s=<point name>``, the nodes ``loopworks device --opcua-port``
serves). Addresses are then optional (the device still serves every point over Modbus as
well: a point without one takes the next two free registers from 0)::

    [io]
    protocol = "opcua"
    url = "opc.tcp://127.0.0.1:4841/device/"

    [io.points."sensor.pv"]
    direction = "output"
    node = "nsu=urn:loopworks:device;s=sensor.pv"

This module does not import pymodbus or asyncua.
"""

from __future__ import annotations

import json
import math
import re
import struct
import tomllib
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from loopworks.errors import InputError

if TYPE_CHECKING:
    from loopworks.live.split import Split
    from loopworks.sim.scenario import Scenario

#: the float32 byte orders a point may use (see the module docstring)
WORD_ORDERS = ("abcd", "cdab", "badc", "dcba")
#: point directions: "input" is written by the controller to the device, "output" is read
DIRECTIONS = ("input", "output")
#: point types (each float32 takes two registers)
TYPES = ("float32",)
#: registers per value of each type
REGISTERS = {"float32": 2}
#: the highest Modbus register address
MAX_ADDRESS = 65535
#: Modbus unit ids a device may answer to (0 is the broadcast address)
DEVICE_IDS = (1, 247)
#: how the controller reaches the device's points
PROTOCOLS = ("modbus", "opcua")
#: the namespace URI of the device's own OPC UA nodes (``loopworks device --opcua-port``)
DEVICE_NAMESPACE = "urn:loopworks:device"
#: an OPC UA node as a point names it: ``ns=<index>;`` or ``nsu=<namespace URI>;``, then
#: ``s=``, ``i=``, ``g=`` or ``b=`` and the identifier
NODE_FORM = re.compile(r"^(ns=\d+|nsu=[^;]+);(s|i|g|b)=.+$", re.DOTALL)


def _order(word_order: str) -> str:
    order = word_order.lower() if isinstance(word_order, str) else word_order
    if order not in WORD_ORDERS:
        raise InputError(f"word_order = {word_order!r} is not allowed: expected one of "
                         + ", ".join(WORD_ORDERS))
    return str(order)


def encode_f32(value: float, word_order: str = "abcd") -> list[int]:
    """``value`` as an IEEE-754 single in two 16-bit registers, in ``word_order``.
    NaN and infinities encode; a finite value beyond the float32 range (±3.4e38) is an
    InputError."""
    order = _order(word_order)
    try:
        a, b, c, d = struct.pack(">f", float(value))
    except (OverflowError, TypeError, ValueError):
        raise InputError(f"value {value!r} does not fit a float32 (finite values up to "
                         "±3.4028235e38)") from None
    pairs = {"abcd": ((a, b), (c, d)), "cdab": ((c, d), (a, b)),
             "badc": ((b, a), (d, c)), "dcba": ((d, c), (b, a))}[order]
    return [hi << 8 | lo for hi, lo in pairs]


def decode_f32(regs: Sequence[int], word_order: str = "abcd") -> float:
    """The float32 that two registers hold in ``word_order`` (the inverse of
    :func:`encode_f32`)."""
    order = _order(word_order)
    if len(regs) != 2 or not all(isinstance(r, int) and 0 <= r <= 0xFFFF for r in regs):
        raise InputError(f"registers {list(regs)!r}: a float32 takes exactly two registers, "
                         "each an integer 0..65535")
    (hi0, lo0), (hi1, lo1) = ((regs[0] >> 8, regs[0] & 0xFF), (regs[1] >> 8, regs[1] & 0xFF))
    raw = {"abcd": (hi0, lo0, hi1, lo1), "cdab": (hi1, lo1, hi0, lo0),
           "badc": (lo0, hi0, lo1, hi1), "dcba": (lo1, hi1, lo0, hi0)}[order]
    return float(struct.unpack(">f", bytes(raw))[0])


@dataclass(frozen=True)
class Point:
    """One plant signal in holding registers.

    ``name`` is ``"block.port"``; ``address`` the first holding register (0-based, as on the
    wire); ``direction`` "input" (the controller writes it to the device: a valve's ``op``,
    %) or "output" (the controller reads it: a transmitter's ``pv``, in its own units);
    ``type`` "float32"; ``word_order`` one of :data:`WORD_ORDERS`; ``fault_action`` (inputs
    only): what the device gives the plant when the controller stops writing the point
    (``"hold"`` the last value, the FF default, or a safe value); ``node`` (OPC UA maps
    only): the OPC UA node the controller reads or writes (None: :meth:`RegisterMap.node_of`
    gives the device's own)."""

    name: str
    address: int
    direction: str
    word_order: str = "abcd"
    type: str = "float32"
    fault_action: str | float = "hold"
    node: str | None = None

    def __post_init__(self) -> None:
        where = f"point {self.name!r}"
        if not isinstance(self.name, str) or self.name.count(".") < 1:
            raise InputError(f"point name {self.name!r} must be written 'block.port'")
        if self.node is not None and (not isinstance(self.node, str)
                                      or not NODE_FORM.match(self.node)):
            raise InputError(f"{where}: node = {self.node!r} is not allowed: expected an OPC "
                             "UA node id such as \"ns=2;s=sensor.pv\" or "
                             f"\"nsu={DEVICE_NAMESPACE};s=sensor.pv\"")
        if self.direction not in DIRECTIONS:
            raise InputError(f"{where}: direction = {self.direction!r} is not allowed: "
                             "expected 'input' (written by the controller) or 'output' "
                             "(read by the controller)")
        if self.type not in TYPES:
            raise InputError(f"{where}: type = {self.type!r} is not allowed: expected "
                             + ", ".join(TYPES))
        object.__setattr__(self, "word_order", _order(self.word_order))
        action = self.fault_action
        if isinstance(action, str) and action.lower() == "hold":
            object.__setattr__(self, "fault_action", "hold")
        elif (isinstance(action, bool) or not isinstance(action, int | float)
              or not math.isfinite(action)):
            raise InputError(f"{where}: fault_action = {action!r} is not allowed: expected "
                             "\"hold\" or a finite safe value")
        elif self.direction != "input":
            raise InputError(f"{where}: fault_action is for input points (written by the "
                             "controller) only")
        else:
            object.__setattr__(self, "fault_action", float(action))
        last = MAX_ADDRESS - self.count + 1
        if (isinstance(self.address, bool) or not isinstance(self.address, int)
                or not 0 <= self.address <= last):
            raise InputError(f"{where}: address = {self.address!r} is not allowed: expected "
                             f"a whole number 0..{last} (the {self.count} registers of a "
                             f"{self.type} end at {MAX_ADDRESS} at most)")

    @property
    def count(self) -> int:
        """Registers the point takes."""
        return REGISTERS[self.type]

    @property
    def registers(self) -> range:
        """The addresses the point takes."""
        return range(self.address, self.address + self.count)

    def encode(self, value: float) -> list[int]:
        """``value`` as this point's registers."""
        return encode_f32(value, self.word_order)

    def decode(self, regs: Sequence[int]) -> float:
        """This point's value from its registers."""
        return decode_f32(regs, self.word_order)


@dataclass(frozen=True, init=False)
class RegisterMap:
    """The points of a device, its Modbus unit id, and the addresses of its heartbeat and
    fault-bits registers (uint16 each; None: not served). Addresses may not overlap.

    ``protocol``: how the controller reaches the points, ``"modbus"`` (the registers) or
    ``"opcua"`` (the nodes on the OPC UA server at ``url``, None: given on the command
    line, or the built-in device's). ``poll_period``: seconds of plant time between the
    controller's reads of the device (rounded to whole scans, at least one; None: every
    scan); between reads the controller holds the last values and statuses read."""

    points: tuple[Point, ...]
    device_id: int = 1
    heartbeat_address: int | None = None
    fault_bits_address: int | None = None
    source: str = field(default="<register map>", compare=False)
    protocol: str = "modbus"
    url: str | None = None
    poll_period: float | None = None

    def __init__(self, points: Iterable[Point], device_id: int = 1,
                 heartbeat_address: int | None = None,
                 fault_bits_address: int | None = None,
                 source: str = "<register map>", *, protocol: str = "modbus",
                 url: str | None = None, poll_period: float | None = None) -> None:
        pts = tuple(points)
        object.__setattr__(self, "points", pts)
        object.__setattr__(self, "device_id", device_id)
        object.__setattr__(self, "heartbeat_address", heartbeat_address)
        object.__setattr__(self, "fault_bits_address", fault_bits_address)
        object.__setattr__(self, "source", source)
        object.__setattr__(self, "protocol", protocol)
        object.__setattr__(self, "url", url)
        if poll_period is not None:
            if (isinstance(poll_period, bool) or not isinstance(poll_period, int | float)
                    or not (0.0 < poll_period < math.inf)):
                raise InputError(f"{source}: poll_period = {poll_period!r} is not allowed: "
                                 "expected seconds > 0 (finite)")
            poll_period = float(poll_period)
        object.__setattr__(self, "poll_period", poll_period)
        if protocol not in PROTOCOLS:
            raise InputError(f"{source}: protocol = {protocol!r} is not allowed: expected "
                             + " or ".join(f"{p!r}" for p in PROTOCOLS))
        if url is not None:
            if protocol != "opcua":
                raise InputError(f"{source}: url is for protocol = \"opcua\" maps only (a "
                                 "Modbus device is given with --device modbus://HOST:PORT)")
            check_opcua_url(url, f"{source}: url")
        if protocol != "opcua":
            named = [p.name for p in pts if p.node is not None]
            if named:
                raise InputError(f"{source}: point {named[0]!r}: node is for protocol = "
                                 "\"opcua\" maps only")
        lo, hi = DEVICE_IDS
        if isinstance(device_id, bool) or not isinstance(device_id, int) or not (
                lo <= device_id <= hi):
            raise InputError(f"{source}: device_id = {device_id!r} is not allowed: expected "
                             f"a Modbus unit id {lo}..{hi}")
        used: dict[int, str] = {}
        names: set[str] = set()
        for p in pts:
            if p.name in names:
                raise InputError(f"{source}: point {p.name!r} is listed twice")
            names.add(p.name)
            self._claim(used, p.registers, f"point {p.name!r}")
        for what, address in (("heartbeat_address", heartbeat_address),
                              ("fault_bits_address", fault_bits_address)):
            if address is None:
                continue
            if isinstance(address, bool) or not isinstance(address, int) or not (
                    0 <= address <= MAX_ADDRESS):
                raise InputError(f"{source}: {what} = {address!r} is not allowed: expected "
                                 f"a whole number 0..{MAX_ADDRESS}")
            self._claim(used, range(address, address + 1), what)
        if len(self.inputs) > 16 and fault_bits_address is not None:
            raise InputError(f"{source}: {len(self.inputs)} input points: the fault bits "
                             "register shows 16 at most; leave fault_bits_address out")

    def _claim(self, used: dict[int, str], regs: range, what: str) -> None:
        for r in regs:
            if r in used:
                raise InputError(f"{self.source}: {what} takes register {r}, which "
                                 f"{used[r]} takes already: addresses may not overlap")
            used[r] = what

    @property
    def inputs(self) -> list[Point]:
        """The points the controller writes, in map order (fault bit i is the i-th)."""
        return [p for p in self.points if p.direction == "input"]

    @property
    def outputs(self) -> list[Point]:
        """The points the controller reads, in map order."""
        return [p for p in self.points if p.direction == "output"]

    def node_of(self, point: Point) -> str:
        """The OPC UA node of ``point``: its ``node``, else the device's own,
        ``nsu=urn:loopworks:device;s=<point name>``."""
        return point.node if point.node is not None else (
            f"nsu={DEVICE_NAMESPACE};s={point.name}")

    def point(self, name: str) -> Point:
        """The point named ``name``; InputError lists the names."""
        for p in self.points:
            if p.name == name:
                return p
        raise InputError(f"{self.source}: no point {name!r}; points: "
                         + ", ".join(p.name for p in self.points))

    def text(self) -> str:
        """The map as a table for a user: address, registers, name, direction, type, word
        order; then the device's own registers."""
        rows = [("address", "regs", "name", "direction", "type", "word order / meaning")]
        for p in sorted(self.points, key=lambda p: p.address):
            access = "input (write)" if p.direction == "input" else "output (read)"
            rows.append((str(p.address), f"{p.address}-{p.address + p.count - 1}", p.name,
                         access, p.type, p.word_order))
        if self.heartbeat_address is not None:
            rows.append((str(self.heartbeat_address), str(self.heartbeat_address),
                         "heartbeat", "output (read)", "uint16",
                         "device scan counter, wraps at 65536"))
        if self.fault_bits_address is not None:
            names = ", ".join(f"bit {i} {p.name}" for i, p in enumerate(self.inputs))
            rows.append((str(self.fault_bits_address), str(self.fault_bits_address),
                         "fault bits", "output (read)", "uint16",
                         f"input in fault state: {names or 'none'}"))
        widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]) - 1)]
        lines = [f"Modbus TCP device id {self.device_id}, holding registers (function codes "
                 "3 read, 6/16 write), 0-based addresses"]
        for r in rows:
            lines.append("  ".join(c.ljust(w) for c, w in zip(r, widths, strict=False))
                         + "  " + r[-1])
        return "\n".join(line.rstrip() for line in lines) + "\n"

    def to_toml(self) -> str:
        """The map as the ``[io]`` TOML table (:meth:`from_toml` reads it back)."""
        out = ["# loopworks device register map: holding registers, 0-based addresses",
               "[io]", f"device_id = {self.device_id}"]
        if self.protocol != "modbus":
            out.append(f"protocol = \"{self.protocol}\"  # how the controller reaches the "
                       "points")
        if self.url is not None:
            out.append(f"url = {json.dumps(self.url)}")
        if self.poll_period is not None:
            out.append(f"poll_period = {self.poll_period!r}  # s between the controller's reads")
        if self.heartbeat_address is not None:
            out.append(f"heartbeat_address = {self.heartbeat_address}  # uint16, device "
                       "scan counter (wraps at 65536)")
        if self.fault_bits_address is not None:
            out.append(f"fault_bits_address = {self.fault_bits_address}  # uint16, bit i: "
                       "input point i (in this order) in fault state")
        for p in self.points:
            out += ["", f"[io.points.{json.dumps(p.name)}]", f"address = {p.address}",
                    f"direction = \"{p.direction}\"  # "
                    + ("written by the controller" if p.direction == "input"
                       else "read by the controller"),
                    f"type = \"{p.type}\"", f"word_order = \"{p.word_order}\""]
            if p.node is not None:
                out.append(f"node = {json.dumps(p.node)}")
            if p.direction == "input":
                action = (f"\"{p.fault_action}\"" if p.fault_action == "hold"
                          else repr(p.fault_action))
                out.append(f"fault_action = {action}  # \"hold\" or a safe value, after the "
                           "device's fstate time without a write")
        return "\n".join(out) + "\n"

    def write(self, path: str | Path) -> None:
        """Write :meth:`to_toml` to ``path``; InputError names a path that cannot be
        written."""
        try:
            Path(path).write_text(self.to_toml(), encoding="utf-8")
        except OSError as exc:
            raise InputError(f"{path}: cannot write the register map: {exc.strerror}"
                             ) from None

    @classmethod
    def from_toml(cls, text: str, source: str = "<register map>") -> RegisterMap:
        """Read a map from TOML text holding an ``[io]`` table (other tables are left to
        their readers). InputError names ``source``, the key and what was expected."""
        try:
            raw = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise InputError(f"{source}: invalid TOML: {exc}") from None
        return cls.from_table(raw.get("io"), source)

    @classmethod
    def from_table(cls, io: Any, source: str = "<register map>") -> RegisterMap:
        """Read a map from the parsed ``[io]`` table ``io`` (a scenario's, or a map
        file's). InputError names ``source``, the key and what was expected."""
        if not isinstance(io, dict):
            raise InputError(f"{source}: expected an [io] table with device_id and "
                             "[io.points.\"block.port\"] tables")
        allowed = {"device_id", "heartbeat_address", "fault_bits_address", "points",
                   "protocol", "url", "poll_period"}
        for key in io:
            if key not in allowed:
                raise InputError(f"{source}: io.{key}: unknown key; keys: "
                                 + ", ".join(sorted(allowed)))
        device_id = _int(io.get("device_id", 1), f"{source}: io.device_id",
                         f"a Modbus unit id {DEVICE_IDS[0]}..{DEVICE_IDS[1]}")
        extra = {k: None if io.get(k) is None else _int(
            io[k], f"{source}: io.{k}", f"a register address 0..{MAX_ADDRESS}")
            for k in ("heartbeat_address", "fault_bits_address")}
        protocol = io.get("protocol", "modbus")
        if protocol not in PROTOCOLS:
            raise InputError(f"{source}: io.protocol = {protocol!r}: expected "
                             + " or ".join(f"\"{p}\"" for p in PROTOCOLS))
        url = io.get("url")
        if url is not None:
            if protocol != "opcua":
                raise InputError(f"{source}: io.url: for protocol = \"opcua\" only (a Modbus "
                                 "device is given with --device modbus://HOST:PORT)")
            check_opcua_url(url, f"{source}: io.url")
        opcua = protocol == "opcua"
        points_raw = io.get("points", {})
        if not isinstance(points_raw, dict) or not points_raw:
            raise InputError(f"{source}: io.points: expected tables "
                             "[io.points.\"block.port\"] with address and direction")
        points: list[Point] = []
        unplaced: set[str] = set()
        for name, table in points_raw.items():
            where = f"{source}: io.points.{json.dumps(name)}"
            if not isinstance(table, dict):
                raise InputError(f"{where}: expected a table with address, direction, type "
                                 "and word_order")
            keys = {"address", "direction", "type", "word_order", "fault_action"}
            if opcua:
                keys.add("node")
            for key in table:
                if key not in keys:
                    raise InputError(f"{where}.{key}: unknown key"
                                     + ("; node is for protocol = \"opcua\" maps only"
                                        if key == "node" else "")
                                     + "; keys: " + ", ".join(sorted(keys)))
            if ("address" not in table and not opcua) or "direction" not in table:
                missing = "direction" if "direction" not in table else "address"
                raise InputError(f"{where}: {missing} is missing")
            address = None if "address" not in table else _int(
                table["address"], f"{where}.address", f"a register address 0..{MAX_ADDRESS - 1}")
            node = table.get("node")
            if node is not None and not isinstance(node, str):
                raise InputError(f"{where}.node = {node!r}: expected a string such as "
                                 "\"ns=2;s=sensor.pv\"")
            fields: dict[str, Any] = {}
            for key, default in (("direction", None), ("type", "float32"),
                                 ("word_order", "abcd")):
                value = table.get(key, default)
                if not isinstance(value, str):
                    raise InputError(f"{where}.{key} = {value!r}: expected a string")
                fields[key] = value
            if address is None:
                unplaced.add(name)
            try:
                points.append(Point(name, 0 if address is None else address,
                                    fields["direction"], fields["word_order"], fields["type"],
                                    table.get("fault_action", "hold"), node))
            except InputError as exc:
                raise InputError(f"{where}: {exc}") from None
        return cls(_place(points, unplaced, extra.values()), device_id,
                   extra["heartbeat_address"],
                   extra["fault_bits_address"], source=source, protocol=protocol, url=url,
                   poll_period=io.get("poll_period"))

    @classmethod
    def read(cls, path: str | Path) -> RegisterMap:
        """:meth:`from_toml` of the file at ``path``."""
        try:
            text = Path(path).read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise InputError(f"{path}: cannot read the register map: {exc}") from None
        return cls.from_toml(text, str(path))


def check_opcua_url(url: Any, where: str) -> str:
    """``url`` if it is an ``opc.tcp://HOST:PORT/...`` URL, else an InputError at ``where``."""
    from urllib.parse import urlparse

    parsed = urlparse(url) if isinstance(url, str) else None
    try:
        ok = parsed is not None and parsed.scheme == "opc.tcp" and bool(parsed.hostname) and (
            parsed.port is None or parsed.port > 0)
    except ValueError:
        ok = False
    if not ok:
        raise InputError(f"{where} = {url!r} is not allowed: expected opc.tcp://HOST:PORT/PATH "
                         "(for example opc.tcp://127.0.0.1:4841/device/)")
    return str(url)


def _place(points: list[Point], unplaced: set[str],
           taken: Iterable[int | None]) -> list[Point]:
    """``points`` with the ones named in ``unplaced`` (read without an address: OPC UA maps)
    placed on the next two free registers from 0, in table order."""
    used = {r for p in points if p.name not in unplaced for r in p.registers}
    used |= {a for a in taken if a is not None}
    out, at = [], 0
    for p in points:
        if p.name in unplaced:
            while at in used or at + 1 in used:
                at += 1
            p = Point(p.name, at, p.direction, p.word_order, p.type, p.fault_action, p.node)
            used |= set(p.registers)
        out.append(p)
    return out


def _int(value: Any, where: str, expected: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise InputError(f"{where} = {value!r}: expected {expected}")
    return value


def default_map(split: Split, device_id: int = 1, word_order: str = "abcd") -> RegisterMap:
    """The device's map: its outputs (what the controller reads) from address 0, then its
    inputs (what the controller writes), two registers each, then the heartbeat and the
    fault bits."""
    names = [(n, "output") for n in split.device_outputs()]
    names += [(n, "input") for n in split.device_inputs()]
    points = [Point(n, 2 * i, d, word_order) for i, (n, d) in enumerate(names)]
    end = 2 * len(points)
    return RegisterMap(points, device_id, heartbeat_address=end,
                       fault_bits_address=end + 1 if len(split.device_inputs()) <= 16 else None)


def map_of(sc: Scenario, split: Split) -> RegisterMap:
    """The device's map of scenario ``sc``: its ``[io]`` table when it has one, else
    :func:`default_map`; every signal that crosses the split must have a point, and every
    point must be one (InputError naming the point or the signal)."""
    if sc.io is None:
        return default_map(split)
    if "devices" in sc.io:
        raise InputError(f"{sc.source}: [io] names several devices ([io.devices]): a "
                         "simulated device serves a one-device map; give it a scenario whose "
                         "[io] is one device's (loopworks.live.devices)")
    regmap = RegisterMap.from_table(sc.io, f"{sc.source}: [io]")
    want = {**{n: "output" for n in split.device_outputs()},
            **{n: "input" for n in split.device_inputs()}}
    for p in regmap.points:
        if p.name not in want:
            raise InputError(f"{sc.source}: [io.points.{json.dumps(p.name)}] is not a signal "
                             "between the plant and the controller; those are "
                             + ", ".join(f"{n} ({d})" for n, d in want.items()))
        if p.direction != want[p.name]:
            raise InputError(f"{sc.source}: [io.points.{json.dumps(p.name)}] direction = "
                             f"{p.direction!r}: expected {want[p.name]!r}")
    missing = [n for n in want if n not in {p.name for p in regmap.points}]
    if missing:
        raise InputError(f"{sc.source}: [io] has no point for {', '.join(missing)}")
    return regmap
