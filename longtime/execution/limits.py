"""Hard limits of a cell: time and memory, whatever the cell is doing.

``--time-limit`` is a soft limit: the shared drivers stop the integration between chunks of
compiled steps and the row keeps what it reached. A cell stuck where no driver looks (a
compiled step that never returns, a plugin's Python, the metrics, the reference) is ended
from outside: cells run in worker processes, each writes a marker file when it starts a
cell (``running-PID``, see ``batches.run_batch`` and ``jobfiles``), and a ``Watchdog`` thread in the parent
(``resident.Resident``'s) kills a worker whose cell has run past its hard limit, ``time_limit + GRACE_S +
GRACE_SHARE * time_limit`` (``hard_limit``), and records a ``timeout`` row for that cell. A cell's
time limit is the job's or the cell's own (``Cell.time_limit``: the default matrix's budget gives
the library peers theirs), the tighter (``cell_limit``). A run stops itself besides at the
bounds of its cell (``run_bounds``: its chain's CPU bound, its pace), and ``stopped_message``
says which stopped it.

Memory: each worker runs under ``RLIMIT_DATA`` (its heap and anonymous mappings), by default
``MEMORY_SHARE`` of the machine's memory (``--memory-limit`` changes it): an allocation
past it raises ``MemoryError`` in that cell (a ``failed`` row saying "memory limit") instead
of inviting the kernel's OOM killer into the whole matrix.
"""
from __future__ import annotations

import argparse
import contextlib
import json
import os
import signal
import threading
import time
from pathlib import Path
from typing import Any, Callable

from longtime.core.status import BOUNDED, MEMORY_LIMIT, PACED  # how a stopped cell's message begins
from longtime.execution import jobfiles

# the hard limit of a cell: its --time-limit, plus this many seconds, plus this share of it
GRACE_S = 10.0
GRACE_SHARE = 0.1
# a cell may use this share of the machine's memory unless --memory-limit says otherwise
MEMORY_SHARE = 0.5
# the smallest --memory-limit taken: no worker process (Python, numpy, numba) starts in less,
# so a smaller limit (1e-12 GiB, 1e-300 %, which round to 0 bytes: no limit) is a mistake
MIN_MEMORY_LIMIT = 2**20
# the largest: beyond any machine's address space (a larger number is a typo, not a limit)
MAX_MEMORY_LIMIT = 2**60
POLL_S = 0.1


def hard_limit(time_limit: float | None) -> float | None:
    """Seconds after which a cell's process is killed (None: never)."""
    if not time_limit:
        return None
    return time_limit + GRACE_S + GRACE_SHARE * time_limit


def grace(time_limit: float) -> float:
    return GRACE_S + GRACE_SHARE * time_limit


def cell_limit(time_limit: float | None, cell: dict[str, Any]) -> float | None:
    """The time limit ``cell`` (a ``Cell.to_dict``) runs under: the job's ``time_limit`` or the
    cell's own, the tighter (None: neither)."""
    limits = [float(x) for x in (time_limit, cell.get("time_limit")) if x]
    return min(limits) if limits else None


def timeout_message(time_limit: float | None, elapsed: float, cell: dict[str, Any] | None = None) -> str:
    """The message of a cell whose process was killed past the hard limit of its time limit
    (``cell_limit`` of the job's ``time_limit`` and ``cell``'s own) after ``elapsed`` seconds."""
    limit = cell_limit(time_limit, cell or {})
    own = bool(cell) and limit != time_limit
    which = "its own time limit" if own else "--time-limit"
    return (f"cell exceeded its hard time limit of {hard_limit(limit):g} s ({which} {limit:g} s "
            f"+ grace {grace(limit):g} s) where the integration could not stop itself; "
            f"its process was killed after {elapsed:.1f} s")


# a run of a library's chain under a CPU bound (``Cell.cpu_bound``: ``Cell.bound`` times the
# CPU seconds of a setting of its library that keeps the target) is judged on its pace from
# those CPU seconds on, and stops where its pace puts its end past this many times its bound
# (8 times that setting's CPU): it has then spent that setting's CPU seconds with less than
# an eighth of its span covered, so it cannot be its library's cheapest, as a run that
# reaches the bound cannot (docs/performance.md: every such run of a main job, run to its
# end, took at least 4.9 times that setting's CPU); a run that reaches its bound stops there
CHAIN_PACE = 4.0


