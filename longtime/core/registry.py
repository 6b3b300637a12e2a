"""Discovery of problems and schemes through entry points.

Groups ``longtime.problems`` and ``longtime.integrators``. A plugin that fails to import
(or is not a Problem / Integrator subclass) is recorded with its error in ``broken()``;
the others go on.
"""
from __future__ import annotations

import re
import threading
import traceback
from dataclasses import dataclass
from importlib.metadata import entry_points

from longtime.core.contract import NAME_RULE, check_registered, name_error
from longtime.core.integrator import Integrator
from longtime.core.outputs import to_stderr
from longtime.core.params import check_choice, check_choices
from longtime.core.problem import Problem

GROUPS = {"problems": ("longtime.problems", Problem), "integrators": ("longtime.integrators", Integrator)}


@dataclass(frozen=True)
class BrokenPlugin:
    group: str
    name: str
    target: str
    error: str


_loaded: dict[str, dict[str, type]] | None = None
_broken: list[BrokenPlugin] = []
# classes registered from Python for this session (``register``): no entry point, no install
_session: dict[str, dict[str, type]] = {"problems": {}, "integrators": {}}
_PICKLING = threading.Lock()  # session_payload's


@to_stderr  # a plugin's module runs as it loads: its output is not the contract's
def _load() -> dict[str, dict[str, type]]:
    global _loaded
    if _loaded is not None:
        return _loaded
    loaded: dict[str, dict[str, type]] = {}
    _broken.clear()
    for kind, (group, base) in GROUPS.items():
        found: dict[str, type] = {}
        for ep in _without_clashes(kind, entry_points(group=group)):
            if not ep.pattern.match(ep.value):  # e.g. a name with '=': "a=b = mod:Cls" reads as a = "b = mod:Cls"
                _broken.append(BrokenPlugin(group, ep.name, ep.value,
                                            f"entry point '{ep.name} = {ep.value}' is not NAME = module:Class; "
                                            f"{NAME_RULE}"))
                continue
            reason = name_error(kind[:-1].replace("integrator", "scheme"), ep.name)
            if reason:  # never loaded: its name would build file names and fields
                _broken.append(BrokenPlugin(group, ep.name, ep.value, reason))
                continue
            try:
                cls = ep.load()
                if not (isinstance(cls, type) and issubclass(cls, base)):
                    raise TypeError(f"{ep.value} is not a subclass of {base.__module__}.{base.__name__}")
                if not cls.name:
                    cls.name = ep.name
                elif cls.name != ep.name:
                    raise TypeError(f"{ep.value} is named '{cls.name}' but registered as '{ep.name}'")
                check_registered(cls)  # complete: not abstract, every declared attribute set
                found[ep.name] = cls
            except Exception as exc:  # a broken plugin must not take the suite down
                last = traceback.format_exception_only(type(exc), exc)[-1].strip()
                _broken.append(BrokenPlugin(group, ep.name, ep.value, last))
        loaded[kind] = found
    _loaded = loaded
    return loaded


def _dist(ep) -> str:
    return getattr(getattr(ep, "dist", None), "name", None) or "?"


def _without_clashes(kind: str, points) -> list:
    """Entry points by name; a name registered more than once is reported as broken, never
    silently replaced: a built-in keeps its name, a clash between plugins loads none."""
    by_name: dict[str, list] = {}
    for ep in points:
        by_name.setdefault(ep.name, []).append(ep)
    kept = []
    for name in sorted(by_name):
        eps = by_name[name]
        if len({(ep.value, _dist(ep)) for ep in eps}) == 1:  # the same one seen twice (a path twice)
            kept.append(eps[0])
            continue
        builtin = [ep for ep in eps if _dist(ep) == "longtime"]
        if builtin:
            kept.append(builtin[0])
        owners = ", ".join(f"{ep.value} ({_dist(ep)})" for ep in eps)
        for ep in eps:
            if builtin and ep is builtin[0]:
                continue
            why = "the built-in keeps it" if builtin else "none of them is loaded"
            _broken.append(BrokenPlugin(GROUPS[kind][0], name, ep.value,
                                        f"name clash: '{name}' is registered by {owners}; {why}"))
    return kept


def check_names(kind: str, names) -> None:
    """Every name must be a loaded problem/integrator: one error listing every unknown name
    (a broken plugin with its reason)."""
    found = problems() if kind == "problem" else integrators()
    for name in names:
        bad = [b for b in broken() if b.name == name and name not in found]
        if bad:
            from longtime.core.params import InputError

            raise InputError(f"{kind} '{name}' is a broken plugin: {bad[0].error}")
    check_choices(kind, names, found)


