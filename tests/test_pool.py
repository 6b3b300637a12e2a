"""Worker processes (longtime.execution.pool): the --jobs rule and the pool of resident children."""
import errno
import math
import os
import signal

import pytest

from longtime.execution.pool import worker_pool, workers
from longtime.execution.resident import CallFailed
from longtime.integrators.splitting import Verlet


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


class KillsItsWorker(Verlet):
    """Verlet that SIGKILLs its own process at dt = 0.05."""

    name = "pool-kills-its-worker"
    summary = "Verlet that kills its process at one step"

    def integrate(self, problem, t_final, max_samples=100_001, timing=None, deadline=None):
        if abs(self.dt_for(problem) - 0.05) < 1e-12:
            os.kill(os.getpid(), signal.SIGKILL)
        return super().integrate(problem, t_final, max_samples=max_samples, timing=timing, deadline=deadline)


def test_a_killed_worker_costs_its_cell_and_the_matrix_goes_on():
    """The process executor: a cell that SIGKILLs its worker is a failed row naming the
    signal; the batch's other cells run on a fresh worker, the other worker's rows stand."""
    from longtime.core import registry
    from longtime.core.integrator import Timing
    from longtime.execution.cells import expand
    from longtime.execution.matrix import ExecOptions, run_matrix

    registry.register(KillsItsWorker)
    cells = expand(["harmonic"], [KillsItsWorker.name, "rk4"], sweeps={"dt": [0.1, 0.05, 0.025]}, t_final=2.0)
    options = ExecOptions(jobs=2, timing=Timing(repeats=1, min_time=0.0), processes=1)
    rows = {(r["integrator"], r["dt"]): r for r in run_matrix(cells, None, None, "process", options)}
    assert len(rows) == 6
    killed = rows[(KillsItsWorker.name, 0.05)]
    assert killed["status"] == "failed" and "SIGKILL" in killed["message"], killed
    assert all(r["status"] == "ok" for key, r in rows.items() if key != (KillsItsWorker.name, 0.05)), rows


class NoSpace(Verlet):
    """Verlet whose run finds no space left on the disk."""

    name = "pool-no-space"
    summary = "Verlet that meets a full disk"

    def integrate(self, problem, t_final, max_samples=100_001, timing=None, deadline=None):
        raise OSError(errno.ENOSPC, "No space left on device", "/full")


def test_a_worker_without_disk_space_interrupts_the_run_and_stores_no_row():
    """A full disk in a worker is the machine's fault, not the cell's: DiskFull (the run is
    interrupted, --resume completes it), never a failed row."""
    from longtime.core import registry
    from longtime.core.integrator import Timing
    from longtime.execution.cells import expand
    from longtime.execution.matrix import ExecOptions, run_matrix
    from longtime.execution.tempdirs import DiskFull

    registry.register(NoSpace)
    cells = expand(["harmonic"], [NoSpace.name], sweeps={"dt": [0.1, 0.05]}, t_final=1.0)
    options = ExecOptions(jobs=2, timing=Timing(repeats=1, min_time=0.0), processes=1)
    with pytest.raises(DiskFull, match="no space"):
        run_matrix(cells, None, None, "process", options)


class _Owner:
    """Hands out its tasks, and keeps what came back."""

    def __init__(self, tasks):
        self.tasks, self.got = list(tasks), []

    def task(self):
        if not self.tasks:
            return None
        fn, args = self.tasks.pop(0)
        return fn, args, self.got.append


def test_queued_tasks_give_their_results_to_their_owner_and_a_failed_one_is_only_not_done():
    from longtime.execution.pool import Queued

    owner = _Owner([(abs, (-3,)), ({}.__getitem__, ("x",)), (abs, (-5,))])
    with worker_pool(2) as pool:
        queued = Queued(pool)
        queued.take(owner)
        assert owner.tasks == [] and owner.got == []  # queued, none given yet
        queued.finish()
    assert owner.got == [3, 5]  # the task that raised is left out: its owner does it


@pytest.mark.parametrize("fails", [1, 2, math.inf])
def test_a_batch_that_cannot_be_handed_to_its_worker_is_handed_again_once(monkeypatch, fails):
    """Writing a batch's job is this process's work, not the cells': where it raises (a
    moment of the machine) and then passes, the batch is handed again and its rows are
    measured (with 2 failures: each batch's first hand-over, the second submitted before the
    first is seen); where it raises again, its cells are failed rows naming why."""
    import threading

    from longtime.core import registry
    from longtime.core.integrator import Timing
    from longtime.execution.cells import expand
    from longtime.execution.matrix import ExecOptions, run_matrix

    payload, lock, calls = registry.session_payload, threading.Lock(), []

    def flaky():  # the pool's first ``fails`` hand-overs raise
        if threading.current_thread().name.startswith("longtime-worker"):
            with lock:
                calls.append(1)
                if len(calls) <= fails:
                    raise AssertionError()
        return payload()

    monkeypatch.setattr(registry, "session_payload", flaky)
    cells = expand(["harmonic"], ["verlet", "rk4"], sweeps={"dt": [0.1, 0.05]}, t_final=1.0)
    options = ExecOptions(jobs=1, timing=Timing(repeats=1, min_time=0.0), processes=1, time_limit=60.0)
    rows = run_matrix(cells, None, None, "process", options)
    if fails < math.inf:
        assert [r["status"] for r in rows] == ["ok"] * 4, rows
    else:
        assert all(r["status"] == "failed" and r["message"] == "worker process failed: AssertionError()"
                   for r in rows), rows
