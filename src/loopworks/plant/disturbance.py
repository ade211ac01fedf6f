r"""Load disturbances: kind ``disturbance.load`` (adds a disturbance ``d`` to its input ``u``).

A disturbance block is a summing junction with a signal generator: ``y = u + d``. Put it where
the disturbance enters the loop, e.g. between the valve and the process (a load on the
manipulated flow, ``"load.u" = "valve.position"``, ``"process.u" = "load.y"``), between the
process and the sensor (an output disturbance or a slow drift of the PV), or leave ``u``
unwired and use ``y`` (= ``d``) as a signal source. Events can still change ``u``.

The disturbance is the sum of five components, each off by default (t = the time of the scan,
see Time)::

    d(t) = bias
         + step_size                                   for t ≥ step_time
         + ramp_rate·(min(t, ramp_end) - ramp_start)   for t ≥ ramp_start
         + w(t)                                        random walk, w = 0 until walk_start
         + sine_amplitude·sin(2π·(t - sine_start)/sine_period + sine_phase)   for t ≥ sine_start

Random walk (seeded; the generator of ``sensor.transmitter``: MRG32k3a with Box-Muller normals
n_k, see that page). With ``walk_time_constant`` = inf it is a Wiener process (Brownian motion)
with diffusion ``walk_std`` σ (units/√s), sampled exactly::

    w(t_0) = 0 at the first scan at or after walk_start,   w(t + dt) = w(t) + σ·√dt·n_k

so its variance grows as σ²·(t - walk_start) whatever the scan time. A finite
``walk_time_constant`` τ makes it mean-reverting (an Ornstein-Uhlenbeck process,
dw = -w/τ·dt + σ·dB), again sampled exactly::

    w(t + dt) = a·w(t) + σ·√(τ/2·(1 - a²))·n_k,   a = exp(-dt/τ)

whose stationary standard deviation is σ·√(τ/2): a bounded, coloured load that does not wander
off over a long run (Gillespie, *Exact numerical simulation of the Ornstein-Uhlenbeck process*,
Phys. Rev. E 54, 1996). The scan's output uses w(t), the value at the start of the scan; the
step to w(t + dt) comes after, so the disturbance is piecewise constant over each scan as a
zero-order hold. One normal is drawn on each scan while the walk runs, so a run is
reproducible from the ``seed`` alone and a resumed run continues the stream exactly.

Time. t is the ``clock`` input when it is finite (a module feeds the module time, a replay the
``t`` column), else the block's own time: the sum of dt over earlier scans, starting at 0. The
switching instants use the 1e-9 s tolerance of module events, so a step at 20 s happens on the
scan at 20 s even when 0.1 s scans sum to 19.999999999999996.

Status. ``y`` carries the status of ``u`` unchanged (the disturbance neither degrades nor
improves it, as a summing junction, seed 000 line 28's pass-through); a non-finite ``u`` is
Bad input whatever its status says (issue 11 point 1), so a NaN ``u`` gives a NaN ``y`` with
status Bad (non-specific, 0, unless ``u`` arrived Bad: then its byte). A sum that overflows
(1e308 + 1e308) is Bad too. ``d`` is Good; in the one case its arithmetic leaves the float
range (a clock or parameters near it: ramp_rate·t, a sine angle) ``d`` is NaN with status Bad
and ``y`` is Bad with it; the random walk only advances to finite values.

Before its first scan the block publishes its outputs for t = 0 and the ``u`` input latched
now (issue 11 point 8): y = u + d(0), d(0) (the walk is 0 then), so a block that reads ``y``
earlier in a module's order sees the real signal, not 0.

Options for the spec's open points
----------------------------------

None: plant-and-tuning names load disturbances only as events of a scenario (plant-and-tuning
3.4 item 6, 4.1, 4.2); the components above are the textbook signals, each with its equation
here.

Example
-------

Python (a +2 step at 10 s on a 5 % per minute ramp starting at 0)::

    import loopworks
    load = loopworks.create_block("disturbance.load", step_size=2.0, step_time=10.0,
                                  ramp_rate=5.0 / 60.0)
    for k in range(12):
        r = load.step(1.0, u=40.0)
    print(r["y"].value, r["d"].value)    # t = 11 s: 40 + 2 + 11/12 = 42.916666666666664

Replay (``loopworks replay disturbance.load load.csv -p step_size=5 -p step_time=2
-p sine_amplitude=1 -p sine_period=4``), with ``load.csv``::

    t,u
    0,10
    1,10
    2,10
    3,10

gives ``y`` 10, 11, 15, 14 (t = 0..3 s: sin 0, sin 90°, 5 + sin 180°, 5 + sin 270°; the
second and fourth within rounding) and ``d`` 0, 1, 5, 4.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

from loopworks.blocks.block import Block
from loopworks.blocks.kernel import FloatArray, IntArray, primitive
from loopworks.blocks.layout import index
from loopworks.blocks.params import Param, Port
from loopworks.blocks.primitives import finite
from loopworks.blocks.registry import register
from loopworks.blocks.status import BAD, BAD_NON_SPECIFIC, GOOD_NC
from loopworks.errors import ParameterError
from loopworks.plant.sensor import (
    RNG_SLOTS,
    STREAM_DISTURBANCE,
    TWO_PI,
    at_or_after,
    rng_normal,
    rng_seed_state,
    scan_time,
)

INPUTS = (
    Port("u", 0.0, "u", "the signal the disturbance is added to; unwired = 0", status=True),
    Port("clock", math.nan, "s", "time (module time / replay t); NaN = the block's own "
         "time"),
)
OUTPUTS = (
    Port("y", 0.0, "u", "u + d, with the status of u", status=True),
    Port("d", 0.0, "u", "the disturbance alone (Good; Bad only when its arithmetic "
         "leaves the float range)", status=True),
)
#: the coefficient array p (coefficients())
COEFFS = ("bias", "step_size", "step_time", "ramp_rate", "ramp_start", "ramp_end",
          "walk_std", "walk_start", "walk_tau", "sine_amp", "sine_period", "sine_phase",
          "sine_start")
#: the state array x: own time, walk value, generator (RNG_SLOTS words from rng_s10)
STATES = ("time", "walk", "rng_s10", "rng_s11", "rng_s12", "rng_s20", "rng_s21", "rng_s22")
P, X, U, Y = index(COEFFS, "P"), index(STATES, "X"), index(INPUTS, "U"), index(OUTPUTS, "Y")


@primitive
def disturbance(p: FloatArray, t: float, walk: float) -> float:
    """d(t) with the walk's value ``walk`` (module docstring); NaN where the arithmetic leaves
    the float range."""
    d = float(p[P.bias])
    if at_or_after(t, p[P.step_time]):
        d += float(p[P.step_size])
    rate = float(p[P.ramp_rate])
    if rate != 0.0 and at_or_after(t, p[P.ramp_start]):
        d += rate * max(min(t, float(p[P.ramp_end])) - float(p[P.ramp_start]), 0.0)
    d += walk  # w(t): the walk at the start of this scan
    amplitude = float(p[P.sine_amp])
    if amplitude != 0.0 and at_or_after(t, p[P.sine_start]):
        angle = (TWO_PI * (t - float(p[P.sine_start])) / float(p[P.sine_period])
                 + float(p[P.sine_phase]))
        if finite(angle):
            d += amplitude * math.sin(angle)
        else:  # sin(±inf) is NaN compiled but an error in Python: NaN in both
            d = math.nan
    return d if finite(d) else math.nan


@primitive
def publish(u: FloatArray, us: IntArray, y: FloatArray, ys: IntArray, d: float) -> None:
    """y = u + d with the status of u (Bad non-specific when the sum is not finite), and d
    (Good, or Bad when NaN)."""
    total = float(u[U.u]) + d
    status = us[U.u]
    if not finite(total) and (status & 0xC0) != BAD:
        status = BAD_NON_SPECIFIC
    y[Y.y] = total
    ys[Y.y] = status
    y[Y.d] = d
    ys[Y.d] = GOOD_NC if finite(d) else BAD_NON_SPECIFIC


def load_kernel(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                y: FloatArray, ys: IntArray) -> None:
    """One scan: d(t) from the components, y = u + d (equations in the module docstring).
    Array elements are read into Python floats (plain IEEE arithmetic when interpreted)."""
    t = scan_time(float(u[U.clock]), x, X.time, dt)
    walk = float(x[X.walk])
    d = disturbance(p, t, walk)
    sigma = float(p[P.walk_std])
    if sigma > 0.0 and at_or_after(t, p[P.walk_start]):
        n = rng_normal(x, X.rng_s10)  # drawn on every such scan: the stream never shifts
        tau = float(p[P.walk_tau])
        if finite(tau):  # Ornstein-Uhlenbeck, exact step
            a = math.exp(-dt / tau)
            step = a * walk + sigma * math.sqrt(0.5 * tau * (1.0 - a * a)) * n
        else:  # Wiener process, exact step
            step = walk + sigma * math.sqrt(dt) * n
        if finite(step):
            x[X.walk] = step
    publish(u, us, y, ys, d)


@register
class Load(Block):
    """Load disturbance: y = u + d, d = bias + step + ramp + random walk + sinusoid."""

    kind = "disturbance.load"
    summary = ("Load disturbance y = u + d: bias, step, ramp, seeded random walk "
               "(Wiener or Ornstein-Uhlenbeck) and sinusoid")
    kernel = staticmethod(load_kernel)

    PARAMS: ClassVar[tuple[Param, ...]] = (
        Param("bias", 0.0, "u", "constant part of d"),
        Param("step_size", 0.0, "u", "step added from step_time on"),
        Param("step_time", 0.0, "s", "time of the step"),
        Param("ramp_rate", 0.0, "u/s", "slope of the ramp; 0 = no ramp"),
        Param("ramp_start", 0.0, "s", "time the ramp starts (d = 0 before)"),
        Param("ramp_end", math.inf, "s", "time the ramp stops and holds its value; inf = never",
              hi=math.inf, hi_open=False),
        Param("walk_std", 0.0, "u/√s", "random-walk diffusion σ: variance grows by σ²·dt per "
              "scan; 0 = no walk", lo=0.0, lo_open=False),
        Param("walk_start", 0.0, "s", "time the random walk starts (w = 0 before)"),
        Param("walk_time_constant", math.inf, "s", "mean reversion τ (Ornstein-Uhlenbeck, "
              "stationary std σ·√(τ/2)); inf = pure random walk", lo=0.0, hi=math.inf,
              hi_open=False),
        Param("seed", 0, "", "seed of the random walk (MRG32k3a via SplitMix64)", "int",
              lo=0.0, hi=2.0 ** 53, lo_open=False, hi_open=False),
        Param("sine_amplitude", 0.0, "u", "amplitude of the sinusoid; 0 = none"),
        Param("sine_period", 60.0, "s", "period of the sinusoid", lo=0.0),
        Param("sine_phase", 0.0, "deg", "phase of the sinusoid at sine_start"),
        Param("sine_start", 0.0, "s", "time the sinusoid starts (0 before)"),
    )
    INPUTS: ClassVar[tuple[Port, ...]] = INPUTS
    OUTPUTS: ClassVar[tuple[Port, ...]] = OUTPUTS
    COEFFS: ClassVar[tuple[str, ...]] = COEFFS
    STATES: ClassVar[tuple[str, ...]] = STATES

    def coefficients(self) -> dict[str, Any]:
        prm: dict[str, Any] = self.params
        if prm["ramp_end"] < prm["ramp_start"]:
            raise ParameterError(
                f"{self.kind}: parameter 'ramp_end' = {prm['ramp_end']:g} is out of range: it "
                f"must be >= ramp_start = {prm['ramp_start']:g}")
        return {"bias": float(prm["bias"]), "step_size": float(prm["step_size"]),
                "step_time": float(prm["step_time"]), "ramp_rate": float(prm["ramp_rate"]),
                "ramp_start": float(prm["ramp_start"]), "ramp_end": float(prm["ramp_end"]),
                "walk_std": float(prm["walk_std"]), "walk_start": float(prm["walk_start"]),
                "walk_tau": float(prm["walk_time_constant"]),
                "sine_amp": float(prm["sine_amplitude"]),
                "sine_period": float(prm["sine_period"]),
                "sine_phase": math.radians(float(prm["sine_phase"])),
                "sine_start": float(prm["sine_start"])}

    def initial_state(self) -> list[float]:
        x = [0.0] * self.n_x
        x[X.rng_s10:X.rng_s10 + RNG_SLOTS] = rng_seed_state(int(self.params["seed"]),
                                                            STREAM_DISTURBANCE)
        return x

    def reset(self) -> None:
        super().reset()
        self.publish_start()

    def publish_start(self) -> None:
        """Publish the outputs before the first scan: t = 0 (or the latched clock) and the
        ``u`` latched now (module docstring). A module that settles its wires calls it
        again."""
        clock = float(self.u[U.clock])
        t = clock if finite(clock) else float(self.x[X.time])
        publish(self.u, self.us, self.y, self.ys, disturbance(self.p, t, float(self.x[X.walk])))
