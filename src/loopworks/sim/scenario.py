"""Scenario files (TOML): build a :class:`~loopworks.sim.module.Module` and its run settings.

    [simulation]            dt (s), duration (s), optional order = ["process", "pid"],
                            optional metrics_window = [t0, t1] (s) for the scores, optional
                            seed: the run's seed; every block with a ``seed`` parameter
                            then draws from mix_seed(its seed, run seed), so one number
                            changes every noise stream of the run (a sweep gives each
                            instance its own; without it the blocks' own seeds are used)
    [blocks.NAME]           kind = "pid", then parameters, and constants for unwired inputs
    [wires]                 "process.u" = "pid.out"    (destination = source)
    [[events]]              t = 100.0, set = "pid.sp", value = 60.0   (an input or a parameter)
    [compare.NAME]          "compensator.comp_start" = 1.0   (a variant: parameters or input
                            constants changed; variants run side by side, in file order)
    [autotune]              loop = "pid", process_gain = ["compensator.process_gain"]: before
                            the run, a relay test on that controller (loopworks.sim.tune, on
                            the ``variant`` named, default the first) identifies the process
                            gain, and the parameters listed take it (normalised to % of PV
                            span per % of output span with the loop controller's scales).
                            Optional: variant, amplitude, hysteresis, start (s),
                            bias_ratio (d_down/d, default 0.5), offset (the second stage's
                            switching point SP + offset·a, default 0), stable_cycles
                            (default 2), and set = {"load.walk_std" = 0.0}: parameters
                            changed for the test only (a quiet plant, as a test would be
                            scheduled). ``loopworks tune`` uses the same test settings.
                            Loading runs nothing: :func:`run_autotune` is the explicit step
                            that runs the test and rebuilds the variants with the gain
                            (``loopworks simulate`` calls it, with its own progress line).

Blocks run in the order their tables appear, unless ``[simulation] order`` says otherwise. Keys
match parameter and input names in any letter case. Errors name the file and the table.
"""

from __future__ import annotations

import math
import re
import tomllib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from loopworks.blocks.controller import Controller
from loopworks.errors import FileFormatError, LoopworksError
from loopworks.sim.metrics import WINDOW_TOLERANCE
from loopworks.sim.module import Event, Module, check_record_size, scan_count

DEFAULT_SCENARIO = "default.toml"
#: variant names the report's own figures have (``overview.png``, ``signature.png``): a
#: variant's trend plot of that name was overwritten by the report's figure (found by an
#: outside audit)
RESERVED_VARIANTS = ("overview", "signature")
#: a [compare] variant name, usable as a report file name on any system
_FILE_NAME = re.compile(r"[A-Za-z0-9_+-][A-Za-z0-9_+ .-]{0,99}")


class _Simulation(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True)
    dt: float = Field(gt=0, allow_inf_nan=False, description="scan time, s")
    duration: float = Field(gt=0, allow_inf_nan=False, description="run length, s")
    seed: int | None = None
    order: list[str] | None = None
    title: str = ""
    metrics_window: list[float] | None = Field(
        default=None, min_length=2, max_length=2,
        description="[t0, t1] s over which simulate scores each loop")


class _Event(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True)
    t: float = Field(ge=0, allow_inf_nan=False)
    set: str
    value: float | str


class _Autotune(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True)
    loop: str
    process_gain: list[str] = Field(min_length=1)
    variant: str | None = None
    amplitude: float | None = Field(default=None, gt=0, allow_inf_nan=False)
    hysteresis: float | None = Field(default=None, ge=0, allow_inf_nan=False)
    start: float | None = Field(default=None, ge=0, allow_inf_nan=False)
    bias_ratio: float = Field(default=0.5, gt=0, le=1, allow_inf_nan=False)
    offset: float = Field(default=0.0, allow_inf_nan=False)
    stable_cycles: int = Field(default=2, ge=1, le=5)
    set: dict[str, float | int | bool | str] = {}


