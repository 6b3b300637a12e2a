"""Child processes: one way to hand cells to a fresh interpreter and to read what it did.

The parent side (``write_job``, ``start``, ``Child``) and the child side (``read_job``,
``enter``, ``mark``, ``write_result``, ``add_record``) meet in one temporary folder of the
parent (``tempdirs``), which the parent removes when the child is done; its files (named in
``longtime.execution.jobfiles``, which writes them whole or not at all) are:

- ``job.json``: what to run, the only file of this kind (``write_job``): its format's
  ``version``, its ``kind`` (``time``, ``cell``, ``count``, ``batches``, ``call``), the parent's
  process id, the cells, the run options (``RunSpec``) and options of the kind;
- ``session.pkl`` and ``sys_path.json``: the classes registered from Python in the parent
  (pickled by value) and where their modules import from;
- ``stderr.txt``: the child's stderr, whose end names a child that ended without a result;
- ``current``: the child's mark (``mark``): the index of the cell it is in and how many it
  has finished, so that a child that dies or hangs is named on the cell it was in;
- ``result.json``: the result, written whole or not at all (``write_result``);
  ``records.jsonl``: one line per cell as each ends (``add_record``), for a child whose
  results must survive its own death (Valgrind's);
- ``call.pkl`` and ``outcome.pkl``: a ``call`` job's function with its arguments, and what
  it returned or raised (pickled: the function by reference, as a process pool sends it).

A child dies with the thread that started it (``PR_SET_PDEATHSIG``, ``limits``), runs in
its own process group (a kill reaches whatever it started), and ends on ``os._exit``, which
skips the interpreter's teardown (numba's, LLVM's, a thread a plugin left running).

Every child is ``python -m longtime.execution.child FOLDER`` (``start``): it reads its job
and runs the child's side of its kind (``KINDS``: the timing processes', an isolated cell's,
Valgrind's, a resident child's), which lives beside the parent's side of that kind.

``Resident`` is a child that lives on and runs job after job (batches of cells, calls): it
keeps its compiled kernels, and is replaced only when a cell passes its time limit (it is
killed), ends the process, or runs into the memory limit. ``ResidentPool`` is N of them, one
per thread of this process: the default executor's workers (``longtime.execution.matrix``),
warmup's, the results page's and ``pool.run_tasks``'; a Dask worker runs its batches on its own
``resident()``. A crash costs the one child and its cell, never the other workers.
"""
from __future__ import annotations

import contextlib
import importlib
import json
import os
import pickle
import select
import shutil
import signal
import subprocess
import sys
import threading
import time
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from longtime.core import registry
from longtime.core.cache import no_space
from longtime.execution import jobfiles, tempdirs
from longtime.execution.cells import Cell, RunSpec, base_row
from longtime.execution.limits import (
    Watchdog,
    die_with_parent,
    hard_limit,
    hit_memory_limit,
    kill_with_parent,
    set_memory_limit,
    timeout_message,
)

JOB_VERSION = 1
# the child's side of each kind of job: "module:function", called with (folder, job) in the
# child; a child imports only the module its kind runs
KINDS = {"time": "longtime.execution.processes:run_job", "cell": "longtime.execution.isolation:run_job",
         "count": "longtime.execution.valgrind:run_job", "batches": "longtime.execution.child:serve",
         "call": "longtime.execution.child:run_call"}
STDERR_TAIL = 600  # characters of a dead child's stderr kept in the message that names it
POLL_S = 0.05


@dataclass(frozen=True)
class Job:
    """A child's job as it reads it (``read_job``)."""

    kind: str
    parent: int
    cells: list[Cell]
    spec: RunSpec
    options: dict[str, Any]


class JobVersionError(RuntimeError):
    """A job file of another format version (a child of another longtime than its parent's)."""


