"""Maximum sensitivity of a tuning on its process model (plant-and-tuning 3.6).

Oracles: the spec's worked table (K = 1, T = 10, L = 2: Ms of every rule, [V]) and the
ultimate gain of the FOPDT computed here from its phase condition."""

from __future__ import annotations

import math

import pytest
from scipy.optimize import brentq

from loopworks.tuning.robustness import MS_WARNING, max_sensitivity
from loopworks.tuning.rules import tune
from loopworks.tuning.settings import ProcessData

SPEC = {"gain": 1.0, "time_constant": 10.0, "dead_time": 2.0}


@pytest.mark.parametrize(("kc", "ti", "td", "ms"), [
    (3.826, 6.201, 0.0, 2.43),     # ZN ultimate PI
    (5.102, 3.721, 0.930, 2.35),   # ZN ultimate PID
    (2.657, 16.371, 0.0, 1.59),    # Tyreus-Luyben PI
    (3.865, 16.371, 1.181, 2.14),  # Tyreus-Luyben PID
    (4.500, 6.000, 0.0, 3.09),     # ZN step PI
    (6.000, 4.000, 1.000, 3.34),   # ZN step PID
    (1.206, 7.765, 0.0, 1.26),     # AMIGO PI
    (2.450, 5.867, 0.943, 1.41),   # AMIGO PID
    (1.360, 4.866, 0.0, 1.46),     # AMIGO frequency PI
    (1.327, 6.534, 0.0, 1.33),     # AMIGO-f at 135°
    (2.500, 10.000, 0.0, 1.59),    # SIMC PI
    (2.667, 10.667, 0.0, 1.64),    # improved SIMC PI
    (0.833, 10.000, 0.0, 1.16),    # Lambda PI
    (3.667, 11.000, 0.909, 1.77),  # IMC-PID
])
def test_the_spec_worked_table(kc: float, ti: float, td: float, ms: float) -> None:
    # spec 3.6 worked example: Ms of the ideal, unfiltered controller on the exact plant
    assert max_sensitivity(kc, ti, td, **SPEC) == pytest.approx(ms, abs=0.006)


def _ultimate(k: float, tc: float, lag: float) -> tuple[float, float]:
    """Ku, Pu of K·e^(-Ls)/(Ts + 1): atan(ωT) + ωL = π, Ku = √(1 + (ωT)²)/K."""
    w = brentq(lambda w: math.atan(w * tc) + w * lag - math.pi, 1e-9, math.pi / lag)
    return math.sqrt(1.0 + (w * tc) ** 2) / k, 2.0 * math.pi / w


def test_a_p_controller_beyond_the_ultimate_gain_is_unstable() -> None:
    ku, _ = _ultimate(1.0, 10.0, 2.0)
    assert ku == pytest.approx(8.5024, abs=1e-4)  # spec 3.6
    assert max_sensitivity(1.01 * ku, math.inf, 0.0, **SPEC) == math.inf
    below = max_sensitivity(0.99 * ku, math.inf, 0.0, **SPEC)
    assert 50.0 < below < math.inf  # 1/(1 - 0.99)-ish: the curve passes just right of -1


def test_integrating_models_and_derivative_through_the_delay() -> None:
    # AMIGO PI on Kv e^(-Ls)/s, Kc = 0.35/(Kv L), Ti = 13.4 L (spec 3.6) is a robust tuning;
    # Kc 2, Ti 1 on the same plant is unstable (the phase at the crossover is below -180°)
    integ = {"gain": 1.0, "dead_time": 2.0, "time_constant": None}
    assert 1.2 < max_sensitivity(0.35 / 2.0, 13.4 * 2.0, 0.0, **integ) < 1.6
    assert max_sensitivity(2.0, 1.0, 0.0, **integ) == math.inf
    # |C G| -> Kc Td K / T at high frequency while the delay turns the phase: >= 1, unstable
    assert max_sensitivity(2.0, 10.0, 5.0, **SPEC) == math.inf
    assert max_sensitivity(2.0, 10.0, 2.0, **SPEC) < 2.0


def test_an_aggressive_rule_on_a_delay_dominant_plant_is_marked() -> None:
    # Ziegler-Nichols PID from the exact ultimate point of a delay-dominant FOPDT (T = L/10):
    # Kc·Td·K/T = 0.6 Ku·(Pu/8)/T is far above 1, the unfiltered loop is unstable, and the
    # note says so; ZN PI on the same data stays inside 1.2-2 and gets no note, and so does
    # AMIGO PID
    k, tc, lag = 1.0, 0.5, 5.0
    ku, pu = _ultimate(k, tc, lag)
    data = ProcessData(ku=ku, pu=pu, process_gain=k, dead_time=lag, time_constant=tc)
    zn = tune("zn", data, "PID")
    assert zn.ms == math.inf
    assert "Ms = inf on the FOPDT model" in zn.note and "unstable" in zn.note
    assert f"{0.6 * ku * pu / 8 * k / tc:.3g}, is 1 or more" in zn.note
    pi = tune("zn", data, "PI")
    assert pi.ms == pytest.approx(max_sensitivity(0.45 * ku, pu / 1.2, 0.0, gain=k,
                                                  dead_time=lag, time_constant=tc))
    assert pi.ms is not None and pi.ms < MS_WARNING and "Ms =" not in pi.note
    aggressive = tune("zn_step", ProcessData(process_gain=1.0, time_constant=10.0,
                                             dead_time=2.0), "PI")
    assert aggressive.ms == pytest.approx(3.09, abs=0.006)  # spec 3.6 worked table
    assert "Ms = 3.09 on the FOPDT model" in aggressive.note
    amigo = tune("amigo", data, "PID")
    assert amigo.ms is not None and amigo.ms < MS_WARNING and "Ms =" not in amigo.note
    assert tune("zn", ProcessData(ku=ku, pu=pu), "PI").ms is None  # no model: no Ms


def test_a_derivative_gain_through_the_delay_below_one_is_no_instability() -> None:
    # Pessen PID from the exact ultimate point of K 1, L 4 s, T 2 s: Kc·Td·K/T = 0.90 < 1.
    # At high frequency 1 + C·G circles 1 at radius 0.90 and its last angle swings by up to
    # asin(0.90) = 64°: a 45° tolerance on it called this stable loop unstable (found by a
    # reviewer; it settles in a simulation with 50 % overshoot)
    ku, pu = _ultimate(1.0, 2.0, 4.0)
    kc, ti, td = ku / 1.4, pu / 2.5, pu / 6.65  # spec 3.6, Pessen integral rule
    assert 0.85 < kc * td / 2.0 < 1.0
    ms = max_sensitivity(kc, ti, td, gain=1.0, dead_time=4.0, time_constant=2.0)
    assert MS_WARNING < ms < math.inf
    note = tune("pessen", ProcessData(ku=ku, pu=pu, process_gain=1.0, dead_time=4.0,
                                      time_constant=2.0), "PID").note
    assert "Ms = " in note and "unstable" not in note

