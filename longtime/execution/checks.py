"""The checks of the verdict's predictions: the main job re-runs groups of them, a winner
with its runner-up and open rivals so that the rank is tested, covering every class of
problem it ran (``plan_checks``, ``run_checks``), and stores the predicted beside the
measured error and cost (``Store.add_check``). What a check must meet is
longtime.predict.checks's."""
from __future__ import annotations

import contextlib
import math
import time
from dataclasses import dataclass
from typing import Any

from longtime.core.fmt import positive
from longtime.core.status import Status
from longtime.execution import calibration
from longtime.measure.instability import INITIAL_ROUNDING
from longtime.predict.checks import CHECK_BUDGET_S, CHECK_REFERENCE_S, CHECKS, judge_ranks
from longtime.predict.decision import TARGETS, Verdict, predictability, verdicts
from longtime.predict.settings import Measure, Setting, error_kept


@dataclass
class PlannedCheck:
    """One run of a check: ``setting`` re-run to ``horizon``. ``role``: "best" (the decision's
    winner: its predicted error and cost, and its rank), "runner-up" (its prediction), "open"
    (a cheaper setting whose law is undetermined: measured, so that the rank is tested),
    "chaos" (the most accurate setting past the predictability horizon of ``target``: its
    error must exceed ``target`` there) or "growth" (the same past the horizon the growth of
    a perturbation sets, ``_growth_group``). ``group`` names the decision the runs test and
    ``kind`` the class of problem it covers (CHECK_KINDS)."""
    setting: Setting
    horizon: float
    measure: Measure
    role: str
    target: float
    group: str
    kind: str

    def predicted_cpu(self) -> float:
        return self.setting.cpu_at(self.horizon)


# the classes of problem the checks cover, each before a second check of any: a chaotic
# problem (its predictability horizon); the classes a problem declares (``check_class``: an
# unstable orbit and close encounters, each with its growth check, a discretised PDE); a
# short run (a setting whose run spans under a tenth of its problem's default horizon,
# ``Setting.short``); a many-body state (declared); a drift-dominated one (a state component
# that drifts, ``drifting_components``, or a solution error whose energy drifts), an adaptive
# scheme (heyoka, a tolerance), a splitting (a scheme that needs a separable H), the rest
CHECK_KINDS = ("chaotic", "unstable orbit", "close encounters", "short run", "discretised PDE", "many-body",
               "drifting", "adaptive", "splitting", "other")
# the declared classes whose problem gets a growth check (``_growth_group``)
GROWTH_CLASSES = ("unstable orbit", "close encounters")
# a growth check's target is at least this (a hundred times the reference's trusted accuracy,
# longtime.measure.reference.REFERENCE_RTOL: an error above it is measured, not the reference's)
GROWTH_MIN_TARGET = 1e-6
# a growth check runs to where a rounding has grown to this many times its target: a run and
# the suite's reference start from the same rounded state, so only the steps' roundings
# separate them, and those grow less than a rounding of the state in every direction does
# (restricted-three-body, heyoka at tolerance eps: 1.8e-6 at t = 68.1 where a rounding of the
# state has grown to 1.2e-3)
GROWTH_CHECK_MARGIN = 1e3
# the checks' total wall-time estimate (seconds): each run's predicted CPU times TIMED_RUNS
# (its warm-up and timed repeats) plus its reference's time to the horizon, and the timing of
# each problem's reference rate: 12 s for the other classes' groups, and 4 s for a
# drift-dominated problem's group (charged-particle's at T = 1e4 in the default matrix: the
# timing of its reference rate, its reference to 1e4 and its four runs)
CHECKS_TOTAL_S = 16.0
TIMED_RUNS = 4
# a chaos check runs past the predictability horizon by this many Lyapunov times (e^5: the
# pointwise error grows 150 times past the target)
CHAOS_MARGIN_LYAPUNOV = 5.0


def _declared_class(problem: str) -> str | None:
    """The class of question a problem declares (``Problem.check_class``), None if none."""
    from longtime.core import registry

    with contextlib.suppress(Exception):
        return registry.problem_class(problem).check_class
    return None


