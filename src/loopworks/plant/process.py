r"""Process models (blocks with input ``u`` and output ``y``).

Kinds: ``process.first_order`` (a plain lag, the plant of the built-in closed loop),
``process.fopdt``, ``process.sopdt`` and ``process.ipdt`` (first order, second order and
integrating plus dead time) and ``process.tf`` (a general transfer function in s or z).

Timing, for every kind: scan k covers (t_{k-1}, t_k] with t_k - t_{k-1} = dt; the input of the
scan, u_k, is held over it (zero-order hold) and the output is the plant's output at the end of
the scan, y_k = y(t_k). So a controller that runs after the process in the same scan sees this
scan's value. The discretisations are exact for such an input (Åström & Wittenmark,
*Computer-Controlled Systems*, 3rd ed., ch. 2: sampling a continuous-time system, and sampling
a system with time delay); plant-and-tuning section 6 item 3 asks for exact ZOH discretisation
of FOPDT, SOPDT and integrating plants [I].

``process.first_order``: a first-order lag::

    T·dy/dt = K·u - y      →   y_k = y_{k-1} + (1 - e^(-dt/T))·(K·u_k - y_{k-1})

(exact for an input held over the scan; Åström & Wittenmark, *Computer-Controlled Systems*,
ch. 2). An unusable input (see Bad input below) freezes the state and marks ``y`` Bad (no
input, no trustworthy output).

### Plants with dead time

``process.fopdt``   G(s) = K·e^(-θs) / (T·s + 1)

``process.sopdt``   G(s) = K·e^(-θs) / ((T1·s + 1)(T2·s + 1)), two real time constants
(``time_constant_1`` = T1, ``time_constant_2`` = T2, in either order; T1 = T2 allowed). This
is the process-control parametrisation (SIMC's SOPDT, plant-and-tuning 3.6); an underdamped
plant is a ``process.tf`` with den ``1/ωn², 2ζ/ωn, 1``.

``process.ipdt``    G(s) = K·e^(-θs) / s, K in y per (u·s): dy/dt = K·(u(t - θ) - u0)

``process.tf``      G(s) = e^(-θs)·N(s)/D(s) (``domain = "s"``) or
G(z) = z^(-n)·N(z)/D(z) (``domain = "z"``, n = θ/sample_time); N and D are coefficient lists
in descending powers (``num``, ``den``: text such as ``"1, 2"`` for s + 2, or a Python/TOML
list of numbers), proper (deg N ≤ deg D), order deg D ≤ ``max_order``.

### Operating point: starting at a chosen steady state

Every kind with dead time is written around an operating point (u0, y0)::

    y(t) = y0 + G(s)·(u(t) - u0)

``u0`` (default 0) is the input the plant has been receiving for ever: the delay line starts
full of u0, the ``u`` input starts at u0, and the states start at the equilibrium, so an
undisturbed block stays at y0. ``y0`` is the output at that steady state; left out it is the
plant's own steady state: K·u0 for fopdt/sopdt, G(0)·u0 (s) or G(1)·u0 (z) for tf, and 0 for
ipdt and integrating transfer functions. For the integrating plants u0 is the balancing input
(the input bias): the level moves with u - u0.

### Equations (per piece of constant delayed input w over a duration h)

fopdt and sopdt run in absolute form with the bias b = y0 - K·u0 (0 unless y0 is given), so
that ``process.fopdt`` with θ = 0 and y0 = K·u0 is ``process.first_order`` bit for bit: both
call the same ``lag_step`` primitive with the same arguments::

    target = K·w + b
    fopdt:  y ← lag_step(y, target, h, T) = y + (1 - e^(-h/T))·(target - y)
    sopdt:  x1 ← lag_step(x1, target, h, T1)
            y  ← lag_step(y, target, h, T2) + (x1_old - target)·g,
            g = T1·(e^(-h/T1) - e^(-h/T2))/(T1 - T2)
              = (h/T2)·e^(-min(a, b))·φ(-|a - b|),  a = h/T1, b = h/T2, φ(z) = (e^z - 1)/z

(the second lag's exact response: its own lag to the target plus the first lag's transient
passing through it; the φ form has no cancellation when T1 ≈ T2 and gives (h/T)·e^(-h/T) at
T1 = T2). T2 = 0 makes sopdt the fopdt, T = 0 a pure gain. ipdt: y ← y + K·(w - u0)·h.

``process.tf`` is realised with ``scipy.signal.tf2ss`` (controller canonical form,
ξ' = Aξ + B·w, y = y0 + Cξ + D·w, w = u - u0) and discretised once, at construction, with
``scipy.signal.cont2discrete(method="zoh")`` at the scan time ``sample_time``. With
θ = (n + f)·dt (n whole scans, 0 ≤ f < 1) the delayed input during a scan is w_{k-n-1} for
the first f·dt and w_{k-n} for the rest (the modified z-transform)::

    ξ_k = Φ·ξ_{k-1} + Γ1·w_{k-n-1} + Γ0·w_{k-n}
    y_k = y0 + C·ξ_k + D·w_{k-n}
    Φ = e^(A·dt),  Γ0 = Γ((1-f)·dt),  Γ1 = e^(A(1-f)dt)·Γ(f·dt),  Γ(h) = ∫_0^h e^(As) ds·B

(f = 0: Γ1 = 0, Γ0 = Γ(dt)). The kernel runs it as y_k = y0 + CΦ·ξ_{k-1} + CΓ1·w_{k-n-1} +
(CΓ0 + D)·w_{k-n}, then updates ξ. A z-domain transfer function is the literal difference
equation over the scan index, y_k = y0 + C·ξ_{k-1} + D·w_{k-n}, ξ_k = A·ξ_{k-1} + B·w_{k-n}
(Y(z) = G(z)·U(z)): the ZOH equivalent of a strictly proper G(s) from a textbook table,
which carries one sample of delay, behaves as the same G(s) with θ increased by one scan;
z·G_zoh(z) behaves as G(s) itself.

### Dead time: an exact delay line

The line records the input of each scan (after bad-input handling) with the scan's duration.
A scan integrates the model over the delayed input u(t - θ), t in (t_{k-1}, t_k]: the pieces
of the recorded inputs that fall in (t_{k-1} - θ, t_k - θ], oldest first, each with the
exact step above. So the output is the exact continuous-time response for any θ and any
sequence of dt (a replay's ``t`` column may vary):

- θ = n·dt (a whole number of scans): one piece, y_k = model(u_{k-n}) exactly; in particular
  with T = 0, y_k = K·u_{k-n}, and with θ = 0 the model sees u_k;
- θ = (n + f)·dt: two pieces, f·dt of u_{k-n-1} then (1 - f)·dt of u_{k-n}; a plant with no
  lag (T = 0) shows u_{k-n}, the held input at t_k - θ;
- before the first input reaches the plant, the line gives u0;
- piece boundaries within 1e-9·(θ + dt) s of a scan boundary are taken as on it (rounding of
  sums of dt; the last piece always ends exactly at t_k).

While every scan the window reaches lasted the current dt (a module's fixed scan), the pieces
follow from θ/dt directly (constant work per scan); after a change of dt the line is walked
back through the recorded durations until the new dt has filled the window (work grows with
θ/dt). Both are the exact response; they may differ in the last bits.

``delay_capacity`` is the number of past scans the line keeps (default 1000; memory: two
floats per scan). It must cover the dead time: θ ≤ delay_capacity·dt. ``step()`` raises an
InputError naming ``delay_capacity`` when a dt is too small for it; a module refuses to run
at such a dt, and a replay refuses a file that has one, naming its first such row. The
kernel called directly (a plan, a live loop) skips a scan whose window reaches past the kept
history (only once ``delay_capacity`` scans have been recorded; until then the missing
history is u0): the plant and the line stay as they were and ``y`` keeps its value with
status Bad: configuration error (4). ``process.tf`` knows its scan time, so it checks
n (+1 when f > 0) ≤ ``delay_capacity`` at construction (ParameterError).

Changing ``dead_time`` with ``set_params`` between scans is exact (the line holds the recorded
times); ``delay_capacity`` and ``max_order`` fix the state layout and cannot be changed. fopdt
and sopdt keep their output and move towards the new K·u + b; process.tf re-discretises and
keeps ξ, the deviation from the steady state at u0, so with ``y0`` left at its default (the
new G(0)·u0) a change of gain moves the output at once, as if the plant had always had it.

### process.tf and dt: a fixed ``sample_time``

The scan time dt arrives with each scan, but the discretisation (scipy, in Python) cannot run
inside a kernel, and a module or replay calls the kernel directly. So ``process.tf`` takes its
scan time as the parameter ``sample_time`` (required; for ``domain = "z"`` it is the transfer
function's own sample time) and runs only at that dt (relative tolerance 1e-6; such a scan is
taken as exactly ``sample_time``): ``step()`` raises an InputError naming ``sample_time`` for
another dt, a module refuses to run at one, and a replay refuses a file that has one, naming
its first such row (data row and time); the kernel called directly at another dt skips the
scan with status Bad: configuration error (4). A z-domain dead time must be a whole number
of samples (ParameterError naming ``dead_time`` otherwise). fopdt, sopdt and ipdt compute
their exact steps from each scan's dt and need no such parameter.

### Bad input

A NaN, ±inf or Bad-status ``u`` marks ``y`` Bad (non-specific, 0) for that scan; Uncertain
inputs are used (``y`` Good). So is an input the model's float arithmetic cannot carry
(issue 11 point 1): one whose contribution to the model, K·(u - u0) (first_order: K·u; tf:
(u - u0) times its largest input coefficient), exceeds ``MODEL_RANGE`` = 1e150 in magnitude.
Such a value (1e308, say) is a fault, not a signal: kept in the delay line or the state it
would overflow a later scan (1e308 + 1e308), so it is refused where it enters. What the plant
does meanwhile is the option ``bad_input``:

- ``hold_input`` (default; issue 5: "hold the last input and mark y Bad"): the plant keeps
  running on the last good input (u0 before any), which also enters the delay line, so the
  output keeps moving as the real process would with the actuator held;
- ``freeze``: the scan is skipped (state and line unchanged, ``y`` holds), as
  ``process.first_order`` does.

A scan whose result would still leave the float range (an integrator driven past ±1.8e308, an
unstable transfer function that has run away, or parameters near the float range) is skipped
the same way: state and line unchanged, ``y`` holds with status Bad (non-specific). No output
or state is ever NaN or infinite.

### State (``state_dict()``, ``load_state()``)

fopdt/sopdt/ipdt: ``y``; ``lag1`` (sopdt's first lag; equal to y for fopdt, 0 for ipdt);
``u_held`` (the last good input); ``line``, the delay line as one list of
4 + 2·delay_capacity numbers: head (the ring slot of the newest entry), count (the entries
recorded), run_dt and run_len (the newest run_len entries lasted run_dt), then the inputs of
the ring slots and their durations. process.tf: ``y``, ``u_held`` and ``xi_line``: the state
vector ξ (max_order numbers, deviation from the steady state), the scratch of the update
(max_order, no meaning between scans), then the line. A state saved by an earlier loopworks,
with the line as separate names (``line_head``, ``line_u_0``, ...), is refused with an
InputError.

### Options and decisions

These points interpret issue 5 and plant-and-tuning section 6 item 3 (tagged [I] there); they
are not vendor facts. Each is named and documented:

- ``bad_input`` = ``hold_input`` | ``freeze`` (above);
- ``delay_capacity`` = 1000 scans (above); non-multiple dead times are exact (above);
- sopdt parametrisation: two time constants (above);
- ``process.tf``: fixed ``sample_time`` instead of re-discretising when dt changes; the
  z-domain transfer function is the literal difference equation (above);
- ``max_order`` = 8: the transfer-function order the state reserves room for.

Defaults are the spec's reference plants: fopdt K = 1, T = 10 s, θ = 2 s (plant-and-tuning 2.8,
3.2, 5.1), ipdt K = 0.1 /s, θ = 2 s (plant-and-tuning 3.2, 5.1).

### Worked example

Python (the unit step reaches the output after θ = 2 s, then y = 1 - e^(-(t-2)/10))::

    import loopworks
    p = loopworks.create_block("process.fopdt", gain=1.0, time_constant=10.0, dead_time=2.0)
    ys = [p.step(0.5, u=1.0)["y"].value for _ in range(8)]
    # [0, 0, 0, 0, 0.0487706, 0.0951626, 0.139292, 0.181269]

    tf = loopworks.create_block("process.tf", num="1", den="10, 1", sample_time=0.5)
    tf.step(0.5, u=1.0)["y"].value        # 0.0487706 = 1 - e^(-0.05)

Replay (``loopworks replay process.ipdt ramp.csv -p gain=0.1 -p dead_time=1``), ramp.csv::

    t,u
    0,1
    0.5,1
    1.0,1
    1.5,1
    2.0,1

gives y = 0, 0, 0.05, 0.1, 0.15: the first row's scan takes its dt from the second row, so
the input starts at t = -0.5 s, reaches the integrator 1 s later, and the level then ramps at
0.1/s.
"""

