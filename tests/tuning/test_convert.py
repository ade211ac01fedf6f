"""Conversion between every controller (issue 6 point 4): golden values from the spec,
exactness, round trips and the errors. Closed-loop matching is in test_convert_closed_loop."""

from __future__ import annotations

import math
import random

import pytest

from loopworks.catalog import create_block
from loopworks.errors import ParameterError
from loopworks.tuning.convert import (
    KINDS,
    convert,
    from_ideal,
    from_loop_units,
    port_spans,
    to_ideal,
)
from loopworks.tuning.settings import Ideal


def close(a: float, b: float, rel: float = 1e-9) -> bool:
    if math.isinf(a) or math.isinf(b):
        return a == b
    return abs(a - b) <= rel * max(abs(a), abs(b), 1e-300)


def test_ge_isa_to_ind_g11() -> None:
    # spec vendor-blocks 1.9 G11: Kc 2.00, Ti 10 s, Td 0.5 s -> Kp 200, Ki 0.2/s (200), Kd 1 s (100)
    c = convert("ge.pid_isa", {"kc": 2.0, "ti": 10.0, "td": 0.5}, "ge.pid_ind")
    assert (c.params["word6"], c.params["word8"], c.params["word7"]) == (200, 200, 100)
    assert close(float(c.params["kp"]), 2.0) and close(float(c.params["ki"]), 0.2)
    assert close(float(c.params["kd"]), 1.0)
    assert c.exact


def test_a_ge_target_keeps_its_every_sweep_sample_period() -> None:
    """GE's Sample Period 0 means every sweep (spec vendor-blocks 1.2, word 3; the block's
    default): a conversion or a `tune` of a GE loop at that default was refused, after the
    whole relay test, "'sample_period' = 0.0 is out of range: allowed (0, inf)" (found by an
    engineer). It stays 0 and the law runs at the loop's scan."""
    c = convert("pid", {"k": 2.0, "ti": 10.0}, "ge.pid_isa", sample_time=0.1,
                target={"sample_period": 0.0})
    assert c.params["sample_period"] == 0.0 and c.params["word8"] == 100
    create_block("ge.pid_isa", **{k: v for k, v in c.params.items()
                                  if not k.startswith("word")})
    with pytest.raises(ParameterError, match="'sample_period' = -1"):
        convert("pid", {"k": 2.0, "ti": 10.0}, "ge.pid_isa", target={"sample_period": -1})


def test_ge_words_as_source() -> None:
    # spec 1.5: Kp = word6/100, Kd = word7/100 s, Ki = word8/1000 /s; ISA word 8 = 1000/Ti
    ideal, exact, _ = to_ideal("ge.pid_ind", {"word6": 400, "word7": 0, "word8": 1500})
    assert close(ideal.kc, 4.0) and close(ideal.ti, 4.0 / 1.5) and ideal.td == 0.0 and exact
    ideal, _, _ = to_ideal("ge.pid_isa", {"word6": 250, "word7": 50, "word8": 40})
    assert close(ideal.kc, 2.5) and close(ideal.ti, 25.0) and close(ideal.td, 0.5)


def test_deltav_series_dv3() -> None:
    # spec vendor-blocks 4.8 DV3: series GAIN 2, RESET 10, RATE 2 -> Kc 2.4, Ti 12, Td 1.6667
    ideal, exact, note = to_ideal("deltav.pid", {"form": "series", "gain": 2, "reset": 10,
                                                 "rate": 2})
    assert close(ideal.kc, 2.4) and close(ideal.ti, 12.0) and close(ideal.td, 20.0 / 12.0)
    assert not exact and "series" in note


def test_s5_pi_example() -> None:
    # spec 2.13: K = R = 1000, TI = 100 nominal, TA = 1 s: TA/TN = 0.1, so TN = 10 s; Kc = 1
    ideal, exact, _ = to_ideal("s5.pid", {"k": 1000, "r": 1000, "ti": 100, "scale": "nominal"},
                               sample_time=1.0)
    assert close(ideal.kc, 1.0) and close(ideal.ti, 10.0) and exact
    # exact scaling: K = 1000/1024 (spec 2.2); R weights only P: Ti = R·TN
    ideal, _, _ = to_ideal("s5.pid", {"k": 1000, "r": 512, "ti": 100}, sample_time=2.0)
    assert close(ideal.kc, 1000 / 1024 * 0.5) and close(ideal.ti, 0.5 * 2.0 / (100 / 1024))
    # K < 0 inverts the action (spec 2.5)
    assert to_ideal("s5.pid", {"k": -1000}, sample_time=1.0)[0].direct


