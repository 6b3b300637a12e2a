"""Observed convergence order: a least-squares slope of log error against log step, fitted
only on the asymptotic range and only where the data determine it.

For each sweep (one problem, one scheme, one final time and every setting but the swept
step or tolerance), the points are (mean_dt, error): mean_dt is dt for a fixed-step scheme
and t_final / steps for an adaptive one, so a tolerance sweep measures the same order.
The error is the whole state's ``l2_error_state`` where the row has one (one norm of the
state for every step of the sweep: a scheme's order does not depend on the norm, and the
largest block of ``l2_error`` may change from one step to the next), else ``l2_error``
(rows that predate it), else the energy drift ``H.max``.

The rule (docs/metrics.md, "Observed order"), on the points by increasing step, each
point left out named with why:

1. floors: an error below ``ROUND_OFF_FLOOR`` (round-off) or below ``REFERENCE_MARGIN``
   times the reference's own error (the row's ``error_floor``, in l2_error's units, else
   its ``reference_error``) is dropped; so is an
   error above ``MAX_ERROR`` (the scheme does not resolve the solution), and a row past
   its predictability horizon (a chaotic solution lost);
2. the local slopes log(e2/e1)/log(h2/h1) between successive points are computed; at the
   small end a point in the floor's zone (an error below ``FLOOR_ZONE`` times its floor)
   whose slope falls below the next one's by more than ``SLOPE_BAND`` is on the floor (it
   flattens the curve), and is dropped as such;
3. the asymptotic range grows from the smallest step while its local slopes agree: within
   ``slope_tolerance`` of one another (``SLOPE_BAND``, ``RELATIVE_BAND`` of the order fitted
   through them, or that fit's interval from ``INTERVAL_POINTS`` points on); the larger
   steps beyond it are dropped as pre-asymptotic. A drift of the slopes within it is not
   pre-asymptotic: kahan-li-8's 8.14, 8.08, 7.97 is an order 8;
4. the order is determined when the range holds at least ``MIN_POINTS`` points. Otherwise
   it is undetermined, with the reason: "2 points only (...): not an order", or the local
   slopes: "pre-asymptotic: local slopes 3.20, 3.65, 3.85 (dt 0.1 to 0.0125) still rise
   toward small steps (...)", or "local slopes disagree: ..." when they do not move one way;
5. a range whose local slopes still approach the declared order as the step shrinks (each
   nearer it than the one at the next larger step, by more than ``SLOPE_BAND`` in all) while
   the smallest step's slope misses it by more than ``ORDER_TOLERANCE`` is pre-asymptotic
   too: its fit would read an order below the declared one that smaller steps would not
   (rk4's 3.65, 3.85 on the pendulum; yoshida8's 6.71, 7.38, 7.80 on henon-heiles), and
   the order is undetermined, with the slopes (``_approaching``).

A determined order is the least-squares slope over the range with a 95 % interval (Student
t on the slope's standard error). It is flagged when it differs from the declared order by
more than its interval and ``ORDER_TOLERANCE``, and its local slopes, widened by as much, do
not reach the declared order (``_flagged``). An undetermined order is never flagged.
``order_text`` is the one way an order is printed; ``Order`` is one sweep's fit as the API returns it.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any, Iterable

from longtime.core.fmt import positive
from longtime.core.roles import row_fields
from longtime.core.status import Status
from longtime.measure.lyapunov import past_predictability
from longtime.numerics.loglog import fit_slope

ROUND_OFF_FLOOR = 1e-13
REFERENCE_MARGIN = 10.0
MAX_ERROR = 1e-1
MIN_POINTS = 3
ORDER_TOLERANCE = 0.1
# local slopes within this of one another agree: the curvature a converged sweep still shows
SLOPE_BAND = 0.1
# ... and so do slopes within this fraction of the order fitted through them, or within that
# fit's interval when it has at least INTERVAL_POINTS points (from 3, Student's t of one
# degree of freedom, 12.7, makes any drift look small)
RELATIVE_BAND = 0.1
INTERVAL_POINTS = 4
FLOOR_ZONE = 1e3
ERROR_FIELDS = ("l2_error_state", "l2_error", "H.max")
SOLUTION_ERRORS = ("l2_error_state", "l2_error")
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


def slope_tolerance(pts: list[tuple[float, float]]) -> float:
    """How far apart the local slopes of the (x, error) points ``pts`` may be and still
    agree: SLOPE_BAND, RELATIVE_BAND of the order fitted through them, or that fit's 95 %
    interval when it has at least INTERVAL_POINTS points, whichever is largest. A drift of
    the slopes within it biases the fit by less than the order's tenth or its interval."""
    slope, ci = fit_slope(*zip(*pts))
    return max(SLOPE_BAND, RELATIVE_BAND * abs(slope), ci if ci is not None and len(pts) >= INTERVAL_POINTS else 0.0)


