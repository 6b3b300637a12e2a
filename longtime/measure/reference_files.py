"""A reference's files on disk (longtime.measure.reference): the key of a problem's file (all
that decides its content), and each file written whole with its checksum and read only where
the checksum holds."""
from __future__ import annotations

import hashlib
import io
from pathlib import Path
from typing import Any, Callable

import numpy as np

from longtime.core import heyoka_build
from longtime.core.cache import cache_dir, digest, discard, write_atomic
from longtime.core.problem import Problem


def problem_chunks(problem: Problem) -> tuple[str | bytes, ...]:
    """What identifies a problem's trajectory in a key: name and settings, initial state, t0
    and kernel parameters."""
    return problem.identity(), problem.u0.tobytes(), repr(problem.t0), problem.params.tobytes()


def cache_path(problem: Problem, *parts: str | bytes, suffix: str = ".npz") -> Path:
    """The cache file of ``parts`` for ``problem``. Its key covers all that decides the
    content: the problem (name, settings, initial state, t0, kernel parameters), its ODE as
    heyoka reads it (an edited right-hand side or coefficient is another file), ``parts``,
    the code mode of the double run and heyoka's version."""
    import heyoka as hy

    ode = "" if problem.heyoka_system is None else repr([str(e) for e in problem.heyoka_system()[1]])
    # compact and straight-line code round differently: the double run's mode is part of the key
    mode = "compact" if heyoka_build.compact_mode(problem, np.float64, reference=True) else "straight-line"
    key = digest(*problem_chunks(problem), ode, *parts, mode, hy.__version__)
    return cache_dir("reference") / f"{problem.name}-{key}{suffix}"


# every cache file ends with this and the SHA-256 (hex) of the bytes that precede it; np.load
# reads an .npy or .npz up to its own end, so the trailer is invisible to it
_TRAILER = b"\nlongtime-sha256:"


def load_cached(path: Path, read: Callable[[], Any]) -> Any:
    """``read()`` of a cache file, or None when there is none. The file is trusted only when
    its bytes match the checksum ``save_cached`` appended; one that does not (truncated, corrupt,
    written without it) or that ``read`` rejects is deleted with a warning naming it, so it
    is recomputed instead of failing, or being believed, on every rerun."""
    if not path.exists():
        return None
    try:
        data = path.read_bytes()
        body, mark, checksum = data.rpartition(_TRAILER)
        if not mark:
            raise ValueError("no checksum at its end")
        if hashlib.sha256(body).hexdigest().encode() != checksum:
            raise ValueError("its checksum does not match its contents")
        return read()
    except Exception as exc:  # np.load raises ValueError, OSError, EOFError, BadZipFile, KeyError...
        discard(path, "reference", exc)
        return None


def save_cached(path: Path, array: np.ndarray | None = None, **arrays: np.ndarray) -> None:
    """Write the file with its checksum, atomically: workers that compute the same
    reference at once both write whole files."""
    buffer = io.BytesIO()
    if array is not None:
        np.save(buffer, array)
    else:
        np.savez(buffer, **arrays)
    body = buffer.getvalue()
    write_atomic(path, body + _TRAILER + hashlib.sha256(body).hexdigest().encode())
