"""A scenario cut in two: the plant side (a field device) and the controller side.

The live commands run one scenario on two machines, or two processes: ``loopworks device``
scans the plant blocks and serves their I/O, and ``loopworks serve`` scans the controller
blocks against it. :func:`split_scenario` makes the two modules from one scenario:

* **plant** blocks are those whose kind starts with ``process.``, ``valve.``, ``sensor.`` or
  ``disturbance.``; every other block (controllers, compensators, signal generators, calc)
  is on the **controller** side;
* a wire inside one side stays a wire; a wire that crosses becomes an unwired input of the
  side that reads it (``to_plant``: ``("valve.op", "compensator.signal_out")``;
  ``to_controller``: ``("pid.pv", "sensor.pv")``), which the live I/O sets every scan. Until
  then it holds, as a constant, the value its source has in the full module: a plant output
  once the module has settled (:meth:`loopworks.sim.module.Module.reset`), a controller
  output after the module's first scan (before it, a controller's output is a placeholder:
  a valve opening of 0 would shut the valve before the controller first writes);
* each ``[[events]]`` entry goes to the side its target block is on.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from loopworks.errors import InputError
from loopworks.sim.module import Event, Module
from loopworks.sim.scenario import Scenario

#: block kinds with these prefixes are the plant: what a field device would hold
PLANT_PREFIXES = ("process.", "valve.", "sensor.", "disturbance.")


def is_plant_kind(kind: str) -> bool:
    """True for a plant block kind (``process.fopdt``, ``valve.karnopp``, ...)."""
    return kind.lower().startswith(PLANT_PREFIXES)


@dataclass(frozen=True)
class Split:
    """The two sides of a scenario variant.

    ``to_plant`` lists (plant input, controller output) pairs, ``to_controller`` lists
    (controller input, plant output) pairs, each as ``"block.port"``; ``dt`` is the scan
    time of both sides (s), the scenario's."""

    plant: Module
    controller: Module
    to_plant: list[tuple[str, str]]
    to_controller: list[tuple[str, str]]
    variant: str
    dt: float

    def device_inputs(self) -> list[str]:
        """The plant inputs the controller writes (``"valve.op"``), each once, in wire order."""
        return list(dict.fromkeys(dest for dest, _ in self.to_plant))

    def device_outputs(self) -> list[str]:
        """The plant outputs the controller reads (``"sensor.pv"``), each once, in wire
        order."""
        return list(dict.fromkeys(src for _, src in self.to_controller))


def _output(module: Module, ref: str) -> float:
    """The value of output ``ref`` ("block.port") of ``module``, as it holds now."""
    block, port = ref.rsplit(".", 1)
    return float(module.blocks[block].outputs()[port].value)


def split_scenario(sc: Scenario, variant: str | None = None) -> Split:
    """Cut variant ``variant`` (default: the scenario's first) of ``sc`` into its plant and
    controller modules; see the module docstring for the rules. InputError names an unknown
    variant and lists the scenario's, or a scenario with no block on one side."""
    names = list(sc.variants)
    if variant is None:
        variant = names[0]
    elif variant not in sc.variants:
        raise InputError(f"variant {variant!r} is not a variant of {sc.source}; variants: "
                         + ", ".join(names))
    full = sc.build(variant)
    plant_names = [n for n in full.order if is_plant_kind(full.blocks[n].kind)]
    ctrl_names = [n for n in full.order if n not in plant_names]
    for side, members in (("plant", plant_names), ("controller", ctrl_names)):
        if not members:
            kinds = ", ".join(f"{n} ({b.kind})" for n, b in full.blocks.items())
            raise InputError(
                f"{sc.source}: no {side} block to run live: plant blocks have kinds starting "
                f"with {', '.join(PLANT_PREFIXES)}, the others are the controller's; "
                f"blocks: {kinds}")
    plant_set = set(plant_names)

    def side_of(ref: str) -> bool:
        return ref.rsplit(".", 1)[0] in plant_set

    plant_wires: dict[str, str] = {}
    ctrl_wires: dict[str, str] = {}
    to_plant: list[tuple[str, str]] = []
    to_controller: list[tuple[str, str]] = []
    for dest, src in full.wires.items():
        if side_of(dest) and side_of(src):
            plant_wires[dest] = src
        elif not side_of(dest) and not side_of(src):
            ctrl_wires[dest] = src
        elif side_of(dest):
            to_plant.append((dest, src))
        else:
            to_controller.append((dest, src))

    # the controller's outputs are placeholders until its first scan (a valve opening of 0
    # would shut the valve before the controller writes): the device's inputs start at what
    # the controller gives after one scan of the whole loop
    probe = sc.build(variant)
    probe.scan(sc.dt)

    def constants(members: list[str], crossing: list[tuple[str, str]], source: Module
                  ) -> dict[str, dict[str, Any]]:
        values = {n: dict(full.constants[n]) for n in members if n in full.constants}
        for dest, src in crossing:
            block, port = dest.rsplit(".", 1)
            values.setdefault(block, {})[port] = _output(source, src)
        return values

    plant_inputs = constants(plant_names, to_plant, probe)
    ctrl_inputs = constants(ctrl_names, to_controller, full)
    plant_events = [Event(e.t, e.target, e.value) for e in full.events if side_of(e.target)]
    ctrl_events = [Event(e.t, e.target, e.value) for e in full.events
                   if not side_of(e.target)]
    # the full module's blocks become the plant's (it is not used again); a second build
    # gives the controller its own blocks (a block object belongs to one module)
    other = sc.build(variant)
    plant = Module({n: full.blocks[n] for n in plant_names}, wires=plant_wires,
                   inputs=plant_inputs, order=plant_names, events=plant_events)
    controller = Module({n: other.blocks[n] for n in ctrl_names}, wires=ctrl_wires,
                        inputs=ctrl_inputs, order=ctrl_names, events=ctrl_events)
    return Split(plant, controller, to_plant, to_controller, variant, sc.dt)
