"""``loopworks.compat.PID`` against simple-pid 2.0.1 itself (the independent reference), and
what it does differently on purpose (its module docstring)."""

from __future__ import annotations

import math
import random
from typing import Any

import pytest
import simple_pid

from loopworks.compat import PID
from loopworks.errors import ParameterError


def _settings(rng: random.Random) -> tuple[dict[str, Any], bool]:
    kw: dict[str, Any] = {
        "Kp": rng.choice([0.0, 0.5, 2.0]), "Ki": rng.choice([0.0, 0.3, 1.5]),
        "Kd": rng.choice([0.0, 0.05, 0.4]), "setpoint": rng.uniform(-5, 5),
        "sample_time": rng.choice([None, 0.01, 0.2]),
        "output_limits": rng.choice([(None, None), (-3, 3), (0, None), (None, 1.0)]),
        "proportional_on_measurement": rng.random() < 0.5,
        "differential_on_measurement": rng.random() < 0.5,
        "starting_output": rng.uniform(-2, 2)}
    if rng.random() < 0.3:
        kw["error_map"] = lambda e: max(-1.0, min(1.0, e))
    direct = rng.random() < 0.3
    if direct:
        kw["Kp"], kw["Ki"], kw["Kd"] = -kw["Kp"], -kw["Ki"], -kw["Kd"]
    return kw, direct


@pytest.mark.parametrize("seed", range(40))
def test_same_outputs_and_components_as_simple_pid(seed: int) -> None:
    """Random settings (signs, limits, P and D on measurement or error, an error map,
    sample_time) and a random session of 300 calls (dt given or from time_fn, setpoint and
    Kp changes, manual and back, set_auto_mode with a last output) on a bounded plant: the
    port's output and components equal simple-pid's to 1e-9 (relative) at every call."""
    rng = random.Random(seed)
    kw, direct = _settings(rng)
    now = [0.0]
    theirs = simple_pid.PID(time_fn=lambda: now[0], **kw)
    ours = PID(time_fn=lambda: now[0], **kw)
    pv = 0.0
    for k in range(300):
        now[0] += 0.1
        if rng.random() < 0.02:
            theirs.setpoint = ours.setpoint = rng.uniform(-5, 5)
        if rng.random() < 0.02:
            g = rng.uniform(0, 3)
            theirs.Kp = ours.Kp = -g if direct else g
        if rng.random() < 0.02:
            auto = rng.random() < 0.5
            theirs.auto_mode = ours.auto_mode = auto
        if rng.random() < 0.01:
            last = rng.uniform(-3, 0)
            theirs.set_auto_mode(True, last)
            ours.set_auto_mode(True, last)
        dt = rng.choice([0.1, 0.05, 0.005, None])
        a, b = theirs(pv, dt), ours(pv, dt)
        if a is None:
            assert b is None, k
            continue
        assert b is not None
        assert b == pytest.approx(a, rel=1e-9, abs=1e-9), (k, kw)
        assert ours.components == pytest.approx(theirs.components, rel=1e-9, abs=1e-9), k
        pv += 0.1 * (max(-10.0, min(10.0, a)) - pv) + rng.uniform(-0.1, 0.1)


def test_attributes_set_between_calls_take_effect() -> None:
    """Kp, Ki, Kd, tunings, setpoint and output_limits set as attributes (simple-pid's way)."""
    ours, theirs = PID(1, 0.5, 0.1, sample_time=None), simple_pid.PID(1, 0.5, 0.1,
                                                                     sample_time=None)
    for pid in (ours, theirs):
        pid(1.0, dt=0.1)
        pid.tunings = (3.0, 0.2, 0.0)
        pid.setpoint = 4.0
        pid.output_limits = (-1.0, 2.5)
    for pv in (0.0, 1.0, 2.0, 5.0, 3.0):
        assert ours(pv, dt=0.1) == pytest.approx(theirs(pv, dt=0.1), rel=1e-12)
    assert ours.tunings == (3.0, 0.2, 0.0)
    assert ours.output_limits == (-1.0, 2.5)


