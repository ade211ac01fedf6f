"""Batches: N instances of one module run by one compiled call (issue 14).

A batch is a template module and N instances of it that differ only in values: parameters
(``"block.parameter"``), constant inputs (``"block.input"``) and the run seed. Instance i's
buffers are row i of two arrays, ``F`` (N × the module's floats) and ``S`` (N × its ints), laid
out as the template's execution plan lays out its one buffer (:mod:`loopworks.blocks.plan`).
A row is made by applying the instance's values to the template (``set_params``: the
parameters validated and the coefficients computed once per instance; constants as
``Module`` takes them), resetting it (the start settled as :meth:`Module.reset` settles it)
and copying its buffers. The scans then run for every row in one call of the plan's ``batch``
entry: the instances in parallel over the machine's cores (``numba.prange``), each instance's
scans in one thread, recording only the signals asked for.

Events: an input event sets the same value in every row (written into the template once and
copied down its column); a parameter event is applied to each row by the block's own
``set_params`` on that row's buffers and parameters (so a bumpless retune corrects each
instance's own integral). The scans between events are one compiled call each.

A parameter that sizes a block's state (``FIXED_PARAMS``: a delay line's capacity) gives the
instances different layouts; :func:`groups` splits the instances by those values, one batch
per group.

Seeds: with a run seed s_i, every block with a ``seed`` parameter draws from
``mix_seed(its seed, s_i)`` (:func:`loopworks.plant.sensor.mix_seed`), as ``[simulation] seed``
does; its seed is the instance's value when the instance varies it, else the template's.

A batch gives the same numbers as building each instance's module and running it
(``tests/sim/test_batch.py`` checks it to 1e-12, every example scenario).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from loopworks.blocks.plan import BATCH_SIGNATURE, entry
from loopworks.errors import InputError, LoopworksError
from loopworks.sim.module import Module, _split, scan_count

Value = float | int | str


class InstanceError(InputError):
    """An instance's values were refused (a parameter out of range, a combination its block
    rejects): ``index`` is the instance's number in the batch."""

    def __init__(self, index: int, error: LoopworksError) -> None:
        super().__init__(str(error))
        self.index = index


def fixed_names(module: Module, names: Sequence[str]) -> list[str]:
    """The names among ``names`` ("block.parameter") that size a block's state, so that
    instances differing in them need different layouts (``FIXED_PARAMS``)."""
    out = []
    for name in names:
        block, param = _split(name, "varied name")
        param = param.lower()  # the block keeps its case (a [wires] name), the parameter not
        b = module.blocks.get(block)
        if b is not None and param in b.FIXED_PARAMS and param not in b._in_index:
            out.append(name)
    return out