from __future__ import annotations

import functools
import math
import re
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from loopworks.blocks import layout
from loopworks.blocks.block import Block, Outputs
from loopworks.blocks.kernel import FloatArray, IntArray, primitive
from loopworks.blocks.layout import Array, index
from loopworks.blocks.params import Param, Port, fmt_value
from loopworks.blocks.primitives import finite, lag_step
from loopworks.blocks.registry import register
from loopworks.blocks.status import BAD, BAD_CONFIGURATION_ERROR, BAD_NON_SPECIFIC, GOOD_NC
from loopworks.errors import InputError, ParameterError

# Every process kind has one input u and one output y, so one U and one Y serve them all
# (PROCESS_INPUTS and PROCESS_OUTPUTS below are these ports with an operating point)
FIRST_ORDER_INPUTS = (Port("u", 0.0, "u", "process input", status=True),)
FIRST_ORDER_OUTPUTS = (Port("y", 0.0, "y", "process output", status=True),)
#: process.first_order: the coefficient array p and the state array x
FIRST_ORDER_COEFFS = ("gain", "tau", "y0")
FIRST_ORDER_STATES = ("y",)
PF, XF = index(FIRST_ORDER_COEFFS, "PF"), index(FIRST_ORDER_STATES, "XF")
U, Y = index(FIRST_ORDER_INPUTS, "U"), index(FIRST_ORDER_OUTPUTS, "Y")

