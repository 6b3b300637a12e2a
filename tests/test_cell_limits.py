"""A cell's own time limit (the default matrix's: a library peer's cell, a setting estimated too
slow) is held by the worker's watchdog and by the isolated executor as the run's --time-limit
is; and every process that runs cells runs BLAS on one thread."""
import json
import os
import subprocess
import sys
import time

import pytest

from longtime.core import registry, threads
from longtime.execution import budget, jobfiles, limits
from longtime.execution.cells import Cell, RunSpec, expand
from longtime.execution.limits import Watchdog, cell_limit, timeout_message


def _sleeper():
    return subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])


def _watch(tmp_path, monkeypatch, job_limit, cell, wait_s):
    """A worker (a sleeping process) in ``cell`` under a watchdog of the job's ``job_limit``,
    with no grace: what the watchdog recorded within ``wait_s`` and whether it killed it."""
    monkeypatch.setattr(limits, "GRACE_S", 0.0)
    monkeypatch.setattr(limits, "GRACE_SHARE", 0.0)
    worker = _sleeper()
    try:
        jobfiles.running_marker(tmp_path, worker.pid).write_text(json.dumps(cell))
        recorded = []
        with Watchdog(tmp_path, job_limit, lambda c, elapsed: recorded.append((c, elapsed))):
            deadline = time.monotonic() + wait_s
            while not recorded and time.monotonic() < deadline:
                time.sleep(0.05)
        return recorded, worker.poll() is not None or _ended(worker)
    finally:
        worker.kill()
        worker.wait()


def _ended(proc, wait_s=2.0):
    try:
        proc.wait(timeout=wait_s)
        return True
    except subprocess.TimeoutExpired:
        return False


def test_the_watchdog_kills_a_cell_past_its_own_limit_without_a_job_limit(tmp_path, monkeypatch):
    cell = {**Cell("harmonic", "diffrax-tsit5").to_dict(), "time_limit": 0.3}
    recorded, killed = _watch(tmp_path, monkeypatch, None, cell, wait_s=10)
    assert killed and recorded, "the cell ran past its own limit and was not killed"
    assert recorded[0][0]["time_limit"] == 0.3 and recorded[0][1] >= 0.3
    message = timeout_message(None, recorded[0][1], recorded[0][0])
    assert "its own time limit 0.3 s" in message and "--time-limit" not in message


def test_the_watchdog_keeps_the_tighter_of_the_jobs_limit_and_the_cells(tmp_path, monkeypatch):
    cell = {**Cell("harmonic", "verlet").to_dict(), "time_limit": 30.0}
    recorded, killed = _watch(tmp_path, monkeypatch, 0.3, cell, wait_s=10)
    assert killed and recorded
    assert "--time-limit 0.3 s" in timeout_message(0.3, recorded[0][1], recorded[0][0])
    assert cell_limit(0.3, cell) == 0.3 and cell_limit(600.0, cell) == 30.0 and cell_limit(None, {}) is None


def test_a_cell_without_a_limit_is_left_alone(tmp_path, monkeypatch):
    recorded, killed = _watch(tmp_path, monkeypatch, None, Cell("harmonic", "verlet").to_dict(), wait_s=1.0)
    assert not recorded and not killed


def test_the_isolated_executor_kills_a_cell_at_its_own_limit(monkeypatch):
    from longtime.execution import isolation

    monkeypatch.setattr(limits, "GRACE_S", 0.0)
    monkeypatch.setattr(limits, "GRACE_SHARE", 0.0)
    cell = Cell("harmonic", "verlet", time_limit=0.5)
    assert isolation._kill_after(cell, None) == pytest.approx(0.5)
    assert isolation._kill_after(cell, 0.2) == pytest.approx(0.2)
    assert isolation._kill_after(Cell("harmonic", "verlet"), None) is None


def test_the_default_matrix_limits_each_library_peers_cell_and_says_why():
    names = [n for n in registry.integrators() if registry.integrator_class(n).cell_budget_s]
    assert names, "no library peer is registered"
    cells, _ = budget.fit(expand(["kepler"], names + ["rk4"], default_sweep=True))
    peers = [c for c in cells if c.integrator in names and not c.skip_reason]
    assert peers and all(c.time_limit is not None and c.time_limit <= budget.PEER_LIMIT_S for c in peers)
    assert all(c.limit_reason for c in peers)
    assert all(c.time_limit is None for c in cells if c.integrator == "rk4")
    again = Cell.from_dict(peers[0].to_dict())
    assert again.limit_reason == peers[0].limit_reason and again.key == peers[0].key


def test_single_threaded_sets_what_the_environment_leaves_unset():
    env = threads.single_threaded({"OPENBLAS_NUM_THREADS": "4", "PATH": "/bin"})
    assert env["OPENBLAS_NUM_THREADS"] == "4" and env["PATH"] == "/bin"
    assert all(env[name] == "1" for name in threads.VARIABLES if name != "OPENBLAS_NUM_THREADS")


def test_a_pool_worker_runs_blas_on_one_thread():
    from longtime.execution.resident import ResidentPool

    spec = RunSpec()
    saved = {name: os.environ.pop(name, None) for name in threads.VARIABLES}
    try:
        with ResidentPool(1, spec) as pool:
            seen = [pool.submit(os.getenv, name).result(timeout=120) for name in threads.VARIABLES]
    finally:
        os.environ.update({k: v for k, v in saved.items() if v is not None})
    assert seen == ["1"] * len(threads.VARIABLES)
