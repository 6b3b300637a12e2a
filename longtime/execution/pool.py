"""Worker processes: how many a ``--jobs`` value means, and the process pool every command
that fans work out uses (the matrix, warmup, the round-off study, the results page)."""
from __future__ import annotations

import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor
from typing import Callable


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
