r"""Conversion of PID settings between every controller in loopworks (issue 6 point 4).

Kinds: ``pid`` (ideal, parallel, series), ``ge.pid_ind`` / ``ge.pid_isa`` (engineering values
or raw words 6-8), ``s5.pid`` (raw data-block words, given the OB 13 sample time),
``e2.pid`` (per-update gains, throttling range) and ``deltav.pid`` (standard or series).

Every conversion goes source -> normalised :class:`~loopworks.tuning.settings.Ideal` (%/%,
continuous time, derivative filter ``tf``, ``direct``) -> target. Parameter names are the
blocks' own (any letter case); context values (spans, sample time) may be given in the
parameters too. Parameters of the source that are not tuning parameters (limits, modes,
options) are **ignored**, and the note names them; options that change the linear control law
(a dead band, E2's Minimum Accumulated Error, a filter cell) make the conversion inexact and are
named too.

The discrete laws
-----------------

Each controller class says what its parameters mean as a discrete law, in its own module, beside
its kernel (:class:`~loopworks.blocks.controller.Controller`: ``law()`` parameters -> a
:class:`~loopworks.blocks.law.DiscreteLaw`, ``from_law()`` back, with the vendor's words and
rounding; the equations are in their docstrings). This module holds only what compares two
laws: whether they are the same, and by how much they differ.

The reference discretisation is the generic ``pid``'s (:mod:`loopworks.blocks.law`). With
pv_span, out_span the port units of 100 % of PV and of output (each controller's ``spans()``),
Kc (%/%) = k_port·pv_span/out_span.

Exactness rule
--------------

A conversion is **exact** when the target block realises the same control law as the source
block at the same sample time: the same discrete-time P, I, D and derivative filter (same
gains, same integrator and derivative discretisation, same Tf, same setpoint weights b, c), up
to float rounding (1e-9 relative), no integer word was rounded, and neither side has an option
that makes the law differ (dead band, MAE, filter cell). Blocks whose parameters are in
continuous time (pid, GE, DeltaV) realise it at whatever sample time both run; per-sample
blocks (S5, E2) fix Δ, and the other side must run at that Δ. Vendor integer arithmetic (GE
and S5 native counts) rounds signals, not parameters: it is not counted.

Where it is not exact, ``note`` says why and gives bounds: the relative frequency-response
error of the whole controller |C_t(jω) - C_s(jω)|/|C_s(jω)|, computed numerically from the two
discrete responses (z = e^(jωΔ); continuous when no Δ is known) at ω = 1/Ti and ω = 1/Td, and
for the typical causes the term bound:

* derivative filter Tf_s onto Tf_t (e.g. DeltaV's α·RATE onto a block without a filter): the
  D term's relative error |1/(1 + jωTf_t) - 1/(1 + jωTf_s)| (for Tf_t = 0:
  αTdω/√(1 + (αTdω)²) ≤ αTdω), stated at ω = 1/Td;
* a rectangular integral at another Δ, or DeltaV's one-sample-late reset: the rectangular sum
  differs from 1/s by (ωΔ/2)/sin(ωΔ/2) in magnitude and ωΔ/2 in phase, and the late reset by
  z⁻¹ (relative error 2·sin(ωΔ/2) ≤ ωΔ), stated at ω = 1/Ti;
* rounding to integer words: the largest relative parameter change.
"""

from __future__ import annotations

import cmath
import contextlib
import functools
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import Any, TypeVar

from loopworks.blocks.controller import Controller
from loopworks.blocks.forms import ideal_to_parallel
from loopworks.blocks.law import TOL, DiscreteLaw, Ideal, ParamValue, number
from loopworks.catalog import block_class, controller_kinds, create_block
from loopworks.errors import LoopworksError, ParameterError

KINDS: tuple[str, ...] = tuple(controller_kinds())  # the controller kinds, sorted


