"""The soft controller's OPC UA server (loopworks.live.opcua) against a fake controller.

One LoopServer serves the whole module (Server.init takes about 2 s): it runs on its own event
loop in a thread, as it would beside a controller; each test is a client session in
``asyncio.run``. Tests that change the controller's state put it back.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import stat
import threading
from collections.abc import Awaitable, Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

import pytest
from asyncua import Client, ua
from asyncua.crypto.cert_gen import setup_self_signed_certificate
from asyncua.ua.attribute_ids import AttributeIds
from asyncua.ua.status_codes import StatusCodes
from cryptography.x509.oid import ExtendedKeyUsageOID

from loopworks.blocks import status as st
from loopworks.errors import InputError
from loopworks.live.opcua import (
    MODES,
    LoopServer,
    Variable,
    WriteRefused,
    _self_signed,
    opcua_status,
    security_policies,
)
from loopworks.live.users import add_user, load_users

T = TypeVar("T")
PERMITTED = ("OOS", "MAN", "AUTO")


@dataclass
class FakeController:
    """SP writable in 0..100, OUT only in MAN (else BadInvalidState), MODE among PERMITTED;
    GAIN is clamped to 0.1..10 (accepted: the published value shows the clamp)."""

    values: dict[str, float | int] = field(default_factory=lambda: {
        "PV": 45.0, "SP": 50.0, "OUT": 20.0, "MODE": MODES.index("AUTO"), "GAIN": 1.5,
        "SCANS": 0})
    writes: list[tuple[str | None, str | None, str, str, float | int]] = field(
        default_factory=list)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def loops(self) -> dict[str, list[Variable]]:
        v = self.values
        return {"pid": [
            Variable("PV", v["PV"], "double", False, "degC", "Process variable"),
            Variable("SP", v["SP"], "double", True, "degC", "Setpoint"),
            Variable("OUT", v["OUT"], "double", True, "%", "Output"),
            Variable("MODE", "AUTO", "mode", True, description="Actual mode"),
            Variable("GAIN", v["GAIN"], "double", True),
            Variable("SCANS", v["SCANS"], "int", False, description="Scans run"),
        ], "tic2": [Variable("PV", 1, "double", False)]}

    def write(self, user: str | None, role: str | None, loop: str, name: str,
              value: float | int) -> None:
        with self.lock:
            if name == "SP" and not 0.0 <= value <= 100.0:
                raise WriteRefused("BadOutOfRange", f"SP {value}: allowed 0..100")
            if name == "OUT" and self.values["MODE"] != MODES.index("MAN"):
                raise WriteRefused("BadInvalidState", "OUT is written in MAN only")
            if name == "MODE" and MODES[int(value)] not in PERMITTED:
                raise WriteRefused("BadOutOfRange", f"mode {MODES[int(value)]} is not "
                                                    f"permitted: {PERMITTED}")
            if name == "GAIN":
                value = min(max(value, 0.1), 10.0)
            self.values[name] = value
            self.writes.append((user, role, loop, name, value))

    def snapshot(self) -> dict[str, tuple[float | int, int]]:
        with self.lock:
            return {f"pid.{k}": (v, st.GOOD_NC) for k, v in self.values.items()}


@dataclass
class Served:
    server: LoopServer
    controller: FakeController
    url: str
    loop: asyncio.AbstractEventLoop

    def call(self, make: Callable[[], Awaitable[T]]) -> T:
        """Run a coroutine on the server's event loop (publish, as the controller would)."""
        async def run() -> T:
            return await make()

        return asyncio.run_coroutine_threadsafe(run(), self.loop).result(timeout=10)

    def publish(self, values: dict[str, tuple[float | int | str, int]] | None = None) -> None:
        self.call(lambda: self.server.publish(values or self.controller.snapshot()))

    def reset(self) -> None:
        with self.controller.lock:
            self.controller.values.update(SP=50.0, OUT=20.0, MODE=MODES.index("AUTO"),
                                          GAIN=1.5)
            self.controller.writes.clear()
        self.publish()


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Served]:
    path = tmp_path_factory.mktemp("users") / "users.toml"
    add_user(path, "op", "op-pass", "operator")
    add_user(path, "viewer", "view-pass", "viewer")
    controller = FakeController()
    server = LoopServer(controller, load_users(path), port=0)
    loop = asyncio.new_event_loop()
    thread = threading.Thread(target=loop.run_forever, daemon=True)
    thread.start()
    url = asyncio.run_coroutine_threadsafe(server.start(), loop).result(timeout=30)
    served = Served(server, controller, url, loop)
    try:
        yield served
    finally:
        served.call(server.stop)
        loop.call_soon_threadsafe(loop.stop)
        thread.join(timeout=10)
        loop.close()


