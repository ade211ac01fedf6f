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

The discrete law of each block (from its code and spec; Δ = sample time)
-----------------------------------------------------------------------

The generic ``pid`` is the reference: P = Kc·e; ΔI_k = (Kc/Ti)·Δ·e_k (backward Euler, the
current error); D_k = (Tf·D_{k-1} + Kc·Td·Δe_k)/(Tf + Δ) (backward-Euler filtered derivative,
Tf = 0: the plain backward difference). With pv_span, out_span the port units of 100 % of PV
and of output, Kc (%/%) = k_port·pv_span/out_span.

* ``pid`` (blocks/pid.py): k, ti, td (ideal); kp, ki, kd (parallel: Kc = kp, Ti = kp/ki,
  Td = kd/kp); series k', ti', td' via ``blocks.forms.series_to_ideal`` (plant-and-tuning 3.5).
  Tf = ``tf``, else Td/``n`` (n = 10 by default: a pid without ``tf`` filters its D). Setpoint
  weights b (P) and c (D, default 0 = derivative on PV). Spans: context pv_span, out_span
  (default 100, 100).
* ``ge.pid_ind`` / ``ge.pid_isa`` (vendor-blocks 1.2, 1.5, 1.6): P = Kp·e, ΔI = Ki·e·dt,
  D = Kd·Δ/dt (no filter), so Kc = Kp, Ti = Kp/Ki, Td = Kd/Kp; ISA: Kp = Kc, Ki = Kc/Ti,
  Kd = Kc·Td. Words: word6 = 100·Kp (Kc), word7 = 100·Kd (Td, s), word8 = 1000·Ki (IND) or
  1000/Ti (ISA). Same law as the generic pid with Tf = 0. ``derivative_on_pv`` is c = 0.
  Spans: context pv_span, cv_span counts (default 32000, 32000). Native arithmetic runs the
  rounded words (the conversion does too); ``arithmetic = "float"`` in the target context keeps
  the engineering values unrounded.
* ``s5.pid`` (vendor-blocks 2.2, 2.5, 2.6): K = k/scale, R = r/scale, TI = ti/scale,
  TD = td/scale (scale 1024 exact, 1000 nominal), TA = the OB 13 interval (``sample_time``).
  The velocity law dY = K[R·PW + TI·XW + dD] summed gives the position
  Y = K·R·XW + K·TI·ΣXW + K·ΣdD, so Kc = |K|·R and Ti = R·TA/TI (= R·TN). Law A,
  dD_k = d(TD·QW_k + dD_{k-1}) with d = dd_decay, sums to
  ΣdD = d·TD(1 - z⁻¹)/(1 - d·z⁻¹)·E, which is the pid's backward-Euler filtered D with
  Tf = d·TA/(1 - d) and Kc·Td = |K|·d·TD·TA/(1 - d): for d = 0.5, Tf = TA and Td = TV/R. d = 1
  (the literal law) is extra P: Kc = |K|(R + TD), no D. K < 0 is direct action (spec 2.5: the
  Siemens "direct" for K > 0 is ISA reverse). Spans: context pv_span, out_span counts (default
  1000, 1000). To S5 the gain goes into k with r = 1.0 (r = 1024 or 1000) unless the target
  context gives r.
* ``e2.pid`` (vendor-blocks 3.2, 3.3): per update Δ (``update_interval``): Padj = kp·Δe·100/TR,
  Iadj = ki·e, Dadj = kd·(e - 2e₋₁ + e₋₂); summed: P gain kp·100/TR %/EU, I gain ki/Δ %/(EU·s),
  D gain kd·Δ %·s/EU, an unfiltered backward difference: the pid's law with Tf = 0
  (i_tr_normalise / d_tr_normalise multiply ki / kd by 100/TR). e = input - setpoint is direct
  action. Spans: context pv_span EU (default 100), output 100 %. To E2: kp = 1 and TR chosen,
  unless the target context gives throttling_range (then kp is chosen); MAE is set to 0.
* ``deltav.pid`` (vendor-blocks 4.1, 4.2, 4.7): GAIN %/% on PV_SCALE/OUT_SCALE, RESET s/repeat
  (inf = no I), RATE s, filter ALPHA·RATE. Standard: D as the pid with Tf = α·RATE; the reset
  R_k = R_{k-1} + (Δ/RESET)·Kc·e_{k-1} integrates the *previous* error (forward Euler, Euler
  reset law, reset_feedback error). Series (lead_lag): (P + D)·(1 + I) with D of gain
  K'(1 - α)RATE', i.e. K'(1 + 1/(RESET's))(1 + RATE's)/(α·RATE's + 1); its Ideal is
  ``series_to_ideal`` ignoring the filter. STRUCTURE gives b = BETA, c = GAMMA.

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
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

from loopworks.blocks.forms import (
    ideal_to_parallel,
    ideal_to_series,
    parallel_to_ideal,
    series_to_ideal,
)
from loopworks.blocks.params import validate
from loopworks.catalog import block_class, create_block
from loopworks.errors import ParameterError
from loopworks.tuning.settings import Ideal

KINDS = ("pid", "ge.pid_ind", "ge.pid_isa", "s5.pid", "e2.pid", "deltav.pid")
TOL = 1e-9  # relative: what "the same" means in float arithmetic

ParamValue = float | int | str | bool