def test_s5_derivative_law_a_is_backward_euler_filter() -> None:
    # spec 2.6 law A: an error step s gives a D part TD·s/2, /4, ... (2.13 table: 100, -50, ..);
    # the converted pid (Tf = TA, kd = K·TV) gives the same outputs scan by scan.
    s5 = create_block("s5.pid", jit=False, k=1024, r=1024, ti=0, td=2048, arithmetic="float")
    conv = convert("s5.pid", {"k": 1024, "r": 1024, "ti": 0, "td": 2048}, "pid",
                   sample_time=1.0)
    assert conv.exact and close(float(conv.params["tf"]), 1.0)
    assert close(float(conv.params["td"]), 2.0)  # Td = TV/R = TD·TA/R
    expected = [200.0, 150.0, 125.0, 112.5, 106.25]  # spec 2.13 D-element check, law A Y
    for want in expected:
        assert s5.step(1.0, w=100.0, x=0.0)["y"].value == pytest.approx(want)
    # pid's first scan has no previous error; compare from a common start instead
    s5 = create_block("s5.pid", jit=False, k=1024, r=1024, ti=0, td=2048, arithmetic="float")
    pid = create_block("pid", jit=False, **conv.params, out_lo=-1e9, out_hi=1e9)
    errors = [0.0, 0.0, 100.0, 100.0, 130.0, 90.0, 90.0, 0.0]
    for e in errors:
        ys = s5.step(1.0, w=e, x=0.0)["y"].value
        yp = pid.step(1.0, sp=e, pv=0.0)["out"].value
        assert yp == pytest.approx(ys, abs=1e-9)


def test_e2_throttling_range_gain() -> None:
    # spec 3.3 E1: TR 10, kp 1: output +10 % per 1 EU, i.e. 10 %/EU; pv span 100 EU -> 10 %/%
    ideal, _, _ = to_ideal("e2.pid", {"throttling_range": 10, "kp": 1, "ki": 0.5,
                                         "kd": 2, "update_interval": 4,
                                         "min_accumulated_error": 0})
    assert close(ideal.kc, 10.0)
    assert close(ideal.ti, 10.0 * 4 / 0.5)  # Kc_port/(ki/Δ)
    assert close(ideal.td, 2 * 4 / 10.0)  # kd·Δ / Kc_port
    assert ideal.direct  # e = input - setpoint (spec 3.3 [A])
    # to E2 with a given TR: kp is chosen (issue: keep kp = 1 unless TR is given)
    c = from_ideal("e2.pid", Ideal(2.0, 20.0), sample_time=2.0,
                   context={"throttling_range": 25.0})
    assert close(float(c.params["kp"]), 2.0 * 25 / 100) and c.exact
    c = from_ideal("e2.pid", Ideal(2.0, 20.0), sample_time=2.0)
    assert c.params["kp"] == 1.0 and close(float(c.params["throttling_range"]), 50.0)
    assert close(float(c.params["ki"]), 2.0 * 2.0 / 20.0)  # 2 %/EU / 20 s · 2 s


def test_e2_default_mae_is_inexact() -> None:
    _, exact, note = to_ideal("e2.pid", {"ki": 0.3})
    assert not exact and "min_accumulated_error" in note and "2 s" in note


def test_pid_forms_and_spans() -> None:
    ideal, exact, _ = to_ideal("pid", {"form": "parallel", "kp": 2, "ki": 0.5, "kd": 1,
                                       "tf": 0.1, "c": 1}, context={"pv_span": 50,
                                                                    "out_span": 200})
    assert close(ideal.kc, 2 * 50 / 200) and close(ideal.ti, 4.0) and close(ideal.td, 0.5)
    assert exact
    c = from_ideal("pid", Ideal(2.0, 10.0, 2.0), context={"form": "series"})
    k, ti, td = (float(c.params[n]) for n in ("k", "ti", "td"))
    # series -> ideal (plant-and-tuning 3.5): K'(1 + Td'/Ti'), Ti' + Td', Ti'Td'/(Ti' + Td')
    assert close(k * (1 + td / ti), 2.0) and close(ti + td, 10.0) and close(ti * td / (ti + td),
                                                                            2.0)


