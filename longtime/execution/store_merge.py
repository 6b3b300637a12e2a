"""Merging stores: every run of several stores copied into one, each with its own machine."""
from __future__ import annotations

import json
import os
import sqlite3
from contextlib import closing
from pathlib import Path
from typing import Any, Iterable

from longtime.core.params import InputError
from longtime.execution.store import Store

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
