"""The results page: one self-contained static HTML file (figures inline as SVG, no
script or style from the network, no server).

Head: the run's metadata (command, commit, versions, machine) and the counts of each
status. Per problem: the work-precision figure (error against the minimum CPU time of the
repeats, a bar to the slowest repeat), the drift of every invariant against time for a
representative setting of each scheme (log-log, so growth laws read as slopes; one panel
per invariant), the change of the problem's diagnostics likewise, the Pareto front as a
table, the growth classes per scheme and setting, the fitted orders, and the stability
intervals of the schemes where they were measured. Then one capability matrix, schemes x
problems: ran / skipped and why / diverged / failed.

Colours: one per scheme family (the module that defines the scheme: explicit RK,
splitting, ...), a marker per scheme within it; legends sit outside the axes.

The figures are drawn by longtime.reporting.figures.results (ahead of the page, by idle
pool workers, with longtime.reporting.figures_ahead).
"""
from __future__ import annotations

import json
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Iterable

from longtime.measure.orders import left_out, observed_orders
from longtime.reporting.figures.results import all_figures
from longtime.reporting.figures.style import styles
from longtime.reporting.figures_ahead import FiguresAhead, stability_schemes
from longtime.reporting.markup import CSS, SCRIPT, escape, num, slug, table
from longtime.reporting.report import (
    _not_ok,
    format_counts,
    main_t_final,
    pareto,
    pareto_field,
    pareto_groups,
    setting,
    status_counts,
    target_text,
)

PAGE_NAME = "index.html"


def provenance_text(run: dict) -> str:
    """longtime's commit (dirty marked) and the code under test of a stored run."""
    from longtime.execution import provenance

    versions = json.loads(run["versions"]) if run.get("versions") else {}
    own = versions.get("longtime_git") if isinstance(versions, dict) else None
    mine = ""
    if isinstance(own, dict) and own.get("commit"):
        mine = f"longtime {own['commit'][:10]}{'+dirty' if own.get('dirty') else ''}; "
    return mine + provenance.text(provenance.run_code(run))


def _meta(runs: list[dict]) -> str:
    body = []
    for r in runs:
        versions = json.loads(r["versions"]) if r.get("versions") else {}
        machine = json.loads(r["machine"]) if r.get("machine") else {}
        body += [["run", f"{r['id']} ({r.get('status')}; {r.get('done')} of {r.get('planned')} cells)"],
                 ["command", f"longtime {r.get('command') or ''}"],
                 ["started / finished", f"{r.get('started')} / {r.get('finished') or '-'}"],
                 ["commit", r.get("git_commit") or "-"],
                 ["code under test", provenance_text(r)],
                 ["versions", ", ".join(f"{k} {v}" for k, v in versions.items() if v and isinstance(v, str))],
                 ["machine", ", ".join(f"{k} {v}" for k, v in machine.items() if v)]]
        if "calibrations" in r:
            from longtime.execution.calibration import drift_text

            body.append(["calibration", drift_text(r["calibrations"])])
    rows = "".join(f"<tr><td>{escape(a)}</td><td>{escape(b)}</td></tr>" for a, b in body)
    return f'<table class="meta">{rows}</table>'


def _pareto_table(rows: list[dict]) -> str:
    field = pareto_field(rows)
    front = pareto(rows, field) if field else []
    if not front:
        return '<p class="note">No ok row with an error and a CPU time.</p>'
    body = [[target_text(p), p["best"]["integrator"], setting(p["best"]), num(p["best"]["cpu_s"]),
             (f"{p['next']['integrator']} ({setting(p['next'])})" if p["next"] else "none"),
             (f"x{p['slower']:.3g}" if p["slower"] else "-")] for p in pareto_groups(front)]
    return (f'<p class="note">For each target, the fastest ok row whose {escape(field)} meets it over t_final = '
            f'{main_t_final(rows):.6g} (CPU: the minimum of the repeats) and the fastest other scheme meeting it.</p>'
            + table([f"{field} <=", "fastest scheme", "setting", "CPU s", "next best scheme", "next is slower"],
                     body))


