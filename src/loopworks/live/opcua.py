"""The soft controller's own OPC UA server: every loop's variables, who may write them.

``LoopServer(controller, users)`` exposes a running controller (``loopworks serve``) through
asyncua. The controller is anything with the two methods of ``Controller``:

- ``loops() -> {loop: [Variable, ...]}``, called once by ``start()``;
- ``write(user, role, loop, name, value)``, called for each write an operator's client makes;
  it raises ``WriteRefused(code, message)`` to refuse one (range, mode rules), ``code`` being
  an OPC UA status code name such as ``"BadOutOfRange"`` or ``"BadInvalidState"``;

and it pushes its values each scan with ``await server.publish({"pid.PV": (value, status)})``,
``status`` being the Fieldbus status byte (``loopworks.blocks.status``), mapped to an OPC UA
status code by ``opcua_status``.

Address space (namespace ``urn:loopworks``)::

    Objects/loopworks/<loop>/<NAME>      NodeId ns=<idx>;s=<loop>.<NAME>, e.g. "pid.PV"

- ``double`` variables are Double nodes; ``int`` ones (counters such as SCANS) Int64 nodes;
- a ``mode`` variable (MODE) is an Int32 node (0 OOS, 1 IMAN, 2 LO, 3 MAN, 4 AUTO, 5 CAS)
  with the standard ``EnumStrings`` property (LocalizedText[], index = code: what UaExpert and
  other Part 8 aware clients use to show the name), plus a read-only companion String node
  ``<NAME>_TEXT`` (``pid.MODE_TEXT`` = ``"AUTO"``), which any client, however generic, shows
  as the mode's name. Clients write MODE as an integer code (a mode name as a String is
  accepted as well);
- units are the ``EngineeringUnits`` property (EUInformation, UnitId -1: no UNECE code) and
  also appear in the Description (``"Process variable [degC]"``);
- every loop has a read-only String node ``<loop>.LAST_REFUSAL`` set by the server: the last
  write to the loop it refused, ``"<user> <NAME> <code>: <reason>"`` (``"op SP
  BadOutOfRange: SP = 150 is outside 0..100"``; ``anonymous`` for a client without a user).
  An OPC UA write answers a status code only; a client that wants the reason (the faceplate)
  reads it right after a refusal.

Identity: anonymous clients may read and never write. With a ``Users`` file, clients may log in
with a user name and password (checked at session activation: a wrong password is refused with
BadUserAccessDenied, the connection fails). Writes by anonymous clients and viewers are refused
with BadUserAccessDenied, writes to read-only variables with BadNotWritable; an operator's
write goes to ``controller.write`` and a ``WriteRefused`` is answered with its code. Each
write, accepted or refused, is logged on the ``loopworks.serve`` logger with user, node, value
and outcome, and a refusal is put on the loop's ``LAST_REFUSAL`` node before it is answered.
An accepted write does not change the node: its value is what the controller
publishes next (a clamped SP shows clamped).

Writes are intercepted per item by wrapping the server's attribute service ``write`` (the
asyncua entry point that knows the session's user and returns one status code per item);
``set_attribute_value_setter`` sees neither the user nor can it answer a code per item.

Security: the server binds to 127.0.0.1 unless told otherwise. Without a certificate it offers
only NoSecurity (passwords then travel in clear text), and refuses to start on a host that is
not a loopback address. With ``certificate_dir`` it generates a self-signed certificate there
on first start (RSA 2048, ``cryptography``; reused afterwards) and offers Basic256Sha256 and
Aes256_Sha256_RsaPss, Sign & Encrypt (clients then need a certificate of their own, even to
log in with a password); NoSecurity is still offered on loopback, never elsewhere.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import hashlib
import hmac
import inspect
import ipaddress
import logging
import math
import os
import secrets
import socket
from collections.abc import Awaitable, Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, Protocol, cast

from asyncua import ua
from asyncua.common.callback import CallbackType
from asyncua.crypto.permission_rules import User as UaUser
from asyncua.crypto.permission_rules import UserRole
from asyncua.server.server import Server
from asyncua.ua.attribute_ids import AttributeIds
from asyncua.ua.object_ids import ObjectIds
from asyncua.ua.status_codes import StatusCodes

from loopworks.blocks import status as st
from loopworks.errors import InputError

if TYPE_CHECKING:
    from asyncua.server.internal_server import InternalServer

    from loopworks.live.users import Users

log = logging.getLogger("loopworks.serve")

NAMESPACE = "urn:loopworks"
#: the read-only String node of each loop that holds the last refused write and its reason
LAST_REFUSAL = "LAST_REFUSAL"
APPLICATION_URI = "urn:loopworks:serve"
MODES: tuple[str, ...] = ("OOS", "IMAN", "LO", "MAN", "AUTO", "CAS")
Kind = Literal["double", "mode", "int"]
KINDS: tuple[str, ...] = ("double", "mode", "int")
_VARIANT = {"double": ua.VariantType.Double, "mode": ua.VariantType.Int32,
            "int": ua.VariantType.Int64}
_INTEGER_TYPES = {ua.VariantType.SByte, ua.VariantType.Byte, ua.VariantType.Int16,
                  ua.VariantType.UInt16, ua.VariantType.Int32, ua.VariantType.UInt32,
                  ua.VariantType.Int64, ua.VariantType.UInt64}
_NUMBER_TYPES = _INTEGER_TYPES | {ua.VariantType.Float, ua.VariantType.Double}
_UNECE = "http://www.opcfoundation.org/UA/units/un/cefact"


# --- the interface to the controller ------------------------------------------------------

@dataclass(frozen=True)
class Variable:
    """One variable of a loop, as the controller declares it to the server.

    ``kind``: ``"double"`` (PV, SP, OUT, GAIN, LATE_P99_MS ...), ``"mode"`` (MODE: a code
    0..5 or a name of ``MODES``) or ``"int"`` (SCANS, OVERRUNS ...). ``value`` is the initial
    value (shown, with status Good, until the first ``publish``)."""

    name: str
    value: float | int | str
    kind: Kind
    writable: bool
    units: str = ""
    description: str = ""


class WriteRefused(Exception):
    """Raised by ``Controller.write`` to refuse a write: ``code`` is the name of a Bad OPC UA
    status code (``"BadOutOfRange"``, ``"BadInvalidState"``, ``"BadUserAccessDenied"``,
    ``"BadTypeMismatch"``, ``"BadNotWritable"`` ...) that the client receives."""

    def __init__(self, code: str, message: str) -> None:
        value = getattr(StatusCodes, code, None)
        if not isinstance(value, int) or not ua.StatusCode(ua.UInt32(value)).is_bad():
            raise ValueError(f"WriteRefused code {code!r} is not the name of a Bad OPC UA "
                             f"status code (e.g. 'BadOutOfRange')")
        super().__init__(f"{code}: {message}")
        self.code = code
        self.message = message


class Controller(Protocol):
    """What ``LoopServer`` needs of a running controller."""

    def loops(self) -> dict[str, list[Variable]]:
        """Loop name -> its variables; called once, by ``LoopServer.start``."""
        ...

    def write(self, user: str | None, role: str | None, loop: str, name: str,
              value: float | int) -> Awaitable[None] | None:
        """Apply a client's write (a float for a double, the code for a mode, an int for an
        int), or raise ``WriteRefused``. Called on the server's event loop (the one that ran
        ``start``): it must not block. A controller in another process returns an awaitable
        that raises ``WriteRefused`` or returns once the controller answered."""
        ...


# --- status ---------------------------------------------------------------------------------

_STATUS: dict[int, str] = {
    st.BAD_NON_SPECIFIC: "Bad",
    st.BAD_CONFIGURATION_ERROR: "BadConfigurationError",
    st.BAD_NOT_CONNECTED: "BadNotConnected",
    st.BAD_DEVICE_FAILURE: "BadDeviceFailure",
    st.BAD_SENSOR_FAILURE: "BadSensorFailure",
    st.BAD_NO_COMM_LUV: "BadNoCommunication",
    st.BAD_NO_COMM_NO_LUV: "BadNoCommunication",
    st.BAD_OUT_OF_SERVICE: "BadOutOfService",
    st.UNCERTAIN_NON_SPECIFIC: "Uncertain",
    st.UNCERTAIN_LAST_USABLE_VALUE: "UncertainLastUsableValue",
    st.UNCERTAIN_SUBSTITUTE: "UncertainSubstituteValue",
    st.UNCERTAIN_INITIAL_VALUE: "UncertainInitialValue",
    st.UNCERTAIN_SENSOR_CONVERSION: "UncertainSensorNotAccurate",
    st.UNCERTAIN_EU_RANGE_VIOLATION: "UncertainEngineeringUnitsExceeded",
    st.UNCERTAIN_SUB_NORMAL: "UncertainSubNormal",
    st.GOOD_C_NON_SPECIFIC: "GoodCascade",
    st.GOOD_C_IA: "GoodCascadeInitializationAcknowledged",
    st.GOOD_C_IR: "GoodCascadeInitializationRequest",
    st.GOOD_C_NI: "GoodCascadeNotInvited",
    st.GOOD_C_NS: "GoodCascadeNotSelected",
    st.GOOD_C_LO: "GoodLocalOverride",
    st.GOOD_C_FSA: "GoodFaultStateActive",
    st.GOOD_C_IFS: "GoodInitiateFaultState",
}
_QUALITY_DEFAULT = {st.BAD: "Bad", st.UNCERTAIN: "Uncertain", st.GOOD_NC: "Good",
                    st.GOOD_CASCADE: "GoodCascade"}
_INFO_DATAVALUE = 0x400  # StatusCode InfoType = DataValue: bits 8-9 are then the limit bits


def opcua_status(byte: int) -> ua.StatusCode:
    """The OPC UA status code (Part 8 §6.3 / Part 4 §7.39) of a Fieldbus status byte.

    =====  ==============================  ===========================================
    byte   Fieldbus quality: substatus     OPC UA status code
    =====  ==============================  ===========================================
    0x00   Bad: non-specific               Bad
    0x04   Bad: configuration error        BadConfigurationError
    0x08   Bad: not connected              BadNotConnected
    0x0C   Bad: device failure             BadDeviceFailure
    0x10   Bad: sensor failure             BadSensorFailure
    0x14   Bad: no comm, last usable val.  BadNoCommunication
    0x18   Bad: no comm, no usable value   BadNoCommunication
    0x1C   Bad: out of service             BadOutOfService
    0x40   Uncertain: non-specific         Uncertain
    0x44   Uncertain: last usable value    UncertainLastUsableValue
    0x48   Uncertain: substitute           UncertainSubstituteValue
    0x4C   Uncertain: initial value        UncertainInitialValue
    0x50   Uncertain: sensor conversion    UncertainSensorNotAccurate
    0x54   Uncertain: EU range violation   UncertainEngineeringUnitsExceeded
    0x58   Uncertain: sub-normal           UncertainSubNormal
    0x80   Good NC: non-specific           Good
    0x84-  Good NC: active/unacknowledged  Good (OPC UA carries alarms as events, not in
    0x98   block/advisory/critical alarm   a value's status)
    0xC0   Good cascade: non-specific      GoodCascade
    0xC4   Good cascade: init. acknowl.    GoodCascadeInitializationAcknowledged
    0xC8   Good cascade: init. request     GoodCascadeInitializationRequest
    0xCC   Good cascade: not invited       GoodCascadeNotInvited
    0xD0   Good cascade: not selected      GoodCascadeNotSelected
    0xD8   Good cascade: local override    GoodLocalOverride
    0xDC   Good cascade: fault state act.  GoodFaultStateActive
    0xE0   Good cascade: init. fault st.   GoodInitiateFaultState
    other  undefined substatus             the quality's generic code: Bad, Uncertain,
                                           Good, GoodCascade
    =====  ==============================  ===========================================

    Limit bits (1-0: 1 low, 2 high, 3 constant) become the StatusCode's LimitBits (bits 8-9,
    with InfoType DataValue, bit 10), e.g. 0x82 (Good, high limited) -> 0x00000600. Clients
    test ``is_good()/is_uncertain()/is_bad()`` as usual; asyncua's ``.name`` only knows codes
    without info bits, so it shows the generic severity name for a limited value.

    OPC UA servers replace the value of a Bad status with Null (Part 4 §7.7.1; asyncua does):
    the server publishes Bad with the value anyway and clients read None.
    """
    byte = st.check_byte(byte)
    name = _STATUS.get(byte & 0xFC) or _QUALITY_DEFAULT[st.quality(byte)]
    value: int = getattr(StatusCodes, name)
    if st.limits(byte):
        value |= _INFO_DATAVALUE | (st.limits(byte) << 8)
    return ua.StatusCode(ua.UInt32(value))


#: the inverse of ``opcua_status``: an OPC UA status code (a StatusCodes name) read from a
#: server -> the Fieldbus status byte a block takes. Every code of ``_STATUS`` maps back to its
#: byte (BadNoCommunication to 0x14, with the last usable value: a reader without one makes
#: it 0x18); a few more codes a server may send map to the byte that means the same.
_FROM_OPCUA: dict[str, int] = {
    "Good": st.GOOD_NC,
    "GoodCascade": st.GOOD_C_NON_SPECIFIC,
    "GoodCascadeInitializationAcknowledged": st.GOOD_C_IA,
    "GoodCascadeInitializationRequest": st.GOOD_C_IR,
    "GoodCascadeNotInvited": st.GOOD_C_NI,
    "GoodCascadeNotSelected": st.GOOD_C_NS,
    "GoodLocalOverride": st.GOOD_C_LO,
    "GoodFaultStateActive": st.GOOD_C_FSA,
    "GoodInitiateFaultState": st.GOOD_C_IFS,
    "Uncertain": st.UNCERTAIN_NON_SPECIFIC,
    "UncertainLastUsableValue": st.UNCERTAIN_LAST_USABLE_VALUE,
    "UncertainSubstituteValue": st.UNCERTAIN_SUBSTITUTE,
    "UncertainInitialValue": st.UNCERTAIN_INITIAL_VALUE,
    "UncertainSensorNotAccurate": st.UNCERTAIN_SENSOR_CONVERSION,
    "UncertainEngineeringUnitsExceeded": st.UNCERTAIN_EU_RANGE_VIOLATION,
    "UncertainSubNormal": st.UNCERTAIN_SUB_NORMAL,
    "Bad": st.BAD_NON_SPECIFIC,
    "BadConfigurationError": st.BAD_CONFIGURATION_ERROR,
    "BadNodeIdUnknown": st.BAD_CONFIGURATION_ERROR,
    "BadNodeIdInvalid": st.BAD_CONFIGURATION_ERROR,
    "BadNotReadable": st.BAD_CONFIGURATION_ERROR,
    "BadUserAccessDenied": st.BAD_CONFIGURATION_ERROR,
    "BadNotConnected": st.BAD_NOT_CONNECTED,
    "BadDeviceFailure": st.BAD_DEVICE_FAILURE,
    "BadSensorFailure": st.BAD_SENSOR_FAILURE,
    "BadNoCommunication": st.BAD_NO_COMM_LUV,
    "BadCommunicationError": st.BAD_NO_COMM_LUV,
    "BadConnectionClosed": st.BAD_NO_COMM_LUV,
    "BadServerNotConnected": st.BAD_NO_COMM_LUV,
    "BadServerHalted": st.BAD_NO_COMM_LUV,
    "BadShutdown": st.BAD_NO_COMM_LUV,
    "BadTimeout": st.BAD_NO_COMM_LUV,
    "BadWaitingForInitialData": st.BAD_NO_COMM_NO_LUV,
    "BadOutOfService": st.BAD_OUT_OF_SERVICE,
}
_FROM_CODE: dict[int, int] = {getattr(StatusCodes, name): byte
                              for name, byte in _FROM_OPCUA.items()}


def fieldbus_status(code: ua.StatusCode | int) -> int:
    """The Fieldbus status byte of an OPC UA status code read from a server (the inverse of
    :func:`opcua_status`, table ``_FROM_OPCUA``).

    =================================================  ===================================
    OPC UA status code                                 byte
    =================================================  ===================================
    Good, GoodCascade..., GoodLocalOverride ...        0x80, 0xC0..0xE0 (as opcua_status)
    Uncertain, UncertainLastUsableValue ...            0x40..0x58 (as opcua_status)
    Bad, BadConfigurationError, BadNotConnected,       0x00, 0x04, 0x08, 0x0C, 0x10, 0x1C
    BadDeviceFailure, BadSensorFailure, BadOutOfServ.
    BadNodeIdUnknown/Invalid, BadNotReadable,          0x04 configuration error
    BadUserAccessDenied
    BadNoCommunication, BadCommunicationError,         0x14 no communication (last usable
    BadConnectionClosed, BadServerNotConnected,        value; 0x18 when the reader has
    BadServerHalted, BadShutdown, BadTimeout           none)
    BadWaitingForInitialData                           0x18 no communication, no value
    any other Good / Uncertain / Bad code              0x80 / 0x40 / 0x0C device failure
    =================================================  ===================================

    LimitBits (bits 8-9, with InfoType DataValue) become the byte's limit bits."""
    value = int(code.value if isinstance(code, ua.StatusCode) else code) & 0xFFFFFFFF
    base = value & 0xFFFF0000
    byte = _FROM_CODE.get(base)
    if byte is None:
        severity = value >> 30  # 0 Good, 1 Uncertain, 2 (3) Bad
        byte = (st.GOOD_NC if severity == 0 else st.UNCERTAIN_NON_SPECIFIC if severity == 1
                else st.BAD_DEVICE_FAILURE)
    if value & _INFO_DATAVALUE:
        byte |= (value >> 8) & 0x03
    return byte


