"""An answer measured at its horizon: ``longtime recommend``'s candidates run to the
question's horizon T, each against a reference trusted to T, within a wall-time budget
(``measure_at``).

The candidates come cheapest predicted first (``candidates``): the settings predicted to
keep the target at T and those whose law is undetermined past their run (a short run, an
"open" rival) but whose measured error keeps it. Each runs as a cell (``run_cell``, its
heyoka reference checked to T) timed by a warm-up and TIMED_RUNS runs; a candidate whose
predicted cost cannot fit what is left of the budget is not run (it could win: the answer
names the command that runs it). Once one keeps the target, a candidate predicted to cost
more than RIVAL_FACTOR times its measured CPU is not run: a predicted cost is seldom that
far off, so it cannot win.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

from longtime.core.fmt import positive
from longtime.core.status import Status
from longtime.predict.settings import SOLUTION_FIELDS, Setting

# the default wall-time budget of the runs (``longtime recommend --budget``)
DEFAULT_BUDGET_S = 60.0
# timed runs after the warm-up: the CPU figure is their minimum
TIMED_RUNS = 2
# once a candidate keeps the target, a rival is still run while its predicted CPU is at most
# this many times the winner's measured CPU
RIVAL_FACTOR = 10.0
# at most this many candidates are run
MAX_RUNS = 6


@dataclass
class Measured:
    """One candidate run to the horizon: its row, the error it keeps (None: not measured up
    to the horizon, with ``why``), and whether it keeps the target."""
    setting: Setting
    row: dict[str, Any]
    error: float | None
    cpu_s: float | None
    keeps: bool
    why: str = ""

    def text(self) -> str:
        if self.error is None:
            return f"{self.setting.text}: not measured at T ({self.why})"
        cpu = f"{self.cpu_s:.3g} s" if self.cpu_s is not None else "CPU not measured"
        return f"{self.setting.text}: error {self.error:.2g} measured at T, CPU {cpu}"


def candidates(cands: list[Setting], target: float, horizon: float) -> list[Setting]:
    """The settings worth running to ``horizon``: predicted to keep ``target`` there, or
    undetermined past their run (a short run, an open rival) with a measured error that keeps
    it; one per setting, cheapest predicted CPU at ``horizon`` first."""
    out = []
    for s in cands:
        e = s.error_at(horizon)
        if (e is not None and e <= target) or (s.state_at(horizon) == "undetermined" and s.error <= target):
            out.append(s)
    return sorted(out, key=lambda s: (s.cpu_at(horizon), s.text))


def reference_seconds(s: Setting, horizon: float, budget_s: float) -> float:
    """The wall seconds the reference check to ``horizon`` of ``s``'s problem is estimated to
    take: 0 where it is cached or runs no heyoka, else its heyoka runs' rate
    (``check_seconds_per_t``, timed over the problem's default final time within a fifth of
    ``budget_s``) times the horizon's span; inf where it cannot run."""
    from longtime.execution.cells import build, cell_of_row
    from longtime.measure import reference

    try:
        problem = build(cell_of_row(s.row))[0]
        if not reference.has_reference(problem) or reference.check_cached(problem, horizon):
            return 0.0
        span = min(float(problem.default_t_final), horizon - problem.t0)
        rate = reference.check_seconds_per_t(problem, span, budget_s=max(budget_s / 5, 0.5))
    except Exception:  # a reference that cannot run here
        return math.inf
    return rate * (horizon - problem.t0)


def measure_at(cands: list[Setting], field: str, target: float, horizon: float, budget_s: float,
               max_samples: int | None = None) -> tuple[list[Measured], list[Setting], float, str]:
    """Run ``cands`` (in order, ``candidates``) to ``horizon`` within ``budget_s`` wall seconds:
    the measured ones, the ones the budget could not run (their predicted cost does not fit
    what is left, or MAX_RUNS were run; not those that cannot win, RIVAL_FACTOR), the wall
    seconds spent, and why nothing ran where the reference check to ``horizon`` alone is
    estimated past the budget ('' otherwise)."""
    from longtime.core.integrator import Timing
    from longtime.execution.cells import DEFAULT_MAX_SAMPLES, cell_of_row, run_cell

    started = time.perf_counter()
    timing = Timing(repeats=TIMED_RUNS, min_time=0.0, min_runs=1)
    done: list[Measured] = []
    skipped: list[Setting] = []
    if cands:
        ref_s = reference_seconds(cands[0], horizon, budget_s)
        spent = time.perf_counter() - started
        if not ref_s < budget_s - spent:
            return [], list(cands), spent, (f"its reference check to T is estimated at {ref_s:.3g} s, past the "
                                            f"budget's {budget_s - spent:.3g} s left")
    for s in cands:
        left = budget_s - (time.perf_counter() - started)
        best = min((m.cpu_s for m in done if m.keeps and m.cpu_s is not None), default=math.inf)
        predicted = s.cpu_at(horizon)
        if predicted > best * RIVAL_FACTOR:
            continue
        if len(done) >= MAX_RUNS or not (predicted * (TIMED_RUNS + 1) < left):
            skipped.append(s)
            continue
        row = run_cell(cell_of_row(s.row, t_final=horizon), max_samples or DEFAULT_MAX_SAMPLES, timing=timing,
                       time_limit=max(left, 1.0), reference_budget_s=max(left, 1.0))
        done.append(_judge(s, row, field, target, horizon))
    return done, skipped, time.perf_counter() - started, ""


def _judge(s: Setting, row: dict[str, Any], field: str, target: float, horizon: float) -> Measured:
    """The error ``field`` the run measured up to ``horizon`` (only where its reference was
    trusted to the horizon) and whether it keeps ``target``."""
    cpu = row.get("cpu_s") if positive(row.get("cpu_s")) else None
    if row.get("status") != Status.OK:
        return Measured(s, row, None, cpu, False, f"{row.get('status')}: {row.get('message') or ''}".strip(": "))
    error = row.get(field)
    if not positive(error):
        return Measured(s, row, None, cpu, False, f"no {field} measured")
    if field in SOLUTION_FIELDS and not (row.get("error_horizon") or 0) >= horizon * (1 - 1e-9):
        reach = row.get("error_horizon")
        return Measured(s, row, None, cpu, False, f"its reference is trusted only up to t = {reach:.4g}"
                        if positive(reach) else "no reference trusted")
    if row.get("solution_lost"):
        return Measured(s, row, float(error), cpu, False)
    return Measured(s, row, float(error), cpu, float(error) <= target)
