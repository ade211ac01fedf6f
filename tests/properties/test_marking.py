"""A kernel marked :func:`loopworks.blocks.kernel.sees_nonfinite` runs without the guard's
marking step (issue 12: no per-scan status copy): for it, showing a non-finite input value
to it as Bad must change nothing. Random parameters within the documented ranges and random
inputs with NaN, ±inf, ±1e308 and every status quality (tests.properties.strategies)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import loopworks
from tests.properties.strategies import cases

MARKED_KINDS = [k for k in loopworks.kinds()
                if getattr(loopworks.block_class(k).kernel, "_lw_sees_nonfinite", False)]


def test_some_kernel_is_marked() -> None:
    assert "pid" in MARKED_KINDS


@pytest.mark.parametrize("kind", MARKED_KINDS)
@given(data=st.data())
def test_marking_changes_nothing(kind: str, data: st.DataObject) -> None:
    """Two copies of the block, one kernel call each per scan on the same inputs: one sees the
    statuses as latched, the other with every non-finite value's status Bad (0), as the
    guard's marking shows them. States, outputs and statuses stay identical."""
    case = data.draw(cases(kind))
    raw = loopworks.create_block(kind, jit=False, **case.params)
    marked = loopworks.create_block(kind, jit=False, **case.params)
    kernel = type(raw).kernel
    for k, (dt, inputs) in enumerate(zip(case.dts, case.inputs, strict=True)):
        raw.set_inputs(inputs)
        marked.set_inputs(inputs)
        us = marked.us.copy()
        us[~np.isfinite(marked.u) & ((us & 0xC0) != 0)] = 0
        with np.errstate(all="ignore"):
            kernel(dt, raw.p, raw.x, raw.u, raw.us, raw.y, raw.ys)
            kernel(dt, marked.p, marked.x, marked.u, us, marked.y, marked.ys)
        where = f"{kind} scan {k} (params {case.params}, inputs {inputs})"
        assert np.array_equal(raw.x, marked.x, equal_nan=True), where
        assert np.array_equal(raw.y, marked.y, equal_nan=True), where
        assert np.array_equal(raw.ys, marked.ys), where
