"""Searches of a scheme's parameter, over runs of cells: one algorithm, two uses.

``bracket_and_bisect`` finds the value of a parameter at which a measured quantity that
grows with it (an error against a tolerance or a step; a mean step against eps_res) is
nearest a target: from a start, steps by a factor towards the target until the target is
bracketed, then bisects on the logarithm of the parameter.

- ``Matcher`` (``longtime match``, the KdV section of ``longtime reproduce``): the value of
  the scheme's accuracy parameter (``eps_res``, ``tol`` or ``dt``) whose error at t_final is
  nearest a target, then re-timed (best of ``repeat``).
- ``search_mean_step`` (``longtime reproduce``): the value whose mean step is nearest the
  paper's (BPL's eps_res for the paper's mean steps on Toda and Duffing).

Every run goes through ``longtime.execution.cells.run_cell`` (or the caller's runner), so it is a row
like any other, with its status and metrics.
"""
from __future__ import annotations

import math
import sys
from typing import Callable

from longtime.core import registry, roles
from longtime.core.params import InputError
from longtime.core.status import Status
from longtime.execution.cells import Cell, build, run_cell
from longtime.execution.store import Store

MAX_FIXED_STEPS = 2_000_000  # smallest dt tried: the span over this many steps
CLOSE_ENOUGH = math.log(1.2)  # the matched search stops within 20 % of the target
MATCH_SAMPLES = 2001  # states kept per run: the metrics need the final state, not every step


def log_distance(quantity: float, target: float) -> float:
    """|log(quantity / target)|; infinite for a failed run (0 or inf)."""
    return abs(math.log(quantity / target)) if 0 < quantity < math.inf else math.inf


def bracket_and_bisect(measure: Callable[[float], float], start: float, target: float, *,
                       factor: float, close: float, max_evals: int, low: float = 0.0,
                       high: float = math.inf, min_ratio: float = 1.0) -> dict[float, float]:
    """{value: measure(value)} of every evaluation of a search for measure(value) near
    ``target``, measure growing with value, value within [low, high]. Stops at an
    evaluation within log distance ``close`` of the target, after ``max_evals``, at a bound,
    or when the bracket is narrower than ``min_ratio``."""
    tried: dict[float, float] = {}
    value = min(max(start, low), high)
    below = above = None  # the tightest values with measure <= target and > target

    while True:
        tried[value] = q = measure(value)
        if q <= target:
            below = value
        else:
            above = value
        if log_distance(q, target) <= close or len(tried) >= max_evals:
            break
        if below is not None and above is not None:
            if above / below <= min_ratio:
                break
            value = math.sqrt(below * above)
        elif below is None:
            value = value / factor
            if value < low:
                break
        else:
            value = value * factor
            if value > high:
                break
    return tried


def nearest(tried: dict[float, float], target: float) -> float:
    """The value whose measure is nearest the target, in log."""
    return min(tried, key=lambda v: log_distance(tried[v], target))


def accuracy_parameter(scheme: str) -> str:
    """The parameter the search varies: the scheme's first accuracy parameter, else its step."""
    names = roles.accuracy(registry.integrator_class(scheme))
    if not names:
        raise InputError(f"scheme '{scheme}' declares no parameter of role {' or '.join(roles.ACCURACY_ROLES)}: "
                         "nothing to match")
    return names[0]


def _error(row: dict, metric: str) -> float:
    value = row.get(metric)
    return float(value) if row.get("status") == Status.OK and value is not None else math.inf


