"""Execution plans: blocks laid out in one flat buffer, run by one generated step function.

A plan is the compiled form of a run. Its blocks' arrays live in one float buffer ``F`` (per
block ``[p | x | u | y]``) and one int buffer ``S`` (per block ``[us | ys]``), at offsets fixed
when the plan is made; wires, the controller clock and the record are index copies into them.
From that shape loopworks writes Python source: one function that, per scan, copies each
block's wired inputs, sets its clock and calls its kernel (under the numeric guard of
:func:`loopworks.blocks.kernel.guarded_scan`) in the declared order, with every offset a
literal. numba compiles it with ``cache=True``; the source file is named by a hash of the
plan's shape and of loopworks' own source, so a second process loads the machine code from
disk instead of compiling, and a changed kernel can never load stale code.

Three entry points are generated from the same layout:

* ``scans(F, S, dt, t0, k0, n, T, RF, RS, IF, IS, at)``: n scans of a module
  (``Module.run``), scan k at t = t0 (k = 0) or (k0 + k)·dt, recording T[at + k] = t,
  RF[:, at + k] = F[IF] and RS[:, at + k] = S[IS] (one row per signal, so each signal's
  record is one contiguous array). The module's usual record (every signal: ``Record``) is
  written with literal offsets, another one by a loop over IF and IS: the loop over index
  arrays costs a sixth of a pid + fopdt scan;
* ``step(dt, fa, sa, ia, a, ib, b, good)``: one scan of one block (``Block.step``) on its
  buffers F and S given by their addresses (:mod:`loopworks.blocks.address`), after writing
  input ``ia`` = a and ``ib`` = b (-1: none; their statuses Good NC unless ``good``: all
  statuses are Good NC already); returns the outputs' values, then their statuses, as one
  tuple (what the caller reads, with no second call into the arrays);
* ``rows(dts, F, S, U, US, Y, YS)``: one block over rows of inputs (``replay``);
* ``call(dt, p, x, u, us, y, ys)``: one scan of one block on its own seven arrays, for kinds
  whose sizes vary per instance (one compiled function for all sizes);
* ``batch(F, S, dt, k0, m, R, IR, RS, IS, at)``: m scans of N instances of a module at once
  (``loopworks.sim.batch``): instance i's buffers are row i of ``F`` (N × the module's floats)
  and ``S``; the instances run in parallel (``numba.prange``, one thread per core, each
  instance's scans in one thread), scan k at t = (k0 + k)·dt, recording
  R[i, j, at + k] = F[i, IR[j]] and its status RS[i, j, at + k] = S[i, IS[j]].

Where the cache lives: ``LOOPWORKS_CACHE_DIR`` if set, else the platform's user cache
directory (``$XDG_CACHE_HOME/loopworks`` or ``~/.cache/loopworks`` on Linux,
``~/Library/Caches/loopworks`` on macOS, ``%LOCALAPPDATA%\\loopworks\\Cache`` on Windows). A
cache that cannot be written falls back to compiling in memory, with one warning line per
process, never an error. Processes that need the same plan at once compile it once: the
first holds a lock file beside it while it compiles, the others wait and load its machine
code.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import os
import sys
import tempfile
import types
import warnings
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager, suppress
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from loopworks.blocks.block import Block

#: called with a one-line message before the first plan of a process that has to be compiled
#: (not loaded from the cache); the CLI sets it to print the line, a library user hears nothing
announce: Callable[[str], None] | None = None

CALL_SIGNATURE = ("none(float64, float64[::1], float64[::1], float64[::1], int64[::1], "
                  "float64[::1], int64[::1])")
#: ``scans`` and ``fused``: the record's statuses are bytes (a status is one byte, spec
#: architecture: the Foundation Fieldbus status byte), its values float64
SCANS_SIGNATURE = ("none(float64[::1], int64[::1], float64, float64, int64, int64, "
                   "float64[::1], float64[:, ::1], uint8[:, ::1], int64[::1], int64[::1], "
                   "int64)")


#: the usual record of a module's ``scans``/``fused`` plan, (IF, IS) as tuples (see above)
Record = tuple[tuple[int, ...], tuple[int, ...]]


def step_signature(n_y: int) -> str:
    """The signature of a one-block plan's ``step`` for a kind of ``n_y`` outputs."""
    ret = ", ".join(["float64"] * n_y + ["int64"] * n_y)
    return f"Tuple(({ret},))(float64, int64, int64, int64, float64, int64, float64, boolean)"