def test_bad_input_holds_the_output_where_simple_pid_gives_nan() -> None:
    """A NaN input is Bad input: the output holds (simple-pid returns NaN), and control
    resumes bumplessly from the held output at the next good input."""
    ours, theirs = PID(2, 1, 0, setpoint=5, sample_time=None), simple_pid.PID(
        2, 1, 0, setpoint=5, sample_time=None)
    held = ours(4.0, dt=0.1)
    theirs(4.0, dt=0.1)
    assert math.isnan(theirs(math.nan, dt=0.1))
    assert ours(math.nan, dt=0.1) == held
    assert ours(math.inf, dt=0.1) == held
    nxt = ours(4.0, dt=0.1)
    assert math.isfinite(nxt)
    assert abs(nxt - held) < 1.0  # re-initialised from the held output: one I step, no jump


@pytest.mark.parametrize("pom", [False, True])
def test_after_a_bad_input_the_controller_follows_simple_pid_again(pom: bool) -> None:
    """One NaN input with proportional on measurement froze the output for ever: the NaN
    became the last input, so every later feedforward was NaN (found by an outside audit),
    and components after a held update no longer added up to the output. Now the held
    update keeps the last usable terms and input; the next good input re-initialises the
    integral from the held output (one update of simple-pid's law from there)."""
    t = [0.0]
    ours = PID(1.0, 0.5, 0.1, setpoint=1.0, proportional_on_measurement=pom,
               sample_time=None, time_fn=lambda: t[0])
    outs, terms = [], []
    for x in (0.0, 0.2, math.nan, 0.3, 0.4):
        t[0] += 1.0
        outs.append(ours(x))
        terms.append(ours.components)
    assert outs[2] == outs[1] and terms[2] == terms[1]  # held: the last usable update's
    assert sum(terms[2]) == pytest.approx(outs[2], abs=1e-12)
    # by hand: I = held out - P - D at re-initialisation, then + Ki·e·dt; P and D from the
    # last usable input 0.2 (P on measurement: P_prev - Kp·Δinput; D on measurement)
    p_prev = -0.2 if pom else 0.8
    p3 = p_prev - 0.1 if pom else 1.0 - 0.3
    d3 = -0.1 * (0.3 - 0.2) / 1.0
    i3 = (outs[1] - p3 - d3) + 0.5 * (1.0 - 0.3) * 1.0
    assert outs[3] == pytest.approx(p3 + i3 + d3, abs=1e-12)
    assert math.isfinite(outs[4]) and outs[4] != outs[3]


@pytest.mark.parametrize("bad", [math.nan, 2e12])
def test_a_bad_first_input_gives_no_output_and_the_next_is_the_first(bad: float) -> None:
    """A bad first input returned 0.0 (the kernel's initial output, neither the starting
    output nor simple-pid's "no output yet") and lost starting_output: now None, and the
    next good input is simple-pid's first update (P 1 + I 3 + 1·1·1 = 5)."""
    t = [0.0]
    ours = PID(1.0, 1.0, 0.0, setpoint=1.0, sample_time=None, time_fn=lambda: t[0],
               starting_output=3.0)
    t[0] += 1.0
    assert ours(bad) is None and ours.components == (0.0, 3.0, 0.0)
    t[0] += 1.0
    assert ours(0.0) == 5.0 and ours.components == (1.0, 4.0, 0.0)


def test_the_proportional_term_is_not_rounded_through_a_large_derivative() -> None:
    """Proportional on measurement with an error map and derivative on error: P was read
    back as (P + the derivative fix) - the derivative fix, and a D of 7e4 left 1.5e-11 of
    rounding in a P of 11.5 (the docstring promises 1e-15 of Kp·input; found by an outside
    audit). simple-pid itself is the reference."""
    got = []
    for cls in (simple_pid.PID, PID):
        t = [4.318298397179304]
        pid = cls(Kp=0.9921368608964709, Ki=0.0, Kd=3.0301958628096735,
                  setpoint=4.618266054820353, sample_time=1.0,
                  proportional_on_measurement=True, differential_on_measurement=False,
                  starting_output=1.0384385838096986, error_map=lambda e: e * abs(e),
                  time_fn=lambda t=t: t[0])
        pid(8.721986820020856)
        pid.sample_time = 0.0
        t[0] = 6.326890252551946
        pid(-2.9081396523824417, dt=0.001)
        got.append(pid.components)
    assert got[1][0] == pytest.approx(got[0][0], rel=1e-15, abs=0.0)
    assert got[1][2] == pytest.approx(got[0][2], rel=1e-15)


