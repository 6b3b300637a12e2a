"""Reference trajectories, and how far they are trusted.

A cell's reference is its problem's exact solution where it has one, else heyoka's adaptive
Taylor integrator at machine-epsilon tolerance with ``high_accuracy`` (compensated summation
for long runs), evaluated at the cell's samples through ``propagate_grid`` (dense output, so
heyoka's own steps are not clipped) and cached on disk; an exact solution on a grid of at
least EXACT_DISK_SAMPLES times is cached on disk too.

``reference_check`` estimates the reference's error, once per problem, initial state and
final time (cached on disk): heyoka in double is compared with heyoka in long double (80-bit
on x86_64) on a check grid of about CHECK_POINTS times, every k-th step of the double run,
so fast passages (a pericentre) are sampled as densely as heyoka resolves them. The relative
difference estimates the double reference's error; the horizon is the last check time up to
which it stays <= REFERENCE_RTOL. Where that horizon ends before t_final (chaos), long double
is checked against real128 the same way, and the cells use the long-double reference when
its horizon is the longer one. An exact solution is compared with the long-double run; one
without a heyoka system carries the accuracy its problem declares (``exact_rtol``). Every
heyoka run has the wall-time budget $LONGTIME_REFERENCE_SECONDS (default 120): a check that
passes it trusts the reference at most as far as it got, and says so.

A problem that is a discretisation without a heyoka system (kdv's Fourier-Galerkin system:
a diagonal linear part, ``linear_part`` and ``nonlinear``) has as its reference the solution
of that system, the one its schemes integrate: DOP853 at rtol SYSTEM_RTOL on the
integrating-factor form z = exp(-L (t - t0)) u, z' = exp(-L (t - t0)) N(exp(L (t - t0)) z),
whose rate is the nonlinear term's alone, dense output at the samples. Its check integrates
the system itself (u' = L u + N(u)) by DOP853 at the same tolerance on the check grid: two
formulations, two step sequences; their relative difference is ``reference_error``. Its
solution of the PDE (``pde_solution``) is not the reference: the row's
``discretisation_error`` measures how far it is (longtime.measure.metrics).
"""
from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from longtime.core.cache import digest
from longtime.core.params import InputError
from longtime.core.problem import Problem
from longtime.measure.reference_files import cache_path, load_cached, problem_chunks, save_cached
from longtime.measure.reference_runs import (
    BUDGET_VARIABLE,
    SYSTEM,
    SYSTEM_RTOL,
    ReferenceUnavailable,
    _ladder,
    budget_seconds,
    fp_type,
    propagate,
    start_integrator,
    system_states,
)

# the relative accuracy a heyoka reference must keep to be trusted (the horizon's level)
REFERENCE_RTOL = 1e-8
CHECK_POINTS = 2000  # the check grid holds between this many and twice as many times
_CHECKS: dict[str, dict[str, Any]] = {}  # check runs already loaded in this process
# exact solutions already evaluated in this process, by problem and sample times: the cells of
# one problem share their sample grids (every scheme at one dt), and an exact solution such
# as kepler's long-double Newton solve is paid once a grid; the oldest entries go past _EXACT_KEEP
_EXACT: dict[str, np.ndarray] = {}
_EXACT_KEEP = 64
# an exact solution on a grid of at least this many times is also cached on disk: each cell
# runs in its own process, where the in-process cache holds nothing yet
EXACT_DISK_SAMPLES = 10_000


@dataclass(frozen=True)
class Trust:
    """How far a problem's reference is trusted over [t0, t_final] (see ``reference_check``).

    ``error`` estimates the relative error of the reference states: the maximum over the
    check times in [t0, horizon] of |u_ref(t) - u_hi(t)| / |u_hi(t)| (Euclidean norms), u_hi
    the heyoka run in the next precision, or the accuracy the problem declares for its exact
    solution (``exact_rtol``); None when nothing could check it. ``horizon`` is the last
    check time up to which that estimate stays <= ``rtol``.
    """

    source: str  # "exact", or the precision of the heyoka reference the cells use
    rtol: float
    horizon: float
    error: float | None
    basis: str  # what was compared
    note: str = ""  # a time budget that ran out, a declared accuracy

    def fields(self) -> dict[str, Any]:
        name = self.source if self.source in ("exact", SYSTEM) else f"heyoka {self.source}"
        return {"reference": name,
                "reference_error": self.error, "reference_horizon": self.horizon,
                "reference_rtol": self.rtol}

    def message(self, t_end: float) -> str:
        """What a row ending at ``t_end`` must say about its reference ('' if nothing)."""
        parts = [self.note] if self.note else []
        if self.horizon < t_end - _slack(t_end):
            parts.append(f"reference trusted to {self.rtol:g} only up to t = {self.horizon:.6g} "
                         f"({self.basis}); errors measured up to there")
        return "; ".join(parts)


