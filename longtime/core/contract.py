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
from longtime.core.status import Status

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
    # the right-hand side written in jax.numpy, jax_rhs(t, u, params) -> u' (the diffrax peers)
    "jax_rhs": ("jax_rhs",),
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


def check_samples(scheme: str, problem: Any, traj: Any, t_final: float) -> str | None:
    """Why the samples a scheme returned cannot be believed (None when they can): every
    scheme's, the external ones' (which no compiled driver checks) included. The times are
    finite, start at t0 and increase; the states are (n, dim); a run that says ``ok`` ends
    at t_final and is finite throughout; the CPU and wall times are finite and >= 0."""
    import numpy as np

    t, u = np.asarray(traj.t), np.asarray(traj.u)
    if t.ndim != 1 or t.size == 0 or u.shape != (t.size, problem.dim):
        return (f"{scheme} returned samples of shapes t {t.shape}, u {u.shape}; expected t (n,) and u (n, "
                f"{problem.dim}) for {problem.name}'s state of dimension {problem.dim}")
    if not np.all(np.isfinite(t)):
        return f"{scheme} returned non-finite sample times"
    scale = max(1.0, abs(problem.t0), abs(t_final))
    if abs(t[0] - problem.t0) > 1e-12 * scale:
        return f"{scheme} returned samples starting at t={t[0]:.17g}, not at t0={problem.t0:g}"
    back = np.flatnonzero(np.diff(t) <= 0)
    if back.size:
        i = int(back[0])
        return f"{scheme} returned sample times that do not increase: t[{i}]={t[i]:.17g}, t[{i + 1}]={t[i + 1]:.17g}"
    for name in ("cpu_s", "wall_s"):
        value = getattr(traj, name)
        if not (isinstance(value, (int, float, np.floating)) and np.isfinite(value) and value >= 0):
            return f"{scheme} returned {name}={value!r}: a time must be finite and >= 0"
    if traj.status == Status.OK:
        if abs(t[-1] - t_final) > 1e-9 * scale:
            return (f"{scheme} says ok but its samples end at t={t[-1]:.17g}, before t_final={t_final:g} "
                    f"(a run that stops early is a timeout or failed)")
        bad = np.flatnonzero(~np.all(np.isfinite(u), axis=1))
        if bad.size:
            return f"{scheme} says ok but its state is not finite from t={t[int(bad[0])]:.6g} on"
    return None


# ------------------------------------------------------------------ a plugin's outputs, probed once
def built_in(cls_or_func: Any) -> bool:
    """Whether a class or function is longtime's own (tested by the suite, not probed)."""
    module = getattr(cls_or_func, "__module__", "") or ""
    return module.startswith("longtime.")


def _shape_check(owner: str, what: str, value: Any, expected: tuple, meaning: str) -> None:
    import numpy as np

    shape = np.shape(value)
    if shape[:len(expected)] != expected or len(shape) > len(expected) + (1 if len(expected) == 1 else 0):
        raise InputError(f"{owner}: {what} returned shape {shape}; expected {meaning}")


def exact_probe_times(problem: Any, t_final: float) -> Any:
    """The times ``exact`` is probed at: t0, t_final and points between, as many as make the
    expected (times, dim) output non-square (3 times, or 4 on a 3-component problem), so that
    an output transposed to (dim, times) has a shape that tells it from wrong values."""
    import numpy as np

    count = 4 if problem.dim == 3 else 3
    return np.linspace(problem.t0, t_final, count)


def check_problem_outputs(problem: Any, t_final: float) -> None:
    """The Python-level outputs of a plugin's problem: ``exact`` at t0, t_final and a time
    between (``exact_probe_times``) is (times, dim), not transposed, and starts at the initial
    state; ``blocks()`` puts every component in exactly one block; each invariant, violation
    and diagnostic on the initial state twice is (2,) or (2, k). An InputError names the
    problem and the output."""
    import numpy as np

    owner, dim = f"problem {problem.name}", problem.dim
    t = np.array([problem.t0, t_final], dtype=float)
    U = np.vstack([problem.u0, problem.u0])
    if problem.exact is not None:
        times = exact_probe_times(problem, t_final)
        count = times.size
        E = problem.exact(times)
        if np.shape(E) == (dim, count):
            raise InputError(f"{owner}: exact(t) for {count} times returned shape {np.shape(E)}: transposed; "
                             f"expected ({count}, {dim}), a row per time, a column per component of the state")
        _shape_check(owner, f"exact(t) for {count} times", E, (count, dim),
                     f"({count}, {dim}): a row per time, a column per component of the state (dimension {dim})")
        E = np.asarray(E, dtype=float)
        tol = max(float(problem.exact_rtol or 0.0), 1e-8) * max(1.0, float(np.max(np.abs(problem.u0))))
        if not np.all(np.abs(E[0] - problem.u0) <= tol):
            raise InputError(f"{owner}: exact(t0) = {E[0].tolist()} is not the initial state {problem.u0.tolist()}")
    blocks = problem.blocks()
    groups = [list(v) for v in blocks.values()] if isinstance(blocks, dict) else None
    flat = sorted(i for g in groups for i in g) if groups and all(groups) else None
    if flat != list(range(dim)):
        raise InputError(f"{owner}: blocks() returned {blocks!r}: expected {{name: component indices}} with every "
                         f"component 0..{dim - 1} in exactly one non-empty block")
    for kind in ("invariants", "violations", "diagnostics"):
        for name, values in (getattr(problem, kind)(t, U) or {}).items():
            _shape_check(owner, f"{kind}(t, U)[{name!r}] for 2 samples", values, (2,),
                         "(2,) or (2, k): a value (or k values) per sample")


