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

from abc import ABCMeta, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

from loopworks.blocks.law import DiscreteLaw, Realisation, span


@dataclass(frozen=True)
class Roles:
    """Which port of a controller plays which role (None: the controller has no such port).

    ``sp``, ``pv`` and ``out`` every controller has; ``ff`` feedforward, ``mode`` the mode
    input, ``man_out`` the operator's output in manual, ``track`` the tracking switch and
    ``track_value`` the value tracked; ``working_sp`` the output that gives the setpoint the
    controller works to after its own limits, ramp and filter (where it has one)."""

    sp: str
    pv: str
    out: str
    ff: str | None = None
    mode: str | None = None
    man_out: str | None = None
    track: str | None = None
    track_value: str | None = None
    working_sp: str | None = None

    def as_dict(self) -> dict[str, str | None]:
        """The roles by name (the JSON of ``loopworks blocks KIND --json``)."""
        return {"sp": self.sp, "pv": self.pv, "out": self.out, "ff": self.ff,
                "mode": self.mode, "man_out": self.man_out, "track": self.track,
                "track_value": self.track_value, "working_sp": self.working_sp}


@dataclass(frozen=True)
class Action:
    """Which parameter decides the action, and how: the controller is direct acting (error
    PV - SP, the output rises with the PV) when ``params[parameter] <op> value``, ``op`` being
    "=" or "<" (S5: direct when K < 0), and reverse acting (SP - PV) otherwise."""

    parameter: str
    op: str
    value: Any

    def direct_acting(self, params: Mapping[str, Any]) -> bool:
        """True when ``params`` make the controller direct acting."""
        given = params[self.parameter]
        return bool(given < self.value) if self.op == "<" else bool(given == self.value)

    def rule(self) -> str:
        """The rule in words, e.g. ``direct (e = PV - SP) when k < 0, else reverse``."""
        value = str(self.value).lower() if isinstance(self.value, bool) else str(self.value)
        return (f"direct (e = PV - SP) when {self.parameter} {self.op} {value}, else reverse "
                "(e = SP - PV)")


@dataclass(frozen=True)
class Handover:
    """How another source takes over the controller's output bumplessly and gives it back.

    ``inputs``: (controller input, what drives it) pairs, where what drives it is "active"
    (1 while the other source has the output, else 0), "inactive" (the opposite), "out" (the
    other source's output) or "override" (the other source's override flag); ``params``:
    parameters the controller needs for it (a tracking enable)."""

    inputs: tuple[tuple[str, str], ...]
    params: Mapping[str, Any] = field(default_factory=dict)


