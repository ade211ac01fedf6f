"""Properties every registered block kind keeps, on random parameters (within the documented
ranges) and random input sequences with NaN, ±inf, ±1e308, subnormals, every status quality and
dt jitter (issue 11, "make the class impossible"):

* no output is non-finite unless its status is Bad (an output that carries no status is always
  finite); no state is left non-finite;
* every output that has limits stays within them;
* the same inputs give the same outputs; save/resume mid-run gives the same outputs as one run;
* after a burst of Bad input the block's outputs are usable (not Bad) again.

The number of examples comes from the Hypothesis profile: ``default`` (the normal suite) or
``slow`` (``HYPOTHESIS_PROFILE=slow``: 10,000 examples per property per kind).
"""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import loopworks
from loopworks.blocks import layout
from loopworks.blocks.block import Block
from tests.properties.limits import output_limits
from tests.properties.strategies import Case, cases

KINDS = loopworks.kinds()

#: outputs that by the kind's documented rule stay unusable after Bad input, until an operator
#: acts: kind -> (outputs, the rule)
LATCHED_AFTER_BAD = {
    "relay": (("override", "period", "amplitude", "cycles", "phase", "stage", "shift", "relay",
               "active", "inactive"),
              "a Bad PV aborts the relay test and restores u0 (plant-and-tuning 3.4 item 7); a "
              "new test starts on the next enable edge"),
}


def run(block: Block, case: Case, start: int = 0, stop: int | None = None) -> list[list[Any]]:
    """Step ``block`` through scans start..stop of ``case``; each scan's outputs and statuses."""
    rows = []
    for dt, inputs in zip(case.dts[start:stop], case.inputs[start:stop], strict=True):
        out = block.step(dt, **inputs)
        rows.append([(out[name].value, out[name].status) for name in out])
    return rows


def same(a: list[list[Any]], b: list[list[Any]]) -> bool:
    """Equal scan by scan, NaN equal to NaN."""
    return np.array_equal(np.array(a, dtype=float), np.array(b, dtype=float), equal_nan=True)


def check_sound(block: Block, scan: int, case: Case) -> None:
    for i, port in enumerate(block.OUTPUTS):
        value, status = float(block.y[i]), int(block.ys[i])
        if not math.isfinite(value):
            assert port.status and status & 0xC0 == 0, (
                f"{block.kind} scan {scan}: output {port.name} = {value} with status {status} "
                f"(params {case.params}, inputs {case.inputs[scan]})")
    if np.isfinite(block.x).all():
        return
    for name, value in zip(layout.names(block.STATES, block.params), block.x, strict=True):
        assert math.isfinite(value), (
            f"{block.kind} scan {scan}: state {name} = {value} (params {case.params}, "
            f"inputs {case.inputs[scan]})")


@pytest.mark.parametrize("kind", KINDS)
@given(data=st.data())
def test_sound_within_limits_repeatable_and_resumable(kind: str, data: st.DataObject) -> None:
    """The first three properties on one random case: every scan's outputs finite unless Bad
    and its states finite, within their limits; a second block given the same inputs gives
    the same outputs (saving its state on the way changes nothing); a third one resumed from
    that saved state at the middle scan gives the same outputs from there."""
    case = data.draw(cases(kind))
    block = case.make()
    limits = output_limits(block)
    whole = []
    for k, (dt, inputs) in enumerate(zip(case.dts, case.inputs, strict=True)):
        out = block.step(dt, **inputs)
        whole.append([(out[name].value, out[name].status) for name in out])
        check_sound(block, k, case)
        for name, (lo, hi) in limits.items():
            i = block._out_index[name]
            value, status = float(block.y[i]), int(block.ys[i])
            if status & 0xC0 != 0 or not block.OUTPUTS[i].status:
                assert lo <= value <= hi, (
                    f"{kind} scan {k}: {name} = {value} outside its limits [{lo}, {hi}] "
                    f"(params {case.params})")
    half = len(case.dts) // 2
    again = case.make()
    head = run(again, case, 0, half)
    saved = json.loads(json.dumps(again.state_dict()))
    assert same(whole, head + run(again, case, half)), (
        f"{kind}: two runs differ ({case.params})")
    resumed = case.make()
    resumed.load_state(saved)
    tail = run(resumed, case, half)
    assert same(whole, head + tail), f"{kind}: resumed at scan {half} differs ({case.params})"


BURST_LENGTHS = st.integers(1, 5)
BURST_VALUES = st.sampled_from([math.nan, math.inf, -math.inf, 1e308])
BURST_STATUSES = st.sampled_from([0, 0x0C, 0x18, 128])


@pytest.mark.parametrize("kind", KINDS)
@given(data=st.data())
def test_recovers_after_a_bad_burst(kind: str, data: st.DataObject) -> None:
    """Good inputs, a burst of NaN / inf / Bad status, then the same good inputs as before the
    burst for long enough: every output that is usable without the burst is usable again."""
    case = data.draw(cases(kind, special=0.0, bad=0.0, scans=(6, 20)))
    burst_len = data.draw(BURST_LENGTHS)
    burst = []
    ports = case.make().INPUTS  # an instance's: deltav.calc's come from its expression
    for _ in range(burst_len):
        row: dict[str, Any] = {}
        for port in ports:
            if port.choices or port.name == "clock":
                row[port.name] = case.inputs[-1][port.name]
            else:
                value = data.draw(BURST_VALUES)
                status = data.draw(BURST_STATUSES)
                row[port.name] = (value, status)
        burst.append(row)
    tail = 60
    steady = [case.inputs[-1]] * tail
    dt = case.dts[-1]
    reference = Case(case.kind, case.params, case.dts + [dt] * tail, case.inputs + steady)
    disturbed = Case(case.kind, case.params, case.dts + [dt] * (burst_len + tail),
                     case.inputs + burst + steady)
    ref = run(reference.make(), reference)[-1]
    block = disturbed.make()
    got = run(block, disturbed)[-1]
    latched = LATCHED_AFTER_BAD.get(kind, ((), ""))[0]
    for (name, (_, ref_status), (value, status)) in zip(block.OUTPUTS, ref, got, strict=True):
        if ref_status & 0xC0 != 0 and name.name not in latched:
            assert status & 0xC0 != 0 and math.isfinite(value), (
                f"{kind}: output {name.name} still {value} status {status} {tail} scans after "
                f"a Bad burst (params {case.params})")
