"""One cell per process, with a time limit.

A cell that hangs or takes the interpreter down (``os._exit``, a segfault in compiled
code, out of memory) must become a row, not stop the matrix. Each cell runs in a fresh
child interpreter (``python -m longtime.execution.isolation``) started with ``subprocess``, not
``multiprocessing``: the child then also works from daemonic processes such as Dask's
workers, which may not have multiprocessing children. The child reads the cell from a
JSON file and writes its row to another; the parent kills the child's whole process
group when the time limit passes (a ``timeout`` row) and reads a dead child's exit code
or signal and the end of its stderr (a ``failed`` row).

The price is one interpreter start and one kernel compilation per cell (about a second):
use this executor for untrusted or unstable plugins and time limits, the process pool for
speed.
"""
from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

from longtime.core import registry
from longtime.core.cache import no_space
from longtime.core.timing import Timing
from longtime.execution import tempdirs
from longtime.execution.cells import (
    DEFAULT_MAX_SAMPLES,
    DEFAULT_TIME_LIMIT,
    Cell,
    base_row,
    run_cell,
)
from longtime.execution.limits import die_with_parent, set_memory_limit

POLL_S = 0.05
# a child's start-up (Python, numpy, numba, the plugins) before its cell begins: its time limit
# counts from the cell's start, as the pool's watchdog counts it, and this bounds the start-up
STARTUP_S = 120.0
STDERR_TAIL = 600  # characters of a dead child's stderr kept in its row's message


def _signal_name(code: int) -> str:
    try:
        return signal.Signals(code).name
    except ValueError:
        return f"signal {code}"


@dataclass
class _Child:
    cell: Cell
    folder: Path
    proc: subprocess.Popen
    deadline: float
    started: float = field(default_factory=time.perf_counter)
    begun: bool = False  # the child has begun its cell (running_since)

    @property
    def out_path(self) -> Path:
        return self.folder / "row.json"

    @property
    def err_path(self) -> Path:
        return self.folder / "stderr.txt"

    def running_since(self, timeout: float | None) -> None:
        """Once the child has begun its cell (its ``started`` file), the time limit counts from
        then; before, from its start plus STARTUP_S."""
        if timeout and not self.begun and (self.folder / "started").exists():
            self.begun = True
            self.deadline = time.perf_counter() + timeout


def _start(cell: Cell, max_samples: int, timeout: float | None, timing: Timing,
           time_limit: float | None = DEFAULT_TIME_LIMIT, memory_limit: int | None = None) -> _Child:
    try:
        return _spawn(cell, max_samples, timeout, timing, time_limit, memory_limit)
    except OSError as exc:
        if no_space(exc):
            raise tempdirs.disk_full(exc, f"writing the files of {cell.problem} x {cell.integrator}") from None
        raise


def _spawn(cell: Cell, max_samples: int, timeout: float | None, timing: Timing,
           time_limit: float | None, memory_limit: int | None) -> _Child:
    folder = tempdirs.make("cell")
    job = {"cell": cell.to_dict(), "max_samples": max_samples, "parent": os.getpid(), "time_limit": time_limit,
           "timing": timing.to_dict(), "memory_limit": memory_limit}
    (folder / "cell.json").write_text(json.dumps(job))
    write_session(folder)
    with open(folder / "stderr.txt", "wb") as err:
        proc = subprocess.Popen(
            [sys.executable, "-m", "longtime.execution.isolation", str(folder)],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=err,
            start_new_session=True)  # its own process group: a kill reaches its children too
    deadline = time.perf_counter() + timeout + STARTUP_S if timeout else float("inf")
    return _Child(cell, folder, proc, deadline)


def write_session(folder: Path) -> None:
    """The classes registered from Python in this process (pickled by value) and where their
    modules import from, for a child interpreter started on ``folder`` (``restore_session``)."""
    session = registry.session_payload()
    if session is not None:
        (folder / "session.pkl").write_bytes(session)
        (folder / "sys_path.json").write_text(json.dumps(sys.path))


def restore_session(folder: Path) -> None:
    """In the child: register what ``write_session`` saved in ``folder``."""
    if (folder / "session.pkl").exists():
        sys.path[:0] = [p for p in json.loads((folder / "sys_path.json").read_text()) if p not in sys.path]
        registry.restore_session((folder / "session.pkl").read_bytes())


def kill_group(proc: subprocess.Popen) -> None:
    """Kill a child started with ``start_new_session`` and its children."""
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        proc.kill()
    proc.wait()


