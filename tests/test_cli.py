"""Bad input: a clear message naming the argument, exit code 2, and nothing in the store lost."""
import json
import sqlite3

import numba
import numpy as np
import pytest

from longtime import Problem
from longtime.commands.cli import main
from longtime.core import registry
from longtime.core.params import InputError
from longtime.execution.cells import Cell
from longtime.execution.store import Store


def run_cli(capsys, *argv):
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.fixture
def db(tmp_path):
    """A store holding one finished run of one row, written without running a cell: bad input
    is refused before any cell runs, so what a refusal must keep is a row, not a measurement."""
    path = tmp_path / "store.sqlite"
    store = Store(path)
    cell = Cell("harmonic", "rk4", t_final=10.0)
    run_id = store.begin_run("run -p harmonic -i rk4", [cell])
    store.add_row(run_id, cell, {"problem": "harmonic", "integrator": "rk4", "status": "ok", "t_final": 10.0})
    store.finish_run(run_id, "done")
    assert len(stored_rows(path)) == 1
    return path


def stored_rows(path):
    with sqlite3.connect(path) as con:
        return con.execute("SELECT row FROM rows ORDER BY id").fetchall()


BAD = [
    (["-p", "nope", "-i", "rk4"], ["unknown problem 'nope'", "harmonic", "toda"]),
    (["-p", "toda", "-i", "rk5"], ["unknown integrator 'rk5'", "rk4sym"]),
    (["-p", "toda", "-i", "rk4", "--dt", "0"], ["dt=0.0", "> 0"]),
    (["-p", "toda", "-i", "rk4", "--dt", "-0.1"], ["dt=-0.1", "> 0"]),
    (["-p", "toda", "-i", "rk4", "--dt", "nan"], ["dt=nan", "finite"]),
    (["-p", "toda", "-i", "rk4", "--t-final", "0"], ["t_final=0.0", "> t0"]),
    (["-p", "toda", "-i", "rk4", "--t-final", "inf"], ["t_final=inf"]),
    (["-p", "harmonic", "-i", "rk4", "--set", "q0=nan"], ["q0", "finite"]),
    (["-p", "toda", "-i", "rk4", "--set", "bogus=1"], ["--set bogus", "their parameters: compensated, d, dt"]),
    (["-p", "toda", "-i", "rk4", "--set", "d=2"], ["d=", ">= 3"]),
    (["-p", "toda", "-i", "rk4", "--eps-res", "1e-6"], ["--eps-res", "not a parameter"]),
    (["-p", "toda", "-i", "midpoint", "--set", "max_iter=0"], ["max_iter", "> 0"]),
    (["-p", "toda", "-i", "midpoint", "--set", "max_iter=1e19"], ["max_iter", "64-bit"]),
    (["-p", "toda", "-i", "midpoint", "--set", "max_iter=99999999999999999999"], ["max_iter", "64-bit"]),
    (["-p", "toda", "-i", "rk4", "--set", "d=3", "--set", "d=4"], ["--set d is given twice"]),
    (["-p", "toda", "-i", "rk4", "--set", "d=3,4", "--set", "d=5"], ["--set d is given twice"]),
    (["-p", "toda", "-i", "rk4", "--dt", "0.1", "--set", "dt=0.2,0.3"], ["--dt and --set dt="]),
]


@pytest.mark.parametrize("args, words", BAD, ids=[" ".join(a) for a, _ in BAD])
def test_bad_input_is_a_clear_error_and_keeps_the_store(capsys, db, args, words):
    before = stored_rows(db)
    code, out, err = run_cli(capsys, "run", *args, "--db", str(db))
    assert code == 2
    assert out == ""
    for word in words:
        assert word in err, err
    assert stored_rows(db) == before


def test_input_errors_are_one_line(capsys):
    code, out, err = run_cli(capsys, "run", "-p", "toda", "-i", "rk4", "--set", "d=3", "--set", "d=4", "--no-store")
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1, err


@pytest.mark.parametrize("order, words", [("5..1", "an empty range"), ("1..1000000000000", "over the limit")])
def test_order_ranges_refused(capsys, order, words):
    with pytest.raises(SystemExit) as exc:
        main(["run", "-p", "toda", "-i", "bpl", "--order", order, "--no-store"])
    assert exc.value.code == 2
    assert words in capsys.readouterr().err


def test_argument_syntax_errors_exit_non_zero(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["run", "-p", "toda", "-i", "rk4", "--dt", "abc"])
    assert exc.value.code == 2
    assert "--dt takes comma-separated numbers" in capsys.readouterr().err


@numba.njit
def _rhs_nonseparable(t, u, params, out):
    out[0] = u[1]
    out[1] = -u[0] - 0.1 * u[1]


class Damped(Problem):
    name = "test-damped"
    summary = "damped oscillator with no separable split"
    rhs = staticmethod(_rhs_nonseparable)

    def initial_state(self):
        return [1.0, 0.0]


class NotFinite(Damped):
    name = "test-not-finite"

    def initial_state(self):
        return [np.nan, 0.0]


@pytest.fixture
def extra_problems():
    found = registry._load()["problems"]
    found.update({"test-damped": Damped, "test-not-finite": NotFinite})
    yield
    found.pop("test-damped")
    found.pop("test-not-finite")


