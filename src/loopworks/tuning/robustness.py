r"""Robustness of a tuning on a process model: the maximum sensitivity Ms (plant-and-tuning 3.6).

The loop transfer function of an ideal, unfiltered PID on a FOPDT or an integrating model::

    C(s) = Kc·(1 + 1/(Ti·s) + Td·s)          (Ti = inf: no integral action)
    G(s) = K·e^(-Ls)/(T·s + 1)   or   Kv·e^(-Ls)/s
    Ms   = max over ω of |1/(1 + C(jω)·G(jω))|

Ms is the inverse of the shortest distance from the Nyquist curve to -1 (Åström & Hägglund,
*Advanced PID Control*, 2006, §4.4): 1.2-2.0 are the usual design values (AMIGO aims at 1.4),
and Ms grows without bound as the loop approaches instability. The spec's worked example
(K = 1, T = 10, L = 2) gives 2.43 for Ziegler-Nichols PI and 1.26 for AMIGO PI.

Stability (Nyquist; the open loop has no poles in the right half plane and n = 0, 1 or 2 at
the origin, one for the integral action and one for an integrating process): along the
D-contour, indented to the right of the origin, the argument of 1 + C·G changes by
2·Δ(0+ → ∞) - n·π, which is 0 exactly when the closed loop is stable, Δ being the change along
the positive imaginary axis. With derivative action the loop gain tends to Kc·Td·K/T (Kc·Td·Kv
on an integrating model) at high frequency while the delay turns its phase without end: at 1 or
more the curve encircles -1 infinitely often (a neutral delay system), unstable. An unstable
closed loop has Ms = inf.
"""

from __future__ import annotations

import math

import numpy as np

#: Above this Ms a tuning gets a warning: 2.0 is the upper end of the usual design range
#: (Åström & Hägglund 2006, §4.4: "reasonable values of Ms are in the range 1.2 to 2.0").
MS_WARNING = 2.0


def loop_gain(omega: np.ndarray, kc: float, ti: float, td: float, *, gain: float,
              dead_time: float, time_constant: float | None) -> np.ndarray:
    """C(jω)·G(jω) (module docstring); ``time_constant`` None: the integrating model, with
    ``gain`` its Kv."""
    s = 1j * omega
    c = kc * (1.0 + (0.0 if math.isinf(ti) else 1.0 / (ti * s)) + td * s)
    g = gain * np.exp(-dead_time * s) / (s if time_constant is None else time_constant * s + 1.0)
    return np.asarray(c * g)


def derivative_gain(kc: float, td: float, *, gain: float,
                    time_constant: float | None) -> float:
    """|C·G| at high frequency of an unfiltered PID: Kc·Td·|K|/T (Kc·Td·|Kv| on an integrating
    model, ``time_constant`` None); 1 or more through a dead time is unstable."""
    return kc * td * abs(gain) / (time_constant if time_constant is not None else 1.0)


def max_sensitivity(kc: float, ti: float, td: float, *, gain: float, dead_time: float,
                    time_constant: float | None) -> float:
    """Ms of the ideal PID (kc, ti s, td s; ti = inf without integral action) on the FOPDT
    model K = ``gain``, L = ``dead_time``, T = ``time_constant``, or on Kv·e^(-Ls)/s with
    ``time_constant`` None; inf when the closed loop is unstable (module docstring). The loop
    gain is in loop units on both sides (kc·K is dimensionless); a negative process gain is
    taken with a direct-acting controller, as the rules give it."""
    k = abs(gain)
    if not (kc > 0.0 and k > 0.0 and dead_time > 0.0):
        raise ValueError("max_sensitivity needs kc > 0, a gain other than 0 and a dead time > 0")
    if td > 0.0 and derivative_gain(kc, td, gain=k, time_constant=time_constant) >= 1.0:
        return math.inf  # derivative kick through the delay: a neutral, unstable loop
    slow = max(dead_time, time_constant or 0.0, 0.0 if math.isinf(ti) else ti)
    # a log grid up to 1/L (the slow part), then a linear one fine enough to follow the
    # delay's phase (0.01 rad per step) until the loop gain has fallen far below 1
    low = np.geomspace(1e-6 / slow, 1.0 / dead_time, 4000)
    high = np.arange(1.0 / dead_time, 400.0 / dead_time, 0.01 / dead_time)
    omega = np.concatenate([low, high[1:]])
    ret = 1.0 + loop_gain(omega, kc, ti, td, gain=k, dead_time=dead_time,
                          time_constant=time_constant)
    integrators = (0 if math.isinf(ti) else 1) + (1 if time_constant is None else 0)
    turn = float(np.unwrap(np.angle(ret))[-1] - np.angle(ret[0]))
    # encirclements of -1: (2·Δ - n·π)/2π. At high frequency 1 + C·G circles 1 at radius c =
    # Kc·Td·K/T < 1 (or shrinks to 1), so the last angle is off its limit by asin(c) < π/2 at
    # most: rounding to whole turns is exact (a tolerance of π/4 called c > 0.71 unstable)
    if round((2.0 * turn - integrators * math.pi) / (2.0 * math.pi)) != 0:
        return math.inf
    return float(np.max(1.0 / np.abs(ret)))
