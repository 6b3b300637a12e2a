"""Worker processes (longtime.execution.pool): the --jobs rule and the pool of resident children."""
import os

import pytest

from longtime.execution.child import CallFailed
from longtime.execution.pool import worker_pool, workers


def test_jobs_rule():
    cores = os.cpu_count() or 1
    assert workers(0) == cores
    assert workers(3) == 3
    assert workers(5, tasks=2) == 2
    assert workers(0, tasks=0) == 1
    assert workers(0, tasks=10**6) == cores


def test_pool_runs_calls_in_other_processes_and_a_crash_costs_one_worker():
    """A call runs in a child; what it raises comes back; a call that kills its child fails
    alone (naming the signal) and the next call runs in a fresh child."""
    with worker_pool(1) as pool:
        first = pool.submit(os.getpid).result(timeout=120)
        assert first != os.getpid()
        assert pool.submit(os.getpid).result(timeout=120) == first  # the same child, kept
        with pytest.raises(KeyError):
            pool.submit({}.__getitem__, "x").result(timeout=120)
        with pytest.raises(CallFailed, match="SIGKILL"):
            pool.submit(os.kill, first, 9).result(timeout=120)
        again = pool.submit(os.getpid).result(timeout=120)
        assert again not in (first, os.getpid())
        assert pool.pids() == [again]
    assert pool.pids() == []
