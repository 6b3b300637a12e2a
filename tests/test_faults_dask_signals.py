"""Dask cells under the process pool's hard time and memory limits,
no process of a Dask task outliving its worker, a scheduler address that is not Dask ending
in bounded time before a run is recorded, and stop signals honoured by a process stuck in a
compiled step (--executor serial). Bounded: one worker, limits of a second."""
import json
import os
import signal
import subprocess
import sys
import time

import pytest
from test_faults_limits import _spin_env, env  # noqa: F401  (the plugins' fixture)

from longtime.execution.limits import SIGNAL_GRACE_S, hard_limit
from longtime.execution.store import Store

pytestmark = pytest.mark.slow  # every test here starts processes, clusters or long runs


def _cli(environ, *args, **kwargs):
    return subprocess.Popen([sys.executable, "-m", "longtime.commands.cli", *args], env=environ,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kwargs)


def _alive(pid):
    try:
        return open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def _wait_for(path, seconds=180):
    deadline = time.time() + seconds
    while time.time() < deadline and not (path.exists() and path.read_text().strip()):
        time.sleep(0.1)
    assert path.exists(), f"{path} never written"
    return [int(x) for x in path.read_text().split()]


def test_a_spinning_dask_cell_ends_as_a_timeout_row(env, tmp_path):  # noqa: F811
    pytest.importorskip("distributed")
    proc = _cli(_spin_env(env, tmp_path), "run", "-p", "harmonic", "-i", "plug-spin,verlet", "--dt", "0.1",
                "--t-final", "1", "--time-limit", "1", "--executor", "dask", "--jobs", "1", "--no-store",
                "--format", "json")
    out, err = proc.communicate(timeout=300)
    rows = {r["integrator"]: r for r in json.loads(out)}
    assert rows["plug-spin"]["status"] == "timeout", (rows["plug-spin"], err[-2000:])
    assert "killed" in rows["plug-spin"]["message"]
    assert str(hard_limit(1.0)).rstrip("0").rstrip(".") in rows["plug-spin"]["message"]
    assert rows["verlet"]["status"] == "ok"
    for pid in _wait_for(tmp_path / "spin.txt"):
        assert not _alive(pid)


def test_a_dask_cell_past_the_memory_limit_fails_with_the_limit(env):  # noqa: F811
    pytest.importorskip("distributed")
    proc = _cli(env, "run", "-p", "harmonic", "-i", "plug-hog,verlet", "--dt", "0.1", "--t-final", "1",
                "--memory-limit", "1", "--executor", "dask", "--jobs", "1", "--no-store", "--format", "json")
    out, err = proc.communicate(timeout=300)
    rows = {r["integrator"]: r for r in json.loads(out)}
    assert rows["plug-hog"]["status"] == "failed"
    assert rows["plug-hog"]["message"].startswith("memory limit"), rows["plug-hog"]["message"]
    assert rows["verlet"]["status"] == "ok"


def test_no_process_of_a_dask_task_outlives_its_client(env, tmp_path):  # noqa: F811
    """The client (with its local cluster) killed outright while a cell spins without a time
    limit: the cell's process dies with its worker, the worker with the client."""
    pytest.importorskip("distributed")
    proc = _cli(_spin_env(env, tmp_path), "run", "-p", "harmonic", "-i", "plug-spin", "--dt", "0.1", "--t-final", "1",
                "--time-limit", "0", "--executor", "dask", "--jobs", "1", "--no-store", start_new_session=True)
    (cell,) = _wait_for(tmp_path / "spin.txt")
    os.kill(proc.pid, signal.SIGKILL)
    proc.communicate(timeout=30)
    deadline = time.time() + 60
    while time.time() < deadline and _alive(cell):
        time.sleep(0.5)
    alive = _alive(cell)
    if alive:  # leave nothing behind, whatever the verdict
        os.killpg(proc.pid, signal.SIGKILL)
    assert not alive, "the spinning cell outlived its client by 60 s"


def test_a_scheduler_address_that_is_not_dask_ends_in_bounded_time(tmp_path):
    pytest.importorskip("distributed")
    server = subprocess.Popen([sys.executable, "-m", "http.server", "0", "--bind", "127.0.0.1"],
                              stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        line = server.stdout.readline()  # "Serving HTTP on 127.0.0.1 port N ..."
        port = int(line.split(" port ")[1].split()[0])
        db = tmp_path / "s.sqlite"
        start = time.monotonic()
        proc = _cli(os.environ, "run", "-p", "harmonic", "-i", "rk4", "--dt", "0.1", "--t-final", "2",
                    "--scheduler", f"tcp://127.0.0.1:{port}", "--db", str(db))
        _, err = proc.communicate(timeout=120)
        elapsed = time.monotonic() - start
    finally:
        server.kill()
        server.wait()
    assert proc.returncode == 2, err
    assert len(err.strip().splitlines()) == 1 and "no Dask scheduler answered" in err, err
    assert not db.exists() or Store(db).runs() == []  # no empty run left
    assert elapsed < 90  # 10 s for the scheduler to answer, the rest is the command's start


def _stuck_serial(env, tmp_path):  # noqa: F811
    spin = _spin_env(env, tmp_path)
    db = tmp_path / "serial.sqlite"
    proc = _cli(spin, "matrix", "-p", "harmonic", "-i", "plug-spin", "--dt", "0.1", "--t-final", "1",
                "--executor", "serial", "--db", str(db), "--no-progress", "--no-report")
    _wait_for(tmp_path / "spin.txt.step")
    time.sleep(0.5)  # inside the compiled step
    return proc, db


def test_sigterm_ends_a_serial_run_stuck_in_a_compiled_step(env, tmp_path):  # noqa: F811
    proc, db = _stuck_serial(env, tmp_path)
    os.kill(proc.pid, signal.SIGTERM)
    start = time.monotonic()
    try:
        proc.communicate(timeout=SIGNAL_GRACE_S + 30)
    except subprocess.TimeoutExpired:
        proc.kill()
        pytest.fail("SIGTERM ignored by a process stuck in compiled code")
    assert SIGNAL_GRACE_S - 1 < time.monotonic() - start < SIGNAL_GRACE_S + 20
    died = Store(db).died_in(1)
    assert [c.integrator for c in died] == ["plug-spin"]  # the store knows the cell it was in


def test_a_second_signal_ends_a_stuck_serial_run_at_once(env, tmp_path):  # noqa: F811
    proc, _ = _stuck_serial(env, tmp_path)
    os.kill(proc.pid, signal.SIGINT)
    time.sleep(0.5)
    os.kill(proc.pid, signal.SIGINT)
    start = time.monotonic()
    try:
        proc.communicate(timeout=SIGNAL_GRACE_S)
    except subprocess.TimeoutExpired:
        proc.kill()
        pytest.fail("a second signal did not end the process")
    assert time.monotonic() - start < SIGNAL_GRACE_S - 2