def session(served: Served, user: str | None = None, password: str = "") -> Client:
    client = Client(served.url, timeout=5)
    if user is not None:
        client.set_user(user)
        client.set_password(password)
    return client


async def node(client: Client, key: str) -> Any:
    idx = await client.get_namespace_index("urn:loopworks")
    return client.get_node(ua.NodeId(key, idx))


async def read(client: Client, key: str) -> ua.DataValue:
    return await (await node(client, key)).read_data_value(raise_on_bad_status=False)


async def write_code(client: Client, key: str, variant: ua.Variant) -> str:
    """The status code name the server answers to a write (Good when accepted)."""
    try:
        await (await node(client, key)).write_value(ua.DataValue(variant))
    except ua.UaStatusCodeError as exc:
        return ua.StatusCode(exc.code).name
    return "Good"


def double(x: float) -> ua.Variant:
    return ua.Variant(x, ua.VariantType.Double)


# --- status mapping --------------------------------------------------------------------------

EXPECTED = {
    0x00: "Bad", 0x04: "BadConfigurationError", 0x08: "BadNotConnected",
    0x0C: "BadDeviceFailure", 0x10: "BadSensorFailure", 0x14: "BadNoCommunication",
    0x18: "BadNoCommunication", 0x1C: "BadOutOfService",
    0x40: "Uncertain", 0x44: "UncertainLastUsableValue", 0x48: "UncertainSubstituteValue",
    0x4C: "UncertainInitialValue", 0x50: "UncertainSensorNotAccurate",
    0x54: "UncertainEngineeringUnitsExceeded", 0x58: "UncertainSubNormal",
    0x80: "Good", 0x84: "Good", 0x88: "Good", 0x8C: "Good", 0x90: "Good", 0x94: "Good",
    0x98: "Good",
    0xC0: "GoodCascade", 0xC4: "GoodCascadeInitializationAcknowledged",
    0xC8: "GoodCascadeInitializationRequest", 0xCC: "GoodCascadeNotInvited",
    0xD0: "GoodCascadeNotSelected", 0xD8: "GoodLocalOverride", 0xDC: "GoodFaultStateActive",
    0xE0: "GoodInitiateFaultState",
}


def test_every_named_fieldbus_substatus_is_mapped() -> None:
    assert set(st.SUBSTATUS_NAMES) <= set(EXPECTED)  # the table covers status.py's names


@pytest.mark.parametrize("byte", sorted(EXPECTED))
def test_opcua_status_of_each_substatus(byte: int) -> None:
    code = opcua_status(byte)
    assert code.name == EXPECTED[byte]
    assert code.value == getattr(StatusCodes, EXPECTED[byte])
    quality = st.quality(byte)
    assert code.is_bad() == (quality == st.BAD)
    assert code.is_uncertain() == (quality == st.UNCERTAIN)
    assert code.is_good() == (quality in (st.GOOD_NC, st.GOOD_CASCADE))


@pytest.mark.parametrize(("byte", "name"), [(0x20, "Bad"), (0x3C, "Bad"), (0x5C, "Uncertain"),
                                            (0x7C, "Uncertain"), (0xBC, "Good"),
                                            (0xD4, "GoodCascade"), (0xFC, "GoodCascade")])
