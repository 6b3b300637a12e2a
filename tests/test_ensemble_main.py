"""The main job's ensemble step (longtime.execution.ensembles): each scheme's distance between
its and heyoka's late-time distributions on a chaotic problem, stored in the store's
ensembles table and shown on the page and in the report."""
from __future__ import annotations

import sqlite3

import pytest

from longtime.execution import ensembles
from longtime.execution.cells import Cell
from longtime.execution.store import SCHEMA, SCHEMA_VERSION, Store


def _row(scheme: str, dt: float, t_final: float = 500.0) -> dict:
    """An ok row of henon-heiles at its default state, as the matrix stores one (the step
    reads its scheme, setting, final time and CPU time)."""
    return {"problem": "henon-heiles", "integrator": scheme, "status": "ok", "dt": dt, "tol": None,
            "order": None, "eps_res": None, "t_final": t_final, "settings": "", "cpu_s": 1e-4}


@pytest.fixture(scope="module")
def henon_heiles(tmp_path_factory):
    """The step run on henon-heiles for verlet at a small step, rk4 at a large one and
    explicit Euler (which diverges there), stored; (store, run id, records read back)."""
    db = tmp_path_factory.mktemp("ens") / "ens.sqlite"
    store = Store(db)
    rows = [_row("verlet", 0.01), _row("rk4", 0.4), _row("euler", 0.01)]
    cells = [Cell("henon-heiles", r["integrator"], {}, {"dt": r["dt"]}) for r in rows]
    run_id = store.begin_run("test ensembles", cells)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(ensembles, "DEADLINE_S", 120.0)  # a loaded machine is no timeout here
        mp.setattr(ensembles, "PROBLEM_S", 600.0)
        ensembles.run(store, run_id, rows)
    store.finish_run(run_id, "done")
    return store, run_id, {r["integrator"]: r for r in Store(db, readonly=True).ensembles(run_id)}


def test_the_state_is_chaotic_and_the_floor_is_small(henon_heiles):
    """The ensemble starts from a state with a measured Lyapunov time (not the default
    state where that one is regular) and runs tens of Lyapunov times."""
    _, _, by = henon_heiles
    rec = by["verlet"]
    assert rec["lyapunov_time"] is not None and 1 < rec["lyapunov_time"] < 50, rec["lyapunov_note"]
    assert rec["span_lyapunov"] >= 20
    assert rec["members"] == ensembles.MEMBERS and len(rec["floors"]) == ensembles.FLOOR_ENSEMBLES
    assert 0 < rec["floor"] < 0.1 and rec["floor"] == max(rec["floors"])


def test_a_symplectic_scheme_at_a_small_step_is_within_twice_the_floor(henon_heiles):
    _, _, by = henon_heiles
    rec = by["verlet"]
    assert rec["status"] == "ok" and rec["dt"] == 0.01
    assert rec["distance"] <= 2 * rec["floor"], rec
    assert rec["distinguishable"] is False


def test_a_bad_setting_is_far_above_the_floor(henon_heiles):
    _, _, by = henon_heiles
    rec = by["rk4"]  # dt = 0.4: rk4's dissipation shrinks the visited distribution
    assert rec["status"] == "ok" and rec["distance"] > 4 * rec["floor"], rec
    assert rec["distinguishable"] is True


def test_a_diverged_member_is_a_status_never_a_number(henon_heiles):
    store, run_id, by = henon_heiles
    rec = by["euler"]
    assert rec["status"] == "diverged" and "distance" not in rec and rec["member_status"] == {"diverged": 1}
    with pytest.raises(ValueError, match="carries a distance"):
        store.add_ensemble(run_id, {**rec, "distance": 0.5})


def test_the_page_and_the_report_show_the_distances(henon_heiles):
    from longtime.reporting.page_tables import ensemble_table

    _, _, by = henon_heiles
    html = ensemble_table(list(by.values()))
    for text in ("verlet", "rk4", "as heyoka", "told apart", "diverged", "chaotic state", "floor", "--no-ensemble"):
        assert text in html, text
    line = ensembles.summary(list(by.values()))["henon-heiles"]
    assert line.startswith("1 of 2 schemes as heyoka"), line
    assert "told apart: rk4" in line and "no distance: diverged 1" in line, line


