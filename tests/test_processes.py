"""Timing across processes, verdicts on the spread between them, and provenance of the code
under test. No timed assertions: the structure of what is measured and how it is judged."""
import json
import subprocess

import pytest

from longtime.commands import cli
from longtime.core.params import InputError
from longtime.core.timing import Timing
from longtime.execution import processes, provenance
from longtime.execution.cells import Cell, run_cell
from longtime.execution.matrix import ExecOptions, run_matrix
from longtime.execution.processes import MAX_ROUNDS, check_processes, merge, time_cells
from longtime.reporting.compare_cells import compare_rows
from longtime.reporting.compare_text import label
from longtime.reporting.history import process_factor, series_specs


@pytest.mark.slow
def test_n_processes_give_n_minima_and_cpu_s_is_their_minimum():
    cells = [Cell("kepler", "rk4", {}, {"dt": 0.01}, 20.0), Cell("harmonic", "verlet", {}, {"dt": 0.05}, 20.0)]
    rows = run_matrix(cells, None, None, "serial", ExecOptions(processes=3, timing=Timing(repeats=6, min_time=0)))
    for row in rows:
        assert row["status"] == "ok", row["message"]
        mins = row["cpu_s_processes"]
        assert len(mins) == 3 and all(m > 0 for m in mins)
        assert row["cpu_s"] == min(mins)
        # the spread between the fresh processes, which spread their runs over seconds
        assert row["cpu_s_process_spread"] == pytest.approx(max(mins[1:]) / min(mins[1:]))
        assert row["repeats"] == len(row["cpu_s_samples"]) and min(row["cpu_s_samples"]) == row["cpu_s"]
        # the row's own process repeats ceil(6 / 3) times at most; each fresh one at least that
        assert 3 * 2 <= row["repeats"] <= 2 + 2 * MAX_ROUNDS
        assert row["cpu_s_calibrated"] == pytest.approx(row["cpu_s"] / row["calibration_cpu_s"])


def test_a_timing_process_runs_its_cells_in_rounds_until_their_runs_span_seconds(monkeypatch):
    cells = [Cell("harmonic", "verlet", {}, {"dt": 0.05}, 20.0), Cell("kepler", "rk4", {}, {"dt": 0.01}, 5.0)]
    monkeypatch.setattr(processes, "SPREAD_S", 0.0)
    quick = time_cells(cells, 1000, Timing(repeats=2, min_time=0))
    assert [len(r["cpu_s_samples"]) for r in quick] == [2, 2]  # no span asked: the minimum runs alone
    once = time_cells(cells, 1000, Timing(repeats=5, min_time=0, min_runs=1))
    assert [len(r["cpu_s_samples"]) for r in once] == [1, 1]  # a large batch: one run a cell
    budget = time_cells(cells, 1000, Timing(repeats=4, min_time=600.0, min_runs=1))
    assert [len(r["cpu_s_samples"]) for r in budget] == [4, 4]  # under the time budget: up to the repeats
    monkeypatch.setattr(processes, "SPREAD_S", 600.0)
    monkeypatch.setattr(processes, "MAX_ROUNDS", 5)
    spread = time_cells(cells, 1000, Timing(repeats=2, min_time=0, min_runs=1))
    assert [len(r["cpu_s_samples"]) for r in spread] == [5, 5]  # rounds until the span, at most MAX_ROUNDS
    for r, q in zip(spread, quick):
        assert r["status"] == "ok" and r["cpu_s"] == min(r["cpu_s_samples"])
        assert r["samples_digest"] == q["samples_digest"]


def test_one_process_keeps_its_own_minimum():
    rows = run_matrix([Cell("kepler", "rk4", {}, {"dt": 0.01}, 5.0)], None, None, "serial",
                      ExecOptions(processes=1, timing=Timing(repeats=2, min_time=0)))
    assert rows[0]["cpu_s_processes"] == [rows[0]["cpu_s"]] and rows[0]["cpu_s_process_spread"] is None


