"""The controller's I/O from an OPC UA server (``OpcuaIO``): against a scanning device with its
OPC UA server (one, in a thread of its own, shared by the tests), the status mapping back to
Fieldbus bytes, and ``loopworks serve`` with ``[io] protocol = "opcua"`` end to end against
``loopworks device --opcua-port`` (subprocesses)."""

from __future__ import annotations

import asyncio
import math
import signal
import subprocess
import threading
import time
from collections.abc import Coroutine, Iterator
from pathlib import Path
from typing import Any, TypeVar

import pytest
from asyncua import ua
from asyncua.client.client import Client
from pymodbus.client import AsyncModbusTcpClient

from loopworks.blocks import status as st
from loopworks.errors import InputError
from loopworks.live.device import Device
from loopworks.live.device_opcua import DeviceOpcua
from loopworks.live.opcua import _FROM_OPCUA, _STATUS, fieldbus_status, opcua_status
from loopworks.live.opcua_io import OpcuaIO
from loopworks.live.registers import Point, RegisterMap, default_map, encode_f32, map_of
from loopworks.live.serve import parse_device
from loopworks.live.split import split_scenario
from loopworks.sim.scenario import load_scenario, parse_scenario

from .test_live_end_to_end import OUTPUT, free_port, loopworks, wait_for_line

T = TypeVar("T")
SC = load_scenario(None)
SPEEDUP = 50.0


class Field:
    """A device scanning in a thread of its own, serving Modbus and OPC UA, plus a test node
    ``s=test.pv`` whose status a test sets."""

    def __init__(self) -> None:
        self.loop = asyncio.new_event_loop()
        self.thread = threading.Thread(target=self.loop.run_forever, daemon=True)
        self.thread.start()
        split = split_scenario(SC)
        self.regmap = default_map(split)
        self.device = Device(split, self.regmap, speedup=SPEEDUP, fstate_time=30.0)
        self.server = DeviceOpcua(self.device, "127.0.0.1", 0)
        self.url = self.run(self._start())

    async def _start(self) -> str:
        self.modbus_port = await self.device.start("127.0.0.1", 0)
        url = await self.server.start()
        assert self.server.server is not None
        idx = self.server.namespace_index
        objects = self.server.server.nodes.objects
        self.test_node = await objects.add_variable(ua.NodeId("test.pv", idx),
                                                    ua.QualifiedName("test.pv", idx),
                                                    ua.Variant(1.0, ua.VariantType.Double))
        self.scanning = asyncio.get_running_loop().create_task(self.device.run())
        return url

    def run(self, coro: Coroutine[Any, Any, T]) -> T:
        return asyncio.run_coroutine_threadsafe(coro, self.loop).result(30)

    def set_test(self, value: float, code: str) -> None:
        dv = ua.DataValue(ua.Variant(value, ua.VariantType.Double),
                          StatusCode=ua.StatusCode(getattr(ua.StatusCodes, code)))
        self.run(self.test_node.write_value(dv))

    def close(self) -> None:
        async def stop() -> None:
            await self.server.stop()
            await self.device.stop()
            await asyncio.wait_for(self.scanning, 2.0)

        self.run(stop())
        self.loop.call_soon_threadsafe(self.loop.stop)
        self.thread.join(5)


@pytest.fixture(scope="module")
def field() -> Iterator[Field]:
    f = Field()
    yield f
    f.close()