# Context values a kind takes besides its block parameters (they may be given in params too).
_CONTEXT: dict[str, tuple[str, ...]] = {
    "pid": ("pv_span", "out_span"),
    "ge.pid_ind": ("pv_span", "cv_span", "word6", "word7", "word8"),
    "ge.pid_isa": ("pv_span", "cv_span", "word6", "word7", "word8"),
    "s5.pid": ("pv_span", "out_span", "sample_time"),
    "e2.pid": ("pv_span",),
    "deltav.pid": (),
}
# The parameters a conversion reads (the others are ignored and named in the note).
_USED: dict[str, tuple[str, ...]] = {
    "pid": ("form", "k", "ti", "td", "kp", "ki", "kd", "n", "tf", "action", "b", "c"),
    "ge.pid_ind": ("kp", "ki", "kd", "direct_acting", "derivative_on_pv", "derivative_filter",
                   "derivative_filter_time", "config_word", "sample_period", "arithmetic",
                   "deadband_pos", "deadband_neg"),
    "ge.pid_isa": ("kc", "ti", "td", "direct_acting", "derivative_on_pv", "derivative_filter",
                   "derivative_filter_time", "config_word", "sample_period", "arithmetic",
                   "deadband_pos", "deadband_neg"),
    "s5.pid": ("k", "r", "ti", "td", "scale", "dd_decay", "xz_on", "arithmetic"),
    "e2.pid": ("throttling_range", "kp", "ki", "kd", "update_interval", "error_sign",
               "i_tr_normalise", "d_tr_normalise", "d_form", "min_accumulated_error",
               "filter_period"),
    "deltav.pid": ("form", "structure", "gain", "reset", "rate", "alpha", "beta", "gamma",
                   "direct_acting", "series_derivative", "reset_discretisation",
                   "derivative_discretisation", "reset_feedback", "ideadband",
                   "pv_scale_eu_0", "pv_scale_eu_100", "out_scale_eu_0", "out_scale_eu_100"),
}


@dataclass(frozen=True)
class Conversion:
    """The target's parameters (its own names), whether the target reproduces the source
    exactly (module docstring), a note (assumptions, what is inexact and the bound) and the
    intermediate normalised ideal settings."""

    params: dict[str, ParamValue]
    exact: bool
    note: str
    ideal: Ideal


@dataclass(frozen=True)
class _Law:
    """A block's discrete control law. ``ideal`` in %/%; ``dt`` the sample time the law is
    fixed to (None: the parameters are continuous-time, it runs at any Δ); ``integral``
    "backward" (current error) or "forward" (previous error); ``derivative`` "backward"
    (backward-Euler filter Tf) or "exp" (GE's exponential lag on the raw difference);
    ``series`` (K', Ti', Td', d_factor, Tf) for DeltaV's series form; ``flags``: sentences
    naming what makes the law differ from the linear one; ``notes``: assumptions."""

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


# ----------------------------------------------------------------------------------------------
# Parameter handling
# ----------------------------------------------------------------------------------------------
def _kind(kind: str) -> str:
    k = str(kind).strip().lower()
    if k not in KINDS:
        raise ParameterError(f"convert: kind '{kind}' is not allowed: expected one of "
                             + ", ".join(KINDS))
    return k


def _split(kind: str, params: Mapping[str, Any] | None) -> tuple[dict[str, Any],
                                                                    dict[str, Any]]:
    """Lower-case ``params`` and split them into block parameters and context values; an
    unknown name is a ParameterError listing the valid ones."""
    names = {p.name for p in block_class(kind).PARAMS}
    extra = set(_CONTEXT[kind])
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


def _number(name: str, value: Any, lo: float = 0.0, *, lo_open: bool = True,
            allow_inf: bool = False, kind: str = "convert") -> float:
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


def _span(ctx: Mapping[str, Any], name: str, default: float, kind: str) -> float:
    return _number(name, ctx.get(name, default), kind=kind)


def port_spans(kind: str, params_or_context: Mapping[str, Any]) -> tuple[float, float]:
    """(pv_span, out_span): the port units that make 100 % of PV span and of output span.

    pid: context pv_span, out_span (default 100, 100); GE: pv_span, cv_span counts (default
    32000, 32000); S5: pv_span, out_span counts (default 1000, 1000); E2: pv_span EU (default
    100) and 100 (%); DeltaV: the PV_SCALE and OUT_SCALE spans (default 100, 100)."""
    kind = _kind(kind)
    ctx = {str(k).lower(): v for k, v in params_or_context.items()}
    if kind == "pid":
        return _span(ctx, "pv_span", 100.0, kind), _span(ctx, "out_span", 100.0, kind)
    if kind.startswith("ge."):
        return _span(ctx, "pv_span", 32000.0, kind), _span(ctx, "cv_span", 32000.0, kind)
    if kind == "s5.pid":
        return _span(ctx, "pv_span", 1000.0, kind), _span(ctx, "out_span", 1000.0, kind)
    if kind == "e2.pid":
        return _span(ctx, "pv_span", 100.0, kind), 100.0
    spans = []
    for scale in ("pv_scale", "out_scale"):
        e0 = float(ctx.get(f"{scale}_eu_0", 0.0))
        e100 = float(ctx.get(f"{scale}_eu_100", 100.0))
        if not e100 > e0:
            raise ParameterError(f"{kind}: parameter '{scale}_eu_100' = {e100:g} must be "
                                 f"greater than {scale}_eu_0 = {e0:g}")
        spans.append(e100 - e0)
    return spans[0], spans[1]


def _ignored(kind: str, block: Mapping[str, Any]) -> tuple[str, ...]:
    unused = sorted(n for n in block if n not in _USED[kind])
    if not unused:
        return ()
    return (f"Not converted (not tuning parameters): {', '.join(unused)}.",)


def _no_ideal(kind: str, name: str, value: Any) -> ParameterError:
    return ParameterError(f"{kind}: parameter '{name}' = {value} has no ideal form (no "
                          "proportional action): allowed > 0")


