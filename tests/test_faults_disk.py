"""A full disk is an interruption, never a result. A full temp
folder stores no ``failed`` row (the run is ``interrupted``, exit 1, and ``--resume``
completes it once there is space); a full cache folder is skipped with a warning, as numba
skips a cache it cannot write; a complete run whose end mark was lost is marked done by
``--resume``. The disk is a 1 MiB tmpfs where one can be mounted (root), else ENOSPC is
simulated where the write happens."""
import errno
import json
import os
import sqlite3
import subprocess
import sys
import uuid
from pathlib import Path

import pytest

from longtime.commands.cli import main
from longtime.execution.store import Store

PAGE = 4096


def _mount_tmpfs(path: Path) -> bool:
    if os.geteuid() != 0:
        return False
    path.mkdir(parents=True, exist_ok=True)
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1M", "tmpfs", str(path)],
                          capture_output=True)
    return done.returncode == 0


@pytest.fixture
def full_disk(tmp_path):
    """A folder on a 1 MiB tmpfs filled to one free page (Python's own probe of a temp folder
    still passes; a row file does not fit); None where no tmpfs can be mounted."""
    mount = tmp_path / f"full-{uuid.uuid4().hex[:6]}"
    if not _mount_tmpfs(mount):
        yield None
        return
    try:
        with open(mount / "fill", "wb") as f:
            f.write(b"\0" * (1024 * 1024 - PAGE))
    except OSError:
        pass
    try:
        yield mount
    finally:
        subprocess.run(["umount", "-l", str(mount)], capture_output=True)


def _cli(*args, env=None):
    return subprocess.run([sys.executable, "-m", "longtime.commands.cli", *args], env=env,
                          capture_output=True, text=True, timeout=600)


def _runs(db):
    with sqlite3.connect(db) as con:
        return (con.execute("SELECT id, status FROM runs").fetchall(),
                con.execute("SELECT status, row FROM rows").fetchall())


@pytest.mark.slow
def test_full_temp_folder_interrupts_the_run_and_resume_completes_it(full_disk, tmp_path):
    if full_disk is None:
        pytest.skip("no tmpfs can be mounted here (the simulated case is the next test)")
    db = tmp_path / "s.sqlite"
    env = {**os.environ, "TMPDIR": str(full_disk)}
    argv = ["matrix", "-p", "harmonic", "-i", "rk4", "--dt", "0.1,0.05", "--t-final", "5", "--db", str(db),
            "--no-progress", "--no-html", "--no-report"]
    done = _cli(*argv, env=env)
    assert done.returncode == 1, done.stderr
    assert "no space left" in done.stderr and "--resume 1" in done.stderr, done.stderr
    assert "Traceback" not in done.stderr
    runs, rows = _runs(db)
    assert runs == [(1, "interrupted")] and rows == []  # no failed row
    (full_disk / "fill").unlink()  # space is back
    done = _cli("matrix", "--resume", "--db", str(db), "--no-progress", "--no-html", "--no-report", env=env)
    assert done.returncode == 0, done.stderr
    runs, rows = _runs(db)
    assert runs == [(1, "done")] and sorted(s for s, _ in rows) == ["ok", "ok"]


@pytest.mark.slow
def test_no_space_in_a_cell_is_not_stored_as_a_failed_row(tmp_path, monkeypatch, capsys):
    """Simulated ENOSPC inside the cell (serial executor, this process): exit 1, no row, the
    run interrupted; resumed, the cells run."""
    from longtime.execution import cells

    real = cells.metrics.evaluate

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device", str(tmp_path / "x"))

    monkeypatch.setattr(cells.metrics, "evaluate", full)
    db = tmp_path / "s.sqlite"
    argv = ["matrix", "-p", "harmonic", "-i", "rk4", "--dt", "0.1,0.05", "--t-final", "5", "--db", str(db),
            "--executor", "serial", "--no-progress", "--no-html", "--no-report"]
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert "no space left" in err and "interrupted" in err, err
    assert _runs(db) == ([(1, "interrupted")], [])
    monkeypatch.setattr(cells.metrics, "evaluate", real)
    assert main(["matrix", "--resume", "--db", str(db), "--executor", "serial", "--no-progress",
                 "--no-html", "--no-report"]) == 0
    runs, rows = _runs(db)
    assert runs == [(1, "done")] and [s for s, _ in rows] == ["ok", "ok"]