def _growth_cell(row: dict, name: str) -> str:
    """One growth law as a table cell: the class, alpha and its interval; an undetermined
    class with its reason beside it, a class with what it rests on as its title."""
    cls = row.get(f"{name}.growth_class")
    if not cls:
        return "<td>-</td>"
    alpha, ci = row.get(f"{name}.growth"), row.get(f"{name}.growth_ci")
    text = f"{cls} {alpha:.2f}" if isinstance(alpha, (int, float)) else cls  # exponents: two decimals
    if isinstance(ci, list) and len(ci) == 2 and all(isinstance(c, (int, float)) for c in ci):
        text += f" [{ci[0]:.2f}, {ci[1]:.2f}]"
    if cls == "saturated" and row.get(f"{name}.saturated_t") is not None:
        text += f" (at t = {num(row[f'{name}.saturated_t'])}; alpha before)"
    reason = row.get(f"{name}.growth_reason") or ""
    if cls == "undetermined":
        return f'<td class="undetermined">{escape(text)}<br><span class="note">{escape(reason)}</span></td>'
    return f'<td title="{escape(reason)}">{escape(text)}</td>'


def _growth_table(rows: list[dict]) -> str | None:
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
            body.append(cells + [_growth_cell(mine[0], n) for n in names])
    if not body:
        return None
    return ('<p class="note">Growth law of each drift (and of the solution error) fitted over time, per setting: '
            'the class, the exponent alpha of e ~ t^alpha on the last two decades and its interval (it spans the '
            'slopes on three windows of a decade). A class stands only where the windows agree on it (or the '
            'error is at round-off); otherwise it is undetermined, with the reason (docs/metrics.md). Hover a '
            'class for the window slopes.</p>'
            + table(["scheme", "setting", *[f"{'solution error' if n == 'error' else n}" for n in names]], body,
                     raw=True))


def _orders_table(fits: list[dict]) -> str | None:
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
                                 f"{num(f['order_points'][0][0])} .. {num(f['order_points'][-1][0])})") + "</td>",
                     f"<td>{flag}</td>"])
    return table(["scheme", *(["N"] if with_n else []), "declared", "observed", "95 % interval", "points used", ""],
                  body, raw=True)


def _capability_matrix(rows: list[dict]) -> str:
    problems = sorted({r["problem"] for r in rows})
    schemes = sorted({r["integrator"] for r in rows})
    body = []
    for s in schemes:
        cells = [f"<td>{escape(s)}</td>"]
        for p in problems:
            mine = [r for r in rows if r["problem"] == p and r["integrator"] == s]
            if not mine:
                cells.append('<td class="skipped">not in run</td>')
                continue
            counts = status_counts(mine)
            worst = next(st for st in ("failed", "timeout", "diverged", "skipped", "ok") if counts.get(st))
            title = text = format_counts(counts)
            if worst == "skipped":
                title = "skipped: " + str(mine[0].get("message") or "").removeprefix(s + " ")
                text = title.split(", which")[0]  # the column names the problem
            cells.append(f'<td class="{worst}" title="{escape(title)}">{escape(text)}</td>')
        body.append(cells)
    return table(["scheme \\ problem", *problems], body, raw=True)


def _stability_table(found: dict[str, str]) -> str | None:
    """The table of the interval texts ``found`` (scheme -> text)."""
    if not found:
        return None
    body = [[s, txt] for s, txt in sorted(found.items())]
    return ('<p class="note">Imaginary-axis stability interval: the y with |R(iy)| <= 1 (to 1e-9), R measured '
            'from one step of each scheme on the rotation q\' = p, p\' = -q (<code>longtime list --stability</code>, '
            '<code>longtime plot stability</code>); a step h on a mode of frequency omega is stable while '
            'omega h is in it.</p>' + table(["scheme", "interval of y"], body))


