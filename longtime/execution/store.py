"""The results store: an embedded SQLite database (stdlib sqlite3).

A run records its plan (every cell) when it starts and appends each row in its own
transaction as the cell finishes, so an interrupted matrix keeps every finished cell and
``--resume`` runs only the rest. Metadata: time, command, git commit, versions, machine.
"""
from __future__ import annotations

import functools
import json
import os
import platform
import sqlite3
import subprocess
import sys
import threading
import time
from contextlib import closing, contextmanager
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Iterable, Iterator
from urllib.parse import quote

from longtime.core.params import InputError
from longtime.core.roles import ROW_PARAMETERS
from longtime.execution.cells import Cell

DEFAULT_PATH = "longtime.sqlite"
# A longtime store says so in its SQLite header: application_id (ASCII "LTim") and
# user_version (the schema version), and has the tables and columns of SCHEMA. A file
# without the stamp is refused untouched unless it is a store of the first layout (no version)
# existed (the same three tables, with the same columns, and nothing else).
APPLICATION_ID = 0x4C54696D
# 2: the calibrations table; 3: the checks table; 4: the ensembles table (a store of an older
# version gains them when opened for writing)
SCHEMA_VERSION = 4
ADDED_IN = {"calibrations": 2, "checks": 3, "ensembles": 4}  # the schema version that added a table (1: every other)
_TABLES = {"runs", "planned", "rows"}  # a store of the first layout, without a schema version or 'started'

SCHEMA = """
CREATE TABLE IF NOT EXISTS runs (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    started TEXT NOT NULL, finished TEXT, status TEXT NOT NULL,
    command TEXT, git_commit TEXT, versions TEXT, machine TEXT
);
CREATE TABLE IF NOT EXISTS planned (
    run_id INTEGER NOT NULL REFERENCES runs(id), cell_key TEXT NOT NULL, cell TEXT NOT NULL,
    PRIMARY KEY (run_id, cell_key)
);
CREATE TABLE IF NOT EXISTS rows (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    run_id INTEGER NOT NULL REFERENCES runs(id), cell_key TEXT NOT NULL,
    problem TEXT NOT NULL, integrator TEXT NOT NULL, status TEXT NOT NULL,
    row TEXT NOT NULL, created TEXT NOT NULL,
    UNIQUE (run_id, cell_key)
);
CREATE TABLE IF NOT EXISTS started (
    run_id INTEGER NOT NULL REFERENCES runs(id), cell_key TEXT NOT NULL, pid INTEGER, host TEXT,
    started TEXT NOT NULL, PRIMARY KEY (run_id, cell_key)
);
CREATE TABLE IF NOT EXISTS calibrations (
    run_id INTEGER NOT NULL REFERENCES runs(id), t REAL NOT NULL, pid INTEGER, phase TEXT,
    cpu_s REAL NOT NULL, point TEXT NOT NULL, PRIMARY KEY (run_id, pid, t)
);
CREATE TABLE IF NOT EXISTS checks (
    run_id INTEGER NOT NULL REFERENCES runs(id), cell_key TEXT NOT NULL,
    problem TEXT NOT NULL, integrator TEXT NOT NULL, row TEXT NOT NULL, created TEXT NOT NULL,
    PRIMARY KEY (run_id, cell_key)
);
CREATE TABLE IF NOT EXISTS ensembles (
    run_id INTEGER NOT NULL REFERENCES runs(id), problem TEXT NOT NULL, integrator TEXT NOT NULL,
    status TEXT NOT NULL, record TEXT NOT NULL, created TEXT NOT NULL,
    PRIMARY KEY (run_id, problem, integrator)
);
PRAGMA application_id = %d;
PRAGMA user_version = %d;
""" % (APPLICATION_ID, SCHEMA_VERSION)

# runs that this process marked interrupted, as (store path, run id): the message of an
# interrupted command names them (longtime.commands.guard)
INTERRUPTED: list[tuple[str, int]] = []


SETTLE_S = 1.0  # how long a file that may be a store in creation is looked at again until it is refused


class _Unsettled(Exception):
    """A file that is not a store yet, perhaps only for the moment (its message says why)."""


