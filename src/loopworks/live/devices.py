"""Several field devices behind one controller: an ``[io]`` table with ``[io.devices.NAME]``.

A plant's I/O is often spread over devices (the transmitter on one remote I/O rack, the valve
on another, each its own Modbus unit or OPC UA server, each polled at its own rate). Each
``[io.devices.NAME]`` table has the shape of a one-device ``[io]`` table (``device_id``,
``protocol``, ``poll_period``, heartbeat and fault-bits addresses, ``[...points."block.port"]``)
plus the device's address, ``url = "modbus://HOST:PORT"`` or ``"opc.tcp://HOST:PORT/PATH"``::

    [io.devices.rack1]
    url = "modbus://10.0.0.5:502"
    poll_period = 1.0
    [io.devices.rack1.points."sensor.pv"]
    address = 0
    direction = "output"

    [io.devices.rack2]
    url = "modbus://10.0.0.6:502"
    [io.devices.rack2.points."valve.op"]
    address = 0
    direction = "input"

Every signal that crosses the split must be a point of exactly one device.
:class:`MultiIO` is the controller's I/O over all of them: each device read at its own poll
period (its last values and statuses held in between), each output written to its device; a
device that fails makes its own points Bad, the others carry on.
"""

from __future__ import annotations

import asyncio
import json
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from loopworks.errors import InputError
from loopworks.live.registers import RegisterMap

if TYPE_CHECKING:
    from loopworks.live.split import Split
    from loopworks.sim.scenario import Scenario

#: the keys of an [io] table that names several devices
MULTI_KEYS = ("devices",)


@dataclass(frozen=True)
class Link:
    """One device of the controller: its name, its map and its URL."""

    name: str
    regmap: RegisterMap
    url: str


def has_devices(sc: Scenario) -> bool:
    """True when the scenario's ``[io]`` table names several devices."""
    return isinstance(sc.io, dict) and "devices" in sc.io


def links_of(sc: Scenario, split: Split) -> list[Link]:
    """The devices of ``sc``'s ``[io.devices]`` tables, checked against ``split`` (module
    docstring); InputError names the file, the device, the key and what was expected."""
    from loopworks.live.serve import parse_device

    io = sc.io
    assert isinstance(io, dict)
    extra = [k for k in io if k not in MULTI_KEYS]
    where = f"{sc.source}: [io]"
    if extra:
        raise InputError(f"{where}: {extra[0]} next to [io.devices]: with several devices, "
                         "every key goes in its device's table [io.devices.NAME]")
    tables = io["devices"]
    if not isinstance(tables, dict) or not tables:
        raise InputError(f"{where}.devices: expected [io.devices.NAME] tables")
    links: list[Link] = []
    owner: dict[str, str] = {}
    for name, table in tables.items():
        at = f"{sc.source}: [io.devices.{name}]"
        if not isinstance(table, dict):
            raise InputError(f"{at}: expected a table with url and points")
        body = dict(table)
        url = body.pop("url", None)
        if not isinstance(url, str):
            raise InputError(f"{at}: url is missing: expected \"modbus://HOST:PORT\" or "
                             "\"opc.tcp://HOST:PORT/PATH\"")
        protocol, _, _ = parse_device(url)
        if body.get("protocol", protocol) != protocol:
            raise InputError(f"{at}: protocol = {body['protocol']!r} does not match url "
                             f"{url!r}")
        body["protocol"] = protocol
        if protocol == "opcua":
            body["url"] = url
        regmap = RegisterMap.from_table(body, at)
        for p in regmap.points:
            if p.name in owner:
                raise InputError(f"{at}: point {json.dumps(p.name)} is a point of device "
                                 f"{owner[p.name]} already: each signal has one device")
            owner[p.name] = name
        links.append(Link(name, regmap, url))
    want = {**{n: "output" for n in split.device_outputs()},
            **{n: "input" for n in split.device_inputs()}}
    for link in links:
        for p in link.regmap.points:
            if p.name not in want:
                raise InputError(f"{sc.source}: [io.devices.{link.name}.points."
                                 f"{json.dumps(p.name)}] is not a signal between the plant "
                                 "and the controller; those are "
                                 + ", ".join(f"{n} ({d})" for n, d in want.items()))
            if p.direction != want[p.name]:
                raise InputError(f"{sc.source}: [io.devices.{link.name}.points."
                                 f"{json.dumps(p.name)}] direction = {p.direction!r}: "
                                 f"expected {want[p.name]!r}")
    missing = [n for n in want if n not in owner]
    if missing:
        raise InputError(f"{sc.source}: [io.devices] has no point for {', '.join(missing)}")
    return links


class MultiIO:
    """The controller's I/O over several devices (module docstring), with the interface of
    :class:`~loopworks.live.modbus_io.ModbusIO`. ``dt``: the controller's scan, s (the
    poll periods are rounded to whole scans)."""

    def __init__(self, links: Sequence[Link], dt: float) -> None:
        from loopworks.live.serve import make_io

        self.links = list(links)
        self.ios = [make_io(link.regmap, link.url) for link in self.links]
        self.every = [1 if link.regmap.poll_period is None
                      else max(1, round(link.regmap.poll_period / dt)) for link in self.links]
        self.held: list[dict[str, tuple[float, int]] | None] = [None] * len(self.links)
        self.reads = 0
        self.writes_to = [{p.name for p in link.regmap.points if p.direction == "input"}
                          for link in self.links]
        #: the points the last write left unwritten (a device whose write failed)
        self.unwritten: set[str] = set()

    async def read(self) -> dict[str, tuple[float, int]]:
        """Every device's outputs; a device is read when its poll period is due."""
        due = [i for i, n in enumerate(self.every)
               if self.held[i] is None or self.reads % n == 0]
        self.reads += 1
        fresh = await asyncio.gather(*(self.ios[i].read() for i in due))
        for i, values in zip(due, fresh, strict=True):
            self.held[i] = values
        out: dict[str, tuple[float, int]] = {}
        for values in self.held:
            out.update(values or {})
        return out

    async def write(self, values: dict[str, float]) -> bool:
        """Each output to its device; False when any device's write failed, whose points are
        then ``unwritten`` (the other devices' were written)."""
        parts = [{k: v for k, v in values.items() if k in names} for names in self.writes_to]
        sent = [(io, part) for io, part in zip(self.ios, parts, strict=True) if part]
        done = await asyncio.gather(*(io.write(part) for io, part in sent))
        self.unwritten = {k for (_, part), ok in zip(sent, done, strict=True) if not ok
                          for k in part}
        return all(done)

    def status(self) -> dict[str, Any]:
        """The devices' counters added up (``connected``: all of them), and per device."""
        each = [io.status() for io in self.ios]
        total: dict[str, Any] = {"connected": all(s.get("connected", False) for s in each)}
        for key in ("reads", "read_errors", "writes", "write_errors", "readback_mismatches",
                    "reconnects"):
            total[key] = sum(int(s.get(key, 0)) for s in each)
        total["devices"] = {link.name: s for link, s in zip(self.links, each, strict=True)}
        return total

    def close(self) -> None:
        for io in self.ios:
            io.close()

    async def aclose(self) -> None:
        from loopworks.live.serve import close_io

        for io in self.ios:
            await close_io(io)
