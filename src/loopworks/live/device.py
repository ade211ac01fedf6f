"""A simulated field device: a scenario's plant blocks scanned in real time, serving their
I/O as Modbus TCP holding registers (pymodbus 3.16 ``SimDevice``/``SimData`` datastore).

Each scan (period dt/speedup wall seconds, on absolute deadlines, runtime-and-ecosystem 3.1):

1. read the device-input registers (what the controller wrote: a valve's ``op``, %) into the
   plant module's inputs;
2. run one plant scan of dt plant seconds (events of the plant side apply at their plant
   time);
3. write every device-output register (a transmitter's ``pv``), bump the heartbeat (a uint16
   scan counter, wrapping) and write the fault bits.

A late scan starts at once; one more than a period late skips to the next grid slot
("Next" semantics) and is counted in :attr:`Device.overruns`.

**Fault state** (an FF AO block that loses its setpoint, runtime-and-ecosystem 3.2): when the
controller has not written a device input for ``fstate_time`` wall seconds, that input's
fault action applies: ``"hold"`` (the default: keep the last value written) or a safe value
(``fault_actions={"valve.op": 0.0}``). It is logged once; the next good write ends it (also
logged). A non-finite value written (NaN, ±inf) is refused: the plant input keeps its last
value, the refusal is logged, and it does not count as a write for the fault timer (a Bad
setpoint is no setpoint); over Modbus it is answered with the exception "illegal data value"
and the register keeps the value the plant uses. Writes to the device's output registers are
answered with the Modbus exception "illegal data address".

**Other protocols.** :meth:`Device.write_input` is a write to a device input by another
protocol than Modbus (the OPC UA server of :mod:`loopworks.live.device_opcua`): it counts for
the fault timer like a Modbus write (the latest write of either protocol wins, and is copied
into the input's registers), and :meth:`Device.add_scan_hook` runs a coroutine after each
scan (to publish the outputs there).

Events go to the logger ``loopworks.device``; each message carries the plant time (the log
record carries the wall time).
"""

from __future__ import annotations

import asyncio
import logging
import math
import time
from collections.abc import Awaitable, Callable, Mapping

from pymodbus.constants import ExcCodes
from pymodbus.server import ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

from loopworks.blocks.block import Block
from loopworks.errors import InputError
from loopworks.live.registers import Point, RegisterMap
from loopworks.live.split import Split
from loopworks.sim.module import scan_count

log = logging.getLogger("loopworks.device")

class _Refusals(logging.Filter):
    """pymodbus logs a request it cannot serve (another unit id, an unknown register) as a
    traceback with a hex dump of the frame, on every poll; it answers exception 4 (server
    device failure) all the same. The device logs the first such request as one line and
    drops the rest (a client polling a wrong unit id filled the terminal)."""

    def __init__(self, unit: int) -> None:
        super().__init__()
        self.unit = unit
        self.count = 0

    def filter(self, record: logging.LogRecord) -> bool:
        if not record.getMessage().startswith("Datastore unable to fulfill request"):
            return True
        self.count += 1
        if self.count == 1:
            log.warning("a client asked for a unit id or register this device does not serve "
                        "(it serves unit id %d): answered Modbus exception 4 (server device "
                        "failure); further such requests are answered alike, not logged",
                        self.unit)
        return False


#: Modbus function codes that write holding registers (6 single, 16 multiple, 22 mask
#: write, 23 read/write multiple)
WRITE_CODES = frozenset({6, 16, 22, 23})
#: the read function code the device itself uses to reach its datastore
_OWN_CODE = 3
#: the largest finite float32
F32_MAX = 3.4028234663852886e38


