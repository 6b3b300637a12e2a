"""Observed convergence order: a least-squares slope of log error against log step.

For each sweep (one problem, one scheme, one final time and every setting but the swept
step or tolerance), the points are (mean_dt, error): mean_dt is dt for a fixed-step scheme
and t_final / steps for an adaptive one, so a tolerance sweep measures the same order.
The error is ``l2_error`` where the row has one, else the energy drift ``H.max``.

The asymptotic range is chosen automatically:
- points at the floor are dropped: an error below ``ROUND_OFF_FLOOR`` (round-off), or
  below ``REFERENCE_MARGIN`` times the row's ``reference_error`` (the reference's own
  accuracy);
- points before the asymptotic regime are dropped: an error above ``MAX_ERROR`` (the
  scheme is not resolving the solution), and then the largest steps while the remaining
  points are not on one line (a successive slope differs from the fitted slope by more
  than ``SLOPE_SPREAD``), keeping at least ``MIN_POINTS`` points.

The slope comes with a 95 % interval (Student t on the slope's standard error; none from
two points). A scheme whose observed order differs from its declared one by more than
the interval (and by more than ``ORDER_TOLERANCE``, the curvature a finite sweep always
shows) is flagged.
"""
from __future__ import annotations

import math
from typing import Any, Iterable

from .fmt import positive
from .numerics.loglog import fit_slope

ROUND_OFF_FLOOR = 1e-13
REFERENCE_MARGIN = 10.0
MAX_ERROR = 1e-1
SLOPE_SPREAD = 0.5
MIN_POINTS = 3
ORDER_TOLERANCE = 0.1
ERROR_FIELDS = ("l2_error", "H.max")
GROUP_KEYS = ("run_id", "problem", "integrator", "t_final", "order", "settings")


def _x(row: dict) -> float | None:
    if positive(row.get("dt")) and row.get("tol") is None and row.get("eps_res") is None:
        return float(row["dt"])
    return float(row["mean_dt"]) if positive(row.get("mean_dt")) else None


def asymptotic_points(points: list[tuple[float, float, float | None]]) -> list[tuple[float, float]]:
    """(x, error, reference_error) -> the (x, error) of the asymptotic range, by increasing x."""
    kept = sorted((x, e) for x, e, ref in points
                  if e >= ROUND_OFF_FLOOR and e <= MAX_ERROR
                  and not (ref is not None and positive(ref) and e < REFERENCE_MARGIN * ref))
    # one x per point (a repeated setting in one run would weigh twice)
    kept = list({x: (x, e) for x, e in kept}.values())
    while len(kept) > MIN_POINTS:
        slope, _ = fit_slope(*zip(*kept))
        local = [math.log(e2 / e1) / math.log(x2 / x1) for (x1, e1), (x2, e2) in zip(kept, kept[1:])]
        if max(abs(s - slope) for s in local) <= SLOPE_SPREAD:
            break
        kept = kept[:-1]  # the largest step is the one furthest from the asymptotic regime
    return kept


def distinct_runs(members: list[dict], field: str) -> list[dict]:
    """The rows of one sweep, one per computation: rows with the same step count and the same
    error are one run under different labels (a dt larger than the span takes one step of the
    span whatever its value), and only the one whose label is nearest its mean step
    (``mean_dt``) is a point of the fit."""
    best: dict[tuple, dict] = {}
    out = []
    for r in members:
        steps, x, mean = r.get("steps"), _x(r), r.get("mean_dt")
        if not (isinstance(steps, int) and steps > 0 and x is not None and positive(mean)):
            out.append(r)
            continue
        key = (steps, r.get(field))
        other = best.get(key)
        if other is None or abs(math.log(x / mean)) < abs(math.log(_x(other) / other["mean_dt"])):
            best[key] = r
    return out + list(best.values())


def declared_order(row: dict) -> int | None:
    from . import registry

    try:
        cls = registry.integrator_class(row["integrator"])
    except Exception:  # a scheme no longer installed: no declared order to compare with
        return None
    if cls.order is not None:
        return int(cls.order)
    # a fixed-step series scheme's order is its parameter N (taylor); a resummed one under
    # residual control (bpl) declares none
    param = cls.parameters.get("order")
    if param is None or cls.kind != "fixed":
        return None
    return int(row["order"]) if positive(row.get("order")) else (int(param.default) if param.default else None)


def observed_orders(rows: Iterable[dict[str, Any]]) -> list[dict[str, Any]]:
    """One fit per sweep with at least two usable points: problem, integrator, the fixed
    settings, declared_order, observed_order, observed_order_ci (None from two points),
    order_points ([[x, error], ...] used), order_variable, order_error_field, order_flag."""
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        if r.get("status") == "ok":
            groups.setdefault(tuple(str(r.get(k)) for k in GROUP_KEYS), []).append(r)
    out = []
    for members in groups.values():
        field = next((f for f in ERROR_FIELDS if sum(positive(r.get(f)) for r in members) >= 2), None)
        if field is None:
            continue
        points = [(_x(r), float(r[field]), r.get("reference_error") if field == "l2_error" else None)
                  for r in distinct_runs(members, field) if positive(r.get(field)) and _x(r) is not None]
        used = asymptotic_points(points)
        if len(used) < 2 or len({x for x, _ in used}) < 2:
            continue
        slope, ci = fit_slope(*zip(*used))
        first = members[0]
        declared = declared_order(first)
        flag = (declared is not None and ci is not None
                and abs(slope - declared) > max(ci, ORDER_TOLERANCE))
        variable = "dt" if all(r.get("tol") is None and r.get("eps_res") is None for r in members) else "mean_dt"
        out.append({"problem": first["problem"], "integrator": first["integrator"],
                    "run_id": first.get("run_id"), "t_final": first.get("t_final"),
                    "order": first.get("order"), "settings": first.get("settings"),
                    "declared_order": declared, "observed_order": slope, "observed_order_ci": ci,
                    "order_points": [[x, e] for x, e in used], "order_variable": variable,
                    "order_error_field": field, "order_flag": bool(flag)})
    return sorted(out, key=lambda d: (d["problem"], d["integrator"], str(d["order"])))
