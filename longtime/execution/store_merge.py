"""Merging stores: every run of several stores copied into one, each with its own machine."""
from __future__ import annotations

import json
import os
import re
import sqlite3
from contextlib import closing
from pathlib import Path
from typing import Any, Iterable

from longtime.core import rowschema
from longtime.core.params import InputError
from longtime.execution.matrix import PHASES_FIELD
from longtime.execution.store import Store, StoreError

# the tables that hang off a run (every one with a run_id column), in the order they are copied;
# rows go through the store's row check (``_copy_rows``), the others are added where missing
_RUN_TABLES = ("planned", "started", "rows", "calibrations", "checks", "ensembles")
# the records beside the rows that are checked as the store checks one it adds: table -> (what
# a record is, its JSON column, its fields)
_RECORDS = {"checks": ("check", "row", rowschema.CHECK_FIELDS),
            "ensembles": ("ensemble", "record", rowschema.ENSEMBLE_FIELDS)}
# the row check's reason without the row's names, and a wrong value's part without the value
_ROW_OF = re.compile(r"^row of .*? x .*?: ")
_WRONG_VALUE = re.compile(r"^([^:]+): \w+ .*, (not .+)$")


def merge_stores(sources: Iterable[str | os.PathLike], into: str | os.PathLike) -> list[dict[str, Any]]:
    """Copy every run of the stores ``sources`` into the store ``into`` (created if missing),
    each with its own machine, versions, calibrations and rows: runs stay apart, never pooled
    as if measured in one place. A run keeps its id where ``into`` has none of that id, else
    it gets the next free one; its machine record gains ``merged_from`` (the store and run id
    it came from, kept through later merges).

    A run already in ``into`` (the same start, command, commit, versions and machine) is
    brought up to date: the rows its source gained since are added, a row its source completed
    since (fewer ``phases_missing``) replaces the copy's, and its status and end follow the
    source's where the copy is not done. A row that differs otherwise between the two is left
    as the copy has it and counted (``differ``). A run still running in its source (not marked
    finished) is copied as it stands, with status ``running``; a later merge adds the rest.

    Every row is checked as the store checks a row it adds (``Store.add_row``): a row refused
    is not copied, and counted by its reason (``refused``); so are the checks and ensemble
    records, checked as ``Store.add_check`` and ``Store.add_ensemble`` check them
    (``refused_records``: "check: reason" or "ensemble: reason" -> records refused).

    Returns one record per run of the sources: ``store``, ``run`` (its id there), ``id`` (its id
    in ``into``; None when it was there already and nothing changed), ``copy`` (its id in
    ``into``), ``merged`` (``copied``, ``updated`` or ``unchanged``), ``status`` (in the source),
    ``added`` (rows added), ``replaced`` (rows completed), ``differ`` (rows that differ, left as
    they were), ``refused`` (reason -> rows refused), ``refused_records`` (the checks' and
    ensemble records' reasons -> records refused) and ``status_was`` (the copy's status
    before an update, else None)."""
    into_path = Path(into).absolute()
    sources = [Path(s) for s in sources]
    for src in sources:
        if src.absolute() == into_path:
            raise InputError(f"merge: {src} is both a source and --into: give another --into file")
    readers = [Store(src, readonly=True) for src in sources]  # each must be a longtime store
    target = Store(into)
    done: list[dict[str, Any]] = []
    with closing(target._connect()) as out, out:
        known = out.execute("SELECT id, started, command, git_commit, versions, machine FROM runs")
        copies = {_run_identity(*r[1:]): r[0] for r in known}
        for reader in readers:
            with closing(reader._connect()) as con:
                con.row_factory = sqlite3.Row
                con.execute("BEGIN")  # one snapshot of the source, whatever a running matrix writes meanwhile
                for run in con.execute("SELECT * FROM runs ORDER BY id").fetchall():
                    done.append(_merge_run(con, out, target, dict(run), reader.path, copies))
    return done


