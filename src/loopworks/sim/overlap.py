"""Overlapping a replay's stages: the next chunk is read while this one runs, and the last one
is written meanwhile, each in a worker thread.

The stages release the GIL where they spend their time (pyarrow's reader, the compiled kernel
runner, the compiled formatter, file writes), so on two cores a bulk replay takes about as long
as its slowest stage instead of the sum of all three. Order and errors are as if the stages ran
one after the other: items come out in order, an error raised while producing an item is raised
where that item would have come out, and a writer's error is raised by the next submit (or by
:meth:`WriteBehind.finish`). At most one item is ahead and one write behind, so memory stays
bounded.
"""

from __future__ import annotations

import contextlib
import queue
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any, Generic, TypeVar

T = TypeVar("T")

_END = object()


class Ahead(Generic[T]):
    """The items of an iterator, produced one ahead in a worker thread. Call :meth:`close`
    when done (also after an error), before what the producer reads is closed."""

    def __init__(self, items: Iterator[T]) -> None:
        self._queue: queue.Queue[tuple[Any, BaseException | None]] = queue.Queue(maxsize=1)
        self._stop = threading.Event()
        self._done = False
        self._thread = threading.Thread(target=self._produce, args=(items,), daemon=True,
                                        name="loopworks-read-ahead")
        self._thread.start()

    def _produce(self, items: Iterator[T]) -> None:
        """Worker: put each item (then the end, or the error that ended it) on the queue."""
        try:
            for item in items:
                if not self._put((item, None)):
                    return
            self._put((_END, None))
        except BaseException as exc:  # handed to the consumer, raised there
            self._put((_END, exc))

    def _put(self, entry: tuple[Any, BaseException | None]) -> bool:
        """Put an entry, waiting while the consumer is one behind; False once closed."""
        while not self._stop.is_set():
            try:
                self._queue.put(entry, timeout=0.05)
                return True
            except queue.Full:
                continue
        return False

    def __iter__(self) -> Ahead[T]:
        return self

    def __next__(self) -> T:
        if self._done:
            raise StopIteration
        item, error = self._queue.get()
        if item is _END:
            self._done = True
            if error is not None:
                raise error
            raise StopIteration
        return item  # type: ignore[no-any-return]

    def close(self) -> None:
        """Stop the producer and wait for it."""
        self._stop.set()
        while self._thread.is_alive():
            with contextlib.suppress(queue.Empty):
                self._queue.get(timeout=0.05)
        self._thread.join()
        self._done = True


class WriteBehind:
    """Calls submitted functions in one worker thread, in order, at most one behind the
    caller. Call :meth:`finish` to wait for the last, and :meth:`close` in any case."""

    def __init__(self) -> None:
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="loopworks-write")
        self._pending: Future[None] | None = None

    def submit(self, fn: Callable[..., None], *args: Any) -> None:
        """Run ``fn(*args)`` after the previous call has finished (raising its error)."""
        self.finish()
        self._pending = self._pool.submit(fn, *args)

    def finish(self) -> None:
        """Wait for the last call; raise its error, if any."""
        pending, self._pending = self._pending, None
        if pending is not None:
            pending.result()

    def close(self) -> None:
        """Wait for the worker to stop (a pending error is dropped: one is being raised)."""
        self._pool.shutdown(wait=True)
