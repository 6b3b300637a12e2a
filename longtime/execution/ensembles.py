"""The main job's ensemble step: on each chaotic problem it covers, per scheme, the distance
between the distributions the scheme's and heyoka's ensembles visit late in the run
(longtime.measure.ensemble), stored apart from the rows (``Store.add_ensemble``).

Which problems: the chaotic problems of the rows with a declared chaotic state, the settings
a problem class gives as ``chaotic_settings`` (a dict; {} for its default state):
henon-heiles and figure-eight-perturbed, whose default states show no chaos (docs/problems.md,
"Chaos from the default states"). The other chaotic problems are left to ``longtime
ensemble``: their heyoka ensembles (lennard-jones' above all) do not fit the main job's
budget. The state's Lyapunov time is measured (longtime.measure.lyapunov); where none is
determined, each scheme's record says so (status ``skipped``), never a distance.

Which setting of each scheme: one of its ok rows, the one nearest the default (the
problem's default step for a fixed-step scheme, the scheme's default tolerance and order
otherwise; ties to the cheaper), integrated from the chaotic state over the span: the rows'
final time, or SPAN_LYAPUNOV Lyapunov times where that is longer (the members must
decorrelate before the late window), at most the problem's default final time.

The floor: the largest distance between heyoka's pool and FLOOR_ENSEMBLES heyoka ensembles
of other seeds (the spread a finite ensemble shows by itself, taken at its largest of a few
draws: one draw alone is a noisy threshold).

What it costs: MEMBERS members of the scheme (heyoka's ensembles are computed once per
problem and cached beside the references); a scheme whose members are estimated (its row's
CPU time x the span over the row's x MEMBERS) above SCHEME_S is not run (``skipped``, with
the estimate); the schemes run cheapest first, their members together under a deadline of
DEADLINE_S seconds of wall time (past it: ``timeout``), and none starts once the problem's
schemes have spent PROBLEM_S seconds of CPU (``skipped``, saying so). A member that
diverged, failed or timed out makes the scheme's record that status, with the members'
counts, and no distance.
"""
from __future__ import annotations

import math
import time
from collections import Counter
from typing import Any, Iterable

import numpy as np

from longtime.core import registry
from longtime.core.roles import ROW_PARAMETERS
from longtime.core.status import Status
from longtime.measure import ensemble, lyapunov

MEMBERS = 8
SIZE = ensemble.DEFAULT_SIZE
WINDOW = ensemble.DEFAULT_WINDOW
SEED = 1
SPAN_LYAPUNOV = 20.0
SCHEME_S = 0.25
DEADLINE_S = 1.0
PROBLEM_S = 4.0  # CPU seconds of the schemes' members a problem (process time: the load does not move it)
# heyoka ensembles beside the reference pool: the floor is the largest of their distances to it
FLOOR_ENSEMBLES = 3
REFERENCE_S = 60.0  # heyoka's ensembles of a problem (once: cached), their compile included
def _declared(pcls) -> dict[str, Any] | None:
    """The chaotic state a problem declares (``chaotic_settings``), or None."""
    declared = getattr(pcls, "chaotic_settings", None)
    return dict(declared) if declared is not None else None


def chaotic_problems(rows: Iterable[dict[str, Any]]) -> list[str]:
    """The problems of ``rows`` that the step covers: chaotic, with a heyoka system, a
    declared chaotic state and an ok row."""
    out = []
    for name in sorted({r["problem"] for r in rows if r.get("status") == Status.OK}):
        try:
            pcls = registry.problem_class(name)
        except Exception:  # a plugin's problem no longer installed: nothing to run
            continue
        if getattr(pcls, "chaotic", False) and pcls.heyoka_system is not None and _declared(pcls) is not None:
            out.append(name)
    return out


def state_settings(name: str) -> dict[str, Any]:
    """The problem settings the ensemble starts from (its declared chaotic state)."""
    return _declared(registry.problem_class(name)) or {}


def _distance_from_default(row: dict[str, Any], problem, scheme_cls) -> float:
    """How far a row's setting is from the scheme's default (log distance of each swept
    parameter that has a default)."""
    far = 0.0
    for key in ROW_PARAMETERS:
        value = row.get(key)
        if not isinstance(value, (int, float)) or isinstance(value, bool) or not value > 0:
            continue
        default = problem.default_dt if key == "dt" else getattr(scheme_cls.parameters.get(key), "default", None)
        if isinstance(default, (int, float)) and default > 0:
            far += abs(math.log(value / default))
    return far