class StoreError(RuntimeError):
    """A write to the store failed during a run (a full disk, an I/O error, a lock held too
    long): the run cannot go on; every row committed before is kept. ``run_id``: the run it
    was writing (None: no run was recorded)."""

    def __init__(self, message: str, path: str, run_id: int | None = None) -> None:
        super().__init__(message)
        self.path, self.run_id = path, run_id


def _columns(con: sqlite3.Connection, tables: Iterable[str]) -> dict[str, list[str]]:
    return {t: [r[1] for r in con.execute("SELECT * FROM pragma_table_info(?)", (t,))] for t in tables}


@functools.cache
def _schema_columns() -> dict[str, list[str]]:
    """The columns of every table of SCHEMA (built in memory: SCHEMA is their one home)."""
    with closing(sqlite3.connect(":memory:")) as con:
        con.executescript(SCHEMA)
        return _columns(con, [r[0] for r in con.execute("SELECT name FROM sqlite_master WHERE type = 'table' "
                                                        "AND name NOT LIKE 'sqlite_%'")])


def _check_path(path: Path, must_exist: bool) -> bool:
    """Whether ``path`` exists as a regular file; an InputError for anything else, before
    SQLite sees it (it would create /dev/null-journal, or a traceback)."""
    if path.is_dir():
        raise InputError(f"store {path}: is a directory, not a store file")
    if path.exists():
        if not path.is_file():
            raise InputError(f"store {path}: not a regular file")
        if not os.access(path, os.R_OK):
            raise InputError(f"store {path}: not readable (permission denied)")
        return True
    for parent in path.absolute().parents:
        if parent.exists():
            if not parent.is_dir():
                raise InputError(f"store {path}: {parent} is a file, not a folder")
            break
    if must_exist:
        raise InputError(f"store {path}: no such file (nothing was created)")
    return False


def default_path() -> str:
    return os.environ.get("LONGTIME_DB") or DEFAULT_PATH  # set but empty: unset, as in a shell


def _now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def environment(cells: Iterable[Cell] = ()) -> dict[str, Any]:
    """What a run measured on: package versions, the machine, and the code: ``versions``'
    ``longtime_git`` (longtime's own commit and dirty flag) and ``code`` (the commit and dirty
    flag of each repository that holds a problem or scheme of ``cells`` other than
    longtime's: longtime.execution.provenance). ``git_commit`` is the commit of the code
    measured: $LONGTIME_GIT_COMMIT where the caller names it, else the one repository of the
    code under test, else longtime's own."""
    from importlib.metadata import PackageNotFoundError, version

    from longtime.execution import provenance

    versions: dict[str, Any] = {"python": sys.version.split()[0]}
    for pkg in ("longtime", "numpy", "scipy", "numba", "llvmlite", "heyoka", "pandas", "rebound"):
        try:
            versions[pkg] = version(pkg)
        except PackageNotFoundError:
            versions[pkg] = None
    machine = {"platform": platform.platform(), "machine": platform.machine(),
               "processor": platform.processor(), "cpus": os.cpu_count(), "node": platform.node(),
               "cpu_model": cpu_model()}
    own = provenance.longtime_state()
    code = provenance.of_cells(cells)
    versions["longtime_git"] = {"commit": own["commit"], "dirty": own["dirty"]}
    versions["code"] = code
    committed = [c["commit"] for c in code if c.get("commit")]
    commit = os.environ.get("LONGTIME_GIT_COMMIT") or (committed[0] if len(committed) == 1 else None) or own["commit"]
    return {"versions": versions, "machine": machine, "git_commit": commit}


@functools.cache
def cpu_model() -> str | None:
    """The CPU's model name (/proc/cpuinfo's ``model name``, else platform.processor()), or None."""
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                key, _, value = line.partition(":")
                if key.strip() in ("model name", "Model") and value.strip():
                    return value.strip()
    except OSError:
        pass
    return platform.processor() or None


