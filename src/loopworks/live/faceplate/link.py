"""The faceplate's link to a running controller: one OPC UA client that browses every loop
once per connection and then reads all their values every ``period`` seconds.

``Link(url)`` is run as a task (``await link.run()``). Each connection:

1. a new asyncua ``Client`` connects anonymously (reads only);
2. ``Objects/loopworks/<loop>/<NAME>`` is browsed once: each variable's NodeId, data type,
   description, engineering units (the ``EngineeringUnits`` property), whether it is
   writable, and for a mode its ``EnumStrings``;
3. then one Read request of every variable every ``period`` s; each poll becomes a
   :class:`Sample` handed to every subscriber (the SSE streams) and appended to each loop's
   trend history (PV, SP, OUT).

A failed read (the server gone: ``ConnectionError`` at once; a stalled one: the request
timeout) marks the link down: every value is **stale** from then on, a gap is put in the
trends, the client is dropped and a new one is tried with backoff (0.5 s to 2 s) until the
controller is back (a reconnecting asyncua Client can hang, a new one does not). A
controller whose ``SCANS`` counter stops moving for :data:`STILL_AFTER` s while its server
still answers is shown as not scanning: its values are stale too.

Writes go through the OPC UA session of the user who makes them (``write(client, ...)``),
so the controller checks that user's role and logs the write under that name; anonymous
writes go through the link's own session, and the controller refuses them. A refusal's reason
(``SP = 150 is outside 0..100``) is read from the loop's ``LAST_REFUSAL`` node right after it
(``loopworks.live.opcua``): the OPC UA answer itself is a status code only. A user's session
waits :data:`WRITE_TIMEOUT` s for an answer, longer than ``serve`` takes to answer
``BadTimeout`` for a stalled controller (which guarantees such a write is never made later).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import time
from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

from asyncua import ua
from asyncua.client.client import Client
from asyncua.ua.attribute_ids import AttributeIds
from asyncua.ua.status_codes import get_name_and_doc
from asyncua.ua.uaerrors import UaError, UaStatusCodeError

from loopworks.live.opcua import LAST_REFUSAL
from loopworks.live.supervisor import REPLY_TIMEOUT

log = logging.getLogger("loopworks.faceplate")

NAMESPACE = "urn:loopworks"
DEFAULT_URL = "opc.tcp://127.0.0.1:4840/loopworks/"
#: seconds of trend kept per loop
HISTORY_SECONDS = 900.0
#: seconds without a new SCANS count before a loop's values are shown stale
STILL_AFTER = 3.0
#: the variables a trend keeps
TREND = ("PV", "SP", "OUT")
#: seconds a user's write waits for the controller's answer: longer than serve's own
#: REPLY_TIMEOUT, so a stalled controller is answered by serve's BadTimeout
WRITE_TIMEOUT = REPLY_TIMEOUT + 2.0
_ERRORS = (ConnectionError, OSError, TimeoutError, asyncio.TimeoutError, UaError)


@dataclass
class Point:
    """One variable of a loop, as browsed."""

    name: str
    nodeid: ua.NodeId
    vtype: ua.VariantType
    units: str = ""
    description: str = ""
    writable: bool = False
    enum: list[str] = field(default_factory=list)

    def meta(self) -> dict[str, Any]:
        return {"units": self.units, "description": self.description,
                "writable": self.writable, "enum": self.enum,
                "type": self.vtype.name}


@dataclass
class Value:
    """A value as read: ``value`` (None when Bad), the status code's name and its quality
    (``good``, ``uncertain``, ``bad``)."""

    value: float | int | str | None
    status: str
    quality: str

    def json(self) -> list[Any]:
        return [self.value, self.status, self.quality]


def _quality(code: ua.StatusCode) -> str:
    if code.is_good():
        return "good"
    if code.is_uncertain():
        return "uncertain"
    return "bad"


def status_name(code: int) -> str:
    """The name of an OPC UA status code (its severity when the code carries info bits)."""
    name, _ = get_name_and_doc(code)
    if name.startswith("Unknown"):
        sc = ua.StatusCode(ua.UInt32(code))
        return "Good" if sc.is_good() else "Uncertain" if sc.is_uncertain() else "Bad"
    return name


def _value(dv: ua.DataValue) -> Value:
    code = dv.StatusCode if dv.StatusCode is not None else ua.StatusCode(ua.UInt32(0))
    raw = dv.Value.Value if dv.Value is not None else None
    if isinstance(raw, float) and not math.isfinite(raw):
        raw = None
    if not isinstance(raw, int | float | str) or isinstance(raw, bool):
        raw = None if not isinstance(raw, bool) else int(raw)
    return Value(raw, status_name(code.value), _quality(code))


class WriteError(Exception):
    """A write the controller (or the link) refused: ``code`` is the OPC UA status code name
    (``BadOutOfRange``, ``BadUserAccessDenied`` ...) or ``NotConnected``/``BadNodeIdUnknown``;
    ``message`` says what it means."""

    def __init__(self, code: str, message: str) -> None:
        super().__init__(f"{code}: {message}")
        self.code = code
        self.message = message


class Link:
    """The OPC UA link (module docstring)."""

    def __init__(self, url: str = DEFAULT_URL, *, period: float = 0.25,
                 timeout: float = 2.0, history: float = HISTORY_SECONDS) -> None:
        self.url = url
        self.period = period
        self.timeout = timeout
        self.history_seconds = history
        self.connected = False
        self.error = "not connected yet"
        self.since = time.time()
        self.version = 0  # bumped when the browsed loops change
        self.loops: dict[str, dict[str, Point]] = {}
        self.values: dict[str, dict[str, Value]] = {}
        self.history: dict[str, deque[list[float | None]]] = {}
        self.scanning: dict[str, bool] = {}
        self._scans: dict[str, tuple[Any, float]] = {}
        self.subscribers: set[asyncio.Queue[dict[str, Any]]] = set()
        self.client: Client | None = None
        self.last: dict[str, Any] = self._sample(time.time())

    # -- what the pages read ---------------------------------------------------------------

    def meta(self) -> dict[str, Any]:
        """The browsed loops and their variables' units, descriptions, writability."""
        return {"version": self.version, "url": self.url,
                "loops": {loop: {n: p.meta() for n, p in points.items()}
                          for loop, points in self.loops.items()}}

    def _link(self) -> dict[str, Any]:
        return {"connected": self.connected, "error": self.error, "since": self.since,
                "version": self.version}

    def _sample(self, now: float) -> dict[str, Any]:
        loops = {}
        for loop, values in self.values.items():
            stale = not self.connected or not self.scanning.get(loop, True)
            loops[loop] = {"stale": stale, "scanning": self.scanning.get(loop, True),
                           "values": {n: v.json() for n, v in values.items()}}
        return {"t": now, "link": self._link(), "loops": loops}

    def trend(self, loop: str, seconds: float) -> list[list[float | None]]:
        """The loop's samples [t, PV, SP, OUT] of the last ``seconds`` (None: no value)."""
        rows = self.history.get(loop, deque())
        start = time.time() - seconds
        return [r for r in rows if r[0] is not None and r[0] >= start]

    def subscribe(self, size: int = 50) -> asyncio.Queue[dict[str, Any]]:
        """A queue of samples (the oldest dropped when the reader falls ``size`` behind)."""
        q: asyncio.Queue[dict[str, Any]] = asyncio.Queue(size)
        self.subscribers.add(q)
        return q

    def unsubscribe(self, q: asyncio.Queue[dict[str, Any]]) -> None:
        self.subscribers.discard(q)

    def _broadcast(self, sample: dict[str, Any]) -> None:
        self.last = sample
        for q in list(self.subscribers):
            if q.full():
                with contextlib.suppress(asyncio.QueueEmpty):
                    q.get_nowait()
            q.put_nowait(sample)

    # -- the supervisor --------------------------------------------------------------------

    async def run(self) -> None:
        """Connect, browse, poll; on any loss mark everything stale and start again."""
        delay = 0.5
        while True:
            client = Client(self.url, timeout=self.timeout, watchdog_intervall=1.0)
            try:
                await asyncio.wait_for(client.connect(), self.timeout + 1.0)
                self.client = client
                await self._browse(client)
                self.connected, self.error, self.since = True, "", time.time()
                log.info("connected to %s: loops %s", self.url, ", ".join(self.loops))
                delay = 0.5
                await self._poll(client)
            except asyncio.CancelledError:
                await self._drop(client)
                raise
            except Exception as exc:  # any failure of the link: stale, and try again
                why = _why(exc)
                if self.connected:
                    log.warning("lost %s: %s", self.url, why)
                self._down(why)
                await self._drop(client)
                await asyncio.sleep(delay)
                delay = min(delay * 2, 2.0)

    def _down(self, why: str) -> None:
        was = self.connected
        self.connected = False
        self.error = why
        if was:
            self.since = time.time()
        now = time.time()
        for rows in self.history.values():  # a gap in the trend
            if rows and rows[-1][1:] != [None, None, None]:
                rows.append([now, None, None, None])
        self._broadcast(self._sample(now))

    async def _drop(self, client: Client) -> None:
        self.client = None
        with contextlib.suppress(Exception):
            await asyncio.wait_for(client.disconnect(), 1.0)

    async def _browse(self, client: Client) -> None:
        idx = await client.get_namespace_index(NAMESPACE)
        root = await client.nodes.objects.get_child(f"{idx}:loopworks")
        loops: dict[str, dict[str, Point]] = {}
        for obj in await root.get_children():
            if await obj.read_node_class() != ua.NodeClass.Object:
                continue
            loop = str((await obj.read_browse_name()).Name)
            points: dict[str, Point] = {}
            for node in await obj.get_children():
                if await node.read_node_class() != ua.NodeClass.Variable:
                    continue
                name = str((await node.read_browse_name()).Name)
                desc = (await node.read_description()).Text or ""
                vtype = await node.read_data_type_as_variant_type()
                level = (await node.read_attribute(AttributeIds.AccessLevel)).Value
                access = int(level.Value) if level is not None and level.Value else 0
                point = Point(name, node.nodeid, vtype, description=desc,
                              writable=bool(access & ua.AccessLevel.CurrentWrite.mask))
                for prop in await node.get_properties():
                    pname = str((await prop.read_browse_name()).Name)
                    if pname == "EngineeringUnits":  # (mypy: asyncua's String is str)
                        eu = await prop.read_value()
                        point.units = eu.DisplayName.Text or ""
                    elif pname == "EnumStrings":
                        point.enum = [t.Text for t in await prop.read_value()]
                points[name] = point
            loops[loop] = points
        if {k: list(v) for k, v in loops.items()} != {k: list(v) for k, v in
                                                        self.loops.items()}:
            self.version += 1
        self.loops = loops
        for loop in loops:
            self.history.setdefault(loop, deque())
        for loop in list(self.history):
            if loop not in loops:
                del self.history[loop]
        self.values = {loop: {} for loop in loops}
        self._scans = {}

    async def _poll(self, client: Client) -> None:
        keys = [(loop, name) for loop, points in self.loops.items() for name in points]
        nodes = [client.get_node(self.loops[loop][name].nodeid) for loop, name in keys]
        next_at = time.monotonic()
        while True:
            dvs = await asyncio.wait_for(client.read_attributes(nodes), self.timeout)
            now = time.time()
            mono = time.monotonic()
            values: dict[str, dict[str, Value]] = {loop: {} for loop in self.loops}
            for (loop, name), dv in zip(keys, dvs, strict=True):
                values[loop][name] = _value(dv)
            self.values = values
            for loop, vals in values.items():
                scans = vals.get("SCANS")
                if scans is not None:
                    prev = self._scans.get(loop)
                    if prev is None or prev[0] != scans.value:
                        self._scans[loop] = (scans.value, mono)
                        self.scanning[loop] = True
                    else:
                        self.scanning[loop] = mono - prev[1] < STILL_AFTER
                row: list[float | None] = [now]
                for name in TREND:
                    v = vals.get(name)
                    ok = (v is not None and isinstance(v.value, int | float)
                          and v.quality != "bad" and self.scanning.get(loop, True))
                    row.append(float(v.value) if ok and v is not None
                               and v.value is not None else None)
                rows = self.history[loop]
                rows.append(row)
                while rows and rows[0][0] is not None and rows[0][0] < now - \
                        self.history_seconds:
                    rows.popleft()
            self._broadcast(self._sample(now))
            next_at += self.period
            pause = next_at - time.monotonic()
            if pause < 0:
                next_at = time.monotonic()
                pause = 0
            await asyncio.sleep(pause)

    # -- writes ----------------------------------------------------------------------------

    def variant(self, loop: str, name: str, value: Any) -> ua.Variant:
        """The value an operator typed as a Variant of the node's data type (a mode by name
        or code), or WriteError(BadNodeIdUnknown / BadTypeMismatch)."""
        point = self.loops.get(loop, {}).get(name)
        if point is None:
            raise WriteError("BadNodeIdUnknown", f"no variable {loop}.{name}")
        if isinstance(value, str) and point.enum:
            text = value.strip().upper()
            if text not in point.enum:
                raise WriteError("BadOutOfRange", f"{name} = {value!r}: expected one of "
                                 f"{', '.join(point.enum)}")
            return ua.Variant(point.enum.index(text), point.vtype)
        try:
            number = float(value)
        except (TypeError, ValueError):
            raise WriteError("BadTypeMismatch", f"{name} = {value!r}: expected a number") \
                from None
        if not math.isfinite(number):
            raise WriteError("BadOutOfRange", f"{name} = {value!r}: expected a finite number")
        if point.vtype in (ua.VariantType.Double, ua.VariantType.Float):
            return ua.Variant(number, point.vtype)
        if number != int(number):
            raise WriteError("BadTypeMismatch", f"{name} = {value!r}: expected a whole number")
        return ua.Variant(int(number), point.vtype)

    async def write(self, client: Client | None, loop: str, name: str, value: Any,
                    user: str | None = None) -> None:
        """Write ``loop.name`` through ``client`` (the session of ``user``; None: this link's
        own, anonymous one); raises WriteError with the controller's status code when
        refused, and its reason when the server gave it (:meth:`reason`), else the code's
        stock text."""
        variant = self.variant(loop, name, value)
        client = client or self.client
        if client is None or not self.connected:
            raise WriteError("NotConnected", "the faceplate has no link to the controller")
        node = client.get_node(self.loops[loop][name].nodeid)
        try:
            await asyncio.wait_for(node.write_value(ua.DataValue(variant)), WRITE_TIMEOUT + 1.0)
        except UaStatusCodeError as exc:
            code = status_name(exc.code)
            _, doc = get_name_and_doc(exc.code)
            why = await self.reason(client, loop, f"{user or 'anonymous'} {name} {code}: ")
            raise WriteError(code, why or doc) from None

    async def reason(self, client: Client, loop: str, prefix: str) -> str | None:
        """The reason of the refusal the loop's LAST_REFUSAL node holds when its text starts
        with ``prefix`` (``"op SP BadOutOfRange: "``: this user's refusal of this write), else
        None (an older server without the node, another write refused since)."""
        point = self.loops.get(loop, {}).get(LAST_REFUSAL)
        if point is None:
            return None
        try:
            text = await asyncio.wait_for(client.get_node(point.nodeid).read_value(),
                                          self.timeout)
        except Exception:  # the reason is a courtesy: the refusal stands without it
            return None
        if isinstance(text, str) and text.startswith(prefix) and len(text) > len(prefix):
            return text[len(prefix):]
        return None


def _why(exc: BaseException) -> str:
    if isinstance(exc, asyncio.TimeoutError | TimeoutError):
        return "the controller did not answer in time"
    if isinstance(exc, ConnectionError | OSError):
        return f"no connection to the controller ({exc.__class__.__name__}: {exc})"
    if isinstance(exc, UaStatusCodeError):
        return f"the controller answered {status_name(exc.code)}"
    return f"{exc.__class__.__name__}: {exc}"


def is_link_error(exc: BaseException) -> bool:
    """Whether ``exc`` is a lost or stalled connection (rather than a refusal)."""
    return isinstance(exc, _ERRORS) and not isinstance(exc, UaStatusCodeError)


def flatten(rows: Iterable[list[float | None]]) -> list[list[float | None]]:
    """Rows [t, PV, SP, OUT] as uPlot's columns [[t...], [PV...], [SP...], [OUT...]]."""
    cols: list[list[float | None]] = [[], [], [], []]
    for row in rows:
        for i in range(4):
            cols[i].append(row[i])
    return cols
