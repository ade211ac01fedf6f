"""The Fieldbus status byte and the value+status pair that blocks take and give.

A status byte has three parts (spec vendor-blocks 4.6, FF encoding used by DeltaV ``.ST`` fields):

    bit 7-6  quality    0 Bad, 1 Uncertain, 2 Good non-cascade, 3 Good cascade
    bit 5-2  substatus  meaning depends on the quality (table below)
    bit 1-0  limits     0 not limited, 1 low limited, 2 high limited, 3 constant

    byte = quality << 6 | substatus << 2 | limits

Good non-cascade, not limited (0x80 = 128) is the default everywhere. Plain module-level integer
constants keep the kernels numba-friendly: a kernel only ever sees ``int`` status bytes.
"""

from __future__ import annotations

from typing import NamedTuple

# Quality (bits 7-6), as the base byte value.
BAD = 0x00
UNCERTAIN = 0x40
GOOD_NC = 0x80
GOOD_CASCADE = 0xC0

# Limit bits (1-0).
NOT_LIMITED = 0
LOW_LIMITED = 1
HIGH_LIMITED = 2
CONSTANT = 3

# Common full bytes (quality + substatus), spec 4.6.
BAD_NON_SPECIFIC = 0x00
BAD_CONFIGURATION_ERROR = 0x04
BAD_NOT_CONNECTED = 0x08
BAD_DEVICE_FAILURE = 0x0C
BAD_SENSOR_FAILURE = 0x10
BAD_NO_COMM_LUV = 0x14
BAD_NO_COMM_NO_LUV = 0x18
BAD_OUT_OF_SERVICE = 0x1C
UNCERTAIN_NON_SPECIFIC = 0x40
UNCERTAIN_LAST_USABLE_VALUE = 0x44
UNCERTAIN_SUBSTITUTE = 0x48
UNCERTAIN_INITIAL_VALUE = 0x4C
UNCERTAIN_SENSOR_CONVERSION = 0x50
UNCERTAIN_EU_RANGE_VIOLATION = 0x54
UNCERTAIN_SUB_NORMAL = 0x58
GOOD_NC_NON_SPECIFIC = 0x80
GOOD_NC_ACTIVE_BLOCK_ALARM = 0x84
GOOD_NC_ACTIVE_ADVISORY = 0x88
GOOD_NC_ACTIVE_CRITICAL = 0x8C
GOOD_NC_UNACK_BLOCK_ALARM = 0x90
GOOD_NC_UNACK_ADVISORY = 0x94
GOOD_NC_UNACK_CRITICAL = 0x98
GOOD_C_NON_SPECIFIC = 0xC0
GOOD_C_IA = 0xC4
GOOD_C_IR = 0xC8
GOOD_C_NI = 0xCC
GOOD_C_NS = 0xD0
GOOD_C_LO = 0xD8
GOOD_C_FSA = 0xDC
GOOD_C_IFS = 0xE0

QUALITY_NAMES = {BAD: "Bad", UNCERTAIN: "Uncertain", GOOD_NC: "Good_NC", GOOD_CASCADE: "Good_C"}
LIMIT_NAMES = {NOT_LIMITED: "", LOW_LIMITED: "LowLimited", HIGH_LIMITED: "HighLimited",
               CONSTANT: "Constant"}