class Store:
    """A store file. ``readonly`` opens an existing store without writing anything (no
    journal switch, no table created: ``report`` on a read-only file); ``create=False``
    refuses a missing file instead of creating an empty store (``--resume``, ``report``).
    Anything that is not a longtime store of this or an older schema (an empty file
    included) is an InputError naming the file, and the file is left as it was."""

    def __init__(self, path: str | os.PathLike | None = None, *, readonly: bool = False,
                 create: bool = True) -> None:
        if path is not None and not str(path).strip():
            raise InputError(f"store path {str(path)!r} is empty: give --db a file name")
        self.path = Path(path or default_path())
        self.readonly = readonly
        self._writer: sqlite3.Connection | None = None  # see _row_writer
        self._writer_lock = threading.Lock()
        self.skipped: set[int] = set()  # ids of the stored rows ``rows`` skipped (bad_row)
        exists = _check_path(self.path, must_exist=readonly or not create)
        if exists:
            self._check_identity()
        if readonly:
            return
        try:
            if not self.path.parent.exists():
                self.path.parent.mkdir(parents=True, exist_ok=True)
            with closing(self._connect()) as con:
                # one transaction: a failure (a full disk) leaves no half-made store
                con.executescript("BEGIN IMMEDIATE;\n" + SCHEMA + "COMMIT;")
        except (OSError, sqlite3.Error) as exc:
            if not exists:  # the file this call began: nothing of it stays
                for p in (self.path, *(Path(f"{self.path}{x}") for x in ("-wal", "-shm", "-journal"))):
                    p.unlink(missing_ok=True)
            raise InputError(f"store {self.path}: cannot write it: {exc}") from None

    def _check_identity(self) -> None:
        """Refuse, untouched, a file that is not a longtime store (or is a newer one)."""
        sidecars = [Path(f"{self.path}{x}") for x in ("-wal", "-shm", "-journal")]
        before = {p for p in sidecars if p.exists()}
        try:
            self._identify()
        except InputError:
            for p in sidecars:  # reading a WAL file may have created these: leave nothing behind
                if p not in before and p.exists():
                    p.unlink()
            raise

    def _identify(self) -> None:
        """A store is recognised by its stamp and its schema (tables and their columns), never
        by its table names alone. A file that is empty, or a database without a table, may be
        a store that another process is creating (its schema is one transaction): it is
        looked at again for up to SETTLE_S seconds before it is refused."""
        deadline = time.monotonic() + SETTLE_S
        while True:
            try:
                return self._identify_once()
            except _Unsettled as exc:
                if time.monotonic() > deadline:
                    raise InputError(str(exc)) from None
                time.sleep(0.05)

    def _identify_once(self) -> None:
        refuse = "refusing to touch it: use another --db"
        if self.path.stat().st_size == 0:
            raise _Unsettled(f"store {self.path}: an empty file, not a longtime store; {refuse}")
        try:
            with closing(self._open_ro()) as con:
                # one read transaction: the stamp, the tables and their columns from one snapshot,
                # not the stamp from before another process's schema transaction and the tables after
                con.execute("BEGIN")
                app = con.execute("PRAGMA application_id").fetchone()[0]
                version = con.execute("PRAGMA user_version").fetchone()[0]
                tables = {r[0] for r in con.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
                tables.discard("sqlite_sequence")
                columns = _columns(con, tables)
                con.execute("PRAGMA quick_check(1)").fetchone()  # a truncated file fails here
        except sqlite3.DatabaseError as exc:
            raise InputError(f"store {self.path}: not a readable SQLite database ({exc})") from None
        expected = _schema_columns()
        if app == APPLICATION_ID:
            if version > SCHEMA_VERSION:
                raise InputError(f"store {self.path}: schema version {version} is newer than this longtime "
                                 f"reads ({SCHEMA_VERSION}); upgrade longtime or use another --db")
            # a table of SCHEMA belongs to every version from the one that added it on
            wrong = sorted(t for t in expected if ADDED_IN.get(t, 1) <= version and columns.get(t) != expected[t])
            if wrong:
                raise InputError(f"store {self.path}: stamped as a longtime store, but its tables are not a "
                                 f"store's ({', '.join(wrong)} missing or different); {refuse}")
        elif app == 0 and version == 0 and not tables:
            raise _Unsettled(f"store {self.path}: an SQLite database without tables, not a longtime store; {refuse}")
        elif app != 0 or version != 0 or tables != _TABLES or any(columns[t] != expected[t] for t in tables):
            what = (f"tables {', '.join(sorted(tables))}, not a longtime store's columns" if tables == _TABLES
                    else f"tables: {', '.join(sorted(tables)) or 'none'}")
            raise InputError(f"store {self.path}: a SQLite file of another program ({what}); {refuse}")

    def _open_ro(self) -> sqlite3.Connection:
        uri = f"file:{quote(str(self.path.absolute()))}?mode=ro"
        if not Path(f"{self.path}-wal").exists():
            # nothing left in a write-ahead log: read the file as it is, creating no -shm/-wal
            # beside it (a read-only folder allows none)
            uri += "&immutable=1"
        try:
            return sqlite3.connect(uri, uri=True, timeout=30)
        except sqlite3.Error as exc:
            raise InputError(f"store {self.path}: cannot open it: {exc}") from None

    def _connect(self, check_same_thread: bool = True) -> sqlite3.Connection:
        if self.readonly:
            return self._open_ro()
        con = sqlite3.connect(self.path, timeout=30, check_same_thread=check_same_thread)
        con.execute("PRAGMA journal_mode=WAL")
        return con

    def _row_writer(self) -> sqlite3.Connection:
        """One connection kept open for the per-cell writes (rows, started marks). A connection
        per row cost about 5 ms (a main job's 668 rows: 3.4 s of the client's CPU beside the
        workers, profiled): closing the last connection checkpoints the write-ahead log, and each commit
        synced it to disk. In WAL mode, synchronous=NORMAL still keeps every committed row
        through a crash of the process (only a power loss can drop the last few)."""
        if self._writer is None:
            self._writer = self._connect(check_same_thread=False)  # the lock serialises its users
            self._writer.execute("PRAGMA synchronous=NORMAL")
        return self._writer

    def close(self) -> None:
        """Close the per-cell writer (finish_run does; reopened if needed)."""
        with self._writer_lock:
            if self._writer is not None:
                self._writer.close()
                self._writer = None

    @contextmanager
    def _writing(self, what: str, run_id: int | None = None) -> Iterator[None]:
        """A failed write (sqlite3.Error) as a StoreError naming the store, ``what`` and the run."""
        try:
            yield
        except sqlite3.Error as exc:
            raise StoreError(f"store {self.path}: cannot write {what}: {exc}", str(self.path), run_id) from exc

    def begin_run(self, command: str, cells: Iterable[Cell]) -> int:
        cells = list(cells)
        env = environment(cells)
        with self._writing("a new run"), closing(self._connect()) as con, con:
            cur = con.execute(
                "INSERT INTO runs (started, status, command, git_commit, versions, machine) "
                "VALUES (?, 'running', ?, ?, ?, ?)",
                (_now(), command, env["git_commit"], json.dumps(env["versions"]), json.dumps(env["machine"])))
            run_id = int(cur.lastrowid)
            con.executemany("INSERT OR IGNORE INTO planned (run_id, cell_key, cell) VALUES (?, ?, ?)",
                            [(run_id, c.key, json.dumps(c.to_dict())) for c in cells])
        return run_id

    def add_row(self, run_id: int, cell: Cell, row: dict[str, Any]) -> None:
        what = f"the row of {cell.problem} x {cell.integrator} (run {run_id})"
        with self._writing(what, run_id), self._writer_lock, self._row_writer() as con:  # commits the row
            con.execute(
                "INSERT OR REPLACE INTO rows (run_id, cell_key, problem, integrator, status, row, created) "
                "VALUES (?, ?, ?, ?, ?, ?, ?)",
                (run_id, cell.key, row["problem"], row["integrator"], row["status"],
                 json.dumps(row), _now()))

    def update_row(self, run_id: int, cell: Cell, row: dict[str, Any]) -> None:
        """Replace the stored row of ``cell`` in ``run_id`` (its place in the run's order kept):
        the cell's timing from other processes folded in after it was stored."""
        what = f"the row of {cell.problem} x {cell.integrator} (run {run_id})"
        with self._writing(what, run_id), self._writer_lock, self._row_writer() as con:
            con.execute("UPDATE rows SET status = ?, row = ? WHERE run_id = ? AND cell_key = ?",
                        (row["status"], json.dumps(row), run_id, cell.key))

    def mark_started(self, run_id: int, cell: Cell) -> None:
        """Record that this process starts ``cell`` (in-process executors): if the process
        dies in it (a plugin's os.abort, a segfault), the store knows which cell it was."""
        with self._writing(f"the start of a cell (run {run_id})", run_id), self._writer_lock, self._row_writer() as con:
            con.execute("INSERT OR REPLACE INTO started (run_id, cell_key, pid, host, started) VALUES (?, ?, ?, ?, ?)",
                        (run_id, cell.key, os.getpid(), platform.node(), _now()))

    def died_in(self, run_id: int) -> list[Cell]:
        """Cells of ``run_id`` that a process started and never finished: where it died."""
        with closing(self._connect()) as con:
            try:
                rows = con.execute(
                    "SELECT p.cell FROM planned p JOIN started s ON s.run_id = p.run_id AND s.cell_key = p.cell_key "
                    "WHERE p.run_id = ? AND p.cell_key NOT IN (SELECT cell_key FROM rows WHERE run_id = ?) "
                    "ORDER BY p.rowid", (run_id, run_id)).fetchall()
            except sqlite3.OperationalError:  # a store of the first layout, without 'started', opened read-only
                return []
        return [Cell.from_dict(json.loads(r[0])) for r in rows]

    def discard_run(self, run_id: int) -> None:
        """Remove a run that stored no row (rejected before any cell ran: nothing to resume)."""
        self.close()
        with closing(self._connect()) as con, con:
            if con.execute("SELECT COUNT(*) FROM rows WHERE run_id = ?", (run_id,)).fetchone()[0]:
                return
            for table in ("started", "planned", "calibrations", "checks", "ensembles"):
                con.execute(f"DELETE FROM {table} WHERE run_id = ?", (run_id,))
            con.execute("DELETE FROM runs WHERE id = ?", (run_id,))

    def add_calibrations(self, run_id: int, points: Iterable[dict[str, Any]]) -> None:
        """Store calibrations of the machine's speed (longtime.execution.calibration) taken during the
        run; one already stored is kept as it is."""
        points = list(points)
        if not points:
            return
        with self._writer_lock, self._row_writer() as con:
            con.executemany("INSERT OR IGNORE INTO calibrations (run_id, t, pid, phase, cpu_s, point) "
                            "VALUES (?, ?, ?, ?, ?, ?)",
                            [(run_id, p["t"], p.get("pid"), p.get("phase"), p["cpu_s"], json.dumps(p))
                             for p in points])

    def calibrations(self, run_id: int) -> list[dict[str, Any]]:
        """The calibrations of ``run_id`` in time order (none for a run stored before them)."""
        with closing(self._connect()) as con:
            try:
                fetched = con.execute("SELECT point FROM calibrations WHERE run_id = ? ORDER BY t",
                                      (run_id,)).fetchall()
            except sqlite3.OperationalError:  # a store of schema version 1, opened read-only
                return []
        return [json.loads(text) for (text,) in fetched]

    def add_check(self, run_id: int, cell: Cell, check: dict[str, Any]) -> None:
        """Store a checked prediction (longtime.execution.checks.check_row): the row of a
        re-run at a horizon past the stored rows, with the predicted error and CPU time beside
        the measured. Checks are kept apart from the run's rows: they are no cell of its
        matrix (a report, an order fit or a resume never sees them as one)."""
        with self._writing(f"a check of {cell.problem} x {cell.integrator} (run {run_id})", run_id), \
                self._writer_lock, self._row_writer() as con:
            con.execute("INSERT OR REPLACE INTO checks (run_id, cell_key, problem, integrator, row, created) "
                        "VALUES (?, ?, ?, ?, ?, ?)",
                        (run_id, cell.key, check["problem"], check["integrator"], json.dumps(check), _now()))

    def checks(self, run_id: int | None = None) -> list[dict[str, Any]]:
        """The checked predictions of ``run_id`` (default: every run's), in the order stored;
        none in a store older than the checks table."""
        return self._records("checks", "row", run_id)

    def add_ensemble(self, run_id: int, record: dict[str, Any]) -> None:
        """Store one scheme's ensemble distance on a chaotic problem
        (longtime.execution.ensembles): its record, whose ``status`` says whether it holds a
        distance (ok) or why not; kept apart from the rows (no cell of the matrix)."""
        if record.get("status") != "ok" and record.get("distance") is not None:
            raise ValueError(f"an ensemble record of status {record.get('status')!r} carries a distance")
        with self._writing(f"the ensemble of {record['problem']} x {record['integrator']} (run {run_id})", run_id), \
                self._writer_lock, self._row_writer() as con:
            con.execute("INSERT OR REPLACE INTO ensembles (run_id, problem, integrator, status, record, created) "
                        "VALUES (?, ?, ?, ?, ?, ?)",
                        (run_id, record["problem"], record["integrator"], record["status"], json.dumps(record),
                         _now()))

    def ensembles(self, run_id: int | None = None) -> list[dict[str, Any]]:
        """The ensemble records of ``run_id`` (default: every run's), in the order stored;
        none in a store older than the ensembles table."""
        return self._records("ensembles", "record", run_id)

    def _records(self, table: str, column: str, run_id: int | None) -> list[dict[str, Any]]:
        """The JSON records of a side table (checks, ensembles) of ``run_id`` (default: every
        run's) with their run id, in the order stored; none where a store opened read-only
        predates the table."""
        query, args = f"SELECT run_id, {column} FROM {table}", ()
        if run_id is not None:
            query, args = query + " WHERE run_id = ?", (run_id,)
        with closing(self._connect()) as con:
            try:
                fetched = con.execute(query + " ORDER BY rowid", args).fetchall()
            except sqlite3.OperationalError:  # an older schema without the table
                return []
        return [{"run_id": rid, **json.loads(text)} for rid, text in fetched]

    def set_machine(self, run_id: int, machine: dict[str, Any]) -> None:
        """Replace the machine ``run_id`` is recorded to have run on (a run measured elsewhere
        and recorded here, a test's second "machine")."""
        with self._writing(f"the machine of run {run_id}", run_id), closing(self._connect()) as con, con:
            con.execute("UPDATE runs SET machine = ? WHERE id = ?", (json.dumps(machine), run_id))

    def finish_run(self, run_id: int, status: str) -> None:
        self.close()
        with self._writing(f"the end of run {run_id} ({status})", run_id), closing(self._connect()) as con, con:
            con.execute("UPDATE runs SET finished = ?, status = ? WHERE id = ?", (_now(), status, run_id))
        if status == "interrupted":
            INTERRUPTED.append((str(self.path), run_id))

    def pending(self, run_id: int) -> list[Cell]:
        with closing(self._connect()) as con:
            rows = con.execute(
                "SELECT cell FROM planned WHERE run_id = ? AND cell_key NOT IN "
                "(SELECT cell_key FROM rows WHERE run_id = ?) ORDER BY rowid", (run_id, run_id)).fetchall()
        return [Cell.from_dict(json.loads(r[0])) for r in rows]

    def incomplete_rows(self, run_id: int, field: str) -> list[tuple[Cell, dict[str, Any]]]:
        """(cell, row) of each stored row of ``run_id`` whose ``field`` (its missing phases,
        longtime.execution.matrix.PHASES_FIELD) names one, in the run's order."""
        with closing(self._connect()) as con:
            fetched = con.execute(
                "SELECT p.cell, w.row FROM rows w JOIN planned p ON p.run_id = w.run_id AND p.cell_key = w.cell_key "
                "WHERE w.run_id = ? ORDER BY w.id", (run_id,)).fetchall()
        out = []
        for cell, text in fetched:
            try:
                row = json.loads(text)
            except ValueError:
                continue
            if isinstance(row, dict) and row.get(field):
                out.append((Cell.from_dict(json.loads(cell)), row))
        return out

    def runs(self) -> list[dict[str, Any]]:
        with closing(self._connect()) as con:
            con.row_factory = sqlite3.Row
            out = []
            for r in con.execute(
                    "SELECT r.*, (SELECT COUNT(*) FROM planned p WHERE p.run_id = r.id) AS planned, "
                    "(SELECT COUNT(*) FROM rows w WHERE w.run_id = r.id) AS done FROM runs r ORDER BY id"):
                out.append(dict(r))
        return out

    def run(self, run_id: int) -> dict[str, Any]:
        """The run ``run_id`` (with its planned and done counts); InputError if none."""
        found = [r for r in self.runs() if r["id"] == run_id]
        if not found:
            ids = [r["id"] for r in self.runs()]
            known = f"runs {ids[0]}..{ids[-1]}" if ids else "no runs"
            raise InputError(f"run {run_id} is not in {self.path} ({known})")
        return found[0]

    def latest_run(self, command_prefix: str | None = None) -> int | None:
        runs = [r for r in self.runs() if not command_prefix or (r["command"] or "").startswith(command_prefix)]
        return runs[-1]["id"] if runs else None

    def latest_incomplete_run(self, command_prefix: str | tuple[str, ...] | None = None) -> int | None:
        """The newest run (of commands starting with ``command_prefix``, or one of them) that
        did not finish: a cell not stored, or not marked done (interrupted, or its process died)."""
        runs = [r for r in self.runs() if (not command_prefix or (r["command"] or "").startswith(command_prefix))
                and (r["status"] != "done" or r["done"] < r["planned"])]
        return runs[-1]["id"] if runs else None

    def rows(self, run_id: int | None = None) -> list[dict[str, Any]]:
        """The stored rows (of ``run_id``, or all), each with its ``run_id``. A row that is not
        structurally a row (``bad_row``: not JSON, not an object, no names, a parameter that
        is not a number) is skipped with one warning line naming its id and the reason: one
        bad row never costs the store its report, comparison or history."""
        query, args = "SELECT id, run_id, row FROM rows", ()
        if run_id is not None:
            query, args = query + " WHERE run_id = ?", (run_id,)
        with closing(self._connect()) as con:
            fetched = con.execute(query + " ORDER BY id", args).fetchall()
        out = []
        for row_id, rid, text in fetched:
            try:
                row = json.loads(text)
                reason = bad_row(row)
            except (TypeError, ValueError) as exc:  # not JSON (or not text)
                row, reason = None, f"not JSON ({type(exc).__name__}: {str(exc)[:80]})"
            if reason is None:
                out.append({"run_id": rid, **row})
            elif row_id not in self.skipped:  # one warning per row and Store
                self.skipped.add(row_id)
                print(f"warning: store {self.path}: row {row_id} (run {rid}) skipped: {reason}", file=sys.stderr)
        return out


_NAMES = ("problem", "integrator", "status")
_NUMBERS = (*ROW_PARAMETERS, "t_final")


def bad_row(row: Any) -> str | None:
    """Why a stored row cannot be read as one (None: it can): it must be a JSON object whose
    problem, integrator and status are non-empty texts and whose row parameters (dt, tol,
    eps_res, order, t_final) are numbers or null."""
    if not isinstance(row, dict):
        return f"not a JSON object but {type(row).__name__ if row is not None else 'null'}"
    for key in _NAMES:
        if not isinstance(row.get(key), str) or not row[key]:
            return f"{key} is {row.get(key)!r}, not a name" if key in row else f"no {key}"
    for key in _NUMBERS:
        value = row.get(key)
        if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float))):
            return f"{key} is {value!r}, not a number"
    for key in ("settings", "parameters", "message"):
        if row.get(key) is not None and not isinstance(row[key], str):
            return f"{key} is {type(row[key]).__name__}, not a text"
    return None


