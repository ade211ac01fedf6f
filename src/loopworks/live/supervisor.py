"""``loopworks serve`` as processes: the controller scans in a process of its own, so nothing an
OPC UA client does (a flood of requests, a login's password hashing) can stall its scans.

* the **controller process** runs :class:`~loopworks.live.serve.LiveController` on its
  scheduler, with its Modbus I/O; at the start of each scan it takes the operators' pending
  writes from a command queue (validated there, by the blocks' rules, and answered), and after
  each scan it puts its snapshot on an event queue (dropped, never waited for, when the queue
  is full: the scans do not wait for the server);
* this process (the **supervisor**) runs the OPC UA server: it publishes the snapshots, and
  hands each client's write to the controller process, answering the client with the
  controller's verdict (``BadTimeout`` when there is none within :data:`REPLY_TIMEOUT`);
  each write carries a deadline, :data:`APPLY_MARGIN` s before that answer is due, and the
  controller drops (never applies) a write it takes from the queue after its deadline (a
  stalled controller resuming): a write the client was told failed is never made later;
* without ``--device`` (and without a ``url`` in an OPC UA ``[io]`` table), the scenario's
  plant runs in a third process as the device (serving OPC UA as well when the table says
  ``protocol = "opcua"``);
* with ``--faceplate``, the operator's web faceplate (``loopworks faceplate``) runs in a
  process of its own as an OPC UA client of this one, so a browser cannot stall either.

The supervisor is the controller's watchdog: a controller process that dies (killed, a crash)
is started again at once, and resumes from its last checkpoint (at most
:data:`MAX_RESTARTS` times a minute); a controller process whose supervisor dies stops
(saving its checkpoint). Processes are *spawned*, not forked, so no event loop or lock of the
parent is inherited.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import logging
import multiprocessing as mp
import os
import queue
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from loopworks.errors import InputError, LoopworksError
from loopworks.live.opcua import Variable, WriteRefused
from loopworks.live.tasks import cancel_and_wait

log = logging.getLogger("loopworks.serve")

#: how long a client's write waits for the controller's answer, s
REPLY_TIMEOUT = 5.0
#: a write the controller takes later than this before its answer is due is dropped, s:
#: room for the controller's checkpoint and its answer to reach the supervisor in time
APPLY_MARGIN = 1.0
#: how long the controller process may take to start (a fresh machine compiles kernels), s
START_TIMEOUT = 300.0
#: restarts of a dying controller allowed within a minute
MAX_RESTARTS = 5
#: snapshots the event queue holds before new ones are dropped
QUEUE_SIZE = 1000


@dataclass(frozen=True)
class Job:
    """What the controller process runs (picklable)."""

    config: str | None
    variant: str | None
    device: str  # modbus://HOST:PORT or opc.tcp://HOST:PORT/PATH
    speedup: float
    duration: float | None
    state_dir: str


def log_to_stderr() -> None:
    """The live loggers' events on stderr, each with its time (every process of serve)."""
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s"))
    for name in ("loopworks.serve", "loopworks.device"):
        logger = logging.getLogger(name)
        logger.addHandler(handler)
        logger.setLevel(logging.INFO)


# -- the controller process ------------------------------------------------------------------

def controller_main(job: Job, commands: Any, events: Any) -> None:
    """Entry point of the controller process. A user error (a checkpoint of another
    scenario ...) is sent to the supervisor as ``("error", message)`` for its one ``error:``
    line, and the process exits with code 2, without a traceback."""
    log_to_stderr()
    try:
        asyncio.run(_controller(job, commands, events))
    except LoopworksError as exc:
        with contextlib.suppress(Exception):
            events.put(("error", str(exc)), timeout=2.0)
        sys.exit(2)


def take_commands(ctl: Any, commands: Any, events: Any,
                  now: Callable[[], float] = time.monotonic) -> bool:
    """Apply the operators' pending writes from ``commands`` to ``ctl`` (a LiveController),
    each answered on ``events`` as ``("reply", ident, code or None, message)``; True when a
    stop command came. A write is ``("write", ident, deadline, user, role, loop, name,
    value)``: taken after ``deadline`` (``time.monotonic``, the same clock in every process
    of the machine), it is dropped, not applied, and answered BadTimeout: its client has been
    (or is being) told it failed."""
    while True:
        try:
            cmd = commands.get_nowait()
        except queue.Empty:
            return False
        if cmd[0] == "stop":
            return True
        _, ident, deadline, user, role, name, var, value = cmd
        late = now() - deadline
        try:
            if late > 0.0:
                log.warning("write %s.%s = %r by %s: dropped, not applied: it reached the "
                            "controller %.3g s after its deadline, when its client had been "
                            "told it failed (BadTimeout)", name, var, value, user, late)
                raise WriteRefused("BadTimeout", "the controller took the write too late: "
                                   "it was not applied")
            ctl.write(user, role, name, var, value)
            reply: tuple[Any, ...] = ("reply", ident, None, "")
        except WriteRefused as exc:
            reply = ("reply", ident, exc.code, exc.message)
        except Exception as exc:  # answered, never a crash of the scans
            log.exception("write %s.%s = %r failed", name, var, value)
            reply = ("reply", ident, "BadInternalError", str(exc))
        with contextlib.suppress(queue.Full):  # never wait for the supervisor
            events.put_nowait(reply)


