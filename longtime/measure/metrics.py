"""The quantities of docs/metrics.md, computed the same way for every scheme.

e_I(t) = |I(u(t)) - I(u0)| / |I(u0)| (a vector invariant: Euclidean norms), the absolute
error where I(u0) = 0. Per invariant NAME: NAME.max, NAME.final, NAME.mean (time average of
e_I by the trapezoid rule over the samples, which are every step up to max_samples),
NAME.t_1pct, NAME.t_50pct (first sample time with e_I > 1 % / 50 %, null if never).
Against the reference, over the samples up to its horizon (``error_horizon`` is the last
one), every solution error is measured per block of the state (``Problem.blocks``: a body's
position, its momentum; by default each component), each block b relative to the size of
its own motion (``motion_scale``): S_b = sqrt(mean_i sum_{j in b} (u_ref,ij - line_j(t_i))^2),
line_j the least-squares line in t of component j (its mean and any drift taken out), so
that a drifting or constant component (charged-particle's x3 = 0.1 + 0.2 t) cannot hide a
lost solution, nor a body that moves little beside the others (Jupiter beside the outer
solar system's 53 AU) its loss. The error of block b at a sample is e_b(t) = |u_b -
u_ref,b| / S_b, and the solution error the largest block's: e(t) = max_b e_b(t);
``l2_error`` = max_b sqrt(mean_i |u_b,i - u_ref,b,i|^2) / S_b (``error_block`` names that
block); ``final_error`` = e at the last sample, null when the horizon ends before it;
``max_error`` = the largest e over the samples (what a setting keeps up to the horizon);
``l2_error_state`` and ``final_error_state`` are the same of the whole state as one block;
``error_curve`` keeps e's upper envelope and the largest block's l2_error up to each of its
times (``error_curve``); ``drifting_components`` counts the reference's components that
drift (``drifting_components``).
``error_floor`` is the reference's own error (``reference_error``, relative to the state)
in l2_error's units, reference_error x the reference's RMS size / S_b of l2_error's block; an l2_error or
final_error below it is not measured, only bounded by about twice the floor:
``error_below_floor`` says so, and the row's message. Where the problem discretises a PDE
(``pde_solution``), ``discretisation_error`` is the l2_error of the PDE's solution against
the reference, the system's own solution: the space discretisation's share, which no
time step removes.
Growth law of each error (longtime.measure.growth): NAME.growth, NAME.growth_ci, NAME.growth_class,
NAME.growth_reason, NAME.growth_windows, NAME.saturated_t per invariant, and the same as
``error.`` for the solution error e(t) over the samples up to the horizon. ``drift_curves``
keeps the drift curve of every invariant (``drift_curve``: the first one's alone).
Diagnostics (``Problem.diagnostics``: quantities watched, not conserved): diag.NAME.max and
diag.NAME.final of |D(t) - D(0)| / |D(0)| (absolute where D(0) = 0) and their curves in
``diag_curves``; never a growth class.
A problem that declares itself ``chaotic`` adds ``predictability_t``: the first sample time
at which the solution error e(t) reaches O1_ERROR (null where it stays below, or
without a reference).
Non-finite values become null: a diverged run is a status, never a NaN in a table.
"""
from __future__ import annotations

import math
from typing import Any, Callable

import numba
import numpy as np

from longtime.core.contract import check_name
from longtime.core.problem import Problem
from longtime.core.status import Status
from longtime.core.trajectory import Trajectory
from longtime.measure.block_errors import BlockErrors, Blocks, Motion
from longtime.measure.growth import growth_fields
from longtime.measure.lyapunov import predictability
from longtime.measure.reference import Trust, trust_fields

DRIFT_POINTS = 80  # points of the drift curve each row keeps (drift_envelope)
# a relative error (l2, final, or the solution error at a sample) from this on is O(1): the
# solution is not followed (a row's ``solution_lost``, a chaotic row's predictability horizon)
O1_ERROR = 0.5
# a component whose samples a straight line in t explains to this fraction drifts (drifting_components)
DRIFT_R2 = 0.9
WINDOW_POINTS = 1001  # reference states at log-spaced times of the run's first hundredth (motion_window)