# ------------------------------------------------------------------ the parent's side
def write_job(folder: Path, kind: str, cells: list[Cell], spec: RunSpec, **options: Any) -> None:
    """The job of a child started on ``folder``: the one writer of a child's job file
    (atomically: a child never reads half a job), with the session beside it. ``kind``:
    one of ``KINDS``."""
    if kind not in KINDS:
        raise ValueError(f"job kind {kind!r}: expected one of {', '.join(KINDS)}")
    data = {"version": JOB_VERSION, "kind": kind, "parent": os.getpid(), "cells": [c.to_dict() for c in cells],
            "spec": spec.to_dict(), "options": options}
    jobfiles.write_json(folder / jobfiles.JOB, data)
    session = registry.session_payload()
    if session is not None:
        jobfiles.write(folder / jobfiles.SESSION, session)
    # the modules this process imports (a plugin in development, a scheme beside a test) are
    # importable in the child too
    jobfiles.write_json(folder / jobfiles.SYS_PATH, [p for p in sys.path if p])


def signal_name(code: int) -> str:
    try:
        return signal.Signals(code).name
    except ValueError:
        return f"signal {code}"


def how_it_ended(returncode: int) -> str:
    """``exited with code N`` or ``killed by SIGNAME``."""
    return f"killed by {signal_name(-returncode)}" if returncode < 0 else f"exited with code {returncode}"


@dataclass
class Child:
    """A started child (``start``): its folder, its process, when it started."""

    folder: Path
    proc: subprocess.Popen
    started: float = field(default_factory=time.monotonic)
    unreadable: str = ""  # why its result file could not be read, where it could not
    relayed: int = 0  # bytes of its stderr passed on to this process's (``Resident``)

    @property
    def pid(self) -> int:
        return self.proc.pid

    def ended(self) -> bool:
        return self.proc.poll() is not None

    def wait(self, seconds: float | None) -> bool:
        """Wait for the child to end, at most ``seconds`` (None: for ever); past them it is
        killed with its process group. Whether it ended on its own."""
        try:
            self.proc.wait(timeout=seconds)
            return True
        except subprocess.TimeoutExpired:
            self.kill()
            return False

    def kill(self) -> None:
        """Kill the child and the processes it started (its process group)."""
        if self.proc.poll() is None:
            try:
                os.killpg(self.proc.pid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):
                self.proc.kill()
        self.proc.wait()

    def result(self) -> Any | None:
        """What the child wrote with ``write_result`` (None where it wrote nothing, or where
        what is there cannot be read: a folder, not JSON; ``failure`` then says so)."""
        path = self.folder / jobfiles.RESULT
        try:
            return json.loads(path.read_text()) if path.exists() else None
        except (OSError, ValueError) as exc:
            reason = getattr(exc, "strerror", None) or exc
            self.unreadable = f"its {jobfiles.RESULT} cannot be read ({type(exc).__name__}: {reason})"
            return None

    def records(self) -> dict[str, dict]:
        """The child's ``add_record`` lines, by cell key."""
        path = self.folder / jobfiles.RECORDS
        lines = path.read_text().splitlines() if path.exists() else []
        return {item["key"]: item for item in map(json.loads, lines)}

    def marks(self) -> list[int]:
        """The child's mark: [the index of the cell it is in, the cells it has finished]."""
        try:
            return [int(x) for x in (self.folder / jobfiles.MARK).read_text().split()]
        except (OSError, ValueError):
            return []

    def current_cell(self) -> int | None:
        """The index of the cell the child was in (its mark), None before its first."""
        marks = self.marks()
        return marks[0] if marks else None

    def stderr(self) -> str:
        path = self.folder / jobfiles.STDERR
        return path.read_text(errors="replace") if path.exists() else ""

    def failure(self, what: str) -> str:
        """Why a child that ended gave no result: ``what`` (the child, named) exited with code
        N or was killed by a named signal, and the end of its stderr."""
        tail = self.stderr().strip()[-STDERR_TAIL:]
        ended = f"{what} {how_it_ended(self.proc.returncode)} without a result"
        return "; ".join(m for m in (ended, self.unreadable, tail and f"stderr: {tail}") if m)

    def clear(self) -> None:
        """Remove what the last job left in the folder (its result, records, mark, a batch's
        row files and markers)."""
        jobfiles.clear(self.folder)

    def remove(self) -> None:
        """Kill the child if it runs and remove its folder: it leaves no file."""
        self.kill()
        shutil.rmtree(self.folder, ignore_errors=True)