class Controller(metaclass=ABCMeta):
    """Mixin of every controller block class (with :class:`loopworks.blocks.block.Block`).

    Class attributes: ``ROLES``, ``AUTOMATIC`` and ``MANUAL`` (input values, by input name,
    that put the controller in automatic and in manual; values as a scenario file writes
    them: an enumerated input by its name, NaN for no value; to put a controller in manual,
    write ``MANUAL`` and then the operator's output to the ``man_out`` role; a controller
    whose ``man_out`` is itself the switch, E2's override, has an empty ``MANUAL``),
    ``ACTION``, ``HANDOVER``. Methods read the block's validated parameters (``params``, as
    ``Block.params`` holds them)."""

    kind: ClassVar[str]  # the block kind (Block's)
    ROLES: ClassVar[Roles]
    AUTOMATIC: ClassVar[Mapping[str, Any]]
    MANUAL: ClassVar[Mapping[str, Any]]
    ACTION: ClassVar[Action]
    HANDOVER: ClassVar[Handover]

    @classmethod
    def direct_acting(cls, params: Mapping[str, Any]) -> bool:
        """True when the error is PV - SP (the output rises with the PV): ``ACTION``'s rule."""
        return cls.ACTION.direct_acting(params)

    @classmethod
    def setpoint_input(cls, inputs: Mapping[str, float]) -> str:
        """The input the controller takes its setpoint from, given its current input values
        (by name): the ``sp`` role, unless a cascade mode switches it to another input."""
        return cls.ROLES.sp

    @classmethod
    def incremental(cls, params: Mapping[str, Any]) -> str | None:
        """None when the output is a position (the output value itself); else why it is an
        increment (a velocity algorithm whose actuator integrates), naming the parameter."""
        return None

    @classmethod
    @abstractmethod
    def output_range(cls, params: Mapping[str, Any]) -> tuple[float, float]:
        """The output's limits (low, high) in the output's own units."""

    @classmethod
    def pv_range(cls, params: Mapping[str, Any]) -> tuple[float, float] | None:
        """The PV's engineering range (low, high) in the PV's units where the block declares
        one (DeltaV's PV_SCALE), else None. A live PV read from a device outside it is
        Uncertain, EU range violation (runtime-and-ecosystem 2d: "Modbus has no quality
        bits ... a value outside the engineering range -> Uncertain")."""
        return None

    # -- the discrete law both ways (loopworks.blocks.law; compared in tuning/convert.py) ----
    #: context values the law takes besides the block parameters (spans, a sample time, raw
    #: words); a conversion accepts them among the parameters too
    LAW_CONTEXT: ClassVar[tuple[str, ...]] = ()
    #: the parameters ``law()`` reads; a conversion names the others as not converted
    LAW_PARAMS: ClassVar[tuple[str, ...]] = ()
    #: True when the law's gains are per sample (S5, E2): the parameters fix the sample time;
    #: False when they are continuous-time and the block runs the law at any Δ
    PER_SAMPLE: ClassVar[bool] = False

    #: (lo, hi) when the setpoint is a signed integer word (GE's SP operand and S5's W are
    #: 16-bit words in counts): an operator's SP must be a whole number in it; None: any
    #: real number (the block's own SP limits apply, ``loopworks.live.serve``)
    SP_WORD: ClassVar[tuple[int, int] | None] = None

    #: the context names of the PV and output spans and their defaults (port units of 100 %)
    SPANS: ClassVar[tuple[tuple[str, float], tuple[str, float]]] = (
        ("pv_span", 100.0), ("out_span", 100.0))

    def stored_params(self) -> dict[str, Any]:
        """The parameters as the vendor's storage holds them, where it quantises what was
        given (GE's 16-bit words); empty when every parameter runs as given."""
        return {}

    @classmethod
    def out_span(cls, params: Mapping[str, Any]) -> float:
        """The output's units of 100 % of its span (``SPANS``' default: 100 for an output in
        %, the vendor's counts of 100 %): what output travel is scored against."""
        return cls.SPANS[1][1]

    @classmethod
    def spans(cls, context: Mapping[str, Any]) -> tuple[float, float]:
        """(pv_span, out_span): the port units that make 100 % of PV and of output span, from
        the context values (or parameters) in ``context`` (lower-case names): ``SPANS``."""
        (pv, pv_default), (out, out_default) = cls.SPANS
        return (span(context, pv, pv_default, cls.kind),
                span(context, out, out_default, cls.kind))

    @classmethod
    @abstractmethod
    def law(cls, params: Mapping[str, Any], dt: float | None,
            context: Mapping[str, Any]) -> DiscreteLaw:
        """The block's discrete law for the given block ``params`` (lower-case names, as given:
        validated here), at sample time ``dt`` (None: not known) with ``context``
        (``LAW_CONTEXT`` values). A ParameterError when the law has no ideal form."""

    @classmethod
    @abstractmethod
    def from_law(cls, law: DiscreteLaw, dt: float | None,
                 context: Mapping[str, Any]) -> Realisation:
        """Parameters realising ``law`` (its ideal settings and setpoint weights) at sample time
        ``dt``, with the vendor's rounding and word limits; ``context``: the target's spans and
        choices (lower-case names)."""