def solution_lost(row: dict[str, Any]) -> tuple[bool | None, float | None]:
    """(lost, error): whether a row's solution is lost, its l2_error or final_error (each the
    largest block's) at least O1_ERROR, so that any one block lost loses it; None without a
    measured error."""
    worst = max((e for e in (row.get("l2_error"), row.get("final_error")) if e is not None), default=None)
    return (None if worst is None else bool(worst >= O1_ERROR)), worst


def finite_or_none(x) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


def relative_error(values: np.ndarray) -> np.ndarray:
    values = np.asarray(values, dtype=float)
    v0 = values[0]
    diff = values - v0
    if values.ndim == 1:
        num, den = np.abs(diff), abs(float(v0))
    else:
        num, den = np.linalg.norm(diff, axis=1), float(np.linalg.norm(v0))
    return num / den if den > 0 else num


def motion_scale(t: np.ndarray, reference: np.ndarray, window: tuple[np.ndarray, np.ndarray] | None = None) -> float:
    """S, the RMS size of the reference's motion over its samples: sqrt(detrended_ss / n),
    the larger of that over the samples and over ``window`` ((times, states) at log-spaced
    times of the run's start, ``motion_window``); the RMS size of the state where nothing
    moves. Samples evenly spaced by a period see a periodic motion at one phase only
    (kepler's 10,001 samples over 10,000 periods): the window's times alias with no period."""
    reference = np.asarray(reference, dtype=float)
    return float(BlockErrors.of(t, reference, reference, window).scales[0])


def motion_window(problem: Problem, t_end: float, trust: Trust | None) -> tuple[np.ndarray, np.ndarray] | None:
    """(times, reference states) at WINDOW_POINTS log-spaced times of [t0, t0 + W], W = the
    run's span / 100 (its first hundredth, where the reference is trusted), for
    ``motion_scale``; None where the reference cannot give them."""
    from longtime.measure.reference import reference_states
    from longtime.measure.reference_runs import ReferenceUnavailable

    span = min(float(t_end - problem.t0), float(trust.horizon - problem.t0)) if trust else float(t_end - problem.t0)
    if trust is None or not span > 0:
        return None
    times = problem.t0 + span / 100 * np.logspace(-3, 0, WINDOW_POINTS)
    precision = "double" if trust.source == "exact" else trust.source
    try:
        return times, reference_states(problem, times, precision)
    except (ReferenceUnavailable, ValueError, RuntimeError):
        return None


def solution_errors(t: np.ndarray, U: np.ndarray, reference: np.ndarray,
                    window: tuple[np.ndarray, np.ndarray] | None = None,
                    blocks: Blocks | None = None) -> tuple[np.ndarray, np.ndarray, float]:
    """(e, l2, S) of states ``U`` against ``reference`` at times ``t`` (BlockErrors): with
    ``blocks`` None the whole state's, S = motion_scale, e(t) = |u - u_ref| / S at each
    sample, l2 at each sample = the l2_error of the samples up to it (the l2_error a run
    ending there reports); with ``blocks``, e and l2 of the largest block at each sample
    and S the largest block's scale at the end."""
    errors = BlockErrors.of(t, U, reference, window, blocks)
    pointwise, l2 = errors.largest
    return pointwise, l2, float(errors.scales[errors.names.index(errors.worst)])


def drifting_components(t: np.ndarray, reference: np.ndarray, motion: Motion | None = None) -> int:
    """How many components of ``reference`` drift: their samples follow a straight line in t
    (coefficient of determination at least DRIFT_R2, charged-particle's x3 = 0.1 + 0.2 t)
    over the run; a component that oscillates about a mean over the run is no drift. The
    verdict's checks cover a drift-dominated problem. ``motion``: the reference's
    ``Motion``, whose centred times and states are read instead of centring them again."""
    t = np.asarray(t, dtype=float)
    if t.size < 3 or not np.ptp(t) > 0:
        return 0
    x, y = (motion.t, motion.x) if motion is not None else (t - t.mean(), reference - reference.mean(axis=0))
    slope = (x @ y) / (x @ x)
    explained = slope**2 * (x @ x)
    # numpy sums (samples, components >= 2) over the samples one sample after another, as
    # the motion's cumulative sums do: its sums give the same bits without another pass
    # (one component numpy sums pairwise)
    total = motion.sum_of_squares() if motion is not None and y.shape[1] >= 2 else (y**2).sum(axis=0)
    moving = total > 0
    return int(np.sum(explained[moving] >= DRIFT_R2 * total[moving]))


