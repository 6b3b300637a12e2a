"""The results store: an embedded SQLite database (stdlib sqlite3).

A run records its plan (every cell) when it starts and appends each row in its own
transaction as the cell finishes, so an interrupted matrix keeps every finished cell and
``--resume`` runs only the rest. Metadata: time, command, git commit, versions, machine.
Every row it adds is checked against the declared row fields (longtime.core.rowschema).
The file's schema and its recognition: longtime.execution.store_schema; the tables beside
the rows: longtime.execution.store_records; merging stores: longtime.execution.store_merge.
"""
from __future__ import annotations

import json
import os
import platform
import sqlite3
import sys
import threading
from contextlib import closing, contextmanager
from pathlib import Path
from typing import Any, Iterable, Iterator

from longtime.core import rowschema
from longtime.core.params import InputError
from longtime.core.roles import ROW_PARAMETERS
from longtime.execution.cells import Cell
from longtime.execution.run_environment import environment, machine_key
from longtime.execution.store_records import RunRecords
from longtime.execution.store_schema import (
    APPLICATION_ID,
    SCHEMA,
    SCHEMA_VERSION,
    StoreError,
    check_identity,
    check_path,
    default_path,
    now,
    open_readonly,
)

__all__ = ["APPLICATION_ID", "INTERRUPTED", "SCHEMA", "SCHEMA_VERSION", "Store", "StoreError", "bad_row",
           "default_path", "environment"]

# runs that this process marked interrupted, as (store path, run id): the message of an
# interrupted command names them (longtime.commands.guard)
INTERRUPTED: list[tuple[str, int]] = []


class Store(RunRecords):
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
        exists = check_path(self.path, must_exist=readonly or not create)
        if exists:
            check_identity(self.path)  # refused untouched where it is no store
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

    def _connect(self, check_same_thread: bool = True) -> sqlite3.Connection:
        if self.readonly:
            return open_readonly(self.path)
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
                (now(), command, env["git_commit"], json.dumps(env["versions"]), json.dumps(env["machine"])))
            run_id = int(cur.lastrowid)
            con.executemany("INSERT OR IGNORE INTO planned (run_id, cell_key, cell) VALUES (?, ?, ?)",
                            [(run_id, c.key, json.dumps(c.to_dict())) for c in cells])
        return run_id

    def add_row(self, run_id: int, cell: Cell, row: dict[str, Any]) -> None:
        """Store the row of ``cell`` in ``run_id``: a StoreError naming the field where the row
        has a field the registry does not declare or a value of the wrong type
        (longtime.core.rowschema); nothing is written then."""
        what = f"the row of {cell.problem} x {cell.integrator} (run {run_id})"
        text = self._row_text(row, what, run_id)
        with self._writing(what, run_id), self._writer_lock, self._row_writer() as con:  # commits the row
            con.execute(
                "INSERT OR REPLACE INTO rows (run_id, cell_key, problem, integrator, status, row, created) "
                "VALUES (?, ?, ?, ?, ?, ?, ?)",
                (run_id, cell.key, row["problem"], row["integrator"], row["status"], text, now()))

    def update_row(self, run_id: int, cell: Cell, row: dict[str, Any]) -> None:
        """Replace the stored row of ``cell`` in ``run_id`` (its place in the run's order kept):
        the cell's timing from other processes folded in after it was stored. Checked as
        ``add_row`` checks a row."""
        what = f"the row of {cell.problem} x {cell.integrator} (run {run_id})"
        text = self._row_text(row, what, run_id)
        with self._writing(what, run_id), self._writer_lock, self._row_writer() as con:
            con.execute("UPDATE rows SET status = ?, row = ? WHERE run_id = ? AND cell_key = ?",
                        (row["status"], text, run_id, cell.key))

    def _row_text(self, row: dict[str, Any], what: str, run_id: int) -> str:
        """The JSON text ``row`` is stored as, once it holds against the declared row fields
        (the scheme's own counters included)."""
        try:
            rowschema.check(row)
        except rowschema.RowError as exc:
            raise StoreError(f"store {self.path}: refused {what}: {exc}", str(self.path), run_id) from None
        return json.dumps(row)

    def mark_started(self, run_id: int, cell: Cell) -> None:
        """Record that this process starts ``cell`` (in-process executors): if the process
        dies in it (a plugin's os.abort, a segfault), the store knows which cell it was."""
        with self._writing(f"the start of a cell (run {run_id})", run_id), self._writer_lock, self._row_writer() as con:
            con.execute("INSERT OR REPLACE INTO started (run_id, cell_key, pid, host, started) VALUES (?, ?, ?, ?, ?)",
                        (run_id, cell.key, os.getpid(), platform.node(), now()))

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

    def set_machine(self, run_id: int, machine: dict[str, Any]) -> None:
        """Replace the machine ``run_id`` is recorded to have run on (a run measured elsewhere
        and recorded here, a test's second "machine")."""
        with self._writing(f"the machine of run {run_id}", run_id), closing(self._connect()) as con, con:
            con.execute("UPDATE runs SET machine = ? WHERE id = ?", (json.dumps(machine), run_id))

    def finish_run(self, run_id: int, status: str) -> None:
        self.close()
        with self._writing(f"the end of run {run_id} ({status})", run_id), closing(self._connect()) as con, con:
            con.execute("UPDATE runs SET finished = ?, status = ? WHERE id = ?", (now(), status, run_id))
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

    def latest_incomplete_run(self, command_prefix: str | tuple[str, ...] | None = None,
                              machine: dict[str, Any] | None = None) -> int | None:
        """The newest run (of commands starting with ``command_prefix``, or one of them) that
        did not finish: a cell not stored, or not marked done (interrupted, or its process died);
        with ``machine``, only a run recorded on that machine (``recorded_machine``)."""
        runs = [r for r in self.runs() if (not command_prefix or (r["command"] or "").startswith(command_prefix))
                and (r["status"] != "done" or r["done"] < r["planned"])
                and (machine is None or not other_machine(recorded_machine(r), machine))]
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


