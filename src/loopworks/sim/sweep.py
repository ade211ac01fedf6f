r"""Parameter sweeps: many instances of a scenario's loop, each with its own parameter values
and noise, scored by the loop metrics (issue 14).

Varied names and specs (``loopworks sweep SCENARIO --vary NAME=SPEC``): NAME is
``block.parameter`` or ``block.input`` (an input's constant), SPEC one of

==================  ===========================================================
``a:b:n``           n values from a to b, evenly spaced (grid)
``v1,v2,v3``        a list of numbers or names (grid)
``uniform(a,b)``    sampled: a + (b - a)·u
``loguniform(a,b)`` sampled: exp(ln a + (ln b - ln a)·u), 0 < a < b
``normal(m,s)``     sampled: m + s·Φ⁻¹(u)
``choice(v1,v2)``   sampled: v_⌊k·u⌋ of the k values
==================  ===========================================================

Lists and ranges form a full grid. The distributions are sampled ``samples`` times by a seeded
Latin hypercube (McKay, Beckman & Conover 1979, Technometrics 21(2)): each distribution's u in
[0, 1) is cut into ``samples`` equal strata, one uniform draw in each, the strata in a random
order independently per distribution, and the value is the distribution's inverse CDF at u.
With both, every grid point runs with every sample: grid × samples points.

Instances: every point runs in every ``[compare]`` variant (or the one named). Point i has the
seed s_i = ``mix_seed(sweep seed, i)`` (:func:`loopworks.plant.sensor.mix_seed`) and runs as the
scenario would with ``[simulation] seed = s_i``: each noisy block draws from
``mix_seed(its seed, s_i)``, so points are independent, the variants of one point share their
noise (as ``simulate``'s variants do), and a row of the results is reproduced by
``loopworks simulate`` with that seed and those values. The scenario's ``[autotune]`` relay
test runs for every point, before the sweep, on the scenario with the point's values (as
``simulate`` of that point runs it: with them, then ``[autotune] set``; it uses no run seed,
so once per distinct point), and its process gain goes into the point's instances and the
results (a column named after each ``process_gain`` target); varying a target is refused.
Metrics are those of ``simulate`` over the scenario's
``metrics_window``, for every controller of the module.

Execution: a process parses the scenario text once; the instances of one variant (and one
value of each parameter that sizes a block's state) run as one batch
(:mod:`loopworks.sim.batch`): one compiled call scans all of a chunk's instances, in parallel
over the cores, recording only the signals the metrics read (``Module.metric_signals``), and
the chunk's metrics are computed at once (:func:`loopworks.sim.metrics.loop_metrics` on N
rows). A chunk's record is bounded by ``CHUNK_BYTES``; only the metrics are kept, so memory
grows with the instances' metrics, not their trajectories.
"""

from __future__ import annotations

import math
import os
import re
import statistics
import time
import warnings
from collections.abc import Callable, Iterable, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from contextlib import suppress
from dataclasses import dataclass, field, replace
from itertools import product
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import numpy as np

from loopworks.errors import InputError, LoopworksError
from loopworks.sim.module import scan_count
from loopworks.sim.result import SimResult

Value = float | int | str

#: ``workers="auto"`` (the CLI's default) runs a sweep of at least this many instances in
#: one process per core, at most :data:`AUTO_WORKERS`, and smaller ones in this process.
#: Each instance's row and metrics are made in Python (about 0.1-0.2 ms), which one process
#: does on one core while its batch's scans use every core; a process takes about 2 s to
#: start and load its plans [measured 2026-12-08 on 2 cores, pid + fopdt, 1,000 scans per
#: instance, wall time of one process against two: 4,000 instances 1.0 s against 1.9 s,
#: 10,000 2.3-2.4 s against 2.8-3.0 s, 40,000 9.1-9.7 s against 6.4-7.1 s]
AUTO_WORKERS_INSTANCES = 50_000
#: the most processes ``"auto"`` starts (each holds its own copy of numba and the plans,
#: about 170 MB)
AUTO_WORKERS = 4

_RANGE = re.compile(r"^\s*([^:]+):([^:]+):([^:]+)\s*$")
_CALL = re.compile(r"^\s*([a-z]+)\s*\((.*)\)\s*$", re.IGNORECASE)
DISTRIBUTIONS = ("uniform", "loguniform", "normal", "choice")
#: the most instances a sweep runs (points × variants) [ours: ten million instances of the
#: smallest loop take an hour on two cores; a grid of 1e20 values or 1e13 samples is a typo,
#: and was a traceback from numpy, out of memory]
MAX_INSTANCES = 10_000_000


@dataclass(frozen=True)
class Axis:
    """One varied name: grid ``values``, or a sampled ``distribution`` with its ``args``."""

    name: str
    values: tuple[Value, ...] = ()
    distribution: str = ""
    args: tuple[Value, ...] = ()

    @property
    def sampled(self) -> bool:
        return bool(self.distribution)

    def at(self, u: float) -> Value:
        """The distribution's value at u in [0, 1) (its inverse CDF)."""
        kind, args = self.distribution, self.args
        if kind == "choice":
            return args[min(int(u * len(args)), len(args) - 1)]
        a, b = float(args[0]), float(args[1])
        if kind == "uniform":
            return a + (b - a) * u
        if kind == "loguniform":
            return math.exp(math.log(a) + (math.log(b) - math.log(a)) * u)
        return a + b * statistics.NormalDist().inv_cdf(min(max(u, 1e-12), 1.0 - 1e-12))


