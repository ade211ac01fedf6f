"""The block model: parameters, named ports with status, inspectable state, and a kernel.

A block subclass declares ``PARAMS``, ``INPUTS``, ``OUTPUTS``, ``COEFFS`` and ``STATES`` (the
last two are layouts, :mod:`loopworks.blocks.layout`, from which its kernel's index names are
generated), a static ``kernel`` (see :mod:`loopworks.blocks.kernel`) and ``coefficients()``,
which turns the validated parameters into the named values of the ``p`` array the kernel
reads (packed in the declared order). Everything else is here:

* parameters are validated when the block is made (:mod:`loopworks.blocks.params`);
* ``step(dt, **inputs)`` advances one scan. An input keeps its last given value until it is
  given again (as a wired DCS input does); unset inputs take their port default;
* ``state_dict()`` / ``load_state()`` save and restore everything that persists between scans,
  so a run resumed from saved state continues exactly as an uninterrupted one;
* ``reset()`` returns to the state right after construction.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence
from typing import Any, ClassVar

import numpy as np

from loopworks.blocks import layout
from loopworks.blocks import status as st
from loopworks.blocks.kernel import (
    FloatArray,
    IntArray,
    Kernel,
    guarded_entry,
    guarded_scan,
    jit_enabled,
    step_entry,
)
from loopworks.blocks.params import Param, Port, validate
from loopworks.blocks.status import Signal
from loopworks.errors import InputError


class Outputs(tuple, Mapping[str, Signal]):  # type: ignore[type-arg]
    """The outputs of one scan, by port name: ``result["out"]`` is a :class:`Signal`.

    A snapshot taken when the scan ended (the compiled scan returns its output values and
    statuses as one tuple), so a result always shows the scan that produced it, however long
    it is held. The :class:`Signal` pairs are built when read."""

    __slots__ = ()

    # tuple.__getitem__(self, 0): port name -> index; 1: (values..., statuses...)
    def __getitem__(self, name: str) -> Signal:  # type: ignore[override]
        get = tuple.__getitem__
        index = get(self, 0)
        i = index[name]
        values = get(self, 1)
        return Signal(float(values[i]), int(values[i + len(index)]))

    def __iter__(self) -> Iterator[str]:
        return iter(tuple.__getitem__(self, 0))

    def __len__(self) -> int:
        return len(tuple.__getitem__(self, 0))

    def __contains__(self, name: object) -> bool:
        return name in tuple.__getitem__(self, 0)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Mapping) and dict(self.items()) == dict(other.items())

    def __hash__(self) -> int:
        return id(self)

    def __repr__(self) -> str:
        return "Outputs(" + ", ".join(f"{k}={self[k]}" for k in self) + ")"


_new_outputs = tuple.__new__
_INF = math.inf


_MISSING: Any = object()  # a keyword step()'s default: the input was not given


def keyword_step(inputs: Sequence[Port]) -> Any:
    """A kind's ``step(dt, *, sp=..., pv=..., **other)``: :meth:`Block.step` with the kind's
    input ports as keyword-only parameters, generated from its ``INPUTS`` (so a call binds
    them without building a dict of keywords, and ``help(block.step)`` lists them).

    The rule is :meth:`Block.step`'s: up to two plain floats given to non-enumerated ports
    by their exact names go to the compiled scan in its one call; any other call (an int, a
    ``(value, status)`` pair, an enumerated input, a third input, a name in another letter
    case) takes :meth:`Block.step`'s general path with the given inputs in port order, then
    ``other`` in the order given. Returns None when a port name cannot be a parameter."""
    import keyword

    names = [port.name for port in inputs]
    if any(not n.isidentifier() or keyword.iskeyword(n) or n in ("self", "dt", "other")
           or n.startswith("_") for n in names):
        return None
    slow = ("return _general(self, dt, {" + ", ".join(f"{n!r}: {n}" for n in names)
            + "}, other)")
    def packed(ia: int, a: str, ib: int, b: str) -> str:
        return (f"return _new(_Outputs, (self._out_index, self._packed(dt, self._fa, self._sa, "
                f"{ia}, {a}, {ib}, {b}, self._all_good)))")

    lines = ["def step(self, dt, " + ("*, " if names else "")
             + "".join(f"{n}=_M, " for n in names) + "**other):",
             "    if other or not 0.0 < dt < _INF:",
             f"        {slow}"]
    # the common call first: only the first two float ports given (or fewer), as floats
    first = [i for i, port in enumerate(inputs) if not port.choices][:2]
    if len(first) == 2:
        (i, m), (k, n) = ((i, names[i]) for i in first)
        rest = [x for j, x in enumerate(names) if j not in first]
        lines += ["    if " + " and ".join(f"{x} is _M" for x in rest) + ":" if rest
                  else "    if True:",
                  f"        if {m} is _M:",
                  f"            if {n} is _M:",
                  f"                {packed(-1, '0.0', -1, '0.0')}",
                  f"            if {n}.__class__ is float:",
                  f"                {packed(k, n, -1, '0.0')}",
                  f"        elif {m}.__class__ is float:",
                  f"            if {n} is _M:",
                  f"                {packed(i, m, -1, '0.0')}",
                  f"            if {n}.__class__ is float:",
                  f"                {packed(i, m, k, n)}",
                  f"        {slow}"]
    lines += ["    ia = ib = -1",
              "    a = b = 0.0"]
    for i, port in enumerate(inputs):
        n = port.name
        lines += [f"    if {n} is not _M:"]
        if port.choices:
            lines += [f"        {slow}"]
            continue
        lines += [f"        if {n}.__class__ is not float or ib >= 0:",
                  f"            {slow}",
                  "        if ia < 0:",
                  f"            ia = {i}",
                  f"            a = {n}",
                  "        else:",
                  f"            ib = {i}",
                  f"            b = {n}"]
    lines += ["    return _new(_Outputs, (self._out_index, self._packed(",
              "        dt, self._fa, self._sa, ia, a, ib, b, self._all_good)))"]
    namespace: dict[str, Any] = {"_M": _MISSING, "_INF": _INF, "_new": _new_outputs,
                                 "_Outputs": Outputs, "_general": _general_step}
    exec("\n".join(lines), namespace)  # the source is built above from the port names
    step = namespace["step"]
    step.__doc__ = Block.step.__doc__
    step.__qualname__ = "step"
    step.generated = True
    return step


def _general_step(block: Block, dt: float, given: Mapping[str, Any],
                  other: Mapping[str, Any]) -> Outputs:
    """A keyword step()'s general path: :meth:`Block.step` with the inputs given."""
    inputs = {name: value for name, value in given.items() if value is not _MISSING}
    inputs.update(other)
    return Block.step(block, dt, **inputs)


