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

The drift curves come from the rows: each keeps the upper envelope of every invariant's
error (and every diagnostic's change) at 80 log-spaced times (``drift_curves``,
``diag_curves``, metrics.drift_envelope), so the page runs nothing; a row stored when rows
kept only the first invariant's (``drift_curve``) shows that one. Only a row stored before
rows kept any is run again, untimed, skipped when
its stored CPU time exceeds ``DRIFT_BUDGET_S`` or once a problem's re-runs add up to
``DRIFT_PROBLEM_BUDGET_S`` (cheapest first); the caption says which setting was drawn and
names those left out.
"""
from __future__ import annotations

import hashlib
import html
import io
import json
import math
import re
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from .figures import plain_log_ticks, pyplot
from .fmt import positive
from .orders import left_out, observed_orders
from .roles import ROW_PARAMETERS
from .report import (_not_ok, format_counts, main_t_final, pareto, pareto_field, pareto_groups, setting, status_counts,
                     target_text)

DRIFT_BUDGET_S = 2.0  # stored cpu_s above which a drift curve is not recomputed for the page
DRIFT_PROBLEM_BUDGET_S = 10.0  # and the stored cpu_s of the curves re-run for one problem, in all
DRIFT_SAMPLES = 2001
LINE_STYLES = ("-", "--", ":", "-.")
MAX_PANELS = 12  # invariants (or diagnostics) a drift figure draws; the caption names the rest
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "<", ">", "*", "h")
FAMILY_COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2",
                  "#17becf", "#7f7f7f", "#bcbd22")
PAGE_NAME = "index.html"


def family(scheme: str) -> str:
    """The family of a scheme: the module of longtime.integrators that defines it or the
    built-in family it subclasses ('explicit_rk', 'splitting', ...; a plugin's Splitting is
    'splitting'), else the module that defines it."""
    from . import registry

    try:
        cls = registry.integrator_class(scheme)
    except Exception:  # a scheme of an old run that is no longer installed
        return "other"
    builtin = next((k.__module__ for k in cls.__mro__ if k.__module__.startswith("longtime.integrators.")),
                   cls.__module__)
    return builtin.rsplit(".", 1)[-1]


def styles(schemes: Sequence[str]) -> dict[str, dict[str, str]]:
    """scheme -> {color, marker}: one colour per family, one marker per scheme within it."""
    fams = sorted({family(s) for s in schemes})
    out, used = {}, {}
    for s in sorted(schemes):
        f = family(s)
        k = used.get(f, 0)
        used[f] = k + 1
        out[s] = {"color": FAMILY_COLOURS[fams.index(f) % len(FAMILY_COLOURS)],
                  "marker": MARKERS[k % len(MARKERS)]}
    return out


def svg(fig) -> str:
    """The figure as inline SVG markup (no XML prolog); closes the figure.

    Text stays text (``svg.fonttype`` none): the page can be searched for a scheme's name, and
    the SVG is a third smaller and faster to write than with every glyph as a path. The
    figure is drawn once: its tight box is measured with Agg's renderer, which lays the
    figure out without drawing it, where ``bbox_inches="tight"`` draws the whole figure
    twice (together about a third of the page's time). The right margin leaves room for a
    browser without DejaVu Sans, whose fallback font may set the legend a little wider."""
    import matplotlib
    from matplotlib.transforms import Bbox

    for ax in fig.axes:
        plain_log_ticks(ax)
    x0, y0, x1, y1 = fig.get_tightbbox(fig.canvas.get_renderer()).extents
    box = Bbox.from_extents(x0 - 0.1, y0 - 0.1, x1 + 0.3, y1 + 0.1)  # inches
    buf = io.StringIO()
    with matplotlib.rc_context({"svg.fonttype": "none"}):
        fig.savefig(buf, format="svg", bbox_inches=box)
    pyplot().close(fig)
    text = buf.getvalue()
    return text[text.index("<svg"):]


def _legend_outside(ax) -> None:
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0, frameon=False)


def sweeps(rows: list[dict]) -> dict[tuple, list[dict]]:
    """The rows as curves, (scheme, t_final, settings, N or None) -> rows, in that order: a
    scheme's points at another final time or other settings are another curve, never
    joined to its main sweep. N splits a scheme's rows into curves where it was set (bpl's
    N=10 and N=15), not where the scheme derived it from the tolerance (heyoka,
    taylor-adaptive without --order: each tol has its own N, and the tol sweep is one curve)."""
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault((r["integrator"], r.get("t_final"), r.get("settings") or ""), []).append(r)
    out: dict[tuple, list[dict]] = {}
    for key, mine in sorted(groups.items(), key=lambda kv: (kv[0][0], str(kv[0][1]), kv[0][2])):
        orders = {_order(r) for r in mine}
        per_tol: dict[Any, set] = {}
        for r in mine:
            per_tol.setdefault(r.get("tol"), set()).add(_order(r))
        derived = len(per_tol) > 1 and None not in per_tol and all(len(n) == 1 for n in per_tol.values())
        if len(orders) == 1 or derived:
            out[(*key, None)] = mine
            continue
        for n in sorted(orders, key=lambda n: -1 if n is None else n):
            out[(*key, n)] = [r for r in mine if _order(r) == n]
    return out


def _order(row: dict) -> int | None:
    n = row.get("order")
    return int(n) if isinstance(n, (int, float)) and n == n else None


def work_precision_svg(rows: list[dict], field: str, style: dict) -> str | None:
    ok = [r for r in rows if r.get("status") == "ok" and positive(r.get("cpu_s")) and positive(r.get(field))]
    if not ok:
        return None
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7.0, 4.2))
    t_main = main_t_final(ok)
    for (scheme, t_final, settings, order), mine in sweeps(ok).items():
        pts = sorted((r["cpu_s"], r[field], r.get("cpu_s_max") or r["cpu_s"]) for r in mine)
        x, y, x_max = (np.array(v) for v in zip(*pts))
        st, other_t = style[scheme], t_final != t_main
        label = f"{scheme} ({family(scheme)})" + (f" t_final={t_final:.4g}" if other_t else "") \
            + (f" N={order}" if order is not None else "") + (f" {settings}" if settings else "")
        ax.errorbar(x, y, xerr=[np.zeros_like(x), x_max - x], color=st["color"], marker=st["marker"], ms=5,
                    lw=1.1, ls="--" if other_t or settings else "-", capsize=0, elinewidth=2.2, alpha=0.9,
                    label=label)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("CPU seconds (minimum of repeats; bar to the slowest)")
    ax.set_ylabel(field)
    ax.grid(True, which="both", alpha=0.3)
    _legend_outside(ax)
    return svg(fig)


def representative(rows: list[dict]) -> dict[str, dict]:
    """scheme -> the ok row of median CPU time among its rows (the drawn setting)."""
    out = {}
    for scheme in sorted({r["integrator"] for r in rows}):
        ok = sorted((r for r in rows if r["integrator"] == scheme and r.get("status") == "ok"
                     and positive(r.get("cpu_s"))), key=lambda r: r["cpu_s"])
        if ok:
            out[scheme] = ok[(len(ok) - 1) // 2]
    return out


def row_curves(row: dict) -> dict[str, list[tuple[str, np.ndarray, np.ndarray]]]:
    """{"invariant": [(name, t, e(t))], "diagnostic": [...]} of a row's setting, t counted
    from t[0]: the envelopes the row keeps (``drift_curves`` and ``diag_curves``, from
    metrics.drift_envelope; a row stored when rows kept only ``drift_curve`` has its first
    invariant's), or for a row stored before rows kept any, a run of its setting again
    (untimed)."""
    def kept(curves, key):
        return [(c[key], np.r_[0.0, c["t"]], np.r_[0.0, c["error"]]) for c in curves or []
                if isinstance(c, dict) and c.get("t")]

    if "drift_curve" in row:
        first = [row["drift_curve"]] if row.get("drift_curve") else []
        return {"invariant": kept(row["drift_curves"] if "drift_curves" in row else first, "invariant"),
                "diagnostic": kept(row.get("diag_curves"), "diagnostic")}
    from . import registry
    from .cells import Cell, integrate_cell
    from .metrics import relative_error

    # the row's settings are the problem's and the scheme's merged (cells.base_row): split them
    settings = json.loads(row["settings"]) if row.get("settings") else {}
    pcls, icls = registry.problem_class(row["problem"]), registry.integrator_class(row["integrator"])
    psets = {k: v for k, v in settings.items() if k in pcls.parameters}
    isets = {k: v for k, v in settings.items() if k in icls.parameters}
    for k in ROW_PARAMETERS:  # the parameters with a row field of their own
        value = row.get(k)
        if k in icls.parameters and positive(value):
            isets[k] = int(value) if icls.parameters[k].kind is int else value
    problem, traj = integrate_cell(Cell(row["problem"], row["integrator"], psets, isets, row["t_final"]),
                                   max_samples=DRIFT_SAMPLES)
    with np.errstate(all="ignore"):
        return {kind: [(name, traj.t, relative_error(values)) for name, values in found.items()]
                for kind, found in (("invariant", problem.invariants(traj.t, traj.u)),
                                    ("diagnostic", problem.diagnostics(traj.t, traj.u)))}


def drift_svg(rows: list[dict], style: dict, kind: str = "invariant") -> tuple[str | None, list[str]]:
    """The drift figure of one problem, one panel per invariant (``kind`` "diagnostic": per
    diagnostic, their change), and the notes on what it leaves out."""
    notes, curves, spent = [], [], 0.0
    # the cheapest first, so a problem's budget leaves out the fewest schemes
    for scheme, row in sorted(representative(rows).items(), key=lambda item: item[1]["cpu_s"]):
        rerun = "drift_curve" not in row  # a row stored before rows kept it: run it again
        if not rerun and not (row.get("drift_curves") or row.get("drift_curve") or row.get("diag_curves")):
            continue  # nothing to draw (a row measured since rows keep their curves)
        if rerun and (row["cpu_s"] > DRIFT_BUDGET_S or spent + row["cpu_s"] > DRIFT_PROBLEM_BUDGET_S):
            notes.append(f"{scheme}: not drawn (its run takes {row['cpu_s']:.3g} s)")
            continue
        spent += row["cpu_s"] if rerun else 0.0
        try:
            found = row_curves(row)[kind]
        except Exception as exc:  # a scheme that cannot be re-run here leaves a note, not a hole
            notes.append(f"{scheme}: not drawn ({type(exc).__name__}: {exc})")
            continue
        curves += [(scheme, row, name, t, err) for name, t, err in found]
    names = list(dict.fromkeys(c[2] for c in curves))
    if not names:
        return None, notes
    if len(names) > MAX_PANELS:
        notes.append(f"{', '.join(names[MAX_PANELS:])}: not drawn here (longtime plot drift --invariant NAME)")
        names = names[:MAX_PANELS]
    plt = pyplot()
    cols = min(len(names), 3)
    rows_ = -(-len(names) // cols)
    size = (7.0, 4.2) if len(names) == 1 else (3.2 * cols, 2.6 * rows_ + 0.2)
    fig, axes = plt.subplots(rows_, cols, figsize=size, squeeze=False, sharex=True)
    what = "relative error" if kind == "invariant" else "relative change"
    handles: dict[str, Any] = {}
    for k, ax in enumerate(axes.flat):
        if k >= len(names):
            ax.set_visible(False)
            continue
        mine = [c for c in curves if c[2] == names[k]]
        for i, (scheme, row, name, t, err) in enumerate(mine):
            keep = (t > t[0]) & (err > 0)
            st = style[scheme]
            every = max(1, int(keep.sum()) // 12)
            label = f"{scheme} {setting(row)}"
            # curves that coincide (a diagnostic the schemes all follow) stay apart: a dash
            # pattern and the markers shifted per curve
            (line,) = ax.loglog(t[keep] - t[0], err[keep], color=st["color"], marker=st["marker"],
                                markevery=(i % every, every), ms=4 if len(names) == 1 else 3, lw=0.9,
                                ls=LINE_STYLES[i % len(LINE_STYLES)], label=label)
            handles.setdefault(label, line)
        ax.grid(True, which="both", alpha=0.3)
        if len(names) == 1:
            ax.set_ylabel(f"{what} of {names[k]}")
        else:
            ax.set_title(names[k], fontsize=10)
            if k % cols == 0:
                ax.set_ylabel(what, fontsize=9)
            ax.tick_params(labelsize=8)
        if k >= len(names) - cols:
            ax.set_xlabel("t - t0")
    axes[0, -1 if len(names) >= cols else len(names) - 1].legend(
        list(handles.values()), list(handles), fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0),
        borderaxespad=0.0, frameon=False)
    fig.tight_layout()
    return svg(fig), notes


# ------------------------------------------------------------------ HTML
CSS = """
body{font-family:DejaVu Sans,Helvetica,Arial,sans-serif;margin:1.5em auto;max-width:1100px;color:#222;
line-height:1.35;padding:0 1em}
h1{font-size:1.5em}h2{font-size:1.25em;border-bottom:1px solid #ccc;margin-top:2em}h3{font-size:1.05em}
table{border-collapse:collapse;font-size:.85em;margin:.4em 0 1em}
td,th{border:1px solid #ddd;padding:2px 6px;text-align:left;vertical-align:top}
th{background:#f3f3f3}td.num{text-align:right;font-variant-numeric:tabular-nums}
.ok{background:#e8f5e9}.skipped{background:#f5f5f5;color:#666}.diverged{background:#fff3e0}
.failed,.timeout{background:#ffebee}.undetermined{background:#fff8e1}.flag{color:#b71c1c;font-weight:bold}
figure{margin:.5em 0}figure svg{max-width:100%;height:auto}figcaption{font-size:.85em;color:#555}
.meta td:first-child{font-weight:bold}.note{font-size:.85em;color:#555}
nav a{margin-right:.8em}
"""

# records errors and checks that every figure has a drawn size; a browser test reads the
# result from <body data-figures="..." data-errors="..."> (no network, no external script)
SCRIPT = """
(function(){var errs=[];
window.addEventListener('error',function(e){errs.push(String(e.message));document.body.dataset.errors=errs.join('|');});
window.addEventListener('load',function(){var figs=document.querySelectorAll('figure.plot');var drawn=0;
figs.forEach(function(f){var s=f.querySelector('svg');if(s){var b=s.getBoundingClientRect();
if(b.width>50&&b.height>50&&s.querySelectorAll('path').length>0){drawn++;f.dataset.rendered='yes';}}});
document.body.dataset.figures=figs.length;document.body.dataset.rendered=drawn;
document.body.dataset.errors=errs.join('|');});})();
"""


def _e(x: Any) -> str:
    return html.escape("" if x is None else str(x))


def _num(x, digits: int = 3) -> str:
    return f"{x:.{digits}g}" if isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) else "-"


def _table(header: Sequence[str], body: list[Sequence[str]], raw: bool = False) -> str:
    head = "".join(f"<th>{_e(h)}</th>" for h in header)
    rows = "".join("<tr>" + "".join(c if raw else f"<td>{_e(c)}</td>" for c in r) + "</tr>" for r in body)
    return f"<table><tr>{head}</tr>{rows}</table>"


def _slug(name: str) -> str:
    return re.sub(r"[^a-z0-9-]", "-", name.lower())


def _meta(runs: list[dict]) -> str:
    body = []
    for r in runs:
        versions = json.loads(r["versions"]) if r.get("versions") else {}
        machine = json.loads(r["machine"]) if r.get("machine") else {}
        body += [["run", f"{r['id']} ({r.get('status')}; {r.get('done')} of {r.get('planned')} cells)"],
                 ["command", f"longtime {r.get('command') or ''}"],
                 ["started / finished", f"{r.get('started')} / {r.get('finished') or '-'}"],
                 ["commit", r.get("git_commit") or "-"],
                 ["versions", ", ".join(f"{k} {v}" for k, v in versions.items() if v)],
                 ["machine", ", ".join(f"{k} {v}" for k, v in machine.items() if v)]]
        if "calibrations" in r:
            from .calibration import drift_text

            body.append(["calibration", drift_text(r["calibrations"])])
    rows = "".join(f"<tr><td>{_e(a)}</td><td>{_e(b)}</td></tr>" for a, b in body)
    return f'<table class="meta">{rows}</table>'


def _pareto_table(rows: list[dict]) -> str:
    field = pareto_field(rows)
    front = pareto(rows, field) if field else []
    if not front:
        return '<p class="note">No ok row with an error and a CPU time.</p>'
    body = [[target_text(p), p["best"]["integrator"], setting(p["best"]), _num(p["best"]["cpu_s"]),
             (f"{p['next']['integrator']} ({setting(p['next'])})" if p["next"] else "none"),
             (f"x{p['slower']:.3g}" if p["slower"] else "-")] for p in pareto_groups(front)]
    return (f'<p class="note">For each target, the fastest ok row whose {_e(field)} meets it over t_final = '
            f'{main_t_final(rows):.6g} (CPU: the minimum of the repeats) and the fastest other scheme meeting it.</p>'
            + _table([f"{field} <=", "fastest scheme", "setting", "CPU s", "next best scheme", "next is slower"],
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
        text += f" (at t = {_num(row[f'{name}.saturated_t'])}; alpha before)"
    reason = row.get(f"{name}.growth_reason") or ""
    if cls == "undetermined":
        return f'<td class="undetermined">{_e(text)}<br><span class="note">{_e(reason)}</span></td>'
    return f'<td title="{_e(reason)}">{_e(text)}</td>'


def _growth_table(rows: list[dict]) -> str | None:
    """One line per scheme and setting (the longest run first): per invariant and the
    solution error, the growth class, the fitted exponent and its interval."""
    from .report import growth_names, growth_settings

    names = growth_names(rows)
    if not names:
        return None
    body = []
    for scheme in sorted({r["integrator"] for r in rows}):
        for text, mine in growth_settings([r for r in rows if r["integrator"] == scheme]):
            cells = [f"<td>{_e(scheme)}</td>", f"<td>{_e(text or '-')}</td>"]
            body.append(cells + [_growth_cell(mine[0], n) for n in names])
    if not body:
        return None
    return ('<p class="note">Growth law of each drift (and of the solution error) fitted over time, per setting: '
            'the class, the exponent alpha of e ~ t^alpha on the last two decades and its interval (it spans the '
            'slopes on three windows of a decade). A class stands only where the windows agree on it (or the '
            'error is at round-off); otherwise it is undetermined, with the reason (docs/metrics.md). Hover a '
            'class for the window slopes.</p>'
            + _table(["scheme", "setting", *[f"{'solution error' if n == 'error' else n}" for n in names]], body,
                     raw=True))


def _orders_table(fits: list[dict]) -> str | None:
    if not fits:
        return None
    body, with_n = [], any(f["order"] is not None for f in fits)
    for f in fits:
        ci = f["observed_order_ci"]
        flag = '<span class="flag">misses declared</span>' if f["order_flag"] else ""
        body.append(["<td>" + _e(f["integrator"]) + "</td>",
                     *(["<td>" + _e("-" if f["order"] is None else f"N={f['order']}") + "</td>"] if with_n else []),
                     f'<td class="num">{_e(f["declared_order"] if f["declared_order"] is not None else "-")}</td>',
                     f'<td class="num">{f["observed_order"]:.2f}</td>',
                     f'<td class="num">{"-" if ci is None else f"+- {ci:.2f}"}</td>',
                     "<td>" + _e(f"{len(f['order_points'])} ({f['order_error_field']} vs {f['order_variable']}: "
                                 f"{_num(f['order_points'][0][0])} .. {_num(f['order_points'][-1][0])})") + "</td>",
                     f"<td>{flag}</td>"])
    return _table(["scheme", *(["N"] if with_n else []), "declared", "observed", "95 % interval", "points used", ""],
                  body, raw=True)


def _capability_matrix(rows: list[dict]) -> str:
    problems = sorted({r["problem"] for r in rows})
    schemes = sorted({r["integrator"] for r in rows})
    body = []
    for s in schemes:
        cells = [f"<td>{_e(s)}</td>"]
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
            cells.append(f'<td class="{worst}" title="{_e(title)}">{_e(text)}</td>')
        body.append(cells)
    return _table(["scheme \\ problem", *problems], body, raw=True)


def _stability_schemes(rows: list[dict]) -> tuple[dict[str, list | None], dict[str, list | None]]:
    """The schemes of ``rows`` whose stability intervals the page shows, each with the N its
    rows ran with (a series scheme; its default N where the row has none): (built-in ones,
    measured here where not cached: their solves are capped; plugins', read from the cache
    only, since a plugin's step that never returns would hang the page: `longtime list
    --stability` measures them)."""
    from . import registry
    from .stability import SERIES_ORDERS

    wanted: dict[str, set | None] = {}
    for r in rows:
        if r.get("status") == "skipped":
            wanted.setdefault(r["integrator"], None)
            continue
        n = r.get("order")
        orders = wanted.get(r["integrator"]) or set()
        orders.add(int(n) if isinstance(n, (int, float)) and n == n else None)
        wanted[r["integrator"]] = orders
    schemes = {}
    for s, orders in wanted.items():
        param = registry.integrator_class(s).parameters.get("order") if s in registry.integrators() else None
        if param is None:
            schemes[s] = None
        else:
            schemes[s] = sorted({param.default if n is None else n for n in (orders or {None})}) or [SERIES_ORDERS[0]]
    builtin = {s: o for s, o in schemes.items()
               if s in registry.integrators() and registry.integrator_class(s).__module__.startswith("longtime.")}
    return builtin, {s: o for s, o in schemes.items() if s not in builtin}


def _stability_table(found: dict[str, str]) -> str | None:
    """The table of the interval texts ``found`` (scheme -> text)."""
    if not found:
        return None
    body = [[s, txt] for s, txt in sorted(found.items())]
    return ('<p class="note">Imaginary-axis stability interval: the y with |R(iy)| <= 1 (to 1e-9), R measured '
            'from one step of each scheme on the rotation q\' = p, p\' = -q (<code>longtime list --stability</code>, '
            '<code>longtime plot stability</code>); a step h on a mode of frequency omega is stable while '
            'omega h is in it.</p>' + _table(["scheme", "interval of y"], body))


def problem_figures(rows: list[dict[str, Any]], style: dict, drift: bool = True) -> dict[str, Any]:
    """One problem's figures: {"field", "work_precision" (SVG or None), "drift" (SVG or
    None), "drift_notes", "diagnostics" (SVG or None: the problem's diagnostics, where its
    rows keep them), "diagnostics_notes"}."""
    field = pareto_field(rows)
    out: dict[str, Any] = {"field": field, "work_precision": None, "drift": None, "drift_notes": [],
                           "diagnostics": None, "diagnostics_notes": []}
    if field:
        out["work_precision"] = work_precision_svg(rows, field, style)
    if drift:
        out["drift"], out["drift_notes"] = drift_svg(rows, style)
        if any(r.get("diag_curves") for r in rows):
            out["diagnostics"], out["diagnostics_notes"] = drift_svg(rows, style, "diagnostic")
    return out


def _all_figures(by_problem: dict[str, list[dict]], style: dict, drift: bool, jobs: int,
                 stability: dict[str, list | None], ahead: "FiguresAhead | None" = None
                 ) -> tuple[dict[str, dict], dict[str, str]]:
    """problem_figures of every problem, and the interval texts of the ``stability`` schemes
    (measured where not cached), on ``jobs`` processes: matplotlib spends about a third of a
    second a figure, and a scheme's stability interval about a second when not cached, all of
    it in Python, so only processes run them side by side. Figures ``ahead`` drew from the
    same rows and styles are taken as they are, and the intervals it found at the same N."""
    from .stability import cached_texts, interval_texts

    figures = {}
    for p, rows in by_problem.items():
        found = ahead.figures(p, rows, style, drift) if ahead is not None else None
        if found is not None:
            figures[p] = found
    todo = {p: rows for p, rows in by_problem.items() if p not in figures}
    texts = {s: ahead.interval(s, o) for s, o in stability.items()} if ahead is not None else {}
    texts = {s: text for s, text in texts.items() if text is not None}
    found, missing = cached_texts({s: o for s, o in stability.items() if s not in texts})
    texts.update(found)
    if jobs <= 1 or len(todo) + len(missing) < 4:
        figures.update({p: problem_figures(rows, style, drift) for p, rows in todo.items()})
        texts.update(interval_texts(missing, compute=True))
        return figures, texts
    from .pool import spawn_pool

    with spawn_pool(jobs) as pool:
        intervals = [pool.submit(interval_texts, {s: o}, True) for s, o in missing.items()]
        drawn = {p: pool.submit(problem_figures, rows, style, drift) for p, rows in todo.items()}
        for f in intervals:
            texts.update(f.result())
        figures.update({p: f.result() for p, f in drawn.items()})
        return figures, texts


class FiguresAhead:
    """A page's figures drawn while the matrix still runs: each problem's as soon as its last
    cell is stored, by a pool worker that has no cell left to run (``task`` is the process
    pool's ``ExecOptions.idle_work``; ``add`` sees each row as it is stored), and likewise a
    built-in scheme's stability interval once its last cell is stored (measured into the
    cache on a cold machine: about a second a scheme). The figures of a main job's last
    problems are then drawn beside its last cells instead of after them. The page takes a
    figure only if it was drawn from the very rows and styles it would draw it from (a
    resumed run's page has older rows too), an interval only for the same N; it does the
    others itself."""

    def __init__(self, cells: Sequence, run_id: int | None, drift: bool = True):
        self.run_id, self.drift = run_id, drift
        self.left: dict[str, int] = {}  # cells not stored yet, per problem and per scheme
        for c in cells:
            for name in (("problem", c.problem), ("scheme", c.integrator)):
                self.left[name] = self.left.get(name, 0) + 1
        self.style = styles(sorted({c.integrator for c in cells}))
        self.rows: dict[str, list[dict]] = {}
        self.outcomes: dict[str, list[dict]] = {}  # per scheme: what _stability_schemes reads
        self.ready: list[tuple[str, str]] = []
        self.drawn: dict[str, tuple[str, dict]] = {}
        self.intervals: dict[str, tuple[Any, str | None]] = {}  # scheme -> (its N, its text)

    def add(self, cell, row: dict) -> None:
        """A stored row (kept as the store gives it back: JSON and its run id)."""
        self.rows.setdefault(cell.problem, []).append({"run_id": self.run_id, **json.loads(json.dumps(row))})
        self.outcomes.setdefault(cell.integrator, []).append(
            {k: row.get(k) for k in ("integrator", "status", "order")})
        for name in (("problem", cell.problem), ("scheme", cell.integrator)):
            self.left[name] = self.left.get(name, 1) - 1
            if self.left[name] == 0:
                self.ready.append(name)

    def task(self):
        """(a function, its arguments, where its result goes): the figures of a problem whose
        rows are all in, or the stability interval of such a scheme; None when there is none."""
        while self.ready:
            kind, name = self.ready.pop(0)
            if kind == "problem":
                rows = self.rows.pop(name)
                key = self._key(rows, self.style, self.drift)
                return problem_figures, (rows, self.style, self.drift), \
                    lambda figs: self.drawn.__setitem__(name, (key, figs))
            builtin, _ = _stability_schemes(self.outcomes.pop(name))
            if name in builtin:  # a plugin's is read from the cache only (see _stability_schemes)
                from .stability import interval_texts

                orders = builtin[name]
                return interval_texts, ({name: orders}, True), \
                    lambda texts: self.intervals.__setitem__(name, (orders, texts.get(name)))
        return None

    def figures(self, problem: str, rows: list[dict], style: dict, drift: bool) -> dict | None:
        """The figures drawn ahead for ``problem`` if they were drawn from these rows and styles."""
        key, figs = self.drawn.get(problem, (None, None))
        return figs if key is not None and key == self._key(rows, style, drift) else None

    def interval(self, scheme: str, orders) -> str | None:
        """``scheme``'s interval text if it was found ahead at these N (None: a scheme without N)."""
        if scheme not in self.intervals:
            return None
        found_orders, text = self.intervals[scheme]
        return text if found_orders == orders else None

    @staticmethod
    def _key(rows: list[dict], style: dict, drift: bool) -> str:
        text = json.dumps([rows, style, drift], sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()


def build_page(rows: list[dict[str, Any]], runs: list[dict[str, Any]], drift: bool = True,
               stability: bool = True, jobs: int = 1, ahead: FiguresAhead | None = None,
               history: str | None = None) -> str:
    """The page's HTML for ``rows`` (of the ``runs`` whose metadata heads it); the figures are
    drawn on ``jobs`` processes, but for those ``ahead`` drew from the same rows. ``history``:
    the history section (longtime.history.page_section), placed before the capability matrix."""
    problems = sorted({r["problem"] for r in rows})
    style = styles(sorted({r["integrator"] for r in rows}))
    # the heaviest problems first, so the processes finish together
    by_problem = dict(sorted(((p, [r for r in rows if r["problem"] == p]) for p in problems),
                             key=lambda item: -len(item[1])))
    from .stability import interval_texts

    builtin, plugins = _stability_schemes(rows) if stability else ({}, {})
    figures, intervals = _all_figures(by_problem, style, drift, jobs, builtin, ahead)
    fits = observed_orders(rows)
    missing = left_out(rows)
    counts = status_counts(rows)
    out = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
           '<meta name="viewport" content="width=device-width, initial-scale=1">',
           "<title>longtime results</title>", f"<style>{CSS}</style>", "</head><body>",
           "<h1>longtime: results</h1>", _meta(runs), *_calibration_figures(runs),
           f"<p><b>{len(rows)} cells:</b> " + _e(format_counts(counts)) + "</p>",
           "<nav>" + "".join(f'<a href="#{_slug(p)}">{_e(p)}</a>' for p in problems)
           + ('<a href="#history">history</a>' if history else "")
           + '<a href="#capabilities">capability matrix</a></nav>']
    for p in problems:
        mine, figs = by_problem[p], figures[p]
        out.append(f'<h2 id="{_slug(p)}">{_e(p)}</h2><p>{_e(format_counts(status_counts(mine)))}</p>')
        out.append("<h3>Fastest scheme per accuracy (Pareto front)</h3>" + _pareto_table(mine))
        fig = figs["work_precision"]
        if fig:
            out.append(f'<h3>Work-precision</h3><figure class="plot">{fig}<figcaption>{_e(figs["field"])} against '
                       f"CPU seconds, one point per setting; colour: scheme family, marker: scheme."
                       f"</figcaption></figure>")
        if drift:
            fig, notes = figs["drift"], figs["drift_notes"]
            if fig:
                out.append(f'<h3>Invariant drift against time</h3><figure class="plot">{fig}<figcaption>'
                           f"Relative error of each invariant (absolute where it starts at 0), log-log (a "
                           f"slope is a growth law), for each scheme's setting of median CPU time (the upper "
                           f"envelope each row keeps); one panel per invariant."
                           f"{_e(' ' + '; '.join(notes)) if notes else ''}</figcaption></figure>")
            fig, notes = figs.get("diagnostics"), figs.get("diagnostics_notes") or []
            if fig:
                out.append(f'<h3>Diagnostics against time</h3><figure class="plot">{fig}<figcaption>'
                           f"Change of each diagnostic from its initial value, relative (absolute where it "
                           f"starts at 0), log-log: quantities the problem watches but the flow does not "
                           f"conserve, so never a drift and never classed."
                           f"{_e(' ' + '; '.join(notes)) if notes else ''}</figcaption></figure>")
        growth = _growth_table(mine)
        if growth:
            out.append("<h3>Growth classes</h3>" + growth)
        orders = _orders_table([f for f in fits if f["problem"] == p])
        if orders:
            out.append("<h3>Observed order</h3><p class=\"note\">Least-squares slope of log error against "
                       "log step over the asymptotic range (floors and pre-asymptotic points dropped), "
                       "with its 95 % interval.</p>" + orders)
        mine_missing = [m for m in missing if m["problem"] == p]
        if mine_missing:
            out.append(("" if orders else "<h3>Observed order</h3>") + "<p>Left out of the order table:</p><ul>"
                       + "".join(f"<li>{_e(m['integrator'])}: {_e(m['reason'])}</li>" for m in mine_missing)
                       + "</ul>")
        folded = _not_ok(mine)
        if folded:
            out.append("<h3>Not run to the end, or the solution lost</h3><ul>" + "".join(
                f"<li>{_e(why)}: {_e(', '.join(s))}</li>" for why, s in sorted(folded.items())) + "</ul>")
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
    from .calibration import calibration_svg

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
