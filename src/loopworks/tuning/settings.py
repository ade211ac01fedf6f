"""The common currency of the tuning layer: controller settings and process data.

``Ideal`` is a controller in the ideal (ISA, non-interacting) form of plant-and-tuning 3.5, in
continuous time::

    u = s·Kc·[ e + (1/Ti)·∫e dt + Td·p/(1 + Tf·p)·e ]      s = +1 reverse, -1 direct

with ``kc`` in % of output span per % of PV span (normalised, as DeltaV's GAIN), unless a
function says it works in loop (port) units. ``ProcessData`` carries what a relay test or a
model gives the tuning rules.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Ideal:
    """Ideal-form settings: gain ``kc``, integral time ``ti`` (s, inf = none), derivative time
    ``td`` (s, 0 = none), derivative filter time constant ``tf`` (s, 0 = none) and ``direct``
    action (e = PV - SP) instead of reverse (e = SP - PV)."""

    kc: float
    ti: float = math.inf
    td: float = 0.0
    tf: float = 0.0
    direct: bool = False


@dataclass(frozen=True)
class ProcessData:
    """What is known of the process (None = unknown). Gains in loop units (PV per OUT).

    ``ku``, ``pu``: ultimate gain and period (s); ``process_gain`` K, ``dead_time`` L (s),
    ``time_constant`` T (s) of a FOPDT model K·e^(-Ls)/(Ts + 1); ``integrating_gain`` Kv of
    Kv·e^(-Ls)/s; ``relay_gain`` Kφ = 4d/(πa), ``relay_period`` P (s) and ``relay_phase_lag``
    φ (rad) of the point a relay with hysteresis identifies (AMIGO-f, spec 3.6)."""

    ku: float | None = None
    pu: float | None = None
    process_gain: float | None = None
    dead_time: float | None = None
    time_constant: float | None = None
    integrating_gain: float | None = None
    relay_gain: float | None = None
    relay_period: float | None = None
    relay_phase_lag: float | None = None
