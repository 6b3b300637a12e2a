"""Children that live on (``longtime.execution.child``'s protocol, job after job).

``Resident`` is a child that runs job after job (batches of cells, calls): it keeps its
compiled kernels, and is replaced only when a cell passes its time limit (it is killed),
ends the process, or runs into the memory limit. ``ResidentPool`` is N of them, one per
thread of this process: the default executor's workers (``longtime.execution.matrix``),
warmup's, the results page's and ``pool.run_tasks``'; a Dask worker runs its batches on its
own ``resident()``. A crash costs the one child and its cell, never the other workers.
"""
from __future__ import annotations

import contextlib
import pickle
import select
import subprocess
import threading
import time
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any, Callable

from longtime.core.status import Status
from longtime.execution import jobfiles, tempdirs
from longtime.execution.cells import Cell, RunSpec, base_row
from longtime.execution.child import POLL_S, Child, relay_stderr, start, write_job
from longtime.execution.limits import (
    Watchdog,
    hard_limit,
    hit_memory_limit,
    timeout_message,
)


class Stopped(RuntimeError):
    """A job handed to a ``Resident`` that has been stopped (its pool shut down)."""


class CallFailed(RuntimeError):
    """A ``call`` whose child ended without its outcome (killed, a segfault, os._exit)."""