def build_page(rows: list[dict[str, Any]], runs: list[dict[str, Any]], drift: bool = True,
               stability: bool = True, jobs: int = 1, ahead: FiguresAhead | None = None,
               history: str | None = None) -> str:
    """The page's HTML for ``rows`` (of the ``runs`` whose metadata heads it); the figures are
    drawn on ``jobs`` processes, but for those ``ahead`` drew from the same rows. ``history``:
    the history section (longtime.reporting.history.page_section), placed before the capability matrix."""
    problems = sorted({r["problem"] for r in rows})
    style = styles(sorted({r["integrator"] for r in rows}))
    # the heaviest problems first, so the processes finish together
    by_problem = dict(sorted(((p, [r for r in rows if r["problem"] == p]) for p in problems),
                             key=lambda item: -len(item[1])))
    from longtime.measure.stability import interval_texts

    builtin, plugins = stability_schemes(rows) if stability else ({}, {})
    figures, intervals = all_figures(by_problem, style, drift, jobs, builtin, ahead)
    fits = observed_orders(rows)
    missing = left_out(rows)
    counts = status_counts(rows)
    out = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
           '<meta name="viewport" content="width=device-width, initial-scale=1">',
           "<title>longtime results</title>", f"<style>{CSS}</style>", "</head><body>",
           "<h1>longtime: results</h1>", _meta(runs), *_calibration_figures(runs),
           f"<p><b>{len(rows)} cells:</b> " + escape(format_counts(counts)) + "</p>",
           "<nav>" + "".join(f'<a href="#{slug(p)}">{escape(p)}</a>' for p in problems)
           + ('<a href="#history">history</a>' if history else "")
           + '<a href="#capabilities">capability matrix</a></nav>']
    for p in problems:
        mine, figs = by_problem[p], figures[p]
        out.append(f'<h2 id="{slug(p)}">{escape(p)}</h2><p>{escape(format_counts(status_counts(mine)))}</p>')
        out.append("<h3>Fastest scheme per accuracy (Pareto front)</h3>" + _pareto_table(mine))
        fig = figs["work_precision"]
        if fig:
            out.append(f'<h3>Work-precision</h3><figure class="plot">{fig}<figcaption>{escape(figs["field"])} against '
                       f"CPU seconds, one point per setting; colour: scheme family, marker: scheme."
                       f"</figcaption></figure>")
        fig = figs.get("work_precision_instructions")
        if fig:
            out.append(f'<h3>Work-precision in instructions</h3><figure class="plot">{fig}<figcaption>'
                       f"{escape(figs['field'])} against the instructions of the integration, counted under "
                       f"Valgrind (--cost instructions): a deterministic cost, blind to cache misses and "
                       f"memory stalls; cells without a count are left out.</figcaption></figure>")
        if drift:
            fig, notes = figs["drift"], figs["drift_notes"]
            if fig:
                out.append(f'<h3>Invariant drift against time</h3><figure class="plot">{fig}<figcaption>'
                           f"Relative error of each invariant (absolute where it starts at 0), log-log (a "
                           f"slope is a growth law), for each scheme's setting of median CPU time (the upper "
                           f"envelope each row keeps); one panel per invariant."
                           f"{escape(' ' + '; '.join(notes)) if notes else ''}</figcaption></figure>")
            fig, notes = figs.get("diagnostics"), figs.get("diagnostics_notes") or []
            if fig:
                out.append(f'<h3>Diagnostics against time</h3><figure class="plot">{fig}<figcaption>'
                           f"Change of each diagnostic from its initial value, relative (absolute where it "
                           f"starts at 0), log-log: quantities the problem watches but the flow does not "
                           f"conserve, so never a drift and never classed."
                           f"{escape(' ' + '; '.join(notes)) if notes else ''}</figcaption></figure>")
        growth = _growth_table(mine)
        if growth:
            out.append("<h3>Growth classes</h3>" + growth)
        orders = _orders_table([f for f in fits if f["problem"] == p])
        if orders:
            out.append("<h3>Observed order</h3><p class=\"note\">Least-squares slope of log error against "
                       "log step over the asymptotic range (floors and pre-asymptotic points dropped), "
                       "with its 95 % interval; only where at least two local slopes agree within 0.1 "
                       "(otherwise the order is undetermined, listed below with its slopes, and never "
                       "flagged).</p>" + orders)
        mine_missing = [m for m in missing if m["problem"] == p]
        if mine_missing:
            out.append(("" if orders else "<h3>Observed order</h3>") + "<p>Left out of the order table:</p><ul>"
                       + "".join(f"<li>{escape(m['integrator'])}: {escape(m['reason'])}</li>" for m in mine_missing)
                       + "</ul>")
        folded = _not_ok(mine)
        if folded:
            out.append("<h3>Not run to the end, or the solution lost</h3><ul>" + "".join(
                f"<li>{escape(why)}: {escape(', '.join(s))}</li>" for why, s in sorted(folded.items())) + "</ul>")
    if history:
        out.append(history)
    out.append('<h2 id="capabilities">Capability matrix</h2>' + _capability_matrix(rows))
    stab = _stability_table({**interval_texts(plugins), **intervals}) if stability else None
    if stab:
        out.append('<h2 id="stability">Linear stability</h2>' + stab)
    out.append(f'<p class="note">Written {datetime.now(timezone.utc).isoformat(timespec="seconds")} by '
               f"<code>longtime report --html</code>.</p>")
    out.append(f"<script>{SCRIPT}</script></body></html>")
    return "\n".join(out)


