"""The tables of the results page (longtime.reporting.page), each one HTML fragment from
stored rows: the Pareto front, the growth classes, the chaos and ensemble tables, the
observed orders, the capability matrix and the stability intervals."""
from __future__ import annotations

from longtime.core.rowschema import formatted
from longtime.core.status import Status, bounded
from longtime.reporting.markup import escape, num, table
from longtime.reporting.report import (
    format_counts,
    main_t_final,
    pareto,
    pareto_field,
    pareto_groups,
    setting,
    status_counts,
    target_text,
)


def pareto_table(rows: list[dict]) -> str:
    field = pareto_field(rows)
    front = pareto(rows, field) if field else []
    if not front:
        return '<p class="note">No ok row with an error and a CPU time.</p>'
    body = [[target_text(p), p["best"]["integrator"], setting(p["best"]), formatted("cpu_s", p["best"]["cpu_s"]),
             (f"{p['next']['integrator']} ({setting(p['next'])})" if p["next"] else "none"),
             (f"x{p['slower']:.3g}" if p["slower"] else "-")] for p in pareto_groups(front)]
    return (f'<p class="note">For each target, the fastest ok row whose {escape(field)} meets it over t_final = '
            f'{formatted("t_final", main_t_final(rows))} (CPU: the minimum of the repeats) and the fastest other '
            'scheme meeting it.</p>'
            + table([f"{field} <=", "fastest scheme", "setting", "CPU s", "next best scheme", "next is slower"],
                     body))


def growth_cell(row: dict, name: str) -> str:
    """One growth law as a table cell: the class; alpha, its interval and what the class
    rests on as its title (a tooltip); an undetermined class opens on a click to its reason."""
    cls = row.get(f"{name}.growth_class")
    if not cls:
        return "<td>-</td>"
    alpha, ci = row.get(f"{name}.growth"), row.get(f"{name}.growth_ci")
    fit = f"alpha {formatted(f'{name}.growth', alpha)}" if isinstance(alpha, (int, float)) else ""
    if fit and isinstance(ci, list) and len(ci) == 2 and all(isinstance(c, (int, float)) for c in ci):
        fit += f" [{formatted(f'{name}.growth_ci', ci)}]"
    if cls == "saturated" and row.get(f"{name}.saturated_t") is not None:
        fit += f" (before t = {formatted(f'{name}.saturated_t', row[f'{name}.saturated_t'])})"
    reason = row.get(f"{name}.growth_reason") or ""
    title = "; ".join(x for x in (fit, reason) if x)
    if cls == "undetermined":
        return (f'<td class="undetermined"><details><summary title="{escape(title)}">undetermined</summary>'
                f'<span class="note">{escape(title)}</span></details></td>')
    return f'<td class="law" title="{escape(title)}">{escape(cls)}</td>'


def growth_table(rows: list[dict]) -> str | None:
    """One line per scheme and setting (the longest run first): per invariant and the
    solution error, the growth class, the fitted exponent and its interval."""
    from longtime.reporting.report import growth_names, growth_settings

    names = growth_names(rows)
    if not names:
        return None
    body = []
    for scheme in sorted({r["integrator"] for r in rows}):
        for text, mine in growth_settings([r for r in rows if r["integrator"] == scheme]):
            cells = [f"<td>{escape(scheme)}</td>", f"<td>{escape(text or '-')}</td>"]
            body.append(cells + [growth_cell(mine[0], n) for n in names])
    if not body:
        return None
    return ('<p class="note">Growth law of each drift (and of the solution error) fitted over time, per setting: '
            'the class, the exponent alpha of e ~ t^alpha on the last two decades and its interval (it spans the '
            'slopes on three windows of a decade). A class stands only where the windows agree on it (or the '
            'error is at round-off); otherwise it is undetermined (docs/metrics.md). Hover a class for its '
            'exponent, interval and window slopes; click an undetermined one for its reason.</p>'
            + table(["scheme", "setting", *[f"{'solution error' if n == 'error' else n}" for n in names]], body,
                     raw=True))


