"""The simulated field device's points on OPC UA as well (``loopworks device --opcua-port``):
the same PV as over Modbus, a write of valve.op that moves the plant, the fault-state timer
fed by either protocol, refusals. One device and one OPC UA server (about 2 s to start),
scanned by hand so that both protocols see the same scan."""

from __future__ import annotations

import asyncio
import math
import time

import pytest
from asyncua import ua
from asyncua.client.client import Client
from pymodbus.client import AsyncModbusTcpClient

from loopworks.errors import InputError
from loopworks.live.device import Device
from loopworks.live.device_opcua import DeviceOpcua
from loopworks.live.registers import decode_f32, default_map, encode_f32
from loopworks.live.split import split_scenario
from loopworks.sim.scenario import load_scenario

SC = load_scenario(None)
PV, OP = 0, 2  # the built-in scenario's default map


def double(x: float) -> ua.Variant:
    return ua.Variant(x, ua.VariantType.Double)


def test_the_device_serves_its_points_on_opcua_as_on_modbus() -> None:
    split = split_scenario(SC)
    device = Device(split, default_map(split), speedup=50.0, fstate_time=0.3)

    async def main() -> None:
        port = await device.start("127.0.0.1", 0)
        server = DeviceOpcua(device, "127.0.0.1", 0)
        url = await server.start()
        assert url.startswith("opc.tcp://127.0.0.1:") and url.endswith("/loopworks/device/")
        modbus = AsyncModbusTcpClient("127.0.0.1", port=port, timeout=1, retries=0)
        assert await modbus.connect()
        client = Client(url)
        await client.connect()
        try:
            idx = await client.get_namespace_index("urn:loopworks:device")
            pv = client.get_node(ua.NodeId("sensor.pv", idx))
            op = client.get_node(ua.NodeId("valve.op", idx))
            # the nodes are under Objects/device, Doubles
            folder = await client.nodes.objects.get_child([f"{idx}:device"])
            assert {n.nodeid for n in await folder.get_children()} == {pv.nodeid, op.nodeid}
            assert await pv.read_data_type_as_variant_type() == ua.VariantType.Double

            async def both() -> tuple[ua.DataValue, float]:
                dv = await pv.read_data_value(raise_on_bad_status=False)
                rr = await modbus.read_holding_registers(PV, count=2, device_id=1)
                return dv, decode_f32(rr.registers)

            await device.scan()
            dv, reg = await both()
            assert dv.StatusCode.is_good()
            assert dv.Value.Value == device.output_values()["sensor.pv"]
            assert abs(dv.Value.Value - reg) <= 1e-6 * abs(reg)  # the float32 of it
            first = dv.Value.Value

            # a plant output is read-only
            [code] = await client.write_values([pv], [double(1.0)],
                                               raise_on_partial_error=False)
            assert code.is_bad()

            # a write of valve.op reaches the plant at the next scan, like a Modbus write,
            # and is copied into the registers
            [code] = await client.write_values([op], [double(90.0)])
            assert code.is_good()
            await device.scan()
            valve = device.module.blocks["valve"]
            assert float(valve.u[[q.name for q in valve.INPUTS].index("op")]) == 90.0
            rr = await modbus.read_holding_registers(OP, count=2, device_id=1)
            assert decode_f32(rr.registers) == 90.0
            for _ in range(60):  # 30 s of plant time with the valve at 90 %
                [code] = await client.write_values([op], [double(90.0)])
                await device.scan()
            dv, reg = await both()
            assert dv.Value.Value > first + 1.0, (first, dv.Value.Value)
            assert abs(dv.Value.Value - reg) <= 1e-6 * abs(reg)

            # NaN and a wrong type are refused; the plant keeps 90
            # a finite double beyond the float32 of the registers too (1e300 was taken, and
            # the registers read +inf; found by an outside audit)
            [nan, big, wrong] = await client.write_values(
                [op, op, op], [double(math.nan), double(1e300),
                               ua.Variant(5, ua.VariantType.Int64)],
                raise_on_partial_error=False)
            assert nan.name == big.name == "BadOutOfRange"
            assert wrong.name == "BadTypeMismatch"
            await device.scan()
            assert device.values["valve.op"] == 90.0

            # the fault-state timer: a write by either protocol counts
            time.sleep(0.4)
            await device.scan()
            assert "valve.op" in device.faulted
            await client.write_values([op], [double(70.0)])
            await device.scan()
            assert "valve.op" not in device.faulted
            time.sleep(0.4)
            await device.scan()
            assert "valve.op" in device.faulted
            await modbus.write_registers(OP, encode_f32(60.0), device_id=1)
            await device.scan()
            assert "valve.op" not in device.faulted
            # ... and the node shows what the device holds, whoever wrote it
            dv = await op.read_data_value(raise_on_bad_status=False)
            assert dv.Value.Value == 60.0

            # the latest write wins
            await modbus.write_registers(OP, encode_f32(30.0), device_id=1)
            await client.write_values([op], [double(40.0)])
            await device.scan()
            assert device.values["valve.op"] == 40.0
            await client.write_values([op], [double(41.0)])
            await modbus.write_registers(OP, encode_f32(31.0), device_id=1)
            await device.scan()
            assert device.values["valve.op"] == 31.0
        finally:
            await client.disconnect()
            modbus.close()
            await server.stop()
            await device.stop()

    asyncio.run(main())


def test_the_device_opcua_server_is_loopback_only() -> None:
    split = split_scenario(SC)
    device = Device(split, default_map(split))
    with pytest.raises(InputError, match="loopback"):
        DeviceOpcua(device, "0.0.0.0", 4841)
    with pytest.raises(InputError, match="port"):
        DeviceOpcua(device, "127.0.0.1", 70000)
