"""The faceplate web application: ``create_app(opcua_url)`` -> a FastAPI app.

Routes:

- ``GET /``: the overview page (every loop's PV, SP, OUT, mode and status);
- ``GET /loop/<name>``: a loop's faceplate (bars, values, mode, alarms, compensator, trend);
- ``GET /events``: server-sent events, one ``data:`` JSON sample per poll of the controller
  (``{"t", "link": {...}, "loops": {loop: {"stale", "values": {NAME: [value, status,
  quality]}}}}``), ``: keep-alive`` comments in between;
- ``GET /api/meta`` (loops, units, descriptions, writability), ``GET /api/state`` (the last
  sample), ``GET /api/loop/<name>/trend?seconds=N`` (``[[t...], [PV...], [SP...],
  [OUT...]]``), ``GET /api/session``;
- ``POST /api/login`` ``{"user", "password"}``, ``POST /api/logout``;
- ``POST /api/loop/<name>/write`` ``{"name": "SP", "value": 55}``: the write goes to the
  controller as an OPC UA write in the session of the logged-in user (so the controller
  checks that user's role and logs the write under that name), or, for a visitor who has not
  logged in, in the faceplate's own anonymous session, which the controller refuses
  (``BadUserAccessDenied``); a refusal answers 409 with ``{"code", "message"}``.
- ``/static/...``: the page's JavaScript, CSS and the vendored uPlot.

Sessions: logging in opens an OPC UA session as that user (a wrong password is refused by
the controller's server at session activation); the browser gets a random token in an
HttpOnly, SameSite=Strict cookie, and a per-session CSRF token it must send back as the
``X-CSRF-Token`` header with each change. The password stays in this process's memory only
(to open the user's session again after the controller comes back) and is never sent to
the page. Sessions end on logout or after :data:`SESSION_IDLE` s without a request.
"""

from __future__ import annotations

import asyncio
import contextlib
import html
import json
import logging
import secrets
import time
from collections.abc import AsyncIterator
from dataclasses import dataclass, field
from importlib import resources
from typing import Any

from asyncua.client.client import Client
from asyncua.ua.status_codes import StatusCodes
from asyncua.ua.uaerrors import UaStatusCodeError
from fastapi import FastAPI, HTTPException, Request
from fastapi.responses import HTMLResponse, JSONResponse, Response, StreamingResponse
from fastapi.staticfiles import StaticFiles
from pydantic import BaseModel, Field, StrictFloat, StrictInt, StrictStr

from loopworks.live.faceplate.link import (
    WRITE_TIMEOUT,
    Link,
    WriteError,
    flatten,
    is_link_error,
    status_name,
)
from loopworks.live.tasks import cancel_and_wait

log = logging.getLogger("loopworks.faceplate")

COOKIE = "loopworks_session"
#: seconds without a request before a session ends
SESSION_IDLE = 8 * 3600.0
#: seconds between keep-alive comments on an idle event stream
KEEPALIVE = 10.0


class Login(BaseModel):
    user: str = Field(min_length=1, max_length=64)
    password: str = Field(max_length=256)


class Change(BaseModel):
    name: str = Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_]+$")
    # strict: a JSON true/false is no number (false was taken as 0 and put a loop in OOS)
    value: StrictInt | StrictFloat | StrictStr


@dataclass
class Session:
    user: str
    password: str
    csrf: str
    client: Client | None = None
    used: float = field(default_factory=time.monotonic)
    lock: asyncio.Lock = field(default_factory=asyncio.Lock)