ROWS_SIGNATURE = ("none(float64[::1], float64[::1], int64[::1], float64[:, ::1], int64[:, ::1], "
                  "float64[:, ::1], int64[:, ::1])")
BATCH_SIGNATURE = ("none(float64[:, ::1], int64[:, ::1], float64, int64, int64, "
                   "float64[:, :, ::1], int64[::1], uint8[:, :, ::1], int64[::1], int64)")


@dataclass(frozen=True)
class Slot:
    """One block in a plan: its kernel, its array sizes and its offsets in F and S.

    In F the block holds ``[p | x | u | y]`` from ``f0``; in S it holds ``[us | ys]`` from
    ``s0``. ``full``: the kernel runs under the full numeric guard (else it is sound by
    itself and only its non-finite inputs are marked Bad). ``links`` are its wired inputs as
    (input index, source slot index, source output index), in the order they are copied;
    ``clock`` is the input the module time goes to."""

    kernel: Any
    n_p: int
    n_x: int
    n_u: int
    n_y: int
    f0: int
    s0: int
    full: bool = True
    links: tuple[tuple[int, int, int], ...] = ()
    clock: int | None = None

    @property
    def p0(self) -> int:
        return self.f0

    @property
    def x0(self) -> int:
        return self.f0 + self.n_p

    @property
    def u0(self) -> int:
        return self.f0 + self.n_p + self.n_x

    @property
    def y0(self) -> int:
        return self.f0 + self.n_p + self.n_x + self.n_u

    @property
    def f1(self) -> int:
        return self.y0 + self.n_y

    @property
    def ys0(self) -> int:
        return self.s0 + self.n_u

    @property
    def s1(self) -> int:
        return self.ys0 + self.n_y


def layout(sizes: Sequence[tuple[Any, int, int, int, int, bool]]) -> list[Slot]:
    """Slots for blocks of (kernel, n_p, n_x, n_u, n_y, full), packed one after the other."""
    slots: list[Slot] = []
    f0 = s0 = 0
    for kernel, n_p, n_x, n_u, n_y, full in sizes:
        slot = Slot(kernel, n_p, n_x, n_u, n_y, f0, s0, full)
        slots.append(slot)
        f0, s0 = slot.f1, slot.s1
    return slots


# -- where the generated source and its machine code live ------------------------------------

def cache_dir() -> Path:
    """The directory plans are cached in (see the module docstring)."""
    env = os.environ.get("LOOPWORKS_CACHE_DIR", "").strip()
    if env:
        return Path(env).expanduser()
    if sys.platform == "win32":
        base = os.environ.get("LOCALAPPDATA") or str(Path.home() / "AppData" / "Local")
        return Path(base) / "loopworks" / "Cache"
    if sys.platform == "darwin":
        return Path.home() / "Library" / "Caches" / "loopworks"
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "loopworks"


def _code_parts(code: types.CodeType) -> Iterator[bytes]:
    """What a code object computes, without its line numbers or docstring position: its
    byte code, names and constants, nested code objects (comprehensions) included."""
    yield code.co_code
    yield repr((code.co_names, code.co_varnames, code.co_freevars)).encode()
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            yield from _code_parts(const)
        else:
            yield repr(const).encode()


def _all_names(code: types.CodeType) -> set[str]:
    names = set(code.co_names)
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            names |= _all_names(const)
    return names


