"""Where the suite keeps files between runs: $LONGTIME_CACHE_DIR (default ~/.cache/longtime).

Folders: ``kernels`` holds the generated modules of compiled loops (``longtime.core.jitcache``)
and, in their ``__pycache__``, numba's cache of them (in $NUMBA_CACHE_DIR instead when that
is set); ``reference`` holds the heyoka reference solutions. Everything there is rebuilt
on demand: ``longtime cache info`` shows the folders, ``longtime cache clear`` empties
them. LONGTIME_NO_KERNEL_CACHE=1 turns the kernel cache off (every process compiles its
kernels from the closures; nothing is written to ``kernels``).
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path


def cache_root() -> Path:
    """The cache folder, not created."""
    return Path(os.environ.get("LONGTIME_CACHE_DIR") or Path.home() / ".cache" / "longtime")


def cache_dir(*parts: str) -> Path:
    path = cache_root().joinpath(*parts)
    path.mkdir(parents=True, exist_ok=True)
    return path


def check_cache_root() -> None:
    """Refuse, before anything runs, a cache folder that cannot be used (a file, a read-only
    folder, a path under a file): every cell would fail on its own otherwise. Tried by
    creating the folder and a file in it, so that it holds for root too."""
    import tempfile

    from longtime.core.params import InputError

    root = cache_root()
    try:
        if root.exists() and not root.is_dir():
            raise NotADirectoryError(0, "it is not a folder")
        root.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(dir=root, prefix=".probe-")
        os.close(fd)
        os.unlink(probe)
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


def write_atomic(path: Path, data: bytes) -> None:
    """Write ``path`` whole or not at all (a temporary file renamed over it): a reader never
    sees a half-written file, and processes writing the same file at once each write whole."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_bytes(data)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


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