async def _controller(job: Job, commands: Any, events: Any) -> None:
    from loopworks.live.devices import MultiIO, has_devices, links_of
    from loopworks.live.registers import map_of
    from loopworks.live.serve import LiveController, close_io, make_io, run_controller
    from loopworks.live.split import split_scenario
    from loopworks.sim.scenario import load_scenario

    sc = load_scenario(job.config)
    split = split_scenario(sc, job.variant)
    io: Any
    if has_devices(sc):  # several devices, each at the url of its table
        links = links_of(sc, split)
        io = MultiIO(links, split.dt)
        maps: Any = [link.regmap for link in links]
    else:
        maps = map_of(sc, split)
        io = make_io(maps, job.device)
    ctl = LiveController(split, maps, io,
                         checkpoint=Path(job.state_dir) / "checkpoint.json")
    events.put(("hello", ctl.loops(), ctl.resumed, ctl.scans, ctl.dt))
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(NotImplementedError, RuntimeError):
            loop.add_signal_handler(sig, stop.set)
    parent = os.getppid()

    def before() -> None:
        if os.getppid() != parent:  # the supervisor is gone: stop, saving the checkpoint
            log.error("the supervisor process is gone: stopping")
            stop.set()
            return
        if take_commands(ctl, commands, events):
            stop.set()

    def publish(snapshot: dict[str, tuple[float, int]]) -> None:
        with contextlib.suppress(queue.Full):
            events.put_nowait(("snap", snapshot))

    try:
        stats = await run_controller(ctl, speedup=job.speedup, duration=job.duration,
                                     stop=stop, publish=publish, before=before)
        with contextlib.suppress(queue.Full):
            events.put(("done", stats.summary(), io.status()), timeout=2.0)
    finally:
        await close_io(io)


# -- the device process ------------------------------------------------------------------------

def device_main(config: str | None, variant: str | None, speedup: float, conn: Any,
                opcua: bool = False) -> None:
    """Entry point of the built-in device's process: sends its URL on ``conn`` (its OPC UA
    endpoint when ``opcua``, else modbus://127.0.0.1:PORT)."""
    log_to_stderr()

    async def run() -> None:
        from loopworks.live.device import Device
        from loopworks.live.registers import map_of
        from loopworks.live.split import split_scenario
        from loopworks.sim.scenario import load_scenario

        sc = load_scenario(config)
        split = split_scenario(sc, variant)
        device = Device(split, map_of(sc, split), speedup=speedup)
        url = f"modbus://127.0.0.1:{await device.start('127.0.0.1', 0)}"
        ua_server = None
        if opcua:
            from loopworks.live.device_opcua import DeviceOpcua

            ua_server = DeviceOpcua(device, "127.0.0.1", 0)
            url = await ua_server.start()
        conn.send(url)
        stop = asyncio.Event()
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGINT, signal.SIGTERM):
            with contextlib.suppress(NotImplementedError, RuntimeError):
                loop.add_signal_handler(sig, stop.set)
        task = asyncio.create_task(device.run())
        await stop.wait()
        if ua_server is not None:
            await ua_server.stop()
        await device.stop()
        await cancel_and_wait(task)

    asyncio.run(run())


# -- the supervisor ----------------------------------------------------------------------------

