"""Checks of the plugin contract (docs/plugins.md), run when a class is defined and when it
is registered, so that a plugin that breaks the contract is reported by ``longtime list``
as broken, with a one-line reason, instead of failing inside a compiled loop.

When a class is defined (``__init_subclass__`` of ``Problem`` and ``Integrator``), what
it sets must be well formed: a compiled function is a numba dispatcher attached with
``staticmethod``, capabilities that come in pairs are provided together, ``requires``
names known capabilities, ``kind`` is one of the drivers. When the registry loads a class
from an entry point, it must also be complete: not abstract, a problem with a ``rhs``,
every attribute its family declares (an annotation without a value, as ``A``, ``b``,
``c`` of a tableau family or ``kicks``, ``drifts`` of a splitting) set.
"""
from __future__ import annotations

import inspect
import re
from typing import Any

from numba.core.registry import CPUDispatcher

from longtime.core.params import InputError, Param

# capability name -> attribute(s) of a problem that provide it
CAPABILITIES: dict[str, tuple[str, ...]] = {
    "separable": ("grad_T", "grad_V"),
    "jacobian": ("jac",),
    "exact": ("exact",),
    "heyoka": ("heyoka_system",),
    "taylor": ("taylor",),
    "constraints": ("constraints",),
    "linear_part": ("linear_part", "nonlinear"),
    # a fast linear oscillation with unit masses: q'' = -Omega^2 q - grad U(q), Omega diagonal
    "oscillatory": ("frequencies", "grad_U"),
    # a velocity-dependent (Lorentz) force on unit charges and masses in space:
    # u = (x, v), x and v in R^(3N), x_k'' = v_k x B(x_k) + E(x_k) for each particle k
    "lorentz": ("field_B", "field_E"),
}

# compiled functions a problem may provide (see docs/plugins.md)
COMPILED_ATTRIBUTES = ("rhs", "grad_T", "grad_V", "jac", "taylor", "linear_part", "nonlinear",
                       "frequencies", "grad_U", "field_B", "field_E")
CONSTRAINT_FUNCTIONS = ("phi", "grad_phi", "mass", "grad_U")
KINDS = ("fixed", "adaptive", "external")
# every name a plugin gives (problem, scheme, parameter, invariant): it becomes part of file
# names, row fields (NAME.max) and the results page, so it is a plain identifier
NAME_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9_+-]{0,63}")
NAME_RULE = ("a name is 1 to 64 characters: ASCII letters, digits, '_', '-' and '+', starting with "
             "a letter or a digit")


class ContractError(InputError, TypeError):
    """A problem or scheme class that breaks the plugin contract: bad input (an in-memory
    class defined or registered from Python fails with the one-line reason ``longtime
    list`` gives a broken plugin), and a TypeError (the class itself is wrong)."""


def _owner(cls: type) -> str:
    return f"{cls.__module__}.{cls.__qualname__}"


def _check_compiled(owner: str, attr: str, raw: Any, via_class: bool = True) -> None:
    if raw is None:
        return
    if via_class:
        if isinstance(raw, CPUDispatcher):
            raise ContractError(f"{owner}.{attr} must be attached as staticmethod({raw.py_func.__name__}) "
                                f"(a bare compiled function becomes a bound method)")
        if not isinstance(raw, staticmethod):
            raise ContractError(f"{owner}.{attr} must be a compiled function attached as staticmethod(...), "
                                f"got {type(raw).__name__}")
        raw = raw.__func__
    if not isinstance(raw, CPUDispatcher):
        name = getattr(raw, "__name__", type(raw).__name__)
        raise ContractError(f"{owner}.{attr} = {name} is not compiled: decorate it with @numba.njit")


def check_problem_definition(cls: type) -> None:
    owner = _owner(cls)
    for attr in COMPILED_ATTRIBUTES:
        if attr in vars(cls):
            _check_compiled(owner, attr, vars(cls)[attr])
    for cap, attrs in CAPABILITIES.items():
        given = [a for a in attrs if getattr(cls, a, None) is not None]
        if given and len(given) < len(attrs):
            missing = [a for a in attrs if a not in given]
            raise ContractError(f"{owner}: capability '{cap}' needs {' and '.join(attrs)}; "
                                f"{', '.join(missing)} missing")
    constraints = vars(cls).get("constraints")
    if constraints is not None:
        n = getattr(constraints, "n_constraints", None)
        if not isinstance(n, int) or n < 1:
            raise ContractError(f"{owner}.constraints.n_constraints must be an integer >= 1, got {n!r}")
        for attr in CONSTRAINT_FUNCTIONS:
            if getattr(constraints, attr, None) is None:
                raise ContractError(f"{owner}.constraints has no {attr} (needs {', '.join(CONSTRAINT_FUNCTIONS)})")
            _check_compiled(f"{owner}.constraints", attr, getattr(constraints, attr), via_class=False)
    _check_common(cls, owner, "problem")


