"""Tuning rules (plant-and-tuning 3.6; the ZN series reading is 3.5).

Golden values: the worked-example table at the end of spec 3.6 (K = 1, T = 10, L = 2,
Ku = 8.5024, Pu = 7.4415) including its Ms column, and, for rules the table does not list, the
spec's formulas evaluated by hand in the test. Ms is computed here with numpy on a dense
frequency grid, independently of loopworks.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from loopworks.blocks import forms
from loopworks.errors import ParameterError
from loopworks.tuning.rules import RULES, Tuning, default_rule, rule_names, tune
from loopworks.tuning.settings import Ideal, ProcessData

K, T, L = 1.0, 10.0, 2.0
KU, PU = 8.5024, 7.4415
KV = 0.1  # integrating example Kv·e^(-2s)/s (spec 3.2)

FOPDT = ProcessData(process_gain=K, dead_time=L, time_constant=T)
ULTIMATE = ProcessData(ku=KU, pu=PU)
ULTIMATE_K = ProcessData(ku=KU, pu=PU, process_gain=K)
RELAY_135 = ProcessData(relay_gain=5.028, relay_period=12.75, relay_phase_lag=math.radians(135),
                        process_gain=K)
INTEGRATING = ProcessData(integrating_gain=KV, dead_time=L)
EVERYTHING = ProcessData(ku=KU, pu=PU, process_gain=K, dead_time=L, time_constant=T,
                         relay_gain=5.028, relay_period=12.75,
                         relay_phase_lag=math.radians(135))

W = np.logspace(-4, 2, 300_000)


def max_sensitivity(kc: float, ti: float, td: float, plant: str = "fopdt") -> float:
    """Ms = max over ω of |1/(1 + C(jω)G(jω))|, C = Kc(1 + 1/(Ti jω) + Td jω) (ideal,
    unfiltered), G = e^(-2jω)/(10jω + 1) or 0.1·e^(-2jω)/(jω)."""
    s = 1j * W
    c = kc * (1.0 + 1.0 / (ti * s) + td * s)
    g = np.exp(-L * s) / (T * s + 1.0) if plant == "fopdt" else KV * np.exp(-L * s) / s
    return float(np.max(np.abs(1.0 / (1.0 + c * g))))


# spec 3.6 worked example: rule, controller, data, options, Kc, Ti, Td (None = —), Ms
TABLE = [
    ("zn", "PI", ULTIMATE, {}, 3.826, 6.201, None, 2.43),
    ("zn", "PID", ULTIMATE, {}, 5.102, 3.721, 0.930, 2.35),
    ("tyreus_luyben", "PI", ULTIMATE, {}, 2.657, 16.371, None, 1.59),
    ("tyreus_luyben", "PID", ULTIMATE, {}, 3.865, 16.371, 1.181, 2.14),
    ("zn_step", "PI", FOPDT, {}, 4.500, 6.000, None, 3.09),
    ("zn_step", "PID", FOPDT, {}, 6.000, 4.000, 1.000, 3.34),
    ("amigo", "PI", FOPDT, {}, 1.206, 7.765, None, 1.26),
    ("amigo", "PID", FOPDT, {}, 2.450, 5.867, 0.943, 1.41),
    ("amigo_frequency", "PI", ULTIMATE_K, {}, 1.360, 4.866, None, 1.46),
    ("amigo_f", "PI", RELAY_135, {}, 1.327, 6.534, None, 1.33),
    ("simc", "PI", FOPDT, {"tau_c": L}, 2.500, 10.000, None, 1.59),
    ("simc_improved", "PI", FOPDT, {"tau_c": L}, 2.667, 10.667, None, 1.64),
    ("lambda", "PI", FOPDT, {"lam": T}, 0.833, 10.000, None, 1.16),
    ("imc", "PID", FOPDT, {"lam": L}, 3.667, 11.000, 0.909, 1.77),
]


@pytest.mark.parametrize(("rule", "controller", "data", "options", "kc", "ti", "td", "ms"),
                         TABLE, ids=[f"{r[0]}-{r[1]}" for r in TABLE])
def test_worked_example_row(rule: str, controller: str, data: ProcessData,
                            options: dict[str, float], kc: float, ti: float, td: float | None,
                            ms: float) -> None:
    # spec 3.6: to the printed digits (one unit in the last place: the table's inputs Ku, K135,
    # P135 are themselves rounded, and its ZN PID Kc 5.102 is 0.6·8.5024 = 5.1014 rounded up)
    t = tune(rule, data, controller, **options)
    assert (t.rule, t.controller, t.form) == (rule, controller, "ideal")
    assert t.kc == pytest.approx(kc, abs=1e-3)
    assert t.ti == pytest.approx(ti, abs=1e-3)
    assert t.td == (0.0 if td is None else pytest.approx(td, abs=1e-3))
    ideal = t.ideal()
    assert (ideal.kc, ideal.ti, ideal.td, ideal.tf) == (t.kc, t.ti, t.td, 0.0)
    assert max_sensitivity(ideal.kc, ideal.ti, ideal.td) == pytest.approx(ms, abs=0.015)


def test_defaults_are_the_worked_example_choices() -> None:
    # spec 3.6: SIMC τc = L, Lambda λ = T, IMC λ = L
    for rule, options in (("simc", {"tau_c": L}), ("simc_improved", {"tau_c": L}),
                          ("lambda", {"lam": T})):
        assert tune(rule, FOPDT) == tune(rule, FOPDT, "PI", **options)
    assert tune("imc", FOPDT, "PID") == tune("imc", FOPDT, "PID", lam=L)


def test_amigo_frequency_pid() -> None:
    # spec 3.6: κ = 1/(K·Ku); Kc = (0.3 - 0.1κ⁴)Ku, Ti = 0.6Pu/(1 + 2κ),
    # Td = 0.15(1 - κ)Pu/(1 - 0.95κ); "Ms ≈ 1.46" on the example plant [V]
    kappa = 1.0 / (1.0 * 8.5024)
    assert kappa == pytest.approx(0.1176, abs=1e-4)
    t = tune("amigo_frequency", ULTIMATE_K, "PID")
    assert t.kc == pytest.approx((0.3 - 0.1 * kappa**4) * 8.5024, rel=1e-12)
    assert t.ti == pytest.approx(0.6 * 7.4415 / (1.0 + 2.0 * kappa), rel=1e-12)
    assert t.td == pytest.approx(0.15 * (1.0 - kappa) * 7.4415 / (1.0 - 0.95 * kappa), rel=1e-12)
    assert max_sensitivity(t.kc, t.ti, t.td) == pytest.approx(1.46, abs=0.015)


def test_zn_pid_ideal_is_the_series_quarter_period_pid() -> None:
    # spec 3.5 note: the ideal ZN PID equals a series PID with Ti' = Td' = Pu/4, Kc' = 0.3Ku
    t = tune("zn", ULTIMATE, "PID")
    series = forms.ideal_to_series(t.kc, t.ti, t.td)
    assert series == pytest.approx((0.3 * KU, PU / 4.0, PU / 4.0), rel=1e-12)
    kc, ti, td = forms.series_to_ideal(0.3 * KU, PU / 4.0, PU / 4.0)
    ideal = t.ideal()
    assert (ideal.kc, ideal.ti, ideal.td) == pytest.approx((kc, ti, td), rel=1e-12)


@pytest.mark.parametrize(("rule", "controller", "factors"), [
    # spec 3.6 ultimate-point table: Kc = a·Ku, Ti = b·Pu, Td = c·Pu (b = inf: no integral)
    ("zn", "P", (0.5, math.inf, 0.0)),
    ("ciancone_marlin", "PI", (1 / 3.3, 1 / 4, 0.0)),
    ("ciancone_marlin", "PID", (1 / 3.3, 1 / 4.4, 1 / 8.1)),
    ("pessen", "PID", (1 / 1.4, 1 / 2.5, 1 / 6.65)),
    ("some_overshoot", "PID", (1 / 3, 1 / 2, 1 / 3)),
    ("no_overshoot", "PID", (1 / 5, 1 / 2, 1 / 3)),
])
def test_ultimate_point_rules(rule: str, controller: str,
                              factors: tuple[float, float, float]) -> None:
    a, b, c = factors
    t = tune(rule, ULTIMATE, controller)
    assert (t.kc, t.ti, t.td) == pytest.approx((a * KU, b * PU, c * PU), rel=1e-12)
    assert t.form == "ideal"


def test_integrating_rules() -> None:
    # spec 3.6, integrating Kv·e^(-Ls)/s with Kv = 0.1, L = 2 (so Kv·L = 0.2)
    data = INTEGRATING
    t = tune("amigo", data, "PI")  # Kc = 0.35/(Kv·L), Ti = 13.4L
    assert (t.kc, t.ti, t.td) == pytest.approx((1.75, 26.8, 0.0))
    t = tune("amigo", data, "PID")  # Kc = 0.45/(Kv·L), Ti = 8L, Td = 0.5L
    assert (t.kc, t.ti, t.td) == pytest.approx((2.25, 16.0, 1.0))
    t = tune("simc", data)  # Kc = 1/(k'(τc + L)), Ti = 4(τc + L), τc = L
    assert (t.kc, t.ti, t.td) == pytest.approx((2.5, 16.0, 0.0))
    t = tune("simc", data, tau_c=1.0)
    assert (t.kc, t.ti) == pytest.approx((1.0 / (0.1 * 3.0), 12.0))
    t = tune("lambda", data, lam=5.0)  # Kc = (2λ + L)/(Kv(λ + L)²), Ti = 2λ + L
    assert (t.kc, t.ti) == pytest.approx((12.0 / (0.1 * 49.0), 12.0))
    assert t.note == ""


def test_integrating_lambda_default_and_its_ms() -> None:
    # default λ = 3L: Kc = 7L/(Kv·16L²) = 7/(16·0.1·2), Ti = 7L; Ms depends on λ/L only
    t = tune("lambda", INTEGRATING)
    assert (t.kc, t.ti) == pytest.approx((7.0 / 3.2, 14.0))
    assert max_sensitivity(t.kc, t.ti, 0.0, "integrating") == pytest.approx(1.61, abs=0.01)
    assert t.note == ""
    t2 = tune("lambda", INTEGRATING, lam=2 * L)
    assert max_sensitivity(t2.kc, t2.ti, 0.0, "integrating") == pytest.approx(1.95, abs=0.01)
    assert t2.note == ""
    assert "2L" in tune("lambda", INTEGRATING, lam=1.9 * L).note


def test_integrating_gain_takes_precedence() -> None:
    both = ProcessData(process_gain=K, dead_time=L, time_constant=T, integrating_gain=KV)
    assert tune("amigo", both).ti == pytest.approx(13.4 * L)


def test_simc_sopdt_pid_is_series() -> None:
    # spec 3.6: SIMC SOPDT PID in series form: Kc' = T1/(K(τc + L)), Ti' = min(T1, 4(τc+L)),
    # Td' = T2; T1 = 10, T2 = 3, τc = L = 2 -> (2.5, 10, 3); ideal by spec 3.5 by hand:
    # Kc = 2.5·(1 + 3/10) = 3.25, Ti = 13, Td = 30/13
    t = tune("simc", FOPDT, "PID", t2=3.0)
    assert t.form == "series"
    assert (t.kc, t.ti, t.td) == pytest.approx((2.5, 10.0, 3.0))
    ideal = t.ideal()
    assert isinstance(ideal, Ideal)
    assert (ideal.kc, ideal.ti, ideal.td, ideal.tf) == pytest.approx((3.25, 13.0, 30.0 / 13.0, 0))


def test_validity_notes() -> None:
    # spec 3.6: AMIGO PID τ = L/(L+T) < 0.3; IMC λ/L < 0.8; Lambda λ < L; AMIGO-f φ 120-140°
    assert "0.167" in tune("amigo", FOPDT, "PID").note
    assert tune("amigo", ProcessData(process_gain=1, dead_time=5, time_constant=5), "PID").note \
        == ""
    assert "0.8" in tune("imc", FOPDT, "PID", lam=1.5).note
    assert "Rivera" not in tune("imc", FOPDT, "PID", lam=1.6).note  # (its Ms 2.01 is noted)
    assert "< L = 2 s" in tune("lambda", FOPDT, lam=1.9).note
    assert tune("lambda", FOPDT, lam=2.0).note == ""
    off = ProcessData(relay_gain=5.0, relay_period=12.0, relay_phase_lag=math.radians(110),
                      process_gain=1.0)
    assert "120-140" in tune("amigo_f", off).note
    assert tune("amigo_f", RELAY_135).note == ""


def test_negative_process_gain_gives_direct_action() -> None:
    neg = ProcessData(process_gain=-K, dead_time=L, time_constant=T)
    t, ref = tune("amigo", neg, "PID"), tune("amigo", FOPDT, "PID")
    assert (t.kc, t.ti, t.td, t.direct, ref.direct) == (ref.kc, ref.ti, ref.td, True, False)
    assert t.ideal().direct


def test_every_rule_and_controller_gives_positive_settings() -> None:
    for name, rule in RULES.items():
        assert rule.name == name and rule.description and rule.controllers
        data = INTEGRATING if name == "lambda" else EVERYTHING
        for controller in rule.controllers:
            options = {"t2": 1.0} if (name, controller) == ("simc", "PID") else {}
            t = tune(name, data, controller.lower(), **options)
            assert isinstance(t, Tuning) and t.controller == controller
            assert math.isfinite(t.kc) and t.kc > 0 and t.ti > 0 and t.td >= 0
            assert (t.ti == math.inf) == (controller == "P")
            assert (t.td > 0) == (controller == "PID")


def test_rule_names_and_docs_page() -> None:
    names = rule_names()
    assert names == list(RULES) and len(set(names)) == len(names) == 14
    page = (Path(__file__).resolve().parents[2] / "docs" / "tuning-rules.md").read_text()
    for name in names:
        assert f"`{name}`" in page, f"docs/tuning-rules.md does not describe {name}"


def test_default_rule() -> None:
    assert default_rule(EVERYTHING) == "amigo"
    assert default_rule(INTEGRATING) == "amigo"
    assert default_rule(ProcessData(ku=KU, pu=PU, process_gain=K, relay_gain=5.028,
                                    relay_period=12.75, relay_phase_lag=math.radians(135))) \
        == "amigo_f"
    assert default_rule(ProcessData(ku=KU, pu=PU, process_gain=K, relay_gain=5.0,
                                    relay_period=12.0, relay_phase_lag=math.radians(170))) \
        == "amigo_frequency"
    assert default_rule(ULTIMATE_K) == "amigo_frequency"
    assert default_rule(ULTIMATE) == "tyreus_luyben"
    with pytest.raises(ParameterError, match="ku, pu"):
        default_rule(ProcessData(ku=KU))


# --- bad input ------------------------------------------------------------------------------

def test_missing_data_names_field_and_rule() -> None:
    with pytest.raises(ParameterError, match=r"'zn'.*missing pu"):
        tune("zn", ProcessData(ku=KU))
    with pytest.raises(ParameterError, match=r"'amigo'.*missing time_constant"):
        tune("amigo", ProcessData(process_gain=K, dead_time=L))
    with pytest.raises(ParameterError, match=r"'amigo_frequency'.*missing process_gain"):
        tune("amigo_frequency", ULTIMATE)


def test_controller_not_offered_lists_offered() -> None:
    with pytest.raises(ParameterError, match=r"'PID'.*'lambda'.*one of PI$"):
        tune("lambda", FOPDT, "PID")
    with pytest.raises(ParameterError, match=r"'pessen'.*one of PID$"):
        tune("pessen", ULTIMATE, "PI")
    with pytest.raises(ParameterError, match="one of P, PI, PID"):
        tune("zn", ULTIMATE, "PD")
    with pytest.raises(ParameterError, match="integrating"):
        tune("simc", INTEGRATING, "PID")


@pytest.mark.parametrize(("rule", "controller", "options", "message"), [
    ("simc", "PI", {"tau_c": -0.1}, r"tau_c = -0\.1 s .*\[0, inf\)"),
    ("simc_improved", "PI", {"tau_c": math.nan}, r"tau_c = nan"),
    ("lambda", "PI", {"lam": 0.0}, r"lam = 0 s .*\(0, inf\)"),
    ("imc", "PID", {"lam": -1.0}, r"lam = -1 s .*\(0, inf\)"),
    ("zn_step", "PI", {"lam": 1.0}, r"'lam' is unknown for rule 'zn_step'.*none"),
    ("lambda", "PI", {"tau_c": 1.0}, r"'tau_c' is unknown.*options are lam"),
    ("simc", "PID", {}, r"t2 is missing"),
    ("simc", "PID", {"t2": 0.0}, r"t2 = 0 s .*\(0, 10\]"),
    ("simc", "PID", {"t2": 11.0}, r"t2 = 11 s .*\(0, 10\]"),
    ("simc", "PI", {"t2": 3.0}, r"t2 = 3 s .*only by simc PID"),
])
def test_bad_options(rule: str, controller: str, options: dict[str, float],
                     message: str) -> None:
    with pytest.raises(ParameterError, match=message):
        tune(rule, FOPDT, controller, **options)


@pytest.mark.parametrize(("rule", "data", "message"), [
    ("amigo", ProcessData(process_gain=K, dead_time=0.0, time_constant=T),
     r"dead_time = 0 .*'amigo'.*\(0, inf\)"),
    ("zn", ProcessData(ku=-1.0, pu=PU), r"ku = -1 .*\(0, inf\)"),
    ("zn", ProcessData(ku=KU, pu=math.inf), r"pu = inf .*\(0, inf\)"),
    ("simc", ProcessData(process_gain=0.0, dead_time=L, time_constant=T),
     r"process_gain = 0 .*non-zero"),
    ("amigo_f", ProcessData(relay_gain=5.0, relay_period=12.0, relay_phase_lag=135.0,
                            process_gain=1.0), r"relay_phase_lag = 135 rad .*radians"),
])
def test_bad_data(rule: str, data: ProcessData, message: str) -> None:
    with pytest.raises(ParameterError, match=message):
        tune(rule, data)


def test_data_outside_a_rules_validity_is_refused() -> None:
    # issue 11: AMIGO frequency needs κ = 1/(K·Ku) < 1 (a low-pass plant has 1/Ku = |G(jωu)|
    # < K; the PID's Td has a pole at κ = 1/0.95). Before: PI Kc = 0.16·Ku, Ti = Pu/(1 + 9)
    # returned for K·Ku = 0.5.
    with pytest.raises(ParameterError, match=r"process_gain·ku = 0\.5 .*\(1, inf\)"):
        tune("amigo_frequency", ProcessData(ku=0.5, pu=PU, process_gain=1.0))
    with pytest.raises(ParameterError, match="process_gain·ku = 1 "):
        tune("amigo_frequency", ProcessData(ku=1.0, pu=PU, process_gain=1.0), "PID")
    # AMIGO-f at φ = 2.7 rad with κ = 20: (2.50 - 0.92φ)/(1 + (10.75 - 4.01φ)κ) < 0, a
    # negative gain (before: returned as Kc = -0.03 Kφ)
    phi = 2.7
    kappa = 20.0
    assert (2.50 - 0.92 * phi) / (1.0 + (10.75 - 4.01 * phi) * kappa) < 0.0
    with pytest.raises(ParameterError, match=r"'amigo_f' gives kc = -.*outside \(0, inf\)"):
        tune("amigo_f", ProcessData(relay_gain=1.0, relay_period=10.0, relay_phase_lag=phi,
                                    process_gain=1.0 / kappa))


def test_unknown_rule_lists_rules() -> None:
    with pytest.raises(ParameterError, match=r"'ziegler'.*zn, zn_step"):
        tune("ziegler", ULTIMATE)
    assert tune("ZN-Step", FOPDT).rule == "zn_step"


def test_a_ku_pu_rule_on_a_hysteresis_point_is_marked() -> None:
    """Spec 3.1: with hysteresis the relay point lies at π − arcsin(ε/a) of lag, not 180°;
    its period is not Pu (spec 3.2 table, ε = 0.05: P 9.039 s against Pu 7.4415 s). Tyreus-
    Luyben read it as the ultimate point silently (Ti 45 % long at ε = 0.5, found by an
    independent reference): a rule reading pu says so; a point within 5° is not marked."""
    a, eps = 0.22221, 0.05
    phi = math.pi - math.asin(eps / a)  # 13.0° short of 180°
    data = ProcessData(ku=5.881, pu=9.039, relay_phase_lag=phi)
    for rule in ("tyreus_luyben", "zn"):
        t = tune(rule, data, "PI")
        assert "short of 180°" in t.note and f"{math.degrees(math.pi - phi):.1f}°" in t.note
    assert tune("tyreus_luyben", data, "PI").ti == pytest.approx(2.2 * 9.039)  # still given
    near = ProcessData(ku=7.0, pu=7.4, relay_phase_lag=math.pi - math.radians(4.0))
    assert tune("tyreus_luyben", near, "PI").note == ""
    assert tune("tyreus_luyben", ProcessData(ku=7.0, pu=7.4), "PI").note == ""
    # a FOPDT rule does not read pu: no note
    fopdt = ProcessData(process_gain=1.0, dead_time=2.0, time_constant=10.0,
                        ku=5.881, pu=9.039, relay_phase_lag=phi)
    assert tune("amigo", fopdt, "PI").note == ""


def test_a_p_controller_gets_the_rule_that_offers_one() -> None:
    """`tune --controller P` failed: the default (amigo) offers PI and PID only; Ziegler-
    Nichols is the rule with a P setting (spec 3.6: Kc = 0.5 Ku)."""
    assert default_rule(EVERYTHING, "P") == "zn"
    assert default_rule(EVERYTHING, "PI") == "amigo"
    assert tune(default_rule(ULTIMATE, "p"), ULTIMATE, "P").kc == pytest.approx(0.5 * KU)
