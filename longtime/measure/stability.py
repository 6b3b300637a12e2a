"""Linear stability measured from the schemes themselves.

The test equation u' = lambda u (complex lambda = re + i im) is the problem ``linear-test``:
the real 2x2 system x' = re x - im y, y' = im x + re y for u = x + i y. One step of a
scheme's own compiled step (``make_step``, or ``make_try_step`` with its error control
switched off: tol, eps_res = 1e300) of size h = 1 with lambda = z from u = 1 gives the
amplification factor R(z) = x1 + i y1. A real scheme treats u = i the same way
(R(z) i) exactly when its step is complex-linear; where it is not (a partitioned
scheme, BPL's componentwise Pade), |R| is the worst growth over ``PHASES`` starting
phases e^(i theta) instead.

The imaginary-axis interval (the largest Y with |R(iy)| <= 1 + ``TOL`` on all of
[0, Y]) caps the step on oscillatory problems: a mode of frequency omega is stable while
omega h <= Y. A scheme with implicit stages has two limits, told apart: the method's linear
stability, from the stability function R(z) = 1 + z b^T (I - zA)^-1 1 of its tableau (the
Gauss methods, midpoint and rk4sym have |R(iy)| = 1 on the whole axis), and the limit of its
fixed-point stage iteration, which stops converging near h ||A|| |lambda| = 1: its measured
step fails there (``linear_interval``, ``solver_y``). Beside it, where it differs, the Y up to
which the growth stays below 1 % per step (``GROWTH_1PCT``, bpl's amplification onset): a truncated series of order
N = 5, 6 (mod 4) grows by y^(N+2)-small factors from y = 0, so only this bound says
where its growth becomes fast. It is measured on the rotation q' = p, p' = -q (the ``harmonic`` problem,
omega = 1, step h = y), which every scheme that needs a separable Hamiltonian can also
step; for a linear but not complex-linear step (Verlet, symplectic Euler) the growth is
the spectral radius of the 2x2 step matrix, the factor a mode sees step after step.
The series schemes' factor depends on N: it is measured for the fixed-order sum at each
N of ``SERIES_ORDERS``. Results are cached in $LONGTIME_CACHE_DIR/stability by a
fingerprint of the compiled step (its code and everything it closes over).
"""
from __future__ import annotations

import json
import math
from typing import Any, Callable, Iterable, Sequence

import numpy as np

from longtime.core import roles
from longtime.core.cache import discard, write_atomic
from longtime.core.params import InputError
from longtime.core.phases import phase as breakdown_phase
from longtime.problems.linear_test import LinearTest

TOL = 1e-9  # |R| above 1 + TOL is growth (round-off in |R| is ~1e-15)
GROWTH_1PCT = 1e-2  # the looser bound (bpl's amplification onset): a mode grows by 1 % per step
PHASES = 48  # starting phases where a step is not linear (BPL's componentwise Pade)
Y_MAX = 12.0  # the imaginary axis is scanned on [0, Y_MAX]
Y_STEP = 0.01
SERIES_ORDERS = (4, 6, 8, 10, 12, 14)
OFF = 1e300  # tolerance that switches an error control off


# ------------------------------------------------------------------ one step of a scheme
class Unmeasurable(Exception):
    """The scheme has no step kernel to measure, or cannot step this problem."""


def one_step(scheme, problem) -> Callable[[np.ndarray, np.ndarray, float], bool]:
    """step(u, params, h) -> accepted: one step of the scheme's own compiled step, in place on
    u, taken by the very loop its runs use (``compiled_loop``, called with the argument types
    of a run): the matrix's harmonic cells have compiled it already, so a cold main job's
    intervals cost a disk load per scheme, not a compile of the bare step.
    Accepted: the step returned OK (a non-finite result included: its growth is inf); an
    adaptive step must also have been taken whole, at once (error control off)."""
    from longtime.core import drivers
    from longtime.core.stepping import AdaptiveIntegrator, FixedStepIntegrator

    reason = scheme.incompatibility(problem)
    if reason:
        raise Unmeasurable(reason)
    fixed = isinstance(scheme, FixedStepIntegrator)
    if not (fixed or isinstance(scheme, AdaptiveIntegrator)):
        raise Unmeasurable(f"{scheme.name} is {_kind(scheme.kind)} integrator: no step kernel to measure")
    loop = scheme.compiled_loop(problem)
    work = np.zeros(scheme.work_shape(problem))
    scheme.prepare_work(problem, work)
    out_t, out_u = np.empty(2), np.empty((2, problem.dim))
    if fixed:
        sample_at = np.array([1, 2])

        def one(u, params, h):
            # a fresh work: a multi-step scheme's memory must not carry from the last point
            status = loop(u, 0.0, h, h, 0, 1, 1, sample_at, 0, 0, params, work.copy(), out_t, out_u,
                          drivers.new_counters(), math.inf)[0]
            return status != drivers.FAILED

        return one
    u_new = np.empty(problem.dim)

    def one(u, params, h):
        counters = drivers.new_counters()
        status = loop(u, 0.0, h, h, h, 1, params, work.copy(), u_new, out_t, out_u, counters,
                      np.array([math.inf, 0.0]), math.inf)[0]
        whole = counters[drivers.STEPS] == 1 and counters[drivers.REJECTED] == 0
        return status in (drivers.OK, drivers.DIVERGED) and whole

    return one