def _run_identity(started: str, command: str | None, commit: str | None, versions: str | None,
                  machine: str | None) -> tuple:
    """What tells a run apart from every other: its start, command, commit, versions and
    machine (without the merge's own note of where it came from)."""
    try:
        place = json.loads(machine or "null")
    except (ValueError, RecursionError):
        place = machine
    if isinstance(place, dict):
        place = {k: v for k, v in place.items() if k != "merged_from"}
    try:
        text = json.dumps(place, sort_keys=True)
    except (TypeError, ValueError, RecursionError):
        text = str(machine)
    return started, command, commit, versions, text


def _merge_run(con: sqlite3.Connection, out: sqlite3.Connection, target: Store, run: dict[str, Any], path: Path,
               copies: dict[tuple, int]) -> dict[str, Any]:
    """Copy the run ``run`` of the store ``con`` (at ``path``) and everything of it into ``out``,
    or bring its copy there up to date."""
    record = {"store": str(path), "run": run["id"], "id": None, "copy": None, "merged": "unchanged",
              "status": run["status"], "status_was": None, "added": 0, "replaced": 0, "differ": 0, "refused": {},
              "refused_records": {}}
    identity = _run_identity(run["started"], run["command"], run["git_commit"], run["versions"], run["machine"])
    new_id = copies.get(identity)
    if new_id is None:
        new_id = _new_run(out, run, path)
        copies[identity] = new_id
        record["merged"] = "copied"
    else:
        status, finished = out.execute("SELECT status, finished FROM runs WHERE id = ?", (new_id,)).fetchone()
        if _newer(run, status, finished):
            out.execute("UPDATE runs SET status = ?, finished = ? WHERE id = ?",
                        (run["status"], run["finished"], new_id))
            record["status_was"] = status
    record["copy"] = new_id
    for table in _RUN_TABLES:
        try:
            fetched = con.execute(f"SELECT * FROM {table} WHERE run_id = ? ORDER BY rowid", (run["id"],)).fetchall()
        except sqlite3.OperationalError:  # an older store without the table
            continue
        if table == "rows":
            _copy_rows(out, target, fetched, new_id, record)
            continue
        for item in fetched:
            if table in _RECORDS and not _record_holds(item, *_RECORDS[table], record["refused_records"]):
                continue
            values = {k: item[k] for k in item.keys()}
            values["run_id"] = new_id
            names = ", ".join(values)
            out.execute(f"INSERT OR IGNORE INTO {table} ({names}) VALUES ({', '.join('?' * len(values))})",
                        tuple(values.values()))
    if record["merged"] == "unchanged" and (record["status_was"] is not None or record["added"] or record["replaced"]):
        record["merged"] = "updated"
    if record["merged"] != "unchanged":
        record["id"] = new_id
    return record


def _record_holds(item: sqlite3.Row, what: str, column: str, fields: tuple[rowschema.Field, ...],
                  refused: dict[str, int]) -> bool:
    """Whether the stored record ``item`` (a check or an ensemble record, JSON in ``column``)
    holds against its declared fields (rowschema.record_problems); else it is counted in
    ``refused`` under ``what`` and the kind of its first problem."""
    try:
        wrong = rowschema.record_problems(json.loads(item[column]), fields)
    except (TypeError, ValueError, RecursionError) as exc:  # not JSON (or not text)
        wrong = [f"not JSON ({type(exc).__name__})"]
    if wrong:
        reason = f"{what}: {_kind('; '.join(wrong))}"
        refused[reason] = refused.get(reason, 0) + 1
    return not wrong


