"""Statistical accuracy past the predictability horizon: on a chaotic problem a pointwise
error means nothing after a few Lyapunov times, but the distribution the orbit visits does.

An ensemble of K initial states, the problem's own perturbed by a seeded relative ``size``
(u0_k = u0 (1 + size z), z ~ N(0, 1) from rng([seed, k])), is integrated by the scheme and
by heyoka (double, the reference integrator at tolerance 1e-15). The observable (the
problem's ``chaos_observable`` where it declares one, else the first state component) is
pooled over the members and over the late window of the run (its last ``window`` share of
the span), and the two pools are compared by the 1-Wasserstein distance (scipy), divided by
the reference pool's standard deviation: 0 means the same distribution, 1 a shift by a
standard deviation.

How small a distance can be told from zero: the ensemble is finite, so two reference
ensembles of other seeds differ too. ``floor`` is the distance between the reference pool
and a second reference ensemble (seed + 1): a scheme's distance at or below it is as good
as the reference can show.
"""
from __future__ import annotations

import contextlib
import math
from typing import Any

import numpy as np

from longtime.core.integrator import Integrator
from longtime.core.problem import Problem
from longtime.core.status import Status

DEFAULT_MEMBERS = 16
DEFAULT_SIZE = 1e-6
DEFAULT_WINDOW = 0.5
GRID = 2001  # reference samples per member over the span
MAX_SAMPLES = 20_001
# a distance above this many floors is told apart from the reference
FLOOR_FACTOR = 2.0


def initial_states(problem: Problem, members: int, size: float, seed: int) -> list[np.ndarray]:
    return [problem.u0 * (1.0 + size * np.random.default_rng([seed, k]).standard_normal(problem.dim))
            for k in range(members)]


def observable(problem: Problem, t: np.ndarray, U: np.ndarray) -> tuple[str, np.ndarray]:
    """(name, values at the samples) of the problem's chaos observable."""
    declared = getattr(problem, "chaos_observable", None)
    if declared is not None:
        return declared(t, U)
    return "u[0]", U[:, 0]


@contextlib.contextmanager
def _started_at(problem: Problem, state: np.ndarray):
    """``problem`` starting from ``state`` inside the block, from its own initial state after."""
    u0 = problem.u0
    problem.u0 = state
    try:
        yield problem
    finally:
        problem.u0 = u0


def _late(t: np.ndarray, values: np.ndarray, t0: float, t_final: float, window: float) -> np.ndarray:
    keep = (t >= t_final - window * (t_final - t0)) & np.isfinite(values)
    return values[keep]


def _reference_pool(problem: Problem, states: list[np.ndarray], t_final: float, window: float,
                    budget_s: float | None = None) -> np.ndarray:
    from longtime.measure.reference_runs import propagate

    grid = np.linspace(problem.t0, t_final, GRID)
    pool = []
    for state in states:
        with _started_at(problem, state):
            U, stopped = propagate(problem, grid, "double", budget_s)
        if stopped is not None:
            raise RuntimeError(f"heyoka's ensemble run stopped at t = {stopped:.6g} (its time budget)")
        pool.append(_late(grid, observable(problem, grid, U)[1], problem.t0, t_final, window))
    return np.concatenate(pool)


def reference_pools(problem: Problem, t_final: float, members: int, size: float, seed: int, window: float,
                    budget_s: float | None = None, others: int = 1) -> tuple[np.ndarray, list[np.ndarray]]:
    """The reference pool (heyoka's ensemble of ``seed``) and ``others`` more (seeds + 1,
    + 2, ...) that the floor is measured against, cached beside the references (their key:
    the problem, its settings, state and ODE, heyoka's version; here also the ensemble's own
    parameters): every scheme of a problem is compared with the same pools, computed once."""
    from longtime.measure import reference_files

    key = repr((float(t_final), members, size, seed, window, GRID, others))
    path = reference_files.cache_path(problem, "ensemble", key)
    found = reference_files.load_cached(path, lambda: _read_pools(path))
    if found is not None:
        return found
    pools = [_reference_pool(problem, initial_states(problem, members, size, seed + k), t_final, window, budget_s)
             for k in range(others + 1)]
    reference_files.save_cached(path, **{f"pool{k}": pool for k, pool in enumerate(pools)})
    return pools[0], pools[1:]


def _read_pools(path) -> tuple[np.ndarray, list[np.ndarray]]:
    with np.load(path) as data:
        pools = [np.array(data[f"pool{k}"]) for k in range(len(data.files))]
    return pools[0], pools[1:]