class Resident:
    """A long-lived child that runs batches of cells (``run``) and calls (``call``), keeping
    its compiled kernels between them. A cell that passes the hard limit of its time limit
    is killed with the child (a ``timeout`` row), a cell that ends the child gets a
    ``failed`` row naming how, and the batch's other cells run on in a fresh child; a cell
    that runs into the memory limit has its row, and the child is replaced after the batch
    (its heap may stay fragmented near the limit). The child dies with the thread that
    started it: use one ``Resident`` per thread."""

    # a child's start-up and a batch's work outside any cell (the calibration) may take this
    # long before the child is taken for hung
    STARTUP_S = 120.0

    def __init__(self) -> None:
        self.child: Child | None = None
        self.memory_limit: int | None = None
        self.stopped = False

    @property
    def pid(self) -> int | None:
        """The process id of its child while one runs, else None."""
        return self.child.pid if self.child is not None and not self.child.ended() else None

    def run(self, cells: list[Cell], spec: RunSpec) -> list[dict]:
        rows: dict[str, dict] = {}
        todo = list(cells)
        while todo:
            child = self._child(spec)
            child.clear()
            write_job(child.folder, "batches", todo, spec)
            rows.update(self._batch(child, todo, spec))
            todo = [c for c in todo if c.key not in rows]
        if any(hit_memory_limit(r) for r in rows.values()):
            self.close()
        return [rows[c.key] for c in cells]

    def call(self, fn: Callable, args: tuple, spec: RunSpec) -> Any:
        """``fn(*args)`` in the child (under ``spec``'s memory limit, without a time limit):
        what it returns, or the exception it raises; ``CallFailed`` naming how the child
        ended where it gave no outcome (then it is replaced on the next job)."""
        child = self._child(spec)
        child.clear()
        write_job(child.folder, "call", [], spec)
        jobfiles.write(child.folder / jobfiles.CALL, pickle.dumps((fn, args)))
        try:
            line = self._ask(child, None, hang_s=None)
        finally:
            relay_stderr(child)
        outcome = child.folder / jobfiles.OUTCOME
        if line == b"done" and outcome.exists():
            kind, value = pickle.loads(outcome.read_bytes())
            if kind == "raised":
                raise value
            return value
        self._reap(child, line)
        why = child.failure("worker process")
        self.close()
        raise CallFailed(f"{getattr(fn, '__qualname__', fn)}: {why}")

    def _child(self, spec: RunSpec) -> Child:
        if self.stopped:
            raise Stopped("the worker was stopped")
        if self.child is not None and (self.child.ended() or self.memory_limit != spec.memory_limit):
            self.close()
        if self.child is None:
            folder = tempdirs.make("cell")
            write_job(folder, "batches", [], spec)
            self.child = start(folder, pipes=True, dies_at_start=False)
            self.memory_limit = spec.memory_limit
            self._ready(self.child)
        return self.child

    def _ready(self, child: Child) -> None:
        """Wait (at most STARTUP_S) for a new child's ``ready``: it has read its standing job,
        so the job file is the next job's to write. A child that ends or hangs before it is
        named by the job it is then sent (``_ask``)."""
        fd, deadline = child.proc.stdout.fileno(), time.monotonic() + self.STARTUP_S
        while time.monotonic() < deadline:
            if select.select([fd], [], [], POLL_S)[0]:
                child.proc.stdout.readline()
                return

    def _batch(self, child: Child, cells: list[Cell], spec: RunSpec) -> dict[str, dict]:
        """The rows of ``cells`` run in ``child``: all of them when the batch ends whole; else
        those finished and the row of the cell the child ended in (or, where it ended outside
        any cell, of the first cell not finished), and the child is gone."""
        killed: list[tuple[dict, float]] = []
        # a cell's own time limit (the default matrix's library peers') is watched without a job's
        watchdog = Watchdog(child.folder, spec.time_limit, lambda cell, elapsed: killed.append((cell, elapsed)))
        try:
            watchdog.start()
            line = self._ask(child, hard_limit(spec.time_limit))
        finally:
            watchdog.stop()  # joined: a kill it made is in ``killed``
            relay_stderr(child)
        result = child.result() if line == b"done" else None
        if result is not None:
            return dict(zip((c.key for c in cells), result))
        self._reap(child, line)  # ended, or its result cannot be read: the rows it wrote, cell by cell
        done = {Cell.from_dict(cell).key: row for cell, row in jobfiles.finished_rows(child.folder)}
        running = [Cell.from_dict(c) for c in jobfiles.running_cells(child.folder)]
        if killed:
            cell = Cell.from_dict(killed[0][0])
            if cell.key not in done:  # else it ended just ahead of the kill: its own row stands
                done[cell.key] = {**base_row(cell), "status": Status.TIMEOUT,
                                  "message": timeout_message(spec.time_limit, killed[0][1], killed[0][0])}
        elif any(c.key not in done for c in cells):
            why = child.failure("cell process") if line is not None else \
                f"the cell process did not answer within {self.STARTUP_S:g} s of its start or its last cell"
            cell = next((c for c in running if c.key not in done), None) or \
                next(c for c in cells if c.key not in done)  # ended outside any cell: the next one fails
            done[cell.key] = {**base_row(cell), "status": Status.FAILED, "message": why}
        self.close()
        return done

    def _reap(self, child: Child, line: bytes | None) -> None:
        """A child that gave no answer ended (or is killed): its answer channel closed
        (``line`` empty) when it ends on its own, so it is given a moment to, and named by
        how. One that ended for want of disk space (``tempdirs.NO_SPACE_EXIT``) is a fault of
        the machine, not of its cell: ``DiskFull``, and the child is gone."""
        if line == b"":
            with contextlib.suppress(subprocess.TimeoutExpired):
                child.proc.wait(timeout=5)
        child.kill()
        if child.proc.returncode == tempdirs.NO_SPACE_EXIT:
            tail = child.stderr().strip().splitlines()
            self.close()
            raise tempdirs.DiskFull(tail[-1] if tail else "no space left on the disk for a worker's files")

    def _ask(self, child: Child, limit: float | None, hang_s: float | None = STARTUP_S) -> bytes | None:
        """Send the child its job and wait for its answer: ``b"done"``, ``b""`` when it ended,
        None when no cell began within ``hang_s`` (the child hangs outside any cell; None:
        wait for ever)."""
        try:
            child.proc.stdin.write(b"go\n")
            child.proc.stdin.flush()
        except (BrokenPipeError, OSError):
            child.proc.wait()
            return b""
        quiet_since = time.monotonic()
        fd = child.proc.stdout.fileno()
        while True:
            if select.select([fd], [], [], POLL_S)[0]:
                return child.proc.stdout.readline().strip()
            if hang_s is None:
                continue
            if jobfiles.running_markers(child.folder):
                quiet_since = time.monotonic()
            elif time.monotonic() - quiet_since > hang_s + (limit or 0):
                return None

    def close(self) -> None:
        """Stop the child and remove its folder."""
        child, self.child = self.child, None
        if child is not None:
            child.remove()

    def stop(self) -> None:
        """Close the child, and start no other: a job it is running ends (its thread's
        ``run`` or ``call`` raises ``Stopped``, or returns what it has), the next is refused."""
        self.stopped = True
        self.close()


