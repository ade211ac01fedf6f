"""Tuning rules: controller settings from process data (plant-and-tuning 3.6).

Each rule states the PID form it assumes (``"ideal"``, u = Kc·[e + (1/Ti)∫e dt + Td·de/dt],
or ``"series"``, C = Kc'(1 + 1/(Ti's))(1 + Td's); spec 3.5) and gives Kc, Ti, Td in that form,
with Kc in loop units (OUT per PV: the reciprocal of the process gain's units), Ti = inf when
there is no integral action and Td = 0 when there is no derivative action.
``Tuning.ideal()`` converts to the ideal form with the one copy of the form conversions
(``loopworks.blocks.forms``); ``loopworks.tuning.convert`` takes it on to the parameters of a
target block (spans, units, vendor form).

Notation: ultimate gain Ku and period Pu; FOPDT model K·e^(-Ls)/(Ts + 1); integrating model
Kv·e^(-Ls)/s; a relay point with hysteresis: gain Kφ = 4d/(πa), period P, phase lag φ (rad).
Gains are used by magnitude: a negative process (or integrating) gain gives the same settings
with ``direct = True`` (e = PV - SP).

Spec tags of 3.6, repeated in each rule's docstring: [L] literature value recalled from the
primary source, [S] read in a public source file or document, [V] checked numerically in the
spec, [I] the spec author's interpretation.

>>> t = tune("simc", ProcessData(process_gain=1.0, dead_time=2.0, time_constant=10.0))
>>> (t.kc, t.ti, t.td)
(2.5, 10.0, 0.0)
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, fields, replace
from types import MappingProxyType

from loopworks.blocks.forms import series_to_ideal
from loopworks.errors import ParameterError
from loopworks.tuning.robustness import MS_WARNING, derivative_gain, max_sensitivity
from loopworks.tuning.settings import Ideal, ProcessData

CONTROLLERS = ("P", "PI", "PID")

# The models a rule can work from: the ProcessData fields each one needs.
ULTIMATE = ("ku", "pu")
FOPDT = ("process_gain", "dead_time", "time_constant")
INTEGRATING = ("integrating_gain", "dead_time")
ULTIMATE_K = ("ku", "pu", "process_gain")
RELAY_POINT = ("relay_gain", "relay_period", "relay_phase_lag", "process_gain")

_MODEL_NAMES = {ULTIMATE: "ultimate point", FOPDT: "FOPDT", INTEGRATING: "integrating",
                ULTIMATE_K: "ultimate point and static gain",
                RELAY_POINT: "relay point with static gain"}

# AMIGO-f (Hägglund & Åström 2004) is fitted for φ ≈ 120-140°; its Kc and Ti factors
# (2.50 - 0.92φ) and (-3.05 + 1.72φ) are positive only for 3.05/1.72 < φ < 2.50/0.92 rad.
PHI_MIN = 3.05 / 1.72
PHI_MAX = 2.50 / 0.92
PHI_VALID = (math.radians(120.0), math.radians(140.0))

#: a relay point more than this short of 180° of lag (rad; hysteresis puts it at
#: π - arcsin(ε/a), spec 3.1) is not the ultimate point: a rule reading its period as Pu is
#: marked. 5° lengthens the period by about 5 % on the spec 3.2 plant (K 1, T 10 s, L 2 s),
#: the spread tune calls uncertain; 13° (ε = 0.05) gives 9.04 s for Pu 7.44 s.
ULTIMATE_PHASE_TOLERANCE = math.radians(5.0)


@dataclass(frozen=True)
class Tuning:
    """Settings a rule gives: ``kc``, ``ti`` (s, inf = none), ``td`` (s, 0 = none) in the
    ``form`` the rule assumes (``"ideal"`` or ``"series"``), kc in loop units (OUT per PV).
    ``direct`` is True when the process gain is negative (e = PV - SP). ``note`` holds
    validity warnings ("" when the data are inside the rule's stated range)."""

    rule: str
    controller: str
    form: str
    kc: float
    ti: float
    td: float
    note: str = ""
    direct: bool = False
    #: maximum sensitivity on the process model the data hold (tuning.robustness; inf:
    #: unstable), None without a model
    ms: float | None = None

    def ideal(self) -> Ideal:
        """The same controller in the ideal form (spec 3.5 via ``blocks.forms``), unfiltered
        (tf = 0), kc still in loop units."""
        if self.form == "series":
            kc, ti, td = series_to_ideal(self.kc, self.ti, self.td)
        else:
            kc, ti, td = self.kc, self.ti, self.td
        return Ideal(kc=kc, ti=ti, td=td, tf=0.0, direct=self.direct)


@dataclass(frozen=True)
class _Out:
    kc: float
    ti: float = math.inf
    td: float = 0.0
    form: str = "ideal"
    note: str = ""


# A rule's arithmetic: (known data by field name, gains as magnitudes; the model used;
# controller; options) -> settings.
_Compute = Callable[[Mapping[str, float], tuple[str, ...], str, Mapping[str, float]], _Out]


@dataclass(frozen=True)
class Rule:
    """A tuning rule: ``name``; ``needs``, the models it works from (each a tuple of
    ProcessData fields; the first one fully known is used); the ``controllers`` it offers;
    the ``form`` it assumes; its ``options``; a one-line ``description`` with source and
    spec tag."""

    name: str
    needs: tuple[tuple[str, ...], ...]
    controllers: tuple[str, ...]
    form: str
    options: tuple[str, ...]
    description: str
    compute: _Compute


# --- rules from the ultimate point (Ku, Pu) --------------------------------------------------

def _table(rows: Mapping[str, tuple[float, float, float]]) -> _Compute:
    """A rule given as factors of the ultimate point: Kc = a·Ku, Ti = b·Pu, Td = c·Pu."""

    def compute(v: Mapping[str, float], model: tuple[str, ...], controller: str,
                options: Mapping[str, float]) -> _Out:
        a, b, c = rows[controller]
        return _Out(a * v["ku"], b * v["pu"], c * v["pu"])

    return compute


_INF = math.inf

_zn = _table({"P": (0.5, _INF, 0.0), "PI": (0.45, 1.0 / 1.2, 0.0),
              "PID": (0.6, 0.5, 0.125)})
_zn.__doc__ = """Ziegler–Nichols (1942), ultimate point, ideal form (spec 3.6, [L] for PID):
P: Kc = 0.5Ku; PI: Kc = 0.45Ku, Ti = Pu/1.2; PID: Kc = 0.6Ku, Ti = Pu/2, Td = Pu/8.
Derived on analog (series) controllers; the ideal PID set equals the series PID Kc' = 0.3Ku,
Ti' = Td' = Pu/4 (spec 3.5 [V, algebra]), so both readings are the same controller."""

_tyreus_luyben = _table({"PI": (1.0 / 3.2, 2.2, 0.0), "PID": (1.0 / 2.2, 2.2, 1.0 / 6.3)})
_tyreus_luyben.__doc__ = """Tyreus–Luyben (1992), ideal form (spec 3.6 [S: osPID, Yu]):
PI: Kc = Ku/3.2, Ti = 2.2Pu; PID: Kc = Ku/2.2, Ti = 2.2Pu, Td = Pu/6.3."""

_ciancone_marlin = _table({"PI": (1.0 / 3.3, 0.25, 0.0),
                           "PID": (1.0 / 3.3, 1.0 / 4.4, 1.0 / 8.1)})
_ciancone_marlin.__doc__ = """Ciancone–Marlin as tabulated in osPID, ideal form (spec 3.6 [S]):
PI: Kc = Ku/3.3, Ti = Pu/4; PID: Kc = Ku/3.3, Ti = Pu/4.4, Td = Pu/8.1."""

_pessen = _table({"PID": (1.0 / 1.4, 1.0 / 2.5, 1.0 / 6.65)})
_pessen.__doc__ = """Pessen integral rule, ideal PID (spec 3.6 [S]): Kc = Ku/1.4, Ti = Pu/2.5,
Td = Pu/6.65."""

_some_overshoot = _table({"PID": (1.0 / 3.0, 0.5, 1.0 / 3.0)})
_some_overshoot.__doc__ = """"Some overshoot", ideal PID (spec 3.6 [S]): Kc = Ku/3, Ti = Pu/2,
Td = Pu/3."""

_no_overshoot = _table({"PID": (1.0 / 5.0, 0.5, 1.0 / 3.0)})
_no_overshoot.__doc__ = """"No overshoot", ideal PID (spec 3.6 [S]): Kc = Ku/5, Ti = Pu/2,
Td = Pu/3."""


def _amigo_frequency(v: Mapping[str, float], model: tuple[str, ...], controller: str,
                     options: Mapping[str, float]) -> _Out:
    """AMIGO from the ultimate point and the static gain, ideal form (Åström & Hägglund 2006
    §7; spec 3.6 [L], Ms ≈ 1.46 on the worked example [V]), κ = 1/(K·Ku):

        PI:  Kc = 0.16Ku,              Ti = Pu/(1 + 4.5κ)
        PID: Kc = (0.3 - 0.1κ⁴)Ku,     Ti = 0.6Pu/(1 + 2κ),  Td = 0.15(1 - κ)Pu/(1 - 0.95κ)

    Refused (ParameterError) when κ ≥ 1: a low-pass plant has 1/Ku = |G(jωu)| < K.
    """
    ku, pu = v["ku"], v["pu"]
    kappa = 1.0 / (v["process_gain"] * ku)
    if not kappa < 1.0:
        raise ParameterError(
            f"process_gain·ku = {1.0 / kappa:.4g} is out of range for rule 'amigo_frequency': "
            "allowed (1, inf): a low-pass plant's gain at its ultimate frequency, 1/Ku, is "
            "below its static gain K, so K·Ku > 1 (κ = 1/(K·Ku) < 1; the Td formula has a pole "
            "at κ = 1/0.95); the static gain and the ultimate point disagree")
    if controller == "PI":
        return _Out(0.16 * ku, pu / (1.0 + 4.5 * kappa))
    return _Out((0.3 - 0.1 * kappa**4) * ku, 0.6 * pu / (1.0 + 2.0 * kappa),
                0.15 * (1.0 - kappa) * pu / (1.0 - 0.95 * kappa))


def _amigo_f(v: Mapping[str, float], model: tuple[str, ...], controller: str,
             options: Mapping[str, float]) -> _Out:
    """AMIGO-f at a relay point with phase lag φ (rad), ideal PI (Hägglund & Åström 2004,
    Asian J. Control 6:469-482, as coded in osPID; spec 3.6 [S]), κ = 1/(Kφ·K):

        Kc = (2.50 - 0.92φ)/(1 + (10.75 - 4.01φ)κ)·Kφ
        Ti = (-3.05 + 1.72φ)/(1 + (-6.10 + 3.44φ)κ)²·P

    Fitted for φ ≈ 120-140° (a note says when φ is outside).
    """
    k_phi, period, phi = v["relay_gain"], v["relay_period"], v["relay_phase_lag"]
    kappa = 1.0 / (k_phi * v["process_gain"])
    kc = (2.50 - 0.92 * phi) / (1.0 + (10.75 - 4.01 * phi) * kappa) * k_phi
    ti = (-3.05 + 1.72 * phi) / (1.0 + (-6.10 + 3.44 * phi) * kappa) ** 2 * period
    note = ""
    if not PHI_VALID[0] <= phi <= PHI_VALID[1]:
        note = (f"relay_phase_lag = {math.degrees(phi):.1f}° is outside 120-140°, the range "
                "AMIGO-f was fitted for")
    return _Out(kc, ti, note=note)


# --- rules from a FOPDT or integrating model -------------------------------------------------

def _zn_step(v: Mapping[str, float], model: tuple[str, ...], controller: str,
             options: Mapping[str, float]) -> _Out:
    """Ziegler–Nichols step response (reaction curve), ideal form (spec 3.6), a = K·L/T:

        PI: Kc = 0.9/a, Ti = 3L;   PID: Kc = 1.2/a, Ti = 2L, Td = L/2
    """
    lag = v["dead_time"]
    a = v["process_gain"] * lag / v["time_constant"]
    if controller == "PI":
        return _Out(0.9 / a, 3.0 * lag)
    return _Out(1.2 / a, 2.0 * lag, 0.5 * lag)


def _amigo(v: Mapping[str, float], model: tuple[str, ...], controller: str,
           options: Mapping[str, float]) -> _Out:
    """AMIGO (Åström & Hägglund 2004/2006), ideal form (targets Ms ≈ 1.4).

    FOPDT K·e^(-Ls)/(Ts + 1) (spec 3.6 [S: LBL, AlCap23]):

        PI:  Kc = 0.15/K + (0.35 - LT/(L + T)²)·T/(K·L),  Ti = 0.35L + 13LT²/(T² + 12LT + 7L²)
        PID: Kc = (0.2 + 0.45T/L)/K,  Ti = L(0.4L + 0.8T)/(L + 0.1T),  Td = 0.5LT/(0.3L + T)

    the PID with a note when τ = L/(L + T) < 0.3 (outside the book's validity range, as
    AlCap23 warns). Integrating Kv·e^(-Ls)/s, used when ``integrating_gain`` is given
    (spec 3.6 [L]):

        PI:  Kc = 0.35/(Kv·L),  Ti = 13.4L;     PID: Kc = 0.45/(Kv·L),  Ti = 8L,  Td = 0.5L
    """
    lag = v["dead_time"]
    if model == INTEGRATING:
        kv = v["integrating_gain"]
        if controller == "PI":
            return _Out(0.35 / (kv * lag), 13.4 * lag)
        return _Out(0.45 / (kv * lag), 8.0 * lag, 0.5 * lag)
    k, t = v["process_gain"], v["time_constant"]
    if controller == "PI":
        kc = 0.15 / k + (0.35 - lag * t / (lag + t) ** 2) * t / (k * lag)
        return _Out(kc, 0.35 * lag + 13.0 * lag * t**2 / (t**2 + 12.0 * lag * t + 7.0 * lag**2))
    tau = lag / (lag + t)
    note = ""
    if tau < 0.3:
        note = (f"normalised dead time tau = L/(L+T) = {tau:.3f} < 0.3: outside the validity "
                "range Åström & Hägglund give for AMIGO PID")
    return _Out((0.2 + 0.45 * t / lag) / k, lag * (0.4 * lag + 0.8 * t) / (lag + 0.1 * t),
                0.5 * lag * t / (0.3 * lag + t), note=note)


def _simc(v: Mapping[str, float], model: tuple[str, ...], controller: str,
          options: Mapping[str, float]) -> _Out:
    """SIMC (Skogestad 2003), τc ≥ 0 (option ``tau_c``, default L: "tight" control).

    FOPDT PI, ideal form (spec 3.6 [S]):  Kc = T/(K(τc + L)),  Ti = min(T, 4(τc + L)).
    SOPDT K·e^(-Ls)/((T1s + 1)(T2s + 1)), T1 = ``time_constant`` ≥ T2 = option ``t2``, PID in
    the **series** form (spec 3.6 [L]):  Kc' = T1/(K(τc + L)),  Ti' = min(T1, 4(τc + L)),
    Td' = T2.
    Integrating k'·e^(-Ls)/s PI (spec 3.6 [L]):  Kc = 1/(k'(τc + L)),  Ti = 4(τc + L).
    """
    lag = v["dead_time"]
    tau_c = options.get("tau_c", lag)
    if model == INTEGRATING:
        return _Out(1.0 / (v["integrating_gain"] * (tau_c + lag)), 4.0 * (tau_c + lag))
    k, t = v["process_gain"], v["time_constant"]
    kc, ti = t / (k * (tau_c + lag)), min(t, 4.0 * (tau_c + lag))
    if controller == "PI":
        return _Out(kc, ti)
    return _Out(kc, ti, options["t2"], form="series")


def _simc_improved(v: Mapping[str, float], model: tuple[str, ...], controller: str,
                   options: Mapping[str, float]) -> _Out:
    """Improved SIMC PI (Grimholt & Skogestad), ideal form (spec 3.6 [S]), option ``tau_c``
    (default L):  Kc = (T + L/3)/(K(τc + L)),  Ti = min(T + L/3, 4(τc + L))."""
    k, lag, t = v["process_gain"], v["dead_time"], v["time_constant"]
    tau_c = options.get("tau_c", lag)
    return _Out((t + lag / 3.0) / (k * (tau_c + lag)), min(t + lag / 3.0, 4.0 * (tau_c + lag)))


def _lambda(v: Mapping[str, float], model: tuple[str, ...], controller: str,
            options: Mapping[str, float]) -> _Out:
    """Lambda tuning PI (form-independent; reported as ideal), option ``lam`` = λ, the desired
    closed-loop time constant (spec 3.6 [L/I]).

    FOPDT (default λ = T):  Kc = T/(K(λ + L)),  Ti = T;  note when λ < L.
    Integrating (default λ = 3L):  Kc = (2λ + L)/(Kv(λ + L)²),  Ti = 2λ + L.  Ms of this loop
    depends on λ/L only; λ = 3L gives Ms ≈ 1.61 (close to SIMC's 1.59 on the worked FOPDT
    example), λ = 2L gives 1.95 and λ = L 3.3, so the note warns when λ < 2L.
    """
    lag = v["dead_time"]
    if model == INTEGRATING:
        lam = options.get("lam", 3.0 * lag)
        note = ""
        if lam < 2.0 * lag:
            note = (f"lam = {lam:g} s < 2L = {2.0 * lag:g} s: Ms above 1.95 on an integrating "
                    "process (too little robustness margin)")
        return _Out((2.0 * lam + lag) / (v["integrating_gain"] * (lam + lag) ** 2),
                    2.0 * lam + lag, note=note)
    k, t = v["process_gain"], v["time_constant"]
    lam = options.get("lam", t)
    note = ""
    if lam < lag:
        note = f"lam = {lam:g} s < L = {lag:g} s: Lambda tuning should never use λ below L"
    return _Out(t / (k * (lam + lag)), t, note=note)


def _imc(v: Mapping[str, float], model: tuple[str, ...], controller: str,
         options: Mapping[str, float]) -> _Out:
    """IMC-PID from a FOPDT model with a 1st-order Padé delay and a 1st-order filter, ideal
    form (spec 3.6 [V, algebra]; Rivera et al. 1986), option ``lam`` = λ (default L):

        Kc = (T + L/2)/(K(λ + L/2)),  Ti = T + L/2,  Td = TL/(2T + L)

    with a note when λ/L < 0.8 (Rivera et al. recommend λ/L ≳ 0.8 for PID [L]).
    """
    k, lag, t = v["process_gain"], v["dead_time"], v["time_constant"]
    lam = options.get("lam", lag)
    note = ""
    if lam / lag < 0.8:
        note = (f"lam/L = {lam / lag:.3g} < 0.8: below the range Rivera et al. recommend for "
                "IMC-PID")
    return _Out((t + lag / 2.0) / (k * (lam + lag / 2.0)), t + lag / 2.0,
                t * lag / (2.0 * t + lag), note=note)


def _rule(name: str, needs: tuple[tuple[str, ...], ...], controllers: tuple[str, ...],
          compute: _Compute, description: str, form: str = "ideal",
          options: tuple[str, ...] = ()) -> tuple[str, Rule]:
    return name, Rule(name, needs, controllers, form, options, description, compute)


RULES: Mapping[str, Rule] = MappingProxyType(dict([
    _rule("zn", (ULTIMATE,), ("P", "PI", "PID"), _zn,
          "Ziegler-Nichols 1942 ultimate-point rule (quarter-decay, aggressive) [L]"),
    _rule("zn_step", (FOPDT,), ("PI", "PID"), _zn_step,
          "Ziegler-Nichols 1942 step-response (reaction curve) rule, a = KL/T"),
    _rule("tyreus_luyben", (ULTIMATE,), ("PI", "PID"), _tyreus_luyben,
          "Tyreus-Luyben 1992 ultimate-point rule, conservative [S: osPID, Yu]"),
    _rule("ciancone_marlin", (ULTIMATE,), ("PI", "PID"), _ciancone_marlin,
          "Ciancone-Marlin ultimate-point rule as tabulated in osPID [S]"),
    _rule("pessen", (ULTIMATE,), ("PID",), _pessen,
          "Pessen integral rule from the ultimate point [S]"),
    _rule("some_overshoot", (ULTIMATE,), ("PID",), _some_overshoot,
          "'some overshoot' ultimate-point PID [S]"),
    _rule("no_overshoot", (ULTIMATE,), ("PID",), _no_overshoot,
          "'no overshoot' ultimate-point PID [S]"),
    _rule("amigo", (INTEGRATING, FOPDT), ("PI", "PID"), _amigo,
          "AMIGO, Åström-Hägglund 2004/2006, FOPDT [S: LBL, AlCap23] or integrating [L]"),
    _rule("amigo_frequency", (ULTIMATE_K,), ("PI", "PID"), _amigo_frequency,
          "AMIGO from the ultimate point and static gain, Åström-Hägglund 2006 §7 [L]"),
    _rule("amigo_f", (RELAY_POINT,), ("PI",), _amigo_f,
          "AMIGO-f at a relay point with hysteresis, Hägglund-Åström 2004, as in osPID [S]"),
    _rule("simc", (INTEGRATING, FOPDT), ("PI", "PID"), _simc,
          "SIMC, Skogestad 2003: FOPDT PI [S], integrating PI [L], SOPDT PID (option t2, "
          "series form) [L]", form="ideal (PI), series (PID)", options=("tau_c", "t2")),
    _rule("simc_improved", (FOPDT,), ("PI",), _simc_improved,
          "improved SIMC PI, Grimholt-Skogestad [S]", options=("tau_c",)),
    _rule("lambda", (INTEGRATING, FOPDT), ("PI",), _lambda,
          "Lambda tuning PI, FOPDT or integrating [L/I]", options=("lam",)),
    _rule("imc", (FOPDT,), ("PID",), _imc,
          "IMC-PID, 1st-order Padé and filter, Rivera et al. 1986 [V, algebra]",
          options=("lam",)),
]))


def rule_names() -> list[str]:
    """The rule names, in the order of spec 3.6."""
    return list(RULES)


def _rule_for(name: str) -> Rule:
    key = name.strip().lower().replace("-", "_")
    if key not in RULES:
        raise ParameterError(f"rule = {name!r} is unknown: one of {', '.join(RULES)}")
    return RULES[key]


def _fields_text(names: tuple[str, ...]) -> str:
    return ", ".join(names)


def _model(rule: Rule, data: ProcessData) -> tuple[str, ...]:
    """The first of the rule's models whose fields are all known, else ParameterError naming
    the missing fields."""
    for model in rule.needs:
        if all(getattr(data, f) is not None for f in model):
            return model
    wants = " or ".join(
        f"{_MODEL_NAMES[m]} ({_fields_text(m)}; missing "
        f"{_fields_text(tuple(f for f in m if getattr(data, f) is None))})"
        for m in rule.needs)
    raise ParameterError(f"rule {rule.name!r} needs ProcessData fields of {wants}")


def _checked(rule: Rule, data: ProcessData, model: tuple[str, ...]) -> tuple[dict[str, float],
                                                                              bool]:
    """The model's fields as floats (gains by magnitude) and whether the gain is negative.
    Ranges: gains finite and non-zero; times, Ku and Kφ in (0, inf); φ in (PHI_MIN, PHI_MAX)."""
    values: dict[str, float] = {}
    direct = False
    for name in model:
        raw = getattr(data, name)
        try:
            x = float(raw)
        except (TypeError, ValueError):
            raise ParameterError(
                f"{name} = {raw!r} is not a number (rule {rule.name!r})") from None
        where = f"is out of range for rule {rule.name!r}"
        if name in ("process_gain", "integrating_gain"):
            if not (math.isfinite(x) and x != 0.0):
                raise ParameterError(f"{name} = {x:g} {where}: allowed finite and non-zero "
                                     "(a negative gain gives a direct-acting controller)")
            direct = x < 0.0  # a model holds one gain
            x = abs(x)
        elif name == "relay_phase_lag":
            if not PHI_MIN < x < PHI_MAX:
                raise ParameterError(
                    f"{name} = {x:g} rad {where}: allowed ({PHI_MIN:.4g}, {PHI_MAX:.4g}) rad "
                    f"= ({math.degrees(PHI_MIN):.1f}°, {math.degrees(PHI_MAX):.1f}°), where "
                    "AMIGO-f gives a positive Kc and Ti (give φ in radians)")
        elif not (math.isfinite(x) and x > 0.0):
            raise ParameterError(f"{name} = {x:g} {where}: allowed (0, inf)")
        values[name] = x
    return values, direct


def _options(rule: Rule, model: tuple[str, ...], controller: str,
             values: Mapping[str, float], options: Mapping[str, float]) -> dict[str, float]:
    """Validated options: tau_c in [0, inf); lam in (0, inf); t2 in (0, T1] (T1 =
    time_constant), required by SIMC PID and only then allowed."""
    out: dict[str, float] = {}
    for name, raw in options.items():
        if name not in rule.options:
            allowed = ", ".join(rule.options) if rule.options else "none"
            raise ParameterError(f"option {name!r} is unknown for rule {rule.name!r}: "
                                 f"its options are {allowed}")
        try:
            x = float(raw)
        except (TypeError, ValueError):
            raise ParameterError(f"{name} = {raw!r} is not a number") from None
        if name == "tau_c" and not (math.isfinite(x) and x >= 0.0):
            raise ParameterError(f"tau_c = {x:g} s is out of range: allowed [0, inf)")
        if name == "lam" and not (math.isfinite(x) and x > 0.0):
            raise ParameterError(f"lam = {x:g} s is out of range: allowed (0, inf)")
        if name == "t2":
            if controller != "PID" or model != FOPDT:
                raise ParameterError(
                    f"t2 = {x:g} s is out of place: it is the second time constant of the "
                    "SOPDT model, used only by simc PID on FOPDT data (process_gain, "
                    "dead_time, time_constant)")
            t1 = values["time_constant"]
            if not (math.isfinite(x) and 0.0 < x <= t1):
                raise ParameterError(f"t2 = {x:g} s is out of range: allowed (0, {t1:g}] s "
                                     "(T2 <= T1 = time_constant)")
        out[name] = x
    if rule.name == "simc" and controller == "PID" and "t2" not in out:
        if model == INTEGRATING:
            raise ParameterError("controller = 'PID' is not offered by rule 'simc' for an "
                                 "integrating process: use 'PI'")
        raise ParameterError("t2 is missing: rule 'simc' gives a PID only for the SOPDT model; "
                             "give option t2, the second time constant, in (0, time_constant]")
    return out


CONTROLLERS = ("P", "PI", "PID")


def check_request(rule: str | None, controller: str, options: Mapping[str, float]) -> None:
    """ParameterError for what :func:`tune` would refuse whatever the process: an unknown
    rule, a controller it does not offer (P, PI or PID without a rule), an option it does
    not take or one out of its range (tau_c, lam); ``loopworks tune`` checks it before its
    relay test (a wrong --rule was told only after the test, or never when the test was
    refused; found by an outside audit)."""
    ctrl = str(controller).strip().upper()
    if rule is None:
        if ctrl not in CONTROLLERS:  # the rule, and its options, come from the data
            raise ParameterError(f"controller = {controller!r} is not allowed: one of "
                                 + ", ".join(CONTROLLERS))
        return
    r = _rule_for(rule)
    if ctrl not in r.controllers:
        raise ParameterError(f"controller = {controller!r} is not offered by rule {r.name!r}: "
                             f"one of {', '.join(r.controllers)}")
    for name, raw in options.items():
        if name == "t2":
            continue  # its range needs the identified time constant
        _options(r, (), ctrl, {}, {name: raw})


def tune(rule: str, data: ProcessData, controller: str = "PI", **options: float) -> Tuning:
    """Settings from tuning rule ``rule`` (a name in ``RULES``) for a ``controller`` ("P",
    "PI" or "PID", any case) from the process ``data``; ``options``: ``tau_c`` (SIMC, s,
    default L), ``lam`` (Lambda, s, default T, or 3L when integrating; IMC, default L), ``t2``
    (SIMC PID, s). Raises ParameterError for an unknown rule, a controller the rule does not
    offer, missing or out-of-range data, and unknown or out-of-range options."""
    r = _rule_for(rule)
    ctrl = str(controller).strip().upper()
    if ctrl not in r.controllers:
        raise ParameterError(f"controller = {controller!r} is not offered by rule {r.name!r}: "
                             f"one of {', '.join(r.controllers)}")
    model = _model(r, data)
    values, direct = _checked(r, data, model)
    opts = _options(r, model, ctrl, values, options)
    out = r.compute(values, model, ctrl, opts)
    _check_settings(r, out)
    notes = [out.note] if out.note else []
    if "pu" in model:
        notes += _not_ultimate(r.name, data)
    tuning = Tuning(rule=r.name, controller=ctrl, form=out.form, kc=out.kc, ti=out.ti,
                    td=out.td, direct=direct)
    ms, on = _robustness(tuning, data)
    if ms is not None and ms > MS_WARNING:
        hf = _derivative_gain(tuning, data)
        notes.append(f"Ms = {ms:.3g} on {on}: " + (
            "the closed loop is unstable" + (
                f" (the unfiltered derivative's gain through the dead time, Kc·Td·|K|/T = "
                f"{hf:.3g}, is 1 or more: a derivative filter decides it)" if hf >= 1.0
                else "") if math.isinf(ms) else
            f"above {MS_WARNING:g}, the upper end of the usual design range 1.2-2 (Åström & "
            "Hägglund 2006): an aggressive tuning with little margin to instability")
            + "; 'amigo' (Ms about 1.4) or a slower rule is more robust")
    return replace(tuning, note="; ".join(notes), ms=ms)


def _derivative_gain(tuning: Tuning, data: ProcessData) -> float:
    """:func:`~loopworks.tuning.robustness.derivative_gain` of the tuning on the data's model,
    0 without a model."""
    ideal = tuning.ideal()
    k = data.process_gain if data.time_constant is not None else data.integrating_gain
    if k is None or data.time_constant == 0.0:
        return 0.0
    return derivative_gain(ideal.kc, ideal.td, gain=k, time_constant=data.time_constant)


def _robustness(tuning: Tuning, data: ProcessData) -> tuple[float | None, str]:
    """Ms of the tuning (ideal form) on the process model the data hold (FOPDT first, then
    integrating), and the model in words; (None, "") without a model with a dead time."""
    ideal = tuning.ideal()
    k, lag, tc = data.process_gain, data.dead_time, data.time_constant
    if k is not None and lag is not None and tc is not None and k != 0.0 and lag > 0.0 \
            and tc > 0.0:
        return (max_sensitivity(ideal.kc, ideal.ti, ideal.td, gain=k, dead_time=lag,
                                time_constant=tc),
                f"the FOPDT model (K {k:.4g}, T {tc:.4g} s, L {lag:.4g} s)")
    kv = data.integrating_gain
    if kv is not None and lag is not None and kv != 0.0 and lag > 0.0:
        return (max_sensitivity(ideal.kc, ideal.ti, ideal.td, gain=kv, dead_time=lag,
                                time_constant=None),
                f"the integrating model (Kv {kv:.4g} 1/s, L {lag:.4g} s)")
    return None, ""


def _not_ultimate(rule: str, data: ProcessData) -> list[str]:
    """The validity note of a rule that reads (Ku, Pu) as the ultimate point when the data
    came from a relay point short of 180° of lag by more than ``ULTIMATE_PHASE_TOLERANCE``
    (a relay with hysteresis, spec 3.1): its period is longer than the ultimate period."""
    phi = data.relay_phase_lag
    if phi is None or not math.pi - float(phi) > ULTIMATE_PHASE_TOLERANCE:
        return []
    short = math.degrees(math.pi - float(phi))
    return [f"rule {rule!r} reads the relay point as the ultimate point, but it lies at "
            f"{math.degrees(float(phi)):.1f}° of lag, {short:.1f}° short of 180° (hysteresis: "
            "spec 3.1): its period pu is longer than the ultimate period, so Ti and Td come "
            "out long (13° gave 9.04 s for Pu 7.44 s on the spec 3.2 plant); less hysteresis, "
            "or rule 'amigo_f' (made for such a point, with a static gain), avoids it"]


def _check_settings(rule: Rule, out: _Out) -> None:
    """Settings a controller can take: Kc finite and > 0, Ti in (0, inf], Td finite and >= 0;
    anything else means the data lie outside the range where the rule's formulas hold, and is
    refused rather than returned (ParameterError naming the setting)."""
    for name, value, ok, allowed in (
            ("kc", out.kc, math.isfinite(out.kc) and out.kc > 0.0, "(0, inf)"),
            ("ti", out.ti, out.ti > 0.0, "(0, inf]"),
            ("td", out.td, math.isfinite(out.td) and out.td >= 0.0, "[0, inf)")):
        if not ok:
            raise ParameterError(
                f"rule {rule.name!r} gives {name} = {value:.4g}, outside {allowed}: the process "
                "data lie outside the range the rule's formulas hold for")


def default_rule(data: ProcessData, controller: str = "PI") -> str:
    """A sensible rule for what is known, in this order: ``amigo`` (FOPDT or integrating model:
    robust, Ms ≈ 1.4), ``amigo_f`` (relay point with static gain, φ within 120-140°),
    ``amigo_frequency`` (ultimate point and static gain), ``tyreus_luyben`` (ultimate point
    only: the conservative ultimate-point rule, Ms 1.59 for PI on the worked example where
    Ziegler-Nichols gives 2.43, and it absorbs part of the relay's Ku bias, spec 3.2). A P
    controller, which only ``zn`` offers (spec 3.6), gets ``zn``. Raises ParameterError when
    no rule has its data."""

    def known(model: tuple[str, ...]) -> bool:
        return all(getattr(data, f) is not None for f in model)

    if str(controller).strip().upper() == "P" and known(ULTIMATE):
        return "zn"
    if known(FOPDT) or known(INTEGRATING):
        return "amigo"
    if known(RELAY_POINT) and data.relay_phase_lag is not None \
            and PHI_VALID[0] <= data.relay_phase_lag <= PHI_VALID[1]:
        return "amigo_f"
    if known(ULTIMATE_K):
        return "amigo_frequency"
    if known(ULTIMATE):
        return "tyreus_luyben"
    models = " or ".join(f"{_MODEL_NAMES[m]} ({_fields_text(m)})"
                         for m in (FOPDT, INTEGRATING, RELAY_POINT, ULTIMATE))
    given = [f.name for f in fields(data) if getattr(data, f.name) is not None]
    raise ParameterError(f"no tuning rule fits the process data (given: "
                         f"{', '.join(given) or 'nothing'}): need {models}")
