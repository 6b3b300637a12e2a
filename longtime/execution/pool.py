"""Worker processes: how many a ``--jobs`` value means, and the process pool every command
that fans work out uses (the matrix, warmup, the round-off study, the results page)."""
from __future__ import annotations

import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor
from typing import Any, Callable, Iterator


def workers(jobs: int, tasks: int | None = None) -> int:
    """The worker processes for ``--jobs``: ``jobs`` when > 0, else one per core; never more
    than ``tasks`` (when given), and at least one."""
    n = jobs if jobs > 0 else (os.cpu_count() or 1)
    return max(1, n if tasks is None else min(n, tasks))


def spawn_pool(workers: int, initializer: Callable | None = None, initargs: tuple = ()) -> ProcessPoolExecutor:
    """A pool of ``workers`` spawned processes: a fork after numba's or heyoka's threads (or a
    Dask client's) have started can deadlock, so no pool forks."""
    return ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                               initializer=initializer, initargs=initargs)


def run_tasks(fn: Callable, tasks: list[tuple], jobs: int, scheduler: str | None = None) -> Iterator[tuple[tuple, Any]]:
    """Yield (task, fn(*task)) as the tasks finish: on the Dask cluster at ``scheduler``, else
    on a pool of ``workers(jobs)`` spawned processes (in this process when that is one).
    The studies that fan out independent runs (round-off, the breakdown horizon) use it."""
    if scheduler:
        try:
            from distributed import Client, as_completed
        except ImportError:
            from longtime.core.params import InputError

            raise InputError("--scheduler needs dask.distributed: pip install 'longtime[dask]'") from None
        client = Client(scheduler)
        try:
            futures = {client.submit(fn, *task, pure=False): task for task in tasks}
            for fut in as_completed(futures):
                yield futures[fut], fut.result()
        finally:
            client.close()
        return
    from concurrent.futures import as_completed as finished

    n = workers(jobs, len(tasks))
    if n == 1:
        for task in tasks:
            yield task, fn(*task)
        return
    with spawn_pool(n) as pool:
        futures = {pool.submit(fn, *task): task for task in tasks}
        for fut in finished(futures):
            yield futures[fut], fut.result()