@dataclass(frozen=True)
class Conversion:
    """The target's parameters (its own names), whether the target reproduces the source
    exactly (module docstring), a note (assumptions, what is inexact and the bound) and the
    intermediate normalised ideal settings."""

    params: dict[str, ParamValue]
    exact: bool
    note: str
    ideal: Ideal
    #: where not exact, the stated controller frequency-response errors as data:
    #: (ω rad/s, |C_t(jω) - C_s(jω)|/|C_s(jω)|) at ω = 1/Ti and 1/Td (the note's figures)
    response_errors: tuple[tuple[float, float], ...] = ()
    #: the options of either side outside the two linear laws (a dead band, E2's Minimum
    #: Accumulated Error, a filter cell): their effect is not in ``response_errors``, which
    #: compare the linear laws only (a dead band of ±50 counts, stated 0, moved the output
    #: 11 times as far at ω = 1/Ti; found by an outside audit)
    unmodelled: tuple[str, ...] = ()


# ----------------------------------------------------------------------------------------------
# Parameter handling
# ----------------------------------------------------------------------------------------------
def _controller(kind: str) -> type[Controller]:
    """The controller class of ``kind`` (any letter case), or a ParameterError listing them."""
    k = str(kind).strip().lower()
    kinds = controller_kinds()
    if k not in kinds:
        raise ParameterError(f"convert: kind '{kind}' is not allowed: expected one of "
                             + ", ".join(kinds))
    cls = block_class(k)
    assert issubclass(cls, Controller)
    return cls


def _split(cls: type[Controller], params: Mapping[str, Any] | None
           ) -> tuple[dict[str, Any], dict[str, Any]]:
    """Lower-case ``params`` and split them into block parameters and context values; an
    unknown name is a ParameterError listing the valid ones."""
    kind = cls.kind
    names = {p.name for p in block_class(kind).PARAMS}
    extra = set(cls.LAW_CONTEXT)
    block: dict[str, Any] = {}
    ctx: dict[str, Any] = {}
    for raw, value in (params or {}).items():
        name = str(raw).strip().lower()
        if name in names:
            block[name] = value
        elif name in extra:
            ctx[name] = value
        else:
            raise ParameterError(f"{kind}: unknown parameter '{raw}'; valid names: "
                                 + ", ".join(sorted(names | extra)))
    return block, ctx


def port_spans(kind: str, params_or_context: Mapping[str, Any]) -> tuple[float, float]:
    """(pv_span, out_span): the port units that make 100 % of PV span and of output span, as
    the controller class of ``kind`` reads them from parameters or context values (its
    ``spans()``)."""
    return _controller(kind).spans({str(k).lower(): v for k, v in params_or_context.items()})


def _ignored(cls: type[Controller], block: Mapping[str, Any]) -> tuple[str, ...]:
    unused = sorted(n for n in block if n not in cls.LAW_PARAMS)
    if not unused:
        return ()
    return (f"Not converted (not tuning parameters): {', '.join(unused)}.",)


def _law_of(kind: str, params: Mapping[str, Any] | None, dt: float | None,
            context: Mapping[str, Any] | None) -> DiscreteLaw:
    cls = _controller(kind)
    block, ctx = _split(cls, params)
    ctx.update({str(k).lower(): v for k, v in (context or {}).items()})
    law = cls.law(block, dt, ctx)
    return replace(law, notes=law.notes + _ignored(cls, block))