def _new_run(out: sqlite3.Connection, run: dict[str, Any], path: Path) -> int:
    """Insert the run record of ``run`` (of the store at ``path``) into ``out``: its id kept where
    free; its machine gains ``merged_from``. Returns its id there."""
    try:
        machine = json.loads(run["machine"] or "null")
    except (ValueError, RecursionError):
        machine = None
    if not isinstance(machine, dict):
        machine = {"recorded": run["machine"]}
    machine.setdefault("merged_from", {"store": str(path), "run": run["id"]})
    try:
        machine_text = json.dumps(machine)
    except (TypeError, ValueError, RecursionError):
        machine_text = json.dumps({"recorded": run["machine"], "merged_from": {"store": str(path), "run": run["id"]}})
    taken = out.execute("SELECT 1 FROM runs WHERE id = ?", (run["id"],)).fetchone()
    values = (run["started"], run["finished"], run["status"], run["command"], run["git_commit"], run["versions"],
              machine_text)
    if taken:
        cur = out.execute("INSERT INTO runs (started, finished, status, command, git_commit, versions, machine) "
                          "VALUES (?, ?, ?, ?, ?, ?, ?)", values)
    else:
        cur = out.execute("INSERT INTO runs (id, started, finished, status, command, git_commit, versions, machine) "
                          "VALUES (?, ?, ?, ?, ?, ?, ?, ?)", (run["id"], *values))
    return int(cur.lastrowid)


def _newer(run: dict[str, Any], status: str, finished: str | None) -> bool:
    """Whether the source's state of ``run`` is newer than its copy's (``status``, ``finished``):
    the copy is not done and the source's state differs (resumed, interrupted again or
    finished), or both are done and the source ended later (done again after a resume)."""
    if (run["status"], run["finished"]) == (status, finished):
        return False
    if status != "done":
        return True
    return run["status"] == "done" and (run["finished"] or "") > (finished or "")


def _copy_rows(out: sqlite3.Connection, target: Store, fetched: list, new_id: int, record: dict[str, Any]) -> None:
    """Add the rows ``fetched`` (of one run of a source) to the run ``new_id`` of ``out``: each
    checked by the store's row check; a cell the copy lacks is added, a row the source
    completed since replaces the copy's, any other difference is counted and left."""
    have = dict(out.execute("SELECT cell_key, row FROM rows WHERE run_id = ?", (new_id,)).fetchall())
    for item in fetched:
        text = item["row"]
        if have.get(item["cell_key"]) == text:
            continue
        what = f"the row of {item['problem']} x {item['integrator']} (run {new_id})"
        try:
            row = json.loads(text)
            checked = target._row_text(row, what, new_id)
        except (TypeError, ValueError, RecursionError) as exc:  # not JSON (or not text)
            record["refused"][f"not JSON ({type(exc).__name__})"] = record["refused"].get(
                f"not JSON ({type(exc).__name__})", 0) + 1
            continue
        except StoreError as exc:
            reason = _kind(str(exc).split(f"refused {what}: ", 1)[-1])
            record["refused"][reason] = record["refused"].get(reason, 0) + 1
            continue
        values = {k: item[k] for k in item.keys() if k != "id"}
        values.update(run_id=new_id, row=checked)
        names = ", ".join(values)
        placeholders = ", ".join("?" * len(values))
        if item["cell_key"] not in have:
            out.execute(f"INSERT INTO rows ({names}) VALUES ({placeholders})", tuple(values.values()))
            record["added"] += 1
        elif _completes(row, have[item["cell_key"]]):
            out.execute("UPDATE rows SET status = ?, row = ? WHERE run_id = ? AND cell_key = ?",
                        (values["status"], checked, new_id, item["cell_key"]))
            record["replaced"] += 1
        elif json.loads(have[item["cell_key"]]) != row:
            record["differ"] += 1
        have[item["cell_key"]] = checked


def _completes(row: dict[str, Any], stored_text: str) -> bool:
    """Whether ``row`` is the stored row completed: it lacks fewer phases (``phases_missing``)
    than the stored one, and every phase it lacks the stored one lacks too."""
    try:
        stored = json.loads(stored_text)
    except ValueError:
        return True  # the copy's row cannot be read: the checked row takes its place
    if not isinstance(stored, dict):
        return True
    before = set(stored.get(PHASES_FIELD) or ())
    after = set(row.get(PHASES_FIELD) or ())
    return after < before


def _kind(reason: str) -> str:
    """The kind of a row check's refusal ``reason``: the fields named and what each is not,
    without the row's names and the values (two rows refused for the same field's type are
    of one kind)."""
    parts = _ROW_OF.sub("", reason).split("; ")
    return "; ".join(_WRONG_VALUE.sub(r"\1: \2", part) for part in parts)