def _group_kind(v: Verdict, runs: list[Setting]) -> str:
    from longtime.core import registry

    declared = _declared_class(v.problem)
    if declared in ("unstable orbit", "close encounters", "discretised PDE"):
        return declared
    if any(s.short for s in runs):
        return "short run"
    if declared == "many-body":
        return declared
    if any(s.kind == "drifting" or (s.row.get("drifting_components") or 0) > 0 for s in runs):
        return "drifting"  # an energy that drifts, or a state with a drifting component
    if any(positive(s.row.get("tol")) for s in runs):
        return "adaptive"
    for s in runs:
        with contextlib.suppress(Exception):
            if "separable" in getattr(registry.integrator_class(s.scheme), "requires", ()):
                return "splitting"
    return "other"


def _chaos_group(v: Verdict, rows: list[dict[str, Any]], budget_s: float) -> list[PlannedCheck]:
    """A check of a chaotic problem's predictability horizon: its most accurate setting, at
    the finest map target E that it keeps over its run and whose horizon lies past its run,
    re-run CHAOS_MARGIN_LYAPUNOV Lyapunov times past that horizon (within ``budget_s``)."""
    mine = [r for r in rows if r.get("problem") == v.problem]
    if v.measure is None or not v.measure.solution or not v.candidates:
        return []
    s = min(v.candidates, key=lambda c: (c.error, c.cpu_per_t))
    for target in sorted(TARGETS):
        limit = predictability(mine, target)
        if limit is None or limit.lyapunov_time is None or target < 10 * s.error or limit.horizon <= s.span:
            continue
        h = limit.horizon + CHAOS_MARGIN_LYAPUNOV * limit.lyapunov_time
        if s.cpu_at(h) > budget_s:
            return []
        return [PlannedCheck(s, h, v.measure, "chaos", target, f"{v.problem} {target:g} chaos", "chaotic")]
    return []


def _growth_group(v: Verdict, rows: list[dict[str, Any]], budget_s: float) -> list[PlannedCheck]:
    """A check of the predictability horizon the growth of a perturbation sets on a problem
    declaring an unstable orbit or close encounters (GROWTH_CLASSES): its most accurate
    setting, at the finest map target E (at least GROWTH_MIN_TARGET and ten times its
    error) whose horizon, the time a rounding of the state grows to E
    (longtime.measure.instability, over ten times the main final time), lies past its run,
    re-run to where a rounding has grown to GROWTH_CHECK_MARGIN times E (no farther than
    its reference is trusted, and there at least a tenth of that): its pointwise error there
    (``final_error``) must exceed E. None where a stored row's reference stops
    before that time (it would not be judged)."""
    if v.measure is None or not v.measure.solution or not v.candidates or v.t_main is None:
        return []
    declared = _declared_class(v.problem)
    if declared not in GROWTH_CLASSES:
        return []
    from longtime.execution.cells import build, cell_of_row
    from longtime.measure import instability

    s = min(v.candidates, key=lambda c: (c.error, c.cpu_per_t))
    try:
        problem = build(cell_of_row(s.row))[0]
        growth = instability.measure(problem, 10 * v.t_main, budget_s=CHECK_REFERENCE_S)
    except Exception:  # no heyoka system, a compile past its budget: no growth check
        return []
    ends = [float(r["reference_horizon"]) for r in rows if r.get("problem") == v.problem
            and positive(r.get("reference_horizon")) and r["reference_horizon"] < float(r.get("t_final") or 0)]
    for target in sorted(TARGETS):
        h, horizon = growth.horizon(target), growth.horizon(GROWTH_CHECK_MARGIN * target)
        if h is None or horizon is None or target < max(GROWTH_MIN_TARGET, 10 * s.error) or h <= s.span:
            continue
        # no farther than its reference is trusted, rounded down to 3 significant figures (a
        # round final time, and inside the reach of the check run's own reference check)
        horizon = _judged_until(problem, horizon)
        unit = 10.0 ** (math.floor(math.log10(horizon)) - 2) if horizon > 0 else 1.0
        horizon = math.floor(horizon / unit) * unit
        if horizon <= h or INITIAL_ROUNDING * (growth.factor_at(horizon) or 0.0) < GROWTH_CHECK_MARGIN / 10 * target:
            return []
        if s.cpu_at(horizon) > budget_s or any(e < horizon for e in ends):
            return []
        return [PlannedCheck(s, horizon, v.measure, "growth", target, f"{v.problem} {target:g} growth", declared)]
    return []