class _Scenario(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=False)
    simulation: _Simulation
    blocks: dict[str, dict[str, Any]]
    wires: dict[str, str] = {}
    events: list[_Event] = []
    compare: dict[str, dict[str, float | int | bool | str]] = {}
    autotune: _Autotune | None = None
    #: the live commands' Modbus register map (loopworks.live.registers); simulate ignores it
    io: dict[str, Any] | None = None


@dataclass
class Scenario:
    """A loaded scenario: its modules (one per ``[compare]`` variant, else one named "base";
    ``module`` is the first), and how long and how finely to run them. ``warnings`` are what
    loaded but looks unintended (an event after the end of the run). ``autotune_test`` is the
    ``[autotune]`` relay test, checked but not run; ``autotune`` is its result once
    :func:`run_autotune` has run it (None before)."""

    module: Module
    dt: float
    duration: float
    seed: int | None
    title: str
    source: str
    variants: dict[str, Module] = field(default_factory=dict)
    text: str = ""
    metrics_window: tuple[float, float] | None = None
    autotune: dict[str, Any] | None = None
    autotune_test: AutotuneTest | None = None
    warnings: list[str] = field(default_factory=list)
    #: every variant's block tables (names and keys lower-cased), as built
    tables: dict[str, dict[str, dict[str, Any]]] = field(default_factory=dict, repr=False)
    _model: Any = field(default=None, repr=False)

    @property
    def io(self) -> dict[str, Any] | None:
        """The scenario's ``[io]`` table as written (the register map of ``loopworks device``
        and ``serve``, read by :func:`loopworks.live.registers.map_of`), or None."""
        return None if self._model is None else self._model.io

    def build(self, variant: str, changes: Mapping[str, Any] | None = None,
              seed: int | None = None) -> Module:
        """A fresh module of ``variant`` with ``changes`` ("block.parameter" or "block.input"
        = value) applied and, with ``seed``, every seeded block's seed mixed with it (as a
        ``[simulation] seed`` would: :func:`loopworks.plant.sensor.mix_seed`). A wrong name or
        value is a FileFormatError naming it."""
        return self._make(variant, changes, self.seed if seed is None else seed)

    def template(self, variant: str, changes: Mapping[str, Any] | None = None) -> Module:
        """A fresh module of ``variant`` with ``changes`` applied and every block's own seed
        (no run seed mixed in): the template of a batch (:mod:`loopworks.sim.batch`), which
        mixes each instance's seed itself."""
        return self._make(variant, changes, None)

    def _make(self, variant: str, changes: Mapping[str, Any] | None,
              seed: int | None) -> Module:
        tables = {name: dict(table) for name, table in self.tables[variant].items()}
        for key, value in (changes or {}).items():
            block, fname = split_ref(key)
            tables[block][fname] = value
        where = self.source if variant == "base" else f"{self.source} (compare.{variant})"
        return _build(self._model, tables, where, seed)


@dataclass
class AutotuneTest:
    """How the scenario's ``[autotune]`` relay-tests its loop: the controller ``loop``, the
    :func:`loopworks.sim.tune.relay_test` keyword arguments ``relay``, and ``build``, which
    makes a fresh module of the tested variant with ``changes`` ("block.parameter" = value:
    a sweep's point) and then the ``set`` changes applied."""

    loop: str
    variant: str
    relay: dict[str, Any]
    build: Callable[..., Module]
    #: the modules of every variant with ``process_gain`` (%PV/%OUT) written into the
    #: ``[autotune] process_gain`` parameters
    rebuild: Callable[[float], dict[str, Module]] = field(repr=False, default=lambda g: {})


def split_ref(ref: str) -> tuple[str, str]:
    """("block", "name") of a "block.parameter" or "block.input" reference: the block as the
    scenario names it (block names keep their case, as in [wires]), the parameter or input
    name in lower case (parameter names are case-insensitive in a block's table)."""
    block, _, name = ref.rpartition(".")
    return block, name.lower()


def _format_validation(err: ValidationError, source: str) -> str:
    lines = []
    for e in err.errors(include_url=False):
        loc = ".".join(str(p) for p in e["loc"])
        got = f" (got {e['input']!r})" if "input" in e and not isinstance(e["input"], dict) else ""
        lines.append(f"{source}: {loc}: {e['msg']}{got}")
    return "; ".join(lines)