def test_port_spans_and_loop_units() -> None:
    assert port_spans("ge.pid_ind", {}) == (32000.0, 32000.0)
    assert port_spans("s5.pid", {}) == (1000.0, 1000.0)
    assert port_spans("e2.pid", {"pv_span": 40}) == (40.0, 100.0)
    assert port_spans("deltav.pid", {"pv_scale_eu_0": 0, "pv_scale_eu_100": 400,
                                     "out_scale_eu_100": 50}) == (400.0, 50.0)
    # 2 %/EU on an E2 with a 40 EU span is 0.8 %/%: TR = 100/2 = 50 EU with kp = 1
    c = from_loop_units("e2.pid", 2.0, 30.0, 0.0, sample_time=1.0, context={"pv_span": 40})
    assert close(c.ideal.kc, 0.8) and close(float(c.params["throttling_range"]), 50.0)


def test_quantised_words_are_inexact() -> None:
    c = from_ideal("ge.pid_ind", Ideal(2.0, 7.0, 0.0))
    assert c.params["word8"] == 286  # 1000·2/7 = 285.7
    assert not c.exact and "rounding to integer words" in c.note
    rel = abs(2.0 / 0.286 - 7.0) / 7.0
    assert f"{rel:.3g}" in c.note
    c = from_ideal("ge.pid_ind", Ideal(2.0, 7.0, 0.0), context={"arithmetic": "float"})
    assert c.exact and c.params["arithmetic"] == "float"


def test_inexact_bounds_in_note() -> None:
    # DeltaV's filtered derivative onto GE (no filter): αTdω/√(1+(αTdω)²) at ω = 1/Td
    c = convert("deltav.pid", {"gain": 1.5, "reset": 20, "rate": 4, "alpha": 0.125,
                               "structure": "pid_action_on_error"}, "ge.pid_isa",
                sample_time=1.0, target={"arithmetic": "float"})
    assert not c.exact
    a = 0.125
    assert f"{a / math.sqrt(1 + a * a):.3g}" in c.note
    # the one-sample-late reset: ≤ Δ/Ti
    assert f"{1.0 / 20:.3g}" in c.note
    # different sample times of per-sample blocks
    c = convert("e2.pid", {"kp": 1, "throttling_range": 50, "ki": 0.1,
                           "min_accumulated_error": 0, "update_interval": 2}, "s5.pid",
                target={"sample_time": 1.0})
    assert not c.exact and "Δ = 2 s" in c.note
    h = 1.0 / (2.0 * 2.0 / 0.1 * 2.0 / 2.0) / 2.0  # ωΔ/2 at ω = 1/Ti, Ti = 40 s, Δ = 2 s
    assert f"{h / math.sin(h):.6g}" in c.note


def test_setpoint_weights_pass_through() -> None:
    c = convert("pid", {"k": 1, "ti": 10, "td": 1, "tf": 0}, "ge.pid_ind")  # c = 0: D on PV
    assert c.params["derivative_on_pv"] is True and c.exact
    c = convert("pid", {"k": 1, "ti": 10, "td": 1, "tf": 0}, "e2.pid", sample_time=1.0)
    assert not c.exact and "setpoint path" in c.note
    c = convert("pid", {"k": 1, "ti": 10, "td": 1, "tf": 0.25, "c": 1}, "deltav.pid")
    assert c.params["structure"] == "pid_action_on_error" and c.params["alpha"] == 0.25


@pytest.mark.parametrize("kind", KINDS)
def test_unknown_parameter(kind: str) -> None:
    with pytest.raises(ParameterError, match=r"unknown parameter 'bogus'"):
        to_ideal(kind, {"bogus": 1}, sample_time=1.0)


def test_errors_name_parameter_value_range() -> None:
    with pytest.raises(ParameterError, match=r"'sample_time'.*required.*allowed"):
        to_ideal("s5.pid", {"k": 1000})
    with pytest.raises(ParameterError, match=r"td = 3 .*td <= Ti/4"):
        from_ideal("pid", Ideal(1.0, 10.0, 3.0), context={"form": "series"})
    with pytest.raises(ParameterError, match=r"'k' = 40960 is out of range: allowed 0..32767"):
        from_ideal("s5.pid", Ideal(40.0, 10.0), sample_time=1.0)
    with pytest.raises(ParameterError, match=r"'ti' = 102400 is out of range: allowed 0..9999"):
        from_ideal("s5.pid", Ideal(1.0, 0.01), sample_time=1.0)  # TI = 100·1024 words
    with pytest.raises(ParameterError, match=r"'update_interval'.*required"):
        from_ideal("e2.pid", Ideal(1.0, 10.0))
    with pytest.raises(ParameterError, match=r"'kp' = 0.0 has no ideal form"):
        to_ideal("ge.pid_ind", {"kp": 0, "ki": 1})
    with pytest.raises(ParameterError, match=r"kind 'foo'"):
        convert("foo", {}, "pid")
    with pytest.raises(ParameterError, match=r"'d_form' = 'as_printed'"):
        to_ideal("e2.pid", {"d_form": "as_printed"})
    with pytest.raises(ParameterError, match=r"'kp' = -2 is out of range: allowed \[0, inf\)"):
        to_ideal("pid", {"kp": -2.0, "form": "parallel"})