def relay_stderr(child: Child) -> None:
    """What a long-lived child wrote on its stderr since the last relay (a warning, a
    plugin's output, a crash's report), passed on to this process's stderr, where a process
    pool's workers would have written it."""
    try:
        with open(child.folder / jobfiles.STDERR, "rb") as err:
            err.seek(child.relayed)
            data = err.read()
    except OSError:
        return
    child.relayed += len(data)
    if data:
        sys.stderr.write(data.decode(errors="replace"))
        sys.stderr.flush()


def start(folder: Path, prefix: tuple[str, ...] | list[str] = (), env: dict[str, str] | None = None,
          pipes: bool = False, dies_at_start: bool = True) -> Child:
    """Start ``python -m longtime.execution.child FOLDER`` (under ``prefix``, such as
    Valgrind's command) on the job written in ``folder``: its own process group, stdin and
    stdout closed (or, with ``pipes``, pipes to this process), stderr into the folder. ``dies_at_start``: the
    child dies with the thread that starts it from before its first instruction (a
    ``preexec_fn``, unsafe where other threads may hold locks, as on a Dask worker; without
    it the child asks for it itself in ``enter``)."""
    argv = [*prefix, sys.executable, "-m", "longtime.execution.child", str(folder)]
    stream = subprocess.PIPE if pipes else subprocess.DEVNULL
    with open(folder / jobfiles.STDERR, "wb") as err:
        proc = subprocess.Popen(argv, stdin=stream, stdout=stream, stderr=err, env=env, start_new_session=True,
                                preexec_fn=kill_with_parent if dies_at_start else None)
    return Child(folder, proc)


# ------------------------------------------------------------------ the child's side
def read_job(folder: str | Path) -> Job:
    """The job in ``folder`` (JobVersionError for a job of another format)."""
    data = json.loads((Path(folder) / jobfiles.JOB).read_text())
    if data.get("version") != JOB_VERSION:
        raise JobVersionError(f"job file {Path(folder) / jobfiles.JOB} has format version {data.get('version')!r}; "
                              f"this longtime reads version {JOB_VERSION}")
    return Job(kind=data["kind"], parent=data["parent"], cells=[Cell.from_dict(c) for c in data["cells"]],
               spec=RunSpec.from_dict(data["spec"]), options=data.get("options") or {})


def enter(folder: str | Path, job: Job) -> None:
    """What a child does before its first cell: die with its parent (and exit at once if it
    is gone), register the parent's session classes, run under the job's memory limit. A
    session that cannot be restored is said on stderr: the cells that need it fail alone."""
    path = Path(folder)
    die_with_parent(job.parent)
    if (path / jobfiles.SYS_PATH).exists():
        sys.path[:0] = [p for p in json.loads((path / jobfiles.SYS_PATH).read_text()) if p not in sys.path]
    if (path / jobfiles.SESSION).exists():
        try:
            registry.restore_session((path / jobfiles.SESSION).read_bytes())
        except Exception as exc:
            print(f"longtime: the session's registered classes could not be restored: {exc!r}", file=sys.stderr)
    set_memory_limit(job.spec.memory_limit)


def mark(folder: str | Path, cell: int, finished: int) -> None:
    """The child is in cell ``cell`` and has finished ``finished`` cells (``Child.marks``)."""
    jobfiles.write(Path(folder) / jobfiles.MARK, f"{cell} {finished}")


def write_result(folder: str | Path, result: Any) -> None:
    """The child's result, atomically: the parent never reads half a result."""
    jobfiles.write_json(Path(folder) / jobfiles.RESULT, result)


def add_record(folder: str | Path, key: str, item: dict[str, Any]) -> None:
    """One cell's record, on disk at once (``Child.records``)."""
    with open(Path(folder) / jobfiles.RECORDS, "a") as records:
        records.write(json.dumps({"key": key, **item}) + "\n")