def load_scenario(path: str | Path | None = None) -> Scenario:
    """Load a scenario file; ``None`` loads the built-in default scenario."""
    if path is None:
        text = resources.files("loopworks.scenarios").joinpath(DEFAULT_SCENARIO).read_text()
        return parse_scenario(text, f"<built-in {DEFAULT_SCENARIO}>")
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8-sig")  # a byte-order mark (Windows editors) too
    except OSError as exc:
        raise FileFormatError(f"{p}: cannot read the scenario: {exc.strerror}") from None
    except UnicodeDecodeError as exc:
        raise FileFormatError(f"{p}: not UTF-8 text (byte {exc.start}): a scenario is a TOML "
                              "file") from None
    return parse_scenario(text, str(p))


def parse_scenario(text: str, source: str = "<scenario>") -> Scenario:
    """Build a scenario from TOML text; ``source`` names it in error messages."""
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise FileFormatError(f"{source}: invalid TOML: {exc}") from None
    try:
        sc = _Scenario.model_validate(raw)
    except ValidationError as exc:
        raise FileFormatError(_format_validation(exc, source)) from None
    if not sc.blocks:
        raise FileFormatError(f"{source}: [blocks] is empty: expected at least one "
                              "[blocks.NAME] table with a kind")
    tables: dict[str, dict[str, Any]] = {}
    for name, table in sc.blocks.items():
        if not isinstance(table, dict) or "kind" not in {k.lower() for k in table}:
            raise FileFormatError(f"{source}: [blocks.{name}]: expected a table with "
                                  "kind = \"...\"")
        seen: dict[str, str] = {}
        for key in table:
            if key.lower() in seen:
                raise FileFormatError(f"{source}: [blocks.{name}]: '{key}' and "
                                      f"'{seen[key.lower()]}' are one parameter (names are "
                                      "read in any letter case): give it once")
            seen[key.lower()] = key
        tables[name] = {k.lower(): v for k, v in table.items()}
    wired: dict[str, str] = {}
    for destination in sc.wires:
        block, _, port = destination.rpartition(".")
        key = f"{block}.{port.lower()}"
        if key in wired:  # the module would keep one of them, the record the other
            raise FileFormatError(f"{source}: [wires]: '{destination}' and '{wired[key]}' "
                                  "are one input (port names are read in any letter case): "
                                  "wire it once")
        wired[key] = destination
    variants: dict[str, dict[str, dict[str, Any]]] = {}
    if not sc.compare:
        variants["base"] = tables
    for variant, overrides in sc.compare.items():
        if not _FILE_NAME.fullmatch(variant):
            raise FileFormatError(
                f"{source}: [compare.{variant}]: a variant's name names its report files "
                f"({variant}.png, {variant}.csv): use letters, digits, '_', '-', '.' and "
                "spaces, not starting with '.'")
        if variant.lower() in RESERVED_VARIANTS:
            raise FileFormatError(
                f"{source}: [compare.{variant}]: the report's own {variant.lower()}.png has "
                "this name: name the variant otherwise")
        changed = {name: dict(table) for name, table in tables.items()}
        given: dict[str, str] = {}
        for key in overrides:
            lowered = key.rpartition(".")[0] + "." + key.rpartition(".")[2].lower()
            if lowered in given:
                raise FileFormatError(f"{source}: compare.{variant}: '{key}' and "
                                      f"'{given[lowered]}' are one parameter (names are read "
                                      "in any letter case): give it once")
            given[lowered] = key
        for key, value in overrides.items():
            block, sep, fname = key.rpartition(".")
            if not sep or block not in changed:
                raise FileFormatError(
                    f"{source}: compare.{variant}: '{key}' must be 'block.parameter' or "
                    f"'block.input' with a block of this scenario ({', '.join(tables)})")
            if fname.lower() == "kind":
                raise FileFormatError(f"{source}: compare.{variant}: '{key}': a variant "
                                      "changes parameters and inputs, not the kind")
            changed[block][fname.lower()] = value
        variants[variant] = changed

    def where(name: str) -> str:
        return source if name == "base" else f"{source} (compare.{name})"

    sim = sc.simulation
    try:
        n = scan_count(sim.duration, sim.dt)
    except LoopworksError as exc:
        raise FileFormatError(f"{source}: [simulation]: {exc}") from None
    window = _window(sim, n, source)
    # every variant built and checked before anything runs (the autotune test included)
    modules = {name: _build(sc, t, where(name), sim.seed) for name, t in variants.items()}
    try:
        check_record_size(sum(m.record_bytes(n) for m in modules.values()), sim.duration,
                          sim.dt, n)
    except LoopworksError as exc:
        raise FileFormatError(f"{source}: [simulation]: {exc}"
                              + (f" ({len(modules)} variants)" if len(modules) > 1 else "")
                              ) from None
    warnings = [f"{source}: event at t = {ev.t:g} s (set = '{ev.target}') is after the last "
                f"scan (t = {(n - 1) * sim.dt:g} s) of the {sim.duration:g} s run: it never "
                "happens" for ev in next(iter(modules.values())).late_events(sim.duration, sim.dt)]
    for line in dict.fromkeys(w for m in modules.values() for w in m.unit_warnings()):
        warnings.append(f"{source}: {line}")
    if abs(n * sim.dt - sim.duration) > 1e-9 * max(sim.duration, 1.0):
        warnings.append(f"{source}: [simulation] duration = {sim.duration:g} s is not a whole "
                        f"number of scans of dt = {sim.dt:g} s: the run has the nearest "
                        f"count, {n} scans ({n * sim.dt:g} s)")
    test = None
    if sc.autotune is not None:
        test = _autotune_test(sc, variants, source)
        targets = tuple(sc.autotune.process_gain)

        def rebuild(gain: float) -> dict[str, Module]:
            for table in variants.values():
                for ref in targets:
                    block, param = split_ref(ref)
                    table[block][param] = gain
            return {name: _build(sc, t, where(name), sim.seed) for name, t in variants.items()}

        test.rebuild = rebuild
    first = next(iter(modules.values()))
    return Scenario(first, sim.dt, sim.duration, sim.seed, sim.title, source, modules, text,
                    window, None, test, warnings, variants, sc)


