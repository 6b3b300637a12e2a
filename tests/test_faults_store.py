"""Faults around the store and the command's end: a lost Dask scheduler, foreign and empty
stores, a full disk, SIGTERM and SIGHUP, leftover temp folders, errors in one line.

Each test's docstring says the fault it guards against."""
import hashlib
import os
import resource
import signal
import socket
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest
from _plugins import longtime
from test_faults import _cli, _permission_prefix

from longtime.commands import listing
from longtime.commands.cli import main
from longtime.execution import batches
from longtime.execution.store import APPLICATION_ID, Store

QUICK = ["-p", "harmonic", "-i", "verlet", "--dt", "0.1", "--t-final", "1"]


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def one_line(err: str) -> str:
    """The error line of a command's stderr, checked to be its only line and no traceback."""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def runs(db) -> list[tuple[int, str]]:
    with sqlite3.connect(f"file:{db}?mode=ro", uri=True) as con:
        return con.execute("SELECT id, status FROM runs ORDER BY id").fetchall()


def statuses(db) -> list[str]:
    with sqlite3.connect(f"file:{db}?mode=ro", uri=True) as con:
        return [r[0] for r in con.execute("SELECT status FROM rows")]


# --- a store is recognised by its schema ------------------------------------------------------

def test_foreign_file_with_a_stores_table_names_is_refused_untouched(tmp_path, capsys):
    """A foreign file with tables named runs, rows and planned is not taken for an old store: it is
    refused untouched (not stamped, not switched to WAL, no table added), without an
    OperationalError traceback."""
    db = tmp_path / "theirs.sqlite"
    with sqlite3.connect(db) as con:
        con.execute("CREATE TABLE runs (name TEXT, at REAL)")
        con.execute("CREATE TABLE rows (x INTEGER, y INTEGER)")
        con.execute("CREATE TABLE planned (what TEXT)")
        con.execute("INSERT INTO runs VALUES ('marathon', 3.5)")
    before = sha256(db)
    for argv in (["run", *QUICK], ["matrix", "--resume", "--no-progress"], ["report"]):
        assert main([*argv, "--db", str(db)]) == 2, argv
        assert "another program" in one_line(capsys.readouterr().err)
    assert sha256(db) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["theirs.sqlite"]


@pytest.mark.parametrize("kind", ["empty", "stamped"])
def test_empty_file_and_stamped_file_without_tables_are_refused(tmp_path, capsys, kind):
    """An empty file and a stamped file without tables are refused untouched, in one line, by `report`
    (no OperationalError traceback) and by `run` (which does not take an empty file for a new
    store)."""
    db = tmp_path / "s.sqlite"
    if kind == "empty":
        db.write_bytes(b"")
    else:
        with sqlite3.connect(db) as con:
            con.execute(f"PRAGMA application_id = {APPLICATION_ID}")
            con.execute("PRAGMA user_version = 1")
    before = sha256(db)
    for argv in (["report"], ["run", *QUICK]):
        assert main([*argv, "--db", str(db)]) == 2, argv
        line = one_line(capsys.readouterr().err)
        assert line.startswith(f"longtime {argv[0]}: error: store {db}") and "refusing to touch it" in line
    assert sha256(db) == before and sorted(p.name for p in tmp_path.iterdir()) == ["s.sqlite"]


def test_a_store_that_another_process_is_creating_is_waited_for(tmp_path):
    """An empty file or a database without tables is refused, but it is also what a store
    looks like for a moment while another process creates it: that store is accepted."""
    import threading

    from longtime.execution.store import SCHEMA

    db = tmp_path / "new.sqlite"
    creator = sqlite3.connect(db, check_same_thread=False)
    creator.execute("PRAGMA journal_mode=WAL")  # as Store does: a database without tables so far

    def create_schema():
        time.sleep(0.3)
        creator.executescript("BEGIN IMMEDIATE;\n" + SCHEMA + "COMMIT;")

    thread = threading.Thread(target=create_schema)
    thread.start()
    try:
        assert Store(db).runs() == []
    finally:
        thread.join()
        creator.close()