def test_incompatible_pair_asked_for_explicitly(capsys, db, extra_problems):
    before = stored_rows(db)
    code, _, err = run_cli(capsys, "run", "-p", "test-damped", "-i", "verlet", "--db", str(db))
    assert code == 2
    assert "incompatible pair verlet x test-damped" in err and "separable" in err
    assert stored_rows(db) == before


def test_incompatible_pair_in_a_matrix_is_a_skipped_row(capsys, tmp_path, extra_problems):
    code, out, _ = run_cli(capsys, "matrix", "-p", "test-damped", "-i", "verlet,rk4", "--executor", "serial",
                           "--db", str(tmp_path / "m.sqlite"), "--no-progress", "--t-final", "1")
    assert code == 0
    rows = {json.loads(r[0])["integrator"]: json.loads(r[0]) for r in stored_rows(tmp_path / "m.sqlite")}
    assert rows["verlet"]["status"] == "skipped" and "separable" in rows["verlet"]["message"]
    assert rows["rk4"]["status"] == "ok"


def test_non_finite_initial_state(capsys, db, extra_problems):
    with pytest.raises(InputError, match="initial state of problem 'test-not-finite' is not finite"):
        NotFinite()
    code, _, err = run_cli(capsys, "run", "-p", "test-not-finite", "-i", "rk4", "--db", str(db))
    assert code == 2 and "not finite at components [0]" in err


def test_run_formats(capsys):
    for fmt, check in [("json", lambda s: json.loads(s)[0]["integrator"] == "verlet"),
                       ("csv", lambda s: s.splitlines()[0].startswith("problem,integrator,status")),
                       ("table", lambda s: "harmonic: accuracy against cost" in s)]:
        code, out, _ = run_cli(capsys, "run", "-p", "harmonic", "-i", "verlet", "--t-final", "5",
                               "--format", fmt, "--no-store")
        assert code == 0 and check(out), out


def test_sweeps_expand_to_one_row_per_point(capsys):
    code, out, _ = run_cli(capsys, "run", "-p", "harmonic", "-i", "verlet,rk4", "--dt", "0.1,0.05",
                           "--t-final", "5", "--format", "json", "--no-store")
    rows = json.loads(out)
    assert code == 0
    assert sorted((r["integrator"], r["dt"]) for r in rows) == [
        ("rk4", 0.05), ("rk4", 0.1), ("verlet", 0.05), ("verlet", 0.1)]
    assert all(r["steps"] == round(5 / r["dt"]) for r in rows)


def test_problem_parameter_and_final_time_sweep(capsys):
    """--set e=V1,V2,V3 and --t-final T1,T2: one row per point; a more eccentric orbit at the
    same step loses more energy, and the drift of the longer run is at least the shorter's."""
    code, out, _ = run_cli(capsys, "run", "-p", "kepler", "-i", "verlet", "--dt", "0.01", "--set", "e=0.5,0.9,0.99",
                           "--t-final", "10,100", "--format", "json", "--no-store", "--repeats", "1")
    rows = json.loads(out)
    assert code == 0 and len(rows) == 6
    assert [(json.loads(r["settings"])["e"], r["t_final"]) for r in rows] == [
        (e, t) for e in (0.5, 0.9, 0.99) for t in (10.0, 100.0)]
    drift = {(json.loads(r["settings"])["e"], r["t_final"]): r["H.max"] for r in rows}
    assert drift[0.5, 10.0] < drift[0.9, 10.0] < drift[0.99, 10.0]
    assert all(drift[e, 100.0] >= drift[e, 10.0] for e in (0.5, 0.9, 0.99))


def test_list_shows_capabilities_and_requirements(capsys):
    code, out, _ = run_cli(capsys, "list", "--format", "json")
    data = json.loads(out)
    problems = {p["name"]: p for p in data["problems"]}
    schemes = {s["name"]: s for s in data["integrators"]}
    assert code == 0
    assert "separable" in problems["toda"]["capabilities"]
    assert schemes["verlet"]["requires"] == ["separable"]
    assert schemes["rk4sym"]["symplectic"] and schemes["rk4sym"]["order"] == 4
    assert schemes["rebound-ias15"]["requires"] == [] and "n-body" in schemes["rebound-ias15"]["needs"]
    # the table: what each scheme needs said (never "needs -" for one that needs a kind of
    # problem), the intervals not measured counted in one line unless --full
    code, out, _ = run_cli(capsys, "list")
    assert code == 0 and "needs an n-body problem" in out
    assert out.count("not measured") == 1 and "`longtime list --full` names each" in out
    code, full, _ = run_cli(capsys, "list", "--full")
    assert code == 0 and full.count("not measured") > 1


def test_integer_parameters_reject_fractions(capsys):
    code, _, err = run_cli(capsys, "run", "-p", "toda", "-i", "rk4", "--set", "d=3.5", "--no-store")
    assert code == 2 and "d=" in err and "int" in err
    code, _, _ = run_cli(capsys, "run", "-p", "toda", "-i", "rk4", "--set", "d=4.0", "--t-final", "1",
                         "--no-store")
    assert code == 0


def test_report_tables_show_no_nan(capsys, tmp_path):
    db = str(tmp_path / "r.sqlite")
    assert main(["run", "-p", "harmonic", "-i", "rk4,verlet", "--t-final", "2", "--db", db]) == 0
    capsys.readouterr()
    assert main(["report", "--db", db, "--full"]) == 0  # the summary, then the full tables
    out = capsys.readouterr().out
    assert "harmonic: accuracy against cost (2 rows)" in out and "NaN" not in out