def scheme_pool(problem: Problem, scheme: Integrator, t_final: float, members: int, size: float, seed: int,
                window: float, deadline: float | None = None) -> tuple[np.ndarray | None, dict[str, int]]:
    """The scheme's pool over the ensemble of ``seed``, and the count of each member's status.
    The pool is None unless every member ran to ``t_final`` (a member that diverged, failed
    or passed ``deadline``, a time.monotonic() value, is a status, never part of a number);
    the members after one that did not are not run."""
    pool, counts = [], {}
    for state in initial_states(problem, members, size, seed):
        with _started_at(problem, state):
            traj = scheme.integrate(problem, t_final, max_samples=MAX_SAMPLES, deadline=deadline)
        counts[traj.status] = counts.get(traj.status, 0) + 1
        if traj.status != Status.OK:
            return None, counts
        pool.append(_late(traj.t, observable(problem, traj.t, traj.u)[1], problem.t0, t_final, window))
    return np.concatenate(pool), counts


def distance(pool: np.ndarray, reference: np.ndarray) -> float | None:
    """W1(pool, reference) / std(reference) (None where the reference does not vary)."""
    from scipy.stats import wasserstein_distance

    scale = float(np.std(reference))
    return float(wasserstein_distance(pool, reference)) / scale if scale > 0 else None


def measure(problem: Problem, scheme: Integrator, t_final: float, members: int = DEFAULT_MEMBERS,
            size: float = DEFAULT_SIZE, seed: int = 1, window: float = DEFAULT_WINDOW) -> dict[str, Any]:
    """The ensemble's fields: ``ensemble.distance`` (W1 / std of the reference pool),
    ``ensemble.floor`` (the same between two reference ensembles), ``ensemble.observable``,
    ``ensemble.members`` (those that ran to t_final), ``ensemble.size``, ``ensemble.window``
    and ``ensemble.note``."""
    states = initial_states(problem, members, size, seed)
    name = observable(problem, np.array([problem.t0]), problem.u0[None, :])[0]
    out: dict[str, Any] = {"ensemble.observable": name, "ensemble.size": size, "ensemble.window": window,
                           "ensemble.distance": None, "ensemble.floor": None, "ensemble.members": 0,
                           "ensemble.note": ""}
    pool, lost = [], 0
    for state in states:
        with _started_at(problem, state):
            traj = scheme.integrate(problem, t_final, max_samples=MAX_SAMPLES)
        if traj.status != Status.OK:
            lost += 1
            continue
        pool.append(_late(traj.t, observable(problem, traj.t, traj.u)[1], problem.t0, t_final, window))
    out["ensemble.members"] = len(pool)
    if not pool:
        out["ensemble.note"] = f"no member ran to t = {t_final:g} ({lost} diverged or failed)"
        return out
    reference, (second,) = reference_pools(problem, t_final, members, size, seed, window)
    if distance(second, reference) is None:
        out["ensemble.note"] = "the reference's observable does not vary over the window"
        return out
    out["ensemble.distance"] = distance(np.concatenate(pool), reference)
    out["ensemble.floor"] = distance(second, reference)
    note = (f"{len(pool)} of {members} members; W1 of {name} over the last {window:.0%} of the span, in units of "
            f"the reference's standard deviation")
    if lost:
        note += f"; {lost} diverged or failed and are left out"
    out["ensemble.note"] = note
    return out


def distinguishable(d: float | None, floor: float | None) -> bool | None:
    """Whether a distance is told apart from the floor: above FLOOR_FACTOR x the floor (None:
    not measured)."""
    if d is None or floor is None or not math.isfinite(d):
        return None
    return d > FLOOR_FACTOR * floor


def verdict(fields: dict[str, Any]) -> str:
    """Whether the scheme's distribution is told apart from the reference's."""
    d, floor = fields.get("ensemble.distance"), fields.get("ensemble.floor")
    told = distinguishable(d, floor)
    if told is None:
        return "not measured"
    if not told:
        return "as the reference (within twice the ensembles' own spread)"
    return f"told apart from the reference ({d / floor:.3g} x the ensembles' own spread)" if floor > 0 else "differs"


def field_spread(problem: Problem, scheme: Integrator, t_final: float, field: str, members: int = 8,
                 size: float = 1e-14, seed: int = 1) -> dict[str, Any]:
    """The round-off spread of one row field (``I.max``, ``H.max``: a figure measured without a
    reference) of a chaotic run: its value from the problem's own initial state and over
    ``members`` initial states perturbed by a relative ``size`` (round-off's own scale). A
    documented figure of a chaotic run is worth the digits this spread leaves it."""
    from longtime.measure.metrics import evaluate

    def value(state: np.ndarray) -> float | None:
        with _started_at(problem, state):
            traj = scheme.integrate(problem, t_final, max_samples=MAX_SAMPLES * 5)
            row = evaluate(problem, traj, None, None)
        if field not in row:
            from longtime.core.params import InputError

            raise InputError(f"--field {field}: not a field of {problem.name}'s rows without a reference "
                             f"(for example {', '.join(k for k in row if k.endswith('.max'))})")
        return row[field]

    own = value(problem.u0)
    values = [value(s) for s in initial_states(problem, members, size, seed)]
    finite = [v for v in values if v is not None]
    return {"field": field, "value": own, "members": members, "size": size, "values": values,
            "min": min(finite) if finite else None, "max": max(finite) if finite else None}