#: the largest magnitude of an input's contribution to a model (module docstring, Bad input)
MODEL_RANGE = 1e150


@primitive
def input_good(value: float, status: int, offset: float, scale: float) -> bool:
    """A usable input: finite, its status not Bad (Uncertain is used), and its contribution
    scale·(value - offset) within ±MODEL_RANGE (module docstring, Bad input)."""
    return (finite(value) and (status & 0xC0) != BAD
            and abs(scale * (value - offset)) <= MODEL_RANGE)


def first_order_kernel(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                       y: FloatArray, ys: IntArray) -> None:
    """One scan of T·dy/dt = K·u - y (module docstring). The state stays a weighted mean of
    y0 and targets K·u within MODEL_RANGE, so it cannot overflow."""
    if not input_good(u[U.u], us[U.u], 0.0, p[PF.gain]):
        ys[Y.y] = BAD_NON_SPECIFIC
    else:
        x[XF.y] = lag_step(x[XF.y], p[PF.gain] * u[U.u], dt, p[PF.tau])
        ys[Y.y] = GOOD_NC
    y[Y.y] = x[XF.y]


@register
class FirstOrder(Block):
    """First-order lag process: T·dy/dt = K·u - y."""

    kind = "process.first_order"
    kernel = staticmethod(first_order_kernel)
    PARAMS: ClassVar[tuple[Param, ...]] = (
        Param("gain", 1.0, "y/u", "steady-state gain K", lo=-math.inf),
        Param("time_constant", 10.0, "s", "time constant T; 0 = no lag", lo=0.0,
              lo_open=False),
        Param("y0", 0.0, "y", "initial output"),
    )
    INPUTS: ClassVar[tuple[Port, ...]] = FIRST_ORDER_INPUTS
    OUTPUTS: ClassVar[tuple[Port, ...]] = FIRST_ORDER_OUTPUTS
    COEFFS: ClassVar[tuple[str, ...]] = FIRST_ORDER_COEFFS
    STATES: ClassVar[tuple[str, ...]] = FIRST_ORDER_STATES

    def coefficients(self) -> dict[str, float]:
        return {"gain": float(self.params["gain"]), "tau": float(self.params["time_constant"]),
                "y0": float(self.params["y0"])}

    def initial_state(self) -> list[float]:
        x = [0.0] * self.n_x
        x[XF.y] = self.p[PF.y0]
        return x

    def reset(self) -> None:
        super().reset()
        self.y[Y.y] = self.p[PF.y0]


# ---------------------------------------------------------------------------------------------
# Shared primitives: the input check, the delay line and the exact lag steps

#: piece boundaries closer than DELAY_TOL·(θ + dt) to a scan boundary are taken as on it
DELAY_TOL = 1e-9
#: process.tf accepts a scan time within DT_RTOL·sample_time of its sample_time
DT_RTOL = 1e-6
HOLD_INPUT, FREEZE = 0.0, 1.0


# The delay line lives in the state array from index ``base``: a ring of the last ``cap``
# scans' inputs and durations. ``head`` is the slot of the newest entry, ``count`` how many
# are recorded (at most cap); the newest ``run_len`` entries all lasted exactly ``run_dt``
# (the fast path); ``data`` holds value_0 .. value_{cap-1}, then dt_0 .. dt_{cap-1}.
LINE_ENTRIES = ("head", "count", "run_dt", "run_len",
                Array("data", lambda prm: 2 * int(prm["delay_capacity"]), "2·delay_capacity"))
LINE = index(LINE_ENTRIES, "Line")
# The line primitives serve two kinds' kernels, whose lines start at different indices (XD.line,
# XT.xi_line + 2·max_order): they take the start as ``base`` and read the offsets within the
# line as plain ints taken from LINE (test_layout accepts in a kernel only the layouts of its
# kind's own four declarations, and LINE is a sub-layout within one of their entries).
LINE_HEAD = LINE.head
LINE_COUNT = LINE.count
LINE_RUN_DT = LINE.run_dt
LINE_RUN_LEN = LINE.run_len
LINE_DATA = LINE.data


def line_size(cap: int) -> int:
    """The number of floats a line of ``cap`` scans takes (4 + 2·cap)."""
    return layout.size(LINE_ENTRIES, {"delay_capacity": cap})


@primitive
def line_slot(x: FloatArray, base: int, cap: int, j: int) -> int:
    """The ring slot of the entry j scans back (j = 1: the previous scan), j ≤ count."""
    slot = int(x[base + LINE_HEAD]) - (j - 1)
    if slot < 0:
        slot += cap
    return slot


@primitive
def line_value(x: FloatArray, base: int, cap: int, j: int, fill: float) -> float:
    """The input recorded j scans back; ``fill`` (u0) beyond the recorded history."""
    if j > int(x[base + LINE_COUNT]):
        return fill
    return float(x[base + LINE_DATA + line_slot(x, base, cap, j)])


@primitive
def line_duration(x: FloatArray, base: int, cap: int, j: int) -> float:
    """The duration of the scan j back; infinite beyond the history (u0 for ever before)."""
    if j > int(x[base + LINE_COUNT]):
        return math.inf
    return float(x[base + LINE_DATA + cap + line_slot(x, base, cap, j)])


