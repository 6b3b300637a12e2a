"""numba's on-disk cache, verified before it is trusted: an index or data file that cannot
be read (truncated, corrupt) is deleted with a warning naming it, and the function is
compiled afresh, instead of failing the same way on every rerun; and an entry compiled
against other code (a callee in another file that changed since) is never loaded.

numba reads its cache in ``IndexDataCacheFile._load_index`` / ``_load_data`` and lets an
unpickling error through; ``install`` wraps both, and extends ``Cache._index_key``
(idempotent, no compilation). Imported by longtime.jitcache, so it is in place before any
kernel or problem function is compiled.
"""
from __future__ import annotations

import weakref

from numba.core import caching

from .cache import discard

_FILE = caching.IndexDataCacheFile


def _discard(path: str, exc: BaseException) -> None:
    discard(path, "numba", exc)


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

    # numba keys an entry by the function's own bytecode, and drops the index only when the
    # function's own file changes: a callee in another module (or a constant imported from
    # one) that changed would still load the old machine code. The key also gets the
    # function's fingerprint (longtime.jitcache): the bytecode of everything it reaches.
    index_key = caching.Cache._index_key
    # a function's fingerprint, once per process (numba asks on every load and save)
    known: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()

    def _index_key(self, sig, codegen):
        key = index_key(self, sig, codegen)
        from .jitcache import Unfreezable, fingerprint

        func = self._py_func
        if func not in known:
            try:
                known[func] = (fingerprint(func),)
            except (Unfreezable, ImportError):  # nothing to add (an object it cannot describe)
                known[func] = ()
        return (*key, *known[func])

    caching.Cache._index_key = _index_key


install()
