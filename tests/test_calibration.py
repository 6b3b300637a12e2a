"""Calibration: the reference workload is timed beside the cells, stored with the run, and
each row's cpu_s is divided by the calibration of its process nearest in time."""
import json
import sqlite3

import pytest

from longtime.commands import cli
from longtime.execution import calibration
from longtime.execution.calibration import Calibrator, annotate, drift, drift_text, measure
from longtime.execution.store import SCHEMA_VERSION, Store


def test_a_calibration_times_the_reference_workload_repeatedly():
    p = measure("before", repeats=4, steps=20_000)
    assert p["phase"] == "before" and len(p["cpu_s_samples"]) == 4
    assert 0 < p["cpu_s"] == min(p["cpu_s_samples"]) <= p["cpu_s_median"] <= p["cpu_s_max"]
    # the workload is RK4 on the oscillator: its energy error at h = 0.01 is tiny and
    # negative (RK4 damps), and grows with the steps
    e1, e2 = calibration.reference_workload(1000, 0.01), calibration.reference_workload(2000, 0.01)
    assert -1e-9 < e2 < e1 < 0


def test_each_row_takes_the_nearest_calibration():
    points = [{"t": 0.0, "cpu_s": 2e-3}, {"t": 10.0, "cpu_s": 4e-3}]
    row = {"cpu_s": 0.02}
    annotate(row, points, 4.0)
    assert row == {"cpu_s": 0.02, "cpu_s_calibrated": pytest.approx(10.0), "calibration_cpu_s": 2e-3,
                   "calibration_workload": "compute", "calibration_t": 0.0}
    annotate(row, points, 6.0)
    assert row["cpu_s_calibrated"] == pytest.approx(5.0)
    failed = {"cpu_s": None}
    annotate(failed, points, 1.0)
    assert "cpu_s_calibrated" not in failed


def test_a_row_beyond_the_caches_takes_the_memory_workload():
    """The memory workload calibrates a row whose working set passes MEMORY_BOUND_BYTES, the
    reference workload every other row (and any row where the point has no memory part)."""
    points = [{"t": 0.0, "cpu_s": 2e-3, "memory_cpu_s": 8e-3}]
    big = {"cpu_s": 0.04, "working_set_bytes": calibration.MEMORY_BOUND_BYTES + 1}
    small = {"cpu_s": 0.04, "working_set_bytes": 1000}
    annotate(big, points, 0.0)
    annotate(small, points, 0.0)
    assert big["calibration_workload"] == "memory" and big["cpu_s_calibrated"] == pytest.approx(5.0)
    assert small["calibration_workload"] == "compute" and small["cpu_s_calibrated"] == pytest.approx(20.0)
    old = {"cpu_s": 0.04, "working_set_bytes": calibration.MEMORY_BOUND_BYTES + 1}
    annotate(old, [{"t": 0.0, "cpu_s": 2e-3}], 0.0)
    assert old["calibration_workload"] == "compute"
    p = measure("batch", repeats=2, steps=1000, memory_bytes=2**20, memory_repeats=2)
    assert p["memory_bytes"] == 2**20 and p["memory_cpu_s"] == min(p["memory_cpu_s_samples"]) > 0


def test_calibrator_calibrates_on_its_interval_and_hands_each_calibration_on_once(monkeypatch):
    clock = iter([100.0, 101.0, 200.0, 200.0])  # measure, due?, due?, measure
    monkeypatch.setattr(calibration, "measure", lambda phase: {"t": next(clock), "cpu_s": 1e-3, "phase": phase})
    monkeypatch.setattr(calibration.time, "time", lambda: next(clock))
    here = Calibrator(interval=50.0)
    here.start()  # the first: calibrates (t=100)
    first = here.cell({"cpu_s": 0.002}, 100.5, 101.0)  # not due: the t=100 one
    assert first["calibration_t"] == 100.0 and len(first[calibration.POINTS_KEY]) == 1
    second = here.cell({"cpu_s": 0.004}, 150.0, 200.0)  # due: calibrates at t=200, nearest to 175
    assert second["calibration_t"] == 200.0 and [p["t"] for p in second[calibration.POINTS_KEY]] == [200.0]
    assert calibration.take_points(second) and calibration.POINTS_KEY not in second


def test_drift_of_a_run():
    points = [{"t": 0.0, "cpu_s": 3.0e-3, "cpu_s_max": 3.1e-3}, {"t": 20.0, "cpu_s": 3.3e-3, "cpu_s_max": 3.3e-3},
              {"t": 40.0, "cpu_s": 3.15e-3, "cpu_s_max": 3.2e-3}]
    d = drift(points)
    assert d["reference_cpu_s"] == pytest.approx(3.15e-3) and d["range"] == pytest.approx(0.1)
    assert d["first_to_last"] == pytest.approx(1.05) and d["span_s"] == 40.0
    assert "3 calibrations over 40 s: 3 .. 3.3 ms, last/first x1.05" in drift_text(points)
    assert drift([]) is None and drift_text([]).startswith("no calibration")