def test_mixed_sign_gains_are_refused_with_their_values() -> None:
    with pytest.raises(ParameterError, match=r"mixed signs \(Kp = 1, Ki = -0.5\)"):
        PID(1, -0.5, 0)
    pid = PID(1, 0.5, 0)
    pid.Ki = -0.5
    with pytest.raises(ParameterError, match="mixed signs"):
        pid(0.0, dt=0.1)


def test_negative_dt_is_refused_as_simple_pid_does() -> None:
    with pytest.raises(ValueError, match="dt has negative value -1"):
        PID()(0.0, dt=-1)


def test_loopworks_keywords_filter_and_antiwindup() -> None:
    """derivative_filter Tf: D_k = (Tf·D_{k-1} - Kd·Δinput)/(Tf + dt) (the generic pid's
    backward-Euler filter); antiwindup = clamping stops the integral where P + I meets the
    limit, where integral_limits lets I reach the limit itself."""
    pid = PID(0, 0, 1.0, sample_time=None, derivative_filter=0.1)
    pid(0.0, dt=0.1)
    assert pid(1.0, dt=0.1) == pytest.approx(-1.0 / 0.2)  # (0.1·0 - 1·1)/(0.1 + 0.1)
    assert pid(1.0, dt=0.1) == pytest.approx(0.1 * (-5.0) / 0.2)
    simple = PID(2, 1, 0, setpoint=10, output_limits=(0, 10), sample_time=None)
    clamped = PID(2, 1, 0, setpoint=10, output_limits=(0, 10), sample_time=None,
                  antiwindup="clamping")
    for pid in (simple, clamped):
        pid(0.0, dt=1.0)
        pid(0.0, dt=1.0)
    assert simple.components[1] == 10.0  # I at the limit (simple-pid)
    assert clamped.components[1] == 0.0  # P = 20 alone is beyond the limit: I does not move
    assert "antiwindup='clamping'" in repr(clamped)
    assert eval(repr(clamped), {"PID": PID}).antiwindup == "clamping"


def test_equal_limits_give_that_output() -> None:
    """simple-pid allows lower == upper (only upper < lower is refused)."""
    pid = PID(1, 1, 0, setpoint=3, output_limits=(2.0, 2.0), sample_time=None)
    assert pid(0.0, dt=0.1) == 2.0
    with pytest.raises(ValueError, match="lower limit must be less than upper limit"):
        pid.output_limits = (3.0, 1.0)


@pytest.mark.parametrize("change", ["flip", "d_on_error", "d_on_measurement"])
def test_a_derivative_changed_between_calls_matches_simple_pid(change: str) -> None:
    """Found by a random comparison (6 of 300 sessions): tunings that flip the sign, or
    differential_on_measurement toggled, kicked loopworks' D by Kd·(c·SP - PV)/dt (the kernel's
    derivative memory kept the old sign and weighting); simple-pid keeps its last input and
    last error and has no kick. Hand values: Kp 1, Ki 1, Kd 1, SP 5, dt 0.1, inputs 1, 2, 3:
    flipped to (-1, -1, -1), D = -Kd·Δe/dt with Δe = -1... = 10 in simple-pid's own form."""
    first = {"flip": True, "d_on_error": True, "d_on_measurement": False}[change]
    for cls in (simple_pid.PID, PID):
        c = cls(1, 1 if change == "flip" else 0, 1, setpoint=5, sample_time=None,
                differential_on_measurement=first)
        c(1.0, dt=0.1)
        c(2.0, dt=0.1)
        if change == "flip":
            c.tunings = (-1, -1, -1)
        else:
            c.differential_on_measurement = not first
        got = (c(3.0, dt=0.1), c.components)
        if cls is simple_pid.PID:
            want = got
    assert got[0] == pytest.approx(want[0], rel=1e-12)
    assert got[1] == pytest.approx(want[1], rel=1e-12)


class _Clock:
    """A clock that moves only when told (both controllers read the same times)."""

    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


@pytest.mark.parametrize("limits", [(0.0, math.inf), (-math.inf, 1.5), (math.nan, 2.0),
                                    (-math.inf, math.inf)])
