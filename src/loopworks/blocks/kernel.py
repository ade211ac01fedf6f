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


def sees_nonfinite(fn: F) -> F:
    """Mark a kernel that treats a non-finite input value as Bad input by itself (it checks
    every input it reads with ``finite``/``measured`` before using it), so showing such inputs
    to it as Bad changes nothing: a kind that is also sound by itself (``Block.SOUND_KERNEL``)
    then runs its kernel with no guard at all, and saves the per-scan status copy that marking
    makes while an unused input holds NaN. The property test "marking changes nothing" checks
    every kernel so marked."""
    fn._lw_sees_nonfinite = True  # type: ignore[attr-defined]
    return fn


def jit_enabled() -> bool:
    """Compiled kernels are used unless the environment sets ``LOOPWORKS_JIT=0``."""
    return os.environ.get("LOOPWORKS_JIT", "1").strip().lower() not in ("0", "false", "no", "off")


def compiled(kernel: Any, inline: bool = False) -> Any:
    """The numba-compiled version of ``kernel`` (compiled once per process).

    ``inline=True`` gives a variant that numba inlines into its caller (the packed step and the
    row runner), which saves the per-call reference counting of six array arguments. The plain
    variant is cached on disk when possible. The primitives a kernel calls are linked in as
    plain compiled functions (:func:`_primitive`).
    """
    key = (kernel, inline)
    fn = _compiled.get(key)
    if fn is None:
        import numba

        copy = _linked_copy(kernel)
        if inline:
            fn = numba.njit(inline="always", nogil=True)(copy)
        else:
            fn = numba.njit(cache=True, nogil=True)(copy)
        _compiled[key] = fn
    return fn


def _linked_copy(fn: Any) -> Any:
    """A copy of ``fn`` whose globals name the compiled primitives instead of the Python ones
    (so the interpreted function stays pure Python)."""
    linked = dict(fn.__globals__)
    for name in fn.__code__.co_names:
        obj = fn.__globals__.get(name)
        if obj is not fn and getattr(obj, "_lw_primitive", False):
            linked[name] = _primitive(obj)
    copy = types.FunctionType(fn.__code__, linked, fn.__name__, fn.__defaults__,
                              fn.__closure__)
    copy.__qualname__ = fn.__qualname__
    copy.__module__ = fn.__module__
    return copy


def _primitive(fn: Any) -> Any:
    """A primitive compiled for the kernels that call it: a plain njit function, not inlined
    by numba (``inline="always"`` inlines in numba's IR, which made each kernel three times
    as slow to compile: pid, deltav.pid, valve.karnopp and process.fopdt 36 s, against 15 s
    this way, 2026-12-07). LLVM still inlines it into the kernel when the kernel's machine
    code is made, and numba prunes the reference counting of its array arguments there:
    ``Module.run`` of pid + fopdt ran at 0.118-0.121 of the numba anchor either way. Not
    cached on disk by itself: it is compiled into each cached kernel entry that calls it."""
    key = ("primitive", fn)
    compiled_fn = _compiled.get(key)
    if compiled_fn is None:
        import numba

        compiled_fn = _compiled[key] = numba.njit(nogil=True)(_linked_copy(fn))
    return compiled_fn


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


def _marking_template(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                      y: FloatArray, ys: IntArray) -> None:
    """One scan of KERNEL, a kernel sound by itself (``Block.SOUND_KERNEL``): only the
    guard's first step, non-finite inputs shown as Bad."""
    KERNEL(dt, p, x, u, MARKED(u, us), y, ys)  # type: ignore[name-defined] # noqa: F821


def _bare_template(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                   y: FloatArray, ys: IntArray) -> None:
    """One scan of KERNEL, sound by itself and seeing non-finite inputs as Bad by itself
    (:func:`sees_nonfinite`): nothing to guard."""
    KERNEL(dt, p, x, u, us, y, ys)  # type: ignore[name-defined] # noqa: F821


def guard_template(full: bool, kernel: Any = None) -> Any:
    """The guard's source function: the full guard, the marking-only one, or none (a sound
    kernel that sees non-finite inputs itself)."""
    if full:
        return _guarded_template
    return _bare_template if getattr(kernel, "_lw_sees_nonfinite", False) else _marking_template


