"""Properties of the controllers ``pid`` and ``e2.pid`` and of the generic compensators
(issue 11, "make the class impossible"), on random parameters within their documented ranges:

* the kernel is sound by itself, for every kind that declares it (``Block.SOUND_KERNEL``): run
  without the numeric guard of ``kernel.guarded_scan`` (only the guard's first step, non-finite
  inputs shown as Bad, is done here), no scan leaves a state non-finite or an output non-finite
  with a status that is not Bad, so the guard's fallback (undo and rerun as Bad input, which
  such kinds skip) is never needed (issue 11 point 1);
* every transfer the block promises to be bumpless is: with PV = SP at the switch, the output
  does not jump (pid: MAN -> AUTO, MAN -> CAS, tracking -> AUTO, a Bad-PV burst -> AUTO, the
  docstring's "every return to control is bumpless"; e2.pid: the end of an override with
  ``override_updates_pid``, spec vendor-blocks 3.7, the option's documented bumpless release);
* the output published before the first scan is the one the first scan gives at steady state
  (issue 11 point 8; e2.pid: Output at Setpoint is "the output when input = setpoint", spec 3.2).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import loopworks
from loopworks.blocks.block import Block
from loopworks.blocks.pid import P as PID_P
from tests.properties.strategies import blocks, cases

#: every kind that declares its kernel sound by itself (``Block.SOUND_KERNEL``, which lets the
#: compiled guard skip its per-scan state copy): the declaration is what this test checks
SOUND_KINDS = [k for k in loopworks.kinds() if loopworks.block_class(k).SOUND_KERNEL]


def raw_step(block: Block, dt: float, inputs: dict[str, Any]) -> None:
    """One scan of the block's own kernel, interpreted and without the guard's fallback:
    only a non-finite input value is shown to the kernel as Bad (0), as the guard shows it."""
    block.set_inputs(inputs)
    us = block.us.copy()
    us[~np.isfinite(block.u) & ((us & 0xC0) != 0)] = 0
    with np.errstate(all="ignore"):
        type(block).kernel(dt, block.p, block.x, block.u, us, block.y, block.ys)


@pytest.mark.parametrize("kind", SOUND_KINDS)
@given(data=st.data())
def test_the_kernel_alone_is_sound(kind: str, data: st.DataObject) -> None:
    case = data.draw(cases(kind))
    block = loopworks.create_block(kind, jit=False, **case.params)
    for k, (dt, inputs) in enumerate(zip(case.dts, case.inputs, strict=True)):
        raw_step(block, dt, inputs)
        where = f"{kind} scan {k} (params {case.params}, inputs {inputs})"
        assert np.isfinite(block.x).all(), f"{where}: state {block.state()}"
        for i, port in enumerate(block.OUTPUTS):
            value, status = float(block.y[i]), int(block.ys[i])
            assert math.isfinite(value) or (port.status and status & 0xC0 == 0), (
                f"{where}: output {port.name} = {value} status {status}")


# -- pid: bumpless transfers -------------------------------------------------------------------

def pid_block(data: st.DataObject) -> Block:
    _, params = data.draw(blocks("pid"))
    return loopworks.create_block("pid", jit=False, **params)


def close(a: float, b: float, scale: float) -> bool:
    """Equal to rounding: a few ulps of the largest term the output is summed from."""
    return abs(a - b) <= 1e-12 * (abs(scale) + abs(a) + abs(b) + 1.0)


def pid_scale(block: Block, sp: float, ff: float) -> float:
    """The largest term of v = P + I + D + ff + bias at PV = SP (P = s·kp·(b - 1)·SP)."""
    kp = block.gains()[0]  # type: ignore[attr-defined]
    return abs(kp * (block.params["b"] - 1.0) * sp) + abs(ff) + abs(block.params["bias"])


values = st.floats(-100.0, 200.0, allow_nan=False)


def settle_check(block: Block, held: float, dt: float, scale: float, n: int,
                 **inputs: Any) -> None:
    """n scans at PV = SP after a switch: the output stays at ``held`` (no jump).

    With ``antiwindup = "integral_limits"`` (pid docstring) the return re-initialises the
    integral to u - P - D - ff - bias and then keeps it within out_lo..out_hi, as simple-pid's
    set_auto_mode does: the output continues from ``held`` while that integral lies within
    the limits, and otherwise from P + clamp(integral) + ff + bias (D is 0 at the return, and
    the integral does not move at PV = SP), limited, and stays there. Unless an error gap
    (``e_deadband`` > 0) holds the output: at PV = SP the error is inside it, so the output
    stays at ``held`` and nothing is re-initialised (pid docstring, "Dead bands"). A jump to
    that new output is rate limited: each scan moves at most rate_limit·dt towards it (pid
    docstring, the effective limits)."""
    gap = block.params.get("e_deadband", 0.0) > 0.0
    target = held
    step = block.params["rate_limit"] * dt
    for k in range(n):
        outputs = block.step(dt, **inputs)
        if k == 0 and block.params["antiwindup"] == "integral_limits" and not gap:
            lo, hi = block.params["out_lo"], block.params["out_hi"]
            p, ff, bias = outputs["p_term"].value, float(inputs["ff"]), block.params["bias"]
            integral = min(max(held - p - ff - bias, lo), hi)
            target = min(max(p + integral + ff + bias, lo), hi)
        expected = min(max(target, held - step), held + step)
        out = outputs["out"]
        assert close(out.value, expected, scale), (
            f"scan {k} after the switch: out {out.value} != {expected} ({block!r})")
        held = out.value


@given(data=st.data(), mode=st.sampled_from(["AUTO", "CAS"]))
def test_pid_man_to_auto_or_cas_is_bumpless(data: st.DataObject, mode: str) -> None:
    """pid docstring: "every return to control is bumpless": the first AUTO (CAS) scan with
    PV = SP continues from the MAN output (man_out limited to out_lo..out_hi)."""
    block = pid_block(data)
    dt = data.draw(st.floats(0.01, 2.0))
    sp, ff = data.draw(values), data.draw(values)
    for _ in range(data.draw(st.integers(1, 4))):  # MAN at any PV, some operator writes
        block.step(dt, mode="MAN", man_out=data.draw(values), pv=data.draw(values), sp=sp,
                   ff=ff)
    held = block.outputs()["out"].value
    target = {"sp": sp} if mode == "AUTO" else {"cas_sp": sp}
    settle_check(block, held, dt, pid_scale(block, sp, ff), 5, mode=mode, pv=sp, ff=ff,
                 **target)


@given(data=st.data())
def test_pid_tracking_to_auto_is_bumpless(data: st.DataObject) -> None:
    """track = 1 puts track_value on the output; back to AUTO with PV = SP the output stays
    there (pid docstring: tracking re-initialises the controller at the next computing scan)."""
    block = pid_block(data)
    dt = data.draw(st.floats(0.01, 2.0))
    sp, ff = data.draw(values), data.draw(values)
    for _ in range(data.draw(st.integers(0, 4))):  # control at any PV first
        block.step(dt, mode="AUTO", sp=sp, pv=data.draw(values), ff=ff)
    for _ in range(data.draw(st.integers(1, 3))):
        block.step(dt, track=1.0, track_value=data.draw(values), pv=data.draw(values))
    held = block.outputs()["out"].value
    lo, hi = block.params["out_lo"], block.params["out_hi"]
    assert lo <= held <= hi
    settle_check(block, held, dt, pid_scale(block, sp, ff), 5, track=0.0, sp=sp, pv=sp,
                 ff=ff)


@given(data=st.data(), bad=st.sampled_from([math.nan, math.inf, -math.inf, 1e308, -1e308,
                                            3.5e38, (40.0, 0), (40.0, 0x1C)]))
def test_pid_returns_bumplessly_after_bad_pv(data: st.DataObject, bad: Any) -> None:
    """A burst of Bad PV (NaN, ±inf, beyond ±1e12, Bad status): the output holds (bad_pv =
    hold) or goes to safe_out; at the first good PV = SP it continues from there."""
    block = pid_block(data)
    dt = data.draw(st.floats(0.01, 2.0))
    sp, ff = data.draw(values), data.draw(values)
    for _ in range(data.draw(st.integers(0, 4))):
        block.step(dt, mode="AUTO", sp=sp, pv=data.draw(values), ff=ff)
    before = block.outputs()["out"].value
    safe = block.params["bad_pv"] == "safe"
    for _ in range(data.draw(st.integers(1, 4))):
        out = block.step(dt, sp=sp, pv=bad, ff=ff)["out"]
        # hold: Uncertain, last usable value (0x44); safe: Uncertain, substitute (0x48)
        assert (out.value, out.status & 0xFC) == ((block.p[PID_P.safe], 0x48) if safe
                                                  else (before, 0x44))
    settle_check(block, out.value, dt, pid_scale(block, sp, ff), 5, sp=sp, pv=sp, ff=ff)


@given(data=st.data())
def test_pid_first_scan_at_steady_state_gives_the_published_output(data: st.DataObject) -> None:
    """Issue 11 point 8: before its first scan the pid publishes clamp(bias); at PV = SP with
    b = 1 and no feedforward the first scan gives exactly that."""
    _, params = data.draw(blocks("pid"))
    block = loopworks.create_block("pid", jit=False, **{**params, "b": 1.0})
    published = block.outputs()["out"].value
    sp = data.draw(values)
    assert block.step(data.draw(st.floats(0.01, 2.0)), sp=sp, pv=sp)["out"].value == published


# -- e2.pid ------------------------------------------------------------------------------------

def e2_block(data: st.DataObject, **fixed: Any) -> Block:
    _, params = data.draw(blocks("e2.pid"))
    return loopworks.create_block("e2.pid", jit=False, **{**params, **fixed})


@given(data=st.data())
def test_e2_override_release_with_override_updates_pid_is_bumpless(data: st.DataObject) -> None:
    """spec 3.7 option ``override_updates_pid``: OUT and F take the override value while it is
    active, so its release is bumpless: with PV = SP over the override (for three update
    intervals, so the error memories are at setpoint) the output stays at the override value."""
    block = e2_block(data, override_updates_pid=True)
    lo, hi = block.params["output_min"], block.params["output_max"]
    interval = block.params["update_interval"]
    dt = max(data.draw(st.floats(0.01, 2.0)), interval / 100.0)
    sp = data.draw(values)
    for _ in range(data.draw(st.integers(0, 4))):  # control at any PV first
        block.step(dt, sp=sp, pv=data.draw(values))
    value = data.draw(st.floats(lo, hi))
    for _ in range(math.ceil(3.0 * interval / dt) + 1):
        assert block.step(dt, sp=sp, pv=sp, override=value)["out"].value == value
    for k in range(5):
        out = block.step(dt, sp=sp, pv=sp, override=math.nan)["out"]
        assert out.value == value, f"scan {k} after the release: {out.value} != {value}"
        assert out.status & 0xC0 == 0x80


@given(data=st.data())
def test_e2_first_scan_at_setpoint_gives_the_published_output(data: st.DataObject) -> None:
    """Issue 11 point 8 and spec 3.2/3.9: before its first scan the E2 publishes its start-up
    output (initial_output, default Output at Setpoint, "the output when input = setpoint");
    the first scan with input = setpoint gives exactly that, whatever startup_errors."""
    block = e2_block(data)
    before = block.outputs()
    start = block.x[0]  # the PID's stored output at start-up
    assert before["out"].value == start and before["pid_out"].value == start
    sp = data.draw(values)
    after = block.step(data.draw(st.floats(0.01, 2.0)), sp=sp, pv=sp)
    assert after["out"].value == start and after["pid_out"].value == start