def _kind(kind: str) -> str:
    """"an external", "a fixed": the kind with its article."""
    return ("an " if kind[:1] in "aeiou" else "a ") + kind


def _scheme(name: str, order: int | None = None):
    from longtime.core import registry

    cls = registry.integrator_class(name)
    # error control off: every accuracy parameter at OFF
    settings: dict[str, Any] = {k: OFF for k in roles.with_role([cls], "accuracy")}
    if order is not None:
        settings.update({k: order for k in roles.with_role([cls], "order")})
    if "tol" in settings and name.startswith("taylor"):
        raise Unmeasurable(f"{name} chooses its order from tol: the fixed-order 'taylor' is measured")
    from longtime.core.stepping import AdaptiveIntegrator, FixedStepIntegrator

    if not issubclass(cls, (FixedStepIntegrator, AdaptiveIntegrator)):
        raise Unmeasurable(f"{name} is {_kind(cls.kind)} integrator: no step kernel to measure")
    return cls(**settings)


def _growth(step, params: np.ndarray, h: float, phases: int) -> tuple[complex, float]:
    """(R from u = 1, the growth a mode sees) of one step; nan where the step fails."""
    u1 = np.array([1.0, 0.0])
    ui = np.array([0.0, 1.0])
    if not (step(u1, params, h) and step(ui, params, h)):
        return complex(np.nan, np.nan), np.nan
    r = complex(u1[0], u1[1])
    if not np.all(np.isfinite(u1)) or not np.all(np.isfinite(ui)):
        return r, np.inf
    # linear? two probes at phases that no symmetry of the rotation relates to 0 or pi/2
    # (a componentwise Pade is homogeneous, so u = 1 and u = i alone cannot tell)
    m = np.column_stack([u1, ui])
    linear = True
    for theta in (0.3, 1.1):
        probe = np.array([math.cos(theta), math.sin(theta)])
        linear = linear and step(probe, params, h) and np.allclose(
            probe, m @ np.array([math.cos(theta), math.sin(theta)]), rtol=1e-10, atol=1e-12)
    if linear:
        scale = max(1.0, abs(r))
        if abs(ui[0] + u1[1]) <= 1e-12 * scale and abs(ui[1] - u1[0]) <= 1e-12 * scale:
            return r, abs(r)  # complex-linear: multiplication by R
        return r, float(max(abs(np.linalg.eigvals(m))))  # the factor that repeats, step after step
    worst = 0.0
    # u -> -u maps a step onto its negative (odd in u), so half a turn of phases covers all
    for theta in np.linspace(0.0, np.pi, phases, endpoint=False):
        u = np.array([math.cos(theta), math.sin(theta)])
        if not step(u, params, h):
            return r, np.nan
        worst = max(worst, math.hypot(u[0], u[1]))
    return r, worst


def region(name: str, re: Sequence[float], im: Sequence[float], order: int | None = None,
           phases: int = PHASES) -> np.ndarray:
    """|R(z)| on the grid z = re[j] + i im[k] (shape (len(im), len(re))); nan where the step
    fails (an implicit solve that does not converge)."""
    scheme = _scheme(name, order)
    step = one_step(scheme, LinearTest())
    out = np.empty((len(im), len(re)))
    for k, y in enumerate(im):
        for j, x in enumerate(re):
            out[k, j] = _growth(step, np.array([float(x), float(y)]), 1.0, phases)[1]
    return out


