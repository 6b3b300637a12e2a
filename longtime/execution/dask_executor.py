"""The Dask executor: cells as batched tasks on a cluster; only this process writes the store.

Cells go to the workers in batches of one problem x scheme pair (at most ``BATCH_CELLS``
each, and enough batches to keep every worker busy), so a worker compiles a pair's kernel
once and keeps it (a worker is a long-lived process: its compiled loops stay in memory
between tasks), and the scheduler's per-task cost is paid per batch, not per cell. Rows
come back to the client, which yields them to ``run_matrix``: workers never touch the
store, so a store on the client's disk serves any cluster.

Under a time or memory limit (the default has one), a worker runs its batches in a child
process that lives from batch to batch (``run_batch_limited``): a cell that hangs is killed
with the child at its hard limit, a new child takes the next cell, and the worker itself is
never held.

A worker that dies (killed, out of memory, a crashing cell) loses only its running batch:
Dask reschedules the batch on another worker, up to the scheduler's
``distributed.scheduler.allowed-failures`` (default 3); a batch that kills that many workers
comes back as ``failed`` rows naming the error. Only a task that ran and raised is a property
of its cells: a future that the cluster gave up on (the scheduler lost, the future cancelled,
the client's connection closed) raises ``ExecutorLost``, none of its cells is stored, and
the run is marked ``interrupted``. An interrupted client keeps every stored row, and
``longtime matrix --resume`` runs the rest (on any cluster, or none).
"""
from __future__ import annotations

import shutil
from typing import Iterator

from longtime.core.params import InputError
from longtime.core.status import Status
from longtime.execution import tempdirs
from longtime.execution.cells import Cell, RunSpec, base_row, run_cell
from longtime.execution.limits import hard_limit
from longtime.execution.resident import resident


class ExecutorLost(RuntimeError):
    """The executor lost cells it was running (a Dask scheduler gone, a cancelled future, a
    closed client): an interruption, not a property of the cells, so none of them is stored."""


BATCH_CELLS = 64  # cells per task at most: large enough to amortise dispatch, small to balance
BATCHES_PER_WORKER = 4  # at least this many tasks per worker, so no worker idles at the end