def trust_fields(trust: Trust | None) -> dict[str, Any]:
    """The row fields of ``trust``; all null without a reference."""
    if trust is None:
        return dict.fromkeys(("reference", "reference_error", "reference_horizon", "reference_rtol"))
    return trust.fields()


def _slack(t: float) -> float:
    return 1e-12 * max(1.0, abs(t))


def has_reference(problem: Problem) -> bool:
    caps = problem.capabilities()
    return "exact" in caps or "heyoka" in caps or "linear_part" in caps


def integrates_system(problem: Problem) -> bool:
    """The reference is the integrating-factor solution of the problem's system (see the
    module): no exact solution, no heyoka system, a diagonal linear part."""
    return (problem.exact is None and problem.heyoka_system is None
            and "linear_part" in problem.capabilities())


def trusted_reference(problem: Problem, times: np.ndarray, t_final: float,
                      budget_s: float | None = None) -> tuple[np.ndarray, Trust]:
    """The reference states at the leading ``times`` up to the horizon of the check over
    [t0, t_final], and that check. Raises ReferenceUnavailable when no time after t0 is
    trusted (a check that passed its time budget at once)."""
    trust = reference_check(problem, t_final, budget_s)
    k = int(np.searchsorted(times, trust.horizon + _slack(trust.horizon), side="right"))
    if k < 2:
        raise ReferenceUnavailable(trust.note or f"not trusted past t = {trust.horizon:.6g} ({trust.basis})")
    precision = "double" if trust.source == "exact" else trust.source
    return reference_states(problem, times[:k], precision, budget_s), trust


def reference_states(problem: Problem, times: np.ndarray, precision: str = "double",
                     budget_s: float | None = None) -> np.ndarray:
    """States (len(times), dim) of the problem's true trajectory from problem.u0 at t0: the
    exact solution, else heyoka in ``precision``, else the integrating-factor solution of the
    system (``integrates_system``; ``precision`` is then not read), cached.

    Raises ReferenceUnavailable when heyoka stops early or takes more than ``budget_s``
    wall seconds (default $LONGTIME_REFERENCE_SECONDS or 120).
    """
    times = np.asarray(times, dtype=float)
    if problem.exact is not None:
        key = digest(*problem_chunks(problem), times.tobytes())
        if key not in _EXACT:
            while len(_EXACT) >= _EXACT_KEEP:
                del _EXACT[next(iter(_EXACT))]
            _EXACT[key] = _exact_states(problem, times)
        return _EXACT[key].copy()
    system = integrates_system(problem)
    if problem.heyoka_system is None and not system:
        raise InputError(f"problem '{problem.name}' has neither an exact solution nor a heyoka system")
    if system:
        precision = f"{SYSTEM} rtol={SYSTEM_RTOL!r}"
    else:
        fp_type(precision)  # validates
    path = cache_path(problem, "states", precision, times.tobytes(), suffix=".npy")
    def read():
        states = np.load(path)
        if states.shape != (times.size, problem.dim) or not np.isfinite(states).all():
            raise ValueError(f"holds {states.shape} states, expected {(times.size, problem.dim)}, all finite")
        return states

    cached = load_cached(path, read)
    if cached is not None:
        return cached
    # propagate_grid wants a strictly increasing grid that starts at the current time
    grid, inverse = np.unique(times, return_inverse=True)
    if grid[0] < problem.t0:
        raise InputError(f"reference times start at {grid[0]} < t0 = {problem.t0}")
    starts_later = grid[0] > problem.t0
    if starts_later:
        grid = np.r_[problem.t0, grid]
    if system:
        states, stopped = system_states(problem, grid, "factor", budget_s)
    else:
        states, stopped = propagate(problem, grid, precision, budget_s)
    if stopped is not None:
        what = SYSTEM if system else f"heyoka {precision}"
        raise ReferenceUnavailable(f"{what} reference for {problem.name} passed its time "
                                   f"budget at t = {stopped:.6g} (LONGTIME_REFERENCE_SECONDS)")
    states = states[int(starts_later):][inverse]
    save_cached(path, states)
    return states