def _feed(obj: Any, digest: Any, seen: set[int]) -> None:
    """Feed ``digest`` with what the machine code compiled from ``obj`` depends on: for a
    function, its code and, through the globals it names, the functions it calls (a
    primitive, a numba dispatcher's Python function), the constants it reads (numba freezes
    global values into the machine code) and the modules it uses (a loopworks module by its
    whole source, any other by name); its defaults and closure cells likewise."""
    if id(obj) in seen:
        return
    seen.add(id(obj))
    py_func = getattr(obj, "py_func", None)  # a numba dispatcher
    if py_func is not None:
        # compiled apart (a primitive) or not at all: a kernel calling a plain function
        # fails to compile, so the two must not share machine code
        digest.update(b"dispatcher")
        obj = py_func
    if isinstance(obj, types.FunctionType):
        digest.update(f"function {obj.__module__}.{obj.__qualname__}".encode())
        if getattr(obj, "_lw_sees_nonfinite", False):  # it runs without the marking guard
            digest.update(b"sees nonfinite")
        for part in _code_parts(obj.__code__):
            digest.update(part)
        for name in sorted(_all_names(obj.__code__)):
            if name in obj.__globals__:
                digest.update(f"global {name}".encode())
                _feed(obj.__globals__[name], digest, seen)
        for value in obj.__defaults__ or ():
            _feed(value, digest, seen)
        for cell in obj.__closure__ or ():
            _feed(cell.cell_contents, digest, seen)
    elif isinstance(obj, types.ModuleType):
        digest.update(f"module {obj.__name__}".encode())
        if obj.__name__.startswith("loopworks"):
            digest.update(_source(obj.__name__))
    elif isinstance(obj, bool | int | float | complex | str | bytes | type(None)):
        digest.update(f"{type(obj).__name__} {obj!r}".encode())
    elif isinstance(obj, tuple | list | frozenset):
        digest.update(f"{type(obj).__name__} {len(obj)}".encode())
        for item in obj:
            _feed(item, digest, seen)
    elif isinstance(obj, np.ndarray):
        digest.update(repr((obj.dtype.str, obj.shape)).encode() + obj.tobytes())
    else:  # a class, a numpy function or type: its name
        digest.update(f"{type(obj).__qualname__} "
                      f"{getattr(obj, '__module__', '')}.{getattr(obj, '__qualname__', '')}"
                      .encode())


@cache
def _source(module: str) -> bytes:
    """A loopworks module's source as this process first read it (b"" when not found): once
    per process, so every plan name the process makes comes from one reading of each file.
    Read again for each hash, a file edited while a long run was going gave the plans made
    after the edit new names while the kind entries they link to kept the old ones: the
    machine code cached under the new name then named a module no later process makes
    (ModuleNotFoundError on every load; :func:`entry` now also recovers from that)."""
    path = _origin(module)
    return path.read_bytes() if path is not None else b""


def _origin(module: str) -> Path | None:
    """The source file of a module, or None (not found, or not Python source)."""
    try:
        spec = importlib.util.find_spec(module)
    except (ImportError, ValueError):
        return None
    if spec is None or spec.origin is None or not spec.origin.endswith(".py"):
        return None
    return Path(spec.origin)


@cache
def _kernels_hash(kernels: tuple[Any, ...]) -> str:
    """A hash of what the machine code of a plan over ``kernels`` depends on: each kernel's
    code and everything it uses (:func:`_feed`), the source of the guard and plan machinery
    (``blocks.kernel``, this module), numba's version and Python's. A change to a kernel, to a
    primitive or constant it uses, gives its plans new names, so no stale machine code can
    load; a change elsewhere in a kernel's module (a docstring, a parameter's meaning, another
    class) does not, so it costs no compilation. (The generated text is hashed with it by the
    callers.)"""
    import numba

    digest = hashlib.sha256()
    for name in ("loopworks.blocks.kernel", "loopworks.blocks.address", __name__):
        digest.update(_source(name))
    seen: set[int] = set()
    for kernel in kernels:
        _feed(kernel, digest, seen)
    digest.update(numba.__version__.encode())
    digest.update(sys.version.encode())
    return digest.hexdigest()[:16]


def resolve(module: str, qualname: str) -> Any:
    """The object ``module.qualname`` (generated plans name kernels this way)."""
    obj: Any = importlib.import_module(module)
    for part in qualname.split("."):
        obj = getattr(obj, part)
    return obj


def _reference(kernel: Any) -> tuple[str, str] | None:
    """(module, qualname) under which ``kernel`` can be imported, or None (a kernel made at
    run time: the plan is then compiled in memory, not cached)."""
    module, qualname = getattr(kernel, "__module__", None), getattr(kernel, "__qualname__", "")
    if not module or "<" in qualname:
        return None
    try:
        found = resolve(module, qualname)
    except (ImportError, AttributeError):
        return None
    return (module, qualname) if found is kernel else None


