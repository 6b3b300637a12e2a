"""The dask executor: a small matrix on a distributed LocalCluster gives the serial rows."""
from __future__ import annotations

import pytest

from longtime.commands.cli import build_parser
from longtime.execution.cells import expand
from longtime.execution.matrix import ExecOptions, run_matrix

pytestmark = pytest.mark.slow  # every test here starts processes, clusters or long runs

distributed = pytest.importorskip("distributed")

# fields that do not depend on timing
DETERMINISTIC = ("problem", "integrator", "status", "message", "dt", "steps", "rhs_evals", "nl_iters",
                 "H.max", "H.mean", "L.max", "l2_error", "final_error")


def _deterministic(rows):
    return [{k: r.get(k) for k in DETERMINISTIC} for r in rows]


def test_dask_matrix_gives_the_serial_rows(tmp_path):
    cells = expand(["harmonic", "kepler"], ["rk4", "midpoint"], sweeps={"dt": [0.1, 0.05]}, t_final=3.0)
    serial = run_matrix(cells, None, None, "serial", ExecOptions())
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                                  dashboard_address=None) as cluster:
        rows = run_matrix(cells, None, None, "dask", ExecOptions(scheduler=cluster.scheduler_address))
        # with a time limit each task runs its cell in a child process of the worker
        limited = run_matrix(cells[:2], None, None, "dask",
                             ExecOptions(scheduler=cluster.scheduler_address, cell_timeout=120))
    assert all(r["status"] == "ok" for r in rows)
    assert _deterministic(rows) == _deterministic(serial)
    assert _deterministic(limited) == _deterministic(serial[:2])


def test_scheduler_flag_selects_the_dask_executor():
    args = build_parser().parse_args(["matrix", "--scheduler", "tcp://127.0.0.1:8786"])
    assert args.executor == "dask" and args.scheduler == "tcp://127.0.0.1:8786"
    args = build_parser().parse_args(["matrix", "--executor", "process", "--scheduler", "tcp://h:1"])
    assert args.executor == "process"


def test_a_local_cluster_leaves_no_scratch_space(tmp_path, monkeypatch):
    """The local cluster's scratch space (dask-scratch-space, its lock files) goes with it."""
    import tempfile

    tmp = tmp_path / "tmp"
    tmp.mkdir()
    monkeypatch.setenv("TMPDIR", str(tmp))
    monkeypatch.setattr(tempfile, "tempdir", str(tmp))
    rows = run_matrix(expand(["harmonic"], ["rk4"], sweeps={"dt": [0.1]}, t_final=1.0), None, None, "dask",
                      ExecOptions(jobs=1))
    assert [r["status"] for r in rows] == ["ok"]
    assert list(tmp.iterdir()) == []


TRACKER_KILLED = """
import os, signal, threading, time
from multiprocessing import resource_tracker


def kill_the_tracker():
    while resource_tracker._resource_tracker._pid is None:
        time.sleep(0.05)
    os.kill(resource_tracker._resource_tracker._pid, signal.SIGKILL)


if __name__ == "__main__":
    import longtime

    threading.Thread(target=kill_the_tracker, daemon=True).start()
    rows = longtime.sweep("harmonic", ["rk4", "verlet"], dt=[0.1, 0.05], t_final=2.0, executor="dask", jobs=2,
                          processes=1, repeats=1, min_time=0, progress=False)
    print(sorted(rows["status"]))
"""


def test_a_killed_resource_tracker_costs_one_line_and_no_traceback(tmp_path):
    """multiprocessing's resource tracker (the local cluster's workers are its processes)
    killed while the cluster runs: the rows come, and the tracker started in its place prints
    no KeyError traceback for the names it never saw."""
    import subprocess
    import sys

    script = tmp_path / "killed_tracker.py"
    script.write_text(TRACKER_KILLED)
    res = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=600)
    assert res.returncode == 0 and res.stdout.strip() == "['ok', 'ok', 'ok', 'ok']", res.stderr
    # neither the tracker's KeyError tracebacks nor its warning (Dask's own log lines may come)
    assert "KeyError" not in res.stderr and "resource_tracker.py" not in res.stderr, res.stderr
    assert res.stderr.count("resource tracker process had ended (killed?); a new one runs") == 1, res.stderr
