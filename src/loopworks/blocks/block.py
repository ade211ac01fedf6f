"""The block model: parameters, named ports with status, inspectable state, and a kernel.

A block subclass declares ``PARAMS``, ``INPUTS``, ``OUTPUTS`` and ``STATES``, a static
``kernel`` (see :mod:`loopworks.blocks.kernel`) and ``coefficients()``, which turns the validated
parameters into the flat ``p`` array the kernel reads. Everything else is here:

* parameters are validated when the block is made (:mod:`loopworks.blocks.params`);
* ``step(dt, **inputs)`` advances one scan. An input keeps its last given value until it is
  given again (as a wired DCS input does); unset inputs take their port default;
* ``state_dict()`` / ``load_state()`` save and restore everything that persists between scans,
  so a run resumed from saved state continues exactly as an uninterrupted one;
* ``reset()`` returns to the state right after construction.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from typing import Any, ClassVar, cast

import numpy as np

from loopworks.blocks import status as st
from loopworks.blocks.kernel import FloatArray, IntArray, Kernel, entry_point, jit_enabled
from loopworks.blocks.params import Param, Port, validate
from loopworks.blocks.status import Signal
from loopworks.errors import InputError


class Outputs(Mapping[str, Signal]):
    """The outputs of one scan, by port name: ``result["out"]`` is a :class:`Signal`."""

    __slots__ = ("_index", "_y", "_ys")

    def __init__(self, index: dict[str, int], y: Any, ys: Any) -> None:
        self._index, self._y, self._ys = index, y, ys

    def __getitem__(self, name: str) -> Signal:
        i = self._index[name]
        return Signal(self._y[i], self._ys[i])

    def __iter__(self) -> Iterator[str]:
        return iter(self._index)

    def __len__(self) -> int:
        return len(self._index)

    def __repr__(self) -> str:
        return "Outputs(" + ", ".join(f"{k}={self[k]}" for k in self._index) + ")"


class Block:
    """Base class of every block kind. Subclasses are registered with ``@register``."""

    kind: ClassVar[str] = ""
    summary: ClassVar[str] = ""
    PARAMS: ClassVar[tuple[Param, ...]] = ()
    INPUTS: ClassVar[tuple[Port, ...]] = ()
    OUTPUTS: ClassVar[tuple[Port, ...]] = ()
    STATES: ClassVar[tuple[str, ...]] = ()

    @staticmethod
    def kernel(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
               y: FloatArray, ys: IntArray) -> None:
        """One scan. Subclasses replace this with their arithmetic."""
        raise NotImplementedError  # pragma: no cover - abstract

    def __init__(self, *, jit: bool | None = None, **params: Any) -> None:
        self.given: dict[str, Any] = {k.lower(): v for k, v in params.items()}
        self.params: dict[str, Any] = validate(self.kind, self.PARAMS, params)
        self.p: FloatArray = np.asarray(self.coefficients(), dtype=np.float64)
        self.jit = jit_enabled() if jit is None else jit
        self._in_index = {port.name: i for i, port in enumerate(self.INPUTS)}
        self._out_index = {port.name: i for i, port in enumerate(self.OUTPUTS)}
        self._run: Kernel = entry_point(type(self).kernel) if self.jit else type(self).kernel
        self.x: FloatArray = np.zeros(len(self.STATES))
        self.u: FloatArray = np.zeros(len(self.INPUTS))
        self.us: IntArray = np.zeros(len(self.INPUTS), dtype=np.int64)
        self.y: FloatArray = np.zeros(len(self.OUTPUTS))
        self.ys: IntArray = np.zeros(len(self.OUTPUTS), dtype=np.int64)
        # memoryviews on the same buffers: item access from Python is several times cheaper
        self._um: Any = memoryview(cast(Any, self.u))
        self._usm: Any = memoryview(cast(Any, self.us))
        self._ym: Any = memoryview(cast(Any, self.y))
        self._ysm: Any = memoryview(cast(Any, self.ys))
        self.reset()

    # -- to be provided by subclasses -------------------------------------------------------
    def coefficients(self) -> list[float]:
        """The kernel's ``p`` array from ``self.params``; cross-parameter checks go here."""
        raise NotImplementedError  # pragma: no cover - abstract

    def initial_state(self) -> list[float]:
        """State right after construction or ``reset()``; zeros unless overridden."""
        return [0.0] * len(self.STATES)

    # -- the block API ------------------------------------------------------------------------
    def reset(self) -> None:
        """Return to the state right after construction (inputs to their defaults)."""
        self.x[:] = self.initial_state()
        self.u[:] = [port.default for port in self.INPUTS]
        self.us[:] = st.GOOD_NC
        self.y[:] = 0.0
        self.ys[:] = st.GOOD_NC

    def step(self, dt: float, **inputs: Any) -> Outputs:
        """Advance one scan of ``dt`` seconds. Inputs are floats, :class:`Signal` pairs
        ``(value, status)``, or for enumerated inputs their names (``mode="MAN"``)."""
        if not 0.0 < dt < math.inf:
            raise InputError(
                f"{self.kind}: dt = {dt!r} s is not allowed: dt must be > 0 and finite")
        if inputs:
            index, u, us = self._in_index, self._um, self._usm
            for name, value in inputs.items():
                i = index.get(name)
                if i is not None and type(value) is float:  # the fast path
                    u[i] = value
                    us[i] = 128
                else:
                    self.set_inputs({name: value})
        self._run(float(dt), self.p, self.x, self.u, self.us, self.y, self.ys)
        return Outputs(self._out_index, self._ym, self._ysm)

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
            if type(value) is float or type(value) is int:
                u[i] = value
                us[i] = st.GOOD_NC
            elif isinstance(value, tuple):
                try:
                    us[i] = st.check_byte(value[1], f"{self.kind}: status of input '{name}'")
                    u[i] = float(value[0])
                except (TypeError, ValueError, IndexError) as exc:
                    raise InputError(str(exc)) from None
            else:
                try:
                    u[i] = self.INPUTS[i].parse(value)
                except (TypeError, ValueError) as exc:
                    raise InputError(f"{self.kind}: {exc}") from None
                us[i] = st.GOOD_NC

    def outputs(self) -> Outputs:
        """The outputs of the last scan."""
        return Outputs(self._out_index, self._ym, self._ysm)

    def state(self) -> dict[str, float]:
        """The named state variables, for inspection."""
        return {name: float(v) for name, v in zip(self.STATES, self.x, strict=True)}

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
        """Restore what :meth:`state_dict` saved. The kind and state names must match."""
        if saved.get("kind") != self.kind:
            raise InputError(f"saved state is for kind {saved.get('kind')!r}, not {self.kind!r}")
        names = set(saved["state"])
        if names != set(self.STATES):
            raise InputError(f"{self.kind}: saved state names {sorted(names)} do not match "
                             f"{sorted(self.STATES)}")
        self.x[:] = [float(saved["state"][n]) for n in self.STATES]
        for arr, sarr, ports, key in ((self.u, self.us, self.INPUTS, "inputs"),
                                      (self.y, self.ys, self.OUTPUTS, "outputs")):
            for i, port in enumerate(ports):
                value, status = saved[key][port.name]
                arr[i] = float(value)
                sarr[i] = st.check_byte(status)

    @classmethod
    def describe(cls) -> str:
        """A short description for ``loopworks blocks``."""
        return cls.summary or (cls.__doc__ or "").strip().splitlines()[0]

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.given.items())
        return f"create_block({self.kind!r}{', ' if args else ''}{args})"
