"""Issue 16, done-when, against real processes on 127.0.0.1: ``loopworks device`` and
``loopworks serve`` as subprocesses, an asyncua client as the operator's station.

One run (module fixture) of the device and the controller at speedup 10 (a 0.5 s scan every
50 ms of wall time); the tests run in order on it: reads, writes and refusals, the device
killed and restarted, the controller killed and restarted from its checkpoint."""

from __future__ import annotations

import asyncio
import contextlib
import os
import random
import re
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

asyncua = pytest.importorskip("asyncua")  # an ordinary dependency: always there
from asyncua import Client, ua  # noqa: E402

SPEEDUP = 10.0
SCAN_WALL = 0.5 / SPEEDUP  # s of wall time per controller scan
MAN, AUTO = 3, 4


_ISSUED: set[int] = set()


def free_port() -> int:
    """A port on 127.0.0.1 that binds now and that this test process has not handed out before.

    Drawn below the kernel's ephemeral range (32768-60999 on Linux), so that no client's outgoing
    connection takes it between this check and the server's bind; and never the same twice (two
    calls that each bind port 0 and close can get the same port back: CI once started the device
    and the OPC UA server both on 42913)."""
    rng = random.Random(os.getpid() ^ time.monotonic_ns())
    for _ in range(1000):
        port = rng.randrange(20000, 32768)
        if port in _ISSUED:
            continue
        with socket.socket() as s:
            try:
                s.bind(("127.0.0.1", port))
            except OSError:
                continue
        _ISSUED.add(port)
        return port
    raise RuntimeError("no free port in 20000-32767 on 127.0.0.1")