def _judged_until(problem, horizon: float) -> float:
    """``horizon``, or the end of the reference's trusted horizon where its check over
    [t0, horizon] (cached, within CHECK_REFERENCE_S) ends before it: a check past it would
    not be judged."""
    from longtime.measure.reference import reference_check
    from longtime.measure.reference_runs import ReferenceUnavailable

    try:
        return min(horizon, reference_check(problem, horizon, CHECK_REFERENCE_S).horizon)
    except ReferenceUnavailable:
        return problem.t0


def _decision_groups(v: Verdict, budget_s: float) -> list[list[list[PlannedCheck]]]:
    """Per setting the map names as the winner past its run (within its reach), its groups:
    at each horizon where it wins, the winner, its runner-up and its open rivals (at most
    two), within ``budget_s`` of predicted CPU together; the farthest horizon first (the
    planner takes the first that fits the checks' time)."""
    best: dict[int, list[list[PlannedCheck]]] = {}
    # at each horizon the decision with the most rivals first (the rank tested against most)
    for d in sorted(v.grid.values(), key=lambda d: (-d.horizon, -(d.runner_up is not None) - len(d.open[:2]),
                                                    d.target)):
        b = d.best
        if b is None or d.horizon <= b.span * (1 + 1e-9):
            continue
        if any(g[0].horizon == d.horizon for g in best.get(id(b), [])):
            continue
        runs = [(b, "best")] + ([(d.runner_up, "runner-up")] if d.runner_up else []) + [(o, "open") for o in d.open[:2]]
        if sum(x.cpu_at(d.horizon) for x, _ in runs) > budget_s:
            continue
        group = f"{v.problem} {d.target:g} T={d.horizon:g}"
        kind = _group_kind(v, [x for x, _ in runs])
        best.setdefault(id(b), []).append([PlannedCheck(x, d.horizon, v.measure, role, d.target, group, kind)
                                           for x, role in runs])
    return sorted(best.values(), key=lambda gs: (-gs[0][0].horizon / gs[0][0].setting.span, gs[0][0].setting.text))


def plan_checks(rows: list[dict[str, Any]], limit: int = CHECKS, budget_s: float = CHECK_BUDGET_S,
                reference_rate=None, total_s: float = CHECKS_TOTAL_S) -> list[PlannedCheck]:
    """The checks to run, as groups of runs (PlannedCheck): per problem, a chaos check where
    it is chaotic (``_chaos_group``), a growth check where it declares an unstable orbit or
    close encounters (``_growth_group``) and its decisions' groups (``_decision_groups``: the
    winner with its runner-up and open rivals, each group's predicted CPU within
    ``budget_s``); at most ``limit`` groups whose estimated wall time (TIMED_RUNS times the
    predicted CPU, plus the reference: ``reference_rate(verdict)`` wall seconds per unit of
    t, default ``reference_seconds_per_t``) totals at most ``total_s``. Each class of
    problem (CHECK_KINDS) present gets a group before any class gets a second: a class's turn
    goes to its first group that fits among those of problems whose reference is timed and of
    one more problem, and among the drifting class's groups those of a drift-dominated
    problem (a drifting state component) come first."""
    rate_of = reference_seconds_per_t if reference_rate is None else reference_rate
    pool: dict[str, list[list[PlannedCheck]]] = {k: [] for k in CHECK_KINDS}
    found = verdicts(rows)
    per_problem = []
    for v in found.values():
        if v.measure is None:
            continue
        groups = ([[g]] if (g := _chaos_group(v, rows, budget_s)) else []) \
            + ([[g]] if (g := _growth_group(v, rows, budget_s)) else []) + _decision_groups(v, budget_s)
        per_problem.append((v, groups))
    # round-robin over problems within each kind, so one problem does not take a kind's turns
    depth = max((len(g) for _, g in per_problem), default=0)
    for k in range(depth):
        for v, groups in per_problem:
            if k < len(groups):
                pool[groups[k][0][0].kind].append(groups[k])
    pool["drifting"].sort(key=lambda alternatives: not _drift_dominated(alternatives[0]))  # stable: depth order kept
    rates: dict[str, float] = {}
    out: list[PlannedCheck] = []
    chosen, spent = 0, 0.0
    while chosen < limit and any(pool.values()):
        for kind in CHECK_KINDS:
            if chosen >= limit:
                break
            # the kind's turn: its first group that fits among those of the problems whose reference
            # is timed and of one more (the spent time only grows: a group that does not fit is dropped)
            timed, kept = False, []
            for k, alternatives in enumerate(pool[kind]):
                v = found[alternatives[0][0].setting.row["problem"]]
                if v.problem not in rates:
                    if timed:
                        kept.append(alternatives)
                        continue
                    timed = True
                    started = time.perf_counter()
                    rates[v.problem] = rate_of(v)
                    spent += time.perf_counter() - started  # timing the reference is part of the checks' time
                group = next((g for g in alternatives if _fits(g, rates[v.problem], spent, total_s)), None)
                if group is not None:  # the farthest horizon whose runs and reference fit
                    out += group
                    chosen += 1
                    spent += _cost(group, rates[v.problem])
                    kept += pool[kind][k + 1:]
                    break
            pool[kind] = kept
    return out


