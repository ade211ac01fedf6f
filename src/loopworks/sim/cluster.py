"""Running a sweep's instances on a Dask distributed cluster (``loopworks sweep --scheduler``).

The instances are cut into chunks of at least ``CHUNK_SECONDS`` of work (estimated from one
instance run here first, after a warm-up run that also checks the scenario builds), each chunk
runs :func:`loopworks.sim.sweep.run_jobs` on a worker (which parses the scenario text once and
runs its instances through the compiled plan), and the metrics come back in instance order: the
same numbers as a local run, instance by instance, since every instance is fixed by its values
and its seed. Dask is an optional extra: ``pip install "loopworks[cluster]"``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

from loopworks.errors import InputError

if TYPE_CHECKING:
    from loopworks.sim.sweep import Job

CHUNK_SECONDS = 0.1  # the least work a chunk carries, s (Dask's overhead is ~1 ms a task)


def run_on_cluster(address: str, text: str, source: str, jobs: Sequence[Job],
                   progress: Callable[[int, int], None] | None = None,
                   plan: str = "auto") -> list[dict[str, float]]:
    """Every job's metrics, in job order, computed on the Dask scheduler at ``address``
    (``plan``: the batches' plan, :func:`loopworks.sim.sweep.run_jobs`)."""
    check_address(address)
    from distributed import Client, as_completed

    from loopworks.sim.sweep import run_jobs

    total = len(jobs)
    if total == 0:
        return []
    try:
        client = Client(address, timeout="10s")  # type: ignore[no-untyped-call]
    except OSError as exc:
        raise InputError(f"--scheduler {address}: cannot reach the scheduler: {exc}") from None
    with client:  # connected first: a wrong address is an error before any work
        # warm-up here: builds and compiles (or loads) the plan
        run_jobs(text, source, jobs[:1], plan, total)
        start = time.perf_counter()
        first = run_jobs(text, source, jobs[:1], plan, total)
        per = max(time.perf_counter() - start, 1e-6)
        size = max(1, math.ceil(CHUNK_SECONDS / per))
        chunks = [list(jobs[i:i + size]) for i in range(1, total, size)]
        futures = [client.submit(run_jobs, text, source, chunk, plan, total, pure=False)
                   for chunk in chunks]
        index = {f.key: k for k, f in enumerate(futures)}
        results: list[list[dict[str, float]] | None] = [None] * len(chunks)
        done = 1
        if progress is not None:
            progress(done, total)
        for future in as_completed(futures):  # type: ignore[no-untyped-call]
            k = index[future.key]
            results[k] = future.result()
            done += len(chunks[k])
            if progress is not None:
                progress(done, total)
    return [*first, *(row for part in results if part is not None for row in part)]


def check_address(address: str) -> None:
    """Before anything runs: Dask is installed (else how to get it) and ``address`` is a
    scheduler's address (a malformed one is an InputError here, before a Client is made: a
    Client that fails to parse its address leaves its event-loop thread behind)."""
    try:
        from distributed.comm.addressing import get_address_host_port, parse_address
    except ImportError:
        raise InputError(f"--scheduler {address}: running on a Dask cluster needs the cluster "
                         "extra: pip install \"loopworks[cluster]\"") from None

    try:
        scheme, _ = parse_address(address)
        if scheme != "inproc":  # an in-process cluster's address has no port
            _, port = get_address_host_port(address)
            if not 0 < port < 65536:
                raise ValueError(f"port {port} is not 1..65535")
    except (ValueError, TypeError) as exc:
        raise InputError(f"--scheduler {address!r}: not a scheduler address ({exc}): expected "
                         "tcp://HOST:PORT, as the scheduler prints it") from None
