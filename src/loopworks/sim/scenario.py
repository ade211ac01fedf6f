"""Scenario files (TOML): build a :class:`~loopworks.sim.module.Module` and its run settings.

    [simulation]            dt (s), duration (s), seed, optional order = ["process", "pid"]
    [blocks.NAME]           kind = "pid", then parameters, and constants for unwired inputs
    [wires]                 "process.u" = "pid.out"    (destination = source)
    [[events]]              t = 100.0, set = "pid.sp", value = 60.0

Blocks run in the order their tables appear, unless ``[simulation] order`` says otherwise. Keys
match parameter and input names in any letter case. Errors name the file and the table.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from loopworks.errors import FileFormatError, LoopworksError
from loopworks.sim.module import Event, Module

DEFAULT_SCENARIO = "default.toml"


class _Simulation(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True)
    dt: float = Field(gt=0, allow_inf_nan=False, description="scan time, s")
    duration: float = Field(gt=0, allow_inf_nan=False, description="run length, s")
    seed: int | None = None
    order: list[str] | None = None
    title: str = ""


class _Event(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True)
    t: float = Field(ge=0, allow_inf_nan=False)
    set: str
    value: float | str


class _Scenario(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=False)
    simulation: _Simulation
    blocks: dict[str, dict[str, Any]]
    wires: dict[str, str] = {}
    events: list[_Event] = []


@dataclass
class Scenario:
    """A loaded scenario: the module, and how long and how finely to run it."""

    module: Module
    dt: float
    duration: float
    seed: int | None
    title: str
    source: str


def _format_validation(err: ValidationError, source: str) -> str:
    lines = []
    for e in err.errors(include_url=False):
        loc = ".".join(str(p) for p in e["loc"])
        got = f" (got {e['input']!r})" if "input" in e and not isinstance(e["input"], dict) else ""
        lines.append(f"{source}: {loc}: {e['msg']}{got}")
    return "; ".join(lines)


def load_scenario(path: str | Path | None = None) -> Scenario:
    """Load a scenario file; ``None`` loads the built-in default scenario."""
    if path is None:
        text = resources.files("loopworks.scenarios").joinpath(DEFAULT_SCENARIO).read_text()
        return parse_scenario(text, f"<built-in {DEFAULT_SCENARIO}>")
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise FileFormatError(f"{p}: cannot read the scenario: {exc.strerror}") from None
    return parse_scenario(text, str(p))


def parse_scenario(text: str, source: str = "<scenario>") -> Scenario:
    """Build a scenario from TOML text; ``source`` names it in error messages."""
    from loopworks.blocks.registry import block_class

    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise FileFormatError(f"{source}: invalid TOML: {exc}") from None
    try:
        sc = _Scenario.model_validate(raw)
    except ValidationError as exc:
        raise FileFormatError(_format_validation(exc, source)) from None
    if not sc.blocks:
        raise FileFormatError(f"{source}: [blocks] is empty: expected at least one "
                              "[blocks.NAME] table with a kind")
    blocks = {}
    constants: dict[str, dict[str, Any]] = {}
    for name, table in sc.blocks.items():
        where = f"{source}: [blocks.{name}]"
        if not isinstance(table, dict) or "kind" not in {k.lower() for k in table}:
            raise FileFormatError(f"{where}: expected a table with kind = \"...\"")
        table = {k.lower(): v for k, v in table.items()}
        kind = table.pop("kind")
        try:
            cls = block_class(str(kind))
        except LoopworksError as exc:
            raise FileFormatError(f"{where}: {exc}") from None
        try:
            params, constants[name] = cls.split_table(table)
            blocks[name] = cls(**params)
        except LoopworksError as exc:
            raise FileFormatError(f"{where}: {exc}") from None
    events = [Event(e.t, e.set, e.value) for e in sc.events]
    try:
        module = Module(blocks, wires=sc.wires, inputs=constants, order=sc.simulation.order,
                        events=events)
    except LoopworksError as exc:
        raise FileFormatError(f"{source}: {exc}") from None
    sim = sc.simulation
    return Scenario(module, sim.dt, sim.duration, sim.seed, sim.title, source)
