"""The simulated field device's points on an OPC UA server as well (``loopworks device
--opcua-port N``): the same points as its Modbus map, for a controller that speaks OPC UA
(:mod:`loopworks.live.opcua_io`) or any OPC UA client.

Address space (namespace :data:`~loopworks.live.registers.DEVICE_NAMESPACE`,
``urn:loopworks:device``)::

    Objects/device/<point>      NodeId ns=<idx>;s=<point name>, e.g. "sensor.pv", "valve.op"

Every point is a Double node:

- a **device output** (what the controller reads: a transmitter's ``pv``) is read-only and
  written after every device scan with status Good and the scan's time as its source
  timestamp, as a double (the Modbus registers hold the float32 of the same value);
- a **device input** (what the controller writes: a valve's ``op``) is writable by any
  client, anonymous included: this is a simulated field device on loopback, with no users.
  A write goes to the plant like a Modbus write (:meth:`Device.write_input`): at the next
  scan, counting for the fault-state timer whichever protocol wrote it (the latest write of
  either wins, and is copied into the input's registers). A value that is not a Double is
  refused with BadTypeMismatch (asyncua's check), a NaN or infinite one, or one beyond the
  float32 range its registers hold (±3.4e38), with BadOutOfRange (logged; the plant keeps
  its input). The node shows the value the device holds (what
  either protocol wrote last).

Security: NoSecurity, anonymous, and so only on a loopback address (127.0.0.1, ::1,
localhost); another host is refused with an InputError, as
:class:`~loopworks.live.opcua.LoopServer` refuses one without a certificate.
"""

from __future__ import annotations

import datetime as dt
import logging
import math
from collections.abc import Awaitable, Callable
from typing import cast

from asyncua import ua
from asyncua.crypto.permission_rules import User as UaUser
from asyncua.crypto.permission_rules import UserRole
from asyncua.server.server import Server
from asyncua.ua.attribute_ids import AttributeIds

from loopworks.errors import InputError
from loopworks.live.device import F32_MAX, Device
from loopworks.live.opcua import _code, _is_loopback, _nid
from loopworks.live.registers import DEVICE_NAMESPACE

log = logging.getLogger("loopworks.device")

#: the endpoint's path: opc.tcp://HOST:PORT/loopworks/device/
PATH = "/loopworks/device/"