def reload() -> None:
    global _loaded
    _loaded = None
    _load()


def kebab(name: str) -> str:
    """'MyForestRuth' -> 'my-forest-ruth': the name of a class registered without one."""
    return re.sub(r"(?<=[a-z0-9])(?=[A-Z])|(?<=[A-Z])(?=[A-Z][a-z])", "-", name).lower().replace("_", "-")


def register(cls: type, name: str | None = None) -> str:
    """Register a Problem or Integrator class defined in Python for this session, under
    ``name`` (default: its ``name``, else its class name in kebab-case), and return the
    name. Cells built from names then find it, in this process and in the process pool's
    workers (``session_payload``). It passes the checks an entry point passes (complete,
    named consistently); a class that breaks the contract, or a name an installed plugin
    or another class holds, raises InputError with a one-line reason. Registering a class
    again under its name (a redefined class in a notebook) replaces the earlier one."""
    from longtime.core.params import InputError

    kind = ("problems" if isinstance(cls, type) and issubclass(cls, Problem) else
            "integrators" if isinstance(cls, type) and issubclass(cls, Integrator) else None)
    if kind is None:
        raise InputError(f"{cls!r} is not a subclass of longtime.Problem or longtime.Integrator")
    own = vars(cls).get("name")  # a name inherited from a registered class is not this class's
    name = name or own or kebab(cls.__name__)
    if not re.fullmatch(r"[a-z0-9]+(-[a-z0-9]+)*", name):
        raise InputError(f"name {name!r}: expected kebab-case (lower-case words joined by '-')")
    if own and own != name:
        raise InputError(f"{cls.__module__}.{cls.__qualname__} is named '{cls.name}' but registered as '{name}'")
    check_registered(cls)  # ContractError: an InputError with the one-line reason
    installed = _load()[kind].get(name)
    if installed is not None and installed is not cls:
        raise InputError(f"{kind[:-1]} name '{name}' is taken by {installed.__module__}.{installed.__qualname__}; "
                         f"give {cls.__qualname__} another name")
    if not own:
        cls.name = name
    _session[kind][name] = cls
    return name


def session_payload() -> bytes | None:
    """The session's registered classes, pickled by value where they live outside an
    importable module (cloudpickle): what a worker process needs to find them (None when
    there are none). One thread pickles at a time: a pool's threads start their workers
    together, and numba gives a compiled function its pickling id on first use without a
    lock of its own, so two pickling it at once fail."""
    if not any(_session.values()):
        return None
    import cloudpickle

    with _PICKLING:
        return cloudpickle.dumps(_session)


def session_only(names) -> list[str]:
    """Those of ``names`` (problems or schemes) registered in this process by ``register``
    and not installed as a plugin: a process that does not inherit this session (a Dask
    worker) cannot find them."""
    installed = _load()
    return [n for n in names if (n in _session["problems"] and n not in installed["problems"])
            or (n in _session["integrators"] and n not in installed["integrators"])]


def restore_session(payload: bytes | None) -> None:
    """Register, in a worker process, the classes of ``session_payload``."""
    if payload:
        import pickle

        for kind, classes in pickle.loads(payload).items():
            _session[kind].update(classes)


def problems() -> dict[str, type[Problem]]:
    return {**_load()["problems"], **_session["problems"]}


def default_problems() -> list[str]:
    """The problems of a matrix run without -p: every registered one that is not a diagnostic."""
    return sorted(n for n, cls in problems().items() if cls.in_default_matrix)


def integrators() -> dict[str, type[Integrator]]:
    return {**_load()["integrators"], **_session["integrators"]}


def broken() -> list[BrokenPlugin]:
    _load()
    return list(_broken)


def problem_class(name: str) -> type[Problem]:
    found = problems()
    _check_known("problem", name, found)
    return found[name]


def integrator_class(name: str) -> type[Integrator]:
    found = integrators()
    _check_known("integrator", name, found)
    return found[name]


def _check_known(kind: str, name: str, found: dict) -> None:
    if name not in found:
        bad = [b for b in broken() if b.name == name]
        if bad:
            from longtime.core.params import InputError

            raise InputError(f"{kind} '{name}' is a broken plugin: {bad[0].error}")
        check_choice(kind, name, found)
