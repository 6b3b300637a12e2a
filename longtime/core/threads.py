"""One thread of BLAS in every process that runs cells.

numpy's and scipy's BLAS (OpenBLAS, or MKL or Accelerate where numpy was built on them) starts
a thread per core in each process and spreads a factorisation or a product over them. The main
job runs one process per core, so in a busy pool the threads of one worker wait on the cores
the other workers hold: an LU factorisation of scipy's Radau, BDF or LSODA, or of an implicit
scheme's Newton solve, then takes several times as long, and the cell's CPU time (its
process's, all threads counted) counts the threads' spinning. The time of such a cell would
depend on what ran beside it, and the pool's work would grow with it
(docs/performance.md, "One thread of BLAS a process").

So every process that runs cells (the pool's and Dask's workers, the timing processes, an
isolated cell's child, Valgrind's) starts with each variable of VARIABLES at 1, unless the
environment sets it already (``single_threaded``); the ``longtime`` command sets them in its
own process before numpy loads (``limit_this_process``), since its checks and the serial
executor run cells there. The libraries read these variables once, when they load, so
they are set before any process imports numpy. This module imports nothing heavy.
"""
from __future__ import annotations

import os
from typing import Mapping

# the thread counts of the BLAS libraries numpy and scipy may load, and of OpenMP
VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "VECLIB_MAXIMUM_THREADS",
             "BLIS_NUM_THREADS")


def single_threaded(env: Mapping[str, str] | None = None) -> dict[str, str]:
    """``env`` (None: this process's environment) with each of VARIABLES it does not set at 1:
    the environment of a process that runs cells."""
    out = dict(os.environ if env is None else env)
    for name in VARIABLES:
        out.setdefault(name, "1")
    return out


def limit_this_process() -> None:
    """Set each of VARIABLES that this process's environment does not set to 1; it takes
    effect only where numpy has not loaded yet (the command's entry point)."""
    for name in VARIABLES:
        os.environ.setdefault(name, "1")
