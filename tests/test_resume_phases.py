"""A run killed in its timing-process phase: its stored rows say what they lack, and
`matrix --resume` times them across processes before it marks the run done."""
import json
import os
import signal
import sqlite3
import subprocess
import sys
import time

import pytest
from _procs import children

from longtime.commands.cli import main

pytestmark = pytest.mark.slow


def _rows(db):
    with sqlite3.connect(db) as con:
        return [json.loads(r[0]) for r in con.execute("SELECT row FROM rows ORDER BY id")]


def _runs(db):
    with sqlite3.connect(db) as con:
        return con.execute("SELECT id, status FROM runs").fetchall()


def test_a_kill_in_the_timing_phase_then_resume_times_every_row_across_processes(tmp_path, capsys):
    db = tmp_path / "k.sqlite"
    env = {**os.environ, "LONGTIME_PROGRESS": "0"}
    proc = subprocess.Popen([sys.executable, "-m", "longtime.commands.cli", "matrix", "-p", "harmonic",
                             "-i", "verlet,rk4", "--dt", "0.01", "--t-final", "20", "--processes", "2",
                             "--executor", "serial", "--repeats", "2", "--min-time", "0", "--checks", "0",
                             "--no-ensemble", "--no-report", "--no-progress", "--db", str(db)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    deadline = time.monotonic() + 120
    while not children(proc.pid, "longtime-timing-"):
        assert proc.poll() is None, proc.stderr.read().decode()
        assert time.monotonic() < deadline, "no timing process started"
        time.sleep(0.02)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    killed = _rows(db)
    assert len(killed) == 2 and all(r["phases_missing"] == ["timing processes"] for r in killed)
    assert all(len(r.get("cpu_s_processes") or []) < 2 for r in killed)
    assert main(["matrix", "--resume", "--executor", "serial", "--processes", "2", "--repeats", "2",
                 "--min-time", "0", "--checks", "0", "--no-ensemble", "--db", str(db), "--no-progress",
                 "--no-report"]) == 0
    assert "2 stored row(s) lack a phase" in capsys.readouterr().err
    resumed = _rows(db)
    assert _runs(db) == [(1, "done")]
    for row in resumed:
        assert row["status"] == "ok", row["message"]
        assert "phases_missing" not in row
        assert len(row["cpu_s_processes"]) == 2 and row["cpu_s"] == min(row["cpu_s_processes"])