def _spread(slopes: list[float]) -> float:
    return max(slopes) - min(slopes)


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
        which = "round-off" if floor == ROUND_OFF_FLOOR else "reference's"
        dropped.append((x0, e0, f"on the {which} floor: it flattens the slope to {slopes[0]:.2f} "
                                f"(next {slopes[1]:.2f}; error within {FLOOR_ZONE:g} x the floor {floor:g})"))
        kept.pop(0)
    pts = [(x, e) for x, e, _ in kept]
    slopes = local_slopes(pts)
    n = 1 if slopes else 0  # local slopes in the range, from the smallest step
    while n < len(slopes) and _spread(slopes[:n + 1]) <= slope_tolerance(pts[:n + 2]):
        n += 1
    out: dict[str, Any] = {"used": pts, "dropped": dropped, "slopes": slopes, "reason": None}
    if len(pts) < MIN_POINTS:  # one slope at most: no interval, nothing to check a trend against
        out["used"] = []
        if len(pts) == 2:
            out["reason"] = (f"2 points only ({variable} {pts[0][0]:.3g} and {pts[1][0]:.3g}, local slope "
                             f"{slopes[0]:.2f}): no interval, no trend to check; not an order")
        return out
    if n < MIN_POINTS - 1:
        out["used"], out["reason"] = [], _trend(pts, slopes, variable)
        dropped += [(x, e, "no asymptotic range") for x, e in pts]
        return out
    for x, e in pts[n + 1:]:
        dropped.append((x, e, f"pre-asymptotic: local slope beyond {slope_tolerance(pts[:n + 1]):.2g} of the "
                              f"smaller steps' {min(slopes[:n]):.2f} .. {max(slopes[:n]):.2f}"))
    out["used"] = pts[:n + 1]
    return out


def _trend(pts: list[tuple[float, float]], slopes: list[float], variable: str) -> str:
    """Why local slopes that do not agree determine no order, the slopes listed from the
    largest step to the smallest, with how far apart they are against how far they may be."""
    listed = ", ".join(f"{s:.2f}" for s in reversed(slopes))
    span = f"({variable} {pts[-1][0]:.3g} to {pts[0][0]:.3g})"
    beyond = (f"{_spread(slopes):.2f} apart, beyond the {slope_tolerance(pts):.2g} that {RELATIVE_BAND:g} of "
              f"the order, {SLOPE_BAND:g} or the fit's interval allow")
    diffs = [b - a for a, b in zip(slopes, slopes[1:])]  # by increasing step
    if all(d < 0 for d in diffs):
        return f"pre-asymptotic: local slopes {listed} {span} still rise toward small steps ({beyond})"
    if all(d > 0 for d in diffs):
        return f"pre-asymptotic: local slopes {listed} {span} still fall toward small steps ({beyond})"
    return f"local slopes disagree: {listed} {span}, {beyond}"


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


def _points(ok: list[dict], field: str) -> tuple[list[tuple[float, float, float | None]], dict[str, int]]:
    """(the (x, error, reference_error) of the sweep's computations, how many rows gave no
    point and why)."""
    points, why = [], {}
    for r in distinct_runs(ok, field):
        if not positive(r.get(field)):
            reason = f"no positive {field}"
        elif _x(r) is None:
            reason = "no step"
        elif field in SOLUTION_ERRORS and past_predictability(r):
            reason = "past its predictability horizon (a chaotic solution lost)"
        else:
            # the reference's error in l2_error's units where the row has it (error_floor)
            ref = next((r[k] for k in ("error_floor", "reference_error") if positive(r.get(k))), None)
            points.append((_x(r), float(r[field]), ref if field in SOLUTION_ERRORS else None))
            continue
        why[reason] = why.get(reason, 0) + 1
    return points, why


def _flagged(slope: float, ci: float | None, slopes: list[float], declared: int | None) -> bool:
    """The declared order is beyond the fit's interval and ORDER_TOLERANCE, and beyond the
    range of the local slopes the fit stands on widened by as much: slopes that drift toward
    the declared order (a drift the range accepts) refute nothing."""
    if declared is None or ci is None:
        return False
    margin = max(ci, ORDER_TOLERANCE)
    return abs(slope - declared) > margin and not (min(slopes) - margin <= declared <= max(slopes) + margin)


