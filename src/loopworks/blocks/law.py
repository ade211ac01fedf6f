r"""The common discrete PID description every controller's ``law()`` gives and ``from_law()``
takes (issue 13): the currency of the conversions in :mod:`loopworks.tuning.convert`.

``Ideal`` is a controller in the ideal (ISA, non-interacting) form of plant-and-tuning 3.5, in
continuous time::

    u = s·Kc·[ e + (1/Ti)·∫e dt + Td·p/(1 + Tf·p)·e ]      s = +1 reverse, -1 direct

with ``kc`` in % of output span per % of PV span (normalised, as DeltaV's GAIN).
:class:`DiscreteLaw` adds how a block discretises it (which error the integral sums, which
derivative filter, the sample time it is fixed to, setpoint weights, DeltaV's series product)
and what makes a block's law differ from the linear one. The reference discretisation is the
generic ``pid``'s: P = Kc·e; ΔI_k = (Kc/Ti)·Δ·e_k (backward Euler, the current error);
D_k = (Tf·D_{k-1} + Kc·Td·Δe_k)/(Tf + Δ) (backward-Euler filtered derivative).

The helpers here (:func:`number`, :func:`word`, :func:`no_ideal`) are the parameter checks the
controllers' ``law()`` and ``from_law()`` share.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from loopworks.blocks.params import Param
from loopworks.errors import ParameterError

TOL = 1e-9  # relative: what "the same" means in float arithmetic

ParamValue = float | int | str | bool


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
class DiscreteLaw:
    """A block's discrete control law. ``ideal`` in %/%; ``b``, ``c`` the setpoint weights of
    P and D; ``dt`` the sample time the law is fixed to (None: the parameters are
    continuous-time, it runs at any Δ); ``integral`` "backward" (current error) or "forward"
    (previous error); ``derivative`` "backward" (backward-Euler filter Tf) or "exp" (GE's
    exponential lag on the raw difference); ``series`` (K', Ti', Td', d_factor, Tf) for
    DeltaV's series form; ``words``: integer words were rounded; ``flags``: sentences naming
    what makes the law differ from the linear one; ``notes``: assumptions."""

    ideal: Ideal
    b: float = 1.0
    c: float = 1.0
    dt: float | None = None
    integral: str = "backward"
    derivative: str = "backward"
    series: tuple[float, float, float, float, float] | None = None
    words: bool = False
    flags: tuple[str, ...] = ()
    notes: tuple[str, ...] = field(default=())


@dataclass(frozen=True)
class Realisation:
    """What ``from_law()`` gives: the target's parameters in its own names (for GE also the
    raw ``word6``..``word8``), the sample time ``dt`` the target runs the law at, the
    ``context`` its ``law()`` needs to read them back (spans, S5's sample time) and ``notes``
    (what the user must do, what may overflow). Whether it is exact is the comparison's job
    (:mod:`loopworks.tuning.convert`)."""

    params: dict[str, ParamValue]
    dt: float | None
    context: dict[str, Any] = field(default_factory=dict)
    notes: tuple[str, ...] = ()


def number(name: str, value: Any, lo: float = 0.0, *, lo_open: bool = True,
           allow_inf: bool = False, kind: str = "convert") -> float:
    """``value`` as a float, or a ParameterError naming ``name`` and the allowed range."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{kind}: parameter '{name}' = {value!r} must be a number") from None
    bad = math.isnan(x) or x < lo or (lo_open and x == lo) or (math.isinf(x) and not allow_inf)
    if bad:
        left = "(" if lo_open else "["
        right = "inf]" if allow_inf else "inf)"
        raise ParameterError(f"{kind}: parameter '{name}' = {value!r} is out of range: allowed "
                             f"{left}{lo:g}, {right}")
    return x


def flag(name: str, value: Any, kind: str = "convert") -> bool:
    """``value`` as true or false as a parameter takes it (a bool, 0 or 1, or the words
    true/false, yes/no, on/off, 1/0 in any case: a CLI's text), or a ParameterError naming
    ``name`` (``bool("false")`` would be True)."""
    return bool(Param(name, False, type="bool").check(value, kind))


def span(ctx: Mapping[str, Any], name: str, default: float, kind: str) -> float:
    """A span from the context (port units of 100 %), ``default`` when not given."""
    return number(name, ctx.get(name, default), kind=kind)


def word(name: str, value: float, kind: str, hi: float = 32767.0) -> int:
    """``abs(value)`` rounded half up to an integer word, at most ``hi``."""
    if not abs(value) + 0.5 < hi + 1.0:  # also inf and NaN: no word holds them
        w = math.floor(abs(value) + 0.5) if math.isfinite(value) else value
        raise ParameterError(f"{kind}: parameter '{name}' = {w:g} is out of range: allowed "
                             f"0..{hi:g} (integer word)")
    w = math.floor(abs(value) + 0.5)
    return int(w)


def no_ideal(kind: str, name: str, value: Any) -> ParameterError:
    """The error of a law without proportional action (it has no ideal form)."""
    return ParameterError(f"{kind}: parameter '{name}' = {value} has no ideal form (no "
                          "proportional action): allowed > 0")
