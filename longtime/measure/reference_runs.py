"""The runs a reference is computed by, and their wall-time budget: heyoka's adaptive Taylor
integrator of a problem in each precision at hand (``_ladder``: double, long double,
real128), evaluated at a grid by dense output (``propagate``), and a discretised system's
solution by DOP853 in its integrating-factor form or directly (``system_states``). How far a
reference is trusted, and which run a cell uses, is longtime.measure.reference."""
from __future__ import annotations

import os
import time
from typing import Callable

import numpy as np

from longtime.core import heyoka_build
from longtime.core.params import InputError
from longtime.core.problem import Problem

PRECISIONS = ("double", "long double", "real128")
# the source of the integrating-factor reference of a discretised system, and its tolerance
SYSTEM = "integrating factor"
SYSTEM_RTOL = 1e-13
# a heyoka run that takes longer than this (wall seconds) is given up: the row keeps its
# status and says so (duffing-1 far past t = 40 needs ever more steps per unit time)
DEFAULT_BUDGET_S = 120.0
BUDGET_VARIABLE = "LONGTIME_REFERENCE_SECONDS"


def budget_seconds() -> float:
    """The wall-time budget of one heyoka run: $LONGTIME_REFERENCE_SECONDS, else 120 s. Read
    when needed (a bad value is an InputError naming the variable, not a crash at import)."""
    text = os.environ.get(BUDGET_VARIABLE, "").strip()
    if not text:
        return DEFAULT_BUDGET_S
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (value > 0 and np.isfinite(value)):
        raise InputError(f"{BUDGET_VARIABLE}={text!r} is not valid: expected a finite number of seconds > 0")
    return value


# the real128 run goes in this many pieces and stops once long double is seen to fail
_PIECES = 16
_TAYLOR: dict[tuple, object] = {}  # compiled integrators, by problem identity and precision


class ReferenceUnavailable(RuntimeError):
    """The reference could not be computed (its time budget ran out, or heyoka failed)."""


def propagate(problem: Problem, grid: np.ndarray, precision: str, budget_s: float | None = None,
               found_out: Callable[[np.ndarray], bool] | None = None) -> tuple[np.ndarray, float | None]:
    """float64 states at the increasing ``grid`` (grid[0] = t0) by heyoka in ``precision``,
    and the time where the budget stopped it (None: it did not; then fewer rows). With
    ``found_out``, the grid goes in _PIECES pieces, ending after one where found_out(rows)."""
    import heyoka as hy

    fp = fp_type(precision)
    deadline = time.perf_counter() + (budget_seconds() if budget_s is None else budget_s)
    ta = start_integrator(problem, precision, deadline)  # its compile counts against the budget
    pieces = _PIECES if found_out is not None else 1
    bounds = np.unique(np.linspace(0, grid.size - 1, pieces + 1).round().astype(int))
    if bounds.size == 1:  # a grid of one time
        bounds = np.r_[0, 0]
    rows: list[np.ndarray] = []
    for a, b in zip(bounds[:-1], bounds[1:]):
        outcome = ta.propagate_grid(grid[a:b + 1].astype(fp), callback=lambda _: time.perf_counter() < deadline)
        part = np.asarray(outcome[-1]).astype(float)
        rows.append(part if a == 0 else part[1:])  # a piece starts where the last one ended
        if outcome[0] == hy.taylor_outcome.cb_stop:
            return np.concatenate(rows), float(ta.time)
        if outcome[0] != hy.taylor_outcome.time_limit:
            raise ReferenceUnavailable(f"heyoka {precision} reference for {problem.name} stopped early: {outcome[0]}")
        if found_out is not None and found_out(np.concatenate(rows)):
            break
    return np.concatenate(rows), None