def _window(sim: _Simulation, n: int, source: str) -> tuple[float, float] | None:
    """``metrics_window`` checked: finite, increasing, inside the run, and holding at least
    two scans (the scans execute at t_k = k·dt, k = 0..n-1)."""
    if sim.metrics_window is None:
        return None
    t0, t1 = sim.metrics_window
    where = f"{source}: simulation.metrics_window = [{t0:g}, {t1:g}]"
    end = (n - 1) * sim.dt
    if not (math.isfinite(t0) and math.isfinite(t1)):
        raise FileFormatError(f"{where}: the bounds must be finite numbers of seconds")
    if not t0 < t1:
        raise FileFormatError(f"{where}: the window is reversed or empty: expected t0 < t1")
    if t0 < 0.0 or t1 > sim.duration:
        raise FileFormatError(f"{where} s is outside the run: expected 0 <= t0 < t1 <= "
                              f"duration = {sim.duration:g} s")
    tol = WINDOW_TOLERANCE  # the metrics' rule (loopworks.sim.metrics.in_window)
    k0, k1 = math.ceil(t0 / sim.dt - tol), min(math.floor(t1 / sim.dt + tol), n - 1)
    if k1 - k0 + 1 < 2:
        raise FileFormatError(f"{where} s holds {max(k1 - k0 + 1, 0)} scan(s) of the run "
                              f"(scans at 0, {sim.dt:g}, ..., {end:g} s): it must hold at "
                              "least 2")
    return t0, t1


