"""Simulated loops with a known valve, for judging a stiction detector (issue 15).

Each loop is one loopworks :class:`~loopworks.sim.module.Module` built from the library's own
blocks (no second copy of a valve or process equation)::

    process (process.fopdt | process.ipdt) -> load (disturbance.load, at the process output)
    -> sensor (sensor.transmitter, noise) -> pid (pid | deltav.pid | e2.pid) -> valve
    (valve.choudhury | valve.karnopp) -> process

run in that order each scan (the plant first, so the controller reads this scan's
measurement, as examples/default.toml does). The loop starts in AUTO at its steady state
(SP = PV = OP = valve = 50 %), the first :data:`WARMUP` seconds are dropped as start-up, and
every ``sample_period / dt``-th scan is kept, as a historian would record it.

What is recorded (:class:`SimulatedLoop`): ``data`` (t, SP, measured PV with noise, OP, the
true stem position, mode all AUTO), the label (``"stiction"`` when the valve has S > 0,
``"no_stiction"`` otherwise), the loop type, the true Choudhury S and J and a one-line
description of the case. A Karnopp valve is made from a nominal S and J (resolution = J,
deadband = S - J, spec plant-and-tuning 1.7, forces by the block's default force balance,
Fs = U·(S + J)/2 and Fc = U·(S - J)/2 with U the force of 1 % of OP, spec 1.1); its true S is
the band it shows on reversal, which is what a Choudhury S measures: with the Stribeck term a
slowly driven stem creeps with its friction near Fs, so that band is 2·Fs/U = S + J (the
``valve.karnopp`` docstring; :func:`karnopp_reversal_band`), not the nominal S. Its J stays
the nominal one, the slip of an overdamped stem from Fs down to Fc, (Fs - Fc)/U = J.

:func:`make_set` draws a balanced, seeded set (composition in its docstring);
:func:`write_csv` writes one loop as a historian CSV that
:func:`loopworks.analysis.loopdata.read_csv` reads back.
"""

from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from loopworks import create_block
from loopworks.analysis.loopdata import LoopData
from loopworks.errors import InputError
from loopworks.plant.valve import resolution_deadband_from_sj
from loopworks.sim.module import Event, Module

FloatArray = npt.NDArray[np.float64]

#: the controller kinds a loop can use; GE's pid_isa and the S5's OB 251 work in 16-bit counts
#: and would need scaling blocks around them, so they are left out
CONTROLLERS = ("pid", "deltav.pid", "e2.pid")
#: the valve models: Choudhury's S/J logic, the physical Karnopp valve, and a clean (linear)
#: valve, which is valve.choudhury with S = J = 0 (its output is its input)
VALVES = ("choudhury", "karnopp", "linear")
LOOP_TYPES = ("self-regulating", "integrating")
#: simulation scan, s: 0.5 s resolves dead times of 1 s and more, and a Karnopp valve's 1 ms
#: substeps stay affordable
DT = 0.5
#: historian period, s: a common archive rate for flow and level tags
SAMPLE_PERIOD = 5.0
#: start-up dropped before recording, s: the loop settles from its initial state and the
#: load walk reaches its stationary spread (its time constant is 600 s)
WARMUP = 1800.0
#: recorded span, s: 2000 samples at 5 s, 5+ periods of the slowest stiction cycle in the set
#: (a few hundred seconds for a slow level loop)
RECORD = 10000.0
#: operating point, % of span: SP, PV, OP and valve position at the start
OPERATING_POINT = 50.0
#: E2 PID update interval, s (the block's default is 2 s; 1 s keeps fast flow loops tunable)
E2_UPDATE = 1.0
#: the largest OP noise std the set allows (Kc times the transmitter noise), %
NOISE_OP = 1.5
#: parameters of the physical valve, from examples/default.toml: a digital positioner
#: (tau_ip 0.5 s) and the spring preload bench-set so op 0..100 % strokes 0..100 %
KARNOPP_PARAMS: dict[str, float] = {"tau_ip": 0.5, "f_init": 1840.8}


