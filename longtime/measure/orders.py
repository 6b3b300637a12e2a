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

from longtime.core.fmt import positive
from longtime.core.roles import row_fields
from longtime.measure.lyapunov import past_predictability
from longtime.numerics.loglog import fit_slope

ROUND_OFF_FLOOR = 1e-13
REFERENCE_MARGIN = 10.0
MAX_ERROR = 1e-1
SLOPE_SPREAD = 0.5
MIN_POINTS = 3
ORDER_TOLERANCE = 0.1
ERROR_FIELDS = ("l2_error", "H.max")
GROUP_KEYS = ("run_id", "problem", "integrator", "t_final", "order", "settings")


def _fixed_step(row: dict) -> bool:
    """The row ran at its step: no accuracy parameter (a tolerance) is set."""
    return all(row.get(k) is None for k in row_fields("accuracy"))


def _x(row: dict) -> float | None:
    if positive(row.get("dt")) and _fixed_step(row):
        return float(row["dt"])
    return float(row["mean_dt"]) if positive(row.get("mean_dt")) else None


def classify_points(points: list[tuple[float, float, float | None]]
                    ) -> tuple[list[tuple[float, float]], list[tuple[float, float, str]]]:
    """(x, error, reference_error) -> (the (x, error) of the asymptotic range, by increasing
    x; the (x, error, why) of the points left out: a floor, above MAX_ERROR, pre-asymptotic)."""
    kept, dropped = [], []
    for x, e, ref in points:
        if e < ROUND_OFF_FLOOR:
            dropped.append((x, e, f"below round-off {ROUND_OFF_FLOOR:g}"))
        elif e > MAX_ERROR:
            dropped.append((x, e, f"above {MAX_ERROR:g}"))
        elif ref is not None and positive(ref) and e < REFERENCE_MARGIN * ref:
            dropped.append((x, e, f"below {REFERENCE_MARGIN:g} x the reference's error"))
        else:
            kept.append((x, e))
    # one x per point (a repeated setting in one run would weigh twice)
    kept = list({x: (x, e) for x, e in sorted(kept)}.values())
    while len(kept) > MIN_POINTS:
        slope, _ = fit_slope(*zip(*kept))
        local = [math.log(e2 / e1) / math.log(x2 / x1) for (x1, e1), (x2, e2) in zip(kept, kept[1:])]
        if max(abs(s - slope) for s in local) <= SLOPE_SPREAD:
            break
        # the largest step is the one furthest from the asymptotic regime
        dropped.append((*kept.pop(), "pre-asymptotic"))
    return kept, sorted(dropped)


def asymptotic_points(points: list[tuple[float, float, float | None]]) -> list[tuple[float, float]]:
    """(x, error, reference_error) -> the (x, error) of the asymptotic range, by increasing x."""
    return classify_points(points)[0]


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
    from longtime.core import registry

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


def _groups(rows: Iterable[dict[str, Any]]) -> list[list[dict]]:
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault(tuple(str(r.get(k)) for k in GROUP_KEYS), []).append(r)
    return list(groups.values())


def _fit(members: list[dict]) -> tuple[dict | None, dict]:
    """(the fit of one sweep or None, why not: {"reason", "dropped"})."""
    ok = [r for r in members if r.get("status") == "ok"]
    if not ok:
        counts: dict[str, int] = {}
        for r in members:
            counts[str(r.get("status"))] = counts.get(str(r.get("status")), 0) + 1
        return None, {"reason": "no ok row (" + ", ".join(f"{n} {s}" for s, n in sorted(counts.items())) + ")",
                      "dropped": []}
    field = next((f for f in ERROR_FIELDS if sum(positive(r.get(f)) for r in ok) >= 2), None)
    if field is None:
        steps = {_x(r) for r in ok}
        why = ("one step size: no sweep to fit" if len(steps) < 2 else
               f"fewer than two rows with {' or '.join(ERROR_FIELDS)}")
        return None, {"reason": why, "dropped": []}
    points = [(_x(r), float(r[field]), r.get("reference_error") if field == "l2_error" else None)
              for r in distinct_runs(ok, field) if positive(r.get(field)) and _x(r) is not None
              and not (field == "l2_error" and past_predictability(r))]  # a lost chaotic solution
    used, dropped = classify_points(points)
    if len(used) < 2 or len({x for x, _ in used}) < 2:
        whys: dict[str, int] = {}
        for _, _, why in dropped:
            whys[why] = whys.get(why, 0) + 1
        if len(whys) == 1 and not used:
            reason = f"every point {next(iter(whys))}"
        else:
            reason = (f"{len(used)} of {len(points)} points left: "
                      + ", ".join(f"{n} {why}" for why, n in sorted(whys.items())))
        return None, {"reason": reason, "dropped": [list(d) for d in dropped]}
    slope, ci = fit_slope(*zip(*used))
    first = members[0]
    declared = declared_order(first)
    flag = (declared is not None and ci is not None
            and abs(slope - declared) > max(ci, ORDER_TOLERANCE))
    variable = "dt" if all(_fixed_step(r) for r in members) else "mean_dt"
    return {"problem": first["problem"], "integrator": first["integrator"],
            "run_id": first.get("run_id"), "t_final": first.get("t_final"),
            "order": first.get("order"), "settings": first.get("settings"),
            "declared_order": declared, "observed_order": slope, "observed_order_ci": ci,
            "order_points": [[x, e] for x, e in used], "order_dropped": [list(d) for d in dropped],
            "order_variable": variable, "order_error_field": field, "order_flag": bool(flag)}, {}


def observed_orders(rows: Iterable[dict[str, Any]]) -> list[dict[str, Any]]:
    """One fit per sweep with at least two usable points: problem, integrator, the fixed
    settings, declared_order, observed_order, observed_order_ci (None from two points),
    order_points ([[x, error], ...] used), order_dropped ([[x, error, why], ...] left out),
    order_variable, order_error_field, order_flag."""
    out = [fit for fit, _ in map(_fit, _groups(rows)) if fit is not None]
    return sorted(out, key=lambda d: (d["problem"], d["integrator"], str(d["order"])))


def left_out(rows: Iterable[dict[str, Any]]) -> list[dict[str, Any]]:
    """Every problem x scheme with rows but no observed order, and why (from its sweep with
    the most rows): 'every point above 0.1', 'no ok row (3 diverged)', 'one step size: no
    sweep to fit', ... A pair whose rows are all ``skipped`` is left to the skip line that
    names its missing capability."""
    rows = list(rows)
    fitted, why = set(), {}
    for members in _groups(rows):
        pair = (members[0]["problem"], members[0]["integrator"])
        if all(r.get("status") == "skipped" for r in members):
            continue
        fit, reason = _fit(members)
        if fit is not None:
            fitted.add(pair)
        elif pair not in why or len(members) > why[pair][0]:
            why[pair] = (len(members), reason, declared_order(members[0]))
    return [{"problem": p, "integrator": i, "reason": r["reason"], "dropped": r["dropped"], "declared_order": d}
            for (p, i), (_, r, d) in sorted(why.items()) if (p, i) not in fitted]


def left_out_text(entries: list[dict[str, Any]]) -> str:
    """'verlet (every point above 0.1); rk4 (no ok row (3 diverged))'."""
    return "; ".join(f"{m['integrator']} ({m['reason']})" for m in entries)
