"""numba's on-disk cache, verified before it is trusted: an index or data file that cannot
be read (truncated, corrupt) is deleted with a warning naming it, and the function is
compiled afresh, instead of failing the same way on every rerun; and an entry compiled
against other code (a callee in another file that changed since) is never loaded.

numba reads its cache in ``IndexDataCacheFile._load_index`` / ``_load_data`` and lets an
unpickling error through; ``install`` wraps both, and extends ``Cache._index_key`` with
what a key function it is given adds (idempotent, no compilation). longtime.core.jitcache
installs it with the fingerprint when it is imported, so it is in place before any kernel
or problem function is compiled.
"""
from __future__ import annotations

import weakref
from typing import Any, Callable

from numba.core import caching

from longtime.core.cache import discard, no_space, skip_cache

_FILE = caching.IndexDataCacheFile


def _discard(path: str, exc: BaseException) -> None:
    discard(path, "numba", exc)


def install(extra_key: Callable[[Any], tuple]) -> None:
    """Guard numba's cache files; ``extra_key(py_func)`` is added to every index key."""
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

    # numba raises when its cache folder has no space left for a compiled function; the
    # function is compiled and runs all the same: a warning, and it stays uncached
    save_overload = caching.Cache.save_overload

    def _save_overload(self, sig, data):
        try:
            save_overload(self, sig, data)
        except OSError as exc:
            if not no_space(exc):
                raise
            from numba.core import config

            numba_dir = bool(config.CACHE_DIR)  # one warning for numba's whole cache folder
            skip_cache(config.CACHE_DIR or self._cache_path, exc,
                       "NUMBA_CACHE_DIR" if numba_dir else "LONGTIME_CACHE_DIR")

    caching.Cache.save_overload = _save_overload

    # numba keys an entry by the function's own bytecode, and drops the index only when the
    # function's own file changes: a callee in another module (or a constant imported from
    # one) that changed would still load the old machine code. The key also gets the
    # function's fingerprint (``extra_key``): the bytecode of everything it reaches.
    index_key = caching.Cache._index_key
    # a function's extra key, once per process (numba asks on every load and save)
    known: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()

    def _index_key(self, sig, codegen):
        key = index_key(self, sig, codegen)
        func = self._py_func
        if func not in known:
            known[func] = extra_key(func)
        return (*key, *known[func])

    caching.Cache._index_key = _index_key