def run_bounds(cell: Any, integrator: Any) -> dict[str, float | None]:
    """The bounds a ``Cell``'s run stops at besides its time limit, for a scheme that stops at
    them (``stops_at_cpu_bound``; a plugin's ``integrate`` may not know them): its chain's CPU
    bound, and its pace bound and the CPU seconds after which its pace is judged
    (``pace_bounds``)."""
    if not integrator.stops_at_cpu_bound:
        return {}
    pace, after, _ = pace_bounds(cell)
    return {"cpu_bound": cell.cpu_bound, "pace_bound": pace, "pace_after": after}


def pace_bounds(cell: Any) -> tuple[float | None, float | None, bool]:
    """(pace bound, CPU seconds after which the pace is judged (None: the default), whether
    the chain's bound set them): ``Cell.pace`` times the cell's own time limit (a setting
    estimated too slow), or, tighter, CHAIN_PACE times its chain's CPU bound, judged from
    the CPU seconds of the setting that kept the target (the bound over ``Cell.bound``)."""
    pace = cell.pace * cell.time_limit if cell.pace and cell.time_limit else None
    if cell.cpu_bound is not None and cell.bound and (pace is None or CHAIN_PACE * cell.cpu_bound < pace):
        return CHAIN_PACE * cell.cpu_bound, cell.cpu_bound / cell.bound, True
    return pace, None, False


def stopped_message(cell: Any, t_end: float, traj: Any, time_limit: float | None, own: bool) -> str:
    """A stopped run's message: at its chain's CPU bound where its own CPU seconds reached it
    (never said of a run the wall clock stopped) or its pace put its end past CHAIN_PACE
    times it, on its pace, else at its time limit (``own``: the ``Cell``'s, else the job's)."""
    if cell.cpu_bound is not None and traj.cpu_s >= cell.cpu_bound:
        reached = f"t={float(traj.t[-1]):.6g} of {t_end:g} reached in {traj.cpu_s:.3g} s CPU"
        return f"{BOUNDED} {cell.bound_reason} ({reached})"
    if traj.message.startswith(PACED):
        if pace_bounds(cell)[2]:
            return (f"{BOUNDED} {cell.bound_reason} (on its pace:{traj.message[len(PACED):]}, "
                    f"{CHAIN_PACE:g} x the bound)")
        return f"{traj.message} ({cell.pace:g} x the cell's time limit of {cell.time_limit:g} s {cell.limit_reason})"
    limit = (f"{time_limit:g} s: the default matrix's time limit {cell.limit_reason or 'of this cell'}"
             if own else f"cell time limit {time_limit:g} s: --time-limit")
    return f"{traj.message} ({limit})"


def machine_memory() -> int:
    """Bytes of physical memory (0 where the platform does not say)."""
    try:
        return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (AttributeError, ValueError, OSError):
        return 0


def default_memory_limit() -> int | None:
    total = machine_memory()
    return int(MEMORY_SHARE * total) if total else None


def memory_argument(text: str) -> int | None:
    """--memory-limit: GiB (``8``, ``0.5``), or a share of the machine's memory (``25%``);
    0: no limit. Returns bytes (None: no limit)."""
    raw = text.strip()
    try:
        value = float(raw[:-1]) if raw.endswith("%") else float(raw)
    except ValueError:
        value = float("nan")
    if not (value >= 0 and value < float("inf")) or (raw.endswith("%") and value > 100):
        raise argparse.ArgumentTypeError(f"--memory-limit takes GiB (e.g. 8 or 0.5) or a share of the machine's "
                                         f"memory (e.g. 25%), 0 for none; got {text!r}")
    if value == 0:
        return None
    if raw.endswith("%"):
        total = machine_memory()
        if not total:
            raise argparse.ArgumentTypeError(f"--memory-limit {text}: the machine's memory is unknown here; give GiB")
        nbytes = total * value / 100
    else:
        nbytes = value * 2**30
    if not nbytes >= MIN_MEMORY_LIMIT:
        raise argparse.ArgumentTypeError(f"--memory-limit {text} is {nbytes:.3g} bytes, below the smallest limit "
                                         f"taken, 1 MiB (no worker process starts in it); give GiB (e.g. 8), "
                                         f"or 0 for no limit")
    if not nbytes <= MAX_MEMORY_LIMIT:
        raise argparse.ArgumentTypeError(f"--memory-limit {text} is beyond any machine's memory "
                                         f"({gib(MAX_MEMORY_LIMIT)}); give GiB (e.g. 8), or 0 for no limit")
    return int(nbytes)


