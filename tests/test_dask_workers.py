"""The Dask executor's batches, and a sweep that loses a worker midway and still completes."""
from __future__ import annotations

import os
import signal

import pytest

from longtime.cells import expand
from longtime.dask_executor import BATCH_CELLS, BATCHES_PER_WORKER, batches
from longtime.integrator import Timing
from longtime.matrix import ExecOptions

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


def test_a_killed_worker_loses_nothing(tmp_path):
    from distributed import Client, LocalCluster

    from longtime.dask_executor import dask_cluster

    cells = expand(["harmonic"], ["rk4", "verlet"], sweeps={"dt": [0.02, 0.01, 0.005, 0.004, 0.002, 0.001]},
                   t_final=50.0)
    options = ExecOptions(timing=Timing(repeats=3, min_time=0.1))
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        options.scheduler = cluster.scheduler_address
        pids = sorted(client.run(os.getpid).values())
        rows = []
        for _, row in dask_cluster(cells, options):
            rows.append(row)
            if len(rows) == 1:  # the other worker is inside a batch now: kill it
                os.kill(pids[-1], signal.SIGKILL)
        restarted = sorted(client.run(os.getpid).values())
    assert restarted != pids  # a worker really died (its nanny started a new one)
    assert sorted(r["dt"] for r in rows) == sorted(c.integrator_settings["dt"] for c in cells)
    assert all(r["status"] == "ok" for r in rows), [r["message"] for r in rows if r["status"] != "ok"]