def test_empty_db_path_is_an_input_error(tmp_path, monkeypatch, capsys):
    """--db "" is an input error; nothing is written to ./longtime.sqlite."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("LONGTIME_DB", raising=False)
    assert main(["run", *QUICK, "--db", ""]) == 2
    assert "--db" in one_line(capsys.readouterr().err)
    assert list(tmp_path.iterdir()) == []


# --- resume -----------------------------------------------------------------------------------

@pytest.mark.slow
def test_resume_without_an_id_takes_the_newest_incomplete_run(tmp_path, monkeypatch, capsys):
    """--resume without an id takes the newest incomplete run, not the newest run ("0 cells left"), and
    the interrupt message names the run's id, not RUN_ID."""
    db = tmp_path / "r.sqlite"
    real = batches.run_cell
    calls = []

    def interrupted_on_second(cell, *args, **kwargs):
        calls.append(cell)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real(cell, *args, **kwargs)

    argv = ["matrix", "-p", "harmonic", "-i", "verlet,euler", "--dt", "0.1", "--t-final", "1",
            "--executor", "serial", "--db", str(db), "--no-progress", "--no-report"]
    monkeypatch.setattr(batches, "run_cell", interrupted_on_second)
    assert main(argv) == 130
    assert f"`longtime matrix --resume 1 --db {db}`" in capsys.readouterr().err
    monkeypatch.setattr(batches, "run_cell", real)
    assert main(argv) == 0  # run 2, complete
    assert main(["matrix", "--resume", "--executor", "serial", "--db", str(db), "--no-progress",
                 "--no-report"]) == 0
    assert "resuming run 1: 1 cells left" in capsys.readouterr().err
    assert runs(db) == [(1, "done"), (2, "done")]
    assert main(["matrix", "--resume", "--db", str(db), "--no-progress"]) == 2
    assert "no incomplete run" in one_line(capsys.readouterr().err)


# --- a lost Dask scheduler ----------------------------------------------------------------------

def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _wait_for(predicate, seconds: float, what: str) -> None:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if predicate():
            return
        time.sleep(0.1)
    pytest.fail(f"timed out waiting for {what}")


def _stored_rows(db) -> int:
    if not db.exists():
        return 0
    try:
        with sqlite3.connect(f"file:{db}?mode=ro", uri=True) as con:
            return con.execute("SELECT COUNT(*) FROM rows").fetchone()[0]
    except sqlite3.Error:
        return 0