class ControllerProcess:
    """The supervisor's handle on the controller process: the OPC UA server's controller
    (``loops``, ``write``), restarted from its checkpoint when it dies."""

    def __init__(self, job: Job) -> None:
        self.job = job
        self.ctx = mp.get_context("spawn")
        self.commands: Any = None
        self.events: Any = None
        self.proc: Any = None
        self._loops: dict[str, list[Variable]] = {}
        self.resumed = False
        self.scans = 0
        self.dt = 0.0
        self.stats: dict[str, Any] = {}
        self.io: dict[str, Any] = {}
        self.restarts: list[float] = []
        #: True when the controller died too often and the supervisor gave up (serve exits 1)
        self.gave_up = False
        self._ids = itertools.count()
        self._pending: dict[int, asyncio.Future[tuple[str | None, str]]] = {}

    async def start(self) -> None:
        """Start the process and wait for its hello (its loops). Each start has new queues:
        a process killed while writing to one may leave its lock held."""
        self.commands = self.ctx.Queue()
        self.events = self.ctx.Queue(QUEUE_SIZE)
        self.proc = self.ctx.Process(target=controller_main,
                                     args=(self.job, self.commands, self.events),
                                     name="loopworks-controller")
        self.proc.start()
        end = time.monotonic() + START_TIMEOUT
        while True:
            msg = await self._get(0.2)
            if msg is not None and msg[0] == "hello":
                _, self._loops, self.resumed, self.scans, self.dt = msg
                return
            if msg is not None and msg[0] == "error":  # a user error, already worded
                self.proc.join(10)
                raise InputError(msg[1])
            if not self.proc.is_alive():
                raise InputError(f"the controller process stopped before it started (exit "
                                 f"code {self.proc.exitcode}); see its messages above")
            if time.monotonic() > end:
                self.proc.terminate()
                raise InputError(f"the controller process did not start within "
                                 f"{START_TIMEOUT:g} s")

    async def _get(self, timeout: float) -> Any:
        def get() -> Any:
            try:
                return self.events.get(timeout=timeout)
            except queue.Empty:
                return None

        return await asyncio.get_running_loop().run_in_executor(None, get)

    def loops(self) -> dict[str, list[Variable]]:
        return self._loops

    def write(self, user: str | None, role: str | None, loop: str, name: str,
              value: float | int) -> Any:
        ident = next(self._ids)
        fut: asyncio.Future[tuple[str | None, str]] = (
            asyncio.get_running_loop().create_future())
        self._pending[ident] = fut
        deadline = time.monotonic() + REPLY_TIMEOUT - APPLY_MARGIN  # take_commands
        self.commands.put(("write", ident, deadline, user, role, loop, name, value))
        return self._answer(ident, fut)

    async def _answer(self, ident: int, fut: asyncio.Future[tuple[str | None, str]]) -> None:
        try:
            code, message = await asyncio.wait_for(fut, REPLY_TIMEOUT)
        except TimeoutError:
            raise WriteRefused("BadTimeout", f"the controller did not answer within "
                               f"{REPLY_TIMEOUT:g} s") from None
        finally:
            self._pending.pop(ident, None)
        if code is not None:
            raise WriteRefused(code, message)

    async def pump(self, publish: Callable[[dict[str, tuple[float, int]]], Any],
                   stop: asyncio.Event) -> None:
        """Publish the controller's snapshots and deliver its answers until it finishes;
        restart it from its checkpoint when it dies; on ``stop``, stop it."""
        stopping = False
        while True:
            if stop.is_set() and not stopping:
                stopping = True
                self.commands.put(("stop",))
            msg = await self._get(0.1)
            if msg is not None:
                kind = msg[0]
                if kind == "snap":
                    await publish(msg[1])
                elif kind == "reply":
                    fut = self._pending.get(msg[1])
                    if fut is not None and not fut.done():
                        fut.set_result((msg[2], msg[3]))
                elif kind == "done":
                    self.stats, self.io = msg[1], msg[2]
                continue
            if self.proc.is_alive():
                continue
            self.proc.join()
            if self.proc.exitcode == 0 or stopping:
                return
            now = time.monotonic()
            self.restarts = [t for t in self.restarts if now - t < 60.0] + [now]
            if len(self.restarts) > MAX_RESTARTS:
                log.error("the controller process died %d times within a minute: giving up",
                          len(self.restarts))
                self.gave_up = True
                return
            log.error("the controller process died (exit code %s): restarting it from its "
                      "checkpoint", self.proc.exitcode)
            await self.start()
            log.info("controller restarted in process %d%s", self.proc.pid,
                     f", resumed at scan {self.scans}" if self.resumed
                     else " from the scenario's start (no checkpoint)")

    def stop_now(self) -> None:
        if self.proc is not None and self.proc.is_alive():
            self.proc.terminate()
            self.proc.join(10)


async def start_device(config: str | None, variant: str | None, speedup: float,
                       opcua: bool = False) -> tuple[Any, str]:
    """The built-in device in a process of its own on 127.0.0.1: (process, its URL: the
    OPC UA endpoint when ``opcua``, else modbus://127.0.0.1:PORT)."""
    ctx = mp.get_context("spawn")
    here, there = ctx.Pipe()
    proc = ctx.Process(target=device_main, args=(config, variant, speedup, there, opcua),
                       name="loopworks-device")
    proc.start()

    def wait() -> str:
        if not here.poll(START_TIMEOUT):
            raise InputError("the device process did not start")
        return str(here.recv())

    try:
        url = await asyncio.get_running_loop().run_in_executor(None, wait)
    except (EOFError, OSError):
        raise InputError(f"the device process stopped before it started (exit code "
                         f"{proc.exitcode})") from None
    return proc, url


