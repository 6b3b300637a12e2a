"""What ``longtime report`` prints (``report_text``): by default the first screen (the
answer table across problems, the counts with their reasons, a line or two per problem);
with ``--full`` the summary per problem (longtime.reporting.report) and every row."""
from __future__ import annotations

from typing import Any, Iterable

from longtime.core.rowtext import setting
from longtime.core.status import Status, bounded
from longtime.measure.lyapunov import past_predictability
from longtime.predict.decision import Verdict
from longtime.predict.settings import SOLUTION_FIELDS
from longtime.reporting.recommend import map_verdicts
from longtime.reporting.report import counts_text, pareto, pareto_field, render, summary

# the answer table's columns: (target error, horizon in units of the run's final time)
ANSWER_TARGETS = ((1e-3, 100.0), (1e-6, 1.0), (1e-10, 1.0))
NO_POINTWISE = "no pointwise answer"
# the default report's width: no line past it (a long list wraps, indented)
WIDTH = 100
ANSWER_CELL = 23  # an answer column's least width (a setting is never cut: wider where it needs)


def _wrap(text: str, indent: str = "    ", width: int = WIDTH) -> list[str]:
    import textwrap

    return textwrap.wrap(text, width=width, subsequent_indent=indent, break_on_hyphens=False) or [""]


def _chaotic(problem: str, rows: list[dict[str, Any]]) -> bool:
    """A problem declared chaotic some of whose rows lost the solution (their error reached
    O(1) within the run): a pointwise error past its predictability horizon answers nothing."""
    from longtime.core import registry

    cls = registry.problems().get(problem)
    return bool(getattr(cls, "chaotic", False)) and any(past_predictability(r) for r in rows)


def answer_rows(rows: list[dict[str, Any]], checks: Iterable[dict[str, Any]] = (),
                verdicts: dict[str, Verdict] | None = None) -> list[dict[str, Any]]:
    """Per problem, the cheapest setting predicted (longtime.reporting.verdict) to keep each
    of ANSWER_TARGETS' errors up to its horizon: {"problem", "field", "t_main", "answers":
    [text per target]}. A chaotic problem's target no setting keeps, once its rows lost the
    solution, is NO_POINTWISE (its ensembles say what holds). ``verdicts``: ``map_verdicts``
    of these rows and checks, where the caller has them already."""
    from longtime.predict.decision import decide
    from longtime.reporting.verdict import decision_text

    out = []
    for problem, v in (map_verdicts(rows, checks) if verdicts is None else verdicts).items():
        mine = [r for r in rows if r.get("problem") == problem]
        chaotic = _chaotic(problem, mine)
        answers, costs = [], []
        for error, factor in ANSWER_TARGETS:
            if v.measure is None or not v.candidates or v.t_main is None:
                answers.append(NO_POINTWISE if chaotic else "nothing measured")
                costs.append("")
                continue
            d = decide(v.candidates, error, v.t_main * factor)
            if d.best is None and chaotic:
                answers.append(NO_POINTWISE)
            elif d.best is None and not d.open:
                answers.append("none measured")
            else:
                answers.append(decision_text(d))
            costs.append(cost_text(d, v.t_main * factor))
        out.append({"problem": problem, "field": v.measure.field if v.measure else None, "t_main": v.t_main,
                    "answers": answers, "costs": costs, "chaotic": chaotic})
    return out


def cost_text(d: Any, horizon: float) -> str:
    """The predicted CPU of a decision's answer up to ``horizon`` and its runner-up's over it
    ('0.012 s, runner-up x2.3'); '' without an answer."""
    b, r = d.best, d.runner_up
    if b is None:
        return ""
    cpu = b.cpu_at(horizon)
    if r is None:
        return f"{cpu:.2g} s, no runner-up"
    if not cpu > 0:
        return f"{cpu:.2g} s"
    ratio = r.cpu_at(horizon) / cpu
    return f"{cpu:.2g} s, runner-up x{ratio:.2g}" if ratio < 10 else f"{cpu:.2g} s, runner-up x{ratio:.0f}"