class Faceplate:
    """The app's state: the link to the controller, the sessions, the shutdown flag."""

    def __init__(self, url: str, *, period: float = 0.25) -> None:
        self.link = Link(url, period=period)
        self.sessions: dict[str, Session] = {}
        self.closing = asyncio.Event()
        self._login_lock = asyncio.Lock()

    def close(self) -> None:
        """End the event streams (called when the server begins to shut down)."""
        self.closing.set()

    async def user_client(self, user: str, password: str) -> Client:
        """A connected OPC UA session as ``user``, or HTTPException (401 / 503). Its requests
        wait :data:`WRITE_TIMEOUT` s, so the controller's own BadTimeout comes first; its
        watchdog probes no more often than that: the server answers a session's requests in
        order, so a probe sent while a write waits for the controller's next scan waits too
        (asyncua's default, 1 s, would drop the session and lose the write's answer)."""
        client = Client(self.link.url, timeout=WRITE_TIMEOUT,
                        watchdog_intervall=2 * WRITE_TIMEOUT)
        client.set_user(user)
        client.set_password(password)
        try:
            await asyncio.wait_for(client.connect(), self.link.timeout + 5.0)
        except UaStatusCodeError as exc:
            with contextlib.suppress(Exception):
                await client.disconnect()
            if exc.code == StatusCodes.BadUserAccessDenied:
                raise HTTPException(401, {"code": "BadUserAccessDenied", "message":
                                          "unknown user or wrong password"}) from None
            raise HTTPException(503, {"code": status_name(exc.code), "message":
                                      "the controller refused the session"}) from None
        except Exception as exc:
            with contextlib.suppress(Exception):
                await client.disconnect()
            raise HTTPException(503, {"code": "NotConnected", "message":
                                      f"cannot reach the controller ({exc.__class__.__name__})"}
                                ) from None
        return client

    def session(self, request: Request) -> Session | None:
        token = request.cookies.get(COOKIE)
        if not token:
            return None
        s = self.sessions.get(token)
        if s is None:
            return None
        if time.monotonic() - s.used > SESSION_IDLE:
            self.sessions.pop(token, None)
            asyncio.get_running_loop().create_task(_disconnect(s.client))
            return None
        s.used = time.monotonic()
        return s

    async def write(self, s: Session | None, loop: str, name: str, value: Any) -> None:
        if s is None:  # the controller's own verdict on an anonymous write
            await self.link.write(None, loop, name, value)
            return
        async with s.lock:
            for attempt in (1, 2):
                if s.client is None:
                    s.client = await self.user_client(s.user, s.password)
                try:
                    await self.link.write(s.client, loop, name, value, s.user)
                    return
                except WriteError:
                    raise
                except Exception as exc:
                    if not is_link_error(exc):
                        raise
                    await _disconnect(s.client)  # its session is gone: a new one
                    s.client = None
                    if isinstance(exc, TimeoutError):  # sent, never answered: not known
                        raise WriteError("NoAnswer", f"the controller did not answer within "
                                         f"{WRITE_TIMEOUT:g} s: the change may still be made; "
                                         "check the value before trying again") from None
                    # not sent (the session died with a controller that restarted since):
                    # once more on a new session, as the link is up again (the operator's
                    # first change after a restart was refused; found by an outside audit)
                    if attempt == 2:
                        raise WriteError("NotConnected", "the link to the controller was "
                                         "lost: the change was not made") from None


async def _disconnect(client: Client | None) -> None:
    if client is not None:
        with contextlib.suppress(Exception):
            await asyncio.wait_for(client.disconnect(), 2.0)


def _static() -> Any:
    return resources.files("loopworks.live.faceplate") / "static"


def _page(title: str, body_attrs: str) -> str:
    return f"""<!doctype html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{html.escape(title)}</title>
<link rel="stylesheet" href="/static/uPlot.min.css">
<link rel="stylesheet" href="/static/faceplate.css">
</head>
<body {body_attrs}>
<header class="bar">
  <a class="home" href="/">loopworks</a>
  <span id="crumb">{html.escape(title)}</span>
  <span id="link" class="link">connecting…</span>
  <span class="who"><span id="user"></span>
    <button id="login-open" type="button">Log in</button>
    <button id="logout" type="button" hidden>Log out</button></span>
</header>
<form id="login" class="login" hidden>
  <label>User <input name="user" autocomplete="username" required></label>
  <label>Password <input name="password" type="password" autocomplete="current-password"></label>
  <button type="submit">Log in</button> <button type="button" id="login-cancel">Cancel</button>
  <span id="login-msg" class="msg"></span>
</form>
<main id="main"></main>
<div id="toast" class="toast" role="status" aria-live="polite"></div>
<script src="/static/uPlot.iife.min.js"></script>
<script src="/static/faceplate.js"></script>
</body>
</html>
"""


