"""Fault injection: crashing, hanging and NaN-returning plugins, foreign and
corrupt stores, bad input, Ctrl-C and SIGKILL. Nothing finished may be lost, no traceback,
no hang, nothing silently wrong. Plugins are pip-installed as tests/_plugins.py describes."""
import json
import os
import signal
import socket
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest
from _permissions import unprivileged
from _plugins import HEUN_SOURCE, install_plugin, longtime

from longtime.commands.cli import main
from longtime.execution.store import Store

FAULTS = '''
import ctypes
import os
import signal
import sys
import time

import numba
import numpy as np

from longtime import Problem
from longtime.integrators.explicit_rk import ExplicitRungeKutta
from longtime.problems.harmonic import Harmonic


''' + HEUN_SOURCE + '''

class Segfault(_Heun):
    summary = "segfaults inside the cell"

    def _integrate(self, *args, **kwargs):
        ctypes.string_at(0)


class Abort(_Heun):
    summary = "calls os.abort()"

    def _integrate(self, *args, **kwargs):
        os.abort()


class Exit(_Heun):
    summary = "calls sys.exit(3)"

    def _integrate(self, *args, **kwargs):
        sys.exit(3)


class Stuck(_Heun):
    summary = "ignores SIGINT and sleeps, as compiled code does"

    def _integrate(self, *args, **kwargs):
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        with open(os.environ["STUCK_FILE"], "a") as f:
            f.write(f"{os.getpid()}\\n")
        time.sleep(600)


class NanInvariant(Harmonic):
    name = "plug-nan-invariant"
    summary = "harmonic oscillator whose invariant is NaN from the middle on"

    def invariants(self, t, U):
        out = dict(super().invariants(t, U))
        name = next(iter(out))
        values = np.array(out[name], dtype=float)
        values[len(values) // 2:] = np.nan
        out[name] = values
        return out


@numba.njit(cache=True)
def _nan_rhs(t, u, params, out):
    out[0] = u[1]
    out[1] = -u[0] if t < 0.5 else np.nan


class NanRhs(Harmonic):
    name = "plug-nan-rhs"
    summary = "harmonic oscillator whose rhs is NaN from t = 0.5"
    rhs = staticmethod(_nan_rhs)


class NanExact(Harmonic):
    name = "plug-nan-exact"
    summary = "harmonic oscillator whose exact solution is NaN from t = 1"
    heyoka_system = None  # nothing to check the exact solution against: the row must say it

    def exact(self, t):
        out = np.array(super().exact(t), dtype=float)
        out[np.asarray(t, dtype=float) - self.t0 >= 1.0] = np.nan
        return out


class Rk4Again(_Heun):
    summary = "a plugin that claims a built-in's name"
'''

ENTRY_POINTS = {
    "problems": {"plug-nan-invariant": "longtime_faults:NanInvariant", "plug-nan-rhs": "longtime_faults:NanRhs",
                 "plug-nan-exact": "longtime_faults:NanExact"},
    "integrators": {"plug-segv": "longtime_faults:Segfault", "plug-abort": "longtime_faults:Abort",
                    "plug-exit": "longtime_faults:Exit", "plug-stuck": "longtime_faults:Stuck",
                    "rk4": "longtime_faults:Rk4Again"},
}


@pytest.fixture(scope="module")
def fault_env(tmp_path_factory):
    env, _ = install_plugin(tmp_path_factory.mktemp("faults"), "longtime-faults", ENTRY_POINTS,
                            {"longtime_faults.py": FAULTS})
    return env


def stored(db):
    with sqlite3.connect(db) as con:
        return [json.loads(r[0]) for r in con.execute("SELECT row FROM rows")]


# --- lost or wrong stored results -----------------------------------------------------------