def test_run_stores_its_calibrations_and_calibrated_rows(tmp_path, capsys):
    db = tmp_path / "cal.sqlite"
    assert cli.main(["run", "-p", "harmonic", "-i", "rk4,verlet", "--dt", "0.1", "--t-final", "50", "--db", str(db),
                     "--format", "json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    store = Store(db)
    points = store.calibrations(1)
    assert [p["phase"] for p in points][0] == "before" and points[-1]["phase"] == "after"
    assert all(len(p["cpu_s_samples"]) == calibration.REPEATS for p in points)
    times = {p["t"]: p["cpu_s"] for p in points}
    for row in store.rows(1):
        assert calibration.POINTS_KEY not in row
        assert times[row["calibration_t"]] == row["calibration_cpu_s"]
        assert row["cpu_s_calibrated"] == row["cpu_s"] / row["calibration_cpu_s"]
    assert {r["integrator"]: r["cpu_s_calibrated"] for r in printed} == \
        {r["integrator"]: r["cpu_s_calibrated"] for r in store.rows(1)}
    assert cli.main(["report", "--db", str(db)]) == 0
    assert "calibration: reference workload" in capsys.readouterr().out


def test_process_pool_workers_calibrate_their_batches(tmp_path, capsys):
    db = tmp_path / "pool.sqlite"
    assert cli.main(["matrix", "-p", "harmonic", "-i", "rk4,verlet", "--dt", "0.1", "--t-final", "50",
                     "--jobs", "2", "--no-html", "--no-progress", "--no-report", "--db", str(db)]) == 0
    store = Store(db)
    points = store.calibrations(1)
    own = {p["pid"] for p in points if p["phase"] in ("before", "after")}
    workers = {p["pid"] for p in points if p["phase"] == "batch"}
    assert len(own) == 1 and len(workers) == 2 and not own & workers
    by_t = {p["t"]: p for p in points}
    for row in store.rows(1):
        assert by_t[row["calibration_t"]]["phase"] == "batch"
        assert row["cpu_s_calibrated"] == pytest.approx(row["cpu_s"] / by_t[row["calibration_t"]]["cpu_s"])


V1_SCHEMA = """
CREATE TABLE runs (id INTEGER PRIMARY KEY AUTOINCREMENT, started TEXT NOT NULL, finished TEXT,
    status TEXT NOT NULL, command TEXT, git_commit TEXT, versions TEXT, machine TEXT);
CREATE TABLE planned (run_id INTEGER NOT NULL, cell_key TEXT NOT NULL, cell TEXT NOT NULL,
    PRIMARY KEY (run_id, cell_key));
CREATE TABLE rows (id INTEGER PRIMARY KEY AUTOINCREMENT, run_id INTEGER NOT NULL, cell_key TEXT NOT NULL,
    problem TEXT NOT NULL, integrator TEXT NOT NULL, status TEXT NOT NULL, row TEXT NOT NULL,
    created TEXT NOT NULL, UNIQUE (run_id, cell_key));
CREATE TABLE started (run_id INTEGER NOT NULL, cell_key TEXT NOT NULL, pid INTEGER, host TEXT,
    started TEXT NOT NULL, PRIMARY KEY (run_id, cell_key));
INSERT INTO runs (started, status, command) VALUES ('2026-01-01T00:00:00+00:00', 'done', 'run old');
INSERT INTO rows (run_id, cell_key, problem, integrator, status, row, created)
    VALUES (1, 'k', 'harmonic', 'rk4', 'ok', '{"problem": "harmonic", "integrator": "rk4", "status": "ok"}', 'x');
PRAGMA application_id = 1280600429;
PRAGMA user_version = 1;
"""


def test_a_store_of_schema_1_keeps_working(tmp_path):
    db = tmp_path / "v1.sqlite"
    with sqlite3.connect(db) as con:
        con.executescript(V1_SCHEMA)
    old = Store(db, readonly=True)  # read as it is: no calibrations, nothing written
    assert old.calibrations(1) == [] and old.checks(1) == [] and len(old.rows(1)) == 1
    assert sqlite3.connect(db).execute("PRAGMA user_version").fetchone()[0] == 1
    store = Store(db)  # opened for writing: gains the tables
    assert sqlite3.connect(db).execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION == 4
    assert store.checks(1) == []
    store.add_calibrations(1, [{"t": 1.0, "pid": 7, "phase": "after", "cpu_s": 2e-3}])
    assert store.calibrations(1) == [{"t": 1.0, "pid": 7, "phase": "after", "cpu_s": 2e-3}]
