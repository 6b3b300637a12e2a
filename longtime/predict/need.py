"""Which cells' timing could change an answer (``need``): the main job times these again in
fresh processes (longtime.execution.processes), the rest keep the time of their own process.

An answer that reads a cell's time is a front of error against CPU: the verdict's and
recommend's decisions (per target error and horizon of its problem, the cheapest setting
predicted to keep the target, its runner-up of another scheme and its open rivals:
longtime.predict.decision), and the report's Pareto front at the problem's main final time
(per accuracy decade, the fastest ok row whose error ``pareto_field`` is at most the
decade). A cell is a contender, and is timed again, where

- its setting keeps some (target, horizon) of its problem's verdict at a predicted CPU time
  within ``FACTOR`` of the cheapest setting that keeps it (the best; the runner-up is such a
  setting or no contender), over the targets the verdict and recommend ask about
  (``decision.TARGETS``); or it is an open rival of a decision (listed while cheaper than
  the best) at more than 1 / ``FACTOR`` of the best's CPU per unit time; or it is a
  decision's best or its problem's most accurate setting (the settings a check re-runs
  first). A setting's cost model reads every run of it, so every row of a contender setting
  is a contender;
- or, at its problem's main final time, its CPU time is within ``FACTOR`` of the fastest
  row whose error is at most its own, in the error the report's front ranks by
  (``pareto_field``) or the verdict reads (its ``measure``), where that error is within the
  targets (at most the coarsest, ``max(TARGETS)``);
- or its problem has no front at all (no ok row with such an error and a time): nothing
  says which of its cells an answer could read, so every one is timed again.

Every other cell is dominated: some cell of its problem meets every target it meets, or
its error, for less than 1 / ``FACTOR`` of its CPU. Under timing by need a cell's own
process times its run only as far as this decision needs (a run or a few:
longtime.core.timing.Timing.screening). A cell's time measured in one process is at most
about twice what several processes measure (a slow moment of the machine slows work through
the caches by up to twice: docs/performance.md, "Two speeds"), and noise only adds time, so a
cell dominated by more than ``FACTOR`` = 2 in its own process's time is dominated in any
timing; its row says by how much and how many runs timed it (``timed_in``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from longtime.core.fmt import positive
from longtime.core.rowtext import main_t_final, setting
from longtime.core.status import Status
from longtime.measure.lyapunov import past_predictability
from longtime.predict.decision import TARGETS, keepers, verdicts
from longtime.predict.settings import SOLUTION_FIELDS, Measure, error_kept

# a cell within this factor of a front's CPU time is a contender (see the module's text)
FACTOR = 2.0
# the error "Which library" asks of each library's settings (longtime.reporting.libraries; the
# verdict's measure: max_error, the largest error of any block of the state over the run,
# relative to its motion); a library peer's cell that has spent FACTOR times the CPU of a
# setting of its library that keeps it cannot be that library's answer (longtime.execution.batches)
TARGET = 1e-6
# the error fields a Pareto front ranks by, the first of them a problem's rows have
# (``pareto_field``; longtime.reporting.report.pareto)
PARETO_FIELDS = (*SOLUTION_FIELDS, "H.max", "I.max", "constraint.max")


# how a cell left out of the timing processes is said to be dominated (``Need.why``)
NOT_ON_FRONT = "not on the front"
NO_FRONT = "on no front"


def left_out(row: dict[str, Any]) -> bool:
    """Whether timing by need left ``row``'s cell in its own process (its ``timed_in``)."""
    text = str(row.get("timed_in") or "")
    return f": {NOT_ON_FRONT}" in text or f": {NO_FRONT}" in text


@dataclass(frozen=True)
class Need:
    """Whether a row's cell is timed again (``retime``), and if not, by how much it is
    dominated (``factor``: its CPU over the cheapest that matches it; None: it is on no
    front, its error meets no target) and why, in words (``why``)."""
    retime: bool
    factor: float | None = None
    why: str = ""


def library_of(scheme: str) -> str:
    """The library whose method ``scheme`` runs (its class's ``library``; "longtime" for the
    suite's own kernels, "unknown" for a scheme no longer installed)."""
    from longtime.core import registry

    try:
        return str(getattr(registry.integrator_class(scheme), "library", "longtime"))
    except Exception:  # a scheme of an old run that is no longer installed
        return "unknown"


