r"""Identification from recorded relay cycles (plant-and-tuning 3.1-3.4, vendor-blocks 5.2).

Input: the sampled signals of a relay test (time ``t``, ``pv``, relay output ``u``, and the stage
of each sample when the test had a symmetric and a biased stage), plus what was applied
(:class:`RelayTest`). A cycle runs from one switch of the relay to its high level (u > u0) to the
next; the analysis uses the last ``cycles`` full cycles of a stage.

Amplitude and period (3.1, 3.4 item 5)::

    a   = mean over cycles of (max PV - min PV)/2             ("peaks")
    a1  = |PV₁|,  X₁ = (2/T)·Σ x(t_k)·e^(-jω t_k)·Δt_k        (first harmonic, ω = 2π/P, over the
                                                               whole cycles: "harmonic")
    P   = mean cycle length (switch to switch)

The first-harmonic amplitude averages the noise out (noise adds to the peaks but has almost no
component at ω); for a non-sinusoidal PV it is smaller than the peak amplitude a (a triangle's is
8/π² of its peak).

Ultimate gain, the two hysteresis conventions of 3.1 (named as such), d = (d_up + d_down)/2::

    ku_describing_function    = 4d/(π a)                  (gain margin at the identified point)
    ku_hysteresis_corrected   = 4d/(π √(a² - ε²))         (the real part; vendor-blocks 5.2)
    ku_harmonic               = |U₁| / |PV₁|              (measured first harmonics of u and PV)

``ku`` is the one ``ku_convention`` names (default ``hysteresis_corrected``, the DeltaV emulator
rule of vendor-blocks 5.2; with ε = 0 the first two agree). The identified point lies at phase
-π + arcsin(ε/a): ``phase_lag`` = π - arcsin(ε/a) rad, ``relay_gain`` Kφ = 4d/(πa) (AMIGO-f).

Static gain from the biased relay (3.3, Shen, Wu & Yu 1996; Berner 2017), over whole cycles::

    K = ∫(PV - PV0) dt / ∫(u - u0) dt

With a symmetric stage before the biased one, the same periodic-steady-state balance is taken
between the two stages, which cancels whatever offset PV0 and u0 carry (a loop not quite at
rest, a valve stuck away from its signal)::

    K = (mean PV over the biased cycles - mean PV over the symmetric cycles)
        / (mean u over the biased cycles - mean u over the symmetric cycles)

The balance is exact only over a window whose ends see the same PV (for K·e^(-Ls)/(Ts + 1),
integrating T·y' + y = K·u(t - L) over [t_a, t_b] gives T·(y(t_b) - y(t_a)) + ∫y = K·∫u(t - L)).
A relay switches on the scan after the PV crossed its band, so a window from switch to switch
ends up to a scan past the crossing, at a PV that differs from cycle to cycle by up to a scan
of PV slope; on a lag-dominant plant T times that is as large as the biased relay's whole mean
offset (issue 11: K = 1 read as 0.64..1.3 from one cycle to the next). So each window runs
from the crossing of the switching level ℓ = c - s·ε (c the stage's switching point, s = +1
reverse, -1 direct) located between the two samples around it by linear interpolation, to the
same crossing cycles later: the PV integrates as the linear interpolation of its samples, the
output as held (zero-order hold). Both window ends then lie on the same relay level, longer
than the dead time before them, so ∫u(t - L) = ∫u and the balance holds for the FOPDT exactly
(up to the interpolation).

The second stage may also switch around a shifted point SP + Δ (``RelayTest.offset``, the relay
block's ``offset``): the balance holds for any relay centre, so the PV mean moves by about Δ and
the output mean by Δ/K, a gain that does not rest on the small mean offsets of a biased relay
on a lag-dominant plant. A relay that oscillated under reverse action proves K > 0 (direct:
K < 0); a K of the other sign (the means moved with a load, or a sticky valve's error) is
refused with a note, and K then comes from the ultimate point as without a biased stage.

With a symmetric relay only, the denominator is ≈ 0 and K comes from the ultimate point (below).

Dead time (3.3): for FOPDT the PV keeps moving for exactly L after each switch, so L = mean
time from a switch to the next PV extremum (an apparent dead time for other plants).

Time constant, ``time_constant_method``:

The time-constant methods take the second stage about its switching point c = SP + Δ, with
the relay levels relative to the input u_c that holds the PV at c on the static line through
the stage's whole-cycle means (ū2, ȳ2)::

    u_c = ū2 + (c - ȳ2)/K,   d_up = u0 + d_up,set - u_c,   d_down = u_c - (u0 - d_down,set)

(for Δ = 0 and a loop at rest at its setpoint, u_c = u0 and these are the relay's own
amplitudes); y below is (PV - c), negated for direct action.

* ``trajectory`` (default, K from the biased stage): the exact FOPDT trajectory behind 3.3.
  After a switch to the high level the PV moves on for L to its trough y_lo (relative to
  c), then rises toward K·d_up and crosses +ε at t_on; likewise after a switch to the low
  level, from its peak y_hi toward -K·d_down, crossing -ε at t_off. With the measured L,
  y_lo and y_hi, each half period gives T; the two are averaged::

      T_on  = (t_on - L)  / ln( (K·d_up - y_lo)   / (K·d_up - ε) )
      T_off = (t_off - L) / ln( (K·d_down + y_hi) / (K·d_down - ε) )

  (better conditioned than the next method when ε is small).
* ``dead_time``: the 3.3 "on" half-period relation with the
  measured L in place of τ/(1 - τ) = L/T, solved for T::

      t_on = T·ln( (e^(L/T)·(d_up + d_down) - d_down + ε/|K|) / (d_up - ε/|K|) )

* ``half_period_ratio`` (Berner 2017, LBL ``Relay.NormalizedTimeDelay``): with γ = max(d)/min(d)
  and ρ = max(t_on, t_off)/min(t_on, t_off), τ = (γ - ρ)/((γ - 1)(0.35ρ + 0.65)), T from the
  relation above with e^(τ/(1 - τ)), then L = T·τ/(1 - τ) (replaces the measured dead time).
* with a symmetric relay only (no K): vendor-blocks 5.2, ωu = 2π/Pu and θ the measured dead
  time::

      τ = tan(π - θ·ωu)/ωu   (needs π/2 < θ·ωu < π),   K = √(1 + (τ·ωu)²)/Ku

Integrating plants (``process = "integrating"``, or ``auto`` when a biased relay's mean output
equals u0, 3.2): ``a = ε + Kv·d·L`` and ``P = 4L + 4ε/(Kv·d)`` give, with L eliminated,
Kv = 4a/(d·P); there is no static gain. Under a biased relay (levels d1 up, d2 down) the
half periods are t_on = L + (2ε + Kv·d2·L)/(Kv·d1) and t_off likewise, a = ε + Kv·L·(d1 + d2)/2,
so Kv = 2(d1 + d2)·a/(d1·d2·P), the same for d1 = d2. Not (a - ε)/(d·L) with the measured L: a relay
sampled every scan switches up to a scan after the PV crossed its threshold, which adds the
same delay δ to both a - ε = Kv·d·(L + δ) and P/4, but not to the time from a switch to the
PV's extremum (L), so that form read Kv 25 % high for L of two scans.

Refusals (:class:`IdentificationRefused`, an InputError: one line, never settings). A record
the formulas above cannot be applied to is refused with its reason:

* a limit cycle shorter than ``MIN_CYCLE_SCANS`` scans (the reason is at the constant, in
  ``loopworks.blocks.relay``): the sampling's cycle, not the plant's;
* a dead time shorter than ``MIN_DEAD_TIME_SCANS`` scans: not identifiable from the samples
  (a pure lag, or a scan too slow for the plant), while every model above divides by it or
  needs it (θ·ωu > π/2);
* a PV amplitude within the hysteresis (a ≤ ε: no point of the Nyquist curve, 3.1);
* a time constant or integrating gain that comes out zero, negative or not finite, or a
  trajectory whose logarithms have no positive argument (the cycle is not FOPDT-like);
* the second stage's equilibrium input outside the relay levels, ρ ≥ γ (3.3).

With a symmetric relay only, the FOPDT through the ultimate point is dropped (a warning; the
ultimate point stays) when its K, estimated per cycle and at the dead time ± its uncertainty,
spreads by more than ``ILL_CONDITIONED`` (±25 %) of its value.

Uncertainty. Every quantity is also estimated cycle by cycle (the amplitude, period and Ku of
each cycle; the dead time of each switch; K from each cycle of the second stage against the
first stage's window; T from each half period or cycle), and ``uncertainty`` holds half the
range of those estimates, for times read on the scan grid (period, dead time) at least half a
scan, for K at least what the stages' drift off the static line allows (``_gain_uncertainty``),
for T from a biased stage at least how far T moves with K ± K's uncertainty (inf where it has
no solution there: every per-cycle T is computed at the one K); None where there is only one
estimate. A PV quantised in steps above ``QUANTUM_WARNING`` (2 %) of the cycle amplitude
(``loopworks.analysis.quality.pv_quantum``) gets a warning: the staircase biases K, T and L
beyond their spread. A quantity whose uncertainty exceeds
``SPREAD_WARNING`` (5 %, the spread 3.4 calls stable) of its value gets a warning, and so does a
stage whose interpolated cycle means of the PV or of the output moved by more than 5 % of a or
of d over the analysed cycles (the cycles are not stationary: a load, or a loop that was not at
rest, moved them, and the static gain rests on those means).
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from itertools import pairwise
from typing import Any

import numpy as np

from loopworks.analysis.quality import pv_quantum
from loopworks.blocks.relay import MIN_CYCLE_SCANS
from loopworks.errors import InputError, ParameterError
from loopworks.tuning.settings import ProcessData

KU_CONVENTIONS = ("hysteresis_corrected", "describing_function", "harmonic")
AMPLITUDE_ESTIMATES = ("peaks", "harmonic")
TIME_CONSTANT_METHODS = ("trajectory", "dead_time", "half_period_ratio")
PROCESS_TYPES = ("auto", "self_regulating", "integrating")
#: The shortest dead time the record can show, in scans: the switch-to-extremum time is read
#: on the scan grid, and a loop closed through a sampled controller has up to a scan of delay
#: of its own, so a measured L of one scan or less is the sampling, not the plant.
MIN_DEAD_TIME_SCANS = 2
#: Relative half-range of the per-cycle estimates above which a quantity gets a warning (the
#: "≤ 5 % spread" of stable cycles, plant-and-tuning 3.4 item 4).
SPREAD_WARNING = 0.05
#: a PV quantised in steps above this fraction of the cycle amplitude a gets a warning [ours:
#: K 1, T 20 s, L 2 s under the pid, d 5 %: steps of 1 % of a read K 0.997 ± 0.04; of 2 %,
#: 0.91 ± 0.13; of 6 and 10 %, 1.15 ± 0.03 and 1.14 ± 0.02, off by more than their ±]
QUANTUM_WARNING = 0.02
#: above this relative difference of a symmetric relay's high and low half periods, a load
#: (or a loop not at rest) biases the cycle (spec 3.4 item 6; osPID's 20 %)
ASYMMETRY_LIMIT = 0.2
#: below this share of the relay amplitude d, the two stages' mean outputs are the same and
#: the process is taken as integrating (an integrator's mean input is its load, whatever the
#: relay) [ours: a lag-dominant FOPDT, T/L 25, shifts it by 0.97 % of d; T/L 20 by more]
LAG_DOMINANT_SHIFT = 0.01
#: Relative half-range above which the FOPDT through the ultimate point (symmetric relay only)
#: is dropped: τ = tan(π - θ·ωu)/ωu is ill-conditioned as θ·ωu nears π/2 (lag-dominant
#: plants), and a K known to ±25 % does not determine settings whose gain scales with 1/K.
ILL_CONDITIONED = 0.25


class IdentificationRefused(InputError):
    """The record cannot support an identification: the message says why (one line)."""


@dataclass(frozen=True)
class RelayTest:
    """What a relay test applied: setpoint ``sp`` and PV before the test ``pv0`` (PV units),
    relay centre ``u0`` and amplitudes ``amplitude`` (d_up), ``amplitude_down`` (OUT units),
    ``hysteresis`` ε (PV units, half-width), the error sign ``action``, and ``offset`` Δ (PV
    units): the second stage's switching point minus SP (the relay block's ``shift``)."""

    sp: float
    pv0: float
    u0: float
    amplitude: float
    amplitude_down: float
    hysteresis: float = 0.0
    action: str = "reverse"
    offset: float = 0.0


@dataclass(frozen=True)
class Identification:
    """The identified quantities (units: PV, OUT, s; gains PV per OUT, Ku OUT per PV).
    ``uncertainty``: half the range of the per-cycle estimates of each quantity (None: one
    estimate, or not identified); ``warnings``: what makes the result uncertain; ``scan``: the
    record's sampling interval (s)."""

    relay_amplitude: float
    relay_amplitude_down: float
    hysteresis: float
    amplitude: float
    amplitude_harmonic: float
    period: float
    ku: float
    ku_convention: str
    ku_describing_function: float
    ku_hysteresis_corrected: float
    ku_harmonic: float
    pu: float
    phase_lag: float
    process_type: str
    process_gain: float | None
    integrating_gain: float | None
    dead_time: float
    time_constant: float | None
    cycles: int
    notes: list[str] = field(default_factory=list)
    uncertainty: dict[str, float | None] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    scan: float = math.nan

    def process_data(self) -> ProcessData:
        """What the tuning rules take."""
        return ProcessData(
            ku=self.ku, pu=self.pu, process_gain=self.process_gain, dead_time=self.dead_time,
            time_constant=self.time_constant, integrating_gain=self.integrating_gain,
            relay_gain=self.ku_describing_function, relay_period=self.period,
            relay_phase_lag=self.phase_lag)

    def as_dict(self) -> dict[str, Any]:
        """Plain dict (JSON-ready; NaN and ±inf become None, in nested dicts too)."""
        return {key: _json_ready(value) for key, value in asdict(self).items()}