def missed_text(c: dict[str, Any]) -> str:
    """Why a stored check failed ('' where it held or was not judged): the measured error
    or CPU time as a multiple of the predicted, past the bounds check_holds allows, or the
    winner's rank lost."""
    from longtime.predict.checks import CHECK_COST_FACTOR, CHECK_ERROR_FACTOR, check_holds, cpu_pair

    if check_holds(c) is not False:
        return ""
    if c.get("check_role") == "chaos":
        return f"error {c.get('measured_error'):.2g} measured, not above the target {c['check_target']:g}"
    out = []
    me, pe = c.get("measured_error"), c.get("predicted_error")
    mc, pc, calibrated = cpu_pair(c)
    low = 0.0 if c.get("predicted_bound") else 1 / CHECK_ERROR_FACTOR
    if not low <= me / pe <= CHECK_ERROR_FACTOR:
        out.append(f"error x{me / pe:.2g} the predicted ({me:.2g} against {pe:.2g}; within "
                   f"x{CHECK_ERROR_FACTOR:g} holds)")
    if mc > CHECK_COST_FACTOR * pc:
        out.append(f"CPU x{mc / pc:.2g} the predicted, in calibrated time (the machine's speed taken out: not "
                   f"its load; within x{CHECK_COST_FACTOR:g} holds)" if calibrated else
                   f"CPU x{mc / pc:.2g} the predicted ({mc:.3g} s against {pc:.3g} s; within x{CHECK_COST_FACTOR:g} "
                   f"holds; not calibrated: the machine may have been loaded)")
    if c.get("rank_held") is False:
        out.append("a rival kept the target for less: " + ", ".join(c.get("rank_lost_to") or []))
    return "; ".join(out)


def answer_table(answers: list[dict[str, Any]]) -> list[str]:
    """The cross-problem table of ``answer_rows``: a line per problem with each answer's
    setting in full, and beneath it a line with each answer's predicted CPU time and its
    runner-up's as a multiple of it."""
    width = max([len("problem")] + [len(a["problem"]) + (4 if a["field"] not in (None, *SOLUTION_FIELDS) else 0)
                                   for a in answers])
    head = [f"{e:.0e} to {'T' if f == 1 else f'{f:g} T'}" for e, f in ANSWER_TARGETS]
    cols = [max([ANSWER_CELL, len(head[k])] + [len(a["answers"][k]) for a in answers if len(a["answers"]) > k]
                + [len(c) for a in answers for c in a.get("costs", [])[k:k + 1]]) for k in range(len(head))]
    lines = [(f"{'problem':<{width}}  {'T':>8}  " + "  ".join(f"{h:<{w}}" for h, w in zip(head, cols))).rstrip()]
    for a in answers:
        invariant = a["field"] not in (None, *SOLUTION_FIELDS)
        name = a["problem"] + (f" ({a['field'].removesuffix('.max')})" if invariant else "")
        t = f"{a['t_main']:.4g}" if a["t_main"] else "-"
        if all(x == NO_POINTWISE for x in a["answers"]):
            lines.append(f"{name:<{width}}  {t:>8}  {NO_POINTWISE} (chaotic: the solution is lost within the run)")
            continue
        lines.append((f"{name:<{width}}  {t:>8}  " + "  ".join(f"{c:<{w}}" for c, w in zip(a["answers"], cols)))
                     .rstrip())
        costs = a.get("costs") or []
        if any(costs):
            lines.append((f"{'':<{width}}  {'':>8}  " + "  ".join(f"{c:<{w}}" for c, w in zip(costs, cols))).rstrip())
    return lines


def _pairs_text(pairs: list[tuple[str, str]], limit: int = 2 * WIDTH - 40) -> str:
    """'verlet, yoshida6 on duffing-1, toda; rk4 on kepler': the problems of each set of
    schemes, the largest sets first; past ``limit`` characters the rest counted."""
    by: dict[str, list[str]] = {}
    for problem, scheme in sorted(set(pairs)):
        by.setdefault(problem, []).append(scheme)
    sets: dict[tuple[str, ...], list[str]] = {}
    for problem, schemes in by.items():
        sets.setdefault(tuple(schemes), []).append(problem)
    parts, shown = [], 0
    for schemes, problems in sorted(sets.items(), key=lambda kv: (-len(kv[0]) * len(kv[1]), kv[0])):
        part = f"{', '.join(schemes)} on {', '.join(problems)}"
        if not parts and len(part) > limit:  # the largest set alone is too long: counted
            part = f"{', '.join(schemes)} on {len(problems)} problems"
            if len(part) > limit:
                part = f"{len(schemes)} schemes on {', '.join(problems)}" if len(problems) == 1 else \
                    f"{len(schemes)} schemes on {len(problems)} problems"
        if parts and sum(map(len, parts)) + len(part) > limit:
            rest = len(set(pairs)) - shown
            parts.append(f"{rest} more pair{'s' if rest != 1 else ''} (`--full`)")
            break
        parts.append(part)
        shown += len(schemes) * len(problems)
    return "; ".join(parts)


# the pairs named after a count on the first screen: about one line of them, the rest counted
ONE_LINE = WIDTH


def _need(why: str) -> str:
    """A skip reason's short form: 'needs separable, which the problem does not provide' ->
    'needs separable'; 'needs the package diffrax: pip install ...' kept whole (it says the fix)."""
    import re

    return why if "pip install" in why else re.split(r" \(|, which", why)[0]