@primitive
def line_push(x: FloatArray, base: int, cap: int, value: float, dt: float) -> None:
    """Record this scan's input and duration, overwriting the oldest entry when full."""
    head = int(x[base + LINE_HEAD]) + 1
    if head >= cap:
        head = 0
    x[base + LINE_HEAD] = head
    x[base + LINE_DATA + head] = value
    x[base + LINE_DATA + cap + head] = dt
    if x[base + LINE_COUNT] < cap:
        x[base + LINE_COUNT] = x[base + LINE_COUNT] + 1.0
    if dt == x[base + LINE_RUN_DT]:
        if x[base + LINE_RUN_LEN] < cap:
            x[base + LINE_RUN_LEN] = x[base + LINE_RUN_LEN] + 1.0
    else:
        x[base + LINE_RUN_DT] = dt
        x[base + LINE_RUN_LEN] = 1.0


def line_initial(cap: int, u0: float) -> FloatArray:
    """An empty line (the history before it is u0): head at the last slot, no entries. Read
    only, made once per (cap, u0) (-0.0 apart from 0.0): every reset copies it into a
    block's state."""
    return _line_initial(cap, u0, math.copysign(1.0, u0))


@functools.lru_cache(maxsize=64)
def _line_initial(cap: int, u0: float, sign: float) -> FloatArray:
    data = np.zeros(2 * cap)
    data[:cap] = u0
    line = layout.pack(LINE_ENTRIES, {"head": cap - 1.0, "count": 0.0, "run_dt": 0.0,
                                      "run_len": 0.0, "data": data},
                       "delay line", {"delay_capacity": cap})
    line.flags.writeable = False
    return line


@primitive
def phi(z: float) -> float:
    """(e^z - 1)/z, 1 at z = 0 (accurate near 0 through expm1)."""
    if z == 0.0:
        return 1.0
    return math.expm1(z) / z


@primitive
def lag2_gain(h: float, t1: float, t2: float) -> float:
    """g = T1·(e^(-h/T1) - e^(-h/T2))/(T1 - T2) for T1, T2 > 0, written without cancellation:
    (h/T2)·e^(-min(a, b))·φ(-|a - b|) with a = h/T1, b = h/T2 (module docstring)."""
    a = h / t1
    b = h / t2
    return b * math.exp(-min(a, b)) * phi(-abs(a - b))


# fopdt, sopdt and ipdt: one kernel. p: the model (LAG or INTEGRATING), K, T1, T2, u0, the
# bias b = y0 - K·u0, θ, delay_capacity, bad_input (HOLD_INPUT or FREEZE), y0
DEAD_TIME_COEFFS = ("model", "gain", "t1", "t2", "u0", "bias", "theta", "cap", "bad_mode",
                    "y_init")
LAG, INTEGRATING = 0.0, 1.0
# x: output, first lag (sopdt; = y for fopdt, 0 for ipdt), last good input, the delay line
DEAD_TIME_STATES = ("y", "lag1", "u_held",
                    Array("line", lambda prm: line_size(int(prm["delay_capacity"])),
                          "4 + 2·delay_capacity"))
PD, XD = index(DEAD_TIME_COEFFS, "PD"), index(DEAD_TIME_STATES, "XD")


@primitive
def lag2_step(x: FloatArray, target: float, h: float, t1: float, t2: float) -> None:
    """Exact step of two lags in series towards a held ``target``: x[XD.lag1] (T1) feeds
    x[XD.y] (T2); T2 = 0: one lag (x[XD.y] = x[XD.lag1]); T1 = 0: the target feeds the
    second."""
    x1 = x[XD.lag1]
    x1_new = lag_step(x1, target, h, t1)
    if t2 <= 0.0:
        x[XD.y] = x1_new
    elif t1 <= 0.0:
        x[XD.y] = lag_step(x[XD.y], target, h, t2)
    else:
        x[XD.y] = lag_step(x[XD.y], target, h, t2) + (x1 - target) * lag2_gain(h, t1, t2)
    x[XD.lag1] = x1_new


@primitive
def plant_advance(p: FloatArray, x: FloatArray, w: float, h: float) -> None:
    """Advance the plant over a duration h of constant delayed input w (exact)."""
    if p[PD.model] == INTEGRATING:
        x[XD.y] = x[XD.y] + p[PD.gain] * (w - p[PD.u0]) * h
    else:
        lag2_step(x, p[PD.gain] * w + p[PD.bias], h, p[PD.t1], p[PD.t2])


def dead_time_kernel(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                     y: FloatArray, ys: IntArray) -> None:
    """One scan of fopdt/sopdt/ipdt: the delayed input's pieces in (t_{k-1} - θ, t_k - θ],
    oldest first, each an exact step (module docstring)."""
    good = input_good(u[U.u], us[U.u], p[PD.u0], p[PD.gain])
    if not good and p[PD.bad_mode] == FREEZE:
        y[Y.y] = x[XD.y]
        ys[Y.y] = BAD_NON_SPECIFIC
        return
    v = u[U.u] if good else x[XD.u_held]
    y_old = x[XD.y]
    x1_old = x[XD.lag1]
    cap = int(p[PD.cap])
    theta = p[PD.theta]
    u0 = p[PD.u0]
    count = int(x[XD.line + LINE_COUNT])
    # Fast path: every scan the window touches lasted this dt, so θ = (n + f)·dt gives the
    # pieces directly: f·dt of the input n + 1 scans back, then (1 - f)·dt of n back.
    ratio = theta / dt
    run = x[XD.line + LINE_RUN_LEN]
    if dt == x[XD.line + LINE_RUN_DT] and ratio < cap + 2.0:
        n = math.floor(ratio + DELAY_TOL * (ratio + 1.0))
        f = ratio - n
        if f <= DELAY_TOL * (ratio + 1.0):
            f = 0.0
        need = n + 1 if f > 0.0 else n
        if need <= run or run >= count:
            if need > count and count >= cap:  # that part of the history is no longer kept
                y[Y.y] = x[XD.y]
                ys[Y.y] = BAD_CONFIGURATION_ERROR
                return
            if f > 0.0:
                plant_advance(p, x, line_value(x, XD.line, cap, n + 1, u0), f * dt)
                plant_advance(p, x, v if n == 0 else line_value(x, XD.line, cap, n, u0),
                              dt - f * dt)
            else:
                plant_advance(p, x, v if n == 0 else line_value(x, XD.line, cap, n, u0), dt)
            end_scan(x, y, ys, v, dt, cap, good, y_old, x1_old)
            return
    # General path (dt has varied): walk the recorded durations.
    end = theta + dt
    tol = DELAY_TOL * end
    # 1. the oldest entry reaching into the window: entry j (0 = this scan) covers the ages
    #    [a, a + d] before t_k; the window is [θ, θ + dt].
    j = 0
    a = 0.0
    d = dt
    while a + d < end - tol:
        j += 1
        a += d
        if j > count and count >= cap:  # that part of the history is no longer kept
            y[Y.y] = x[XD.y]
            ys[Y.y] = BAD_CONFIGURATION_ERROR
            return
        d = line_duration(x, XD.line, cap, j)
    # 2. the pieces, oldest first; the last one ends exactly at t_k - θ
    remaining = dt
    while True:
        last = j == 0 or a <= theta + tol
        w = v if j == 0 else line_value(x, XD.line, cap, j, u0)
        if last:
            plant_advance(p, x, w, remaining)
            break
        h = min(d, end - a)
        if h > remaining:
            h = remaining
        if h > 0.0:
            plant_advance(p, x, w, h)
            remaining -= h
        j -= 1
        d = dt if j == 0 else line_duration(x, XD.line, cap, j)
        a -= d
    end_scan(x, y, ys, v, dt, cap, good, y_old, x1_old)


