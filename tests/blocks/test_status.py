"""The Fieldbus status byte (spec vendor-blocks 4.6)."""

import pytest

from loopworks.blocks import status as st
from loopworks.blocks.status import Signal


def test_quality_bases_match_the_ff_encoding() -> None:  # spec 4.6
    assert (st.BAD, st.UNCERTAIN, st.GOOD_NC, st.GOOD_CASCADE) == (0x00, 0x40, 0x80, 0xC0)


def test_worked_bytes_of_the_spec() -> None:  # spec 4.6: 0x80 = 128, 0x81 = 129, 0x82 = 130
    assert st.make(st.GOOD_NC) == 128
    assert st.make(st.GOOD_NC, 0, st.LOW_LIMITED) == 129
    assert st.make(st.GOOD_NC, 0, st.HIGH_LIMITED) == 130
    assert st.with_limits(128, st.CONSTANT) == 131


@pytest.mark.parametrize(("byte", "quality", "sub", "lim"), [
    (0x1C, st.BAD, 7, 0),          # Bad, out of service
    (0x47, st.UNCERTAIN, 1, 3),    # Uncertain, last usable value, constant
    (0xD8, st.GOOD_CASCADE, 6, 0),  # Good cascade, LO
    (0x82, st.GOOD_NC, 0, 2),
])
def test_parts_of_a_byte(byte: int, quality: int, sub: int, lim: int) -> None:
    assert st.quality(byte) == quality
    assert st.substatus(byte) == sub
    assert st.limits(byte) == lim
    assert st.make(quality, sub, lim) == byte


def test_readable_names() -> None:
    assert st.name(128) == "Good_NC:NonSpecific"
    assert st.name(130) == "Good_NC:NonSpecific:HighLimited"
    assert st.name(0x1C) == "Bad:OutOfService"
    assert st.name(0xC8) == "Good_C:IR"
    assert st.name(0x44 | 3) == "Uncertain:LastUsableValue:Constant"


def test_predicates() -> None:
    assert st.is_bad(0x10) and not st.is_bad(0x40)
    assert st.is_good(0x80) and st.is_good(0xC0) and not st.is_good(0x44)


def test_signal_defaults_to_good_non_cascade() -> None:
    s = Signal(1.5)
    assert s.status == 128
    assert s.quality_name == "Good_NC"
    assert str(s) == "1.5 [Good_NC:NonSpecific]"


@pytest.mark.parametrize("bad", [-1, 256, 1.5])
def test_check_byte_rejects_non_bytes(bad: float) -> None:
    with pytest.raises(ValueError, match="status byte"):
        st.check_byte(bad)  # type: ignore[arg-type]