def _autotune_test(sc: _Scenario, variants: dict[str, dict[str, dict[str, Any]]],
                   source: str) -> AutotuneTest:
    """The [autotune] table checked: the variant, the test-only changes, the relay options."""
    at = sc.autotune
    assert at is not None
    where = f"{source}: [autotune]"
    name = at.variant or next(iter(variants))
    if name not in variants:
        raise FileFormatError(f"{where}: variant = {name!r} is not a [compare] variant of this "
                              f"scenario ({', '.join(variants)})")
    from loopworks.catalog import block_class

    for ref in at.process_gain:
        block, sep, param = ref.rpartition(".")
        if not sep or block not in variants[name]:
            raise FileFormatError(f"{where}: process_gain entry {ref!r} must be "
                                  f"'block.parameter' with a block of this scenario")
        try:
            cls = block_class(str(variants[name][block]["kind"]))
        except LoopworksError:
            continue  # the block's own table reports its unknown kind
        params = [p.name for p in cls.PARAMS]
        if param.lower() not in params:
            raise FileFormatError(f"{where}: process_gain entry {ref!r}: {cls.kind} has no "
                                  f"parameter '{param}'; parameters: {', '.join(params)}")
    for ref in at.set:
        block, sep, param = ref.rpartition(".")
        if not sep or block not in variants[name]:
            raise FileFormatError(f"{where}: set entry {ref!r} must be 'block.parameter' with "
                                  "a block of this scenario")

    def build(changes: Mapping[str, Any] | None = None, seed: int | None = None) -> Module:
        tables = {block: dict(table) for block, table in variants[name].items()}
        for ref, value in [*(changes or {}).items(), *at.set.items()]:
            block, param = split_ref(ref)
            tables[block][param] = value
        return _build(sc, tables, f"{source} (autotune)", seed)

    relay: dict[str, Any] = {"amplitude": at.amplitude, "hysteresis": at.hysteresis,
                             "start": at.start, "bias_ratio": at.bias_ratio,
                             "offset": at.offset, "stable_cycles": at.stable_cycles}
    test = AutotuneTest(at.loop, name, relay, build)
    from loopworks.sim.tune import check_relay_test

    try:  # what the test would refuse before its first scan, refused now
        check_relay_test(test.build(), test.loop, sc.simulation.dt, **relay)
    except LoopworksError as exc:
        raise FileFormatError(f"{where}: {_as_key(exc)}") from None
    return test


def _as_key(exc: LoopworksError) -> str:
    """The relay test's message about its loop as the [autotune] table's key names it
    (``loop``), not as the tune command's option (``--loop``)."""
    return str(exc).replace("--loop '", "loop '")


def autotune_gain(sc: Scenario, changes: Mapping[str, Any] | None = None,
                  progress: Callable[[float], None] | None = None,
                  seed: int | None = None) -> tuple[float, Any]:
    """The ``[autotune]`` relay test of the scenario with ``changes`` ("block.parameter" =
    value, a sweep's point; then ``set``) applied and the run ``seed`` mixed into every seeded
    block's, as the run it tunes has it (``[simulation] seed``, a sweep point's seed): (the
    identified process gain in the controller's %PV/%OUT, the
    :class:`~loopworks.sim.tune.RelayRun`). Changes nothing; a test that identifies no
    process gain raises FileFormatError naming the table."""
    from loopworks.sim.tune import relay_test

    test = sc.autotune_test
    assert test is not None
    where = f"{sc.source}: [autotune]"
    module = test.build(changes, seed)
    try:
        run = relay_test(module, test.loop, sc.dt, progress=progress, **test.relay)
    except LoopworksError as exc:
        raise FileFormatError(f"{where}: {_as_key(exc)}") from None
    idn = run.identification
    if idn is None or idn.process_gain is None:
        why = "" if idn is None else " (" + "; ".join(idn.notes) + ")"
        raise FileFormatError(f"{where}: the relay test on '{test.loop}' ended with "
                              f"'{run.outcome}' and gave no process gain{why}")
    ctrl = module.blocks[test.loop]
    assert isinstance(ctrl, Controller)  # relay_test refuses any other block
    pv_span, out_span = ctrl.spans({k: v for k, v in ctrl.params.items() if v is not None})
    return idn.process_gain * out_span / pv_span, run


