"""The faceplate app (loopworks.live.faceplate) against a LoopServer with a fake controller,
without a browser: the app runs on uvicorn in a thread (as ``loopworks faceplate`` runs it),
the OPC UA server on its own event loop in another; requests are plain urllib.

(FastAPI's TestClient needs httpx, which loopworks does not depend on; a real server on a
free loopback port is as fast and exercises the event stream too.)"""

from __future__ import annotations

import asyncio
import contextlib
import http.cookiejar
import json
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from loopworks.blocks import status as st
from loopworks.live.opcua import LoopServer
from loopworks.live.users import add_user, load_users
from tests.live.test_live_end_to_end import free_port
from tests.live.test_opcua import FakeController

uvicorn = pytest.importorskip("uvicorn")  # an ordinary dependency: always there


class Loop:
    """An event loop in a thread."""

    def __init__(self) -> None:
        self.loop = asyncio.new_event_loop()
        self.thread = threading.Thread(target=self.loop.run_forever, daemon=True)
        self.thread.start()

    def run(self, coro: Any, timeout: float = 30.0) -> Any:
        return asyncio.run_coroutine_threadsafe(coro, self.loop).result(timeout)

    def close(self) -> None:
        self.loop.call_soon_threadsafe(self.loop.stop)
        self.thread.join(5)


class Setup:
    def __init__(self, tmp: Path) -> None:
        users = tmp / "users.toml"
        add_user(users, "op", "secret", "operator")
        add_user(users, "viewer", "look", "viewer")
        self.ctl = FakeController()
        self.opcua_port = free_port()
        self.ua = Loop()
        self.server = LoopServer(self.ctl, load_users(users), port=self.opcua_port)
        self.url = self.ua.run(self.server.start())
        from loopworks.live.faceplate.app import create_app
        from loopworks.live.faceplate.server import _Server

        self.app = create_app(self.url, period=0.1)
        self.http = free_port()
        config = uvicorn.Config(self.app, host="127.0.0.1", port=self.http,
                                log_level="warning", timeout_graceful_shutdown=2)
        self.web = _Server(config, self.app.state.faceplate.close)
        self.web_thread = threading.Thread(target=self.web.run, daemon=True)
        self.web_thread.start()
        end = time.monotonic() + 10
        while not self.web.started and time.monotonic() < end:
            time.sleep(0.02)
        assert self.web.started
        self.base = f"http://127.0.0.1:{self.http}"

    def publish(self, values: dict[str, tuple[float | int, int]]) -> None:
        self.ua.run(self.server.publish(values))

    def close(self) -> None:
        self.web.should_exit = True
        self.web_thread.join(10)
        with contextlib.suppress(Exception):
            self.ua.run(self.server.stop())
        self.ua.close()


@pytest.fixture(scope="module")
def setup(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Setup]:
    s = Setup(tmp_path_factory.mktemp("faceplate-app"))
    try:
        yield s
    finally:
        s.close()


class Browser:
    """urllib with a cookie jar, answering (status, JSON or text)."""

    def __init__(self, base: str) -> None:
        self.base = base
        self.opener = urllib.request.build_opener(
            urllib.request.HTTPCookieProcessor(http.cookiejar.CookieJar()))
        self.csrf = ""

    def call(self, path: str, body: Any = None, *, csrf: bool = True) -> tuple[int, Any]:
        data = None if body is None else json.dumps(body).encode()
        req = urllib.request.Request(self.base + path, data=data)
        if data is not None:
            req.add_header("Content-Type", "application/json")
            if csrf and self.csrf:
                req.add_header("X-CSRF-Token", self.csrf)
        try:
            with self.opener.open(req, timeout=15) as r:
                status, raw, kind = r.status, r.read(), r.headers.get("content-type", "")
        except urllib.error.HTTPError as exc:
            status, raw, kind = exc.code, exc.read(), exc.headers.get("content-type", "")
        return status, json.loads(raw) if "json" in kind else raw.decode()


def until(fn: Any, timeout: float = 5.0) -> Any:
    end = time.monotonic() + timeout
    while True:
        value = fn()
        if value or time.monotonic() > end:
            return value
        time.sleep(0.05)


def state(b: Browser) -> dict[str, Any]:
    return dict(b.call("/api/state")[1])