def check_integrator_definition(cls: type) -> None:
    owner = _owner(cls)
    known = set(CAPABILITIES) | {"rhs", "invariants", "autonomous"}
    unknown = sorted(set(cls.requires) - known)
    if unknown:
        raise ContractError(f"{owner}.requires names unknown capabilities {', '.join(unknown)}; "
                            f"known: {', '.join(sorted(known))}")
    if cls.kind not in KINDS:
        raise ContractError(f"{owner}.kind = {cls.kind!r}: expected one of {', '.join(KINDS)}")
    if cls.order is not None and not (isinstance(cls.order, int) and cls.order >= 1):
        raise ContractError(f"{owner}.order = {cls.order!r}: expected an integer >= 1 or None")
    _check_common(cls, owner, "scheme")


def name_error(kind: str, name: Any) -> str | None:
    """Why ``name`` is not a valid name of a ``kind`` (None when it is): see NAME_RULE."""
    if isinstance(name, str) and NAME_PATTERN.fullmatch(name):
        return None
    return f"{kind} name {name!r} is not valid: {NAME_RULE}"


def check_name(kind: str, name: Any) -> None:
    reason = name_error(kind, name)
    if reason:
        raise ContractError(reason)


def _check_common(cls: type, owner: str, kind: str) -> None:
    if not isinstance(cls.name, str):
        raise ContractError(f"{owner}.name must be a string, got {cls.name!r}")
    if cls.name:  # an empty name is set from the entry point at registration
        check_name(kind, cls.name)
    params = cls.parameters
    if not isinstance(params, dict) or not all(isinstance(k, str) and isinstance(v, Param)
                                               for k, v in params.items()):
        raise ContractError(f"{owner}.parameters must map names to longtime.Param")
    for key in params:
        check_name(f"{owner} parameter", key)


def check_registered(cls: type) -> None:
    """A class loaded from an entry point must be complete (see the module docstring)."""
    owner = _owner(cls)
    if inspect.isabstract(cls):
        raise ContractError(f"{owner} is abstract: implement {', '.join(sorted(cls.__abstractmethods__))}")
    if hasattr(cls, "rhs") and cls.rhs is None:  # a problem: schemes have no rhs slot
        raise ContractError(f"{owner} has no rhs: every problem provides a compiled rhs(t, u, params, out)")
    for klass in cls.__mro__:
        for attr in inspect.get_annotations(klass):
            if not hasattr(cls, attr):
                raise ContractError(f"{owner} does not set {attr}, which its family "
                                    f"{klass.__qualname__} declares")


def check_splitting(cls: type) -> None:
    """(kick, drift) coefficients of a splitting, when the class sets them: two 1-D arrays
    of equal length, finite, each summing to 1 (consistency: one full kick, one full drift)."""
    import numpy as np

    if not (hasattr(cls, "kicks") or hasattr(cls, "drifts")):
        return
    owner = _owner(cls)
    if not (hasattr(cls, "kicks") and hasattr(cls, "drifts")):
        raise ContractError(f"{owner}: a splitting sets both kicks and drifts")
    kicks, drifts = (np.asarray(x, dtype=float) for x in (cls.kicks, cls.drifts))
    if kicks.ndim != 1 or kicks.shape != drifts.shape or kicks.size == 0:
        raise ContractError(f"{owner}: kicks {kicks.shape} and drifts {drifts.shape} must be 1-D of one length")
    if not (np.all(np.isfinite(kicks)) and np.all(np.isfinite(drifts))):
        raise ContractError(f"{owner}: kicks and drifts must be finite")
    for label, x in (("kicks", kicks), ("drifts", drifts)):
        if abs(x.sum() - 1.0) > 1e-12:
            raise ContractError(f"{owner}: {label} sum to {float(x.sum())!r}, not 1 (the scheme would "
                                f"not be consistent)")


def pairs_incompatibility(scheme: str, problem: Any) -> str | None:
    """The ``linear_part`` capability views the state as (Re, Im) pairs: a scheme that uses
    it cannot treat a state of odd dimension (None when it can)."""
    if problem.dim % 2:
        return (f"{scheme} needs a state of (Re, Im) pairs (even dimension); "
                f"{problem.name} has dimension {problem.dim}")
    return None