@pytest.mark.slow
def test_full_cache_folder_is_skipped_with_a_warning(full_disk, tmp_path):
    if full_disk is None:
        pytest.skip("no tmpfs can be mounted here (the simulated case is the next test)")
    env = {**os.environ, "LONGTIME_CACHE_DIR": str(full_disk / "cache"),
           "NUMBA_CACHE_DIR": str(full_disk / "numba")}
    done = _cli("run", "-p", "kepler", "-i", "rk4", "--dt", "0.01", "--t-final", "5", "--format", "json",
                "--db", str(tmp_path / "s.sqlite"), env=env)
    assert done.returncode == 0, done.stderr
    assert [r["status"] for r in json.loads(done.stdout)] == ["ok"]
    assert "cannot cache in" in done.stderr and "No space left" in done.stderr
    assert Store(tmp_path / "s.sqlite").runs()[0]["status"] == "done"


def test_cache_write_without_space_warns_and_goes_on(tmp_path, monkeypatch):
    from longtime.core import cache, files

    def full(fd, data):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(files.os, "write", full)
    with pytest.warns(UserWarning, match="cannot cache in .*No space left on device"):
        assert cache.write_atomic(tmp_path / "kernel.py", b"x") is False
    monkeypatch.undo()
    assert not list(tmp_path.iterdir())

    def denied(fd, data):
        raise OSError(errno.EIO, "Input/output error")

    monkeypatch.setattr(files.os, "write", denied)
    with pytest.raises(OSError):  # only a want of space is skipped
        cache.write_atomic(tmp_path / "kernel.py", b"x")


def test_numba_cache_without_space_warns_and_runs(tmp_path, monkeypatch):
    import numba
    from numba.core import caching

    import longtime.core.jitcache  # noqa: F401  (installs the cache guard)

    def full(self, key, data):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(caching.IndexDataCacheFile, "save", full)
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(numba.config, "CACHE_DIR", str(tmp_path))
    src = tmp_path / "mod_item2.py"
    src.write_text("import numba\n@numba.njit(cache=True)\ndef twice(x):\n    return 2 * x\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    import mod_item2

    with pytest.warns(UserWarning, match="cannot cache in"):
        assert mod_item2.twice(21) == 42


def test_resume_marks_a_complete_run_done(tmp_path, monkeypatch, capsys):
    """All rows stored, the end mark lost to a full disk (SQLite: database or disk is full):
    exit 1 naming the run; --resume sees nothing missing and marks it done, running nothing."""
    db = tmp_path / "s.sqlite"
    real = Store.finish_run

    def full(self, run_id, status):
        if status == "done":
            with self._writing(f"the end of run {run_id} ({status})", run_id):
                raise sqlite3.OperationalError("database or disk is full")
        real(self, run_id, status)

    monkeypatch.setattr(Store, "finish_run", full)
    argv = ["matrix", "-p", "harmonic", "-i", "rk4", "--dt", "0.1,0.05", "--t-final", "2", "--db", str(db),
            "--executor", "serial", "--no-progress", "--no-html", "--no-report"]
    assert main(argv) == 1
    assert "--resume 1" in capsys.readouterr().err
    monkeypatch.setattr(Store, "finish_run", real)
    runs, rows = _runs(db)
    assert runs[0][1] != "done" and len(rows) == 2
    assert main(["matrix", "--resume", "--db", str(db), "--no-progress", "--no-html", "--no-report"]) == 0
    assert "every planned cell is stored; marked done" in capsys.readouterr().err
    runs, rows_after = _runs(db)
    assert runs == [(1, "done")] and rows_after == rows