@primitive
def end_scan(x: FloatArray, y: FloatArray, ys: IntArray, v: float, dt: float, cap: int,
             good: bool, y_old: float, x1_old: float) -> None:
    """Finish a scan of fopdt/sopdt/ipdt: record the input in the line and publish y; a
    result outside the float range skips the scan instead (module docstring, Bad input)."""
    if not (finite(x[XD.y]) and finite(x[XD.lag1])):
        x[XD.y] = y_old
        x[XD.lag1] = x1_old
        y[Y.y] = y_old
        ys[Y.y] = BAD_NON_SPECIFIC
        return
    if good:
        x[XD.u_held] = v
    line_push(x, XD.line, cap, v, dt)
    y[Y.y] = x[XD.y]
    ys[Y.y] = GOOD_NC if good else BAD_NON_SPECIFIC


# ---------------------------------------------------------------------------------------------
# Blocks

#: the ports of the kinds with an operating point (the index U, Y of first_order's)
PROCESS_INPUTS = (Port("u", 0.0, "u", "process input (starts at u0)", status=True),)
PROCESS_OUTPUTS = (Port("y", 0.0, "y", "process output (starts at y0)", status=True),)


def _common_params(u0_meaning: str, y0_meaning: str, y0_default: str) -> tuple[Param, ...]:
    return (
        Param("dead_time", 2.0, "s", "dead time θ; exact for any θ and dt (a delay line)",
              lo=0.0, lo_open=False),
        Param("u0", 0.0, "u", u0_meaning),
        Param("y0", None, "y", y0_meaning, default_text=y0_default),
        Param("delay_capacity", 1000, "scans", "past scans the delay line keeps; needs "
              "dead_time ≤ delay_capacity·dt", type="int", lo=1, hi=10_000_000, lo_open=False,
              hi_open=False),
        Param("bad_input", "hold_input", "", "on a NaN/inf/Bad u: keep running on the last "
              "good input (hold_input) or skip the scan (freeze); y is Bad either way",
              type="choice", choices=("hold_input", "freeze")),
    )


class _LineProcess(Block):
    """Shared machinery of the plants with a delay line: a per-instance state layout sized
    by ``delay_capacity`` (its last entry), the steady-state start, and the dt checks of
    ``step()``."""

    FIXED_LAYOUT = False  # the state size follows delay_capacity (and max_order)
    FIXED_PARAMS: ClassVar[dict[str, str]] = {"delay_capacity": "sizes the block's state"}

    def __init__(self, *, jit: bool | None = None, **params: Any) -> None:
        super().__init__(jit=jit, **{k: _list_as_text(v) for k, v in params.items()})

    def load_state(self, saved: Mapping[str, Any]) -> None:
        """Restore what :meth:`Block.state_dict` saved (see :meth:`Block.load_state`)."""
        state = saved.get("state")
        if isinstance(state, Mapping) and "line_head" in state:
            # saved before the line was one entry: a short message instead of 2000 names
            raise InputError(
                f"{self.kind}: saved state has the delay line as separate names (line_head, "
                "line_u_0, ...), the layout of an earlier loopworks; this version keeps it "
                f"as one entry: state names {', '.join(layout.entries_of(self.STATES))}")
        super().load_state(saved)

    def initial_output(self) -> float:
        """y at the steady state the block starts in."""
        raise NotImplementedError  # pragma: no cover - abstract

    def reset(self) -> None:
        super().reset()
        self.u[U.u] = self.params["u0"]
        self.y[Y.y] = self.initial_output()

    def check_dt(self, dt: float) -> None:
        """Raise InputError if a scan of ``dt`` s cannot run (the kernel would skip it)."""
        theta = float(self.params["dead_time"])
        cap = int(self.params["delay_capacity"])
        if theta - cap * dt > DELAY_TOL * (theta + dt):
            scans = theta / dt * (1.0 - DELAY_TOL)
            most = next(p.hi for p in self.PARAMS if p.name == "delay_capacity")
            if scans > most:  # no delay line holds it (and the count may not be an integer)
                raise InputError(
                    f"{self.kind}: dead_time = {theta:g} s at dt = {dt:g} s needs {scans:.4g} "
                    f"scans of delay line, more than the most a delay line holds "
                    f"(delay_capacity ≤ {most:g}): give a shorter dead_time or a longer dt")
            need = math.ceil(scans)
            raise InputError(
                f"{self.kind}: dead_time = {theta:g} s at dt = {dt:g} s needs {need} scans of "
                f"delay line, more than delay_capacity = {cap}: give delay_capacity ≥ {need}")

    def step(self, dt: float, **inputs: Any) -> Outputs:
        """One scan (see :meth:`Block.step`); first checks that dt suits the delay line."""
        if 0.0 < dt < math.inf:
            self.check_dt(dt)
        return super().step(dt, **inputs)

    def set_params(self, **changes: Any) -> None:
        """Change parameters between scans, keeping the state (see :meth:`Block.set_params`;
        the parameters that size the state, ``FIXED_PARAMS``, cannot change)."""
        super().set_params(**{k: _list_as_text(v) for k, v in changes.items()})