def _approaching(slopes: list[float], declared: int | None) -> bool:
    """The local slopes of a range (by increasing step) still approach the declared order as
    the step shrinks: each nearer it than the one at the next larger step, on one side of it,
    by more than SLOPE_BAND in all, and the smallest step's slope misses it by more than
    ORDER_TOLERANCE (rule 5 of the module)."""
    if declared is None or len(slopes) < 2:
        return False
    gaps = [s - declared for s in slopes]
    one_side = all(g < 0 for g in gaps) or all(g > 0 for g in gaps)
    nearer = all(abs(a) < abs(b) for a, b in zip(gaps, gaps[1:]))
    return (one_side and nearer and abs(gaps[-1]) - abs(gaps[0]) > SLOPE_BAND
            and abs(gaps[0]) > ORDER_TOLERANCE)


def _fit(members: list[dict]) -> tuple[dict | None, dict]:
    """(the fit of one sweep or None, why not: {"reason", "dropped"})."""
    ok = [r for r in members if r.get("status") == Status.OK]
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
    points, no_point = _points(ok, field)
    variable = "dt" if all(_fixed_step(r) for r in members) else "mean_dt"
    found = asymptotic_range(points, variable)
    used, dropped, slopes = found["used"], sorted(found["dropped"]), [float(x) for x in found["slopes"]]
    rows_without = ", ".join(f"{n} row{'s' * (n > 1)} {why}" for why, n in sorted(no_point.items()))
    if found["reason"] is not None:
        reason = found["reason"] + (f"; {rows_without}" if rows_without else "")
        return None, {"reason": reason, "dropped": [list(d) for d in dropped], "slopes": slopes,
                      "error_field": field, "variable": variable}
    if len({x for x, _ in used}) < MIN_POINTS:
        whys: dict[str, int] = {}
        for _, _, why in dropped:
            whys[why] = whys.get(why, 0) + 1
        if len(whys) == 1 and not used and not no_point:
            reason = f"every point {next(iter(whys))}"
        else:
            parts = [f"{n} {why}" for why, n in sorted(whys.items())] + ([rows_without] if rows_without else [])
            reason = (f"{len(used)} of {len(points)} points left, fewer than {MIN_POINTS}: "
                      + ("; ".join(parts) or "no point"))
        return None, {"reason": reason, "dropped": [list(d) for d in dropped], "slopes": slopes,
                      "error_field": field, "variable": variable}
    slope, ci = fit_slope(*zip(*used))
    first = members[0]
    declared = declared_order(first)
    range_slopes = local_slopes(used)
    if _approaching(range_slopes, declared):
        listed = ", ".join(f"{x:.2f}" for x in reversed(range_slopes))
        way = "rise" if range_slopes[0] < declared else "fall"
        reason = (f"pre-asymptotic: local slopes {listed} ({variable} {used[-1][0]:.3g} to {used[0][0]:.3g}) "
                  f"still {way} toward the declared order {declared} as the step shrinks, the smallest step's "
                  f"{range_slopes[0]:.2f} {abs(declared - range_slopes[0]):.2f} from it: the fit over them "
                  f"({slope:.2f}) is not the order" + (f"; {rows_without}" if rows_without else ""))
        return None, {"reason": reason, "dropped": [list(d) for d in dropped], "slopes": slopes,
                      "error_field": field, "variable": variable}
    return {"problem": first["problem"], "integrator": first["integrator"],
            "run_id": first.get("run_id"), "t_final": first.get("t_final"),
            "order": first.get("order"), "settings": first.get("settings"),
            "declared_order": declared, "observed_order": slope, "observed_order_ci": ci,
            "order_points": [[x, e] for x, e in used], "order_dropped": [list(d) for d in dropped],
            "order_variable": variable, "order_error_field": field,
            "order_flag": _flagged(slope, ci, range_slopes, declared), "order_slopes": slopes}, {}


def order_text(value: float, ci: float | None, points: int, slopes: list[float] = (), digits: int = 2) -> str:
    """The one way an observed order is printed: '8.07 +- 0.10'; ', local slopes 3.45 to
    3.78' after it when the slopes of its range drift beyond SLOPE_BAND; and an order from
    fewer than MIN_POINTS points (no interval), which ``observed_orders`` never gives but a
    caller may hold, flagged: '5.16 (2 points: not an order)'."""
    if points < MIN_POINTS or ci is None:
        return f"{value:.{digits}f} ({points} points: not an order)"
    text = f"{value:.{digits}f} +- {ci:.{digits}f}"
    if slopes and _spread(list(slopes)) > SLOPE_BAND:
        text += f", local slopes {min(slopes):.{digits}f} to {max(slopes):.{digits}f}"
    return text


