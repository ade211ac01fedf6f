"""Parameter and port declarations, and the validation of parameter values.

A block declares its parameters as :class:`Param` records (name, unit, default, range, meaning).
:func:`validate` turns user-given values (Python numbers, or strings from a CLI or CSV) into
checked values, raising :class:`~loopworks.errors.ParameterError` that names the parameter, the
value and the allowed range.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

from loopworks.errors import ParameterError

ParamValue = float | int | bool | str | None
ParamType = Literal["float", "int", "bool", "choice", "text"]


def _fmt(x: float) -> str:
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    return f"{x:g}"


@dataclass(frozen=True)
class Param:
    """One block parameter.

    ``lo``/``hi`` bound a numeric value; ``lo_open``/``hi_open`` exclude the bound. An infinite
    value is accepted only where the matching bound is an included infinity (``ti`` in (0, inf]).
    A ``default`` of None means "not given": the block derives it (``default_text`` says how).
    """

    name: str
    default: ParamValue
    unit: str = ""
    meaning: str = ""
    type: ParamType = "float"
    lo: float = -math.inf
    hi: float = math.inf
    lo_open: bool = True
    hi_open: bool = True
    choices: tuple[str, ...] = ()
    default_text: str = ""

    def range_text(self) -> str:
        """The allowed values, e.g. ``(0, inf]`` or ``one of ideal, parallel, series``."""
        if self.type == "choice":
            return "one of " + ", ".join(self.choices)
        if self.type == "text":
            return "text"
        if self.type == "bool":
            return "true or false"
        if self.lo == -math.inf and self.hi == math.inf and self.lo_open and self.hi_open:
            return "any finite number" + (" (integer)" if self.type == "int" else "")
        left = "(" if self.lo_open else "["
        right = ")" if self.hi_open else "]"
        text = f"{left}{_fmt(self.lo)}, {_fmt(self.hi)}{right}"
        return text + (" integer" if self.type == "int" else "")

    def check(self, value: Any, kind: str = "") -> ParamValue:
        """Return ``value`` converted to this parameter's type, or raise ParameterError. None
        means "not given": the default."""
        where = f"{kind}: " if kind else ""
        if value is None:  # not given: the default (None where the block derives it)
            return self.default
        if self.type == "choice":
            text = str(value).strip().lower()
            if text not in self.choices:
                raise ParameterError(
                    f"{where}parameter '{self.name}' = {value!r} is not allowed: "
                    f"expected {self.range_text()}")
            return text
        if self.type == "bool":
            return _to_bool(value, self.name, where)
        if self.type == "text":
            if not isinstance(value, str):
                raise ParameterError(f"{where}parameter '{self.name}' = {value!r} must be text")
            return value
        if type(value) is float or type(value) is int:  # the common case: no message made
            x = float(value)
        else:
            x = _to_float(value, self.name, where, f": allowed {self.range_text()}"
                          + (f" {self.unit}" if self.unit else ""))
        if self.type == "int" and math.isfinite(x) and x != int(x):
            raise ParameterError(
                f"{where}parameter '{self.name}' = {value!r} must be an integer: allowed "
                f"{self.range_text()}" + (f" {self.unit}" if self.unit else ""))
        below = x < self.lo or (self.lo_open and x == self.lo)
        above = x > self.hi or (self.hi_open and x == self.hi)
        if math.isnan(x) or below or above or (self.type == "int" and not math.isfinite(x)):
            raise ParameterError(
                f"{where}parameter '{self.name}' = {_fmt_value(value)} is out of range: "
                f"allowed {self.range_text()}" + (f" {self.unit}" if self.unit else ""))
        return int(x) if self.type == "int" else x


def fmt_value(value: Any) -> str:
    """A value for a message: :func:`_fmt_value` (short when that is the value, else in
    full)."""
    return _fmt_value(value)


def _fmt_value(value: Any) -> str:
    """A given value as the user can recognise it: short (``%g``) when that is the value,
    else in full (1000000001.0 printed as 1e+09 looked like the allowed bound 1e+09)."""
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        short = _fmt(value)
        return short if float(short) == value else repr(value)
    return repr(value) if isinstance(value, str) else str(value)


def _to_float(value: Any, name: str, where: str, allowed: str = "") -> float:
    """``value`` as a float; ParameterError naming the parameter, the value and ``allowed``
    (its range) when it is not a number (a bool is not one)."""
    if isinstance(value, bool):
        raise ParameterError(f"{where}parameter '{name}' = {value!r} must be a number{allowed}")
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ParameterError(
            f"{where}parameter '{name}' = {value!r} must be a number{allowed}") from None


_TRUE = {"true", "1", "yes", "on"}
_FALSE = {"false", "0", "no", "off"}


def _to_bool(value: Any, name: str, where: str) -> bool:
    if isinstance(value, bool):
        return value
    if isinstance(value, int | float) and value in (0, 1):
        return bool(value)
    text = str(value).strip().lower()
    if text in _TRUE:
        return True
    if text in _FALSE:
        return False
    raise ParameterError(f"{where}parameter '{name}' = {value!r} must be true or false")


@dataclass(frozen=True)
class Port:
    """A named input or output. ``choices`` name the integer codes of an enumerated input
    (``mode``: MAN=0, AUTO=1, CAS=2); ``status`` says whether the port carries a status byte."""

    name: str
    default: float = 0.0
    unit: str = ""
    meaning: str = ""
    status: bool = False
    choices: tuple[str, ...] = ()

    @property
    def expected(self) -> str:
        """What a value of this port is, for an error message: a number, or one of the
        enumerated port's names or their codes."""
        return (f"one of {', '.join(self.choices)} or their codes 0..{len(self.choices) - 1}"
                if self.choices else "a number")

    def parse(self, value: Any) -> float:
        """A float for this port; an enumerated port takes its names (any case) or codes, or a
        value that is not a number (NaN, ±inf: no value, which the block treats as a Bad input,
        as it does the same value with a status)."""
        expected = self.expected
        if isinstance(value, str):
            text = value.strip()
            if self.choices and text.upper() in self.choices:
                return float(self.choices.index(text.upper()))
            try:
                x = float(text)
            except ValueError:
                raise ValueError(f"input '{self.name}' = {value!r}: expected {expected}") from None
        else:
            x = float(value)
        if self.choices and math.isfinite(x) and x not in range(len(self.choices)):
            raise ValueError(f"input '{self.name}' = {value!r}: expected {expected}")
        return x


def validate(kind: str, specs: tuple[Param, ...], given: dict[str, Any]) -> dict[str, ParamValue]:
    """Check ``given`` against ``specs``; names match in any letter case.

    Returns every parameter with defaults filled in (None where the block derives the default).
    """
    by_name = {p.name: p for p in specs}
    out: dict[str, ParamValue] = {p.name: p.default for p in specs}
    for raw_name, value in given.items():
        name = raw_name.lower()
        if name not in by_name:
            raise ParameterError(
                f"{kind}: unknown parameter '{raw_name}'; valid names: "
                + ", ".join(p.name for p in specs))
        out[name] = by_name[name].check(value, kind)
    return out
