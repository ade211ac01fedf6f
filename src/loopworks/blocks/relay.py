r"""The relay experiment: kind ``relay`` (Åström & Hägglund 1984; plant-and-tuning 3.1, 3.3, 3.4).

The block sits between a loop's controller and what the controller drives. While ``enable`` is
off it passes the controller's output ``u_in`` through (within ``out_lo``..``out_hi``). When
``enable`` rises it takes over the loop for a relay test around the operating point and
afterwards hands the loop back.

Relay law (spec 3.1), with u0 the output when the test starts (``u_in`` then, or the ``u0``
parameter when given), e the error and ε the ``hysteresis`` (half-width; total band 2ε)::

    e = SP - PV (action reverse) or PV - SP (action direct)
    r = +1 when e > +ε,  r = -1 when e < -ε,  otherwise r keeps its last value
    out = clamp(u0 + d_up, out_lo, out_hi)    when r = +1
    out = clamp(u0 - d_down, out_lo, out_hi)  when r = -1

At the start r = +1 when e ≥ 0, else -1. ``amplitude_down`` (d_down) different from
``amplitude`` (d_up) gives the biased (asymmetric) relay of spec 3.3, from which the static gain
follows. With ``biased_stage`` the test runs in two stages: first the symmetric relay (d_down =
d_up) until it converges, then a second stage with ``amplitude_down``, again until it
converges; the ``stage`` output says which (1, 2).

In the second stage the relay can also switch around a shifted point (``offset``)::

    e = SP + Δ - PV (reverse) or PV - SP - Δ (direct),   Δ = offset · ā1

with ā1 the mean PV amplitude of the first stage's stable cycles (output ``shift`` = Δ). The
periodic-steady-state balance of spec 3.3 holds for any relay centre, so the PV mean moves by
about Δ and the output mean by Δ/K between the stages: a static gain that does not rest on the
small asymmetry of a biased relay on a lag-dominant plant (the biased relay's mean offsets are a
few % of d there, the size of a sticky valve's error). Since a = (4d/π)|G(jωu)| and |G(jωu)| ≤ K
on a low-pass plant, |Δ/K| ≤ (4/π)·|offset|·d: offset ≤ 0.5 keeps both relay levels on their
side of the new equilibrium.

Cycles and convergence (spec 3.4). A cycle runs from one switch to r = +1 to the next. For every
cycle the block measures its period P, its PV amplitude a (half the peak-to-peak) and its
means of the PV and of the output (over the scans of the cycle, each held for its dt). The
first ``discard_cycles`` cycles of a stage are ignored; the stage has converged when the last
``stable_cycles`` cycles agree and are stationary (the "2-3 stable cycles with ≤ 5 % spread"
default of spec 3.4, tol = ``tolerance``; P̄, ā: their mean period and amplitude; d_up + d_down: the
output's peak-to-peak)::

    max P - min P                   ≤ tol·P̄ + dt
    max a - min a                   ≤ tol·ā
    max mean(PV) - min mean(PV)     ≤ (tol + 2·dt/P̄)·ā
    max mean(out) - min mean(out)   ≤ tol·d_up + (d_up + d_down)·dt/P̄

The dt terms are the scan's own share: the relay switches on the scan grid, so a cycle is a
whole number of scans and moving one of its ends by a scan changes its period by dt and its
means by up to (peak-to-peak)·dt/P. The means test keeps a drifting loop (one not at rest
when the test began, a load moving it) from "converging": the static gain rests on those
means.

A stage whose stable cycles are shorter than ``MIN_CYCLE_SCANS`` scans (reason at the
constant) ends the test with ``phase`` 8, too fast, instead of converging.

End of the test. The test ends when it has converged (``phase`` 2) or is aborted (spec 3.4 item 7):
``timeout`` seconds since the start (3), |SP - PV| > ``max_deviation`` (4, runaway),
``max_cycles`` cycles in a stage without convergence (5), no relay switch for
``max_half_period`` seconds (6: no oscillation, e.g. a valve that never reverses), a Bad or
non-finite PV or SP, or one whose arithmetic overflows (SP - PV, a cycle's amplitude or
integral not finite) (7), or a cycle shorter than ``MIN_CYCLE_SCANS`` scans (8). On the scan
that ends it the output returns to u0 (item 7: restore u0) with ``active`` still 1, so a
controller that tracks ``out`` while ``active`` is on holds u0; from the next scan on the block
passes ``u_in`` through again and ``active`` is 0. A controller that re-initialises when
tracking stops (every loopworks controller does) then continues from u0: the handback is
bumpless. ``enable`` must fall and rise again for a new test.

Hand-over wiring (``loopworks.sim.tune`` does it): the controller's output goes to ``u_in``,
the consumers of the controller's output read ``out``, and the controller tracks ``out`` while
``active`` (generic ``pid``: ``track``/``track_value``; ``deltav.pid``: ``trk_in_d``/
``trk_val`` with ``track_enable``, the LO mode DeltaV uses for its tuner, vendor-blocks 5.1;
GE: ``man``/``manual_command``; S5: ``auto`` = ``inactive``, ``yh``; E2: ``override`` =
the ``override`` output, NaN with status Bad when inactive).

Outputs ``cycles``, ``period`` and ``amplitude`` report the latest full cycle of the running
stage; the full analysis (Ku, Pu, gains, dead time) is done on the recorded signals by
``loopworks.tuning.identify``.

Status. ``override``, ``period`` and ``amplitude`` carry a status: NaN (no test running, no full
cycle yet) with status Bad (non-specific), a value with Good; the E2 override cell ignores a Bad
override (vendor-blocks 3.7). ``out`` is Good, constant, while the relay drives it; otherwise it
passes ``u_in`` through with its status, clamped to ``out_lo``..``out_hi`` (with the status's
high or low limit bit where it is clamped); a ``u_in`` that is not finite leaves ``out`` at its
last value with status Bad (u_in's own, or non-specific). The other outputs are always finite.
Bad input: an enable rising while the PV or SP is Bad or non-finite starts no cycle (the test
ends at once with ``phase`` 7, returning u0 = ``u_in``, or the last finite output when ``u_in``
is Bad too); no state is ever left non-finite, so a new test after the inputs recover starts
clean.

Time. t is the ``clock`` input when finite, else the block's own time (the sum of dt).
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

from loopworks.blocks.block import Block
from loopworks.blocks.kernel import FloatArray, IntArray, primitive
from loopworks.blocks.layout import Array, index
from loopworks.blocks.params import Param, Port
from loopworks.blocks.primitives import clamp, finite
from loopworks.blocks.registry import register
from loopworks.blocks.status import (
    BAD_NON_SPECIFIC,
    CONSTANT,
    GOOD_NC,
    HIGH_LIMITED,
    LOW_LIMITED,
    UNCERTAIN,
)
from loopworks.errors import ParameterError

# Phase codes (output ``phase``)
(IDLE, RUNNING, CONVERGED, TIMEOUT, RUNAWAY, NOT_CONVERGED, NO_OSCILLATION, BAD_INPUT,
 TOO_FAST) = 0, 1, 2, 3, 4, 5, 6, 7, 8
PHASE_NAMES = ("idle", "running", "converged", "timeout", "runaway", "not_converged",
               "no_oscillation", "bad_input", "too_fast")
N_SLOTS = 5  # cycles remembered for the convergence test (stable_cycles ≤ N_SLOTS)
#: The shortest limit cycle the test accepts, in scans. The relay acts on the scan grid, so
#: every switch time, the period and the switch-to-extremum dead time are known to one scan
#: only: below 10 scans per period that is more than 10 % of the period (twice the 5 %
#: convergence tolerance of 3.4) and a half period has fewer than 5 samples to find the PV
#: extremum in. Such a cycle is the sampling's, not the plant's: a loop with no dead time
#: cycles every 2 scans, the relay chasing its own one-scan delay (issue 11).
MIN_CYCLE_SCANS = 10

INPUTS = (
    Port("sp", 0.0, "pv", "setpoint the relay switches around", status=True),
    Port("pv", 0.0, "pv", "process variable", status=True),
    Port("u_in", 0.0, "out", "the controller's output, passed through when no test runs",
         status=True),
    Port("enable", 0.0, "", "a rise (> 0.5) starts a test; a fall stops it"),
    Port("clock", math.nan, "s", "time (module time); NaN = the block's own time"),
)
OUTPUTS = (
    Port("out", 0.0, "out", "relay output during the test, else u_in (clamped to "
         "out_lo..out_hi)", status=True),
    Port("active", 0.0, "", "1 while the relay drives the loop (controller tracks out)"),
    Port("inactive", 1.0, "", "1 - active (for S5 auto)", choices=("MAN", "AUTO")),
    Port("override", math.nan, "out", "out while active, else NaN with status Bad (for E2 "
         "override)", status=True),
    Port("relay", 0.0, "", "relay state +1 / -1 while running (on the scan that ends "
         "the test: the state it switched to), else 0"),
    Port("phase", 0.0, "", "0 idle, 1 running, 2 converged, 3 timeout, 4 runaway, 5 not "
         "converged, 6 no oscillation, 7 bad input, 8 too fast (cycles under "
         f"{MIN_CYCLE_SCANS} scans)"),
    Port("stage", 0.0, "", "1 symmetric, 2 second (biased and/or offset), 0 not running "
         "(the ending scan keeps its stage)"),
    Port("shift", 0.0, "pv", "Δ: the relay's switching point minus SP (0 in the first "
         "stage)"),
    Port("cycles", 0.0, "", "cycles completed in the running stage"),
    Port("period", math.nan, "s", "period of the latest cycle (NaN, status Bad, before the "
         "first)", status=True),
    Port("amplitude", math.nan, "pv", "PV amplitude (half peak-to-peak) of the latest "
         "cycle (NaN, status Bad, before the first)", status=True),
)
#: the coefficient array p (coefficients()); sign: +1 reverse, -1 direct; u0: NaN = u_in at
#: the start; biased: 1 = biased_stage
COEFFS = ("d_up", "d_down", "hysteresis", "sign", "lo", "hi", "u0", "timeout",
          "max_deviation", "max_cycles", "max_half_period", "discard_cycles", "stable_cycles",
          "tolerance", "biased", "offset")
#: the state array x; the Arrays hold the N_SLOTS latest cycles, oldest first
STATES = (
    "time", "phase", "r", "u0", "t0", "t_switch", "t_up", "n_up", "pv_max", "pv_min",
    "stage", "enable_prev", "out", "period", "amplitude",
    Array("periods", N_SLOTS, "the latest cycle periods"),
    Array("amplitudes", N_SLOTS, "the latest cycle PV amplitudes"),
    "shift",            # Δ: the second stage's switching point minus SP
    "pv_integral",      # ∫PV dt over the running cycle
    "out_integral",     # ∫out dt over the running cycle
    "cycle_time",       # Σdt over the running cycle
    Array("pv_means", N_SLOTS, "the latest cycle means of PV"),
    Array("out_means", N_SLOTS, "the latest cycle means of out"),
    "has_t_up",         # 1 once t_up holds a switch up of this test
    "has_cycle")        # 1 once period and amplitude hold a full cycle
P, X, U, Y = index(COEFFS, "P"), index(STATES, "X"), index(INPUTS, "U"), index(OUTPUTS, "Y")


@primitive
def _spread(x: FloatArray, first: int, n: int) -> float:
    """max - min over x[first:first + n]."""
    lo = math.inf
    hi = -math.inf
    for i in range(first, first + n):
        v = float(x[i])
        lo = min(lo, v)
        hi = max(hi, v)
    return hi - lo


@primitive
def _average(x: FloatArray, first: int, n: int) -> float:
    """Mean of x[first:first + n] (each term divided first: no overflow for finite x)."""
    total = 0.0
    for i in range(first, first + n):
        total += float(x[i]) / n
    return total


@primitive
def _stationary(x: FloatArray, stable: int, tol: float, d: float, span: float,
                dt: float) -> bool:
    """The last ``stable`` cycles agree (3.4, module docstring): (max - min) of their periods
    ≤ tol·P̄ + dt, of their amplitudes ≤ tol·ā, of their PV means ≤ (tol + 2dt/P̄)·ā and of
    their output means ≤ tol·d + span·dt/P̄ (span: the output's peak-to-peak)."""
    first = N_SLOTS - stable
    per = _average(x, X.periods + first, stable)
    amp = _average(x, X.amplitudes + first, stable)
    return (per > 0.0 and amp > 0.0
            and _spread(x, X.periods + first, stable) <= tol * per + dt
            and _spread(x, X.amplitudes + first, stable) <= tol * amp
            and _spread(x, X.pv_means + first, stable) <= (tol + 2.0 * dt / per) * amp
            and _spread(x, X.out_means + first, stable) <= tol * d + span * dt / per)


def relay_kernel(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                 y: FloatArray, ys: IntArray) -> None:
    """One scan of the relay experiment (equations in the module docstring)."""
    clock = float(u[U.clock])
    t = clock if finite(clock) and us[U.clock] >= UNCERTAIN else float(x[X.time])
    if finite(t + dt):
        x[X.time] = t + dt
    enable = float(u[U.enable]) > 0.5
    rising = enable and float(x[X.enable_prev]) < 0.5
    x[X.enable_prev] = 1.0 if enable else 0.0
    sign = float(p[P.sign])
    sp = float(u[U.sp])
    pv = float(u[U.pv])
    inputs_ok = (finite(sp) and finite(pv) and finite(sp - pv) and finite(sp + x[X.shift] - pv)
                 and us[U.sp] >= UNCERTAIN and us[U.pv] >= UNCERTAIN)
    u_in = float(u[U.u_in])
    u_in_ok = finite(u_in) and us[U.u_in] >= UNCERTAIN
    phase = int(x[X.phase])
    if rising and phase != RUNNING:  # a new test
        u0 = float(p[P.u0])
        if not finite(u0):
            u0 = u_in if u_in_ok else float(x[X.out])
        x[X.u0] = u0
        x[X.t0] = t
        x[X.t_switch] = t
        x[X.has_t_up] = 0.0
        x[X.n_up] = 0.0
        x[X.stage] = 1.0
        x[X.has_cycle] = 0.0
        x[X.shift] = 0.0
        x[X.pv_integral] = 0.0
        x[X.out_integral] = 0.0
        x[X.cycle_time] = 0.0
        e0 = sign * (sp - pv) if inputs_ok else 0.0
        x[X.r] = 1.0 if e0 >= 0.0 else -1.0
        x[X.pv_max] = pv if inputs_ok else 0.0
        x[X.pv_min] = pv if inputs_ok else 0.0
        phase = RUNNING
    elif not enable and phase != RUNNING:
        phase = IDLE
    r = float(x[X.r])
    u0 = float(x[X.u0])
    ending = False
    if phase == RUNNING:
        if not enable:
            phase = IDLE
            ending = True
        elif not inputs_ok:
            phase = BAD_INPUT
            ending = True
        elif abs(sp - pv) > float(p[P.max_deviation]):
            phase = RUNAWAY
            ending = True
        elif t - float(x[X.t0]) > float(p[P.timeout]) + 1e-9:
            phase = TIMEOUT
            ending = True
        elif t - float(x[X.t_switch]) > float(p[P.max_half_period]) + 1e-9:
            phase = NO_OSCILLATION
            ending = True
    if phase == RUNNING:
        e = sign * (sp + float(x[X.shift]) - pv)
        hyst = float(p[P.hysteresis])
        new_r = r
        if e > hyst:
            new_r = 1.0
        elif e < -hyst:
            new_r = -1.0
        if new_r != r:
            x[X.t_switch] = t
            if new_r > 0.0:  # a switch up closes a cycle
                period = t - float(x[X.t_up])
                amp = 0.5 * float(x[X.pv_max]) - 0.5 * float(x[X.pv_min])
                cyc = float(x[X.cycle_time])
                pv_mean = float(x[X.pv_integral]) / cyc if cyc > 0.0 else math.nan
                out_mean = float(x[X.out_integral]) / cyc if cyc > 0.0 else math.nan
                if float(x[X.has_t_up]) < 0.5:
                    pass  # the first switch up: no full cycle yet
                elif not (finite(period) and finite(amp) and finite(pv_mean)
                          and finite(out_mean)):
                    phase = BAD_INPUT  # the PV left the range of the arithmetic
                    ending = True
                else:
                    # shift the cycle memories and store this cycle
                    for i in range(N_SLOTS - 1):
                        x[X.periods + i] = x[X.periods + i + 1]
                        x[X.amplitudes + i] = x[X.amplitudes + i + 1]
                        x[X.pv_means + i] = x[X.pv_means + i + 1]
                        x[X.out_means + i] = x[X.out_means + i + 1]
                    x[X.periods + N_SLOTS - 1] = period
                    x[X.amplitudes + N_SLOTS - 1] = amp
                    x[X.pv_means + N_SLOTS - 1] = pv_mean
                    x[X.out_means + N_SLOTS - 1] = out_mean
                    x[X.period] = period
                    x[X.amplitude] = amp
                    x[X.has_cycle] = 1.0
                    x[X.n_up] = float(x[X.n_up]) + 1.0
                    n = int(x[X.n_up])
                    stable = int(p[P.stable_cycles])
                    d_down = float(p[P.d_down]) if float(x[X.stage]) > 1.5 \
                        or float(p[P.biased]) < 0.5 else float(p[P.d_up])
                    if (n >= int(p[P.discard_cycles]) + stable
                            and _stationary(x, stable, float(p[P.tolerance]), float(p[P.d_up]),
                                            float(p[P.d_up]) + d_down, dt)):
                        first = X.periods + N_SLOTS - stable
                        shift = float(p[P.offset]) * _average(x, X.amplitudes + N_SLOTS - stable,
                                                            stable)
                        if _average(x, first, stable) < (MIN_CYCLE_SCANS - 0.5) * dt:
                            phase = TOO_FAST
                            ending = True
                        elif float(p[P.biased]) > 0.5 and float(x[X.stage]) < 1.5:
                            if finite(shift):
                                x[X.stage] = 2.0  # the second stage starts with this cycle
                                x[X.n_up] = 0.0
                                x[X.shift] = shift  # Δ = offset · (mean stable amplitude)
                            else:
                                phase = BAD_INPUT
                                ending = True
                        else:
                            phase = CONVERGED
                            ending = True
                    elif n >= int(p[P.max_cycles]):
                        phase = NOT_CONVERGED
                        ending = True
                x[X.t_up] = t
                x[X.has_t_up] = 1.0
                x[X.pv_max] = pv
                x[X.pv_min] = pv
                x[X.pv_integral] = 0.0
                x[X.out_integral] = 0.0
                x[X.cycle_time] = 0.0
            r = new_r
            x[X.r] = r
    if (phase == RUNNING or ending) and finite(pv):
        x[X.pv_max] = max(float(x[X.pv_max]), pv)
        x[X.pv_min] = min(float(x[X.pv_min]), pv)
    lo = float(p[P.lo])
    hi = float(p[P.hi])
    if ending:
        out = clamp(u0, lo, hi)
        active = True
        x[X.r] = 0.0
    elif phase == RUNNING:
        d_down = float(p[P.d_down]) if float(x[X.stage]) > 1.5 or float(p[P.biased]) < 0.5 \
            else float(p[P.d_up])
        out = clamp(u0 + float(p[P.d_up]) if r > 0.0 else u0 - d_down, lo, hi)
        active = True
        # the cycle's integrals (zero-order hold: this scan's PV and output last dt)
        pv_int = float(x[X.pv_integral]) + pv * dt
        out_int = float(x[X.out_integral]) + out * dt
        if finite(pv_int) and finite(out_int):
            x[X.pv_integral] = pv_int
            x[X.out_integral] = out_int
            x[X.cycle_time] = float(x[X.cycle_time]) + dt
        else:  # the PV left the range of the arithmetic
            phase = BAD_INPUT
            out = clamp(u0, lo, hi)
            x[X.r] = 0.0
    else:  # passing u_in through, within the output limits; a non-finite u_in: the last out
        out = clamp(u_in, lo, hi) if finite(u_in) else float(x[X.out])
        active = False
    x[X.phase] = float(phase)
    if finite(out):
        x[X.out] = out
    running = active  # RUNNING, or the scan that ends the test
    y[Y.out] = out
    if active:
        ys[Y.out] = GOOD_NC | CONSTANT
    elif not finite(u_in):
        ys[Y.out] = us[U.u_in] if us[U.u_in] < UNCERTAIN else BAD_NON_SPECIFIC
    elif u_in > hi:  # passed through with its status, limit bits where clamped
        ys[Y.out] = (us[U.u_in] & 0xFC) | HIGH_LIMITED
    elif u_in < lo:
        ys[Y.out] = (us[U.u_in] & 0xFC) | LOW_LIMITED
    else:
        ys[Y.out] = us[U.u_in]
    y[Y.active] = 1.0 if active else 0.0
    y[Y.inactive] = 0.0 if active else 1.0
    y[Y.override] = out if active else math.nan
    y[Y.relay] = r if running else 0.0
    y[Y.phase] = float(phase)
    y[Y.stage] = float(x[X.stage]) if running else 0.0
    y[Y.shift] = float(x[X.shift]) if running else 0.0
    y[Y.cycles] = float(x[X.n_up])
    have = float(x[X.has_cycle]) > 0.5
    y[Y.period] = float(x[X.period]) if have else math.nan
    y[Y.amplitude] = float(x[X.amplitude]) if have else math.nan
    for i in range(Y.active, Y.amplitude + 1):
        ys[i] = GOOD_NC
    for i in (Y.override, Y.period, Y.amplitude):  # NaN = not available: Bad
        if not finite(float(y[i])):
            ys[i] = BAD_NON_SPECIFIC


@register
class Relay(Block):
    """Relay experiment: symmetric or biased relay with hysteresis, limits, abort rules."""

    kind = "relay"
    summary = ("relay auto-tuning experiment: symmetric or biased relay with hysteresis, "
               "convergence and abort rules, bumpless handback (plant-and-tuning 3.1-3.4)")
    kernel = staticmethod(relay_kernel)

    PARAMS: ClassVar[tuple[Param, ...]] = (
        Param("amplitude", 5.0, "out", "relay amplitude d (d_up): out = u0 + d while the error "
              "is above the band (spec 3.1)", lo=0.0),
        Param("amplitude_down", None, "out", "d_down: out = u0 - d_down below the band; differs "
              "from amplitude for the biased relay of spec 3.3", lo=0.0,
              default_text="amplitude"),
        Param("hysteresis", 0.0, "pv", "ε, half-width of the switching band around SP; above "
              "the noise band, 2-3 σ of the noise (spec 3.4)", lo=0.0, lo_open=False),
        Param("action", "reverse", "", "reverse: e = SP - PV; direct: e = PV - SP", "choice",
              choices=("reverse", "direct")),
        Param("out_lo", 0.0, "out", "low limit of the relay output"),
        Param("out_hi", 100.0, "out", "high limit of the relay output (> out_lo)"),
        Param("u0", None, "out", "centre of the relay; NaN = u_in when the test starts",
              default_text="u_in at the start"),
        Param("timeout", 3600.0, "s", "abort when the test has run this long (spec 3.4)", lo=0.0,
              hi=math.inf, hi_open=False),
        Param("max_deviation", math.inf, "pv", "abort when |SP - PV| exceeds this (runaway)",
              lo=0.0, hi=math.inf, hi_open=False),
        Param("max_cycles", 10, "", "abort when a stage has run this many cycles without "
              "converging (osPID: 20 peaks, spec 3.4)", "int", lo=1.0, hi=1e6, lo_open=False,
              hi_open=False),
        Param("max_half_period", 300.0, "s", "abort when the relay has not switched for this "
              "long: no oscillation (osPID: 5 min without a peak, spec 3.4)", lo=0.0, hi=math.inf,
              hi_open=False),
        Param("discard_cycles", 1, "", "cycles ignored at the start of each stage (spec 3.4)",
              "int", lo=0.0, hi=1e6, lo_open=False, hi_open=False),
        Param("stable_cycles", 2, "", f"cycles that must agree for convergence (≤ {N_SLOTS})",
              "int", lo=1.0, hi=float(N_SLOTS), lo_open=False, hi_open=False),
        Param("tolerance", 0.05, "", "convergence: (max - min)/mean of the periods and of the "
              "amplitudes of those cycles (spec 3.4: 5 %)", lo=0.0),
        Param("biased_stage", False, "", "after the symmetric relay converges, run a second "
              "stage with amplitude_down and/or the offset switching point (static gain, spec 3.3)",
              "bool"),
        Param("offset", 0.0, "", "second stage: the relay switches around SP + Δ, Δ = offset × "
              "the first stage's PV amplitude a (signed; 0 = around SP)"),
    )
    INPUTS: ClassVar[tuple[Port, ...]] = INPUTS
    OUTPUTS: ClassVar[tuple[Port, ...]] = OUTPUTS
    COEFFS: ClassVar[tuple[str, ...]] = COEFFS
    STATES: ClassVar[tuple[Any, ...]] = STATES

    def coefficients(self) -> dict[str, Any]:
        prm: dict[str, Any] = self.params
        lo, hi = float(prm["out_lo"]), float(prm["out_hi"])
        if not lo < hi:
            raise ParameterError(
                f"relay: parameter 'out_hi' = {hi:g} must be greater than out_lo = {lo:g}")
        d_up = float(prm["amplitude"])
        d_down = d_up if prm["amplitude_down"] is None else float(prm["amplitude_down"])
        if prm["biased_stage"] and d_down == d_up and prm["offset"] == 0.0:
            raise ParameterError(
                f"relay: parameter 'amplitude_down' = {d_down:g} must differ from amplitude "
                f"= {d_up:g}, or 'offset' must be non-zero, when biased_stage is on (the "
                "second stage must move the mean output)")
        return {"d_up": d_up, "d_down": d_down, "hysteresis": prm["hysteresis"],
                "sign": 1.0 if prm["action"] == "reverse" else -1.0, "lo": lo, "hi": hi,
                "u0": math.nan if prm["u0"] is None else float(prm["u0"]),
                "timeout": prm["timeout"], "max_deviation": prm["max_deviation"],
                "max_cycles": prm["max_cycles"], "max_half_period": prm["max_half_period"],
                "discard_cycles": prm["discard_cycles"], "stable_cycles": prm["stable_cycles"],
                "tolerance": prm["tolerance"], "biased": 1.0 if prm["biased_stage"] else 0.0,
                "offset": prm["offset"]}

    def initial_state(self) -> list[float]:
        return [0.0] * self.n_x  # every state finite (kernel.guarded_scan)

    def reset(self) -> None:
        super().reset()
        for i in (Y.override, Y.period, Y.amplitude):  # NaN before the first scan: Bad
            self.ys[i] = BAD_NON_SPECIFIC

    def initial_outputs(self) -> list[float]:
        return [0.0, 0.0, 1.0, math.nan, 0.0, 0.0, 0.0, 0.0, 0.0, math.nan, math.nan]