def _json_ready(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _json_ready(v) for k, v in value.items()}
    return value


@dataclass(frozen=True)
class Cycles:
    """Indices of the switches to the high level (``ups``) and to the low level (``downs``)."""

    ups: np.ndarray
    downs: np.ndarray


def switches(high: np.ndarray) -> Cycles:
    """Switch indices of a relay whose state is ``high`` (bool per sample)."""
    change = np.flatnonzero(high[1:] != high[:-1]) + 1
    return Cycles(ups=change[high[change]], downs=change[~high[change]])


def _slice_switches(high: np.ndarray, i0: int, i1: int) -> Cycles:
    """The switches at samples i0..i1 (sample i0 - 1 is looked at, so one at i0 counts)."""
    a = max(i0 - 1, 0)
    sw = switches(high[a:i1 + 1])
    return Cycles(ups=sw.ups + a, downs=sw.downs + a)


def first_harmonic(t: np.ndarray, x: np.ndarray, period: float, i0: int, i1: int) -> complex:
    """X₁ = (2/T)·Σ x_k·e^(-jω t_k)·Δt_k over samples i0..i1-1 (zero-order hold, Δt_k = t_{k+1}
    - t_k), T = t[i1] - t[i0], ω = 2π/period. The mean is removed first."""
    seg = x[i0:i1] - np.mean(x[i0:i1])
    dts = np.diff(t[i0:i1 + 1])
    w = 2.0 * math.pi / period
    total = float(t[i1] - t[i0])
    return complex(2.0 / total * np.sum(seg * np.exp(-1j * w * t[i0:i1]) * dts))


