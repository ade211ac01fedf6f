"""The seed's module (seed 000) as examples/deltav_stick_slip.toml, run through the module API:
PID OUT -> compensator SIGNAL_IN, SGGN1 -> DITHER_OUT, SIGNAL_OUT -> the plant (spec 6.1, 6.5).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from loopworks.sim.scenario import load_scenario

EXAMPLE = Path(__file__).resolve().parents[3] / "examples" / "deltav_stick_slip.toml"


@pytest.fixture(scope="module")
def run() -> dict[str, np.ndarray]:
    sc = load_scenario(EXAMPLE)
    assert sc.module.order == ["pid", "sggn1", "compensator", "process"]
    result = sc.module.run(sc.duration, sc.dt)
    return {name: result[name] for name in result.names} | {"t": result.t}


def test_signal_out_is_pid_out_plus_kick_plus_dither(run: dict[str, np.ndarray]) -> None:
    """spec 6.3 line 26: SIGNAL_OUT = SIGNAL_IN + KICKER_DELT + DITHER_DELT, with SIGNAL_IN the
    PID OUT of the same scan (the PID runs first), to float32 (spec 6.1 precision)."""
    np.testing.assert_array_equal(run["compensator.signal_in"], run["pid.out"])
    expected = (run["pid.out"].astype(np.float32).astype(float)
                + run["compensator.kicker_delt"] + run["compensator.dither_delt"])
    np.testing.assert_allclose(run["compensator.signal_out"], expected, atol=1e-4)
    np.testing.assert_array_equal(run["process.u"], run["compensator.signal_out"])


def test_sggn1_runs_first_with_last_scans_amplitude(run: dict[str, np.ndarray]) -> None:
    """spec 6.1, 6.5: SGGN1 (#3) runs before the CALC (#4), so its amplitude is the DITHER_AMP
    of the previous scan; DITHER_AMP = (0.5 + 0.5·0.2)·1·0.5 = 0.3 (spec 6.2: the header's
    0.6 % peak to peak); the square wave alternates every 1 s scan, starting with +."""
    amp = run["compensator.dither_amp"]
    assert amp == pytest.approx(0.3, abs=1e-6)
    np.testing.assert_array_equal(run["sggn1.amplitude"][1:], amp[:-1])
    out = run["sggn1.out"][1:]
    assert np.abs(out) == pytest.approx(0.3, abs=1e-6)
    assert (np.sign(out[1:]) == -np.sign(out[:-1])).all()
    np.testing.assert_array_equal(run["compensator.dither_out"], run["sggn1.out"])


def test_dither_inside_the_band_kick_outside(run: dict[str, np.ndarray]) -> None:
    """spec 6.3 lines 15-23: above SP + NB/2 or below SP - NB the dither is zero and the kick is
    -/+ KICKER_OUT·CNTRL_ACTION·VALVE_ACTION = ±0.3; inside, DITHER_DELT = -DITHER_OUT
    (CNTRL_ACTION -1, VALVE_ACTION +1) and the kick holds. NOISE_BAND = 0.3·2·1 = 0.6."""
    pv, sp = run["compensator.pv"], run["compensator.sp"]
    nb = run["compensator.noise_band"]
    assert nb == pytest.approx(0.6, abs=1e-6)
    high = pv > sp + 0.5 * nb + 1e-4
    low = pv < sp - nb - 1e-4
    band = ~high & ~low & (pv > sp - nb + 1e-4) & (pv < sp + 0.5 * nb - 1e-4)
    assert high.any() and band.any()  # approaches SP from above: kicks, then dithers
    assert (run["compensator.dither_delt"][high | low] == 0.0).all()
    assert run["compensator.kicker_delt"][high] == pytest.approx(-0.3, abs=1e-6)
    assert run["compensator.kicker_delt"][low] == pytest.approx(0.3, abs=1e-6)
    np.testing.assert_allclose(run["compensator.dither_delt"][band],
                               -run["compensator.dither_out"][band], atol=1e-6)


def test_the_loop_controls_to_setpoint(run: dict[str, np.ndarray]) -> None:
    """The PID starts in MAN at 40 % (PV near 80) and goes to AUTO at 60 s (spec 4.5, 4.7).
    In MAN the reset is back-initialised each scan: R = OUT - P with P = 0.5·(50 - PV%)
    (steps 5, 10). The first AUTO scan then moves by the change of P plus one reset step:
    R_k = R + (1/20)·(40 - R) (step 7, Euler, F = the last limited OUT), OUT = P_k + R_k,
    about 39.3 (no proportional bump). The PV then ends near SP 50."""
    t = run["t"]
    i = int(np.flatnonzero(t >= 60.0)[0])
    pv = run["pid.filtered_pv"]
    p_prev, p_now = 0.5 * (50.0 - pv[i - 1]), 0.5 * (50.0 - pv[i])
    r_prev = 40.0 - p_prev
    expected = p_now + r_prev + (1.0 / 20.0) * (40.0 - r_prev)
    assert run["pid.out"][:i] == pytest.approx(40.0, abs=1e-4)
    assert run["pid.out"][i] == pytest.approx(expected, abs=1e-4)
    assert abs(run["pid.out"][i] - 40.0) < 1.0
    assert abs(run["process.y"][-1] - 50.0) < 1.0