def batches(cells: list[Cell], workers: int) -> list[list[Cell]]:
    """``cells`` (runnable) as tasks: each pair's cells (largest pairs first) cut into
    chunks of at most BATCH_CELLS, and small enough for BATCHES_PER_WORKER tasks per worker."""
    from longtime.execution.batches import batches_by_pair

    # floor: then sum over pairs of ceil(n / size) >= len(cells) / size >= the tasks wanted
    size = max(1, min(BATCH_CELLS, len(cells) // (BATCHES_PER_WORKER * max(1, workers))))
    return [pair[i:i + size] for pair in batches_by_pair(cells) for i in range(0, len(pair), size)]


# how long a scheduler has to answer, connection and handshake included
CONNECT_S = 10.0


def check_scheduler(address: str, seconds: float = CONNECT_S) -> None:
    """Refuse, before a run is recorded, an address where no Dask scheduler answers within
    ``seconds``: nothing listening, or a server of another kind (an HTTP server accepts the
    connection and never completes Dask's handshake, which Dask's connect timeout does not
    cover). Connects with Dask's own comm layer and asks the peer's identity."""
    import asyncio

    try:
        from distributed.comm import connect
    except ImportError:
        raise InputError("executor 'dask' needs dask.distributed: pip install 'longtime[dask]'") from None

    async def identity():
        comm = await connect(address, timeout=seconds)
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    refused = _unreachable(address, seconds)
    if refused:  # Dask's connect retries a refused connection until its timeout: say it at once
        raise InputError(f"--scheduler {address}: cannot connect to a Dask scheduler there ({refused})")
    try:
        info = asyncio.run(asyncio.wait_for(identity(), seconds))
    except (asyncio.TimeoutError, TimeoutError):
        raise InputError(f"--scheduler {address}: no Dask scheduler answered there within {seconds:g} s "
                         f"(something listens, but does not speak Dask's protocol)") from None
    except Exception as exc:  # refused, closed mid-handshake, garbage
        raise InputError(f"--scheduler {address}: cannot connect to a Dask scheduler there "
                         f"({type(exc).__name__}: {str(exc)[:200]})") from None
    if not isinstance(info, dict) or info.get("type") != "Scheduler":
        kind = info.get("type") if isinstance(info, dict) else type(info).__name__
        raise InputError(f"--scheduler {address}: the server there is not a Dask scheduler (it says {kind!r})")


def _unreachable(address: str, seconds: float) -> str | None:
    """Why nothing accepts a TCP connection at ``address`` (refused, no route), or None when
    something does or the address is not TCP."""
    import socket

    from distributed.comm.addressing import parse_address, parse_host_port

    scheme, location = parse_address(address)
    if scheme not in ("tcp", "tls"):
        return None
    host, port = parse_host_port(location)
    try:
        with socket.create_connection((host, port), timeout=seconds):
            return None
    except OSError as exc:
        return exc.strerror or str(exc)


def _connect(options, n_cells: int):
    """(client, local cluster or None, the local cluster's scratch folder or None)."""
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise InputError("executor 'dask' needs dask.distributed: pip install 'longtime[dask]'") from None
    if options.scheduler:
        try:
            return Client(options.scheduler, timeout="10s"), None, None
        except (OSError, TimeoutError, ValueError) as exc:
            raise InputError(f"--scheduler {options.scheduler}: cannot connect to a Dask scheduler "
                             f"there ({exc})") from None
    # the workers' scratch space (Dask's dask-scratch-space and its lock files) in a folder of
    # this process, removed with the cluster (``_close``) or by a later process's sweep
    import dask

    from longtime.execution.pool import guard_resource_tracker

    guard_resource_tracker()  # the workers' processes are multiprocessing's: its tracker killed is one line
    scratch = tempdirs.make("dask")
    with dask.config.set({"temporary-directory": str(scratch)}):  # the scheduler's and the nannies' too
        cluster = LocalCluster(n_workers=min(options.workers(), n_cells), threads_per_worker=1,
                               dashboard_address=None, local_directory=str(scratch))
    return Client(cluster), cluster, scratch


def dask_cluster(cells: list[Cell], options) -> Iterator[tuple[Cell, dict]]:
    """Cells as tasks on a Dask cluster: ``options.scheduler`` is its address (without one, a
    local cluster of ``options.jobs`` single-threaded worker processes). Workers need longtime
    and the plugins installed. Under a time or memory limit each worker runs its batches in a
    long-lived child process (``run_batch_limited``); with ``cell_timeout`` each cell is its
    own task, run in a fresh child process of the worker (longtime.execution.isolation)."""
    from distributed import as_completed  # _connect has checked that it is installed

    from longtime.execution.batches import run_batch
    from longtime.execution.isolation import run_cell_isolated

    for cell in cells:
        if cell.skip_reason:
            yield cell, run_cell(cell)
    runnable = [c for c in cells if not c.skip_reason]
    if not runnable:
        return
    client, cluster, scratch = _connect(options, len(runnable))
    spec = options.run_spec()
    try:
        if options.cell_timeout:
            futures = {client.submit(run_cell_isolated, c, spec, options.cell_timeout, pure=False): [c]
                       for c in runnable}
        else:
            workers = max(1, len(client.scheduler_info().get("workers", {})))
            if hard_limit(options.time_limit) is not None or options.memory_limit:
                futures = {client.submit(run_batch_limited, batch, spec, pure=False): batch
                           for batch in batches(runnable, workers)}
            else:
                futures = {client.submit(run_batch, batch, spec, pure=False): batch
                           for batch in batches(runnable, workers)}
        left = len(runnable)
        for fut in as_completed(futures):
            batch = futures[fut]
            try:
                rows = fut.result()
                rows = rows if isinstance(rows, list) else [rows]
            except Exception as exc:
                if fut.status != "error":  # not the task's own failure: the cluster gave the future up
                    where = f"the Dask scheduler {options.scheduler}" if options.scheduler else "the local Dask cluster"
                    raise ExecutorLost(f"{where} was lost ({type(exc).__name__}): {left} of {len(runnable)} "
                                       f"cells not run, none of them stored") from None
                from longtime.execution.tempdirs import disk_full, out_of_space

                if out_of_space(exc):  # the worker's disk, not the cells
                    raise disk_full(exc, "a Dask worker ran its cells") from None
                # the batch raised, or killed allowed-failures workers (KilledWorker)
                rows = [{**base_row(c), "status": Status.FAILED, "message": f"dask task failed: {exc!r}"}
                        for c in batch]
            left -= len(batch)
            yield from zip(batch, rows)
    finally:
        _close(client, cluster)
        if scratch is not None:
            shutil.rmtree(scratch, ignore_errors=True)


def run_batch_limited(cells: list[Cell], spec: RunSpec) -> list[dict]:
    """A batch's rows on a Dask worker under the process executor's limits, run in the worker's
    long-lived child process (longtime.execution.resident.Resident, one per worker thread),
    which keeps its compiled kernels from batch to batch: a cell past the hard limit of
    ``spec.time_limit`` is killed with the child (a ``timeout`` row) and the child replaced,
    a cell past ``spec.memory_limit`` fails (``failed: memory limit``) and the child is
    replaced after the batch. The child dies with its worker (PR_SET_PDEATHSIG, and the end
    of its stdin), so no process of the task outlives it."""
    return resident().run(cells, spec)


def _close(client, cluster) -> None:
    """Close the client (and the local cluster), its logs silenced: after the scheduler is lost
    the client's reconnection logs tracebacks as it is cancelled, and the command reports the
    loss in one line."""
    import logging

    loggers = [logging.getLogger(name) for name in ("distributed.client", "distributed.utils", "distributed.core")]
    levels = [lg.level for lg in loggers]
    try:
        for lg in loggers:
            lg.setLevel(logging.CRITICAL)
        client.close()
        if cluster is not None:
            cluster.close()
    finally:
        for lg, level in zip(loggers, levels):
            lg.setLevel(level)