@dataclass(frozen=True)
class SimulatedLoop:
    """One simulated loop and the truth about it.

    ``data``: what a historian records (t, SP, measured PV, OP, mode) plus the true stem
    ``position``; ``label``: ``"stiction"`` or ``"no_stiction"``; ``loop_type``:
    ``"self-regulating"`` (a flow loop, FOPDT) or ``"integrating"`` (a level loop, IPDT);
    ``case``: a short description; ``s``, ``j``: the true Choudhury S and J, % of span (0, 0
    for a clean valve; a Karnopp valve's S is the band it shows on reversal,
    :func:`karnopp_reversal_band`, its J the nominal one); ``s_nominal``: the S the valve
    was made from (= ``s`` except for a Karnopp valve);
    ``controller``: the controller kind; ``valve``: ``"choudhury"``, ``"karnopp"`` or
    ``"linear"``; ``seed``: the seed the loop was drawn and simulated from; ``noise``: the
    transmitter noise's standard deviation, % of span.
    """

    data: LoopData
    label: str
    loop_type: str
    case: str
    s: float
    j: float
    controller: str
    valve: str
    seed: int
    s_nominal: float = 0.0
    noise: float = 0.0


# ----------------------------------------------------------------------------- tuning

def _open_loop(loop_type: str, gain: float, time_constant: float, delay: float, ti: float,
               w: FloatArray) -> npt.NDArray[np.complex128]:
    """G(jw)·(1 + 1/(jw·Ti)): the loop's frequency response per unit controller gain."""
    s = 1j * w
    proc = gain / (time_constant * s + 1.0) if loop_type == "self-regulating" else gain / s
    return np.asarray(proc * np.exp(-delay * s) * (1.0 + 1.0 / (ti * s)))


def ultimate(loop_type: str, gain: float, time_constant: float, dead_time: float, ti: float,
             dt: float = DT) -> tuple[float, float]:
    """(Ku, Pu): the PI gain at which the loop reaches the stability limit and the period it
    oscillates at there, for a PI with integral time ``ti``; the scan adds ``dt`` of delay
    (half a scan of hold, half of the controller reading last scan's value on average)."""
    w = np.logspace(-5.0, 2.0, 40000) / max(dead_time + dt, 1e-3)
    lf = _open_loop(loop_type, gain, time_constant, dead_time + dt, ti, w)
    phase = np.unwrap(np.angle(lf))
    k = int(np.flatnonzero(phase <= -math.pi)[0])
    return 1.0 / float(abs(lf[k])), 2.0 * math.pi / float(w[k])


def simc(loop_type: str, gain: float, time_constant: float, dead_time: float) -> tuple[float,
                                                                                       float]:
    """SIMC PI (Skogestad) with tau_c = dead time: (Kc, Ti). Self-regulating: Kc =
    T/(K·2L), Ti = min(T, 8L); integrating: Kc = 1/(K·2L), Ti = 8L. A robust, sensible tuning
    (gain margin about 3), which the set then scales."""
    tc = dead_time
    if loop_type == "self-regulating":
        return time_constant / (gain * (tc + dead_time)), min(time_constant, 4.0 * (tc + dead_time))
    return 1.0 / (gain * (tc + dead_time)), 4.0 * (tc + dead_time)


# ----------------------------------------------------------------------------- one loop

def _controller(kind: str, kc: float, ti: float) -> Any:
    """A reverse-acting (e = SP - PV) PI of gain ``kc`` (%OP/%PV) and integral time ``ti`` (s),
    starting in AUTO with its output at the operating point."""
    op = OPERATING_POINT
    if kind == "pid":
        return create_block("pid", k=kc, ti=ti, bias=op, action="reverse")
    if kind == "deltav.pid":
        return create_block("deltav.pid", gain=kc, reset=ti, initial_out=op)
    if kind == "e2.pid":
        # throttling range 100 (the PV span): Padj = kp·Δe; Iadj = ki·e per update
        return create_block("e2.pid", throttling_range=100.0, kp=kc, ki=kc * E2_UPDATE / ti,
                            update_interval=E2_UPDATE, output_at_setpoint=op,
                            min_accumulated_error=0.0, error_sign="setpoint_minus_input")
    raise InputError(f"controller {kind!r}: expected one of {', '.join(CONTROLLERS)}")