def test_infinite_or_nan_output_limits_are_no_limit_as_in_simple_pid(
        limits: tuple[float, float]) -> None:
    """simple-pid takes output_limits = (0, inf) (a NaN limit never clamps either); the
    kernel needs finite limits and refused them, in the constructor and in the setter, and
    a refused setter left the limits stored so every later call failed (found by an outside
    audit). Outputs agree with simple-pid's call by call."""
    ca, cb = _Clock(), _Clock()
    a = simple_pid.PID(2.0, 1.0, 0.0, setpoint=1.0, sample_time=None, output_limits=limits,
                       time_fn=ca)
    b = PID(2.0, 1.0, 0.0, setpoint=1.0, sample_time=None, output_limits=limits, time_fn=cb)
    for k, x in enumerate([0.0, 0.2, 0.5, 2.5, 3.0, 0.9]):
        ca.t = cb.t = 0.1 * (k + 1)
        assert b(x) == pytest.approx(a(x), rel=1e-12, abs=1e-15), (k, limits)


def test_a_refused_limit_leaves_the_limits_as_they_were() -> None:
    """A limit the kernel cannot take (equal ones beyond the largest float) is refused and
    the controller keeps its limits and keeps working."""
    pid = PID(1.0, 0.5, 0.0, setpoint=1.0, sample_time=None, output_limits=(-1.0, 1.0))
    pid(0.0, dt=0.1)
    with pytest.raises(ParameterError, match=r"compat\.PID"):
        pid.output_limits = (math.inf, math.inf)
    assert pid.output_limits == (-1.0, 1.0)
    assert pid(0.0, dt=0.1) is not None


def test_an_integral_not_kept_within_the_limits_is_shown_as_it_is() -> None:
    """antiwindup = "none": the kernel's integral is not kept within the output limits;
    components showed it clipped to them (as the int limit itself), 1 for an integral of 30
    (found by an outside audit)."""
    pid = PID(1.0, 10.0, 0.0, setpoint=10.0, sample_time=None, output_limits=(-1, 1),
              antiwindup="none")
    for _ in range(3):
        pid(0.0, dt=0.1)
    _, i_term, _ = pid.components
    assert i_term == pytest.approx(30.0) and isinstance(i_term, float)  # 3 × Ki·e·dt = 3 × 10


def test_refusals_name_this_classs_keywords() -> None:
    """A value the kernel refuses is named by the keyword the user gave: 'tf', 'tt' were the
    kernel's names (found by an outside audit)."""
    with pytest.raises(ParameterError, match=r"compat.PID: parameter 'derivative_filter' = -1"):
        PID(1.0, derivative_filter=-1)
    with pytest.raises(ParameterError, match=r"'tracking_time' = 0"):
        PID(1.0, 0.5, antiwindup="back_calculation", tracking_time=0)


def test_a_clock_gone_back_with_a_sample_time_returns_the_last_output() -> None:
    """simple-pid with a sample_time (even 0) returns the last output when its clock steps
    back (dt < sample_time); this computed with dt = 1e-16 and gave a 1e14 derivative kick
    (found by an outside audit). Without a sample time the documented difference stays."""
    ca, cb = _Clock(), _Clock()
    a = simple_pid.PID(1.0, 0.5, 0.1, setpoint=1.0, sample_time=0, time_fn=ca)
    b = PID(1.0, 0.5, 0.1, setpoint=1.0, sample_time=0, time_fn=cb)
    for t, x in [(0.1, 0.0), (0.2, 0.3), (0.19, 0.2), (0.3, 0.25)]:
        ca.t = cb.t = t
        assert b(x) == pytest.approx(a(x), rel=1e-12), t


@pytest.mark.parametrize("jit", [None, False])
def test_copies_and_pickles_update_apart_from_the_original(jit: bool | None) -> None:
    """copy.deepcopy of a compiled PID kept the original's buffer addresses: the copy's calls
    returned the output from before the copy and moved the original instead; a shallow copy
    shared the state; pickling raised (found by an outside audit). Each is now a controller
    of its own, as simple-pid's are."""
    import copy
    import pickle

    def made(cls: Any, **extra: Any) -> Any:
        pid = cls(1.0, 0.5, 0.1, setpoint=1.0, sample_time=None, **extra)
        pid(0.0, 0.1)
        return pid

    theirs = made(simple_pid.PID)
    expected = [theirs(pv, 0.1) for pv in (0.5, 0.8)]
    for how in (copy.deepcopy, copy.copy, lambda p: pickle.loads(pickle.dumps(p))):
        ours = made(PID, jit=jit)
        twin = how(ours)
        assert [twin(pv, 0.1) for pv in (0.5, 0.8)] == pytest.approx(expected, rel=1e-12)
        assert [ours(pv, 0.1) for pv in (0.5, 0.8)] == pytest.approx(expected, rel=1e-12)
