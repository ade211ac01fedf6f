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
    # what the ranges do not cover, said with the prediction (an engineer found most true
    # figures outside them: the fitted process and the load are taken as they are)
    assert "cover S and J within ±30 % and the process gain within ±20 % only" in \
        rec["summary"] and "try the option on the plant" in rec["summary"]
    for o in rec["options"]:
        assert o["pv_std_p5"] <= o["pv_std"] <= o["pv_std_p95"]
    # a sticky self-regulating loop with J > 0 cycles (spec 5.1): the valve moves
    assert base["valve_travel"] > 0.0


def test_nonsense_is_refused() -> None:
    with pytest.raises(InputError, match=r"S = 0\.0"):
        recommend(0.0, 0.0, FOPDT, 1.0, 10.0, 0.05, 1.0)
    with pytest.raises(InputError, match="Kc"):
        recommend(3.0, 1.0, FOPDT, -1.0, 10.0, 0.05, 1.0)


def test_a_fitted_loop_that_does_not_reproduce_the_record_predicts_nothing() -> None:
    # the record: plant-and-tuning 5.1's sticky flow loop (FOPDT K 1, T 10 s, L 2 s; PI Kc 1,
    # Ti 10 s; S 3 %, J 1 %). With the controller it was recorded under, the options are
    # predicted; with a controller of 20 times that gain (past the fitted loop's stability
    # limit), the simulated loop varies far more than the record, and nothing is predicted
    import numpy as np

    from loopworks.analysis.diagnosis import REPRODUCE_FACTOR, _recommendation
    from loopworks.analysis.valve_fit import ControllerFit, fit_valve, model_pv

    from .test_valve_fit import closed_loop

    data = closed_loop(3.0, 1.0)
    fit = fit_valve(data)
    model = model_pv(data, fit)
    right = _recommendation(data, fit, ControllerFit(1.0, 10.0, 1.0, True, ""), model, 4)
    assert right is not None and [o["name"] for o in right["options"]] == list(OPTIONS)
    wrong = _recommendation(data, fit, ControllerFit(20.0, 10.0, 1.0, True, ""), model, 4)
    assert wrong is not None and wrong["options"] == [] and wrong["recommended"] is None
    assert "does not reproduce the record" in wrong["summary"]
    recorded = float(np.std(data.sp - data.pv))
    assert f"{REPRODUCE_FACTOR:g} times" in wrong["summary"] and f"{recorded:.3g}" in \
        wrong["summary"]


@pytest.mark.parametrize("process", [
    FOPDT, {"model": "integrating", "gain": 0.04, "dead_time_s": 3.0}], ids=["fopdt", "ipdt"])
def test_the_options_do_not_depend_on_the_pv_units(process: dict[str, float]) -> None:
    """The same loop recorded with its PV in other units (×64, ÷128: exact in binary) gets the
    same options, its PV figures in its own units; a direct-acting loop (K < 0) the same as
    its mirror image. Before, the load and the SP step were in the record's units: the spec
    5.1 loop recorded ×50 moved its valve a tenth as far, and ÷100 was "not reproduced"."""
    args = (3.0, 1.0)
    base = recommend(*args, process, 1.0, 10.0, 0.05, 1.0, samples=4)
    assert base["options"] and base["options"][0]["valve_travel"] > 0.0
    for scale in (64.0, 1.0 / 128.0, -1.0):
        other = {**process, "gain": process["gain"] * scale}
        got = recommend(*args, other, 1.0 / abs(scale), 10.0, 0.05 * abs(scale), 1.0,
                        samples=4)
        assert got["recommended"] == base["recommended"]
        for a, b in zip(base["options"], got["options"], strict=True):
            assert b["name"] == a["name"]
            assert b["valve_travel"] == a["valve_travel"]
            for key in ("pv_std", "pv_std_p5", "pv_std_p95"):
                assert b[key] == pytest.approx(a[key] * abs(scale), rel=1e-12), (scale, key)