def gib(nbytes: float) -> str:
    return f"{nbytes / 2**30:.3g} GiB"


def set_memory_limit(nbytes: int | None) -> None:
    """Limit this process's data (heap and anonymous mappings) to ``nbytes`` (None: leave it)."""
    if not nbytes:
        return
    try:
        import resource

        _, hard = resource.getrlimit(resource.RLIMIT_DATA)
        soft = nbytes if hard == resource.RLIM_INFINITY else min(nbytes, hard)
        resource.setrlimit(resource.RLIMIT_DATA, (soft, hard))
    except (ImportError, ValueError, OSError):  # not on this platform: no limit
        pass


@contextlib.contextmanager
def memory_limited(nbytes: int | None):
    """This process under ``nbytes`` of data (RLIMIT_DATA) while the block runs, then its
    earlier limit again: the serial executor and ``longtime.solve`` run cells in the user's
    own process (a notebook's, a script's), which keeps its limit afterwards."""
    if not nbytes:
        yield
        return
    try:
        import resource

        before = resource.getrlimit(resource.RLIMIT_DATA)
    except (ImportError, ValueError, OSError):
        yield
        return
    set_memory_limit(nbytes)
    try:
        yield
    finally:
        try:
            resource.setrlimit(resource.RLIMIT_DATA, before)
        except (ValueError, OSError):
            pass


def memory_argument_api(value) -> int | None:
    """``memory_limit=`` of the API as ``--memory-limit`` takes it: GiB (a number), a share of
    the machine's memory ("25%"), 0 or None for none. Returns bytes (None: no limit)."""
    from longtime.core.params import InputError, check_number

    if value is None:
        return None
    if isinstance(value, str) and value.strip().endswith("%"):
        try:
            return memory_argument(value)
        except argparse.ArgumentTypeError:
            raise InputError(f"memory_limit={value!r} is not valid: expected GiB (a number >= 0), a share of the "
                             f"machine's memory (e.g. '25%') or None") from None
    check_number("memory_limit", value, minimum=0)
    return int(value * 2**30) or None


def hit_memory_limit(row: dict) -> bool:
    """Whether ``row`` is of a cell stopped by its memory limit (``memory_message``)."""
    return str(row.get("message") or "").startswith(MEMORY_LIMIT)


def memory_message(exc: BaseException) -> str:
    """The message of a cell that ran out of memory: the limit it ran into, when there is one."""
    limit = None
    try:
        import resource

        soft, _ = resource.getrlimit(resource.RLIMIT_DATA)
        limit = None if soft == resource.RLIM_INFINITY else soft
    except (ImportError, ValueError, OSError):
        pass
    what = str(exc).strip() or type(exc).__name__
    if limit is None:
        return f"out of memory: {what}"
    return f"{MEMORY_LIMIT}: the cell may use {gib(limit)} (--memory-limit); {what}"


def die_with_parent(parent: int) -> None:
    """Ask Linux to kill this process when its parent dies (a SIGKILLed matrix leaves no
    orphan computing); elsewhere a no-op. Exits at once if the parent is already gone."""
    kill_with_parent()
    if os.getppid() != parent:
        os._exit(1)


def kill_with_parent() -> None:
    """A ``preexec_fn`` for ``subprocess.Popen``: the child (and the program it runs, such as
    Valgrind) gets SIGKILL when the thread that started it ends (Linux; elsewhere a no-op),
    from its very start, before its interpreter has read a line."""
    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


