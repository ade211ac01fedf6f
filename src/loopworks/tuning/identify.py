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
equals u0, 3.2): ``a = ε + Kv·d·L`` gives Kv = (a - ε)/(d·L); there is no static gain.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from itertools import pairwise
from typing import Any

import numpy as np
from scipy.optimize import brentq

from loopworks.errors import InputError, ParameterError
from loopworks.tuning.settings import ProcessData

KU_CONVENTIONS = ("hysteresis_corrected", "describing_function", "harmonic")
AMPLITUDE_ESTIMATES = ("peaks", "harmonic")
TIME_CONSTANT_METHODS = ("trajectory", "dead_time", "half_period_ratio")
PROCESS_TYPES = ("auto", "self_regulating", "integrating")


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
    """The identified quantities (units: PV, OUT, s; gains PV per OUT, Ku OUT per PV)."""

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

    def process_data(self) -> ProcessData:
        """What the tuning rules take."""
        return ProcessData(
            ku=self.ku, pu=self.pu, process_gain=self.process_gain, dead_time=self.dead_time,
            time_constant=self.time_constant, integrating_gain=self.integrating_gain,
            relay_gain=self.ku_describing_function, relay_period=self.period,
            relay_phase_lag=self.phase_lag)

    def as_dict(self) -> dict[str, Any]:
        """Plain dict (JSON-ready; NaN becomes None)."""
        out: dict[str, Any] = {}
        for key, value in asdict(self).items():
            out[key] = None if isinstance(value, float) and not math.isfinite(value) else value
        return out


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


def _trajectory_time_constant(y: np.ndarray, high: np.ndarray, i0: int, i1: int, t_on: float,
                              t_off: float, lag: float, k: float, d_up: float, d_down: float,
                              eps: float) -> float:
    """T from the measured trough/peak of the biased stage (``trajectory`` method); y is the PV
    relative to the stage's switching point, signed so that a high output raises it, and
    d_up, d_down the relay levels relative to the equilibrium input there."""
    sw = _slice_switches(high, i0, i1)
    lows = [float(np.min(y[a:b + 1])) for a, b in _pairs(sw.ups, sw.downs)]
    highs = [float(np.max(y[a:b + 1])) for a, b in _pairs(sw.downs, sw.ups)]
    if not lows or not highs:
        raise InputError("the biased relay stage has no complete on and off half periods")
    y_lo, y_hi = float(np.mean(lows)), float(np.mean(highs))
    t_up = (t_on - lag) / math.log((k * d_up - y_lo) / (k * d_up - eps))
    t_dn = (t_off - lag) / math.log((k * d_down + y_hi) / (k * d_down - eps))
    return 0.5 * (t_up + t_dn)


def _pairs(starts: np.ndarray, ends: np.ndarray) -> list[tuple[int, int]]:
    """(start, the next end after it) for each start that has one."""
    return [(int(a), int(ends[ends > a][0])) for a in starts if np.any(ends > a)]


def _solve_time_constant(t_on: float, lag_ratio: float | None, dead_time: float | None,
                         d_up: float, d_down: float, eps_k: float) -> float:
    """T from the 3.3 "on" half-period relation; lag_ratio = τ/(1 - τ) when known, else L/T
    with the measured dead time (solved for T)."""
    if d_up - eps_k <= 0.0:
        raise InputError("the relay amplitude is too small for the hysteresis: d_up <= ε/|K|")

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
        raise InputError("no time constant matches the measured half period and dead time")
    return float(brentq(f, lo, hi, xtol=1e-12 * t_on, rtol=1e-12))


