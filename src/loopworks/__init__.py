"""loopworks: industrial PID control loops.

Faithful vendor PID blocks, plant models, closed-loop simulation and historian replay, all built
on one block model (:mod:`loopworks.blocks`).

    >>> import loopworks
    >>> pid = loopworks.create_block("pid", k=2.0, ti=10.0)
    >>> pid.step(0.1, sp=50.0, pv=40.0)["out"].value
    20.2
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

__all__ = ["Module", "Signal", "__version__", "block_class", "create_block", "diagnose", "kinds",
           "sweep"]

if TYPE_CHECKING:
    from loopworks.blocks.block import Block
    from loopworks.blocks.status import Signal
    from loopworks.sim.module import Module


def create_block(kind: str, **params: Any) -> Block:
    """Make a block of ``kind`` with validated parameters (names in any letter case).

    The kinds (``loopworks blocks KIND`` describes each: parameters, inputs, outputs):

    * controllers: ``pid`` (generic), ``deltav.pid``, ``e2.pid``, ``s5.pid``, ``ge.pid_ind``,
      ``ge.pid_isa``
    * compensators and signals: ``deltav.stick_slip``, ``deltav.sggn``, ``deltav.calc``,
      ``compensator.constant_reinforcement``, ``compensator.knocker``,
      ``compensator.two_move``
    * tuning: ``relay``
    * processes: ``process.first_order``, ``process.fopdt``, ``process.sopdt``,
      ``process.ipdt``, ``process.tf``
    * valves: ``valve.choudhury``, ``valve.kano``, ``valve.he``, ``valve.karnopp``,
      ``valve.backlash``, ``valve.quantiser``, ``valve.resolution``
    * sensors and disturbances: ``sensor.transmitter``, ``disturbance.load``

    >>> create_block("process.fopdt", gain=2.0, time_constant=10.0, dead_time=1.0).kind
    'process.fopdt'
    """
    from loopworks.catalog import create_block as _create

    return _create(kind, **params)


def kinds() -> list[str]:
    """Every registered block kind."""
    from loopworks.catalog import kinds as _kinds

    return _kinds()


def block_class(kind: str) -> type[Block]:
    """The class of a block kind."""
    from loopworks.catalog import block_class as _bc

    return _bc(kind)


def __dir__() -> list[str]:
    """The module's names, with the lazily imported ``Module``, ``Signal``, ``sweep`` and
    ``diagnose``."""
    return sorted({*globals(), *__all__})


def __getattr__(name: str) -> Any:
    if name == "Signal":
        from loopworks.blocks.status import Signal

        return Signal
    if name == "Module":
        from loopworks.sim.module import Module

        return Module
    if name == "sweep":  # loopworks.sweep(scenario, vary={...}, samples=...): sim/sweep.py
        from loopworks.sim.sweep import sweep

        return sweep
    if name == "diagnose":  # loopworks.diagnose("loop.csv", "integrating"): analysis/diagnosis
        from loopworks.analysis.diagnosis import diagnose

        return diagnose
    raise AttributeError(f"module 'loopworks' has no attribute {name!r}")
