"""numba's on-disk cache, verified before it is trusted: an index or data file that cannot
be read (truncated, corrupt) is deleted with a warning naming it, and the function is
compiled afresh, instead of failing the same way on every rerun.

numba reads its cache in ``IndexDataCacheFile._load_index`` / ``_load_data`` and lets an
unpickling error through; ``install`` wraps both (idempotent, no compilation). Imported by
longtime.jitcache, so it is in place before any kernel or problem function is compiled.
"""
from __future__ import annotations

import os
import warnings

from numba.core import caching

_FILE = caching.IndexDataCacheFile


def _discard(path: str, exc: BaseException) -> None:
    warnings.warn(f"discarding the unreadable numba cache file {path}: {exc!r}", stacklevel=3)
    try:
        os.unlink(path)
    except OSError:
        pass


def install() -> None:
    if getattr(_FILE, "_longtime_guarded", False):
        return
    load_index, load_data = _FILE._load_index, _FILE._load_data

    def _load_index(self):
        try:
            return load_index(self)
        except Exception as exc:  # UnpicklingError, EOFError, ValueError...: a miss, not a failure
            _discard(self._index_path, exc)
            return {}

    def _load_data(self, name):
        try:
            return load_data(self, name)
        except OSError:
            raise
        except Exception as exc:
            _discard(self._data_path(name), exc)
            raise OSError(f"unreadable cache file {name}") from exc  # numba's load: a miss

    _FILE._load_index, _FILE._load_data = _load_index, _load_data
    _FILE._longtime_guarded = True


install()
