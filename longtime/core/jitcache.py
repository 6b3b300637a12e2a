"""On-disk caching of the compiled loops that factories build as closures.

numba cannot cache a closure (a loop closed over a problem's rhs and a scheme's tableau):
its cache is keyed by source location, so every process recompiles every kernel, about a
second each. ``cacheable`` rewrites such a closure as a small generated module in which
the closure's free variables become module globals (a jitted function is imported by name,
an array is rebuilt from its bytes, a number is a literal), decorated with
``njit(cache=True)``. The module's name is the hash of its text, so equal kernels share
one file and one cache entry, across processes and runs. Anything it cannot freeze (a
free variable holding an arbitrary object) makes it return the closure unchanged: caching
is an optimisation, never a requirement.

A module imports the jitted functions it calls (a problem's rhs, a helper) by name, and
numba's cache of a caller never notices that a callee's source changed. So each module
also carries the ``fingerprint`` of its closure: a digest of the bytecode of every
function reachable from it and of every value it closes over, and of the package
version. Editing any of them (a plugin's rhs, a coefficient, a captured dimension) gives
another module text, hence another module and a fresh compilation: a cached kernel is
never stale. The same fingerprint keys the compiled loops shared within a process
(``longtime.core.kernel_cache.cached_kernel``).
"""
from __future__ import annotations

import functools
import importlib.util
import inspect
import linecache
import math
import os
import sys
import textwrap
import types
import weakref
from typing import Any

import numpy as np
from numba.core.extending import _Intrinsic
from numba.core.registry import CPUDispatcher
from numba.core.types import Type as NumbaType

from longtime.core import cache_guard
from longtime.core.cache import cache_dir, digest, discard, write_atomic
from longtime.core.version import __version__

_DECORATOR_OPTIONS = ("inline", "fastmath", "error_model", "boundscheck")
_MODULES: dict[str, types.ModuleType] = {}
# fingerprints by the object they describe, once a process: a kernel's closure is described
# when its loop is found, again in its generated module's header and in numba's cache key
_FINGERPRINTS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


class Unfreezable(Exception):
    pass


def cacheable(dispatcher):
    """The same kernel as a disk-cacheable module function, or the closure itself."""
    if os.environ.get("LONGTIME_NO_KERNEL_CACHE"):
        return dispatcher
    try:
        module = _load(_generate(dispatcher))
        return getattr(module, dispatcher.py_func.__name__)
    except (Unfreezable, OSError, SyntaxError, TypeError):
        return dispatcher


def _is_module_level(fn) -> bool:
    return "<locals>" not in fn.__qualname__ and getattr(sys.modules.get(fn.__module__), fn.__name__, None) is not None


def _literal(value: Any) -> str:
    if isinstance(value, (bool, np.bool_, type(None))):
        return repr(None if value is None else bool(value))
    if isinstance(value, str):
        return repr(value)
    if isinstance(value, (int, np.integer)):
        return repr(int(value))
    if isinstance(value, (float, np.floating)):
        v = float(value)
        return repr(v) if math.isfinite(v) else f"float('{v}')"
    if isinstance(value, tuple) and all(isinstance(v, (int, float, bool)) for v in value):
        return "(" + "".join(_literal(v) + ", " for v in value) + ")"
    raise Unfreezable(type(value).__name__)


def _binding(name: str, value: Any, imports: set[str]) -> str:
    """One line of the generated module that gives ``name`` the value ``value``."""
    if isinstance(value, types.ModuleType):
        return f"import {value.__name__} as {name}" if value.__name__ != name else f"import {name}"
    if isinstance(value, CPUDispatcher):
        fn = value.py_func
        if _is_module_level(fn):
            return f"from {fn.__module__} import {fn.__name__} as {name}"
        module = _load(_generate(value))  # a closure used by this one gets its own module
        return f"from {module.__name__} import {fn.__name__} as {name}"
    if isinstance(value, np.ndarray):
        imports.add("import numpy as _np")
        a = np.ascontiguousarray(value)
        return (f"{name} = _np.frombuffer(bytes.fromhex('{a.tobytes().hex()}'), "
                f"dtype=_np.dtype('{a.dtype.str}')).reshape({a.shape!r}).copy()")
    return f"{name} = {_literal(value)}"


def _names_used(code: types.CodeType) -> set[str]:
    names = set(code.co_names)
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            names |= _names_used(const)
    return names