def identify(t: np.ndarray, pv: np.ndarray, u: np.ndarray, test: RelayTest, *,
             relay: np.ndarray | None = None, stage: np.ndarray | None = None, cycles: int = 2,
             ku_convention: str = "hysteresis_corrected", amplitude_estimate: str = "peaks",
             process: str = "auto", time_constant_method: str = "trajectory") -> Identification:
    """Identify the loop from a recorded relay test (equations in the module docstring).

    ``relay`` is the relay state per sample (> 0 high; the ``relay`` block's output of that
    name); without it the state is u > u0. ``stage`` (per sample: 1 symmetric, 2 biased,
    0 other) selects the stages; without it every sample belongs to one stage, biased when
    amplitude_down != amplitude. Raises InputError
    when there are fewer than ``cycles`` full cycles to analyse.
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
    high = (u > test.u0) if relay is None else (np.asarray(relay, dtype=float) > 0.0)
    notes: list[str] = []
    d_up, d_down, eps = test.amplitude, test.amplitude_down, test.hysteresis
    biased_only = stage is None and d_up != d_down
    if stage is None:
        stage = np.full(len(t), 2 if biased_only else 1)
    sym = _window(high, np.asarray(stage) == (2 if biased_only else 1), cycles,
                  "biased" if biased_only else "symmetric")
    has_biased = biased_only or bool(np.any(np.asarray(stage) == 2))
    bia = sym if biased_only else (
        _window(high, np.asarray(stage) == 2, cycles, "biased") if has_biased else None)

    i0, i1 = sym
    ups = _slice_switches(high, i0, i1).ups
    n_cyc = len(ups) - 1
    periods = np.diff(t[ups])
    period = float(np.mean(periods))
    amps = [0.5 * (np.max(pv[a:b]) - np.min(pv[a:b])) for a, b in pairwise(ups)]
    a_peaks = float(np.mean(amps))
    pv1 = first_harmonic(t, pv, period, i0, i1)
    u1 = first_harmonic(t, u, period, i0, i1)
    a_h1 = abs(pv1)
    a = a_peaks if amplitude_estimate == "peaks" else a_h1
    d = 0.5 * (d_up + (d_down if biased_only else d_up))
    ku_df = 4.0 * d / (math.pi * a)
    ku_hc = 4.0 * d / (math.pi * math.sqrt(a * a - eps * eps)) if a > eps else math.nan
    ku_h1 = abs(u1) / a_h1
    ku = {"describing_function": ku_df, "hysteresis_corrected": ku_hc,
          "harmonic": ku_h1}[ku_convention]
    phase_lag = math.pi - math.asin(min(eps / a, 1.0))
    dead_time = _dead_time(t, pv, high, test.sp, i0, i1)

    # static gain and process type
    k_static: float | None = None
    kv: float | None = None
    kind = process
    mean_u2 = mean_y2 = math.nan
    if bia is not None:
        b0, b1 = bia
        mean_u2, mean_y2 = _mean(t, u, b0, b1), _mean(t, pv, b0, b1)
        if biased_only:
            mean_du, mean_dy = mean_u2 - test.u0, mean_y2 - test.pv0
        else:  # two levels: differences of the two stages' whole-cycle means
            mean_du = mean_u2 - _mean(t, u, i0, i1)
            mean_dy = mean_y2 - _mean(t, pv, i0, i1)
        if process == "auto":
            kind = "integrating" if abs(mean_du) < 0.01 * max(d_up, d_down) else "self_regulating"
        if kind == "self_regulating":
            k_static = mean_dy / mean_du
            if (k_static < 0.0) != (test.action == "direct"):
                notes.append(
                    f"the two stages give K = {k_static:.4g}, whose sign contradicts the "
                    f"{test.action} action under which the relay oscillated: the stages' means "
                    "moved with something else (a load change, a sticky valve); no static gain "
                    "(a larger offset or amplitude, or a quieter plant, helps)")
                k_static = None
    elif process == "auto":
        kind = "self_regulating"
        notes.append("symmetric relay only: the process is taken as self-regulating and its "
                     "gain comes from the ultimate point (vendor-blocks 5.2)")
    time_constant: float | None = None
    if kind == "integrating":
        kv = (a_peaks - eps) / (d * dead_time)
        notes.append("integrating process: Kv = (a - ε)/(d·L) (spec 3.2)")
    elif k_static is not None and bia is not None:
        b0, b1 = bia
        t_on, t_off = _on_off(t, _slice_switches(high, b0, b1))
        eps_k = eps / abs(k_static)
        # the relay levels relative to the input that holds the PV at the switching point c,
        # on the static line through the stage's means: y = ȳ2 + K·(u - ū2)
        centre = test.sp + (test.offset if has_biased else 0.0)
        u_eq = mean_u2 + (centre - mean_y2) / k_static
        e_up = test.u0 + test.amplitude - u_eq
        e_down = u_eq - (test.u0 - test.amplitude_down)
        if min(e_up, e_down) <= 0.0:
            raise InputError(f"the second stage's equilibrium input {u_eq:.4g} is outside the "
                             "relay levels: the static gain is not consistent with the cycle")
        if time_constant_method == "half_period_ratio":
            gamma = max(e_up, e_down) / min(e_up, e_down)
            rho = max(t_on, t_off) / min(t_on, t_off)
            tau = (gamma - rho) / ((gamma - 1.0) * (0.35 * rho + 0.65))
            if not 0.0 < tau < 1.0:
                raise InputError(f"half-period ratio ρ = {rho:.4g} gives τ = {tau:.4g}, outside "
                                 "(0, 1): the process is not FOPDT-like (spec 3.3 needs ρ < γ)")
            time_constant = _solve_time_constant(t_on, tau / (1.0 - tau), None, e_up, e_down,
                                                 eps_k)
            dead_time = time_constant * tau / (1.0 - tau)
        elif time_constant_method == "dead_time":
            time_constant = _solve_time_constant(t_on, None, dead_time, e_up, e_down, eps_k)
        else:
            sign = 1.0 if test.action == "reverse" else -1.0
            time_constant = _trajectory_time_constant(
                sign * (pv - centre), high, b0, b1, t_on, t_off, dead_time, abs(k_static),
                e_up, e_down, eps)
    else:
        try:
            k_static, time_constant = fopdt_from_ultimate(ku, period, dead_time)
        except InputError as exc:
            notes.append(f"{exc} (vendor-blocks 5.2)")
    return Identification(
        relay_amplitude=d_up, relay_amplitude_down=d_down if has_biased else d_up,
        hysteresis=eps, amplitude=a_peaks, amplitude_harmonic=a_h1, period=period, ku=ku,
        ku_convention=ku_convention, ku_describing_function=ku_df,
        ku_hysteresis_corrected=ku_hc, ku_harmonic=ku_h1, pu=period, phase_lag=phase_lag,
        process_type=kind, process_gain=k_static, integrating_gain=kv, dead_time=dead_time,
        time_constant=time_constant, cycles=n_cyc, notes=notes)


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
    before the mask starts is looked at too, so a switch on its first sample counts)."""
    idx = np.flatnonzero(mask)
    if len(idx) == 0:
        raise InputError(f"the relay test has no {what} stage to analyse")
    ups = _slice_switches(high, int(idx[0]), int(idx[-1])).ups
    if len(ups) < cycles + 1:
        raise InputError(f"the {what} relay stage has {max(len(ups) - 1, 0)} full cycles; "
                         f"the analysis needs {cycles}")
    return int(ups[-cycles - 1]), int(ups[-1])