def _valve(kind: str, s: float, j: float) -> Any:
    op = OPERATING_POINT
    if kind == "linear":
        return create_block("valve.choudhury", s=0.0, j=0.0, y0=op)
    if kind == "choudhury":
        return create_block("valve.choudhury", s=s, j=j, y0=op)
    if kind == "karnopp":
        resolution, deadband = resolution_deadband_from_sj(s, j)
        return create_block("valve.karnopp", resolution=resolution, deadband=deadband, y0=op,
                            **KARNOPP_PARAMS)
    raise InputError(f"valve {kind!r}: expected one of {', '.join(VALVES)}")


def simulate_loop(*, loop_type: str = "self-regulating", controller: str = "pid",
                  valve: str = "choudhury", s: float = 0.0, j: float = 0.0,
                  noise: float = 0.1, gain: float = 1.0, time_constant: float = 10.0,
                  dead_time: float = 2.0, kc: float | None = None, ti: float | None = None,
                  walk_std: float = 0.0, walk_time_constant: float = 600.0,
                  sine_amplitude: float = 0.0, sine_period: float = 60.0,
                  sp_step: float = 0.0, sp_step_time: float = 10.0, dt: float = DT,
                  sample_period: float = SAMPLE_PERIOD, warmup: float = WARMUP,
                  duration: float = RECORD, case: str = "", seed: int = 0) -> SimulatedLoop:
    """Simulate one loop and record it as a historian would.

    ``loop_type``: ``"self-regulating"`` (process.fopdt: ``gain`` %PV/%OP, ``time_constant``
    s, ``dead_time`` s) or ``"integrating"`` (process.ipdt: ``gain`` %PV/s per %OP,
    ``dead_time`` s). ``controller``: a kind of :data:`CONTROLLERS`, a PI with ``kc`` and
    ``ti`` (default the SIMC tuning, :func:`simc`). ``valve``: ``"choudhury"`` or
    ``"karnopp"`` with Choudhury ``s``, ``j`` (% of span), or ``"linear"`` (no stiction).
    ``noise``: transmitter noise standard deviation, % of span; ``walk_std`` (%/√s) and
    ``walk_time_constant`` (s): an Ornstein-Uhlenbeck load at the process output;
    ``sine_amplitude`` (%) and ``sine_period`` (s): an oscillating external disturbance there;
    ``sp_step`` (%) at ``sp_step_time`` (s): a setpoint change. The run lasts ``warmup +
    duration`` seconds in scans of ``dt``; the record keeps every ``sample_period`` s after
    ``warmup``, its times from 0. ``seed`` seeds the noise and the load. Deterministic.
    """
    if loop_type not in LOOP_TYPES:
        raise InputError(f"loop_type {loop_type!r}: expected one of {', '.join(LOOP_TYPES)}")
    every = round(sample_period / dt)
    if every < 1 or abs(every * dt - sample_period) > 1e-9 * sample_period:
        raise InputError(f"sample_period = {sample_period:g} s is not a whole number of "
                         f"scans of dt = {dt:g} s")
    if kc is None or ti is None:
        kc0, ti0 = simc(loop_type, gain, time_constant, dead_time)
        kc = kc0 if kc is None else kc
        ti = ti0 if ti is None else ti
    op = OPERATING_POINT
    capacity = max(10, math.ceil(dead_time / dt) + 2)
    if loop_type == "self-regulating":
        process = create_block("process.fopdt", gain=gain, time_constant=time_constant,
                               dead_time=dead_time, u0=op, y0=op, delay_capacity=capacity)
    else:
        process = create_block("process.ipdt", gain=gain, dead_time=dead_time, u0=op, y0=op,
                               delay_capacity=capacity)
    rng = np.random.default_rng(seed)
    load_seed, sensor_seed = (int(v) for v in rng.integers(0, 2**52, size=2))
    load = create_block("disturbance.load", walk_std=walk_std,
                        walk_time_constant=walk_time_constant, seed=load_seed,
                        sine_amplitude=sine_amplitude, sine_period=sine_period,
                        sine_phase=float(rng.uniform(0.0, 360.0)))
    sensor = create_block("sensor.transmitter", noise_std=noise, seed=sensor_seed)
    blocks = {"process": process, "load": load, "sensor": sensor,
              "pid": _controller(controller, kc, ti), "valve": _valve(valve, s, j)}
    wires = {"valve.op": "pid.out", "process.u": "valve.position", "load.u": "process.y",
             "sensor.y": "load.y", "pid.pv": "sensor.pv"}
    events = [Event(sp_step_time, "pid.sp", op + sp_step)] if sp_step else []
    module = Module(blocks, wires=wires, inputs={"pid": {"sp": op}}, events=events)
    record = ["pid.sp", "sensor.pv", "pid.out", "valve.position"]
    result = module.run(warmup + duration, dt, record=record)
    start = round(warmup / dt)
    keep = slice(start, None, every)
    t = result.t[keep]
    data = LoopData(t=t - t[0], sp=result["pid.sp"][keep], pv=result["sensor.pv"][keep],
                    op=result["pid.out"][keep], position=result["valve.position"][keep],
                    mode=np.ones(len(t)), source=case or "simulated")
    sticky = valve != "linear" and s > 0.0
    shown = karnopp_reversal_band(s, j) if valve == "karnopp" else s
    return SimulatedLoop(data=data, label="stiction" if sticky else "no_stiction",
                         loop_type=loop_type, case=case, s=shown if sticky else 0.0,
                         j=j if sticky else 0.0, controller=controller, valve=valve, seed=seed,
                         s_nominal=s if sticky else 0.0, noise=noise)


