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

A child that lives on and runs job after job is ``longtime.execution.resident``'s.
"""
from __future__ import annotations

import importlib
import json
import os
import pickle
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from longtime.core import registry, threads
from longtime.execution import jobfiles, tempdirs
from longtime.execution.cells import Cell, RunSpec
from longtime.execution.limits import (
    die_with_parent,
    kill_with_parent,
    set_memory_limit,
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
    env = threads.single_threaded(env)  # its cells' BLAS on the one core it is given
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
            if not tempdirs.out_of_space(exc):
                raise
            tempdirs.exit_out_of_space(exc, "a worker wrote its files")
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