def _mean(t: np.ndarray, x: np.ndarray, i0: int, i1: int) -> float:
    """Time-weighted mean of x over samples i0..i1-1 (zero-order hold)."""
    return float(np.sum(x[i0:i1] * np.diff(t[i0:i1 + 1])) / (t[i1] - t[i0]))


def _on_off(t: np.ndarray, sw: Cycles) -> tuple[float, float]:
    """Mean durations of the high (on) and low (off) relay levels between the switches."""
    on = [float(t[b] - t[a]) for a, b in _pairs(sw.ups, sw.downs)]
    off = [float(t[b] - t[a]) for a, b in _pairs(sw.downs, sw.ups)]
    if not on or not off:
        raise InputError("the biased relay stage has no complete on and off half periods")
    return float(np.mean(on)), float(np.mean(off))


def _dead_time(t: np.ndarray, pv: np.ndarray, high: np.ndarray, sp: float, i0: int,
               i1: int) -> float:
    """Mean time from a relay switch to the next PV extremum (3.3)."""
    sw = _slice_switches(high, i0, i1)
    idx = np.sort(np.concatenate([sw.ups, sw.downs]))
    lags = []
    for a, b in pairwise(idx):
        seg = pv[a:b + 1]
        j = int(np.argmin(seg)) if pv[a] < sp else int(np.argmax(seg))
        lags.append(float(t[a + j] - t[a]))
    if not lags:
        raise InputError("the relay test has no switch to measure the dead time from")
    return float(np.mean(lags))