def _number(text: str, where: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"{where}: '{text.strip()}' is not a number") from None
    if not math.isfinite(value):
        raise InputError(f"{where}: '{text.strip()}' is not a finite number")
    return value


def _item(text: str) -> Value:
    """A list item: an int, a float, else a name (a mode, a choice)."""
    t = text.strip()
    for cast in (int, float):
        with suppress(ValueError):  # not this type: try the next, else it is a name
            return cast(t)
    return t


def _decimal(value: float) -> float:
    """A grid value as the decimal it stands for: linspace's rounding (1:2:11 gave
    1.7000000000000002, shown so in the results) taken off at 15 significant digits, the
    most a double keeps for every decimal."""
    return float(f"{value:.15g}")


def parse_vary(text: str) -> Axis:
    """``NAME=SPEC`` as an :class:`Axis`; an InputError that quotes it and says what was
    expected."""
    name, sep, spec = text.partition("=")
    name, spec = name.strip(), spec.strip()
    where = f"--vary {text}"
    if not sep or "." not in name or not spec:
        raise InputError(f"{where}: expected NAME=SPEC with NAME block.parameter or "
                         "block.input, SPEC a:b:n, v1,v2,..., uniform(a,b), loguniform(a,b), "
                         "normal(m,s) or choice(v1,v2,...)")
    call = _CALL.match(spec)
    if call:
        kind, inner = call.group(1).lower(), call.group(2)
        parts = [p for p in inner.split(",")]
        if kind not in DISTRIBUTIONS:
            raise InputError(f"{where}: unknown distribution '{call.group(1)}': expected one "
                             "of " + ", ".join(DISTRIBUTIONS))
        if kind == "choice":
            if not inner.strip():
                raise InputError(f"{where}: choice() needs at least one value")
            items = tuple(_item(p) for p in parts)
            if any(v == "" for v in items):
                raise InputError(f"{where}: an empty value in choice()")
            return Axis(name, distribution=kind, args=items)
        if len(parts) != 2:
            raise InputError(f"{where}: {kind}() takes two numbers, got {len(parts)}")
        a, b = (_number(p, where) for p in parts)
        if kind in ("uniform", "loguniform") and not a < b:
            raise InputError(f"{where}: {kind}(a, b) needs a < b, got a = {a:g}, b = {b:g}")
        if kind == "loguniform" and not a > 0.0:
            raise InputError(f"{where}: loguniform(a, b) needs 0 < a, got a = {a:g}")
        if kind == "normal" and not b > 0.0:
            raise InputError(f"{where}: normal(m, s) needs s > 0, got s = {b:g}")
        return Axis(name, distribution=kind, args=(a, b))
    grid = _RANGE.match(spec)
    if grid:
        a, b = _number(grid.group(1), where), _number(grid.group(2), where)
        n_text = grid.group(3).strip()
        try:
            n_value = float(n_text)
        except ValueError:
            n_value = math.nan
        if not (math.isfinite(n_value) and n_value >= 1 and n_value.is_integer()):  # 3, 3.0
            raise InputError(f"{where}: in a:b:n, n = '{n_text}' must be a whole number >= 1")
        n = int(n_value)
        if n > MAX_INSTANCES:
            raise InputError(f"{where}: n = {n_text} values: a sweep runs at most "
                             f"{MAX_INSTANCES:,} instances")
        if n == 1 and a != b:
            raise InputError(f"{where}: a:b:1 is one value, a = {a:g}, and drops b = {b:g}: "
                             "give n >= 2, or the one value")
        if n == 1:
            return Axis(name, values=(a,))
        # the ends as given (a, b), the values between them as the decimals they stand for
        inner = [_decimal(float(v)) for v in np.linspace(a, b, n)[1:-1]]
        values = (a, *inner, b)
        if len(set(values)) < n:
            raise InputError(f"{where}: {n} values from {a!r} to {b!r} are not all different "
                             f"in floating point: give fewer values or a wider range")
        return Axis(name, values=values)
    if ":" in spec:
        raise InputError(f"{where}: a range is a:b:n, three parts (n values from a to b), "
                         f"not '{spec}'")
    items = tuple(_item(p) for p in spec.split(","))
    if any(v == "" for v in items):
        raise InputError(f"{where}: an empty value in the list")
    return Axis(name, values=items)


def latin_hypercube(n: int, d: int, rng: np.random.Generator) -> np.ndarray:
    """n × d points in [0, 1)^d, one in each of the n strata of every dimension (module
    docstring)."""
    u = np.empty((n, d))
    for j in range(d):
        u[:, j] = (rng.permutation(n) + rng.random(n)) / n
    return u


