"""Register maps and float32 word orders (runtime-and-ecosystem 2c)."""

from __future__ import annotations

import math
import struct
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as hs
from pymodbus.client import AsyncModbusTcpClient

from loopworks.errors import InputError
from loopworks.live.registers import (
    WORD_ORDERS,
    Point,
    RegisterMap,
    decode_f32,
    default_map,
    encode_f32,
)
from loopworks.live.split import split_scenario
from loopworks.sim.scenario import load_scenario

# hand-computed: 123456.0 = 0x47F12000, 1.0 = 0x3F800000, -2.5 = 0xC0200000
GOLDEN = [
    (123456.0, "abcd", [0x47F1, 0x2000]),
    (123456.0, "cdab", [0x2000, 0x47F1]),
    (123456.0, "badc", [0xF147, 0x0020]),
    (123456.0, "dcba", [0x0020, 0xF147]),
    (1.0, "abcd", [0x3F80, 0x0000]),
    (1.0, "dcba", [0x0000, 0x803F]),
    (-2.5, "abcd", [0xC020, 0x0000]),
    (-2.5, "badc", [0x20C0, 0x0000]),
]


@pytest.mark.parametrize(("value", "order", "regs"), GOLDEN)
def test_golden_registers(value: float, order: str, regs: list[int]) -> None:
    assert encode_f32(value, order) == regs
    assert decode_f32(regs, order) == value


def test_abcd_and_cdab_agree_with_pymodbus() -> None:
    f32 = AsyncModbusTcpClient.DATATYPE.FLOAT32
    for value in (123456.0, -0.15625, 3.0e38, 1e-40):
        assert encode_f32(value, "abcd") == AsyncModbusTcpClient.convert_to_registers(
            value, f32, word_order="big")
        assert encode_f32(value, "cdab") == AsyncModbusTcpClient.convert_to_registers(
            value, f32, word_order="little")


@given(hs.floats(width=32, allow_nan=True), hs.sampled_from(WORD_ORDERS))
def test_round_trip(value: float, order: str) -> None:
    regs = encode_f32(value, order)
    assert len(regs) == 2 and all(0 <= r <= 0xFFFF for r in regs)
    back = decode_f32(regs, order)
    assert back == value or (math.isnan(back) and math.isnan(value))


@given(hs.integers(0, 0xFFFF), hs.integers(0, 0xFFFF), hs.sampled_from(WORD_ORDERS))
def test_every_order_is_a_permutation_of_the_ieee_bytes(r0: int, r1: int, order: str) -> None:
    value = decode_f32([r0, r1], order)
    if not math.isnan(value):  # NaN payloads need not survive
        assert encode_f32(value, order) == [r0, r1]
    raw = struct.pack(">f", value)
    assert sorted(raw) == sorted(bytes([r0 >> 8, r0 & 0xFF, r1 >> 8, r1 & 0xFF])) or math.isnan(
        value)


def test_encoding_errors_name_the_value_and_what_is_allowed() -> None:
    with pytest.raises(InputError, match=r"'xyzw'.*abcd, cdab, badc, dcba"):
        encode_f32(1.0, "xyzw")
    with pytest.raises(InputError, match=r"1e\+39 does not fit a float32"):
        encode_f32(1e39)
    with pytest.raises(InputError, match=r"exactly two registers"):
        decode_f32([1, 2, 3])
    with pytest.raises(InputError, match=r"0..65535"):
        decode_f32([70000, 0])
    assert encode_f32(1.0, "CDAB") == [0x0000, 0x3F80]  # any letter case


def test_point_checks() -> None:
    with pytest.raises(InputError, match=r"direction = 'sideways'.*'input'.*'output'"):
        Point("valve.op", 0, "sideways")
    with pytest.raises(InputError, match=r"address = 65535.*0..65534"):
        Point("valve.op", 65535, "input")
    with pytest.raises(InputError, match=r"'op' must be written 'block.port'"):
        Point("op", 0, "input")
    with pytest.raises(InputError, match=r"type = 'int16'.*float32"):
        Point("valve.op", 0, "input", type="int16")