def test_the_app_browses_every_loop_with_units_and_writability(setup: Setup) -> None:
    b = Browser(setup.base)
    assert until(lambda: state(b)["link"]["connected"])
    status, meta = b.call("/api/meta")
    assert status == 200 and set(meta["loops"]) == {"pid", "tic2"}
    pid = meta["loops"]["pid"]
    assert pid["PV"]["units"] == "degC" and not pid["PV"]["writable"]
    assert pid["SP"]["writable"] and pid["SP"]["type"] == "Double"
    assert pid["MODE"]["enum"][:6] == ["OOS", "IMAN", "LO", "MAN", "AUTO", "CAS"]
    assert "MODE_TEXT" in pid
    values = state(b)["loops"]["pid"]["values"]
    assert values["PV"] == [45.0, "Good", "good"]
    assert values["MODE_TEXT"][0] == "AUTO"


def test_pages_and_static_files_are_served_escaped_and_self_contained(setup: Setup) -> None:
    b = Browser(setup.base)
    status, page = b.call("/")
    assert status == 200 and 'data-page="overview"' in page
    for asset in ("/static/faceplate.js", "/static/faceplate.css", "/static/uPlot.iife.min.js",
                  "/static/uPlot.min.css", "/static/uPlot.LICENSE"):
        assert b.call(asset)[0] == 200, asset
    status, page = b.call("/loop/pid")
    assert status == 200 and 'data-loop="pid"' in page
    assert "http://" not in page and "https://" not in page  # nothing from the internet
    assert until(lambda: state(b)["link"]["connected"])
    assert b.call("/loop/%3Cscript%3E")[0] == 404  # an unknown loop, once browsed


def test_bad_and_uncertain_values_keep_their_status(setup: Setup) -> None:
    b = Browser(setup.base)
    setup.publish({"pid.PV": (47.0, st.BAD_NO_COMM_LUV), "pid.OUT": (21.0, 0x44)})
    try:
        v = until(lambda: (lambda x: x if x["PV"][2] == "bad" else None)(
            state(b)["loops"]["pid"]["values"]))
        assert v["PV"] == [None, "BadNoCommunication", "bad"]  # Bad: no number
        assert v["OUT"] == [21.0, "UncertainLastUsableValue", "uncertain"]
        trend = b.call("/api/loop/pid/trend?seconds=5")[1]
        assert len(trend) == 4 and trend[1][-1] is None and trend[3][-1] == 21.0
    finally:
        setup.publish({"pid.PV": (45.0, st.GOOD_NC), "pid.OUT": (20.0, st.GOOD_NC)})


def test_an_anonymous_change_is_refused_by_the_controller(setup: Setup) -> None:
    b = Browser(setup.base)
    assert until(lambda: state(b)["link"]["connected"])
    status, answer = b.call("/api/loop/pid/write", {"name": "SP", "value": 60})
    assert status == 409 and answer["code"] == "BadUserAccessDenied"
    assert "log in" in answer["message"]
    assert not [w for w in setup.ctl.writes if w[3] == "SP" and w[4] == 60.0]