def design(axes: Sequence[Axis], samples: int, seed: int) -> list[dict[str, Value]]:
    """The points of a sweep: the grid of the grid axes, each with every Latin-hypercube sample
    of the sampled axes (``samples`` of them; one point when there are none)."""
    grid_axes = [a for a in axes if not a.sampled]
    dist_axes = [a for a in axes if a.sampled]
    if dist_axes and samples < 1:
        raise InputError(f"--samples {samples}: the distributions need at least 1 sample")
    draws: list[dict[str, Value]] = [{}]
    if dist_axes:
        # any integer is a seed (a scenario's may be negative): modulo 2**64, as mix_seed
        # takes it, numpy's generator needs one >= 0
        u = latin_hypercube(samples, len(dist_axes), np.random.default_rng(seed % 2**64))
        draws = [{a.name: a.at(float(u[i, j])) for j, a in enumerate(dist_axes)}
                 for i in range(samples)]
    points: list[dict[str, Value]] = []
    for combo in product(*(a.values for a in grid_axes)):
        fixed = {a.name: v for a, v in zip(grid_axes, combo, strict=True)}
        points.extend({**fixed, **draw} for draw in draws)
    return points


# -- running ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Job:
    """One instance: its point number, variant, changes (varied values and the autotune's
    gain) and seed."""

    point: int
    variant: str
    changes: dict[str, Value]
    seed: int


_CACHE: dict[tuple[str, str], Any] = {}


def _scenario(text: str, source: str) -> Any:
    """The parsed scenario, once per process."""
    from loopworks.sim.scenario import parse_scenario

    key = (text, source)
    if key not in _CACHE:
        _CACHE.clear()
        _CACHE[key] = parse_scenario(text, source)
    return _CACHE[key]


#: the most a batch's record may hold at once (bytes): instances run in chunks this bounds
CHUNK_BYTES = 64 * 1024**2


def _metrics(result: SimResult, window: tuple[float, float] | None) -> list[dict[str, float]]:
    """Every metric of every loop (``"loop: metric"`` when there are several loops) of each
    instance of ``result``: one instance (1-D records) or N (N × scans records)."""
    loops = result.controllers()
    columns: dict[str, np.ndarray] = {}
    for loop in loops:
        for name, value in result.metrics(loop, window=window).items():
            columns[name if len(loops) == 1 else f"{loop}: {name}"] = np.atleast_1d(value)
    if not columns:
        return []
    names = list(columns)
    values = zip(*(np.asarray(col, dtype=np.float64).tolist() for col in columns.values()),
                 strict=True)
    return [dict(zip(names, row, strict=True)) for row in values]


def metric_columns(sc: Any) -> list[str]:
    """The metric columns a sweep of scenario ``sc`` has (:func:`_metrics`' names, over
    every variant: a valve's metrics only where a loop has a valve), from a run of a few
    scans of each variant, so that a ``--metric`` the scenario lacks is refused before the
    sweep runs (found by an outside audit: after every instance had run, nothing written)."""
    names: dict[str, None] = {}
    for module in sc.variants.values():
        for name in _metrics(module.run(4 * sc.dt, sc.dt), None)[0]:
            names[name] = None
    return list(names)


_TEMPLATES: dict[tuple[str, str, str, tuple[tuple[str, Value], ...]], Any] = {}


def _template(sc: Any, variant: str, key: tuple[tuple[str, Value], ...]) -> Any:
    """The batch (:class:`loopworks.sim.batch.Batch`) of ``variant`` with the state-sizing
    values ``key``, recording what the metrics read; made once per process and scenario."""
    from loopworks.sim.batch import Batch

    at = (sc.text, sc.source, variant, key)
    if at not in _TEMPLATES:
        if len(_TEMPLATES) > 64:
            _TEMPLATES.clear()
        module = sc.template(variant, dict(key))
        _TEMPLATES[at] = Batch(module, module.metric_signals(), check=False)
    return _TEMPLATES[at]


def _refused(job: Job, exc: LoopworksError) -> InputError:
    values = ", ".join(f"{k} = {v!r}" for k, v in job.changes.items())
    return InputError(f"instance {job.point} ({job.variant}; {values}): {exc}")