def test_undefined_substatus_gives_the_generic_code_of_its_quality(byte: int, name: str) -> None:
    assert opcua_status(byte).value == getattr(StatusCodes, name)


@pytest.mark.parametrize(("limit", "bits"), [(st.LOW_LIMITED, 0x500), (st.HIGH_LIMITED, 0x600),
                                             (st.CONSTANT, 0x700)])
def test_limit_bits_become_the_status_code_limit_bits(limit: int, bits: int) -> None:
    for base in (0x80, 0x54, 0x14, 0xD8):
        code = opcua_status(base | limit)
        assert code.value == opcua_status(base).value | bits
        assert code.is_bad() == opcua_status(base).is_bad()
        assert code.is_uncertain() == opcua_status(base).is_uncertain()


@pytest.mark.parametrize("byte", [-1, 256, 1.5])
def test_opcua_status_refuses_a_non_byte(byte: Any) -> None:
    with pytest.raises(ValueError, match="not a status byte"):
        opcua_status(byte)


def test_write_refused_takes_bad_status_code_names_only() -> None:
    assert WriteRefused("BadInvalidState", "why").code == "BadInvalidState"
    for code in ("Good", "UncertainInitialValue", "BadNoSuchCode"):
        with pytest.raises(ValueError, match="not the name of a Bad OPC UA status code"):
            WriteRefused(code, "why")


# --- configuration ---------------------------------------------------------------------------

def test_nosecurity_is_refused_on_a_host_that_is_not_loopback() -> None:
    server = LoopServer(FakeController(), None, host="0.0.0.0", port=0)
    assert not server.loopback
    with pytest.raises(InputError, match=r"NoSecurity.*loopback"):
        asyncio.run(server.start())
    assert server.server is None
    for host in ("127.0.0.1", "::1", "localhost", "127.0.0.2"):
        assert LoopServer(FakeController(), None, host=host).loopback


# --- the live server -------------------------------------------------------------------------

def test_anonymous_client_reads_every_variable_by_node_id(served: Served) -> None:
    served.reset()

    async def scenario() -> None:
        async with session(served) as client:
            assert (await read(client, "pid.PV")).Value.Value == 45.0
            sp = await read(client, "pid.SP")
            assert sp.Value.Value == 50.0 and sp.Value.VariantType == ua.VariantType.Double
            assert sp.StatusCode.is_good() and sp.SourceTimestamp is not None
            assert (await read(client, "pid.OUT")).Value.Value == 20.0
            mode = await read(client, "pid.MODE")
            assert mode.Value.Value == 4 and mode.Value.VariantType == ua.VariantType.Int32
            assert (await read(client, "pid.MODE_TEXT")).Value.Value == "AUTO"
            enum = await read(client, "pid.MODE.EnumStrings")
            assert [t.Text for t in enum.Value.Value] == list(MODES)
            scans = await read(client, "pid.SCANS")
            assert scans.Value.VariantType == ua.VariantType.Int64
            assert (await read(client, "tic2.PV")).Value.Value == 1.0  # an int made a float
            eu = (await read(client, "pid.PV.EngineeringUnits")).Value.Value
            assert eu.DisplayName.Text == "degC"
            pv = await node(client, "pid.PV")
            assert (await pv.read_description()).Text == "Process variable [degC]"
            # the browse path Objects/loopworks/pid/SP leads to the same node
            idx = await client.get_namespace_index("urn:loopworks")
            found = await client.nodes.objects.get_child([f"{idx}:loopworks", f"{idx}:pid",
                                                          f"{idx}:SP"])
            assert found.nodeid == ua.NodeId("pid.SP", idx)

    asyncio.run(scenario())


