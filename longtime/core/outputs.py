"""stdout carries only the contract (the rows, the report, JSON); whatever else writes there
goes to stderr.

``contract_stdout`` (around a command) points file descriptor 1 at stderr and gives
``sys.stdout`` a stream on a duplicate of the real stdout: what a plugin's compiled code
writes to fd 1 (printf), and what worker processes started meanwhile print (they inherit
fd 1), reaches stderr, while the command's own ``print`` reaches stdout. ``to_stderr``
(around the functions that run plugin code in this process: loading, building, running a
cell) sends Python-level output there too (``print``, and numba's ``print``, which writes
through ``sys.stdout``).
"""
from __future__ import annotations

import contextlib
import functools
import io
import os
import sys
from typing import Callable, Iterator, TypeVar

F = TypeVar("F", bound=Callable)


def _flush_c_stdio() -> None:
    """Flush the C library's stdio buffers (a compiled printf's text waits there)."""
    try:
        import ctypes

        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError):
        pass


@contextlib.contextmanager
def contract_stdout() -> Iterator[None]:
    """Within: fd 1 is stderr; ``sys.stdout`` writes to the real stdout. Does nothing when
    ``sys.stdout`` is not fd 1 (a test's capture, an embedding program's stream)."""
    try:
        fd = sys.stdout.fileno()
    except (AttributeError, OSError, ValueError):
        fd = None
    if fd != 1:
        yield
        return
    real = sys.stdout
    real.flush()
    _flush_c_stdio()
    saved = os.dup(1)
    os.dup2(2, 1)
    sys.stdout = io.TextIOWrapper(io.FileIO(saved, "w", closefd=False), encoding=real.encoding,
                                  errors=real.errors, line_buffering=real.line_buffering)
    try:
        yield
    finally:
        with contextlib.suppress(Exception):
            sys.stdout.flush()
        _flush_c_stdio()
        os.dup2(saved, 1)
        os.close(saved)
        sys.stdout = real


def to_stderr(fn: F) -> F:
    """``fn`` with Python's stdout sent to stderr while it runs (it runs plugin code)."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        with contextlib.redirect_stdout(sys.stderr):
            return fn(*args, **kwargs)

    return wrapper  # type: ignore[return-value]