def _finish(child: _Child, timed_out: bool, timeout: float | None) -> dict:
    """The row of a child that has ended (or was killed)."""
    try:
        if child.out_path.exists():  # written atomically: a whole row
            return json.loads(child.out_path.read_text())
        row = base_row(child.cell)
        elapsed = time.perf_counter() - child.started
        if timed_out:
            row.update(status="timeout",
                       message=f"cell exceeded its time limit of {timeout:g} s (process killed after "
                               f"{elapsed:.1f} s, its start-up included)")
            return row
        code = child.proc.returncode
        if code == tempdirs.NO_SPACE_EXIT:  # the child found no space for its row: not the cell's fault
            tail = child.err_path.read_text(errors="replace").strip().splitlines() if child.err_path.exists() else []
            raise tempdirs.DiskFull(tail[-1] if tail else f"no space left on the disk for the row of "
                                    f"{child.cell.problem} x {child.cell.integrator}")
        how = f"killed by {_signal_name(-code)}" if code < 0 else f"exited with code {code}"
        tail = child.err_path.read_text(errors="replace").strip()[-STDERR_TAIL:] if child.err_path.exists() else ""
        row.update(status="failed",
                   message=f"cell process {how} without a result" + (f"; stderr: {tail}" if tail else ""))
        return row
    finally:
        for p in child.folder.iterdir():
            p.unlink()
        child.folder.rmdir()


def run_isolated(cells: list[Cell], max_samples: int = DEFAULT_MAX_SAMPLES, timeout: float | None = None,
                 jobs: int = 1, timing: Timing | None = None, time_limit: float | None = DEFAULT_TIME_LIMIT,
                 memory_limit: int | None = None) -> Iterator[tuple[Cell, dict]]:
    """Rows of ``cells``, each run in its own child process, ``jobs`` at a time, as they end."""
    queue = list(cells)
    running: list[_Child] = []
    try:
        while queue or running:
            while queue and len(running) < max(1, jobs):
                cell = queue.pop(0)
                if cell.skip_reason:  # nothing to run: no process needed
                    yield cell, run_cell(cell)
                    continue
                # the cell stops itself at its time limit, keeping what it reached; under a hard
                # timeout, early enough to report ahead of the kill
                limit = min(x for x in (time_limit, 0.8 * (timeout or 0), float("inf")) if x)
                running.append(_start(cell, max_samples, timeout, timing or Timing(),
                                      None if limit == float("inf") else limit, memory_limit))
            still = []
            for child in running:
                child.running_since(timeout)
                if child.proc.poll() is not None:
                    yield child.cell, _finish(child, False, timeout)
                elif time.perf_counter() > child.deadline:
                    kill_group(child.proc)
                    yield child.cell, _finish(child, True, timeout)
                else:
                    still.append(child)
            if len(still) == len(running) and running:
                time.sleep(POLL_S)
            running = still
    finally:  # interrupted: no orphan keeps computing, no folder stays
        for child in running:
            if child.proc.poll() is None:
                kill_group(child.proc)
            shutil.rmtree(child.folder, ignore_errors=True)


def run_cell_isolated(cell: Cell, max_samples: int = DEFAULT_MAX_SAMPLES, timeout: float | None = None,
                      timing: Timing | None = None, time_limit: float | None = DEFAULT_TIME_LIMIT) -> dict:
    """One cell's row, run in a child process with a time limit (for remote executors)."""
    for _, row in run_isolated([cell], max_samples, timeout, jobs=1, timing=timing, time_limit=time_limit):
        return row
    raise AssertionError("unreachable")


def _child_main(folder: str) -> None:
    path = Path(folder)
    job = json.loads((path / "cell.json").read_text())
    die_with_parent(job["parent"])
    restore_session(path)
    set_memory_limit(job.get("memory_limit"))
    try:
        (path / "started").touch()  # the parent's time limit counts from here
        row = run_cell(Cell.from_dict(job["cell"]), job["max_samples"], timing=Timing.from_dict(job["timing"]),
                       time_limit=job.get("time_limit"))
        tmp = path / "row.json.part"
        tmp.write_text(json.dumps(row))
        tmp.replace(path / "row.json")  # atomic: the parent never reads half a row
    except (OSError, tempdirs.DiskFull) as exc:
        if not (no_space(exc) or isinstance(exc, tempdirs.DiskFull)):
            raise
        (path / "row.json.part").unlink(missing_ok=True)
        print(tempdirs.disk_full(exc, "writing the row"), file=sys.stderr)
        sys.stderr.flush()
        os._exit(tempdirs.NO_SPACE_EXIT)
    sys.stderr.flush()
    os._exit(0)  # skip interpreter teardown: a thread a plugin left running cannot hang us


if __name__ == "__main__":
    _child_main(sys.argv[1])