def _ku_df(d: float, a: float) -> float:
    """Ku = 4d/(πa), the describing function of the ideal relay (3.1)."""
    return 4.0 * d / (math.pi * a)


def _ku_hc(d: float, a: float, eps: float) -> float:
    """Ku = 4d/(π√(a² - ε²)), the hysteresis-corrected convention (3.1); NaN when a ≤ ε."""
    return 4.0 * d / (math.pi * math.sqrt(a * a - eps * eps)) if a > eps else math.nan


def short_cycle(period: float, scan: float) -> str:
    """Why a limit cycle of ``period`` s on scans of ``scan`` s under ``MIN_CYCLE_SCANS``
    scans is refused (one line)."""
    return (f"the limit cycle's period {period:.4g} s is {period / scan:.3g} scans of {scan:g} "
            f"s, under the {MIN_CYCLE_SCANS} scans a relay cycle needs to be measured: it is the "
            "sampling's cycle, not the plant's (no dead time the scan can resolve); a shorter dt "
            "or a plant with dead time")


# --- whole-cycle windows between interpolated crossings ----------------------------------------

@dataclass(frozen=True)
class _Record:
    """The record with its running integrals: PV as linear interpolation (trapezoids), the
    output as held (zero-order hold)."""

    t: np.ndarray
    pv: np.ndarray
    u: np.ndarray
    pv_cum: np.ndarray
    u_cum: np.ndarray

    @classmethod
    def of(cls, t: np.ndarray, pv: np.ndarray, u: np.ndarray) -> _Record:
        dts = np.diff(t)
        zero = np.zeros(1)
        return cls(t, pv, u, np.concatenate([zero, np.cumsum(0.5 * (pv[1:] + pv[:-1]) * dts)]),
                   np.concatenate([zero, np.cumsum(u[:-1] * dts)]))

    def _at(self, tau: float) -> tuple[int, float]:
        j = int(np.clip(np.searchsorted(self.t, tau, side="right") - 1, 0, len(self.t) - 2))
        return j, tau - float(self.t[j])

    def pv_integral(self, tau: float) -> float:
        """∫ PV dt from t[0] to tau (linear interpolation between samples)."""
        j, h = self._at(tau)
        slope = (self.pv[j + 1] - self.pv[j]) / (self.t[j + 1] - self.t[j])
        return float(self.pv_cum[j] + (self.pv[j] + 0.5 * slope * h) * h)

    def u_integral(self, tau: float) -> float:
        """∫ u dt from t[0] to tau (u[k] held from t[k] to t[k + 1])."""
        j, h = self._at(tau)
        return float(self.u_cum[j] + self.u[j] * h)

    def crossing(self, k: int, level: float) -> float:
        """The time in (t[k-1], t[k]] at which the PV's linear interpolation crosses
        ``level`` (t[k] when the two samples do not bracket it)."""
        if k < 1:
            return float(self.t[k])
        x0, x1 = float(self.pv[k - 1]), float(self.pv[k])
        if (x0 - level) * (x1 - level) > 0.0 or x0 == x1:
            return float(self.t[k])
        frac = (x0 - level) / (x0 - x1)
        return float(self.t[k - 1] + frac * (self.t[k] - self.t[k - 1]))


