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