# ----------------------------------------------------------------------------------------------
# Comparison of two laws: exactness and bounds
# ----------------------------------------------------------------------------------------------
def _response(law: DiscreteLaw, w: float, dt: float | None) -> complex:
    """C(jω) of the law (error -> output, %/%), discrete at ``dt`` (continuous when None)."""
    def integ(ki: float, kind: str) -> complex:
        if dt is None:
            return ki / complex(0.0, w)
        zi = cmath.exp(complex(0.0, -w * dt))
        return ki * dt * (zi if kind == "forward" else 1.0) / (1.0 - zi)

    def deriv(kd: float, tf: float, kind: str) -> complex:
        if dt is None:
            return kd * complex(0.0, w) / (1.0 + complex(0.0, w * tf))
        zi = cmath.exp(complex(0.0, -w * dt))
        if kind == "exp" and tf > 0.0:
            a = 1.0 - math.exp(-dt / tf)
            return kd * (1.0 - zi) / dt * a / (1.0 - (1.0 - a) * zi)
        return kd * (1.0 - zi) / (tf + dt - tf * zi)

    if law.series is not None:
        k, ti, td, d_factor, tf = law.series
        i_part = integ(1.0 / ti, law.integral) if ti < math.inf else 0.0
        d_part = deriv(d_factor * td, tf, law.derivative) if td > 0.0 else 0.0
        return k * (1.0 + d_part) * (1.0 + i_part)
    ideal = law.ideal
    kp, ki, kd = ideal_to_parallel(ideal.kc, ideal.ti, ideal.td)
    out = complex(kp)
    if ki > 0.0:
        out += integ(ki, law.integral)
    if kd > 0.0:
        out += deriv(kd, ideal.tf, law.derivative)
    return out


def _rel(a: float, b: float) -> float:
    if a == b:
        return 0.0
    if math.isinf(a) or math.isinf(b):
        return math.inf
    return abs(a - b) / max(abs(a), abs(b))