# ----------------------------------------------------------------------------------------------
# Source: block parameters -> discrete law
# ----------------------------------------------------------------------------------------------
def _law_of(kind: str, params: Mapping[str, Any] | None, dt: float | None,
            context: Mapping[str, Any] | None) -> _Law:
    kind = _kind(kind)
    block, ctx = _split(kind, params)
    ctx.update({str(k).lower(): v for k, v in (context or {}).items()})
    prm = validate(kind, block_class(kind).PARAMS, block)
    law = _LAWS[kind](prm, block, ctx, dt, kind)
    return replace(law, notes=law.notes + _ignored(kind, block))


def _pid_law(prm: dict[str, Any], given: dict[str, Any], ctx: dict[str, Any],
             dt: float | None, kind: str) -> _Law:
    pv_span, out_span = port_spans(kind, ctx)
    form = prm["form"]
    if form == "parallel":
        kp = 1.0 if prm["kp"] is None else float(prm["kp"])
        ki = 0.0 if prm["ki"] is None else float(prm["ki"])
        kd = 0.0 if prm["kd"] is None else float(prm["kd"])
        if not kp > 0.0:
            raise _no_ideal(kind, "kp", kp)
        k, ti, td = parallel_to_ideal(kp, ki, kd)
    else:
        k = 1.0 if prm["k"] is None else float(prm["k"])
        ti = math.inf if prm["ti"] is None else float(prm["ti"])
        td = 0.0 if prm["td"] is None else float(prm["td"])
        if form == "series" and td > 0.0:
            k, ti, td = series_to_ideal(k, ti, td)
    if prm["tf"] is not None:
        tf = float(prm["tf"])
    else:
        n = 10.0 if prm["n"] is None else float(prm["n"])
        tf = 0.0 if td == 0.0 or n == math.inf else td / n
    notes: tuple[str, ...] = ()
    if prm["tf"] is None and td > 0.0 and tf > 0.0:
        notes = (f"The pid filters its derivative with Tf = Td/n = {tf:g} s (n default 10).",)
    ideal = Ideal(k * pv_span / out_span, ti, td, tf if td > 0.0 else 0.0,
                  prm["action"] == "direct")
    return _Law(ideal, b=float(prm["b"]), c=float(prm["c"]), dt=dt, notes=notes)


def _ge_bits(prm: dict[str, Any], kind: str) -> dict[str, bool]:
    flags = ("direct_acting", "invert_output", "derivative_on_pv", "deadband_subtract",
             "arw_hold", "derivative_filter")
    if prm["config_word"] is not None:
        cw = int(prm["config_word"])
        return {name: bool(cw >> bit & 1) for bit, name in enumerate(flags)}
    return {name: bool(prm[name]) for name in flags}


def _ge_law(prm: dict[str, Any], given: dict[str, Any], ctx: dict[str, Any],
            dt: float | None, kind: str) -> _Law:
    pv_span, cv_span = port_spans(kind, ctx)
    isa = kind == "ge.pid_isa"
    names = ("kc", "td", "ti") if isa else ("kp", "kd", "ki")
    words: dict[int, int] = {}
    for n, name in zip((6, 7, 8), names, strict=True):
        wname = f"word{n}"
        if wname in ctx:
            w = _number(wname, ctx[wname], 0.0, lo_open=False, kind=kind)
            if w != int(w) or w > 32767:
                raise ParameterError(f"{kind}: parameter '{wname}' = {ctx[wname]!r} is out "
                                     "of range: allowed 0..32767 (integer)")
            if name in given:  # both (a conversion's output): they must agree
                v = float(prm[name])
                scale = {6: 100.0, 7: 100.0, 8: 1000.0}[n]
                want = (0 if v == math.inf else math.floor(1000.0 / v + 0.5)) \
                    if (isa and n == 8) else math.floor(v * scale + 0.5)
                if want != int(w):
                    raise ParameterError(f"{kind}: parameter '{wname}' = {int(w)} does not "
                                         f"match '{name}' = {v:g} (word {want}): give one")
                continue
            words[n] = int(w)
    native = prm["arithmetic"] == "native"
    notes: list[str] = []

    def value(n: int, name: str, scale: float) -> float:
        if n in words:
            return words[n] / scale
        v = float(prm[name])
        if native and math.isfinite(v):
            w = math.floor(abs(v) * scale + 0.5)
            if abs(w / scale - v) > TOL * abs(v):
                notes.append(f"Native arithmetic runs {name} = {v:g} as word {n} = {w} "
                             f"({w / scale:g}); the conversion uses the word.")
            return w / scale
        return v

    if isa:
        kc = value(6, "kc", 100.0)
        td = value(7, "td", 100.0)
        if 8 in words:
            ti = math.inf if words[8] == 0 else 1000.0 / words[8]
        else:
            ti = float(prm["ti"])
            if native and math.isfinite(ti):
                w8 = math.floor(1000.0 / ti + 0.5)
                if w8 == 0:
                    raise ParameterError(f"{kind}: parameter 'ti' = {ti:g} s is out of range: "
                                         "word 8 = 1000/ti would round to 0")
                if abs(1000.0 / w8 - ti) > TOL * ti:
                    notes.append(f"Native arithmetic runs ti = {ti:g} s as word 8 = {w8} "
                                 f"(Ti = {1000.0 / w8:g} s); the conversion uses the word.")
                ti = 1000.0 / w8
        if not kc > 0.0:
            raise _no_ideal(kind, "kc", kc)
        kp = kc
    else:
        kp = value(6, "kp", 100.0)
        kd = value(7, "kd", 100.0)
        ki = value(8, "ki", 1000.0)
        if not kp > 0.0:
            raise _no_ideal(kind, "kp", kp)
        _, ti, td = parallel_to_ideal(kp, ki, kd)
    bits = _ge_bits(prm, kind)
    derivative = "backward"
    tf = 0.0
    if bits["derivative_filter"] and td > 0.0:
        derivative = "exp"
        tf = (float(prm["derivative_filter_time"]) if prm["derivative_filter_time"] is not None
              else (td if isa else kp * td) / 10.0)
        if tf == 0.0:
            derivative = "backward"
    flags: list[str] = []
    if float(prm["deadband_pos"]) != 0.0 or float(prm["deadband_neg"]) != 0.0:
        flags.append("The GE error dead band (words 4, 5) is a non-linearity the target does "
                     "not have (not converted).")
    period = float(prm["sample_period"])
    law_dt = max(period, 0.01) if period > 0.0 else dt
    ideal = Ideal(kp * pv_span / cv_span, ti, td, tf, bits["direct_acting"])
    return _Law(ideal, b=1.0, c=0.0 if bits["derivative_on_pv"] else 1.0, dt=law_dt,
                derivative=derivative, words=native, flags=tuple(flags), notes=tuple(notes))


