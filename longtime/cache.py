"""Where the suite keeps files between runs: $LONGTIME_CACHE_DIR (default ~/.cache/longtime).

Folders: ``kernels`` holds the generated modules of compiled loops (``longtime.jitcache``)
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


def digest(*chunks: bytes | str) -> str:
    h = hashlib.sha256()
    for c in chunks:
        h.update(c.encode() if isinstance(c, str) else c)
        h.update(b"\0")
    return h.hexdigest()[:32]