def run_jobs(text: str, source: str, jobs: Sequence[Job], plan: str = "auto",
             total: int | None = None) -> list[dict[str, float]]:
    """The metrics of each job's instance (``{"loop: metric" or "metric": value}``), in job
    order: the instances of one variant (and one value of each parameter that sizes a block's
    state) run as one batch (:mod:`loopworks.sim.batch`), in chunks whose record fits in
    ``CHUNK_BYTES``; interpreted (``LOOPWORKS_JIT=0``), one module per instance. ``plan``
    and ``total`` (the sweep's instances, of which these jobs are a part) choose the batch's
    plan (:meth:`loopworks.sim.batch.Batch.run`)."""
    from loopworks.sim.batch import InstanceError, fixed_names

    sc = _scenario(text, source)
    rows: list[dict[str, float]] = [{} for _ in jobs]
    groups: dict[tuple[str, tuple[tuple[str, Value], ...]], list[int]] = {}
    names = list(dict.fromkeys(name for job in jobs for name in job.changes))
    fixed: dict[str, list[str]] = {}
    for k, job in enumerate(jobs):
        if job.variant not in fixed:
            fixed[job.variant] = fixed_names(_template(sc, job.variant, ()).module, names)
        key = tuple((n, job.changes[n]) for n in fixed[job.variant] if n in job.changes)
        groups.setdefault((job.variant, key), []).append(k)
    n = scan_count(sc.duration, sc.dt)
    t = np.arange(n) * sc.dt
    for (variant, key), members in groups.items():
        try:
            batch = _template(sc, variant, key)
        except LoopworksError as exc:
            raise _refused(jobs[members[0]], exc) from None
        template = batch.module
        record = template.metric_signals()
        info: dict[str, Any] = {"kinds": {b: template.blocks[b].kind for b in template.order},
                                "wires": dict(template.wires),
                                "incremental": template.incremental_outputs()}
        if not template.compiled:  # interpreted: one module per instance
            for k in members:
                job = jobs[k]
                try:
                    module = sc.build(job.variant, job.changes, job.seed)
                    result = module.run(sc.duration, sc.dt, record=record)
                except LoopworksError as exc:
                    raise _refused(job, exc) from None
                rows[k] = _metrics(result, sc.metrics_window)[0]
            continue
        size = max(1, CHUNK_BYTES // max(1, len(record) * n * 9))  # a value and a status
        for at in range(0, len(members), size):
            chunk = members[at:at + size]
            try:
                batch.load([jobs[k].changes for k in chunk], [jobs[k].seed for k in chunk],
                           dt=sc.dt)
            except InstanceError as exc:
                raise _refused(jobs[chunk[exc.index]], exc) from None
            R, RS = batch.run(sc.duration, sc.dt, plan,
                              len(jobs) if total is None else total)
            # the instances whose controllers' outputs are increments alike (a swept S5
            # velocity) are scored together, each with its output span (a swept OUT_SCALE)
            kinds: dict[frozenset[str], list[int]] = {}
            for i, k in enumerate(chunk):
                kinds.setdefault(template.incremental_outputs(jobs[k].changes), []).append(i)
            for incremental, at_ in kinds.items():
                # every instance alike (the usual case): views, not copies of the record
                sel = slice(None) if len(at_) == len(chunk) else np.asarray(at_)
                values = {name: R[sel, j] for j, name in enumerate(record)}
                status = {name: RS[sel, j] for j, name in enumerate(record)}
                info["incremental"] = incremental
                info["out_spans"] = template.out_spans([jobs[chunk[i]].changes for i in at_])
                for i, row in zip(at_, _metrics(SimResult(t, values, status, **info),
                                                sc.metrics_window), strict=True):
                    rows[chunk[i]] = row
    return rows


@dataclass
class SweepResult:
    """One row per instance: ``columns`` (variant, point, seed, the varied names, then every
    metric of every loop), as equal-length lists; ``varied`` the varied names; ``design``:
    "grid", "monte carlo" or "grid × monte carlo"; ``seconds`` the run's wall time."""

    columns: dict[str, list[Any]]
    varied: list[str]
    design: str
    grid_shape: tuple[int, ...] = ()
    seconds: float = 0.0
    metrics: list[str] = field(default_factory=list)
    #: the full trajectories asked for (``sweep(trajectories=[point, ...])``), by
    #: (variant, point): every signal of that instance's run
    trajectories: dict[tuple[str, int], SimResult] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.columns["variant"])

    def to_arrow(self) -> Any:
        """A pyarrow Table of the rows; a metric with no value (n/a, NaN here) is null, as in
        ``metrics.json`` (an empty field in ``results.csv``)."""
        import pyarrow as pa

        def column(values: list[Any]) -> Any:  # a metric n/a in every row stays a double
            floats = bool(values) and all(isinstance(v, float) for v in values)
            return pa.array(values, from_pandas=True, type=pa.float64() if floats else None)

        return pa.table({name: column(values) for name, values in self.columns.items()})

    def to_pandas(self) -> Any:
        """A pandas DataFrame of the rows (pandas is optional: ``pip install pandas``)."""
        try:
            import pandas  # noqa: F401
        except ImportError:
            raise ImportError("to_pandas() needs pandas: pip install pandas") from None
        return self.to_arrow().to_pandas()

    def best(self, metric: str, *, largest: bool = False) -> dict[str, Any]:
        """The row with the smallest (``largest``: the largest) finite ``metric``; a signed
        one (``metrics.SIGNED``: final error, step size) by its size, |value| (the smallest
        final error was the most negative, the largest error of the sweep)."""
        from loopworks.sim.metrics import SIGNED

        if metric not in self.columns:
            raise KeyError(f"no metric '{metric}'; metrics: {', '.join(self.metrics)}")
        size = metric.rpartition(": ")[2] in SIGNED  # "loop: final error" too
        values = [(abs(v) if size else v) if isinstance(v, float) and math.isfinite(v)
                  else math.nan for v in self.columns[metric]]
        finite = [i for i, v in enumerate(values) if not math.isnan(v)]
        if not finite:
            raise KeyError(f"'{metric}' is n/a in every instance")
        pick = (max if largest else min)(finite, key=lambda i: values[i])
        return {k: col[pick] for k, col in self.columns.items()}

    def plot(self, metric: str | None = None, directory: str | Path | None = None
             ) -> list[Path]:
        """The summary figures (:mod:`loopworks.sim.sweep_report`), written to ``directory``
        (default: the current directory); returns their paths."""
        from loopworks.sim.sweep_report import figures

        return figures(self, Path(directory) if directory is not None else Path("."), metric)


