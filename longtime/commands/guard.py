"""How a ``longtime`` command ends when it fails or is stopped: one place, one line.

``run_command`` runs a parsed command and turns every way it can end into an exit code and
at most one line on stderr, ``longtime CMD: error: ...`` (the traceback too with the global
``--debug``):

- 0: done; 1: a failure that changing the command does not fix (a cell failed in ``run``,
  a store that cannot be written during a run, a lost Dask scheduler, an unexpected error);
  2: bad input (an ``InputError``); a full disk (``DiskFull``: a temp file, a row file)
  is 1 with the run marked ``interrupted`` and no row stored for the cells it stopped;
- 130, 143, 129: stopped by SIGINT (Ctrl-C), SIGTERM, SIGHUP. SIGTERM and SIGHUP raise
  ``Stopped``, a KeyboardInterrupt, wherever the command is, so they run every cleanup that
  Ctrl-C runs: the pool's workers killed, the run marked ``interrupted``, temp folders
  removed. The message names the run to resume;
- 141: stdout closed by its reader (``longtime list | head``), quietly.
"""
from __future__ import annotations

import argparse
import contextlib
import os
import select
import signal
import sys
import threading
import traceback
from typing import Iterator

from longtime.core.outputs import contract_stdout
from longtime.core.params import InputError
from longtime.execution.dask_executor import ExecutorLost
from longtime.execution.tempdirs import DiskFull

STOP_SIGNALS = (signal.SIGTERM, signal.SIGHUP)


class Stopped(KeyboardInterrupt):
    """SIGTERM or SIGHUP, raised in the main thread like Ctrl-C's KeyboardInterrupt."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


@contextlib.contextmanager
def stop_signals() -> Iterator[None]:
    """SIGTERM and SIGHUP raise ``Stopped`` while the block runs (in the main thread; a signal
    the parent set to be ignored, as ``nohup`` does for SIGHUP, stays ignored). A second
    signal does not cut the cleanup the first one started; where cells run in this process,
    a process stuck in compiled code is ended by limits.signal_relay (the first signal after
    its grace, a second at once)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    fired: list[int] = []

    def handler(signum, frame):
        if not fired:
            fired.append(signum)
            raise Stopped(signum)

    from longtime.execution.limits import RELAY_SIGNALS

    previous = {}
    for sig in STOP_SIGNALS:
        if signal.getsignal(sig) == signal.SIG_DFL:
            previous[sig] = signal.signal(sig, handler)
    relayed = RELAY_SIGNALS["enabled"]
    RELAY_SIGNALS["enabled"] = True  # cells run in this process: a stop signal ends it (limits.signal_relay)
    try:
        yield
    finally:
        RELAY_SIGNALS["enabled"] = relayed
        for sig, old in previous.items():
            signal.signal(sig, old)


def _resume(path: str, rid: int) -> str:
    """The command that completes run ``rid`` of the store ``path``."""
    from longtime.execution.store import default_path

    return f"`longtime matrix --resume {rid}" + ("" if path == default_path() else f" --db {path}") + "`"


def _resume_hint(what: str) -> str:
    """Where the runs that this command marked interrupted stand, and how to complete them."""
    from longtime.execution.store import INTERRUPTED

    if not INTERRUPTED:
        return ""
    path, rid = INTERRUPTED[-1]
    return f"; run {rid} is marked interrupted: {_resume(path, rid)} {what}"


def _stdout_closed() -> bool:
    """Whether stdout is a pipe whose reader has gone."""
    try:
        poller = select.poll()
        poller.register(sys.stdout.fileno(), select.POLLOUT)
        return any(event & select.POLLERR for _, event in poller.poll(0))
    except (AttributeError, OSError, ValueError):
        return False


class Parser(argparse.ArgumentParser):
    """argparse's parser, its errors one line (``longtime CMD: error: ...``, exit 2) without
    the usage text; ``--help`` gives that."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see `{self.prog} --help`)\n")


def run_command(args: argparse.Namespace) -> int:
    """``args.func(args)``'s exit code, every failure caught here (see the module's doc)."""
    from longtime.execution.store import INTERRUPTED, StoreError

    command, debug = args.command, getattr(args, "debug", False)
    INTERRUPTED.clear()

    def fail(message: str, code: int) -> int:
        if debug:
            traceback.print_exc()
        print(f"longtime {command}: {message}", file=sys.stderr)
        return code

    try:
        with stop_signals(), contract_stdout():  # what plugins print, even compiled, goes to stderr
            code = int(args.func(args) or 0)
            sys.stdout.flush()  # a reader that has gone is found here, not in the exit's flush
            return code
    except InputError as exc:
        return fail(f"error: {exc}", 2)
    except KeyboardInterrupt as exc:  # Ctrl-C, or SIGTERM / SIGHUP (Stopped)
        signum = getattr(exc, "signum", signal.SIGINT)
        hint = _resume_hint("completes it")
        print(f"longtime {command}: interrupted by {signal.Signals(signum).name}"
              + (f": finished cells are in the store{hint}" if hint else ""), file=sys.stderr)
        return 128 + signum
    except ExecutorLost as exc:
        return fail(f"error: {exc}{_resume_hint('runs them (on any executor)')}", 1)
    except DiskFull as exc:  # no row stored for the cell that met it: the run is interrupted
        return fail(f"error: {exc}{_resume_hint('runs the rest once there is space')}", 1)
    except StoreError as exc:
        hint = _resume_hint("completes it")
        if not hint and exc.run_id is not None:  # not even its end could be written: it reads as incomplete
            hint = f"; {_resume(exc.path, exc.run_id)} completes run {exc.run_id} once the store can be written"
        return fail(f"error: {exc}" + (f"; the rows committed before are kept{hint}" if hint else ""), 1)
    except BrokenPipeError:
        if not _stdout_closed():
            return fail(f"error: {_describe(sys.exc_info()[1])}{_debug_hint(debug)}", 1)
        with contextlib.suppress(OSError):  # nothing more reaches it, not even the exit's flush
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 128 + signal.SIGPIPE
    except Exception as exc:
        return fail(f"error: {_describe(exc)}{_debug_hint(debug)}", 1)


def _describe(exc: BaseException | None) -> str:
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__


def _debug_hint(debug: bool) -> str:
    return "" if debug else " (`longtime --debug ...` shows the traceback)"
