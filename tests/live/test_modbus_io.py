"""The controller's Modbus I/O against a real device on 127.0.0.1: statuses made up for what
Modbus does not carry (runtime-and-ecosystem.md 2d, 3.2), read-back, reconnection."""

from __future__ import annotations

import asyncio
import contextlib
import math
import time
from collections.abc import AsyncIterator
from typing import Any

import pytest
from pymodbus.client import AsyncModbusTcpClient

from loopworks.blocks import status as st
from loopworks.live.device import Device
from loopworks.live.modbus_io import ModbusIO
from loopworks.live.registers import default_map, encode_f32
from loopworks.live.split import split_scenario
from loopworks.sim.scenario import load_scenario

SC = load_scenario(None)


def test_reads_writes_readback_and_a_lost_device() -> None:
    split = split_scenario(SC)
    regmap = default_map(split)
    pv, op = regmap.point("sensor.pv"), regmap.point("valve.op")

    async def main() -> None:
        device = Device(split_scenario(SC), regmap, speedup=50.0)
        port = await device.start("127.0.0.1", 0)
        scanning = asyncio.create_task(device.run())
        io = ModbusIO(regmap, "127.0.0.1", port)
        try:
            values = await io.read()
            value, status = values["sensor.pv"]
            assert status == st.GOOD_NC and abs(value - 50.0) < 2.0
            assert await io.write({"valve.op": 61.25})
            await asyncio.sleep(0.05)
            await io.read()
            assert io.counters.readback_mismatches == 0
            assert device.applied("valve.op") == 61.25
            # someone else overwrites the valve register: the read-back differs, counted
            other = AsyncModbusTcpClient("127.0.0.1", port=port, timeout=1, retries=0)
            assert await other.connect()
            await other.write_registers(op.address, encode_f32(12.0), device_id=1)
            other.close()
            await io.read()
            assert io.counters.readback_mismatches == 1
            assert any("read-back of valve.op" in e for e in io.counters.events)
            # the device goes away: Bad, no communication, with the last value
            last = (await io.read())["sensor.pv"][0]
            await device.stop()
            scanning.cancel()
            values = await io.read()
            assert values["sensor.pv"] == (last, st.BAD_NO_COMM_LUV)
            assert io.counters.read_errors >= 1
            assert not await io.write({"valve.op": 50.0})
            # it comes back on the same port: reconnected within the backoff (<= 1 s)
            device2 = Device(split_scenario(SC), regmap, speedup=50.0)
            await device2.start("127.0.0.1", port)
            scanning = asyncio.create_task(device2.run())
            start = time.monotonic()
            while time.monotonic() - start < 3.0:
                value, status = (await io.read())["sensor.pv"]
                if status == st.GOOD_NC:
                    break
                await asyncio.sleep(0.02)
            assert status == st.GOOD_NC and math.isfinite(value)
            assert time.monotonic() - start < 1.5
            assert io.counters.reconnects == 1
            await device2.stop()
        finally:
            io.close()
            scanning.cancel()

    asyncio.run(main())
    assert pv.address == 0


def test_no_device_at_all_is_bad_without_a_usable_value() -> None:
    split = split_scenario(SC)
    regmap = default_map(split)

    async def main() -> dict[str, tuple[float, int]]:
        import socket

        with socket.socket() as s:  # a port nobody listens on
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        io = ModbusIO(regmap, "127.0.0.1", port)
        try:
            return await io.read()
        finally:
            io.close()

    value, status = asyncio.run(main())["sensor.pv"]
    assert status == st.BAD_NO_COMM_NO_LUV and math.isnan(value)


@contextlib.asynccontextmanager
async def _device_and_io(regmap: Any, wrong: Any) -> AsyncIterator[tuple[Device, ModbusIO]]:
    """The scenario's device serving ``regmap`` at speedup 50 on loopback, scanning, and a
    ModbusIO client to it that uses the altered map ``wrong``; both stopped after."""
    device = Device(split_scenario(SC), regmap, speedup=50.0)
    port = await device.start("127.0.0.1", 0)
    scanning = asyncio.create_task(device.run())
    io = ModbusIO(wrong, "127.0.0.1", port)
    try:
        yield device, io
    finally:
        io.close()
        scanning.cancel()
        await device.stop()