def _compare(src: DiscreteLaw, tgt: DiscreteLaw) -> tuple[bool, list[str]]:
    """Whether ``tgt`` realises ``src`` exactly, and sentences saying why not, with bounds."""
    s, t = src.ideal, tgt.ideal
    why: list[str] = []
    has_i = s.ti < math.inf or t.ti < math.inf
    has_d = s.td > 0.0 or t.td > 0.0
    if s.direct != t.direct:
        why.append("The action (direct/reverse) differs.")
    errs = {"Kc": _rel(s.kc, t.kc), "Ti": _rel(s.ti, t.ti), "Td": _rel(s.td, t.td)}
    if has_d:
        errs["Tf"] = _rel(s.tf, t.tf) if max(s.tf, t.tf) > 0.0 else 0.0
    moved = {k: v for k, v in errs.items() if v > TOL and k != "Tf"}
    if moved:
        name = max(moved, key=lambda k: moved[k])
        cause = "rounding to integer words" if (src.words or tgt.words) \
            else "the target's parameter ranges"
        before, after = {"Kc": (s.kc, t.kc), "Ti": (s.ti, t.ti), "Td": (s.td, t.td)}[name]
        # relative to the source's value (the symmetric |a - b|/max said 0.199 for Ti
        # 41.0 s -> 51.2 s, +24.9 %; found by an engineer)
        change = ((after - before) / abs(before) if before != 0.0 and math.isfinite(before)
                  and math.isfinite(after) else math.inf)
        unit = "" if name == "Kc" else " s"
        why.append(f"Largest relative parameter change from {cause}: {name} {before:.4g} → "
                   f"{after:.4g}{unit} ({change:+.3g}, {100.0 * change:+.3g} %).")
    if has_d and errs.get("Tf", 0.0) > TOL and s.td > 0.0 and math.isfinite(1.0 / s.td):
        w = 1.0 / s.td
        e = abs(1.0 / complex(1.0, w * t.tf) - 1.0 / complex(1.0, w * s.tf))
        why.append(f"Derivative filter Tf = {s.tf:g} s in the source, {t.tf:g} s in the "
                   "target: the D term's relative frequency-response error "
                   f"|1/(1+jωTf_t) - 1/(1+jωTf_s)| is {e:.3g} at ω = 1/Td = {w:.4g} rad/s "
                   f"(≤ ω·|ΔTf| = {w * abs(s.tf - t.tf):.3g}).")
    dt = src.dt if src.dt is not None else tgt.dt
    if src.dt is not None and tgt.dt is not None and _rel(src.dt, tgt.dt) > TOL:
        if has_i or has_d:
            why.append(f"The source runs at Δ = {src.dt:g} s, the target at {tgt.dt:g} s: "
                       "each rectangular integral differs from 1/s by (ωΔ/2)/sin(ωΔ/2) in "
                       f"magnitude and ωΔ/2 in phase ({_rect(s.ti, src.dt)} vs "
                       f"{_rect(s.ti, tgt.dt)} at ω = 1/Ti), and the backward differences "
                       "likewise.")
        else:  # P only: the same gain, but its output held over other intervals
            why.append(f"The source updates its output every {src.dt:g} s, the target every "
                       f"{tgt.dt:g} s: the same proportional gain, its output held over "
                       "different intervals (a P-only E2 kept its 2 s default where the source "
                       "ran at the sample time given, and was called exact).")
    if has_i and src.integral != tgt.integral:
        bound = f"≤ Δ/Ti = {dt / s.ti:.3g}" if dt is not None and s.ti < math.inf \
            else "≤ Δ/Ti (give sample_time for a number)"
        fwd = "source" if src.integral == "forward" else "target"
        why.append(f"The {fwd}'s integral sums the previous scan's error (forward Euler), the "
                   "other's the current one (backward Euler): the I term differs by z⁻¹, "
                   f"relative error 2·sin(ωΔ/2) ≤ ωΔ; at ω = 1/Ti {bound}.")
    if has_d and src.derivative != tgt.derivative:
        lag = "source" if src.derivative == "exp" else "target"
        why.append(f"The {lag}'s derivative filter is an exponential lag on the raw difference, "
                   "the other's a backward-Euler filter: they differ by O(Δ/Tf)"
                   + ("" if dt is not None else " (give sample_time for a number)") + ".")
    if (src.series is None) != (tgt.series is None) and has_d:
        why.append("A series form K'(1 + 1/(Ti's))(1 + Td's)/(αTd's + 1) keeps its filter "
                   "inside the product: no ideal form with one filter equals it.")
    elif src.series is not None and tgt.series is not None and any(
            _rel(a, b) > TOL for a, b in zip(src.series, tgt.series, strict=True)):
        why.append("The series settings differ (the derivative filter or its gain).")
    if _rel(src.b, tgt.b) > TOL or (has_d and _rel(src.c, tgt.c) > TOL):
        why.append(f"The setpoint path differs (P on b·SP - PV, D on c·SP - PV): source "
                   f"b = {src.b:g}, c = {src.c:g}; target b = {tgt.b:g}, c = {tgt.c:g}. The "
                   "response to PV is not affected by this.")
    why.extend(src.flags)
    why.extend(tgt.flags)
    if not why:
        return True, []
    errors = _response_errors(src, tgt, dt)
    text = [f"{e:.3g} at ω = {label} = {w:.4g} rad/s" if w is not None
            else f"{e:.3g} (P only, any ω)" for label, w, e in errors]
    where = f"discrete, Δ = {dt:g} s" if dt is not None else "continuous, no Δ given"
    unmodelled = (" It compares the two linear laws only: the options named above (a dead "
                  "band, a feedback path the linear law does not hold) are not in it, and "
                  "their effect is not bounded here." if src.flags or tgt.flags else "")
    why.append("Controller frequency-response error |C_t - C_s|/|C_s| "
               f"({where}): " + ("; ".join(text) if text else "not stated: neither "
                                 "ω = 1/Ti nor ω = 1/Td lies below the Nyquist frequency π/Δ, "
                                 "or the responses are not computable in double precision at "
                                 "these settings") + "." + unmodelled)
    return False, why