# ------------------------------------------------------------------ a child that runs batch after batch
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
        limit = hard_limit(spec.time_limit)
        watchdog = Watchdog(child.folder, limit, lambda cell, elapsed: killed.append((cell, elapsed))) \
            if limit else None
        try:
            if watchdog is not None:
                watchdog.start()
            line = self._ask(child, limit)
        finally:
            if watchdog is not None:
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
                done[cell.key] = {**base_row(cell), "status": "timeout",
                                  "message": timeout_message(spec.time_limit, killed[0][1])}
        elif any(c.key not in done for c in cells):
            why = child.failure("cell process") if line is not None else \
                f"the cell process did not answer within {self.STARTUP_S:g} s of its start or its last cell"
            cell = next((c for c in running if c.key not in done), None) or \
                next(c for c in cells if c.key not in done)  # ended outside any cell: the next one fails
            done[cell.key] = {**base_row(cell), "status": "failed", "message": why}
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
            return [one.child.pid for one in self._residents if one.child is not None and not one.child.ended()]

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
        return [one.child.pid for one in _RESIDENTS.values() if one.child is not None and not one.child.ended()]


def close_residents() -> None:
    """Stop every resident child of this process and remove their folders."""
    with _RESIDENTS_LOCK:
        for one in _RESIDENTS.values():
            with contextlib.suppress(Exception):
                one.close()
        _RESIDENTS.clear()


def main(folder: str) -> None:
    """A child started on ``folder`` (``start``): runs its job's kind (``KINDS``). A job of a
    kind this longtime does not know ends it with one line on stderr (exit 1)."""
    job = read_job(folder)
    if job.kind not in KINDS:
        sys.exit(f"longtime: job file {Path(folder) / jobfiles.JOB} has kind {job.kind!r}; "
                 f"this longtime runs {', '.join(KINDS)}")
    module, _, name = KINDS[job.kind].partition(":")
    getattr(importlib.import_module(module), name)(folder, job)


def serve(folder: str, job: Job) -> None:
    """The resident child: a job for each line on stdin (the job file says which: a
    ``batches`` job's cells, a ``call``), ``done`` on the answer channel when its rows or its
    outcome are written; ends at end of file."""
    from longtime.core import phases
    from longtime.execution.batches import run_batch

    phases.since_process_start("worker start")
    answers = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)  # what a plugin prints goes to stderr, never into the answers
    enter(folder, job)
    answers.write(b"ready\n")  # the job file is read: the parent may write the next
    answers.flush()
    for _ in sys.stdin.buffer:
        job = read_job(folder)
        try:
            if job.kind == "call":
                answer_call(folder)
            else:
                write_result(folder, run_batch(job.cells, job.spec, folder))
        except (OSError, tempdirs.DiskFull) as exc:  # no space for its files: not the cells' fault
            if not (no_space(exc) or isinstance(exc, tempdirs.DiskFull)):
                raise
            print(tempdirs.disk_full(exc, "a worker wrote its files"), file=sys.stderr)
            sys.stderr.flush()
            os._exit(tempdirs.NO_SPACE_EXIT)
        answers.write(b"done\n")
        answers.flush()
    sys.stderr.flush()
    os._exit(0)


def answer_call(folder: str | Path) -> None:
    """Run the call in ``folder`` (``CALL``) and write what it returned or raised
    (``OUTCOME``); an outcome that cannot be pickled goes back as a RuntimeError naming it."""
    fn, args = pickle.loads((Path(folder) / jobfiles.CALL).read_bytes())
    try:
        outcome = ("returned", fn(*args))
    except Exception as exc:  # the caller's to handle; SystemExit and the like end the child
        outcome = ("raised", exc)
    try:
        data = pickle.dumps(outcome)
    except Exception as exc:
        data = pickle.dumps(("raised", RuntimeError(f"{type(outcome[1]).__name__}: {outcome[1]} "
                                                    f"(not picklable: {exc})")))
    jobfiles.write(Path(folder) / jobfiles.OUTCOME, data)


def run_call(folder: str, job: Job) -> None:
    """The child's side of a one-off ``call`` job: the call's outcome written, then exit."""
    enter(folder, job)
    answer_call(folder)
    sys.stderr.flush()
    os._exit(0)


if __name__ == "__main__":
    # through the module as its importers know it: one copy of its classes, not a second as __main__
    from longtime.execution.child import main as _main

    _main(sys.argv[1])
