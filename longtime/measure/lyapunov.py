"""The maximal Lyapunov exponent of a problem's trajectory, measured from the reference
integrator, and the Lyapunov time 1/lambda that a chaotic problem's errors are read in.

Benettin's method with two nearby runs: heyoka (the reference's integrator in double:
tolerance eps, high accuracy) integrates the state u
and a companion v = u + d0 w (|w| = 1) over intervals of length tau; after each interval
the separation d = |v - u| gives ln(d / d0), and v is set back to u + d0 (v - u) / d. The
exponent is the mean of ln(d / d0) / tau over the intervals. Its 95 % interval comes from
the means of BLOCKS consecutive blocks of intervals (Student's t over the block means),
after the first block is dropped (the separation has not yet turned into the most unstable
direction). The exponent determines a Lyapunov time only where the separation grew faster
than any power of t could make it: over the span, lambda_low * span (the e-foldings of the
interval's lower end) must exceed POWER_FOLDINGS = 3 ln(INTERVALS), what a separation growing
like t^3 accumulates over the intervals. A regular orbit's separation grows like t (shear),
so its finite-time exponent falls like ln t / t and never passes; ``lyapunov_time`` is then
null with the reason.

d0 = 1e-8 relative to |u0|: large beside the integrator's error (eps per step), small
enough that the separation stays linear over tau (the renormalisation keeps it so). The
result is cached beside the references (same key: problem, settings, state, ODE, heyoka).
"""
from __future__ import annotations

import copy
import math
from typing import Any

import numpy as np

from longtime.core.problem import Problem

SEPARATION = 1e-8
INTERVALS = 400
BLOCKS = 8
POWER_FOLDINGS = 3 * math.log(INTERVALS)


def span(problem: Problem) -> float:
    """The time the exponent is measured over: the problem's ``lyapunov_span`` if it gives
    one, else its default final time."""
    return float(getattr(problem, "lyapunov_span", None) or problem.default_t_final)


# measured exponents of this process, by problem identity, initial state and span: every row
# of a chaotic problem reads one, and the disk cache's key is not free to compute
_MEASURED: dict[tuple, dict[str, Any]] = {}


def measure(problem: Problem, t_span: float | None = None, budget_s: float = 60.0) -> dict[str, Any]:
    """{"lyapunov_exponent", "lyapunov_exponent_ci", "lyapunov_time", "lyapunov_span",
    "lyapunov_note"} of ``problem`` from its initial state (cached)."""
    t_span = span(problem) if t_span is None else float(t_span)
    key = (problem.identity(), problem.u0.tobytes(), t_span)
    if key not in _MEASURED:
        _MEASURED[key] = _measure(problem, t_span, budget_s)
    return dict(_MEASURED[key])


def _measure(problem: Problem, t_span: float, budget_s: float) -> dict[str, Any]:
    return summarise(separations(problem, t_span, budget_s), t_span / INTERVALS, t_span)


def separations(problem: Problem, t_span: float, budget_s: float, cached_only: bool = False) -> np.ndarray | None:
    """ln(d / d0) of each of the INTERVALS intervals over [t0, t0 + ``t_span``] (NaN from
    where the budget ran out), cached beside the references: the Lyapunov exponent's data,
    and summed, the growth of a perturbation (longtime.measure.instability).
    ``cached_only``: None where they are not cached (nothing is integrated)."""
    from longtime.measure import reference_files

    path = reference_files.cache_path(problem, "lyapunov", repr(float(t_span)),
                                      repr((SEPARATION, INTERVALS, BLOCKS)), suffix=".npy")
    logs = reference_files.load_cached(path, lambda: np.load(path))
    if logs is None and cached_only:
        return None
    if logs is None:
        logs = _separations(problem, t_span, budget_s)
        reference_files.save_cached(path, logs)
    return logs


def _separations(problem: Problem, t_span: float, budget_s: float) -> np.ndarray:
    """ln(d / d0) of each interval (NaN from where the budget ran out)."""
    import time

    from longtime.measure import reference_runs

    if problem.heyoka_system is None:
        raise ValueError(f"problem {problem.name} has no heyoka system: its Lyapunov exponent is not measured")
    u0 = problem.u0.astype(float)
    d0 = SEPARATION * max(1.0, float(np.linalg.norm(u0)))
    w = np.random.default_rng(0).standard_normal(u0.size)
    deadline = time.perf_counter() + budget_s
    # the reference's own integrator (double, tolerance eps), compiled once per process for the
    # reference and copied here: measuring the exponent compiles nothing more
    base = reference_runs.start_integrator(problem, "double", deadline)
    ta_u, ta_v = copy.deepcopy(base), copy.deepcopy(base)
    ta_u.state[:] = u0
    ta_v.state[:] = u0 + d0 * w / np.linalg.norm(w)
    tau = t_span / INTERVALS
    logs = np.full(INTERVALS, np.nan)
    for k in range(INTERVALS):
        t_next = problem.t0 + (k + 1) * tau
        ta_u.propagate_until(t_next)
        ta_v.propagate_until(t_next)
        diff = np.asarray(ta_v.state) - np.asarray(ta_u.state)
        d = float(np.linalg.norm(diff))
        if not (math.isfinite(d) and d > 0) or time.perf_counter() > deadline:
            break
        logs[k] = math.log(d / d0)
        ta_v.state[:] = np.asarray(ta_u.state) + diff * (d0 / d)
    return logs