# the tables that hang off a run (every one with a run_id column), in the order they are copied
_RUN_TABLES = ("planned", "started", "rows", "calibrations", "checks", "ensembles")


def merge_stores(sources: Iterable[str | os.PathLike], into: str | os.PathLike) -> list[dict[str, Any]]:
    """Copy every run of the stores ``sources`` into the store ``into`` (created if missing),
    each with its own machine, versions, calibrations and rows: runs stay apart, never pooled
    as if measured in one place. A run keeps its id where ``into`` has none of that id, else
    it gets the next free one; its machine record gains ``merged_from`` (the store and run id
    it came from, kept through later merges). A run already in ``into`` (the same start,
    command, commit, versions and machine) is not copied again. Returns one record per run
    of the sources: ``store``, ``run`` (its id there), ``id`` (its id in ``into``; None when
    it was there already) and ``status``."""
    into_path = Path(into).absolute()
    sources = [Path(s) for s in sources]
    for src in sources:
        if src.absolute() == into_path:
            raise InputError(f"merge: {src} is both a source and --into: give another --into file")
    readers = [Store(src, readonly=True) for src in sources]  # each must be a longtime store
    target = Store(into)
    done: list[dict[str, Any]] = []
    with closing(target._connect()) as out, out:
        known = out.execute("SELECT started, command, git_commit, versions, machine FROM runs")
        seen = {_run_identity(*r) for r in known}
        for reader in readers:
            with closing(reader._connect()) as con:
                con.row_factory = sqlite3.Row
                for run in con.execute("SELECT * FROM runs ORDER BY id").fetchall():
                    done.append(_merge_run(con, out, dict(run), reader.path, seen))
    return done