def error_curve(t: np.ndarray, pointwise: np.ndarray, l2_at: Callable[[np.ndarray], np.ndarray],
                points: int = DRIFT_POINTS) -> dict[str, Any] | None:
    """The solution error as a curve small enough to keep in the row: e(t)'s upper envelope
    (drift_envelope: ``t``, ``error``) and ``l2``, the l2_error over the samples up to each
    of those times (6 significant digits; ``l2_at`` gives it at sample indices). Predictions
    at a horizon within the run read it."""
    curve = drift_envelope("solution", t, pointwise, points, kind="curve")
    if curve is None:
        return None
    tau = t - t[0]
    idx = np.clip(np.searchsorted(tau, np.asarray(curve["t"]) * (1 + 1e-9), side="right") - 1, 0, t.size - 1)
    curve["l2"] = six_digits(l2_at(idx))
    return curve


def six_digits(values: np.ndarray) -> list[float]:
    """``values`` rounded to 6 significant digits, as a row keeps a curve's points:
    float(f"{v:.6g}") of each, computed in floating point where that is exact
    (``_six_digits``), else by the formatting itself."""
    values = np.ascontiguousarray(values, dtype=float).reshape(-1)
    out, exact = np.empty(values.size), np.empty(values.size, dtype=np.bool_)
    _six_digits(values, _POW10, out, exact)
    rounded = out.tolist()
    for i in np.flatnonzero(~exact).tolist():
        rounded[i] = float(f"{float(values[i]):.6g}")
    return rounded


_POW10 = np.array([float(10**k) for k in range(23)])  # 10^0 .. 10^22, each exact in a double


@numba.njit(cache=True)
def _six_digits(values, pow10, out, exact):
    """float(f"{v:.6g}") of each value where floating point gets it exactly, with
    ``exact`` False elsewhere (0, not finite, below 1e-17 or from 1e28 on, or a product
    within 1e-9 of a rounding tie or of a decade's ends). Python rounds |v| to the
    6-digit decimal D = round(Y) 10^-p, Y = |v| 10^p in [1e5, 1e6), and reads D back to the
    nearest double. Here y = |v| 10^p is one correctly rounded operation on exact
    operands (10^p exact up to 10^22), so |y - Y| <= half an ulp of y (below 6e-11):
    away from a tie round(y) = round(Y) = q, and q / 10^p (or q 10^-p) is one
    correctly rounded operation on exact operands, the double nearest D. Written by hand:
    a few operations per value instead of formatting and parsing a string."""
    for i in range(values.size):
        v = values[i]
        a = abs(v)
        exact[i] = False
        out[i] = v
        if not (a > 0 and a < np.inf):
            continue
        p = 5 - int(math.floor(math.log10(a)))
        y = 0.0
        for _ in range(2):  # log10's decade may be one off at a power of 10
            if p > 22 or p < -22:
                break
            y = a * pow10[p] if p >= 0 else a / pow10[-p]
            if y < 1e5:
                p += 1
            elif y >= 1e6:
                p -= 1
            else:
                break
        if not (1e5 + 1e-9 < y < 1e6 - 1e-9) or p > 22 or p < -22:
            continue
        whole = math.floor(y)
        frac = y - whole  # exact: y and whole are within 1 of each other
        if abs(frac - 0.5) < 1e-9:
            continue
        q = whole + 1.0 if frac > 0.5 else whole
        r = q / pow10[p] if p >= 0 else q * pow10[-p]
        out[i] = -r if v < 0 else r
        exact[i] = True


def time_mean(t: np.ndarray, y: np.ndarray) -> float:
    span = float(t[-1] - t[0])
    if t.size < 2 or span <= 0:
        return float(y[-1])
    return float(np.trapezoid(y, t) / span)


def first_crossing(t: np.ndarray, err: np.ndarray, level: float) -> float | None:
    above = np.flatnonzero(~(err <= level))  # NaN counts as crossed
    return float(t[above[0]]) if above.size else None


