r"""Transmitters: kind ``sensor.transmitter`` (takes the process output ``y``, gives ``pv``).

A transmitter turns the process variable into the measurement a controller reads. In a
simulated loop it sits between the process and the controller (``"tt.y" = "process.y"``,
``"pid.pv" = "tt.pv"``). It adds what a real measurement adds to the true value: a calibration
(gain and offset), the sensor's own lag (a thermowell, a damping setting), measurement noise,
the resolution of the A/D conversion, the saturation of the output range, and failures. The
PV it gives is what the loop metrics of plant-and-tuning section 4 are computed from, so every
effect is explicit and switchable (all off by default: ``pv = y``).

Signal path, one scan of ``dt`` seconds (k = this scan)::

    m_k  = gain·y_k + offset                                  calibration
    z_k  = z_{k-1} + (1 - exp(-dt/T))·(m_k - z_{k-1})        first-order lag, T = time_constant
    v_k  = z_k + noise_std·n_k                                n_k ~ N(0, 1), seeded
    v_k  = q·floor(v_k/q + 1/2)                               quantisation, q = quantum > 0
    pv_k = clamp(v_k, pv_lo, pv_hi)                           output range (limited when
                                                              v_k before or after the
                                                              quantiser is beyond it)

* The lag is the exact zero-order-hold step of T·dz/dt = m - z (Åström & Wittenmark,
  *Computer-Controlled Systems*, ch. 2; the shared primitive ``lag_step``); T = 0 is no lag.
  It starts settled: z takes the first good measurement (no start-up transient).
* Before its first scan the transmitter publishes the PV of that settled start for the ``y``
  input latched now (issue 11 point 8): calibration, quantisation and range of it, no noise;
  so a controller that reads ``pv`` earlier in a module's order sees a real measurement.
* Noise is added after the lag (electronics noise on the sensed value) and before the
  quantiser (the A/D converter digitises the noisy signal), as in a real transmitter. The
  quantiser is the memoryless one of plant-and-tuning 1.5 (``y = q·round(x/q)``, halves
  rounded up).
* A value clamped at ``pv_lo``/``pv_hi`` (a saturated 4-20 mA signal) gets the limit bits
  (low 1, high 2) and the quality ``range_status`` says: Uncertain, EU range violation (0x54,
  the Fieldbus substatus for a value outside its range) by default, or Good (0x80). [I]

Noise generator
---------------

The Gaussian numbers come from L'Ecuyer's MRG32k3a combined multiple recursive generator
(P. L'Ecuyer, *Good parameters and implementations for combined multiple recursive random
number generators*, Operations Research 47(1), 1999, 159-164) in its double-precision form:
six integers below 2^32 held as floats in the block state, every intermediate product below
2^53, so the arithmetic is exact in IEEE doubles, interpreted or compiled, and the state
survives ``state_dict()``/JSON exactly. Period about 2^191. Two uniforms u1, u2 in (0, 1) give
one normal by Box-Muller, ``n = sqrt(-2 ln u1)·cos(2π u2)`` (Box & Muller, Ann. Math. Stat.
29, 1958). The ``seed`` (an integer) sets the six starting integers through SplitMix64
(Steele, Lea & Flood, OOPSLA 2014), mixed with a per-kind stream number so a sensor and a
disturbance with the same seed draw independent streams. Blocks of the same kind with the same
seed draw the same numbers: give each noisy block its own seed.

One normal is drawn on every scan while ``noise_std`` > 0, whatever the input or failure state,
so the noise of scan k is always the k-th number of the stream: a run is reproducible from the
seed alone, and resuming from a saved state continues the stream exactly.

Failures (injected by parameters)
---------------------------------

``failure`` selects one failure mode, active while ``failure_start`` ≤ t < ``failure_end`` (t
in seconds: the ``clock`` input, i.e. the module time or a replay's ``t`` column, else the
block's own time, the sum of the dt of earlier scans; both ends with a 1e-9 s tolerance, as
module events). During the failure:

* ``stuck``: the value freezes at the last PV before the failure (no noise); status Good
  (128): a stuck transmitter (plugged impulse line, frozen electronics) does not know it.
* ``bad``: the value holds the last PV before the failure (the last usable value); status Bad,
  sensor failure (0x10): the device detects the fault, as an AI block reports it.
* ``nan``: the value is NaN; status Bad, non-specific (0x00): a corrupted value, as a PLC
  float tag or a Modbus register gives it. A NaN is Bad whatever the device claims (issue 11
  point 1: no value is non-finite unless its status is Bad), so loopworks marks it where it
  arises (until issue 11 this mode gave status Good).

``failure_status`` (a status byte) replaces the mode's status; with ``failure = "nan"`` it must
be a Bad status (0..63).

The sensing element keeps following the process during a failure (the lag keeps running), so
when the failure ends the PV returns to the current reading at once. If the failure is active
from the first scan, the frozen value is the first scan's reading.

Input status: an Uncertain ``y`` gives an Uncertain ``pv`` (the input's byte, limit bits
cleared); a Bad or non-finite ``y`` (a broken process model), or a reading gain·y + offset
beyond ±1e150 (``MODEL_RANGE`` of the process models: a fault, not a measurement), holds the PV
and the lag, with the input's status if it is Bad, else Bad non-specific (0x00); so does a
noisy value that overflows (a noise_std near the float range). Before the first usable scan
the PV held is the start value published before the first scan. An injected failure takes
precedence over both.

Options for the spec's [I] points
---------------------------------

The plant-and-tuning spec names measurement noise (plant-and-tuning section 6 item 3) and the
quantiser (plant-and-tuning 1.5) without fixing how a transmitter combines them; these
interpretations [I] are parameters:

* ``range_status`` = ``uncertain``: status of a value clamped at ``pv_lo``/``pv_hi`` (0x54 plus
  the limit bits); ``good`` gives 0x80 plus the limit bits.
* ``failure_status``: the status during a failure; default per mode (table above).

Example
-------

Python::

    import loopworks
    tt = loopworks.create_block("sensor.transmitter", time_constant=2.0, noise_std=0.1,
                                quantum=0.05, seed=7, failure="bad", failure_start=10.0)
    for k in range(12):
        r = tt.step(1.0, y=50.0)
    print(r["pv"])            # the last PV before t = 10 s, [Bad:SensorFailure]

Replay (``loopworks replay sensor.transmitter tt.csv -p quantum=0.5 -p failure=stuck
-p failure_start=2``), with ``tt.csv``::

    t,y
    0,10.1
    1,10.3
    2,11.0
    3,12.0

gives ``pv`` 10, 10.5, 10.5, 10.5 (10.3 rounds to 10.5; stuck from t = 2 s at the last PV) and
``pv.ST`` 128 on every row.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

from loopworks.blocks.block import Block
from loopworks.blocks.kernel import FloatArray, IntArray, primitive
from loopworks.blocks.layout import index
from loopworks.blocks.params import Param, Port
from loopworks.blocks.primitives import finite, lag_step
from loopworks.blocks.registry import register
from loopworks.blocks.status import (
    BAD,
    BAD_NON_SPECIFIC,
    BAD_SENSOR_FAILURE,
    GOOD_NC,
    HIGH_LIMITED,
    LOW_LIMITED,
    UNCERTAIN,
    UNCERTAIN_EU_RANGE_VIOLATION,
)
from loopworks.errors import ParameterError
from loopworks.plant.process import MODEL_RANGE
from loopworks.plant.valve import quantise

# -- the seeded generator (shared with loopworks.plant.disturbance) ---------------------------

# MRG32k3a constants (L'Ecuyer 1999, double-precision implementation)
M1 = 4294967087.0
M2 = 4294944443.0
A12 = 1403580.0
A13N = 810728.0
A21 = 527612.0
A23N = 1370589.0
NORM = 2.328306549295727688e-10  # 1/(M1 + 1)
TWO_PI = 2.0 * math.pi

#: number of state slots the generator uses (s10, s11, s12, s20, s21, s22)
RNG_SLOTS = 6
#: stream numbers mixed into the seed, one per block kind that draws random numbers
STREAM_SENSOR = 1
STREAM_DISTURBANCE = 2

_MASK64 = (1 << 64) - 1


def _splitmix64(state: int) -> tuple[int, int]:
    """One SplitMix64 step (Steele, Lea & Flood 2014): (new state, 64-bit output)."""
    state = (state + 0x9E3779B97F4A7C15) & _MASK64
    z = state
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & _MASK64
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & _MASK64
    return state, z ^ (z >> 31)


def mix_seed(seed: int, run: int) -> int:
    """A block's seed in run number ``run`` (a scenario's ``[simulation] seed``, a sweep
    instance's seed): two SplitMix64 steps of seed·φ + run (φ = 0x9E3779B97F4A7C15), the top 53
    bits (the ``seed`` parameter's range). Different runs give independent streams; so do two
    blocks with different seeds in one run."""
    state = (int(seed) * 0x9E3779B97F4A7C15 + int(run)) & _MASK64
    state, _ = _splitmix64(state)
    _, z = _splitmix64(state)
    return z >> 11


def rng_seed_state(seed: int, stream: int) -> list[float]:
    """The six MRG32k3a starting integers (as floats) for ``seed`` and a ``stream`` number.

    SplitMix64 of ``seed·2^8 + stream`` gives six 64-bit words, reduced modulo m1 (first
    three) and m2 (last three). Each triple must not be all zero (L'Ecuyer 1999); a zero triple
    (probability about 2^-96) is replaced by 12345s, the generator's customary seed."""
    state = ((int(seed) << 8) + int(stream)) & _MASK64
    words = []
    for _ in range(RNG_SLOTS):
        state, z = _splitmix64(state)
        words.append(z)
    first = [float(w % int(M1)) for w in words[:3]]
    second = [float(w % int(M2)) for w in words[3:]]
    if first == [0.0, 0.0, 0.0]:  # pragma: no cover - probability 2^-96
        first = [12345.0] * 3
    if second == [0.0, 0.0, 0.0]:  # pragma: no cover
        second = [12345.0] * 3
    return first + second


@primitive
def rng_uniform(x: FloatArray, i: int) -> float:
    """Next MRG32k3a number in (0, 1); the state is x[i..i+5] (L'Ecuyer 1999, Fig. 1)::

        p1 = (1403580·s11 - 810728·s10) mod m1,   s1 ← (s11, s12, p1)
        p2 = (527612·s22 - 1370589·s20) mod m2,   s2 ← (s21, s22, p2)
        u  = (p1 - p2 mod m1)/(m1 + 1), with p1 ≤ p2 mapped to p1 - p2 + m1

    Every product is below 2^53, so float arithmetic is exact."""
    p1 = float(A12 * x[i + 1] - A13N * x[i])
    k = float(int(p1 / M1))
    p1 -= k * M1
    if p1 < 0.0:
        p1 += M1
    x[i] = x[i + 1]
    x[i + 1] = x[i + 2]
    x[i + 2] = p1
    p2 = float(A21 * x[i + 5] - A23N * x[i + 3])
    k = float(int(p2 / M2))
    p2 -= k * M2
    if p2 < 0.0:
        p2 += M2
    x[i + 3] = x[i + 4]
    x[i + 4] = x[i + 5]
    x[i + 5] = p2
    if p1 <= p2:
        return (p1 - p2 + M1) * NORM
    return (p1 - p2) * NORM


@primitive
def rng_normal(x: FloatArray, i: int) -> float:
    """A standard normal number from two uniforms (Box-Muller, cosine branch):
    n = sqrt(-2·ln u1)·cos(2π·u2). u1 is never 0, so n is always finite."""
    u1 = rng_uniform(x, i)
    u2 = rng_uniform(x, i)
    return math.sqrt(-2.0 * math.log(u1)) * math.cos(TWO_PI * u2)


@primitive
def at_or_after(t: float, start: float) -> bool:
    """t ≥ start with the 1e-9 s tolerance module events use (time sums like 0.1 + 0.1 + ...
    land a hair below the exact instant)."""
    return t >= start - 1e-9


@primitive
def scan_time(clock: float, x: FloatArray, i: int, dt: float) -> float:
    """The time of this scan: the ``clock`` input when finite, else the block's own time
    x[i]; afterwards x[i] holds the time of the next scan (this one + dt)."""
    t = clock if finite(clock) else float(x[i])
    if finite(t + dt):
        x[i] = t + dt
    return t


# -- sensor.transmitter ------------------------------------------------------------------------

# Failure modes (p[P.failure]): FAILURES[mode]
NONE, STUCK, BAD_MODE, NAN_MODE = 0, 1, 2, 3
FAILURES = ("none", "stuck", "bad", "nan")

INPUTS = (
    Port("y", 0.0, "y", "the true process variable (process output)", status=True),
    Port("clock", math.nan, "s", "time for the failure window (module time / replay t); "
         "NaN = the block's own time"),
)
OUTPUTS = (
    Port("pv", 0.0, "pv", "the measurement", status=True),
)
#: the coefficient array p (coefficients())
COEFFS = ("gain", "offset", "tau", "noise", "quantum", "pv_lo", "pv_hi", "range_good",
          "failure", "f_start", "f_end", "f_status")
#: the state array x: the lag, its started flag, the PV held for failures, the time, the
#: generator (RNG_SLOTS words from rng_s10, read by rng_normal(x, X.rng_s10))
STATES = ("lag", "started", "held", "held_ok", "time",
          "rng_s10", "rng_s11", "rng_s12", "rng_s20", "rng_s21", "rng_s22")
P, X, U, Y = index(COEFFS, "P"), index(STATES, "X"), index(INPUTS, "U"), index(OUTPUTS, "Y")


@primitive
def usable(reading: float, status: int) -> bool:
    """A reading the transmitter can measure: status not Bad, finite, within ±MODEL_RANGE."""
    return (status & 0xC0) != BAD and finite(reading) and abs(reading) <= MODEL_RANGE


@primitive
def shaped(p: FloatArray, value: float, status_in: int) -> tuple[float, int]:
    """(pv, status) of a measured value: quantised (q > 0), then limited to pv_lo..pv_hi with
    the limit bits and the range status when the value or its quantised value is beyond the
    range (a value above pv_hi that the quantiser rounds down onto it is still a saturated
    signal: 100.1 on 0..100 with q = 0.5 read 100, Good); Good, or the Uncertain input's
    byte (limit bits cleared)."""
    q = float(p[P.quantum])
    digital = quantise(value, q) if q > 0.0 else value
    status = GOOD_NC
    if (status_in & 0xC0) == UNCERTAIN:
        status = status_in & 0xFC
    base = GOOD_NC if p[P.range_good] != 0.0 else UNCERTAIN_EU_RANGE_VIOLATION
    if value > p[P.pv_hi] or digital > p[P.pv_hi]:
        return float(p[P.pv_hi]), base | HIGH_LIMITED
    if value < p[P.pv_lo] or digital < p[P.pv_lo]:
        return float(p[P.pv_lo]), base | LOW_LIMITED
    return digital, status


def transmitter_kernel(dt: float, p: FloatArray, x: FloatArray, u: FloatArray, us: IntArray,
                       y: FloatArray, ys: IntArray) -> None:
    """One scan of the transmitter (equations in the module docstring)."""
    # array elements are read into Python floats: plain IEEE arithmetic when interpreted (no
    # numpy warnings on inf - inf), free when compiled
    t = scan_time(float(u[U.clock]), x, X.time, dt)
    noise = 0.0
    if p[P.noise] > 0.0:  # one normal every scan: scan k always gets the k-th number
        noise = float(p[P.noise]) * rng_normal(x, X.rng_s10)
    status_in = us[U.y]
    reading = float(p[P.gain]) * float(u[U.y]) + float(p[P.offset])
    value = math.nan
    status = BAD_NON_SPECIFIC
    if usable(reading, status_in):
        if x[X.started] == 0.0:  # starts settled at the first good measurement
            x[X.lag] = reading
            x[X.started] = 1.0
        else:  # a weighted mean of readings within MODEL_RANGE: finite
            x[X.lag] = lag_step(x[X.lag], reading, dt, p[P.tau])
        value = float(x[X.lag]) + noise
        if finite(value):
            value, status = shaped(p, value, status_in)
    if not finite(value):  # hold, like the lag; before any scan, the published start
        value = float(x[X.held]) if x[X.held_ok] != 0.0 else float(y[Y.pv])
        status = status_in if (status_in & 0xC0) == BAD else BAD_NON_SPECIFIC
    mode = p[P.failure]
    failed = mode != NONE and at_or_after(t, p[P.f_start]) and not at_or_after(t, p[P.f_end])
    if failed:
        if x[X.held_ok] == 0.0:  # failed from the first scan: freeze this scan's reading
            x[X.held] = value
            x[X.held_ok] = 1.0
        value = math.nan if mode == NAN_MODE else float(x[X.held])
        status = int(p[P.f_status])
    else:
        x[X.held] = value
        x[X.held_ok] = 1.0
    y[Y.pv] = value
    ys[Y.pv] = status


_DEFAULT_STATUS = {"none": GOOD_NC, "stuck": GOOD_NC, "bad": BAD_SENSOR_FAILURE,
                   "nan": BAD_NON_SPECIFIC}


@register
class Transmitter(Block):
    """Transmitter: calibration, lag, seeded noise, quantisation, range, injected failures."""

    kind = "sensor.transmitter"
    summary = ("Transmitter: gain/offset, first-order lag, seeded Gaussian noise, "
               "quantisation, output range and injected failures (stuck, Bad, NaN)")
    kernel = staticmethod(transmitter_kernel)

    PARAMS: ClassVar[tuple[Param, ...]] = (
        Param("gain", 1.0, "pv/y", "calibration gain: m = gain·y + offset"),
        Param("offset", 0.0, "pv", "calibration offset (a zero error or a unit conversion)"),
        Param("time_constant", 0.0, "s", "sensor lag T (exact ZOH step); 0 = no lag",
              lo=0.0, lo_open=False),
        Param("noise_std", 0.0, "pv", "standard deviation of the Gaussian measurement noise; "
              "0 = none", lo=0.0, lo_open=False),
        Param("seed", 0, "", "seed of the noise generator (MRG32k3a via SplitMix64)", "int",
              lo=0.0, hi=2.0 ** 53, lo_open=False, hi_open=False),
        Param("quantum", 0.0, "pv", "resolution q: pv = q·floor(v/q + 1/2); 0 = none "
              "(plant-and-tuning 1.5)", lo=0.0, lo_open=False),
        Param("pv_lo", -math.inf, "pv", "lowest PV the output can give (saturation)",
              lo=-math.inf, lo_open=False),
        Param("pv_hi", math.inf, "pv", "highest PV the output can give (saturation)",
              hi=math.inf, hi_open=False),
        Param("range_status", "uncertain", "", "quality of a PV clamped at pv_lo/pv_hi: "
              "Uncertain EU range violation (0x54) or Good (0x80), plus the limit bits [I]",
              "choice", choices=("uncertain", "good")),
        Param("failure", "none", "", "injected failure: stuck (frozen value), bad (Bad "
              "sensor failure, value held), nan (NaN value)", "choice", choices=FAILURES),
        Param("failure_start", 0.0, "s", "time the failure begins (clock input or own time)"),
        Param("failure_end", math.inf, "s", "time the failure ends; inf = never",
              hi=math.inf, hi_open=False),
        Param("failure_status", None, "", "status byte during the failure (nan: a Bad "
              "status, 0..63)", "int", lo=0.0, hi=255.0, lo_open=False, hi_open=False,
              default_text="stuck 128, bad 16 (0x10), nan 0"),
    )
    INPUTS: ClassVar[tuple[Port, ...]] = INPUTS
    OUTPUTS: ClassVar[tuple[Port, ...]] = OUTPUTS
    COEFFS: ClassVar[tuple[str, ...]] = COEFFS
    STATES: ClassVar[tuple[str, ...]] = STATES

    def coefficients(self) -> dict[str, Any]:
        prm: dict[str, Any] = self.params
        if prm["pv_lo"] >= prm["pv_hi"]:
            raise ParameterError(
                f"{self.kind}: parameter 'pv_hi' = {prm['pv_hi']:g} is out of range: it must "
                f"be above pv_lo = {prm['pv_lo']:g}")
        if prm["failure_end"] < prm["failure_start"]:
            raise ParameterError(
                f"{self.kind}: parameter 'failure_end' = {prm['failure_end']:g} is out of "
                f"range: it must be >= failure_start = {prm['failure_start']:g}")
        status = prm["failure_status"]
        if status is None:
            status = _DEFAULT_STATUS[prm["failure"]]
        elif prm["failure"] == "nan" and int(status) & 0xC0 != BAD:
            raise ParameterError(
                f"{self.kind}: parameter 'failure_status' = {int(status)} is out of range for "
                "failure = 'nan': a NaN value is Bad, so its status must be Bad, 0..63 "
                "(issue 11 point 1)")
        return {"gain": float(prm["gain"]), "offset": float(prm["offset"]),
                "tau": float(prm["time_constant"]), "noise": float(prm["noise_std"]),
                "quantum": float(prm["quantum"]), "pv_lo": float(prm["pv_lo"]),
                "pv_hi": float(prm["pv_hi"]),
                "range_good": 1.0 if prm["range_status"] == "good" else 0.0,
                "failure": float(FAILURES.index(prm["failure"])),
                "f_start": float(prm["failure_start"]), "f_end": float(prm["failure_end"]),
                "f_status": float(status)}

    def initial_state(self) -> list[float]:
        x = [0.0] * self.n_x
        x[X.rng_s10:X.rng_s10 + RNG_SLOTS] = rng_seed_state(int(self.params["seed"]),
                                                            STREAM_SENSOR)
        return x

    def reset(self) -> None:
        super().reset()
        self.publish_start()

    def publish_start(self) -> None:
        """Before the first scan: the PV of the settled start for the ``y`` latched now
        (module docstring): calibrated, quantised and limited, no noise; 0 with Bad status
        when that ``y`` is unusable. A module that settles its wires calls it again."""
        p = self.p
        reading = float(p[P.gain]) * float(self.u[U.y]) + float(p[P.offset])
        status_in = int(self.us[U.y])
        if usable(reading, status_in):
            self.y[Y.pv], self.ys[Y.pv] = shaped(p, reading, status_in)
        else:
            self.y[Y.pv], self.ys[Y.pv] = 0.0, BAD_NON_SPECIFIC