def test_login_and_an_operators_changes_as_that_user(setup: Setup) -> None:
    b = Browser(setup.base)
    assert until(lambda: state(b)["link"]["connected"])
    status, answer = b.call("/api/login", {"user": "op", "password": "wrong"})
    assert status == 401 and answer["detail"]["code"] == "BadUserAccessDenied"
    status, answer = b.call("/api/login", {"user": "op", "password": "secret"})
    assert status == 200 and answer["user"] == "op" and "password" not in answer
    b.csrf = answer["csrf"]
    assert b.call("/api/session")[1]["user"] == "op"
    # a change without the CSRF token is refused before it reaches the controller
    status, answer = b.call("/api/loop/pid/write", {"name": "SP", "value": 61}, csrf=False)
    assert status == 403
    status, answer = b.call("/api/loop/pid/write", {"name": "SP", "value": 62})
    assert status == 200 and answer["code"] == "Good"
    assert setup.ctl.writes[-1] == ("op", "operator", "pid", "SP", 62.0)
    status, answer = b.call("/api/loop/pid/write", {"name": "SP", "value": 1000})
    assert status == 409 and answer["code"] == "BadOutOfRange"
    status, answer = b.call("/api/loop/pid/write", {"name": "OUT", "value": 30})
    assert status == 409 and answer["code"] == "BadInvalidState"  # not in MAN
    status, answer = b.call("/api/loop/pid/write", {"name": "MODE", "value": "MAN"})
    assert status == 200 and setup.ctl.writes[-1][3:] == ("MODE", 3)
    status, answer = b.call("/api/loop/pid/write", {"name": "OUT", "value": 30})
    assert status == 200 and setup.ctl.writes[-1][3:] == ("OUT", 30.0)
    b.call("/api/loop/pid/write", {"name": "MODE", "value": "AUTO"})
    status, answer = b.call("/api/loop/pid/write", {"name": "PV", "value": 3})
    assert status == 409 and answer["code"] == "BadNotWritable"
    status, answer = b.call("/api/loop/pid/write", {"name": "NOPE", "value": 3})
    assert status == 409 and answer["code"] == "BadNodeIdUnknown"
    status, answer = b.call("/api/loop/pid/write", {"name": "MODE", "value": "SLEEP"})
    assert status == 409 and answer["code"] == "BadOutOfRange"
    # a JSON boolean is no number: false was taken as 0 and put the loop out of service
    # (found by a user); refused before it reaches the controller
    count = len(setup.ctl.writes)
    for value in (False, True):
        assert b.call("/api/loop/pid/write", {"name": "MODE", "value": value})[0] == 422
    assert len(setup.ctl.writes) == count
    assert b.call("/api/logout", {})[0] == 200
    status, answer = b.call("/api/loop/pid/write", {"name": "SP", "value": 63})
    assert status == 409 and answer["code"] == "BadUserAccessDenied"  # anonymous again


def login(setup: Setup) -> Browser:
    b = Browser(setup.base)
    assert until(lambda: state(b)["link"]["connected"])
    status, answer = b.call("/api/login", {"user": "op", "password": "secret"})
    assert status == 200
    b.csrf = answer["csrf"]
    return b


def test_a_refusal_shows_the_controller_s_reason_not_the_stock_text(setup: Setup) -> None:
    # the controller's reason (the serve log's) comes from the loop's LAST_REFUSAL node; the
    # OPC UA stock text ("The value was out of range.") told the operator nothing
    b = login(setup)
    status, answer = b.call("/api/loop/pid/write", {"name": "SP", "value": 150})
    assert status == 409 and answer == {"code": "BadOutOfRange",
                                        "message": "SP 150.0: allowed 0..100"}
    status, answer = b.call("/api/loop/pid/write", {"name": "OUT", "value": 30})
    assert status == 409 and answer == {"code": "BadInvalidState",
                                        "message": "OUT is written in MAN only"}
    b.call("/api/logout", {})


def test_a_stalled_controller_s_badtimeout_reaches_the_operator(
        setup: Setup, monkeypatch: pytest.MonkeyPatch) -> None:
    # serve answers BadTimeout when its controller process does not answer (and then never
    # makes the write, loopworks.live.supervisor); the faceplate's session must wait for that
    # answer: with a 2 s request timeout it told "NotConnected ... the change was not made"
    # while serve still waited, and its 1 s watchdog dropped the session meanwhile
    from loopworks.live.opcua import WriteRefused

    async def stalled() -> None:
        await asyncio.sleep(3.0)
        raise WriteRefused("BadTimeout", "the controller did not answer within 3 s")

    b = login(setup)
    monkeypatch.setattr(setup.ctl, "write", lambda *args: stalled())
    status, answer = b.call("/api/loop/pid/write", {"name": "SP", "value": 58})
    assert status == 409 and answer == {"code": "BadTimeout",
                                        "message": "the controller did not answer within 3 s"}
    monkeypatch.undo()
    status, answer = b.call("/api/loop/pid/write", {"name": "SP", "value": 57})
    assert status == 200  # the same session goes on
    b.call("/api/logout", {})