def sweep(scenario: str | Path | None, vary: Mapping[str, Any] | Iterable[str] | str, *,
          samples: int = 100, seed: int | None = None, variant: str | None = None,
          workers: int | str | None = None, scheduler: str | None = None,
          progress: Callable[[int, int], None] | None = None,
          trajectories: Sequence[int] = (),
          relay_progress: Callable[[int, int], None] | None = None,
          plan: str = "auto") -> SweepResult:
    """Sweep ``scenario`` (a TOML path; None: the built-in one) over ``vary`` (``{name: spec}``
    or ``["name=spec", ...]``, module docstring): ``samples`` Latin-hypercube samples of the
    distributions, ``seed`` (default: the scenario's ``[simulation] seed``, else 0), every
    ``[compare]`` variant or only ``variant``, in ``workers`` processes (default: one, whose
    compiled batch runs on every core; ``"auto"``, the CLI's default: one per core, at most
    :data:`AUTO_WORKERS`, for a sweep of :data:`AUTO_WORKERS_INSTANCES` instances or more) or
    on the Dask scheduler at ``scheduler``.
    ``progress(done, total)`` is called as instances finish, ``relay_progress(done, total)``
    as the points' ``[autotune]`` relay tests do (before them). ``trajectories``: points whose
    full runs (every signal, in every swept variant) the result keeps in ``.trajectories``
    (the rest keep only their metrics). ``plan``: the batches' compiled plan, ``"auto"``,
    ``"compiled"`` or ``"fused"`` (:meth:`loopworks.sim.batch.Batch.run`: ``"fused"``
    inlines every kernel, compiled once per module shape and cached, and runs the scans in
    about half the time; ``"auto"`` takes it when it is cached or the sweep is long enough
    to pay for compiling it). Every name and value is checked before anything runs."""
    from loopworks.sim.scenario import load_scenario, split_ref

    texts = ([f"{k}=" + (",".join(map(str, v)) if isinstance(v, list | tuple) else str(v))
              for k, v in vary.items()] if isinstance(vary, Mapping)
             else [vary] if isinstance(vary, str) else list(vary))  # one "NAME=SPEC" too
    if not texts:
        raise InputError("nothing to vary: give at least one --vary NAME=SPEC")
    if plan not in ("auto", "compiled", "fused"):
        raise InputError(f"plan = {plan!r} is not allowed: expected auto, compiled or fused")
    for what, number in (("samples", samples), ("workers", workers)):
        if what == "workers" and (number is None or number == "auto"):
            continue
        if isinstance(number, bool) or not isinstance(number, int | np.integer):
            raise InputError(f"--{what} {number!r}: expected a whole number >= 1")
    axes = [parse_vary(t) for t in texts]
    axes = [replace(a, name=".".join(split_ref(a.name))) for a in axes]  # the column name
    names = [a.name for a in axes]
    if len(set(names)) != len(names):
        twice = next(n for n in names if names.count(n) > 1)
        given = [t for t, a in zip(texts, axes, strict=True) if a.name == twice]
        raise InputError(f"--vary {twice} is given twice ({'; '.join(given)}): vary each "
                         "name once")
    if scheduler is not None:
        from loopworks.sim.cluster import check_address

        check_address(scheduler)
        if workers is not None and workers != "auto":
            raise InputError(f"--workers {workers} with --scheduler: give one of them (a "
                             "--scheduler sweep runs on the cluster's workers)")
    sc = load_scenario(scenario)
    variants = list(sc.variants)
    if variant is not None:
        if variant not in sc.variants:
            raise InputError(f"--variant '{variant}': no such variant; variants: "
                             + ", ".join(variants))
        variants = [variant]
    for k, axis in enumerate(axes):
        _check_axis(sc, axis, variants)
        _check_whole(sc, axis, variants)
        axis = axes[k] = _typed(sc, axis, variants)
        for value, inside, what in _support(axis):
            try:  # just inside an end: an end on a bound the parameter excludes is fine
                _check_value(sc, axis.name, value if inside is None else inside, variants,
                             what)
            except InputError:
                _check_value(sc, axis.name, value, variants, what)  # the end's own error
                raise
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int | np.integer)):
        raise InputError(f"--seed {seed!r}: expected a whole number")
    sweep_seed = (sc.seed if sc.seed is not None else 0) if seed is None else int(seed)
    count = math.prod(len(a.values) for a in axes if not a.sampled)
    count *= len(variants) * (samples if any(a.sampled for a in axes) else 1)
    if count > MAX_INSTANCES:
        raise InputError(f"the sweep would run {count:,} instances (grid × samples × "
                         f"variants): at most {MAX_INSTANCES:,}")
    points = design(axes, samples, sweep_seed)
    for i, point in enumerate(points):
        for name, value in point.items():
            _check_value(sc, name, value, variants, f"instance {i}")
    _check_points(sc, points, names, variants)
    from loopworks.plant.sensor import mix_seed

    seeds = [mix_seed(sweep_seed, i) for i in range(len(points))]
    tuned, untuned = _autotune_points(sc, points, names, relay_progress, seeds)

    for keep in trajectories:
        if not (isinstance(keep, int | np.integer) and not isinstance(keep, bool)
                and 0 <= keep < len(points)):
            raise InputError(f"--trajectory {keep}: no such point; points are 0 to "
                             f"{len(points) - 1}")
    jobs = [Job(i, v, {**point, **tuned[i]}, seeds[i])
            for v in variants for i, point in enumerate(points)]
    runnable = [k for k, job in enumerate(jobs) if job.point not in untuned]
    start = time.perf_counter()
    ran = _execute(sc.text, sc.source, [jobs[k] for k in runnable], workers, scheduler,
                   progress, plan)
    seconds = time.perf_counter() - start
    metrics: list[dict[str, float]] = [{} for _ in jobs]  # n/a where the relay test failed
    for k, row in zip(runnable, ran, strict=True):
        metrics[k] = row
    metric_names = list(dict.fromkeys(k for row in metrics for k in row))
    columns: dict[str, list[Any]] = {"variant": [j.variant for j in jobs],
                                     "point": [j.point for j in jobs],
                                     "seed": [j.seed for j in jobs]}
    for name in names + list(tuned[0] if tuned else {}):  # varied, then [autotune]'s
        values = [j.changes[name] for j in jobs]
        if any(isinstance(v, str) for v in values):  # a choice input's names and codes mixed
            values = [v if isinstance(v, str) else f"{v:g}" for v in values]
        columns[name] = values
    if untuned:
        columns[AUTOTUNE_ERROR] = [untuned.get(j.point) for j in jobs]
    for m in metric_names:
        columns[m] = [row.get(m, math.nan) for row in metrics]
    grid_axes = [a for a in axes if not a.sampled]
    kind = ("grid" if not any(a.sampled for a in axes) else
            "monte carlo" if not grid_axes else "grid × monte carlo")
    kept: dict[tuple[str, int], SimResult] = {}
    for keep in trajectories:
        if keep in untuned:  # no gain to run it with: its row says why
            continue
        for v in variants:
            job = next(j for j in jobs if j.variant == v and j.point == keep)
            kept[(v, keep)] = sc.build(v, job.changes, job.seed).run(sc.duration, sc.dt)
    return SweepResult(columns, names, kind, tuple(len(a.values) for a in grid_axes),
                       seconds, metric_names, kept)