# -- round trips -------------------------------------------------------------------------------
def _random_sources(rng: random.Random) -> list[tuple[str, dict[str, object]]]:
    """Random sources whose law every kind below can realise exactly (D on the error, no
    filter unless S5-like)."""
    kc = rng.uniform(0.2, 5.0)
    ti = rng.uniform(5.0, 200.0)
    td = rng.uniform(0.0, ti / 5.0)
    out: list[tuple[str, dict[str, object]]] = [
        ("pid", {"k": kc, "ti": ti, "td": td, "tf": 0.0, "c": 1.0}),
        ("pid", {"form": "parallel", "kp": kc, "ki": kc / ti, "kd": kc * td, "tf": 0.0,
                 "c": 1.0}),
        ("ge.pid_ind", {"kp": kc, "ki": kc / ti, "kd": kc * td, "arithmetic": "float"}),
        ("ge.pid_isa", {"kc": kc, "ti": ti, "td": td, "arithmetic": "float"}),
        ("e2.pid", {"kp": rng.uniform(0.5, 2.0), "throttling_range": rng.uniform(5, 80),
                    "ki": rng.uniform(0.01, 1.0), "kd": rng.uniform(0.0, 3.0),
                    "min_accumulated_error": 0.0, "update_interval": 1.0}),
        ("s5.pid", {"k": rng.randint(-3000, 3000) or 1, "r": rng.randint(200, 2000),
                    "ti": rng.randint(0, 500), "td": rng.randint(0, 3000)}),
        ("deltav.pid", {"gain": kc, "reset": ti, "rate": td, "alpha": 0.3,
                        "structure": "pid_action_on_error"}),
    ]
    return out


_TARGET_CONTEXT: dict[str, dict[str, object]] = {
    "ge.pid_ind": {"arithmetic": "float"}, "ge.pid_isa": {"arithmetic": "float"}}


def test_round_trips_exact_pairs() -> None:
    rng = random.Random(6)
    exact_pairs: set[tuple[str, str]] = set()
    for _ in range(40):
        for src_kind, params in _random_sources(rng):
            for tgt_kind in KINDS:
                forms = [{"form": f} for f in ("ideal", "parallel", "series")] \
                    if tgt_kind == "pid" else [{}]
                for form in forms:
                    ctx = {**_TARGET_CONTEXT.get(tgt_kind, {}), **form}
                    try:
                        there = convert(src_kind, params, tgt_kind, sample_time=1.0,
                                        target=ctx)
                    except ParameterError:
                        continue  # e.g. series form with Ti < 4·Td, a word out of range
                    if not there.exact:
                        assert "error" in there.note or "differs" in there.note
                        continue
                    exact_pairs.add((src_kind, tgt_kind))
                    back_ctx = dict(_TARGET_CONTEXT.get(src_kind, {}))
                    if src_kind == "s5.pid":
                        back_ctx["r"] = params["r"]
                    if src_kind == "pid":  # a pid converted to a pid keeps its form
                        back_ctx["form"] = params.get("form", "ideal")
                    if src_kind == "e2.pid":
                        back_ctx["throttling_range"] = params["throttling_range"]
                    back = convert(tgt_kind, there.params, src_kind, sample_time=1.0,
                                   target=back_ctx)
                    assert back.exact, (src_kind, tgt_kind, back.note)
                    for name, value in params.items():
                        got = back.params.get(name, value)
                        if isinstance(value, (int, float)) and not isinstance(value, bool):
                            assert close(float(got), float(value)), (src_kind, tgt_kind, name)
    assert len(exact_pairs) >= 15
    # the pairs the spec's equations make exact (module docstring)
    for pair in [("pid", "ge.pid_ind"), ("pid", "ge.pid_isa"), ("pid", "e2.pid"),
                 ("ge.pid_ind", "e2.pid"), ("e2.pid", "ge.pid_isa"), ("s5.pid", "pid"),
                 ("ge.pid_isa", "pid"), ("deltav.pid", "deltav.pid"), ("pid", "pid")]:
        assert pair in exact_pairs, pair
    # DeltaV's one-scan-late reset is never exact against a backward-Euler integral
    assert ("deltav.pid", "pid") not in exact_pairs