def as_read(row: dict[str, Any], run_id: int | None) -> dict[str, Any]:
    """``row`` as ``Store.rows`` gives it back once stored in ``run_id``: its JSON text read
    back, with its ``run_id``; no store is read."""
    return {"run_id": run_id, **json.loads(json.dumps(row))}


# the fields every reader of a stored row relies on: its names, status, parameters and texts
READ_FIELDS = ("problem", "integrator", "status", *ROW_PARAMETERS, "t_final", "settings", "parameters", "message")


def bad_row(row: Any) -> str | None:
    """Why a stored row cannot be read as one (None: it can): it must be a JSON object whose
    READ_FIELDS hold against the declared row (longtime.core.rowschema): problem, integrator
    and a status of its values, row parameters (dt, tol, eps_res, order) and t_final of their
    types, settings, parameters and message texts."""
    if not isinstance(row, dict):
        return f"not a JSON object but {type(row).__name__ if row is not None else 'null'}"
    wrong = rowschema.problems(row, only=READ_FIELDS)
    return wrong[0] if wrong else None


def recorded_machine(run: dict[str, Any]) -> dict[str, Any] | None:
    """The machine the run ``run`` (a record of ``Store.runs``) is recorded to have run on
    (None: its record names none)."""
    try:
        machine = json.loads(run.get("machine") or "null")
    except (TypeError, ValueError, RecursionError):  # a hand-edited or nested-beyond-reading record
        return None
    return machine if isinstance(machine, dict) and any(machine_key(machine)) else None


def other_machine(recorded: dict[str, Any] | None, here: dict[str, Any]) -> bool:
    """Whether ``recorded`` names a machine other than ``here`` (host name, CPU model and core
    count: longtime.execution.run_environment.machine_key)."""
    return recorded is not None and machine_key(recorded) != machine_key(here)


def machine_text(machine: dict[str, Any]) -> str:
    """A machine in a few words: its host name, CPU model and core count."""
    node, model, cpus = machine_key(machine)
    return f"{node or 'an unnamed host'} ({model or 'CPU model unknown'}, {cpus if cpus is not None else '?'} cores)"