@pytest.mark.slow
def test_crashing_worker_fails_only_its_cell_and_the_others_run(fault_env, tmp_path):
    """A segfault and an os.abort() in the process pool: before, the broken pool failed every
    cell still pending (21 of 24) and --resume found nothing left."""
    db = tmp_path / "pool.sqlite"
    res = longtime(fault_env, "matrix", "-p", "harmonic", "-i", "plug-segv,plug-abort,verlet,euler",
                   "--dt", "0.1", "--t-final", "5", "--jobs", "2", "--executor", "process",
                   "--db", str(db), "--no-progress", "--no-report")
    assert res.returncode == 0, res.stderr
    rows = stored(db)
    assert len(rows) == 4
    status = {(r["integrator"], r["dt"]): r for r in rows}
    for dt in (0.1,):
        assert status[("verlet", dt)]["status"] == "ok", status[("verlet", dt)]["message"]
        assert status[("euler", dt)]["status"] == "ok"
        assert status[("plug-segv", dt)]["status"] == "failed"
        assert "SIGSEGV" in status[("plug-segv", dt)]["message"]
        assert "SIGABRT" in status[("plug-abort", dt)]["message"]
    assert "BrokenProcessPool" not in json.dumps(rows)
    assert Store(db).runs()[-1]["status"] == "done"


@pytest.mark.slow
def test_serial_run_survives_sys_exit(fault_env, tmp_path):
    """A plugin's sys.exit(3) ended the whole `run` (rc 3) with no row."""
    db = tmp_path / "exit.sqlite"
    res = longtime(fault_env, "run", "-p", "harmonic", "-i", "plug-exit,verlet", "--dt", "0.1",
                   "--t-final", "2", "--db", str(db), "--format", "json")
    assert res.returncode == 1, res.stderr  # a cell failed
    rows = {r["integrator"]: r for r in json.loads(res.stdout)}
    assert rows["plug-exit"]["status"] == "failed" and "SystemExit: 3" in rows["plug-exit"]["message"]
    assert rows["verlet"]["status"] == "ok"
    assert len(stored(db)) == 2 and Store(db).runs()[-1]["status"] == "done"


@pytest.mark.slow
def test_repeated_names_and_values_are_one_cell(tmp_path, capsys):
    db = tmp_path / "dup.sqlite"
    assert main(["run", "-p", "harmonic,harmonic", "-i", "verlet,verlet", "--dt", "0.1,0.1",
                 "--t-final", "1", "--db", str(db), "--format", "json"]) == 0
    assert len(json.loads(capsys.readouterr().out)) == 1 and len(stored(db)) == 1


def _foreign(path):
    with sqlite3.connect(path) as con:
        con.execute("CREATE TABLE rows (x TEXT)")
        con.execute("INSERT INTO rows VALUES ('theirs')")
    return path.read_bytes()


@pytest.mark.slow
def test_foreign_and_newer_sqlite_files_are_refused_untouched(tmp_path, capsys):
    """Another program's SQLite file, and a store of a newer schema, are refused and left as they were:
    longtime adds no table to them and does not crash."""
    foreign = tmp_path / "other.sqlite"
    before = _foreign(foreign)
    argv = ["run", "-p", "harmonic", "-i", "verlet", "--dt", "0.1", "--t-final", "1"]
    assert main([*argv, "--db", str(foreign)]) == 2
    assert "another program" in capsys.readouterr().err
    assert foreign.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["other.sqlite"]  # no journal left either

    newer = tmp_path / "newer.sqlite"
    Store(newer)
    with sqlite3.connect(newer) as con:
        con.execute("PRAGMA user_version = 99")
    assert main(["report", "--db", str(newer)]) == 2
    assert "newer" in capsys.readouterr().err


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["text", "truncated", "directory", "devnull", "under-file", "missing"])
def test_bad_store_paths_are_one_line_errors(tmp_path, capsys, kind):
    path = tmp_path / "s.sqlite"
    if kind == "text":
        path.write_text("not a database\n" * 100)
    elif kind == "truncated":
        store = Store(tmp_path / "full.sqlite")
        store.begin_run("x", [])
        path.write_bytes((tmp_path / "full.sqlite").read_bytes()[:1500])
    elif kind == "directory":
        path.mkdir()
    elif kind == "devnull":
        path = Path(os.devnull)
    elif kind == "under-file":
        (tmp_path / "file").write_text("x")
        path = tmp_path / "file" / "s.sqlite"
    listing = sorted(p.name for p in tmp_path.iterdir())
    commands = [["report", "--db", str(path)], ["matrix", "--resume", "--db", str(path), "--no-progress"]]
    if kind != "missing":  # a missing store is created by run
        commands.append(["run", "-p", "harmonic", "-i", "verlet", "--dt", "0.1", "--t-final", "1",
                         "--db", str(path)])
    for argv in commands:
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert "error: store" in err and str(path) in err and "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == listing  # nothing created
    assert not Path(os.devnull + "-journal").exists()