def drift_fields(name: str, t: np.ndarray, err: np.ndarray) -> dict[str, Any]:
    finite = np.isfinite(err)
    upto = int(np.argmin(finite)) if not finite.all() else err.size
    tt, ee = t[:upto], err[:upto]
    if upto < 2:  # the initial sample alone measures no drift: null, never 0
        return {f"{name}.{k}": None for k in ("max", "mean", "final", "t_1pct", "t_50pct")}
    return {
        f"{name}.max": finite_or_none(np.max(ee)),
        f"{name}.mean": finite_or_none(time_mean(tt, ee)),
        f"{name}.final": finite_or_none(err[-1]),
        f"{name}.t_1pct": first_crossing(t, err, 0.01),
        f"{name}.t_50pct": first_crossing(t, err, 0.5),
    }


def drift_envelope(name: str, t: np.ndarray, err: np.ndarray, points: int = DRIFT_POINTS,
                   kind: str = "invariant") -> dict[str, Any] | None:
    """A drift curve small enough to keep in the row: e_I at the sample where it is largest
    within each of ``points`` log-spaced bins of t - t0 (its upper envelope, so a bounded
    but oscillating error keeps its peaks), 6 significant digits. The results page draws
    it; nothing has to be run again to show how the error grew. ``kind`` names the key
    that holds ``name`` ("invariant", or "diagnostic" for a diagnostic's curve)."""
    t, err = np.ascontiguousarray(t, dtype=float), np.ascontiguousarray(err, dtype=float)
    first, last = _kept_ends(t, err)
    if first == last:  # fewer than two samples kept
        return None
    edges = np.logspace(np.log10(t[first] - t[0]), np.log10(t[last] - t[0]), points + 1)
    peaks = np.empty(points, dtype=np.int64)
    count = _envelope_peaks(t, err, edges, peaks)
    if count < 0:  # times out of order: more runs than bins
        peaks = np.empty(t.size, dtype=np.int64)
        count = _envelope_peaks(t, err, edges, peaks)
    peaks = peaks[:count]
    return {kind: name, "t": six_digits(t[peaks] - t[0]), "error": six_digits(err[peaks])}


@numba.njit(cache=True)
def _kept_ends(t, err):
    """(first, last): the first and the last sample that drift_envelope keeps (t - t[0] > 0,
    err finite); (-1, -1) without one. Each scan stops at its first kept sample."""
    first = last = -1
    for i in range(t.size):
        if t[i] - t[0] > 0 and np.isfinite(err[i]):
            first = i
            break
    for i in range(t.size - 1, first - 1 if first >= 0 else t.size, -1):
        if t[i] - t[0] > 0 and np.isfinite(err[i]):
            last = i
            break
    return first, last


@numba.njit(cache=True)
def _envelope_peaks(t, err, edges, peaks):
    """drift_envelope's peaks: over the kept samples (t - t[0] > 0, err finite), each in bin
    searchsorted(edges, t - t[0], "right") - 1 clipped to the bins, the sample where err is
    largest (the first of equals, as np.argmax) within each run of one bin, written to
    ``peaks``; the count of runs, or -1 where ``peaks`` is too short. One pass instead of
    numpy's masks, copies, bins and an argmax per run."""
    bins = edges.size - 1
    j = -1  # the last edge at or below tau: edges ascend, the samples move it a step or two
    count, run, best = 0, -1, 0.0
    for i in range(t.size):
        tau, e = t[i] - t[0], err[i]
        if not (tau > 0 and np.isfinite(e)):
            continue
        while j + 1 < edges.size and edges[j + 1] <= tau:
            j += 1
        while j >= 0 and edges[j] > tau:
            j -= 1
        b = min(max(j, 0), bins - 1)
        if count == 0 or b != run:
            if count == peaks.size:
                return -1
            peaks[count], run, best = i, b, e
            count += 1
        elif e > best:
            peaks[count - 1], best = i, e
    return count


def discretisation_error(problem: Problem, t: np.ndarray, errors: BlockErrors) -> float | None:
    """The l2_error of the problem's ``pde_solution`` at the times ``t`` against the
    reference (the system's solution) of the row's ``errors`` (its blocks and their motion
    scales), as a row's: how far the space discretisation alone is from the PDE."""
    return finite_or_none(errors.final_l2(problem.pde_solution(t)).max())


