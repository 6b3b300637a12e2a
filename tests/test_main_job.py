"""The main job from Python (longtime.execution.main_job): a tiny selection planned, run into
a store, its predictions checked; a resumed run; bad input as InputError. And the API's
main_job, which adds the results page and the report."""
import pytest

from longtime.core.integrator import Timing
from longtime.core.params import InputError
from longtime.execution.main_job import MainJobSpec, Selection, plan, run_main_job
from longtime.execution.matrix import ExecOptions
from longtime.execution.store import Store

QUICK = ExecOptions(jobs=1, timing=Timing(repeats=1, min_time=0.0), processes=1)
# 200 timed runs a cell: the checks' budget is a share of the rows' CPU time, repeats included
TIMED = ExecOptions(jobs=1, timing=Timing(repeats=200, min_time=0.0, min_runs=200), processes=1)
TINY = Selection(problems=("harmonic",), schemes=("rk4", "verlet"), t_final=(20.0,))


def _spec(db, **kw) -> MainJobSpec:
    return MainJobSpec(**{"selection": TINY, "executor": "serial", "options": QUICK, "db": str(db),
                          "ensembles": False, **kw})


def test_a_tiny_main_job_stores_every_planned_cell_and_checks_predictions(tmp_path, capsys):
    cells, moves = plan(TINY, QUICK)
    assert cells and not moves  # harmonic at t = 20 fits the budget
    job = run_main_job(_spec(tmp_path / "s.sqlite", checks=2, options=TIMED))
    assert job.ran and job.run_id == 1
    assert len(job.rows) == len(cells)
    assert {r["integrator"] for r in job.rows} == {"rk4", "verlet"}
    assert {r["problem"] for r in job.rows} == {"harmonic"}
    assert all(r["status"] == "ok" and r["t_final"] == 20.0 for r in job.rows)
    store = Store(tmp_path / "s.sqlite")
    assert store.run(job.run_id)["status"] == "done"
    assert job.checks == store.checks(job.run_id)
    # checks re-run stored settings past their runs: each a row of one of the job's schemes
    assert 0 < len(job.checks) and all(c["t_final"] > 20.0 and c["integrator"] in ("rk4", "verlet")
                                       for c in job.checks)
    assert job.ensembles == []  # not measured (and harmonic is not chaotic)
    err = capsys.readouterr().err
    assert f"run 1: {len(cells)} cells into" in err and "checks: " in err


def test_a_resumed_run_whose_cells_are_stored_runs_nothing(tmp_path):
    db = tmp_path / "s.sqlite"
    first = run_main_job(_spec(db, checks=0))
    again = run_main_job(_spec(db, checks=0, resume=first.run_id))
    assert not again.ran and again.run_id == first.run_id
    assert len(again.rows) == len(first.rows)
    with pytest.raises(InputError, match="no incomplete run"):
        run_main_job(_spec(db, checks=0, resume=0))
    with pytest.raises(InputError, match="--resume -1"):
        run_main_job(_spec(db, checks=0, resume=-1))


def test_a_baseline_without_common_cells_is_refused_before_a_run_is_recorded(tmp_path):
    db = tmp_path / "s.sqlite"
    run_main_job(_spec(db, checks=0, selection=Selection(problems=("harmonic",), schemes=("verlet",),
                                                         t_final=(5.0,))))
    with pytest.raises(InputError, match="no cell in common"):
        run_main_job(_spec(db, checks=0, baseline=1,
                           selection=Selection(problems=("harmonic",), schemes=("rk4",), t_final=(5.0,))))
    assert [r["id"] for r in Store(db).runs()] == [1]


def test_the_api_main_job_writes_the_page_and_the_report(tmp_path):
    from longtime.api import main_job

    spec = _spec(tmp_path / "s.sqlite", checks=0,
                 selection=Selection(problems=("harmonic",), schemes=("verlet",), t_final=(5.0,)))
    out = main_job(spec, html=tmp_path / "page")
    assert out.page_error is None and out.page == tmp_path / "page" / "index.html" and out.page.exists()
    assert "harmonic" in out.text and "verlet" in out.text
    assert len(out.job.rows) == len(plan(spec.selection, QUICK)[0])


def test_the_rows_handed_on_as_the_timing_processes_end_are_the_rows_the_store_gives_back(tmp_path):
    """The workers' ensembles start from the timed rows as the store updates them (run_matrix's
    ``on_timed``, ``main_job.as_stored``): the chaotic problems' rows, the very records
    ``Store.rows`` reads back afterwards (the ensembles read nothing else)."""
    from longtime.execution.main_job import as_stored
    from longtime.execution.matrix import run_matrix

    cells, _ = plan(Selection(problems=("henon-heiles", "harmonic"), schemes=("verlet",), t_final=(20.0,)), QUICK)
    store = Store(tmp_path / "s.sqlite")
    run_id = store.begin_run("test", cells)
    handed: list[dict] = []
    run_matrix(cells, store, run_id, "serial", QUICK, on_timed=handed.extend)
    read = [r for r in store.rows(run_id) if r["problem"] == "henon-heiles"]
    assert read and len(handed) == len(cells)
    assert as_stored(handed, run_id) == read  # harmonic, not chaotic, left out


@pytest.mark.slow
def test_the_workers_of_the_checks_stay_up_for_the_page_until_their_stack_closes(tmp_path):
    """With ``keep_workers``, the main job's workers (those of its checks and of the figures
    left to the timed rows) outlive the job, as what ``ahead`` made's ``workers``, until the
    caller's stack closes: the page draws on them rather than on processes of its own."""
    import contextlib
    import os

    from longtime.reporting.figures_ahead import FiguresAhead

    options = ExecOptions(jobs=1, timing=Timing(repeats=1, min_time=0.0), processes=2)
    spec = _spec(tmp_path / "s.sqlite", checks=1, executor="process", options=options)
    with contextlib.ExitStack() as stack:
        job = run_main_job(spec, ahead=FiguresAhead, keep_workers=stack)
        workers = job.ahead.workers
        assert workers is not None and workers.submit(os.getpid).result() in workers.pids()
        # the figures left to the timed rows were drawn on them: the page finds them
        harmonic = [r for r in job.rows if r["problem"] == "harmonic"]
        assert job.ahead.figures("harmonic", harmonic, job.ahead.style, True)
    with pytest.raises(RuntimeError):  # stopped with the stack
        workers.submit(os.getpid)
