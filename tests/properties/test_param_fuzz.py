"""Fuzzing block construction from Python (standards: "a wrong parameter raises an error that
names it, its value and the allowed range").

Any kind, any of its parameters given a value of any type (numbers at and beyond every edge,
NaN, infinities, text, None, lists): ``create_block`` gives a block or a ParameterError that
names a parameter; a block then takes a few scans of random inputs at random
dt and gives outputs (finite unless Bad) or a LoopworksError, never another exception."""

from __future__ import annotations

import math
import re
from typing import Any

from hypothesis import given
from hypothesis import strategies as st

import loopworks
from loopworks.catalog import block_class, kinds
from loopworks.errors import LoopworksError, ParameterError

VALUES: list[Any] = [0, 1, -1, 0.0, -0.0, 1e-320, 1e308, -1e308, math.inf, -math.inf, math.nan,
                     2**63, -2**63 - 1, True, False, "", "x", "AUTO", "inf", "nan", "1", [],
                     [1.0], {}, None, 1e12, 1e-12, 0.5, 100.0, 3, 7]
KINDS = kinds()


@st.composite
def construction(draw: st.DrawFn) -> tuple[str, dict[str, Any]]:
    kind = draw(st.sampled_from(KINDS))
    params = {}
    for p in block_class(kind).PARAMS:
        if draw(st.integers(0, 9)) < 3:
            params[p.name] = draw(st.sampled_from(VALUES + list(p.choices)))
    return kind, params


@given(made=construction(), data=st.data())
def test_any_parameter_values_give_a_block_or_a_named_error(
        made: tuple[str, dict[str, Any]], data: st.DataObject) -> None:
    kind, params = made
    try:
        block = loopworks.create_block(kind, jit=False, **params)
    except ParameterError as exc:  # names a parameter of the kind (a given one, or one it
        # conflicts with: "'interval' = 1 ... must be above pulse_width = 1 s")
        names = [p.name for p in block_class(kind).PARAMS]
        assert any(re.search(rf"\b{name}\b", str(exc)) for name in names), str(exc)
        assert "\n" not in str(exc).strip(), str(exc)
        return
    except LoopworksError as exc:  # a combination the block refuses: one line
        assert str(exc).strip() and "\n" not in str(exc).strip(), str(exc)
        return
    for _ in range(data.draw(st.integers(1, 4))):
        inputs = {port.name: data.draw(st.sampled_from(VALUES))
                  for port in block_class(kind).INPUTS if data.draw(st.booleans())}
        try:
            outputs = block.step(data.draw(st.sampled_from([0.1, 1.0, 1e-9, 1e9])), **inputs)
        except LoopworksError as exc:
            assert str(exc).strip(), repr(exc)
            continue
        for name, signal in outputs.items():
            assert math.isfinite(signal.value) or (signal.status & 0xC0) == 0, (
                f"{kind}.{name} = {signal.value} with status {signal.status:#x}")


TEXT_VALUES = ["0", "1", "-1", "1e308", "-1e308", "inf", "-inf", "nan", "", "x", "1e-320",
               "AUTO", "true", "false", "2", "100", "0.5", "1e12", "ideal", "parallel",
               "series", "standard", "direct", "reverse", "exact"]
TARGET_NAMES = ["form", "alpha", "r", "scale", "dd_decay", "throttling_range", "i_tr_normalise",
                "d_tr_normalise", "arithmetic", "sample_period", "update_interval",
                "pv_scale_eu_0", "pv_scale_eu_100", "out_scale_eu_100", "b", "c", "spans"]


@given(data=st.data())
def test_any_conversion_gives_settings_or_a_one_line_error(data: st.DataObject) -> None:
    """``loopworks convert`` as the CLI calls it (every value text): between any two controller
    kinds, with any source parameters, target settings and sample time, the result is a
    conversion whose note states no NaN, or one error line (found by fuzzing: target
    settings read with int() and float(), bool("false"), words of inf, 1/Td of a subnormal
    Td)."""
    from loopworks.catalog import controller_kinds
    from loopworks.tuning.convert import convert

    kinds = controller_kinds()
    source = data.draw(st.sampled_from(kinds))
    names = [p.name for p in block_class(source).PARAMS]
    params = {data.draw(st.sampled_from(names)): data.draw(st.sampled_from(TEXT_VALUES))
              for _ in range(data.draw(st.integers(0, 4)))}
    target = {data.draw(st.sampled_from(TARGET_NAMES)): data.draw(st.sampled_from(TEXT_VALUES))
              for _ in range(data.draw(st.integers(0, 3)))}
    sample_time = data.draw(st.sampled_from([None, "1", "0.1", "1e-320", "1e308", "0", "x"]))
    try:
        out = convert(source, params, data.draw(st.sampled_from(kinds)),
                      sample_time=sample_time, target=target)  # type: ignore[arg-type]
    except LoopworksError as exc:
        assert str(exc).strip() and "\n" not in str(exc).strip(), str(exc)
        return
    assert out.note and "nan" not in out.note.lower(), out.note
    for name, value in out.params.items():
        assert not (isinstance(value, float) and math.isnan(value)), (name, out.params)