def pick_rows(rows: list[dict[str, Any]], problem) -> dict[str, dict[str, Any]]:
    """Per scheme, the ok row of the problem nearest the default setting (the shorter run
    first where two are as near: the default sweep's, not the long-time cell)."""
    out: dict[str, dict[str, Any]] = {}
    for scheme in sorted({r["integrator"] for r in rows}):
        mine = [r for r in rows if r["integrator"] == scheme and r.get("status") == Status.OK
                and isinstance(r.get("cpu_s"), (int, float)) and r.get("t_final")]
        if not mine:
            continue
        try:
            icls = registry.integrator_class(scheme)
        except Exception:
            continue
        out[scheme] = min(mine, key=lambda r: (round(_distance_from_default(r, problem, icls), 9), r["t_final"],
                                                r["cpu_s"]))
    return out


def measure_problem(name: str, rows: list[dict[str, Any]], members: int = MEMBERS) -> list[dict[str, Any]]:
    """One record per scheme with an ok row of problem ``name`` (see the module's text)."""
    from longtime.execution.cells import Cell, build, cell_of_row

    settings = state_settings(name)
    problem = registry.problem_class(name)(**settings)
    mine = [r for r in rows if r["problem"] == name]
    picks = pick_rows(mine, problem)
    base = {"problem": name, "problem_settings": settings, "members": members, "size": SIZE, "window": WINDOW,
            "seed": SEED}
    try:
        found = lyapunov.measure(problem)
    except Exception as exc:
        found = {"lyapunov_time": None, "lyapunov_note": f"not measured: {exc}"}
    t_lyap = found["lyapunov_time"]
    base.update(lyapunov_time=t_lyap, lyapunov_note=found["lyapunov_note"])

    def record(row: dict[str, Any], **fields: Any) -> dict[str, Any]:
        kept = {k: row.get(k) for k in (*ROW_PARAMETERS, "settings")}
        return {**base, "integrator": row["integrator"], **kept, "row_t_final": row.get("t_final"), **fields}

    if t_lyap is None:
        return [record(r, status=Status.SKIPPED, note=f"no chaos measured from this state: {found['lyapunov_note']}")
                for r in picks.values()]
    rows_t = max(r["t_final"] for r in picks.values()) if picks else problem.default_t_final
    span = min(max(rows_t, SPAN_LYAPUNOV * t_lyap), max(problem.default_t_final, rows_t))
    t_final = problem.t0 + span
    base.update(t_final=t_final, span_lyapunov=span / t_lyap,
                observable=ensemble.observable(problem, np.array([problem.t0]), problem.u0[None, :])[0])
    try:
        reference, others = ensemble.reference_pools(problem, t_final, members, SIZE, SEED, WINDOW, REFERENCE_S,
                                                     others=FLOOR_ENSEMBLES)
    except Exception as exc:  # no heyoka ensemble within its budget: said, not fatal
        return [record(r, status=Status.FAILED, note=f"heyoka's ensemble: {type(exc).__name__}: {exc}")
                for r in picks.values()]
    floors = [ensemble.distance(other, reference) for other in others]
    if any(f is None for f in floors):
        return [record(r, status=Status.FAILED, note="the reference's observable does not vary over the window")
                for r in picks.values()]
    floor = max(floors)
    base.update(floor=floor, floors=floors)
    out = []
    # the cheapest first: what the problem's budget leaves out is the costliest
    order = sorted(picks.items(), key=lambda kv: (kv[1]["cpu_s"] / kv[1]["t_final"], kv[0]))
    spent = 0.0
    for scheme, row in order:
        estimate = row["cpu_s"] * span / row["t_final"] * members
        if estimate > SCHEME_S:
            out.append(record(row, status=Status.SKIPPED, note=f"its members are estimated at {estimate:.2g} s of CPU "
                                                         f"(its row's), above the step's {SCHEME_S:g} s a scheme"))
            continue
        if spent > PROBLEM_S:
            out.append(record(row, status=Status.SKIPPED, note=f"the step's {PROBLEM_S:g} s of CPU for the problem "
                                                                f"were spent (the cheaper schemes first)"))
            continue
        cell = cell_of_row(row)
        _, integrator = build(Cell(name, scheme, settings, cell.integrator_settings))
        reason = integrator.incompatibility(problem)
        if reason:
            out.append(record(row, status=Status.SKIPPED, note=reason))
            continue
        start = time.process_time()
        try:
            pool, counts = ensemble.scheme_pool(problem, integrator, t_final, members, SIZE, SEED, WINDOW,
                                                deadline=time.monotonic() + DEADLINE_S)
        except Exception as exc:  # a scheme's fault is its record's status, never a number
            pool, counts = None, {Status.FAILED: 1}
            note = f"{type(exc).__name__}: {exc}"
        else:
            note = ""
        cpu = time.process_time() - start
        spent += cpu
        if pool is None:
            status = next((s for s in (Status.FAILED, Status.TIMEOUT, Status.DIVERGED) if counts.get(s)), Status.FAILED)
            ran = sum(counts.values())
            deadline = " (past the step's deadline)" if status == Status.TIMEOUT else ""
            note = note or f"member {ran} of {members} {status}{deadline}; no distance"
            out.append(record(row, status=status, member_status=counts, cpu_s=cpu, note=note))
            continue
        d = ensemble.distance(pool, reference)
        out.append(record(row, status=Status.OK, distance=d, member_status=counts, cpu_s=cpu,
                          distinguishable=ensemble.distinguishable(d, floor)))
    return sorted(out, key=lambda r: r["integrator"])