# -- generated source ----

# -- plans -------------------------------------------------------------------------------------

#: the first lines of ``scans`` and ``rows``: F and S as views of the buffers F0 and S0 that
#: hold no reference count (``numba.carray`` at their addresses, :mod:`loopworks.blocks.address`;
#: the caller's F0 and S0 keep the memory alive for the call). Every kernel call hands the
#: kernel six slices of them; slices of a counted array would each take and drop a reference
#: (two atomic operations) per call, which was a third of a module's scan.
_UNCOUNTED = ("    F = numba.carray(float64_at(F0.ctypes.data), F0.shape[0])",
              "    S = numba.carray(int64_at(S0.ctypes.data), S0.shape[0])")


#: the most coefficients a fused plan hands a kernel as a tuple (:func:`_coefficients`)
TUPLE_COEFFICIENTS = 64


def _coefficients(slots: Sequence[Slot], pad: str) -> tuple[list[str], dict[int, str]]:
    """A fused plan's coefficients: each block's p (between 1 and :data:`TUPLE_COEFFICIENTS`
    numbers) read once into a tuple before the scan loop, and the kernel handed the tuple in
    place of its slice of F: (the lines that read them, slot index -> tuple name). A scan
    never writes its coefficients (they change between calls: a parameter event, a sweep's
    row), and values in a tuple are values the compiler knows no store in the loop can
    change, so what a kernel derives from them alone (exp(-dt/T) of a lag) is worked out once
    per call instead of once per scan: a quarter less time per scan of pid + fopdt. A kernel
    written for arrays reads a tuple alike (``p[P.kp]``); one that cannot (writing p, slicing
    it at run time) does not compile so, and :func:`entry` compiles that plan with slices
    instead. Every kind of loopworks compiles with tuples (checked 2026-12-08: one module of
    every kind, fused, gave its compiled plan's numbers; three minutes of compiling, too long
    for the suite, which checks pid + fopdt and the fallback)."""
    lines, names = [], {}
    for i, slot in enumerate(slots):
        if 0 < slot.n_p <= TUPLE_COEFFICIENTS:
            names[i] = f"P{i}"
            items = ", ".join(f"F[{slot.p0 + j}]" for j in range(slot.n_p))
            lines.append(f"{pad}P{i} = ({items},)")
    return lines, names


def _call(slot: Slot, g: str, dt: str, p: str | None = None) -> str:
    """The guarded kernel call of one slot on views of F and S (``p``: its coefficients'
    tuple, :func:`_coefficients`)."""
    coefficients = p if p is not None else f"F[{slot.p0}:{slot.x0}]"
    return (f"{g}({dt}, {coefficients}, F[{slot.x0}:{slot.u0}], "
            f"F[{slot.u0}:{slot.y0}], S[{slot.s0}:{slot.ys0}], F[{slot.y0}:{slot.f1}], "
            f"S[{slot.ys0}:{slot.s1}])")


def _header(kernels: dict[tuple[Any, bool], str], refs: dict[Any, Any],
            linked: bool) -> list[str]:
    """Imports and one guarded kernel per (kernel, full): inlined (``guarded_scan``: in each
    kind's own ``call`` entry, and in a module's ``fused`` scans), or, ``linked`` (a module's
    ``scans``, a block's ``step``, a replay's ``rows``), that kind's cached ``call`` entry
    (:func:`kernel_call`), so those plans compile only their glue (well under a second) and
    each kernel is compiled once per machine, whatever the modules' shapes and whichever
    command runs it first. A fused plan compiles its kernels again, once per module shape:
    the price of half the time per scan, paid only by long runs (``PLAN_FUSE_BLOCK_SCANS``)."""
    lines = ["# Generated by loopworks (loopworks.blocks.plan); do not edit.",
             "import numba", "", "from loopworks.blocks.address import float64_at, int64_at",
             "from loopworks.blocks.kernel import guarded_scan",
             "from loopworks.blocks.plan import kernel_call, resolve", ""]
    for (kernel, full), g in kernels.items():
        ref = refs[kernel]
        source = f"resolve({ref[0]!r}, {ref[1]!r})" if ref else f"KERNELS[{g[1:]}]"
        make = "kernel_call" if linked else "guarded_scan"
        lines.append(f"{g} = {make}({source}, True, {full})")
    return lines