def test_anonymous_and_viewer_writes_are_refused(served: Served,
                                                 caplog: pytest.LogCaptureFixture) -> None:
    served.reset()
    caplog.set_level(logging.INFO, logger="loopworks.serve")

    async def scenario() -> None:
        async with session(served) as client:
            assert await write_code(client, "pid.SP", double(60.0)) == "BadUserAccessDenied"
            assert await write_code(client, "pid.PV", double(1.0)) == "BadNotWritable"
        async with session(served, "viewer", "view-pass") as client:
            assert await write_code(client, "pid.SP", double(60.0)) == "BadUserAccessDenied"
            assert (await read(client, "pid.SP")).Value.Value == 50.0  # readable

    asyncio.run(scenario())
    assert served.controller.writes == []
    refused = [r.getMessage() for r in caplog.records if "refused" in r.getMessage()]
    assert any("pid.SP = 60.0 by anonymous: refused, BadUserAccessDenied" in m for m in refused)
    assert any("pid.SP = 60.0 by viewer (viewer): refused, BadUserAccessDenied" in m
               for m in refused)


def test_the_user_access_level_is_the_sessions_own(served: Served) -> None:
    """OPC UA Part 3 5.6.2: UserAccessLevel is what *this* user may do. Anonymous and viewer
    sessions were shown SP as writable (3) while every write was refused, so a generic
    client offered them an editable field; an operator's is 3, and AccessLevel (what the
    node allows anyone) is 3 for everyone."""
    write = ua.AccessLevel.CurrentWrite.mask
    read_ = ua.AccessLevel.CurrentRead.mask

    async def levels(user: str | None, password: str = "") -> list[tuple[int, int]]:
        async with session(served, user, password) as client:
            out = []
            for key in ("pid.SP", "pid.MODE", "pid.PV"):
                n = await node(client, key)
                out.append(((await n.read_attribute(AttributeIds.AccessLevel)).Value.Value,
                            (await n.read_attribute(AttributeIds.UserAccessLevel)).Value.Value))
            return out

    sp_mode_pv = [(read_ | write, read_ | write)] * 2 + [(read_, read_)]
    assert asyncio.run(levels("op", "op-pass")) == sp_mode_pv
    for who in ((None,), ("viewer", "view-pass")):
        assert asyncio.run(levels(*who)) == [(read_ | write, read_)] * 2 + [(read_, read_)], who


@pytest.mark.parametrize(("user", "password"), [("op", "wrong"), ("op", ""),
                                                ("nobody", "op-pass")])
def test_wrong_password_or_unknown_user_is_refused_at_connection(
        served: Served, user: str, password: str) -> None:
    async def scenario() -> str:
        client = session(served, user, password)
        try:
            await client.connect()
        except ua.UaStatusCodeError as exc:
            return ua.StatusCode(exc.code).name
        finally:
            with contextlib.suppress(Exception):
                await client.disconnect()
        return "connected"

    assert asyncio.run(scenario()) == "BadUserAccessDenied"


def test_operator_writes_sp_the_controller_sees_it_and_the_published_value_shows(
        served: Served, caplog: pytest.LogCaptureFixture) -> None:
    served.reset()
    caplog.set_level(logging.INFO, logger="loopworks.serve")

    async def scenario() -> None:
        async with session(served, "op", "op-pass") as client:
            assert await write_code(client, "pid.SP", double(62.5)) == "Good"
            assert served.controller.writes == [("op", "operator", "pid", "SP", 62.5)]
            # not the client's value: the node changes when the controller publishes
            assert (await read(client, "pid.SP")).Value.Value == 50.0
            served.publish()
            assert (await read(client, "pid.SP")).Value.Value == 62.5
            # an integer variant is accepted for a Double and given as a float
            assert await write_code(client, "pid.SP", ua.Variant(70, ua.VariantType.Int32)) \
                == "Good"
            assert served.controller.writes[-1] == ("op", "operator", "pid", "SP", 70.0)
            assert isinstance(served.controller.writes[-1][-1], float)

    asyncio.run(scenario())
    assert any(r.getMessage() == "write pid.SP = 62.5 by op (operator): accepted"
               for r in caplog.records)