def karnopp_reversal_band(s: float, j: float) -> float:
    """The band (% of OP) a ``valve.karnopp`` made from nominal ``s``, ``j`` (force balance,
    spec 1.1: Fs = U·(S + J)/2) shows after a reversal when driven slowly, as a loop's
    integral action drives it: with the Stribeck term the creeping stem's friction is near
    Fs in either direction, so the OP must travel 2·Fs/U = S + J (the block's docstring,
    "Stiction as S and J"; checked against the block in tests/analysis/test_synthetic.py)."""
    return s + j


# ----------------------------------------------------------------------------- the set

#: the set's groups and their shares (twelfths): half sticky, half clean
GROUPS: tuple[tuple[str, int], ...] = (("choudhury", 4), ("karnopp", 2), ("clean", 2),
                                       ("aggressive", 2), ("external", 2))


def _counts(n: int) -> list[tuple[str, int]]:
    """Loops per group for a set of ``n``: the shares of :data:`GROUPS`, rounded by largest
    remainder so that they add up to ``n``."""
    total = sum(w for _, w in GROUPS)
    exact = [n * w / total for _, w in GROUPS]
    counts = [math.floor(x) for x in exact]
    for k in sorted(range(len(GROUPS)), key=lambda k: counts[k] - exact[k])[:n - sum(counts)]:
        counts[k] += 1
    return [(name, c) for (name, _), c in zip(GROUPS, counts, strict=True)]