def test_good_reads_write_and_read_back(field: Field) -> None:
    async def main() -> None:
        io = OpcuaIO(field.regmap, field.url)
        try:
            values = await io.read()
            assert set(values) == {"sensor.pv"}
            v, s = values["sensor.pv"]
            assert s == st.GOOD_NC and math.isfinite(v)
            assert abs(v - field.device.output_values()["sensor.pv"]) < 5.0
            assert await io.write({"valve.op": 42.5})
            await asyncio.sleep(0.1)  # a few device scans
            assert field.device.values["valve.op"] == 42.5
            await io.read()
            assert io.status()["readback_mismatches"] == 0
            # another client overwrites the valve: the next read-back differs
            modbus = AsyncModbusTcpClient("127.0.0.1", port=field.modbus_port, timeout=1)
            assert await modbus.connect()
            await modbus.write_registers(2, encode_f32(10.0), device_id=1)
            modbus.close()
            await asyncio.sleep(0.1)
            await io.read()
            status = io.status()
            assert status["readback_mismatches"] == 1
            assert status == {"connected": True, "reads": 3, "read_errors": 0, "writes": 1,
                              "write_errors": 0, "readback_mismatches": 1, "reconnects": 0}
            assert not await io.write({"valve.op": math.nan})  # not written
        finally:
            await io.aclose()

    asyncio.run(main())


def test_a_stopped_server_is_bad_no_communication_then_good_again(field: Field) -> None:
    async def main() -> None:
        io = OpcuaIO(field.regmap, field.url)
        try:
            v, s = (await io.read())["sensor.pv"]
            assert s == st.GOOD_NC
            field.run(field.server.stop())
            assert (await io.read())["sensor.pv"] == (v, st.BAD_NO_COMM_LUV)
            assert not await io.write({"valve.op": 50.0})
            assert not io.status()["connected"]
            await asyncio.sleep(0.3)
            assert (await io.read())["sensor.pv"] == (v, st.BAD_NO_COMM_LUV)
            field.run(field.server.start())
            back = time.monotonic()
            while time.monotonic() - back < 2.0:
                v2, s2 = (await io.read())["sensor.pv"]
                if s2 == st.GOOD_NC:
                    break
                await asyncio.sleep(0.05)
            assert s2 == st.GOOD_NC, f"still {s2:#x} 2 s after the restart"
            assert v2 != v  # a fresh value
            assert await io.write({"valve.op": 50.0})
            status = io.status()
            assert status["connected"] and status["reconnects"] == 1
            assert status["read_errors"] >= 2
        finally:
            await io.aclose()

    asyncio.run(main())


def test_no_server_before_any_read_is_bad_no_communication_without_a_value() -> None:
    async def main() -> None:
        io = OpcuaIO(default_map(split_scenario(SC)),
                     f"opc.tcp://127.0.0.1:{free_port()}/loopworks/device/")
        v, s = (await io.read())["sensor.pv"]
        assert math.isnan(v) and s == st.BAD_NO_COMM_NO_LUV
        assert io.status()["read_errors"] == 1 and not io.status()["connected"]
        await io.aclose()

    asyncio.run(main())


def test_a_node_s_status_maps_back_to_its_byte(field: Field) -> None:
    split = split_scenario(SC)
    base = default_map(split)
    points = [Point("sensor.pv", 0, "output", node="nsu=urn:loopworks:device;s=test.pv"),
              Point("valve.op", 2, "input")]
    regmap = RegisterMap(points, protocol="opcua")
    assert base.point("valve.op").address == 2

    async def main() -> None:
        io = OpcuaIO(regmap, field.url)
        try:
            field.set_test(7.0, "Good")
            assert (await io.read())["sensor.pv"] == (7.0, st.GOOD_NC)
            field.set_test(8.0, "UncertainLastUsableValue")
            assert (await io.read())["sensor.pv"] == (8.0, st.UNCERTAIN_LAST_USABLE_VALUE)
            field.set_test(9.0, "UncertainEngineeringUnitsExceeded")
            assert (await io.read())["sensor.pv"] == (9.0, st.UNCERTAIN_EU_RANGE_VIOLATION)
            field.set_test(10.0, "BadSensorFailure")  # the server wipes the value
            assert (await io.read())["sensor.pv"] == (9.0, st.BAD_SENSOR_FAILURE)
            field.set_test(11.0, "BadNoCommunication")
            assert (await io.read())["sensor.pv"] == (9.0, st.BAD_NO_COMM_LUV)
            field.set_test(12.0, "BadInternalError")  # not in the table: device failure
            assert (await io.read())["sensor.pv"] == (9.0, st.BAD_DEVICE_FAILURE)
            field.set_test(math.inf, "Good")
            assert (await io.read())["sensor.pv"] == (9.0, st.BAD_DEVICE_FAILURE)
        finally:
            await io.aclose()
        # a namespace the server does not have: configuration error, no value
        other = RegisterMap([Point("sensor.pv", 0, "output", node="nsu=urn:nowhere;s=x"),
                             Point("valve.op", 2, "input")], protocol="opcua")
        io = OpcuaIO(other, field.url)
        try:
            v, s = (await io.read())["sensor.pv"]
            assert math.isnan(v) and s == st.BAD_CONFIGURATION_ERROR
        finally:
            await io.aclose()

    asyncio.run(main())


