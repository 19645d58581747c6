"""Chunks as Dask tasks: on a local cluster over this machine's cores, or on an existing cluster.

Each chunk is one independent task (``compute.chunk_results`` of its robots). The scheduler hands a
chunk whose worker died to another worker, up to ``distributed.scheduler.allowed-failures`` times; a
chunk that raised is retried RETRIES times. Results come back to this process, which stores each
chunk as it finishes, so the workers need the package but no shared file system.
"""

from __future__ import annotations

import logging
import os
import socket
import uuid
from contextlib import ExitStack
from typing import Callable, Sequence

from wallbot_sim.sweep.compute import chunk_results
from wallbot_sim.sweep.errors import SweepError
from wallbot_sim.sweep.spec import SweepSpec

RETRIES = 2
"""Extra attempts of a chunk whose task raised (a dead worker's chunk is rescheduled besides)."""
LOCAL_HOST = '127.0.0.1'
"""The local cluster listens on the loopback interface only: nothing outside this machine reaches it."""
CONNECT_TIMEOUT = '20s'
"""How long the Dask client may take to join a scheduler that accepted its connection."""
REACH_TIMEOUT = 3.0
"""Seconds a scheduler's port may take to accept a TCP connection (Dask's client retries a refused one until its
timeout, which would keep a mistyped address waiting)."""


def reach_scheduler(address: str) -> None:
    """SweepError unless the host and port of ``address`` (tcp:// or tls://) accept a TCP connection within
    REACH_TIMEOUT; other protocols are left to Dask."""
    protocol, _, location = address.rpartition('://')
    if protocol not in ('', 'tcp', 'tls'):
        return
    host, _, port = location.rpartition(':')
    if not port.isdigit():
        raise SweepError(f'cannot reach the Dask scheduler at {address}: expected tcp://HOST:PORT')
    try:
        socket.create_connection((host.strip('[]') or LOCAL_HOST, int(port)), timeout=REACH_TIMEOUT).close()
    except OSError as error:
        reason = 'no answer' if isinstance(error, TimeoutError) else error.strerror or str(error)
        raise SweepError(f'cannot reach the Dask scheduler at {address}: {reason}') from None


def local_workers(chunks: Sequence[int], workers: int | None = None) -> int:
    """The processes a local cluster computes ``chunks`` with: ``workers`` (default: one per core), one per chunk
    at most."""
    return min(workers or os.cpu_count() or 1, len(chunks))


def computes_here(chunks: Sequence[int], workers: int | None = None, scheduler: str | None = None) -> bool:
    """Whether ``run_chunks`` computes ``chunks`` in this process: no scheduler given and one worker's work."""
    return scheduler is None and local_workers(chunks, workers) == 1


def run_chunks(spec: SweepSpec, chunks: Sequence[int], on_done: Callable[[int, list[list[float]]], None],
               workers: int | None = None, scheduler: str | None = None, security: object | None = None) -> None:
    """Compute ``chunks`` (indices into ``spec.chunks()``) and give each one's rows to ``on_done`` as it
    finishes. ``scheduler``: an existing cluster's address (tcp://HOST:PORT, or tls://... with
    ``security``, a ``distributed.Security``); None: a local cluster of ``workers`` processes
    (default: one per core), at most one per chunk: one chunk, or ``workers`` 1, is computed in this process,
    without Dask (a local cluster takes seconds to start)."""
    if not chunks:
        return
    if computes_here(chunks, workers, scheduler):  # one worker: this process, no cluster to start
        for index in chunks:
            on_done(index, chunk_results(spec.settings, [spec.parameters(robot) for robot in spec.chunks()[index]]))
        return
    from dask.distributed import Client, LocalCluster, as_completed  # only when a sweep runs
    from distributed.scheduler import KilledWorker

    with ExitStack() as stack:
        if scheduler is None:
            cluster = stack.enter_context(LocalCluster(
                n_workers=local_workers(chunks, workers), threads_per_worker=1, processes=True, host=LOCAL_HOST,
                dashboard_address=None, silence_logs=logging.ERROR))
            client = stack.enter_context(Client(cluster))
        else:
            try:
                client = stack.enter_context(Client(scheduler, timeout=CONNECT_TIMEOUT, security=security))
            except (OSError, TimeoutError, ValueError) as error:
                raise SweepError(f'cannot reach the Dask scheduler at {scheduler}: {error}') from None
            except Exception as error:  # noqa: BLE001 - whatever Dask makes of a port that answers otherwise
                raise SweepError(f'{scheduler} did not answer as a Dask scheduler '
                                 f'({type(error).__name__} in the handshake)') from None
        # settings go with every task (small): scattered data would die with the workers holding it,
        # and a worker that joins later would not have it
        settings = spec.settings
        ranges = spec.chunks()
        run = uuid.uuid4().hex[:8]
        futures = {}
        for index in chunks:
            robots = [spec.parameters(robot) for robot in ranges[index]]
            future = client.submit(chunk_results, settings, robots, key=f'wallbot-sweep-{run}-chunk-{index:06d}',
                                   retries=RETRIES, pure=False)
            futures[future] = index
        for future in as_completed(futures):
            try:
                rows = future.result()
            except KilledWorker:
                raise SweepError(f'chunk {futures[future]}: every worker that ran it died (the scheduler\'s '
                                 'allowed-failures); the finished chunks are kept') from None
            on_done(futures[future], rows)