def _response_errors(src: DiscreteLaw, tgt: DiscreteLaw, dt: float | None
                     ) -> list[tuple[str, float | None, float]]:
    """(label, ω, |C_t(jω) - C_s(jω)|/|C_s(jω)|) at ω = 1/Ti and 1/Td of the source (each law
    discrete at its own Δ, else at ``dt``); with neither, the P-only error (ω None)."""
    s = src.ideal
    found: list[tuple[str, float | None, float]] = []
    steps = [x for x in (src.dt, tgt.dt, dt) if x is not None]
    nyquist = math.pi / max(steps) if steps else math.inf
    for label, w in (("1/Ti", 1.0 / s.ti if s.ti < math.inf else 0.0),
                     ("1/Td", 1.0 / s.td if s.td > 0.0 else 0.0)):
        # (a subnormal Td: 1/Td overflows, no frequency to state; above the Nyquist
        # frequency π/Δ a discrete response is an alias of a lower one: none either)
        if 0.0 < w < math.inf and w < nyquist:
            cs = _response(src, w, src.dt if src.dt is not None else dt)
            ct = _response(tgt, w, tgt.dt if tgt.dt is not None else dt)
            found.append((label, w, abs(ct - cs) / abs(cs)))
    if not found and s.ti == math.inf and s.td == 0.0:  # P only: the same at every ω
        cs, ct = _response(src, 1.0, None), _response(tgt, 1.0, None)
        found.append(("", None, abs(ct - cs) / abs(cs)))
    # a response of subnormal times (Δ, Ti of 1e-320 s) can be 0/0: no figure, not a NaN
    return [(label, w, e) for label, w, e in found if math.isfinite(e)]


def _rect(ti: float, dt: float) -> str:
    if ti == math.inf:
        return "no I"
    h = dt / ti / 2.0
    return f"{h / math.sin(h):.6g}∠{math.degrees(h):.3g}°"


# ----------------------------------------------------------------------------------------------
# Public API
# ----------------------------------------------------------------------------------------------
def _canonical(ideal: Ideal, dt: float | None, ctx: Mapping[str, Any]) -> DiscreteLaw:
    return DiscreteLaw(ideal, b=float(ctx.get("b", 1.0)), c=float(ctx.get("c", 1.0)), dt=dt)


def _note(parts: list[str] | tuple[str, ...], exact: bool) -> str:
    head = "Exact: the target realises the same discrete control law." if exact \
        else "Not exact."
    return " ".join([head, *parts])


F = TypeVar("F", bound=Callable[..., Any])


