"""The controller's Modbus TCP I/O to a field device: read the inputs, write the outputs, and
make up the status Modbus does not carry (runtime-and-ecosystem.md 2d, 3.2).

Each point is a 32-bit float in two holding registers (:mod:`loopworks.live.registers`). The
device outputs (PV and the like) are read in one request per scan; each controller output is
written, then read back on the next scan and compared. Statuses, as a DCS gives them:

* a read that fails (no connection, time-out, exception response) makes every input
  **Bad, no communication**: ``BAD_NO_COMM_LUV`` (0x14) with the last value read when there
  was one, else ``BAD_NO_COMM_NO_LUV`` (0x18) with NaN;
* a non-finite value read is **Bad, device failure** (0x0C) with the last usable value;
* otherwise Good (0x80).

A lost connection is retried with exponential backoff (``RETRY_MIN`` doubling to
``RETRY_MAX`` seconds), never blocking a scan longer than the request time-out; every
transition (lost, restored, a write that failed, a read-back that differs) is logged on the
``loopworks.serve`` logger with its time.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from loopworks.blocks import status as st
from loopworks.live.registers import Point, RegisterMap, decode_f32, encode_f32

log = logging.getLogger("loopworks.serve")

#: first and longest wait between reconnection attempts, s
#: Modbus exception codes (Modbus Application Protocol V1.1b3, 7)
EXCEPTIONS = {1: "illegal function", 2: "illegal data address", 3: "illegal data value",
              4: "server device failure", 6: "server device busy",
              10: "gateway path unavailable", 11: "gateway target device failed to respond"}
RETRY_MIN = 0.1
RETRY_MAX = 1.0
#: a request's time-out, s (a scan waits at most this for the device)
TIMEOUT = 0.5
#: largest read-back difference that counts as equal (float32 rounding of the written value)
READBACK_TOLERANCE = 1e-6


@dataclass
class IOCounters:
    """Communication figures since start."""

    reads: int = 0
    read_errors: int = 0
    writes: int = 0
    write_errors: int = 0
    readback_mismatches: int = 0
    reconnects: int = 0
    connected: bool = False
    events: list[str] = field(default_factory=list)


def _runs(points: Sequence[Point]) -> list[tuple[int, int]]:
    """(first address, register count) of each run of adjacent points: a device serves only
    the registers its map names, so one read across a gap between points is refused
    (exception 2: the loop never ran on a map with a gap; found by an outside audit)."""
    runs: list[list[int]] = []
    for lo, hi in sorted((p.address, p.address + 2) for p in points):
        if runs and lo <= runs[-1][1]:
            runs[-1][1] = max(runs[-1][1], hi)
        else:
            runs.append([lo, hi])
    return [(lo, hi - lo) for lo, hi in runs]


class ModbusIO:
    """Reads the device outputs named by ``regmap`` and writes its inputs over Modbus TCP at
    ``host:port`` (module docstring). Call :meth:`read` and :meth:`write` once per scan."""

    def __init__(self, regmap: RegisterMap, host: str, port: int, *,
                 timeout: float = TIMEOUT) -> None:
        from pymodbus.client import AsyncModbusTcpClient

        self.regmap = regmap
        self.host, self.port = host, port
        self.inputs = [p for p in regmap.points if p.direction == "output"]
        self.outputs = [p for p in regmap.points if p.direction == "input"]
        self.client = AsyncModbusTcpClient(host, port=port, timeout=timeout, retries=0,
                                           reconnect_delay=0)
        self.counters = IOCounters()
        self.last: dict[str, float] = {}
        self.written: dict[str, float] = {}
        self._retry_at = 0.0
        self._backoff = RETRY_MIN
        self._lost_logged = False
        #: the last refusal logged ("what: exception code"), None after a good read
        self._refusal: str | None = None  # the read refusal last logged
        self._write_refusals: set[str] = set()  # the write refusals logged, until one works

    def _event(self, message: str, level: int = logging.WARNING) -> None:
        stamp = time.strftime("%Y-%m-%dT%H:%M:%S", time.localtime())
        self.counters.events.append(f"{stamp} {message}")
        log.log(level, message)

    async def connect(self) -> bool:
        """Connect unless connected or still backing off; True when connected."""
        if self.client.connected:
            return True
        now = time.monotonic()
        if now < self._retry_at:
            return False
        ok = bool(await self.client.connect())
        if ok:
            if self._lost_logged:
                self.counters.reconnects += 1
                self._event(f"device {self.host}:{self.port} connected again", logging.INFO)
            else:
                self._event(f"device {self.host}:{self.port} connected", logging.INFO)
            self._lost_logged = False
            self._backoff = RETRY_MIN
            self.counters.connected = True
        else:
            self._lost(f"cannot connect to the device {self.host}:{self.port}")
        return ok

    def _refused(self, what: str, rr: Any, write: bool = False) -> None:
        """The device answered ``what`` with a Modbus exception: logged once per kind of
        refusal (the link stays up; a wrong unit id or address refuses every poll, which
        logged "lost" and "connected again" every second before). A refused write is logged
        once until a write of that point succeeds (the good reads between did not count: it
        was logged every scan, found by an outside audit)."""
        code = int(getattr(rr, "exception_code", 0) or 0)
        key = f"{what}: {code}"
        if write:
            if key in self._write_refusals:
                return
            self._write_refusals.add(key)
        elif self._refusal == key:
            return
        else:
            self._refusal = key
        meaning = EXCEPTIONS.get(code, "an exception")
        effect = ("the loop's OUT is Bad (no communication) until a write succeeds" if write
                  else "its points are Bad (configuration error) meanwhile")
        self._event(f"device {self.host}:{self.port} answered {what} of unit id "
                    f"{self.regmap.device_id} with exception {code} ({meaning}): check the "
                    f"[io] map's device_id and addresses against the device; {effect}")

    def _lost(self, why: str) -> None:
        self.counters.connected = False
        if not self._lost_logged:
            self._event(f"{why}: inputs Bad (no communication); retrying every "
                        f"{RETRY_MIN:g}..{RETRY_MAX:g} s")
            self._lost_logged = True
        self._retry_at = time.monotonic() + self._backoff
        self._backoff = min(self._backoff * 2.0, RETRY_MAX)
        self.client.close()

    async def read(self) -> dict[str, tuple[float, int]]:
        """Every device output as (value, status byte) (module docstring), and the read-back
        of the last written outputs compared."""
        self.counters.reads += 1
        values: dict[str, tuple[float, int]] = {}
        regs: dict[int, int] | None = None
        if await self.connect():
            try:
                regs = {}
                for first, count in _runs(self.regmap.points):
                    rr = await self.client.read_holding_registers(
                        first, count=count, device_id=self.regmap.device_id)
                    if rr.isError():  # it answered: connected, but refused (not a lost link)
                        self.counters.read_errors += 1
                        self._refused(f"reading registers {first}..{first + count - 1}", rr)
                        for p in self.inputs:
                            last = self.last.get(p.name)
                            values[p.name] = (math.nan if last is None else last,
                                              st.BAD_CONFIGURATION_ERROR)
                        return values
                    regs.update(zip(range(first, first + count), rr.registers, strict=True))
                self._refusal = None
            except Exception as exc:  # a lost device surfaces as several exception types
                self.counters.read_errors += 1
                self._lost(f"reading the device failed ({type(exc).__name__}: {exc})")
                regs = None
        else:
            self.counters.read_errors += 1
        if regs is None:
            for p in self.inputs:
                last = self.last.get(p.name)
                values[p.name] = ((last, st.BAD_NO_COMM_LUV) if last is not None
                                  else (math.nan, st.BAD_NO_COMM_NO_LUV))
            return values
        for p in self.inputs:
            v = decode_f32([regs[p.address], regs[p.address + 1]], p.word_order)
            if math.isfinite(v):
                self.last[p.name] = v
                values[p.name] = (v, st.GOOD_NC)
            else:
                last = self.last.get(p.name)
                values[p.name] = ((last, st.BAD_DEVICE_FAILURE) if last is not None
                                  else (math.nan, st.BAD_DEVICE_FAILURE))
        for p in self.outputs:
            if p.name in self.written:
                back = decode_f32([regs[p.address], regs[p.address + 1]], p.word_order)
                want = self.written[p.name]
                if not abs(back - want) <= READBACK_TOLERANCE * max(1.0, abs(want)):
                    self.counters.readback_mismatches += 1
                    self._event(f"read-back of {p.name}: wrote {want:.6g}, device holds "
                                f"{back:.6g}")
        return values

    async def write(self, values: dict[str, float]) -> bool:
        """Write the controller outputs (point name → value); False when any write failed
        (the point's value stays unwritten; the device applies its fault action)."""
        if not self.client.connected:
            return False
        ok = True
        for p in self.outputs:
            if p.name not in values:
                continue
            value = float(values[p.name])
            if not math.isfinite(value):
                self._event(f"{p.name}: not written, value {value!r} is not finite")
                ok = False
                continue
            self.counters.writes += 1
            try:
                rr = await self.client.write_registers(
                    p.address, encode_f32(value, p.word_order), device_id=self.regmap.device_id)
                if rr.isError():  # refused, not lost: the link stays up
                    self.counters.write_errors += 1
                    self._refused(f"writing {p.name} (register {p.address})", rr, write=True)
                    ok = False
                    continue
                self._write_refusals = {k for k in self._write_refusals
                                        if not k.startswith(f"writing {p.name} ")}
            except Exception as exc:
                self.counters.write_errors += 1
                self._lost(f"writing {p.name} failed ({type(exc).__name__}: {exc})")
                return False
            # what the device holds is the float32 of the value
            self.written[p.name] = decode_f32(encode_f32(value, p.word_order), p.word_order)
        return ok

    def close(self) -> None:
        self.client.close()

    def status(self) -> dict[str, Any]:
        """The counters, JSON-able."""
        c = self.counters
        return {"connected": c.connected, "reads": c.reads, "read_errors": c.read_errors,
                "writes": c.writes, "write_errors": c.write_errors,
                "readback_mismatches": c.readback_mismatches, "reconnects": c.reconnects}