def fit_text(fit: dict[str, Any]) -> str:
    """``order_text`` of a fit of ``observed_orders``."""
    return order_text(fit["observed_order"], fit["observed_order_ci"], len(fit["order_points"]),
                      local_slopes([tuple(p) for p in fit["order_points"]]))


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
    finals: dict[tuple, set] = {}
    for members in _groups(rows):
        pair = (members[0]["problem"], members[0]["integrator"])
        if all(r.get("status") == Status.SKIPPED for r in members):
            continue
        finals.setdefault(pair, set()).add(members[0].get("t_final"))
        fit, reason = _fit(members)
        t_final = members[0].get("t_final")
        # the sweep with the most rows, of equal ones the shortest run's (the default sweep's,
        # where an order is measured, before a long-time cell's)
        rank = (len(members), -t_final if positive(t_final) else -math.inf)
        if fit is not None:
            fitted.add(pair)
        elif pair not in why or rank > why[pair][0]:
            why[pair] = (rank, reason, declared_order(members[0]), t_final)
    # a pair swept at several final times names the one its reason is about
    return [{"problem": p, "integrator": i, "reason": r["reason"] + (
                f" (its sweep to t = {tf:.4g})" if len(finals[p, i]) > 1 and positive(tf) else ""),
             "dropped": r["dropped"], "declared_order": d,
             "slopes": r["slopes"], "error_field": r.get("error_field"), "variable": r.get("variable")}
            for (p, i), (_, r, d, tf) in sorted(why.items()) if (p, i) not in fitted]


def left_out_text(entries: list[dict[str, Any]]) -> str:
    """'verlet (every point above 0.1); rk4 (no ok row (3 diverged))'."""
    return "; ".join(f"{m['integrator']} ({m['reason']})" for m in entries)


@dataclasses.dataclass(frozen=True)
class Order:
    """The observed order of one sweep (one problem, one scheme, one final time and setting):
    ``value`` (the least-squares slope of log error against log step; None when no order
    could be fitted, ``reason`` says why), ``ci`` its 95 % half-width (an order
    needs 3 points), ``points`` the (step, error) pairs used, ``dropped`` the (step, error, why)
    pairs left out (floors, above 0.1, pre-asymptotic), ``declared`` the scheme's declared
    order and ``flag`` (a determined order misses it beyond its interval and 0.1, and its
    local slopes do not reach it; an
    undetermined one is never flagged), ``slopes`` the local slopes between successive
    points above the floors (by increasing step). An undetermined order (the local slopes
    still trend: pre-asymptotic) has ``value`` None and its ``reason`` lists the slopes."""

    problem: str
    scheme: str
    value: float | None
    ci: float | None
    points: list[tuple[float, float]]
    dropped: list[tuple[float, float, str]]
    declared: int | None
    flag: bool = False
    error_field: str | None = None
    variable: str | None = None
    t_final: float | None = None
    settings: str | None = None
    reason: str | None = None
    slopes: list[float] = dataclasses.field(default_factory=list)

    @property
    def determined(self) -> bool:
        return self.value is not None

    @property
    def interval(self) -> tuple[float, float] | None:
        if self.value is None or self.ci is None:
            return None
        return (self.value - self.ci, self.value + self.ci)

    def __str__(self) -> str:
        head = f"{self.scheme} on {self.problem}: "
        if self.value is None:
            return head + f"order undetermined ({self.reason})" + (
                f", declared {self.declared}" if self.declared is not None else "")
        text = head + "observed order " + order_text(self.value, self.ci, len(self.points),
                                                     local_slopes(self.points), 3)  # +- its 95 % interval
        text += f", declared {self.declared}" if self.declared is not None else ""
        if self.flag:
            text += " (MISSES the declared order beyond its interval and 0.1)"
        text += f"; {len(self.points)} points used ({self.error_field} against {self.variable} "
        text += ", ".join(f"{x:.3g}" for x, _ in self.points) + ")"
        if self.dropped:
            text += "; dropped: " + ", ".join(f"{self.variable}={x:.3g} ({why})" for x, _, why in self.dropped)
        return text
