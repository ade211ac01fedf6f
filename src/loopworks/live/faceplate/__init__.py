"""``loopworks faceplate``: an operator's faceplate in the browser for a running
``loopworks serve``, as an OPC UA client of it (so no browser can stall the controller).

- :mod:`.link`: the OPC UA link (browse once, poll, stale while lost, reconnect);
- :mod:`.app`: the FastAPI app (pages, server-sent events, JSON API, logins, writes);
- ``static/``: the page's plain JavaScript and CSS, and uPlot 1.6.32 (MIT), vendored;
- :func:`run`: the app on uvicorn, ending its event streams when it shuts down.

Imports FastAPI and uvicorn: only the ``faceplate`` command loads this package.
"""

from __future__ import annotations

from loopworks.live.faceplate.server import run

__all__ = ["run"]
