"""Batches of cells as one worker runs them: the cells of one problem x scheme pair
together (a worker compiles the pair's kernel once), largest first, each row calibrated
against the machine's speed and, with a folder, written there as it finishes (a worker that
dies mid-batch loses nothing finished). The resident children of the process executor and
of the Dask executor (``longtime.execution.resident.Resident``) run their batches here."""
from __future__ import annotations

import time

from longtime.core import phases
from longtime.execution import calibration, jobfiles
from longtime.execution.cells import Cell, RunSpec, cell_size, run_cell


def batches_by_pair(cells: list[Cell]) -> list[list[Cell]]:
    """Cells of one problem x scheme pair together: one worker compiles each kernel once.
    Largest first (by ``estimated_work``), so no long batch starts last and runs alone."""
    groups: dict[tuple[str, str], list[Cell]] = {}
    for c in cells:
        groups.setdefault((c.problem, c.integrator), []).append(c)
    dims: dict[str, int] = {}
    return sorted(groups.values(), key=lambda batch: -sum(estimated_work(c, dims) for c in batch))


def estimated_work(cell: Cell, dims: dict[str, int]) -> float:
    """A rough size of a cell, for ordering only: state dimension x steps (the cell's dt, or
    the problem's default step for adaptive schemes). ``dims`` caches dimensions."""
    try:
        dim, steps, _ = cell_size(cell, dims)
        return dim * max(steps, 0.0)
    except Exception:  # an invalid setting: run_cell reports it; order it anywhere
        return 0.0


def calibrated_row(here: calibration.Calibrator, cell: Cell, spec: RunSpec) -> dict:
    """run_cell's row, run as ``spec`` says, with the machine's speed beside it
    (longtime.execution.calibration)."""
    t0 = time.time()
    with phases.phase("cell"):  # building the cell, the row: what its nested phases leave
        row = run_cell(cell, spec.max_samples, timing=spec.timing, time_limit=spec.time_limit)
    return row if cell.skip_reason else here.cell(row, t0, time.time())


def run_batch(cells: list[Cell], spec: RunSpec, folder: str | None = None) -> list[dict]:
    """Rows of ``cells`` in this worker, run as ``spec`` says (its memory limit is the
    worker's, set where the worker starts). With ``folder``, the cell in progress and each finished
    row are also written there, so that a worker that dies mid-batch loses nothing finished
    and its parent knows which cell it died in."""
    rows = []
    here = calibration.here()
    here.start()
    for c in cells:
        marker = jobfiles.running_marker(folder) if folder else None
        if marker is not None:
            jobfiles.write_json(marker, c.to_dict())
        row = calibrated_row(here, c, spec)
        if marker is not None:
            jobfiles.write_row(folder, c.key, c.to_dict(), row)
            marker.unlink(missing_ok=True)  # gone when the watchdog has claimed it
        rows.append(row)
    here.finish()
    return rows