def test_a_viewer_is_refused_by_the_controller(setup: Setup) -> None:
    b = Browser(setup.base)
    status, answer = b.call("/api/login", {"user": "viewer", "password": "look"})
    assert status == 200
    b.csrf = answer["csrf"]
    status, answer = b.call("/api/loop/pid/write", {"name": "SP", "value": 64})
    assert status == 409 and answer["code"] == "BadUserAccessDenied"
    assert "viewer" in answer["message"]


def test_the_event_stream_sends_samples(setup: Setup) -> None:
    with urllib.request.urlopen(setup.base + "/events", timeout=10) as r:
        assert r.headers["content-type"].startswith("text/event-stream")
        samples = []
        while len(samples) < 3:
            line = r.readline().decode()
            if line.startswith("data: "):
                samples.append(json.loads(line[6:]))
    assert samples[-1]["t"] > samples[1]["t"]
    assert samples[-1]["loops"]["pid"]["values"]["SP"][2] == "good"


def test_a_lost_server_marks_everything_stale_and_the_link_recovers(setup: Setup) -> None:
    b = Browser(setup.base)
    assert until(lambda: state(b)["link"]["connected"])
    operator = Browser(setup.base)  # logged in, with an OPC UA session of its own
    status, answer = operator.call("/api/login", {"user": "op", "password": "secret"})
    assert status == 200
    operator.csrf = answer["csrf"]
    assert operator.call("/api/loop/pid/write", {"name": "SP", "value": 55})[0] == 200
    setup.ua.run(setup.server.stop())
    lost = time.monotonic()
    assert until(lambda: not state(b)["link"]["connected"], 3.0)
    assert time.monotonic() - lost < 2.5
    assert all(loop["stale"] for loop in state(b)["loops"].values())
    status, answer = b.call("/api/loop/pid/write", {"name": "SP", "value": 50})
    assert status == 503 and answer["code"] == "NotConnected"
    setup.server = LoopServer(setup.ctl, setup.server.users, port=setup.opcua_port)
    setup.ua.run(setup.server.start())
    assert until(lambda: state(b)["link"]["connected"], 10.0)
    setup.publish({"pid.SCANS": (7, st.GOOD_NC)})  # the fake's scans move: not stale
    assert until(lambda: not state(b)["loops"]["pid"]["stale"], 3.0)
    # the operator's session died with the server: the first change after the restart opens
    # a new one and is made (it was refused "NotConnected" with the link up; found by an
    # outside audit)
    status, answer = operator.call("/api/loop/pid/write", {"name": "SP", "value": 56})
    assert status == 200 and answer["code"] == "Good", answer
    assert setup.ctl.writes[-1] == ("op", "operator", "pid", "SP", 56.0)


def test_a_controller_whose_scans_stop_is_shown_stale(setup: Setup) -> None:
    b = Browser(setup.base)
    setup.publish({"pid.SCANS": (8, st.GOOD_NC)})
    assert until(lambda: not state(b)["loops"]["pid"]["stale"], 3.0)
    assert until(lambda: state(b)["loops"]["pid"]["stale"], 5.0)  # SCANS still for 3 s
    assert state(b)["link"]["connected"] and not state(b)["loops"]["pid"]["scanning"]


def test_a_login_the_faceplate_no_longer_holds_is_told_not_sent_as_anonymous(
        setup: Setup) -> None:
    """After a restart the page still showed the operator logged in and a change went to the
    controller as an anonymous write ("log in as an operator"; found by an operator's run). A
    write with a session cookie the faceplate does not hold is refused with SessionEnded,
    the cookie cleared, and nothing reaches the controller."""
    import urllib.error
    import urllib.request

    before = len(setup.ctl.writes)
    req = urllib.request.Request(
        setup.base + "/api/loop/pid/write", data=json.dumps({"name": "SP", "value": 63}).encode(),
        headers={"Content-Type": "application/json", "Cookie": "loopworks_session=gone"},
        method="POST")
    with pytest.raises(urllib.error.HTTPError) as info:
        urllib.request.urlopen(req, timeout=10)
    assert info.value.code == 401
    answer = json.loads(info.value.read())
    assert answer["code"] == "SessionEnded" and "log in again" in answer["message"]
    assert "loopworks_session=\"\"" in str(info.value.headers.get("set-cookie")) or \
        "Max-Age=0" in str(info.value.headers.get("set-cookie"))
    assert len(setup.ctl.writes) == before