def _calibration_figures(runs: list[dict[str, Any]]) -> list[str]:
    """Per run with calibrations: how the machine's speed drifted during it."""
    from longtime.reporting.figures.results import calibration_svg

    out = []
    for r in runs:
        fig = calibration_svg(r.get("calibrations") or [])
        if fig:
            out.append(f'<figure class="plot">{fig}<figcaption>Run {r["id"]}: the reference workload\'s CPU time '
                       f"(the fastest of its repeats, a bar to the slowest) at each calibration; each row's "
                       f"<code>cpu_s_calibrated</code> is its <code>cpu_s</code> over the calibration of its "
                       f"process nearest in time.</figcaption></figure>")
    return out


def write_page(out_dir: str | Path, rows: list[dict[str, Any]], runs: list[dict[str, Any]],
               drift: bool = True, jobs: int = 1, ahead: FiguresAhead | None = None,
               history: str | None = None) -> Path:
    """Write ``out_dir``/index.html (figures drawn on ``jobs`` processes, or ``ahead``);
    return its path."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = out / PAGE_NAME
    path.write_text(build_page(rows, runs, drift=drift, jobs=jobs, ahead=ahead, history=history), encoding="utf-8")
    return path


def write_html(out_dir, rows: list[dict[str, Any]], store, run_ids: Iterable[int] | None = None,
               jobs: int | None = None, ahead=None):
    """The results page of ``rows`` into ``out_dir``/index.html, headed by the metadata of
    ``run_ids`` (default: every run the rows come from), its figures drawn on ``jobs``
    processes (default: one per core) but for those drawn ``ahead`` (an
    figures_ahead.FiguresAhead); returns its path."""
    from longtime.reporting.history import page_section

    ids = sorted(set(run_ids) if run_ids is not None else {r.get("run_id") for r in rows if r.get("run_id")})
    runs = [{**r, "calibrations": store.calibrations(r["id"])} for r in store.runs() if r["id"] in ids]
    history = page_section(store, rows, styles(sorted({r["integrator"] for r in rows})))
    from longtime.execution.pool import workers

    return write_page(out_dir, rows, runs, jobs=workers(jobs or 0), ahead=ahead, history=history)