def _loguniform(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def draw_loop(group: str, loop_type: str, controller: str, seed: int,
              variant: int = 0) -> SimulatedLoop:
    """One loop of ``group`` (a name of :data:`GROUPS`), its parameters drawn from ``seed``.

    Ranges (uniform unless said), and why:

    * process: flow (self-regulating, FOPDT) K 0.5..2 %/%, T 5..60 s, dead time 1..10 s;
      level (integrating, IPDT) K 0.01..0.1 %/s per % (log-uniform), dead time 1..10 s: the
      spread of fast and slow flow and level loops;
    * tuning: SIMC PI (:func:`simc`) times 0.7..1.4, a sensible tuning as found in plants;
    * noise: transmitter noise std 0.02..0.5 % (log-uniform), a good transmitter to a noisy
      flow meter, cut to :data:`NOISE_OP`/Kc so the noise the controller passes to the valve
      stays below 1.5 % (a loop noisier than that gets a PV filter or a lower gain in a
      plant); with J down to 0 this includes slip jumps far below the noise;
    * load: an Ornstein-Uhlenbeck walk at the process output, time constant 600 s, stationary
      std 0.1..1 %, the slow drift every plant has;
    * ``choudhury`` and ``karnopp``: S 0.5..5 %, J = 0 (pure deadband) for one loop in six,
      else 0..S, the range reported for sticky valves; the Karnopp valve is given resolution J
      and deadband S - J (spec 1.7);
    * ``clean``: a linear valve, noise and load only;
    * ``aggressive``: a linear valve and Kc = Ku/GM with the gain margin GM 1.05..1.2: a loop
      tuned close to its stability limit, lightly damped, ringing at about its ultimate period
      Pu on the noise and the load (Kc is about 1.6..2.8 times SIMC's). The factor 2.5..4
      first planned would put most of these loops beyond the limit, where the oscillation
      grows until the output saturates at 0 or 100 %, a cycle no plant would run with;
    * ``external``: a linear valve and a sinusoid at the process output of amplitude 2..20 %
      (cut down so the OP amplitude stays within 15 % and the PV's within 20 %, keeping the
      loop off its output limits) and a period near the loop's own (``variant`` 0: Pu·0.8..1.5,
      Pu the ultimate period) or away from it (``variant`` 1: Pu·4..20, the periods of
      stiction cycles: the classic false alarm).
    """
    rng = np.random.default_rng(seed)
    flow = loop_type == "self-regulating"
    if flow:
        gain, tau, dead = rng.uniform(0.5, 2.0), rng.uniform(5.0, 60.0), rng.uniform(1.0, 10.0)
    else:
        gain, tau, dead = _loguniform(rng, 0.01, 0.1), 0.0, rng.uniform(1.0, 10.0)
    noise = _loguniform(rng, 0.02, 0.5)
    walk_time_constant = 600.0
    walk_std = rng.uniform(0.1, 1.0) / math.sqrt(walk_time_constant / 2.0)
    kc, ti = simc(loop_type, gain, tau, dead)
    kc *= rng.uniform(0.7, 1.4)
    s = j = 0.0
    valve = "linear"
    sine_amplitude, sine_period = 0.0, 60.0
    scan_delay = E2_UPDATE if controller == "e2.pid" else DT
    process = (f"flow K={gain:.3g} T={tau:.3g}s L={dead:.3g}s" if flow
               else f"level K={gain:.3g}/s L={dead:.3g}s")
    what = ""
    if group in ("choudhury", "karnopp"):
        valve = group
        s = float(rng.uniform(0.5, 5.0))
        j = 0.0 if rng.uniform() < 1.0 / 6.0 else float(rng.uniform(0.0, s))
        what = f"{group} S={s:.2f} J={j:.2f}" + (
            f" (nominal; {karnopp_reversal_band(s, j):.2f} on reversal)"
            if group == "karnopp" else "")
    elif group == "clean":
        what = "linear valve"
    elif group == "aggressive":
        ku, _ = ultimate(loop_type, gain, tau, dead, ti, scan_delay)
        margin = rng.uniform(1.05, 1.2)
        kc = ku / margin
        what = f"linear valve, aggressive Kc (GM {margin:.2f})"
    elif group == "external":
        _, pu = ultimate(loop_type, gain, tau, dead, ti, scan_delay)
        ratio = rng.uniform(0.8, 1.5) if variant == 0 else _loguniform(rng, 4.0, 20.0)
        sine_period = pu * ratio
        w = np.array([2.0 * math.pi / sine_period])
        lf = kc * _open_loop(loop_type, gain, tau, dead + scan_delay, ti, w)[0]
        sens = abs(1.0 / (1.0 + lf))  # PV per unit of disturbance
        ctrl = abs(lf / (1.0 + lf)) / max(abs(lf / kc / (1.0 + 1.0 / (1j * w[0] * ti))), 1e-12)
        sine_amplitude = min(rng.uniform(2.0, 20.0), 20.0 / sens, 15.0 / ctrl)
        near = "near" if variant == 0 else "away from"
        what = (f"linear valve, external sine {sine_amplitude:.2g}% period "
                f"{sine_period:.3g}s ({near} the loop's {pu:.3g}s)")
    else:
        raise InputError(f"group {group!r}: expected one of {', '.join(g for g, _ in GROUPS)}")
    noise = min(noise, NOISE_OP / kc)
    case = f"{process}, {controller}, {what}, noise {noise:.2g}"
    return simulate_loop(loop_type=loop_type, controller=controller, valve=valve, s=s, j=j,
                         noise=noise, gain=gain, time_constant=tau, dead_time=dead, kc=kc,
                         ti=ti, walk_std=walk_std, walk_time_constant=walk_time_constant,
                         sine_amplitude=sine_amplitude, sine_period=sine_period, case=case,
                         seed=seed)


def make_set(n: int = 240, seed: int = 0) -> list[SimulatedLoop]:
    """A balanced, seeded set of ``n`` simulated loops (same ``n`` and ``seed``, same loops).

    Composition (:data:`GROUPS`, in twelfths, rounded to whole loops): half sticky, 4/12
    Choudhury valves and 2/12 Karnopp valves; half clean, 2/12 a linear valve with noise and
    load only, 2/12 an aggressive tuning, 2/12 an external oscillating disturbance (every
    other one near the loop's own period, the others away from it). Within each group the
    loops alternate flow (self-regulating) and level (integrating), and the controller cycles
    through :data:`CONTROLLERS` every two loops, so each group holds each loop type and
    controller equally (to within one loop). For n = 240: 80 Choudhury, 40 Karnopp, 40 clean,
    40 aggressive, 40 external. Loop k's parameters and noise come from the seed
    ``SeedSequence([seed, k])``; the ranges are in :func:`draw_loop`.
    """
    if n < 1:
        raise InputError(f"n = {n}: at least one loop is needed")
    loops: list[SimulatedLoop] = []
    for group, count in _counts(n):
        for i in range(count):
            k = len(loops)
            loop_seed = int(np.random.SeedSequence([seed, k]).generate_state(1)[0])
            loops.append(draw_loop(group, LOOP_TYPES[i % 2], CONTROLLERS[(i // 2) % 3],
                                   loop_seed, variant=(i // 6) % 2))
    return loops


# ----------------------------------------------------------------------------- export

def write_csv(loop: SimulatedLoop | LoopData, path: str | os.PathLike[str], *,
              position: bool = False) -> None:
    """Write a loop as a historian CSV: columns t (s), sp, pv, op, mode (1 = AUTO), and the
    true stem position too when ``position`` (a historian rarely has it). Values are written
    with ``repr`` so :func:`loopworks.analysis.loopdata.read_csv` reads them back exactly."""
    data = loop.data if isinstance(loop, SimulatedLoop) else loop
    columns: list[tuple[str, FloatArray | None]] = [
        ("t", data.t), ("sp", data.sp), ("pv", data.pv), ("op", data.op), ("mode", data.mode)]
    if position:
        columns.append(("position", data.position))
    present = [(name, values) for name, values in columns if values is not None]
    with open(path, "w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh)
        writer.writerow([name for name, _ in present])
        for row in zip(*(values for _, values in present), strict=True):
            writer.writerow([repr(float(v)) for v in row])