def _cost(group: list[PlannedCheck], rate: float) -> float:
    """A group's estimated wall seconds: TIMED_RUNS times its runs' predicted CPU, plus its
    reference's ``rate`` seconds per unit of t to its horizon."""
    return TIMED_RUNS * sum(c.predicted_cpu() for c in group) + rate * group[0].horizon


def _fits(group: list[PlannedCheck], rate: float, spent: float, total_s: float) -> bool:
    """Whether a group fits the checks' time left and its reference half of CHECK_REFERENCE_S."""
    cost = _cost(group, rate)
    return math.isfinite(cost) and spent + cost <= total_s and rate * group[0].horizon <= CHECK_REFERENCE_S / 2


def _drift_dominated(group: list[PlannedCheck]) -> bool:
    """Whether a group's runs are of a problem with a drifting state component
    (``drifting_components``, charged-particle's x3 = 0.1 + 0.2 t)."""
    return any((c.setting.row.get("drifting_components") or 0) > 0 for c in group)


def reference_seconds_per_t(v: Verdict) -> float:
    """The wall seconds per unit of t that a check of ``v``'s problem spends on its
    reference: 0 for an invariant's error (no reference), else the reference check's
    heyoka runs timed over ten times the problem's main final time
    (longtime.measure.reference.check_seconds_per_t). It only tells whether a check fits its
    budget, so a rate measured on this machine is kept beside the references and read back by
    the next main job (its measure costs seconds of the main process, serially, on every run)."""
    if v.measure is None or not v.measure.solution:
        return 0.0
    import numpy as np

    from longtime.execution.cells import build, cell_of_row
    from longtime.execution.run_environment import machine_key, this_machine
    from longtime.measure.reference import check_seconds_per_t
    from longtime.measure.reference_files import cache_path, load_cached, save_cached
    from longtime.measure.reference_runs import ReferenceUnavailable

    row = next(s.row for s in v.candidates)
    problem = build(cell_of_row(row))[0]
    span, budget_s = 10 * v.t_main, CHECK_REFERENCE_S / 10
    path = cache_path(problem, "check-seconds-per-t", repr(span), repr(budget_s), repr(machine_key(this_machine())),
                      suffix=".npy")
    kept = load_cached(path, lambda: float(np.load(path)))
    if kept is not None:
        return kept
    try:
        rate = check_seconds_per_t(problem, span, budget_s=budget_s)
    except ReferenceUnavailable:
        return math.inf  # its reference cannot be run here: no check of it is planned
    save_cached(path, np.array(rate))  # inf too: nothing reached within the budget is a measure
    return rate


def _calibrated(cpu_s: float | None, row: dict[str, Any]) -> float | None:
    """``cpu_s`` in the calibrated units of ``row`` (its cpu_s_calibrated over its cpu_s:
    the machine's speed when the row was timed); None where the row has no calibration."""
    own, calibrated = row.get("cpu_s"), row.get("cpu_s_calibrated")
    return cpu_s * calibrated / own if positive(cpu_s) and positive(own) and positive(calibrated) else None