@dataclass(frozen=True)
class _Means:
    """Interpolated whole-cycle means of a stage: over all its analysed cycles and per cycle."""

    pv: float
    u: float
    pv_cycles: np.ndarray
    u_cycles: np.ndarray


def _stage_means(rec: _Record, ups: np.ndarray, level: float) -> _Means:
    """Means over the windows between the interpolated crossings of ``level`` at the switches
    up ``ups`` (module docstring)."""
    edges = [rec.crossing(int(k), level) for k in ups]
    fy = np.array([rec.pv_integral(e) for e in edges])
    fu = np.array([rec.u_integral(e) for e in edges])
    span = np.diff(edges)
    whole = edges[-1] - edges[0]
    return _Means(float((fy[-1] - fy[0]) / whole), float((fu[-1] - fu[0]) / whole),
                  np.diff(fy) / span, np.diff(fu) / span)


# --- time constant -----------------------------------------------------------------------------

def _trajectory_time_constants(y: np.ndarray, rec: _Record, sw: Cycles, levels: tuple[float, float],
                               lag: float, k: float, d_up: float, d_down: float,
                               eps: float) -> list[list[float]]:
    """T of each on and each off half period of the biased stage (``trajectory`` method): [[T_on
    per half period], [T_off per half period]]; y is the PV relative to the stage's switching
    point, signed so that a high output raises it, and d_up, d_down the relay levels relative to
    the equilibrium input there. Refused where a logarithm has no positive argument."""
    out: list[list[float]] = [[], []]
    for which, (starts, ends, drive) in enumerate(((sw.ups, sw.downs, d_up),
                                                   (sw.downs, sw.ups, d_down))):
        for a, b in _pairs(starts, ends):
            half = _half_period(rec, a, b, levels[1 - which])
            # the trough below c after a switch up (as a depth), the peak after a switch down
            extreme = -float(np.min(y[a:b + 1])) if which == 0 else float(np.max(y[a:b + 1]))
            num, den = k * drive + extreme, k * drive - eps
            if not (den > 0.0 and num > den and half > lag):
                level = "high" if which == 0 else "low"
                raise IdentificationRefused(
                    f"the {level}-level half period ({half:.4g} s, dead time {lag:.4g} s) does "
                    "not follow a first-order trajectory (its log argument "
                    f"{num:.4g}/{den:.4g} is not above 1): the cycle is not FOPDT-like, no "
                    "time constant")
            out[which].append((half - lag) / math.log(num / den))
    if not out[0] or not out[1]:
        raise IdentificationRefused("the biased relay stage has no complete on and off half "
                                    "periods")
    return out


def _pairs(starts: np.ndarray, ends: np.ndarray) -> list[tuple[int, int]]:
    """(start, the next end after it) for each start that has one."""
    return [(int(a), int(ends[ends > a][0])) for a in starts if np.any(ends > a)]


def _solve_time_constant(t_on: float, lag_ratio: float | None, dead_time: float | None,
                         d_up: float, d_down: float, eps_k: float) -> float:
    """T from the 3.3 "on" half-period relation; lag_ratio = τ/(1 - τ) when known, else L/T
    with the measured dead time (solved for T)."""
    if d_up - eps_k <= 0.0:
        raise IdentificationRefused(
            "the relay amplitude is too small for the hysteresis: d_up <= ε/|K|")

    def rhs(ratio: float) -> float:  # ln((e^r(d_up + d_down) - d_down + ε/|K|)/(d_up - ε/|K|))
        return ratio + math.log(((d_up + d_down) - (d_down - eps_k) * math.exp(-ratio))
                                / (d_up - eps_k))

    if lag_ratio is not None:
        return t_on / rhs(lag_ratio)
    assert dead_time is not None

    def f(tc: float) -> float:
        return tc * rhs(dead_time / tc) - t_on

    lo, hi = 1e-9 * t_on, 1e9 * t_on
    if f(lo) * f(hi) > 0.0:
        raise IdentificationRefused(
            "no time constant matches the measured half period and dead time")
    from scipy.optimize import brentq  # imported when needed: it takes a second to load

    return float(brentq(f, lo, hi, xtol=1e-12 * t_on, rtol=1e-12))


def _half_period_ratio(t_on: float, t_off: float, e_up: float, e_down: float,
                       eps_k: float) -> tuple[float, float]:
    """(T, L) by Berner's half-period ratio (module docstring)."""
    gamma = max(e_up, e_down) / min(e_up, e_down)
    rho = max(t_on, t_off) / min(t_on, t_off)
    tau = (gamma - rho) / ((gamma - 1.0) * (0.35 * rho + 0.65))
    if not 0.0 < tau < 1.0:
        raise IdentificationRefused(
            f"half-period ratio ρ = {rho:.4g} gives τ = {tau:.4g}, outside (0, 1): the "
            f"process is not FOPDT-like (spec 3.3 needs ρ < γ = {gamma:.4g})")
    tc = _solve_time_constant(t_on, tau / (1.0 - tau), None, e_up, e_down, eps_k)
    return tc, tc * tau / (1.0 - tau)


# --- the identification ------------------------------------------------------------------------