def _s5_law(prm: dict[str, Any], given: dict[str, Any], ctx: dict[str, Any],
            dt: float | None, kind: str) -> _Law:
    ta = ctx.get("sample_time", dt)
    if ta is None:
        raise ParameterError("s5.pid: parameter 'sample_time' (the OB 13 interval TA, s) is "
                             "required: allowed (0, inf) s")
    ta = _number("sample_time", ta, kind=kind)
    pv_span, out_span = port_spans(kind, ctx)
    scale = 1024.0 if prm["scale"] == "exact" else 1000.0
    big_k = prm["k"] / scale
    r, ti_c, td_c = prm["r"] / scale, prm["ti"] / scale, prm["td"] / scale
    d = float(prm["dd_decay"])
    mag = abs(big_k)
    flags: list[str] = []
    if d >= 1.0:  # the literal law: D acts as extra P of gain TD (spec 2.6)
        kc = mag * (r + td_c)
        kd = 0.0
        tf = 0.0
    else:
        kc = mag * r
        kd = mag * d * td_c * ta / (1.0 - d)
        tf = d * ta / (1.0 - d) if kd > 0.0 else 0.0
    if not kc > 0.0:
        raise _no_ideal(kind, "k·r" if mag > 0.0 else "k", prm["k"] if mag == 0.0 else
                        f"{prm['k']}·{prm['r']}")
    ti = kc * ta / (mag * ti_c) if ti_c > 0.0 else math.inf
    if prm["xz_on"]:
        flags.append("xz_on: the S5 differentiates the XZ input, not the error (not "
                     "converted; treated as D on the error).")
    notes = [f"S5 at TA = {ta:g} s, scale {prm['scale']} (÷{scale:g}), dd_decay {d:g}."]
    if prm["arithmetic"] == "native":
        notes.append("Native fixed point rounds every product (about a count per scan); "
                     "that is signal rounding, not counted here.")
    ideal = Ideal(kc * pv_span / out_span, ti, kd / kc, tf, big_k < 0.0)
    return _Law(ideal, dt=ta, flags=tuple(flags), notes=tuple(notes), words=True)


def _e2_law(prm: dict[str, Any], given: dict[str, Any], ctx: dict[str, Any],
            dt: float | None, kind: str) -> _Law:
    pv_span, _ = port_spans(kind, ctx)
    notes: list[str] = []
    if "update_interval" in given or dt is None:
        step = float(prm["update_interval"])
        if "update_interval" not in given:
            notes.append(f"E2 update_interval not given: the block default {step:g} s.")
    else:
        step = dt
    if prm["d_form"] == "as_printed":
        raise ParameterError("e2.pid: parameter 'd_form' = 'as_printed' has no continuous "
                             "equivalent (it adds an error to an error per minute): allowed "
                             "second_difference")
    tr = float(prm["throttling_range"])
    kp = float(prm["kp"])
    if not kp > 0.0:
        raise _no_ideal(kind, "kp", kp)
    kc_port = kp * 100.0 / tr  # %/EU
    ki = float(prm["ki"]) * (100.0 / tr if prm["i_tr_normalise"] else 1.0) / step
    kd = float(prm["kd"]) * (100.0 / tr if prm["d_tr_normalise"] else 1.0) * step
    flags: list[str] = []
    mae = float(prm["min_accumulated_error"])
    if mae > 0.0 and ki > 0.0:
        flags.append(f"E2 min_accumulated_error = {mae:g} EU stops the I action while "
                     "abs(e) <= MAE (a dead band the target does not have; set it to 0).")
    if float(prm["filter_period"]) > 0.0:
        flags.append("The E2 filter cell (filter_period > 0) lags the output (not converted).")
    ideal = Ideal(kc_port * pv_span / 100.0, kc_port / ki if ki > 0.0 else math.inf,
                  kd / kc_port, 0.0, prm["error_sign"] == "input_minus_setpoint")
    return _Law(ideal, dt=step, flags=tuple(flags), notes=tuple(notes))


_DV_STRUCTURES: dict[str, tuple[bool, float, float, bool]] = {
    "pid_action_on_error": (True, 1.0, 1.0, True),
    "pi_action_on_error_d_action_on_pv": (True, 1.0, 0.0, True),
    "i_action_on_error_pd_action_on_pv": (True, 0.0, 0.0, True),
    "pd_action_on_error": (True, 1.0, 1.0, False),
    "p_action_on_error_d_action_on_pv": (True, 1.0, 0.0, False),
    "id_action_on_error": (False, 0.0, 1.0, True),
    "i_action_on_error_d_action_on_pv": (False, 0.0, 0.0, True),
    "two_degrees_of_freedom": (True, math.nan, math.nan, True),
}