def count_lines(rows: list[dict[str, Any]], orders: bool = True) -> list[str]:
    """The counts of the rows, each count that is not ok with its reason: skipped pairs by
    what the scheme needs (once, not per problem), rows that did not run to the end by
    status and first reason, rows that lost the solution, the orders left out, the settings
    the budget moved."""
    import re

    from longtime.execution.budget import notes
    from longtime.measure.orders import left_out as left_out_of_fits
    from longtime.predict.need import FACTOR as NEED_FACTOR
    from longtime.predict.need import left_out

    lines = [f"{len(rows)} cells: {counts_text(rows)}"]
    skipped: dict[str, list[tuple[str, str]]] = {}
    for r in rows:
        if r.get("status") == Status.SKIPPED:
            why = str(r.get("message") or "no reason stored").removeprefix(f"{r['integrator']} ")
            why = re.sub(rf"\b{re.escape(r['problem'])}\b", "the problem", why)
            skipped.setdefault(why, []).append((r["problem"], r["integrator"]))
    if skipped:  # one paragraph: what the schemes need, by count; `--full` names the pairs
        total = sum(len(p) for p in skipped.values())
        by_count = sorted(skipped.items(), key=lambda kv: -len(kv[1]))
        needs = "; ".join(f"{_need(why)} {len(pairs)}" for why, pairs in by_count)
        lines += _wrap(f"  skipped {total}, does not apply: {needs} (`--full` names the pairs)")
    for status in (Status.DIVERGED, Status.FAILED, Status.TIMEOUT):
        bad = [r for r in rows if r.get("status") == status and not bounded(r)]
        reasons: dict[str, list[tuple[str, str]]] = {}
        for r in bad:
            first = str(r.get("message") or "no message stored").split(";")[0].strip()
            first = re.sub(r"\s*\b(at|near|from|to) t ?= ?[-+0-9.e]+", "", first)  # the reason, not where
            reasons.setdefault(first, []).append((r["problem"], r["integrator"]))
        for why, pairs in sorted(reasons.items(), key=lambda kv: -len(kv[1])):
            lines += _wrap(f"  {status} {len(pairs)} ({why}): {_pairs_text(sorted(set(pairs)), ONE_LINE)}")
    stopped = sorted({(r["problem"], r["integrator"]) for r in rows if bounded(r)})
    if stopped:  # no failure: a cheaper setting of the library keeps the target
        lines += _wrap(f"  stopped at their library's bound {sum(map(bounded, rows))} (past x2 the CPU of a setting "
                       f"of the same library that keeps the target: not its answer): {_pairs_text(stopped, ONE_LINE)}")
    lost = [(r["problem"], r["integrator"]) for r in rows if r.get("status") == Status.OK and r.get("solution_lost")]
    if lost:
        lines += _wrap(f"  ok but lost the solution {len(lost)} (error O(1) at the end): "
                       f"{_pairs_text(sorted(set(lost)), ONE_LINE)}")
    moved = notes(rows)
    if moved:
        lines += _wrap(f"  moved by the default matrix's budget {len(moved)} (a run over its seconds: fewer "
                       f"settings, a time limit, or a shorter t_final for a fixed step): "
                       f"{_pairs_text(sorted(moved), ONE_LINE)}")
    alone = sum(1 for r in rows if left_out(r))
    if alone:
        lines += _wrap(f"  timed in its own process only {alone} (dominated by more than x{NEED_FACTOR:g} on every "
                       f"front of error against CPU: their time changes no answer; each row's timed_in says by how "
                       f"much; --timing all times every cell in every process)")
    if orders:
        out = left_out_of_fits(rows)
        if out:
            kinds: dict[str, list[tuple[str, str]]] = {}
            for m in out:
                why = re.sub(r"\s*\(.*", "", str(m["reason"]).split(":")[0]).strip()
                why = "too few points left" if re.match(r"\d+ of \d+ points left", why) else why
                kinds.setdefault(why, []).append(
                    (m["problem"], m["integrator"]))
            lines += _wrap(f"  left out of the order fits {len(out)}: " + ", ".join(
                f"{why} {len(pairs)}" for why, pairs in sorted(kinds.items(), key=lambda kv: -len(kv[1])))
                + " (`--full` names each)")
    return lines


