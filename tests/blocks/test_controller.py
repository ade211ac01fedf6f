"""The controller interface's action and output range (loopworks.blocks.controller): what each
controller class says equals what the relay test used before the tables moved into the classes
(issue 13 point 1): the action parameter of each vendor (pid ``action``; DeltaV CONTROL_OPTS
direct acting, spec 4.2/4.9; GE Config Word bit 0, spec 1.3; S5 K < 0, spec 2.5; E2
``error_sign``, spec 3.3) and the output limits (pid ``out_lo``/``out_hi``; DeltaV
OUT_LO_LIM/OUT_HI_LIM when both are given, else OUT_SCALE, spec 4.1; GE clamps words 11/10,
spec 1.2; S5 BGUG/BGOG, spec 2.8; E2 Output at Minimum/Maximum, spec 3.4)."""

from __future__ import annotations

from typing import Any

import pytest

from loopworks.blocks.controller import Controller
from loopworks.catalog import block_class, controller_kinds, create_block

CONTROLLERS = ["deltav.pid", "e2.pid", "ge.pid_ind", "ge.pid_isa", "pid", "s5.pid"]

#: (kind, parameters, direct acting, output range) as sim/tune.py's tables gave them
CASES: list[tuple[str, dict[str, Any], bool, tuple[float, float]]] = [
    ("pid", {}, False, (0.0, 100.0)),
    ("pid", {"action": "direct", "out_lo": -5.0, "out_hi": 5.0}, True, (-5.0, 5.0)),
    ("deltav.pid", {}, False, (0.0, 100.0)),
    ("deltav.pid", {"direct_acting": True, "out_scale_eu_0": -50.0, "out_scale_eu_100": 250.0},
     True, (-50.0, 250.0)),
    ("deltav.pid", {"out_scale_eu_100": 200.0, "out_lo_lim": 10.0, "out_hi_lim": 150.0},
     False, (10.0, 150.0)),
    # one limit alone: the OUT_SCALE span, as before (the relay's own limits)
    ("deltav.pid", {"out_hi_lim": 80.0}, False, (0.0, 100.0)),
    ("ge.pid_ind", {}, False, (0.0, 32000.0)),
    ("ge.pid_ind", {"direct_acting": True, "lower_clamp": -1000.0, "upper_clamp": 16000.0},
     True, (-1000.0, 16000.0)),
    ("ge.pid_isa", {}, False, (0.0, 32000.0)),
    ("ge.pid_isa", {"direct_acting": True, "invert_output": True, "upper_clamp": 20000.0},
     True, (0.0, 20000.0)),
    ("s5.pid", {}, False, (-32768.0, 32767.0)),
    ("s5.pid", {"k": -500, "bgug": 0, "bgog": 27648}, True, (0.0, 27648.0)),
    ("s5.pid", {"k": 0}, False, (-32768.0, 32767.0)),
    ("e2.pid", {}, True, (0.0, 100.0)),
    ("e2.pid", {"error_sign": "setpoint_minus_input", "output_min": 10.0,
                "output_max": 90.0}, False, (10.0, 90.0)),
]


def test_the_controllers_are_the_six_kinds() -> None:
    assert controller_kinds() == CONTROLLERS
    for kind in CONTROLLERS:
        assert issubclass(block_class(kind), Controller)


@pytest.mark.parametrize(("kind", "params", "direct", "limits"), CASES)
def test_action_and_output_range_as_before(kind: str, params: dict[str, Any], direct: bool,
                                           limits: tuple[float, float]) -> None:
    block = create_block(kind, **params)
    cls = type(block)
    assert issubclass(cls, Controller)
    assert cls.direct_acting(block.params) is direct
    assert cls.output_range(block.params) == limits


def test_only_s5_velocity_outputs_increments() -> None:
    """spec 2.7: the velocity algorithm (D 11.3) outputs dY_k; the relay test refuses it."""
    for kind in CONTROLLERS:
        cls = block_class(kind)
        assert issubclass(cls, Controller)
        assert cls.incremental(cls().params) is None, kind
    s5 = block_class("s5.pid")
    assert issubclass(s5, Controller)
    assert "velocity" in (s5.incremental(s5(velocity=True).params) or "")


@pytest.mark.parametrize("kind", ["ge.pid_ind", "ge.pid_isa"])
def test_ge_action_follows_the_config_word(kind: str) -> None:
    """spec 1.3: bit 0 of the Config Word (word 13) is the direct-acting flag; a block given
    ``config_word`` instead of the flags acts as its bit 0 says."""
    cls = block_class(kind)
    assert issubclass(cls, Controller)
    assert cls.direct_acting(create_block(kind, config_word=1).params) is True
    assert cls.direct_acting(create_block(kind, config_word=4).params) is False
    assert cls.direct_acting(create_block(kind, config_word=5).params) is True


def test_a_controller_without_its_law_cannot_be_made() -> None:
    """The interface's output range and law are abstract: a controller class that does not
    say them is refused at construction, naming what is missing."""
    from loopworks.blocks.block import Block

    class Incomplete(Controller, Block):
        kind = "incomplete"

    with pytest.raises(TypeError, match="from_law, law, output_range"):
        Incomplete()
