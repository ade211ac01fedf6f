"""Several devices behind one controller (``[io.devices.NAME]``): the tables checked against
the split, each device read at its own poll period, each output written to its device, a
failed device making only its own points Bad."""

from __future__ import annotations

import asyncio
import math

import pytest

from loopworks.blocks import status as st
from loopworks.errors import InputError
from loopworks.live.device import Device
from loopworks.live.devices import MultiIO, has_devices, links_of
from loopworks.live.registers import default_map, map_of
from loopworks.live.serve import LiveController
from loopworks.live.split import split_scenario
from loopworks.sim.scenario import Scenario, load_scenario, parse_scenario

BUILT_IN = load_scenario(None)


def tables(pv_port: int, op_port: int) -> str:
    return f"""
[io.devices.rack1]
url = "modbus://127.0.0.1:{pv_port}"
poll_period = 1.0
[io.devices.rack1.points."sensor.pv"]
address = 0
direction = "output"

[io.devices.rack2]
url = "modbus://127.0.0.1:{op_port}"
[io.devices.rack2.points."valve.op"]
address = 2
direction = "input"
"""


def scenario(io: str) -> Scenario:
    return parse_scenario(BUILT_IN.text + io, "racks.toml")


def test_the_devices_tables() -> None:
    sc = scenario(tables(5020, 5021))
    assert has_devices(sc)
    links = links_of(sc, split_scenario(sc))
    assert [(k.name, k.url, [p.name for p in k.regmap.points]) for k in links] == [
        ("rack1", "modbus://127.0.0.1:5020", ["sensor.pv"]),
        ("rack2", "modbus://127.0.0.1:5021", ["valve.op"])]
    assert links[0].regmap.poll_period == 1.0 and links[1].regmap.poll_period is None
    with pytest.raises(InputError, match="several devices"):
        map_of(sc, split_scenario(sc))  # a simulated device serves one device's map


@pytest.mark.parametrize(("io", "message"), [
    (tables(1, 2).replace('url = "modbus://127.0.0.1:1"\n', ""), r"rack1\]: url is missing"),
    (tables(1, 2).replace('"valve.op"', '"sensor.pv"').replace(
        'address = 2\ndirection = "input"', 'address = 2\ndirection = "output"'),
     r"sensor\.pv.* device rack1 already"),
    (tables(1, 2).split("[io.devices.rack2]")[0], r"no point for valve\.op"),
    ("\n[io]\ndevice_id = 1\n" + tables(1, 2).replace("[io.devices", "[io.devices", 1),
     r"device_id next to \[io.devices\]"),
    (tables(1, 2).replace("modbus://127.0.0.1:1", "http://x"), r"modbus://HOST:PORT"),
])
def test_a_wrong_devices_table_is_located(io: str, message: str) -> None:
    sc = scenario(io)
    with pytest.raises(InputError, match=message):
        links_of(sc, split_scenario(sc))


def test_a_controller_over_two_devices() -> None:
    split0 = split_scenario(BUILT_IN)

    async def main() -> None:
        # two simulated devices, each a whole plant; the controller reads the PV of the
        # first (every 1 s = 2 scans) and writes the valve of the second (every scan)
        a = Device(split_scenario(BUILT_IN), default_map(split0), speedup=50.0,
                   fstate_time=3600.0)
        b = Device(split_scenario(BUILT_IN), default_map(split0), speedup=50.0,
                   fstate_time=3600.0)
        pa, pb = await a.start("127.0.0.1", 0), await b.start("127.0.0.1", 0)
        tasks = [asyncio.create_task(a.run()), asyncio.create_task(b.run())]
        sc = scenario(tables(pa, pb))
        split = split_scenario(sc)
        links = links_of(sc, split)
        io = MultiIO(links, split.dt)
        ctl = LiveController(split, [k.regmap for k in links], io)
        try:
            for _ in range(10):
                await ctl.scan()
                await asyncio.sleep(0.01)
            rack1, rack2 = io.ios
            assert rack1.counters.reads == 5  # scans 0, 2, 4, 6, 8
            assert rack2.counters.reads == 10
            comp = ctl.module.blocks["compensator"]
            out = float(comp.y[comp._out_index["signal_out"]])
            await asyncio.sleep(0.05)
            assert b.applied("valve.op") == pytest.approx(out, rel=1e-6)  # float32
            assert io.status()["write_errors"] == 0
            # the PV's device goes away: its point Bad (no communication, last value), the
            # valve's device still written
            await a.stop()
            tasks[0].cancel()
            for _ in range(2):  # the next read of rack1 is due within two scans
                await ctl.scan()
            value, status = ctl.snapshot()["pid.PV"]
            assert status == st.BAD_NO_COMM_LUV and math.isfinite(value)
            assert await io.write({"valve.op": 42.0})
            await asyncio.sleep(0.05)
            assert b.applied("valve.op") == 42.0
        finally:
            await io.aclose()
            await b.stop()
            for t in tasks:
                t.cancel()

    asyncio.run(main())


def test_a_failed_device_leaves_only_its_points_unwritten() -> None:
    """serve publishes OUT Bad for the loops whose device points were not written
    (LiveController.out): with two devices, one down, only that one's points."""
    class Fake:
        def __init__(self, ok: bool) -> None:
            self.ok = ok

        async def write(self, values: dict[str, float]) -> bool:
            return self.ok

    multi = object.__new__(MultiIO)
    multi.ios = [Fake(True), Fake(False)]  # type: ignore[list-item]
    multi.writes_to = [{"valve_a.op"}, {"valve_b.op"}]
    ok = asyncio.run(multi.write({"valve_a.op": 1.0, "valve_b.op": 2.0}))
    assert not ok and multi.unwritten == {"valve_b.op"}
    multi.ios[1].ok = True  # type: ignore[attr-defined]
    assert asyncio.run(multi.write({"valve_a.op": 1.0, "valve_b.op": 2.0}))
    assert multi.unwritten == set()