def test_an_unknown_target_is_named_before_the_source_is_read() -> None:
    """An S5 source without its sample time is an error too; the unknown target comes first."""
    with pytest.raises(ParameterError, match="kind 'foo' is not allowed"):
        convert("s5.pid", {"k": 1}, "foo")


@pytest.mark.parametrize("text, normalised", [("false", False), ("no", False), ("0", False),
                                              ("true", True), ("ON", True), (True, True)])
def test_a_target_flag_given_as_text_means_what_it_says(text: object, normalised: bool) -> None:
    """``-t i_tr_normalise=false`` from the CLI arrives as the text "false": it means false
    (it meant true before, bool("false")). E2 ki = Kc·Δ/Ti = 2·1/10 = 0.2 %/EU per update,
    times TR/100 = 0.5 when normalised (spec 3.3)."""
    out = convert("pid", {"k": 2.0, "ti": 10.0}, "e2.pid", sample_time=1.0,
                  target={"i_tr_normalise": text, "throttling_range": 50.0})
    assert out.params["ki"] == pytest.approx(0.1 if normalised else 0.2, rel=1e-12)
    assert bool(out.params.get("i_tr_normalise", False)) is normalised
    with pytest.raises(ParameterError, match=r"'d_tr_normalise' = 'maybe' must be true or false"):
        convert("pid", {"k": 2.0, "ti": 10.0}, "e2.pid", sample_time=1.0,
                target={"d_tr_normalise": "maybe"})


@pytest.mark.parametrize("to_kind, target, name", [
    ("s5.pid", {"r": "series"}, "r"), ("s5.pid", {"r": "1e-320"}, "r"),
    ("s5.pid", {"r": "2.5"}, "r"), ("deltav.pid", {"alpha": "AUTO"}, "alpha"),
    ("deltav.pid", {"pv_scale_eu_0": "x"}, "pv_scale_eu_0"),
    ("deltav.pid", {"out_scale_eu_100": "inf"}, "out_scale_eu_100")])
def test_a_malformed_target_setting_is_named(to_kind: str, target: dict[str, str],
                                             name: str) -> None:
    """Target settings from the CLI are text: a malformed one is a ParameterError naming it
    (found by fuzzing `loopworks convert`: they were ValueErrors from int() and float())."""
    with pytest.raises(ParameterError, match=rf"'{name}' = "):
        convert("pid", {"k": 2.0, "ti": 10.0}, to_kind, sample_time=1.0, target=target)


def test_settings_beyond_double_precision_are_refused_with_the_values() -> None:
    """Found by fuzzing `loopworks convert`: a Td of 1e308 s in GE's integer words, a sample
    time of 1e308 s in the frequency responses, one of 1e-320 s divided into E2's gains. Each
    is a ParameterError with the values given, not an OverflowError, a "math domain error"
    or a ZeroDivisionError."""
    with pytest.raises(ParameterError, match=r"'word7' = inf is out of range: allowed "
                                             r"0..32767 \(integer word\)"):
        convert("pid", {"k": 1.0, "td": 1e308}, "ge.pid_isa", sample_time=1.0)
    # a sample time of 1e308 s: 1/Td lies far above the Nyquist frequency π/Δ, where a
    # discrete response is an alias, so no error is stated (it overflowed there before)
    slow = convert("deltav.pid", {"rate": 0.5}, "s5.pid", sample_time=1e308)
    assert not slow.exact and slow.response_errors == () and "Nyquist" in slow.note
    with pytest.raises(ParameterError, match=r"beyond what the conversion can compute .*"
                                             r"sample_time = 1e-320"):
        convert("e2.pid", {}, "e2.pid", sample_time=1e-320)


@pytest.mark.parametrize("to_kind, target, name", [
    ("pid", {"zz": "1"}, "zz"), ("pid", {"k": "5"}, "k"),
    ("s5.pid", {"rounding": "floor"}, "rounding"), ("ge.pid_isa", {"form": "series"}, "form"),
    ("ge.pid_ind", {"word8": "3"}, "word8"), ("e2.pid", {"kp": "2"}, "kp")])