def test_fieldbus_status_is_the_inverse_of_opcua_status() -> None:
    for byte in _STATUS:
        back = fieldbus_status(opcua_status(byte))
        assert back == (st.BAD_NO_COMM_LUV if byte == st.BAD_NO_COMM_NO_LUV else byte), hex(byte)
        for limit in (st.LOW_LIMITED, st.HIGH_LIMITED, st.CONSTANT):
            assert fieldbus_status(opcua_status(byte | limit)) == back | limit
    for name, byte in _FROM_OPCUA.items():
        code = ua.StatusCode(getattr(ua.StatusCodes, name))
        assert fieldbus_status(code) == byte, name
        there = opcua_status(byte)
        assert (there.is_good(), there.is_uncertain(), there.is_bad()) == (
            code.is_good(), code.is_uncertain(), code.is_bad()), name
        if byte in _STATUS and byte != st.BAD_NO_COMM_NO_LUV:
            assert fieldbus_status(there) == byte
    # codes outside the table: the severity's byte
    assert fieldbus_status(ua.StatusCode(ua.StatusCodes.GoodClamped)) == st.GOOD_NC
    assert fieldbus_status(ua.StatusCode(ua.StatusCodes.UncertainNoCommunicationLastUsableValue)
                           ) == st.UNCERTAIN_NON_SPECIFIC
    assert fieldbus_status(ua.StatusCode(ua.StatusCodes.BadInternalError)) == (
        st.BAD_DEVICE_FAILURE)


IO = """
[io]
protocol = "opcua"
url = "{url}"
[io.points."sensor.pv"]
direction = "output"
[io.points."valve.op"]
direction = "input"
node = "nsu=urn:loopworks:device;s=valve.op"
"""


def test_the_io_table_s_opcua_keys_are_checked() -> None:
    sc = parse_scenario(SC.text + IO.format(url="opc.tcp://127.0.0.1:4841/x/"), "p.toml")
    regmap = map_of(sc, split_scenario(sc))
    assert (regmap.protocol, regmap.url) == ("opcua", "opc.tcp://127.0.0.1:4841/x/")
    assert [p.address for p in regmap.points] == [0, 2]  # placed: the device serves Modbus too
    assert regmap.node_of(regmap.point("sensor.pv")) == "nsu=urn:loopworks:device;s=sensor.pv"
    assert RegisterMap.from_toml(regmap.to_toml()) == regmap
    assert parse_device("opc.tcp://127.0.0.1:4841/x/") == ("opcua", "127.0.0.1", 4841)
    assert parse_device("modbus://127.0.0.1:5020") == ("modbus", "127.0.0.1", 5020)
    for bad, where in (('protocol = "opcua"', 'protocol = "bacnet"'),
                       ('url = "{url}"', 'url = "http://x"'),
                       ('node = "nsu=urn:loopworks:device;s=valve.op"', 'node = "valve.op"')):
        text = SC.text + IO.replace(bad, where).format(url="opc.tcp://h:1/")
        with pytest.raises(InputError, match=where.split(" ")[0]) as info:
            map_of(parse_scenario(text, "p.toml"), split_scenario(SC))
        assert "p.toml" in str(info.value)
    # Modbus maps keep their addresses required and have no node
    modbus = SC.text + '[io.points."sensor.pv"]\ndirection = "output"\n'
    with pytest.raises(InputError, match="address is missing"):
        RegisterMap.from_toml("[io]\n" + modbus.split("[io]\n", 1)[-1], "m.toml")
    with pytest.raises(InputError, match="node is for"):
        RegisterMap.from_table({"points": {"sensor.pv": {"address": 0, "direction": "output",
                                                         "node": "ns=2;s=x"}}})