#: the results column that says why a point's ``[autotune]`` relay test gave no gain (null
#: for the points whose test did); present only when a test failed
AUTOTUNE_ERROR = "autotune_error"


def _autotune_points(sc: Any, points: Sequence[Mapping[str, Value]], names: Sequence[str],
                     progress: Callable[[int, int], None] | None = None,
                     seeds: Sequence[int | None] | None = None
                     ) -> tuple[list[dict[str, Value]], dict[int, str]]:
    """Per point, the ``[autotune]`` parameters with the gain its own relay test identifies
    (the scenario with the point's values, then ``[autotune] set``, and the point's run seed
    ``seeds[i]``, as ``simulate`` of that point with that ``[simulation] seed`` would run it);
    empty dicts without ``[autotune]``. Varying a parameter ``[autotune]`` writes is refused (the
    test would overwrite the value, as in ``simulate``).

    A point whose test identifies no gain (a relay that did not converge on that valve) gets
    NaN and is returned in the second value, point -> the test's error: its instances do
    not run (``simulate`` of the point fails alike), their metrics are n/a, and one warning
    counts them. A whole sweep failed on one such point of a Monte Carlo before (the
    built-in scenario's valve.resolution = 0.2637 of uniform(0.2, 0.8)). When every point
    fails, the first one's error is raised."""
    from loopworks.sim.scenario import autotune_gain, split_ref

    if sc.autotune_test is None:
        return [{} for _ in points], {}
    targets = [".".join(split_ref(ref)) for ref in sc._model.autotune.process_gain]
    for name in names:
        if name in targets:
            raise InputError(f"--vary {name}: [autotune] writes this parameter from its relay "
                             f"test (as simulate does, it would overwrite each value); remove "
                             "[autotune] from the scenario to vary it")
    gains: dict[tuple[tuple[str, Value | None], ...], float | str] = {}
    out: list[dict[str, Value]] = []
    failed: dict[int, str] = {}
    seeds = [None] * len(points) if seeds is None else list(seeds)
    for i, point in enumerate(points):
        key = (*sorted(point.items()), ("seed", seeds[i]))
        if key not in gains:
            try:
                gains[key] = autotune_gain(sc, point, seed=seeds[i])[0]
            except LoopworksError as exc:
                gains[key] = str(exc)
        gain = gains[key]
        if isinstance(gain, str):
            failed[i] = gain
            gain = math.nan
        out.append({t: gain for t in targets})
        if progress is not None:
            progress(i + 1, len(points))
    if failed:
        first = min(failed)
        values = ", ".join(f"{k} = {v!r}" for k, v in points[first].items())
        if len(failed) == len(points):
            raise InputError(f"point {first} ({values}): {failed[first]}")
        warnings.warn(f"{len(failed)} of {len(points)} points' [autotune] relay tests "
                      f"identified no process gain; their instances did not run and their "
                      f"metrics are n/a (column {AUTOTUNE_ERROR}). The first, point {first} "
                      f"({values}): {failed[first]}", stacklevel=2)
    return out, failed