def check_row(c: PlannedCheck, row: dict[str, Any]) -> dict[str, Any]:
    """A check's stored record: the re-run's row with the prediction beside it (a rival with
    no prediction, an "open" one, has predicted_error null; ``predicted_bound`` true where the
    prediction is an upper bound, an undetermined law's steepest window extrapolated)."""
    s, horizon, m = c.setting, c.horizon, c.measure
    # a growth check's claim is pointwise: the error at the horizon, not the largest over [0, T]
    field = "final_error" if c.role == "growth" else m.field
    ok = row.get("status") == Status.OK
    measured = (row.get(field) if c.role == "growth" else error_kept(row, m)) if ok else None
    if (c.role == "growth" or m.solution) and measured is not None \
            and not (row.get("error_horizon") or 0) >= horizon * (1 - 1e-9):
        measured = None  # the reference stopped short of the horizon: an error over less than the prediction's span
    from longtime.execution.cells import cell_of_row

    predicted = s.error_at(horizon) if c.role in ("best", "runner-up") else None
    # an undetermined law's prediction past the run is its steepest window's: an upper bound
    bound = predicted is not None and s.bound_exponent is not None and horizon > s.span * (1 + 1e-9)
    law = (f"chaotic: error above {c.target:g} past t = {horizon:.4g}" if c.role == "chaos" else
           f"unstable: a rounding of the state grows to {c.target:g} before t = {horizon:.4g}, the error at T above it"
           if c.role == "growth" else s.law_text())
    return {**row, "check_of": cell_of_row(s.row).key, "check_of_run": s.row.get("run_id"), "check_field": field,
            "check_law": law,
            "check_role": c.role, "check_group": c.group, "check_kind": c.kind, "check_target": c.target,
            "predicted_error": predicted, "predicted_bound": bound, "predicted_cpu_s": s.cpu_at(horizon),
            "predicted_cpu_s_calibrated": _calibrated(s.cpu_at(horizon), s.row),
            "predicted_cpu_model": s.cost.text() if s.cost else "per-time",
            "measured_error": measured if positive(measured) else None,
            "from_t_final": s.span, "from_error": s.error}


def run_checks(store, run_id: int, rows: list[dict[str, Any]], options=None,
               limit: int = CHECKS, budget_s: float = CHECK_BUDGET_S,
               reference_s: float = CHECK_REFERENCE_S, total_s: float = CHECKS_TOTAL_S,
               pool=None) -> list[dict[str, Any]]:
    """Run ``plan_checks``'s checks of ``rows`` (each a cell at its horizon under ``options``'
    time limit, timed by at most TIMED_RUNS - 1 runs after its warm-up, its reference given
    ``reference_s`` wall seconds: on ``pool``'s workers, a worker_pool, each in a worker as
    the matrix's cells are, else one at a time in this process), judge each group's rank
    (``judge_ranks``) and store each with its prediction (``Store.add_check``); returns the
    stored checks."""
    from longtime.core.integrator import Timing
    from longtime.execution.cells import cell_of_row
    from longtime.execution.matrix import ExecOptions, worker_failed

    plan = plan_checks(rows, limit, budget_s, total_s=total_s)
    if not plan:
        return []
    options = options or ExecOptions()
    # the warm-up and TIMED_RUNS - 1 timed runs at most (the checks' time estimate), no minimum time
    timing = Timing(repeats=min(options.timing.repeats, TIMED_RUNS - 1), min_time=0.0)
    cells = [cell_of_row(c.setting.row, t_final=c.horizon) for c in plan]
    args = [(cell, options.max_samples, timing, options.time_limit, reference_s) for cell in cells]
    if pool is None:
        measured = [checked_run(*a) for a in args]
    else:  # the costliest first, so that the workers end together
        order = sorted(range(len(plan)), key=lambda k: -plan[k].predicted_cpu())
        futures = {k: pool.submit(checked_run, *args[k]) for k in order}
        measured = []
        for k, cell in enumerate(cells):
            try:
                measured.append(futures[k].result())
            except Exception as exc:  # its worker gave no row: the check measured nothing
                measured.append(worker_failed(cell, exc))
    records = [check_row(c, row) for c, row in zip(plan, measured)]
    judge_ranks(records)
    if store is not None:
        for cell, record in zip(cells, records):
            store.add_check(run_id, cell, record)
    return records


def checked_run(cell, max_samples: int, timing, time_limit: float | None, reference_s: float) -> dict[str, Any]:
    """A check's cell run (``run_cell``), its CPU calibrated by the speed of the process that
    timed it (its calibration if recent, else one measured now): a check's CPU is judged in
    calibrated units."""
    from longtime.execution.cells import run_cell

    point = calibration.here().recent("checks")
    row = run_cell(cell, max_samples, True, timing, time_limit, None, reference_s)
    calibration.annotate(row, [point], point["t"])
    return row
