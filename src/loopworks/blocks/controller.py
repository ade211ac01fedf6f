"""The controller interface: what a PID block declares about itself, beside its kernel.

Every controller kind (the generic ``pid`` and each vendor's PID) implements :class:`Controller`
in its own module, so the knowledge of that controller is written once, there: which of its
ports play which role, which input values put it in automatic and in manual, its action, its
output range, how it hands over bumplessly to another signal source (a relay test, an
operator), and its discrete control law both ways (``law()`` and ``from_law()``). Tools (the
conversions, the relay test, ``loopworks blocks KIND --json``, the live runtime) read this
declaration instead of keeping tables of vendor names.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar


@dataclass(frozen=True)
class Roles:
    """Which port of a controller plays which role (None: the controller has no such port).

    ``sp``, ``pv`` and ``out`` every controller has; ``ff`` feedforward, ``mode`` the mode
    input, ``man_out`` the operator's output in manual, ``track`` the tracking switch and
    ``track_value`` the value tracked."""

    sp: str
    pv: str
    out: str
    ff: str | None = None
    mode: str | None = None
    man_out: str | None = None
    track: str | None = None
    track_value: str | None = None

    def as_dict(self) -> dict[str, str | None]:
        """The roles by name (the JSON of ``loopworks blocks KIND --json``)."""
        return {"sp": self.sp, "pv": self.pv, "out": self.out, "ff": self.ff,
                "mode": self.mode, "man_out": self.man_out, "track": self.track,
                "track_value": self.track_value}


@dataclass(frozen=True)
class Handover:
    """How another source takes over the controller's output bumplessly and gives it back.

    ``inputs``: (controller input, what drives it) pairs, where what drives it is "active"
    (1 while the other source has the output, else 0), "inactive" (the opposite), "out" (the
    other source's output) or "override" (the other source's override flag); ``params``:
    parameters the controller needs for it (a tracking enable)."""

    inputs: tuple[tuple[str, str], ...]
    params: Mapping[str, Any] = field(default_factory=dict)


class Controller:
    """Mixin of every controller block class (with :class:`loopworks.blocks.block.Block`).

    Class attributes: ``ROLES``, ``AUTOMATIC`` and ``MANUAL`` (input values, by input name,
    that put the controller in automatic and in manual; values as a scenario file writes
    them), ``HANDOVER``. Methods read the block's validated parameters (``params``, as
    ``Block.params`` holds them)."""

    ROLES: ClassVar[Roles]
    AUTOMATIC: ClassVar[Mapping[str, Any]]
    MANUAL: ClassVar[Mapping[str, Any]]
    HANDOVER: ClassVar[Handover]

    @classmethod
    def direct_acting(cls, params: Mapping[str, Any]) -> bool:
        """True when the error is PV - SP (the output rises with the PV)."""
        raise NotImplementedError  # pragma: no cover - each controller says

    @classmethod
    def output_range(cls, params: Mapping[str, Any]) -> tuple[float, float]:
        """The output's limits (low, high) in the output's own units."""
        raise NotImplementedError  # pragma: no cover - each controller says
