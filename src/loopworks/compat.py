"""A drop-in for simple-pid users: ``from loopworks.compat import PID``.

:class:`PID` takes simple-pid 2.0.1's constructor and call, and computes every update with
the generic ``pid`` block's kernel (:mod:`loopworks.blocks.pid`), set up to realise
simple-pid's law (simple-pid 2.0.1, ``simple_pid/pid.py``, ``PID.__call__``)::

    e_k = setpoint - input_k,   m_k = error_map(e_k) (m_k = e_k without a map)
    P_k = Kp·m_k                          (proportional on error)
    P_k = P_{k-1} - Kp·(input_k - input_{k-1})   (proportional on measurement, P_0 = 0)
    I_k = clamp(I_{k-1} + Ki·m_k·dt, output_limits)
    D_k = -Kd·(input_k - input_{k-1})/dt         (derivative on measurement, the default)
    D_k = Kd·(e_k - m_{k-1})/dt                  (derivative on error; D_0 = 0 either way)
    output_k = clamp(P_k + I_k + D_k, output_limits)

The kernel runs the parallel form with ``antiwindup = "integral_limits"`` (the integral kept
within the output limits, as above), no derivative filter (``tf = 0``), setpoint weights
b = 1 (proportional on error) or 0, c = 0 (derivative on measurement) or 1. What the kernel's
law does not hold directly is fed to its inputs, each exactly:

* proportional on measurement: the kernel's P with b = 0 is -Kp·input_k, so its feedforward
  input carries P_{k-1} + Kp·input_{k-1} (which makes the sum P_{k-1} - Kp·Δinput);
* an error map: the kernel's setpoint input is input_k + m_k, so its error is m_k (up to one
  rounding of the sum); with derivative on error the feedforward adds Kd·(e_k - m_k)/dt, which
  turns the kernel's Kd·(m_k - m_{k-1})/dt into simple-pid's Kd·(e_k - m_{k-1})/dt.

Gains of one sign: all ≥ 0 is reverse action, all ≤ 0 direct action (the kernel takes
magnitudes and an action); gains of mixed signs are refused (ParameterError, naming them).
No limit (None) is the largest float. Modes, ``sample_time``, ``time_fn`` and ``dt`` are
simple-pid's, handled here, and so are its attributes (``Kp``, ``setpoint``, ...: set them at
any time; the next update uses them).

Where loopworks differs from simple-pid, on purpose (the generic pid's contract):

* an input or setpoint that is NaN, infinite or beyond ±1e12 is Bad: the output holds its
  last value (None before the first usable update), ``components`` stay those of the last
  usable update, and the controller re-initialises bumplessly when the input is good again,
  where simple-pid returns NaN from then on. The feedforward that carries proportional on
  measurement or a mapped error's derivative (above) is held to the same ±1e12, so an error
  map with derivative on error and a clock that stood still (dt = 1e-16) holds the output
  where simple-pid returns its 1e16-sized terms;
* a sum that overflows is treated likewise instead of returning ±inf or NaN;
* a ``time_fn`` that goes back gives dt = 1e-16, as one that stands still, when there is no
  ``sample_time`` (simple-pid computes with the negative dt; with a sample time both return
  the last output);
* the sums are the kernel's: results can differ from simple-pid's in the last bit or so
  (1e-15 relative; proportional on measurement 1e-15 of Kp·input).

loopworks' own choices, as keywords: ``derivative_filter`` (the filter time constant Tf in s,
0 = none as simple-pid), ``antiwindup`` (``integral_limits``, simple-pid's, the default;
``clamping``, ``back_calculation`` with ``tracking_time``, or ``none``) and ``jit`` (compiled
kernel or the interpreter; default: ``LOOPWORKS_JIT``).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable
from typing import Any

from loopworks.blocks.pid import PID as PIDBlock
from loopworks.blocks.pid import X, Y
from loopworks.blocks.status import GOOD_NC
from loopworks.errors import ParameterError

Limits = tuple[float | None, float | None]
_BIG = sys.float_info.max


def clamp_limits(value: float | None, limits: Limits) -> float | None:
    """``value`` within ``limits`` (low, high), either None for no limit; None stays None
    (simple-pid's ``_clamp``)."""
    lower, upper = limits
    if value is None:
        return None
    if upper is not None and value > upper:
        return upper
    if lower is not None and value < lower:
        return lower
    return value


#: the kernel's parameter names and this class's keywords, for the kernel's messages
_KEYWORDS = {"tf": "derivative_filter", "tt": "tracking_time", "out_lo": "output_limits[0]",
             "out_hi": "output_limits[1]", "antiwindup": "antiwindup"}


def _ours(exc: ParameterError) -> ParameterError:
    """The kernel's refusal in this class's words: its keywords for the kernel's names."""
    text = str(exc)
    for kernel, ours in _KEYWORDS.items():
        text = text.replace(f"'{kernel}'", f"'{ours}'")
    return ParameterError(text.replace("pid: ", "compat.PID: ", 1))


def _kernel_limit(limit: float | None, side: float) -> float:
    """An output limit as the kernel takes it: None, NaN (never compared true, so no limit
    in simple-pid's clamp) and an infinite limit on its own side are no limit, the largest
    float on that side (the kernel takes finite limits only: (0, inf) was refused where
    simple-pid takes it; found by an outside audit)."""
    if limit is None or math.isnan(float(limit)):
        return side * _BIG
    value = float(limit)
    return side * _BIG if math.isinf(value) and value * side > 0 else value


def _signs(kp: float, ki: float, kd: float) -> bool:
    """True for direct action (every gain ≤ 0), False for reverse (every gain ≥ 0);
    ParameterError for gains of mixed signs."""
    gains = {"Kp": kp, "Ki": ki, "Kd": kd}
    for name, value in gains.items():
        if not math.isfinite(value):
            raise ParameterError(f"compat.PID: {name} = {value!r} is out of range: allowed "
                                 "any finite number")
    if any(v > 0 for v in gains.values()) and any(v < 0 for v in gains.values()):
        given = ", ".join(f"{k} = {v:g}" for k, v in gains.items() if v != 0)
        raise ParameterError(
            f"compat.PID: gains of mixed signs ({given}) are not allowed: the controller's "
            "action is one sign for all three (all >= 0: reverse, all <= 0: direct)")
    return any(v < 0 for v in gains.values())


class PID:
    """simple-pid's ``PID``, run by loopworks' generic pid kernel (module docstring)."""

    def __init__(self, Kp: float = 1.0, Ki: float = 0.0, Kd: float = 0.0,
                 setpoint: float = 0, sample_time: float | None = 0.01,
                 output_limits: Limits | None = (None, None), auto_mode: bool = True,
                 proportional_on_measurement: bool = False,
                 differential_on_measurement: bool = True,
                 error_map: Callable[[float], float] | None = None,
                 time_fn: Callable[[], float] | None = None, starting_output: float = 0.0,
                 *, derivative_filter: float = 0.0, antiwindup: str = "integral_limits",
                 tracking_time: float | None = None, jit: bool | None = None) -> None:
        self.Kp, self.Ki, self.Kd = Kp, Ki, Kd
        self.setpoint = setpoint
        self.sample_time = sample_time
        self._min_output: float | None = None
        self._max_output: float | None = None
        self._auto_mode = auto_mode
        self.proportional_on_measurement = proportional_on_measurement
        self.differential_on_measurement = differential_on_measurement
        self.error_map = error_map
        self.derivative_filter = derivative_filter
        self.antiwindup = antiwindup
        self.tracking_time = tracking_time
        self._proportional = 0.0
        self._derivative = 0.0
        self._last_time: float | None = None
        self._last_output: float | None = None
        self._last_error: float | None = None
        self._last_input: float | None = None
        if time_fn is None:
            import time  # as simple-pid: a machine without it must give time_fn

            time_fn = time.monotonic
        self.time_fn = time_fn
        self._applied: tuple[Any, ...] | None = None
        try:
            self._block = PIDBlock(jit=jit, **self._block_params())
        except ParameterError as exc:
            raise _ours(exc) from None
        self._applied = self._settings()
        self.output_limits = output_limits
        self.reset()
        self._integral = clamp_limits(starting_output, self.output_limits)

    def __copy__(self) -> PID:
        """A shallow copy, as simple-pid's: the same settings and a controller state of its
        own (the kernel's block is copied; simple-pid keeps its state in plain numbers, so
        its shallow copy updates apart from the original: found by an outside audit)."""
        import copy

        new = type(self).__new__(type(self))
        new.__dict__.update(self.__dict__)
        new._block = copy.deepcopy(self._block)
        return new

    # -- the block -----------------------------------------------------------------------
    def _settings(self) -> tuple[Any, ...]:
        return (self.Kp, self.Ki, self.Kd, self._min_output, self._max_output,
                self.proportional_on_measurement, self.differential_on_measurement,
                self.error_map is not None, self.derivative_filter, self.antiwindup,
                self.tracking_time)

    def _block_params(self) -> dict[str, Any]:
        direct = _signs(float(self.Kp), float(self.Ki), float(self.Kd))
        lo, hi = _kernel_limit(self._min_output, -1.0), _kernel_limit(self._max_output, 1.0)
        if lo == hi:  # simple-pid allows equal limits; the block needs lo < hi (clamped here)
            hi = math.nextafter(hi, math.inf)
        params: dict[str, Any] = {
            "form": "parallel", "kp": abs(float(self.Kp)), "ki": abs(float(self.Ki)),
            "kd": abs(float(self.Kd)), "tf": float(self.derivative_filter),
            "action": "direct" if direct else "reverse",
            "b": 0.0 if self.proportional_on_measurement else 1.0,
            "c": 1.0 if not self.differential_on_measurement else 0.0,
            "out_lo": lo, "out_hi": hi, "antiwindup": self.antiwindup, "retune": "textbook"}
        if self.tracking_time is not None:
            params["tt"] = float(self.tracking_time)
        return params

    def _apply(self) -> None:
        """Give the block the attributes as they are now (a user may have set Kp, ...); a
        value the kernel refuses is named by this class's keyword (its message named the
        kernel's: 'tf', 'tt', 'out_hi')."""
        settings = self._settings()
        if settings != self._applied:
            try:
                self._block.set_params(**self._block_params())
            except ParameterError as exc:
                raise _ours(exc) from None
            self._applied = settings

    # -- simple-pid's interface ----------------------------------------------------------
    def __call__(self, input_: float, dt: float | None = None) -> float | None:
        """One update with the measurement ``input_``; ``dt`` (s) instead of the time
        elapsed since the last update (simple-pid's ``__call__``). Returns the output, or the
        last one when in manual or within ``sample_time`` (None before the first)."""
        if not self.auto_mode:
            return self._last_output
        now = self.time_fn()
        measured = dt is None
        if dt is None:
            assert self._last_time is not None
            dt = now - self._last_time
            if dt == 0.0:  # a clock that stood still (simple-pid's 1e-16)
                dt = 1e-16
        elif dt <= 0:
            raise ValueError(f"dt has negative value {dt}, must be positive")
        if (self.sample_time is not None and dt < self.sample_time
                and self._last_output is not None):
            return self._last_output  # also a clock gone back, as simple-pid (dt < 0)
        if measured and not dt > 0.0:  # gone back, no sample time (simple-pid: dt < 0)
            dt = 1e-16
        error = self.setpoint - input_
        pv = float(input_)
        mapped = float(error if self.error_map is None else self.error_map(error))
        self._apply()
        first = self._last_input is None
        kp, kd = float(self.Kp), float(self.Kd)
        ff = 0.0
        if self.proportional_on_measurement:
            # the kernel's P is -Kp·input_k: the offset makes it P_{k-1} - Kp·Δinput
            ff += self._proportional + kp * (pv if self._last_input is None
                                             else float(self._last_input))
        ff_p = ff  # the proportional part of the feedforward
        d_fix = 0.0
        if self.error_map is not None and not self.differential_on_measurement and not first:
            d_fix = kd * (float(error) - mapped) / dt  # D on the unmapped error (docstring)
        ff += d_fix
        sp = float(self.setpoint) if self.error_map is None else pv + mapped
        fresh = self._block.x.copy() if self._last_output is None else None
        out = self._block.step(float(dt), sp=sp, pv=pv, ff=ff)
        if int(self._block.ys[Y.out]) & 0xC0 != GOOD_NC:
            # a Bad input: the kernel held its output; the terms and the last input stay
            # those of the last usable update, and before the first there is no output
            # (None, not the kernel's 0) and the next usable update is the first
            if fresh is not None:
                self._block.x[:] = fresh
            self._last_time = now
            return self._last_output
        y = self._block.y
        p_term = float(y[Y.p_term])
        self._proportional = (p_term + ff_p if self.proportional_on_measurement
                              else p_term)
        self._derivative = float(y[Y.d_term]) + d_fix
        del out
        output = clamp_limits(float(y[Y.out]), self.output_limits)
        self._last_output = output
        self._last_input = input_
        self._last_error = mapped
        self._last_time = now
        return output

    def __repr__(self) -> str:
        extra = ""
        if self.derivative_filter != 0.0:
            extra += f", derivative_filter={self.derivative_filter!r}"
        if self.antiwindup != "integral_limits":
            extra += f", antiwindup={self.antiwindup!r}"
        if self.tracking_time is not None:
            extra += f", tracking_time={self.tracking_time!r}"
        return (f"{type(self).__name__}(Kp={self.Kp!r}, Ki={self.Ki!r}, Kd={self.Kd!r}, "
                f"setpoint={self.setpoint!r}, sample_time={self.sample_time!r}, "
                f"output_limits={self.output_limits!r}, auto_mode={self.auto_mode!r}, "
                f"proportional_on_measurement={self.proportional_on_measurement!r}, "
                f"differential_on_measurement={self.differential_on_measurement!r}, "
                f"error_map={self.error_map!r}{extra})")

    @property
    def _integral(self) -> float:
        """The integral term I (the kernel's state; within the output limits, as simple-pid
        keeps it, unless ``antiwindup = "none"``, where the kernel's integral is not)."""
        raw = float(self._block.x[X.i])
        if self.antiwindup == "none":  # not clipped to what it is not kept within
            return raw
        value = clamp_limits(raw, self.output_limits)
        assert value is not None
        return float(value)

    @_integral.setter
    def _integral(self, value: float | None) -> None:
        self._block.x[X.i] = 0.0 if value is None else float(value)

    @property
    def components(self) -> tuple[float, float, float]:
        """The P, I and D terms of the last update."""
        return self._proportional, self._integral, self._derivative

    @property
    def tunings(self) -> tuple[float, float, float]:
        """(Kp, Ki, Kd)."""
        return self.Kp, self.Ki, self.Kd

    @tunings.setter
    def tunings(self, tunings: tuple[float, float, float]) -> None:
        self.Kp, self.Ki, self.Kd = tunings

    @property
    def auto_mode(self) -> bool:
        """Whether the controller computes (auto) or holds its last output (manual)."""
        return self._auto_mode

    @auto_mode.setter
    def auto_mode(self, enabled: bool) -> None:
        self.set_auto_mode(enabled)

    def set_auto_mode(self, enabled: bool, last_output: float | None = None) -> None:
        """Switch auto mode on or off; from manual to auto the controller is reset and its
        integral starts at ``last_output`` (0 when None), within the limits."""
        if enabled and not self._auto_mode:
            self.reset()
            self._integral = clamp_limits(last_output if last_output is not None else 0.0,
                                          self.output_limits)
        self._auto_mode = enabled

    @property
    def output_limits(self) -> Limits:
        """(lower, upper) output limits, None for no limit in that direction."""
        return self._min_output, self._max_output

    @output_limits.setter
    def output_limits(self, limits: Limits | None) -> None:
        if limits is None:
            self._min_output, self._max_output = None, None
            return
        min_output, max_output = limits
        if None not in limits and max_output < min_output:  # type: ignore[operator]
            raise ValueError("lower limit must be less than upper limit")
        before = self._min_output, self._max_output
        self._min_output, self._max_output = min_output, max_output
        try:
            self._apply()
        except ParameterError:  # refused: the controller keeps the limits it had
            self._min_output, self._max_output = before
            raise
        self._integral = clamp_limits(float(self._block.x[X.i]), self.output_limits)
        self._last_output = clamp_limits(self._last_output, self.output_limits)

    def reset(self) -> None:
        """Clear the terms, the last input and output, and restart the clock."""
        self._apply()
        self._block.reset()
        self._proportional = 0.0
        self._derivative = 0.0
        self._integral = clamp_limits(0.0, self.output_limits)
        self._last_time = self.time_fn()
        self._last_output = None
        self._last_input = None
        self._last_error = None