def kept_error(row: dict[str, Any], m: Measure, target: float = TARGET) -> float | None:
    """The error of ``row`` in ``m`` (``error_kept`` over its whole run) where it is an ok row
    with a CPU time that keeps the solution and ``target``; else None. "Which library" reads
    its entries by it, and the main job bounds a library peer's chain by it."""
    if row.get("status") != Status.OK or row.get("solution_lost") or not positive(row.get("cpu_s")):
        return None
    error = error_kept(row, m)
    return error if error is not None and error <= target else None


def pareto_field(rows: list[dict[str, Any]]) -> str | None:
    """The error a problem's Pareto front ranks by: the first of PARETO_FIELDS that an ok row
    of ``rows`` has."""
    ok = [r for r in rows if r.get("status") == Status.OK]
    return next((f for f in PARETO_FIELDS if any(positive(r.get(f)) for r in ok)), None)


def setting_key(row: dict[str, Any]) -> tuple:
    """A row's setting within its problem (the verdict's: its scheme and parameters)."""
    return row.get("problem"), row.get("integrator"), setting(row)


def need(rows: list[dict[str, Any]], factor: float = FACTOR) -> list[Need]:
    """Per row of ``rows`` (one run's), whether its cell's timing could change an answer
    (see the module's text), in the order of ``rows``."""
    ratio = [math.inf] * len(rows)  # each row's smallest CPU ratio to a front
    keys = [setting_key(r) for r in rows]
    key_of = {id(r): k for r, k in zip(rows, keys)}  # a candidate's row is one of ``rows``
    named: set[tuple] = set()  # settings an answer or a check names
    by_problem: dict[str, list[int]] = {}
    for i, r in enumerate(rows):
        by_problem.setdefault(str(r.get("problem")), []).append(i)
    found = verdicts(rows)
    for problem, members in by_problem.items():
        mine = [rows[i] for i in members]
        within: dict[tuple, float] = {}
        v = found.get(problem)
        if v is not None and v.candidates:
            for (target, horizon), d in v.grid.items():
                if d.best is None or not d.best.cpu_at(horizon) > 0:
                    continue
                named.add(key_of[id(d.best.row)])
                cheapest = d.best.cpu_at(horizon)
                for s in keepers(v.candidates, target, horizon):  # the runner-up among them
                    _least(within, key_of[id(s.row)], s.cpu_at(horizon) / cheapest)
                for s in d.open:  # listed while cheaper than the best: within FACTOR below it
                    if s.cpu_per_t > 0:
                        _least(within, key_of[id(s.row)], d.best.cpu_per_t / s.cpu_per_t)
            named.add(key_of[id(min(v.candidates, key=lambda c: (c.error, c.cpu_per_t)).row)])
        t_main = main_t_final(mine)
        fronts = 0
        read = {pareto_field(mine), v.measure.field if v is not None and v.measure is not None else None}
        for field in (f for f in PARETO_FIELDS if f in read):
            ok = [i for i in members if _on_front_candidate(rows[i], field, t_main)]
            fronts += bool(ok)
            for i in ok:
                err = rows[i][field]
                if err > max(TARGETS):
                    continue
                best = min(rows[j]["cpu_s"] for j in ok if rows[j][field] <= err)
                ratio[i] = min(ratio[i], rows[i]["cpu_s"] / best)
        for i in members:
            ratio[i] = min(ratio[i], within.get(keys[i], math.inf))
        if not fronts and not within:
            for i in members:
                ratio[i] = 1.0  # no front: every cell is timed again
    out = []
    for i, r in enumerate(rows):
        if ratio[i] <= factor or keys[i] in named:
            out.append(Need(True, ratio[i] if math.isfinite(ratio[i]) else None))
        elif math.isfinite(ratio[i]):
            out.append(Need(False, ratio[i], f"{NOT_ON_FRONT} by x{ratio[i]:.2g}"))
        else:
            out.append(Need(False, None, f"{NO_FRONT}: its error meets no target (at most {max(TARGETS):g})"))
    return out


def _least(ratios: dict[tuple, float], key: tuple, ratio: float) -> None:
    ratios[key] = min(ratios.get(key, math.inf), ratio)


def _on_front_candidate(row: dict[str, Any], field: str, t_main: float | None) -> bool:
    """An ok row at its problem's main final time with a CPU time and an error in ``field``
    (a chaotic problem's row past its predictability horizon has no L2 accuracy to offer)."""
    return (row.get("status") == Status.OK and positive(row.get("cpu_s")) and positive(row.get(field))
            and row.get("t_final") == t_main and not (field == "l2_error" and past_predictability(row)))