# --- the server -----------------------------------------------------------------------------

class _Identity(UaUser):  # asyncua's User, plus the loopworks role
    def __init__(self, name: str | None, loop_role: str | None) -> None:
        super().__init__(role=UserRole.User, name=name)
        self.loop_role = loop_role


class _UserManager:
    """asyncua user manager: anonymous -> reader; user name + password against ``Users``.

    A verified password is remembered (as an HMAC under a per-process random key) so that a
    client reconnecting does not cost another 45 ms scrypt on the event loop."""

    def __init__(self, users: Users | None) -> None:
        self._users = users
        self._key = secrets.token_bytes(32)
        self._verified: dict[bytes, str] = {}

    def get_user(self, iserver: InternalServer, username: str | None = None,
                 password: str | None = None, certificate: Any = None) -> UaUser | None:
        if username is None:  # anonymous (``certificate`` is then the channel's peer, if any:
            return _Identity(None, None)  # X509 identity tokens are not offered)
        if self._users is None:
            log.warning("login as %r refused: this server has no users file", username)
            return None
        given = password or ""
        mac = hmac.new(self._key, f"{username}\0{given}".encode(), hashlib.sha256).digest()
        role = self._verified.get(mac)
        if role is None:
            role = self._users.authenticate(username, given)
            if role is None:
                log.warning("login as %r refused: unknown user or wrong password", username)
                return None
            if len(self._verified) > 256:
                self._verified.clear()
            self._verified[mac] = role
        log.info("login as %r (%s)", username, role)
        return _Identity(username, role)