def identify(t: np.ndarray, pv: np.ndarray, u: np.ndarray, test: RelayTest, *,
             relay: np.ndarray | None = None, stage: np.ndarray | None = None, cycles: int = 2,
             ku_convention: str = "hysteresis_corrected", amplitude_estimate: str = "peaks",
             process: str = "auto", time_constant_method: str = "trajectory") -> Identification:
    """Identify the loop from a recorded relay test (equations in the module docstring).

    ``relay`` is the relay state per sample (> 0 high; the ``relay`` block's output of that
    name); without it the state is u > u0. ``stage`` (per sample: 1 symmetric, 2 biased,
    0 other) selects the stages; without it every sample belongs to one stage, biased when
    amplitude_down != amplitude. Raises InputError when there are fewer than ``cycles`` full
    cycles to analyse, and :class:`IdentificationRefused` when the record cannot support an
    identification (module docstring, "Refusals").
    """
    for name, value, allowed in (("ku_convention", ku_convention, KU_CONVENTIONS),
                                 ("amplitude_estimate", amplitude_estimate, AMPLITUDE_ESTIMATES),
                                 ("process", process, PROCESS_TYPES),
                                 ("time_constant_method", time_constant_method,
                                  TIME_CONSTANT_METHODS)):
        if value not in allowed:
            raise ParameterError(f"{name} = {value!r} is not allowed: expected one of "
                                 + ", ".join(allowed))
    if cycles < 1:
        raise ParameterError(f"cycles = {cycles} is out of range: allowed [1, inf)")
    t, pv, u = (np.asarray(a, dtype=float) for a in (t, pv, u))
    if len(t) < 3 or not (np.all(np.isfinite(t)) and np.all(np.diff(t) > 0.0)):
        raise InputError("the relay record needs at least 3 samples at increasing finite times")
    high = (u > test.u0) if relay is None else (np.asarray(relay, dtype=float) > 0.0)
    scan = float(np.median(np.diff(t)))
    notes: list[str] = []
    warnings: list[str] = []
    unc: dict[str, float | None] = {}
    d_up, d_down, eps = test.amplitude, test.amplitude_down, test.hysteresis
    s = 1.0 if test.action == "reverse" else -1.0
    biased_only = stage is None and d_up != d_down
    if stage is None:
        stage = np.full(len(t), 2 if biased_only else 1)
    stage = np.asarray(stage)
    sym = _window(high, stage == (2 if biased_only else 1), cycles,
                  "biased" if biased_only else "symmetric")
    has_biased = biased_only or bool(np.any(stage == 2))
    bia = sym if biased_only else (
        _window(high, stage == 2, cycles, "biased") if has_biased else None)
    rec = _Record.of(t, pv, u)

    i0, i1 = sym
    sw_sym = _slice_switches(high, i0, i1)
    ups = sw_sym.ups
    n_cyc = len(ups) - 1
    periods = np.diff(t[ups])
    period = float(np.mean(periods))
    if period < (MIN_CYCLE_SCANS - 0.5) * scan:
        raise IdentificationRefused(short_cycle(period, scan))
    amps = np.array([0.5 * (np.max(pv[a:b]) - np.min(pv[a:b])) for a, b in pairwise(ups)])
    a_peaks = float(np.mean(amps))
    pv1 = first_harmonic(t, pv, period, i0, i1)
    u1 = first_harmonic(t, u, period, i0, i1)
    a_h1 = abs(pv1)
    a = a_peaks if amplitude_estimate == "peaks" else a_h1
    if not a > eps:
        raise IdentificationRefused(
            f"the PV amplitude {a:.4g} is not above the hysteresis ε = {eps:.4g}: the relay "
            "identified no point (spec 3.1 needs a > ε)")
    if not biased_only:
        _check_symmetry(t, ups, sw_sym.downs, warnings)
    d = 0.5 * (d_up + (d_down if biased_only else d_up))

    def ku_of(amp: float) -> float:  # Ku of one cycle under the convention (harmonic: DF)
        return _ku_hc(d, amp, eps) if ku_convention == "hysteresis_corrected" \
            else _ku_df(d, amp)

    ku_df = _ku_df(d, a)
    ku_hc = _ku_hc(d, a, eps)
    ku_h1 = abs(u1) / a_h1
    ku = {"describing_function": ku_df, "hysteresis_corrected": ku_hc,
          "harmonic": ku_h1}[ku_convention]
    phase_lag = math.pi - math.asin(min(eps / a, 1.0))
    lags = _lags(t, pv, high, s, i0, i1)
    dead_time = float(np.mean(lags))
    if dead_time < MIN_DEAD_TIME_SCANS * scan - 1e-9 * scan:
        raise IdentificationRefused(
            f"the dead time {dead_time:.4g} s (switch to PV extremum) is under "
            f"{MIN_DEAD_TIME_SCANS} scans of {scan:g} s: not identifiable from the record (a "
            "pure lag, or a scan too slow for the plant), and every model needs it")
    unc["amplitude"] = _half_range(amps)
    unc["period"] = _time_half_range(periods, scan)
    unc["ku"] = _half_range(np.array([ku_of(x) for x in amps])) if ku_convention != "harmonic" \
        else None
    unc["dead_time"] = _time_half_range(np.asarray(lags), scan)
    # the switching point of the second stage (of the only stage, for a biased relay alone)
    centre = test.sp + (test.offset if has_biased else 0.0)
    means_sym = _stage_means(rec, ups, (centre if biased_only else test.sp) - s * eps)
    _stationarity(warnings, "biased" if biased_only else "symmetric", means_sym, a, d,
                  gain=has_biased)

    # static gain and process type
    k_static: float | None = None
    k_cycles: np.ndarray | None = None
    kv: float | None = None
    kind = process
    means_bia: _Means | None = None
    if bia is not None:
        b0, b1 = bia
        means_bia = means_sym if biased_only else _stage_means(
            rec, _slice_switches(high, b0, b1).ups, centre - s * eps)
        if biased_only:
            mean_du, mean_dy = means_bia.u - test.u0, means_bia.pv - test.pv0
            du_cyc, dy_cyc = means_bia.u_cycles - test.u0, means_bia.pv_cycles - test.pv0
        else:  # two levels: differences of the two stages' whole-cycle means
            _stationarity(warnings, "second", means_bia, a, 0.5 * (d_up + d_down))
            mean_du, mean_dy = means_bia.u - means_sym.u, means_bia.pv - means_sym.pv
            du_cyc, dy_cyc = means_bia.u_cycles - means_sym.u, means_bia.pv_cycles - means_sym.pv
        if process == "auto":
            kind = ("integrating" if abs(mean_du) < LAG_DOMINANT_SHIFT * max(d_up, d_down)
                    else "self_regulating")
            if kind == "integrating":
                notes.append(
                    f"the two stages' mean outputs differ by {abs(mean_du):.3g}, under "
                    f"{LAG_DOMINANT_SHIFT:.0%} of d: an integrating process, or a "
                    "self-regulating one the relay cannot tell from one: so lag-dominant (T "
                    "above about 25 L), or behind a hysteresis that is much of the PV's "
                    f"amplitude (here ε = {eps:.3g}, a = {a:.3g}: a T = 5 L plant read so at ε "
                    "= 0.63 a, not at 0.57 a); it is tuned as integrating, as SIMC treats T > "
                    "8 L (a smaller --hysteresis, or process='self_regulating' and a larger "
                    "offset, measure its K and T)")
                warnings.append(notes[-1])
        if kind == "self_regulating":
            k_static = mean_dy / mean_du
            with np.errstate(divide="ignore", invalid="ignore"):
                k_cycles = dy_cyc / du_cyc
            if (k_static < 0.0) != (test.action == "direct") or not math.isfinite(k_static):
                notes.append(
                    f"the two stages give K = {k_static:.4g}, whose sign contradicts the "
                    f"{test.action} action under which the relay oscillated: the stages' means "
                    "moved with something else (a load change, a sticky valve); no static gain "
                    "(a larger offset or amplitude, or a quieter plant, helps)")
                warnings.append(notes[-1])
                k_static = k_cycles = None
    elif process == "auto":
        kind = "self_regulating"
        notes.append("symmetric relay only: the process is taken as self-regulating and its "
                     "gain comes from the ultimate point (vendor-blocks 5.2)")
    time_constant: float | None = None
    if kind == "integrating":
        d1, d2 = d_up, (d_down if biased_only else d_up)
        kv = 2.0 * (d1 + d2) * a_peaks / (d1 * d2 * period)
        if not (math.isfinite(kv) and kv > 0.0):
            raise IdentificationRefused(f"the integrating gain comes out {kv:.4g}: not "
                                        "identifiable (spec 3.2 needs a > ε)")
        kv *= s  # signed as K is: negative under a direct-acting relay
        unc["integrating_gain"] = _half_range(2.0 * (d1 + d2) * amps / (d1 * d2 * periods))
        notes.append("integrating process: Kv = 4a/(d·P) (spec 3.2, a = ε + Kv·d·L and "
                     "P = 4L + 4ε/(Kv·d))")
    elif k_static is not None and bia is not None and means_bia is not None:
        unc["process_gain"] = _gain_uncertainty(
            k_static, k_cycles, mean_du, means_bia, None if biased_only else means_sym)
        time_constant, dead_time, unc_t = _time_constant(
            rec, high, bia, test, means_bia, k_static, centre, dead_time, s, eps,
            time_constant_method)
        # T rests on K (the relay levels about the static line, ε/|K|): K ± its uncertainty
        # moves T as well, which the per-cycle spread (all at one K) does not show
        dk = unc["process_gain"]
        if dk is not None and dk > 0.0:
            for k_other in (k_static - dk, k_static + dk):
                t_other = math.inf
                if k_other * k_static > 0.0:
                    with contextlib.suppress(IdentificationRefused):  # no T there: ± inf
                        t_other = _time_constant(rec, high, bia, test, means_bia, k_other,
                                                 centre, dead_time, s, eps,
                                                 time_constant_method)[0]
                shift = abs(t_other - time_constant) if math.isfinite(t_other) else math.inf
                unc_t = shift if unc_t is None else max(unc_t, shift)
        unc["time_constant"] = unc_t
        if time_constant_method == "half_period_ratio":
            unc["dead_time"] = None
    else:
        try:
            k_static, time_constant = fopdt_from_ultimate(ku, period, dead_time)
            # per cycle, and at the dead time ± its uncertainty (θ·ωu enters through a tan)
            spread_l = unc["dead_time"] or 0.0
            per_cycle = np.array([
                _or_nan(lambda x=x, p=p, lag=lag: fopdt_from_ultimate(  # type: ignore[misc]
                    ku_of(x), p, lag))
                for x, p in zip(amps, periods, strict=True)
                for lag in (dead_time - spread_l, dead_time + spread_l)])
            unc["process_gain"] = _half_range(per_cycle[:, 0])
            unc["time_constant"] = _half_range(per_cycle[:, 1])
            spread_k = unc["process_gain"]
            if spread_k is not None and spread_k > ILL_CONDITIONED * k_static:
                warnings.append(
                    f"no FOPDT model: K = {k_static:.3g} ± "
                    f"{'∞' if math.isinf(spread_k) else f'{spread_k:.2g}'} through the ultimate "
                    f"point is ill-conditioned here (θ·ωu = {2 * math.pi * dead_time / period:.3g}"
                    " rad, near π/2: a lag-dominant plant); only the ultimate point is used (a "
                    "biased stage gives K)")
                k_static = time_constant = None
            else:
                warnings.append(
                    "K and T come through the ultimate point (vendor-blocks 5.2), from the "
                    "describing function's Ku, which reads the true Ku 17-19 % low on the spec "
                    "3.2 plants (K = 1, T = 10 s, L = 2 s: K 1.01, T 8.2 s): the model and the "
                    "settings built on it are approximate; a biased second stage (tune without "
                    "--symmetric) measures K (spec 3.3)")
        except InputError as exc:
            k_static = time_constant = None
            notes.append(f"{exc} (vendor-blocks 5.2)")
            warnings.append(f"no FOPDT model: {exc}; only the ultimate point is identified")
    if time_constant is not None and not (math.isfinite(time_constant) and time_constant > 0.0):
        raise IdentificationRefused(f"the time constant comes out {time_constant:.4g} s: not "
                                    "identifiable (the cycle is not FOPDT-like)")
    values = {"amplitude": a_peaks, "period": period, "ku": ku, "dead_time": dead_time,
              "process_gain": k_static, "integrating_gain": kv, "time_constant": time_constant}
    for key, est in values.items():
        spread = unc.get(key)
        # (1 + 1e-9): half a scan of 0.2 s read from the run's times is 0.10000000000000142,
        # not "more than 5 %" of a dead time of 2 s
        if est is not None and spread is not None \
                and spread > SPREAD_WARNING * abs(est) * (1.0 + 1e-9):
            warnings.append(f"{key} = {est:.4g} ± {spread:.2g} ({100 * spread / abs(est):.0f} "
                            f"%): uncertain by more than {100 * SPREAD_WARNING:.0f} % (the "
                            "spread of the per-cycle estimates; for times, at least half a scan"
                            + ("; for K, also the stages' drift" if key == "process_gain"
                               else "; for T, also K's ±" if key == "time_constant"
                               else "") + ")")
    q = pv_quantum(np.asarray(pv, dtype=np.float64))
    if q > QUANTUM_WARNING * a_peaks:
        warnings.append(
            f"the PV moves in steps of {q:.3g}, {100 * q / a_peaks:.0f} % of the cycle amplitude "
            f"a = {a_peaks:.3g}: the relay switches and the analysis reads crossings, extremes "
            "and means on a staircase, so K, T and L can be further off than their ± (steps "
            "of 6-10 % of a read K 1.14-1.15 ± 0.03 for a true 1); a finer measurement or a "
            "larger relay amplitude helps")
    if n_cyc < 2:
        warnings.append("one cycle analysed per stage: no spread, the uncertainty is unknown")
    return Identification(
        relay_amplitude=d_up, relay_amplitude_down=d_down if has_biased else d_up,
        hysteresis=eps, amplitude=a_peaks, amplitude_harmonic=a_h1, period=period, ku=ku,
        ku_convention=ku_convention, ku_describing_function=ku_df,
        ku_hysteresis_corrected=ku_hc, ku_harmonic=ku_h1, pu=period, phase_lag=phase_lag,
        process_type=kind, process_gain=k_static, integrating_gain=kv, dead_time=dead_time,
        time_constant=time_constant, cycles=n_cyc, notes=notes,
        uncertainty={key: unc.get(key) if values[key] is not None else None for key in values},
        warnings=warnings, scan=scan)