def imaginary_growth(name: str, ys: Iterable[float], order: int | None = None,
                     phases: int = PHASES) -> np.ndarray:
    """The growth of one step of size y on the rotation q' = p, p' = -q, for each y."""
    from longtime.problems.harmonic import Harmonic

    scheme = _scheme(name, order)
    problem = Harmonic()
    step = one_step(scheme, problem)
    return np.array([_growth(step, problem.params, float(y), phases)[1] for y in ys])


def _first_stable_run(ys: np.ndarray, growth: np.ndarray, tol: float) -> tuple[float, int | None]:
    bad = np.nonzero(~(growth <= 1.0 + tol))[0]
    if bad.size == 0:
        return float(ys[-1]), None
    k = int(bad[0])
    return (float(ys[k - 1]) if k else 0.0), k


def implicit_tableau(name: str) -> tuple[np.ndarray, np.ndarray] | None:
    """(A, b) of a Runge-Kutta scheme whose stages are implicit (a non-zero a_ij with
    j >= i), None for any other scheme."""
    from longtime.core import registry

    cls = registry.integrator_class(name)
    A, b = getattr(cls, "A", None), getattr(cls, "b", None)
    if A is None or b is None:
        return None
    A = np.asarray(A, dtype=float)
    return (A, np.asarray(b, dtype=float)) if A.ndim == 2 and np.any(np.triu(A) != 0) else None


def stability_function(A: np.ndarray, b: np.ndarray, z: complex) -> complex:
    """R(z) = 1 + z b^T (I - z A)^-1 1: one step of the tableau on u' = lambda u, z = lambda h,
    with its stages solved exactly (no iteration)."""
    s = b.size
    stages = np.linalg.solve(np.eye(s) - z * A, np.ones(s, dtype=complex))
    return complex(1.0 + z * (b @ stages))


def linear_interval(name: str, y_max: float = Y_MAX, y_step: float = Y_STEP) -> dict[str, Any] | None:
    """{"y", "bounded", "why"}: the method's own linear stability on the imaginary axis, the
    largest Y with |R(iy)| <= 1 + TOL on all of [0, Y] from the stability function of its
    tableau (the stage equations solved exactly); None for a scheme without implicit stages,
    whose measured step is the method (nothing iterates in it)."""
    tableau = implicit_tableau(name)
    if tableau is None:
        return None
    ys = np.arange(y_step, y_max + 0.5 * y_step, y_step)
    growth = np.array([abs(stability_function(*tableau, complex(0.0, y))) for y in ys])
    y, k = _first_stable_run(ys, growth, TOL)
    if k is None:
        return {"y": y, "bounded": False, "why": f"|R(iy)| <= 1 on all of [0, {y_max:g}]"}
    return {"y": round(y, 6), "bounded": True, "why": f"|R| = {growth[k]:.6g} at y = {ys[k]:.3g}"}


def imaginary_interval(name: str, order: int | None = None, y_max: float = Y_MAX,
                       y_step: float = Y_STEP) -> dict[str, Any]:
    """{"y", "bounded", "why", "y_1pct"}: the largest Y (to y_step) with growth <= 1 + TOL
    on all of [0, Y] (bounded False: the whole scanned range is) of the scheme's compiled
    step, and the same with growth up to 1 % per step allowed (``y_1pct``: where a mode's
    growth becomes fast). A scheme with implicit stages adds "linear" (``linear_interval``:
    the method's stability, from R(z)) and "solver_y" (the largest y its stage iteration
    converges to, None where it converges on all the scan): the measured interval of such a
    scheme ends where the first of the two does."""
    ys = np.arange(y_step, y_max + 0.5 * y_step, y_step)
    growth = imaginary_growth(name, ys, order)
    y, k = _first_stable_run(ys, growth, TOL)
    y_1pct, _ = _first_stable_run(ys, growth, GROWTH_1PCT)
    if k is None:
        out = {"y": y, "bounded": False, "why": f"stable on all of [0, {y_max:g}]", "y_1pct": y_1pct}
    else:
        why = "step failed" if np.isnan(growth[k]) else f"|R| = {growth[k]:.6g}"
        out = {"y": round(y, 6), "bounded": True, "why": f"{why} at y = {ys[k]:.3g}", "y_1pct": round(y_1pct, 6)}
    linear = linear_interval(name, y_max, y_step)
    if linear is not None:
        failed = np.nonzero(np.isnan(growth))[0]
        out.update(linear=linear, solver_y=(float(ys[failed[0] - 1]) if failed[0] else 0.0) if failed.size else None)
    return out