def test_a_target_setting_the_target_does_not_take_is_refused(
        to_kind: str, target: dict[str, str], name: str) -> None:
    """Found by a user's run of `convert -t`: a name the target's realisation never reads
    (unknown, another vendor's, or a parameter the conversion computes) was silently
    ignored, so `-t k=5` left k at 2. It is an error listing the settings it takes."""
    with pytest.raises(ParameterError, match=rf"target setting '{name}' = .* is not one it "
                                             r"takes: allowed .*"):
        convert("pid", {"k": 2.0, "ti": 10.0}, to_kind, sample_time=1.0, target=target)


@pytest.mark.parametrize("kind", ["ge.pid_isa", "s5.pid"])
def test_arithmetic_must_be_native_or_float(kind: str) -> None:
    """`-t arithmetic=bogus` read as native; it is one of native, float (spec: GE words; the
    S5's native arithmetic decides the dead zone a conversion states)."""
    with pytest.raises(ParameterError, match=r"'arithmetic' = 'bogus' is not allowed: "
                                             r"expected one of native, float"):
        convert("pid", {"k": 2.0, "ti": 10.0}, kind, sample_time=1.0,
                target={"arithmetic": "bogus"})


def test_an_integral_rounded_to_a_zero_word_is_refused() -> None:
    """A PI whose integral word rounds to 0 became a P-only controller with exit 0 (GE's
    independent form: word 8 = 1000·Kp/Ti; S5: TI = R·TA/Ti): refused as ge.pid_isa's
    word 8 already was. Kp = 2: word 8 = 2000/Ti >= 0.5 up to Ti = 4000 s; S5 with R = 1024
    (scale exact) and TA = 1 s: TI = 1024/Ti >= 0.5 up to 2048 s."""
    with pytest.raises(ParameterError, match=r"'ti' = 50000 s is out of range: allowed up "
                                             r"to 4000 s .* or inf"):
        convert("pid", {"k": 2.0, "ti": 50000.0}, "ge.pid_ind", sample_time=1.0)
    assert convert("pid", {"k": 2.0, "ti": 3900.0}, "ge.pid_ind",
                   sample_time=1.0).params["word8"] == 1
    with pytest.raises(ParameterError, match=r"'ti' = 100000 s is out of range: allowed up "
                                             r"to 2048 s .* or inf"):
        convert("pid", {"k": 2.0, "ti": 100000.0}, "s5.pid", sample_time=1.0)
    assert convert("pid", {"k": 2.0, "ti": 2000.0}, "s5.pid", sample_time=1.0).params["ti"] == 1


def test_a_kind_converted_to_itself_keeps_its_own_settings() -> None:
    """docs/conversion.md: every kind is exact with itself. s5.pid k = 1200, r = 1000, ti =
    50 at TA = 1 s became r = 1024 (the target's default), k = 1172 and ti = 51 words, not
    exact (found by a user's run); the source's given target settings (S5's r, a pid's or
    DeltaV's form) are now the target's, unless -t says otherwise."""
    src = {"k": 1200, "r": 1000, "ti": 50}
    out = convert("s5.pid", src, "s5.pid", sample_time=1.0)
    assert out.exact and (out.params["k"], out.params["r"], out.params["ti"]) == (1200, 1000, 50)
    assert convert("s5.pid", src, "s5.pid", sample_time=1.0, target={"r": 1024}).params["r"] \
        == 1024
    series = convert("pid", {"k": 2.0, "ti": 10.0, "td": 1.0, "form": "series"}, "pid")
    assert series.exact and series.params["form"] == "series"
    dv = convert("deltav.pid", {"gain": 2.0, "reset": 10.0, "rate": 1.0, "form": "series"},
                 "deltav.pid", sample_time=1.0)
    assert dv.exact and dv.params["form"] == "series"


# -- found by an independent reference of the conversions (2026-12-06) ------------------------


def test_a_pid_dead_band_makes_the_conversion_inexact() -> None:
    """docs/conversion.md: exact means no non-linear option; DeltaV IDEADBAND, GE's dead band
    and E2's MAE say so, but the pid's i_deadband and e_deadband were dropped as "not tuning
    parameters" under "exact: true" (closed loop 0.5 % of PV apart)."""
    for extra in ({"i_deadband": 1.0}, {"e_deadband": 0.5}):
        out = convert("pid", {"k": 2.0, "ti": 10.0, **extra}, "ge.pid_ind", sample_time=1.0)
        name = next(iter(extra))
        assert not out.exact and f"{name} = " in out.note and "not converted" in out.note
        assert "linear laws only" in out.note  # the stated error does not cover it
    assert convert("pid", {"k": 2.0, "ti": 10.0}, "ge.pid_ind", sample_time=1.0).exact