def test_a_clamped_write_shows_the_controllers_value(served: Served) -> None:
    served.reset()

    async def scenario() -> None:
        async with session(served, "op", "op-pass") as client:
            assert await write_code(client, "pid.GAIN", double(50.0)) == "Good"
            served.publish()
            assert (await read(client, "pid.GAIN")).Value.Value == 10.0

    asyncio.run(scenario())


def test_operator_writes_refused_by_the_controller_get_its_code(
        served: Served, caplog: pytest.LogCaptureFixture) -> None:
    served.reset()
    caplog.set_level(logging.INFO, logger="loopworks.serve")

    async def scenario() -> None:
        async with session(served, "op", "op-pass") as client:
            assert await write_code(client, "pid.SP", double(150.0)) == "BadOutOfRange"
            assert await write_code(client, "pid.SP", double(float("nan"))) == "BadOutOfRange"
            assert await write_code(client, "pid.SP", ua.Variant("60", ua.VariantType.String)) \
                == "BadTypeMismatch"
            assert await write_code(client, "pid.OUT", double(30.0)) == "BadInvalidState"
            assert await write_code(client, "pid.PV", double(1.0)) == "BadNotWritable"
            assert await write_code(client, "pid.SCANS", ua.Variant(3, ua.VariantType.Int64)) \
                == "BadNotWritable"
            assert served.controller.writes == []
            # MODE: a code out of 0..5, then a mode that is not permitted, then MAN
            mode = ua.VariantType.Int32
            assert await write_code(client, "pid.MODE", ua.Variant(9, mode)) == "BadOutOfRange"
            assert await write_code(client, "pid.MODE", ua.Variant(5, mode)) == "BadOutOfRange"
            assert await write_code(client, "pid.MODE", ua.Variant(3, mode)) == "Good"
            served.publish()
            assert (await read(client, "pid.MODE")).Value.Value == 3
            assert (await read(client, "pid.MODE_TEXT")).Value.Value == "MAN"
            # in MAN the operator may write OUT; a mode name is accepted as well
            assert await write_code(client, "pid.OUT", double(30.0)) == "Good"
            assert await write_code(client, "pid.MODE",
                                    ua.Variant("auto", ua.VariantType.String)) == "Good"
            assert [w[3:] for w in served.controller.writes] == [
                ("MODE", 3), ("OUT", 30.0), ("MODE", 4)]

    asyncio.run(scenario())
    messages = [r.getMessage() for r in caplog.records]
    assert "write pid.OUT = 30.0 by op (operator): refused, BadInvalidState: OUT is written " \
           "in MAN only" in messages
    assert any("pid.SP = 150.0 by op (operator): refused, BadOutOfRange: SP 150.0" in m
               for m in messages)