@dataclass
class _Node:
    loop: str
    var: Variable
    nodeid: ua.NodeId
    text_nodeid: ua.NodeId | None = None  # the <NAME>_TEXT companion of a mode


class LoopServer:
    """The OPC UA server of a running controller: ``await start()`` -> endpoint URL,
    ``await publish({...})`` each scan, ``await stop()``."""

    def __init__(self, controller: Controller, users: Users | None, host: str = "127.0.0.1",
                 port: int = 4840, *, certificate_dir: str | Path | None = None) -> None:
        self.controller = controller
        self.users = users
        self.host = host
        self.port = port
        self.certificate_dir = None if certificate_dir is None else Path(certificate_dir)
        self.server: Server | None = None
        self.endpoint: str | None = None
        self.namespace_index: int | None = None
        self._nodes: dict[str, _Node] = {}
        self._by_nodeid: dict[ua.NodeId, _Node] = {}
        self._refusals: dict[str, ua.NodeId] = {}  # loop -> its LAST_REFUSAL node

    @property
    def loopback(self) -> bool:
        """True when the server binds to a loopback address only."""
        return _is_loopback(self.host)

    def node_id(self, key: str) -> ua.NodeId:
        """The NodeId of ``"<loop>.<NAME>"`` (after ``start``)."""
        return self._nodes[key].nodeid

    async def start(self) -> str:
        """Build the address space from ``controller.loops()``, start serving; returns the
        endpoint URL (with the bound port when ``port`` is 0)."""
        if self.server is not None:
            raise RuntimeError("LoopServer.start: already started")
        if not self.loopback and self.certificate_dir is None:
            raise InputError(f"OPC UA server on host {self.host!r}: without a certificate only "
                             f"NoSecurity is available, which is allowed on a loopback address "
                             f"only (127.0.0.1, ::1, localhost); give a certificate directory "
                             f"or bind to 127.0.0.1")
        loops = self.controller.loops()
        _check_loops(loops)
        server = Server(user_manager=_UserManager(self.users))  # type: ignore[arg-type]
        await server.init()
        server.set_server_name("loopworks")
        await server.set_application_uri(APPLICATION_URI)
        host = f"[{self.host}]" if ":" in self.host else self.host
        server.set_endpoint(f"opc.tcp://{host}:{self.port}/loopworks/")
        policies = security_policies(self.loopback, self.certificate_dir is not None)
        if self.certificate_dir is not None:
            cert, key = await _self_signed(self.certificate_dir, self.host)
            await server.load_certificate(str(cert))
            await server.load_private_key(str(key))
        server.set_security_policy(policies)
        tokens: list[type] = [ua.AnonymousIdentityToken]
        if self.users is not None:
            tokens.append(ua.UserNameIdentityToken)
        server.set_identity_tokens(tokens)
        idx = await server.register_namespace(NAMESPACE)
        self.namespace_index = idx
        await self._build(server, idx, loops)
        self._intercept_writes(server)
        server.subscribe_server_callback(CallbackType.PostRead, self._user_access_level)
        await server.start()
        self.server = server
        bound = server.bserver.port if server.bserver is not None else self.port
        self.endpoint = f"opc.tcp://{host}:{bound}/loopworks/"
        log.info("OPC UA server on %s (%s), %d loops, %d variables", self.endpoint,
                 ", ".join(_policy_names(policies)), len(loops), len(self._nodes))
        return self.endpoint

    async def stop(self) -> None:
        """Stop serving (clients are disconnected)."""
        if self.server is not None:
            server, self.server = self.server, None
            await server.stop()

    async def publish(self, values: Mapping[str, tuple[float | int | str, int]]) -> None:
        """Set variables from the controller's scan: ``{"pid.PV": (value, status_byte)}``.
        Call it on the server's event loop; a key may be left out (it keeps its value).

        A Bad status is published with its value, which OPC UA clients read as None."""
        server = self.server
        if server is None:
            raise RuntimeError("LoopServer.publish: the server is not started")
        now = cast(ua.DateTime, dt.datetime.now(dt.UTC))
        for key, (value, status) in values.items():
            node = self._nodes.get(key)
            if node is None:
                raise KeyError(f"publish: {key!r} is not a variable of this server: expected "
                               f"'<loop>.<NAME>' as declared by loops()")
            code = opcua_status(status)
            variant = _variant(node.var.kind, value, key)
            await server.write_attribute_value(node.nodeid, ua.DataValue(
                variant, StatusCode=code, SourceTimestamp=now, ServerTimestamp=now))
            if node.text_nodeid is not None:
                await server.write_attribute_value(node.text_nodeid, ua.DataValue(
                    ua.Variant(MODES[variant.Value], ua.VariantType.String), StatusCode=code,
                    SourceTimestamp=now, ServerTimestamp=now))

    async def __aenter__(self) -> LoopServer:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.stop()

    # --- internals ---

    async def _build(self, server: Server, idx: int,
                     loops: Mapping[str, list[Variable]]) -> None:
        root = await server.nodes.objects.add_object(_nid("loopworks", idx),
                                                     ua.QualifiedName("loopworks", idx))
        for loop, variables in loops.items():
            obj = await root.add_object(_nid(loop, idx), ua.QualifiedName(loop, idx))
            for var in variables:
                key = f"{loop}.{var.name}"
                nodeid = _nid(key, idx)
                variant = _variant(var.kind, var.value, key)
                node = await obj.add_variable(nodeid, ua.QualifiedName(var.name, idx), variant)
                text = var.description or var.name
                if var.units:
                    text += f" [{var.units}]"
                await node.write_attribute(AttributeIds.Description, ua.DataValue(
                    ua.Variant(ua.LocalizedText(text), ua.VariantType.LocalizedText)))
                if var.units:
                    eu = ua.EUInformation(NamespaceUri=_UNECE, UnitId=-1,
                                          DisplayName=ua.LocalizedText(var.units),
                                          Description=ua.LocalizedText(var.units))
                    await node.add_property(_nid(f"{key}.EngineeringUnits", idx),
                                            ua.QualifiedName("EngineeringUnits", 0), eu,
                                            datatype=ua.NodeId(ua.Int32(ObjectIds.EUInformation)))
                if var.writable:
                    await node.set_writable()
                entry = _Node(loop, var, nodeid)
                if var.kind == "mode":
                    await node.add_property(
                        _nid(f"{key}.EnumStrings", idx), ua.QualifiedName("EnumStrings", 0),
                        [ua.LocalizedText(m) for m in MODES], ua.VariantType.LocalizedText)
                    entry.text_nodeid = _nid(f"{key}_TEXT", idx)
                    await obj.add_variable(entry.text_nodeid,
                                           ua.QualifiedName(f"{var.name}_TEXT", idx),
                                           ua.Variant(MODES[variant.Value],
                                                      ua.VariantType.String))
                self._nodes[key] = entry
                self._by_nodeid[nodeid] = entry
            refusal = _nid(f"{loop}.{LAST_REFUSAL}", idx)
            node = await obj.add_variable(refusal, ua.QualifiedName(LAST_REFUSAL, idx),
                                          ua.Variant("", ua.VariantType.String))
            await node.write_attribute(AttributeIds.Description, ua.DataValue(ua.Variant(
                ua.LocalizedText("the last write to this loop the controller refused: "
                                 "<user> <NAME> <code>: <reason>"),
                ua.VariantType.LocalizedText)))
            self._refusals[loop] = refusal

    def _intercept_writes(self, server: Server) -> None:
        service = server.iserver.attribute_service
        original: Callable[..., Awaitable[list[ua.StatusCode]]] = service.write

        async def write(params: ua.WriteParameters,
                        user: UaUser | None = None) -> list[ua.StatusCode]:
            # the server's own session (Admin) is never a client: asyncua's checks apply
            if user is None or user.role == UserRole.Admin:
                return await original(params, user=user or UaUser(role=UserRole.Admin))
            results: list[ua.StatusCode] = []
            for item in params.NodesToWrite:
                node = self._by_nodeid.get(item.NodeId)
                if node is None and item.NodeId not in server.iserver.aspace:
                    # no such node: said so, not "access denied" (asyncua checks the user's
                    # rights first; found by an operator writing a loop's missing MODE)
                    results.append(_code("BadNodeIdUnknown"))
                elif node is None and item.AttributeId == AttributeIds.Value and (
                        self._kept(item.NodeId)):
                    # a node the server keeps itself (<NAME>_TEXT, LAST_REFUSAL): read-only
                    # for everyone, so not "access denied" (asyncua checks the user first);
                    # logged and noted as every refused write is (it was neither; found by
                    # an outside audit)
                    loop, what = self._kept_name(item.NodeId)
                    raw = (item.Value.Value.Value if item.Value is not None
                           and item.Value.Value is not None else None)
                    who = f"{user.name} ({getattr(user, 'loop_role', None)})" if (
                        user.name) else "anonymous"
                    log.warning("write %s.%s = %r by %s: refused, BadNotWritable: a read-only "
                                "variable", loop, what, raw, who)
                    await self._note_refusal(loop, f"{user.name or 'anonymous'} {what} "
                                                   "BadNotWritable: a read-only variable")
                    results.append(_code("BadNotWritable"))
                elif node is None or item.AttributeId != AttributeIds.Value:
                    results += await original(ua.WriteParameters(NodesToWrite=[item]),
                                              user=user)
                else:
                    results.append(await self._client_write(user, node, item.Value))
            return results

        service.write = write  # type: ignore[method-assign]

    def _user_access_level(self, event: Any, _dispatcher: Any) -> None:
        """A read's answer as its session's user has the rights: a writable loop variable's
        ``UserAccessLevel`` (OPC UA Part 3, 5.6.2: the access level *this user* has) lacks
        CurrentWrite unless the user is an operator. A generic client offered anonymous and
        viewer sessions an editable SP that every write refused (``AccessLevel``, what the
        node allows anyone, is unchanged). Runs after every read (asyncua's PostRead
        callback); the answer's list is replaced item by item, never the stored value."""
        user = event.user
        if not isinstance(user, _Identity) or user.loop_role == "operator":
            return  # the server's own session (asyncua's Admin), or an operator
        answers = event.response_params
        for i, item in enumerate(event.request_params.NodesToRead):
            if item.AttributeId != AttributeIds.UserAccessLevel or (
                    item.NodeId not in self._by_nodeid):
                continue
            value = answers[i].Value
            if value is not None and isinstance(value.Value, int):
                answers[i] = ua.DataValue(ua.Variant(
                    value.Value & ~ua.AccessLevel.CurrentWrite.mask, ua.VariantType.Byte))

    def _kept_name(self, nodeid: ua.NodeId) -> tuple[str, str]:
        """(loop, variable name) of a node the server keeps itself (:meth:`_kept`)."""
        for loop, refusal in self._refusals.items():
            if refusal == nodeid:
                return loop, LAST_REFUSAL
        node = next(n for n in self._nodes.values() if n.text_nodeid == nodeid)
        return node.loop, f"{node.var.name}_TEXT"

    def _kept(self, nodeid: ua.NodeId) -> bool:
        """A value node the server keeps itself: a mode's ``<NAME>_TEXT`` or a loop's
        ``LAST_REFUSAL``."""
        return nodeid in self._refusals.values() or any(
            n.text_nodeid == nodeid for n in self._nodes.values())

    async def _client_write(self, user: UaUser, node: _Node,
                            dv: ua.DataValue) -> ua.StatusCode:
        """One client's write of one node: the controller's verdict as a status code; a
        refusal is logged and put on the loop's LAST_REFUSAL node before it is answered."""
        name = user.name
        role = getattr(user, "loop_role", None)
        key = f"{node.loop}.{node.var.name}"
        raw = dv.Value.Value if dv.Value is not None else None
        who = f"{name} ({role})" if name else "anonymous"
        try:
            if not node.var.writable:
                raise WriteRefused("BadNotWritable", "a read-only variable")
            if role != "operator":
                raise WriteRefused("BadUserAccessDenied", "only operators may write")
            if dv.StatusCode is not None and not dv.StatusCode.is_good():
                # a value its writer marks Bad or Uncertain is not a setting to apply (it was
                # applied as Good; found by an outside audit)
                raise WriteRefused("BadWriteNotSupported", "a value written with status "
                                   f"{dv.StatusCode.name}: the controller takes Good values")
            value = _client_value(node.var.kind, dv.Value)
            done = self.controller.write(name, role, node.loop, node.var.name, value)
            if inspect.isawaitable(done):  # a controller in another process answers later
                await done
        except WriteRefused as exc:
            log.warning("write %s = %r by %s: refused, %s: %s", key, raw, who, exc.code,
                        exc.message)
            await self._note_refusal(node.loop, f"{name or 'anonymous'} {node.var.name} "
                                                f"{exc.code}: {exc.message}")
            return _code(exc.code)
        except Exception:
            log.exception("write %s = %r by %s: refused, the controller failed", key, raw, who)
            return _code("BadInternalError")
        log.info("write %s = %r by %s: accepted", key, value, who)
        return _code("Good")

    async def _note_refusal(self, loop: str, text: str) -> None:
        """Put ``text`` on the loop's LAST_REFUSAL node (module docstring)."""
        nodeid = self._refusals.get(loop)
        if self.server is None or nodeid is None:
            return
        now = cast(ua.DateTime, dt.datetime.now(dt.UTC))
        await self.server.write_attribute_value(nodeid, ua.DataValue(
            ua.Variant(text, ua.VariantType.String), SourceTimestamp=now, ServerTimestamp=now))


