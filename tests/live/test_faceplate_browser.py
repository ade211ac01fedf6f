"""Issue 17, done-when, in a real browser: ``loopworks device``, ``loopworks serve`` (with a
users file) and ``loopworks faceplate`` as subprocesses on loopback, the system's Chromium
driven headless by Playwright.

One run (module fixture) at speedup 20 (a 0.5 s scan every 25 ms of wall time); the tests run
in order on it: the overview and a faceplate, the trend advancing, an anonymous change
refused, an operator's SP change followed by the PV, both screen sizes, the controller
stopped (stale) and started again (recovered), the faceplate stopping with a page open.

Chromium is the system's (``/usr/bin/chromium``, installed by ``.ci/run`` from the
distribution's packages); without it these tests fail, they never skip. The page sets a
Content-Security-Policy without 'unsafe-eval', so the tests read the page's test hooks
(``window.__lw``) with ``page.evaluate`` polls rather than ``wait_for_function``."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.live.test_live_end_to_end import free_port, loopworks, wait_for_line

CHROMIUM = os.environ.get("LOOPWORKS_CHROMIUM", "/usr/bin/chromium")
ARGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync",
        "--disable-dev-shm-usage"]
SPEEDUP = 20.0
ERRORS: list[str] = []  # the page's uncaught JavaScript errors
SHOTS = Path(os.environ.get("LOOPWORKS_SHOTS", "/tmp/loopworks-faceplate-shots"))


class Run:
    def __init__(self, tmp: Path) -> None:
        self.tmp = tmp
        self.modbus, self.opcua, self.http = free_port(), free_port(), free_port()
        self.users = tmp / "users.toml"
        for name, password, role in (("op", "secret", "operator"), ("viewer", "look", "viewer")):
            add = loopworks("users", "add", str(self.users), name, "--role", role, cwd=tmp,
                            stdin=password)
            add.communicate(password + "\n", timeout=60)
            assert add.returncode == 0
        self.device = loopworks("device", "--modbus-port", str(self.modbus), "--speedup",
                                str(SPEEDUP), "--fstate-time", "30", "--map-file",
                                str(tmp / "map.toml"), cwd=tmp)
        self.serve: subprocess.Popen[str] | None = None
        self.face: subprocess.Popen[str] | None = None

    @property
    def url(self) -> str:
        return f"opc.tcp://127.0.0.1:{self.opcua}/loopworks/"

    @property
    def base(self) -> str:
        return f"http://127.0.0.1:{self.http}"

    def start_serve(self) -> None:
        self.serve = loopworks("serve", "--device", f"modbus://127.0.0.1:{self.modbus}",
                               "--opcua-port", str(self.opcua), "--users", str(self.users),
                               "--speedup", str(SPEEDUP), "--state-dir",
                               str(self.tmp / "state"), cwd=self.tmp)
        wait_for_line(self.serve, "namespace urn:loopworks")

    def stop_serve(self) -> None:
        assert self.serve is not None
        self.serve.send_signal(signal.SIGTERM)
        assert self.serve.wait(timeout=20) == 0

    def stop(self) -> None:
        for proc in (self.face, self.serve, self.device):
            if proc is not None and proc.poll() is None:
                proc.send_signal(signal.SIGINT)
                try:
                    proc.wait(timeout=20)
                except subprocess.TimeoutExpired:
                    proc.kill()


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Run]:
    r = Run(tmp_path_factory.mktemp("faceplate"))
    try:
        wait_for_line(r.device, "serving Modbus TCP")
        r.start_serve()
        r.face = loopworks("faceplate", r.url, "--port", str(r.http), cwd=r.tmp)
        wait_for_line(r.face, "faceplate on http://127.0.0.1:")
        yield r
    finally:
        r.stop()


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    if not (os.path.isfile(CHROMIUM) and os.access(CHROMIUM, os.X_OK)):
        pytest.fail(f"no Chromium at {CHROMIUM}: install the system's package (apt-get install "
                    f"chromium; .ci/run does) or set LOOPWORKS_CHROMIUM; never "
                    f"'playwright install'", pytrace=False)
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=ARGS)
        try:
            yield b
        finally:
            b.close()


@pytest.fixture(scope="module")
def page(browser: Any, run: Run) -> Iterator[Any]:
    context = browser.new_context(viewport={"width": 1280, "height": 900})
    pg = context.new_page()
    pg.on("pageerror", lambda e: ERRORS.append(str(e)))
    yield pg
    context.close()


def until(pg: Any, expr: str, timeout: float = 10.0) -> Any:
    """Poll ``expr`` in the page until it is truthy; its value."""
    end = time.monotonic() + timeout
    value = None
    while time.monotonic() < end:
        value = pg.evaluate(expr)
        if value:
            return value
        time.sleep(0.1)
    raise AssertionError(f"{expr} still {value!r} after {timeout} s")


def text(pg: Any, selector: str) -> str:
    return str(pg.locator(selector).first.text_content() or "")


def number(pg: Any, selector: str) -> float:
    return float(text(pg, selector).replace("?", "").strip())


def test_the_overview_lists_every_loop_with_its_values(page: Any, run: Run) -> None:
    page.goto(run.base + "/")
    until(page, "window.__lw.events > 2 && window.__lw.connected")
    tile = page.locator('.tile[data-loop="pid"]')
    assert tile.count() == 1
    until(page, "document.querySelector('.tile [data-v=mode]').textContent === 'AUTO'")
    for name in ("PV", "SP", "OUT"):
        cell = tile.locator(f'[data-v="{name}"]')
        assert "q-good" in (cell.get_attribute("class") or ""), name
        float(cell.text_content() or "")  # a number, Good
    # the built-in DeltaV PID's PV is in its PV_SCALE's engineering units (each value in the
    # units its block declares; all were "% of PV span", GE's counts too)
    assert "EU" in (tile.text_content() or "")
    assert text(page, '.tile [data-v="badge"]') == ""  # not stale
    tile.click()
    page.wait_for_url(run.base + "/loop/pid")
    assert not ERRORS, ERRORS


def test_the_faceplate_shows_the_loop_and_its_trend_advances(page: Any, run: Run) -> None:
    page.goto(run.base + "/loop/pid")
    until(page, "window.__lw.trendLength > 3")
    n0, x0 = page.evaluate("[window.__lw.trendLength, window.__lw.lastX]")
    assert text(page, "#mode-actual") == "AUTO" and text(page, "#mode-target") == "AUTO"
    assert "q-good" in (page.locator("#v-PV").get_attribute("class") or "")
    assert text(page, "#face .u") == "EU"
    assert page.locator("#comp").count() == 1  # the built-in loop's stiction compensator
    assert "deltav.stick_slip" in text(page, "#comp")
    assert text(page, "#comp-state").startswith("OFF")  # the first variant: compensation off
    assert page.locator("#chart canvas").count() >= 1  # uPlot drew
    time.sleep(1.5)
    n1, x1 = page.evaluate("[window.__lw.trendLength, window.__lw.lastX]")
    assert x1 > x0 + 1.0 and n1 > n0
    alarms = text(page, "#alarms")  # (scan overruns may show: 25 ms scans beside a browser)
    assert "LINK LOST" not in alarms and "BAD" not in alarms and "MODE" not in alarms, alarms


def test_a_change_without_logging_in_is_refused_by_the_controller(page: Any,
                                                                   run: Run) -> None:
    sp0 = number(page, "#v-SP")
    page.fill("#in-SP", "70")
    page.click("#set-SP")
    until(page, "window.__lw.result !== null")
    result = page.locator("#result")
    assert result.get_attribute("data-code") == "BadUserAccessDenied"
    assert "err" in (result.get_attribute("class") or "")
    assert "log in as an operator" in text(page, "#result")
    time.sleep(0.5)
    assert number(page, "#v-SP") == sp0
    assert run.serve is not None
    wait_for_line(run.serve, "by anonymous: refused, BadUserAccessDenied")  # the controller's log


def test_an_operator_logs_in_changes_sp_and_the_pv_follows(page: Any, run: Run) -> None:
    # the scenario's SP step at 60 s of plant time overrides an SP written before it
    until(page, "Number(document.querySelector('#v-SCANS').textContent) >= 125", 15)
    page.click("#login-open")
    page.fill("#login input[name=user]", "op")
    page.fill("#login input[name=password]", "wrong")
    page.click("#login button[type=submit]")
    until(page, "document.querySelector('#login-msg').textContent.includes('refused')")
    page.fill("#login input[name=password]", "secret")
    page.click("#login button[type=submit]")
    until(page, "document.querySelector('#user').textContent === 'op'")
    assert "secret" not in page.content()  # no credentials in the page
    pv0 = number(page, "#v-PV")
    target = round(pv0 + 10.0)
    page.fill("#in-SP", str(target))
    page.click("#set-SP")
    until(page, "window.__lw.result && window.__lw.result.ok && "
                "window.__lw.result.text.startsWith('SP =')")
    until(page, f"Number(document.querySelector('#v-SP').textContent) === {target}", 5)
    # the PV follows: within 120 s of plant time (6 s of wall) near the new SP, on the
    # value and on the trend's last sample
    until(page, f"Math.abs(Number(document.querySelector('#v-PV').textContent) - {target})"
                " < 1.5", 20)
    row = until(page, f"window.__lw.lastRow && Math.abs(window.__lw.lastRow[1] - {target}) < 1.5"
                      " && window.__lw.lastRow", 5)
    assert row[2] == target  # the trend's SP
    assert run.serve is not None
    wait_for_line(run.serve, f"write pid.SP = {float(target)!r} by op (operator): accepted")
    # the controller's refusals are shown: out of range, OUT outside MAN
    page.fill("#in-SP", "1000")
    page.click("#set-SP")
    until(page, "document.querySelector('#result').dataset.code === 'BadOutOfRange'")
    # with the controller's reason (its LAST_REFUSAL node), not OPC UA's stock text
    assert "SP = 1000 is outside 0..100" in page.text_content("#result")
    page.fill("#in-OUT", "40")
    page.click("#set-OUT")
    until(page, "document.querySelector('#result').dataset.code === 'BadInvalidState'")
    assert "OUT is written in MAN only" in page.text_content("#result")
    # MAN, then OUT, then back to AUTO
    page.click("#mode-MAN")
    until(page, "document.querySelector('#mode-target').textContent === 'MAN'", 5)
    page.fill("#in-OUT", "42.5")
    page.click("#set-OUT")
    until(page, "Number(document.querySelector('#v-OUT').textContent) === 42.5", 5)
    # three quick clicks of +1 ask for 43.5, 44.5, 45.5: each adds to the OUT last asked for,
    # not to the displayed one, which lags a refresh (they asked for 43.5 three times)
    for _ in range(3):
        page.click("button.slew[data-slew='1']")
    until(page, "Number(document.querySelector('#v-OUT').textContent) === 45.5", 5)
    page.click("#mode-AUTO")
    until(page, "document.querySelector('#mode-actual').textContent === 'AUTO'", 5)
    # tuning
    page.fill("#in-GAIN", "0.9")
    page.locator("#in-GAIN").press("Enter")
    until(page, "document.querySelector('#v-GAIN').textContent === '0.9'", 5)
    page.fill("#in-GAIN", "0.125")  # a setting shows as given (it showed 0.13)
    page.locator("#in-GAIN").press("Enter")
    until(page, "document.querySelector('#v-GAIN').textContent === '0.125'", 5)
    page.fill("#in-GAIN", "-1")
    page.locator("#in-GAIN").press("Enter")
    until(page, "document.querySelector('#result').dataset.code === 'BadOutOfRange'")
    assert not ERRORS, ERRORS


@pytest.mark.parametrize(("width", "height", "name"), [(390, 844, "phone"),
                                                        (2560, 1440, "monitor")])
def test_the_pages_fit_a_phone_and_a_control_room_monitor(browser: Any, run: Run, width: int,
                                                           height: int, name: str) -> None:
    SHOTS.mkdir(parents=True, exist_ok=True)
    context = browser.new_context(viewport={"width": width, "height": height})
    try:
        pg = context.new_page()
        for path, shot in (("/", "overview"), ("/loop/pid", "loop")):
            pg.goto(run.base + path)
            until(pg, "window.__lw.events > 2 && window.__lw.connected")
            if shot == "loop":
                until(pg, "window.__lw.trendLength > 3")
                box = pg.locator("#chart canvas").first.bounding_box()
                assert box is not None and box["width"] <= width
            pg.screenshot(path=str(SHOTS / f"{shot}-{name}.png"), full_page=True)
            sw, iw = pg.evaluate("[document.scrollingElement.scrollWidth, innerWidth]")
            assert sw <= iw, f"{path} overflows at {width} px: {sw} > {iw}"
            assert (SHOTS / f"{shot}-{name}.png").stat().st_size > 5000
    finally:
        context.close()


def test_a_stopped_controller_shows_stale_and_the_page_recovers(page: Any, run: Run) -> None:
    page.goto(run.base + "/loop/pid")
    until(page, "window.__lw.connected && window.__lw.trendLength > 3")
    assert page.evaluate("window.__lw.stale") is False
    run.stop_serve()
    stopped = time.monotonic()
    until(page, "window.__lw.stale === true && window.__lw.connected === false", 5)
    assert time.monotonic() - stopped < 3.0
    assert "q-stale" in (page.locator("#v-PV").get_attribute("class") or "")
    assert "q-stale" in (page.locator("#v-OUT").get_attribute("class") or "")
    assert text(page, "#badge") == "STALE"
    assert "CONTROLLER LINK LOST" in text(page, "#link")
    assert "CONTROLLER LINK LOST" in text(page, "#alarms")
    run.start_serve()
    until(page, "window.__lw.connected === true && window.__lw.stale === false", 20)
    until(page, "document.querySelector('#v-PV').className.includes('q-good')", 5)
    n0 = page.evaluate("window.__lw.trendLength")
    until(page, f"window.__lw.trendLength > {n0} + 2", 5)
    assert page.evaluate("window.__lw.lastRow[1]") is not None


def test_the_faceplate_stops_promptly_with_a_page_open(page: Any, run: Run) -> None:
    page.goto(run.base + "/")
    until(page, "window.__lw.events > 1")
    assert run.face is not None
    run.face.send_signal(signal.SIGINT)  # an event stream is open
    start = time.monotonic()
    run.face.wait(timeout=15)
    assert time.monotonic() - start < 5.0
    until(page, "window.__lw.connected === false", 6)  # the page says so
