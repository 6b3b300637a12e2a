"""The Dask executor's batches, and a sweep that loses a worker midway and still completes."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

from longtime.execution.cells import expand
from longtime.execution.dask_executor import BATCH_CELLS, BATCHES_PER_WORKER, batches

distributed = pytest.importorskip("distributed")


def test_batches_hold_one_pair_each_and_keep_every_worker_busy():
    cells = expand(["harmonic", "kepler"], ["rk4", "verlet", "gauss4"], sweeps={"dt": [0.1, 0.05, 0.02, 0.01]},
                   t_final=1.0, sets={})
    many = cells * 30  # 720 cells: the batch size is capped
    for group, workers in ((cells, 2), (many, 2), (many, 16)):
        tasks = batches(group, workers)
        assert sorted(c.key for b in tasks for c in b) == sorted(c.key for c in group)
        assert all(len({(c.problem, c.integrator) for c in b}) == 1 for b in tasks)
        assert max(len(b) for b in tasks) <= BATCH_CELLS
        assert len(tasks) >= min(len(group), BATCHES_PER_WORKER * workers)


# run in a fresh interpreter, as `longtime matrix --scheduler` would be: a pytest process that
# has already hosted in-process clusters can leave distributed's event-loop state behind
KILL_PROBE = r"""
import json, os, signal
from distributed import Client, LocalCluster
from longtime.core.timing import Timing
from longtime.execution.cells import expand
from longtime.execution.dask_executor import dask_cluster
from longtime.execution.matrix import ExecOptions

if __name__ == "__main__":
    cells = expand(["harmonic"], ["rk4", "verlet"], sweeps={"dt": [0.02, 0.01, 0.005, 0.004, 0.002, 0.001]},
                   t_final=50.0)
    options = ExecOptions(timing=Timing(repeats=3, min_time=0.1))
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        with Client(cluster) as client:
            pids = sorted(client.run(os.getpid).values())
        options.scheduler = cluster.scheduler_address
        rows = []
        for _, row in dask_cluster(cells, options):
            rows.append(row)
            if len(rows) == 1:  # the other worker is inside a batch now: kill it
                os.kill(pids[-1], signal.SIGKILL)
        with Client(cluster) as client:
            restarted = sorted(client.run(os.getpid).values())
    print(json.dumps({"pids": pids, "restarted": restarted, "cells": [c.integrator_settings["dt"] for c in cells],
                      "rows": [{k: r.get(k) for k in ("dt", "status", "message")} for r in rows]}))
"""


@pytest.mark.slow
def test_a_killed_worker_loses_nothing(tmp_path):
    probe = tmp_path / "kill_probe.py"
    probe.write_text(KILL_PROBE)
    done = subprocess.run([sys.executable, str(probe)], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out["restarted"] != out["pids"]  # a worker really died (its nanny started a new one)
    rows = out["rows"]
    assert sorted(r["dt"] for r in rows) == sorted(out["cells"])
    assert all(r["status"] == "ok" for r in rows), [r["message"] for r in rows if r["status"] != "ok"]
