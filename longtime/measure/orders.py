"""Observed convergence order: a least-squares slope of log error against log step, fitted
only on the asymptotic range and only where the data determine it.

For each sweep (one problem, one scheme, one final time and every setting but the swept
step or tolerance), the points are (mean_dt, error): mean_dt is dt for a fixed-step scheme
and t_final / steps for an adaptive one, so a tolerance sweep measures the same order.
The error is ``l2_error`` where the row has one, else the energy drift ``H.max``.

The rule (docs/metrics.md, "Observed order"), on the points by increasing step, each
point left out named with why:

1. floors: an error below ``ROUND_OFF_FLOOR`` (round-off) or below ``REFERENCE_MARGIN``
   times the row's ``reference_error`` (the reference's own accuracy) is dropped; so is an
   error above ``MAX_ERROR`` (the scheme does not resolve the solution);
2. the local slopes log(e2/e1)/log(h2/h1) between successive points are computed; at the
   small end a point in the floor's zone (an error below ``FLOOR_ZONE`` times its floor)
   whose slope falls below the next one's by more than ``SLOPE_BAND`` is the floor
   flattening the curve, and is dropped;
3. the asymptotic range grows from the smallest step while its local slopes stay within
   ``SLOPE_BAND`` of one another; the larger steps beyond it are dropped as pre-asymptotic;
4. the order is determined when the range holds at least ``MIN_POINTS`` points (two local
   slopes that agree), or when the sweep has two usable points only (one slope, no
   interval: nothing to check a trend against). Otherwise it is undetermined, with the
   local slopes: "pre-asymptotic: local slopes 3.20, 3.65, 3.85 (dt 0.1 to 0.0125) still
   rise toward small steps", or "local slopes disagree: ..." when they do not move one way.

A determined order is the least-squares slope over the range with a 95 % interval (Student
t on the slope's standard error; none from two points). Only a determined order is
compared with the declared one: it is flagged when it differs by more than its interval
and more than ``ORDER_TOLERANCE``. An undetermined order is never flagged.
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
MIN_POINTS = 3
ORDER_TOLERANCE = 0.1
# local slopes within this of one another agree: the curvature a converged sweep still shows
SLOPE_BAND = 0.1
FLOOR_ZONE = 1e3
ERROR_FIELDS = ("l2_error", "H.max")
GROUP_KEYS = ("run_id", "problem", "integrator", "t_final", "order", "settings")


def _fixed_step(row: dict) -> bool:
    """The row ran at its step: no accuracy parameter (a tolerance) is set."""
    return all(row.get(k) is None for k in row_fields("accuracy"))


def _x(row: dict) -> float | None:
    if positive(row.get("dt")) and _fixed_step(row):
        return float(row["dt"])
    return float(row["mean_dt"]) if positive(row.get("mean_dt")) else None


def local_slopes(points: list[tuple[float, float]]) -> list[float]:
    """log(e2/e1) / log(x2/x1) between successive (x, error) points (by increasing x)."""
    return [math.log(e2 / e1) / math.log(x2 / x1) for (x1, e1), (x2, e2) in zip(points, points[1:])]


def _floors(points: list[tuple[float, float, float | None]]
            ) -> tuple[list[tuple[float, float, float]], list[tuple[float, float, str]]]:
    """(the (x, error, floor) of the points above their floors and at most MAX_ERROR, one
    per x, by increasing x; the (x, error, why) of the others)."""
    kept, dropped = [], []
    for x, e, ref in points:
        floor = ROUND_OFF_FLOOR
        if ref is not None and positive(ref):
            floor = max(floor, REFERENCE_MARGIN * float(ref))
        if e < ROUND_OFF_FLOOR:
            dropped.append((x, e, f"below round-off {ROUND_OFF_FLOOR:g}"))
        elif e > MAX_ERROR:
            dropped.append((x, e, f"above {MAX_ERROR:g}"))
        elif e < floor:
            dropped.append((x, e, f"below {REFERENCE_MARGIN:g} x the reference's error"))
        else:
            kept.append((x, e, floor))
    # one x per point (a repeated setting in one run would weigh twice)
    return list({x: (x, e, f) for x, e, f in sorted(kept)}.values()), dropped


def asymptotic_range(points: list[tuple[float, float, float | None]], variable: str = "step") -> dict[str, Any]:
    """(x, error, reference_error) -> {"used": the (x, error) of the asymptotic range by
    increasing x, "dropped": the (x, error, why) left out, "slopes": the local slopes of the
    points above the floors (by increasing x), "reason": None when the order is determined,
    else why not}."""
    kept, dropped = _floors(points)
    while len(kept) >= MIN_POINTS:
        (x0, e0, floor), slopes = kept[0], local_slopes([(x, e) for x, e, _ in kept])
        if not (e0 < FLOOR_ZONE * floor and slopes[0] < slopes[1] - SLOPE_BAND):
            break
        dropped.append((x0, e0, f"the floor flattens the slope to {slopes[0]:.2f} "
                                f"(next {slopes[1]:.2f}; error within {FLOOR_ZONE:g} x its floor {floor:g})"))
        kept.pop(0)
    pts = [(x, e) for x, e, _ in kept]
    slopes = local_slopes(pts)
    n = 1 if slopes else 0  # local slopes in the range, from the smallest step
    while n < len(slopes) and max(slopes[:n + 1]) - min(slopes[:n + 1]) <= SLOPE_BAND:
        n += 1
    out: dict[str, Any] = {"used": pts, "dropped": dropped, "slopes": slopes, "reason": None}
    if len(pts) < 2:
        return out
    if len(pts) == 2:  # one slope: reported without an interval, nothing to check a trend against
        return out
    if n < MIN_POINTS - 1:
        out["used"], out["reason"] = [], _trend(pts, slopes, variable)
        dropped += [(x, e, "no asymptotic range") for x, e in pts]
        return out
    for x, e in pts[n + 1:]:
        dropped.append((x, e, f"pre-asymptotic: local slope beyond {SLOPE_BAND:g} of the smaller steps' "
                              f"{min(slopes[:n]):.2f} .. {max(slopes[:n]):.2f}"))
    out["used"] = pts[:n + 1]
    return out


def _trend(pts: list[tuple[float, float]], slopes: list[float], variable: str) -> str:
    """Why local slopes that do not agree determine no order, the slopes listed from the
    largest step to the smallest."""
    listed = ", ".join(f"{s:.2f}" for s in reversed(slopes))
    span = f"({variable} {pts[-1][0]:.3g} to {pts[0][0]:.3g})"
    diffs = [b - a for a, b in zip(slopes, slopes[1:])]  # by increasing step
    if all(d < 0 for d in diffs):
        return f"pre-asymptotic: local slopes {listed} {span} still rise toward small steps"
    if all(d > 0 for d in diffs):
        return f"pre-asymptotic: local slopes {listed} {span} still fall toward small steps"
    return f"local slopes disagree: {listed} {span}, beyond {SLOPE_BAND:g} of one another"


def classify_points(points: list[tuple[float, float, float | None]]
                    ) -> tuple[list[tuple[float, float]], list[tuple[float, float, str]]]:
    """(x, error, reference_error) -> (the (x, error) of the asymptotic range, by increasing
    x, empty when the order is undetermined; the (x, error, why) of the points left out)."""
    found = asymptotic_range(points)
    return found["used"], sorted(found["dropped"])


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
                      "dropped": [], "slopes": []}
    field = next((f for f in ERROR_FIELDS if sum(positive(r.get(f)) for r in ok) >= 2), None)
    if field is None:
        steps = {_x(r) for r in ok}
        why = ("one step size: no sweep to fit" if len(steps) < 2 else
               f"fewer than two rows with {' or '.join(ERROR_FIELDS)}")
        return None, {"reason": why, "dropped": [], "slopes": []}
    points = [(_x(r), float(r[field]), r.get("reference_error") if field == "l2_error" else None)
              for r in distinct_runs(ok, field) if positive(r.get(field)) and _x(r) is not None
              and not (field == "l2_error" and past_predictability(r))]  # a lost chaotic solution
    variable = "dt" if all(_fixed_step(r) for r in members) else "mean_dt"
    found = asymptotic_range(points, variable)
    used, dropped, slopes = found["used"], sorted(found["dropped"]), [float(x) for x in found["slopes"]]
    if found["reason"] is not None:
        return None, {"reason": found["reason"], "dropped": [list(d) for d in dropped], "slopes": slopes,
                      "error_field": field, "variable": variable}
    if len(used) < 2 or len({x for x, _ in used}) < 2:
        whys: dict[str, int] = {}
        for _, _, why in dropped:
            whys[why] = whys.get(why, 0) + 1
        if len(whys) == 1 and not used:
            reason = f"every point {next(iter(whys))}"
        else:
            reason = (f"{len(used)} of {len(points)} points left: "
                      + ", ".join(f"{n} {why}" for why, n in sorted(whys.items())))
        return None, {"reason": reason, "dropped": [list(d) for d in dropped], "slopes": slopes}
    slope, ci = fit_slope(*zip(*used))
    first = members[0]
    declared = declared_order(first)
    flag = (declared is not None and ci is not None
            and abs(slope - declared) > max(ci, ORDER_TOLERANCE))
    return {"problem": first["problem"], "integrator": first["integrator"],
            "run_id": first.get("run_id"), "t_final": first.get("t_final"),
            "order": first.get("order"), "settings": first.get("settings"),
            "declared_order": declared, "observed_order": slope, "observed_order_ci": ci,
            "order_points": [[x, e] for x, e in used], "order_dropped": [list(d) for d in dropped],
            "order_variable": variable, "order_error_field": field, "order_flag": bool(flag),
            "order_slopes": slopes}, {}


def observed_orders(rows: Iterable[dict[str, Any]]) -> list[dict[str, Any]]:
    """One fit per sweep with at least two usable points: problem, integrator, the fixed
    settings, declared_order, observed_order, observed_order_ci (None from two points),
    order_points ([[x, error], ...] used), order_dropped ([[x, error, why], ...] left out),
    order_variable, order_error_field, order_flag (only a determined order is flagged),
    order_slopes (the local slopes of the points above the floors, by increasing step).
    A sweep whose order is undetermined has no fit here: ``left_out`` names it, with the
    slopes."""
    out = [fit for fit, _ in map(_fit, _groups(rows)) if fit is not None]
    return sorted(out, key=lambda d: (d["problem"], d["integrator"], str(d["order"])))


def left_out(rows: Iterable[dict[str, Any]]) -> list[dict[str, Any]]:
    """Every problem x scheme with rows but no observed order, and why (from its sweep with
    the most rows): 'every point above 0.1', 'no ok row (3 diverged)', 'one step size: no
    sweep to fit', 'pre-asymptotic: local slopes 3.20, 3.65, 3.85 (...) still rise toward
    small steps' (an undetermined order, ``slopes`` beside it), ... A pair whose rows are
    all ``skipped`` is left to the skip line that names its missing capability."""
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
    return [{"problem": p, "integrator": i, "reason": r["reason"], "dropped": r["dropped"], "declared_order": d,
             "slopes": r["slopes"], "error_field": r.get("error_field"), "variable": r.get("variable")}
            for (p, i), (_, r, d) in sorted(why.items()) if (p, i) not in fitted]


def left_out_text(entries: list[dict[str, Any]]) -> str:
    """'verlet (every point above 0.1); rk4 (no ok row (3 diverged))'."""
    return "; ".join(f"{m['integrator']} ({m['reason']})" for m in entries)
