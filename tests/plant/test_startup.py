"""Issue 11 point 8: no start-up kick from the plant kinds.

Every plant kind publishes a real output before its first scan (its documented start value,
or its steady state for the input latched then), so a block that reads it earlier in a
module's order never sees a placeholder 0. In a module the input a block starts from is what
its wire carries before the first scan: the module settles its wires (copies each source's
start value into the inputs it feeds, in order) and the block re-publishes its start for
them (``publish_start``).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from loopworks import Module, create_block
from loopworks.sim.scenario import load_scenario

EXAMPLES = sorted((Path(__file__).resolve().parents[2] / "examples").glob("*.toml"))
PLANT = ("process.", "valve.", "sensor.", "disturbance.")


def plain_loop() -> Module:
    """pid -> valve -> process -> load -> sensor -> pid, in that (the declared, default)
    order: the pid reads the sensor's PV before the sensor's first scan."""
    blocks = {
        "pid": create_block("pid", k=1.0, ti=20.0, out_lo=0.0, out_hi=100.0, bias=50.0),
        "valve": create_block("valve.choudhury", resolution=0.5, deadband=0.2),
        "process": create_block("process.fopdt", gain=1.0, time_constant=20.0,
                                dead_time=2.0, u0=50.0),
        "load": create_block("disturbance.load", bias=1.5),
        "sensor": create_block("sensor.transmitter", gain=2.0, offset=-50.0),
    }
    wires = {"valve.op": "pid.out", "process.u": "valve.position", "load.u": "process.y",
             "sensor.y": "load.y", "pid.pv": "sensor.pv"}
    return Module(blocks, wires, inputs={"pid": {"sp": 53.0}})


def test_plain_loop_in_the_default_order_starts_without_a_kick() -> None:
    """The plant starts at its steady state: process y = K·u0 = 50, the load adds 1.5, the
    sensor reads 2·51.5 - 50 = 53 = SP. So the pid's first PV is 53 (not 0), its output stays
    at the bias, and the valve and the process do not move on the first scans."""
    result = plain_loop().run(5.0, 0.5)
    assert result.values["pid.pv"][0] == pytest.approx(53.0, abs=1e-12)
    for name in ("pid.out", "valve.position", "process.y"):
        assert list(result.values[name]) == pytest.approx([50.0] * 10, abs=1e-12), name
    assert list(result.values["sensor.pv"]) == pytest.approx([53.0] * 10, abs=1e-12)
    assert set(result.status["pid.pv"]) == {128}


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_shipped_examples_read_no_placeholder_from_a_plant_block(path: Path) -> None:
    """Every wire from a plant block that its destination reads before the source's first
    scan carries the source's real start: within 1 unit of what the source gives on that
    first scan (a placeholder 0 against a PV of 60 °C, as examples/cascade.toml had, fails)."""
    scenario = load_scenario(path)
    for variant, module in (scenario.variants or {"base": scenario.module}).items():
        position = {name: i for i, name in enumerate(module.order)}
        module.reset()
        start = {name: module.blocks[name].y.copy() for name in module.order}
        result = module.run(3 * scenario.dt, scenario.dt)
        for dest, src in module.wires.items():
            source, port = src.split(".")
            block = module.blocks[source]
            if not block.kind.startswith(PLANT) or position[source] < position[dest.split(".")[0]]:
                continue
            published = start[source][block._out_index[port]]
            first = result.values[src][0]
            assert abs(published - first) <= 1.0, (
                f"{path.name} [{variant}] {dest} = {src}: reads {published} before the first "
                f"scan, then {first}")
