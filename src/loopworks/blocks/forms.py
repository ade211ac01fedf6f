"""PID forms and the conversions between them (plant-and-tuning 3.5).

Ideal / ISA / standard (non-interacting)::

    u = K·[ e + (1/Ti)·∫e dt + Td·de/dt ]

Parallel: ``kp = K``, ``ki = K/Ti``, ``kd = K·Td``.

Series / interacting / classical: ``C = K'·(1 + 1/(Ti'·s))·(1 + Td'·s)``.

* series → ideal: ``K = K'(1 + Td'/Ti')``, ``Ti = Ti' + Td'``, ``Td = Ti'·Td'/(Ti' + Td')``;
* ideal → series, only when ``Ti ≥ 4·Td``: with ``r = √(1 − 4Td/Ti)``,
  ``K' = (K/2)(1 + r)``, ``Ti' = (Ti/2)(1 + r)``, ``Td' = (Ti/2)(1 − r)``.

``Ti = inf`` means no integral action throughout; then the series and ideal forms coincide
(K' = K, Td' = Td). These are the only copies of these equations in loopworks.
"""

from __future__ import annotations

import math

from loopworks.errors import ParameterError


def series_to_ideal(k: float, ti: float, td: float) -> tuple[float, float, float]:
    """Series (K', Ti', Td') to ideal (K, Ti, Td), plant-and-tuning 3.5:

        K = K'(1 + Td'/Ti'),  Ti = Ti' + Td',  Td = Ti'·Td'/(Ti' + Td')

    Ti' = inf (no integral) gives K = K', Ti = inf, Td = Td'.
    """
    if ti == math.inf:
        return k, math.inf, td
    return k * (1.0 + td / ti), ti + td, ti * td / (ti + td)


def ideal_to_series(k: float, ti: float, td: float) -> tuple[float, float, float]:
    """Ideal (K, Ti, Td) to series (K', Ti', Td'), plant-and-tuning 3.5; needs Ti ≥ 4·Td:

        r = √(1 − 4Td/Ti),  K' = (K/2)(1 + r),  Ti' = (Ti/2)(1 + r),  Td' = (Ti/2)(1 − r)

    Ti = inf gives (K, inf, Td). Raises ParameterError naming ``td`` when Ti < 4·Td (complex
    zeros: no series controller has that response).
    """
    if ti == math.inf or td == 0.0:
        return k, ti, td
    if ti < 4.0 * td:
        raise ParameterError(
            f"td = {td:g} s is out of range for a series form: an ideal PID with Ti = {ti:g} s "
            f"has a series equivalent only for td <= Ti/4 = {ti / 4.0:g} s")
    r = math.sqrt(1.0 - 4.0 * td / ti)
    return 0.5 * k * (1.0 + r), 0.5 * ti * (1.0 + r), 0.5 * ti * (1.0 - r)


def ideal_to_parallel(k: float, ti: float, td: float) -> tuple[float, float, float]:
    """Ideal (K, Ti, Td) to parallel (kp, ki, kd) = (K, K/Ti, K·Td); Ti = inf gives ki = 0."""
    return k, (k / ti if ti != math.inf else 0.0), k * td


def parallel_to_ideal(kp: float, ki: float, kd: float) -> tuple[float, float, float]:
    """Parallel (kp, ki, kd) to ideal (K, Ti, Td) = (kp, kp/ki, kd/kp); ki = 0 gives Ti = inf.

    Needs kp > 0 (with kp = 0 there is no ideal form: Ti and Td would be 0 and inf)."""
    if not kp > 0.0:
        raise ParameterError(f"kp = {kp:g} is out of range for an ideal form: allowed (0, inf)")
    return kp, (kp / ki if ki > 0.0 else math.inf), kd / kp