def _check_points(sc: Any, points: Sequence[Mapping[str, Value]], names: Sequence[str],
                  variants: list[str]) -> None:
    """Every point's values together, in every swept variant, before anything runs: each
    block's parameters as the point sets them are the block's own ``set_params`` check (a
    range, a combination such as out_lo < out_hi, a transfer function's text), on a template
    set back after each point; a point that changes a parameter sizing a block's state (a
    delay line) builds its module. An InputError names the point and its values (found by
    an outside audit: a combination was refused only when its batch loaded, after other
    instances had run and with nothing written, or, with ``[autotune]``, taken for a relay
    test that failed, the sweep ending well)."""
    from loopworks.sim.batch import fixed_names
    from loopworks.sim.scenario import split_ref

    for variant in variants:
        module = sc.template(variant)
        fixed = set(fixed_names(module, names))
        F, S = module._F.copy(), module._S.copy()
        saved = {n: (b.given, b.params) for n, b in module.blocks.items()}
        for i, point in enumerate(points):
            per_block: dict[str, dict[str, Value]] = {}
            for name, value in point.items():
                block, param = split_ref(name)
                if param not in module.blocks[block]._in_index:  # an input: checked alone
                    per_block.setdefault(block, {})[param] = value
            try:
                if fixed & set(point):
                    sc.template(variant, dict(point))
                    continue
                for block, changes in per_block.items():
                    b = module.blocks[block]
                    try:
                        b.set_params(**changes)
                    finally:
                        b.given, b.params = saved[block]
                        module._F[:] = F
                        module._S[:] = S
            except LoopworksError as exc:
                values = ", ".join(f"{k} = {v!r}" for k, v in point.items())
                where = f" in variant '{variant}'" if len(variants) > 1 else ""
                raise InputError(f"--vary: point {i} ({values}){where}: {exc}") from None


def _check_axis(sc: Any, axis: Axis, variants: list[str]) -> None:
    """The varied name is a parameter or an input of a block of the scenario."""
    from loopworks.catalog import block_class
    from loopworks.sim.scenario import split_ref

    block, fname = split_ref(axis.name)
    tables = sc.tables[variants[0]]
    if block not in tables:
        raise InputError(f"--vary {axis.name}: no block '{block}' in {sc.source}; blocks: "
                         + ", ".join(tables))
    cls = block_class(str(tables[block]["kind"]))
    params = {p.name for p in cls.PARAMS}
    inputs = {p.name for p in cls.INPUTS}
    if fname == "kind" or fname not in params | inputs:
        raise InputError(f"--vary {axis.name}: '{fname}' is not a parameter or input of "
                         f"{block} ({cls.kind}); parameters: {', '.join(sorted(params))}; "
                         f"inputs: {', '.join(sorted(inputs))}")
    if fname in inputs and fname not in params:
        for v in variants:
            source = sc.variants[v].wires.get(f"{block}.{fname}")
            if source is not None:
                raise InputError(f"--vary {axis.name}: the input is wired from '{source}'"
                                 + (f" in variant '{v}'" if len(variants) > 1 else "")
                                 + ": an input takes a wire or a constant, not both")


def _check_whole(sc: Any, axis: Axis, variants: list[str]) -> None:
    """InputError when a continuous distribution is drawn for a whole-number parameter (an S5
    word): its draws are fractions (uniform(400, 600) on s5.k was refused as "s5.k =
    400.0000002 must be an integer"; found by an outside audit)."""
    if axis.distribution not in ("uniform", "loguniform", "normal"):
        return
    from loopworks.catalog import block_class
    from loopworks.sim.scenario import split_ref

    block, fname = split_ref(axis.name)
    cls = block_class(str(sc.tables[variants[0]][block]["kind"]))
    spec = next((p for p in cls.PARAMS if p.name == fname), None)
    if spec is not None and spec.type == "int":
        raise InputError(f"--vary {axis.name}: {axis.distribution}() draws fractional values, "
                         f"and {axis.name} is a whole number ({spec.range_text()}): give a "
                         "list, a:b:n with whole steps, or choice(v1, v2, ...)")


