"""One cell per process, with a time limit.

A cell that hangs or takes the interpreter down (``os._exit``, a segfault in compiled
code, out of memory) must become a row, not stop the matrix. Each cell runs in a fresh
child interpreter (``python -m longtime.execution.child``, a job of kind ``cell``) started
with ``subprocess``, not ``multiprocessing``: the child then also works from daemonic
processes such as Dask's workers, which may not have multiprocessing children. The child reads the cell from a
job file and writes its row as its result (longtime.execution.child); the parent kills the
child's whole process group when the time limit passes (a ``timeout`` row) and reads a dead
child's exit code or signal and the end of its stderr (a ``failed`` row).

The price is one interpreter start and one kernel compilation per cell (about a second):
use this executor for untrusted or unstable plugins and time limits, the process executor for
speed.
"""
from __future__ import annotations

import dataclasses
import os
import shutil
import sys
import time
from dataclasses import dataclass, field
from typing import Iterator

from longtime.core.cache import no_space
from longtime.core.status import Status
from longtime.execution import child as children
from longtime.execution import tempdirs
from longtime.execution.cells import Cell, RunSpec, base_row, run_cell
from longtime.execution.child import Child
from longtime.execution.limits import hard_limit

POLL_S = 0.05
# a child's start-up (Python, numpy, numba, the plugins) before its cell begins: its time limit
# counts from the cell's start, as the worker's watchdog counts it, and this bounds the start-up
STARTUP_S = 120.0


@dataclass
class _Cell:
    """A cell running in its child."""

    cell: Cell
    child: Child
    deadline: float
    timeout: float | None  # seconds from its cell's start to the kill (None: never)
    started: float = field(default_factory=time.perf_counter)
    begun: bool = False  # the child has begun its cell (running_since)

    def running_since(self) -> None:
        """Once the child has begun its cell (its mark), the time limit counts from then;
        before, from its start plus STARTUP_S."""
        if self.timeout and not self.begun and self.child.marks():
            self.begun = True
            self.deadline = time.perf_counter() + self.timeout


def _kill_after(cell: Cell, timeout: float | None) -> float | None:
    """Seconds from ``cell``'s start to its kill: ``timeout``, or the hard limit of the cell's own
    time limit (the default matrix's library peers'), the sooner (None: neither)."""
    kills = [x for x in (timeout, hard_limit(cell.time_limit)) if x]
    return min(kills) if kills else None


def _start(cell: Cell, spec: RunSpec, timeout: float | None) -> _Cell:
    folder = None
    try:
        folder = tempdirs.make("cell")
        children.write_job(folder, "cell", [cell], spec)
        # no preexec_fn: this may be a Dask worker's thread; the child asks to die with it itself
        child = children.start(folder, dies_at_start=False)
    except OSError as exc:
        if folder is not None:
            shutil.rmtree(folder, ignore_errors=True)
        if no_space(exc):
            raise tempdirs.disk_full(exc, f"writing the files of {cell.problem} x {cell.integrator}") from None
        raise
    timeout = _kill_after(cell, timeout)
    deadline = time.perf_counter() + timeout + STARTUP_S if timeout else float("inf")
    return _Cell(cell, child, deadline, timeout)


def _finish(running: _Cell, timed_out: bool) -> dict:
    """The row of a child that has ended (or was killed)."""
    child = running.child
    try:
        row = child.result()
        if row is not None:
            return row
        row = base_row(running.cell)
        elapsed = time.perf_counter() - running.started
        if timed_out:
            row.update(status=Status.TIMEOUT,
                       message=f"cell exceeded its time limit of {running.timeout:g} s (process killed after "
                               f"{elapsed:.1f} s, its start-up included)")
            return row
        if child.proc.returncode == tempdirs.NO_SPACE_EXIT:  # no space for its row: not the cell's fault
            tail = child.stderr().strip().splitlines()
            raise tempdirs.DiskFull(tail[-1] if tail else f"no space left on the disk for the row of "
                                    f"{running.cell.problem} x {running.cell.integrator}")
        row.update(status=Status.FAILED, message=child.failure("cell process"))
        return row
    finally:
        child.remove()


def run_isolated(cells: list[Cell], spec: RunSpec, timeout: float | None = None,
                 jobs: int = 1) -> Iterator[tuple[Cell, dict]]:
    """Rows of ``cells``, each run in its own child process, ``jobs`` at a time, as they end;
    a child is killed ``timeout`` seconds after its cell began (None: never)."""
    queue = list(cells)
    running: list[_Cell] = []
    # the cell stops itself at its time limit, keeping what it reached; under a hard timeout,
    # early enough to report ahead of the kill
    limit = min(x for x in (spec.time_limit, 0.8 * (timeout or 0), float("inf")) if x)
    spec = dataclasses.replace(spec, time_limit=None if limit == float("inf") else limit)
    try:
        while queue or running:
            while queue and len(running) < max(1, jobs):
                cell = queue.pop(0)
                if cell.skip_reason:  # nothing to run: no process needed
                    yield cell, run_cell(cell)
                    continue
                running.append(_start(cell, spec, timeout))
            still = []
            for one in running:
                one.running_since()
                if one.child.ended():
                    yield one.cell, _finish(one, False)
                elif time.perf_counter() > one.deadline:
                    one.child.kill()
                    yield one.cell, _finish(one, True)
                else:
                    still.append(one)
            if len(still) == len(running) and running:
                time.sleep(POLL_S)
            running = still
    finally:  # interrupted: no orphan keeps computing, no folder stays
        for one in running:
            one.child.remove()


def run_cell_isolated(cell: Cell, spec: RunSpec, timeout: float | None = None) -> dict:
    """One cell's row, run in a child process killed ``timeout`` seconds after its cell began
    (for remote executors)."""
    for _, row in run_isolated([cell], spec, timeout, jobs=1):
        return row
    raise AssertionError("unreachable")


def run_job(folder: str, job: children.Job) -> None:
    """The child's side of a ``cell`` job (longtime.execution.child.KINDS): the cell's row as
    its result."""
    children.enter(folder, job)
    (cell,) = job.cells
    try:
        children.mark(folder, 0, 0)  # the parent's time limit counts from here
        row = run_cell(cell, job.spec.max_samples, timing=job.spec.timing, time_limit=job.spec.time_limit)
        children.write_result(folder, row)
    except (OSError, tempdirs.DiskFull) as exc:
        if not tempdirs.out_of_space(exc):
            raise
        tempdirs.exit_out_of_space(exc, "writing the row")
    sys.stderr.flush()
    os._exit(0)  # skip interpreter teardown: a thread a plugin left running cannot hang us
