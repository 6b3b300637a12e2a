"""The store's tables beside the rows, each keyed by its run: the calibrations of the
machine's speed, the checked predictions and the ensemble distances."""
from __future__ import annotations

import json
import sqlite3
from contextlib import closing
from typing import Any, Iterable

from longtime.core import rowschema
from longtime.core.status import Status
from longtime.execution.cells import Cell
from longtime.execution.store_schema import StoreError, now


class RunRecords:
    """The side tables of a store (a part of longtime.execution.store.Store, whose
    connections and write guard it uses)."""

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
        matrix (a report, an order fit or a resume never sees them as one). A StoreError names
        each field that is not the declared row's or a check's (rowschema.CHECK_FIELDS): nothing
        is written then."""
        what = f"a check of {cell.problem} x {cell.integrator} (run {run_id})"
        self._refuse_wrong(check, rowschema.CHECK_FIELDS, what, run_id)
        with self._writing(what, run_id), self._writer_lock, self._row_writer() as con:
            con.execute("INSERT OR REPLACE INTO checks (run_id, cell_key, problem, integrator, row, created) "
                        "VALUES (?, ?, ?, ?, ?, ?)",
                        (run_id, cell.key, check["problem"], check["integrator"], json.dumps(check), now()))

    def checks(self, run_id: int | None = None) -> list[dict[str, Any]]:
        """The checked predictions of ``run_id`` (default: every run's), in the order stored;
        none in a store older than the checks table."""
        return self._records("checks", "row", run_id)

    def add_ensemble(self, run_id: int, record: dict[str, Any]) -> None:
        """Store one scheme's ensemble distance on a chaotic problem
        (longtime.execution.ensembles): its record, whose ``status`` says whether it holds a
        distance (ok) or why not; kept apart from the rows (no cell of the matrix). A
        StoreError names each field that is not the declared row's or an ensemble record's
        (rowschema.ENSEMBLE_FIELDS): nothing is written then."""
        if record.get("status") != Status.OK and record.get("distance") is not None:
            raise ValueError(f"an ensemble record of status {record.get('status')!r} carries a distance")
        what = f"the ensemble of {record.get('problem')} x {record.get('integrator')} (run {run_id})"
        self._refuse_wrong(record, rowschema.ENSEMBLE_FIELDS, what, run_id)
        with self._writing(what, run_id), self._writer_lock, self._row_writer() as con:
            con.execute("INSERT OR REPLACE INTO ensembles (run_id, problem, integrator, status, record, created) "
                        "VALUES (?, ?, ?, ?, ?, ?)",
                        (run_id, record["problem"], record["integrator"], record["status"], json.dumps(record),
                         now()))

    def ensembles(self, run_id: int | None = None) -> list[dict[str, Any]]:
        """The ensemble records of ``run_id`` (default: every run's), in the order stored;
        none in a store older than the ensembles table."""
        return self._records("ensembles", "record", run_id)

    def _refuse_wrong(self, record: dict[str, Any], fields: tuple[rowschema.Field, ...], what: str,
                      run_id: int) -> None:
        """A StoreError naming each wrong field of ``record`` (rowschema.record_problems)."""
        wrong = rowschema.record_problems(record, fields)
        if wrong:
            raise StoreError(f"store {self.path}: refused {what}: " + "; ".join(wrong), str(self.path), run_id)

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