class _DeadTimeProcess(_LineProcess):
    """fopdt, sopdt and ipdt: one kernel (``dead_time_kernel``), the model chosen in p."""

    kernel = staticmethod(dead_time_kernel)
    MODEL_CODE: ClassVar[float] = LAG
    INPUTS: ClassVar[tuple[Port, ...]] = PROCESS_INPUTS
    OUTPUTS: ClassVar[tuple[Port, ...]] = PROCESS_OUTPUTS
    COEFFS: ClassVar[tuple[Any, ...]] = DEAD_TIME_COEFFS
    STATES: ClassVar[tuple[Any, ...]] = DEAD_TIME_STATES

    def lag(self) -> tuple[float, float, float]:
        """(K, T1, T2) of the kind."""
        raise NotImplementedError  # pragma: no cover - abstract

    def initial_output(self) -> float:
        y0 = self.params["y0"]
        if y0 is not None:
            return float(y0)
        if self.MODEL_CODE == INTEGRATING:
            return 0.0
        return self.lag()[0] * float(self.params["u0"])

    def coefficients(self) -> dict[str, float]:
        k, t1, t2 = self.lag()
        u0 = float(self.params["u0"])
        y0 = self.initial_output()
        bias = 0.0 if self.MODEL_CODE == INTEGRATING else y0 - k * u0
        return {"model": self.MODEL_CODE, "gain": k, "t1": t1, "t2": t2, "u0": u0,
                "bias": bias, "theta": float(self.params["dead_time"]),
                "cap": float(self.params["delay_capacity"]),
                "bad_mode": FREEZE if self.params["bad_input"] == "freeze" else HOLD_INPUT,
                "y_init": y0}

    def initial_state(self) -> FloatArray:
        y0 = self.initial_output()
        u0 = float(self.params["u0"])
        x = np.zeros(self.n_x)
        x[XD.y] = y0
        x[XD.lag1] = 0.0 if self.MODEL_CODE == INTEGRATING else y0
        x[XD.u_held] = u0
        x[XD.line:] = line_initial(int(self.params["delay_capacity"]), u0)
        return x


_GAIN = Param("gain", 1.0, "y/u", "steady-state gain K", lo=-math.inf)
_STEADY_U0 = "steady input before t = 0: fills the delay line, the u input starts there"
_STEADY_Y0 = "output at that steady state (an output bias when it differs from gain·u0)"


@register
class FOPDT(_DeadTimeProcess):
    """First order plus dead time: K·e^(-θs)/(T·s + 1)."""

    kind = "process.fopdt"
    summary = "first order plus dead time K·e^(-θs)/(T·s + 1), exact ZOH and delay line"
    PARAMS: ClassVar[tuple[Param, ...]] = (
        _GAIN,
        Param("time_constant", 10.0, "s", "time constant T; 0 = no lag", lo=0.0,
              lo_open=False),
        *_common_params(_STEADY_U0, _STEADY_Y0, "gain·u0"),
    )

    def lag(self) -> tuple[float, float, float]:
        return float(self.params["gain"]), float(self.params["time_constant"]), 0.0


@register
class SOPDT(_DeadTimeProcess):
    """Second order plus dead time: K·e^(-θs)/((T1·s + 1)(T2·s + 1))."""

    kind = "process.sopdt"
    summary = ("second order plus dead time K·e^(-θs)/((T1·s + 1)(T2·s + 1)), exact ZOH and "
               "delay line")
    PARAMS: ClassVar[tuple[Param, ...]] = (
        _GAIN,
        Param("time_constant_1", 10.0, "s", "first time constant T1; 0 = none", lo=0.0,
              lo_open=False),
        Param("time_constant_2", 2.0, "s", "second time constant T2; 0 = none (fopdt)",
              lo=0.0, lo_open=False),
        *_common_params(_STEADY_U0, _STEADY_Y0, "gain·u0"),
    )

    def lag(self) -> tuple[float, float, float]:
        return (float(self.params["gain"]), float(self.params["time_constant_1"]),
                float(self.params["time_constant_2"]))


@register
class IPDT(_DeadTimeProcess):
    """Integrating plus dead time: K·e^(-θs)/s, dy/dt = K·(u(t - θ) - u0)."""

    kind = "process.ipdt"
    summary = "integrating plus dead time K·e^(-θs)/s (dy/dt = K·(u(t-θ) - u0)), delay line"
    MODEL_CODE = INTEGRATING
    PARAMS: ClassVar[tuple[Param, ...]] = (
        Param("gain", 0.1, "y/(u·s)", "integration rate K: dy/dt per unit of u - u0",
              lo=-math.inf),
        *_common_params("balancing input (input bias): y is steady while u = u0; fills the "
                        "delay line, the u input starts there", "initial output", "0"),
    )

    def lag(self) -> tuple[float, float, float]:
        return float(self.params["gain"]), 0.0, 0.0


# ---------------------------------------------------------------------------------------------
# process.tf


def _nmax(prm: Mapping[str, Any]) -> int:
    """max_order: the order the layouts of process.tf have room for."""
    return int(prm["max_order"])


# p: sample time, order, max_order, u0, y0, the delay n (scans), delay_capacity, bad_input,
# E1 = CΓ1, E0 = CΓ0 + D, the input's largest coefficient, then the matrices: C' (nmax),
# Φ (nmax·nmax, row-major), Γ1 (nmax), Γ0 (nmax), nmax = max_order
TF_COEFFS = ("ts", "order", "nmax", "u0", "y0", "ndelay", "cap", "bad_mode", "e1", "e0",
             "scale", Array("matrices", lambda prm: _nmax(prm) * (_nmax(prm) + 3),
                            "max_order·(max_order + 3)"))
# x: output, last good input, then ξ (nmax), work (nmax) and the delay line
TF_STATES = ("y", "u_held",
             Array("xi_line", lambda prm: 2 * _nmax(prm) + line_size(int(prm["delay_capacity"])),
                   "2·max_order + 4 + 2·delay_capacity"))
PT, XT = index(TF_COEFFS, "PT"), index(TF_STATES, "XT")


