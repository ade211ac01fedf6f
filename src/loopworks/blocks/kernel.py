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

Every scan runs through :func:`guarded_scan`, the one place that enforces the numeric contract
of every kind: a non-finite input is Bad input, and no scan leaves a non-finite output with a
status that is not Bad, or a non-finite state.
"""

from __future__ import annotations

import math
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


def _sound_np(x: FloatArray, y: FloatArray, ys: IntArray) -> bool:
    """True when every state is finite and every output is finite or has a Bad status."""
    return bool(np.isfinite(x).all()) and bool((np.isfinite(y) | ((ys & 0xC0) == 0)).all())


def _sound_loop(x: FloatArray, y: FloatArray, ys: IntArray) -> bool:
    """:func:`_sound_np` as loops (compiled: no temporary arrays)."""
    for i in range(x.shape[0]):
        if not math.isfinite(x[i]):
            return False
    for i in range(y.shape[0]):  # noqa: SIM110 - a plain loop compiles without generators
        if not math.isfinite(y[i]) and (ys[i] & 0xC0) != 0:
            return False
    return True


def _marked_np(u: FloatArray, us: IntArray) -> IntArray:
    """The statuses the kernel sees: ``us``, with Bad (0) where the value is not finite and
    its status is not Bad already (a Bad status, its substatus included, is kept)."""
    nonfinite = ~np.isfinite(u) & ((us & 0xC0) != 0)
    return np.where(nonfinite, 0, us) if nonfinite.any() else us


def _marked_loop(u: FloatArray, us: IntArray) -> IntArray:
    """:func:`_marked_np` as loops (compiled: a copy only when a value is not finite)."""
    for i in range(u.shape[0]):
        if not math.isfinite(u[i]) and (us[i] & 0xC0) != 0:
            usk = us.copy()
            for j in range(i, u.shape[0]):
                if not math.isfinite(u[j]) and (us[j] & 0xC0) != 0:
                    usk[j] = 0
            return usk
    return us


def _guarded_template(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                      y: FloatArray, ys: IntArray) -> None:
    """One scan of KERNEL under the numeric contract (see :func:`guarded_scan`). The kernel is
    called from one place only, so compiled it is inlined once."""
    usk = MARKED(u, us)  # type: ignore[name-defined] # noqa: F821
    x0 = x.copy()
    y0 = y.copy()
    ys0 = ys.copy()
    for _attempt in range(2):
        KERNEL(dt, p, x, u, usk, y, ys)  # type: ignore[name-defined] # noqa: F821
        if SOUND(x, y, ys):  # type: ignore[name-defined] # noqa: F821
            return
        # undo the scan; the arithmetic overflowed, so its inputs are not usable: run it again
        # as Bad input
        x[:] = x0
        y[:] = y0
        ys[:] = ys0
        usk = np.zeros_like(us)
    ys[:] = 0  # the kind has no answer for Bad input: everything held, outputs Bad


def _make_guarded(kernel: Any, sound: Any, marked: Any) -> Any:
    return types.FunctionType(_guarded_template.__code__,
                              {"KERNEL": kernel, "SOUND": sound, "MARKED": marked, "np": np},
                              f"guarded_{kernel.__name__}")


_guarded_py: dict[Any, Any] = {}


def _quiet(scan: Any) -> Any:
    """Interpreted, numpy warns where compiled code silently overflows; the guard handles it."""
    def quiet_scan(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                   y: FloatArray, ys: IntArray) -> None:
        with np.errstate(all="ignore"):
            scan(dt, p, x, u, us, y, ys)
    return quiet_scan


def guarded_scan(kernel: Any, jit: bool) -> Any:
    """``kernel`` wrapped in the numeric contract every kind keeps (same signature):

    1. an input value that is NaN or infinite is Bad input: the kernel sees its status as Bad
       (non-specific, 0) unless it arrived Bad already (then its substatus is kept), so it does
       what its vendor does with Bad input (the latched input status itself is not changed);
    2. if the scan still leaves a state non-finite, or an output non-finite with a status that
       is not Bad (the arithmetic overflowed: 1e308 - (-1e308)), the scan is undone and run
       again with every input Bad;
    3. if even that is not sound, the scan is undone and the outputs are held with status Bad.

    So no output is non-finite unless its status is Bad, and no state is ever left non-finite:
    the block recovers as soon as its inputs are good again. Kinds whose vendor defines more
    (float32 storage, 16-bit words) check that in their kernel; this is the floor under all.
    Compiled, the kernel is inlined into the guard.
    """
    if not jit:
        fn = _guarded_py.get(kernel)
        if fn is None:
            fn = _guarded_py[kernel] = _quiet(_make_guarded(kernel, _sound_np, _marked_np))
        return fn
    key = ("guarded", kernel)
    fn = _compiled.get(key)
    if fn is None:
        import numba

        helpers = _compiled.get("guard helpers")
        if helpers is None:
            helpers = _compiled["guard helpers"] = tuple(
                numba.njit(inline="always", nogil=True)(f) for f in (_sound_loop, _marked_loop))
        fn = numba.njit(inline="always", nogil=True)(
            _make_guarded(compiled(kernel, inline=True), *helpers))
        _compiled[key] = fn
    return fn


def guarded_entry(kernel: Any) -> Any:
    """The compiled guarded scan's direct entry for a block's own C-contiguous arrays (the
    standard signature), skipping numba's argument-type dispatch."""
    key = ("guarded_entry", kernel)
    fn = _entries.get(key)
    if fn is None:
        import numba

        disp: Any = numba.njit(nogil=True)(_call_template(guarded_scan(kernel, True)))
        disp.compile(SIGNATURE)
        fn = disp.overloads[disp.signatures[-1]].entry_point
        _entries[key] = fn
    return fn