def run_autotune(sc: Scenario, progress: Callable[[float], None] | None = None
                 ) -> dict[str, Any] | None:
    """Run the scenario's ``[autotune]`` relay test (if it has one) and write the identified
    process gain into every variant: ``sc.variants`` and ``sc.module`` are rebuilt with it, and
    ``sc.autotune`` holds what was identified (for reports), which is also returned.
    ``progress(seconds_of_test)`` is called as the test runs. A test that identifies no
    process gain raises FileFormatError naming the table."""
    test = sc.autotune_test
    if test is None:
        return None
    # the test's noise streams are the run's: [simulation] seed changes them too (it did not,
    # and its identified gain stayed the same whatever the seed; found by an outside audit)
    gain, run = autotune_gain(sc, progress=progress, seed=sc.seed)
    idn = run.identification
    assert idn is not None
    sc.variants = test.rebuild(gain)
    sc.module = next(iter(sc.variants.values()))
    sc.autotune = {"loop": test.loop, "variant": test.variant, "outcome": run.outcome,
                   "process_gain": gain, "relay_shift": run.test.offset,
                   **{k: v for k, v in idn.as_dict().items()
                      if k not in ("process_gain", "notes")}}
    return sc.autotune


def _build(sc: _Scenario, tables: dict[str, dict[str, Any]], source: str,
           seed: int | None = None) -> Module:
    """One module from the block tables (names lower-cased), the wires and the events; with
    a run ``seed`` (``[simulation] seed``), every block with a ``seed`` parameter draws from
    ``mix_seed(its seed, run seed)``."""
    from loopworks.catalog import block_class
    from loopworks.plant.sensor import mix_seed

    blocks = {}
    constants: dict[str, dict[str, Any]] = {}
    for name, original in tables.items():
        where = f"{source}: [blocks.{name}]"
        table = dict(original)
        kind = table.pop("kind")
        try:
            cls = block_class(str(kind))
        except LoopworksError as exc:
            raise FileFormatError(f"{where}: {exc}") from None
        try:
            params, constants[name] = cls.split_table(table)
            blocks[name] = cls(**params)
            if seed is not None and "seed" in blocks[name].params:  # validated first
                params["seed"] = mix_seed(int(blocks[name].params["seed"]), seed)
                blocks[name] = cls(**params)
        except LoopworksError as exc:
            text = str(exc)
            if "unknown parameter" in text and cls.INPUTS:  # a table holds constant inputs too
                text += "; constant inputs: " + ", ".join(p.name for p in cls.INPUTS)
            raise FileFormatError(f"{where}: {text}") from None
    for name, values in constants.items():
        for port, value in values.items():
            spec = blocks[name].INPUTS[blocks[name]._in_index[port]]
            where = f"{source}: [blocks.{name}]: {port} = {value!r}"
            if not isinstance(value, int | float | str):
                raise FileFormatError(f"{where}: a constant input is a number"
                                      + (" or a name" if spec.choices else ""))
            if not _finite(value):
                hint = ("to leave it 'not given' (its default, nan), leave the key out"
                        if math.isnan(spec.default) else
                        f"leave the key out for its default, {spec.default:g}")
                raise FileFormatError(f"{where}: a constant input must be a finite number "
                                      f"({hint})")
            try:
                spec.parse(value)
            except ValueError as exc:
                raise FileFormatError(f"{source}: [blocks.{name}]: {exc}") from None
    events = [Event(e.t, e.set, e.value) for e in sc.events]
    try:
        module = Module(blocks, wires=sc.wires, inputs=constants, order=sc.simulation.order,
                        events=events)
    except LoopworksError as exc:
        raise FileFormatError(f"{source}: {exc}") from None
    for i, ev in enumerate(events, 1):
        if not _finite(ev.value) and not module._is_parameter(ev.target):
            raise FileFormatError(f"{source}: [[events]] #{i} (t = {ev.t:g} s, set = "
                                  f"'{ev.target}'): value = {ev.value}: an input event must "
                                  "set a finite number")
    return module


def _finite(value: Any) -> bool:
    """False for a float (or a numeric text, "nan", "inf") that is not finite."""
    if isinstance(value, str):
        try:
            value = float(value)
        except ValueError:
            return True  # a name (a mode), checked by its port
    return not isinstance(value, float) or math.isfinite(value)
