"""Merged stores stay true: ``matrix --resume`` never resumes another machine's run here, a
later merge brings a run's changes over (rows added, its end), two copies of one run whose
rows differ are named, and every merged row passes the store's row check."""
import json
import sqlite3
from contextlib import closing

from longtime.commands import cli
from longtime.execution.cells import expand
from longtime.execution.run_environment import this_machine
from longtime.execution.store import Store

OTHER = {"node": "ci-runner", "cpu_model": "AMD EPYC (znver4)", "cpus": 96, "machine": "x86_64", "platform": "Linux"}
CELLS = expand(["harmonic"], ["rk4", "verlet"], t_final=5.0)


def _row(cell, cpu_s=1e-3, **extra):
    return {"problem": cell.problem, "integrator": cell.integrator, "status": "ok",
            "dt": cell.integrator_settings.get("dt"), "t_final": 5.0, "cpu_s": cpu_s, **extra}


def _interrupted(path, machine, rows=1):
    """A store with one matrix run of CELLS recorded on ``machine``, interrupted after ``rows`` rows."""
    store = Store(path)
    run_id = store.begin_run("matrix -p harmonic -i rk4,verlet", CELLS)
    store.set_machine(run_id, machine)
    for cell in CELLS[:rows]:
        store.add_row(run_id, cell, _row(cell))
    store.finish_run(run_id, "interrupted")
    return run_id


