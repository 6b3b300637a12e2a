"""The store's file: its schema (tables, stamp and version), how a file is recognised as a
store of this or an older schema (or refused untouched), and the errors of a store.
"""
from __future__ import annotations

import functools
import os
import sqlite3
import time
from contextlib import closing
from datetime import datetime, timezone
from pathlib import Path
from typing import Iterable
from urllib.parse import quote

from longtime.core.params import InputError

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
FIRST_LAYOUT = {"runs", "planned", "rows"}  # a store of the first layout, without a schema version or 'started'

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

SETTLE_S = 1.0  # how long a file that may be a store in creation is looked at again until it is refused


class Unsettled(Exception):
    """A file that is not a store yet, perhaps only for the moment (its message says why)."""


class StoreError(RuntimeError):
    """A write to the store failed during a run (a full disk, an I/O error, a lock held too
    long): the run cannot go on; every row committed before is kept. ``run_id``: the run it
    was writing (None: no run was recorded)."""

    def __init__(self, message: str, path: str, run_id: int | None = None) -> None:
        super().__init__(message)
        self.path, self.run_id = path, run_id


def columns(con: sqlite3.Connection, tables: Iterable[str]) -> dict[str, list[str]]:
    return {t: [r[1] for r in con.execute("SELECT * FROM pragma_table_info(?)", (t,))] for t in tables}


@functools.cache
def schema_columns() -> dict[str, list[str]]:
    """The columns of every table of SCHEMA (built in memory: SCHEMA is their one home)."""
    with closing(sqlite3.connect(":memory:")) as con:
        con.executescript(SCHEMA)
        return columns(con, [r[0] for r in con.execute("SELECT name FROM sqlite_master WHERE type = 'table' "
                                                        "AND name NOT LIKE 'sqlite_%'")])


def check_path(path: Path, must_exist: bool) -> bool:
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
            if not must_exist and not os.access(parent, os.W_OK | os.X_OK):  # a read-only mount too
                raise InputError(f"store {path}: cannot write it: {parent} is not writable (a read-only file "
                                 f"system or no permission); pass --db a writable path, or --no-store")
            break
    if must_exist:
        raise InputError(f"store {path}: no such file (nothing was created)")
    return False


def default_path() -> str:
    return os.environ.get("LONGTIME_DB") or DEFAULT_PATH  # set but empty: unset, as in a shell


def now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def check_identity(path: Path) -> None:
    """Refuse, untouched, a file that is not a longtime store (or is a newer one)."""
    sidecars = [Path(f"{path}{x}") for x in ("-wal", "-shm", "-journal")]
    before = {p for p in sidecars if p.exists()}
    try:
        _identify(path)
    except InputError:
        for p in sidecars:  # reading a WAL file may have created these: leave nothing behind
            if p not in before and p.exists():
                p.unlink()
        raise


def _identify(path: Path) -> None:
    """A store is recognised by its stamp and its schema (tables and their columns), never
    by its table names alone. A file that is empty, or a database without a table, may be
    a store that another process is creating (its schema is one transaction): it is
    looked at again for up to SETTLE_S seconds before it is refused."""
    deadline = time.monotonic() + SETTLE_S
    while True:
        try:
            return _identify_once(path)
        except Unsettled as exc:
            if time.monotonic() > deadline:
                raise InputError(str(exc)) from None
            time.sleep(0.05)


def _identify_once(path: Path) -> None:
    refuse = "refusing to touch it: use another --db"
    if path.stat().st_size == 0:
        raise Unsettled(f"store {path}: an empty file, not a longtime store; {refuse}")
    try:
        with closing(open_readonly(path)) as con:
            # one read transaction: the stamp, the tables and their columns from one snapshot,
            # not the stamp from before another process's schema transaction and the tables after
            con.execute("BEGIN")
            app = con.execute("PRAGMA application_id").fetchone()[0]
            version = con.execute("PRAGMA user_version").fetchone()[0]
            tables = {r[0] for r in con.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
            tables.discard("sqlite_sequence")
            found = columns(con, tables)
            con.execute("PRAGMA quick_check(1)").fetchone()  # a truncated file fails here
    except sqlite3.DatabaseError as exc:
        raise InputError(f"store {path}: not a readable SQLite database ({exc})") from None
    expected = schema_columns()
    if app == APPLICATION_ID:
        if version > SCHEMA_VERSION:
            raise InputError(f"store {path}: schema version {version} is newer than this longtime "
                             f"reads ({SCHEMA_VERSION}); upgrade longtime or use another --db")
        # a table of SCHEMA belongs to every version from the one that added it on
        wrong = sorted(t for t in expected if ADDED_IN.get(t, 1) <= version and found.get(t) != expected[t])
        if wrong:
            raise InputError(f"store {path}: stamped as a longtime store, but its tables are not a "
                             f"store's ({', '.join(wrong)} missing or different); {refuse}")
    elif app == 0 and version == 0 and not tables:
        raise Unsettled(f"store {path}: an SQLite database without tables, not a longtime store; {refuse}")
    elif app != 0 or version != 0 or tables != FIRST_LAYOUT or any(found[t] != expected[t] for t in tables):
        what = (f"tables {', '.join(sorted(tables))}, not a longtime store's columns" if tables == FIRST_LAYOUT
                else f"tables: {', '.join(sorted(tables)) or 'none'}")
        raise InputError(f"store {path}: a SQLite file of another program ({what}); {refuse}")


def open_readonly(path: Path) -> sqlite3.Connection:
    """A read-only connection to the store at ``path`` (an InputError where it cannot open)."""
    uri = f"file:{quote(str(path.absolute()))}?mode=ro"
    if not Path(f"{path}-wal").exists():
        # nothing left in a write-ahead log: read the file as it is, creating no -shm/-wal
        # beside it (a read-only folder allows none)
        uri += "&immutable=1"
    try:
        return sqlite3.connect(uri, uri=True, timeout=30)
    except sqlite3.Error as exc:
        raise InputError(f"store {path}: cannot open it: {exc}") from None
