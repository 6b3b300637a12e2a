"""Worker processes (longtime.execution.pool): the --jobs rule and the spawned pool."""
import os
import subprocess
import sys

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


TRACKER_KILLED = """
import os, signal, sys, time
from multiprocessing import resource_tracker


def double(x):
    return 2 * x


if __name__ == "__main__":
    from longtime.execution.pool import spawn_pool

    with spawn_pool(2) as pool:
        assert list(pool.map(double, range(4))) == [0, 2, 4, 6]
        os.kill(resource_tracker._resource_tracker._pid, signal.SIGKILL)
        time.sleep(0.5)
        assert list(pool.map(double, range(4))) == [0, 2, 4, 6]
    print("done")
"""


def test_a_killed_resource_tracker_costs_one_line_and_no_traceback(tmp_path):
    """multiprocessing's resource tracker killed while a pool runs: the pool goes on, and the
    tracker started in its place prints no KeyError traceback for the names it never saw."""
    script = tmp_path / "killed_tracker.py"
    script.write_text(TRACKER_KILLED)
    res = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=300)
    assert res.returncode == 0 and res.stdout.strip() == "done", res.stderr
    assert "Traceback" not in res.stderr and "KeyError" not in res.stderr, res.stderr
    assert res.stderr.strip().splitlines() == [
        "warning: multiprocessing's resource tracker process had ended (killed?); a new one runs"]