def fingerprint(value: Any) -> str:
    """Digest of everything that decides the code numba compiles for ``value`` (a compiled
    closure, usually): the bytecode of every function reachable from it through its closure
    cells and the globals it reads, recursively (the driver, the step, the problem's rhs and
    its helpers), every value they close over (numbers, tuples, arrays by dtype, shape and
    bytes), their compile options and the package version. Equal in every process: no
    ids, addresses or set order go in. Raises Unfreezable for a value it cannot describe
    (an arbitrary object), whose kernel must then not be shared. Computed once per object
    and process: what a compiled function closes over is fixed once it is compiled."""
    try:
        return _FINGERPRINTS[value]
    except (KeyError, TypeError):  # not seen yet, or not an object a weak reference can name
        pass
    chunks: list[bytes | str] = [f"longtime {__version__}"]
    _describe(value, chunks, {})
    found = digest(*chunks)
    try:
        _FINGERPRINTS[value] = found
    except TypeError:
        pass
    return found


def _describe(value: Any, out: list, seen: dict[int, int]) -> None:
    if isinstance(value, CPUDispatcher):
        out.append("jit")
        _describe(tuple(sorted((k, v) for k, v in value.targetoptions.items() if k != "cache")), out, seen)
        value = value.py_func
    if isinstance(value, types.FunctionType):  # a dispatcher's py_func, or a register_jitable
        if id(value) in seen:  # recursion: refer to the first visit by its rank, not its id
            out.append(f"again {seen[id(value)]}")
            return
        seen[id(value)] = len(seen)
        code = value.__code__
        out.append(f"def {value.__module__}.{value.__qualname__}")
        _describe_code(code, out)
        _describe(value.__defaults__, out, seen)
        for name, cell in zip(code.co_freevars, value.__closure__ or ()):
            out.append(f"free {name}")
            try:
                contents = cell.cell_contents
            except ValueError:  # an empty cell
                raise Unfreezable(f"free variable {name} of {value.__qualname__} is unbound") from None
            _describe(contents, out, seen)
        for name in sorted(_names_used(code) - set(code.co_freevars)):
            if name in value.__globals__:
                out.append(f"global {name}")
                _describe(value.__globals__[name], out, seen)
    elif isinstance(value, np.ndarray):
        a = np.ascontiguousarray(value)
        out += [f"array {a.dtype.str} {a.shape}", a.tobytes()]
    elif type(value) is tuple:  # not a namedtuple: its fields' names and order matter too
        out.append(f"tuple {len(value)}")
        for item in value:
            _describe(item, out, seen)
    elif isinstance(value, types.ModuleType):
        out.append(f"module {value.__name__}")
    elif value is None or isinstance(value, (bool, int, float, complex, str, bytes, np.generic)):
        out.append(f"{type(value).__name__} {value!r}")
    elif isinstance(value, (types.BuiltinFunctionType, np.ufunc)) or (
            isinstance(value, type) and value.__module__ in ("builtins", "numpy")):
        out.append(f"builtin {getattr(value, '__module__', None)}.{value.__name__}")
    elif isinstance(value, NumbaType):  # e.g. ``float64`` imported from numba
        out.append(f"numba type {value}")
    elif isinstance(value, _Intrinsic):  # a library's compiled primitive (rocket-fft's r2c)
        module = value._defn.__module__
        out.append(f"intrinsic {module}.{value._name} {_version_of(module)}")
    else:
        raise Unfreezable(type(value).__name__)


@functools.lru_cache(maxsize=None)
def _version_of(module: str) -> str:
    # a distribution named as its package (rocket_fft) is found directly; packages_distributions()
    # scans every installed distribution, a cost every worker process would pay: only as a fallback
    from importlib.metadata import PackageNotFoundError, packages_distributions, version

    top = module.partition(".")[0]
    try:
        return version(top)
    except PackageNotFoundError:
        pass
    try:
        return version(packages_distributions().get(top, [top])[0])
    except PackageNotFoundError:
        return "unknown"


def _describe_code(code: types.CodeType, out: list) -> None:
    signature = (code.co_argcount, code.co_posonlyargcount, code.co_kwonlyargcount, code.co_flags,
                 code.co_names, code.co_varnames, code.co_freevars, code.co_cellvars)
    out += [f"code {len(code.co_code)}", code.co_code, repr(signature)]  # length: bytes may hold \0
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            _describe_code(const, out)
        else:
            out.append(_constant_text(const))