def _make_guarded(kernel: Any, sound: Any, marked: Any, full: bool, source: Any) -> Any:
    return types.FunctionType(guard_template(full, source).__code__,
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


def guard_helpers() -> tuple[Any, Any]:
    """The compiled (inlined) soundness check and input marking the guards call."""
    helpers = _compiled.get("guard helpers")
    if helpers is None:
        import numba

        helpers = _compiled["guard helpers"] = tuple(
            numba.njit(inline="always", nogil=True)(f) for f in (_sound_loop, _marked_loop))
    return helpers


def guarded_scan(kernel: Any, jit: bool, full: bool = True) -> Any:
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
    ``full=False`` is step 1 only, for a kernel that keeps steps 2-3 by itself
    (``Block.SOUND_KERNEL``, shown by the property tests): no state copy per scan.
    Compiled, the kernel is inlined into the guard, and the guard into its kind's ``call``
    entry (:mod:`loopworks.blocks.plan`), cached on disk; every other plan calls that entry.
    """
    if not jit:
        fn = _guarded_py.get((kernel, full))
        if fn is None:
            fn = _guarded_py[(kernel, full)] = _quiet(
                _make_guarded(kernel, _sound_np, _marked_np, full, kernel))
        return fn
    key = ("guarded", kernel, full)
    fn = _compiled.get(key)
    if fn is None:
        import numba

        fn = _compiled[key] = numba.njit(inline="always", nogil=True)(
            _make_guarded(compiled(kernel, inline=True), *guard_helpers(), full, kernel))
    return fn


def guarded_entry(kernel: Any, full: bool = True) -> Any:
    """The compiled guarded scan's direct entry for a block's own C-contiguous arrays (the
    standard signature), skipping numba's argument-type dispatch; cached on disk, one
    function for every array size."""
    key = ("guarded_entry", kernel, full)
    fn = _entries.get(key)
    if fn is None:
        from loopworks.blocks import plan

        slots = plan.layout([(kernel, 0, 0, 0, 0, full)])
        fn = _entries[key] = plan.entry_point(slots, "call", plan.CALL_SIGNATURE)
    return fn


def step_entry(kernel: Any, n_p: int, n_x: int, n_u: int, n_y: int, full: bool = True) -> Any:
    """A compiled ``step(dt, fa, sa, ia, a, ib, b, good)`` over one float buffer
    F = [p | x | u | y] and one int buffer S = [us | ys], given by their addresses
    (:mod:`loopworks.blocks.address`): a one-block plan (:mod:`loopworks.blocks.plan`), cached
    on disk. It writes up to two inputs, scans, and returns the outputs' values and statuses
    as one tuple.

    No arrays to unbox, the inputs as arguments and the outputs as the result make a single
    step from Python markedly cheaper (one call into machine code). The
    sizes are literals of the generated glue, which calls the kind's cached ``call`` entry
    (:func:`guarded_entry`): each (kernel, sizes) compiles its glue once per machine (well
    under a second), the kernel itself once per machine for every use."""
    key = (kernel, n_p, n_x, n_u, n_y, full)
    fn = _entries.get(key)
    if fn is None:
        from loopworks.blocks import plan

        slots = plan.layout([(kernel, n_p, n_x, n_u, n_y, full)])
        fn = _entries[key] = plan.entry_point(slots, "step", plan.step_signature(n_y))
    return fn


def _run_rows(kernel: Kernel, dts: FloatArray, p: FloatArray, x: FloatArray, U: FloatArray,
              US: IntArray, Y: FloatArray, YS: IntArray, full: bool) -> None:
    """Step a kernel over rows: row k of U/US are the inputs of scan k, Y/YS receive outputs.
    Row 0 of Y/YS holds the outputs before the first scan; each row starts from the last."""
    scan = guarded_scan(kernel, False, full)
    for k in range(dts.shape[0]):
        if k > 0:
            Y[k] = Y[k - 1]
            YS[k] = YS[k - 1]
        scan(dts[k], p, x, U[k], US[k], Y[k], YS[k])


def run_rows(kernel: Kernel, dts: FloatArray, p: FloatArray, x: FloatArray, U: FloatArray,
             US: IntArray, Y: FloatArray, YS: IntArray, jit: bool = True,
             full: bool = True) -> None:
    """Run ``kernel`` over many scans at once (replay chunks). Compiled when ``jit``, as a
    one-block plan's ``rows`` (cached on disk). The caller puts the outputs before the first
    scan in row 0 of Y/YS; ``x`` is updated in place. ``full``: see :func:`guarded_scan`."""
    if not jit:
        _run_rows(kernel, dts, p, x, U, US, Y, YS, full)
        return
    from loopworks.blocks import plan

    n_p, n_x, n_u, n_y = p.shape[0], x.shape[0], U.shape[1], Y.shape[1]
    (slot,) = plan.layout([(kernel, n_p, n_x, n_u, n_y, full)])
    F = np.concatenate([p, x, np.zeros(n_u), Y[0]])
    S = np.concatenate([np.zeros(n_u, dtype=np.int64), YS[0]])
    rows = plan.entry([slot], "rows", plan.ROWS_SIGNATURE)
    rows(np.ascontiguousarray(dts, dtype=np.float64), F, S, np.ascontiguousarray(U),
         np.ascontiguousarray(US), Y, YS)
    x[:] = F[slot.x0:slot.u0]