class Matcher:
    """Matched accuracy: every evaluation is stored (``match_role``: search, matched or
    scaling) when a store is given."""

    def __init__(self, store: Store | None, run_id: int | None, metric: str, target: float,
                 repeat: int, max_evals: int, verbose: bool = True):
        self.store, self.run_id = store, run_id
        self.metric, self.target = metric, target
        self.repeat, self.max_evals, self.verbose = repeat, max_evals, verbose

    def evaluate(self, cell: Cell, role: str) -> dict:
        row = run_cell(cell, max_samples=MATCH_SAMPLES)
        row["match_role"], row["match_target"] = role, self.target
        if self.store is not None:
            self.store.add_row(self.run_id, cell, row)
        if self.verbose:
            print(f"  {cell.integrator:14s} {cell.problem_settings} {cell.integrator_settings}: "
                  f"{row['status']} {self.metric}={row.get(self.metric)} cpu={row.get('cpu_s')}",
                  file=sys.stderr)
        return row

    def timed(self, cell: Cell, first: dict, role: str) -> dict:
        """The best CPU of ``repeat`` runs (a run longer than 5 s is not repeated)."""
        best = first
        for _ in range(self.repeat - 1):
            if best.get("status") != Status.OK or (best.get("cpu_s") or 0.0) > 5.0:
                break
            row = run_cell(cell, max_samples=MATCH_SAMPLES)
            if row.get("status") == Status.OK and row["cpu_s"] < best["cpu_s"]:
                best = row
        best = {**best, "match_role": role, "match_target": self.target, "cpu_runs": self.repeat}
        if self.store is not None:
            self.store.add_row(self.run_id, cell, best)
        return best

    def match(self, base: Cell) -> dict:
        """Search the scheme's accuracy parameter for an error near the target."""
        if base.skip_reason:
            return run_cell(base)  # a skipped row, with the reason as its message
        name = accuracy_parameter(base.integrator)
        problem, integrator = build(base)
        span = base.t_final - problem.t0
        param = integrator.parameters[name]
        if param.role == "step":
            start, (low, high) = problem.default_dt, (span / MAX_FIXED_STEPS, span / 4)
        else:
            (low, high) = roles.search_range(param)
            start = param.default if param.default else math.sqrt(low * high)
        runs: dict[float, tuple[Cell, dict]] = {}

        def error(value: float) -> float:
            cell = Cell(base.problem, base.integrator, dict(base.problem_settings),
                        {**base.integrator_settings, name: value}, base.t_final)
            runs[value] = (cell, self.evaluate(cell, "search"))
            return _error(runs[value][1], self.metric)

        tried = bracket_and_bisect(error, start, self.target, factor=10.0, close=CLOSE_ENOUGH,
                                   max_evals=self.max_evals, low=low, high=high, min_ratio=1.01)
        value = nearest(tried, self.target)
        note = ""
        if log_distance(tried[value], self.target) > CLOSE_ENOUGH:
            meets = [v for v, e in tried.items() if e <= self.target]
            misses = [v for v, e in tried.items() if e > self.target]
            if not meets:
                note = f"error above the target down to {name}={min(tried):.3g}"
            elif not misses:
                note = f"error below the target up to {name}={max(tried):.3g}"
            else:
                # the error jumps across the target (e.g. from the error floor to a stability
                # limit): the cheapest setting that meets the target is the fair point
                value = max(meets)
                above = min(v for v in misses if v > value)
                note = (f"no {name} gives an error near the target: {name}={above:.4g} gives "
                        f"{tried[above]:.3g} ({runs[above][1]['status']}); "
                        f"the largest {name} below the target is shown")
        cell, row = runs[value]
        searched = {v: r.get("mean_dt") for v, (_, r) in sorted(runs.items()) if r.get("status") == Status.OK}
        row = self.timed(cell, row, "matched")
        row.update(match_parameter=name, match_value=value, match_note=note, match_evals=len(tried),
                   match_mean_steps=searched)
        return row


def search_mean_step(run_row: Callable[[Cell], dict], problem: str, scheme: str, parameter: str,
                     target_step: float, t_final: float, start: float, max_evals: int = 8,
                     settings: dict | None = None) -> dict:
    """The row whose mean step is nearest ``target_step`` (a larger eps_res or tol gives
    longer steps; a failed run counts as a short step), run by ``run_row``; ``settings``:
    the scheme's other settings. The row's ``searched`` says what was tried."""
    rows: dict[float, dict] = {}

    def mean_step(value: float) -> float:
        rows[value] = run_row(Cell(problem, scheme, {}, {**(settings or {}), parameter: value}, t_final))
        return (rows[value].get("mean_dt") or 0.0) if rows[value].get("status") == Status.OK else 0.0

    tried = bracket_and_bisect(mean_step, start, target_step, factor=100.0, close=math.log(1.03),
                               max_evals=max_evals)
    value = nearest(tried, target_step)
    if not 0 < tried[value] < math.inf:
        return list(rows.values())[-1]  # every run failed: the last one tried says why
    return {**rows[value], "searched": f"{parameter}={value:.3g} ({len(tried)} runs)"}
