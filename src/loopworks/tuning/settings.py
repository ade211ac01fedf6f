"""The common currency of the tuning layer: controller settings and process data.

``Ideal`` (defined in :mod:`loopworks.blocks.law`, below the vendors, and re-exported here) is
a controller in the ideal (ISA, non-interacting) form of plant-and-tuning 3.5, in continuous
time, with ``kc`` in % of output span per % of PV span, unless a function says it works in
loop (port) units. ``ProcessData`` carries what a relay test or a
model gives the tuning rules.
"""

from __future__ import annotations

from dataclasses import dataclass

from loopworks.blocks.law import Ideal

__all__ = ["Ideal", "ProcessData"]


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
