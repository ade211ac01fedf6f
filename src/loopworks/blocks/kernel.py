"""Kernels: the arithmetic of a block as a plain function numba can compile.

Every block kernel has one signature::

    kernel(dt, p, x, u, us, y, ys) -> None

    dt  float         scan time in seconds (> 0)
    p   float64[:]    coefficients derived from the parameters (read only)
    x   float64[:]    state, updated in place
    u   float64[:]    input values          us  int64[:]  input status bytes
    y   float64[:]    output values, written  ys  int64[:]  output status bytes, written

The same source runs interpreted (one loop, debugging) and compiled with ``numba.njit`` (fast
single steps, replays, and later batches of thousands of loops). Compilation is lazy and cached
per kernel, so importing loopworks never imports numba.
"""

from __future__ import annotations

import os
import types
from collections.abc import Callable
from typing import Any, TypeVar

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
Kernel = Callable[[float, FloatArray, FloatArray, FloatArray, IntArray, FloatArray, IntArray], None]

_compiled: dict[Any, Any] = {}

F = TypeVar("F", bound=Callable[..., Any])


def primitive(fn: F) -> F:
    """Mark a shared helper (clamp, lag, ...) that kernels call.

    Interpreted, it is a plain Python function. When a kernel is compiled, every primitive it
    names is compiled too and linked into the compiled copy only, so the interpreted kernel
    stays pure Python and the comparison between the two is meaningful.
    """
    fn._lw_primitive = True  # type: ignore[attr-defined]
    return fn


def jit_enabled() -> bool:
    """Compiled kernels are used unless the environment sets ``LOOPWORKS_JIT=0``."""
    return os.environ.get("LOOPWORKS_JIT", "1").strip().lower() not in ("0", "false", "no", "off")


def compiled(kernel: Any, inline: bool = False) -> Any:
    """The numba-compiled version of ``kernel`` (compiled once per process).

    ``inline=True`` gives a variant that numba inlines into its caller (the packed step and the
    row runner), which saves the per-call reference counting of six array arguments. The plain
    variant is cached on disk when possible.
    """
    key = (kernel, inline)
    fn = _compiled.get(key)
    if fn is None:
        import numba

        linked = dict(kernel.__globals__)
        for name in kernel.__code__.co_names:
            obj = kernel.__globals__.get(name)
            if obj is not kernel and getattr(obj, "_lw_primitive", False):
                linked[name] = compiled(obj, inline=True)
        copy = types.FunctionType(kernel.__code__, linked, kernel.__name__,
                                  kernel.__defaults__, kernel.__closure__)
        copy.__qualname__ = kernel.__qualname__
        copy.__module__ = kernel.__module__
        if inline:
            fn = numba.njit(inline="always", nogil=True)(copy)
        else:
            fn = numba.njit(cache=True, nogil=True)(copy)
        _compiled[key] = fn
    return fn


SIGNATURE = ("none(float64, float64[::1], float64[::1], float64[::1], int64[::1], float64[::1], "
             "int64[::1])")


def entry_point(kernel: Any) -> Any:
    """The compiled kernel's direct entry for C-contiguous arrays of the standard signature.

    Calling it skips numba's argument-type dispatch (about half the cost of a single step from
    Python). Only for arrays a block owns: float64/int64, one-dimensional, C-contiguous.
    """
    fn = _entries.get(kernel)
    if fn is None:
        disp = compiled(kernel)
        disp.compile(SIGNATURE)
        fn = disp.overloads[disp.signatures[-1]].entry_point
        _entries[kernel] = fn
    return fn


_entries: dict[Any, Any] = {}


def _packed_template(dt: float, F: FloatArray, S: IntArray) -> None:
    KERNEL(dt, F[:A], F[A:B], F[B:C], S[:NU], F[C:D], S[NU:NUY])  # type: ignore[name-defined] # noqa: F821


def packed_entry(kernel: Any, n_p: int, n_x: int, n_u: int, n_y: int) -> Any:
    """A compiled ``step(dt, F, S)`` over one float buffer F = [p | x | u | y] and one int
    buffer S = [us | ys], calling ``kernel`` on views of them.

    Two arrays to unbox instead of six make a single step from Python markedly cheaper. The
    sizes are compile-time constants of the wrapper, so each (kernel, sizes) compiles once.
    """
    key = (kernel, n_p, n_x, n_u, n_y)
    fn = _entries.get(key)
    if fn is None:
        import numba

        consts = {"KERNEL": compiled(kernel, inline=True), "A": n_p, "B": n_p + n_x,
                  "C": n_p + n_x + n_u, "D": n_p + n_x + n_u + n_y, "NU": n_u, "NUY": n_u + n_y}
        wrapper = types.FunctionType(_packed_template.__code__, consts,
                                     f"packed_{kernel.__name__}")
        disp: Any = numba.njit(nogil=True)(wrapper)
        disp.compile("none(float64, float64[::1], int64[::1])")
        fn = disp.overloads[disp.signatures[-1]].entry_point
        _entries[key] = fn
    return fn


def _run_rows(kernel: Kernel, dts: FloatArray, p: FloatArray, x: FloatArray, U: FloatArray,
              US: IntArray, Y: FloatArray, YS: IntArray) -> None:
    """Step a kernel over rows: row k of U/US are the inputs of scan k, Y/YS receive outputs."""
    for k in range(dts.shape[0]):
        kernel(dts[k], p, x, U[k], US[k], Y[k], YS[k])


_row_runners: dict[Any, Callable[..., None]] = {}


def run_rows(kernel: Kernel, dts: FloatArray, p: FloatArray, x: FloatArray, U: FloatArray,
             US: IntArray, Y: FloatArray, YS: IntArray, jit: bool = True) -> None:
    """Run ``kernel`` over many scans at once (replay chunks). Compiled when ``jit``."""
    if not jit:
        _run_rows(kernel, dts, p, x, U, US, Y, YS)
        return
    runner: Any = _row_runners.get(kernel)
    if runner is None:
        import numba

        inner = compiled(kernel, inline=True)

        @numba.njit(nogil=True)
        def runner_fn(dts: FloatArray, p: FloatArray, x: FloatArray, U: FloatArray, US: IntArray,
                      Y: FloatArray, YS: IntArray) -> None:
            for k in range(dts.shape[0]):
                inner(dts[k], p, x, U[k], US[k], Y[k], YS[k])

        runner = runner_fn
        _row_runners[kernel] = runner
    runner(dts, p, x, U, US, Y, YS)