SUBSTATUS_NAMES: dict[int, str] = {
    BAD_NON_SPECIFIC: "NonSpecific",
    BAD_CONFIGURATION_ERROR: "ConfigurationError",
    BAD_NOT_CONNECTED: "NotConnected",
    BAD_DEVICE_FAILURE: "DeviceFailure",
    BAD_SENSOR_FAILURE: "SensorFailure",
    BAD_NO_COMM_LUV: "NoCommLUV",
    BAD_NO_COMM_NO_LUV: "NoCommNoLUV",
    BAD_OUT_OF_SERVICE: "OutOfService",
    UNCERTAIN_NON_SPECIFIC: "NonSpecific",
    UNCERTAIN_LAST_USABLE_VALUE: "LastUsableValue",
    UNCERTAIN_SUBSTITUTE: "Substitute",
    UNCERTAIN_INITIAL_VALUE: "InitialValue",
    UNCERTAIN_SENSOR_CONVERSION: "SensorConversionNotAccurate",
    UNCERTAIN_EU_RANGE_VIOLATION: "EURangeViolation",
    UNCERTAIN_SUB_NORMAL: "SubNormal",
    GOOD_NC_NON_SPECIFIC: "NonSpecific",
    GOOD_NC_ACTIVE_BLOCK_ALARM: "ActiveBlockAlarm",
    GOOD_NC_ACTIVE_ADVISORY: "ActiveAdvisoryAlarm",
    GOOD_NC_ACTIVE_CRITICAL: "ActiveCriticalAlarm",
    GOOD_NC_UNACK_BLOCK_ALARM: "UnackBlockAlarm",
    GOOD_NC_UNACK_ADVISORY: "UnackAdvisoryAlarm",
    GOOD_NC_UNACK_CRITICAL: "UnackCriticalAlarm",
    GOOD_C_NON_SPECIFIC: "NonSpecific",
    GOOD_C_IA: "IA",
    GOOD_C_IR: "IR",
    GOOD_C_NI: "NI",
    GOOD_C_NS: "NS",
    GOOD_C_LO: "LO",
    GOOD_C_FSA: "FSA",
    GOOD_C_IFS: "IFS",
}


def quality(st: int) -> int:
    """Quality part of a status byte, as its base value (BAD, UNCERTAIN, GOOD_NC, GOOD_CASCADE)."""
    return st & 0xC0


def substatus(st: int) -> int:
    """Substatus number 0..15 (bits 5-2)."""
    return (st >> 2) & 0x0F


def limits(st: int) -> int:
    """Limit bits 0..3 (NOT_LIMITED, LOW_LIMITED, HIGH_LIMITED, CONSTANT)."""
    return st & 0x03


def make(quality_base: int, substatus_number: int = 0, limit_bits: int = 0) -> int:
    """Compose a status byte: quality base (0x00/0x40/0x80/0xC0) | substatus << 2 | limits."""
    return (quality_base & 0xC0) | ((substatus_number & 0x0F) << 2) | (limit_bits & 0x03)


def with_limits(st: int, limit_bits: int) -> int:
    """The same status with its limit bits replaced."""
    return (st & 0xFC) | (limit_bits & 0x03)


def is_bad(st: int) -> bool:
    """True when the quality is Bad."""
    return (st & 0xC0) == BAD


def is_good(st: int) -> bool:
    """True for Good non-cascade and Good cascade."""
    return (st & 0x80) != 0


def name(st: int) -> str:
    """Readable name of a status byte, e.g. ``Good_NC:NonSpecific:HighLimited`` for 130."""
    if not 0 <= st <= 255:
        return f"Invalid({st})"
    base = st & 0xFC
    sub = SUBSTATUS_NAMES.get(base, f"Substatus{substatus(st)}")
    text = f"{QUALITY_NAMES[quality(st)]}:{sub}"
    lim = LIMIT_NAMES[limits(st)]
    return f"{text}:{lim}" if lim else text


def check_byte(st: int, what: str = "status") -> int:
    """Return ``st`` as int if it is a valid status byte (0..255), else raise ValueError."""
    value = int(st)
    if value != st or not 0 <= value <= 255:
        raise ValueError(f"{what} = {st!r} is not a status byte: allowed integers 0..255")
    return value


class Signal(NamedTuple):
    """A value with its status byte: what blocks take and give. ``status`` defaults to Good NC."""

    value: float
    status: int = GOOD_NC

    @property
    def quality_name(self) -> str:
        """Readable quality: Bad, Uncertain, Good_NC or Good_C."""
        return QUALITY_NAMES[quality(self.status)]

    def __str__(self) -> str:
        return f"{self.value:g} [{name(self.status)}]"
