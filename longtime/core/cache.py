"""Where the suite keeps files between runs: $LONGTIME_CACHE_DIR (default ~/.cache/longtime).

Folders: ``kernels`` holds the generated modules of compiled loops (``longtime.core.jitcache``)
and, in their ``__pycache__``, numba's cache of them (in $NUMBA_CACHE_DIR instead when that
is set); ``reference`` holds the heyoka reference solutions and the exact solutions on large
grids. Everything there is rebuilt on demand: ``longtime cache info`` shows the folders,
``longtime cache clear`` empties them. LONGTIME_NO_KERNEL_CACHE=1 turns the kernel cache off
(every process compiles its kernels from the closures; nothing is written to ``kernels``).
"""
from __future__ import annotations

import errno
import hashlib
import os
import warnings
from pathlib import Path

from longtime.core import files

# a write that failed for want of space (a full disk, a quota): the place, not the data, is at fault
NO_SPACE_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT})
_warned: set[str] = set()


def no_space(exc: BaseException | None) -> bool:
    """Whether ``exc`` (or an exception it was raised from) is a write that found no space."""
    seen = 0
    while exc is not None and seen < 8:
        if isinstance(exc, OSError) and exc.errno in NO_SPACE_ERRNOS:
            return True
        exc, seen = exc.__cause__ or exc.__context__, seen + 1
    return False


def skip_cache(where: Path | str, exc: OSError, variable: str = "LONGTIME_CACHE_DIR") -> None:
    """A cache write into the folder ``where`` that found no space: a warning (once per
    folder and process), and the run goes on without caching it, as numba does with a cache
    folder it cannot write."""
    folder = str(where)
    if folder not in _warned:
        _warned.add(folder)
        warnings.warn(f"cannot cache in {folder}: {exc.strerror or exc}; running without caching "
                      f"(free space there, or set {variable} elsewhere)", stacklevel=3)


def cache_root() -> Path:
    """The cache folder, not created."""
    return Path(os.environ.get("LONGTIME_CACHE_DIR") or Path.home() / ".cache" / "longtime")


def cache_dir(*parts: str) -> Path:
    """The cache folder ``parts``, created; on a full disk it is only named (reads find
    nothing there, writes are skipped with a warning)."""
    path = cache_root().joinpath(*parts)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        if not no_space(exc):
            raise
        skip_cache(path, exc)
    return path


def probe_folder(folder: Path) -> None:
    """Create ``folder`` (and its parents) and a file in it, then remove the file: raises the
    OSError of a folder that cannot be written (a file, read only, under a file, a full disk).
    Trying, rather than reading permission bits, holds for root too."""
    import tempfile

    if folder.exists() and not folder.is_dir():
        raise NotADirectoryError(0, "it is not a folder")
    folder.mkdir(parents=True, exist_ok=True)
    fd, probe = tempfile.mkstemp(dir=folder, prefix=".probe-")
    os.close(fd)
    os.unlink(probe)


def check_cache_root() -> None:
    """Refuse, before anything runs, a cache folder that cannot be used (a file, a read-only
    folder, a path under a file): every cell would fail on its own otherwise."""
    from longtime.core.params import InputError

    root = cache_root()
    try:
        probe_folder(root)
    except OSError as exc:
        source = "$LONGTIME_CACHE_DIR" if os.environ.get("LONGTIME_CACHE_DIR") else "the default cache folder"
        raise InputError(f"cache folder {root} ({source}) cannot be used: {exc.strerror or exc}; "
                         f"set LONGTIME_CACHE_DIR to a writable folder") from None


def digest(*chunks: bytes | str) -> str:
    h = hashlib.sha256()
    for c in chunks:
        h.update(c.encode() if isinstance(c, str) else c)
        h.update(b"\0")
    return h.hexdigest()[:32]


def write_atomic(path: Path, data: bytes) -> bool:
    """Write the cache file ``path`` whole or not at all (a temporary file renamed over it):
    a reader never sees a half-written file, and processes writing the same file at once each
    write whole. On a full disk nothing is written (``skip_cache``): returns False."""
    try:
        files.write_atomic(path, data)
    except OSError as exc:
        if not no_space(exc):
            raise
        skip_cache(path.parent, exc)
        return False
    return True


def discard(path: Path | str, what: str, exc: BaseException | str) -> None:
    """A cache file that cannot be trusted (unreadable, corrupt, not what it should hold):
    a warning naming it, and the file deleted, so it is rebuilt instead of failing (or being
    believed) on every run."""
    import warnings

    reason = exc if isinstance(exc, str) else repr(exc)
    warnings.warn(f"discarding the unreadable {what} cache file {path}: {reason}", stacklevel=3)
    try:
        os.unlink(path)
    except OSError:
        pass