def _deltav_law(prm: dict[str, Any], given: dict[str, Any], ctx: dict[str, Any],
                dt: float | None, kind: str) -> _Law:
    structure = prm["structure"]
    has_p, beta, gamma, has_i = _DV_STRUCTURES[structure]
    if not has_p:
        raise ParameterError(f"deltav.pid: parameter 'structure' = '{structure}' has no "
                             "ideal form (no P action): allowed a structure with P")
    if structure == "two_degrees_of_freedom":
        beta, gamma = float(prm["beta"]), float(prm["gamma"])
    gain, reset, rate = float(prm["gain"]), float(prm["reset"]), float(prm["rate"])
    if reset == 0.0 or not has_i:
        reset = math.inf
    alpha = float(prm["alpha"])
    direct = bool(prm["direct_acting"])
    flags: list[str] = []
    if prm["reset_discretisation"] != "euler" and reset < math.inf:
        flags.append(f"DeltaV reset_discretisation = {prm['reset_discretisation']} changes "
                     "the integral gain per scan (converted as RESET).")
    if prm["derivative_discretisation"] != "backward" and rate > 0.0:
        flags.append("DeltaV derivative_discretisation = exact (step invariant) is not the "
                     "backward-Euler filter (converted as α·RATE).")
    if prm["reset_feedback"] == "output" and (rate > 0.0 or beta != 1.0) and reset < math.inf:
        flags.append("DeltaV reset_feedback = output integrates D and the setpoint weighting "
                     "too (converted as the spec 4.2 equations).")
    if float(prm["ideadband"]) > 0.0 and reset < math.inf:
        flags.append("DeltaV IDEADBAND freezes the reset near the setpoint (not converted).")
    if dt is not None and reset < dt:
        flags.append(f"RESET = {reset:g} s is shorter than the scan {dt:g} s: the Euler reset "
                     "gain is capped at 1.")
    ctx_spans = {n: prm[n] for n in ("pv_scale_eu_0", "pv_scale_eu_100", "out_scale_eu_0",
                                     "out_scale_eu_100")}
    port_spans(kind, ctx_spans)  # checks the scales
    if prm["form"] == "series":
        k, ti, td = series_to_ideal(gain, reset, rate)
        d_factor = 1.0 - alpha if prm["series_derivative"] == "lead_lag" else 1.0
        ideal = Ideal(k, ti, td, alpha * rate if rate > 0.0 else 0.0, direct)
        return _Law(ideal, b=beta, c=gamma, dt=dt, integral="forward",
                    series=(gain, reset, rate, d_factor, alpha * rate), flags=tuple(flags))
    ideal = Ideal(gain, reset, rate, alpha * rate if rate > 0.0 else 0.0, direct)
    return _Law(ideal, b=beta, c=gamma, dt=dt, integral="forward", flags=tuple(flags))


_LAWS = {"pid": _pid_law, "ge.pid_ind": _ge_law, "ge.pid_isa": _ge_law, "s5.pid": _s5_law,
         "e2.pid": _e2_law, "deltav.pid": _deltav_law}


# ----------------------------------------------------------------------------------------------
# Target: ideal law -> block parameters
# ----------------------------------------------------------------------------------------------
def _make_pid(ideal: Ideal, b: float, c: float, dt: float | None,
              ctx: dict[str, Any]) -> dict[str, ParamValue]:
    pv_span, out_span = port_spans("pid", ctx)
    k = ideal.kc * out_span / pv_span
    form = str(ctx.get("form", "ideal")).lower()
    out: dict[str, ParamValue] = {"form": form}
    if form == "parallel":
        kp, ki, kd = ideal_to_parallel(k, ideal.ti, ideal.td)
        out.update(kp=kp, ki=ki, kd=kd)
    elif form == "series":
        ks, tis, tds = ideal_to_series(k, ideal.ti, ideal.td)
        out.update(k=ks, ti=tis, td=tds)
    elif form == "ideal":
        out.update(k=k, ti=ideal.ti, td=ideal.td)
    else:
        raise ParameterError(f"pid: parameter 'form' = {form!r} is not allowed: expected one "
                             "of ideal, parallel, series")
    out.update(tf=ideal.tf if ideal.td > 0.0 else 0.0,
               action="direct" if ideal.direct else "reverse", b=b, c=c)
    return out


def _word(name: str, value: float, kind: str, hi: float = 32767.0) -> int:
    w = math.floor(abs(value) + 0.5)
    if w > hi:
        raise ParameterError(f"{kind}: parameter '{name}' = {w} is out of range: allowed "
                             f"0..{hi:g} (integer word)")
    return int(w)