def summarise(logs: np.ndarray, tau: float, t_span: float) -> dict[str, Any]:
    """The exponent, its interval and the Lyapunov time from the intervals' ln(d / d0)."""
    from scipy.special import stdtrit

    out: dict[str, Any] = {"lyapunov_exponent": None, "lyapunov_exponent_ci": None, "lyapunov_time": None,
                           "lyapunov_span": float(t_span), "lyapunov_note": ""}
    logs = np.asarray(logs, dtype=float)
    done = int(np.argmin(np.isfinite(logs))) if not np.isfinite(logs).all() else logs.size
    per_block = done // BLOCKS
    if per_block < 2:
        out["lyapunov_note"] = f"undetermined: {done} of {logs.size} intervals measured (too few for {BLOCKS} blocks)"
        return out
    blocks = logs[:per_block * BLOCKS].reshape(BLOCKS, per_block).mean(axis=1)[1:] / tau
    lam = float(blocks.mean())
    half = float(stdtrit(blocks.size - 1, 0.975) * blocks.std(ddof=1) / math.sqrt(blocks.size))
    out["lyapunov_exponent"] = lam
    out["lyapunov_exponent_ci"] = [lam - half, lam + half]
    text = f"lambda = {lam:.3g} [{lam - half:.3g}, {lam + half:.3g}] over t = {t_span:g}"
    if (lam - half) * t_span > POWER_FOLDINGS:
        out["lyapunov_time"] = 1.0 / lam
        out["lyapunov_note"] = f"{text} ({(lam - half) * t_span:.3g} e-foldings at least)"
    else:
        out["lyapunov_note"] = (f"undetermined: {text}, {max(0.0, (lam - half) * t_span):.3g} e-foldings at least, "
                                f"no more than a separation growing like t^3 makes ({POWER_FOLDINGS:.3g}): no sign "
                                "of chaos on this span")
    return out


def predictability(t: np.ndarray, rel_error: np.ndarray, level: float) -> float | None:
    """The first sample time at which the relative solution error reaches ``level`` (None:
    it stays below): the row's predictability horizon."""
    above = np.flatnonzero(~(np.asarray(rel_error) < level))
    return float(t[above[0]]) if above.size else None


def row_fields(problem: Problem, row: dict[str, Any]) -> dict[str, Any]:
    """A chaotic problem's row fields beside its errors: the Lyapunov time of its initial
    state (``lyapunov_time``, ``lyapunov_exponent``, ``lyapunov_note``) and the row's
    predictability horizon in Lyapunov times (``predictability_lyapunov``: its
    ``predictability_t`` / lyapunov_time; ``predictability_note`` says what bounds it where
    the error never reached O(1) within the reference's horizon)."""
    try:
        found = measure(problem)
    except Exception as exc:  # no heyoka system, a compile past its budget: said, not fatal
        found = {"lyapunov_exponent": None, "lyapunov_exponent_ci": None, "lyapunov_time": None,
                 "lyapunov_span": span(problem), "lyapunov_note": f"not measured: {exc}"}
    out = {k: found[k] for k in ("lyapunov_time", "lyapunov_exponent", "lyapunov_note")}
    chaotic_from = getattr(problem, "chaotic_settings", None)
    if found["lyapunov_time"] is None and chaotic_from and any(
            problem.settings.get(k) != v for k, v in chaotic_from.items()):
        # no chaos from this state of a problem measured chaotic elsewhere: the row says where
        where = ",".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in chaotic_from.items())
        out["lyapunov_note"] += f"; the motion is measured chaotic with --set {where} (docs/problems.md)"
    t_lyap, t_lost, horizon = found["lyapunov_time"], row.get("predictability_t"), row.get("error_horizon")
    out["predictability_lyapunov"] = t_lost / t_lyap if t_lyap and t_lost is not None else None
    if horizon is None:
        note = "no reference error measured"
    elif t_lost is None:
        note = f"the error stays below O(1) up to t = {horizon:.6g}, the reference's horizon" + (
            f" ({horizon / t_lyap:.3g} Lyapunov times): the predictability horizon lies beyond" if t_lyap else "")
    else:
        note = f"the error reaches O(1) at t = {t_lost:.6g}" + (f" ({t_lost / t_lyap:.3g} Lyapunov times)"
                                                               if t_lyap else " (no Lyapunov time determined)")
    out["predictability_note"] = note
    return out


def past_predictability(row: dict[str, Any]) -> bool:
    """True for a row whose solution error reached O(1) (``predictability_t``): its L2 error
    measures a lost solution, not accuracy, and enters no order fit and no Pareto front."""
    return row.get("predictability_t") is not None