def _scan(slots: Sequence[Slot], kernels: dict[tuple[Any, bool], str], pad: str,
          tuples: dict[int, str] | None = None) -> list[str]:
    """One scan of a module's blocks in order, at time ``t``: each block's wired inputs
    copied from their sources, its clock set, its guarded kernel called (with its
    coefficients' tuple where ``tuples`` names one)."""
    lines = []
    tuples = tuples or {}
    for index, slot in enumerate(slots):
        for i, src, j in slot.links:
            s = slots[src]
            lines.append(f"{pad}F[{slot.u0 + i}] = F[{s.y0 + j}]")
            lines.append(f"{pad}S[{slot.s0 + i}] = S[{s.ys0 + j}]")
        if slot.clock is not None:
            lines.append(f"{pad}F[{slot.u0 + slot.clock}] = t")
        lines.append(pad + _call(slot, kernels[(slot.kernel, slot.full)], "dt",
                                 tuples.get(index)))
    return lines


def kernel_call(kernel: Any, jit: bool, full: bool) -> Any:
    """The compiled ``call(dt, p, x, u, us, y, ys)`` of ``kernel`` under the guard: a numba
    dispatcher cached on disk, for every array size (``jit`` is always True: the signature
    matches ``guarded_scan`` so generated headers read alike)."""
    assert jit
    return entry(layout([(kernel, 0, 0, 0, 0, full)]), "call", CALL_SIGNATURE)


def _record(usual: Record | None) -> tuple[list[str], list[str]]:
    """The record of one scan of ``scans``/``fused``: (lines before the scan loop, lines in
    it). With a usual record, a test before the loop (are IF and IS the usual ones?) and in
    the loop its writes at literal offsets, else the loop over IF and IS (numba hoists the
    loop-invariant test: two loops, each without the other's branch)."""
    loop = ["for j in range(IF.shape[0]):", "    RF[j, at + k] = F[IF[j]]",
            "for j in range(IS.shape[0]):", "    RS[j, at + k] = S[IS[j]]"]
    if not usual or not (usual[0] or usual[1]):
        return [], [" " * 8 + line for line in loop]
    fs, ss = usual
    test = [f"IF.shape[0] == {len(fs)}", f"IS.shape[0] == {len(ss)}"]
    test += [f"IF[{j}] == {i}" for j, i in enumerate(fs)]
    test += [f"IS[{j}] == {i}" for j, i in enumerate(ss)]
    before = ["    usual = (" + test[0]]
    before += [f"             and {t}" for t in test[1:]]
    before[-1] += ")"
    inside = ["        if usual:"]
    inside += [f"            RF[{j}, at + k] = F[{i}]" for j, i in enumerate(fs)]
    inside += [f"            RS[{j}, at + k] = S[{i}]" for j, i in enumerate(ss)]
    inside += ["        else:"] + [" " * 12 + line for line in loop]
    return before, inside


