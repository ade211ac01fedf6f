"""Stopping an asyncio task for sure: :func:`cancel_and_wait`."""

from __future__ import annotations

import asyncio
import logging
from typing import Any

log = logging.getLogger(__name__)

#: seconds between repeated cancellations of a task that has not ended
RETRY = 0.5
#: cancellations tried before giving up on a task (with a warning)
TRIES = 20


async def cancel_and_wait(task: asyncio.Task[Any], *, retry: float = RETRY,
                          tries: int = TRIES) -> None:
    """Cancel ``task`` and wait until it has ended; its CancelledError is not raised here, any
    other exception it ended with is.

    One ``task.cancel()`` is not always enough: on Python 3.11 a cancellation that arrives as
    an ``asyncio.wait_for`` inside the task completes is lost (CPython gh-86296, fixed in
    3.12), and the task runs on, so ``cancel(); await task`` can wait for ever (the faceplate
    did not stop on Ctrl-C once in CI, its link polling through ``wait_for`` every 0.25 s).
    The cancellation is repeated every ``retry`` seconds until the task ends, at most
    ``tries`` times; then a warning, and the task is left running."""
    for _ in range(tries):
        task.cancel()
        done, _ = await asyncio.wait({task}, timeout=retry)
        if done:
            if not task.cancelled() and task.exception() is not None:
                raise task.exception()  # type: ignore[misc]
            return
    log.warning("task %s did not end after %d cancellations", task.get_name(), tries)