def system_states(problem: Problem, grid: np.ndarray, form: str, budget_s: float | None = None
                  ) -> tuple[np.ndarray, float | None]:
    """float64 states at the increasing ``grid`` (grid[0] = t0) of the problem's system by
    DOP853 at rtol SYSTEM_RTOL, dense output: ``form`` "factor" integrates the
    integrating-factor form (the reference), "direct" the system u' = rhs(t, u) (its check).
    Returns them and the time where the budget stopped the run (None: it did not; then
    fewer rows)."""
    from scipy.integrate import DOP853

    deadline = time.perf_counter() + (budget_seconds() if budget_s is None else budget_s)
    grid = np.asarray(grid, dtype=float)
    t0, params, out = float(grid[0]), problem.params, np.empty(problem.dim)
    diagonal = np.empty(problem.dim)
    problem.linear_part(params, diagonal)
    lam = diagonal[0::2] + 1j * diagonal[1::2]  # L on the complex view z_k = u[2k] + i u[2k+1]

    def turn(u: np.ndarray, t: float, sign: float) -> np.ndarray:
        """exp(sign L (t - t0)) u, pair by pair."""
        z = (u[0::2] + 1j * u[1::2]) * np.exp(sign * lam * (t - t0))
        v = np.empty_like(u)
        v[0::2], v[1::2] = z.real, z.imag
        return v

    if form == "factor":
        def fun(t: float, z: np.ndarray) -> np.ndarray:
            problem.nonlinear(t, turn(z, t, 1.0), params, out)
            return turn(out, t, -1.0)

        def state(t: float, y: np.ndarray) -> np.ndarray:
            return turn(y, t, 1.0)
    elif form == "direct":
        def fun(t: float, u: np.ndarray) -> np.ndarray:
            problem.rhs(t, u, params, out)
            return out.copy()

        def state(t: float, y: np.ndarray) -> np.ndarray:
            return y
    else:
        raise ValueError(f"form={form!r}: expected factor or direct")
    rows = [problem.u0.astype(float)]
    if grid.size == 1:
        return np.array(rows), None
    # the integrating factor is 1 at t0: z(t0) = u0
    atol = SYSTEM_RTOL * 1e-3 * max(float(np.max(np.abs(problem.u0))), np.finfo(float).tiny)
    solver = DOP853(fun, t0, problem.u0.astype(float), float(grid[-1]), rtol=SYSTEM_RTOL, atol=atol)
    done = 1
    while done < grid.size:
        if time.perf_counter() > deadline:
            return np.array(rows), float(solver.t)
        solver.step()
        if solver.status == "failed":  # scipy's OdeSolver.status, not a row's
            raise ReferenceUnavailable(f"{SYSTEM} reference for {problem.name} stopped at t = {solver.t:.6g}")
        reached = int(np.searchsorted(grid, solver.t, side="right"))
        if solver.status == "finished":
            reached = grid.size
        if reached > done:
            dense = solver.dense_output()
            rows += [state(t, y) for t, y in zip(grid[done:reached], dense(grid[done:reached]).T)]
            done = reached
    return np.array(rows), None


def fp_type(precision: str):
    """heyoka's floating-point type of ``precision`` (one of PRECISIONS; else an InputError)."""
    if precision not in PRECISIONS:
        raise InputError(f"precision={precision!r} is not valid: expected one of {', '.join(PRECISIONS)}")
    if precision == "real128":
        import heyoka as hy

        return hy.real128
    return np.float64 if precision == "double" else np.longdouble


def _ladder() -> list[str]:
    """The precisions at hand, each finer than the one before (x86_64: all three; where long
    double is double, or already quadruple, the ladder is shorter)."""
    import heyoka as hy

    ladder, eps = ["double"], np.finfo(np.float64).eps
    if np.finfo(np.longdouble).eps < eps:
        ladder.append("long double")
        eps = np.finfo(np.longdouble).eps
    if hasattr(hy, "real128") and 2.0**-112 < eps:
        ladder.append("real128")
    return ladder


def start_integrator(problem: Problem, precision: str, deadline: float):
    """The problem's heyoka integrator in ``precision``, set to (t0, u0); its compile counts
    against the run's budget (``deadline``, a perf_counter time)."""
    ident = (problem.identity(), precision)
    ta = _TAYLOR.get(ident)
    fp = fp_type(precision)
    if ta is None:
        try:
            ta = heyoka_build.taylor_adaptive(problem, problem.u0.astype(fp), deadline - time.perf_counter(),
                                              high_accuracy=True, fp_type=fp, time=fp(problem.t0),
                                              compact_mode=heyoka_build.compact_mode(problem, fp, reference=True))
        except heyoka_build.CompileTimeout as exc:
            raise ReferenceUnavailable(f"{exc}: past the reference's time budget "
                                       f"({BUDGET_VARIABLE})") from None
        _TAYLOR[ident] = ta
    ta.time = fp(problem.t0)
    ta.state[:] = problem.u0.astype(fp)
    return ta