class Batch:
    """N instances of ``module`` (the template: it is changed as rows are made), recording
    ``record`` (signals, ``"block.port"``). ``check``: refuse a module whose blocks are not
    all compiled (a batch runs only compiled)."""

    def __init__(self, module: Module, record: Sequence[str], check: bool = True) -> None:
        if check and not module.compiled:
            raise InputError("a batch needs every block compiled (LOOPWORKS_JIT=0 runs "
                             "instances one by one)")
        self.module = module
        names = module.signals()
        where = {name: i for i, name in enumerate(names)}
        unknown = [r for r in record if r not in where]
        if unknown:
            raise InputError(f"record: no signal '{unknown[0]}'; signals: " + ", ".join(names))
        self.record = list(record)
        self._rec = np.ascontiguousarray(module._rec_f[[where[r] for r in record]])
        self._rec_s = np.ascontiguousarray(module._rec_s[[where[r] for r in record]])
        #: the seed parameter of every seeded block as the template has it (its own seed)
        self.base_seeds = {n: int(b.params["seed"]) for n, b in module.blocks.items()
                           if "seed" in b.params}
        # every block's parameters as the template has them: each row starts from these
        self._given = {n: dict(b.given) for n, b in module.blocks.items()}
        self._constants = {n: dict(v) for n, v in module.constants.items()}
        self.F = np.zeros((0, module._F.shape[0]))
        self.S = np.zeros((0, module._S.shape[0]), dtype=np.int64)
        #: per row, per block a parameter event changes: (given, params) of that row
        self._params: list[dict[str, tuple[dict[str, Any], dict[str, Any]]]] = []

    # -- making rows ---------------------------------------------------------------------
    def _apply(self, changes: Mapping[str, Value], seed: int | None) -> None:
        """The template set to one instance: its blocks' parameters from the template's plus
        ``changes``, the seeds mixed with ``seed``, its constants, then reset."""
        from loopworks.plant.sensor import mix_seed

        m = self.module
        params: dict[str, dict[str, Any]] = {}
        constants = {n: dict(v) for n, v in self._constants.items()}
        for name, value in changes.items():
            block, port = _split(name, "varied name")
            port = port.lower()
            b = m.blocks[block]
            if port in b._in_index:
                constants.setdefault(block, {})[port] = value
            else:
                params.setdefault(block, {})[port] = value
        if seed is not None:
            for block, base in self.base_seeds.items():
                own = params.get(block, {}).get("seed", base)
                params.setdefault(block, {})["seed"] = mix_seed(int(own), seed)
        for name, b in m.blocks.items():
            wanted = {**self._given[name], **params.get(name, {})}
            if wanted != b.given:
                b.given = dict(self._given[name])  # set_params starts from what was given
                b.set_params(**params.get(name, {}))
        m.constants = constants
        m.reset()

    def load(self, instances: Sequence[Mapping[str, Value]],
             seeds: Sequence[int | None] | None = None, dt: float | None = None) -> None:
        """Make one row per instance (``changes``: name -> value) with its run seed; with the
        scan time ``dt``, each instance's blocks are checked to run at it (``check_dt``: a
        dead time longer than its delay line, a transfer function sampled at another rate),
        as :meth:`run` checks only the template's last instance."""
        n = len(instances)
        seeds = [None] * n if seeds is None else list(seeds)
        m = self.module
        self.F = np.empty((n, m._F.shape[0]))
        self.S = np.empty((n, m._S.shape[0]), dtype=np.int64)
        self._params = []
        targets = {_split(ev.target, "event")[0] for ev in m.events
                   if m._is_parameter(ev.target)}
        for i, (changes, seed) in enumerate(zip(instances, seeds, strict=True)):
            try:
                self._apply(changes, seed)
                if dt is not None:
                    for block in m.blocks.values():
                        block.check_dt(dt)
            except LoopworksError as exc:
                raise InstanceError(i, exc) from None
            self.F[i] = m._F
            self.S[i] = m._S
            self._params.append({b: (dict(m.blocks[b].given), dict(m.blocks[b].params))
                                 for b in targets})

    # -- running -------------------------------------------------------------------------
    def _event(self, index: int) -> None:
        """Apply event ``index`` of the template to every row."""
        m = self.module
        ev = m.events[index]
        block, name = _split(ev.target, "event target")
        b = m.blocks[block]
        if not m._is_parameter(ev.target):
            b.set_inputs({name: ev.value})
            i = b._in_index[name.lower()]
            slot = m._slots[m.order.index(block)]
            self.F[:, slot.u0 + i] = m._F[slot.u0 + i]
            self.S[:, slot.s0 + i] = m._S[slot.s0 + i]
            return
        for row in range(self.F.shape[0]):
            m._F[:] = self.F[row]
            m._S[:] = self.S[row]
            b.given, b.params = (dict(v) for v in self._params[row][block])
            b.set_params(**{name: ev.value})
            self._params[row][block] = (dict(b.given), dict(b.params))
            self.F[row] = m._F
            self.S[row] = m._S

    def run(self, duration: float, dt: float, plan: str = "auto",
            total: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Run every row ``duration`` s in scans of ``dt`` (scan k at t = k·dt, as
        :meth:`Module.run`); returns (R, RS) with R[i, j] the record of signal ``record[j]``
        of instance i and RS[i, j] its statuses (uint8, as :class:`SimResult` keeps them: a
        Bad-status sample counts as no measurement in the metrics, as in a single run).

        ``plan``: ``"fused"`` runs the batch with every kernel inlined (``batch_fused``,
        compiled once per module shape and cached, as :meth:`Module.run`'s ``fused``), as
        ``"auto"`` does when it is cached already or when the sweep's block-scans (``total``
        instances, default these rows, × scans × blocks) reach ``PLAN_FUSE_BLOCK_SCANS``;
        ``"compiled"`` the batch that calls each kind's cached kernel. All give the same
        numbers."""
        from loopworks.blocks.plan import is_cached
        from loopworks.sim.module import PLAN_FUSE_BLOCK_SCANS

        if plan not in ("auto", "compiled", "fused"):
            raise InputError(f"plan = {plan!r} is not allowed: expected auto, compiled or "
                             "fused")
        m = self.module
        n = scan_count(duration, dt)
        work = (self.F.shape[0] if total is None else total) * n * len(m.blocks)
        fuse = plan == "fused" or (plan == "auto" and (
            work >= PLAN_FUSE_BLOCK_SCANS or is_cached(m._slots, "batch_fused")))
        m._next_event = 0
        m.check_dt(dt)  # the template's instance, and after each parameter event
        R = np.empty((self.F.shape[0], len(self.record), n))
        RS = np.empty((self.F.shape[0], len(self.record), n), dtype=np.uint8)
        if self.F.shape[0] == 0:
            return R, RS
        batch = entry(m._slots, "batch_fused" if fuse else "batch", BATCH_SIGNATURE)
        m.t, m.k, m._next_event = 0.0, 0, 0
        done = 0
        while done < n:
            while (m._next_event < len(m.events)
                   and m.events[m._next_event].t <= m.t + 1e-9):
                self._event(m._next_event)
                m._next_event += 1
            k_event = m._next_event_scan(dt)
            stop = n if k_event is None else min(n, max(done + 1, k_event))
            batch(self.F, self.S, dt, done, stop - done, R, self._rec, RS, self._rec_s, done)
            done = stop
            m.k = done
            m.t = done * dt
        return R, RS