def _altered(regmap: Any, **fields: Any) -> Any:
    """A copy of the register map ``regmap`` with ``fields`` changed (what the controller
    believes, against a device that serves ``regmap``)."""
    copy = object.__new__(type(regmap))
    for name, value in {**vars(regmap), **fields}.items():
        object.__setattr__(copy, name, value)
    return copy


def test_a_wrong_unit_id_is_one_line_and_the_link_stays_up(
        caplog: pytest.LogCaptureFixture) -> None:
    """A device that answers every poll with a Modbus exception (a wrong unit id in the [io]
    map) was taken for a lost device: the link was closed and opened again every second, with
    "connected again" and "reading the device failed" logged each time, forever (found by an
    operator's run). A refusal keeps the link, marks the points Bad (configuration error) and
    is logged once, naming the unit id."""
    split = split_scenario(SC)
    regmap = default_map(split)
    wrong = _altered(regmap, device_id=regmap.device_id + 1)

    async def main() -> None:
        async with _device_and_io(regmap, wrong) as (device, io):
            for _ in range(5):
                values = await io.read()
                assert values["sensor.pv"][1] == st.BAD_CONFIGURATION_ERROR
            assert not await io.write({"valve.op": 50.0})
            refusals = [e for e in io.counters.events if "answered" in e]
            assert len(refusals) == 2  # one for the reads, one for the write
            assert f"unit id {regmap.device_id + 1}" in refusals[0]
            assert io.counters.reconnects == 0 and io.client.connected
            assert not [e for e in io.counters.events if "connected again" in e]
            # the device: one line, not pymodbus's traceback and frame dump on every poll
            assert device.refusals is not None and device.refusals.count >= 6
            lines = [r for r in caplog.records if "does not serve" in r.getMessage()]
            assert len(lines) == 1 and "unit id 1" in lines[0].getMessage()
            assert not [r for r in caplog.records
                        if "Datastore unable" in r.getMessage()]

    asyncio.run(main())


def test_a_refused_write_is_logged_once_with_what_the_loop_shows() -> None:
    """A device that refuses the controller's write (here: the output mapped onto its
    read-only heartbeat register) while every read succeeds: the refusal was logged every
    scan (a good read reset the "already logged" mark) and said the points were "Bad
    (configuration error)", while the loop publishes OUT Bad, no communication (found by an
    outside audit). Logged once, saying so."""
    import dataclasses

    split = split_scenario(SC)
    regmap = default_map(split)
    wrong = _altered(regmap, points=tuple(
        dataclasses.replace(p, address=regmap.heartbeat_address) if p.direction == "input"
        else p for p in regmap.points))

    async def main() -> list[str]:
        async with _device_and_io(regmap, wrong) as (_, io):
            for _ in range(5):
                values = await io.read()
                assert values["sensor.pv"][1] == st.GOOD_NC
                assert not await io.write({"valve.op": 50.0})
            return [e for e in io.counters.events if "answered" in e]

    refusals = asyncio.run(main())
    assert len(refusals) == 1 and "answered writing valve.op" in refusals[0]
    assert "OUT is Bad (no communication)" in refusals[0]


def test_a_map_with_a_gap_between_its_points_is_read_run_by_run() -> None:
    """sensor.pv at 0 and valve.op at 10: the controller read registers 0..11 in one request,
    the device (which serves only the registers its map names) answered exception 2, and the
    loop never ran: PV Bad for ever (found by an outside audit). Each run of adjacent points
    is read on its own."""
    import dataclasses

    split = split_scenario(SC)
    regmap = default_map(split)
    moved = tuple(dataclasses.replace(p, address=10) if p.name == "valve.op" else p
                  for p in regmap.points)
    regmap = dataclasses.replace(regmap, points=moved, heartbeat_address=None,
                                 fault_bits_address=None)

    async def main() -> None:
        device = Device(split_scenario(SC), regmap, speedup=50.0)
        port = await device.start("127.0.0.1", 0)
        scanning = asyncio.create_task(device.run())
        io = ModbusIO(regmap, "127.0.0.1", port)
        try:
            value, status = (await io.read())["sensor.pv"]
            assert status == st.GOOD_NC and abs(value - 50.0) < 2.0
            assert await io.write({"valve.op": 61.25})
            await asyncio.sleep(0.05)
            await io.read()
            assert io.counters.read_errors == 0 and io.counters.readback_mismatches == 0
            assert device.applied("valve.op") == 61.25
        finally:
            io.close()
            scanning.cancel()
            await device.stop()

    asyncio.run(main())