# --- helpers --------------------------------------------------------------------------------

def _nid(text: str, idx: int) -> ua.NodeId:
    """The string NodeId ns=<idx>;s=<text>."""
    return ua.NodeId(ua.String(text), ua.Int16(idx))


def _code(name: str) -> ua.StatusCode:
    """The StatusCode of a StatusCodes name."""
    return ua.StatusCode(ua.UInt32(getattr(StatusCodes, name)))


def _is_loopback(host: str) -> bool:
    if host.lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def _policy_names(policies: list[ua.SecurityPolicyType]) -> list[str]:
    return [p.name for p in policies]


def _check_loops(loops: Mapping[str, list[Variable]]) -> None:
    if not loops:
        raise InputError("OPC UA server: the controller declares no loops")
    for loop, variables in loops.items():
        if not loop or "/" in loop:
            raise InputError(f"OPC UA server: loop name {loop!r}: expected a non-empty name "
                             f"without '/'")
        seen: set[str] = set()
        for var in variables:
            if var.kind not in KINDS:
                raise InputError(f"OPC UA server: {loop}.{var.name}: kind {var.kind!r}: "
                                 f"expected one of {', '.join(KINDS)}")
            if var.name == LAST_REFUSAL:
                raise InputError(f"OPC UA server: {loop}.{LAST_REFUSAL} is the server's own "
                                 f"node (the last refused write): do not declare it")
            if not var.name or var.name in seen:
                raise InputError(f"OPC UA server: loop {loop!r}: variable name {var.name!r} "
                                 f"is empty or declared twice")
            seen.add(var.name)
            if var.kind == "mode":
                if f"{var.name}_TEXT" in {v.name for v in variables}:
                    raise InputError(f"OPC UA server: {loop}.{var.name}_TEXT is the mode's "
                                     f"text node: do not declare it")
                seen.add(f"{var.name}_TEXT")


