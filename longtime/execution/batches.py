"""Batches of cells as one worker runs them: the cells of one problem x scheme pair
together (a worker compiles the pair's kernel once), largest first, each row calibrated
against the machine's speed and, with a folder, written there as it finishes (a worker that
dies mid-batch loses nothing finished). The resident children of the process executor and
of the Dask executor (``longtime.execution.resident.Resident``) run their batches here.

A chain: the default matrix's library peers' cells (``Cell.bound``, set by
longtime.execution.budget) of one problem, library and t_final are one batch, cheapest
estimated first (``budget.run_seconds``). Once a cell of the chain keeps the target of
"Which library" (``need.kept_error`` against ``need.TARGET``), each later cell of the chain
runs under a CPU bound of ``Cell.bound`` (``need.FACTOR``) times that cell's CPU seconds
(the cheapest such cell's): a run whose own CPU seconds reach it has spent more than a
setting of its library that keeps the target, so it cannot be the library's entry, and it
stops there (a ``timeout`` row whose message begins with ``status.BOUNDED`` and says why
and how far it got); so does a run that has spent that cell's CPU seconds where its pace
puts its end past ``limits.CHAIN_PACE`` times the bound (its message says so, and where).
The bound is on CPU seconds, never the wall clock: a loaded machine does not make the
claim false."""
from __future__ import annotations

import dataclasses
import math
import time
from typing import Any

from longtime.core import phases
from longtime.execution import budget, calibration, jobfiles
from longtime.execution.cells import Cell, RunSpec, cell_size, run_cell
from longtime.predict.need import TARGET, kept_error, library_of
from longtime.predict.settings import solution_measure


def batches_by_pair(cells: list[Cell]) -> list[list[Cell]]:
    """Cells of one problem x scheme pair together: one worker compiles each kernel once;
    a chain's cells (``chain_key``) together, cheapest estimated first. Largest first (by
    ``estimated_work``), so no long batch starts last and runs alone."""
    groups: dict[tuple, list[Cell]] = {}
    for c in cells:
        groups.setdefault(chain_key(c) or (c.problem, c.integrator), []).append(c)
    dims: dict[str, int] = {}
    for key, batch in groups.items():
        if key[0] == CHAIN:
            batch.sort(key=lambda c: _estimated_seconds(c, dims))
    return sorted(groups.values(), key=lambda batch: -sum(estimated_work(c, dims) for c in batch))


CHAIN = "chain"


def chain_key(cell: Cell) -> tuple | None:
    """The chain of a library peer's cell of the default matrix (its problem and settings,
    library and t_final), None for any other cell."""
    if cell.bound is None or cell.skip_reason:
        return None
    return CHAIN, cell.problem, repr(sorted(cell.problem_settings.items())), library_of(cell.integrator), cell.t_final


def _estimated_seconds(cell: Cell, dims: dict[str, int]) -> float:
    try:
        return budget.run_seconds(cell, dims)
    except Exception:  # an invalid setting: run_cell reports it; order it last
        return math.inf


class Chains:
    """The chains' state in one worker: per chain, the cheapest CPU seconds of a cell that
    kept the target and its setting; ``bounded`` gives a later cell its CPU bound."""

    def __init__(self) -> None:
        self.kept: dict[tuple, tuple[float, str]] = {}

    def bounded(self, cell: Cell) -> Cell:
        """``cell`` under its chain's bound where a cell of its chain kept the target."""
        key = chain_key(cell)
        if key is None or key not in self.kept:
            return cell
        cpu, name = self.kept[key]
        library = key[3]
        named = name if name.startswith(f"{library}-") else f"{library} {name}"  # "scipy dop853", "scipy-rk45"
        reason = (f"x{cell.bound:g} the CPU of {named} ({cpu:.3g} s), which keeps {TARGET:g}: "
                  f"it cannot be {library}'s cheapest")
        return dataclasses.replace(cell, cpu_bound=cell.bound * cpu, bound_reason=reason)

    def saw(self, cell: Cell, row: dict[str, Any]) -> None:
        """A chain's ``row`` of ``cell``: kept if it keeps the target for fewer CPU seconds."""
        key, m = chain_key(cell), solution_measure([row])
        if key is None or m is None or kept_error(row, m) is None:
            return
        cpu = float(row["cpu_s"])
        if key not in self.kept or cpu < self.kept[key][0]:
            self.kept[key] = (cpu, f"{cell.integrator} {budget.setting_text(cell)}")


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
    chains = Chains()
    for c in cells:
        marker = jobfiles.running_marker(folder) if folder else None
        if marker is not None:
            jobfiles.write_json(marker, c.to_dict())
        row = calibrated_row(here, chains.bounded(c), spec)
        chains.saw(c, row)
        if marker is not None:
            jobfiles.write_row(folder, c.key, c.to_dict(), row)
            marker.unlink(missing_ok=True)  # gone when the watchdog has claimed it
        rows.append(row)
    here.finish()
    return rows

