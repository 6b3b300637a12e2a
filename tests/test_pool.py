"""Worker processes (longtime.execution.pool): the --jobs rule and the spawned pool."""
import os

from longtime.execution.pool import spawn_pool, workers


def test_jobs_rule():
    cores = os.cpu_count() or 1
    assert workers(0) == cores
    assert workers(3) == 3
    assert workers(5, tasks=2) == 2
    assert workers(0, tasks=0) == 1
    assert workers(0, tasks=10**6) == cores


def test_spawned_pool_runs_in_other_processes():
    with spawn_pool(1) as pool:
        assert pool.submit(os.getpid).result(timeout=120) != os.getpid()
        assert pool._mp_context.get_start_method() == "spawn"