def test_a_refusal_s_reason_is_on_the_loop_s_last_refusal_node(served: Served) -> None:
    # an OPC UA write answers a status code only; the reason (the controller's message, what
    # the serve log says) is put on <loop>.LAST_REFUSAL before the answer, for the faceplate
    served.reset()

    async def scenario() -> None:
        async with session(served) as anonymous:
            last = await read(anonymous, "pid.LAST_REFUSAL")
            assert last.Value.VariantType == ua.VariantType.String
            assert await write_code(anonymous, "pid.SP", double(60.0)) == "BadUserAccessDenied"
            assert (await read(anonymous, "pid.LAST_REFUSAL")).Value.Value == (
                "anonymous SP BadUserAccessDenied: only operators may write")
        async with session(served, "op", "op-pass") as client:
            assert await write_code(client, "pid.SP", double(150.0)) == "BadOutOfRange"
            assert (await read(client, "pid.LAST_REFUSAL")).Value.Value == (
                "op SP BadOutOfRange: SP 150.0: allowed 0..100")
            assert await write_code(client, "pid.OUT", double(30.0)) == "BadInvalidState"
            assert (await read(client, "pid.LAST_REFUSAL")).Value.Value == (
                "op OUT BadInvalidState: OUT is written in MAN only")
            assert (await read(client, "tic2.LAST_REFUSAL")).Value.Value == ""  # per loop
            # read-only, like every node the server keeps itself
            # (BadNotWritable for everyone: an operator was told BadUserAccessDenied, as if
            # another user could write them)
            for name in ("pid.LAST_REFUSAL", "pid.MODE_TEXT"):
                assert await write_code(client, name, ua.Variant(
                    "x", ua.VariantType.String)) == "BadNotWritable", name
                # and noted, as every refused write is (they were neither logged nor noted;
                # found by an outside audit)
                assert (await read(client, "pid.LAST_REFUSAL")).Value.Value == (
                    f"op {name.split('.')[1]} BadNotWritable: a read-only variable")
            # a value its writer marks Bad is no setting (SP = 53, BadDeviceFailure, was
            # applied as a Good setpoint; found by an outside audit)
            sp = await node(client, "pid.SP")
            with pytest.raises(ua.UaStatusCodeError) as info:
                await sp.write_value(ua.DataValue(double(53.0), StatusCode=ua.StatusCode(
                    ua.StatusCodes.BadDeviceFailure)))
            assert ua.StatusCode(info.value.code).name == "BadWriteNotSupported"
            assert (await read(client, "pid.LAST_REFUSAL")).Value.Value.startswith(
                "op SP BadWriteNotSupported: a value written with status BadDeviceFailure")

    asyncio.run(scenario())


def test_a_declared_last_refusal_variable_is_refused() -> None:
    class Declares(FakeController):
        def loops(self) -> dict[str, list[Variable]]:
            return {"pid": [Variable("LAST_REFUSAL", 0.0, "double", False)]}

    with pytest.raises(InputError, match="LAST_REFUSAL is the server's own node"):
        asyncio.run(LoopServer(Declares(), None, port=0).start())


def test_a_published_bad_status_reads_as_its_opcua_code_without_value(served: Served) -> None:
    served.reset()

    async def scenario() -> None:
        async with session(served) as client:
            served.publish({"pid.PV": (44.0, st.BAD_NO_COMM_LUV),
                            "pid.OUT": (20.0, st.UNCERTAIN_LAST_USABLE_VALUE),
                            "pid.MODE": (0, st.BAD_OUT_OF_SERVICE)})
            pv = await read(client, "pid.PV")
            assert pv.StatusCode.name == "BadNoCommunication"
            assert pv.Value.Value is None  # OPC UA drops the value of a Bad status
            out = await read(client, "pid.OUT")
            assert out.StatusCode.name == "UncertainLastUsableValue"
            assert out.Value.Value == 20.0  # an Uncertain value is kept
            assert (await read(client, "pid.MODE_TEXT")).StatusCode.name == "BadOutOfService"
            served.publish({"pid.PV": (46.0, st.GOOD_NC | st.HIGH_LIMITED)})
            pv = await read(client, "pid.PV")
            assert pv.StatusCode.is_good() and pv.Value.Value == 46.0
            assert pv.StatusCode.value & 0x300 == 0x200  # limit bits: high limited

    asyncio.run(scenario())
    served.publish({"pid.PV": (45.0, st.GOOD_NC)})


def test_a_subscriber_is_notified_of_published_values(served: Served) -> None:
    served.reset()

    class Handler:
        def __init__(self) -> None:
            self.queue: asyncio.Queue[ua.DataValue] = asyncio.Queue()

        def datachange_notification(self, node: Any, val: Any, data: Any) -> None:
            self.queue.put_nowait(data.monitored_item.Value)

    async def scenario() -> list[float]:
        async with session(served) as client:
            handler = Handler()
            sub = await client.create_subscription(10, handler)
            await sub.subscribe_data_change(await node(client, "pid.PV"))
            seen = [(await asyncio.wait_for(handler.queue.get(), 5)).Value.Value]
            for value in (46.0, 47.5):
                served.publish({"pid.PV": (value, st.GOOD_NC)})
                seen.append((await asyncio.wait_for(handler.queue.get(), 5)).Value.Value)
            return seen

    assert asyncio.run(scenario()) == [45.0, 46.0, 47.5]
    served.publish({"pid.PV": (45.0, st.GOOD_NC)})