def test_deltav_reset_is_converted_as_the_block_runs_it() -> None:
    """spec 4.7 step 7: R moves by a = Δ/RESET (Euler, capped at 1), Δ/(RESET + Δ)
    (backward) or 1 - e^(-Δ/RESET) (exact) of the way per scan, i.e. the Euler reset of
    RESET_eff = Δ/a. RESET 0.5 s at Δ 1 s ran as RESET 1 s but converted to ti = 0.5 (twice
    the integral); reset_discretisation = exact converted as RESET with error 0."""
    cases = (("euler", 0.5, 1.0), ("backward", 16.0, 17.0),
             ("exact", 16.0, 1.0 / (1.0 - math.exp(-1.0 / 16.0))))
    for law, reset, effective in cases:
        src = {"gain": 1.0, "reset": reset, "reset_discretisation": law}
        dv = convert("deltav.pid", src, "deltav.pid", sample_time=1.0)
        assert dv.exact and close(dv.params["reset"], effective, 1e-12), (law, dv.params)
        assert "converted so" in dv.note
        ideal, _, _ = to_ideal("deltav.pid", src, sample_time=1.0)
        assert close(ideal.ti, effective, 1e-12)
    # the block runs them alike: RESET 0.5 and 1.0 at Δ = 1 s, Euler
    outs = []
    for reset in (0.5, 1.0):
        b = create_block("deltav.pid", gain=1.0, reset=reset)
        outs.append([b.step(1.0, sp=50.0, pv=50.0 - (k % 3))["out"] for k in range(20)])
    assert len(set(outs[0])) > 2  # the reset moved the output
    assert outs[0] == outs[1]


def test_a_conversion_takes_what_the_block_refuses_as_an_error() -> None:
    """The pid refuses k with kp (another form's gains) and deltav.pid RESET = 0; convert
    accepted both, ignoring kp/ki silently and reading RESET 0 as no integral ("Exact")."""
    with pytest.raises(ParameterError, match="'ki' is for the parallel form"):
        convert("pid", {"k": 2.0, "kp": 5.0, "ki": 3.0}, "ge.pid_ind", sample_time=1.0)
    with pytest.raises(ParameterError, match="'k' is for the ideal and series forms"):
        convert("pid", {"form": "parallel", "k": 2.0, "ti": 3.0}, "pid")
    with pytest.raises(ParameterError, match=r"'reset' = 0 is out of range: allowed \(0, inf\]"):
        convert("deltav.pid", {"gain": 1.0, "reset": 0.0}, "pid", sample_time=1.0)
    ok = convert("deltav.pid", {"gain": 1.0, "reset": 0.0, "reset_zero_disables": True}, "pid",
                 sample_time=1.0)
    assert ok.params["ti"] == math.inf


def test_a_gain_word_at_its_limits() -> None:
    """GE word 6 = 100·Kp: Kp 0.004 rounds to 0 (no P, which the block refuses); the error
    showed the rounded 0.0, or blamed ti when Kp was the cause. S5's K is a signed word,
    -32768..+32767 (spec 2.2): a direct-acting K of 32·1024 = -32768 was refused."""
    for kind, name in (("ge.pid_ind", "kp"), ("ge.pid_isa", "kc")):
        for params in ({"k": 0.004}, {"k": 1e-4, "ti": 1e4}):
            with pytest.raises(ParameterError, match=rf"'{name}' = .* allowed 0.005 and above"):
                convert("pid", params, kind, sample_time=1.0)
    assert convert("pid", {"k": 0.004}, "ge.pid_ind", sample_time=1.0,
                   target={"arithmetic": "float"}).params["kp"] == pytest.approx(0.004)
    out = convert("pid", {"k": 32.0, "action": "direct"}, "s5.pid", sample_time=1.0)
    assert out.params["k"] == -32768
    with pytest.raises(ParameterError, match=r"'k' = 32768 is out of range: allowed 0\.\.32767"):
        convert("pid", {"k": 32.0}, "s5.pid", sample_time=1.0)