def _after_write(point: Point, start: int, address: int, set_values: list[int] | list[bool],
                 current: list[int]) -> list[int] | None:
    """The registers of ``point`` as a write of ``set_values`` at ``address`` leaves them
    (``current``: the registers from address ``start``), or None when the write does not
    touch the point. A write of one register of a float (FC6) made its pair NaN, answered
    as a success (found by an outside audit)."""
    lo, hi = point.address, point.address + point.count
    if hi <= address or lo >= address + len(set_values):
        return None
    out = []
    for r in range(lo, hi):
        if address <= r < address + len(set_values):
            out.append(int(set_values[r - address]))
        elif 0 <= r - start < len(current):
            out.append(int(current[r - start]))
        else:
            return None
    return out


def _f32(value: float) -> float:
    """``value`` as a float32 can hold it: beyond ±3.4e38 it is ±inf."""
    return math.copysign(math.inf, value) if math.isfinite(value) and abs(
        value) > F32_MAX else value


class Device:
    """The plant side of ``split`` served over Modbus TCP with the map ``regmap``.

    ``speedup``: plant seconds per wall second (1 = real time; 20 runs a 0.5 s scan every
    25 ms). ``fstate_time``: wall seconds without a write after which a device input goes
    to its fault state. ``fault_actions``: per device input (``"valve.op"``), ``"hold"`` or
    a finite safe value in the input's units; inputs not named hold.

    Every point of the map must be a plant port (an output, or an unwired input), and every
    signal that crosses between the two sides must have a point."""

    def __init__(self, split: Split, regmap: RegisterMap, speedup: float = 1.0,
                 fstate_time: float = 5.0,
                 fault_actions: Mapping[str, str | float] | None = None) -> None:
        if not 0.0 < speedup < math.inf:
            raise InputError(f"speedup = {speedup!r} is not allowed: expected a finite "
                             "number > 0 (plant seconds per wall second)")
        if not 0.0 < fstate_time < math.inf:
            raise InputError(f"fstate_time = {fstate_time!r} s is not allowed: expected a "
                             "finite number of seconds > 0")
        self.split = split
        self.regmap = regmap
        self.module = split.plant
        self.dt = split.dt
        self.speedup = float(speedup)
        self.fstate_time = float(fstate_time)
        self.period = self.dt / self.speedup
        for each in self.module.blocks.values():
            each.check_dt(self.dt)
        # one scan, undone: each block binds its compiled step now (loaded from the plan
        # cache, or compiled), so the first real-time scan is not late by that
        saved = self.module.state_dict()
        self.module.scan(self.dt)
        self.module.load_state(saved)
        self._check_points()
        self.fault_actions: dict[str, str | float] = {p.name: p.fault_action
                                                      for p in regmap.inputs}
        for name, action in (fault_actions or {}).items():
            if name not in self.fault_actions:
                raise InputError(f"fault_actions: {name!r} is not a device input; inputs: "
                                 + ", ".join(self.fault_actions))
            if isinstance(action, str) and action.lower() == "hold":
                self.fault_actions[name] = "hold"
            elif (isinstance(action, int | float) and not isinstance(action, bool)
                  and math.isfinite(action)):
                self.fault_actions[name] = float(action)
            else:
                raise InputError(f"fault_actions: {name} = {action!r} is not allowed: "
                                 "expected 'hold' or a finite safe value")
        # per input point: where it lands in the plant (block, port), its last good value
        self._inputs: dict[str, tuple[Block, str]] = {}
        self.values: dict[str, float] = {}
        for p in regmap.inputs:
            block, port = p.name.rsplit(".", 1)
            b = self.module.blocks[block]
            self._inputs[p.name] = (b, port)
            self.values[p.name] = float(b.u[[q.name for q in b.INPUTS].index(port)])
        self._outputs: list[tuple[Point, Block, int]] = []
        for p in regmap.outputs:
            block, port = p.name.rsplit(".", 1)
            b = self.module.blocks[block]
            self._outputs.append((p, b, [q.name for q in b.OUTPUTS].index(port)))
        #: the input points in fault state
        self.faulted: set[str] = set()
        #: plant scans run since start
        self.scans = 0
        #: scans that started more than a period late (skipped to the next grid slot)
        self.overruns = 0
        self.port: int | None = None
        self._server: ModbusTcpServer | None = None
        #: the requests for another unit id or an unknown register (counted, logged once)
        self.refusals: _Refusals | None = None
        self._last_write: dict[str, float] = {}
        self._written: dict[str, float] = {}  # client writes since the last scan: wall time
        self._refusing: set[str] = set()
        self._refused_addresses: set[int] = set()
        self._stopping = False
        self._owner = {r: p.name for p in regmap.inputs for r in p.registers}
        # writes by another protocol since the last scan: (value, wall time)
        self._external: dict[str, tuple[float, float]] = {}
        self._scan_hooks: list[Callable[[], Awaitable[None]]] = []

    def write_input(self, name: str, value: float) -> None:
        """A write of device input ``name`` by another protocol than Modbus, applied at the
        next scan as a Modbus write is (a non-finite value is refused there)."""
        if name not in self.fault_actions:
            raise InputError(f"{name!r} is not a device input; inputs: "
                             + ", ".join(self.fault_actions))
        self._external[name] = (float(value), time.monotonic())

    def pending(self, name: str) -> bool:
        """True while a write of input ``name`` by another protocol awaits the next scan."""
        return name in self._external

    def add_scan_hook(self, hook: Callable[[], Awaitable[None]]) -> None:
        """Await ``hook()`` after each scan (after the outputs are written)."""
        self._scan_hooks.append(hook)

    def output_values(self) -> dict[str, float]:
        """Every device output now (point name -> value, a double: the registers hold it as
        a float32)."""
        return {p.name: float(b.y[i]) for p, b, i in self._outputs}

    def _check_points(self) -> None:
        """Each point names a plant port of the right kind; each crossing signal has one."""
        m, where = self.module, self.regmap.source
        for p in self.regmap.points:
            block, port = p.name.rsplit(".", 1)
            b = m.blocks.get(block)
            if b is None:
                raise InputError(f"{where}: point {p.name!r}: '{block}' is not a plant block; "
                                 "plant blocks: " + ", ".join(m.blocks))
            if p.direction == "output":
                names = [q.name for q in b.OUTPUTS]
                if port not in names:
                    raise InputError(f"{where}: point {p.name!r}: block '{block}' ({b.kind}) "
                                     f"has no output '{port}'; outputs: {', '.join(names)}")
            else:
                names = [q.name for q in b.INPUTS]
                if port not in names or p.name in m.wires:
                    free = [n for n in names if f"{block}.{n}" not in m.wires]
                    raise InputError(f"{where}: point {p.name!r}: not an unwired input of "
                                     f"block '{block}' ({b.kind}); unwired inputs: "
                                     + (", ".join(free) or "none"))
        mapped = {(p.name, p.direction) for p in self.regmap.points}
        for name, direction in ([(n, "input") for n in self.split.device_inputs()]
                                + [(n, "output") for n in self.split.device_outputs()]):
            if (name, direction) not in mapped:
                raise InputError(f"{where}: no {direction} point for {name!r}, which the "
                                 "controller " + ("writes" if direction == "input"
                                                  else "reads"))

    # -- time ---------------------------------------------------------------------------
    @property
    def plant_time(self) -> float:
        """Plant time of the next scan (s): scans run × dt."""
        return self.module.t

    def _stamp(self) -> str:
        return f"t = {self.module.t:g} s"

    # -- the Modbus side -----------------------------------------------------------------
    async def _action(self, function_code: int, start_address: int, address: int, count: int,
                      current_registers: list[int], set_values: list[int] | list[bool] | None
                      ) -> ExcCodes | None:
        """The datastore hook: a client's write to an input point is timestamped; one that
        touches any other register is refused (illegal data address)."""
        if set_values is None or function_code not in WRITE_CODES:
            return None
        touched = range(address, address + count)
        foreign = [r for r in touched if r not in self._owner]
        if foreign:
            if foreign[0] not in self._refused_addresses:
                self._refused_addresses.add(foreign[0])
                log.warning("%s: a client wrote register %d, which is not a device input: "
                            "refused (illegal data address)", self._stamp(), foreign[0])
            return ExcCodes.ILLEGAL_ADDRESS
        for point in self.regmap.inputs:  # a point written, whole or in part: finite
            regs = _after_write(point, start_address, address, set_values, current_registers)
            if regs is not None:
                value = point.decode(regs)
                if not math.isfinite(value):
                    if point.name not in self._refusing:  # once per run of refusals
                        self._refusing.add(point.name)
                        log.warning("%s: %s: refused the non-finite value %r written (illegal "
                                    "data value); the plant keeps %g", self._stamp(),
                                    point.name, value, self.values[point.name])
                    return ExcCodes.ILLEGAL_VALUE
        now = time.monotonic()
        for r in touched:
            self._written[self._owner[r]] = now
        return None

    def _registers(self) -> list[SimData]:
        data = [SimData(p.address, values=p.encode(self.values[p.name]),
                        datatype=DataType.REGISTERS) for p in self.regmap.inputs]
        data += [SimData(p.address, values=p.encode(_f32(float(b.y[i]))),
                         datatype=DataType.REGISTERS) for p, b, i in self._outputs]
        for address in (self.regmap.heartbeat_address, self.regmap.fault_bits_address):
            if address is not None:
                data.append(SimData(address, values=[0], datatype=DataType.REGISTERS))
        return sorted(data, key=lambda d: d.address)

    async def start(self, host: str = "127.0.0.1", port: int = 0) -> int:
        """Serve the registers on ``host``:``port`` (0: any free port); return the port."""
        if self._server is not None:
            raise InputError("the device is serving already: stop() it first")
        if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
            raise InputError(f"port = {port!r} is not allowed: expected 0..65535 (0: any "
                             "free port)")
        device = SimDevice(id=self.regmap.device_id, simdata=self._registers(),
                           action=self._action)
        pymodbus_log = logging.getLogger("pymodbus.logging")
        for old in [f for f in pymodbus_log.filters if isinstance(f, _Refusals)]:
            pymodbus_log.removeFilter(old)
        self.refusals = _Refusals(self.regmap.device_id)
        pymodbus_log.addFilter(self.refusals)
        server = ModbusTcpServer(device, address=(host, port))
        try:
            await server.serve_forever(background=True)
        except (RuntimeError, OSError) as exc:
            raise InputError(f"cannot serve Modbus TCP on {host}:{port} ({exc}): is the "
                             "port in use, or the address not this machine's?") from None
        sockets = getattr(server.transport, "sockets", None) or []
        self.port = int(sockets[0].getsockname()[1]) if sockets else port
        self._server = server
        self._stopping = False
        now = time.monotonic()
        self._last_write = {p.name: now for p in self.regmap.inputs}
        log.info("%s: serving Modbus TCP on %s:%d, device id %d: %d points, plant scan "
                 "%g s every %g s of wall time (speedup %g)", self._stamp(), host, self.port,
                 self.regmap.device_id, len(self.regmap.points), self.dt, self.period,
                 self.speedup)
        return self.port

    async def stop(self) -> None:
        """Stop serving (the next client request fails); the plant keeps its state."""
        self._stopping = True
        server, self._server = self._server, None
        if server is not None:
            await server.shutdown()  # type: ignore[no-untyped-call]
            log.info("%s: stopped after %d scans (%d overruns)", self._stamp(), self.scans,
                     self.overruns)

    # -- the scan ------------------------------------------------------------------------
    async def run(self, duration: float | None = None) -> None:
        """Scan for ``duration`` plant seconds (None: until :meth:`stop` or cancellation),
        one scan every dt/speedup wall seconds on absolute deadlines."""
        if self._server is None:
            raise InputError("the device is not serving: await start() first")
        n = None if duration is None else scan_count(duration, self.dt)
        loop = asyncio.get_running_loop()
        deadline = loop.time()
        done = 0
        while not self._stopping and (n is None or done < n):
            await self.scan()
            done += 1
            deadline += self.period
            late = loop.time() - deadline
            if late > self.period:  # "Next": skip the missed slots, count the overrun
                missed = math.floor(late / self.period)
                deadline += missed * self.period
                if not self.overruns:
                    log.warning("%s: a scan ran %.3g s late (period %g s): skipping to the "
                                "next slot; later overruns are counted, not logged",
                                self._stamp(), late, self.period)
                self.overruns += 1
            await asyncio.sleep(max(0.0, deadline - loop.time()))

    async def scan(self) -> None:
        """One device scan: inputs from the registers, one plant scan, outputs, heartbeat."""
        server = self._server
        if server is None:
            raise InputError("the device is not serving: await start() first")
        dev_id = self.regmap.device_id
        now = time.monotonic()
        for p in self.regmap.inputs:
            name = p.name
            wrote = self._written.pop(name, None)
            other = self._external.pop(name, None)
            value = math.nan
            if wrote is not None:
                regs = await server.async_getValues(dev_id, _OWN_CODE, p.address, p.count)
                value = p.decode([int(r) for r in regs])
            if other is not None and (wrote is None or other[1] >= wrote):
                value, wrote = other  # the latest write wins, Modbus or not
                if math.isfinite(value):
                    await server.async_setValues(dev_id, _OWN_CODE, p.address,
                                                 p.encode(_f32(value)))
            if wrote is not None:
                if math.isfinite(value):
                    self.values[name] = value
                    self._last_write[name] = wrote
                    self._refusing.discard(name)
                    if name in self.faulted:
                        self.faulted.discard(name)
                        log.info("%s: %s written again (%g): fault state ends",
                                 self._stamp(), name, value)
                elif name not in self._refusing:
                    self._refusing.add(name)
                    log.warning("%s: %s: refused the non-finite value %r written; the plant "
                                "keeps %g", self._stamp(), name, value, self.values[name])
            if name not in self.faulted and now - self._last_write[name] > self.fstate_time:
                self.faulted.add(name)
                action = self.fault_actions[name]
                what = (f"holds {self.values[name]:g}" if action == "hold"
                        else f"goes to its fault value {action:g}")
                log.warning("%s: %s not written for %g s (fstate_time %g s): fault state, "
                            "the input %s", self._stamp(), name, now - self._last_write[name],
                            self.fstate_time, what)
            block, port = self._inputs[name]
            block.set_inputs({port: self.applied(name)})
        self.module.scan(self.dt)
        self.scans += 1
        for p, block, i in self._outputs:
            await server.async_setValues(dev_id, _OWN_CODE, p.address,
                                         p.encode(_f32(float(block.y[i]))))
        if self.regmap.heartbeat_address is not None:
            await server.async_setValues(dev_id, _OWN_CODE, self.regmap.heartbeat_address,
                                         [self.scans & 0xFFFF])
        if self.regmap.fault_bits_address is not None:
            bits = sum(1 << i for i, p in enumerate(self.regmap.inputs)
                       if p.name in self.faulted)
            await server.async_setValues(dev_id, _OWN_CODE, self.regmap.fault_bits_address,
                                         [bits])
        for hook in self._scan_hooks:
            await hook()

    def applied(self, name: str) -> float:
        """The value device input ``name`` gives the plant now (its fault value while in a
        fault state with one, else the last good value written)."""
        if name not in self.fault_actions:
            raise InputError(f"{name!r} is not a device input; inputs: "
                             + ", ".join(self.fault_actions))
        action = self.fault_actions[name]
        if name in self.faulted and not isinstance(action, str):
            return action
        return self.values[name]