def _time_constant(rec: _Record, high: np.ndarray, bia: tuple[int, int], test: RelayTest,
                   means: _Means, k: float, centre: float, dead_time: float, s: float,
                   eps: float, method: str) -> tuple[float, float, float | None]:
    """(T, L, uncertainty of T) from the second stage (module docstring, time constant)."""
    b0, b1 = bia
    sw = _slice_switches(high, b0, b1)
    levels = (centre - s * eps, centre + s * eps)
    on, off = _on_off(rec, sw, levels)
    t_on, t_off = float(np.mean(on)), float(np.mean(off))
    eps_k = eps / abs(k)
    # the relay levels relative to the input that holds the PV at the switching point c,
    # on the static line through the stage's means: y = ȳ2 + K·(u - ū2)
    u_eq = means.u + (centre - means.pv) / k
    e_up = test.u0 + test.amplitude - u_eq
    e_down = u_eq - (test.u0 - test.amplitude_down)
    if min(e_up, e_down) <= 0.0:
        raise IdentificationRefused(
            f"the second stage's equilibrium input {u_eq:.4g} is outside the relay levels: "
            "the static gain is not consistent with the cycle")
    per_cycle: Callable[[float, float], tuple[float, float]]
    if method == "half_period_ratio":
        tc, lag = _half_period_ratio(t_on, t_off, e_up, e_down, eps_k)
        per_cycle = lambda a, b: _half_period_ratio(a, b, e_up, e_down, eps_k)  # noqa: E731
    elif method == "dead_time":
        tc, lag = _solve_time_constant(t_on, None, dead_time, e_up, e_down, eps_k), dead_time
        per_cycle = lambda a, b: (  # noqa: E731
            _solve_time_constant(a, None, dead_time, e_up, e_down, eps_k), dead_time)
    else:
        halves = _trajectory_time_constants(s * (rec.pv - centre), rec, sw, levels, dead_time,
                                            abs(k), e_up, e_down, eps)
        tc = 0.5 * (float(np.mean(halves[0])) + float(np.mean(halves[1])))
        return tc, dead_time, _half_range(np.array(halves[0] + halves[1]))
    n = min(len(on), len(off))
    estimates = np.array([_or_nan(lambda i=i: per_cycle(on[i], off[i]))[0]  # type: ignore[misc]
                          for i in range(n)])
    return tc, lag, _half_range(estimates)


