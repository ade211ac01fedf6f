"""The generic pid and the three vendor blocks side by side (spec vendor-blocks section 7).

Where the spec says they must agree (PI on the error, no limits, matching tunings, floating-point
arithmetic) one error sequence gives the same output from all four. Where it says they must
differ, each test shows the difference and that it is exactly the documented one:

* S5's feedforward Z is not multiplied by K (spec 2.5, 7);
* E2's P acts on the change of error, so saturation shifts its throttling range (spec 3.4, 7);
* GE's derivative is unfiltered: Kd·Δ/dt on one solution (spec 1.6, 7);
* GE's integer integral stalls for a tiny Ki·e·dt (spec 1.5, 1.8).

Tuning map for the agreement (K gain, Ti integral time in s, dt the scan, B the output at zero
error), each from its spec section:

    generic pid   k = K, ti = Ti, bias = B
    GE PID_IND    kp = K, ki = K/Ti (repeats/s), bias = B                      spec 1.6
    S5 OB 251     k = 1000·K, r = 1000, ti = 1000·dt/Ti (TI = TA/TN), y0 = B    spec 2.2, 2.5
    E2            throttling_range = 100 (so 100 %/TR = 1), kp = K,
                  ki = K·dt/Ti (per update), output_at_setpoint = B            spec 3.3
"""

from __future__ import annotations

import random

import pytest

import loopworks

K, TI, DT, B, SP = 0.8, 20.0, 1.0, 50.0, 1000.0


def error_sequence(n: int = 60, seed: int = 3) -> list[float]:
    rng = random.Random(seed)
    return [round(rng.uniform(-5.0, 5.0), 3) for _ in range(n)]


def run_all_four(errors: list[float]) -> dict[str, list[float]]:
    """Each block, one scan per error value, e = SP - PV (reverse action everywhere)."""
    generic = loopworks.create_block("pid", k=K, ti=TI, bias=B)
    ge = loopworks.create_block("ge.pid_ind", kp=K, ki=K / TI, bias=B, sample_period=DT,
                                upper_clamp=32000, lower_clamp=-32000, arithmetic="float")
    s5 = loopworks.create_block("s5.pid", k=1000 * K, r=1000, ti=1000 * DT / TI, y0=B,
                                bgog=32767, bgug=-32768, arithmetic="float", scale="nominal")
    e2 = loopworks.create_block("e2.pid", throttling_range=100.0, kp=K, ki=K * DT / TI, kd=0.0,
                                output_at_setpoint=B, min_accumulated_error=0.0,
                                update_interval=DT, error_sign="setpoint_minus_input")
    out: dict[str, list[float]] = {"pid": [], "ge": [], "s5": [], "e2": []}
    for e in errors:
        pv = SP - e
        out["pid"].append(generic.step(DT, sp=SP, pv=pv)["out"].value)
        out["ge"].append(ge.step(DT, sp=SP, pv=pv)["cv"].value)
        out["s5"].append(s5.step(DT, w=SP, x=pv)["y"].value)
        out["e2"].append(e2.step(DT, sp=SP, pv=pv)["out"].value)
    return out


def test_pi_on_error_agrees_across_vendors() -> None:
    """spec 7 (algorithm form rows): PI on the error with matching tunings is one controller:
    u_k = B + K·e_k + (K/Ti)·dt·Σ e_j, whether positional (pid, GE), a running sum of
    increments (S5 DW 48) or incremental with OUT += adjustments (E2)."""
    errors = error_sequence()
    expected, total = [], 0.0
    for e in errors:  # the textbook sum, by hand
        total += e
        expected.append(B + K * e + K / TI * DT * total)
    out = run_all_four(errors)
    for name, values in out.items():
        assert values == pytest.approx(expected, abs=1e-9), name


def test_s5_feedforward_is_not_multiplied_by_k() -> None:
    """spec 2.5, 2.13, 7: Z enters as a raw increment; in positioning mode a Z step of +50
    raises Y by exactly 50 whatever K is (with XW = 0)."""
    for k in (500, 1000, 4000):
        s5 = loopworks.create_block("s5.pid", k=k, r=1000, ti=100, arithmetic="float",
                                    scale="nominal")
        y0 = s5.step(1.0, w=0.0, x=0.0, z=0.0)["y"].value
        y1 = s5.step(1.0, w=0.0, x=0.0, z=50.0)["y"].value
        y2 = s5.step(1.0, w=0.0, x=0.0, z=50.0)["y"].value
        assert (y1 - y0, y2 - y1) == (50.0, 0.0), k


def test_s5_feedforward_differs_from_a_k_scaled_term() -> None:
    """The same Z step through the P path (as an error step of 50) scales with K: the S5's
    Z path does not. K = 4000 (gain 4 nominal) makes the error step give 200, the Z step 50."""
    s5 = loopworks.create_block("s5.pid", k=4000, r=1000, ti=0, arithmetic="float",
                                scale="nominal")
    s5.step(1.0, w=0.0, x=0.0)
    via_error = s5.step(1.0, w=50.0, x=0.0)["y"].value
    s5b = loopworks.create_block("s5.pid", k=4000, r=1000, ti=0, arithmetic="float",
                                 scale="nominal")
    s5b.step(1.0, w=0.0, x=0.0, z=0.0)
    via_z = s5b.step(1.0, w=0.0, x=0.0, z=50.0)["y"].value
    assert (via_error, via_z) == (200.0, 50.0)