def _computable(fn: F) -> F:
    """A conversion whose arithmetic leaves double precision (a Td of 1e308 s in integer
    words, a sample time of 1e-320 s divided into a gain, a phase of 1e308 rad) is refused as
    a ParameterError that shows the values given, not an OverflowError, ZeroDivisionError or
    "math domain error" from deep inside it."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return fn(*args, **kwargs)
        except LoopworksError:
            raise
        except (ArithmeticError, ValueError) as exc:
            given = ", ".join([*(repr(a) for a in args),
                               *(f"{k} = {v!r}" for k, v in kwargs.items() if v is not None)])
            raise ParameterError(f"{fn.__name__}: these settings are beyond what the "
                                 f"conversion can compute in double precision ({exc}): "
                                 f"{given}") from None

    return wrapper  # type: ignore[return-value]


@_computable
def to_ideal(kind: str, params: Mapping[str, Any], *, sample_time: float | None = None,
             context: Mapping[str, Any] | None = None) -> tuple[Ideal, bool, str]:
    """The normalised ideal settings of a ``kind`` block with ``params``; ``exact`` is True
    when the generic pid with these settings (and b = c = 1) at the block's sample time is the
    block's own law. ``context``: spans (port_spans), the S5's sample time."""
    dt = None if sample_time is None else number("sample_time", sample_time)
    law = _law_of(kind, params, dt, context)
    exact, why = _compare(law, _canonical(law.ideal, law.dt, {}))
    return law.ideal, exact, _note(list(law.notes) + why, exact)


def setpoint_weights(kind: str, params: Mapping[str, Any],
                     sample_time: float | None = None) -> dict[str, float]:
    """The setpoint weights ``b``, ``c`` of the law a ``kind`` block with ``params`` runs (the
    pid's b and c, DeltaV's STRUCTURE, GE's derivative on PV, ...), as a target context
    takes them: a retuning keeps the structure the user chose."""
    dt = None if sample_time is None else number("sample_time", sample_time)
    law = _law_of(kind, params, dt, None)
    return {"b": law.b, "c": law.c}


class _Read(dict[str, Any]):
    """A context that remembers every name looked up in it (``get``, ``in``, ``[]``), given
    or not: what a controller's ``from_law`` reads is the list of its target settings."""

    def __init__(self, values: Mapping[str, Any]) -> None:
        super().__init__(values)
        self.read: set[str] = set()

    def get(self, key: str, default: Any = None) -> Any:
        self.read.add(key)
        return super().get(key, default)

    def __contains__(self, key: object) -> bool:
        self.read.add(str(key))
        return super().__contains__(key)

    def __getitem__(self, key: str) -> Any:
        self.read.add(key)
        return super().__getitem__(key)


#: what ``response_errors`` leave out when no sample time is known (``Conversion.unmodelled``)
CONTINUOUS = ("the discretisation: no sample time was given, so the responses are compared in "
              "continuous time, where an integral one sample late or a forward against a "
              "backward Euler sum does not show (give sample_time)")


def _from_law(kind: str, law: DiscreteLaw, dt: float | None, ctx: dict[str, Any], *,
              strict: bool = False) -> Conversion:
    """The ``kind`` block realising ``law``; ``strict``: every name of ``ctx`` must be a target
    setting the block's ``from_law`` reads (the user's ``-t``), else a ParameterError that
    lists them (a context made from a block's own parameters carries others)."""
    cls = _controller(kind)
    kind = cls.kind
    read = _Read(ctx)
    made = cls.from_law(law, dt if dt is not None else law.dt, read)
    unused = sorted(set(ctx) - read.read)
    if strict and unused:
        raise ParameterError(
            f"{kind}: target setting '{unused[0]}' = {ctx[unused[0]]!r} is not one it takes: "
            "allowed " + (", ".join(sorted(read.read)) or "none")
            + " (the other parameters are what the conversion computes)")
    block_params = {k: v for k, v in made.params.items() if k not in cls.LAW_CONTEXT}
    create_block(kind, jit=False, **block_params)  # the target block accepts them (ranges, words)
    spans = {k: v for k, v in ctx.items() if k in cls.LAW_CONTEXT and "span" in k}
    tgt = replace(cls.law(block_params, made.dt, {**spans, **made.context}), notes=())
    exact, why = _compare(law, tgt)
    notes = [*law.notes, *made.notes]
    if not cls.PER_SAMPLE and law.dt is not None:
        if tgt.dt is not None and _rel(law.dt, tgt.dt) > TOL:
            notes.append(f"The source's law is fixed to Δ = {law.dt:g} s (run the target at "
                         f"that Δ); at the {tgt.dt:g} s asked for, the target's terms differ "
                         "as the next sentence says.")
        else:
            notes.append(f"Run the target at Δ = {law.dt:g} s.")
    errors = () if exact else tuple(
        (w, e) for _, w, e in _response_errors(law, tgt, law.dt if law.dt is not None
                                                else tgt.dt) if w is not None)
    unmodelled = (*law.flags, *tgt.flags)
    if errors and law.dt is None and tgt.dt is None:
        unmodelled += (CONTINUOUS,)
    return Conversion(params=made.params, exact=exact, note=_note(notes + why, exact),
                      ideal=law.ideal, response_errors=errors, unmodelled=unmodelled)


@_computable
def from_ideal(kind: str, ideal: Ideal, *, sample_time: float | None = None,
               context: Mapping[str, Any] | None = None) -> Conversion:
    """Parameters of a ``kind`` block realising ``ideal`` (normalised %/%, the generic pid's
    discretisation at ``sample_time``). ``context``: the target's spans and choices (pid
    ``form``; GE ``arithmetic``; S5 ``scale``, ``r``, ``dd_decay``; E2 ``throttling_range``,
    ``i_tr_normalise``, ``d_tr_normalise``; DeltaV ``form``, ``alpha``, scales) and the
    setpoint weights ``b``, ``c`` of the law to realise (default 1, 1: the ideal form)."""
    ctx = {str(k).lower(): v for k, v in (context or {}).items()}
    dt = None if sample_time is None else number("sample_time", sample_time)
    return _from_law(kind, _canonical(ideal, dt, ctx), dt, ctx)


@_computable
def convert(from_kind: str, params: Mapping[str, Any], to_kind: str, *,
            sample_time: float | None = None,
            target: Mapping[str, Any] | None = None) -> Conversion:
    """Convert ``params`` of a ``from_kind`` block into parameters of a ``to_kind`` block.

    ``sample_time`` (s) is the loop's sample time: the S5's OB 13 interval TA, the E2's update
    interval and GE's sample period when they are not given, and the scan of pid / DeltaV.
    ``target`` is the target's context (see :func:`from_ideal`)."""
    _controller(to_kind)  # an unknown target is named before the source is read
    dt = None if sample_time is None else number("sample_time", sample_time)
    law = _law_of(from_kind, params, dt, None)
    ctx = {str(k).lower(): v for k, v in (target or {}).items()}
    cls = _controller(to_kind)
    if _controller(from_kind) is cls:  # to itself: with the source's own settings when exact
        try:
            kept = _from_law(to_kind, law, dt, {**_own_settings(cls, law, dt, params), **ctx},
                             strict=True)
        except LoopworksError:
            kept = None
        if kept is not None and kept.exact:
            return kept
    try:
        return _from_law(to_kind, law, dt, ctx, strict=True)
    except ParameterError as exc:  # the target's word or value, named with what was given
        given = ", ".join(f"{k} = {v!r}" for k, v in params.items())
        ideal = law.ideal
        raise ParameterError(
            f"{exc} (converting {_controller(from_kind).kind} with {given}: Kc = "
            f"{ideal.kc:.6g} %/%, Ti = {ideal.ti:.6g} s, Td = {ideal.td:.6g} s; these do not "
            f"fit the target)") from None


def _own_settings(cls: type[Controller], law: DiscreteLaw, dt: float | None,
                  params: Mapping[str, Any]) -> dict[str, Any]:
    """The target settings (the names ``cls.from_law`` reads) that ``params`` of a block of
    the same kind give, or its defaults: an S5's R and scale, a pid's form. A conversion of a
    kind to itself keeps them when that makes it exact (docs/conversion.md: every kind is
    exact with itself), and else takes the target's defaults (a default that is no setting,
    GE's sample period 0 = "the loop's", is not one to keep)."""
    probe = _Read({})
    with contextlib.suppress(LoopworksError):  # what is missing is named in the real run
        cls.from_law(law, dt if dt is not None else law.dt, probe)
    given = {p.name: p.default for p in block_class(cls.kind).PARAMS if p.default is not None}
    given.update({str(k).strip().lower(): v for k, v in params.items()})
    return {name: given[name] for name in probe.read if name in given}


@_computable
def from_loop_units(kind: str, kc: float, ti: float, td: float, *, direct: bool = False,
                    sample_time: float | None = None,
                    context: Mapping[str, Any] | None = None) -> Conversion:
    """Like :func:`from_ideal` with ``kc`` in the controller's port units (out-port units per
    pv-port unit, as a relay test on the module measures them): Kc = kc·pv_span/out_span."""
    pv_span, out_span = port_spans(kind, context or {})
    ideal = Ideal(kc * pv_span / out_span, ti, td, 0.0, direct)
    return from_ideal(kind, ideal, sample_time=sample_time, context=context)
