"""The store keeps every finished cell of an interrupted matrix; --resume runs the rest."""
import json
import os
import signal
import sqlite3
import subprocess
import sys
import time

import pytest

from longtime.commands.cli import main
from longtime.execution import batches
from longtime.execution.store import Store


def rows_by_key(path):
    with sqlite3.connect(path) as con:
        return dict(con.execute("SELECT cell_key, row FROM rows").fetchall())


def test_ctrl_c_keeps_finished_cells_and_resume_completes(tmp_path, monkeypatch, capsys):
    db = tmp_path / "m.sqlite"
    real = batches.run_cell
    calls = []

    def interrupted_on_third(cell, *args, **kwargs):
        calls.append(cell)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(cell, *args, **kwargs)

    monkeypatch.setattr(batches, "run_cell", interrupted_on_third)
    argv = ["matrix", "-p", "harmonic", "-i", "rk4,verlet,euler", "--executor", "serial",
            "--db", str(db), "--no-progress", "--t-final", "10"]
    assert main(argv) == 130
    store = Store(db)
    run = store.runs()[-1]
    assert run["status"] == "interrupted" and run["planned"] == 9 and run["done"] == 2
    first_two = rows_by_key(db)
    monkeypatch.setattr(batches, "run_cell", real)

    assert main(["matrix", "--resume", "--executor", "serial", "--db", str(db), "--no-progress"]) == 0
    run = store.runs()[-1]
    assert len(store.runs()) == 1 and run["done"] == 9 and run["status"] == "done"
    after = rows_by_key(db)
    # nothing measured is redone: the two rows stored before the interruption gain only the
    # phase they lacked (the timing processes; one process here)
    for key, text in first_two.items():
        before, now = json.loads(text), json.loads(after[key])
        assert before.pop("phases_missing") == ["timing processes"] and "phases_missing" not in now
        # the timing phase adds the other processes' times and says how the cell was timed
        assert {k: v for k, v in now.items() if not k.startswith("cpu_s_process") and k != "timed_in"} == before
    assert {json.loads(r)["status"] for r in after.values()} == {"ok"}
    assert "resuming run 1: 7 cells left" in capsys.readouterr().err


@pytest.mark.slow
def test_killed_matrix_keeps_finished_cells(tmp_path):
    db = tmp_path / "killed.sqlite"
    env = {**os.environ, "LONGTIME_DB": str(db)}
    cmd = [sys.executable, "-m", "longtime.commands.cli", "matrix", "-p", "toda", "-i", "rk4sym,gauss6,rk4",
           "--dt", "0.1,0.05,0.025,0.0125", "--t-final", "3000", "--executor", "serial", "--no-progress"]
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 240
    done = 0
    while time.time() < deadline and proc.poll() is None:
        if db.exists():
            try:
                done = len(rows_by_key(db))
            except sqlite3.OperationalError:
                done = 0
            if done >= 2:
                break
        time.sleep(0.05)
    if proc.poll() is not None:
        pytest.fail("the matrix finished before it could be killed: make its cells longer")
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    kept = rows_by_key(db)
    assert 2 <= len(kept) < 12
    assert main(["matrix", "--resume", "--executor", "serial", "--db", str(db), "--no-progress",
                 "--no-report"]) == 0
    final = rows_by_key(db)
    assert len(final) == 12
    for key, text in kept.items():  # measured once: the rows stored before the kill gain only their phases
        before, now = json.loads(text), json.loads(final[key])
        assert "phases_missing" not in now
        before.pop("phases_missing", None)
        # the timing phase adds the other processes' times and says how the cell was timed
        assert {k: v for k, v in now.items() if not k.startswith("cpu_s_process") and k != "timed_in"} == before


def test_runs_record_metadata(tmp_path, capsys):
    db = tmp_path / "meta.sqlite"
    assert main(["run", "-p", "harmonic", "-i", "verlet", "--t-final", "1", "--db", str(db)]) == 0
    run = Store(db).runs()[-1]
    versions = json.loads(run["versions"])
    machine = json.loads(run["machine"])
    assert versions["numpy"] and versions["numba"] and machine["cpus"] >= 1
    assert run["command"].startswith("run ") and run["started"] and run["finished"]


def test_each_row_is_committed_when_added_and_survives_a_killed_process(tmp_path):
    """The store keeps one writer open for a run's rows (a connection per row cost 4 ms); each
    row must still be on disk as soon as add_row returns, even if the process then dies."""
    db = tmp_path / "k.sqlite"
    script = f"""
import os, sys
from longtime.execution.cells import Cell
from longtime.execution.store import Store
store = Store({str(db)!r})
run = store.begin_run("matrix", [Cell("harmonic", "rk4"), Cell("harmonic", "verlet")])
store.add_row(run, Cell("harmonic", "rk4"), {{"problem": "harmonic", "integrator": "rk4", "status": "ok"}})
assert len(Store({str(db)!r}, readonly=True).rows(run)) == 1  # another connection sees it now
sys.stdout.flush()
os._exit(9)  # no close, no finish_run, no interpreter shutdown
"""
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert done.returncode == 9, done.stderr
    store = Store(db)
    assert [r["integrator"] for r in store.rows(store.runs()[-1]["id"])] == ["rk4"]
    assert [c.integrator for c in store.pending(store.runs()[-1]["id"])] == ["verlet"]