class ResidentPool:
    """``workers`` resident children, one per thread of a thread pool of this process, as a
    process pool's workers are: ``submit(fn, *args)`` runs ``fn(*args)`` in one of them (a
    ``call``), ``submit_cells(cells)`` a batch of cells (``Resident.run``: a crash or a hard
    time limit costs its cell, the child is replaced, the batch goes on). Every child runs
    under ``spec``'s memory limit (and a batch as ``spec`` says), dies with its thread (so
    with this process), and is stopped at ``shutdown``; a job then running ends at once."""

    def __init__(self, workers: int, spec: RunSpec | None = None):
        self.spec = spec or RunSpec()
        self._threads = ThreadPoolExecutor(max_workers=max(1, workers), thread_name_prefix="longtime-worker")
        self._local = threading.local()
        self._residents: list[Resident] = []
        self._lock = threading.Lock()

    def _resident(self) -> Resident:
        one = getattr(self._local, "resident", None)
        if one is None:
            one = self._local.resident = Resident()
            with self._lock:
                self._residents.append(one)
        return one

    def submit(self, fn: Callable, *args: Any) -> Future:
        return self._threads.submit(lambda: self._resident().call(fn, args, self.spec))

    def submit_cells(self, cells: list[Cell]) -> Future:
        return self._threads.submit(lambda: self._resident().run(cells, self.spec))

    def pids(self) -> list[int]:
        """The process ids of the children that run."""
        with self._lock:
            return [pid for pid in (one.pid for one in self._residents) if pid is not None]

    def shutdown(self) -> None:
        """Stop every child (killed: after the last result it only spares their interpreter's
        teardown; after Ctrl-C or an error it returns at once even while a child is stuck in
        compiled code) and the threads, the jobs not started cancelled."""
        with self._lock:
            residents = list(self._residents)
        for one in residents:
            with contextlib.suppress(Exception):
                one.stop()
        self._threads.shutdown(wait=False, cancel_futures=True)

    def __enter__(self) -> "ResidentPool":
        return self

    def __exit__(self, *exc) -> None:
        self.shutdown()


_RESIDENTS: dict[int, Resident] = {}
_RESIDENTS_LOCK = threading.Lock()


def resident() -> Resident:
    """This thread's resident child (made on first use; all are stopped at exit)."""
    with _RESIDENTS_LOCK:
        if not _RESIDENTS:
            import atexit

            atexit.register(close_residents)
        return _RESIDENTS.setdefault(threading.get_ident(), Resident())


def resident_pids() -> list[int]:
    """The process ids of this process's resident children that run."""
    with _RESIDENTS_LOCK:
        return [pid for pid in (one.pid for one in _RESIDENTS.values()) if pid is not None]


def close_residents() -> None:
    """Stop every resident child of this process and remove their folders."""
    with _RESIDENTS_LOCK:
        for one in _RESIDENTS.values():
            with contextlib.suppress(Exception):
                one.close()
        _RESIDENTS.clear()
