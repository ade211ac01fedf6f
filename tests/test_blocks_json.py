"""``loopworks blocks KIND --json`` (issue 13 point 2): for every kind the JSON parses and says
exactly what the class declares; for the six controllers the roles, the automatic and manual
input values, the action and the handover are real and work (a block put in MANUAL follows
its man_out input, in AUTOMATIC it controls); docs/blocks-json.md describes every key."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from loopworks.blocks.block import Block
from loopworks.blocks.controller import Controller, Roles
from loopworks.blocks.reference import declaration, json_value
from loopworks.blocks.relay import Relay
from loopworks.catalog import block_class, controller_kinds, kinds
from loopworks.cli import app

DOC = Path(__file__).resolve().parents[1] / "docs" / "blocks-json.md"
TOP = ["kind", "summary", "parameters", "inputs", "outputs", "controller"]


def blocks_json(*args: str) -> Any:
    result = CliRunner().invoke(app, ["blocks", *args, "--json"])
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)


def finite_or_text(x: Any) -> Any:
    """What the JSON holds for a declared value (non-finite floats as text)."""
    return json_value(x)


@pytest.mark.parametrize("kind", kinds())
def test_json_is_the_declaration(kind: str) -> None:
    cls = block_class(kind)
    data = blocks_json(kind)
    assert list(data) == TOP
    assert data == declaration(cls)
    assert (data["kind"], data["summary"]) == (cls.kind, cls.describe())
    assert [p["name"] for p in data["parameters"]] == [p.name for p in cls.PARAMS]
    for p, shown in zip(cls.PARAMS, data["parameters"], strict=True):
        assert shown["unit"] == p.unit and shown["meaning"] == p.meaning
        assert shown["type"] == p.type and shown["default"] == finite_or_text(p.default)
        assert shown["default_text"] == p.default_text
        assert shown["choices"] == list(p.choices) and shown["range_text"] == p.range_text()
        if p.type in ("float", "int"):
            assert shown["range"] == {"lo": finite_or_text(p.lo), "lo_open": p.lo_open,
                                      "hi": finite_or_text(p.hi), "hi_open": p.hi_open}
        else:
            assert shown["range"] is None
    for ports, shown_ports in ((cls.INPUTS, data["inputs"]), (cls.OUTPUTS, data["outputs"])):
        assert [p["name"] for p in shown_ports] == [p.name for p in ports]
        for port, shown in zip(ports, shown_ports, strict=True):
            assert shown["unit"] == port.unit and shown["meaning"] == port.meaning
            assert shown["default"] == finite_or_text(port.default)
            assert shown["status"] is port.status
            assert shown["choices"] == [{"code": i, "name": n} for i, n in enumerate(port.choices)]
    assert (data["controller"] is None) == (not issubclass(cls, Controller))


def test_listing_names_every_kind_and_the_controllers() -> None:
    listing = blocks_json()
    assert [k["kind"] for k in listing] == kinds()
    assert all(k["summary"] == block_class(k["kind"]).describe() for k in listing)
    assert [k["kind"] for k in listing if k["controller"]] == controller_kinds()
    assert len(controller_kinds()) == 6


def test_an_unknown_kind_is_one_error_line() -> None:
    result = CliRunner().invoke(app, ["blocks", "no.such", "--json"])
    assert result.exit_code == 2 and "unknown block kind 'no.such'" in result.output


@pytest.mark.parametrize("kind", controller_kinds())
def test_controller_declaration_names_real_ports_and_values(kind: str) -> None:
    cls = block_class(kind)
    assert issubclass(cls, Controller)
    ctrl = blocks_json(kind)["controller"]
    inputs = {p.name: p for p in cls.INPUTS}
    outputs = {p.name for p in cls.OUTPUTS}
    params = {p.name: p for p in cls.PARAMS}
    roles = ctrl["roles"]
    assert roles == cls.ROLES.as_dict()
    assert roles["sp"] in inputs and roles["pv"] in inputs and roles["out"] in outputs
    for role in ("ff", "mode", "man_out", "track", "track_value"):
        assert roles[role] is None or roles[role] in inputs, role
    assert roles["working_sp"] is None or roles["working_sp"] in outputs
    for values in (ctrl["automatic"], ctrl["manual"]):
        for name, value in values.items():
            assert name in inputs
            inputs[name].parse(value)  # a valid value (names of an enumerated input)
    if roles["mode"] is not None:  # the mode input switches, and differently
        assert roles["mode"] in ctrl["automatic"] and roles["mode"] in ctrl["manual"]
        assert (inputs[roles["mode"]].parse(ctrl["automatic"][roles["mode"]])
                != inputs[roles["mode"]].parse(ctrl["manual"][roles["mode"]]))
    action = ctrl["action"]
    assert action["parameter"] in params and action["op"] in ("=", "<")
    defaults = {p.name: p.default for p in cls.PARAMS}
    assert action["default"] == ("direct" if cls.direct_acting(defaults) else "reverse")
    assert action["parameter"] in action["rule"]
    relay_outputs = {p.name for p in Relay.OUTPUTS}
    for link in ctrl["handover"]["inputs"]:
        assert link["input"] in inputs and link["from"] in relay_outputs
    for name, value in ctrl["handover"]["params"].items():
        assert params[name].check(value, kind) == value


#: kind: (parameters, dt, pv, |error|, manual output), in the controller's own units
BEHAVIOUR: dict[str, tuple[dict[str, Any], float, float, float, float]] = {
    "pid": ({"k": 1.0, "ti": 10.0}, 1.0, 50.0, 5.0, 30.0),
    "deltav.pid": ({"gain": 1.0, "reset": 10.0}, 1.0, 50.0, 5.0, 30.0),
    "ge.pid_ind": ({"kp": 1.0, "ki": 0.1}, 0.1, 9000.0, 1000.0, 8000.0),
    "ge.pid_isa": ({"kc": 1.0, "ti": 10.0}, 0.1, 9000.0, 1000.0, 8000.0),
    "s5.pid": ({"ti": 100}, 1.0, 9000.0, 1000.0, 5000.0),
    "e2.pid": ({}, 1.0, 50.0, 5.0, 30.0),
}


def test_behaviour_covers_every_controller() -> None:
    assert sorted(BEHAVIOUR) == controller_kinds()


@pytest.mark.parametrize("kind", controller_kinds())
@pytest.mark.parametrize("push", [1.0, -1.0])
def test_manual_follows_man_out_and_automatic_controls(kind: str, push: float) -> None:
    """MANUAL plus a man_out value: OUT goes to that value (S5 within manual_steps samples,
    spec 2.9) and stays; then AUTOMATIC with an error that asks for more (push = 1) or less
    output under the declared action: OUT leaves the manual value that way."""
    params, dt, pv, err, man = BEHAVIOUR[kind]
    cls = block_class(kind)
    assert issubclass(cls, Controller)
    block: Block = cls(**params)
    roles = cls.ROLES
    assert roles.man_out is not None
    sign = 1.0 if cls.direct_acting(block.params) else -1.0
    sp = pv - push * sign * err  # e = SP - PV (reverse) or PV - SP (direct) has push's sign
    manual = [block.step(dt, **{roles.sp: sp, roles.pv: pv}, **cls.MANUAL,
                         **{roles.man_out: man})[roles.out].value for _ in range(10)]
    assert manual[-4:] == [man] * 4
    auto = [block.step(dt, **{roles.sp: sp, roles.pv: pv}, **cls.AUTOMATIC)[roles.out].value
            for _ in range(10)]
    assert all(math.isfinite(u) for u in auto)
    assert push * (auto[-1] - man) > 0.0, auto


def _keys(value: Any) -> set[str]:
    if isinstance(value, dict):
        return set(value) | {k for v in value.values() for k in _keys(v)}
    if isinstance(value, list):
        return {k for v in value for k in _keys(v)}
    return set()


def test_the_docs_page_names_every_key() -> None:
    text = DOC.read_text(encoding="utf-8")
    keys = {k for kind in kinds() for k in _keys(declaration(block_class(kind)))}
    keys |= _keys(blocks_json()[0])
    # the names of automatic/manual/handover params are the controller's own inputs and params
    own = {p.name for kind in controller_kinds() for p in
           (*block_class(kind).INPUTS, *block_class(kind).PARAMS)}
    missing = sorted(k for k in keys - own if f"`{k}`" not in text)
    assert missing == []
    for key in (*TOP, *Roles.__dataclass_fields__):
        assert f"`{key}`" in text