class DeviceOpcua:
    """The OPC UA server of ``device`` (module docstring): ``await start()`` -> endpoint URL,
    ``await stop()``; it may be started again after a stop (same port when it was given).
    The device must scan (``Device.start`` and ``Device.run``) for the outputs to move."""

    def __init__(self, device: Device, host: str = "127.0.0.1", port: int = 4841) -> None:
        if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
            raise InputError(f"OPC UA port = {port!r} is not allowed: expected 0..65535 (0: "
                             "any free port)")
        if not _is_loopback(host):
            raise InputError(f"device OPC UA server on host {host!r}: it offers only "
                             "NoSecurity with anonymous writes, which is allowed on a loopback "
                             "address only (127.0.0.1, ::1, localhost)")
        self.device = device
        self.host = host
        self.port = port
        self.server: Server | None = None
        self.endpoint: str | None = None
        self.namespace_index: int | None = None
        self._nodes: dict[str, ua.NodeId] = {}
        self._inputs: dict[ua.NodeId, str] = {}
        self._shown: dict[str, float] = {}
        self._running = False
        device.add_scan_hook(self._publish)

    def node_id(self, name: str) -> ua.NodeId:
        """The NodeId of point ``name`` (after :meth:`start`)."""
        return self._nodes[name]

    async def start(self) -> str:
        """Build the address space (first start only) and serve; returns the endpoint URL
        (with the bound port when ``port`` is 0)."""
        if self._running:
            raise InputError("the device's OPC UA server is serving already: stop() it first")
        host = f"[{self.host}]" if ":" in self.host else self.host
        if self.server is None:
            server = Server()
            await server.init()
            server.set_server_name("loopworks device")
            await server.set_application_uri("urn:loopworks:device:server")
            server.set_endpoint(f"opc.tcp://{host}:{self.port}{PATH}")
            server.set_security_policy([ua.SecurityPolicyType.NoSecurity])
            server.set_identity_tokens([ua.AnonymousIdentityToken])
            idx = await server.register_namespace(DEVICE_NAMESPACE)
            self.namespace_index = idx
            await self._build(server, idx)
            self._intercept_writes(server)
            self.server = server
        try:
            await self.server.start()
        except OSError as exc:
            raise InputError(f"cannot serve OPC UA on {self.host}:{self.port} ({exc}): is the "
                             "port in use?") from None
        self._running = True
        bserver = self.server.bserver
        bound = bserver.port if bserver is not None and bserver.port else self.port
        if self.port == 0:  # a restart binds the same port again
            self.port = int(bound)
            self.server.set_endpoint(f"opc.tcp://{host}:{bound}{PATH}")
        self.endpoint = f"opc.tcp://{host}:{bound}{PATH}"
        await self._publish()
        log.info("t = %g s: serving OPC UA on %s (NoSecurity, anonymous; namespace %s): %d "
                 "points", self.device.plant_time, self.endpoint, DEVICE_NAMESPACE,
                 len(self._nodes))
        return self.endpoint

    async def stop(self) -> None:
        """Stop serving (clients are disconnected); the device keeps scanning."""
        if self.server is not None and self._running:
            self._running = False
            await self.server.stop()
            log.info("t = %g s: OPC UA server stopped", self.device.plant_time)

    # --- internals ---

    async def _build(self, server: Server, idx: int) -> None:
        root = await server.nodes.objects.add_object(_nid("device", idx),
                                                     ua.QualifiedName("device", idx))
        values = self.device.output_values()
        for p in self.device.regmap.points:
            nodeid = _nid(p.name, idx)
            value = self.device.values[p.name] if p.direction == "input" else values[p.name]
            node = await root.add_variable(nodeid, ua.QualifiedName(p.name, idx),
                                           ua.Variant(value, ua.VariantType.Double))
            what = ("device input, written by the controller" if p.direction == "input"
                    else "device output, read by the controller")
            await node.write_attribute(AttributeIds.Description, ua.DataValue(
                ua.Variant(ua.LocalizedText(f"{p.name}: {what}"), ua.VariantType.LocalizedText)))
            if p.direction == "input":
                await node.set_writable()
                self._inputs[nodeid] = p.name
            self._nodes[p.name] = nodeid

    async def _publish(self) -> None:
        """After a device scan: the outputs (Good), and each input the device holds when a
        client's write is not pending."""
        server = self.server
        if server is None or not self._running:
            return
        now = cast(ua.DateTime, dt.datetime.now(dt.UTC))
        good = _code("Good")
        for name, value in self.device.output_values().items():
            await server.write_attribute_value(self._nodes[name], ua.DataValue(
                ua.Variant(value, ua.VariantType.Double), StatusCode=good,
                SourceTimestamp=now, ServerTimestamp=now))
        for name, value in self.device.values.items():
            if self.device.pending(name) or self._shown.get(name) == value:
                continue
            self._shown[name] = value
            await server.write_attribute_value(self._nodes[name], ua.DataValue(
                ua.Variant(value, ua.VariantType.Double), StatusCode=good,
                SourceTimestamp=now, ServerTimestamp=now))

    def _intercept_writes(self, server: Server) -> None:
        """A client's write of an input node: refused when not finite, else written (asyncua
        checks access and type) and handed to the device."""
        service = server.iserver.attribute_service
        original: Callable[..., Awaitable[list[ua.StatusCode]]] = service.write

        async def write(params: ua.WriteParameters,
                        user: UaUser | None = None) -> list[ua.StatusCode]:
            if user is None or user.role == UserRole.Admin:  # the server's own writes
                return await original(params, user=user or UaUser(role=UserRole.Admin))
            results: list[ua.StatusCode] = []
            for item in params.NodesToWrite:
                name = self._inputs.get(item.NodeId)
                one = ua.WriteParameters(NodesToWrite=[item])
                if name is None or item.AttributeId != AttributeIds.Value:
                    results += await original(one, user=user)
                    continue
                variant = item.Value.Value if item.Value is not None else None
                raw = variant.Value if variant is not None else None
                if (variant is not None and variant.VariantType == ua.VariantType.Double
                        and isinstance(raw, float) and not abs(raw) <= F32_MAX):
                    # beyond the float32 its registers hold (1e300: +inf in them; found by an
                    # outside audit) as a NaN or infinite value is
                    why = "not finite" if not math.isfinite(raw) else "beyond the float32 range"
                    log.warning("t = %g s: OPC UA write %s = %r refused (BadOutOfRange): %s; "
                                "the plant keeps %g", self.device.plant_time, name, raw, why,
                                self.device.values[name])
                    results.append(_code("BadOutOfRange"))
                    continue
                [code] = await original(one, user=user)
                if code.is_good() and isinstance(raw, float):
                    self.device.write_input(name, raw)
                    self._shown.pop(name, None)
                results.append(code)
            return results

        service.write = write  # type: ignore[method-assign]
