"""The controller's I/O from an OPC UA server: the device's points read and written as nodes
(an ``[io]`` table with ``protocol = "opcua"``, :mod:`loopworks.live.registers`), with the same
interface as :class:`~loopworks.live.modbus_io.ModbusIO` (``read``, ``write``, ``status``,
``close``).

Each scan reads every point (the device outputs, and the controller outputs to read back)
in **one** Read request, as DataValues with their StatusCode (never ``read_value()``, which
raises on anything but Good: runtime-and-ecosystem 1c), and writes the controller outputs in
one Write request as Doubles (a Float node, a PLC's REAL, is written as a Float: the type
must match exactly). A point's node is its ``node`` in the table, else
``nsu=urn:loopworks:device;s=<point name>``; namespace URIs are resolved to indexes after
each connection. Statuses:

* the server's StatusCode becomes the Fieldbus byte of
  :func:`~loopworks.live.opcua.fieldbus_status` (Good 0x80, Uncertain 0x40..0x58, Bad ...);
  a Bad value comes without a value (the server wipes it), so it carries the last usable
  value read, and BadNoCommunication is 0x14 with it or 0x18 without one;
* a read that fails (no connection, time-out, a service fault) makes every input **Bad, no
  communication**: 0x14 with the last value read, 0x18 with NaN before any;
* a non-finite value read is Bad, device failure (0x0C), a value that is not a number Bad,
  configuration error (0x04), as is a node whose namespace URI the server does not know;
* each controller output written is read back on the next scan and compared.

Reconnection: asyncua's own, ``Client(url, auto_reconnect=True)`` (asyncua >= 2.0.1: its
supervisor task notices a lost link at once when the socket closes, within
``watchdog_intervall`` otherwise, and reconnects with a backoff capped here at
:data:`RETRY_MAX` s, re-creating the session). A scan never waits for it: while the client
is not connected, the inputs are Bad (no communication) without a request. Until the first
connection succeeds (asyncua reconnects only a client that was connected once) the connection
is retried here with the same backoff, :data:`RETRY_MIN` doubling to :data:`RETRY_MAX`; a
client whose supervisor gave up (state disconnected) is replaced by a new one. Every
transition (lost, restored, a write refused, a read-back that differs) is logged on the
``loopworks.serve`` logger with its time.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import time
from typing import TYPE_CHECKING, Any

from asyncua import ua
from asyncua.client.client import Client
from asyncua.client.ua_client import UaClientState
from asyncua.ua.attribute_ids import AttributeIds

from loopworks.blocks import status as st
from loopworks.errors import InputError
from loopworks.live.modbus_io import READBACK_TOLERANCE, RETRY_MAX, RETRY_MIN, IOCounters
from loopworks.live.opcua import fieldbus_status
from loopworks.live.registers import Point, RegisterMap, check_opcua_url

if TYPE_CHECKING:
    from asyncua.common.node import Node

log = logging.getLogger("loopworks.serve")

#: a request's time-out, s (a scan waits at most this for the server)
TIMEOUT = 0.5
#: the DataType NodeIds written with their own variant type (else Double)
_WRITE_TYPES = {ua.NodeId(ua.Int32(10)): ua.VariantType.Float,
                ua.NodeId(ua.Int32(11)): ua.VariantType.Double}


def parse_node(text: str, namespaces: list[str]) -> ua.NodeId:
    """The NodeId of ``ns=<i>;...`` or ``nsu=<uri>;...`` given the server's namespace array;
    InputError when the URI is not among them."""
    if text.startswith("nsu="):
        uri, _, rest = text[4:].partition(";")
        if uri not in namespaces:
            raise InputError(f"node {text!r}: the server has no namespace {uri!r}; its "
                             "namespaces: " + ", ".join(namespaces))
        text = f"ns={namespaces.index(uri)};{rest}"
    try:
        return ua.NodeId.from_string(text)
    except Exception as exc:
        raise InputError(f"node {text!r} is not an OPC UA node id ({exc})") from None


class OpcuaIO:
    """Reads the device outputs named by ``regmap`` and writes its inputs on the OPC UA
    server at ``url`` (module docstring). Call :meth:`read` and :meth:`write` once per scan,
    on one event loop; :meth:`aclose` (or :meth:`close`) at the end."""

    def __init__(self, regmap: RegisterMap, url: str, *, timeout: float = TIMEOUT) -> None:
        self.regmap = regmap
        self.url = check_opcua_url(url, "the OPC UA device url")
        self.timeout = timeout
        self.inputs = [p for p in regmap.points if p.direction == "output"]
        self.outputs = [p for p in regmap.points if p.direction == "input"]
        self.counters = IOCounters()
        self.last: dict[str, float] = {}
        self.written: dict[str, float] = {}
        self.client: Client | None = None
        # per point, after connecting: its node (None: its namespace is unknown there)
        self._nodes: dict[str, Node | None] = {}
        self._types: dict[str, ua.VariantType] = {}
        self._retry_at = 0.0
        self._backoff = RETRY_MIN
        self._lost_logged = False
        self._was_connected = False
        self._refused: dict[str, str] = {}

    def _event(self, message: str, level: int = logging.WARNING) -> None:
        stamp = time.strftime("%Y-%m-%dT%H:%M:%S", time.localtime())
        self.counters.events.append(f"{stamp} {message}")
        log.log(level, message)

    def _lost(self, why: str) -> None:
        self.counters.connected = False
        if not self._lost_logged:
            self._event(f"{why}: inputs Bad (no communication); reconnecting every "
                        f"{RETRY_MIN:g}..{RETRY_MAX:g} s")
            self._lost_logged = True

    def _restored(self) -> None:
        if self._lost_logged:
            self.counters.reconnects += 1
            self._event(f"OPC UA server {self.url} connected again", logging.INFO)
        else:
            self._event(f"OPC UA server {self.url} connected", logging.INFO)
        self._lost_logged = False
        self.counters.connected = True

    def _new_client(self) -> Client:
        client = Client(self.url, timeout=self.timeout, auto_reconnect=True,
                        reconnect_max_delay=RETRY_MAX, reconnect_request_timeout=self.timeout)
        client.session_timeout = 600_000  # what asyncua's server grants at most, ms
        return client

    async def connect(self) -> bool:
        """True when connected (connecting first when never connected and not backing off);
        never waits for asyncua's reconnection."""
        client = self.client
        if client is not None and client.uaclient.state is UaClientState.DISCONNECTED:
            self._drop()  # its supervisor gave up: a new client
            client = None
        if client is not None:
            if client.uaclient.state is not UaClientState.CONNECTED:
                self._was_connected = False
                self._lost(f"the link to the OPC UA server {self.url} is down")
                return False
            if not self._was_connected:  # asyncua reconnected: the server may be another
                try:
                    await self._resolve(client)
                except Exception as exc:
                    self._lost(f"resolving the nodes on {self.url} failed "
                               f"({type(exc).__name__}: {exc})")
                    return False
                self._was_connected = True
            return True
        now = time.monotonic()
        if now < self._retry_at:
            return False
        client = self._new_client()
        try:
            await asyncio.wait_for(client.connect(), 4 * self.timeout)
            await self._resolve(client)
        except Exception as exc:
            with contextlib.suppress(Exception):
                await asyncio.wait_for(client.disconnect(), self.timeout)
            self._retry_at = time.monotonic() + self._backoff
            self._backoff = min(self._backoff * 2.0, RETRY_MAX)
            self._lost(f"cannot connect to the OPC UA server {self.url} "
                       f"({type(exc).__name__}: {exc})")
            return False
        self.client = client
        self._backoff = RETRY_MIN
        self._was_connected = True
        return True

    async def _resolve(self, client: Client) -> None:
        """Each point's node (namespace URIs to indexes) and the outputs' write types."""
        namespaces = list(await client.get_namespace_array())
        nodes: dict[str, Node | None] = {}
        for p in self.regmap.points:
            try:
                nodes[p.name] = client.get_node(parse_node(self.regmap.node_of(p), namespaces))
            except InputError as exc:
                nodes[p.name] = None
                self._event(f"{p.name}: {exc}: Bad (configuration error)")
        known = [(p, n) for p in self.outputs if (n := nodes[p.name]) is not None]
        self._types = {}
        if known:
            dvs = await client.read_attributes([n for _, n in known], AttributeIds.DataType)
            for (p, _), dv in zip(known, dvs, strict=True):
                kind = dv.Value.Value if dv.Value is not None else None
                self._types[p.name] = (_WRITE_TYPES.get(kind, ua.VariantType.Double)
                                       if isinstance(kind, ua.NodeId) else ua.VariantType.Double)
        self._nodes = nodes

    def _connected_client(self) -> Client | None:
        c = self.client
        return c if c is not None and c.uaclient.state is UaClientState.CONNECTED else None

    def _bad(self, p: Point, byte: int) -> tuple[float, int]:
        """Point ``p`` Bad with ``byte``, holding its last usable value (no communication
        without one is 0x18, NaN)."""
        last = self.last.get(p.name)
        if byte & 0xFC == st.BAD_NO_COMM_LUV:
            byte = st.BAD_NO_COMM_LUV if last is not None else st.BAD_NO_COMM_NO_LUV
        return (math.nan if last is None else last, byte)

    async def read(self) -> dict[str, tuple[float, int]]:
        """Every device output as (value, status byte) (module docstring), and the read-back
        of the last written outputs compared."""
        self.counters.reads += 1
        dvs: dict[str, ua.DataValue] | None = None
        if await self.connect():
            client = self._connected_client()
            wanted = [(p.name, n) for p in self.regmap.points
                      if (n := self._nodes.get(p.name)) is not None]
            try:
                if client is None:
                    raise ConnectionError("the link went down")
                got = await asyncio.wait_for(client.read_attributes([n for _, n in wanted]),
                                             self.timeout)
                dvs = {name: dv for (name, _), dv in zip(wanted, got, strict=True)}
                if self._lost_logged or not self.counters.connected:
                    self._restored()
            except Exception as exc:  # a lost server surfaces as several exception types
                self.counters.read_errors += 1
                self._lost(f"reading the OPC UA server {self.url} failed "
                           f"({type(exc).__name__}: {exc})")
                dvs = None
        else:
            self.counters.read_errors += 1
        if dvs is None:
            return {p.name: self._bad(p, st.BAD_NO_COMM_LUV) for p in self.inputs}
        values: dict[str, tuple[float, int]] = {}
        for p in self.inputs:
            dv = dvs.get(p.name)
            if dv is None:  # its namespace is unknown on the server
                values[p.name] = self._bad(p, st.BAD_CONFIGURATION_ERROR)
                continue
            byte = fieldbus_status(dv.StatusCode if dv.StatusCode is not None else 0)
            raw = dv.Value.Value if dv.Value is not None else None
            if st.quality(byte) == st.BAD:
                values[p.name] = self._bad(p, byte)
            elif isinstance(raw, bool) or not isinstance(raw, int | float):
                values[p.name] = self._bad(p, st.BAD_CONFIGURATION_ERROR)
            elif not math.isfinite(raw):
                values[p.name] = self._bad(p, st.BAD_DEVICE_FAILURE)
            else:
                self.last[p.name] = float(raw)
                values[p.name] = (float(raw), byte)
        for p in self.outputs:
            dv = dvs.get(p.name)
            if p.name not in self.written or dv is None:
                continue
            raw = dv.Value.Value if dv.Value is not None else None
            want = self.written[p.name]
            if not (isinstance(raw, int | float) and not isinstance(raw, bool)
                    and abs(raw - want) <= READBACK_TOLERANCE * max(1.0, abs(want))):
                self.counters.readback_mismatches += 1
                code = dv.StatusCode.name if dv.StatusCode is not None else "Good"
                self._event(f"read-back of {p.name}: wrote {want:.6g}, the server holds "
                            f"{raw!r} ({code})")
        return values

    async def write(self, values: dict[str, float]) -> bool:
        """Write the controller outputs (point name -> value) in one request; False when any
        write failed (the point's value stays unwritten; the device applies its fault
        action)."""
        client = self._connected_client()
        if client is None:
            return False
        ok = True
        points: list[tuple[Point, Node, ua.Variant, float]] = []
        for p in self.outputs:
            if p.name not in values:
                continue
            value = float(values[p.name])
            node = self._nodes.get(p.name)
            if not math.isfinite(value):
                self._event(f"{p.name}: not written, value {value!r} is not finite")
                ok = False
                continue
            if node is None:
                ok = False
                continue
            kind = self._types.get(p.name, ua.VariantType.Double)
            points.append((p, node, ua.Variant(value, kind), value))
        if not points:
            return ok
        self.counters.writes += len(points)
        try:
            results = await asyncio.wait_for(client.write_values(
                [n for _, n, _, _ in points], [v for _, _, v, _ in points],
                raise_on_partial_error=False), self.timeout)
        except Exception as exc:
            self.counters.write_errors += len(points)
            self._lost(f"writing to the OPC UA server {self.url} failed "
                       f"({type(exc).__name__}: {exc})")
            return False
        for (p, _, _, value), code in zip(points, results, strict=True):
            if code.is_good():
                self.written[p.name] = value
                if self._refused.pop(p.name, None) is not None:
                    self._event(f"{p.name}: written again", logging.INFO)
                continue
            ok = False
            self.counters.write_errors += 1
            name = code.name
            if self._refused.get(p.name) != name:
                self._refused[p.name] = name
                self._event(f"writing {p.name} = {value:.6g}: refused by the server ({name})")
        return ok

    def _drop(self) -> None:
        client, self.client = self.client, None
        self._was_connected = False
        if client is not None:
            client.uaclient.request_disconnect()  # stops its reconnecting supervisor
            with contextlib.suppress(Exception):
                client.disconnect_socket()

    def close(self) -> None:
        """Drop the connection now (no session close: :meth:`aclose` does that)."""
        self._drop()
        self.counters.connected = False

    async def aclose(self) -> None:
        """Close the session and the connection."""
        client = self.client
        if client is not None and client.uaclient.state is UaClientState.CONNECTED:
            with contextlib.suppress(Exception):
                await asyncio.wait_for(client.disconnect(), 2 * self.timeout)
        self.close()

    def status(self) -> dict[str, Any]:
        """The counters, JSON-able (the keys of ``ModbusIO.status``)."""
        c = self.counters
        return {"connected": c.connected, "reads": c.reads, "read_errors": c.read_errors,
                "writes": c.writes, "write_errors": c.write_errors,
                "readback_mismatches": c.readback_mismatches, "reconnects": c.reconnects}