def _mode_code(value: float | int | str, key: str) -> int:
    if isinstance(value, str):
        if value.upper() in MODES:
            return MODES.index(value.upper())
    elif not isinstance(value, bool) and value == int(value) and 0 <= int(value) < len(MODES):
        return int(value)
    raise InputError(f"{key}: mode {value!r}: expected a code 0..{len(MODES) - 1} or one of "
                     f"{', '.join(MODES)}")


def _variant(kind: str, value: float | int | str, key: str) -> ua.Variant:
    """The controller's value as a Variant of the node's type (an int in a Double node would
    be refused by asyncua as a type mismatch)."""
    if kind == "mode":
        return ua.Variant(_mode_code(value, key), ua.VariantType.Int32)
    if isinstance(value, str):
        raise InputError(f"{key}: value {value!r}: expected a number")
    if kind == "double":
        return ua.Variant(float(value), ua.VariantType.Double)
    return ua.Variant(int(value), _VARIANT[kind])


def _client_value(kind: str, variant: ua.Variant | None) -> float | int:
    """A client's written value for the controller, or WriteRefused(BadTypeMismatch /
    BadOutOfRange). Any number is accepted for a double; integers (or integral numbers) for
    an int; a code 0..5 or a mode name for a mode."""
    if variant is None or variant.is_array or variant.Value is None:
        raise WriteRefused("BadTypeMismatch", f"expected a single {kind} value")
    vtype, value = variant.VariantType, variant.Value
    if kind == "mode" and vtype == ua.VariantType.String:
        if value.upper() not in MODES:
            raise WriteRefused("BadOutOfRange", f"mode {value!r}: expected one of "
                                                f"{', '.join(MODES)}")
        return MODES.index(value.upper())
    if vtype not in _NUMBER_TYPES:
        raise WriteRefused("BadTypeMismatch", f"a {vtype.name}: expected a number")
    if not math.isfinite(value):
        raise WriteRefused("BadOutOfRange", f"{value!r}: expected a finite number")
    if kind == "double":
        return float(value)
    if value != int(value):
        raise WriteRefused("BadTypeMismatch", f"{value!r}: expected a whole number")
    if kind == "mode" and not 0 <= int(value) < len(MODES):
        raise WriteRefused("BadOutOfRange", f"mode {int(value)}: expected a code "
                                            f"0..{len(MODES) - 1} ({', '.join(MODES)})")
    return int(value)


