"""cancel_and_wait: a task that loses a cancellation is still stopped (CPython gh-86296)."""

from __future__ import annotations

import asyncio
import contextlib

import pytest

from loopworks.live.tasks import cancel_and_wait


def test_a_task_that_loses_its_first_cancellation_is_still_stopped() -> None:
    """The task swallows the first CancelledError and runs on, as a task does when the
    cancellation is lost inside ``asyncio.wait_for`` on Python 3.11: one ``cancel(); await``
    would wait for ever; cancel_and_wait cancels again and the task ends."""
    seen: list[str] = []

    async def stubborn() -> None:
        try:
            await asyncio.sleep(3600)
        except asyncio.CancelledError:
            seen.append("lost")
        while True:  # runs on, like the faceplate's link polling
            await asyncio.sleep(0.01)

    async def main() -> bool:
        task = asyncio.create_task(stubborn())
        await asyncio.sleep(0.01)
        await asyncio.wait_for(cancel_and_wait(task, retry=0.05), 5.0)
        return task.cancelled()

    assert asyncio.run(main()) is True
    assert seen == ["lost"]


def test_an_exception_the_task_ended_with_is_raised() -> None:
    async def failing() -> None:
        try:
            await asyncio.sleep(3600)
        except asyncio.CancelledError:
            raise RuntimeError("cleanup failed") from None

    async def main() -> None:
        task = asyncio.create_task(failing())
        await asyncio.sleep(0.01)
        await cancel_and_wait(task, retry=0.05)

    with pytest.raises(RuntimeError, match="cleanup failed"):
        asyncio.run(main())


def test_a_task_that_never_ends_is_left_with_a_warning(caplog: pytest.LogCaptureFixture
                                                         ) -> None:
    """A task that swallows every cancellation is given up on after ``tries``, with a
    warning naming it (here it is then told to stop by a flag, so the test ends)."""
    stop = False

    async def immortal() -> None:
        while not stop:
            with contextlib.suppress(asyncio.CancelledError):
                await asyncio.sleep(0.005)

    async def main() -> bool:
        nonlocal stop
        task = asyncio.create_task(immortal(), name="immortal")
        await asyncio.sleep(0.01)
        await cancel_and_wait(task, retry=0.01, tries=3)
        running = not task.done()
        stop = True
        await task
        return running

    with caplog.at_level("WARNING", logger="loopworks.live.tasks"):
        assert asyncio.run(asyncio.wait_for(main(), 5.0)) is True
    assert "task immortal did not end after 3 cancellations" in caplog.text