def _constant_text(const: Any) -> str:
    # a frozenset's order follows string hashing, which differs between processes
    if isinstance(const, frozenset):
        return "frozenset(" + ", ".join(sorted(map(_constant_text, const))) + ")"
    if isinstance(const, tuple):
        return "(" + ", ".join(map(_constant_text, const)) + ",)"
    return f"{type(const).__name__} {const!r}"


def _generate(dispatcher) -> str:
    fn = dispatcher.py_func
    if fn.__closure__ is None and _is_module_level(fn):
        raise Unfreezable("already a module-level function")
    body = _function_body(fn.__code__)
    options = {k: v for k, v in dispatcher.targetoptions.items() if k in _DECORATOR_OPTIONS}
    decorator = "@numba.njit(" + ", ".join(["cache=True"] + [f"{k}={_literal(v)}" for k, v in options.items()]) + ")"

    imports: set[str] = {"import numba"}
    bindings = []
    free = dict(zip(fn.__code__.co_freevars, (c.cell_contents for c in fn.__closure__ or ())))
    for name, value in sorted(free.items()):
        bindings.append(_binding(name, value, imports))
    for name in sorted(_names_used(fn.__code__) - set(free)):
        if name in fn.__globals__:
            bindings.append(_binding(name, fn.__globals__[name], imports))
    # the fingerprint names the module after the code of everything it imports, too
    header = (f"# generated by longtime.core.jitcache from {fn.__module__}.{fn.__qualname__}\n"
              f"# fingerprint {fingerprint(dispatcher)}\n")
    return header + "\n".join(sorted(imports) + bindings) + f"\n\n\n{decorator}\n{body}\n"


@functools.lru_cache(maxsize=None)
def _function_body(code: types.CodeType) -> str:
    """The source of the function whose code is ``code``, from its ``def`` line, checked
    against the code; once per code object and process (every closure a factory makes
    shares its code, and reading a function's source tokenises its file)."""
    linecache.checkcache(code.co_filename)
    source = textwrap.dedent(inspect.getsource(code))
    lines = source.splitlines()
    start = next(i for i, line in enumerate(lines) if line.lstrip().startswith("def "))
    body = "\n".join(lines[start:])
    _check_same_function(code, body)
    return body


def _check_same_function(old: types.CodeType, body: str) -> None:
    """The source text must be the running function's: a file edited after import (or a
    source lookup that lands on another function) would otherwise freeze the wrong code."""
    module_code = compile(body, "<kernel>", "exec")
    new = next((c for c in module_code.co_consts if isinstance(c, types.CodeType)), None)
    if (
        new is None
        or new.co_name != old.co_name
        or new.co_argcount != old.co_argcount
        or new.co_varnames != old.co_varnames
        or set(new.co_names) != set(old.co_names) | set(old.co_freevars)
        or [c for c in new.co_consts if not isinstance(c, types.CodeType)]
        != [c for c in old.co_consts if not isinstance(c, types.CodeType)]
    ):
        raise Unfreezable(f"source of {getattr(old, 'co_qualname', old.co_name)} does not match its code")


def _load(text: str) -> types.ModuleType:
    """The generated module of ``text``, named after its digest. The file on disk is used
    only when its bytes are exactly ``text`` (anything else, a truncated or corrupt file,
    is discarded with a warning and written again); a compiled ``.pyc`` of it that Python
    cannot load is discarded the same way."""
    name = "longtime_kernel_" + digest(text)
    module = _MODULES.get(name) or sys.modules.get(name)
    if module is None:
        path = cache_dir("kernels") / f"{name}.py"
        data = text.encode()
        try:
            found = path.read_bytes()
        except FileNotFoundError:
            found = None
        if found is not None and found != data:
            discard(path, "kernel", f"its text is not the generated kernel {name}")
        if found != data:
            write_atomic(path, data)
        try:
            module = _import(name, path)
        except Exception as exc:  # a .pyc beside it that cannot be loaded (bad marshal data...)
            pyc = importlib.util.cache_from_source(str(path))
            if not os.path.exists(pyc):
                raise
            discard(pyc, "kernel bytecode", exc)
            module = _import(name, path)
        _MODULES[name] = module
    return module


def _import(name: str, path) -> types.ModuleType:
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[name]
        raise
    return module


def _cache_key_extra(func) -> tuple:
    """What numba's cache index adds to a function's key (cache_guard): its fingerprint."""
    try:
        return (fingerprint(func),)
    except (Unfreezable, ImportError):  # nothing to add (an object it cannot describe)
        return ()


cache_guard.install(_cache_key_extra)  # a corrupt numba cache file is rebuilt, not fatal