@pytest.mark.slow
def test_lost_dask_scheduler_is_an_interruption_not_failed_rows(tmp_path, capsys):
    """Killing the scheduler interrupts the run: its unfinished cells are not stored as failed
    ("FutureCancelledError"), the run is not marked done nor the exit 0, and --resume finds the
    cells left."""
    pytest.importorskip("distributed")
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    logs = tmp_path / "logs"
    logs.mkdir()
    with open(logs / "scheduler.txt", "w") as scheduler_log, open(logs / "worker.txt", "w") as worker_log:
        scheduler = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                                      "--port", str(port), "--no-dashboard"],
                                     stdout=subprocess.DEVNULL, stderr=scheduler_log)
        worker = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", address, "--nworkers", "1",
                                   "--nthreads", "1", "--no-nanny", "--no-dashboard", "--death-timeout", "10"],
                                  stdout=subprocess.DEVNULL, stderr=worker_log)
    db = tmp_path / "dask.sqlite"
    try:
        _wait_for(lambda: "Registered to" in (logs / "worker.txt").read_text(), 60, "the Dask worker")
        # 8 cells in 4 tasks of 2 on the one worker; each cell is 10^7 steps or more, timed at
        # least 3 times (a timing stops early once settled, so the length is in the steps)
        proc = subprocess.Popen([sys.executable, "-m", "longtime.commands.cli", "matrix", "-p", "harmonic",
                                 "-i", "verlet", "--dt", "0.01,0.0101,0.0102,0.0103,0.0104,0.0105,0.0106,0.0107",
                                 "--t-final", "100000", "--repeats", "3", "--scheduler", address, "--db", str(db),
                                 "--no-progress", "--no-report"],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        _wait_for(lambda: _stored_rows(db) > 0 or proc.poll() is not None, 120, "the first row")
        scheduler.kill()
        scheduler.wait()
        _, err = proc.communicate(timeout=60)
    finally:
        for p in (scheduler, worker):
            p.kill()
            p.wait()
    kept = _stored_rows(db)
    assert proc.returncode == 1, err
    assert 0 < kept < 8, "the matrix finished before the scheduler was killed: make its cells longer"
    assert set(statuses(db)) == {"ok"}  # no failed row
    assert runs(db) == [(1, "interrupted")]
    last = err.strip().splitlines()[-1]
    assert "Traceback" not in err and "was lost" in last and f"--resume 1 --db {db}" in last, err
    assert main(["matrix", "--resume", "--executor", "serial", "--repeats", "1", "--min-time", "0",
                 "--db", str(db), "--no-progress", "--no-report"]) == 0
    assert f"resuming run 1: {8 - kept} cells left" in capsys.readouterr().err
    assert statuses(db) == ["ok"] * 8 and runs(db) == [(1, "done")]


@pytest.mark.slow
def test_a_scheduler_that_is_not_an_address_is_one_line_and_leaves_no_run(tmp_path):
    """A scheduler that is not an address is one line, not a ValueError traceback, and leaves no empty
    run in the store to resume."""
    pytest.importorskip("distributed")
    db = tmp_path / "s.sqlite"
    res = _cli([], "matrix", *QUICK, "--scheduler", "not an address", "--db", str(db), "--no-progress")
    assert res.returncode == 2
    assert "--scheduler 'not an address': not a Dask scheduler address" in one_line(res.stderr)
    assert not db.exists()


# --- a full disk ------------------------------------------------------------------------------

def _file_size_limit(limit: int):
    def set_limit():  # a write past the limit fails with EFBIG instead of killing the process
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    return set_limit


@pytest.mark.slow
def test_a_full_disk_is_one_line_and_resume_completes(tmp_path, capsys):
    """A full disk is one line, not a double traceback (the row, then marking the run), the run is not
    left 'running', and --resume completes it. RLIMIT_FSIZE stands for the full disk: a write past
    it fails."""
    cells = ["run", "-p", "harmonic", "-i", "verlet", "--dt", ",".join(f"{0.1 + i / 1000:g}" for i in range(20)),
             "--t-final", "1", "--repeats", "1", "--min-time", "0", "--format", "csv"]
    assert main([*cells, "--no-store"]) == 0  # compiled and cached before the limit
    capsys.readouterr()

    def limited(db, limit):
        return subprocess.run([sys.executable, "-m", "longtime.commands.cli", *cells, "--db", str(db)],
                              capture_output=True, text=True, timeout=300, preexec_fn=_file_size_limit(limit))

    start = tmp_path / "start.sqlite"  # full at the start: no store can be made
    res = limited(start, 16_000)
    assert res.returncode == 2 and "cannot write it" in one_line(res.stderr)
    assert not start.exists() and list(tmp_path.iterdir()) == []

    middle = tmp_path / "middle.sqlite"  # full after a few rows
    res = limited(middle, 100_000)
    assert res.returncode == 1
    line = one_line(res.stderr)
    assert "cannot write" in line and f"--resume 1 --db {middle}" in line
    kept = statuses(middle)
    assert 0 < len(kept) < 20 and set(kept) == {"ok"}
    assert runs(middle) == [(1, "interrupted")]
    assert main(["matrix", "--resume", "--executor", "serial", "--db", str(middle), "--no-progress",
                 "--no-report"]) == 0
    assert statuses(middle) == ["ok"] * 20 and runs(middle) == [(1, "done")]


# --- report's outputs and run ids -----------------------------------------------------------

@pytest.fixture
def one_run(tmp_path, capsys):
    db = tmp_path / "one.sqlite"
    assert main(["run", *QUICK, "--db", str(db)]) == 0
    capsys.readouterr()
    return db


def _error_line(argv, capsys) -> str:
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    return one_line(capsys.readouterr().err)


@pytest.mark.slow
def test_report_outputs_that_cannot_be_written_are_one_line(one_run, tmp_path, capsys):
    """Report outputs that cannot be written are one line each, not a traceback (NotADirectoryError,
    FileExistsError) with exit 1."""
    (tmp_path / "a-file").write_text("x")
    db = ["--db", str(one_run)]
    assert "a-file is a file, not a folder" in _error_line(
        ["report", *db, "--out", str(tmp_path / "a-file" / "r.csv"), "--format", "csv"], capsys)
    assert "a-file is a file, not a folder" in _error_line(["report", *db, "--html", str(tmp_path / "a-file")], capsys)
    assert "a folder, not a file name" in _error_line(["report", *db, "--out", str(tmp_path)], capsys)
    assert (tmp_path / "a-file").read_text() == "x"


@pytest.mark.slow
def test_report_out_into_a_folder_that_cannot_be_written(one_run, tmp_path):
    prefix = _permission_prefix()
    locked = tmp_path / "locked"
    locked.mkdir()
    os.chmod(locked, 0o555)
    try:
        res = _cli(prefix, "report", "--db", str(one_run), "--format", "csv", "--out", str(locked / "r.csv"))
    finally:
        os.chmod(locked, 0o755)
    assert res.returncode == 2 and "cannot be written" in one_line(res.stderr)
    assert list(locked.iterdir()) == []


@pytest.mark.slow
@pytest.mark.parametrize("run", ["¹", "٣", "1.0", "-1"])
def test_a_run_id_is_an_ascii_number(one_run, capsys, run):
    """A run id is an ASCII number: `--run ¹` passes isdigit() and is refused in one line, not a
    traceback from int()."""
    assert main(["report", "--db", str(one_run), "--run", run]) == 2
    assert "expected a run id" in one_line(capsys.readouterr().err)


# --- errors are one line ----------------------------------------------------------------------

def test_an_unexpected_error_is_one_line_and_debug_shows_the_traceback(monkeypatch, capsys):
    """An unexpected error (not bad input) ends in one line naming --debug, which shows the traceback."""

    def broken(args):
        raise RuntimeError("something broke\nsecond line")

    monkeypatch.setattr(listing, "cmd_list", broken)
    assert main(["list"]) == 1
    line = one_line(capsys.readouterr().err)
    assert line.startswith("longtime list: error: RuntimeError: something broke") and "--debug" in line
    assert main(["--debug", "list"]) == 1
    err = capsys.readouterr().err
    assert "Traceback" in err and err.strip().splitlines()[-1].startswith("longtime list: error: RuntimeError")


@pytest.mark.slow
def test_a_closed_stdout_is_quiet():
    """`longtime list | head` (stdout closed by its reader) ends quietly, without a BrokenPipeError
    traceback."""
    proc = subprocess.Popen([sys.executable, "-m", "longtime.commands.cli", "list"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    proc.stdout.close()  # the reader is gone before the first line
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 141 and err == ""


# --- SIGTERM, SIGHUP and temp folders -----------------------------------------------------------

def _pool_folders(tmp: Path) -> list[Path]:
    """The folders of the process executor's workers (one each, resident.Resident)."""
    return sorted(tmp.glob("longtime-cell-*"))


def _pool_matrix(tmp_path, *extra):
    """A matrix on the process pool whose two cells run for minutes, its temp folder in
    tmp_path/tmp; returns once both cells are running."""
    tmp = tmp_path / "tmp"
    tmp.mkdir(exist_ok=True)
    db = tmp_path / "pool.sqlite"

    def default_hup():  # a test runner started under nohup ignores SIGHUP: the child must not
        signal.signal(signal.SIGHUP, signal.SIG_DFL)

    proc = subprocess.Popen([sys.executable, "-m", "longtime.commands.cli", "matrix", "-p", "harmonic",
                             "-i", "rk4,verlet", "--dt", "1e-6", "--t-final", "900", "--repeats", "1", "--jobs", "2",
                             "--executor", "process", "--db", str(db), "--no-progress", "--no-report", *extra],
                            env={**os.environ, "TMPDIR": str(tmp)}, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, preexec_fn=default_hup)
    _wait_for(lambda: sum(len(list(f.glob("running-*"))) for f in _pool_folders(tmp)) == 2
              or proc.poll() is not None, 120, "two running cells")
    assert proc.poll() is None, proc.communicate()[1]
    return proc, db, tmp


@pytest.mark.slow
@pytest.mark.parametrize("sig, code", [(signal.SIGTERM, 143), (signal.SIGHUP, 129)])
def test_sigterm_and_sighup_are_handled_like_ctrl_c(tmp_path, sig, code):
    """SIGTERM and SIGHUP are handled like Ctrl-C: the run is marked interrupted (not left 'running')
    and its workers' folders, with their files, do not stay in the temp folder."""
    proc, db, tmp = _pool_matrix(tmp_path)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == code
    last = err.strip().splitlines()[-1]  # after "run 1: 2 cells into ..."
    assert "Traceback" not in err and f"interrupted by {signal.Signals(sig).name}" in last
    assert f"--resume 1 --db {db}" in last
    assert runs(db) == [(1, "interrupted")]
    assert _pool_folders(tmp) == []


@pytest.mark.slow
def test_a_later_run_removes_the_folders_of_killed_processes(tmp_path):
    """A later run removes the workers' folders a killed (kill -9) matrix left in the temp folder;
    a live process's folder stays."""
    proc, _, tmp = _pool_matrix(tmp_path)
    proc.kill()
    proc.wait()
    left = _pool_folders(tmp)
    assert len(left) == 2 and all(f"-{proc.pid}-" in f.name for f in left)
    live = tmp / f"longtime-cell-{os.getpid()}-mine"  # a live process's folder stays
    live.mkdir()
    res = longtime({**os.environ, "TMPDIR": str(tmp)}, "run", *QUICK, "--cell-timeout", "120", "--no-store")
    assert res.returncode == 0, res.stderr
    assert _pool_folders(tmp) == [live]