def chaos_table(rows: list[dict]) -> str | None:
    """A chaotic problem's rows read in Lyapunov times: the Lyapunov time of its initial
    state, and per scheme and setting the time its solution error reached O(1) (its
    predictability horizon), in time and in Lyapunov times."""
    from longtime.core.rowtext import setting

    chaotic = [r for r in rows if "predictability_t" in r and r.get("status") == Status.OK]
    if not chaotic:
        return None
    first = next((r for r in chaotic if r.get("lyapunov_note")), chaotic[0])
    t_lyap = first.get("lyapunov_time")
    head = (f"Lyapunov time {formatted('lyapunov_time', t_lyap)} ({escape(first.get('lyapunov_note') or '')})"
            if t_lyap else
            f"No Lyapunov time: {escape(first.get('lyapunov_note') or 'not measured')}")
    body = [[r["integrator"], setting(r) or "-",
             *(formatted(f, r.get(f)) for f in ("t_final", "predictability_t", "predictability_lyapunov")),
             r.get("predictability_note") or ""]
            for r in sorted(chaotic, key=lambda r: (r["integrator"], r.get("t_final") or 0, str(setting(r))))]
    return (f'<p class="note">{head}. Past its predictability horizon (the first time its solution error '
            "reaches 0.5) a row's L2 error measures a lost solution: it enters no order fit and no Pareto front; "
            "what can still be right is a distribution (<code>longtime ensemble</code>, docs/metrics.md, "
            '"Chaos").</p>' + table(["scheme", "setting", "t_final", "error O(1) at t", "in Lyapunov times", "note"],
                                     body))


def ensemble_table(records: list[dict]) -> str | None:
    """A chaotic problem's stored ensemble distances (longtime.execution.ensembles): what was
    measured (members, size, state, span, observable, floor), then per scheme its setting, its
    distance, the floor and whether the two are told apart, or the status that left it
    without a distance."""
    from longtime.core.rowtext import setting
    from longtime.measure.ensemble import FLOOR_FACTOR

    if not records:
        return None
    first = next((r for r in records if r.get("floor") is not None), records[0])
    state = ", ".join(f"{k} = {v:g}" if isinstance(v, (int, float)) else f"{k} = {v}"
                      for k, v in (first.get("problem_settings") or {}).items())
    state = (f"the problem's chaotic state {state} (not the rows' state: their Lyapunov time above is that of the "
             f"default state)" if state else "the problem's initial state")
    if first.get("floor") is None:
        return f'<p class="note">No ensemble distance from {escape(state)}: {escape(first.get("note") or "")}.</p>'
    floor = first["floor"]
    head = (f"{first['members']} members from {escape(state)}, perturbed by a seeded relative "
            f"{formatted('size', first['size'])}, integrated to t = {formatted('t_final', first.get('t_final'))} "
            f"({formatted('span_lyapunov', first.get('span_lyapunov'))} Lyapunov times of that state, one is "
            f"{formatted('lyapunov_time', first.get('lyapunov_time'))}) by each scheme at the setting shown (its "
            f"row's nearest the default) and by heyoka. Observable: <code>{escape(first.get('observable') or '')}"
            f"</code>, pooled over the members and the last {first['window']:.0%} of the span. Distance: the "
            f"1-Wasserstein distance between the scheme's and heyoka's pools over the standard deviation of "
            f"heyoka's (0: the same distribution, 1: a shift by a standard deviation). Floor: the same between "
            f"two heyoka ensembles of other seeds ({formatted('floor', floor)}), what a finite ensemble shows by "
            f"itself. Told "
            f"apart: a distance above {FLOOR_FACTOR:g} x the floor. A scheme one of whose members diverged, "
            f"failed or passed the step's deadline has that status and no distance "
            f"(<code>longtime matrix --no-ensemble</code> skips the step; docs/metrics.md, \"Chaos\").")
    ok = sorted((r for r in records if r.get("status") == Status.OK and r.get("distance") is not None),
                key=lambda r: r["distance"])
    rest = sorted((r for r in records if r not in ok), key=lambda r: (r.get("status") or "", r["integrator"]))
    body = []
    for r in ok:
        apart = r["distance"] > FLOOR_FACTOR * floor
        body.append([f"<td>{escape(r['integrator'])}</td>", f"<td>{escape(setting(r) or '-')}</td>",
                     f'<td class="num">{formatted("distance", r["distance"])}</td>',
                     f'<td class="num">{formatted("floor", floor)}</td>',
                     f'<td class="num">{num(r["distance"] / floor) if floor > 0 else "-"}</td>',
                     f'<td class="{"flag" if apart else "ok"}">{"told apart" if apart else "as heyoka"}</td>'])
    for r in rest:
        body.append([f"<td>{escape(r['integrator'])}</td>", f"<td>{escape(setting(r) or '-')}</td>",
                     f'<td class="{escape(r.get("status") or "")}" colspan="4">{escape(r.get("status") or "")}: '
                     f'{escape(r.get("note") or "")}</td>'])
    return (f'<p class="note">{head}</p>'
            + table(["scheme", "setting", "distance", "floor", "distance / floor", "vs the floor"], body, raw=True))