def start_faceplate(endpoint: str, port: int) -> subprocess.Popen[bytes]:
    """``loopworks faceplate ENDPOINT --port PORT`` in a process of its own (its output goes
    to this process's)."""
    log.info("starting the faceplate on http://127.0.0.1:%d/", port)
    return subprocess.Popen([sys.executable, "-m", "loopworks", "faceplate", endpoint,
                             "--port", str(port)])


def stop_faceplate(proc: subprocess.Popen[bytes]) -> None:
    """Stop the faceplate process (SIGTERM, then SIGKILL after 5 s)."""
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(5)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(5)


async def run(config: str | Path | None = None, *, device: str | None = None,
              host: str = "127.0.0.1", opcua_port: int = 4840, users: Path | None = None,
              speedup: float = 1.0, duration: float | None = None, variant: str | None = None,
              state_dir: Path = Path("loopworks-state"), stop: asyncio.Event | None = None,
              ready: Callable[[dict[str, Any]], Any] | None = None,
              faceplate_port: int | None = None) -> dict[str, Any]:
    """``loopworks serve`` (module docstring): the scenario is checked here first (a located
    error before any process starts); ``ready`` gets what is listening (``loops``, ``dt``,
    ``device``, ``endpoint``, ``resumed``, ``scans``, ``checkpoint``, the controller
    process's ``pid``) before the first
    scan's snapshot is published. ``faceplate_port``: start ``loopworks faceplate`` on
    127.0.0.1 at that port beside the controller (stopped with it). Returns the controller's
    scan statistics."""
    from loopworks.live.opcua import LoopServer
    from loopworks.live.serve import device_of
    from loopworks.live.split import split_scenario
    from loopworks.live.users import load_users
    from loopworks.sim.scenario import load_scenario

    if not (speedup > 0.0 and speedup < float("inf")):
        raise InputError(f"speedup = {speedup!r} is not allowed: it must be > 0 and finite")
    from loopworks.live.registers import map_of

    if faceplate_port is not None:
        from loopworks.live.opcua import _is_loopback

        if not _is_loopback(host):
            raise InputError(f"--faceplate: the faceplate connects to the OPC UA server "
                             f"without security, which is offered on a loopback address only; "
                             f"--host {host} is not one (run loopworks faceplate yourself)")
    from loopworks.live.devices import has_devices, links_of

    sc = load_scenario(config)
    dev_proc = None
    if has_devices(sc):  # several devices: each at the url of its [io.devices.NAME] table
        if device is not None:
            raise InputError("--device is for a scenario with one device; this one's [io] "
                             "table names several ([io.devices.NAME], each with its url)")
        links = links_of(sc, split_scenario(sc, variant))  # errors now, not in a child
        target: str | None = ", ".join(link.url for link in links)
        regmap = links[0].regmap
    else:
        regmap = map_of(sc, split_scenario(sc, variant))  # errors now, not in a child process
        target = device_of(regmap, device)
    checkpoint = Path(state_dir) / "checkpoint.json"
    if checkpoint.exists():  # another module's: one error line before any process starts
        from loopworks.live.serve import read_checkpoint

        read_checkpoint(checkpoint, split_scenario(sc, variant).controller)
    accounts = load_users(users) if users is not None else None
    stop = stop or asyncio.Event()
    if target is None:
        dev_proc, target = await start_device(None if config is None else str(config),
                                              variant, speedup, regmap.protocol == "opcua")
    job = Job(None if config is None else str(config), variant, target, speedup, duration,
              str(state_dir))
    ctl = ControllerProcess(job)
    try:
        await ctl.start()
        server = LoopServer(ctl, accounts, host=host, port=opcua_port,
                            certificate_dir=state_dir / "pki")
        endpoint = await server.start()
        face = None if faceplate_port is None else start_faceplate(endpoint, faceplate_port)
        try:
            if ready is not None:
                ready({"loops": list(ctl.loops()), "dt": ctl.dt, "endpoint": endpoint,
                       "device": target, "resumed": ctl.resumed,
                       "scans": ctl.scans, "checkpoint": state_dir / "checkpoint.json",
                       "pid": ctl.proc.pid})
            await ctl.pump(server.publish, stop)
        finally:
            if face is not None:
                stop_faceplate(face)
            await server.stop()
    finally:
        ctl.stop_now()
        if dev_proc is not None and dev_proc.is_alive():
            dev_proc.terminate()
            dev_proc.join(10)
    return {"stats": ctl.stats, "io": ctl.io, "checkpoint": state_dir / "checkpoint.json",
            "gave_up": ctl.gave_up}