def _exact_states(problem: Problem, times: np.ndarray) -> np.ndarray:
    """The problem's exact solution at ``times``, from the disk cache where the grid holds at
    least EXACT_DISK_SAMPLES times (kepler's long-double Newton solve costs more than reading
    it back) and the problem's module can be read: its source is part of the key, so an
    edited formula is another file. A solution of the wrong shape or not finite is returned
    as computed, never cached (the caller's checks name it)."""
    source = _source_digest(problem) if times.size >= EXACT_DISK_SAMPLES else None
    if source is None:
        return np.asarray(problem.exact(times), dtype=float)
    path = cache_path(problem, "exact", source, times.tobytes(), suffix=".npy")
    shape = (times.size, problem.dim)

    def read():
        states = np.load(path)
        if states.shape != shape or not np.isfinite(states).all():
            raise ValueError(f"holds {states.shape} states, expected {shape}, all finite")
        return states

    cached = load_cached(path, read)
    if cached is not None:
        return cached
    states = np.asarray(problem.exact(times), dtype=float)
    if states.shape == shape and np.isfinite(states).all():
        save_cached(path, states)
    return states


def _source_digest(problem: Problem) -> str | None:
    """A digest of the source files of the problem's class and of the classes it derives from
    (where its exact solution's code is), None where one has none to read (a class defined
    interactively)."""
    import inspect

    classes = [c for c in type(problem).__mro__ if c not in (Problem, object) and issubclass(c, Problem)]
    try:
        files = sorted({inspect.getsourcefile(c) or "" for c in classes})
        return digest(*(Path(f).read_bytes() for f in files))
    except (OSError, TypeError):
        return None


def reference_check(problem: Problem, t_final: float, budget_s: float | None = None) -> Trust:
    """How far the reference of ``problem`` is trusted over [t0, t_final] (see the module)."""
    if integrates_system(problem):
        return _system_check(problem, float(t_final), budget_s)
    ladder = _ladder()
    declared = problem.exact_rtol if problem.exact is not None else None
    rtol = max(REFERENCE_RTOL, declared or 0.0)
    if problem.heyoka_system is None or len(ladder) < 2:
        source = "exact" if problem.exact is not None else ladder[0]
        if declared is not None:
            return Trust(source, rtol, float(t_final), declared, "declared by the problem",
                         f"exact solution trusted to {declared:g} only (declared by the problem)")
        why = "no heyoka system" if problem.heyoka_system is None else "no precision above double here"
        return Trust(source, rtol, float(t_final), None, "unchecked", f"reference unchecked ({why})")
    runs = _check_runs(problem, float(t_final), ladder, budget_s)
    times, hi = runs["times"], runs[ladder[1]]
    note = ""
    if runs["stopped"]:
        p, t = min(runs["stopped"].items(), key=lambda item: item[1])
        note = f"the heyoka {p} reference check passed its time budget at t = {t:.6g} (LONGTIME_REFERENCE_SECONDS)"
    if problem.exact is not None:
        err = _relative(problem.exact(times[:len(hi)]), hi)
        return _trust("exact", rtol, times, np.maximum(err, declared or 0.0),
                      f"exact solution vs heyoka {ladder[1]}", note)
    trust = _trust(ladder[0], rtol, times, _relative(runs[ladder[0]][:len(hi)], hi),
                   f"heyoka {ladder[0]} vs {ladder[1]}", note)
    if len(ladder) > 2 and ladder[2] in runs:
        top = runs[ladder[2]]
        finer = _trust(ladder[1], rtol, times, _relative(hi[:len(top)], top),
                       f"heyoka {ladder[1]} vs {ladder[2]}; heyoka {ladder[0]} alone up to "
                       f"t = {trust.horizon:.6g}", note)
        if finer.horizon > trust.horizon:
            return finer
    return trust