def run(store, run_id: int | None, rows: list[dict[str, Any]], members: int = MEMBERS,
        ahead: "Ahead | None" = None) -> list[dict[str, Any]]:
    """Measure every covered problem of ``rows`` and store each record (``store`` None: not
    stored); returns the records. A problem ``ahead`` measured already is not measured again."""
    out = []
    for name in chaotic_problems(rows):
        found = ahead.records.get(name) if ahead is not None else None
        for rec in measure_problem(name, rows, members) if found is None else found:
            if store is not None:
                store.add_ensemble(run_id, rec)
            out.append(rec)
    return out


def measured_ahead(name: str, rows: list[dict[str, Any]], members: int) -> list[dict[str, Any]]:
    """``measure_problem`` in a worker, its time recorded as the ensembles'."""
    from longtime.core import phases

    with phases.phase("ensembles", name):
        return measure_problem(name, rows, members)


class Ahead:
    """The ensembles measured by the main job's workers beside its checks, once the timing
    processes have timed the rows (``task`` hands out each covered problem's measure), so
    that ``run`` finds them done (its ``ahead``). They read the rows as stored, as ``run``
    does: the same records wherever they are measured."""

    def __init__(self, rows: list[dict[str, Any]], members: int = MEMBERS):
        self.members = members
        self.ready = chaotic_problems(rows)
        self.rows = {name: [r for r in rows if r["problem"] == name] for name in self.ready}
        self.records: dict[str, list[dict[str, Any]]] = {}

    def task(self):
        """(the function, its arguments, where its records go) of a covered problem not handed
        out yet, or None."""
        if not self.ready:
            return None
        name = self.ready.pop(0)
        return measured_ahead, (name, self.rows.pop(name), self.members), \
            lambda records: self.records.__setitem__(name, records)


def summary(records: list[dict[str, Any]]) -> dict[str, str]:
    """Per problem, one line: how many schemes' distributions are as the reference's, and
    how many are told apart (the worst named)."""
    out = {}
    for name in sorted({r["problem"] for r in records}):
        mine = [r for r in records if r["problem"] == name]
        first = mine[0]
        if first.get("floor") is None:
            out[name] = f"not measured: {first.get('note') or 'no reference ensemble'}"
            continue
        ok = [r for r in mine if r.get("status") == Status.OK and r.get("distance") is not None]
        apart = sorted((r for r in ok if r.get("distinguishable")), key=lambda r: -r["distance"])
        others = Counter(r.get("status") for r in mine if r not in ok)
        text = (f"{len(ok) - len(apart)} of {len(ok)} schemes as heyoka (distance <= {ensemble.FLOOR_FACTOR:g} x the "
                f"floor {first['floor']:.3g})")
        if apart:
            text += f"; told apart: {', '.join(r['integrator'] for r in apart[:4])}" + (
                f" and {len(apart) - 4} more" if len(apart) > 4 else "") + f" (up to {apart[0]['distance']:.3g})"
        if others:
            text += "; no distance: " + ", ".join(f"{k} {v}" for k, v in sorted(others.items(), key=str))
        settings = ", ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}"
                             for k, v in (first.get("problem_settings") or {}).items())
        out[name] = (f"{text}; {first['members']} members, size {first['size']:g}"
                     + (f", from {settings}" if settings else "")
                     + f", {first.get('observable')} over the last {first['window']:.0%} of t = "
                       f"{first.get('t_final', 0):.4g} ({first.get('span_lyapunov', 0):.3g} Lyapunov times)")
    return out