def floor_fields(row: dict[str, Any], trust: Trust | None, reference: np.ndarray, scale: float,
                 notes: list[str]) -> dict[str, Any]:
    """``error_floor`` (the reference's error in l2_error's units: reference_error times the
    reference's RMS size over the motion scale ``scale``) and ``error_below_floor`` (the
    row's l2_error or final_error is below it: not measured); null without a checked
    reference. A row below the floor says so in ``notes``."""
    if trust is None or trust.error is None or not scale > 0:
        return {"error_floor": None, "error_below_floor": None}
    size = math.sqrt(float(np.mean(np.sum(np.asarray(reference, dtype=float) ** 2, axis=1))))
    floor = finite_or_none(trust.error * size / scale)
    if floor is None:
        return {"error_floor": None, "error_below_floor": None}
    below = [(k, row[k]) for k in ("l2_error", "final_error") if row.get(k) is not None and row[k] < floor]
    if below:
        notes.append(", ".join(f"{k} {v:.2g}" for k, v in below) + f" below the reference's error {floor:.2g} "
                     f"({trust.basis}): not measured, only bounded by about {2 * floor:.2g}")
    return {"error_floor": floor, "error_below_floor": bool(below)}


def diagnostic_fields(problem: Problem, t: np.ndarray, U: np.ndarray, notes: list[str]) -> dict[str, Any]:
    """``diag.NAME.max``, ``diag.NAME.final`` (the change |D(t) - D(0)| relative to |D(0)|,
    absolute where D(0) = 0, as for an invariant) and ``diag_curves`` (its envelope, as
    drift_envelope) of each of the problem's diagnostics; a non-finite value on a finite
    state is named in ``notes``. Diagnostics are watched, never classed."""
    out: dict[str, Any] = {}
    curves = []
    for name, values in problem.diagnostics(t, U).items():
        change = relative_error(values)
        finite = np.isfinite(change)
        upto = change.size if finite.all() else int(np.argmin(finite))
        measured = upto >= 2  # the initial state alone measures nothing: null, never 0
        out[f"diag.{name}.max"] = finite_or_none(np.max(change[:upto])) if measured else None
        out[f"diag.{name}.final"] = finite_or_none(change[-1]) if measured else None
        curve = drift_envelope(name, t, change, kind="diagnostic")
        if curve is not None:
            curves.append(curve)
        if not finite.all():
            notes.append(f"diagnostic {name} is not finite from t = {t[upto]:.6g} on a finite state")
    out["diag_curves"] = curves or None
    return out