def source(slots: Sequence[Slot], entries: Sequence[str],
           usual: Record | None = None, tuples: bool = True) -> tuple[str, list[Any]]:
    """The Python source of a plan's entry points (``scans``, ``step``, ``rows``; the last
    two for a one-block plan), and the kernels it needs injected (those not importable).
    ``usual``: the record a module's ``scans``/``fused`` write at literal offsets."""
    kernels: dict[tuple[Any, bool], str] = {}
    for slot in slots:
        kernels.setdefault((slot.kernel, slot.full), f"G{len(kernels)}")
    refs = {k: _reference(k) for k, _ in kernels}
    injected = [k if refs[k] is None else None for k, _ in kernels]
    lines = _header(kernels, refs, linked=not {"call", "fused", "batch_fused"} & set(entries))
    deco = "@numba.njit(cache=CACHE, nogil=True)"
    # ``fused``: the same scans with every kernel inlined (compiled with the plan, once per
    # module shape), for long runs; ``scans`` reaches each kernel's own cached entry. In a
    # fixed order: the source is hashed into the cache key.
    before, inside = _record(usual)
    for what in [w for w in ("scans", "fused") if w in entries]:
        read, named = (_coefficients(slots, "    ") if what == "fused" and tuples
                       else ([], {}))
        lines += ["", "", deco,
                  f"def {what}(F0, S0, dt, t0, k0, n, T, RF, RS, IF, IS, at):", *_UNCOUNTED,
                  *before, *read,
                  "    for k in range(n):",
                  "        t = t0 if k == 0 else (k0 + k) * dt",
                  "        T[at + k] = t"]
        lines += _scan(slots, kernels, " " * 8, named)
        lines += inside
    # ``batch_fused``: the batch with every kernel inlined (as ``fused`` is to ``scans``)
    for what in [w for w in ("batch", "batch_fused") if w in entries]:
        lines += ["", "", "@numba.njit(cache=CACHE, nogil=True, parallel=True)",
                  f"def {what}(F0, S0, dt, k0, m, R, IR, RS, IS, at):",
                  "    nf = F0.shape[1]",
                  "    ns = S0.shape[1]",
                  "    fa = F0.ctypes.data",
                  "    sa = S0.ctypes.data",
                  "    for i in numba.prange(F0.shape[0]):",
                  "        F = numba.carray(float64_at(fa + i * nf * 8), nf)",
                  "        S = numba.carray(int64_at(sa + i * ns * 8), ns)"]
        read, named = (_coefficients(slots, " " * 8) if what == "batch_fused" and tuples
                       else ([], {}))
        lines += [*read,
                  "        for k in range(m):",
                  "            t = (k0 + k) * dt"]
        lines += _scan(slots, kernels, " " * 12, named)
        lines += ["            for j in range(IR.shape[0]):",
                  "                R[i, j, at + k] = F[IR[j]]",
                  "                RS[i, j, at + k] = numba.uint8(S[IS[j]])"]
    if "call" in entries:
        (slot,) = slots
        lines += ["", "", deco, "def call(dt, p, x, u, us, y, ys):",
                  f"    {kernels[(slot.kernel, slot.full)]}(dt, p, x, u, us, y, ys)"]
    if "step" in entries:
        (slot,) = slots
        # one scan from Python holds the GIL: releasing it would cost more than the scan
        lines += ["", "", "@numba.njit(cache=CACHE)", "def step(dt, fa, sa, ia, a, ib, b, good):",
                  f"    F = numba.carray(float64_at(fa), ({slot.f1},))",
                  f"    S = numba.carray(int64_at(sa), ({slot.s1},))"]
        for at, value in (("ia", "a"), ("ib", "b")):
            lines += [f"    if {at} >= 0:",
                      f"        F[{slot.u0} + {at}] = {value}",
                      "        if not good:",
                      f"            S[{slot.s0} + {at}] = 128"]
        outs = [f"F[{slot.y0 + i}]" for i in range(slot.n_y)]
        outs += [f"S[{slot.ys0 + i}]" for i in range(slot.n_y)]
        lines += ["    " + _call(slot, kernels[(slot.kernel, slot.full)], "dt"),
                  f"    return ({', '.join(outs)},)"]
    if "rows" in entries:
        (slot,) = slots
        lines += ["", "", deco, "def rows(dts, F0, S0, U, US, Y, YS):", *_UNCOUNTED,
                  "    for k in range(dts.shape[0]):",
                  f"        for i in range({slot.n_u}):",
                  f"            F[{slot.u0} + i] = U[k, i]",
                  f"            S[{slot.s0} + i] = US[k, i]",
                  "        " + _call(slot, kernels[(slot.kernel, slot.full)], "dts[k]"),
                  f"        for i in range({slot.n_y}):",
                  f"            Y[k, i] = F[{slot.y0} + i]",
                  f"            YS[k, i] = S[{slot.ys0} + i]"]
    return "\n".join(lines) + "\n", injected if any(k is not None for k in injected) else []


# -- loading ---------------------------------------------------------------------------------

_loaded: dict[str, Any] = {}
_warned = False


def _warn_once(message: str) -> None:
    global _warned
    if not _warned:
        _warned = True
        warnings.warn(message, RuntimeWarning, stacklevel=4)