def test_e2_p_on_change_of_error_shifts_the_window_at_saturation() -> None:
    """spec 3.4, 3.8 E7, 7: TR 10, Kp 1, SP 29, OAS 50, P only: inputs 34, 36, 35 give 100,
    100, 90 on the E2 (the increment past the clamp is lost), while a positional P controller
    with the same proportional band (gain 100 %/10 = 10, bias 50, direct action) gives 100,
    100, 100: 50 + 10·(35 - 29) = 110, clamped. The difference is exactly the 2-unit slide
    times 10 %/unit = 10 % on the third sample; inside the band, before saturating, they agree.
    """
    e2 = loopworks.create_block("e2.pid", throttling_range=10.0, kp=1.0, ki=0.0, kd=0.0,
                                output_at_setpoint=50.0, output_min=0.0, output_max=100.0,
                                min_accumulated_error=0.0, update_interval=1.0)
    positional = loopworks.create_block("pid", k=10.0, bias=50.0, action="direct")
    inputs = [27.0, 30.0, 34.0, 36.0, 35.0]
    e2_out = [e2.step(1.0, sp=29.0, pv=pv)["out"].value for pv in inputs]
    pid_out = [positional.step(1.0, sp=29.0, pv=pv)["out"].value for pv in inputs]
    assert e2_out[:2] == pytest.approx([30.0, 60.0]) == pid_out[:2]
    assert e2_out[2:] == pytest.approx([100.0, 100.0, 90.0])
    assert pid_out[2:] == pytest.approx([100.0, 100.0, 100.0])


def test_ge_derivative_is_unfiltered() -> None:
    """spec 1.6, 1.9 G10, 7: with derivative on PV, a PV rise of 20 in one 0.1 s solution
    gives D = -Kd·20/dt = -200 counts (Kd 1 s) on that solution and 0 on the next; the
    generic pid with its default filter (Tf = Td/10) spreads the same kick:
    D = -K·Td·20/(Tf + dt) = -133.33 then decays by Tf/(Tf + dt) = 1/3 each scan. With
    n = inf the generic pid reproduces GE's one-shot derivative exactly."""
    dt = 0.1
    ge = loopworks.create_block("ge.pid_ind", kp=0.0, ki=0.0, kd=1.0, derivative_on_pv=True,
                                sample_period=dt, upper_clamp=32000, lower_clamp=-32000)
    filtered = loopworks.create_block("pid", k=1.0, td=1.0, b=0.0, out_lo=-1e6, out_hi=1e6)
    unfiltered = loopworks.create_block("pid", k=1.0, td=1.0, b=0.0, n=float("inf"),
                                        out_lo=-1e6, out_hi=1e6)
    pvs = [1000.0, 1000.0, 1020.0, 1020.0, 1020.0]
    ge_cv = [ge.step(dt, sp=1000.0, pv=pv)["cv"].value for pv in pvs]
    f_d = [filtered.step(dt, sp=1000.0, pv=pv)["d_term"].value for pv in pvs]
    u_d = [unfiltered.step(dt, sp=1000.0, pv=pv)["d_term"].value for pv in pvs]
    assert ge_cv[2:] == [-200.0, 0.0, 0.0]
    assert u_d[2:] == pytest.approx([-200.0, 0.0, 0.0])
    tf = 1.0 / 10
    first = -20.0 / (tf + dt)
    assert f_d[2:] == pytest.approx([first, first * tf / (tf + dt),
                                     first * (tf / (tf + dt)) ** 2])


def test_ge_integer_integral_stalls_for_tiny_increments() -> None:
    """spec 1.5, 1.8: Ki word 1 (0.001 repeats/s), e = 1 count, dt = 0.1 s: each solution
    adds 1·1·1000/10^7 = 0.0001 count, below half of the 0.001-count remainder resolution, so
    in native arithmetic the integral never moves. The same block in float arithmetic, and the
    generic pid, integrate 1000 · 0.0001 = 0.1 count over 1000 solutions."""
    dt = 0.1
    native = loopworks.create_block("ge.pid_ind", kp=0.0, ki=0.001, sample_period=dt,
                                    upper_clamp=32000, lower_clamp=-32000)
    floating = loopworks.create_block("ge.pid_ind", kp=0.0, ki=0.001, sample_period=dt,
                                      upper_clamp=32000, lower_clamp=-32000,
                                      arithmetic="float")
    generic = loopworks.create_block("pid", form="parallel", kp=0.0, ki=0.001, out_lo=-1e6,
                                     out_hi=1e6)
    for _ in range(1000):
        native.step(dt, sp=101.0, pv=100.0)
        floating.step(dt, sp=101.0, pv=100.0)
        g = generic.step(dt, sp=101.0, pv=100.0)
    assert native.state()["integral"] == 0.0
    assert native.outputs()["cv"].value == 0.0
    assert floating.state()["integral"] == pytest.approx(0.1, abs=1e-9)
    assert g["i_term"].value == pytest.approx(0.1, abs=1e-9)


def test_s5_and_ge_start_at_their_output_for_a_steady_start() -> None:
    """issue 11 point 8: before their first scan the vendor blocks publish a real output, not
    0, so a block earlier in the module order reads no start-up kick. At a steady start (PV =
    SP) the first scan keeps it: the S5 positioning output is its DW 48 preset y0 = B (XW = 0,
    PW = 0: dY = 0, spec 2.7); the GE output is the Bias B (P = 0, empty integral, spec 1.6)."""
    s5 = loopworks.create_block("s5.pid", k=1000 * K, r=1000, ti=1000 * DT / TI, y0=B)
    ge = loopworks.create_block("ge.pid_ind", kp=K, ki=K / TI, bias=B, sample_period=DT)
    assert (s5.outputs()["y"].value, ge.outputs()["cv"].value) == (B, B)
    assert s5.step(DT, w=SP, x=SP)["y"].value == B
    assert ge.step(DT, sp=SP, pv=SP)["cv"].value == B