def orders_of(name: str) -> list[int | None]:
    """The N at which a series scheme is measured ([None] for the others)."""
    from longtime.core import registry

    return list(SERIES_ORDERS) if roles.with_role([registry.integrator_class(name)], "order") else [None]


def _bounds_text(result: dict[str, Any]) -> str:
    return f"[0, {result['y']:.3g}]" if result["bounded"] else f"[0, >= {result['y']:.3g}]"


def format_interval(result: dict[str, Any]) -> str:
    """'[0, 2.82]' (the interval of the measured step); for a scheme with implicit stages the
    method's linear stability and its solver's convergence limit, each named: 'linear
    stability (|R(iy)| <= 1 from R(z)) [0, >= 12]; fixed-point solver converges to y = 2.07'."""
    if "error" in result:
        return f"not measured: {result['error']}"
    if result.get("linear") is not None:
        solver = ("fixed-point solver converges on all of the scan" if result.get("solver_y") is None
                  else f"fixed-point solver converges to y = {result['solver_y']:.3g} (its step fails beyond)")
        return f"linear stability (|R(iy)| <= 1 from R(z)) {_bounds_text(result['linear'])}; {solver}"
    y = result["y"]
    if not result["bounded"]:
        return f"[0, >= {y:.3g}]"
    text = f"[0, {y:.3g}]" + (" (its step fails beyond)" if result["why"].startswith("step failed") else "")
    y1 = result.get("y_1pct")
    if y1 is not None and y1 > 1.1 * y + 0.05:  # only where the two bounds tell different stories
        text += f" (growth <= 1 %/step to {y1:.3g})"
    return text


# ------------------------------------------------------------------ cached results
def _cache_key(name: str, order: int | None) -> str:
    from longtime.core.cache import digest
    from longtime.core.jitcache import fingerprint
    from longtime.problems.harmonic import Harmonic

    scheme = _scheme(name, order)
    try:
        build = scheme.make_step if hasattr(scheme, "make_step") else scheme.make_try_step
        code = fingerprint(build(Harmonic()))
    except Exception:  # no fingerprint (an opaque closure, a scheme that cannot step it): the class
        code = f"{type(scheme).__module__}.{type(scheme).__qualname__}"
    return digest(name, str(order), code, repr((TOL, GROWTH_1PCT, Y_MAX, Y_STEP, PHASES, 4)))


def _cache_file(name: str, order: int | None):
    from longtime.core.cache import cache_dir

    return cache_dir("stability") / f"{name}-N{order}-{_cache_key(name, order)}.json"


def _read_cached(path) -> dict[str, Any] | None:
    """The result cached in ``path``, or None when there is none; a file that is not a
    whole result (truncated, corrupt, another shape) is discarded with a warning naming it."""
    try:
        result = json.loads(path.read_bytes())
    except FileNotFoundError:
        return None
    except (OSError, ValueError) as exc:  # ValueError: not JSON, or not UTF-8
        discard(path, "stability", exc)
        return None
    number = (int, float)

    def interval(r: Any) -> bool:
        return (isinstance(r, dict) and isinstance(r.get("y"), number) and isinstance(r.get("bounded"), bool)
                and isinstance(r.get("why"), str))

    base = {"y", "bounded", "why", "y_1pct"}
    whole = isinstance(result, dict) and (
        (set(result) == {"error"} and isinstance(result["error"], str))
        or (set(result) in (base, base | {"linear", "solver_y"}) and interval(result)
            and isinstance(result["y_1pct"], number)
            and (set(result) == base or (interval(result["linear"])
                                         and (result["solver_y"] is None or isinstance(result["solver_y"], number))))))
    if not whole:
        discard(path, "stability", f"not a stability result: {str(result)[:80]!r}")
        return None
    return result


def intervals(name: str, compute: bool = True, orders: Iterable[int] | None = None) -> dict[str, dict[str, Any]]:
    """{"" or "N=4": result}: the scheme's imaginary-axis interval(s), from the cache, or
    measured (and cached) when ``compute``; empty when neither. ``orders``: the N of a
    series scheme (default ``SERIES_ORDERS``)."""
    out = {}
    try:
        orders = _wanted_orders(name, orders)
        from longtime.problems.harmonic import Harmonic

        reason = _scheme(name, orders[0]).incompatibility(Harmonic())
        if reason:  # not measurable at all: one reason, not one per N
            raise Unmeasurable(reason)
        for order in orders:
            label = "" if order is None else f"N={order}"
            try:
                path = _cache_file(name, order)
            except Unmeasurable as exc:
                out[label] = {"error": str(exc)}
                continue
            cached = _read_cached(path)
            if cached is not None:
                out[label] = cached
            elif compute:
                try:
                    result = imaginary_interval(name, order)
                except Unmeasurable as exc:
                    result = {"error": str(exc)}
                write_atomic(path, json.dumps(result).encode())
                out[label] = result
    except (InputError, Unmeasurable) as exc:
        out[""] = {"error": str(exc)}
    return out