def _gain_uncertainty(k: float, k_cycles: np.ndarray | None, mean_du: float, biased: _Means,
                      symmetric: _Means | None) -> float | None:
    """± of K = Δȳ/Δū: the larger of the half range of the per-cycle estimates and what the
    stages' own drift allows. Each per-cycle estimate subtracts the same symmetric-stage mean,
    so a symmetric stage that still drifts (a start-up transient, a load moving) moved every
    estimate alike and left their spread small. A cycle whose means moved along the plant's
    static line (ȳ - K·ū unchanged: a cycle a scan longer, at a slightly other mean output)
    says nothing against K; what moved off it, r = ȳ - K·ū per cycle, is the drift, so
    ±(δr_sym + δr_bia)/(2·|Δū|), δ the max - min over a stage's cycles."""
    spread = None if k_cycles is None else _half_range(k_cycles)
    stages = [biased] + ([symmetric] if symmetric is not None else [])
    if not mean_du or any(len(m.pv_cycles) < 2 for m in stages):
        return spread
    off_line = sum(float(np.ptp(m.pv_cycles - k * m.u_cycles)) for m in stages)
    drift = 0.5 * off_line / abs(mean_du)
    return drift if spread is None else max(spread, drift)


def _check_symmetry(t: np.ndarray, ups: np.ndarray, downs: np.ndarray,
                    warnings: list[str]) -> None:
    """A symmetric relay's analysed half periods should be equal (spec 3.4 item 6: a load
    during the test biases the oscillation, unequal half periods; osPID acts above 20 %): a
    warning when they differ by more than ASYMMETRY_LIMIT of their mean. A loop not at rest
    when the test began is such a load: a lag plant (K 1, T 50 s, L 2 s) still 10.8 below SP
    cycled 17.1 s at the high level and 2.3 s at the low, and read Kv 2.4 times too small,
    "converged". Not a refusal: the static gain from two stages' means held (an E2 loop still
    settling, 10.5 s and 2.4 s, read K within 2 %)."""
    on = [float(t[dn] - t[up]) for up, dn in _pairs(ups[:-1], downs)]
    off = [float(t[up] - t[dn]) for dn, up in _pairs(downs, ups[1:])]
    if not on or not off:
        return
    t_on, t_off = float(np.mean(on)), float(np.mean(off))
    gap = abs(t_on - t_off) / (0.5 * (t_on + t_off))
    said = (f"the symmetric relay's half periods are unequal ({t_on:.3g} s at the high level, "
            f"{t_off:.3g} s at the low; {100 * gap:.0f} %): a load moved the loop during the "
            "test, or it was not at rest when the test began (spec 3.4 items 1 and 6)")
    if gap > ASYMMETRY_LIMIT:
        warnings.append(f"{said}; above {100 * ASYMMETRY_LIMIT:.0f} % the cycle's amplitude "
                        "and period, and Ku, Pu and an integrating gain read from them, are "
                        "biased: let the loop settle (a later --start) or test when the load is "
                        "steady")