def evaluate(problem: Problem, traj: Trajectory, reference: np.ndarray | None,
             trust: Trust | None = None) -> dict[str, Any]:
    """Row fields of one trajectory. ``reference`` holds the true states at the leading
    samples traj.t[:len(reference)], those up to the reference's horizon (``trust``): the
    errors cover those samples only; final_error is null unless they reach the last one.
    """
    t, U = traj.t, traj.u
    steps = traj.steps
    span = float(t[-1] - problem.t0)
    row: dict[str, Any] = {
        "steps": steps,
        **{k: v for k, v in traj.counters.items() if k != "steps"},
        "cpu_s": traj.cpu_s,
        "wall_s": traj.wall_s,
        "mean_dt": span / steps if steps else None,
        "min_dt": traj.min_dt,
        "max_dt": traj.max_dt,
        "t_reached": float(t[-1]),
        "samples": int(t.size),
        "l2_error": None,  # null unless a reference is at hand
        "final_error": None,
        "max_error": None,  # the largest block's largest error up to the horizon
        "l2_error_state": None,  # the same of the whole state against its motion (one block)
        "final_error_state": None,
        "error_block": None,  # the block whose l2_error is the row's
        "error_horizon": None,  # the last sample time the errors cover
        "error_curve": None,  # the solution error's curve (null without a reference)
        "drifting_components": None,  # components of the reference that drift (null without one)
        "drift_curve": None,  # null: no invariant (the results page then runs nothing again)
        "drift_curves": None,  # every invariant's curve, in the problem's order
        "diag_curves": None,  # every diagnostic's curve
        **growth_fields("error", np.empty(0), np.empty(0), problem.t0),  # null without a reference
        **trust_fields(trust),
        "error_floor": None,  # null without a checked reference
        "error_below_floor": None,
    }
    if problem.pde_solution is not None:  # a discretised PDE: the space discretisation's error
        row["discretisation_error"] = None
    if problem.chaotic:  # the first time the solution error reaches O(1) (null: it never does)
        row["predictability_t"] = None
    # a diverged run ends on a non-finite state: measure the finite part (until the blow-up)
    finite = int(np.argmin(np.isfinite(U).all(axis=1))) if not np.isfinite(U).all() else t.size
    t, U = t[:finite], U[:finite]
    diverged = traj.status == Status.DIVERGED
    if finite == 0:
        return row
    notes: list[str] = []
    with np.errstate(all="ignore"):
        curves = []
        for k, (name, values) in enumerate(problem.invariants(t, U).items()):
            check_name("invariant", name)  # it names row fields (NAME.max) and the page's text
            err = relative_error(values)
            curves.append(drift_envelope(name, t, err))
            if k == 0:  # the first invariant (H where there is one: listed first)
                row["drift_curve"] = curves[0]
            row.update(drift_fields(name, t, err))
            row.update(growth_fields(name, t, err, problem.t0, diverged, steps=steps))
            bad = np.flatnonzero(~np.isfinite(err))
            if bad.size:  # a plugin's invariant on a finite state: say so, do not just null it
                notes.append(f"invariant {name} is not finite from t = {t[bad[0]]:.6g} on a finite state "
                             f"(its drift is measured up to there)")
        kept = [c for c in curves if c is not None]
        row["drift_curves"] = kept or None
        row.update(diagnostic_fields(problem, t, U, notes))
        for name, values in problem.violations(t, U).items():
            check_name("constraint violation", name)
            values = np.asarray(values, dtype=float)
            measured = values.size >= 2  # the initial state alone: not measured (null, never 0)
            row[f"{name}.max"] = finite_or_none(np.max(values)) if measured else None
            row[f"{name}.final"] = finite_or_none(values[-1]) if measured else None
        # the initial state alone says nothing about the error: at least one sample after t0
        k = min(len(reference), finite) if reference is not None else 0
        if k >= 2 and not np.isfinite(reference[:k]).all():
            bad = int(np.argmin(np.isfinite(reference[:k]).all(axis=1)))
            notes.append(f"the reference is not finite at t = {t[bad]:.6g}: no error measured")
        elif k >= 2:
            window = motion_window(problem, float(t[k - 1]), trust)
            per_block, state = BlockErrors.each(t[:k], U[:k], reference[:k], window,
                                                [Blocks.of(problem), Blocks.whole(problem.dim)])
            rel = per_block.peak
            row["l2_error"] = finite_or_none(per_block.final_l2().max())
            row["max_error"] = finite_or_none(np.max(rel))
            row["l2_error_state"] = finite_or_none(state.final_l2()[0])
            row["error_block"] = per_block.worst
            scale = float(per_block.scales[per_block.names.index(per_block.worst)])  # l2_error's motion
            if problem.pde_solution is not None:
                row["discretisation_error"] = discretisation_error(problem, t[:k], per_block)
            row["error_curve"] = error_curve(t[:k], rel, lambda rows: per_block.l2_at(rows).max(axis=1))
            row["drifting_components"] = drifting_components(t[:k], reference[:k], per_block.motion)
            # growth law of the error relative to the motion, up to the horizon
            row.update(growth_fields("error", t[:k], rel, problem.t0, diverged, steps=steps))
            row["error_horizon"] = float(t[k - 1])
            if problem.chaotic:
                row["predictability_t"] = predictability(t[:k], rel, O1_ERROR)
            if k == finite:
                row["final_error"] = finite_or_none(rel[-1])
                row["final_error_state"] = finite_or_none(state.pointwise[-1, 0])
            row.update(floor_fields(row, trust, reference[:k], scale, notes))
    row.update(traj.extra)
    if notes:
        row["message"] = "; ".join(notes)
    return row
