"""Where a run's wall time goes, by phase, recorded only when $LONGTIME_PHASES names a folder.

``benchmarks/bench_main_job.py`` sets it to print a main job's breakdown (compile,
references, integration, metrics, figures, page, idle workers). Each process then appends
one JSON line per finished phase to ``phases-<pid>.jsonl`` in that folder: the phase's name,
its start and end (``time.time()``), its own seconds (the phases nested in it subtracted)
and its own CPU seconds (``cpu``, the process's CPU time, nested phases' subtracted: on a
loaded machine a phase's wall time also counts the time it waited for a core). numba's
compilations are phases of their own, named after the phase they happen in
("compile:integration" is a kernel compiled on a cell's first run,
"compile:stability" one compiled to measure a stability interval), so a compile is never
counted as the work around it. Without the variable ``phase`` records nothing and numba
is not listened to.
"""
from __future__ import annotations

import contextlib
import json
import os
import time
from typing import Iterator

ENV = "LONGTIME_PHASES"
_FOLDER = os.environ.get(ENV) or None
# the open phases of this process, innermost last: [name, start (time.time()), seconds of the
# nested, detail (what it worked on: a cell's "problem x scheme"), CPU start
# (time.process_time()), CPU seconds of the nested]
_STACK: list[list] = []
_OUT = None


def enabled() -> bool:
    return _FOLDER is not None


@contextlib.contextmanager
def phase(name: str, detail: str | None = None) -> Iterator[None]:
    """Count the wall time of the ``with`` block as ``name`` (nothing when not enabled);
    ``detail`` says what it works on, and the compilations inside it inherit it."""
    if _FOLDER is None:
        yield
        return
    _enter(name, detail)
    try:
        yield
    finally:
        _exit()


@contextlib.contextmanager
def compiling() -> Iterator[None]:
    """A compile outside numba (heyoka's LLVM), named as numba's are: "compile:<enclosing phase>"."""
    if _FOLDER is None:
        yield
        return
    _enter_compile(None)
    try:
        yield
    finally:
        _exit()


def since_process_start(name: str) -> None:
    """Record the time from this process's start until now as ``name`` (its interpreter's
    start and imports: a pool worker's start-up), from /proc where there is one."""
    if _FOLDER is None:
        return
    try:
        with open("/proc/self/stat") as f:
            started_ticks = float(f.read().rsplit(")", 1)[1].split()[19])
        with open("/proc/uptime") as f:
            uptime = float(f.read().split()[0])
    except (OSError, IndexError, ValueError):
        return
    now = time.time()
    start = now - (uptime - started_ticks / os.sysconf("SC_CLK_TCK"))
    _write(name, start, now, now - start, cpu=time.process_time())


def _enter(name: str, detail: str | None = None) -> None:
    _STACK.append([name, time.time(), 0.0, detail, time.process_time(), 0.0])


def _enter_compile(function: str | None) -> None:
    """A compile's phase: named after the enclosing phase, its detail the enclosing one's
    (the cell it compiles for) or else the compiled function's name."""
    outer = _STACK[-1] if _STACK else None
    _enter(f"compile:{outer[0] if outer else 'other'}", (outer[3] if outer else None) or function)


def _exit() -> None:
    name, start, nested, detail, cpu_start, nested_cpu = _STACK.pop()
    end, cpu_end = time.time(), time.process_time()
    if _STACK:
        _STACK[-1][2] += end - start
        _STACK[-1][5] += cpu_end - cpu_start
    _write(name, start, end, max(0.0, end - start - nested), detail, max(0.0, cpu_end - cpu_start - nested_cpu))


def _write(name: str, start: float, end: float, own: float, detail: str | None = None,
           cpu: float | None = None) -> None:
    global _OUT
    if _OUT is None:
        os.makedirs(_FOLDER, exist_ok=True)
        _OUT = open(os.path.join(_FOLDER, f"phases-{os.getpid()}.jsonl"), "a", buffering=1)  # a line each
    record = {"pid": os.getpid(), "phase": name, "start": start, "end": end, "s": own}
    if detail:
        record["detail"] = detail
    if cpu is not None:
        record["cpu"] = cpu
    _OUT.write(json.dumps(record) + "\n")


def _listen_to_numba() -> None:
    """numba's compile events as "compile:<enclosing phase>" (the outermost of nested ones)."""
    from numba.core import event

    class Compiles(event.Listener):
        depth = 0

        def on_start(self, ev) -> None:
            if self.depth == 0:
                dispatcher = (ev.data or {}).get("dispatcher")
                _enter_compile(getattr(getattr(dispatcher, "py_func", None), "__qualname__", None))
            self.depth += 1

        def on_end(self, ev) -> None:
            self.depth -= 1
            if self.depth == 0:
                _exit()

    event.register("numba:compile", Compiles())


def read(folder: str) -> list[dict]:
    """Every phase recorded under ``folder`` (all processes)."""
    out = []
    for name in sorted(os.listdir(folder)) if os.path.isdir(folder) else []:
        if name.startswith("phases-") and name.endswith(".jsonl"):
            with open(os.path.join(folder, name)) as f:
                out += [json.loads(line) for line in f if line.endswith("\n")]
    return out


if _FOLDER is not None:
    _listen_to_numba()