def _make_ge(kind: str, ideal: Ideal, b: float, c: float, dt: float | None,
             ctx: dict[str, Any]) -> dict[str, ParamValue]:
    pv_span, cv_span = port_spans(kind, ctx)
    k = ideal.kc * cv_span / pv_span
    native = str(ctx.get("arithmetic", "native")).lower() != "float"
    out: dict[str, ParamValue] = {}
    if kind == "ge.pid_isa":
        w6 = _word("word6", k * 100.0, kind)
        w7 = _word("word7", ideal.td * 100.0, kind)
        w8 = 0 if ideal.ti == math.inf else _word("word8", 1000.0 / ideal.ti, kind)
        if ideal.ti != math.inf and w8 == 0:
            raise ParameterError(f"{kind}: parameter 'ti' = {ideal.ti:g} s is out of range: "
                                 "allowed up to 2000 s (word 8 = 1000/ti >= 1) or inf")
        if native:
            out.update(kc=w6 / 100.0, ti=math.inf if w8 == 0 else 1000.0 / w8, td=w7 / 100.0)
        else:
            out.update(kc=k, ti=ideal.ti, td=ideal.td)
    else:
        kp, ki, kd = ideal_to_parallel(k, ideal.ti, ideal.td)
        w6 = _word("word6", kp * 100.0, kind)
        w7 = _word("word7", kd * 100.0, kind)
        w8 = _word("word8", ki * 1000.0, kind)
        if native:
            out.update(kp=w6 / 100.0, ki=w8 / 1000.0, kd=w7 / 100.0)
        else:
            out.update(kp=kp, ki=ki, kd=kd)
    out.update(word6=w6, word7=w7, word8=w8, direct_acting=ideal.direct,
               derivative_on_pv=c == 0.0 and ideal.td > 0.0)
    if not native:
        out["arithmetic"] = "float"
    if dt is not None:
        out["sample_period"] = dt
    return out


def _make_s5(ideal: Ideal, b: float, c: float, dt: float | None,
             ctx: dict[str, Any]) -> dict[str, ParamValue]:
    if dt is None:
        raise ParameterError("s5.pid: parameter 'sample_time' (the OB 13 interval TA, s) is "
                             "required: allowed (0, inf) s")
    pv_span, out_span = port_spans("s5.pid", ctx)
    scale_name = str(ctx.get("scale", "exact")).lower()
    if scale_name not in ("exact", "nominal"):
        raise ParameterError(f"s5.pid: parameter 'scale' = {scale_name!r} is not allowed: "
                             "expected one of exact, nominal")
    scale = 1024.0 if scale_name == "exact" else 1000.0
    d = _number("dd_decay", ctx.get("dd_decay", 0.5), 0.0, lo_open=False, kind="s5.pid")
    kc = ideal.kc * out_span / pv_span
    r_word = int(ctx["r"]) if "r" in ctx else int(scale)
    if not 0 < r_word <= 32767:
        raise ParameterError(f"s5.pid: parameter 'r' = {r_word} is out of range: allowed "
                             "1..32767 (integer word)")
    r = r_word / scale
    big_k = kc / r
    ti_c = r * dt / ideal.ti if ideal.ti < math.inf else 0.0
    td_c = 0.0
    if ideal.td > 0.0:
        if not 0.0 < d < 1.0:
            raise ParameterError(f"s5.pid: parameter 'dd_decay' = {d:g} is out of range for a "
                                 "derivative: allowed (0, 1) (law A: 0.5)")
        td_c = r * ideal.td * (1.0 - d) / (d * dt)
    k_word = _word("k", big_k * scale, "s5.pid")
    out: dict[str, ParamValue] = {
        "k": -k_word if ideal.direct else k_word, "r": r_word,
        "ti": _word("ti", ti_c * scale, "s5.pid", 9999.0),
        "td": _word("td", td_c * scale, "s5.pid"), "scale": scale_name, "dd_decay": d}
    return out


def _make_e2(ideal: Ideal, b: float, c: float, dt: float | None,
             ctx: dict[str, Any]) -> dict[str, ParamValue]:
    step = ctx.get("update_interval", dt)
    if step is None:
        raise ParameterError("e2.pid: parameter 'update_interval' (s) is required for the "
                             "per-update gains: give sample_time; allowed (0, inf) s")
    step = _number("update_interval", step, kind="e2.pid")
    pv_span, _ = port_spans("e2.pid", ctx)
    kc_port = ideal.kc * 100.0 / pv_span  # %/EU
    if "throttling_range" in ctx:
        tr = _number("throttling_range", ctx["throttling_range"], kind="e2.pid")
        kp = kc_port * tr / 100.0
    else:
        kp = 1.0
        tr = 100.0 / kc_port
    i_norm = bool(ctx.get("i_tr_normalise", False))
    d_norm = bool(ctx.get("d_tr_normalise", False))
    ki = kc_port / ideal.ti * step if ideal.ti < math.inf else 0.0
    kd = kc_port * ideal.td / step
    if i_norm:
        ki *= tr / 100.0
    if d_norm:
        kd *= tr / 100.0
    out: dict[str, ParamValue] = {
        "throttling_range": tr, "kp": kp, "ki": ki, "kd": kd, "update_interval": step,
        "error_sign": "input_minus_setpoint" if ideal.direct else "setpoint_minus_input",
        "min_accumulated_error": 0.0}
    if i_norm:
        out["i_tr_normalise"] = True
    if d_norm:
        out["d_tr_normalise"] = True
    return out


