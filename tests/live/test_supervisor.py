"""``loopworks serve`` as processes (loopworks.live.supervisor): what the controller process
does with the writes the supervisor hands it, a stalled controller, and a user error in the
controller process."""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import queue
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from asyncua import Client, ua

from loopworks.live import supervisor
from loopworks.live.users import add_user
from tests.live.test_serve import make, scans


def sp_input(ctl: Any) -> float:
    pid = ctl.module.blocks["pid"]
    return float(pid.u[pid._in_index["sp"]])


def test_a_write_taken_after_its_deadline_is_dropped_not_applied() -> None:
    # the supervisor answers BadTimeout REPLY_TIMEOUT s after a write; each write carries a
    # deadline APPLY_MARGIN s before that, and the controller (resuming from a stall) drops
    # one it takes later: a write its client was told failed is never made afterwards
    from loopworks.live.supervisor import take_commands

    ctl, _ = make()
    scans(ctl, 20)
    commands: queue.Queue[tuple[Any, ...]] = queue.Queue()
    events: queue.Queue[tuple[Any, ...]] = queue.Queue()
    now = 1000.0
    commands.put(("write", 1, now - 0.001, "op", "operator", "pid", "SP", 58.0))
    commands.put(("write", 2, now + 1.0, "op", "operator", "pid", "SP", 57.0))
    assert take_commands(ctl, commands, events, now=lambda: now) is False
    late, in_time = events.get_nowait(), events.get_nowait()
    assert late[:3] == ("reply", 1, "BadTimeout") and "not applied" in late[3]
    assert in_time == ("reply", 2, None, "")
    assert sp_input(ctl) == 57.0  # the in-time write only
    commands.put(("write", 3, now - 5.0, "op", "operator", "pid", "SP", 58.0))
    commands.put(("stop",))
    assert take_commands(ctl, commands, events, now=lambda: now) is True
    assert events.get_nowait()[2] == "BadTimeout"
    assert sp_input(ctl) == 57.0


def test_a_write_answered_badtimeout_while_the_controller_is_stalled_is_never_made(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The tester's s13: SIGSTOP the controller process, write SP (answered BadTimeout),
    SIGCONT: SP must not become the written value. REPLY_TIMEOUT is 2 s here (5 s in serve)
    so the test waits less; the deadline is the supervisor's, carried with the write."""
    monkeypatch.setattr(supervisor, "REPLY_TIMEOUT", 2.0)
    users = tmp_path / "users.toml"
    add_user(users, "op", "secret", "operator")
    info: dict[str, Any] = {}
    stop = asyncio.Event()

    async def operator(url: str, pid: int) -> None:
        # the server answers a session's requests in order: asyncua's watchdog (a probe
        # every 1 s, 1 s timeout) would drop the session while the write waits
        client = Client(url, timeout=10, watchdog_intervall=30)
        client.set_user("op")
        client.set_password("secret")
        async with client:
            idx = await client.get_namespace_index("urn:loopworks")

            def node(name: str) -> Any:
                return client.get_node(ua.NodeId(f"pid.{name}", idx))

            end = time.monotonic() + 30
            while (await node("SCANS").read_value()) < 2:
                assert time.monotonic() < end, "the controller does not scan"
                await asyncio.sleep(0.1)
            sp0 = await node("SP").read_value()
            os.kill(pid, signal.SIGSTOP)
            try:
                with pytest.raises(ua.UaStatusCodeError) as refused:
                    await node("SP").write_value(58.0)
                assert refused.value.code == ua.StatusCodes.BadTimeout
                reason = await client.get_node(ua.NodeId("pid.LAST_REFUSAL", idx)).read_value()
                assert reason.startswith("op SP BadTimeout: "), reason
                await asyncio.sleep(0.5)  # the write has sat in the queue past its deadline
            finally:
                os.kill(pid, signal.SIGCONT)
            scans0 = await node("SCANS").read_value()
            end = time.monotonic() + 10
            while (await node("SCANS").read_value()) < scans0 + 3:  # it scans again
                assert time.monotonic() < end, "the controller did not resume"
                await asyncio.sleep(0.1)
            assert await node("SP").read_value() == sp0  # never 58
            await node("SP").write_value(53.0)  # and the next write is made as usual
            assert await node("SP").read_value() != 58.0

    async def main() -> None:
        def ready(got: dict[str, Any]) -> None:
            info.update(got)
            info["task"] = asyncio.get_running_loop().create_task(
                operator(got["endpoint"], got["pid"]))

        run = asyncio.create_task(supervisor.run(
            None, opcua_port=0, users=users, speedup=1.0, state_dir=tmp_path / "state",
            stop=stop, ready=ready))
        end = time.monotonic() + 120
        while "task" not in info:
            if run.done():
                run.result()
            assert time.monotonic() < end, "serve did not start"
            await asyncio.sleep(0.05)
        try:
            await info["task"]
        finally:
            stop.set()
            with contextlib.suppress(Exception):
                await asyncio.wait_for(run, 30)

    asyncio.run(main())


def test_a_checkpoint_of_another_scenario_is_one_error_line(tmp_path: Path) -> None:
    state = tmp_path / "state"
    state.mkdir()
    ctl, _ = make(state / "checkpoint.json")  # the built-in scenario's checkpoint
    ctl.save()
    assert json.loads((state / "checkpoint.json").read_text())["layout"] == ctl.key
    cascade = Path(__file__).resolve().parents[2] / "examples" / "cascade.toml"
    run = subprocess.run([sys.executable, "-m", "loopworks", "serve", str(cascade),
                          "--opcua-port", "0", "--state-dir", str(state)],
                         capture_output=True, text=True, timeout=120,
                         env=dict(os.environ, PYTHONDONTWRITEBYTECODE="1"))
    assert run.returncode == 2, run.stdout + run.stderr
    lines = (run.stdout + run.stderr).splitlines()
    errors = [line for line in lines if line.startswith("error:")]
    assert len(errors) == 1, lines
    assert "checkpoint is of another controller module" in errors[0]
    assert not [line for line in lines if "Traceback" in line or line.startswith("  File ")]
    # refused before anything starts: the built-in device ran for scans before the error
    # (found by an outside audit); the error is now the whole output
    assert lines == errors, lines