def _read_only_store(tmp_path, capsys) -> Path:
    """A store of one verlet row in a folder, both made read-only (the caller restores them)."""
    db = tmp_path / "ro" / "r.sqlite"
    assert main(["run", "-p", "harmonic", "-i", "verlet", "--dt", "0.1", "--t-final", "1",
                 "--db", str(db)]) == 0
    capsys.readouterr()
    os.chmod(db, 0o444)
    os.chmod(db.parent, 0o555)
    return db


@pytest.mark.slow
def test_report_on_a_read_only_store(tmp_path, capsys):
    db = _read_only_store(tmp_path, capsys)
    try:
        before = sorted(db.parent.iterdir())
        assert main(["report", "--db", str(db), "--format", "json"]) == 0
        assert json.loads(capsys.readouterr().out)[0]["integrator"] == "verlet"
        assert sorted(db.parent.iterdir()) == before
    finally:
        os.chmod(db.parent, 0o755)
        os.chmod(db, 0o644)


# --- bad input: one line, exit 2 -------------------------------------------------------------

@pytest.mark.parametrize("argv, expected", [
    (["run", "-p", ",", "-i", "rk4"], "expected comma-separated names"),
    (["matrix", "-p", ",", "--no-progress"], "expected comma-separated names"),
])
def test_empty_name_list_is_an_error(argv, expected, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2 and expected in capsys.readouterr().err


def test_every_unknown_name_is_reported_with_a_suggestion(capsys):
    assert main(["run", "-p", "tdoa,harmonic,nosuch", "-i", "rk4", "--no-store"]) == 2
    err = capsys.readouterr().err
    assert "'tdoa' (did you mean toda?)" in err and "'nosuch'" in err


def test_run_ids_are_checked(tmp_path, capsys):
    db = tmp_path / "ids.sqlite"
    assert main(["matrix", "-p", "harmonic", "-i", "verlet", "--dt", "0.1", "--t-final", "1",
                 "--db", str(db), "--no-progress", "--no-report", "--executor", "serial"]) == 0
    capsys.readouterr()
    for argv, text in [(["report", "--run", "abc"], "expected a run id"),
                       (["report", "--run", "99"], "run 99 is not in"),
                       (["matrix", "--resume", "9999", "--no-progress"], "run 9999 is not in"),
                       (["matrix", "--resume=-5", "--no-progress"], "--resume -5")]:
        assert main([*argv, "--db", str(db)]) == 2, argv
        assert text in capsys.readouterr().err
    assert len(Store(db).runs()) == 1


@pytest.mark.slow
def test_name_clash_with_a_builtin_is_reported(fault_env):
    res = longtime(fault_env, "list", "--format", "json")
    assert res.returncode == 0, res.stderr
    data = json.loads(res.stdout)
    clash = [b for b in data["broken"] if b["name"] == "rk4"]
    assert clash and "name clash" in clash[0]["error"] and "built-in keeps it" in clash[0]["error"]
    rk4 = next(i for i in data["integrators"] if i["name"] == "rk4")
    assert rk4["order"] == 4  # still the built-in, not the plugin's order-2 scheme


# --- hangs: Ctrl-C and SIGKILL ---------------------------------------------------------------

def _alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:  # a zombie is dead
        return Path(f"/proc/{pid}/stat").read_text().split()[2] != "Z"
    except OSError:
        return False


def _stuck_matrix(fault_env, tmp_path):
    stuck_file = tmp_path / "stuck.txt"
    env = {**fault_env, "STUCK_FILE": str(stuck_file), "LONGTIME_DB": str(tmp_path / "stuck.sqlite")}
    proc = subprocess.Popen([sys.executable, "-m", "longtime.commands.cli", "matrix", "-p", "harmonic",
                             "-i", "plug-stuck,verlet", "--dt", "0.1", "--t-final", "1", "--jobs", "2",
                             "--executor", "process", "--no-progress", "--no-report"],
                            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 120
    while time.time() < deadline and not (stuck_file.exists() and stuck_file.read_text().strip()):
        time.sleep(0.2)
    assert stuck_file.exists(), proc.communicate(timeout=30)[1]
    return proc, int(stuck_file.read_text().split()[0])


@pytest.mark.slow
def test_ctrl_c_with_a_stuck_worker_exits_promptly(fault_env, tmp_path):
    """Ctrl-C while a pool worker is stuck in a cell ends the process promptly, not only prints
    'interrupted'."""
    proc, worker = _stuck_matrix(fault_env, tmp_path)
    os.kill(proc.pid, signal.SIGINT)
    start = time.time()
    _, err = proc.communicate(timeout=30)
    assert time.time() - start < 10
    assert proc.returncode == 130 and "interrupted" in err
    time.sleep(0.5)
    assert not _alive(worker)


@pytest.mark.slow
def test_pool_workers_die_with_a_killed_parent(fault_env, tmp_path):
    """After SIGKILL of the parent, its pool workers do not live on."""
    proc, worker = _stuck_matrix(fault_env, tmp_path)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(timeout=10)
    deadline = time.time() + 10
    while time.time() < deadline and _alive(worker):
        time.sleep(0.1)
    assert not _alive(worker)


# --- hangs: estimates and time limits --------------------------------------------------------

@pytest.mark.parametrize("argv, text", [
    (["--dt", "1e-300"], "5e+303 steps"),
    (["--t-final", "1e308"], "more than a run can count"),
    (["--dt", "1e-9", "--t-final", "10"], "1e+10 steps"),
    (["--set", "d=1000000000"], "d='1000000000' is not valid"),
    (["-p", "kdv", "--set", "d=100000000"], "d='100000000' is not valid"),
])
def test_oversized_cells_are_refused_up_front(argv, text, capsys, tmp_path):
    db = tmp_path / "big.sqlite"
    problem = ["-p", "toda"] if "-p" not in argv else []
    assert main(["run", *problem, "-i", "rk4", *argv, "--db", str(db)]) == 2
    err = capsys.readouterr().err
    assert text in err and "Traceback" not in err
    if "steps" in text:
        assert "--allow-large" in err
    assert not db.exists()  # nothing recorded


@pytest.mark.slow
def test_sample_memory_is_estimated_up_front(capsys):
    assert main(["run", "-p", "kdv", "-i", "rk4", "--set", "d=1048576", "--no-store"]) == 2
    assert "GiB" in capsys.readouterr().err


@pytest.mark.slow
def test_time_limit_gives_a_timeout_row(tmp_path, capsys):
    """Every cell has a time limit (default DEFAULT_TIME_LIMIT): a 10^8-step run stops there,
    keeping what it reached."""
    start = time.monotonic()
    assert main(["run", "-p", "harmonic", "-i", "rk4", "--dt", "1e-5", "--t-final", "1000",
                 "--time-limit", "1", "--repeats", "1", "--no-store", "--format", "json"]) == 0
    assert time.monotonic() - start < 30
    (row,) = json.loads(capsys.readouterr().out)
    assert row["status"] == "timeout" and "--time-limit" in row["message"]
    assert 0 < row["t_reached"] < 1000 and row["steps"] > 0


@pytest.mark.slow
def test_ctrl_c_stops_a_long_compiled_loop(tmp_path):
    """SIGINT stops a fixed-step integration inside its compiled loop (10^10 steps), not only at its
    end."""
    env = {**os.environ, "LONGTIME_DB": str(tmp_path / "int.sqlite")}
    # the kernel compiled first (into the disk caches): the SIGINT reaches the compiled loop,
    # not a cold compile (which Python interrupts between bytecodes anyway)
    warm = longtime(env, "run", "-p", "harmonic", "-i", "rk4", "--dt", "1e-6", "--t-final", "0.01",
                    "--repeats", "1", "--no-store")
    assert warm.returncode == 0, warm.stderr
    proc = subprocess.Popen([sys.executable, "-m", "longtime.commands.cli", "run", "-p", "harmonic", "-i", "rk4",
                             "--dt", "1e-6", "--t-final", "900", "--repeats", "1"],
                            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 120  # the run is recorded once its input is checked: main() is running
    while time.time() < deadline and not (tmp_path / "int.sqlite").exists():
        time.sleep(0.2)
    time.sleep(4)  # compilation, then inside the loop (10^9 steps: minutes)
    os.kill(proc.pid, signal.SIGINT)
    start = time.monotonic()
    _, err = proc.communicate(timeout=30)
    assert time.monotonic() - start < 5
    assert proc.returncode == 130 and "Traceback" not in err
    assert Store(tmp_path / "int.sqlite").runs()[-1]["status"] == "interrupted"


# --- silent wrong results ----------------------------------------------------------------------

@pytest.mark.slow
def test_unmeasured_metrics_are_null_and_defaults_are_stored():
    """A run that blows up in its first step (toda --dt 1) reports what it did not measure as null
    (H.max is not 0.0), and the defaults it ran with are stored."""
    import numpy as np

    from longtime.core.registry import problem_class
    from longtime.core.trajectory import Trajectory
    from longtime.execution.cells import Cell, run_cell
    from longtime.measure import metrics

    problem = problem_class("harmonic")()
    traj = Trajectory("diverged", "blew up", t=np.array([0.0, 1.0]),
                      u=np.array([problem.u0, np.full(problem.dim, np.nan)]), cpu_s=0.0, wall_s=0.0,
                      counters={"steps": 1})
    row = metrics.evaluate(problem, traj, np.array([problem.u0, problem.u0]))
    assert row["H.max"] is None and row["H.mean"] is None  # one finite sample measures nothing
    assert row["l2_error"] is None
    rk45 = run_cell(Cell("harmonic", "rk45", {}, {}, 1.0))
    assert rk45["status"] == "ok" and rk45["tol"] is not None
    assert json.loads(rk45["parameters"])["tol"] == rk45["tol"]


@pytest.mark.slow
def test_nan_invariant_of_a_plugin_is_flagged(fault_env):
    res = longtime(fault_env, "run", "-p", "plug-nan-invariant", "-i", "verlet", "--dt", "0.1",
                   "--t-final", "2", "--no-store", "--format", "json")
    assert res.returncode == 0, res.stderr
    (row,) = json.loads(res.stdout)
    assert "is not finite from t = 1" in row["message"]


@pytest.mark.slow
def test_nan_rhs_is_named_as_such(fault_env):
    """rk45 on a rhs that returns NaN names the NaN, not a nonlinear solve that did not converge."""
    res = longtime(fault_env, "run", "-p", "plug-nan-rhs", "-i", "rk45", "--t-final", "2", "--no-store",
                   "--format", "json")
    assert res.returncode == 1, res.stderr
    (row,) = json.loads(res.stdout)
    assert row["status"] == "failed" and "non-finite state" in row["message"]
    assert "nonlinear" not in row["message"]


@pytest.mark.slow
def test_bad_reference_budget_variable_is_an_input_error(fault_env):
    res = longtime({**fault_env, "LONGTIME_REFERENCE_SECONDS": "abc"}, "run", "-p", "harmonic", "-i",
                   "verlet", "--no-store")
    assert res.returncode == 2 and "LONGTIME_REFERENCE_SECONDS='abc'" in res.stderr
    assert "Traceback" not in res.stderr
    assert longtime({**fault_env, "LONGTIME_REFERENCE_SECONDS": "abc"}, "list").returncode == 0


def test_corrupt_reference_cache_is_discarded_and_rebuilt(tmp_path, monkeypatch):
    from longtime.core.registry import problem_class
    from longtime.measure import reference

    monkeypatch.setenv("LONGTIME_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(reference, "_CHECKS", {})
    problem = problem_class("kepler")()
    first = reference.reference_check(problem, 5.0)
    files = list((tmp_path / "reference").iterdir())
    assert files
    for f in files:
        f.write_bytes(b"\x00garbage")
    monkeypatch.setattr(reference, "_CHECKS", {})
    with pytest.warns(UserWarning, match="discarding the unreadable reference cache file"):
        again = reference.reference_check(problem, 5.0)
    assert again == first
    assert all(f.stat().st_size > 100 for f in files if f.exists())


@pytest.mark.slow
def test_serial_run_killed_by_a_plugin_names_the_cell_and_resumes(fault_env, tmp_path):
    """os.abort() in a serial `run` leaves a trace: the store knows the cell the run died in, the
    report says so, and --resume runs that cell in its own process (a failed row naming SIGABRT) and
    the rest as usual; the run is not left 'running' with no trace of the cell. (By default `run`
    runs its cells in a worker process, where the abort is a failed row: test_faults_limits;
    --executor serial runs them here.)"""
    db = tmp_path / "abort.sqlite"
    res = longtime(fault_env, "run", "-p", "harmonic", "-i", "verlet,plug-abort,euler", "--dt", "0.1",
                   "--t-final", "2", "--db", str(db), "--executor", "serial")
    assert res.returncode == -signal.SIGABRT or res.returncode == 134
    assert [r["integrator"] for r in stored(db)] == ["verlet"]
    rep = longtime(fault_env, "report", "--db", str(db), "--format", "csv")
    assert rep.returncode == 0 and "ended inside harmonic x plug-abort" in rep.stderr
    res = longtime(fault_env, "matrix", "--resume", "1", "--db", str(db), "--no-progress", "--no-report")
    assert res.returncode == 0, res.stderr
    rows = {r["integrator"]: r for r in stored(db)}
    assert rows["plug-abort"]["status"] == "failed" and "SIGABRT" in rows["plug-abort"]["message"]
    assert rows["euler"]["status"] == "ok" and rows["verlet"]["status"] == "ok"
    assert Store(db).runs()[-1]["status"] == "done"


@pytest.mark.slow
def test_an_order_one_error_does_not_read_as_a_plain_ok():
    from longtime.execution.cells import Cell, run_cell

    row = run_cell(Cell("harmonic", "euler", {}, {"dt": 1.0}, 50.0))
    assert row["l2_error"] > 0.5
    assert "error O(1)" in row["message"]
    good = run_cell(Cell("harmonic", "rk4", {}, {"dt": 0.01}, 1.0))
    assert good["status"] == "ok" and "O(1)" not in good["message"]


@pytest.mark.slow
def test_corrupt_numba_cache_files_are_discarded_and_rebuilt(tmp_path):
    """A truncated numba cache file is discarded and rebuilt, not a failed row ('pickle data was
    truncated') on every rerun naming no file."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba"), "LONGTIME_CACHE_DIR": str(tmp_path / "lt")}
    argv = ["run", "-p", "harmonic", "-i", "verlet", "--dt", "0.1", "--t-final", "1", "--no-store",
            "--format", "json"]
    first = longtime(env, *argv)
    assert first.returncode == 0, first.stderr
    files = [p for p in (tmp_path / "numba").rglob("*") if p.suffix in (".nbi", ".nbc")]
    assert files
    for p in files:
        p.write_bytes(b"garbage")
    again = longtime(env, *argv)
    assert again.returncode == 0, again.stderr
    assert json.loads(again.stdout)[0]["status"] == "ok"
    assert "discarding the unreadable numba cache file" in again.stderr


@pytest.mark.parametrize("command", [["reproduce", "--quick"], ["plot", "work-precision"],
                                     ["match", "-p", "kdv"]])
def test_out_that_is_a_file_is_an_input_error(command, tmp_path, capsys):
    """`reproduce --out FILE` is an input error before anything runs, not a FileExistsError after the
    run."""
    target = tmp_path / "a-file"
    target.write_text("x")
    with pytest.raises(SystemExit) as exc:
        main([*command, "--out", str(target)])
    assert exc.value.code == 2 and "is a file, not a folder" in capsys.readouterr().err
    assert target.read_text() == "x"


@pytest.mark.slow
def test_a_matrix_rejected_as_it_starts_leaves_no_run(tmp_path, capsys, monkeypatch):
    """A matrix rejected for bad input (found as the executor starts) records no resumable run."""
    from longtime.core.params import InputError
    from longtime.execution import matrix

    def rejecting(cells, options):
        raise InputError("--scheduler tcp://nowhere:1: cannot connect")
        yield  # a generator, like the executors

    monkeypatch.setitem(matrix.EXECUTORS, "serial", rejecting)
    db = tmp_path / "rejected.sqlite"
    assert main(["matrix", "-p", "harmonic", "-i", "verlet", "--dt", "0.1", "--t-final", "1",
                 "--executor", "serial", "--db", str(db), "--no-progress", "--no-report"]) == 2
    assert "cannot connect" in capsys.readouterr().err
    assert Store(db).runs() == []
    assert main(["matrix", "-p", "harmonic", "-i", "verlet", "--max-samples", "1", "--db", str(db),
                 "--no-progress"]) == 2
    assert Store(db).runs() == []


# --- faults of privileges, foreign files and bad numbers ------------------------------------

def _cli(prefix, *args, env=None):
    return subprocess.run([*prefix, sys.executable, "-m", "longtime.commands.cli", *args], env=env or os.environ,
                          capture_output=True, text=True, timeout=300)


def _permission_prefix():
    prefix = unprivileged()
    if prefix is None:
        pytest.skip("running as root without user namespaces: file permissions cannot be enforced")
    return prefix


@pytest.mark.slow
def test_report_on_a_read_only_store_as_a_user_who_cannot_write_it(tmp_path, capsys):
    """test_report_on_a_read_only_store runs as root in CI containers, where the permission
    bits do not hold and the old report (CREATE TABLE, WAL switch) passed it. Here the report
    really cannot write: it must read the rows and leave the folder and file as they were."""
    prefix = _permission_prefix()
    db = _read_only_store(tmp_path, capsys)
    try:
        before = {p.name: p.read_bytes() for p in db.parent.iterdir()}
        res = _cli(prefix, "report", "--db", str(db), "--format", "json")
        assert res.returncode == 0, res.stderr
        assert "Traceback" not in res.stderr
        assert [r["integrator"] for r in json.loads(res.stdout)] == ["verlet"]
        assert {p.name: p.read_bytes() for p in db.parent.iterdir()} == before
    finally:
        os.chmod(db.parent, 0o755)
        os.chmod(db, 0o644)


@pytest.mark.slow
def test_unreadable_store_is_a_one_line_error(tmp_path, capsys):
    prefix = _permission_prefix()
    db = tmp_path / "u.sqlite"
    assert main(["run", "-p", "harmonic", "-i", "verlet", "--dt", "0.1", "--t-final", "1",
                 "--db", str(db)]) == 0
    capsys.readouterr()
    content = db.read_bytes()
    listing = sorted(p.name for p in tmp_path.iterdir())
    os.chmod(db, 0)
    try:
        for argv in (["report"], ["matrix", "--resume", "--no-progress"],
                     ["run", "-p", "harmonic", "-i", "verlet", "--dt", "0.1", "--t-final", "1"]):
            res = _cli(prefix, *argv, "--db", str(db))
            assert res.returncode == 2, (argv, res.stderr)
            assert "error: store" in res.stderr and str(db) in res.stderr, res.stderr
            assert "Traceback" not in res.stderr and len(res.stderr.strip().splitlines()) == 1, res.stderr
    finally:
        os.chmod(db, 0o644)
    assert db.read_bytes() == content and sorted(p.name for p in tmp_path.iterdir()) == listing


@pytest.mark.slow
def test_unreachable_scheduler_is_an_input_error(tmp_path):
    """An unreachable scheduler is an input error: no OSError traceback after 30 s, no run left to
    resume."""
    pytest.importorskip("distributed")
    with socket.socket() as s:  # a local port nothing listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    db = tmp_path / "sched.sqlite"
    start = time.monotonic()
    res = _cli([], "matrix", "-p", "harmonic", "-i", "verlet", "--dt", "0.1", "--t-final", "1",
               "--scheduler", f"tcp://127.0.0.1:{port}", "--db", str(db), "--no-progress", "--no-report")
    assert time.monotonic() - start < 25
    assert res.returncode == 2, res.stderr
    assert f"--scheduler tcp://127.0.0.1:{port}: cannot connect" in res.stderr
    assert "Traceback" not in res.stderr
    assert not db.exists() or Store(db).runs() == []  # nothing to resume


@pytest.mark.slow
def test_a_growing_solution_is_not_called_diverged():
    """duffing-1's solution grows like exp(2t/3): the bound on the initial state's size called
    an accurate rk45 run diverged at t = 34.9 (its 1-norm passes 1e10 there)."""
    import numpy as np

    from longtime.core.registry import integrator_class, problem_class

    problem = problem_class("duffing-1")()
    traj = integrator_class("rk45")().integrate(problem, 40.0)
    assert traj.status == "ok", traj.message
    assert traj.t[-1] == 40.0 and np.abs(traj.u[-1]).sum() > 1e11


@pytest.mark.slow
def test_nan_exact_solution_of_a_plugin_is_named(fault_env):
    """A plugin's exact solution that is NaN is named in the row's message, not a null error on an ok
    row with no message."""
    res = longtime(fault_env, "run", "-p", "plug-nan-exact", "-i", "verlet", "--dt", "0.1",
                   "--t-final", "2", "--no-store", "--format", "json")
    assert res.returncode == 0, res.stderr
    (row,) = json.loads(res.stdout)
    assert row["l2_error"] is None
    assert "not finite at t = 1" in row["message"], row["message"]


@pytest.mark.slow
def test_report_of_a_killed_run_says_it_is_incomplete(fault_env, tmp_path):
    """The report of a SIGKILLed run says it is incomplete, not reads like a finished one."""
    db = tmp_path / "killed.sqlite"
    stuck_file = tmp_path / "stuck.txt"
    proc = subprocess.Popen([sys.executable, "-m", "longtime.commands.cli", "run", "-p", "harmonic", "-i",
                             "verlet,plug-stuck", "--dt", "0.1", "--t-final", "1", "--db", str(db)],
                            env={**fault_env, "STUCK_FILE": str(stuck_file)}, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    deadline = time.time() + 120
    while time.time() < deadline and not (stuck_file.exists() and stuck_file.read_text().strip()):
        time.sleep(0.2)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(timeout=10)
    assert [r["integrator"] for r in stored(db)] == ["verlet"]
    rep = longtime(fault_env, "report", "--db", str(db), "--format", "csv")
    assert rep.returncode == 0, rep.stderr
    assert "is incomplete" in rep.stderr and "1 of 2 cells stored" in rep.stderr, rep.stderr