def test_a_process_that_does_not_reproduce_the_run_fails_the_row():
    row = {"status": "ok", "message": "", "cpu_s": 1.0, "wall_s": 1.0, "cpu_s_samples": [1.0], "samples_digest": "a"}
    merge(row, [{"status": "ok", "cpu_s": 0.9, "wall_s": 0.9, "cpu_s_samples": [0.9], "samples_digest": "a"},
                {"status": "ok", "cpu_s": 0.8, "wall_s": 0.8, "cpu_s_samples": [0.8], "samples_digest": "b",
                 "pid": 7}], 3)
    assert row["status"] == "failed" and "non-deterministic" in row["message"] and "pid 7" in row["message"]
    ok = {"status": "ok", "message": "", "cpu_s": 1.0, "wall_s": 1.0, "cpu_s_samples": [1.0], "samples_digest": "a"}
    merge(ok, [{"status": "ok", "cpu_s": 1.5, "wall_s": 1.5, "cpu_s_samples": [1.5, 1.6], "samples_digest": "a"},
               {"status": "failed", "message": "the timing process exited with code 1"}], 3)
    # with one other process, the spread is the row's own against it
    assert ok["status"] == "ok" and ok["cpu_s_processes"] == [1.0, 1.5] and ok["cpu_s_process_spread"] == 1.5
    assert "timed in 2 of 3 processes: the timing process exited with code 1" in ok["message"]
    assert ok["repeats"] == 3


def test_a_run_with_a_digest_reproduces_it_in_one_process():
    row = run_cell(Cell("kepler", "rk45", {}, {"tol": 1e-8}, 5.0), timing=Timing(repeats=3, min_time=0))
    again = run_cell(Cell("kepler", "rk45", {}, {"tol": 1e-8}, 5.0), timing=Timing(repeats=1))
    assert row["samples_digest"] == again["samples_digest"] and len(row["samples_digest"]) == 40
    other = run_cell(Cell("kepler", "rk45", {}, {"tol": 1e-9}, 5.0), timing=Timing(repeats=1))
    assert other["samples_digest"] != row["samples_digest"]


@pytest.mark.parametrize("value", [0, -1, "x", "1.5"])
def test_a_process_count_below_one_is_bad_input(value):
    with pytest.raises(InputError, match="expected an integer from 1 to"):
        check_processes(value)