def _run_identity(started: str, command: str | None, commit: str | None, versions: str | None,
                  machine: str | None) -> tuple:
    """What tells a run apart from every other: its start, command, commit, versions and
    machine (without the merge's own note of where it came from)."""
    try:
        place = json.loads(machine or "null")
    except ValueError:
        place = machine
    if isinstance(place, dict):
        place = {k: v for k, v in place.items() if k != "merged_from"}
    return started, command, commit, versions, json.dumps(place, sort_keys=True)


def _merge_run(con: sqlite3.Connection, out: sqlite3.Connection, run: dict[str, Any], path: Path,
               seen: set) -> dict[str, Any]:
    """Copy the run ``run`` of the store ``con`` (at ``path``) and everything of it into ``out``."""
    record = {"store": str(path), "run": run["id"], "id": None, "status": run["status"]}
    identity = _run_identity(run["started"], run["command"], run["git_commit"], run["versions"], run["machine"])
    if identity in seen:
        return record
    seen.add(identity)
    try:
        machine = json.loads(run["machine"] or "null")
    except ValueError:
        machine = None
    if not isinstance(machine, dict):
        machine = {"recorded": run["machine"]}
    machine.setdefault("merged_from", {"store": str(path), "run": run["id"]})
    taken = out.execute("SELECT 1 FROM runs WHERE id = ?", (run["id"],)).fetchone()
    values = (run["started"], run["finished"], run["status"], run["command"], run["git_commit"], run["versions"],
              json.dumps(machine))
    if taken:
        cur = out.execute("INSERT INTO runs (started, finished, status, command, git_commit, versions, machine) "
                          "VALUES (?, ?, ?, ?, ?, ?, ?)", values)
    else:
        cur = out.execute("INSERT INTO runs (id, started, finished, status, command, git_commit, versions, machine) "
                          "VALUES (?, ?, ?, ?, ?, ?, ?, ?)", (run["id"], *values))
    new_id = int(cur.lastrowid)
    for table in _RUN_TABLES:
        try:
            fetched = con.execute(f"SELECT * FROM {table} WHERE run_id = ? ORDER BY rowid", (run["id"],)).fetchall()
        except sqlite3.OperationalError:  # an older store without the table
            continue
        for item in fetched:
            values = {k: item[k] for k in item.keys() if not (table == "rows" and k == "id")}
            values["run_id"] = new_id
            names = ", ".join(values)
            out.execute(f"INSERT OR IGNORE INTO {table} ({names}) VALUES ({', '.join('?' * len(values))})",
                        tuple(values.values()))
    record["id"] = new_id
    return record