def tf_kernel(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
              y: FloatArray, ys: IntArray) -> None:
    """One scan of the discretised transfer function (module docstring)."""
    ts = p[PT.ts]
    if not abs(dt - ts) <= DT_RTOL * ts:  # not the scan time it was discretised for
        y[Y.y] = x[XT.y]
        ys[Y.y] = BAD_CONFIGURATION_ERROR
        return
    good = input_good(u[U.u], us[U.u], p[PT.u0], p[PT.scale])
    if not good and p[PT.bad_mode] == FREEZE:
        y[Y.y] = x[XT.y]
        ys[Y.y] = BAD_NON_SPECIFIC
        return
    v = u[U.u] if good else x[XT.u_held]
    order = int(p[PT.order])
    nmax = int(p[PT.nmax])
    n = int(p[PT.ndelay])
    cap = int(p[PT.cap])
    u0 = p[PT.u0]
    xi = XT.xi_line  # ξ (nmax), then work (nmax), then the delay line
    work = xi + nmax
    line = xi + 2 * nmax
    c_row = PT.matrices
    phi_at = PT.matrices + nmax
    g1_at = phi_at + nmax * nmax
    g0_at = g1_at + nmax
    w_new = (v if n == 0 else line_value(x, line, cap, n, u0)) - u0
    w_old = line_value(x, line, cap, n + 1, u0) - u0
    out = p[PT.y0] + p[PT.e1] * w_old + p[PT.e0] * w_new
    for i in range(order):
        out += p[c_row + i] * x[xi + i]
    sound = finite(out)
    for i in range(order):
        s = p[g1_at + i] * w_old + p[g0_at + i] * w_new
        for jj in range(order):
            s += p[phi_at + i * nmax + jj] * x[xi + jj]
        x[work + i] = s
        sound = sound and finite(s)
    if not sound:  # the model left the float range: skip the scan (module docstring)
        for i in range(order):
            x[work + i] = 0.0
        y[Y.y] = x[XT.y]
        ys[Y.y] = BAD_NON_SPECIFIC
        return
    for i in range(order):
        x[xi + i] = x[work + i]
    if good:
        x[XT.u_held] = v
    line_push(x, line, cap, v, dt)
    x[XT.y] = out
    y[Y.y] = out
    ys[Y.y] = GOOD_NC if good else BAD_NON_SPECIFIC


def _list_as_text(value: Any) -> Any:
    """A list/tuple of numbers (Python or TOML) as the text form of a coefficient list."""
    if isinstance(value, list | tuple):
        return ", ".join(repr(float(v)) for v in value)
    return value


_NUMBER_SPLIT = re.compile(r"[\s,;]+")


def parse_coefficients(name: str, text: str, kind: str) -> list[float]:
    """Coefficients from text such as ``"1, 2"``, ``"1 2"`` or ``"[1, 2]"``."""
    body = text.strip().strip("[]()").strip()
    items = [s for s in _NUMBER_SPLIT.split(body) if s]
    try:
        values = [float(s) for s in items]
    except ValueError:
        values = []
    if not values or not all(math.isfinite(v) for v in values):
        raise ParameterError(f"{kind}: parameter '{name}' = {text!r} is not allowed: expected "
                             "a list of finite numbers in descending powers, e.g. '1, 2'")
    return values