def test_processes_zero_on_the_command_line_is_one_line(capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(["run", "-p", "harmonic", "-i", "verlet", "--processes", "0", "--no-store"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--processes" in err and "Traceback" not in err


def _row(cpu, spread, calibrated=None):
    r = {"problem": "kepler", "integrator": "rk4", "status": "ok", "cpu_s": cpu, "t_final": 1.0}
    if spread is not None:
        r["cpu_s_process_spread"] = spread
    if calibrated is not None:
        r.update(cpu_s_calibrated=calibrated, calibration_workload="compute")
    return r


def test_the_cell_verdict_judges_the_spread_between_processes():
    # x1.4 inside a spread of x1.5 between one run's processes: within
    assert compare_rows(_row(1.0, 1.5), _row(1.4, 1.1))["time_verdict"] == "within"
    # x1.3 beyond tight processes (x1.05) and --factor: slower, and the reason names the spread
    c = compare_rows(_row(1.0, 1.05), _row(1.3, 1.02))
    assert c["time_verdict"] == "slower" and c["time_threshold"] == 1.2 and "between processes" in c["regressions"][0]
    # a wide spread raises the threshold above --factor
    assert compare_rows(_row(1.0, 1.6), _row(1.5, 1.1))["time_threshold"] == 1.6
    # rows timed in one process: the single-process factor (x2)
    c = compare_rows(_row(1.0, None), _row(1.5, None))
    assert c["time_verdict"] == "within" and c["time_threshold"] == 2.0 and c["process_spread"] is None
    # the repeats within a process do not enter: a wide spread of samples changes nothing
    a, b = _row(1.0, 1.05), _row(1.3, 1.02)
    a["cpu_s_samples"], b["cpu_s_samples"] = [1.0, 3.0, 5.0], [1.3, 1.3, 1.3]
    assert compare_rows(a, b)["time_verdict"] == "slower"


def test_calibrated_times_are_compared_only_on_the_same_workload():
    a, b = _row(1.0, 1.05, calibrated=10.0), _row(1.0, 1.05, calibrated=2.0)
    b["calibration_workload"] = "memory"
    c = compare_rows(a, b)
    assert c["time_basis"] == "raw" and c["time_verdict"] == "within"


def test_history_steps_pass_the_median_spread_between_processes():
    points = [{"status": "ok", "cpu_s_process_spread": s} for s in (1.1, 1.5, 1.3, 1.05, 1.4)]
    assert process_factor(points, 1.2) == 1.3
    assert process_factor([{"status": "ok", "cpu_s_process_spread": 1.01}], 1.2) == 1.2
    assert process_factor([{"status": "ok"}], 1.2) == 1.2
    specs = series_specs(points, ["l2_error"], 1.2, 2.0)
    assert [s["field"] for s in specs] == ["cpu_s_calibrated", "l2_error"]
    assert specs[0]["factor"] == 1.3 and specs[0]["basis"] == "spread between processes" and specs[1]["factor"] == 2.0


def test_history_headers_differ_in_every_setting_t_final_included():
    a = {"problem": "kepler", "integrator": "rk4", "dt": 0.01, "t_final": 500.0, "settings": ""}
    b = {**a, "t_final": 1000.0}
    c = {**a, "dt": 0.0100000001}
    assert len({label(a), label(b), label(c)}) == 3
    assert "t_final=500" in label(a) and "t_final=1000" in label(b)


def _git(repo, *args):
    return subprocess.run(["git", *args], cwd=repo, check=True, capture_output=True, text=True).stdout.strip()


def test_provenance_finds_the_commit_and_dirty_flag_of_the_code_under_test(tmp_path, monkeypatch):
    repo = tmp_path / "author"
    (repo / "pkg").mkdir(parents=True)
    _git(repo, "init", "-q")
    _git(repo, "config", "user.email", "a@b.c")
    _git(repo, "config", "user.name", "test")
    (repo / "pkg" / "my_scheme_mod.py").write_text("from longtime.integrators.explicit_rk import *\n"
                                                   "class Mine:\n    pass\n")
    _git(repo, "add", "-A")
    _git(repo, "commit", "-q", "-m", "one")
    head = _git(repo, "rev-parse", "HEAD")
    monkeypatch.syspath_prepend(str(repo / "pkg"))
    import my_scheme_mod

    (found,) = provenance.code_under_test([my_scheme_mod.Mine])
    assert found["commit"] == head and found["dirty"] is False and found["repository"] == str(repo.resolve())
    assert found["modules"] == ["my_scheme_mod"]
    (repo / "pkg" / "notes.txt").write_text("uncommitted\n")
    (found,) = provenance.code_under_test([my_scheme_mod.Mine])
    assert found["dirty"] is True
    # longtime's own classes are not the code under test (longtime's commit is recorded apart)
    from longtime.integrators.explicit_rk import RK4

    assert provenance.code_under_test([RK4]) == []
    # a module outside any repository says so
    loose = tmp_path / "loose"
    loose.mkdir()
    (loose / "loose_mod.py").write_text("class Loose:\n    pass\n")
    monkeypatch.syspath_prepend(str(loose))
    import loose_mod

    (entry,) = provenance.code_under_test([loose_mod.Loose])
    assert entry["repository"] is None and "no git repository" in entry["reason"]


@pytest.mark.slow
def test_a_stored_run_records_the_code_under_test(tmp_path, monkeypatch, capsys):
    from longtime.core import registry

    repo = tmp_path / "author"
    repo.mkdir()
    _git(repo, "init", "-q")
    _git(repo, "config", "user.email", "a@b.c")
    _git(repo, "config", "user.name", "test")
    (repo / "author_rk.py").write_text(
        "from longtime.integrators.explicit_rk import RK4\n\n\nclass AuthorRK(RK4):\n"
        "    name = 'author-rk'\n    summary = 'RK4 under another name (test plugin)'\n")
    _git(repo, "add", "-A")
    _git(repo, "commit", "-q", "-m", "one")
    head = _git(repo, "rev-parse", "HEAD")
    monkeypatch.syspath_prepend(str(repo))
    monkeypatch.delenv("LONGTIME_GIT_COMMIT", raising=False)
    import author_rk

    registry.register(author_rk.AuthorRK)
    try:
        _measure_author_runs(tmp_path, head, capsys)
    finally:  # the class's module leaves sys.path with this test: so does the class
        registry._session["integrators"].pop("author-rk", None)


def _measure_author_runs(tmp_path, head, capsys):
    from longtime.execution.store import Store

    db = tmp_path / "s.sqlite"
    assert cli.main(["run", "-p", "harmonic", "-i", "author-rk", "--t-final", "2", "--db", str(db)]) == 0
    (run,) = Store(db).runs()
    assert run["git_commit"] == head
    versions = json.loads(run["versions"])
    assert versions["code"][0]["commit"] == head and versions["code"][0]["dirty"] is False
    assert "commit" in versions["longtime_git"]
    assert cli.main(["run", "-p", "harmonic", "-i", "author-rk", "--t-final", "2", "--db", str(db)]) == 0
    capsys.readouterr()
    assert cli.main(["compare", "1", "2", "--db", str(db)]) == 0
    out = capsys.readouterr().out
    assert f"code under test: {head[:10]} (" in out
    assert cli.main(["history", "--db", str(db), "-i", "author-rk"]) == 0
    assert head[:10] in capsys.readouterr().out


@pytest.mark.slow
def test_benchmark_cell_times_in_processes_and_asv_runs_in_processes():
    from longtime.asvbench import benchmarks
    from longtime.execution.processes import DEFAULT_PROCESSES
    from longtime.testing import benchmark_cell

    class Fixture:  # pytest-benchmark's fixture, reduced to what benchmark_cell calls
        def __init__(self):
            self.extra_info = {}

        def __call__(self, fn, *args):
            return fn(*args)

    bench = Fixture()
    row = benchmark_cell(bench, "kepler", "rk4", t_final=5.0, dt=0.01, processes=3)
    assert row["status"] == "ok"
    assert len(bench.extra_info["cpu_s_processes"]) == 3 and bench.extra_info["cpu_s_processes"][0] == row["cpu_s"]
    assert bench.extra_info["cpu_s_process_spread"] >= 1
    classes = benchmarks(["kepler"], ["rk4"], dt=0.01)
    assert classes["Integration"].processes == DEFAULT_PROCESSES


def test_compare_names_whose_commit_it_shows():
    """A run's commit that is not longtime's own (a plugin's repository) is named as the code
    measured's, never shown as if it were longtime's."""
    from longtime.reporting.compare_text import provenance_lines

    own = {"commit": "a" * 40, "dirty": False}
    same = {"git_commit": "a" * 40, "longtime": "1.0", "longtime_git": own, "code": []}
    lines = provenance_lines({"a": same, "b": {**same, "git_commit": "b" * 40}})
    assert lines[0].startswith("run A: longtime 1.0 (commit aaaaaaaaaa)"), lines
    assert lines[1].startswith("run B: commit of the code measured bbbbbbbbbb; longtime 1.0 (commit aaaaaaaaaa)")