class Block:
    """Base class of every block kind. Subclasses are registered with ``@register``.

    A subclass whose ``step`` is :meth:`Block.step` (it does not write its own) gets the
    keyword form made for its ``INPUTS`` (:func:`keyword_step`)."""

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if cls.step is Block.step or getattr(cls.step, "generated", False):
            step = keyword_step(cls.INPUTS)
            cls.step = step if step is not None else Block.step  # type: ignore[method-assign]

    kind: ClassVar[str] = ""
    summary: ClassVar[str] = ""
    PARAMS: ClassVar[tuple[Param, ...]] = ()
    INPUTS: ClassVar[tuple[Port, ...]] = ()
    OUTPUTS: ClassVar[tuple[Port, ...]] = ()
    #: the coefficient array p: names and Arrays (:mod:`loopworks.blocks.layout`)
    COEFFS: ClassVar[tuple[Any, ...]] = ()
    #: the state array x: names and Arrays (an Array's size may follow the parameters)
    STATES: ClassVar[tuple[Any, ...]] = ()
    #: parameters set_params() refuses to change, each with the reason (they size the state,
    #: give its units, or make its program): a new block is needed
    FIXED_PARAMS: ClassVar[dict[str, str]] = {}
    #: False for kinds whose array sizes vary per instance (``deltav.calc``): the compiled
    #: single-step wrapper is specialised to the sizes, so such kinds step through the kernel's
    #: standard entry point instead of compiling a wrapper per instance.
    FIXED_LAYOUT: ClassVar[bool] = True
    #: True when the kernel keeps the numeric contract by itself (no scan leaves a state, or
    #: an output whose status is not Bad, non-finite once non-finite inputs are shown to it
    #: as Bad): the guard then only marks those inputs, and skips the copy of the state that
    #: its undo needs every scan. The property test "the kernel alone is sound" checks every
    #: kind that declares it; a kind that is not sound by itself sets False (full guard).
    SOUND_KERNEL: ClassVar[bool] = True

    @staticmethod
    def kernel(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
               y: FloatArray, ys: IntArray) -> None:
        """One scan. Subclasses replace this with their arithmetic."""
        raise NotImplementedError  # pragma: no cover - abstract

    def __init__(self, *, jit: bool | None = None, **params: Any) -> None:
        self.given: dict[str, Any] = {k.lower(): v for k, v in params.items()}
        self.params: dict[str, Any] = validate(self.kind, self.PARAMS, params)
        self.p: FloatArray = self._coefficients()
        self.jit = jit_enabled() if jit is None else jit
        self._in_index = {port.name: i for i, port in enumerate(self.INPUTS)}
        # inputs a plain float may be written to directly (enumerated ones are checked)
        self._fast_index = {port.name: i for i, port in enumerate(self.INPUTS)
                            if not port.choices}
        self._out_index = {port.name: i for i, port in enumerate(self.OUTPUTS)}
        self.n_x = layout.size(self.STATES, self.params)
        n_p, n_x, n_u, n_y = len(self.p), self.n_x, len(self.INPUTS), len(self.OUTPUTS)
        # One float buffer [p | x | u | y] and one int buffer [us | ys]; the named arrays are
        # views into them (a module moves them into its plan's buffers, see adopt()).
        self._F: FloatArray = np.zeros(n_p + n_x + n_u + n_y)
        self._S: IntArray = np.zeros(n_u + n_y, dtype=np.int64)
        #: the token of the module whose buffers these are (None: the block's own)
        self._module: object | None = None
        self._F[:n_p] = self.p
        self._bind()
        # every scan runs under the numeric contract (kernel.guarded_scan), through entries
        # bound on the first scan (a block that only runs inside a module's plan needs none)
        self._run: Kernel = self._run_first
        self._packed: Any = self._packed_first
        self._all_good = True  # every input status is Good NC (128): the fast path skips them
        self.reset()

    def _bind(self) -> None:
        """Name the views of the buffers: p, x, u, y in ``_F``; us, ys in ``_S``."""
        n_p, n_x, n_u = len(self.p), self.n_x, len(self.INPUTS)
        F, S = self._F, self._S
        self.p = F[:n_p]
        self.x: FloatArray = F[n_p:n_p + n_x]
        self.u: FloatArray = F[n_p + n_x:n_p + n_x + n_u]
        self.y: FloatArray = F[n_p + n_x + n_u:]
        self.us: IntArray = S[:n_u]
        self.ys: IntArray = S[n_u:]
        # where they are, for the compiled step (blocks.address): the block holds F and S
        self._fa: int = F.ctypes.data
        self._sa: int = S.ctypes.data

    def __getstate__(self) -> dict[str, Any]:
        """What a copy or a pickle keeps: the parameters and the numbers, not the compiled
        entries (closures, which cannot be pickled) nor the buffers' addresses, which
        :meth:`__setstate__` binds again (found by an outside audit: ``copy.deepcopy`` of a
        block kept the original's addresses, so the copy's scans wrote into the original's
        buffers, or into freed memory once the original was gone)."""
        state = dict(self.__dict__)
        for key in ("_run", "_packed", "_fa", "_sa"):
            state.pop(key, None)
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        """A copied or unpickled block: buffers of its own (a module's copy gives its blocks
        views of its own again: ``Module.__setstate__``), entries bound on its first scan."""
        self.__dict__.update(state)
        self._F, self._S = np.array(self._F), np.array(self._S)
        self._module = None
        self._bind()
        self._run = self._run_first
        self._packed = self._packed_first

    def adopt(self, F: FloatArray, S: IntArray) -> None:
        """Move the block's buffers into ``F`` and ``S``, views of a plan's flat buffers of
        this block's sizes: everything the block holds is copied there, and from now on its
        arrays (p, x, u, y, us, ys) are views of them, so a compiled plan and the block's
        own methods (step, state, set_params, load_state) work on the same numbers."""
        if F.shape != self._F.shape or S.shape != self._S.shape:
            raise ValueError(f"{self.kind}: adopt() needs buffers of {self._F.shape[0]} floats "
                             f"and {self._S.shape[0]} ints")
        F[:] = self._F
        S[:] = self._S
        self._F, self._S = F, S
        self._bind()

    def _coefficients(self) -> FloatArray:
        """``coefficients()`` packed in the order ``COEFFS`` declares."""
        values = self.coefficients()
        if not isinstance(values, Mapping):  # a kind not yet declaring COEFFS
            return np.asarray(values, dtype=np.float64)
        return np.asarray(layout.pack(self.COEFFS, values, f"{self.kind}: coefficients()",
                                      self.params), dtype=np.float64)

    # -- to be provided by subclasses -------------------------------------------------------
    def coefficients(self) -> Mapping[str, Any]:
        """The kernel's coefficients from ``self.params``, by their ``COEFFS`` names (an
        Array's as a sequence); cross-parameter checks go here."""
        raise NotImplementedError  # pragma: no cover - abstract

    def initial_state(self) -> Sequence[float] | FloatArray:
        """State right after construction or ``reset()`` (flat, in ``STATES`` order); zeros
        unless overridden."""
        return [0.0] * self.n_x

    def initial_outputs(self) -> list[float]:
        """Outputs before the first scan (what a module's blocks read from this one until it
        runs); zeros unless overridden. Called after the state is initialised."""
        return [0.0] * len(self.OUTPUTS)

    # -- the block API ------------------------------------------------------------------------
    def _bind_entries(self) -> None:
        """The scan entries: a one-block plan's compiled step (cached on disk, blocks.plan),
        the 7-array compiled entry for layouts that vary per instance, or the interpreter."""
        kernel = type(self).kernel
        full = not self.SOUND_KERNEL
        if self.jit and self.FIXED_LAYOUT:
            self._packed = step_entry(kernel, len(self.p), len(self.x), len(self.u),
                                      len(self.y), full)
            self._run = self._run_packed
        else:
            self._run = (guarded_entry(kernel, full) if self.jit
                         else guarded_scan(kernel, False, full))
            self._packed = self._packed_interpreted

    def _run_first(self, dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                   y: FloatArray, ys: IntArray) -> None:
        self._bind_entries()
        self._run(dt, p, x, u, us, y, ys)

    def _packed_first(self, dt: float, fa: int, sa: int, ia: int, a: float, ib: int, b: float,
                      good: bool) -> tuple[Any, ...]:
        self._bind_entries()
        return self._packed(dt, fa, sa, ia, a, ib, b, good)  # type: ignore[no-any-return]

    def _packed_interpreted(self, dt: float, fa: int, sa: int, ia: int, a: float, ib: int,
                            b: float, good: bool) -> tuple[Any, ...]:
        """What the compiled one-block ``step`` does (:func:`loopworks.blocks.plan.source`):
        write up to two inputs, scan, return (values..., statuses...) of the outputs."""
        u, us = self.u, self.us
        if ia >= 0:
            u[ia] = a
            if not good:
                us[ia] = 128
        if ib >= 0:
            u[ib] = b
            if not good:
                us[ib] = 128
        self._run(dt, self.p, self.x, u, us, self.y, self.ys)
        return tuple(self.y.tolist() + self.ys.tolist())

    def _run_packed(self, dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                    y: FloatArray, ys: IntArray) -> None:
        """The 7-array scan of a compiled fixed-layout block, through its packed entry (the
        arrays are views of its own buffers)."""
        self._packed(dt, self._fa, self._sa, -1, 0.0, -1, 0.0, True)

    def reset(self) -> None:
        """Return to the state right after construction (inputs to their defaults)."""
        self.x[:] = self.initial_state()
        self.u[:] = [port.default for port in self.INPUTS]
        self.us[:] = st.GOOD_NC
        self._all_good = True
        self.y[:] = self.initial_outputs()
        self.ys[:] = st.GOOD_NC

    def publish_pass_through(self, out_port: str, in_port: str) -> None:
        """Before the first scan, once a module has settled its wires (``publish_start``):
        the initial outputs again from the inputs latched now, ``out_port`` with the status
        of ``in_port`` (a compensator or a DeltaV stick-slip block passes its input through
        before it has run, so a valve scanned before it reads the controller's output, not a
        placeholder 0)."""
        self.y[:] = self.initial_outputs()
        self.ys[self._out_index[out_port]] = self.us[self._in_index[in_port]]

    def step(self, dt: float, **inputs: Any) -> Outputs:
        """Advance one scan of ``dt`` seconds. Inputs are floats, :class:`Signal` pairs
        ``(value, status)``, or for enumerated inputs their names (``mode="MAN"``)."""
        if not 0.0 < dt < _INF:
            raise InputError(
                f"{self.kind}: dt = {dt!r} s is not allowed: dt must be > 0 and finite")
        # The common call, up to two plain floats by their exact port names (sp=, pv=), hands
        # them to the compiled scan, one call from Python that also returns the outputs;
        # anything else is written here first, in the order given.
        if inputs:
            ia = ib = -1
            a = b = 0.0
            index = self._fast_index
            for name in inputs:
                i = index.get(name, -1)
                value = inputs[name]
                if i < 0 or type(value) is not float:
                    break
                if ia < 0:
                    ia = i
                    a = value
                elif ib < 0:
                    ib = i
                    b = value
                else:
                    break
            else:
                return _new_outputs(Outputs, (self._out_index, self._packed(
                    dt, self._fa, self._sa, ia, a, ib, b, self._all_good)))
            self._write_inputs(inputs)
        return _new_outputs(Outputs, (self._out_index, self._packed(
            dt, self._fa, self._sa, -1, 0.0, -1, 0.0, True)))

    def _write_inputs(self, inputs: Mapping[str, Any]) -> None:
        """step()'s inputs, in the order given: plain floats by their exact port names
        straight into the buffer (status Good NC), anything else through set_inputs."""
        index, u = self._fast_index, self.u
        good = self._all_good
        for name, value in inputs.items():
            i = index.get(name)
            if i is not None and type(value) is float:  # the fast path
                u[i] = value
                if not good:
                    self.us[i] = 128
            else:
                self.set_inputs({name: value})

    def set_inputs(self, inputs: Mapping[str, Any]) -> None:
        """Latch input values (and statuses) without running a scan."""
        index, u, us = self._in_index, self.u, self.us
        for name, value in inputs.items():
            i = index.get(name)
            if i is None:
                i = index.get(name.lower())
                if i is None:
                    raise InputError(
                        f"{self.kind}: unknown input '{name}'; valid inputs: "
                        + ", ".join(index))
            if (type(value) is float or type(value) is int) and not self.INPUTS[i].choices:
                u[i] = value
                us[i] = st.GOOD_NC
            elif isinstance(value, tuple):
                try:
                    us[i] = st.check_byte(value[1], f"{self.kind}: status of input '{name}'")
                    u[i] = float(value[0])
                except (TypeError, ValueError, IndexError) as exc:
                    raise InputError(str(exc)) from None
                if us[i] != st.GOOD_NC:
                    self._all_good = False
            else:
                try:
                    u[i] = self.INPUTS[i].parse(value)
                except (TypeError, ValueError) as exc:
                    raise InputError(f"{self.kind}: {exc}") from None
                us[i] = st.GOOD_NC

    def check_dt(self, dt: float) -> None:
        """Raise InputError if this block cannot run at scan time ``dt`` (s). Modules and
        replays call it before running; blocks with a fixed sample time or a limited delay
        line override it."""

    def set_params(self, **changes: Any) -> None:
        """Change parameters between scans (an operator's new tuning): validated like the
        constructor's; the state is kept, so the next scan continues from it."""
        given = dict(self.given)
        given.update({k.lower(): v for k, v in changes.items()})
        params = validate(self.kind, self.PARAMS, given)
        for name, why in self.FIXED_PARAMS.items():
            if params[name] != self.params[name]:
                raise InputError(f"{self.kind}: {name} {why} and cannot change "
                                 f"({self.params[name]!r} → {params[name]!r}); make a new block")
        # the coefficients are computed from the new values and the new set of names given
        # (a rule on which parameters were given, such as DeltaV's BETA only with the
        # two-degrees-of-freedom structure, judges this change, not the last one)
        old_params, old_given = self.params, self.given
        self.params, self.given = params, given
        try:
            coefficients = self._coefficients()
            if coefficients.shape != self.p.shape:
                raise InputError(f"{self.kind}: changing {', '.join(changes)} changes the "
                                 "block's layout; make a new block instead")
        except Exception:
            self.params, self.given = old_params, old_given
            raise
        self.p[:] = coefficients

    def port_unit(self, port: str, direction: str) -> str:
        """The unit port ``port`` (lower case; ``direction`` "input" or "output") holds its
        value in, as wires compare them (``Module.unit_warnings``): "%", "counts", or the
        declared unit; "EU" of a scale this block does not know is "eu" (whatever it is fed).
        A block that knows its scales (deltav.pid) says "%" where a scale is 0..100."""
        ports = self.INPUTS if direction == "input" else self.OUTPUTS
        unit = next((p.unit for p in ports if p.name == port), "")
        return {"count": "counts", "EU": "eu"}.get(unit, unit)

    def outputs(self) -> Outputs:
        """The outputs of the last scan (a copy)."""
        return _new_outputs(Outputs, (self._out_index,
                                      tuple(self.y.tolist() + self.ys.tolist())))

    def state(self) -> dict[str, Any]:
        """The named state variables, for inspection (an Array's as a list)."""
        return layout.unpack(self.STATES, self.x, self.params)

    def state_dict(self) -> dict[str, Any]:
        """Everything that persists between scans, as plain JSON-able Python values."""
        return {
            "kind": self.kind,
            "params": dict(self.given),
            "state": self.state(),
            "inputs": {port.name: [float(self.u[i]), int(self.us[i])]
                       for i, port in enumerate(self.INPUTS)},
            "outputs": {port.name: [float(self.y[i]), int(self.ys[i])]
                        for i, port in enumerate(self.OUTPUTS)},
        }

    def load_state(self, saved: Mapping[str, Any]) -> None:
        """Restore what :meth:`state_dict` saved. The kind and state names must match. The
        saved parameters that differ from this block's are set first (a retuning by an
        operator or an event before the save is part of what resumes)."""
        if saved.get("kind") != self.kind:
            raise InputError(f"saved state is for kind {saved.get('kind')!r}, not {self.kind!r}")
        changed = {k: v for k, v in (saved.get("params") or {}).items()
                   if k not in self.given or not _same(self.given[k], v)}
        if changed:
            self.set_params(**changed)
        try:
            x = layout.pack(self.STATES, saved["state"], f"{self.kind}: saved state",
                            self.params)
        except (ValueError, TypeError) as exc:
            raise InputError(str(exc)) from None
        if not np.isfinite(x).all():  # a block's state is finite (the kernels' contract)
            names = layout.names(self.STATES, self.params)
            at = int(np.flatnonzero(~np.isfinite(x))[0])
            raise InputError(f"{self.kind}: saved state '{names[at]}' = {float(x[at])!r} "
                             "is not allowed: a state is a finite number")
        for port in self.OUTPUTS:
            value, status = saved["outputs"][port.name]
            if not math.isfinite(float(value)) and st.check_byte(status) & 0xC0 != st.BAD:
                raise InputError(f"{self.kind}: saved output '{port.name}' = {value!r} "
                                 f"with status {status} is not allowed: an output that is "
                                 "not a finite number has a Bad status")
        self.x[:] = x
        for arr, sarr, ports, key in ((self.u, self.us, self.INPUTS, "inputs"),
                                      (self.y, self.ys, self.OUTPUTS, "outputs")):
            for i, port in enumerate(ports):
                value, status = saved[key][port.name]
                arr[i] = float(value)
                sarr[i] = st.check_byte(status)
        self._all_good = bool((self.us == st.GOOD_NC).all())

    @classmethod
    def split_table(cls, table: Mapping[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
        """Split a scenario block table (lower-case keys, no ``kind``) into parameters and
        constants for unwired inputs. Blocks whose ports depend on their parameters override
        this."""
        inputs = {p.name for p in cls.INPUTS}
        return ({k: v for k, v in table.items() if k not in inputs},
                {k: v for k, v in table.items() if k in inputs})

    @classmethod
    def describe(cls) -> str:
        """A short description for ``loopworks blocks``."""
        return cls.summary or (cls.__doc__ or "").strip().splitlines()[0]

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.given.items())
        return f"create_block({self.kind!r}{', ' if args else ''}{args})"


def _same(a: Any, b: Any) -> bool:
    """Two given parameter values are the same (NaN equal to NaN)."""
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return bool(a == b)
