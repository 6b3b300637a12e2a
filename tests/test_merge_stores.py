"""Merged stores stay true: ``matrix --resume`` never resumes another machine's run here, a
later merge brings a run's changes over (rows added, its end), two copies of one run whose
rows differ are named, and every merged row passes the store's row check."""
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
