r"""The DeltaV signal generator (SGGN) as the compensator's dither source: kind ``deltav.sggn``.

In seed 000 the stick-slip compensator module holds an SGGN block, SGGN1, executed as #3
just before the CALC block (#4) whose expression reads DITHER_OUT. The SGGN1 configuration is
not in any retrieved source (spec vendor-blocks 6.5, 8 item 5); the spec's most plausible
reading [A] is a square wave of amplitude DITHER_AMP, zero bias, a fixed period, starting with
+, its output wired to DITHER_OUT. This block is that generator, with sine and triangle as
alternatives.

Equations
---------

The block keeps its position in the cycle, c (cycles, 0 <= c < 1). At the first scan c = 0;
each later scan advances it by the scan time and wraps it::

    c_k = frac(c_{k-1} + 1/(2·N))                (c_0 = 0; N = half_period_scans)
    c_k = frac(c_{k-1} + dt_k / period)          (when a period in seconds is given)
    s_k = frac(c_k + phase / 360)                (phase in degrees)

so c_k is the scans counted (k/(2N), the spec's half-period of N scans, default 1: the square
wave alternates every scan, whatever the scan time) or the elapsed time (t_k - t_0)/period,
modulo 1, and the output of scan k is

    square    out = bias + A·(+1 if s < 1/2 else -1)
    sine      out = bias + A·sin(2π·s)
    triangle  out = bias + A·(4s for s <= 1/4; 2 - 4s for 1/4 < s <= 3/4; 4s - 4 above)

with A = the ``amplitude`` input when it is not NaN, else the ``amplitude`` parameter. All three
start (phase 0) at the beginning of the positive half-wave: the square wave at +A, the sine and
the triangle at 0 rising. The square wave is the sign of the sine.

Wrapping uses a tolerance of 1e-9 cycles, so that binary rounding of dt/period does not move a
scan across an edge it sits on: a position within 1e-9 of a whole cycle is taken as 0 (the
cycle start, kept exactly), and the square wave takes a position within 1e-9 of 1/2 as the
start of the negative half. Hence the default square wave alternates every scan, +A, -A, +A,
... (dt = 1 s, 0.1 s or any other), and ``half_period_scans`` = N (or ``period`` = 2·N·dt)
every N scans: the internal dither of ``deltav.stick_slip`` with ``dither_half_period`` = N.

The ``amplitude`` input lets a module drive the amplitude from another block, as the seed's
compensator does (spec 6.5 [A])::

    "sggn1.amplitude"  = "comp.dither_amp"     (SGGN1 runs first: last scan's DITHER_AMP)
    "comp.dither_out"  = "sggn1.out"

Because SGGN1 runs before the compensator in each scan, it reads the DITHER_AMP the
compensator wrote in the previous scan: a one-scan lag (spec 6.1, 6.5 [D]). A negative
amplitude inverts the wave; a NaN input ("not given") selects the parameter. In a scenario
table, ``amplitude`` is the parameter (the input is reached by a wire).

``out`` is Good non-cascade (128). The input's status is not read (the SGGN1 amplitude is a
parameter reference, not a connection with status). Non-finite values (issue 11 point 1): an
amplitude input that is ±inf or beyond the float32 range of a DeltaV parameter (about 3.4e38,
so ``1e308``) is Bad input: the wave goes on with the last usable amplitude (the parameter if
none was given) and ``out`` is Bad (0) for that scan; the next usable amplitude restores it.
The ``amplitude`` and ``bias`` parameters are float32 values (within ±3.4028235e38), so ``out``
is always finite; should it leave the float32 range (bias and amplitude both near it), it is
Bad too. The scan time dt enters only through c, and only when ``period`` (seconds) is given.
A scan longer than 1e15 periods (where the position within the cycle is lost in rounding)
restarts the cycle at 0.

Before the first scan (issue 11 point 8) ``out`` shows the first scan's value for the
amplitude as given (else the parameter): bias + A·wave(phase), e.g. +A for the default square
wave.

Options for the spec's [A]/[?] points
-------------------------------------

Each is a parameter; the default is the spec's choice (spec 6.5 [A], the SGGN1 configuration is
unknown, spec 8 item 5).

* ``waveform`` = ``square`` (spec 6.5 [A]); ``sine`` and ``triangle`` are the spec's
  alternatives.
* ``half_period_scans`` = 1: the square wave alternates every scan (spec 6.5 [A]: "half-period
  = N scans (configurable, default 1 scan)"), at any scan time. ``period`` (s, not given by
  default) sets a period in seconds instead: the true period is unknown ([?]; RESET_TIME may
  set it, spec 6.5). Before 2026-12-07 the default was ``period`` = 2 s, one scan only at a
  1 s scan (at 0.1 s the wave held +A for ten scans).
* ``bias`` = 0 (spec 6.5 [A]: zero bias).
* ``phase`` = 0°: the wave starts with + (spec 6.5 [A]); 180° starts with -.
* ``amplitude`` input: NaN = the ``amplitude`` parameter; wire DITHER_AMP to it for the
  spec's reading (spec 6.5 [A]).

Example
-------

Python::

    import loopworks
    gen = loopworks.create_block("deltav.sggn", amplitude=0.3, period=2.0)
    print([gen.step(1.0)["out"].value for _ in range(4)])    # [0.3, -0.3, 0.3, -0.3]

The seed's module (SGGN1 first, then the compensator)::

    from loopworks import Module, create_block
    m = Module({"sggn1": create_block("deltav.sggn", period=2.0),
                "comp": create_block("deltav.stick_slip", resolution=0.5, deadband=0.2)},
               wires={"sggn1.amplitude": "comp.dither_amp", "comp.dither_out": "sggn1.out"},
               inputs={"comp": {"signal_in": 40.0, "sp": 50.0, "pv": 50.0, "comp_start": 1.0}})
    r = m.run(4.0, 1.0)
    print(r.values["sggn1.out"])   # 0, -0.3, 0.3, -0.3 (float32 0.30000001): one-scan lag

Replay (``loopworks replay deltav.sggn gen.csv -p waveform=triangle -p period=4``), with
``gen.csv``::

    t,amplitude
    0,2
    1,2
    2,nan
    3,nan

gives ``out`` 0, 2, 0, -1 (the last two scans use the parameter, amplitude 1).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

from loopworks.blocks.block import Block
from loopworks.blocks.kernel import FloatArray, IntArray, primitive
from loopworks.blocks.layout import index
from loopworks.blocks.params import Param, Port
from loopworks.blocks.registry import register
from loopworks.blocks.status import BAD, GOOD_NC
from loopworks.errors import ParameterError
from loopworks.vendors.deltav.calc import FLOAT32_MAX, FLOAT32_OVERFLOW

SQUARE, SINE, TRIANGLE = 0.0, 1.0, 2.0  # values of the waveform coefficient

INPUTS = (
    Port("amplitude", math.nan, "out",
         "amplitude, e.g. wired from the compensator's dither_amp; NaN = the parameter; "
         "±inf or beyond float32 = Bad: the last usable amplitude, out Bad (spec 6.5)"),
)
OUTPUTS = (
    Port("out", 0.0, "out", "bias + amplitude·wave (spec 6.5: DITHER_OUT)", status=True),
)
#: the coefficient array p (coefficients()); phase in cycles
#: period (s, 0: counted in scans) and per_scan (cycles a scan, 1/(2·half_period_scans))
COEFFS = ("waveform", "amplitude", "period", "per_scan", "bias", "phase")
#: the state array x: the position in the cycle, 1 once started, the last usable amplitude
STATES = ("cycle", "started", "amplitude")
P, X, U, Y = index(COEFFS, "P"), index(STATES, "X"), index(INPUTS, "U"), index(OUTPUTS, "Y")

EDGE_TOLERANCE = 1e-9  # cycles: positions this close to an edge are on it
MAX_CYCLES = 1e15  # beyond this many cycles in one scan the position within a cycle is lost


@primitive
def wave(shape: float, cycle: float, phase: float) -> float:
    """The unit wave (-1..1) at position ``cycle`` (0 <= c < 1) advanced by ``phase``
    (cycles): s = frac(c + phase), then square, sine or triangle (module docstring)."""
    s = cycle + phase
    s = s - math.floor(s + EDGE_TOLERANCE)
    if s < 0.0:
        s = 0.0
    if shape == SQUARE:
        return 1.0 if s < 0.5 - EDGE_TOLERANCE else -1.0
    if shape == SINE:
        return math.sin(2.0 * math.pi * s)
    if s <= 0.25:
        return 4.0 * s
    if s <= 0.75:
        return 2.0 - 4.0 * s
    return 4.0 * s - 4.0


@primitive
def usable(amplitude: float) -> bool:
    """True when an amplitude input is a value a DeltaV (float32) parameter can hold: finite
    and within the float32 range. NaN is not an amplitude at all ("not given")."""
    return abs(amplitude) < FLOAT32_OVERFLOW


def sggn_kernel(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                y: FloatArray, ys: IntArray) -> None:
    """One scan of the signal generator (equations in the module docstring)."""
    if x[X.started] == 0.0:
        x[X.started] = 1.0
        cycle = 0.0
    else:
        cycle = float(x[X.cycle]) + (dt / float(p[P.period]) if p[P.period] > 0.0
                                     else float(p[P.per_scan]))
        if not cycle < MAX_CYCLES:  # dt/period beyond float resolution (or NaN): restart
            cycle = 0.0
        cycle = cycle - math.floor(cycle + EDGE_TOLERANCE)
        if cycle < EDGE_TOLERANCE:  # within the tolerance of a whole cycle: the cycle start
            cycle = 0.0
    x[X.cycle] = cycle
    amplitude = float(u[U.amplitude])
    status = GOOD_NC
    if math.isnan(amplitude):  # not given: the parameter
        amplitude = float(p[P.amplitude])
    elif not usable(amplitude):  # ±inf or beyond float32: Bad input, the last usable one
        amplitude = float(x[X.amplitude])
        status = BAD
    x[X.amplitude] = amplitude
    out = float(p[P.bias]) + amplitude * wave(p[P.waveform], cycle, p[P.phase])
    y[Y.out] = out
    ys[Y.out] = status if usable(out) else BAD


@register
class SGGN(Block):
    """DeltaV signal generator: square, sine or triangle wave; the compensator's dither."""

    kind = "deltav.sggn"
    summary = ("DeltaV signal generator (square/sine/triangle; amplitude, period, bias), the "
               "stick-slip compensator's dither source SGGN1")
    kernel = staticmethod(sggn_kernel)

    PARAMS: ClassVar[tuple[Param, ...]] = (
        Param("waveform", "square", "", "wave shape; square is the dither of the seed's "
              "reading [A] (spec 6.5)", "choice", choices=("square", "sine", "triangle")),
        Param("amplitude", 1.0, "out",
              "peak amplitude A (the amplitude input overrides it when not NaN); a float32 "
              "(spec 6.5)", lo=-FLOAT32_MAX, hi=FLOAT32_MAX, lo_open=False, hi_open=False),
        Param("half_period_scans", 1, "scans",
              "half-period in scans: 1 alternates the square wave every scan [A] (spec 6.5)",
              "int", lo=1.0, hi=1e9, lo_open=False, hi_open=False),
        Param("period", None, "s", "period in seconds instead of half_period_scans (the true "
              "period is unknown [?], spec 6.5)", lo=0.0,
              default_text="2·half_period_scans scans"),
        Param("bias", 0.0, "out", "offset added to the wave; 0 [A]; a float32 (spec 6.5)",
              lo=-FLOAT32_MAX, hi=FLOAT32_MAX, lo_open=False, hi_open=False),
        Param("phase", 0.0, "deg", "phase advance; 0 starts with + [A] (spec 6.5)",
              lo=0.0, hi=360.0, lo_open=False),
    )
    INPUTS: ClassVar[tuple[Port, ...]] = INPUTS
    OUTPUTS: ClassVar[tuple[Port, ...]] = OUTPUTS
    COEFFS: ClassVar[tuple[str, ...]] = COEFFS
    STATES: ClassVar[tuple[str, ...]] = STATES

    def coefficients(self) -> dict[str, Any]:
        prm: dict[str, Any] = self.params
        shape = {"square": SQUARE, "sine": SINE, "triangle": TRIANGLE}[prm["waveform"]]
        if prm["period"] is not None and "half_period_scans" in self.given:
            raise ParameterError(f"{self.kind}: give 'period' (s) or 'half_period_scans', not "
                                 f"both (period = {prm['period']:g} s, half_period_scans = "
                                 f"{prm['half_period_scans']})")
        return {"waveform": shape, "amplitude": float(prm["amplitude"]),
                "period": 0.0 if prm["period"] is None else float(prm["period"]),
                "per_scan": 0.5 / float(prm["half_period_scans"]), "bias": float(prm["bias"]),
                "phase": float(prm["phase"]) / 360.0}

    def initial_state(self) -> list[float]:
        """At the cycle start, not started; the last usable amplitude is the parameter."""
        x = [0.0] * self.n_x
        x[X.amplitude] = float(self.p[P.amplitude])
        return x

    def initial_outputs(self) -> list[float]:
        """Before the first scan (issue 11 point 8) ``out`` is the first scan's value for the
        amplitude as given (else the parameter): bias + A·wave(phase)."""
        amplitude = float(self.u[U.amplitude])
        if not usable(amplitude):  # NaN (not given), or not a usable value
            amplitude = float(self.x[X.amplitude])
        return [float(self.p[P.bias])
                + amplitude * wave(self.p[P.waveform], 0.0, self.p[P.phase])]

    @classmethod
    def split_table(cls, table: Mapping[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
        """In a scenario table ``amplitude`` is the parameter; the input is for wires."""
        return dict(table), {}
