"""What a checked prediction must meet (``check_holds``, ``judge_ranks``), how many held
(``check_counts``, ``check_summary``) and how many checks the main job runs with what budget
(``check_budget``): a check re-runs a stored setting past its run and stores the predicted
beside the measured error and cost."""
from __future__ import annotations

import math
from typing import Any

from longtime.core.fmt import positive
from longtime.core.rowtext import setting

# the predictions the main job re-runs, and each one's predicted CPU budget (seconds)
CHECKS = 10
CHECK_BUDGET_S = 3.0
# a check's heyoka reference (to a horizon past the runs', so not cached) gets this many
# seconds of wall time: it is trusted as far as it got, and a check whose reference stops
# short of the horizon is not judged
CHECK_REFERENCE_S = 10.0
# what a check must meet to count as confirmed: error within this factor, cost within that
CHECK_ERROR_FACTOR = 3.0
CHECK_COST_FACTOR = 1.5


def check_holds(c: dict[str, Any]) -> bool | None:
    """Whether a stored check confirms its prediction. A "chaos" or "growth" check: its
    measured error exceeds its target (no pointwise error is kept past the predictability
    horizon). A
    prediction ("best", "runner-up", or a check stored without a role): the measured error
    within CHECK_ERROR_FACTOR of the predicted (a bound, ``predicted_bound``, an "at most":
    the measured error at most CHECK_ERROR_FACTOR times it) and the measured CPU at most
    CHECK_COST_FACTOR times the predicted (calibrated where both carry a calibration:
    ``cpu_pair``), and for the best its rank (``rank_held`` not
    False). None where the check measured no error, or made no prediction (an "open" rival)."""
    role = c.get("check_role")
    me = c.get("measured_error")
    if role in ("chaos", "growth"):
        return None if not positive(me) else bool(me > c["check_target"])
    if role == "open":
        return None
    pe, pc, mc = (c.get(k) for k in ("predicted_error", "predicted_cpu_s", "cpu_s"))
    if not (positive(pe) and positive(me) and positive(pc) and positive(mc)):
        return None
    low = 0.0 if c.get("predicted_bound") else 1 / CHECK_ERROR_FACTOR
    held = (low <= me / pe <= CHECK_ERROR_FACTOR) and cpu_held(c)
    return held and c.get("rank_held") is not False


def cpu_pair(c: dict[str, Any]) -> tuple[float, float, bool]:
    """(measured, predicted CPU, calibrated) of a check: in calibrated units (each over the
    machine's speed when it was timed: the check's and its row's calibrations) where both
    carry one, so that a machine loaded while the checks ran fails no prediction; else in
    CPU seconds."""
    mc, pc = c.get("cpu_s_calibrated"), c.get("predicted_cpu_s_calibrated")
    if positive(mc) and positive(pc):
        return mc, pc, True
    return c.get("cpu_s"), c.get("predicted_cpu_s"), False


def cpu_held(c: dict[str, Any]) -> bool:
    """The check's measured CPU at most CHECK_COST_FACTOR times the predicted (``cpu_pair``)."""
    mc, pc, _ = cpu_pair(c)
    return mc <= CHECK_COST_FACTOR * pc


def check_budget(rows: list[dict[str, Any]], limit: int = CHECKS) -> float:
    """The predicted CPU seconds each check may take: CHECK_BUDGET_S, but the checks together
    at most a quarter of the rows' own CPU time (a small matrix gets small checks)."""
    total = sum(r["cpu_s"] * (r.get("repeats") or 1) for r in rows if positive(r.get("cpu_s")))
    return min(CHECK_BUDGET_S, total / 4 / max(limit, 1))


def judge_ranks(records: list[dict[str, Any]]) -> None:
    """Set ``rank_held`` on each group's "best" record: whether its measured CPU is at most
    CHECK_COST_FACTOR times that of every rival of its group (runner-up, open) whose measured
    error keeps the target (None: no rival measured one that keeps it); ``rank_lost_to`` names
    the rivals it lost to, with their role and measured CPU."""
    for best in (r for r in records if r.get("check_role") == "best"):
        rivals = [r for r in records if r.get("check_group") == best["check_group"] and r is not best
                  and positive(r.get("measured_error")) and r["measured_error"] <= r["check_target"]
                  and positive(r.get("cpu_s"))]
        best["rank_rivals"] = [f"{r['integrator']} {setting(r)}" for r in rivals]
        beaten_by = [r for r in rivals if not best.get("cpu_s", math.inf) <= CHECK_COST_FACTOR * r["cpu_s"]]
        best["rank_lost_to"] = [f"{r['integrator']} {setting(r)} ({r.get('check_role')}, {r['cpu_s']:.3g} s)"
                                for r in beaten_by]
        best["rank_held"] = not beaten_by if rivals else None


def check_counts(checks: list[dict[str, Any]]) -> dict[str, int]:
    """{"held", "failed", "unjudged"}: the checks whose prediction held, failed, or could not
    be judged (check_holds None). The results page reads it."""
    held = [check_holds(c) for c in checks]
    return {"held": sum(h is True for h in held), "failed": sum(h is False for h in held),
            "unjudged": sum(h is None for h in held)}


def check_summary(checks: list[dict[str, Any]]) -> str:
    """'4 of 5 checked predictions held (error within x3, CPU within x1.5, the winner's rank
    tested against its rivals); 1 failed; 2 not judged (...)'."""
    n = check_counts(checks)
    judged = n["held"] + n["failed"]
    text = (f"{n['held']} of {judged} checked predictions held (error within x{CHECK_ERROR_FACTOR:g} of the "
            f"predicted, CPU within x{CHECK_COST_FACTOR:g}, the winner no costlier than x{CHECK_COST_FACTOR:g} a "
            f"rival that kept the target)")
    if n["failed"]:
        text += f"; {n['failed']} failed"
    if n["unjudged"]:
        text += f"; {n['unjudged']} not judged (no error measured, or a rival run without a prediction)"
    return text
