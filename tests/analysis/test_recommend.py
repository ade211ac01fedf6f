"""The recommendation (issue 15 point 5): every option simulated on the fitted loop, the
stated rule applied to their figures."""

from __future__ import annotations

import pytest

from loopworks.analysis.recommend import (
    MIN_GAIN,
    OPTIONS,
    TRAVEL_FACTOR,
    recommend,
    scenario_text,
)
from loopworks.errors import InputError
from loopworks.sim.scenario import parse_scenario

FOPDT = {"model": "fopdt", "gain": 1.0, "time_constant_s": 10.0, "dead_time_s": 2.0}


def test_the_fitted_loop_is_a_scenario_with_every_option() -> None:
    sc = parse_scenario(scenario_text(3.0, 1.0, FOPDT, 1.0, 10.0, 0.05, 0.5, 600.0))
    assert list(sc.variants) == list(OPTIONS)
    valve = sc.tables["none"]["valve"]
    assert (valve["s"], valve["j"]) == (3.0, 1.0)
    assert sc.tables["retuned"]["pid"]["ti"] == 20.0  # half the integral action (spec 2.7)
    dk = sc.tables["dither_kicker"]["dither_kicker"]
    assert (dk["resolution"], dk["deadband"]) == (1.0, 2.0)  # spec 1.7: RES = J, DB = S - J
    integrating = parse_scenario(scenario_text(
        2.0, 0.5, {"model": "integrating", "gain": 0.05, "dead_time_s": 4.0}, 2.0, 60.0, 0.05,
        1.0, 600.0))
    assert integrating.tables["none"]["process"]["kind"] == "process.ipdt"


def test_the_rule_picks_the_lowest_variability_at_an_acceptable_travel() -> None:
    rec = recommend(3.0, 1.0, FOPDT, 1.0, 10.0, 0.05, 1.0, samples=8)
    names = [o["name"] for o in rec["options"]]
    assert names == list(OPTIONS)
    base = rec["options"][0]
    ok = [o for o in rec["options"] if o["valve_travel"] <= TRAVEL_FACTOR * base["valve_travel"]]
    best = min(ok, key=lambda o: o["pv_std"])
    if best["pv_std"] <= (1.0 - MIN_GAIN) * base["pv_std"]:
        assert rec["recommended"] == best["name"]
    else:
        assert rec["recommended"] == "none"
    assert "Repair or replace the valve" in rec["summary"]
    for o in rec["options"]:
        assert o["pv_std_p5"] <= o["pv_std"] <= o["pv_std_p95"]
    # a sticky self-regulating loop with J > 0 cycles (spec 5.1): the valve moves
    assert base["valve_travel"] > 0.0


def test_nonsense_is_refused() -> None:
    with pytest.raises(InputError, match=r"S = 0\.0"):
        recommend(0.0, 0.0, FOPDT, 1.0, 10.0, 0.05, 1.0)
    with pytest.raises(InputError, match="Kc"):
        recommend(3.0, 1.0, FOPDT, -1.0, 10.0, 0.05, 1.0)