def orders_table(fits: list[dict]) -> str | None:
    if not fits:
        return None
    body, with_n = [], any(f["order"] is not None for f in fits)
    for f in fits:
        ci = f["observed_order_ci"]
        flag = '<span class="flag">misses declared</span>' if f["order_flag"] else ""
        body.append(["<td>" + escape(f["integrator"]) + "</td>",
                     *(["<td>" + escape("-" if f["order"] is None else f"N={f['order']}") + "</td>"] if with_n else []),
                     f'<td class="num">{escape(f["declared_order"] if f["declared_order"] is not None else "-")}</td>',
                     f'<td class="num">{f["observed_order"]:.2f}</td>',
                     f'<td class="num">{"-" if ci is None else f"+- {ci:.2f}"}</td>',
                     "<td>" + escape(f"{len(f['order_points'])} ({f['order_error_field']} vs {f['order_variable']}: "
                                 f"{formatted(f['order_variable'], f['order_points'][0][0])} .. "
                                 f"{formatted(f['order_variable'], f['order_points'][-1][0])})") + "</td>",
                     f"<td>{flag}</td>"])
    return table(["scheme", *(["N"] if with_n else []), "declared", "observed", "95 % interval", "points used", ""],
                  body, raw=True)


ABBREVIATIONS = {Status.OK: "ok", Status.SKIPPED: "-", Status.DIVERGED: "div", Status.FAILED: "fail",
                 Status.TIMEOUT: "t/o"}


def capability_matrix(rows: list[dict]) -> str:
    """Schemes x problems, each cell its worst status, abbreviated (the counts and the reason
    of a skip in its title); the problems' names set vertically so that the matrix fits."""
    problems = sorted({r["problem"] for r in rows})
    schemes = sorted({r["integrator"] for r in rows})
    body = []
    for s in schemes:
        cells = [f"<td>{escape(s)}</td>"]
        for p in problems:
            mine = [r for r in rows if r["problem"] == p and r["integrator"] == s]
            if not mine:
                cells.append('<td class="skipped" title="not in this run"></td>')
                continue
            counts = status_counts(mine)
            stopped = sum(map(bounded, mine))  # stopped at its library's bound: no failure, not the worst
            title = format_counts(counts, stopped)
            if stopped:
                counts[Status.TIMEOUT] -= stopped
                title += (f"; {stopped} stopped at its library's bound"
                          " (a cheaper setting of the library keeps the target)")
            worst = next((st for st in (Status.FAILED, Status.TIMEOUT, Status.DIVERGED, Status.SKIPPED, Status.OK)
                          if counts.get(st)), Status.OK)
            text = ABBREVIATIONS[worst]
            lost = sum(1 for r in mine if r.get("status") == Status.OK and r.get("solution_lost"))
            if worst == Status.SKIPPED:
                title = "skipped: " + str(mine[0].get("message") or "").removeprefix(s + " ")
            elif worst != Status.OK:
                text += f" {counts[worst]}/{len(mine)}"
            elif stopped == len(mine):  # every run stopped at its library's bound
                worst, text = "stopped", "stop"
            elif lost:  # ran to the end, but the error reached O(1): not an ok answer
                worst, text = "lost", "lost" if lost == len(mine) else f"lost {lost}/{len(mine)}"
                title += f"; {lost} of them lost the solution (error O(1) at the end)"
            cells.append(f'<td class="{worst} cap" title="{escape(title)}">{escape(text)}</td>')
        body.append(cells)
    head = "".join(f'<th class="rot"><span>{escape(p)}</span></th>' for p in problems)
    rows_html = "".join("<tr>" + "".join(c) + "</tr>" for c in body)
    return ('<p class="note">Each cell: the worst outcome of the scheme on the problem (ok; lost: ran to the end '
            'with an error of O(1), the solution not followed; - skipped: does not apply; div diverged; fail failed; '
            't/o timeout; stop: stopped at its library\'s bound, a cheaper setting of the library keeping the target; '
            'blank: not in this run), with the counts and the reason of a skip in its title.</p>'
            f'<table class="capabilities"><tr><th>scheme \\ problem</th>{head}</tr>{rows_html}</table>')


def stability_table(found: dict[str, str]) -> str | None:
    """The table of the interval texts ``found`` (scheme -> text)."""
    if not found:
        return None
    body = [[s, txt] for s, txt in sorted(found.items())]
    return ('<p class="note">Imaginary-axis stability interval: the y with |R(iy)| <= 1 (to 1e-9), R measured '
            'from one step of each scheme on the rotation q\' = p, p\' = -q (<code>longtime list --stability</code>, '
            '<code>longtime plot stability</code>); a step h on a mode of frequency omega is stable while '
            'omega h is in it.</p>' + table(["scheme", "interval of y"], body))
