"""Screenshots of the faceplate for the docs: ``docs/img/faceplate-overview.png`` and
``docs/img/faceplate-loop.png``.

Runs ``loopworks serve --faceplate`` on the built-in scenario at speedup 10 in a temporary
directory (its own device, free loopback ports, a users file with an operator), lets the
loop run through the scenario's start (AUTO at 5 s, the SP step to 51 at 60 s), logs in as
the operator in headless Chromium (the system's, /usr/bin/chromium), moves the SP to 55
and takes both pages once the PV has followed.

    python docs/scripts/faceplate_screenshots.py [--out docs/img]
"""

from __future__ import annotations

import argparse
import os
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from playwright.sync_api import sync_playwright

ARGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync"]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def until(page: object, expr: str, timeout: float = 30.0) -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if page.evaluate(expr):  # type: ignore[attr-defined]
            return
        time.sleep(0.2)
    raise SystemExit(f"timed out waiting for {expr}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path(__file__).parents[1] / "img")
    parser.add_argument("--chromium", default="/usr/bin/chromium")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        users = Path(tmp) / "users.toml"
        subprocess.run([sys.executable, "-m", "loopworks", "users", "add", str(users), "op",
                        "--role", "operator"], input="secret\n", text=True, check=True)
        http = free_port()
        serve = subprocess.Popen(
            [sys.executable, "-m", "loopworks", "serve", "--speedup", "10", "--opcua-port",
             str(free_port()), "--users", str(users), "--state-dir", str(Path(tmp) / "state"),
             "--faceplate", "--faceplate-port", str(http)], cwd=tmp,
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
            env=dict(os.environ, PYTHONUNBUFFERED="1"))
        lines: list[str] = []
        assert serve.stdout is not None
        out = serve.stdout
        threading.Thread(target=lambda: lines.extend(iter(out.readline, "")),
                         daemon=True).start()
        base = f"http://127.0.0.1:{http}"
        try:
            end = time.monotonic() + 120
            while not any("faceplate on" in ln for ln in lines):
                if serve.poll() is not None or time.monotonic() > end:
                    raise SystemExit("serve --faceplate did not start:\n" + "".join(lines))
                time.sleep(0.2)
            with sync_playwright() as p:
                browser = p.chromium.launch(executable_path=args.chromium, headless=True,
                                            args=ARGS)
                page = browser.new_page(viewport={"width": 1280, "height": 860})
                page.goto(base + "/loop/pid")
                # past the scenario's SP step at 60 s of plant time (6 s of wall)
                until(page, "Number(document.querySelector('#v-SCANS')?.textContent) > 160")
                page.click("#login-open")
                page.fill("#login input[name=user]", "op")
                page.fill("#login input[name=password]", "secret")
                page.click("#login button[type=submit]")
                until(page, "document.querySelector('#user').textContent === 'op'")
                page.fill("#in-SP", "55")
                page.click("#set-SP")
                until(page, "Math.abs(Number(document.querySelector('#v-PV').textContent)"
                            " - 55) < 0.6", 60)
                time.sleep(4)
                page.fill("#in-SP", "200")  # refused by the controller: shown as such
                page.click("#set-SP")
                until(page, "document.querySelector('#result').dataset.code"
                            " === 'BadOutOfRange'")
                page.evaluate("document.querySelector('#toast').style.display = 'none'")
                page.screenshot(path=str(args.out / "faceplate-loop.png"), full_page=True)
                page.set_viewport_size({"width": 1280, "height": 520})
                page.goto(base + "/")
                until(page, "window.__lw.events > 3")
                page.screenshot(path=str(args.out / "faceplate-overview.png"), full_page=True)
                browser.close()
        finally:
            serve.send_signal(signal.SIGINT)
            serve.wait(30)
    print(f"wrote {args.out / 'faceplate-overview.png'} and {args.out / 'faceplate-loop.png'}")


if __name__ == "__main__":
    main()