def test_publish_refuses_an_unknown_key_and_a_bad_mode(served: Served) -> None:
    with pytest.raises(KeyError, match=r"pid\.NOPE"):
        served.publish({"pid.NOPE": (1.0, st.GOOD_NC)})
    with pytest.raises(InputError, match="mode 'FAST'"):
        served.publish({"pid.MODE": ("FAST", st.GOOD_NC)})


def test_without_users_file_anonymous_reads_and_no_login_is_accepted() -> None:
    # a server without users: no user name token is offered, so a login cannot succeed
    async def scenario() -> tuple[bool, str]:
        server = LoopServer(FakeController(), None, port=0)
        url = await server.start()
        try:
            async with Client(url, timeout=5) as client:
                pv = client.get_node(ua.NodeId("pid.PV", 2))
                anonymous_reads = (await pv.read_data_value()).Value.Value == 45.0
            client = Client(url, timeout=5)
            client.set_user("op")
            client.set_password("op-pass")
            try:
                await client.connect()
                outcome = "connected"
            except ua.UaStatusCodeError as exc:
                outcome = ua.StatusCode(exc.code).name
            finally:
                with contextlib.suppress(Exception):
                    await client.disconnect()
            return anonymous_reads, outcome
        finally:
            await server.stop()

    anonymous_reads, outcome = asyncio.run(scenario())
    assert anonymous_reads
    assert outcome == "BadIdentityTokenRejected"


# --- security ---------------------------------------------------------------------------------

def test_security_policies_offer_nosecurity_on_loopback_only() -> None:
    none = ua.SecurityPolicyType.NoSecurity
    secure = [ua.SecurityPolicyType.Basic256Sha256_SignAndEncrypt,
              ua.SecurityPolicyType.Aes256Sha256RsaPss_SignAndEncrypt]
    assert security_policies(loopback=True, certificate=False) == [none]
    assert security_policies(loopback=True, certificate=True) == [none, *secure]
    assert security_policies(loopback=False, certificate=True) == secure


def test_signed_and_encrypted_sessions_with_a_self_signed_certificate(tmp_path: Path) -> None:
    users = tmp_path / "users.toml"
    add_user(users, "op", "op-pass", "operator")
    controller = FakeController()
    server = LoopServer(controller, load_users(users), port=0,
                        certificate_dir=tmp_path / "pki")
    client_key, client_cert = tmp_path / "client.pem", tmp_path / "client.der"

    async def scenario() -> list[tuple[str, str]]:
        url = await server.start()
        try:
            assert server.server is not None
            offered = [(e.SecurityPolicyUri.rsplit("#", 1)[1], e.SecurityMode.name)
                       for e in await server.server.get_endpoints()]
            await setup_self_signed_certificate(
                client_key, client_cert, "urn:loopworks:test-client", "localhost",
                [ExtendedKeyUsageOID.CLIENT_AUTH], {"commonName": "test client"})
            for policy, sp in (("Basic256Sha256", 61.0), ("Aes256Sha256RsaPss", 62.0)):
                client = Client(url, timeout=5)
                client.application_uri = "urn:loopworks:test-client"
                await client.set_security_string(
                    f"{policy},SignAndEncrypt,{client_cert},{client_key}")
                client.set_user("op")
                client.set_password("op-pass")
                async with client:
                    assert (await read(client, "pid.PV")).Value.Value == 45.0
                    assert await write_code(client, "pid.SP", double(sp)) == "Good"
            return offered
        finally:
            await server.stop()

    offered = asyncio.run(scenario())
    assert offered == [("None", "None_"), ("Basic256Sha256", "SignAndEncrypt"),
                       ("Aes256_Sha256_RsaPss", "SignAndEncrypt")]
    assert [w[3:] for w in controller.writes] == [("SP", 61.0), ("SP", 62.0)]
    pki = tmp_path / "pki"
    files = {p.name: p.read_bytes() for p in pki.iterdir()}
    assert set(files) == {"loopworks-server.der", "loopworks-server.pem"}
    assert all(stat.S_IMODE(p.stat().st_mode) == 0o600 for p in pki.iterdir())
    # the next start reuses the certificate, so clients that trust it keep trusting it
    asyncio.run(_self_signed(pki, "127.0.0.1"))
    assert {p.name: p.read_bytes() for p in pki.iterdir()} == files