def _typed(sc: Any, axis: Axis, variants: list[str]) -> Axis:
    """The axis with its listed numbers of the type the parameter declares, so a column's
    type follows the parameter and not how its values were typed (``1,2`` made an int64
    column and ``1.0,2`` a float64 one, and two sweeps of one parameter had two Parquet
    schemas; found by an outside audit): a float parameter's or a numeric input's whole
    numbers become floats, an int parameter's whole floats ints, a bool parameter's true,
    yes or 1 True, a text parameter's numbers text (``process.num=2,3``: the text "2" and
    "3"). A value of another type is left for the checks to refuse."""
    from loopworks.catalog import block_class
    from loopworks.sim.scenario import split_ref

    block, fname = split_ref(axis.name)
    cls = block_class(str(sc.tables[variants[0]][block]["kind"]))
    spec = next((p for p in cls.PARAMS if p.name == fname), None)
    port = next((p for p in cls.INPUTS if p.name == fname), None)
    kind = spec.type if spec is not None else ("" if port is None or port.choices else "float")

    def cast(v: Value) -> Value:
        if kind == "bool" and spec is not None:  # true, yes, 1: one bool column
            try:
                return bool(spec.check(v))
            except LoopworksError:
                return v  # for the checks to refuse
        if isinstance(v, bool) or not isinstance(v, int | float):
            return v
        if kind == "text":  # a transfer function's "2" was read as the number 2
            return str(v)
        if kind == "float":
            return float(v)
        if kind == "int" and float(v).is_integer():
            return int(v)
        return v

    return replace(axis, values=tuple(cast(v) for v in axis.values),
                   args=tuple(cast(v) for v in axis.args) if axis.distribution == "choice"
                   else axis.args)


def _support(axis: Axis) -> list[tuple[Value, Value | None, str]]:
    """The values a sampled axis can draw that decide whether all its draws are allowed:
    (value, a value just inside it or None, where it comes from). A uniform's or a
    log-uniform's ends, with the value a billionth of the interval inside each (an end may
    sit on a bound the parameter excludes: the draws never reach it), and every choice.
    Checked before any point is drawn, so a distribution that reaches outside a
    parameter's range is refused whatever the seed (it was refused only when a draw fell
    outside). A normal reaches every value and is checked draw by draw."""
    if axis.distribution == "choice":
        return [(v, None, f"{axis.distribution}() value") for v in axis.args]
    if axis.distribution in ("uniform", "loguniform"):
        a, b = (float(v) for v in axis.args)
        spec = f"{axis.distribution}({a!r}, {b!r})"  # as given: 1.0000001 is not 1
        return [(a, axis.at(1e-9), f"{spec} reaches a"),
                (b, axis.at(1.0 - 1e-9), f"{spec} reaches b")]
    return []


def _check_value(sc: Any, name: str, value: Value, variants: list[str], where: str) -> None:
    """The value is allowed for the parameter (its range) or the input (a finite number or a
    name it takes)."""
    from loopworks.catalog import block_class
    from loopworks.sim.scenario import split_ref

    block, fname = split_ref(name)
    cls = block_class(str(sc.tables[variants[0]][block]["kind"]))
    try:
        for p in cls.PARAMS:
            if p.name == fname:
                p.check(value, cls.kind)
                return
        port = next(p for p in cls.INPUTS if p.name == fname)
        if isinstance(value, float) and not math.isfinite(value):
            raise InputError(f"{cls.kind}: input '{fname}' must be a finite number")
        port.parse(value)
    except (LoopworksError, ValueError) as exc:
        raise InputError(f"--vary {name}: {where}: {name} = {value!r}: {exc}") from None


def _chunks(jobs: Sequence[Job], size: int) -> list[list[Job]]:
    return [list(jobs[i:i + size]) for i in range(0, len(jobs), size)]


def _share_cores(threads: int) -> None:
    """A worker process's numba threads: its share of the cores."""
    import numba

    numba.set_num_threads(threads)


def _execute(text: str, source: str, jobs: Sequence[Job], workers: int | str | None,
             scheduler: str | None, progress: Callable[[int, int], None] | None,
             plan: str = "auto") -> list[dict[str, float]]:
    """Every job's metrics, in job order: in this process (one worker), in ``workers``
    processes (``"auto"``: :data:`AUTO_WORKERS_INSTANCES`), or on a Dask scheduler."""
    total = len(jobs)
    if scheduler is not None:
        from loopworks.sim.cluster import run_on_cluster

        return run_on_cluster(scheduler, text, source, jobs, progress, plan)
    cores = os.cpu_count() or 1
    if workers == "auto":
        n = min(cores, AUTO_WORKERS) if total >= AUTO_WORKERS_INSTANCES else 1
    else:  # one process by default: the batch runs on every core
        n = 1 if workers is None else int(workers)
    if n < 1:
        raise InputError(f"--workers {n}: expected a whole number >= 1")
    if n == 1 or total <= 1:
        out: list[dict[str, float]] = []
        for chunk in _chunks(jobs, max(8 * cores, total // 100)):
            out.extend(run_jobs(text, source, chunk, plan, total))
            if progress is not None:
                progress(len(out), total)
        return out
    size = max(1, min(64, total // (4 * n)))
    chunks = _chunks(jobs, size)
    results: list[list[dict[str, float]] | None] = [None] * len(chunks)
    done = 0
    with ProcessPoolExecutor(n, mp_context=get_context("spawn"), initializer=_share_cores,
                             initargs=(max(1, cores // n),)) as pool:
        futures = {pool.submit(run_jobs, text, source, chunk, plan, total): k
                   for k, chunk in enumerate(chunks)}
        try:
            for future in as_completed(futures):
                k = futures[future]
                results[k] = future.result()
                done += len(chunks[k])
                if progress is not None:
                    progress(done, total)
        except BaseException:
            pool.shutdown(cancel_futures=True)
            raise
    return [row for part in results if part is not None for row in part]