def test_a_target_at_another_sample_time_is_not_told_two_things() -> None:
    """An E2 source (its law fixed to its update interval, 2 s) converted for a target at
    Δ = 1 s: the note said "Run the target at Δ = 2 s." then "the target at 1 s", which read
    as a contradiction (found by an independent reference). It now says the source's law is
    fixed to 2 s and that what follows is the difference at the 1 s asked for."""
    out = convert("e2.pid", {"update_interval": 2.0, "ki": 0.1}, "pid", sample_time=1.0)
    assert "Run the target at" not in out.note
    assert "fixed to Δ = 2 s (run the target at that Δ); at the 1 s asked for" in out.note
    same = convert("e2.pid", {"update_interval": 2.0, "ki": 0.1}, "pid", sample_time=2.0)
    assert "Run the target at Δ = 2 s." in same.note


def test_a_p_only_e2_keeps_the_sample_time_it_ran_at() -> None:
    """convert(): sample_time is the E2's update interval when it is not given. A P-only E2
    converted to itself kept the block's 2 s default (the laws compared equal: no I or D
    term), and its output was held four times as long; outputs held over other intervals
    are not the same law (found by an outside audit)."""
    src = {"throttling_range": 40.0, "kp": 2.0, "ki": 0.0, "kd": 0.0,
           "min_accumulated_error": 0.0}
    c = convert("e2.pid", src, "e2.pid", sample_time=0.5)
    assert c.exact and c.params["update_interval"] == 0.5
    held = convert("e2.pid", {**src, "update_interval": 2.0}, "pid", sample_time=0.5,
                   target={"form": "ideal"})
    assert not held.exact and "every 2 s" in held.note


def test_a_ge_sample_period_shorter_than_the_scan_is_the_scans_law() -> None:
    """Spec vendor-blocks 1.7 step 3: the GE block measures dt; with a Sample Period of 0.5 s
    on 1 s scans it runs every scan, at 1 s: the same law as the pid at 1 s (it was called
    inexact, with a response error, while the outputs agreed to 1e-14)."""
    c = convert("ge.pid_ind", {"kp": 2.0, "ki": 0.125, "sample_period": 0.5}, "pid",
                sample_time=1.0)
    assert c.exact and c.response_errors == ()
    slower = convert("ge.pid_ind", {"kp": 2.0, "ki": 0.125, "sample_period": 2.0}, "pid",
                     sample_time=1.0)
    assert not slower.exact


def test_what_the_response_errors_leave_out_is_named() -> None:
    """docs/conversion.md: ``unmodelled`` names what ``response_errors`` do not hold: an
    option outside the linear laws (a GE dead band: its stated error 0 while it moved the
    output 11 times as far), or the discretisation when no sample time is known."""
    band = convert("ge.pid_ind", {"kp": 2.0, "ki": 0.1, "deadband_pos": 50,
                                  "deadband_neg": -50}, "pid", sample_time=1.0)
    assert not band.exact and any("dead band" in u for u in band.unmodelled)
    late = convert("pid", {"k": 2.0, "ti": 16.0}, "deltav.pid")
    assert not late.exact and any("no sample time" in u for u in late.unmodelled)
    timed = convert("pid", {"k": 2.0, "ti": 16.0}, "deltav.pid", sample_time=1.0)
    assert timed.unmodelled == () and timed.response_errors[0][1] > 0.0
    assert convert("pid", {"k": 2.0, "ti": 16.0}, "ge.pid_ind").unmodelled == ()


def test_no_response_error_is_stated_above_the_nyquist_frequency() -> None:
    """A discrete response at ω above π/Δ is an alias of a lower one: a pid with Td = 0.1 s
    at Δ = 1 s had its error stated at ω = 1/Td = 10 rad/s (found by an outside audit).
    Only ω = 1/Ti = 1/16 rad/s is stated."""
    c = convert("pid", {"k": 2.0, "ti": 16.0, "td": 0.1, "tf": 0.0}, "deltav.pid",
                sample_time=1.0)
    assert not c.exact and [w for w, _ in c.response_errors] == [1.0 / 16.0]


def test_a_target_that_cannot_hold_the_settings_names_what_was_given() -> None:
    """A target word that overflows is named, and so is what the user gave and the settings
    it stands for: the message named only 'word6' = 40000, a value the user never wrote
    (found by an outside audit)."""
    with pytest.raises(ParameterError) as info:
        convert("pid", {"k": 400, "c": 1}, "ge.pid_ind", sample_time=0.5)
    text = str(info.value)
    assert "'word6' = 40000 is out of range: allowed 0..32767" in text
    assert "(converting pid with k = 400, c = 1: Kc = 400 %/%, Ti = inf s, Td = 0 s;" in text