def _make_deltav(ideal: Ideal, b: float, c: float, dt: float | None,
                 ctx: dict[str, Any]) -> dict[str, ParamValue]:
    form = str(ctx.get("form", "standard")).lower()
    if "alpha" in ctx:
        alpha = float(ctx["alpha"])
    elif ideal.td > 0.0 and ideal.tf > 0.0:
        alpha = min(max(ideal.tf / ideal.td, 0.05), 1.0)
    else:
        alpha = 0.125
    structures = {(1.0, 1.0): "pid_action_on_error",
                  (1.0, 0.0): "pi_action_on_error_d_action_on_pv",
                  (0.0, 0.0): "i_action_on_error_pd_action_on_pv"}
    out: dict[str, ParamValue] = {"form": form}
    if form == "series":
        gain, reset, rate = ideal_to_series(ideal.kc, ideal.ti, ideal.td)
    elif form == "standard":
        gain, reset, rate = ideal.kc, ideal.ti, ideal.td
    else:
        raise ParameterError(f"deltav.pid: parameter 'form' = {form!r} is not allowed: "
                             "expected one of standard, series")
    structure = structures.get((b, c if ideal.td > 0.0 else 0.0), "two_degrees_of_freedom")
    if ideal.td == 0.0 and b == 1.0:
        structure = "pi_action_on_error_d_action_on_pv"
    out.update(structure=structure, gain=gain, reset=reset, rate=rate, alpha=alpha,
               direct_acting=ideal.direct)
    if structure == "two_degrees_of_freedom":
        out.update(beta=b, gamma=c)
    for name in ("series_derivative", "pv_scale_eu_0", "pv_scale_eu_100", "out_scale_eu_0",
                 "out_scale_eu_100"):
        if name in ctx:
            out[name] = ctx[name]
    return out


# ----------------------------------------------------------------------------------------------
# Comparison of two laws: exactness and bounds
# ----------------------------------------------------------------------------------------------
def _response(law: _Law, w: float, dt: float | None) -> complex:
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


def _compare(src: _Law, tgt: _Law) -> tuple[bool, list[str]]:
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
        why.append(f"Largest relative parameter change from {cause}: {moved[name]:.3g} "
                   f"({name}).")
    if has_d and errs.get("Tf", 0.0) > TOL and s.td > 0.0:
        w = 1.0 / s.td
        e = abs(1.0 / complex(1.0, w * t.tf) - 1.0 / complex(1.0, w * s.tf))
        why.append(f"Derivative filter Tf = {s.tf:g} s in the source, {t.tf:g} s in the "
                   "target: the D term's relative frequency-response error "
                   f"|1/(1+jωTf_t) - 1/(1+jωTf_s)| is {e:.3g} at ω = 1/Td = {w:.4g} rad/s "
                   f"(≤ ω·|ΔTf| = {w * abs(s.tf - t.tf):.3g}).")
    dt = src.dt if src.dt is not None else tgt.dt
    if src.dt is not None and tgt.dt is not None and _rel(src.dt, tgt.dt) > TOL \
            and (has_i or has_d):
        why.append(f"The source runs at Δ = {src.dt:g} s, the target at {tgt.dt:g} s: each "
                   "rectangular integral differs from 1/s by (ωΔ/2)/sin(ωΔ/2) in magnitude "
                   f"and ωΔ/2 in phase ({_rect(s.ti, src.dt)} vs {_rect(s.ti, tgt.dt)} at "
                   "ω = 1/Ti), and the backward differences likewise.")
    if has_i and src.integral != tgt.integral:
        bound = f"≤ Δ/Ti = {dt / s.ti:.3g}" if dt is not None and s.ti < math.inf \
            else "≤ Δ/Ti (give sample_time for a number)"
        why.append("DeltaV's reset integrates the previous scan's error (forward Euler), the "
                   "other block the current one (backward Euler): the I term differs by z⁻¹, "
                   f"relative error 2·sin(ωΔ/2) ≤ ωΔ; at ω = 1/Ti {bound}.")
    if has_d and src.derivative != tgt.derivative:
        why.append("GE's derivative filter is an exponential lag on the raw difference, the "
                   "other block's a backward-Euler filter: they differ by O(Δ/Tf)"
                   + ("" if dt is not None else " (give sample_time for a number)") + ".")
    if (src.series is None) != (tgt.series is None) and has_d:
        why.append("DeltaV's series form K'(1 + 1/(Ti's))(1 + Td's)/(αTd's + 1) keeps its "
                   "filter inside the product: no ideal form with one filter equals it.")
    elif src.series is not None and tgt.series is not None and any(
            _rel(a, b) > TOL for a, b in zip(src.series, tgt.series, strict=True)):
        why.append("The DeltaV series settings differ (alpha or series_derivative).")
    if _rel(src.b, tgt.b) > TOL or (has_d and _rel(src.c, tgt.c) > TOL):
        why.append(f"The setpoint path differs (P on b·SP - PV, D on c·SP - PV): source "
                   f"b = {src.b:g}, c = {src.c:g}; target b = {tgt.b:g}, c = {tgt.c:g}. The "
                   "response to PV is not affected by this.")
    why.extend(src.flags)
    why.extend(tgt.flags)
    if not why:
        return True, []
    bounds = []
    for label, w in (("1/Ti", 1.0 / s.ti if s.ti < math.inf else 0.0),
                     ("1/Td", 1.0 / s.td if s.td > 0.0 else 0.0)):
        if w > 0.0:
            cs = _response(src, w, src.dt if src.dt is not None else dt)
            ct = _response(tgt, w, tgt.dt if tgt.dt is not None else dt)
            bounds.append(f"{abs(ct - cs) / abs(cs):.3g} at ω = {label} = {w:.4g} rad/s")
    if not bounds:
        cs, ct = _response(src, 1.0, None), _response(tgt, 1.0, None)
        bounds.append(f"{abs(ct - cs) / abs(cs):.3g} (P only, any ω)")
    where = f"discrete, Δ = {dt:g} s" if dt is not None else "continuous, no Δ given"
    why.append("Controller frequency-response error |C_t - C_s|/|C_s| "
               f"({where}): " + "; ".join(bounds) + ".")
    return False, why


def _rect(ti: float, dt: float) -> str:
    if ti == math.inf:
        return "no I"
    h = dt / ti / 2.0
    return f"{h / math.sin(h):.6g}∠{math.degrees(h):.3g}°"