def test_a_store_of_schema_3_still_opens(tmp_path):
    """A store written before the ensembles table: read as it is (no records), and gains the
    table (schema 4) when opened for writing."""
    db = tmp_path / "v3.sqlite"
    v3 = SCHEMA.split("CREATE TABLE IF NOT EXISTS ensembles")[0] + "PRAGMA application_id = 1280600429;\n" \
                                                                  "PRAGMA user_version = 3;\n"
    with sqlite3.connect(db) as con:
        con.executescript(v3)
        con.execute("INSERT INTO runs (started, status, command) VALUES ('2026-01-01T00:00:00+00:00', 'done', 'x')")
    assert Store(db, readonly=True).ensembles(1) == []
    store = Store(db)
    assert sqlite3.connect(db).execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION == 4
    store.add_ensemble(1, {"problem": "henon-heiles", "integrator": "verlet", "status": "skipped", "note": "x"})
    assert [e["status"] for e in Store(db, readonly=True).ensembles(1)] == ["skipped"]


def test_the_main_job_stores_them_and_a_past_run_s_page_shows_them(tmp_path, capsys):
    """`longtime matrix` on henon-heiles measures the ensembles after the cells, the page
    and the report show them, and `longtime report --html` reads them back from the store;
    --no-ensemble skips the step."""
    from longtime.commands.cli import main

    db, page = tmp_path / "m.sqlite", tmp_path / "page"
    args = ["matrix", "-p", "henon-heiles", "-i", "verlet", "--dt", "0.05", "--t-final", "500", "--db", str(db),
            "--executor", "serial", "--checks", "0", "--no-progress", "--repeats", "1", "--processes", "1"]
    assert main([*args, "--html", str(page)]) == 0
    assert "ensemble distance to heyoka's" in capsys.readouterr().out
    [rec] = Store(db, readonly=True).ensembles(1)
    assert rec["integrator"] == "verlet" and rec["status"] in ("ok", "timeout")
    assert "Chaos: ensemble distance" in (page / "index.html").read_text()
    again = tmp_path / "again"
    assert main(["report", "--db", str(db), "--run", "1", "--html", str(again)]) == 0
    assert "Chaos: ensemble distance" in (again / "index.html").read_text()
    assert main([*args, "--no-ensemble", "--no-html"]) == 0
    assert Store(db, readonly=True).ensembles(2) == []


def test_the_process_executor_measures_them_in_a_worker(tmp_path, monkeypatch, capsys):
    """On the process executor a chaotic problem's ensembles are measured by a worker beside
    the checks, once the rows are timed: the main process measures none, and the store holds
    the same record as a serial run's."""
    from longtime.commands.cli import main

    called = []
    measure = ensembles.measure_problem
    monkeypatch.setattr(ensembles, "measure_problem", lambda *a, **k: called.append(a[0]) or measure(*a, **k))
    db = tmp_path / "m.sqlite"
    args = ["matrix", "-p", "henon-heiles", "-i", "verlet", "--dt", "0.05", "--t-final", "500", "--db", str(db),
            "--checks", "0", "--no-progress", "--repeats", "1", "--processes", "1", "--no-html"]
    assert main([*args, "--jobs", "2"]) == 0
    assert called == []  # measured in a worker
    [ahead] = Store(db, readonly=True).ensembles(1)
    assert main([*args, "--executor", "serial"]) == 0
    assert called == ["henon-heiles"]
    [serial] = Store(db, readonly=True).ensembles(2)
    assert ahead["integrator"] == serial["integrator"] == "verlet"
    assert ahead["status"] == serial["status"] and ahead["lyapunov_time"] == serial["lyapunov_time"]
    if ahead["status"] == "ok":
        # seeded members: the same measure wherever it ran (to the rounding of a BLAS reduction)
        assert ahead["distance"] == pytest.approx(serial["distance"], rel=1e-12)
