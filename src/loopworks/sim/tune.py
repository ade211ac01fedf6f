r"""Relay auto-tuning of a loop in a module (plant-and-tuning 3.4; vendor-blocks 5.1).

:func:`relay_test` takes a module (a loaded scenario's), the name of a loop's controller, and
runs the procedure of 3.4 on the module's own plant:

1. The module runs under its controller until ``start`` (s); events after ``start`` are left
   out. PV0 and the noise σn are measured over the last quarter of that settling time (σn
   from the second differences of the samples, σn = std(Δ²PV)/√6 (white noise of σ gives
   std(Δ²) = √6·σ), which neither a drift nor a smoothly settling transient inflates: first
   differences would read the changing slope of a loop still settling as noise).
2. A ``relay`` block is put between the controller and what it drives; the controller tracks
   the relay's output while the test runs (its LO/manual-tracking path, the controller
   class's ``HANDOVER``, :mod:`loopworks.blocks.controller`), so it hands back bumplessly when
   the test ends.
3. Hysteresis ε defaults to 3σn (3.4 item 2: above the noise band, 2-3 σn); the relay
   amplitude d defaults to 5 % of the controller's output span. With ``biased`` (default) a
   symmetric stage is followed by a second stage for the static gain: a biased relay with
   d_down = ``bias_ratio``·d (default d/2, γ = 2, 3.3), switching around SP + ``offset``·a
   (default offset 0; the relay block's ``offset``, docs/blocks/relay.md), a being the first
   stage's PV amplitude. The relay's switching-point shift Δ is recorded in the
   :class:`~loopworks.tuning.identify.RelayTest` (``offset``).
4. The test ends when the relay block reports convergence or aborts (timeout, runaway, no
   oscillation, bad PV, a cycle too short to measure); the loop then runs ``handback`` more
   seconds under its controller.
5. :func:`loopworks.tuning.identify.identify` analyses the recorded cycles. A test that ends
   without converging, or whose record the identification refuses, raises
   :class:`RelayTestRefused` (an InputError) with the one-line reason and the run.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from loopworks.blocks.block import Block
from loopworks.blocks.controller import Controller
from loopworks.blocks.relay import PHASE_NAMES, RUNNING, Relay
from loopworks.errors import InputError
from loopworks.sim.module import Module, check_record_size, scan_count
from loopworks.tuning.convert import Conversion
from loopworks.tuning.identify import (
    Identification,
    IdentificationRefused,
    RelayTest,
    identify,
    short_cycle,
)
from loopworks.tuning.rules import Tuning

RELAY = "relay_test"


@dataclass
class RelayRun:
    """A relay test on a module: what was applied, the record, and the outcome."""

    loop: str
    kind: str
    test: RelayTest
    outcome: str
    start: float
    t: np.ndarray
    pv: np.ndarray
    u: np.ndarray
    stage: np.ndarray
    relay: np.ndarray
    controller_out: np.ndarray
    noise_std: float
    identification: Identification | None = None
    notes: list[str] = field(default_factory=list)
    refusal: str | None = None

    def refusal_record(self) -> dict[str, Any]:
        """What ``loopworks tune --json`` prints for a refused test (docs/tune.md)."""
        return {"loop": self.loop, "kind": self.kind, "outcome": self.outcome,
                "refusal": self.refusal, "relay_amplitude": self.test.amplitude,
                "relay_amplitude_down": self.test.amplitude_down,
                "hysteresis": self.test.hysteresis, "noise_std": self.noise_std,
                "settings": None}


class RelayTestRefused(IdentificationRefused):
    """A relay test whose record supports no identification (the message says why); ``run``
    is the test."""

    def __init__(self, message: str, run: RelayRun) -> None:
        super().__init__(message)
        self.run = run


def controllers(module: Module) -> list[str]:
    """The blocks of ``module`` that ``relay_test`` can tune (the controllers)."""
    return [name for name, block in module.blocks.items() if isinstance(block, Controller)]


def default_loop(module: Module) -> str:
    """The module's only controller; InputError naming the choices when there are several or
    none."""
    names = controllers(module)
    if len(names) == 1:
        return names[0]
    if not names:
        from loopworks.catalog import controller_kinds

        raise InputError("the scenario has no controller to tune (kinds: "
                         + ", ".join(controller_kinds()) + ")")
    raise InputError("--loop is required: the scenario has several controllers: "
                     + ", ".join(names))


def _drifted_away(pv: np.ndarray, sp: float, band: float) -> tuple[float, float] | None:
    """(|SP - PV| at the start, at the end) when the PV ended further from the setpoint
    than it started by more than 3·``band`` (the relay's hysteresis or the noise), else
    None. A relay that never switched while the PV left the setpoint pushed it the wrong
    way: with the right action its first step carries the PV through the setpoint (a
    switch), or towards it when the loop was not at rest, and a stuck valve leaves it."""
    e = np.abs(sp - np.asarray(pv, dtype=np.float64))
    e = e[np.isfinite(e)]
    if len(e) < 8:
        return None
    first, last = float(np.median(e[:5])), float(np.median(e[-5:]))
    return (first, last) if last - first > 3.0 * band else None


def _why(outcome: str, relay: Relay, dt: float, pv: np.ndarray | None = None,
         noise: float = 0.0) -> str:
    """One line: why a relay test that ended with ``outcome`` gives no identification (a
    second stage that stops switching after the symmetric one cycled is told apart: its
    lower level or shifted point cannot carry the PV through the band, and a larger
    amplitude is not the cure)."""
    prm = relay.params
    period = float(relay.y[relay._out_index["period"]])
    if outcome == "no_oscillation" and relay.y[relay._out_index["stage"]] > 1.5:
        return (f"the second stage of the relay did not switch for {prm['max_half_period']:g}"
                " s after the symmetric stage cycled: its lower level (or shifted switching "
                "point) does not carry the PV back through the band of ±"
                f"{float(prm['hysteresis']):g} (a larger --bias-ratio, a smaller --offset or "
                "--hysteresis, or --symmetric)")
    reasons = {
        "too_fast": short_cycle(period, dt),
        "not_converged": f"no {prm['stable_cycles']} consecutive cycles agreed within "
                         f"{100 * prm['tolerance']:g} % (period, amplitude, cycle means) in "
                         f"{prm['max_cycles']} cycles: the loop was not at rest or a load moved "
                         "it (a later --start), or noise (a larger --hysteresis)",
        "timeout": f"the test reached its timeout of {prm['timeout']:g} s",
        "runaway": f"|SP - PV| exceeded max_deviation = {prm['max_deviation']:g}",
        "no_oscillation": f"the relay did not switch for {prm['max_half_period']:g} s: no "
                          "oscillation (a larger --amplitude: 2d must move a sticky valve)",
        "bad_input": "the PV or SP went Bad or non-finite during the test",
    }
    band = max(float(prm["hysteresis"]), noise, 1e-9)
    away = (_drifted_away(pv, float(relay.u[0]), band)
            if outcome == "no_oscillation" and pv is not None else None)
    if away is not None:
        # the relay drove the output one way and the PV left the setpoint (found by an
        # engineer: a process of negative gain under a reverse-acting PID got the hint "a
        # larger --amplitude")
        moved = (f"the relay did not switch for {prm['max_half_period']:g} s, and the PV "
                 f"moved away from the setpoint (|SP - PV| {away[0]:.3g} at first, "
                 f"{away[1]:.3g} at the end) while the relay drove the output one way")
        if away[0] > 3.0 * band:
            # not at rest when the test began: a drift the relay's ±d cannot turn (an
            # integrating loop off its balance) looks the same (found by an outside audit)
            return (f"{moved}. The loop was not at rest when the test began ({away[0]:.3g} "
                    "off the setpoint): let it settle first (a later --start) or give a "
                    "larger --amplitude; if it was at rest, the controller's action is the "
                    "wrong one for this process (change direct/reverse action)")
        return (f"{moved}: the controller's action is the wrong one for this process (the "
                "process gain has the other sign: change direct/reverse action)")
    return reasons.get(outcome, f"the test ended with '{outcome}'")


def _interface(block: Block) -> type[Controller]:
    """The controller interface of ``block``'s class (a controller, checked before)."""
    cls = type(block)
    assert issubclass(cls, Controller), block.kind
    return cls


def _relay_setup(module: Module, loop: str, dt: float, start: float | None,
                 amplitude: float | None, hysteresis: float | None, biased: bool,
                 bias_ratio: float, offset: float, timeout: float, stable_cycles: int,
                 max_deviation: float) -> tuple[Block, str, dict[str, Any], float, float]:
    """Everything :func:`relay_test` checks before it runs a scan: the loop is a known
    controller wired to a PV, dt and start are usable, and the relay block takes its
    parameters (the hysteresis, unless given, is measured later and checked as 0 here).
    Returns the controller, the PV source, the relay's parameters, d and the start (s)."""
    if loop not in module.blocks:
        raise InputError(f"--loop '{loop}': no such block; blocks: {', '.join(module.blocks)}")
    ctrl = module.blocks[loop]
    if not isinstance(ctrl, Controller):
        raise InputError(f"--loop '{loop}' is a {ctrl.kind} block, not a controller; "
                         "controllers: " + ", ".join(controllers(module)))
    why = ctrl.incremental(ctrl.params)
    if why is not None:
        raise InputError(f"--loop '{loop}': this {ctrl.kind} outputs increments ({why}); the "
                         "relay test needs a controller whose output is the position")
    pv_port = ctrl.ROLES.pv
    pv_src = module.wires.get(f"{loop}.{pv_port}")
    if pv_src is None:
        raise InputError(f"--loop '{loop}': its input '{pv_port}' is not wired to a PV")
    if not 0.0 < dt < math.inf:
        raise InputError(f"dt = {dt!r} s is not allowed: dt must be > 0 and finite")
    lo, hi = ctrl.output_range(ctrl.params)
    d = 0.05 * (hi - lo) if amplitude is None else float(amplitude)
    relay_params: dict[str, Any] = {
        "amplitude": d, "out_lo": lo, "out_hi": hi, "timeout": timeout,
        "stable_cycles": stable_cycles, "max_deviation": max_deviation,
        "biased_stage": biased}
    if biased:
        if not 0.0 < bias_ratio <= 1.0:
            raise InputError(f"bias_ratio = {bias_ratio!r} is not allowed: allowed (0, 1] "
                             "(d_down/d of the second stage, as [autotune] bias_ratio)")
        if not math.isfinite(offset):
            raise InputError(f"offset = {offset!r} is not allowed: must be finite")
        relay_params["amplitude_down"] = bias_ratio * d
        relay_params["offset"] = offset
    if ctrl.direct_acting(ctrl.params):
        relay_params["action"] = "direct"
    start = _default_start(module, dt) if start is None else float(start)
    if not 0.0 <= start < math.inf:
        raise InputError(f"start = {start!r} s is not allowed: must be finite and >= 0")
    settle = scan_count(start, dt, "start", least=0) if start > 0.0 else 0  # the settling
    # keeps the PV of each scan
    check_record_size(8 * settle, start, dt, settle, what="start")
    Relay(**relay_params, hysteresis=0.0 if hysteresis is None else float(hysteresis))
    return ctrl, pv_src, relay_params, d, start


def check_relay_test(module: Module, loop: str, dt: float, *, start: float | None = None,
                     amplitude: float | None = None, hysteresis: float | None = None,
                     biased: bool = True, bias_ratio: float = 0.5, offset: float = 0.0,
                     timeout: float = 7200.0, stable_cycles: int = 2,
                     max_deviation: float = math.inf) -> None:
    """Raise the error :func:`relay_test` would raise before its first scan, running
    nothing (a scenario's ``[autotune]`` is checked so when it loads)."""
    _relay_setup(module, loop, dt, start, amplitude, hysteresis, biased, bias_ratio, offset,
                 timeout, stable_cycles, max_deviation)


def relay_test(module: Module, loop: str, dt: float, *, start: float | None = None,
               amplitude: float | None = None, hysteresis: float | None = None,
               biased: bool = True, bias_ratio: float = 0.5, offset: float = 0.0,
               timeout: float = 7200.0, handback: float | None = None, stable_cycles: int = 2,
               max_deviation: float = math.inf, ku_convention: str = "hysteresis_corrected",
               amplitude_estimate: str = "peaks",
               progress: Callable[[float], None] | None = None) -> RelayRun:
    """Run a relay test on controller ``loop`` of ``module`` with scans of ``dt`` seconds
    (procedure in the module docstring). Raises InputError for a loop that is not a known
    controller or is not wired to a PV, and RelayTestRefused for a test that supports no
    identification. The test runs on a copy of ``module``: the caller's module, its
    events and its controller's settings are left as they were."""
    module = _private_copy(module)
    ctrl, pv_src, relay_params, d, start = _relay_setup(
        module, loop, dt, start, amplitude, hysteresis, biased, bias_ratio, offset, timeout,
        stable_cycles, max_deviation)
    iface = _interface(ctrl)
    out_port, sp_port, working_sp = iface.ROLES.out, iface.ROLES.sp, iface.ROLES.working_sp
    links, settings = iface.HANDOVER.inputs, iface.HANDOVER.params

    # settle under the controller (events up to start only; the later ones are named in the
    # identification's warnings: they were left out with no word; found by an outside audit)
    dropped = [e for e in module.events if e.t >= start - 1e-9]
    module.events = [e for e in module.events if e.t < start - 1e-9]
    module.reset()
    n_settle = round(start / dt)
    pv_hist = np.empty(n_settle)
    for k in range(n_settle):
        module.scan(dt)
        pv_hist[k] = _read(module, pv_src)
    tail = pv_hist[n_settle - max(n_settle // 4, 2):] if n_settle >= 8 else pv_hist
    pv0 = float(np.mean(tail)) if len(tail) else _read(module, pv_src)
    noise = float(np.std(np.diff(tail, 2)) / math.sqrt(6.0)) if len(tail) > 3 else 0.0
    eps = 3.0 * noise if hysteresis is None else float(hysteresis)
    relay_params["hysteresis"] = eps
    _check_levels(loop, float(ctrl.y[ctrl._out_index[out_port]]), relay_params)

    # splice the relay in
    relay = Relay(**relay_params)
    wires = {}
    for dest, src in module.wires.items():
        wires[dest] = f"{RELAY}.out" if src == f"{loop}.{out_port}" else src
    wires[f"{RELAY}.u_in"] = f"{loop}.{out_port}"
    wires[f"{RELAY}.pv"] = pv_src
    sp_value: float | None = None
    # the setpoint the loop works to now (a cascade secondary's comes from its primary)
    sp_port = iface.setpoint_input({name: float(ctrl.u[i]) for name, i in ctrl._in_index.items()})
    if working_sp is not None:
        wires[f"{RELAY}.sp"] = f"{loop}.{working_sp}"
    elif f"{loop}.{sp_port}" in module.wires:
        wires[f"{RELAY}.sp"] = module.wires[f"{loop}.{sp_port}"]
    else:
        sp_value = float(ctrl.u[ctrl._in_index[sp_port]])
    for dest, src in links:
        wires[f"{loop}.{dest}"] = f"{RELAY}.{src}"
    if settings:
        ctrl.set_params(**settings)
    order = list(module.order)
    order.insert(order.index(loop) + 1, RELAY)
    constants = {name: {port: value for port, value in values.items()
                        if f"{name}.{port}" not in wires}
                 for name, values in module.constants.items()}
    constants[RELAY] = {"enable": 1.0, **({} if sp_value is None else {"sp": sp_value})}
    saved = module.state_dict()
    spliced = Module({**module.blocks, RELAY: relay}, wires=wires, inputs=constants,
                     order=order, events=[])
    for name, block in module.blocks.items():  # continue from the settled state
        block.load_state(saved["blocks"][name])
    spliced.t, spliced.k = module.t, module.k
    u0 = float(ctrl.y[ctrl._out_index[out_port]])
    sp = sp_value if sp_value is not None else _read(spliced, wires[f"{RELAY}.sp"])
    test = RelayTest(sp=sp, pv0=pv0, u0=u0, amplitude=d,
                     amplitude_down=relay_params.get("amplitude_down", d), hysteresis=eps,
                     action=relay_params.get("action", "reverse"))

    # the test, then the handback
    rec_t: list[float] = []
    rec_pv: list[float] = []
    rec_u: list[float] = []
    rec_stage: list[float] = []
    rec_r: list[float] = []
    rec_c: list[float] = []
    shift = 0.0
    y = relay.y
    c_out = ctrl._out_index[out_port]
    limit = timeout + 10.0 * dt
    outcome = "timeout"
    while spliced.t - start <= limit:
        spliced.scan(dt)
        rec_t.append(spliced.t - dt)
        rec_pv.append(float(relay.u[1]))
        rec_u.append(float(y[0]))
        rec_stage.append(float(y[6]))
        rec_r.append(float(y[4]))
        rec_c.append(float(ctrl.y[c_out]))
        shift = float(y[7]) if y[6] > 1.5 else shift
        phase = int(y[5])
        if progress is not None and len(rec_t) % 1000 == 0:
            progress(spliced.t - start)
        if phase != RUNNING:
            outcome = PHASE_NAMES[phase]
            break
    test = replace(test, offset=shift)
    run = RelayRun(loop=loop, kind=ctrl.kind, test=test, outcome=outcome, start=start,
                   t=np.asarray(rec_t), pv=np.asarray(rec_pv), u=np.asarray(rec_u),
                   stage=np.asarray(rec_stage), relay=np.asarray(rec_r),
                   controller_out=np.asarray(rec_c), noise_std=noise)
    if outcome == "converged":
        try:
            run.identification = identify(run.t, run.pv, run.u, test, relay=run.relay,
                                          stage=run.stage,
                                          cycles=stable_cycles, ku_convention=ku_convention,
                                          amplitude_estimate=amplitude_estimate)
        except IdentificationRefused as exc:
            run.refusal = str(exc)
        else:
            why = _through_nonlinear_valve(module, loop)
            if why is not None:
                run.identification.warnings.append(why)
            if dropped:
                names = ", ".join(f"{e.target} = {e.value!r} at {e.t:g} s" for e in dropped[:3])
                more = f" and {len(dropped) - 3} more" if len(dropped) > 3 else ""
                run.identification.warnings.append(
                    f"the scenario's events from the test's start ({start:g} s) on were left "
                    f"out: the test runs on the loop as it stands then ({names}{more})")
    else:
        run.refusal = _why(outcome, relay, dt, run.pv, noise)
    extra = (2.0 * run.identification.period if run.identification else 10.0 * dt) \
        if handback is None else handback
    spliced.blocks[RELAY].set_inputs({"enable": 0.0})
    for _ in range(round(extra / dt)):
        spliced.scan(dt)
        run.t = np.append(run.t, spliced.t - dt)
        run.pv = np.append(run.pv, float(relay.u[1]))
        run.u = np.append(run.u, float(y[0]))
        run.stage = np.append(run.stage, 0.0)
        run.relay = np.append(run.relay, 0.0)
        run.controller_out = np.append(run.controller_out, float(ctrl.y[c_out]))
    if run.refusal is not None:
        raise RelayTestRefused(f"the relay test on '{loop}' ended with '{outcome}' after "
                               f"{run.t[-1] - start if len(run.t) else 0.0:.0f} s and gives no "
                               f"identification: {run.refusal}", run)
    return run


def _private_copy(module: Module) -> Module:
    """``module`` with blocks of its own, made from the same kinds and parameters. The test
    keeps only events before its start, sets the controller's handover settings and splices
    a relay in, whose module takes the blocks' buffers; on the caller's module that left a
    module whose later runs read the test's buffers (found by an outside audit: a run after
    ``tune_loop`` started from the test's output, not the module's)."""
    from loopworks.catalog import create_block

    blocks = {name: create_block(b.kind, jit=b.jit, **b.given)
              for name, b in module.blocks.items()}
    return Module(blocks, wires=module.wires, inputs=module.constants, order=module.order,
                  events=module.events)


def _through_nonlinear_valve(module: Module, loop: str) -> str | None:
    """The warning for a relay that cycled through a valve with stick-slip, backlash or a
    resolution (its ``nonlinearity()``; any of the valves downstream, a split range's second
    too), None through linear valves or none."""
    from loopworks.sim.module import downstream_valves

    valves = downstream_valves(
        loop, module.wires, {n: b.kind for n, b in module.blocks.items()},
        set(controllers(module)), lambda n: "position" in module.blocks[n]._out_index)
    said = []
    for valve in valves:
        describe = getattr(module.blocks[valve], "nonlinearity", None)
        what = describe() if describe is not None else None
        if what is not None:
            said.append(f"valve '{valve}' ({module.blocks[valve].kind}: {what})")
    if not said:
        return None
    return (f"the relay cycled through {' and '.join(said)}: "
            "the relay's cycle holds the valve's sticking and jumps, which the analysis reads "
            "as plant (a stick-slip of S = 2 %, J = 1 % made K = 1, T = 10 s read K 3.6, T "
            "39 s, with no spread), so the model and the settings from it can be far off; "
            "test with the valve's stiction compensated, or identify from a step test")


def _check_levels(loop: str, u0: float, relay: dict[str, Any]) -> None:
    """InputError when the relay's levels around the settled output ``u0``, u0 + d and
    u0 - d (the symmetric stage; the biased one moves down by d_down ≤ d), pass the
    controller's output limits: the limits would clip the relay, and a clipped relay is not
    the ±d relay whose cycle the identification reads (spec 3.1-3.3; its stage means, K and
    the process type come out wrong)."""
    d, lo, hi = float(relay["amplitude"]), float(relay["out_lo"]), float(relay["out_hi"])
    if u0 - d >= lo and u0 + d <= hi:
        return
    room = max(0.0, min(u0 - lo, hi - u0))
    raise InputError(
        f"the relay test on '{loop}': its levels u0 ± d = {u0 - d:.4g} .. {u0 + d:.4g} (the "
        f"output {u0:.4g} at the start, d = {d:.4g}) pass the controller's output limits "
        f"{lo:g} .. {hi:g}, which would clip the relay and spoil the identification: give "
        + (f"--amplitude {room:.3g} or less" if room > 0.0 else "an operating point off the "
           "limit") + " (or move the operating point away from the limit)")


def _read(module: Module, ref: str) -> float:
    """The current value of output ``ref`` ("block.port")."""
    name, port = ref.rsplit(".", 1)
    block = module.blocks[name]
    return float(block.y[block._out_index[port]])


def _default_start(module: Module, dt: float) -> float:
    """Settle until 60 s after the last event (at least 100 scans): the loop at rest."""
    last = max((e.t for e in module.events), default=0.0)
    return max(last + 60.0, 100.0 * dt)



@dataclass
class TuneReport:
    """A relay test, the rule's settings and the settings in the controller's own parameters."""

    run: RelayRun
    identification: Identification
    tuning: Tuning
    conversion: Conversion
    handback_jump: float

    def as_dict(self) -> dict[str, Any]:
        """The ``loopworks tune --json`` object (documented in docs/tune.md)."""
        idn = self.identification.as_dict()
        out: dict[str, Any] = {
            "loop": self.run.loop, "kind": self.run.kind, "outcome": self.run.outcome,
            "relay_amplitude": idn["relay_amplitude"],
            "relay_amplitude_down": idn["relay_amplitude_down"],
            "relay_shift": self.run.test.offset,
            "hysteresis": idn["hysteresis"], "noise_std": self.run.noise_std,
            "amplitude": idn["amplitude"], "amplitude_harmonic": idn["amplitude_harmonic"],
            "period": idn["period"], "ku": idn["ku"], "ku_convention": idn["ku_convention"],
            "ku_describing_function": idn["ku_describing_function"],
            "ku_hysteresis_corrected": idn["ku_hysteresis_corrected"],
            "ku_harmonic": idn["ku_harmonic"], "pu": idn["pu"], "phase_lag": idn["phase_lag"],
            "process_type": idn["process_type"], "process_gain": idn["process_gain"],
            "integrating_gain": idn["integrating_gain"], "dead_time": idn["dead_time"],
            "time_constant": idn["time_constant"], "cycles": idn["cycles"],
            "scan": idn["scan"], "uncertainty": idn["uncertainty"],
            # the rule's validity warnings too (a note of Tuning is one by definition)
            "warnings": list(idn["warnings"]) + ([self.tuning.note] if self.tuning.note
                                                 else []),
            "refusal": None,
            "rule": self.tuning.rule, "controller": self.tuning.controller,
            "rule_form": self.tuning.form,
            "tuning": {"kc": self.tuning.kc, "ti": _finite(self.tuning.ti),
                       "td": self.tuning.td},
            "ms": self.tuning.ms,
            "settings": dict(self.conversion.params),
            "exact": self.conversion.exact,
            "note": " ".join(s for s in (self.conversion.note, *self.identification.notes)
                             if s),
            "handback_jump": self.handback_jump,
        }
        return out


def _finite(x: float) -> float | None:
    return x if math.isfinite(x) else None


def tune_loop(module: Module, loop: str, dt: float, *, rule: str | None = None,
              controller: str = "PI", options: dict[str, float] | None = None,
              **relay_options: Any) -> TuneReport:
    """Relay test on ``loop`` (:func:`relay_test`), identification, tuning ``rule`` (default:
    :func:`loopworks.tuning.rules.default_rule` for what was identified) for a ``controller``
    of type P, PI or PID, and the result in the loop controller's own parameters
    (:func:`loopworks.tuning.convert.from_loop_units`, the module's dt as sample time)."""
    from loopworks.tuning.convert import from_loop_units, setpoint_weights
    from loopworks.tuning.rules import default_rule, tune

    run = relay_test(module, loop, dt, **relay_options)
    assert run.identification is not None  # relay_test raises RelayTestRefused otherwise
    data = run.identification.process_data()
    name = default_rule(data, controller) if rule is None else rule
    tuning = tune(name, data, controller, **(options or {}))
    ideal = tuning.ideal()
    ctrl = module.blocks[loop]
    context = {k: v for k, v in ctrl.params.items() if v is not None}
    # the structure the user chose (DeltaV's STRUCTURE, GE's derivative on PV, the pid's b
    # and c) is kept: it was set to the ideal form's (derivative on error) for every vendor
    context.update(setpoint_weights(run.kind, ctrl.params, dt))
    # the relay oscillated under the loop's own action, so that action is the right one
    conversion = from_loop_units(run.kind, ideal.kc, ideal.ti, ideal.td,
                                 direct=_interface(ctrl).direct_acting(ctrl.params),
                                 sample_time=dt, context=context)
    return TuneReport(run, run.identification, tuning, conversion, _handback_jump(run))


def _handback_jump(run: RelayRun) -> float:
    """Largest scan-to-scan change of the controller output after the test, relative to the
    relay amplitude's scale: 0 when the handback is bumpless (the controller continues from
    u0 and moves only as its own law moves it)."""
    end = int(np.flatnonzero(run.stage > 0.0)[-1]) if np.any(run.stage > 0.0) else 0
    after = run.controller_out[end + 1:end + 4]  # tracking u0, then free
    return float(np.max(np.abs(np.diff(after)))) if len(after) > 1 else 0.0
