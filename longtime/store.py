"""The results store: an embedded SQLite database (stdlib sqlite3).

A run records its plan (every cell) when it starts and appends each row in its own
transaction as the cell finishes, so an interrupted matrix keeps every finished cell and
``--resume`` runs only the rest. Metadata: time, command, git commit, versions, machine.
"""
from __future__ import annotations

import json
import os
import platform
import sqlite3
import subprocess
import sys
from contextlib import closing
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Iterable

from .cells import Cell

DEFAULT_PATH = "longtime.sqlite"

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
"""


def default_path() -> str:
    return os.environ.get("LONGTIME_DB", DEFAULT_PATH)


def _now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def environment() -> dict[str, Any]:
    from importlib.metadata import PackageNotFoundError, version

    versions = {"python": sys.version.split()[0]}
    for pkg in ("longtime", "numpy", "scipy", "numba", "heyoka", "pandas"):
        try:
            versions[pkg] = version(pkg)
        except PackageNotFoundError:
            versions[pkg] = None
    machine = {"platform": platform.platform(), "machine": platform.machine(),
               "processor": platform.processor(), "cpus": os.cpu_count(), "node": platform.node()}
    try:
        commit = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True,
                                timeout=5, cwd=Path(__file__).parent).stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        commit = None
    return {"versions": versions, "machine": machine, "git_commit": commit}


class Store:
    def __init__(self, path: str | os.PathLike | None = None) -> None:
        self.path = Path(path or default_path())
        if self.path.parent and not self.path.parent.exists():
            self.path.parent.mkdir(parents=True, exist_ok=True)
        with closing(self._connect()) as con, con:
            con.executescript(SCHEMA)

    def _connect(self) -> sqlite3.Connection:
        con = sqlite3.connect(self.path, timeout=30)
        con.execute("PRAGMA journal_mode=WAL")
        return con

    def begin_run(self, command: str, cells: Iterable[Cell]) -> int:
        env = environment()
        with closing(self._connect()) as con, con:
            cur = con.execute(
                "INSERT INTO runs (started, status, command, git_commit, versions, machine) "
                "VALUES (?, 'running', ?, ?, ?, ?)",
                (_now(), command, env["git_commit"], json.dumps(env["versions"]), json.dumps(env["machine"])))
            run_id = int(cur.lastrowid)
            con.executemany("INSERT OR IGNORE INTO planned (run_id, cell_key, cell) VALUES (?, ?, ?)",
                            [(run_id, c.key, json.dumps(c.to_dict())) for c in cells])
        return run_id

    def add_row(self, run_id: int, cell: Cell, row: dict[str, Any]) -> None:
        with closing(self._connect()) as con, con:
            con.execute(
                "INSERT OR REPLACE INTO rows (run_id, cell_key, problem, integrator, status, row, created) "
                "VALUES (?, ?, ?, ?, ?, ?, ?)",
                (run_id, cell.key, row["problem"], row["integrator"], row["status"],
                 json.dumps(row), _now()))

    def finish_run(self, run_id: int, status: str) -> None:
        with closing(self._connect()) as con, con:
            con.execute("UPDATE runs SET finished = ?, status = ? WHERE id = ?", (_now(), status, run_id))

    def pending(self, run_id: int) -> list[Cell]:
        with closing(self._connect()) as con:
            rows = con.execute(
                "SELECT cell FROM planned WHERE run_id = ? AND cell_key NOT IN "
                "(SELECT cell_key FROM rows WHERE run_id = ?) ORDER BY rowid", (run_id, run_id)).fetchall()
        return [Cell.from_dict(json.loads(r[0])) for r in rows]

    def runs(self) -> list[dict[str, Any]]:
        with closing(self._connect()) as con:
            con.row_factory = sqlite3.Row
            out = []
            for r in con.execute(
                    "SELECT r.*, (SELECT COUNT(*) FROM planned p WHERE p.run_id = r.id) AS planned, "
                    "(SELECT COUNT(*) FROM rows w WHERE w.run_id = r.id) AS done FROM runs r ORDER BY id"):
                out.append(dict(r))
        return out

    def latest_run(self, command_prefix: str | None = None) -> int | None:
        runs = [r for r in self.runs() if not command_prefix or (r["command"] or "").startswith(command_prefix)]
        return runs[-1]["id"] if runs else None

    def rows(self, run_id: int | None = None) -> list[dict[str, Any]]:
        query, args = "SELECT run_id, row FROM rows", ()
        if run_id is not None:
            query, args = query + " WHERE run_id = ?", (run_id,)
        with closing(self._connect()) as con:
            fetched = con.execute(query + " ORDER BY id", args).fetchall()
        return [{"run_id": rid, **json.loads(text)} for rid, text in fetched]