def _write(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` atomically (another process may be writing it too)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.exists() and path.read_text(encoding="utf-8") == text:
        return
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _module(name: str, text: str, injected: list[Any]) -> Any:
    """The generated module, imported from the cache directory (machine code cached next to
    it by numba), or executed in memory when the cache cannot be written."""
    namespace: dict[str, Any]
    directory = cache_dir() / "plans"
    path = directory / f"{name}.py"
    if not injected:
        try:
            _write(path, text)
            probe = directory / "__pycache__"
            probe.mkdir(exist_ok=True)
            if not os.access(probe, os.W_OK):
                raise PermissionError(f"{probe} is not writable")
        except OSError as exc:
            _warn_once(f"loopworks: the plan cache {directory} cannot be written ({exc}); "
                       "compiling in memory (set LOOPWORKS_CACHE_DIR to a writable directory)")
        else:
            spec = importlib.util.spec_from_file_location(name, path)
            assert spec is not None and spec.loader is not None
            mod = importlib.util.module_from_spec(spec)
            mod.__dict__["CACHE"] = True
            sys.modules[name] = mod
            spec.loader.exec_module(mod)
            return mod
    mod = type(sys)(name)
    namespace = mod.__dict__
    namespace.update({"CACHE": False, "KERNELS": injected})
    exec(compile(text, f"<loopworks plan {name}>", "exec"), namespace)
    return mod


def _name(slots: Sequence[Slot], what: str, usual: Record | None = None,
          tuples: bool = True) -> tuple[str, str, list[Any]]:
    """(module name, source, injected kernels) of a plan's entry point."""
    text, injected = source(slots, (what,), usual, tuples)
    key = hashlib.sha256((_kernels_hash(tuple(dict.fromkeys(slot.kernel for slot in slots)))
                          + text).encode()).hexdigest()[:20]
    return f"lw_plan_{key}", text, injected


def is_cached(slots: Sequence[Slot], what: str, usual: Record | None = None) -> bool:
    """True when the entry point's machine code is in the cache (or loaded in this process):
    using it costs a load, not a compilation."""
    name, text, _ = _name(slots, what, usual)
    if name in _loaded and getattr(_loaded[name], what).overloads:
        return True
    directory = _machine_code_dir(cache_dir() / "plans" / f"{name}.py")
    # numba names the index by the function's first line (its decorator's, 1-based: the
    # 0-based index of the ``def`` line): one file to look for, not a listing of the whole
    # cache (1.5 ms, which a sweep paid on every chunk)
    lines = text.splitlines()
    line = next((i for i, row in enumerate(lines) if row.startswith(f"def {what}(")), None)
    if line is None:  # pragma: no cover - every entry is generated with its def
        return any(directory.glob(f"{name}.{what}-*.nbi"))
    tag = f"py{sys.version_info.major}{sys.version_info.minor}"
    return (directory / f"{name}.{what}-{line}.{tag}.nbi").exists()


def _machine_code_dir(path: Path) -> Path:
    """Where numba keeps the machine code of the functions in the source file ``path``: its
    ``__pycache__``, or a directory under ``NUMBA_CACHE_DIR`` when that is set. Asked of
    numba's own cache locators, in numba's order (the first that takes the file wins), so the
    answer follows numba; the ``__pycache__`` guess when numba's internals have moved."""
    try:
        from numba.core.caching import CacheImpl

        locators: list[Any] = list(CacheImpl._locator_classes)
        for locator in locators:
            found = locator.from_function(is_cached, str(path))
            if found is not None:
                return Path(found.get_cache_path())
    except (ImportError, AttributeError, TypeError):
        pass
    return path.parent / "__pycache__"


def entry(slots: Sequence[Slot], what: str, signature: str, usual: Record | None = None,
          tuples: bool = True) -> Any:
    """The compiled entry point ``what`` ("scans", "fused", "step", "rows", "batch" or
    "batch_fused") of a plan laid out as ``slots``, loaded from the cache or compiled (once
    per process, once per machine). A fused entry whose kernels do not all compile with
    their coefficients as tuples (:func:`_coefficients`: a kernel that writes or slices
    them) is compiled again with slices of the buffer."""
    if tuples and what in ("fused", "batch_fused"):
        import numba

        try:
            return _entry(slots, what, signature, usual, True)
        except numba.core.errors.TypingError:
            return _entry(slots, what, signature, usual, False)
    return _entry(slots, what, signature, usual, tuples)


def _entry(slots: Sequence[Slot], what: str, signature: str, usual: Record | None,
           tuples: bool) -> Any:
    """:func:`entry` with the coefficients as tuples or not."""
    name, text, injected = _name(slots, what, usual, tuples)
    mod = _loaded.get(name)
    if mod is None:
        mod = _loaded[name] = _module(name, text, injected)
    disp = getattr(mod, what)
    if not disp.overloads:
        global _announced
        # a kernel's own entry, a batch (parallel) and a fused plan take long to compile; the
        # glue of the other plans (step, rows, scans) takes well under a second: not announced
        if (announce is not None and not _announced
                and what in ("call", "batch", "fused", "batch_fused")
                and not is_cached(slots, what, usual)):
            _announced = True  # one line per process, before the first compilation
            kinds = ", ".join(sorted({_kind(slot.kernel) for slot in slots}))
            thing = (kinds if what == "call" else
                     f"the {what.replace('_', ' ')} plan of this module ({kinds})")
            where = (f"once for this machine (cached in {cache_dir()}; later runs load it)"
                     if getattr(mod, "CACHE", False) else
                     "in memory (the cache cannot be written: every run compiles it)")
            announce(f"compiling {thing} {where}: this can take a minute")
        if getattr(mod, "CACHE", False):
            with _compile_lock(cache_dir() / "plans" / f"{name}.{what}.lock"):
                try:
                    disp.compile(signature)  # loads what another process compiled meanwhile
                except ModuleNotFoundError as exc:
                    if not str(exc.name or "").startswith("lw_plan_"):
                        raise
                    # machine code that names a plan module no process makes any more (its
                    # source changed while the process that compiled it ran): compiled again
                    _forget(cache_dir() / "plans" / f"{name}.py", name, what)
                    disp.compile(signature)
        else:
            disp.compile(signature)
    return disp


def _forget(path: Path, name: str, what: str) -> None:
    """Remove the cached machine code of entry ``what`` of plan ``name`` (numba's index and
    data files), so the next compilation writes it anew."""
    directory = _machine_code_dir(path)
    for pattern in (f"{name}.{what}-*.nbi", f"{name}.{what}-*.nbc"):
        for file in directory.glob(pattern):
            file.unlink(missing_ok=True)


@contextmanager
def _compile_lock(path: Path) -> Iterator[None]:
    """An exclusive lock on ``path`` while a plan is compiled into the cache: a process that
    needs the same plan at the same time (a sweep's workers, a parallel test suite) waits,
    then loads the machine code the first one wrote instead of compiling it too. POSIX
    ``flock``, released by the system if the holder dies; where there is none (Windows, a file
    system without locks) nothing is held and each process compiles, as before."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - Windows
        yield
        return
    try:
        fh = open(path, "a")  # noqa: SIM115 - held open for the lock's lifetime
    except OSError:
        yield
        return
    with fh:
        with suppress(OSError):
            fcntl.flock(fh, fcntl.LOCK_EX)
        yield


_announced = False


def _kind(kernel: Any) -> str:
    """A kernel's name as a user knows it: the registered kinds that run it (``deltav.pid``),
    else its function's name."""
    from loopworks.blocks.registry import registered

    names = sorted(k for k, cls in registered().items() if cls.kernel is kernel)
    return "/".join(names) if names else str(getattr(kernel, "__name__", "kernel"))


def compile_kind(cls: type[Block]) -> tuple[str, float, bool]:
    """Compile the kernel of block class ``cls`` into the cache (its ``call`` entry, which
    every other plan calls), or load it when it is there: (its kind, seconds, True when it had
    to compile). ``loopworks compile`` runs this for many kinds, in several processes."""
    import time

    slots = layout([(cls.kernel, 0, 0, 0, 0, not cls.SOUND_KERNEL)])
    cached = is_cached(slots, "call")
    start = time.perf_counter()
    entry(slots, "call", CALL_SIGNATURE)
    return cls.kind, time.perf_counter() - start, not cached


def entry_point(slots: Sequence[Slot], what: str, signature: str) -> Any:
    """:func:`entry`'s direct machine-code entry: skips numba's argument-type dispatch, so
    it must be called with exactly the signature's array types (C-contiguous, float64/int64)."""
    disp = entry(slots, what, signature)
    return disp.overloads[disp.signatures[-1]].entry_point