def test_overlapping_addresses_are_refused() -> None:
    with pytest.raises(InputError, match=r"'valve.op' takes register 1.*'sensor.pv'"):
        RegisterMap([Point("sensor.pv", 0, "output"), Point("valve.op", 1, "input")])
    with pytest.raises(InputError, match=r"heartbeat_address takes register 2"):
        RegisterMap([Point("sensor.pv", 2, "output")], heartbeat_address=2)
    with pytest.raises(InputError, match=r"device_id = 0.*1..247"):
        RegisterMap([Point("sensor.pv", 0, "output")], device_id=0)


@pytest.fixture(scope="module")
def builtin_map() -> RegisterMap:
    return default_map(split_scenario(load_scenario(None)))


def test_default_map_of_the_builtin_scenario(builtin_map: RegisterMap) -> None:
    assert [(p.name, p.address, p.direction, p.word_order) for p in builtin_map.points] == [
        ("sensor.pv", 0, "output", "abcd"), ("valve.op", 2, "input", "abcd")]
    assert (builtin_map.heartbeat_address, builtin_map.fault_bits_address) == (4, 5)
    assert builtin_map.device_id == 1
    lines = builtin_map.text().splitlines()
    assert lines[1].split()[:4] == ["address", "regs", "name", "direction"]
    assert lines[2].split() == ["0", "0-1", "sensor.pv", "output", "(read)", "float32", "abcd"]
    assert lines[3].split() == ["2", "2-3", "valve.op", "input", "(write)", "float32", "abcd"]
    assert lines[4].split()[:3] == ["4", "4", "heartbeat"]
    assert "bit 0 valve.op" in lines[5]


def test_toml_round_trip(builtin_map: RegisterMap, tmp_path: Path) -> None:
    text = builtin_map.to_toml()
    assert '[io.points."sensor.pv"]' in text and "device_id = 1" in text
    assert RegisterMap.from_toml(text) == builtin_map
    odd = RegisterMap([Point("a.b", 10, "output", "dcba"), Point("c.d", 20, "input", "cdab")],
                      device_id=7, heartbeat_address=100, fault_bits_address=None)
    assert RegisterMap.from_toml(odd.to_toml()) == odd
    path = tmp_path / "map.toml"
    odd.write(path)
    assert RegisterMap.read(path) == odd


GOOD = ('[io]\ndevice_id = 1\n[io.points."sensor.pv"]\naddress = 0\ndirection = "output"\n'
        'type = "float32"\nword_order = "abcd"\n')


@pytest.mark.parametrize(("text", "needles"), [
    ("[io\n", ["bad.toml: invalid TOML"]),
    ("[other]\nx = 1\n", ["bad.toml: expected an [io] table"]),
    (GOOD.replace("address = 0", 'address = "zero"'),
     ['bad.toml: io.points."sensor.pv".address = \'zero\': expected a register address']),
    (GOOD.replace('"output"', '"out"'),
     ['io.points."sensor.pv"', "direction = 'out'", "'input'", "'output'"]),
    (GOOD.replace('"abcd"', '"abdc"'),
     ['io.points."sensor.pv"', "word_order = 'abdc'", "abcd, cdab, badc, dcba"]),
    (GOOD.replace("address = 0\n", ""), ['io.points."sensor.pv": address is missing']),
    (GOOD.replace("address = 0\n", "adress = 0\n"),
     ['io.points."sensor.pv".adress: unknown key',
      "address, direction, fault_action, type, word_order"]),
    (GOOD.replace("device_id = 1", "device_id = 300"), ["device_id = 300", "1..247"]),
    (GOOD.replace("device_id = 1", "device_id = 1\nheartbeat = 4"),
     ["io.heartbeat: unknown key", "heartbeat_address"]),
    (GOOD + '[io.points."valve.op"]\naddress = 1\ndirection = "input"\n',
     ["'valve.op' takes register 1", "'sensor.pv'"]),
    ("[io]\ndevice_id = 1\n", ["io.points: expected tables"]),
])
def test_malformed_map_gives_a_located_error(text: str, needles: list[str]) -> None:
    with pytest.raises(InputError) as info:
        RegisterMap.from_toml(text, "bad.toml")
    for needle in needles:
        assert needle in str(info.value), str(info.value)