def problem_line(problem: str, rows: list[dict[str, Any]], fits: list[dict[str, Any]], chaos: str | None) -> list[str]:
    """One problem in a line or two: the fastest scheme per accuracy at the run's final
    time (each scheme down to the finest decade it is fastest at; its settings in --full),
    the orders that miss the declared one, the ensembles of a chaotic one."""
    field = pareto_field(rows)
    front: list[dict[str, Any]] = []
    for p in pareto(rows, field) if field else []:  # consecutive decades of the same fastest row folded
        if front and front[-1]["best"] is p["best"]:
            front[-1]["finest"] = p["target"]
        else:
            front.append({**p, "finest": p["target"]})
    parts = []
    if front:
        reach: list[list] = []  # [scheme, its finest decade] of consecutive decades a scheme is fastest at
        for p in front:
            if reach and reach[-1][0] == p["best"]["integrator"]:
                reach[-1][1] = p["finest"]
            else:
                reach.append([p["best"]["integrator"], p["finest"]])
        parts.append(f"fastest ({field} <=): " + ", ".join(f"{scheme} to {finest:.0e}" for scheme, finest in reach))
    else:
        parts.append("no ok row with an error and a CPU time")
    misses = [f["integrator"] for f in fits if f["order_flag"]]
    if misses:
        parts.append("misses its order: " + ", ".join(sorted(set(misses))))
    lines = _wrap(f"{problem}: " + "; ".join(parts))
    if chaos:
        lines += _wrap(f"    ensemble distance to heyoka's (W1 / std): {chaos.split(';')[0]}")
    return lines


def first_screen(rows: list[dict[str, Any]], checks: Iterable[dict[str, Any]] = (),
                 ensembles: Iterable[dict[str, Any]] = (), page: str | None = None,
                 verdicts: dict[str, Verdict] | None = None) -> str:
    """The default report (``longtime report``, the end of ``longtime matrix``): the answer
    table across problems, the counts with their reasons, a line or two per problem, the
    notes said once, where the rest is. At most about 80 lines at WIDTH columns for a main
    job's store; ``--full`` prints ``summary(full=True)`` and every row."""
    from longtime.execution.ensembles import summary as ensemble_summary
    from longtime.measure.orders import observed_orders

    if not rows:
        return "no rows"
    checks = list(checks)
    answers = answer_rows(rows, checks, verdicts)
    lines = _wrap("cheapest setting predicted to keep the error up to T (T: the run's final time; the error: the "
                  "solution's, the energy's where marked (H)), beneath it its predicted CPU time and the runner-up's "
                  "as a multiple of it; `longtime recommend -p P --error E --horizon T`:", "  ")
    lines += answer_table(answers)
    lines.append("")
    lines += count_lines(rows)
    lines.append("")
    fits = observed_orders(rows)
    chaos = ensemble_summary(list(ensembles))
    for problem in sorted({r["problem"] for r in rows}):
        mine = [r for r in rows if r["problem"] == problem]
        lines += problem_line(problem, mine, [f for f in fits if f["problem"] == problem], chaos.get(problem))
    lines.append("")
    if checks:
        from longtime.predict.checks import check_summary

        lines += _wrap(f"checks: {check_summary(checks)}")
        for c in checks:
            why = missed_text(c)
            if why:
                lines += _wrap(f"  failed: {c['integrator']} {setting(c)} on {c['problem']} to t = {c['t_final']:.4g} "
                               f"({c.get('check_role') or 'check'}): {why}", "    ")
    lines += _wrap("a prediction extrapolates a setting's growth law up to a multiple of its run's span, never "
                   "past an error of O(1) (docs/metrics.md, \"How far a class is trusted\"); undetermined (S): "
                   "S might keep it but no law reaches that far, `longtime recommend` names the run that decides it",
                   "  ")
    more = "`longtime report --full`: each problem's verdict per horizon, Pareto front, orders, growth and every row"
    lines += _wrap(more, "  ")
    lines.append(f"results page: {page}" if page else "results page: `longtime report --html DIR` writes it")
    return "\n".join(lines)


def report_text(rows: list[dict[str, Any]], fmt: str = "table", full: bool = False,
                checks: Iterable[dict[str, Any]] = (), ensembles: Iterable[dict[str, Any]] = (),
                page: str | None = None, verdicts: dict[str, Verdict] | None = None) -> str:
    """What ``longtime report`` prints: the first screen (format table: ``first_screen``;
    ``checks``: the stored checks of the verdicts' predictions; ``page``: the results page's
    path, named at its end; ``verdicts``: ``map_verdicts`` of the rows and checks, where the
    caller has them); with ``full`` every line of the summary per problem and the
    full per-cell tables instead; csv, json and markdown are the full tables."""
    if fmt != "table":
        return render(rows, fmt)
    if not full:
        return first_screen(rows, checks=checks, ensembles=ensembles, page=page, verdicts=verdicts)
    return summary(rows, full=True, checks=checks, ensembles=ensembles) + "\n\n" + render(rows, "table")
