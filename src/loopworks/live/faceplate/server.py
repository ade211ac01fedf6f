"""The faceplate app served by uvicorn (:func:`run`)."""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from typing import Any

import uvicorn

from loopworks.live.faceplate.app import create_app

#: seconds uvicorn waits for open connections when it stops (the event streams end at once)
GRACEFUL = 2


class _Server(uvicorn.Server):
    """uvicorn, telling the app to end its event streams as soon as it is asked to stop:
    uvicorn waits for open connections before the app's lifespan ends, and an event stream
    never ends by itself (spec: runtime-and-ecosystem section 4)."""

    def __init__(self, config: uvicorn.Config, close: Callable[[], None]) -> None:
        super().__init__(config)
        self._close = close

    async def on_tick(self, counter: int) -> bool:
        done = await super().on_tick(counter)
        if self.should_exit or done:
            self._close()
        return done


def run(opcua_url: str, *, host: str = "127.0.0.1", port: int = 8080,
        ready: Callable[[str], Any] | None = None, period: float = 0.25) -> None:
    """Serve the faceplate of the controller at ``opcua_url`` on http://host:port until
    Ctrl-C / SIGTERM; ``ready`` gets the page's URL once it listens."""
    app = create_app(opcua_url, period=period)
    config = uvicorn.Config(app, host=host, port=port, log_level="warning",
                            timeout_graceful_shutdown=GRACEFUL, lifespan="on")
    server = _Server(config, app.state.faceplate.close)

    async def main() -> None:
        task = asyncio.create_task(server.serve())
        while not server.started:
            if task.done():
                await task
                return
            await asyncio.sleep(0.05)
        if ready is not None:
            bound = port
            for srv in server.servers:
                for sock in srv.sockets:
                    bound = sock.getsockname()[1]
            shown = f"[{host}]" if ":" in host else host
            ready(f"http://{shown}:{bound}/")
        await task

    asyncio.run(main())
    if not server.started:
        raise OSError(f"the faceplate could not listen on {host}:{port}")