# ----------------------------------------------------------------------------------------------
# Public API
# ----------------------------------------------------------------------------------------------
def _canonical(ideal: Ideal, dt: float | None, ctx: Mapping[str, Any]) -> _Law:
    return _Law(ideal, b=float(ctx.get("b", 1.0)), c=float(ctx.get("c", 1.0)), dt=dt)


def _note(parts: list[str] | tuple[str, ...], exact: bool) -> str:
    head = "Exact: the target realises the same discrete control law." if exact \
        else "Not exact."
    return " ".join([head, *parts])


def to_ideal(kind: str, params: Mapping[str, Any], *, sample_time: float | None = None,
             context: Mapping[str, Any] | None = None) -> tuple[Ideal, bool, str]:
    """The normalised ideal settings of a ``kind`` block with ``params``; ``exact`` is True
    when the generic pid with these settings (and b = c = 1) at the block's sample time is the
    block's own law. ``context``: spans (port_spans), the S5's sample time."""
    dt = None if sample_time is None else _number("sample_time", sample_time)
    law = _law_of(kind, params, dt, context)
    exact, why = _compare(law, _canonical(law.ideal, law.dt, {}))
    return law.ideal, exact, _note(list(law.notes) + why, exact)


def _from_law(kind: str, law: _Law, dt: float | None, ctx: dict[str, Any]) -> Conversion:
    kind = _kind(kind)
    target_dt = dt if dt is not None else law.dt
    if kind == "ge.pid_ind" or kind == "ge.pid_isa":
        if "sample_period" in ctx:
            target_dt = _number("sample_period", ctx["sample_period"], kind=kind)
        params = _make_ge(kind, law.ideal, law.b, law.c, target_dt, ctx)
    elif kind == "pid":
        params = _make_pid(law.ideal, law.b, law.c, target_dt, ctx)
    elif kind == "s5.pid":
        if "sample_time" in ctx:
            target_dt = _number("sample_time", ctx["sample_time"], kind=kind)
        params = _make_s5(law.ideal, law.b, law.c, target_dt, ctx)
    elif kind == "e2.pid":
        params = _make_e2(law.ideal, law.b, law.c, target_dt, ctx)
        target_dt = float(params["update_interval"])
    else:
        params = _make_deltav(law.ideal, law.b, law.c, target_dt, ctx)
    block_params = {k: v for k, v in params.items() if not k.startswith("word")}
    create_block(kind, jit=False, **block_params)  # the target block accepts them (ranges, words)
    spans = {k: v for k, v in ctx.items() if k in _CONTEXT[kind] and "span" in k}
    if kind == "s5.pid":
        spans["sample_time"] = target_dt
    tgt = _law_of(kind, block_params, target_dt, spans)
    tgt = replace(tgt, notes=())
    exact, why = _compare(law, tgt)
    notes = list(law.notes)
    if kind == "s5.pid":
        notes.append(f"S5 words for TA = {target_dt:g} s.")
        if abs(int(params["k"])) > 1500 and int(params["td"]) > 0:
            notes.append("|k| > 1500 with a D part can overflow the 16-bit products in native "
                         "arithmetic (spec 2.2).")
    if kind in ("pid", "deltav.pid", "ge.pid_ind", "ge.pid_isa") and law.dt is not None:
        notes.append(f"Run the target at Δ = {law.dt:g} s.")
    return Conversion(params=params, exact=exact, note=_note(notes + why, exact),
                      ideal=law.ideal)


def from_ideal(kind: str, ideal: Ideal, *, sample_time: float | None = None,
               context: Mapping[str, Any] | None = None) -> Conversion:
    """Parameters of a ``kind`` block realising ``ideal`` (normalised %/%, the generic pid's
    discretisation at ``sample_time``). ``context``: the target's spans and choices (pid
    ``form``; GE ``arithmetic``; S5 ``scale``, ``r``, ``dd_decay``; E2 ``throttling_range``,
    ``i_tr_normalise``, ``d_tr_normalise``; DeltaV ``form``, ``alpha``, scales) and the
    setpoint weights ``b``, ``c`` of the law to realise (default 1, 1: the ideal form)."""
    ctx = {str(k).lower(): v for k, v in (context or {}).items()}
    dt = None if sample_time is None else _number("sample_time", sample_time)
    return _from_law(kind, _canonical(ideal, dt, ctx), dt, ctx)


def convert(from_kind: str, params: Mapping[str, Any], to_kind: str, *,
            sample_time: float | None = None,
            target: Mapping[str, Any] | None = None) -> Conversion:
    """Convert ``params`` of a ``from_kind`` block into parameters of a ``to_kind`` block.

    ``sample_time`` (s) is the loop's sample time: the S5's OB 13 interval TA, the E2's update
    interval and GE's sample period when they are not given, and the scan of pid / DeltaV.
    ``target`` is the target's context (see :func:`from_ideal`)."""
    dt = None if sample_time is None else _number("sample_time", sample_time)
    law = _law_of(from_kind, params, dt, None)
    ctx = {str(k).lower(): v for k, v in (target or {}).items()}
    return _from_law(to_kind, law, dt, ctx)


def from_loop_units(kind: str, kc: float, ti: float, td: float, *, direct: bool = False,
                    sample_time: float | None = None,
                    context: Mapping[str, Any] | None = None) -> Conversion:
    """Like :func:`from_ideal` with ``kc`` in the controller's port units (out-port units per
    pv-port unit, as a relay test on the module measures them): Kc = kc·pv_span/out_span."""
    pv_span, out_span = port_spans(kind, context or {})
    ideal = Ideal(kc * pv_span / out_span, ti, td, 0.0, direct)
    return from_ideal(kind, ideal, sample_time=sample_time, context=context)
