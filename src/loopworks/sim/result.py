"""The result of a module run: time-indexed arrays for every port and its status."""

from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from loopworks.blocks.controller import Roles


@dataclass
class SimResult:
    """``t`` (s, the time of each scan); ``values["block.port"]`` and ``status["block.port"]``
    for every input and output of every block; ``kinds`` maps block names to kinds.

    From :meth:`Module.run <loopworks.sim.module.Module.run>` the arrays are read-only: a
    constant input is one value broadcast over the scans, and an input wired to an output
    shares that output's memory (``Module.record_plan``); copy one (``np.array(a)``) to
    change it."""

    t: np.ndarray
    values: dict[str, np.ndarray]
    status: dict[str, np.ndarray]
    kinds: dict[str, str] = field(default_factory=dict)
    wires: dict[str, str] = field(default_factory=dict)
    #: each controller's output units of 100 % (``Controller.out_span``; 100 when not given);
    #: in a batch, an array of one per instance where they differ
    out_spans: dict[str, float | np.ndarray] = field(default_factory=dict)
    #: the controllers whose output is an increment per scan (``Controller.incremental``: S5's
    #: velocity algorithm); their output figures are of the position the increments build
    incremental: frozenset[str] = frozenset()

    def __getitem__(self, name: str) -> np.ndarray:
        """``result["pid.out"]``; ``result["pid.out.ST"]`` gives the status array."""
        if name.upper().endswith(".ST") and name[:-3] in self.status:
            return self.status[name[:-3]]
        try:
            return self.values[name]
        except KeyError:
            raise KeyError(f"no signal '{name}'; signals: {', '.join(self.values)}") from None

    @property
    def names(self) -> list[str]:
        """Every signal name, ``block.port``."""
        return list(self.values)

    def roles(self, block: str) -> Roles | None:
        """The controller roles of ``block`` (which of its ports are SP, PV, OUT, ...: the
        kind's :class:`~loopworks.blocks.controller.Roles`), None when it is no controller."""
        from loopworks.blocks.controller import Controller
        from loopworks.catalog import block_class

        cls = block_class(self.kinds[block])
        return cls.ROLES if issubclass(cls, Controller) else None

    def controllers(self) -> list[str]:
        """The controller blocks (every vendor's: GE's ``cv``, S5's ``w``/``x``/``y`` too)."""
        return [n for n in self.kinds if self.roles(n) is not None]

    def metrics(self, loop: str | None = None, valve: str | None = None,
                window: tuple[float, float] | None = None) -> dict[str, float]:
        """Loop metrics (spec plant-and-tuning 4.1, ``loopworks.sim.metrics.METRICS``) of
        controller ``loop`` (default: the first controller), with the valve's stem travel (its
        ``position``) and valve-command travel (the signal at its ``op`` input) when ``valve``
        names a block with a ``position`` output (default: the valve the loop drives, found
        along the wires), over ``window`` = (t0, t1) s. NaN marks a figure the data cannot
        support."""
        from loopworks.sim.metrics import loop_metrics

        loops = self.controllers()
        if loop is None:
            if not loops:
                raise KeyError("no controller block (kinds: pid, deltav.pid, e2.pid, s5.pid, "
                               "ge.pid_ind, ge.pid_isa)")
            loop = loops[0]
        if valve is None:
            valve = self.valve_of(loop)
        position = self.usable(f"{valve}.position") if valve is not None else None
        command = (self.usable(f"{valve}.op") if valve is not None
                   and f"{valve}.op" in self.values else None)
        roles = self._roles_of(loop)
        out = self.usable(f"{loop}.{roles.out}")
        if loop in self.incremental:  # the actuator's position: the sum of the increments
            good = np.isfinite(out)  # a Bad increment is n/a where it is, not ever after
            out = np.where(good, np.cumsum(np.where(good, out, 0.0), axis=-1), np.nan)
        return loop_metrics(self.t, self.working_sp(loop), self.usable(f"{loop}.{roles.pv}"),
                            out, position=position,
                            window=window, command=command,
                            out_span=self.out_spans.get(loop, 100.0))

    def usable(self, name: str) -> np.ndarray:
        """Signal ``name`` with its Bad-status samples as NaN (a held or last value with Bad
        status is no measurement: the metrics read it as the Bad value it is, n/a); the values
        as recorded when the run kept no status (a sweep's batch)."""
        values = self[name]
        st = self.status.get(name)
        if st is None:
            return values
        bad = (np.asarray(st).astype(np.int64) & 0xC0) == 0  # quality Bad (blocks.status)
        return np.where(bad, np.nan, values) if bad.any() else values

    def pv(self, loop: str) -> np.ndarray:
        """The PV controller ``loop`` saw (its PV role's input: ``pv``, S5's ``x``)."""
        return self[f"{loop}.{self._roles_of(loop).pv}"]

    def out(self, loop: str) -> np.ndarray:
        """The output of controller ``loop`` (its OUT role: ``out``, GE's ``cv``, S5's ``y``)."""
        return self[f"{loop}.{self._roles_of(loop).out}"]

    def out_units(self, loop: str) -> str:
        """The unit controller ``loop``'s output is in, as its kind declares it: ``%`` for
        an output in %, or in the loop's own output units (the generic pid), ``counts``
        (GE, S5), ``EU`` (DeltaV's OUT_SCALE)."""
        from loopworks.catalog import block_class

        cls = block_class(self.kinds[loop])
        unit = cls.OUTPUTS[[p.name for p in cls.OUTPUTS].index(self._roles_of(loop).out)].unit
        return {"out": "%", "count": "counts"}.get(unit, unit or "%")

    def _roles_of(self, loop: str) -> Roles:
        if loop not in self.kinds:
            raise KeyError(f"no block '{loop}'; blocks: {', '.join(self.kinds)}")
        roles = self.roles(loop)
        if roles is None:
            raise KeyError(f"'{loop}' is a {self.kinds[loop]} block, not a controller; "
                           f"controllers: {', '.join(self.controllers())}")
        return roles

    def valve_of(self, loop: str) -> str | None:
        """The first block with a ``position`` output downstream of the loop's output along
        the wires, through the blocks that pass a signal on (compensators, calculations, a
        relay) and not through a process, a sensor, a load or another controller: a loop
        whose output feeds a process that another loop's valve follows drives no valve (it
        got that loop's valve figures: a cascade primary its secondary's), or None."""
        from loopworks.sim.module import downstream_valve

        return downstream_valve(loop, self.wires, self.kinds, set(self.controllers()),
                                lambda name: f"{name}.position" in self.values)

    def working_sp(self, loop: str) -> np.ndarray:
        """The setpoint a controller worked to: its ``working_sp`` role's output when it has
        one (deltav.pid), else ``cas_sp`` in the scans its ``mode`` was CAS (code 2, the
        generic pid), else its SP input."""
        roles = self._roles_of(loop)
        if roles.working_sp is not None:
            return self.values[f"{loop}.{roles.working_sp}"]
        sp = self[f"{loop}.{roles.sp}"]
        if f"{loop}.cas_sp" in self.values and f"{loop}.mode" in self.values:
            return np.where(self.values[f"{loop}.mode"] == 2.0, self.values[f"{loop}.cas_sp"],
                            sp)
        return sp

    def to_pandas(self) -> Any:
        """A pandas DataFrame indexed by ``t`` (s), with a ``NAME.ST`` column per signal.
        pandas is optional: ``pip install loopworks[pandas]``."""
        try:
            import pandas as pd
        except ImportError:
            raise ImportError("to_pandas() needs pandas: pip install pandas") from None
        data: dict[str, np.ndarray] = {}
        for name, v in self.values.items():
            data[name] = v
            data[f"{name}.ST"] = self.status[name]
        return pd.DataFrame(data, index=pd.Index(self.t, name="t"))

    def to_csv(self, path: str | Path) -> None:
        """Write ``t``, every signal and its ``.ST`` status column: a value as ``repr`` writes
        it (it reads back as the same double), a status as an integer. Compiled, the rows are
        formatted by :func:`loopworks.sim.floatfmt.format_rows` (the same text, bit for bit,
        as ``csv.writer``); interpreted (``LOOPWORKS_JIT=0``), by ``csv.writer``."""
        from loopworks.blocks.kernel import jit_enabled

        names = list(self.values)
        n = len(self.t)
        t = np.asarray(self.t, dtype=np.float64)
        values = np.empty((n, len(names)))
        stats = np.empty((n, len(names)), dtype=np.int64)
        for j, name in enumerate(names):
            values[:, j] = self.values[name]
            stats[:, j] = self.status[name]
        with open(path, "w", newline="") as fh:
            csv.writer(fh, lineterminator="\n").writerow(
                ["t", *names, *(f"{n}.ST" for n in names)])
            if jit_enabled() and n > 0:
                from loopworks.sim.floatfmt import format_rows

                fh.flush()
                fh.buffer.write(format_rows(t, values, stats).tobytes())
                return
            body = np.concatenate([t[:, None], values], axis=1).tolist()
            csv.writer(fh, lineterminator="\n").writerows(
                b + s for b, s in zip(body, stats.tolist(), strict=True))

    def plot(self, signals: list[str] | None = None, ax: Any = None) -> Any:
        """Plot signals against time; by default one panel per block with its outputs.

        Returns the matplotlib Axes (a list when several panels are drawn)."""
        import matplotlib.pyplot as plt

        if signals is not None or ax is not None:
            if ax is None:
                _, ax = plt.subplots(figsize=(9, 4))
            for name in signals or self.names:
                ax.plot(self.t, self[name], label=name)
            ax.set_xlabel("t (s)")
            ax.legend(loc="best")
            ax.grid(True, alpha=0.3)
            return ax
        groups = self._panels()
        fig, axes = plt.subplots(len(groups), 1, sharex=True, figsize=(9, 2.6 * len(groups)),
                                 squeeze=False)
        for a, (title, names) in zip(axes[:, 0], groups, strict=True):
            for name in names:
                a.plot(self.t, self.values[name], label=name)
            a.set_title(title, fontsize=10)
            a.legend(loc="best", fontsize=8)
            a.grid(True, alpha=0.3)
        axes[-1, 0].set_xlabel("t (s)")
        fig.tight_layout()
        return list(axes[:, 0])

    def _panels(self) -> list[tuple[str, list[str]]]:
        """Controllers get an SP/PV panel and an OUT panel; other blocks their outputs."""
        from loopworks.catalog import block_class

        panels: list[tuple[str, list[str]]] = []
        for name, kind in self.kinds.items():
            outs = [p.name for p in block_class(kind).OUTPUTS]
            roles = self.roles(name)
            if roles is not None:
                panels.append((f"{name} ({kind}): setpoint and PV",
                               [f"{name}.{roles.sp}", f"{name}.{roles.pv}"]))
                panels.append((f"{name} ({kind}): output", [f"{name}.{roles.out}"]))
            else:
                panels.append((f"{name} ({kind})", [f"{name}.{o}" for o in outs]))
        return panels

    def _repr_html_(self) -> str:
        return (f"<b>SimResult</b>: {len(self.t)} scans, t = {self.t[0]:g}..{self.t[-1]:g} s, "
                f"blocks {', '.join(f'{n} ({k})' for n, k in self.kinds.items())}")