def test_serve_controls_a_device_over_opcua_end_to_end(tmp_path: Path) -> None:
    ua_port, modbus_port, server_port = free_port(), free_port(), free_port()
    url = f"opc.tcp://127.0.0.1:{ua_port}/loopworks/device/"
    scenario = tmp_path / "plant.toml"
    scenario.write_text(SC.text + IO.format(url=url), encoding="utf-8")
    device = loopworks("device", str(scenario), "--opcua-port", str(ua_port), "--modbus-port",
                       str(modbus_port), "--speedup", "10", "--fstate-time", "1", "--map-file",
                       str(tmp_path / "map.toml"), cwd=tmp_path)
    serve = None
    try:
        wait_for_line(device, f"serving OPC UA on {url} (NoSecurity")  # the start lines
        wait_for_line(device, "a plant scan of 0.5 s")
        serve = loopworks("serve", str(scenario), "--opcua-port", str(server_port),
                          "--speedup", "10", "--state-dir", str(tmp_path / "state"),
                          cwd=tmp_path)
        lines = wait_for_line(serve, "namespace urn:loopworks")
        assert any(ln.startswith(f"controlling {url}:") for ln in lines), lines

        async def watch() -> tuple[ua.DataValue, float, float]:
            async with Client(f"opc.tcp://127.0.0.1:{server_port}/loopworks/") as ctl, \
                    Client(url) as dev:
                idx = await ctl.get_namespace_index("urn:loopworks")
                didx = await dev.get_namespace_index("urn:loopworks:device")
                pv = ctl.get_node(ua.NodeId("pid.PV", idx))
                out = ctl.get_node(ua.NodeId("pid.OUT", idx))
                op = dev.get_node(ua.NodeId("valve.op", didx))
                await asyncio.sleep(2.0)  # 40 controller scans
                dv = await pv.read_data_value(raise_on_bad_status=False)
                out_dv = await out.read_data_value(raise_on_bad_status=False)
                op_dv = await op.read_data_value(raise_on_bad_status=False)
                return dv, out_dv.Value.Value, op_dv.Value.Value

        # unwritten while serve started, the valve went to its fault state; the controller's
        # writes over OPC UA end it
        wait_for_line(device, "valve.op not written for", timeout=1)
        wait_for_line(device, "valve.op written again", timeout=10)
        dv, out, op = asyncio.run(watch())
        assert dv.StatusCode.is_good(), dv.StatusCode  # the PV read over OPC UA is Good
        assert math.isfinite(dv.Value.Value) and math.isfinite(out)
        assert 0.0 <= op <= 100.0
        assert not [ln for ln in OUTPUT[device.pid].lines[OUTPUT[device.pid].seen:]
                    if "not written for" in ln]  # written ever since
        serve.send_signal(signal.SIGINT)
        wait_for_line(serve, "stopped:", timeout=30)
        assert serve.wait(30) == 0
    finally:
        for proc in (serve, device):
            if proc is not None and proc.poll() is None:
                proc.send_signal(signal.SIGINT)
                try:
                    proc.wait(timeout=20)
                except subprocess.TimeoutExpired:
                    proc.kill()