def create_app(opcua_url: str, *, period: float = 0.25) -> FastAPI:
    """The faceplate of the controller whose OPC UA server is at ``opcua_url``; ``period``:
    seconds between two reads of its values."""
    fp = Faceplate(opcua_url, period=period)

    @contextlib.asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        task = asyncio.create_task(fp.link.run())
        try:
            yield
        finally:
            fp.close()
            with contextlib.suppress(Exception):
                await cancel_and_wait(task)
            for s in fp.sessions.values():
                await _disconnect(s.client)
            fp.sessions.clear()

    app = FastAPI(title="loopworks faceplate", lifespan=lifespan, docs_url=None,
                  redoc_url=None, openapi_url=None)
    app.state.faceplate = fp
    app.mount("/static", StaticFiles(directory=str(_static())), name="static")

    @app.middleware("http")
    async def headers(request: Request, call_next: Any) -> Response:
        response: Response = await call_next(request)
        response.headers["X-Content-Type-Options"] = "nosniff"
        response.headers["X-Frame-Options"] = "DENY"
        response.headers["Referrer-Policy"] = "no-referrer"
        response.headers["Content-Security-Policy"] = (
            "default-src 'self'; img-src 'self' data:; style-src 'self' 'unsafe-inline'; "
            "frame-ancestors 'none'")
        if request.url.path.startswith("/api/"):
            response.headers["Cache-Control"] = "no-store"
        return response

    @app.get("/", response_class=HTMLResponse)
    async def overview() -> str:
        return _page("Overview", 'data-page="overview"')

    @app.get("/loop/{name}", response_class=HTMLResponse)
    async def loop_page(name: str) -> str:
        if fp.link.loops and name not in fp.link.loops:
            raise HTTPException(404, f"no loop {name!r}; loops: {', '.join(fp.link.loops)}")
        return _page(name, f'data-page="loop" data-loop="{html.escape(name, quote=True)}"')

    @app.get("/favicon.ico", include_in_schema=False)
    async def favicon() -> Response:
        return Response(status_code=204)

    @app.get("/api/meta")
    async def meta() -> dict[str, Any]:
        return fp.link.meta()

    @app.get("/api/state")
    async def state() -> dict[str, Any]:
        return fp.link.last

    @app.get("/api/loop/{name}/trend")
    async def trend(name: str, seconds: float = 300.0) -> list[list[float | None]]:
        if name not in fp.link.history:
            raise HTTPException(404, f"no loop {name!r}")
        return flatten(fp.link.trend(name, max(1.0, min(seconds, fp.link.history_seconds))))

    @app.get("/events")
    async def events(request: Request) -> StreamingResponse:
        q = fp.link.subscribe()

        async def stream() -> AsyncIterator[str]:
            try:
                yield "retry: 1000\n\n"
                yield f"data: {json.dumps(fp.link.last)}\n\n"
                while not fp.closing.is_set():
                    get = asyncio.ensure_future(q.get())
                    closing = asyncio.ensure_future(fp.closing.wait())
                    done, _ = await asyncio.wait({get, closing}, timeout=KEEPALIVE,
                                                 return_when=asyncio.FIRST_COMPLETED)
                    closing.cancel()
                    if get in done:
                        yield f"data: {json.dumps(get.result())}\n\n"
                    else:
                        get.cancel()
                        if fp.closing.is_set() or await request.is_disconnected():
                            break
                        yield ": keep-alive\n\n"
            finally:
                fp.link.unsubscribe(q)

        return StreamingResponse(stream(), media_type="text/event-stream",
                                 headers={"Cache-Control": "no-store",
                                          "X-Accel-Buffering": "no"})

    @app.get("/api/session")
    async def session(request: Request) -> dict[str, Any]:
        s = fp.session(request)
        if s is None:
            return {"user": None}
        return {"user": s.user, "csrf": s.csrf}

    @app.post("/api/login")
    async def login(body: Login, request: Request) -> JSONResponse:
        async with fp._login_lock:  # one at a time: each costs the controller a hash
            try:
                client = await fp.user_client(body.user, body.password)
            except HTTPException as exc:
                if exc.status_code == 401:
                    log.warning("login as %r from %s refused", body.user,
                                request.client.host if request.client else "?")
                    await asyncio.sleep(1.0)  # a brake on guessing
                raise
        old = fp.session(request)
        if old is not None:
            await _disconnect(old.client)
            fp.sessions.pop(request.cookies.get(COOKIE, ""), None)
        token = secrets.token_urlsafe(32)
        s = Session(body.user, body.password, secrets.token_urlsafe(24), client)
        fp.sessions[token] = s
        log.info("login as %r", body.user)
        response = JSONResponse({"user": s.user, "csrf": s.csrf})
        response.set_cookie(COOKIE, token, httponly=True, samesite="strict", path="/",
                            max_age=int(SESSION_IDLE))
        return response

    def _check_csrf(request: Request, s: Session) -> None:
        if not secrets.compare_digest(request.headers.get("x-csrf-token", ""), s.csrf):
            raise HTTPException(403, {"code": "BadSecurityChecksFailed",
                                      "message": "missing or wrong X-CSRF-Token"})

    @app.post("/api/logout")
    async def logout(request: Request) -> JSONResponse:
        s = fp.session(request)
        if s is not None:
            _check_csrf(request, s)
            fp.sessions.pop(request.cookies.get(COOKIE, ""), None)
            await _disconnect(s.client)
        response = JSONResponse({"user": None})
        response.delete_cookie(COOKIE, path="/")
        return response

    @app.post("/api/loop/{name}/write")
    async def write(name: str, body: Change, request: Request) -> JSONResponse:
        s = fp.session(request)
        if s is not None:
            _check_csrf(request, s)
        elif request.cookies.get(COOKIE):
            # a login this faceplate no longer holds (it restarted, or the session idled
            # out): not sent as an anonymous write the page would show under the user's name
            response = JSONResponse(
                {"code": "SessionEnded", "message": "your login ended (the faceplate "
                 "restarted, or the session was idle): log in again; the change was not "
                 "made"}, status_code=401)
            response.delete_cookie(COOKIE, path="/")
            return response
        who = s.user if s is not None else "anonymous"
        try:
            await fp.write(s, name, body.name.upper(), body.value)
        except WriteError as exc:
            log.info("write %s.%s = %r by %s: %s", name, body.name, body.value, who, exc.code)
            hint = exc.message
            if exc.code == "BadUserAccessDenied":
                hint = ("log in as an operator to make changes" if s is None else
                        f"user {s.user} may not make changes (not an operator)")
            status = 503 if exc.code in ("NotConnected", "NoAnswer") else 409
            return JSONResponse({"code": exc.code, "message": hint}, status_code=status)
        log.info("write %s.%s = %r by %s: accepted", name, body.name, body.value, who)
        return JSONResponse({"code": "Good", "message": "accepted by the controller"})

    return app
