r"""``valve.karnopp``: a spring-diaphragm valve with Karnopp stick-slip friction (spec 1.6).

The physical valve of plant-and-tuning 1.6 (Choudhury 2005's "physics" reference; ``sim_karnopp()``
of fellipegm/valve_estimation): the controller output ``op`` (%) sets the I/P converter, whose
pressure P reaches the diaphragm through a first-order lag (the positioner/I-P lag ``tau_ip``);
the stem of a spring-return actuator moves against friction::

    tau_ip·dP/dt = P_op - P,      P_op = p_min + (p_max - p_min)·op/100    (op clipped to 0..100)
    m·dv/dt = Sa·P - k·x - F_init - F_f,      dx/dt = v,      x in [x_min, x_max]

Friction (spec 1.6; Karnopp 1985, zero-velocity band DV = ``dv``):

* sliding (|v| > dv): F_f = [Fc + (Fs - Fc)·exp(-(v/vs)²)]·sign(v) + Fv·v (Coulomb, Stribeck,
  viscous; vs = 0 drops the Stribeck term);
* in the zero-velocity band (|v| <= dv): with F_r = Sa·P - k·x - F_init, the stem sticks
  (v = 0, F_f = F_r) while |F_r| <= Fs, and breaks away in the direction of F_r with
  F_f = sign(F_r)·Fs (+ Fv·v) once |F_r| > Fs (the C++ code's ``|F_at| >= F_s`` boundary is
  immaterial in floating point);
* a velocity that changes sign within a substep means the stem stopped: v = 0, and the band
  rule decides at the next substep whether it stays stuck (the C++ "re-sticks when velocity
  changes sign");
* at a travel limit the stem stops (x clamped, v = 0, as the C++ code does); it stays there
  while F_r pushes it into the stop or |F_r| <= Fs.

``position`` = 100·(x - x_min)/(x_max - x_min) %; ``flow`` = the inherent characteristic of
that position (as for the data-driven valves, ``valve.choudhury``).

Integration (loopworks' method; the C++ uses an explicit trapezoidal scheme at 1e-5 s)
-----------------------------------------------------------------------------------------

``op`` is held over the scan (zero-order hold). Each scan of length dt is cut into
n = ceil(dt/``substep``) equal substeps h = dt/n (at most ``max_substeps``; a longer scan gets
a longer substep). Per substep:

1. the I/P lag exactly: P <- P_op + (P - P_op)·exp(-h/tau_ip);
2. the friction branch from the velocity at the start of the substep (band, or sliding with
   the Coulomb + Stribeck level at that velocity), then semi-implicit (symplectic) Euler with
   the viscous term implicit::

       v' = (m·v + h·(Sa·P - F_init - k·x - F_cs)) / (m + h·Fv [+ h²·k])
       x' = x + h·v'

   The viscous term must be implicit: with the spec's valve m/Fv = 13 µs, far below any
   sensible substep, and the implicit form gives the quasi-static creep speed exactly
   (Fv·v + F_cs(v) = F_r at a fixed point). The spring is explicit (symplectic Euler conserves
   the energy of an undamped stem, so a low-friction slip overshoots honestly) while
   h²·k <= 2m + h·Fv, half the stability bound 4m + 2h·Fv; beyond that the h²·k term makes the
   spring implicit too (stable, slightly dissipative).
3. the band / sign-change / travel-limit rules above.

A stuck stem whose applied force stays within the static band for the whole scan (F_r moves
monotonically within a scan, P being an exponential towards P_op, so both ends are checked)
is advanced in one exact step of the lag, without substeps.

With the default ``substep`` = 1 ms a 0.1 s scan has 100 substeps. Against hand solutions (test
suite): a frictionless step response is within 0.0035 % of travel of the exact second-order
solution, and a 4 times finer substep changes the position scan-rate dither leaves the stem
at by less than 0.02 % of travel (the dither effect itself is 1.4 %; during the dither, with a
0.05 s I/P lag, the two paths differ by up to 0.06 %). Use 1e-5 s to resolve the swing of a
lightly damped stem (period 2·pi·sqrt(m/k) = 17 ms for the spec's m and k). The cost is in
the sliding scans only.

Parameters: the spec's real-valve set (spec 1.6, ``run_models.cpp`` PARAM_VALVULA and
PARAM_ATRITO_KARNOPP, which the spec quotes rounded: p_min = 41368 Pa = 6 psi "41.4 kPa",
tau_ip = 1/0.28 s "3.57 s"). That valve is very sticky (S ≈ 24 % by the force balance below)
and, with F_init = 2550 N, not bench-set: without friction, op 50 % holds the stem at
(Sa·P - F_init)/k = 11.29 mm, 38.9 % of travel (frictionless gain 1.0104 %/%, offset -11.6 %).
``f_init = 1840.8`` (= Sa·p_min) bench-sets it to 0 % at op 0 %.

Stiction as S and J (spec 1.1 [I], 1.7 [I])
-------------------------------------------

Instead of ``f_s``, ``f_c`` give ``s``, ``j`` or ``resolution``, ``deadband`` (% of op span;
J = RES, S = DB + RES as for the data-driven valves). With one % of op worth
U = Sa·(p_max - p_min)/100 newtons, ``sj_mapping`` (spec 1.1) chooses

* ``force_balance`` (default, spec 1.1 [I]): S = (Fs + Fc)/U, J = (Fs - Fc)/U, i.e.
  Fs = U·(S + J)/2 = U·fs, Fc = U·(S - J)/2 = U·fd (needs J <= S);
* ``valve_estimation`` (the estimation code's conversion [S]): S = 2·Fs/U, J = (Fs - Fc)/U,
  i.e. Fs = U·S/2, Fc = Fs - U·J (needs J <= S/2).

The default valve is S = 23.990 %, J = 1.297 % (force balance) or S = 25.287 %, J = 1.2968 %
(valve_estimation; the spec's pair). See :func:`forces_from_sj` and :func:`sj_from_forces`.
With Coulomb friction only (``v_s = 0``) and a slow ramp, the force-balance S and J are what
the valve shows (breakaway from rest past fs, reversal after S plus the viscous share; tested).
With the Stribeck term a slowly driven stem creeps with friction near Fs, so the reversal band
in op tends to 2·Fs/U, the estimation code's S [I].

Initial state
-------------

Without ``y0`` the first op sets the valve at rest in equilibrium with it: P = P_op, and x where
the spring balances the actuator with no friction force, (Sa·P - F_init)/k clipped to the
travel (k = 0: x at op % of travel); the first scan only initialises. With ``y0`` (% of
travel) the stem starts at rest there with the pressure that holds it without friction,
P = (k·x + F_init)/Sa.

Before its first scan the valve publishes its start (issue 11 point 8): ``y0``, or without
``y0`` the position its first scan gives for the op latched now (at rest in equilibrium with
it), as the data-driven valves do.

Status: as for the data-driven valves: an Uncertain op gives Uncertain outputs; a Bad or
non-finite op either freezes the whole state (``bad_op = hold``, outputs Bad) or drives the
actuator with ``fail_op`` (``fail``: loss of signal; outputs Uncertain: substitute). A scan
whose integration does not stay finite (only parameters at the edge of the float range can
do that, e.g. a diaphragm area of 1e-300 m²) is skipped: the state holds and the outputs keep
their values with status Bad: configuration error (0x04).

Options for the spec's [I] points
---------------------------------

* ``sj_mapping`` (spec 1.1): ``force_balance`` (default) or ``valve_estimation``.
* ``dv`` (spec 1.6, Karnopp's zero-velocity band; default 1e-6 m/s) and the integration
  ``substep`` / ``max_substeps`` (loopworks' method, above).
* ``bad_op`` [practice], as for the data-driven valves.

Worked example: dither on a stuck valve (spec 2.2)::

    import loopworks
    v = loopworks.create_block("valve.karnopp", tau_ip=0.05)
    v.step(0.1, op=50.0)          # first op: at rest, position 38.915 % (not bench-set)
    for k in range(50):
        v.step(0.1, op=55.0)      # +5 % of op = +308 N < Fs = 780 N: still 38.915 %
    for k in range(600):          # dither +-12 % of op, toggled every scan
        r = v.step(0.1, op=55.0 + (12.0 if k % 2 == 0 else -12.0))
    r["position"].value           # about 40.30 %: the stem crept while F_r + dither > Fs

The lag passes tanh(0.1 s/(2·tau_ip)) = 76 % of the square wave's amplitude, 564 N, so the stem
creeps until the mean applied force is about Fs - 564 N = 216 N. As a replay of ``op.csv``
(columns ``t,op``): ``loopworks replay valve.karnopp op.csv -p tau_ip=0.05``.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from loopworks.blocks.block import Block
from loopworks.blocks.kernel import FloatArray, IntArray, primitive
from loopworks.blocks.layout import index
from loopworks.blocks.params import Param, Port
from loopworks.blocks.primitives import clamp, finite, sign
from loopworks.blocks.registry import register
from loopworks.blocks.status import BAD_CONFIGURATION_ERROR
from loopworks.errors import ParameterError
from loopworks.plant.valve import (
    CHAR_EQUAL,
    CHAR_LINEAR,
    COMMON_COEFFS,
    COMMON_STATES,
    INPUTS,
    OUTPUTS,
    U,
    Y,
    flow_of,
    hold,
    op_in,
    op_status,
    publish_start,
    sj_from_resolution_deadband,
)

#: the coefficient array p: the common valve part, then the actuator, friction and
#: integration coefficients (dp = p_max - p_min, h = substep, n_max = max_substeps)
COEFFS = (*COMMON_COEFFS, "m", "k", "sa", "f0", "x_min", "x_max", "p_min", "dp", "f_c", "f_s",
          "f_v", "v_s", "tau", "dv", "h", "n_max")
#: the state array x: init, position (%), then stem position x (m), velocity v (m/s),
#: actuator pressure p (Pa), the stuck flag and the friction force (N)
STATES = (*COMMON_STATES, "x", "v", "p", "stuck", "friction")
P, X = index(COEFFS, "P"), index(STATES, "X")


def forces_from_sj(s: float, j: float, sa: float, dp: float,
                   mapping: str = "force_balance") -> tuple[float, float]:
    """(Fs, Fc) in N from S, J in % of op span, spec 1.1. U = Sa·dp/100 N per %:
    ``force_balance`` Fs = U·(S + J)/2, Fc = U·(S - J)/2; ``valve_estimation`` Fs = U·S/2,
    Fc = Fs - U·J."""
    unit = sa * dp / 100.0
    if mapping == "valve_estimation":
        f_s = unit * s / 2.0
        return f_s, f_s - unit * j
    return unit * (s + j) / 2.0, unit * (s - j) / 2.0


def sj_from_forces(f_s: float, f_c: float, sa: float, dp: float,
                   mapping: str = "force_balance") -> tuple[float, float]:
    """(S, J) in % from Fs, Fc in N, spec 1.1: ``force_balance`` S = (Fs + Fc)/U,
    J = (Fs - Fc)/U; ``valve_estimation`` S = 2·Fs/U, J = (Fs - Fc)/U (U = Sa·dp/100)."""
    unit = sa * dp / 100.0
    if mapping == "valve_estimation":
        return 2.0 * f_s / unit, (f_s - f_c) / unit
    return (f_s + f_c) / unit, (f_s - f_c) / unit


@primitive
def holds(f_r: float, xs: float, f_s: float, x_min: float, x_max: float) -> bool:
    """A stem at rest stays: |F_r| <= Fs, or it sits on a travel stop that F_r pushes it into."""
    if abs(f_r) <= f_s:
        return True
    if xs <= x_min and f_r < 0.0:
        return True
    return xs >= x_max and f_r > 0.0


@primitive
def karnopp_init(p: FloatArray, x: FloatArray, p_op: float, op: float) -> None:
    """First op: P = P_op and the stem at rest where the spring balances the actuator."""
    k = p[P.k]
    if k > 0.0:
        xs = clamp((p[P.sa] * p_op - p[P.f0]) / k, p[P.x_min], p[P.x_max])
    else:
        xs = p[P.x_min] + (p[P.x_max] - p[P.x_min]) * op / 100.0
    x[X.x] = xs
    x[X.v] = 0.0
    x[X.p] = p_op
    x[X.stuck] = 1.0
    x[X.friction] = clamp(p[P.sa] * p_op - p[P.f0] - k * xs, -p[P.f_s], p[P.f_s])
    x[X.init] = 1.0


@primitive
def karnopp_advance(dt: float, p: FloatArray, x: FloatArray, p_op: float) -> None:
    """Integrate one scan of length dt with op held (module docstring, Integration)."""
    m = p[P.m]
    k = p[P.k]
    sa = p[P.sa]
    f0 = p[P.f0]
    x_min = p[P.x_min]
    x_max = p[P.x_max]
    f_c = p[P.f_c]
    f_s = p[P.f_s]
    f_v = p[P.f_v]
    v_s = p[P.v_s]
    tau = p[P.tau]
    dv = p[P.dv]
    xs = x[X.x]
    v = x[X.v]
    pr = x[X.p]
    if x[X.stuck] != 0.0:  # a whole scan stuck: one exact step of the lag
        p_end = p_op
        if tau > 0.0:
            p_end = p_op + (pr - p_op) * math.exp(-dt / tau)
        f_end = sa * p_end - f0 - k * xs
        if (holds(sa * pr - f0 - k * xs, xs, f_s, x_min, x_max)
                and holds(f_end, xs, f_s, x_min, x_max)):
            x[X.p] = p_end
            x[X.friction] = clamp(f_end, -f_s, f_s)
            return
    ratio = dt / p[P.h]
    n = int(p[P.n_max])
    if ratio < p[P.n_max]:  # compared as floats first: no int overflow for a huge dt
        n = max(1, math.ceil(ratio))
    h = dt / n
    lag = 0.0
    if tau > 0.0:
        lag = math.exp(-h / tau)
    den = m + h * f_v
    if h * h * k > 2.0 * m + h * f_v:  # beyond half the symplectic stability bound
        den = den + h * h * k
    stuck = x[X.stuck]
    friction = x[X.friction]
    for _ in range(n):
        pr = p_op + (pr - p_op) * lag
        f_r = sa * pr - f0 - k * xs
        if abs(v) <= dv:
            if holds(f_r, xs, f_s, x_min, x_max):
                v = 0.0
                stuck = 1.0
                friction = clamp(f_r, -f_s, f_s)
                continue
            d = sign(f_r)
            f_cs = d * f_s
        else:
            d = sign(v)
            if v_s > 0.0:
                r = v / v_s
                f_cs = d * (f_c + (f_s - f_c) * math.exp(-r * r))
            else:
                f_cs = d * f_c
        stuck = 0.0
        v_new = (m * v + h * (f_r - f_cs)) / den
        if v_new * d < 0.0:  # the stem stopped within the substep
            v_new = 0.0
        xs = xs + h * v_new
        friction = f_cs + f_v * v_new
        if xs < x_min:
            xs = x_min
            v_new = 0.0
        elif xs > x_max:
            xs = x_max
            v_new = 0.0
        v = v_new
    x[X.x] = xs
    x[X.v] = v
    x[X.p] = pr
    x[X.stuck] = stuck
    x[X.friction] = friction


def karnopp_kernel(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                   y: FloatArray, ys: IntArray) -> None:
    """One scan of ``valve.karnopp`` (module docstring)."""
    op = op_in(p, u[U.op], us[U.op], P)
    if math.isnan(op):
        hold(p, x, y, ys, P, X)
        return
    p_op = p[P.p_min] + p[P.dp] * op / 100.0
    saved = (x[X.x], x[X.v], x[X.p], x[X.stuck], x[X.friction], x[X.init])
    if x[X.init] == 0.0:
        karnopp_init(p, x, p_op, op)
    else:
        karnopp_advance(dt, p, x, p_op)
    if not (finite(x[X.x]) and finite(x[X.v]) and finite(x[X.p]) and finite(x[X.friction])):
        x[X.x], x[X.v], x[X.p], x[X.stuck], x[X.friction], x[X.init] = saved
        ys[Y.position] = BAD_CONFIGURATION_ERROR
        ys[Y.flow] = BAD_CONFIGURATION_ERROR
        return
    # x is within [x_min, x_max]: the clamp only removes rounding (100.00000000000003)
    pos = clamp(100.0 * ((x[X.x] - p[P.x_min]) / (p[P.x_max] - p[P.x_min])), 0.0, 100.0)
    x[X.position] = pos
    y[Y.position] = pos
    y[Y.flow] = flow_of(p, pos, P)
    status = op_status(u[U.op], us[U.op])
    ys[Y.position] = status
    ys[Y.flow] = status


_SJ_SETS: tuple[tuple[str, str], ...] = (("f_s", "f_c"), ("s", "j"), ("resolution", "deadband"))


@register
class Karnopp(Block):
    """Spring-diaphragm valve with Karnopp stick-slip friction and an I/P lag (spec 1.6)."""

    kind = "valve.karnopp"
    summary = "physical valve: spring-diaphragm actuator, Karnopp friction, I/P lag " \
              "(plant-and-tuning 1.6)"
    kernel = staticmethod(karnopp_kernel)
    PARAMS: ClassVar[tuple[Param, ...]] = (
        Param("m", 1.6, "kg", "moving mass of stem and actuator (spec 1.6)", lo=0.0),
        Param("k", 210490.0, "N/m", "actuator spring constant: spring force k·x at stem "
              "position x (spec 1.6)", lo=0.0, lo_open=False),
        Param("sa", 0.0445, "m²", "diaphragm area Sa: actuator force Sa·P at pressure P "
              "(spec 1.6)", lo=0.0),
        Param("f_init", 2550.0, "N", "spring preload F_init: spring force at x = 0, against "
              "Sa·P (spec 1.6)"),
        Param("x_min", 0.0, "m", "stem travel, low end (spec 1.6)"),
        Param("x_max", 0.029, "m", "stem travel, high end (> x_min; spec 1.6)"),
        Param("p_min", 41368.0, "Pa", "actuator pressure at op 0 % (spec 1.6: 41.4 kPa)",
              lo=0.0, lo_open=False),
        Param("p_max", 180000.0, "Pa", "actuator pressure at op 100 % (> p_min; spec 1.6)"),
        Param("f_s", None, "N", "static friction Fs: a stuck stem breaks away when the net "
              "applied force exceeds it (spec 1.6)", lo=0.0, lo_open=False,
              default_text="780.0 (no set given)"),
        Param("f_c", None, "N", "Coulomb friction Fc <= Fs: the friction force of a sliding stem, "
              "besides the Stribeck and viscous terms (spec 1.6)", lo=0.0,
              lo_open=False, default_text="700.0 (no set given)"),
        Param("s", None, "%", "Choudhury S instead of f_s, f_c, mapped by sj_mapping "
              "(spec 1.1, 1.7)", lo=0.0, lo_open=False, default_text="-"),
        Param("j", None, "%", "Choudhury J instead of f_s, f_c (spec 1.1, 1.7)", lo=0.0,
              lo_open=False, default_text="-"),
        Param("resolution", None, "%", "practitioner's resolution RES = J instead of f_s, f_c "
              "(spec 1.7)", lo=0.0, lo_open=False, default_text="-"),
        Param("deadband", None, "%", "practitioner's deadband DB = S - J instead of f_s, f_c "
              "(spec 1.7)", lo=0.0, lo_open=False, default_text="-"),
        Param("sj_mapping", "force_balance", "", "S, J to forces: force_balance (spec 1.1 [I]) "
              "or valve_estimation (the estimation code's, spec 1.1 [S])", "choice",
              choices=("force_balance", "valve_estimation")),
        Param("f_v", 125000.0, "N·s/m", "viscous friction coefficient Fv: friction Fv·v at stem "
              "velocity v (spec 1.6)", lo=0.0,
              lo_open=False),
        Param("v_s", 5e-4, "m/s", "Stribeck velocity vs; 0 = no Stribeck term (spec 1.6)",
              lo=0.0, lo_open=False),
        Param("tau_ip", 1.0 / 0.28, "s", "I/P (positioner) first-order lag (spec 1.6: 3.57 s); "
              "0 = none", lo=0.0, lo_open=False),
        Param("dv", 1e-6, "m/s", "Karnopp zero-velocity band DV: a stem slower than this is at "
              "rest and sticks while the net force is within Fs (spec 1.6)", lo=0.0,
              lo_open=False),
        Param("substep", 1e-3, "s", "longest internal integration step: a scan is cut into "
              "ceil(dt/substep) equal substeps (see Integration below)",
              lo=0.0),
        Param("max_substeps", 100000, "", "most substeps per scan (a longer scan gets a longer "
              "substep)", "int", lo=1.0, lo_open=False, hi=1e9, hi_open=False),
        Param("y0", None, "%", "initial stem position, at rest; not given: at rest in "
              "equilibrium with the first op", lo=0.0, hi=100.0, lo_open=False,
              hi_open=False, default_text="first op"),
        Param("characteristic", "linear", "", "inherent flow characteristic giving the 'flow' "
              "output (ISA-75.11.01)", "choice", choices=("linear", "equal_percentage")),
        Param("rangeability", 50.0, "", "rangeability R of the equal-percentage "
              "characteristic", lo=1.0),
        Param("bad_op", "hold", "", "Bad or non-finite op: hold (freeze, outputs Bad) or fail "
              "(drive with fail_op, outputs Uncertain: substitute) [practice]", "choice",
              choices=("hold", "fail")),
        Param("fail_op", 0.0, "%", "op the actuator fails to when bad_op = fail", lo=0.0,
              hi=100.0, lo_open=False, hi_open=False),
    )
    INPUTS: ClassVar[tuple[Port, ...]] = INPUTS  # the valves' ports
    OUTPUTS: ClassVar[tuple[Port, ...]] = OUTPUTS
    COEFFS: ClassVar[tuple[str, ...]] = COEFFS
    STATES: ClassVar[tuple[str, ...]] = STATES

    def nonlinearity(self) -> str | None:
        """The stem's friction in words (Fs, Fc), None without static or Coulomb friction."""
        f_s, f_c = self.friction_forces()
        return (f"static friction Fs = {f_s:.4g} N, Coulomb Fc = {f_c:.4g} N"
                if f_s > 0.0 or f_c > 0.0 else None)

    def friction_forces(self) -> tuple[float, float]:
        """(Fs, Fc) in N from whichever parameter set was given (module docstring)."""
        prm: dict[str, Any] = self.params
        named = {n for n in self.given if prm.get(n) is not None}
        used = [(a, b) for a, b in _SJ_SETS if a in named or b in named]
        if len(used) > 1:
            names = [n for a, b in used for n in (a, b) if n in named]
            raise ParameterError(
                "valve.karnopp: give the friction as one set - f_s, f_c or s, j or resolution, "
                f"deadband (spec 1.1, 1.7) - not parameters of two sets: got {', '.join(names)}")
        if not used:
            return 780.0, 700.0
        a, b = used[0]
        missing = [n for n in (a, b) if n not in named]
        if missing:
            raise ParameterError(
                f"valve.karnopp: parameter '{missing[0]}' is missing: give both {a} and {b}")
        va, vb = float(prm[a]), float(prm[b])
        if a == "f_s":
            if not vb <= va:
                raise ParameterError(
                    f"valve.karnopp: parameter 'f_c' = {vb:g} is out of range: allowed "
                    f"[0, f_s] = [0, {va:g}] N (Coulomb friction <= static friction)")
            return va, vb
        s, j = (va, vb) if a == "s" else sj_from_resolution_deadband(va, vb)
        mapping = str(prm["sj_mapping"])
        limit = s if mapping == "force_balance" else s / 2.0
        if not j <= limit:
            what = "S" if mapping == "force_balance" else "S/2"
            raise ParameterError(
                f"valve.karnopp: J = {j:g} % is out of range for sj_mapping = '{mapping}': "
                f"allowed [0, {what}] = [0, {limit:g}] % (Coulomb friction Fc >= 0)")
        dp = float(prm["p_max"]) - float(prm["p_min"])
        return forces_from_sj(s, j, float(prm["sa"]), dp, mapping)

    def coefficients(self) -> dict[str, float]:
        prm: dict[str, Any] = self.params
        x_min, x_max = float(prm["x_min"]), float(prm["x_max"])
        if not x_max > x_min:
            raise ParameterError(
                f"valve.karnopp: parameter 'x_max' = {x_max:g} must be greater than x_min = "
                f"{x_min:g} m")
        p_min, p_max = float(prm["p_min"]), float(prm["p_max"])
        if not p_max > p_min:
            raise ParameterError(
                f"valve.karnopp: parameter 'p_max' = {p_max:g} must be greater than p_min = "
                f"{p_min:g} Pa")
        f_s, f_c = self.friction_forces()
        if not math.isfinite(x_max - x_min) or not math.isfinite(p_max - p_min):
            raise ParameterError(
                f"valve.karnopp: the travel x_max - x_min = {x_max:g} - {x_min:g} m and the "
                f"pressure span p_max - p_min = {p_max:g} - {p_min:g} Pa must be finite")
        y0 = math.nan if prm["y0"] is None else float(prm["y0"])
        if y0 == y0:
            x_y0 = x_min + (x_max - x_min) * y0 / 100.0
            p_y0 = (float(prm["k"]) * x_y0 + float(prm["f_init"])) / float(prm["sa"])
            if not math.isfinite(p_y0):
                raise ParameterError(
                    f"valve.karnopp: parameter 'sa' = {float(prm['sa']):g} m² is too small: "
                    f"the pressure that holds the stem at y0 = {y0:g} % is not finite")
        # the common valve part: no stroke limit and no start direction (the physics has both)
        return {"rate": math.inf,
                "char": CHAR_EQUAL if prm["characteristic"] == "equal_percentage"
                else CHAR_LINEAR,
                "lnr": math.log(float(prm["rangeability"])),
                "bad_fail": 1.0 if prm["bad_op"] == "fail" else 0.0,
                "fail_op": float(prm["fail_op"]), "start": 0.0, "y0": y0,
                "m": float(prm["m"]), "k": float(prm["k"]), "sa": float(prm["sa"]),
                "f0": float(prm["f_init"]), "x_min": x_min, "x_max": x_max, "p_min": p_min,
                "dp": p_max - p_min, "f_c": f_c, "f_s": f_s, "f_v": float(prm["f_v"]),
                "v_s": float(prm["v_s"]), "tau": float(prm["tau_ip"]), "dv": float(prm["dv"]),
                "h": float(prm["substep"]), "n_max": float(prm["max_substeps"])}

    def initial_state(self) -> list[float]:
        x = np.zeros(self.n_x)  # no y0: init = 0 until the first op, every state finite
        y0 = self.p[P.y0]
        if math.isnan(y0):
            return [float(v) for v in x]
        p = self.p
        xs = p[P.x_min] + (p[P.x_max] - p[P.x_min]) * y0 / 100.0
        x[X.x] = xs
        x[X.p] = (p[P.k] * xs + p[P.f0]) / p[P.sa]
        x[X.stuck] = 1.0
        x[X.init] = 1.0
        x[X.position] = y0
        return [float(v) for v in x]

    def reset(self) -> None:
        super().reset()
        self.publish_start()

    def publish_start(self) -> None:
        """Publish the outputs before the first scan for the op latched now (as
        :func:`loopworks.plant.valve.publish_start`)."""
        publish_start(self)