def test_a_generic_pid_loop_s_modes_on_opcua_are_its_own(tmp_path: Path) -> None:
    """The tester's cascade example: generic pid loops (mode codes MAN 0, AUTO 1, CAS 2)
    showed AUTO as IMAN and CAS as LO, and their MAN/AUTO/CAS writes were refused; the MODE
    node keeps MODES' codes (its EnumStrings) and the controller translates by name."""
    from tests.live.test_serve import make_cascade, scans

    users = tmp_path / "users.toml"
    add_user(users, "op", "op-pass", "operator")
    ctl = make_cascade()
    scans(ctl, 2)

    async def scenario() -> None:
        server = LoopServer(ctl, load_users(users), port=0)
        url = await server.start()
        try:
            await server.publish(ctl.snapshot())
            client = Client(url, timeout=5)
            client.set_user("op")
            client.set_password("op-pass")
            async with client:
                assert (await read(client, "primary.MODE")).Value.Value == MODES.index("AUTO")
                assert (await read(client, "primary.MODE_TEXT")).Value.Value == "AUTO"
                assert (await read(client, "secondary.MODE_TEXT")).Value.Value == "CAS"
                sp = (await read(client, "secondary.SP")).Value.Value
                assert sp == pytest.approx(50.0, abs=1.0)  # the primary's OUT, not sp = 0
                mode = ua.VariantType.Int32
                assert await write_code(client, "secondary.SP", double(40.0)) == \
                    "BadInvalidState"  # the setpoint comes from cas_sp
                assert "cas_sp" in (await read(client, "secondary.LAST_REFUSAL")).Value.Value
                assert await write_code(client, "secondary.MODE",
                                        ua.Variant(MODES.index("MAN"), mode)) == "Good"
                assert await write_code(client, "secondary.MODE",
                                        ua.Variant(MODES.index("OOS"), mode)) == \
                    "BadOutOfRange"
                assert "modes MAN, AUTO, CAS" in (
                    await read(client, "secondary.LAST_REFUSAL")).Value.Value
                await server.publish(ctl.snapshot())
                assert (await read(client, "secondary.MODE_TEXT")).Value.Value == "MAN"
                assert await write_code(client, "secondary.OUT", double(150.0)) == \
                    "BadOutOfRange"
                assert await write_code(client, "secondary.OUT", double(42.0)) == "Good"
        finally:
            await server.stop()

    asyncio.run(scenario())
    secondary = ctl.module.blocks["secondary"]
    assert secondary.u[secondary._in_index["mode"]] == 0.0  # the pid's own MAN
    assert secondary.u[secondary._in_index["man_out"]] == 42.0


def test_a_write_to_a_node_that_does_not_exist_says_so(served: Served) -> None:
    """An operator writing a loop's MODE that the loop does not have got
    BadUserAccessDenied (asyncua checks rights first; found by an operator): it is
    BadNodeIdUnknown, and the controller sees no write."""
    served.reset()

    async def scenario() -> None:
        async with session(served, "op", "op-pass") as client:
            assert await write_code(client, "pid.NO_SUCH", double(1.0)) == "BadNodeIdUnknown"
            assert served.controller.writes == []
            assert await write_code(client, "pid.SP", double(61.0)) == "Good"

    asyncio.run(scenario())