def check_seconds_per_t(problem: Problem, span: float, budget_s: float = 5.0) -> float:
    """Wall seconds per unit of t that ``reference_check`` spends on ``problem`` (its heyoka
    runs in the first two precisions, not cached), timed over [t0, t0 + span] once the
    integrators are compiled; 0 where the check runs no heyoka (no heyoka system, or a
    declared accuracy). Its runs' cost grows with t at about this rate, so a caller can tell
    beforehand whether a check to some horizon fits a budget. The compile has the reference's
    budget (``budget_seconds``); a timed run that passes ``budget_s`` gives the rate of what
    it reached, inf if it reached nothing. Raises ReferenceUnavailable as the check would.
    A system's integrating-factor check (``integrates_system``) is timed the same way."""
    if integrates_system(problem):
        start = time.perf_counter()
        grid = np.linspace(problem.t0, problem.t0 + span, 3)
        _, stopped = system_states(problem, grid, "factor", budget_s)
        _, stopped_hi = system_states(problem, grid, "direct", max(start + budget_s - time.perf_counter(), 0.0))
        reached = min(t for t in (stopped, stopped_hi, grid[-1]) if t is not None) - problem.t0
        return (time.perf_counter() - start) / reached if reached > 0 else math.inf
    ladder = _ladder()
    if problem.heyoka_system is None or len(ladder) < 2:
        return 0.0
    compiled = time.perf_counter() + budget_seconds()
    for precision in ladder[:2]:
        start_integrator(problem, precision, compiled)  # the compile, once a process: not the rate
    start = time.perf_counter()
    deadline = start + budget_s
    times, _, stopped = _stepped_run(problem, problem.t0 + span, budget_s)
    _, stopped_hi = propagate(problem, times, ladder[1], max(deadline - time.perf_counter(), 0.0))
    reached = min(t for t in (stopped, stopped_hi, times[-1]) if t is not None) - problem.t0
    return (time.perf_counter() - start) / reached if reached > 0 else math.inf


def _trust(source: str, rtol: float, times: np.ndarray, err: np.ndarray, basis: str, note: str) -> Trust:
    bad = np.flatnonzero(~(err <= rtol))  # NaN counts as untrusted
    last = (bad[0] if bad.size else err.size) - 1
    if last < 0:  # not even the initial state agrees
        return Trust(source, rtol, float(times[0]), float(err[0]), basis, note)
    return Trust(source, rtol, float(times[last]), float(np.max(err[:last + 1])), basis, note)


def _relative(u: np.ndarray, hi: np.ndarray) -> np.ndarray:
    diff, norm = np.linalg.norm(u - hi, axis=1), np.linalg.norm(hi, axis=1)
    return diff / np.where(norm > 0, norm, 1.0)  # absolute at a zero state


def check_cached(problem: Problem, t_final: float) -> bool:
    """Whether a complete ``reference_check`` of ``problem`` over [t0, t_final] is on disk (or
    loaded in this process): then the check costs nothing more."""
    parts = ("check", repr(float(t_final)), str(CHECK_POINTS), repr(REFERENCE_RTOL), ",".join(_ladder()))
    path = cache_path(problem, *parts)
    return str(path) in _CHECKS or path.exists()


def _cached_check(paths: list[Path]) -> dict[str, Any] | None:
    """A reference check's runs from the first of ``paths`` held in this process or cached on
    disk (None: neither)."""
    for path in paths:
        if str(path) in _CHECKS:
            return _CHECKS[str(path)]

        def read(path=path):
            with np.load(path) as data:
                runs = {k: data[k] for k in data.files if k != "stopped"}
                runs["stopped"] = json.loads(str(data["stopped"]))
            return runs

        runs = load_cached(path, read)
        if runs is not None:
            _CHECKS[str(path)] = runs
            return runs
    return None