_BOUNDSCHECKED: dict[Any, Any] = {}


def boundschecked(func: Any) -> Any:
    """A twin of the compiled ``func`` that checks every index (numba's boundscheck), built
    once per function: an out-of-range read or write raises IndexError instead of
    corrupting memory. The functions it calls keep their own compilation."""
    import numba

    key = getattr(func, "py_func", func)
    if key not in _BOUNDSCHECKED:
        _BOUNDSCHECKED[key] = numba.njit(boundscheck=True)(key)
    return _BOUNDSCHECKED[key]


def probe_problem_kernels(problem: Any) -> None:
    """A plugin's compiled rhs (and grad_T, grad_V of a separable one) run once with bounds
    checked at the initial state, the output filled with NaN first: an index outside the
    arrays, or an output component left unwritten or NaN, is an InputError naming the problem."""
    import numpy as np

    owner, dim, n = f"problem {problem.name}", problem.dim, problem.dim // 2
    calls = [("rhs", problem.rhs, (problem.t0, problem.u0.copy()), dim)]
    if getattr(problem, "grad_T", None) is not None and getattr(problem, "grad_V", None) is not None:
        calls += [("grad_V", problem.grad_V, (problem.u0[:n].copy(),), n),
                  ("grad_T", problem.grad_T, (problem.u0[n:].copy(),), n)]
    for name, func, args, size in calls:
        if func is None or built_in(getattr(func, "py_func", func)):
            continue
        out = np.full(size, np.nan)
        try:
            boundschecked(func)(*args, problem.params, out)
        except IndexError as exc:
            raise InputError(f"{owner}: its {name} indexes outside its arrays at the initial state ({exc}; numba "
                             f"boundscheck): the state has {dim} components, the output {size}") from None
        bad = np.flatnonzero(~np.isfinite(out))
        if bad.size:
            raise InputError(f"{owner}: its {name} returns NaN (or leaves unwritten) components {bad.tolist()} of "
                             f"{size} at the initial state")


def probe_step_kernel(integrator: Any, problem: Any) -> str | None:
    """One step of a plugin's own compiled step (a ``make_step``, or an adaptive scheme's
    ``make_try_step``, that is not longtime's) with bounds checked, from the initial state:
    why it cannot run (an index outside its arrays), naming the scheme, or None."""
    import numpy as np

    from longtime.core import drivers

    fixed = hasattr(type(integrator), "make_step")
    make = getattr(type(integrator), "make_step" if fixed else "make_try_step", None)
    if make is None or built_in(make):
        return None
    try:
        kernel = integrator.make_step(problem) if fixed else integrator.make_try_step(problem)
    except NotImplementedError:  # a scheme that runs its own loop (its _integrate) builds no step
        return None
    work = np.zeros(integrator.work_shape(problem))
    integrator.prepare_work(problem, work)
    h = integrator.dt_for(problem) if fixed else integrator.initial_step(problem, problem.default_t_final or 1.0)
    last = (True,) if fixed else (np.empty(problem.dim),)
    try:
        boundschecked(kernel)(problem.t0, problem.u0.copy(), h, problem.params, work, drivers.new_counters(), *last)
    except IndexError as exc:
        return (f"scheme {integrator.name}: its {'step' if fixed else 'try_step'} indexes outside its arrays ({exc}; "
                f"numba boundscheck, one step of {problem.name} from its initial state, {problem.dim} components)")
    return None


def nan_note(problem: Any, t: Any, u: Any) -> str:
    """Where a state turned NaN (not a growth to infinity): whether the rhs returns NaN at a
    finite state at the end of the run (the last finite sample, and on along the last
    sampled displacement, where the failing step's stages lie); '' when the last sample is
    not NaN."""
    import numpy as np

    if len(t) < 2 or not np.isnan(u[-1]).any() or not np.all(np.isfinite(u[-2])):
        return ""
    last = np.array(u[-2], dtype=float)
    move = last - np.asarray(u[-3], dtype=float) if len(t) >= 3 and np.all(np.isfinite(u[-3])) else 0.0 * last
    for s in (0.0, 0.5, 1.0, 1.5, 2.0):
        y = last + s * move
        out = np.full(problem.dim, np.nan)
        try:
            problem.rhs(float(t[-2]), y, problem.params, out)
        except Exception:  # the note is a help, not a verdict
            return ""
        bad = np.flatnonzero(np.isnan(out))
        if bad.size:
            where = "the last finite sample" if s == 0.0 else "a finite state just past it"
            return (f"the rhs of {problem.name} returns NaN near t={t[-2]:.6g} ({where}, u = "
                    f"{np.array2string(y, precision=4, threshold=6)}), in components {bad.tolist()[:8]}")
    return (f"the state turned NaN after t={t[-2]:.6g} (an invalid operation such as 0/0 or the root of a negative "
            f"number), not a growth to infinity")
