"""A scenario's ``[io]`` table: the register map both live commands use (addresses, word
order, an input's fault action), checked against the split before anything starts."""

from __future__ import annotations

import asyncio
import subprocess
import sys
from pathlib import Path

import pytest
from pymodbus.client import AsyncModbusTcpClient

from loopworks.errors import InputError
from loopworks.live.device import Device
from loopworks.live.registers import decode_f32, encode_f32, map_of
from loopworks.live.split import split_scenario
from loopworks.sim.scenario import Scenario, load_scenario, parse_scenario

BUILT_IN = load_scenario(None)
IO = """
[io]
device_id = 3
[io.points."sensor.pv"]
address = 10
direction = "output"
word_order = "cdab"
[io.points."valve.op"]
address = 20
direction = "input"
word_order = "cdab"
fault_action = 25.0
"""


def scenario(io: str) -> Scenario:
    return parse_scenario(BUILT_IN.text + io, "plant.toml")


def test_the_io_table_is_the_map_of_both_sides() -> None:
    sc = scenario(IO)
    split = split_scenario(sc)
    regmap = map_of(sc, split)
    assert regmap.device_id == 3
    pv, op = regmap.point("sensor.pv"), regmap.point("valve.op")
    assert (pv.address, pv.word_order, op.address, op.fault_action) == (10, "cdab", 20, 25.0)
    # the table is read back from the map file the device writes
    assert type(regmap).from_toml(regmap.to_toml()).point("valve.op").fault_action == 25.0
    # a poll period (s between the controller's reads) is part of the table
    polled = scenario(IO.replace("device_id = 3", "device_id = 3\npoll_period = 2.0"))
    pmap = map_of(polled, split_scenario(polled))
    assert pmap.poll_period == 2.0
    assert type(pmap).from_toml(pmap.to_toml()).poll_period == 2.0
    # simulate ignores it: the same modules as without it
    assert sc.build("compensation_off").order == BUILT_IN.build("compensation_off").order


def test_a_device_serves_the_io_table_and_applies_its_fault_action() -> None:
    sc = scenario(IO)
    split = split_scenario(sc)

    async def main() -> tuple[float, float, float]:
        device = Device(split, map_of(sc, split), speedup=50.0,
                        fstate_time=0.3)
        port = await device.start("127.0.0.1", 0)
        task = asyncio.create_task(device.run())
        client = AsyncModbusTcpClient("127.0.0.1", port=port, timeout=1, retries=0)
        try:
            assert await client.connect()
            rr = await client.read_holding_registers(10, count=2, device_id=3)
            assert not rr.isError()
            pv = decode_f32(rr.registers, "cdab")
            await client.write_registers(20, encode_f32(70.0, "cdab"), device_id=3)
            await asyncio.sleep(0.1)
            written = device.applied("valve.op")
            await asyncio.sleep(0.6)  # no write for longer than fstate_time
            return pv, written, device.applied("valve.op")
        finally:
            client.close()
            await device.stop()
            task.cancel()

    pv, written, faulted = asyncio.run(main())
    assert abs(pv - 50.0) < 2.0  # the plant's PV at rest, decoded in the table's word order
    assert written == 70.0
    assert faulted == 25.0  # the table's fault action


@pytest.mark.parametrize(("io", "message"), [
    (IO.replace('"sensor.pv"', '"sensor.y"'), r"sensor\.y.* is not a signal between"),
    (IO.replace('direction = "output"', 'direction = "input"'),
     r"direction = 'input': expected 'output'"),
    (IO.split('[io.points."valve.op"]')[0], r"\[io\] has no point for valve\.op"),
    (IO.replace("fault_action = 25.0", 'fault_action = "open"'), r"fault_action = 'open'"),
    (IO.replace("address = 20", "address = 11"), r"overlap|registers"),
    (IO.replace("device_id = 3", "device_id = 3\npoll_period = 0"), r"poll_period = 0"),
])
def test_a_wrong_io_table_is_located(io: str, message: str) -> None:
    sc = scenario(io)
    with pytest.raises(InputError, match=message) as info:
        map_of(sc, split_scenario(sc))
    assert "plant.toml" in str(info.value)


def test_serve_refuses_a_wrong_io_table_before_starting(tmp_path: Path) -> None:
    path = tmp_path / "plant.toml"
    path.write_text(BUILT_IN.text + IO.replace('"sensor.pv"', '"sensor.y"'), encoding="utf-8")
    done = subprocess.run([sys.executable, "-m", "loopworks", "serve", str(path),
                           "--opcua-port", "0", "--duration", "1"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2
    assert "error:" in done.stderr and "sensor.y" in done.stderr
    assert not (tmp_path / "loopworks-state").exists()  # nothing started