def loopworks(*args: str, cwd: Path, stdin: str | None = None) -> subprocess.Popen[str]:
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    return subprocess.Popen([sys.executable, "-m", "loopworks", *args], cwd=cwd, env=env,
                            stdin=subprocess.PIPE if stdin is not None else None,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


class Output:
    """A process's merged stdout and stderr, drained by a thread (a full pipe would stall the
    process's logging, and with it its scans)."""

    def __init__(self, proc: subprocess.Popen[str]) -> None:
        self.lines: list[str] = []
        self.seen = 0
        assert proc.stdout is not None
        stream = proc.stdout
        threading.Thread(target=lambda: self.lines.extend(iter(stream.readline, "")),
                         daemon=True).start()


OUTPUT: dict[int, Output] = {}


def wait_for_line(proc: subprocess.Popen[str], text: str, timeout: float = 60.0) -> list[str]:
    """The process's new lines up to the first that holds ``text``."""
    out = OUTPUT.get(proc.pid)
    if out is None:  # one reader per process (a second thread would take lines from it)
        out = OUTPUT[proc.pid] = Output(proc)
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        for i in range(out.seen, len(out.lines)):
            if text in out.lines[i]:
                new, out.seen = out.lines[out.seen:i + 1], i + 1
                return new
        if proc.poll() is not None and len(out.lines) == out.seen:
            break
        time.sleep(0.02)
    raise AssertionError(f"no line with {text!r} within {timeout} s:\n" + "".join(out.lines))


class Live:
    def __init__(self, tmp: Path) -> None:
        self.tmp = tmp
        self.modbus = free_port()
        self.opcua = free_port()
        users = tmp / "users.toml"
        add = loopworks("users", "add", str(users), "op", "--role", "operator", cwd=tmp,
                        stdin="secret\n")
        add.communicate("secret\n", timeout=60)
        assert add.returncode == 0
        self.users = users
        self.device: subprocess.Popen[str] | None = None
        self.serve: subprocess.Popen[str] | None = None
        self.controller_pid = 0

    def start_device(self) -> None:
        self.device = loopworks("device", "--modbus-port", str(self.modbus), "--speedup",
                                str(SPEEDUP), "--fstate-time", "30", "--map-file",
                                str(self.tmp / "map.toml"), cwd=self.tmp)
        wait_for_line(self.device, "serving Modbus TCP")

    def start_serve(self) -> list[str]:
        self.serve = loopworks("serve", "--device", f"modbus://127.0.0.1:{self.modbus}",
                               "--opcua-port", str(self.opcua), "--users", str(self.users),
                               "--speedup", str(SPEEDUP), "--state-dir",
                               str(self.tmp / "state"), cwd=self.tmp)
        lines = wait_for_line(self.serve, "namespace urn:loopworks")
        line = next(ln for ln in lines if ln.startswith("controlling "))
        found = re.search(r"in process (\d+)", line)  # "...; resumed from ..." may follow
        assert found is not None, line
        self.controller_pid = int(found.group(1))
        return lines

    @property
    def url(self) -> str:
        return f"opc.tcp://127.0.0.1:{self.opcua}/loopworks/"

    def stop(self) -> None:
        for proc in (self.serve, self.device):
            if proc is not None and proc.poll() is None:
                proc.send_signal(signal.SIGINT)
                try:
                    proc.wait(timeout=20)
                except subprocess.TimeoutExpired:
                    proc.kill()


@pytest.fixture(scope="module")
def live(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Live]:
    run = Live(tmp_path_factory.mktemp("live"))
    run.start_device()
    run.start_serve()
    yield run
    run.stop()


async def read(client: Client, idx: int, name: str) -> ua.DataValue:
    node = client.get_node(ua.NodeId(f"pid.{name}", idx))
    return await node.read_data_value(raise_on_bad_status=False)


async def until(client: Client, idx: int, name: str, ok: Any, timeout: float) -> ua.DataValue:
    end = time.monotonic() + timeout
    while True:
        dv = await read(client, idx, name)
        if ok(dv) or time.monotonic() > end:
            return dv
        await asyncio.sleep(SCAN_WALL / 2)


def test_the_loop_runs_and_an_operator_moves_its_setpoint(live: Live) -> None:
    async def main() -> None:
        async with Client(live.url) as anon:
            idx = await anon.get_namespace_index("urn:loopworks")
            mode = await until(anon, idx, "MODE_ACTUAL", lambda d: d.Value.Value == AUTO, 20)
            assert mode.Value.Value == AUTO  # the scenario's AUTO event at t = 5 s
            # the scenario's events run live at their plant times: its SP step at 60 s
            # would override an operator's SP written before (docs/live.md)
            scans = await until(anon, idx, "SCANS", lambda d: d.Value.Value >= 125, 30)
            assert scans.Value.Value >= 125
            for name in ("PV", "SP", "OUT"):
                dv = await read(anon, idx, name)
                assert dv.StatusCode.is_good(), name
                assert isinstance(dv.Value.Value, float)
            # anonymous clients read, never write
            with pytest.raises(ua.UaStatusCodeError) as info:
                await anon.get_node(ua.NodeId("pid.SP", idx)).write_value(60.0)
            assert info.value.code == ua.StatusCodes.BadUserAccessDenied
        bad = Client(live.url)
        bad.set_user("op")
        bad.set_password("wrong")
        with pytest.raises(ua.UaStatusCodeError) as info:  # refused at session activation
            await bad.connect()
        assert info.value.code == ua.StatusCodes.BadUserAccessDenied
        with contextlib.suppress(Exception):
            await bad.disconnect()
        op = Client(live.url)
        op.set_user("op")
        op.set_password("secret")
        async with op:
            idx = await op.get_namespace_index("urn:loopworks")
            pv0 = (await read(op, idx, "PV")).Value.Value
            await op.get_node(ua.NodeId("pid.SP", idx)).write_value(pv0 + 10.0)
            # SP shows the DeltaV PID's working SP, a 32-bit float (spec vendor-blocks 4.1)
            sp = await until(op, idx, "SP", lambda d: abs(d.Value.Value - (pv0 + 10.0)) < 1e-4,
                             5)
            assert sp.Value.Value == pytest.approx(pv0 + 10.0)
            # the PV follows: within 120 s of plant time (12 s of wall) it is near the new SP
            pv = await until(op, idx, "PV",
                             lambda d: abs(d.Value.Value - (pv0 + 10.0)) < 1.5, 30)
            assert abs(pv.Value.Value - (pv0 + 10.0)) < 1.5
            with pytest.raises(ua.UaStatusCodeError) as info:
                await op.get_node(ua.NodeId("pid.SP", idx)).write_value(1000.0)
            assert info.value.code == ua.StatusCodes.BadOutOfRange

    asyncio.run(main())


def test_a_lost_device_makes_the_pv_bad_and_holds_out_then_the_loop_recovers(
        live: Live) -> None:
    async def main() -> None:
        async with Client(live.url) as c:
            idx = await c.get_namespace_index("urn:loopworks")
            assert (await read(c, idx, "PV")).StatusCode.is_good()
            assert live.device is not None
            scans0 = (await read(c, idx, "SCANS")).Value.Value
            live.device.kill()
            live.device.wait(timeout=10)
            pv = await until(c, idx, "PV", lambda d: d.StatusCode.is_bad(), 5)
            scans1 = (await read(c, idx, "SCANS")).Value.Value
            assert pv.StatusCode.value == ua.StatusCodes.BadNoCommunication
            # within 2 scans (one more for the scan the client's read may lag by)
            assert scans1 - scans0 <= 3
            mode = await read(c, idx, "MODE_ACTUAL")
            assert mode.Value.Value == MAN  # DeltaV: actual mode Man on a Bad PV (spec 4.5)
            out1 = (await read(c, idx, "OUT")).Value.Value
            await asyncio.sleep(5 * SCAN_WALL)
            assert (await read(c, idx, "OUT")).Value.Value == out1  # held
            assert (await read(c, idx, "MODE")).Value.Value == AUTO  # the target is kept
            live.start_device()
            restarted = time.monotonic()
            pv = await until(c, idx, "PV", lambda d: d.StatusCode.is_good(), 10)
            assert pv.StatusCode.is_good()
            assert time.monotonic() - restarted < 2.0
            mode = await until(c, idx, "MODE_ACTUAL", lambda d: d.Value.Value == AUTO, 5)
            assert mode.Value.Value == AUTO  # back to its target once the PV is Good

    asyncio.run(main())
    assert live.serve is not None and live.serve.poll() is None  # no crash


def operator(live: Live) -> Client:
    c = Client(live.url)
    c.set_user("op")
    c.set_password("secret")
    return c


async def man_at(live: Live, out: float) -> None:
    async with operator(live) as c:
        idx = await c.get_namespace_index("urn:loopworks")
        await c.get_node(ua.NodeId("pid.MODE", idx)).write_value(
            ua.Variant(MAN, ua.VariantType.Int32))
        await c.get_node(ua.NodeId("pid.OUT", idx)).write_value(out)
        dv = await until(c, idx, "OUT", lambda d: d.Value.Value == out, 5)
        assert dv.Value.Value == out


async def expect_resumed_at(live: Live, out: float) -> None:
    async with operator(live) as c:
        idx = await c.get_namespace_index("urn:loopworks")
        dv = await until(c, idx, "OUT", lambda d: d.StatusCode.is_good(), 10)
        assert dv.Value.Value == out
        assert (await read(c, idx, "MODE_ACTUAL")).Value.Value == MAN
        # back to AUTO: the DeltaV PID's return from MAN is bumpless (spec 4.5), so its
        # first moves start from where OUT was
        await c.get_node(ua.NodeId("pid.MODE", idx)).write_value(
            ua.Variant(AUTO, ua.VariantType.Int32))
        mode = await until(c, idx, "MODE_ACTUAL", lambda d: d.Value.Value == AUTO, 5)
        assert mode.Value.Value == AUTO
        assert abs((await read(c, idx, "OUT")).Value.Value - out) < 3.0


def restarted_pid(line: str) -> int:
    """The new controller process of serve's "controller restarted in process N" line."""
    found = re.search(r"restarted in process (\d+)", line)
    assert found is not None, line
    return int(found.group(1))


def test_a_killed_controller_is_restarted_from_its_checkpoint_without_a_bump(
        live: Live) -> None:
    # the operator puts the loop in MAN at OUT = 37 %; a controller started from scratch
    # would come back in MAN at the scenario's MAN_OUT of 50 % (then AUTO at 5 s), one that
    # resumed from its checkpoint (every 10 scans) comes back where it was
    asyncio.run(man_at(live, 37.0))
    time.sleep(20 * SCAN_WALL)  # a checkpoint or two after the change
    assert live.serve is not None
    os.kill(live.controller_pid, signal.SIGKILL)
    lines = wait_for_line(live.serve, "controller restarted", timeout=60)
    assert any("died" in line for line in lines), "".join(lines)
    assert "resumed at scan" in lines[-1]
    live.controller_pid = restarted_pid(lines[-1])
    asyncio.run(expect_resumed_at(live, 37.0))
    assert live.serve.poll() is None


def test_a_restarted_serve_resumes_from_its_checkpoint_without_a_bump(live: Live) -> None:
    asyncio.run(man_at(live, 41.0))
    assert live.serve is not None
    live.serve.send_signal(signal.SIGTERM)  # stops and writes its checkpoint
    assert live.serve.wait(timeout=20) == 0
    lines = live.start_serve()
    assert any("resumed from" in line for line in lines), "".join(lines)
    asyncio.run(expect_resumed_at(live, 41.0))


def test_writes_acknowledged_just_before_the_controller_is_killed_survive_it(
        live: Live) -> None:
    # the tester's s06: OUT and GAIN written (answered Good), the controller killed 0.3 s
    # later: restarted from a checkpoint up to 10 scans old it came back at the old OUT and
    # GAIN; each accepted write is now saved in the checkpoint before it is answered
    async def write_then_kill() -> None:
        async with operator(live) as c:
            idx = await c.get_namespace_index("urn:loopworks")
            await c.get_node(ua.NodeId("pid.MODE", idx)).write_value(
                ua.Variant(MAN, ua.VariantType.Int32))
            await c.get_node(ua.NodeId("pid.OUT", idx)).write_value(44.0)
            await c.get_node(ua.NodeId("pid.GAIN", idx)).write_value(0.9)
            os.kill(live.controller_pid, signal.SIGKILL)  # before a periodic checkpoint

    async def check_then_restore() -> None:
        async with operator(live) as c:
            idx = await c.get_namespace_index("urn:loopworks")
            # the nodes hold the killed controller's last snapshot until the new one
            # publishes (that snapshot may predate the last write): wait for the values
            gain = await until(c, idx, "GAIN", lambda d: d.Value.Value == 0.9, 10)
            assert gain.Value.Value == 0.9
            out = await until(c, idx, "OUT", lambda d: d.Value.Value == 44.0, 5)
            assert out.Value.Value == 44.0 and out.StatusCode.is_good()
            assert (await read(c, idx, "MODE_TEXT")).Value.Value == "MAN"
            await c.get_node(ua.NodeId("pid.GAIN", idx)).write_value(0.8)
            await c.get_node(ua.NodeId("pid.MODE", idx)).write_value(
                ua.Variant(AUTO, ua.VariantType.Int32))

    assert live.serve is not None
    asyncio.run(write_then_kill())
    lines = wait_for_line(live.serve, "controller restarted", timeout=60)
    assert "resumed at scan" in lines[-1]
    live.controller_pid = restarted_pid(lines[-1])
    asyncio.run(check_then_restore())
    assert live.serve.poll() is None