@register
class TransferFunction(_LineProcess):
    """General transfer function in s (exact ZOH at sample_time) or z, with dead time."""

    kind = "process.tf"
    summary = ("transfer function N/D in s (ZOH-discretised with scipy at sample_time) or z, "
               "with dead time")
    kernel = staticmethod(tf_kernel)
    FIXED_PARAMS: ClassVar[dict[str, str]] = {"delay_capacity": "sizes the block's state",
                                              "max_order": "sizes the block's state"}
    PARAMS: ClassVar[tuple[Param, ...]] = (
        Param("num", "1", "", "numerator coefficients N, descending powers (text '1, 2' = "
              "s + 2, or a list)", type="text"),
        Param("den", "10, 1", "", "denominator coefficients D, descending powers; leading "
              "coefficient ≠ 0", type="text"),
        Param("domain", "s", "", "s: continuous G(s), discretised exactly (ZOH); z: discrete "
              "G(z) run as its difference equation", type="choice", choices=("s", "z")),
        Param("sample_time", None, "s", "required: the scan time dt the block runs at (s: the "
              "ZOH step; z: G(z)'s sample time)", lo=0.0, default_text="required"),
        Param("dead_time", 0.0, "s", "dead time θ (z: a whole number of samples)", lo=0.0,
              lo_open=False),
        Param("u0", 0.0, "u", _STEADY_U0),
        Param("y0", None, "y", "output at that steady state (an output bias)",
              default_text="G(0)·u0 (s), G(1)·u0 (z); 0 if integrating"),
        Param("max_order", 8, "", "largest order deg D the state has room for", type="int",
              lo=1, hi=50, lo_open=False, hi_open=False),
        Param("delay_capacity", 1000, "scans", "past scans the delay line keeps; needs "
              "ceil(dead_time/sample_time) ≤ delay_capacity", type="int", lo=1, hi=10_000_000,
              lo_open=False, hi_open=False),
        Param("bad_input", "hold_input", "", "on a NaN/inf/Bad u: keep running on the last "
              "good input (hold_input) or skip the scan (freeze); y is Bad either way",
              type="choice", choices=("hold_input", "freeze")),
    )
    INPUTS: ClassVar[tuple[Port, ...]] = PROCESS_INPUTS
    OUTPUTS: ClassVar[tuple[Port, ...]] = PROCESS_OUTPUTS
    COEFFS: ClassVar[tuple[Any, ...]] = TF_COEFFS
    STATES: ClassVar[tuple[Any, ...]] = TF_STATES

    def _model(self) -> tuple[list[float], list[float]]:
        """(num, den) normalised: leading zeros of num dropped, den[0] = 1; checked."""
        kind = self.kind
        num = parse_coefficients("num", str(self.params["num"]), kind)
        den = parse_coefficients("den", str(self.params["den"]), kind)
        if den[0] == 0.0:
            raise ParameterError(f"{kind}: parameter 'den' = {self.params['den']!r} is not "
                                 "allowed: its leading coefficient must not be 0")
        while len(num) > 1 and num[0] == 0.0:
            num = num[1:]
        if len(num) > len(den):
            raise ParameterError(
                f"{kind}: parameter 'num' = {self.params['num']!r} is not allowed: the "
                f"transfer function must be proper (deg num {len(num) - 1} > deg den "
                f"{len(den) - 1})")
        order = len(den) - 1
        if order > int(self.params["max_order"]):
            raise ParameterError(
                f"{kind}: parameter 'max_order' = {self.params['max_order']} is too small for "
                f"den of order {order}: give max_order ≥ {order}")
        lead = den[0]
        return [c / lead for c in num], [c / lead for c in den]

    def initial_output(self) -> float:
        y0 = self.params["y0"]
        if y0 is not None:
            return float(y0)
        num, den = self._model()
        u0 = float(self.params["u0"])
        if self.params["domain"] == "s":
            n0, d0 = num[-1], den[-1]
        else:  # D(1) within the rounding of its terms is a pole at z = 1 (integrating):
            # 1 - 1.3 + 0.3 sums to -5.6e-17, and y0 came out as -9e16 with a Good status
            n0, d0 = sum(num), sum(den)
            if abs(d0) <= 1e-12 * sum(abs(c) for c in den):
                d0 = 0.0
        return 0.0 if d0 == 0.0 else n0 / d0 * u0

    def _delay(self, ts: float) -> tuple[int, float]:
        """θ = (n + f)·sample_time: (n, f), f snapped to 0 within the line's tolerance."""
        theta = float(self.params["dead_time"])
        ratio = theta / ts
        n = math.floor(ratio + DELAY_TOL * (ratio + 1.0))
        f = ratio - n
        if f <= DELAY_TOL * (ratio + 1.0):
            f = 0.0
        if self.params["domain"] == "z" and f != 0.0:
            raise ParameterError(
                f"{self.kind}: parameter 'dead_time' = {fmt_value(theta)} s is not allowed "
                "for a "
                f"z-domain transfer function: it must be a whole number of samples of "
                f"sample_time = {ts:g} s")
        need = n + (1 if f > 0.0 else 0)
        cap = int(self.params["delay_capacity"])
        if need > cap:
            raise ParameterError(
                f"{self.kind}: parameter 'delay_capacity' = {cap} is too small: dead_time = "
                f"{theta:g} s at sample_time = {ts:g} s needs {need} scans: give "
                f"delay_capacity ≥ {need}")
        return n, f

    def coefficients(self) -> dict[str, Any]:
        ts_given = self.params["sample_time"]
        if ts_given is None:
            raise ParameterError(
                f"{self.kind}: parameter 'sample_time' is required: the scan time dt (s) the "
                "block runs at (domain s: the ZOH discretisation step; domain z: the sample "
                "time of G(z))")
        ts = float(ts_given)
        num, den = self._model()
        n, f = self._delay(ts)
        order = len(den) - 1
        nmax = int(self.params["max_order"])
        cprime = [0.0] * nmax
        phi_m = [0.0] * (nmax * nmax)
        g1 = [0.0] * nmax
        g0 = [0.0] * nmax
        e1 = 0.0
        e0 = num[0] if order == 0 else 0.0
        if order > 0:
            e1, e0 = self._discretise(num, den, ts, f, cprime, phi_m, g1, g0)
        # the input's largest coefficient: (u - u0) times it must stay within MODEL_RANGE
        scale = max(1.0, abs(e1), abs(e0), *(abs(g) for g in g1), *(abs(g) for g in g0))
        values: dict[str, Any] = {
            "ts": ts, "order": float(order), "nmax": float(nmax), "u0": float(self.params["u0"]),
            "y0": self.initial_output(), "ndelay": float(n),
            "cap": float(self.params["delay_capacity"]),
            "bad_mode": FREEZE if self.params["bad_input"] == "freeze" else HOLD_INPUT,
            "e1": e1, "e0": e0, "scale": scale, "matrices": [*cprime, *phi_m, *g1, *g0]}
        if not all(math.isfinite(v) for v in layout.pack(TF_COEFFS, values, self.kind)):
            raise ParameterError(
                f"{self.kind}: num = {self.params['num']!r}, den = {self.params['den']!r} at "
                f"sample_time = {ts:g} s give non-finite discrete coefficients")
        return values

    def _discretise(self, num: list[float], den: list[float], ts: float, f: float,
                    cprime: list[float], phi_m: list[float], g1: list[float],
                    g0: list[float]) -> tuple[float, float]:
        """Fill C' = CΦ, Φ, Γ1, Γ0 (module docstring); return (E1, E0) = (CΓ1, CΓ0 + D).
        For the z domain: C' = C, Φ = A, Γ1 = 0, Γ0 = B, E1 = 0, E0 = D."""
        cp, phi_d, gam1, gam0, e1, e0 = _discrete_matrices(
            tuple(num), tuple(den), ts, f, self.params["domain"] == "z")
        order = len(cp)
        nmax = int(self.params["max_order"])
        for i in range(order):
            cprime[i], g1[i], g0[i] = cp[i], gam1[i], gam0[i]
            for j in range(order):
                phi_m[i * nmax + j] = phi_d[i][j]
        return e1, e0

    def initial_state(self) -> FloatArray:
        u0 = float(self.params["u0"])
        x = np.zeros(self.n_x)  # ξ = 0: the steady state at u0
        x[XT.y] = self.initial_output()
        x[XT.u_held] = u0
        x[XT.xi_line + 2 * _nmax(self.params):] = line_initial(
            int(self.params["delay_capacity"]), u0)
        return x

    def check_dt(self, dt: float) -> None:
        """Raise InputError unless dt is the ``sample_time`` the block was discretised for."""
        ts = float(self.params["sample_time"])
        if not abs(dt - ts) <= DT_RTOL * ts:
            raise InputError(
                f"{self.kind}: dt = {fmt_value(dt)} s is not allowed: this transfer function "
                "runs at "
                f"sample_time = {ts:g} s (give sample_time = {fmt_value(dt)} to discretise it for "
                "that scan time)")


@functools.lru_cache(maxsize=256)
def _discrete_matrices(num: tuple[float, ...], den: tuple[float, ...], ts: float, f: float,
                       z_domain: bool) -> tuple[tuple[float, ...], tuple[tuple[float, ...], ...],
                                                tuple[float, ...], tuple[float, ...], float,
                                                float]:
    """(C', Φ, Γ1, Γ0, E1, E0) of ``process.tf`` (module docstring) from its controllable
    canonical state-space form: for the s domain the zero-order-hold discretisation at ``ts``
    with the fractional delay ``f`` (of a sample) split between Γ1 and Γ0; for the z domain
    C' = C, Φ = A, Γ1 = 0, Γ0 = B, E1 = 0, E0 = D. A pure function of its arguments, cached:
    a sweep or a test builds the same transfer function many times, and scipy's matrix
    exponential is most of a block's construction."""
    from scipy import signal

    a, b, c, d = signal.tf2ss(list(num), list(den))
    order = a.shape[0]
    if z_domain:
        phi_d, gam1, gam0, cp = a, np.zeros((order, 1)), b, c
        e1, e0 = 0.0, float(d[0, 0])
    else:
        phi_d, gam_full = signal.cont2discrete((a, b, c, d), ts, method="zoh")[:2]
        if f == 0.0:
            gam0 = gam_full
            gam1 = np.zeros((order, 1))
        else:
            phi0, gam0 = signal.cont2discrete((a, b, c, d), (1.0 - f) * ts,
                                              method="zoh")[:2]
            gam_f = signal.cont2discrete((a, b, c, d), f * ts, method="zoh")[1]
            gam1 = phi0 @ gam_f
        cp = c @ phi_d
        e1 = float((c @ gam1)[0, 0])
        e0 = float((c @ gam0)[0, 0] + d[0, 0])
    return (tuple(float(v) for v in cp[0]), tuple(tuple(float(v) for v in row) for row in phi_d),
            tuple(float(v) for v in gam1[:, 0]), tuple(float(v) for v in gam0[:, 0]), e1, e0)
