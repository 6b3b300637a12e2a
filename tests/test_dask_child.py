"""Dask workers' long-lived children (longtime.execution.resident.Resident): batches run one after
the other in the same child; a spinning cell ends at its hard limit as a timeout row and the
child is replaced; no child (nor its folder) outlives its cluster or a killed worker."""
import json
import subprocess
import sys
import time

import pytest
from _procs import alive
from test_faults_limits import _spin_env, env  # noqa: F401  (the plugins' fixture)

from longtime.execution.limits import hard_limit

pytestmark = pytest.mark.slow
distributed = pytest.importorskip("distributed")

# a fresh interpreter, as `longtime matrix` on Dask would be
PROBE = r"""
import json, os, signal, time
from distributed import Client, LocalCluster
from longtime.core.integrator import Timing
from longtime.execution.cells import Cell
from longtime.execution.child import RunSpec
from longtime.execution.resident import resident_pids
from longtime.execution.dask_executor import run_batch_limited


def pids(client):
    return sorted(p for ps in client.run(resident_pids).values() for p in ps)


if __name__ == "__main__":
    spec = RunSpec(1000, Timing(repeats=1, min_time=0.0), time_limit=1.0, memory_limit=None)
    ok = [Cell("harmonic", "verlet", {}, {"dt": 0.1}, 1.0), Cell("harmonic", "rk4", {}, {"dt": 0.1}, 1.0)]
    spin = Cell("harmonic", "plug-spin", {}, {"dt": 0.1}, 1.0)
    out = {}
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        with Client(cluster) as client:
            first = client.submit(run_batch_limited, ok[:1], spec, pure=False).result()
            out["first"] = pids(client)
            second = client.submit(run_batch_limited, ok[1:], spec, pure=False).result()
            out["second"] = pids(client)
            started = time.monotonic()
            spun = client.submit(run_batch_limited, [spin, *ok], spec, pure=False).result()
            out["spin_s"] = time.monotonic() - started
            out["after_spin"] = pids(client)
            out["rows"] = [{k: r.get(k) for k in ("integrator", "status", "message")} for r in first + second + spun]
            (worker,) = client.run(os.getpid).values()
            os.kill(worker, signal.SIGKILL)  # the worker dies: its child must die with it
            time.sleep(3.0)
            client.submit(run_batch_limited, ok[:1], spec, pure=False).result()  # on the new worker
            out["new_worker"] = pids(client)
    print(json.dumps(out))
"""


def _gone(pids, seconds=15.0):
    deadline = time.monotonic() + seconds
    while any(alive(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.1)
    return [p for p in pids if alive(p)]


def test_a_worker_keeps_its_child_until_a_cell_passes_its_limit_and_no_child_outlives_the_cluster(
        env, tmp_path):  # noqa: F811
    probe = tmp_path / "probe.py"
    probe.write_text(PROBE)
    temp = tmp_path / "temp"
    temp.mkdir()
    done = subprocess.run([sys.executable, str(probe)], env={**_spin_env(env, tmp_path), "TMPDIR": str(temp)},
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    rows = out["rows"]
    assert [r["status"] for r in rows] == ["ok", "ok", "timeout", "ok", "ok"], rows
    assert "killed" in rows[2]["message"] and f"{hard_limit(1.0):g} s" in rows[2]["message"], rows[2]
    assert out["spin_s"] >= hard_limit(1.0)
    # one child for both batches: the kernels stay loaded between them
    assert len(out["first"]) == 1 and out["first"] == out["second"]
    # the spinning cell took its child with it; the rest of its batch ran in a new one
    assert len(out["after_spin"]) == 1 and out["after_spin"] != out["first"]
    assert not _gone(out["first"])
    # the killed worker's child died with it; the cluster closed took the last one
    assert not _gone(out["after_spin"]), "a child outlived its killed worker"
    assert not _gone(out["new_worker"]), "a child outlived its closed cluster"
    assert not list(temp.glob("longtime-*")), "a child's folder was left behind"