class PastLimit(RuntimeError):
    """A call into a plugin (``call_limited``) that did not return within its hard limit."""


def call_limited(func: Callable[..., Any], *args: Any, time_limit: float | None,
                 memory_limit: int | None = None) -> Any:
    """``func(*args)`` under the limits of a cell: in a forked child of this process (it has
    this process's classes and compiled kernels) under ``memory_limit``, killed past
    ``hard_limit(time_limit)`` (``PastLimit``); what it returns or raises comes back here
    (pickled). Where the platform cannot fork, or without a time limit, it runs here.
    For calls whose effects are only their result or their exception (checks)."""
    import pickle
    import select

    limit = hard_limit(time_limit)
    if limit is None or not hasattr(os, "fork"):
        return func(*args)
    # a fork, not a child of longtime.execution.child: the calls take live objects (a
    # plugin's problem and scheme instances, of classes that may be defined only in this
    # process, as a notebook's are) that a fresh interpreter cannot unpickle, and the forked
    # child reuses the kernels this process has compiled for them. The fork runs only the
    # call and exits (os._exit): no thread of this process runs in it.
    read_end, write_end = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: never returns into the caller's code
        try:
            os.close(read_end)
            kill_with_parent()
            set_memory_limit(memory_limit)
            try:
                outcome = ("returned", func(*args))
            except BaseException as exc:  # noqa: BLE001 (every outcome goes back to the parent)
                outcome = ("raised", exc)
            try:
                data = pickle.dumps(outcome)
            except Exception as exc:  # an unpicklable result or exception: its text goes back
                data = pickle.dumps(("raised", RuntimeError(f"{type(outcome[1]).__name__}: {outcome[1]} "
                                                            f"(not picklable: {exc})")))
            view = memoryview(data)
            while view:
                view = view[os.write(write_end, view):]
        finally:
            os._exit(0)
    os.close(write_end)
    chunks, deadline, ended = [], time.monotonic() + limit, False
    try:
        while True:
            left = deadline - time.monotonic()
            ready = select.select([read_end], [], [], max(0.0, left))[0] if left > 0 else []
            if not ready:
                raise PastLimit(f"it did not return within {limit:g} s (the hard limit of a cell with a time limit "
                                f"of {time_limit:g} s); it was stopped")
            data = os.read(read_end, 1 << 16)
            if not data:
                ended = True
                break
            chunks.append(data)
    finally:
        os.close(read_end)
        if not ended:  # past the limit, or a stop signal here: the child ends with the call
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
        _, status = os.waitpid(pid, 0)
    if not chunks:
        how = f"killed by signal {-os.waitstatus_to_exitcode(status)}" if os.WIFSIGNALED(status) else \
            f"exited with code {os.waitstatus_to_exitcode(status)}"
        raise PastLimit(f"its process {how} without a result")
    kind, value = pickle.loads(b"".join(chunks))
    if kind == "raised":
        raise value
    return value


class Watchdog:
    """Kills a worker whose cell has run past its hard limit: ``hard_limit`` of the job's
    ``time_limit`` or the cell's own, the tighter (``cell_limit``).

    Workers write ``running-PID`` (the cell, as JSON) into ``folder`` when a cell starts and
    remove it when the cell ends; the file's age is the cell's. Past the limit the watchdog
    claims the marker (renamed to ``killed-PID``: the cell is not taken for one that ended
    its worker), kills the worker and calls ``record(cell_dict, elapsed)``, which gives the
    cell its ``timeout`` row (``resident.Resident``: the batch's other cells go on in a fresh
    worker)."""

    def __init__(self, folder: str | Path, time_limit: float | None,
                 record: Callable[[dict[str, Any], float], None]):
        self.folder, self.time_limit, self.record = Path(folder), time_limit, record
        self.killed = 0
        # the cell in progress, its marker read once: (marker name, its start, its hard limit, the cell)
        self._cell: tuple[str, float, float | None, dict[str, Any]] | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._watch, name="longtime-watchdog", daemon=True)

    def start(self) -> "Watchdog":
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join()

    def __enter__(self) -> "Watchdog":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    def _watch(self) -> None:
        while not self._stop.wait(POLL_S):
            for marker in jobfiles.running_markers(self.folder):
                with contextlib.suppress(OSError, ValueError):
                    self._check(marker)

    def _check(self, marker: Path) -> None:
        started = marker.stat().st_mtime
        if self._cell is None or self._cell[:2] != (marker.name, started):  # a cell begun
            cell = json.loads(marker.read_text())
            self._cell = (marker.name, started, hard_limit(cell_limit(self.time_limit, cell)), cell)
        _, _, limit, cell = self._cell
        elapsed = time.time() - started
        if limit is None or elapsed <= limit:
            return
        pid = jobfiles.marker_pid(marker)
        marker.rename(jobfiles.killed_marker(marker))  # fails when the cell has just ended (its worker removed it)
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.kill(pid, signal.SIGKILL)
        self.killed += 1
        self.record(cell, elapsed)


