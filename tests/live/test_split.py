"""split_scenario: the built-in scenario cut into its plant (the device) and controller."""

from __future__ import annotations

import pytest

from loopworks.errors import InputError
from loopworks.live.split import is_plant_kind, split_scenario
from loopworks.sim.scenario import load_scenario, parse_scenario

SC = load_scenario(None)


def test_builtin_scenario_blocks_go_to_their_side() -> None:
    split = split_scenario(SC)
    assert split.variant == "compensation_off"  # the first [compare] variant
    assert split.dt == 0.5
    assert split.plant.order == ["process", "load", "sensor", "valve"]
    assert split.controller.order == ["pid", "sggn1", "compensator"]
    assert {b.kind for b in split.plant.blocks.values()} == {
        "process.fopdt", "disturbance.load", "sensor.transmitter", "valve.karnopp"}


def test_builtin_scenario_crossing_wires() -> None:
    split = split_scenario(SC)
    assert split.to_plant == [("valve.op", "compensator.signal_out")]
    assert split.to_controller == [("pid.pv", "sensor.pv")]
    assert split.device_inputs() == ["valve.op"]
    assert split.device_outputs() == ["sensor.pv"]
    # the wires inside each side stay; the crossing ones are gone from both
    assert split.plant.wires == {"process.u": "valve.position", "load.u": "process.y",
                                 "sensor.y": "load.y"}
    assert "valve.op" not in split.plant.wires and "pid.pv" not in split.controller.wires
    assert split.controller.wires["compensator.signal_in"] == "pid.out"
    assert len(split.plant.wires) + len(split.controller.wires) + 2 == len(
        SC.build("compensation_off").wires)


def test_crossing_inputs_start_at_the_full_modules_settled_values() -> None:
    # the PV as the plant publishes it at rest; the valve opening as the controller gives it
    # after its first scan (before it, the compensator's output is a placeholder 0 that
    # would shut the valve)
    split = split_scenario(SC)
    full = SC.build("compensation_off")
    pv = full.blocks["sensor"].outputs()["pv"].value
    full.scan(SC.dt)
    op = full.blocks["compensator"].outputs()["signal_out"].value
    assert pv == pytest.approx(50.0)  # the settled start of the built-in loop
    assert op == pytest.approx(50.0)  # MAN at MAN_OUT = 50 %
    assert split.controller.constants["pid"]["pv"] == pv
    assert split.plant.constants["valve"]["op"] == op
    # held by the blocks as their inputs (the module applied the constants on reset)
    valve, pid = split.plant.blocks["valve"], split.controller.blocks["pid"]
    assert valve.u[[p.name for p in valve.INPUTS].index("op")] == op
    assert pid.u[[p.name for p in pid.INPUTS].index("pv")] == pv
    # the scenario's own constants are kept
    assert split.controller.constants["pid"]["sp"] == 50.0


def test_the_two_sides_hold_independent_blocks() -> None:
    split = split_scenario(SC)
    plant_ids = {id(b) for b in split.plant.blocks.values()}
    assert not plant_ids & {id(b) for b in split.controller.blocks.values()}
    split.plant.blocks["valve"].set_inputs({"op": 80.0})
    for _ in range(40):
        split.plant.scan(split.dt)
    assert split.plant.blocks["valve"].outputs()["position"].value > 60.0
    assert split.plant.t == pytest.approx(20.0)
    assert split.controller.t == 0.0


def test_events_go_to_the_side_of_their_target() -> None:
    split = split_scenario(SC)
    assert [e.target for e in split.controller.events] == ["pid.mode", "pid.sp"]
    assert split.plant.events == []
    text = SC.text + '\n[[events]]\nt = 30.0\nset = "process.gain"\nvalue = 2.0\n'
    split = split_scenario(parse_scenario(text, "with-plant-event.toml"))
    assert [(e.t, e.target, e.value) for e in split.plant.events] == [
        (30.0, "process.gain", 2.0)]
    assert len(split.controller.events) == 2


def test_variant_choice_and_unknown_variant() -> None:
    on = split_scenario(SC, "compensation_on")
    assert on.variant == "compensation_on"
    assert on.controller.constants["compensator"]["comp_start"] == 1.0
    with pytest.raises(InputError, match=r"'nope'.*compensation_off, compensation_on"):
        split_scenario(SC, "nope")


def test_a_scenario_with_no_plant_block_is_refused() -> None:
    text = ('[simulation]\ndt = 1.0\nduration = 10.0\n[blocks.pid]\nkind = "pid"\n'
            'k = 1.0\nti = 10.0\n')
    with pytest.raises(InputError, match=r"no plant block.*process\., valve\."):
        split_scenario(parse_scenario(text, "ctrl-only.toml"))


@pytest.mark.parametrize(("kind", "plant"), [
    ("process.fopdt", True), ("valve.karnopp", True), ("sensor.transmitter", True),
    ("disturbance.load", True), ("deltav.pid", False), ("deltav.stick_slip", False),
    ("pid", False), ("processor", False)])
def test_plant_kinds(kind: str, plant: bool) -> None:
    assert is_plant_kind(kind) is plant