def _half_range(x: np.ndarray) -> float | None:
    """(max - min)/2 of the finite estimates; None with fewer than two, inf when any is not
    finite (an estimate that failed for one cycle)."""
    if len(x) < 2:
        return None
    if not np.all(np.isfinite(x)):
        return math.inf
    return 0.5 * float(np.max(x) - np.min(x))


def _time_half_range(x: np.ndarray, scan: float) -> float | None:
    """:func:`_half_range` of times read on the scan grid: at least half a scan."""
    spread = _half_range(x)
    return None if spread is None else max(spread, 0.5 * scan)


def _stationarity(warnings: list[str], what: str, means: _Means, a: float, d: float,
                  gain: bool = True) -> None:
    """Warn when a stage's interpolated cycle means of the PV moved by more than
    SPREAD_WARNING·a, or of the output by more than SPREAD_WARNING·d, over its cycles;
    ``gain``: a static gain is read from those means (not with a symmetric relay alone,
    whose cycle is then uncertain itself)."""
    if len(means.pv_cycles) < 2:
        return
    dy = float(np.ptp(means.pv_cycles))
    du = float(np.ptp(means.u_cycles))
    if dy > SPREAD_WARNING * a or du > SPREAD_WARNING * d:
        warnings.append(
            f"the {what} stage is not stationary: its cycle means moved by {dy:.3g} (PV, "
            f"{100 * dy / a:.0f} % of a) and {du:.3g} (output, {100 * du / d:.0f} % of d) over "
            f"the analysed cycles, above {100 * SPREAD_WARNING:.0f} % (a load, or a loop not at "
            "rest when the test began): "
            + ("the static gain rests on those means" if gain
               else "the cycle's amplitude and period drift with them"))


def _or_nan(estimate: Callable[[], tuple[float, float]]) -> tuple[float, float]:
    """A per-cycle estimate, (NaN, NaN) where that cycle admits none."""
    try:
        return estimate()
    except InputError:
        return math.nan, math.nan


def fopdt_from_ultimate(ku: float, pu: float, dead_time: float) -> tuple[float, float]:
    """(K, T) of the FOPDT with dead time θ through the ultimate point (vendor-blocks 5.2):
    ωu = 2π/Pu, τ = tan(π - θ·ωu)/ωu (needs π/2 < θ·ωu < π), K = √(1 + (τ·ωu)²)/Ku."""
    wu = 2.0 * math.pi / pu
    if not math.pi / 2 < dead_time * wu < math.pi:
        raise InputError(f"θ·ωu = {dead_time * wu:.4g} is outside (π/2, π): no FOPDT with dead "
                         f"time {dead_time:g} s has its ultimate period at {pu:g} s")
    tc = math.tan(math.pi - dead_time * wu) / wu
    return math.sqrt(1.0 + (tc * wu) ** 2) / ku, tc


def fopdt_from_gain(k: float, ku: float, pu: float) -> tuple[float, float]:
    """(T, L) of the FOPDT with static gain K through the ultimate point (plant-and-tuning
    3.3): ωu = 2π/Pu, T = √((Ku·K)² - 1)/ωu, L = (π - atan(ωu·T))/ωu."""
    wu = 2.0 * math.pi / pu
    if not abs(ku * k) > 1.0:
        raise InputError(f"Ku·K = {ku * k:.4g}: a FOPDT needs |Ku·K| > 1")
    tc = math.sqrt((ku * k) ** 2 - 1.0) / wu
    return tc, (math.pi - math.atan(wu * tc)) / wu


def _window(high: np.ndarray, mask: np.ndarray, cycles: int, what: str) -> tuple[int, int]:
    """(i0, i1): the samples of the last ``cycles`` full cycles inside ``mask`` (the sample
    before the mask starts is looked at too, so a switch on its first sample counts, and the
    sample after it ends: the relay ends a stage on the scan of the switch that closes its
    last converged cycle, and that scan is the next stage's first)."""
    idx = np.flatnonzero(mask)
    if len(idx) == 0:
        raise InputError(f"the relay test has no {what} stage to analyse")
    ups = _slice_switches(high, int(idx[0]), min(int(idx[-1]) + 1, len(high) - 1)).ups
    if len(ups) < cycles + 1:
        raise InputError(f"the {what} relay stage has {max(len(ups) - 1, 0)} full cycles; "
                         f"the analysis needs {cycles}")
    return int(ups[-cycles - 1]), int(ups[-1])


def _half_period(rec: _Record, a: int, b: int, level: float) -> float:
    """From the switch at sample a to the PV's crossing of ``level`` that made the relay
    switch back at sample b (interpolated: the 3.3 relations take the switch at the crossing,
    while a sampled relay switches up to a scan after it)."""
    return rec.crossing(b, level) - float(rec.t[a])


def _on_off(rec: _Record, sw: Cycles, levels: tuple[float, float]
            ) -> tuple[list[float], list[float]]:
    """Durations of the high (on) and low (off) relay levels, from each switch to the crossing
    behind the next one; ``levels`` = (switch-up level, switch-down level) of the PV."""
    on = [_half_period(rec, a, b, levels[1]) for a, b in _pairs(sw.ups, sw.downs)]
    off = [_half_period(rec, a, b, levels[0]) for a, b in _pairs(sw.downs, sw.ups)]
    if not on or not off:
        raise IdentificationRefused("the biased relay stage has no complete on and off half "
                                    "periods")
    return on, off


def _lags(t: np.ndarray, pv: np.ndarray, high: np.ndarray, s: float, i0: int,
          i1: int) -> list[float]:
    """Time from each relay switch to the next PV extremum (3.3): after a switch to the high
    level the PV (reverse action, s = +1) still falls to its trough; direct action, the other
    way round."""
    sw = _slice_switches(high, i0, i1)
    idx = np.sort(np.concatenate([sw.ups, sw.downs]))
    lags = []
    for a, b in pairwise(idx):
        seg = s * pv[a:b + 1]
        j = int(np.argmin(seg)) if high[a] else int(np.argmax(seg))
        lags.append(float(t[a + j] - t[a]))
    if not lags:
        raise InputError("the relay test has no switch to measure the dead time from")
    return lags