async def _self_signed(directory: Path, host: str) -> tuple[Path, Path]:
    """The server's certificate (DER) and private key (PEM, mode 0600) in ``directory``:
    generated on first use (RSA 2048, valid 5 years; subject alternative names: the
    application URI, this machine's host name, localhost and ``host`` if it is an IP address),
    and again when missing, expired or unreadable, which clients must then trust anew."""
    from asyncua.crypto import cert_gen, uacrypto
    from cryptography import x509
    from cryptography.hazmat.primitives.serialization import Encoding
    from cryptography.x509.oid import ExtendedKeyUsageOID

    cert_file = directory / "loopworks-server.der"
    key_file = directory / "loopworks-server.pem"
    hostname = socket.gethostname()
    try:
        directory.mkdir(parents=True, exist_ok=True, mode=0o700)
        if cert_file.is_file() and key_file.is_file():
            try:
                cert = await uacrypto.load_certificate(cert_file)
                await uacrypto.load_private_key(key_file)
                if not uacrypto.check_certificate(cert, APPLICATION_URI, hostname):  # no error
                    return cert_file, key_file
            except (ValueError, TypeError) as exc:  # unreadable: made again
                log.warning("%s: cannot load the certificate (%s): generating a new one",
                            directory, exc)
        key = cert_gen.generate_private_key()
        names: list[x509.GeneralName] = [x509.UniformResourceIdentifier(APPLICATION_URI),
                                         x509.DNSName(hostname), x509.DNSName("localhost")]
        with contextlib.suppress(ValueError):
            address = ipaddress.ip_address(host.strip("[]"))
            if not address.is_unspecified:
                names.append(x509.IPAddress(address))
        cert = cert_gen.generate_self_signed_app_certificate(
            key, f"loopworks serve {hostname}", {"organizationName": "loopworks"}, names,
            [ExtendedKeyUsageOID.SERVER_AUTH, ExtendedKeyUsageOID.CLIENT_AUTH], days=5 * 365)
        _write_private(key_file, cert_gen.dump_private_key_as_pem(key))
        _write_private(cert_file, cert.public_bytes(Encoding.DER))
    except OSError as exc:
        raise InputError(f"{directory}: cannot write the server certificate: "
                         f"{exc.strerror}") from None
    log.warning("generated a self-signed OPC UA server certificate %s (clients must trust "
                "it)", cert_file)
    return cert_file, key_file


def _write_private(path: Path, data: bytes) -> None:
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "wb") as out:
        out.write(data)
    os.chmod(path, 0o600)


def security_policies(loopback: bool, certificate: bool) -> list[ua.SecurityPolicyType]:
    """The security policies offered: NoSecurity on a loopback address only; with a
    certificate, Basic256Sha256 and Aes256_Sha256_RsaPss with Sign & Encrypt."""
    policies = [ua.SecurityPolicyType.NoSecurity] if loopback else []
    if certificate:
        policies += [ua.SecurityPolicyType.Basic256Sha256_SignAndEncrypt,
                     ua.SecurityPolicyType.Aes256Sha256RsaPss_SignAndEncrypt]
    return policies