# how long a process running cells in itself (--executor serial, --time-limit 0) has, after a
# first SIGINT / SIGTERM / SIGHUP, to end on its own (a compiled step never returns to Python,
# where the signal is handled) before it is killed; a second signal kills it at once
SIGNAL_GRACE_S = GRACE_S
# set by the command line (longtime.commands.guard): a command's process ends on a stop signal;
# a Python session (the API, a notebook) that catches KeyboardInterrupt is never killed
RELAY_SIGNALS = {"enabled": False}

_RELAY = r"""
import os, select, signal, sys, time
fd, pid, grace = int(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3])
stops = {int(s) for s in sys.argv[4].split(",")}
seen, deadline = 0, None
while True:
    wait = None if deadline is None else max(0.0, deadline - time.monotonic())
    ready, _, _ = select.select([fd], [], [], wait)
    if not ready:
        os.kill(pid, signal.SIGKILL)
        break
    data = os.read(fd, 64)
    if not data:
        break
    seen += sum(1 for b in data if b in stops)
    if seen >= 2:
        os.kill(pid, signal.SIGKILL)
        break
    if seen and deadline is None:
        deadline = time.monotonic() + grace
"""


@contextlib.contextmanager
def signal_relay(grace: float = SIGNAL_GRACE_S):
    """While cells run in this process: a first SIGINT, SIGTERM or SIGHUP ends it within
    ``grace`` seconds, a second at once, even where a compiled step never returns to Python
    (where Python runs its signal handlers). Python's C-level handler writes each signal's
    number to a wakeup pipe (``signal.set_wakeup_fd``) whatever the main thread is doing; a
    small relay process reads it and, past the grace or at the second signal, kills this
    process (SIGKILL: the store keeps what it committed and knows the cell it was in, as after
    a crash). The relay ends with this process (end of file on the pipe). Only in a command's
    main thread (``RELAY_SIGNALS``); elsewhere a no-op."""
    import subprocess
    import sys

    if not RELAY_SIGNALS["enabled"] or threading.current_thread() is not threading.main_thread():
        yield
        return
    read_end, write_end = os.pipe()
    os.set_blocking(write_end, False)
    try:
        previous = signal.set_wakeup_fd(write_end, warn_on_full_buffer=False)
    except (ValueError, OSError):
        os.close(read_end)
        os.close(write_end)
        yield
        return
    stops = ",".join(str(int(s)) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP))
    try:
        relay = subprocess.Popen([sys.executable, "-S", "-c", _RELAY, str(read_end), str(os.getpid()), str(grace),
                                  stops], pass_fds=(read_end,), stdin=subprocess.DEVNULL,
                                 stdout=subprocess.DEVNULL, start_new_session=True)
    except OSError:
        relay = None
    os.close(read_end)
    try:
        yield
    finally:
        with contextlib.suppress(ValueError, OSError):
            signal.set_wakeup_fd(previous)
        os.close(write_end)  # end of file: the relay exits
        if relay is not None:
            with contextlib.suppress(Exception):
                relay.wait(timeout=2)