def _wanted_orders(name: str, orders: Iterable[int] | None) -> list[int | None]:
    return orders_of(name) if orders is None or orders_of(name) == [None] else sorted(set(orders))


def cached_texts(schemes: dict[str, Iterable[int] | None]) -> tuple[dict[str, str], dict[str, Iterable[int] | None]]:
    """(scheme -> its interval text, for the schemes of ``schemes`` (name -> its N or None) with
    every N in the cache or none measurable at all; the others, which ``interval_texts(...,
    compute=True)`` would measure), from one read of the cache."""
    texts, missing = {}, {}
    for s, orders in schemes.items():
        found = _found(s, orders, compute=False)
        if "" in found or len(found) >= len(_wanted_orders(s, orders)):  # "": why none can be measured
            texts[s] = _text(found)
        else:
            missing[s] = orders
    return texts, missing


def _found(name: str, orders: Iterable[int] | None, compute: bool) -> dict[str, dict[str, Any]]:
    try:
        return intervals(name, compute=compute, orders=orders)
    except Exception as exc:  # a scheme no longer installed, a step that cannot be built
        return {"": {"error": f"{type(exc).__name__}: {exc}"}}


def _text(found: dict[str, dict[str, Any]]) -> str:
    return "; ".join(f"{label} {format_interval(r)}".strip() for label, r in found.items())


def interval_texts(schemes: dict[str, Iterable[int] | None], compute: bool = False) -> dict[str, str]:
    """scheme -> its interval text ('N=10 [0, 0.32] ...' for a series scheme at the given N),
    from the cache, measured where missing when ``compute``."""
    out = {}
    with breakdown_phase("stability"):
        for s, orders in schemes.items():
            found = _found(s, orders, compute)
            if found:
                out[s] = _text(found)
    return out


# ------------------------------------------------------------------ bpl's amplification
AMPLIFICATION_GROWTH = GROWTH_1PCT  # |R| above 1 + this counts as amplification


def amplification(ys, order: int = 10, phases: int = PHASES, **settings) -> np.ndarray:
    """|R(iy)|: the growth of one step of length y of ``bpl`` (its compiled step, the
    residual test switched off) on the rotation q' = p, p' = -q (the harmonic oscillator,
    omega = 1), the worst over ``phases`` starting phases. A Fourier mode of frequency
    omega is such a rotation, so this is how one step of length h treats it at y = omega h.
    Each component gets its own Pade approximant, so the step is not a linear map and its
    growth depends on the phase; the maximum is what a mode with any phase can see.
    A step the kernel cannot take at y (non-finite sum) gives inf."""
    from longtime.integrators.bpl import BorelPadeLaplace
    from longtime.problems.harmonic import Harmonic

    problem = Harmonic()
    scheme = BorelPadeLaplace(order=order, **{**settings, "eps_res": 1e300})
    step = one_step(scheme, problem)  # the cached loop of bpl on harmonic: no compile per call
    ys = np.asarray(ys, dtype=float)
    worst = np.zeros(ys.size)
    for phase in np.linspace(0.0, np.pi, phases, endpoint=False):
        for k, y in enumerate(ys):
            u = np.array([math.cos(phase), -math.sin(phase)])
            growth = math.hypot(u[0], u[1]) if step(u, problem.params, float(y)) else np.inf
            worst[k] = max(worst[k], growth)
    return worst


def amplification_onset(order: int = 10, growth: float = AMPLIFICATION_GROWTH, **settings) -> float:
    """The smallest y = omega h (to 0.02) at which one bpl step amplifies some rotation
    by more than 1 + ``growth``: past it, a mode of frequency omega grows step after step."""
    ys = np.arange(0.02, 8.0 + 1e-9, 0.02)
    over = np.nonzero(amplification(ys, order, **settings) > 1.0 + growth)[0]
    return round(float(ys[over[0]]), 2) if over.size else math.inf
