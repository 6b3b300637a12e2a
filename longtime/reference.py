"""Reference trajectories: the exact solution where a problem has one, else heyoka.

heyoka's adaptive Taylor integrator runs at machine-epsilon tolerance with
``high_accuracy`` (compensated summation for long runs); ``precision="long double"``
uses 80-bit extended floats for ground truth on chaotic problems. States are computed on
the requested times through ``propagate_grid`` (dense output, so heyoka's own steps are not
clipped) and cached on disk by problem, settings, initial state, times and precision.
"""
from __future__ import annotations

import os
import time

import numpy as np

from .cache import cache_dir, digest
from .params import InputError
from .problem import Problem

PRECISIONS = {"double": np.float64, "long double": np.longdouble}
# a reference that takes longer than this (wall seconds) is given up: the row keeps its
# status and says so (duffing-1 far past t = 40 needs ever more steps per unit time)
DEFAULT_BUDGET_S = float(os.environ.get("LONGTIME_REFERENCE_SECONDS", "120"))


class ReferenceUnavailable(RuntimeError):
    """The reference could not be computed (its time budget ran out, or heyoka failed)."""
_TAYLOR: dict[tuple, object] = {}  # compiled integrators, by problem identity and precision


def has_reference(problem: Problem) -> bool:
    caps = problem.capabilities()
    return "exact" in caps or "heyoka" in caps


def reference_states(problem: Problem, times: np.ndarray, precision: str = "double",
                     budget_s: float | None = None) -> np.ndarray:
    """States (len(times), dim) of the problem's true trajectory from problem.u0 at t0.

    Raises ReferenceUnavailable when heyoka stops early or takes more than ``budget_s``
    wall seconds (default $LONGTIME_REFERENCE_SECONDS or 120).
    """
    times = np.asarray(times, dtype=float)
    if problem.exact is not None:
        return np.asarray(problem.exact(times), dtype=float)
    if problem.heyoka_system is None:
        raise InputError(f"problem '{problem.name}' has neither an exact solution nor a heyoka system")
    if precision not in PRECISIONS:
        raise InputError(f"precision={precision!r} is not valid: expected one of {', '.join(PRECISIONS)}")
    import heyoka as hy

    key = digest(problem.identity(), problem.u0.tobytes(), repr(problem.t0), times.tobytes(),
                 precision, hy.__version__)
    path = cache_dir("reference") / f"{problem.name}-{key}.npy"
    if path.exists():
        return np.load(path)
    # propagate_grid wants a strictly increasing grid that starts at the current time
    grid, inverse = np.unique(times, return_inverse=True)
    if grid[0] < problem.t0:
        raise InputError(f"reference times start at {grid[0]} < t0 = {problem.t0}")
    starts_later = grid[0] > problem.t0
    if starts_later:
        grid = np.r_[problem.t0, grid]
    ta = _taylor(problem, precision)
    fp = PRECISIONS[precision]
    ta.time = fp(problem.t0)
    ta.state[:] = problem.u0.astype(fp)
    deadline = time.perf_counter() + (DEFAULT_BUDGET_S if budget_s is None else budget_s)
    outcome = ta.propagate_grid(grid.astype(fp), callback=lambda _: time.perf_counter() < deadline)
    if outcome[0] == hy.taylor_outcome.cb_stop:
        raise ReferenceUnavailable(f"heyoka reference for {problem.name} passed its time budget "
                                   f"at t = {float(ta.time):.6g} (LONGTIME_REFERENCE_SECONDS)")
    if outcome[0] != hy.taylor_outcome.time_limit:
        raise ReferenceUnavailable(f"heyoka reference for {problem.name} stopped early: {outcome[0]}")
    states = np.asarray(outcome[-1], dtype=float)[int(starts_later):][inverse]
    np.save(path, states)
    return states


def _taylor(problem: Problem, precision: str):
    ident = (problem.identity(), precision)
    ta = _TAYLOR.get(ident)
    if ta is None:
        import heyoka as hy

        variables, rhs = problem.heyoka_system()
        fp = PRECISIONS[precision]
        ta = hy.taylor_adaptive(list(zip(variables, rhs)), problem.u0.astype(fp),
                                tol=np.finfo(fp).eps, high_accuracy=True, fp_type=fp,
                                time=fp(problem.t0))
        _TAYLOR[ident] = ta
    return ta