def test_resume_refuses_another_machines_run(tmp_path, capsys):
    db = tmp_path / "merged.sqlite"
    _interrupted(db, OTHER)
    for extra in ([], ["1"]):
        assert cli.main(["matrix", "--resume", *extra, "--executor", "serial", "--db", str(db), "--no-progress"]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "run 1" in err
        assert "ci-runner (AMD EPYC (znver4), 96 cores)" in err and this_machine()["node"] in err
    store = Store(db, readonly=True)
    assert len(store.rows(1)) == 1 and store.run(1)["status"] == "interrupted"  # left as it was


def test_resume_without_an_id_takes_this_machines_run(tmp_path, capsys):
    db = tmp_path / "merged.sqlite"
    mine = _interrupted(db, this_machine())
    theirs = Store(db).begin_run("matrix -p harmonic -i rk4,verlet", CELLS)
    Store(db).set_machine(theirs, OTHER)
    Store(db).finish_run(theirs, "interrupted")
    assert cli.main(["matrix", "--resume", "--executor", "serial", "--repeats", "1", "--processes", "1",
                     "--db", str(db), "--no-progress", "--checks", "0"]) == 0
    store = Store(db, readonly=True)
    assert len(store.rows(mine)) == 2 and store.run(mine)["status"] == "done"
    assert store.rows(theirs) == [] and store.run(theirs)["status"] == "interrupted"


def _merge(capsys, *stores, into, code=0):
    capsys.readouterr()
    assert cli.main(["merge", *map(str, stores), "--into", str(into), "--format", "json"]) == code
    out = capsys.readouterr()
    return json.loads(out.out), out.err


def test_a_later_merge_brings_the_rows_and_the_end_a_run_gained(tmp_path, capsys):
    a, c = tmp_path / "a.sqlite", tmp_path / "c.sqlite"
    run_id = _interrupted(a, OTHER)
    [first], _ = _merge(capsys, a, into=c)
    assert first["merged"] == "copied" and len(Store(c, readonly=True).rows(first["copy"])) == 1
    store = Store(a)  # resumed on its machine: the second cell stored, the run done
    store.add_row(run_id, CELLS[1], _row(CELLS[1]))
    store.finish_run(run_id, "done")
    [again], err = _merge(capsys, a, into=c)
    assert again["merged"] == "updated" and again["added"] == 1 and again["status_was"] == "interrupted"
    merged = Store(c, readonly=True)
    assert len(merged.rows(again["copy"])) == 2 and merged.run(again["copy"])["status"] == "done"
    assert len(merged.runs()) == 1
    [third], _ = _merge(capsys, a, into=c)  # nothing new: nothing done
    assert third["merged"] == "unchanged" and third["id"] is None


def test_a_run_merged_while_it_runs_is_completed_by_the_next_merge(tmp_path, capsys):
    a, c = tmp_path / "a.sqlite", tmp_path / "c.sqlite"
    store = Store(a)
    run_id = store.begin_run("matrix -p harmonic -i rk4,verlet", CELLS)
    store.add_row(run_id, CELLS[0], _row(CELLS[0], phases_missing=["timing"]))  # its timing processes still to run
    [first], err = _merge(capsys, a, into=c)
    assert first["status"] == "running" and "still running there" in err
    assert Store(c, readonly=True).run(first["copy"])["status"] == "running"
    store.update_row(run_id, CELLS[0], _row(CELLS[0], cpu_s=2e-3))
    store.add_row(run_id, CELLS[1], _row(CELLS[1]))
    store.finish_run(run_id, "done")
    [again], _ = _merge(capsys, a, into=c)
    assert (again["added"], again["replaced"], again["differ"]) == (1, 1, 0)
    merged = Store(c, readonly=True)
    assert merged.run(again["copy"])["status"] == "done"
    assert [r["cpu_s"] for r in merged.rows(again["copy"])] == [2e-3, 1e-3]
    assert not any(r.get("phases_missing") for r in merged.rows(again["copy"]))


def test_two_copies_of_a_run_whose_rows_differ_are_named(tmp_path, capsys):
    a, b, c = tmp_path / "a.sqlite", tmp_path / "b.sqlite", tmp_path / "c.sqlite"
    run_id = _interrupted(a, OTHER, rows=2)
    b.write_bytes(a.read_bytes())  # the same run, then one of its rows edited in b
    Store(b).update_row(run_id, CELLS[1], _row(CELLS[1], cpu_s=5.0))
    records, err = _merge(capsys, a, b, into=c, code=1)
    assert [r["merged"] for r in records] == ["copied", "unchanged"] and records[1]["differ"] == 1
    warned = [line for line in err.splitlines() if "differ" in line]
    assert len(warned) == 1 and f"{b} run {run_id}: 1 row(s) differ" in warned[0]
    assert [r["cpu_s"] for r in Store(c, readonly=True).rows()] == [1e-3, 1e-3]


def test_merge_copies_only_the_rows_the_store_accepts(tmp_path, capsys):
    a, c = tmp_path / "a.sqlite", tmp_path / "c.sqlite"
    run_id = _interrupted(a, OTHER, rows=1)
    bad = {"k1": json.dumps(_row(CELLS[1], cpu_s="fast")), "k2": json.dumps(_row(CELLS[1], evil_field=1)),
           "k3": "{not json", "k4": json.dumps([1, 2]), "k5": json.dumps(_row(CELLS[1], cpu_s="slow"))}
    with closing(sqlite3.connect(a)) as con, con:  # a hand-edited store
        con.executemany("INSERT INTO rows (run_id, cell_key, problem, integrator, status, row, created) "
                        "VALUES (?, ?, 'harmonic', 'verlet', 'ok', ?, 'now')",
                        [(run_id, key, text) for key, text in bad.items()])
    [record], err = _merge(capsys, a, into=c)
    assert record["added"] == 1 and sum(record["refused"].values()) == 5
    refused = [line for line in err.splitlines() if "refused by the row check" in line]
    assert len(refused) == 4  # one line each kind: cpu_s not a number (two rows), evil_field, not JSON, a list
    assert any("2 row(s)" in line and "cpu_s: not a number" in line for line in refused)
    assert any("1 row(s)" in line and "evil_field" in line for line in refused)
    assert any("not JSON" in line for line in refused)
    capsys.readouterr()
    assert cli.main(["report", "--db", str(c), "--run", "all", "--format", "json"]) == 0
    served = json.loads(capsys.readouterr().out)
    assert "evil_field" not in json.dumps(served) and "fast" not in json.dumps(served)


def test_merge_copies_only_the_checks_and_ensemble_records_the_store_accepts(tmp_path, capsys):
    """A check or an ensemble record that the store would refuse to add (a status outside the
    statuses, a field it does not declare, not JSON) is not copied, and counted by its kind."""
    a, c = tmp_path / "a.sqlite", tmp_path / "c.sqlite"
    run_id = _interrupted(a, OTHER, rows=1)
    check = {**_row(CELLS[0]), "check_of": CELLS[0].key, "check_role": "best", "measured_error": 1e-7}
    ensemble = {"problem": "harmonic", "integrator": "verlet", "status": "ok", "members": 8, "distance": 0.1}
    with closing(sqlite3.connect(a)) as con, con:  # a hand-edited store
        con.executemany("INSERT INTO checks (run_id, cell_key, problem, integrator, row, created) "
                        "VALUES (?, ?, 'harmonic', 'rk4', ?, 'now')",
                        [(run_id, "k1", json.dumps(check)), (run_id, "k2", json.dumps({**check, "status": "sucess"})),
                         (run_id, "k3", "{not json")])
        con.executemany("INSERT INTO ensembles (run_id, problem, integrator, status, record, created) "
                        "VALUES (?, 'harmonic', ?, 'ok', ?, 'now')",
                        [(run_id, "verlet", json.dumps(ensemble)),
                         (run_id, "rk4", json.dumps({**ensemble, "integrator": "rk4", "colour": "red"}))])
    [record], err = _merge(capsys, a, into=c)
    assert record["refused_records"] == {"check: status: 'sucess' is not one of ok, diverged, failed, timeout, "
                                         "skipped": 1, "check: not JSON (JSONDecodeError)": 1,
                                         "ensemble: colour: not a declared field (longtime.core.rowschema)": 1}
    assert sum("record(s) not copied" in line for line in err.splitlines()) == 3
    merged = Store(c, readonly=True)
    assert [k["status"] for k in merged.checks()] == ["ok"] and [e["integrator"] for e in merged.ensembles()] == [
        "verlet"]


def test_a_machine_record_nested_past_reading_merges_as_no_machine(tmp_path, capsys):
    """A hand-edited store whose run's machine text is JSON nested deeper than Python reads
    (a RecursionError) merges its run and rows, read as a run of no named machine."""
    source, target = tmp_path / "a.sqlite", tmp_path / "c.sqlite"
    _interrupted(source, OTHER, rows=2)
    with closing(sqlite3.connect(source)) as con:
        con.execute("UPDATE runs SET machine = ?", ("[" * 100_000 + "]" * 100_000,))
        con.commit()
    _merge(capsys, source, into=target)
    store = Store(target)
    assert len(store.runs()) == 1 and len(store.rows(store.runs()[0]["id"])) == 2