def _call_template_body(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                        y: FloatArray, ys: IntArray) -> None:
    GUARDED(dt, p, x, u, us, y, ys)  # type: ignore[name-defined] # noqa: F821


def _call_template(guarded: Any) -> Any:
    return types.FunctionType(_call_template_body.__code__, {"GUARDED": guarded},
                              "guarded_entry")


def _packed_template(dt: float, F: FloatArray, S: IntArray) -> None:
    GUARDED(dt, F[:A], F[A:B], F[B:C], S[:NU], F[C:D], S[NU:NUY])  # type: ignore[name-defined] # noqa: F821


def packed_entry(kernel: Any, n_p: int, n_x: int, n_u: int, n_y: int) -> Any:
    """A compiled ``step(dt, F, S)`` over one float buffer F = [p | x | u | y] and one int
    buffer S = [us | ys], calling ``kernel`` (guarded, :func:`guarded_scan`) on views of them.

    Two arrays to unbox instead of six make a single step from Python markedly cheaper. The
    sizes are compile-time constants of the wrapper, so each (kernel, sizes) compiles once.
    """
    key = (kernel, n_p, n_x, n_u, n_y)
    fn = _entries.get(key)
    if fn is None:
        import numba

        consts = {"GUARDED": guarded_scan(kernel, True), "A": n_p, "B": n_p + n_x,
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
    """Step a kernel over rows: row k of U/US are the inputs of scan k, Y/YS receive outputs.
    Row 0 of Y/YS holds the outputs before the first scan; each row starts from the last."""
    scan = guarded_scan(kernel, False)
    for k in range(dts.shape[0]):
        if k > 0:
            Y[k] = Y[k - 1]
            YS[k] = YS[k - 1]
        scan(dts[k], p, x, U[k], US[k], Y[k], YS[k])


_row_runners: dict[Any, Callable[..., None]] = {}


def run_rows(kernel: Kernel, dts: FloatArray, p: FloatArray, x: FloatArray, U: FloatArray,
             US: IntArray, Y: FloatArray, YS: IntArray, jit: bool = True) -> None:
    """Run ``kernel`` over many scans at once (replay chunks). Compiled when ``jit``. The caller
    puts the outputs before the first scan in row 0 of Y/YS."""
    if not jit:
        _run_rows(kernel, dts, p, x, U, US, Y, YS)
        return
    runner: Any = _row_runners.get(kernel)
    if runner is None:
        import numba

        inner = guarded_scan(kernel, True)

        @numba.njit(nogil=True)
        def runner_fn(dts: FloatArray, p: FloatArray, x: FloatArray, U: FloatArray, US: IntArray,
                      Y: FloatArray, YS: IntArray) -> None:
            for k in range(dts.shape[0]):
                if k > 0:
                    Y[k] = Y[k - 1]
                    YS[k] = YS[k - 1]
                inner(dts[k], p, x, U[k], US[k], Y[k], YS[k])

        runner = runner_fn
        _row_runners[kernel] = runner
    runner(dts, p, x, U, US, Y, YS)