def _check_runs(problem: Problem, t_final: float, ladder: list[str],
                budget_s: float | None) -> dict[str, Any]:
    """The heyoka runs behind ``reference_check`` on its check grid, cached on disk: "times",
    one float64 array of states per precision run (rows reached), "stopped" {precision: t}
    for runs that passed their budget."""
    budget = budget_seconds() if budget_s is None else budget_s
    parts = ("check", repr(t_final), str(CHECK_POINTS), repr(REFERENCE_RTOL), ",".join(ladder))
    paths = [cache_path(problem, *parts), cache_path(problem, *parts, f"budget={budget!r}")]
    runs = _cached_check(paths)
    if runs is not None:
        return runs
    times, low, stopped = _stepped_run(problem, t_final, budget)
    runs: dict[str, Any] = {"times": times, ladder[0]: low}
    stops = {ladder[0]: stopped} if stopped is not None else {}
    hi, stopped = propagate(problem, times, ladder[1], budget)
    runs[ladder[1]] = hi
    if stopped is not None:
        stops[ladder[1]] = stopped
    if (problem.exact is None and len(ladder) > 2
            and np.any(~(_relative(low[:len(hi)], hi) <= REFERENCE_RTOL))):
        def found_out(rows: np.ndarray) -> bool:
            return bool(np.any(~(_relative(hi[:len(rows)], rows) <= REFERENCE_RTOL)))

        runs[ladder[2]], stopped = propagate(problem, times[:len(hi)], ladder[2], budget, found_out)
        if stopped is not None:
            stops[ladder[2]] = stopped
    runs["stopped"] = stops
    path = paths[1] if stops else paths[0]  # a partial check holds only for its budget
    save_cached(path, **{k: v for k, v in runs.items() if k != "stopped"}, stopped=np.array(json.dumps(stops)))
    _CHECKS[str(path)] = runs
    return runs


def _stepped_run(problem: Problem, t_final: float, budget_s: float) -> tuple[np.ndarray, np.ndarray, float | None]:
    """The double heyoka run from t0 to t_final, recorded at every k-th step: k doubles
    whenever 2 CHECK_POINTS steps are held. Returns (times, states, t where the budget
    stopped it or None); the last row is where it ended."""
    import heyoka as hy

    deadline = time.perf_counter() + budget_s  # the compile counts against the budget
    ta = start_integrator(problem, "double", deadline)
    times, states, stride, count = [problem.t0], [problem.u0.copy()], 1, 0

    def record(ta) -> bool:
        nonlocal stride, count
        count += 1
        if count % stride == 0:
            times.append(ta.time)
            states.append(ta.state.copy())
            if len(times) >= 2 * CHECK_POINTS:
                del times[1::2], states[1::2]
                stride *= 2
        return time.perf_counter() < deadline

    outcome = ta.propagate_until(float(t_final), callback=record)[0]
    if outcome not in (hy.taylor_outcome.time_limit, hy.taylor_outcome.cb_stop):
        raise ReferenceUnavailable(f"heyoka double check for {problem.name} stopped early: {outcome}")
    if times[-1] != ta.time:
        times.append(ta.time)
        states.append(ta.state.copy())
    stopped = ta.time if outcome == hy.taylor_outcome.cb_stop else None
    return np.array(times, dtype=float), np.array(states, dtype=float), stopped



def _system_check(problem: Problem, t_final: float, budget_s: float | None) -> Trust:
    """``reference_check`` of an integrating-factor reference: it against the system
    integrated directly on CHECK_POINTS + 1 evenly spaced times (cached on disk)."""
    budget = budget_seconds() if budget_s is None else budget_s
    parts = ("system-check", repr(t_final), str(CHECK_POINTS), repr(SYSTEM_RTOL))
    paths = [cache_path(problem, *parts), cache_path(problem, *parts, f"budget={budget!r}")]
    runs = _cached_check(paths)
    if runs is None:
        times = np.linspace(problem.t0, t_final, CHECK_POINTS + 1)
        factor, stop_factor = system_states(problem, times, "factor", budget)
        direct, stop_direct = system_states(problem, times, "direct", budget)
        stops = {k: v for k, v in (("factor", stop_factor), ("direct", stop_direct)) if v is not None}
        runs = {"times": times, "factor": factor, "direct": direct, "stopped": stops}
        path = paths[1] if stops else paths[0]  # a partial check holds only for its budget
        save_cached(path, times=times, factor=factor, direct=direct, stopped=np.array(json.dumps(stops)))
        _CHECKS[str(path)] = runs
    n = min(len(runs["factor"]), len(runs["direct"]))
    note = ""
    if runs["stopped"]:
        t = min(runs["stopped"].values())
        note = f"the {SYSTEM} reference check passed its time budget at t = {t:.6g} ({BUDGET_VARIABLE})"
    return _trust(SYSTEM, REFERENCE_RTOL, runs["times"], _relative(runs["factor"][:n], runs["direct"][:n]),
                  f"the system by an integrating factor vs directly (DOP853, rtol {SYSTEM_RTOL:g} both)", note)
