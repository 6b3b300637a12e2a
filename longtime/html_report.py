"""The results page: one self-contained static HTML file (figures inline as SVG, no
script or style from the network, no server).

Head: the run's metadata (command, commit, versions, machine) and the counts of each
status. Per problem: the work-precision figure (error against the minimum CPU time of the
repeats, a bar to the slowest repeat), the invariant drift against time for a
representative setting of each scheme (log-log, so growth laws read as slopes), the
Pareto front as a table, the growth classes, the fitted orders, and the stability
intervals of the schemes where they were measured. Then one capability matrix, schemes x
problems: ran / skipped and why / diverged / failed.

Colours: one per scheme family (the module that defines the scheme: explicit RK,
splitting, ...), a marker per scheme within it; legends sit outside the axes.

The drift curves come from the rows: each keeps the upper envelope of its first
invariant's error at 80 log-spaced times (``drift_curve``, metrics.drift_envelope), so the
page runs nothing. Only a row stored before rows kept it is run again, untimed, skipped when
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
from .orders import observed_orders
from .report import (_not_ok, format_counts, main_t_final, pareto, pareto_field, pareto_groups, setting, status_counts,
                     target_text)

DRIFT_BUDGET_S = 2.0  # stored cpu_s above which a drift curve is not recomputed for the page
DRIFT_PROBLEM_BUDGET_S = 10.0  # and the stored cpu_s of the curves re-run for one problem, in all
DRIFT_SAMPLES = 2001
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "<", ">", "*", "h")
FAMILY_COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2",
                  "#17becf", "#7f7f7f", "#bcbd22")
PAGE_NAME = "index.html"


def family(scheme: str) -> str:
    """The family of a scheme: the module that defines it ('explicit_rk', 'splitting', ...)."""
    from . import registry

    try:
        return registry.integrator_class(scheme).__module__.rsplit(".", 1)[-1]
    except Exception:  # a scheme of an old run that is no longer installed
        return "other"


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


def drift_curve(row: dict) -> tuple[np.ndarray, np.ndarray, str] | None:
    """(t, e_I(t), invariant name) of a row's setting: the envelope the row keeps
    (``drift_curve``, from metrics.drift_envelope, t counted from t0), or for a row stored
    before rows kept one, a run of its setting again (untimed)."""
    kept = row.get("drift_curve")
    if isinstance(kept, dict) and kept.get("t"):
        return np.r_[0.0, kept["t"]], np.r_[0.0, kept["error"]], kept["invariant"]
    from . import registry
    from .cells import Cell, integrate_cell
    from .metrics import relative_error

    # the row's settings are the problem's and the scheme's merged (cells.base_row): split them
    settings = json.loads(row["settings"]) if row.get("settings") else {}
    pcls, icls = registry.problem_class(row["problem"]), registry.integrator_class(row["integrator"])
    psets = {k: v for k, v in settings.items() if k in pcls.parameters}
    isets = {k: v for k, v in settings.items() if k in icls.parameters}
    for k in ("dt", "tol", "eps_res", "order"):
        if k in icls.parameters and positive(row.get(k)):
            isets[k] = int(row[k]) if k == "order" else row[k]
    problem, traj = integrate_cell(Cell(row["problem"], row["integrator"], psets, isets, row["t_final"]),
                                   max_samples=DRIFT_SAMPLES)
    inv = problem.invariants(traj.t, traj.u)
    name = "H" if "H" in inv else next(iter(inv), None)
    if name is None:
        return None
    return traj.t, relative_error(inv[name]), name


def drift_svg(rows: list[dict], style: dict) -> tuple[str | None, list[str]]:
    """The drift figure of one problem and the notes on what it leaves out."""
    notes, curves, spent = [], [], 0.0
    # the cheapest first, so a problem's budget leaves out the fewest schemes
    for scheme, row in sorted(representative(rows).items(), key=lambda item: item[1]["cpu_s"]):
        if "drift_curve" in row and not row["drift_curve"]:
            continue  # no invariant to draw (a row measured since rows keep their curve)
        rerun = "drift_curve" not in row  # a row stored before rows kept it: run it again
        if rerun and (row["cpu_s"] > DRIFT_BUDGET_S or spent + row["cpu_s"] > DRIFT_PROBLEM_BUDGET_S):
            notes.append(f"{scheme}: not drawn (its run takes {row['cpu_s']:.3g} s)")
            continue
        spent += row["cpu_s"] if rerun else 0.0
        try:
            curve = drift_curve(row)
        except Exception as exc:  # a scheme that cannot be re-run here leaves a note, not a hole
            notes.append(f"{scheme}: not drawn ({type(exc).__name__}: {exc})")
            continue
        if curve is not None:
            curves.append((scheme, row, *curve))
    if not curves:
        return None, notes
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7.0, 4.2))
    for scheme, row, t, err, name in curves:
        keep = (t > t[0]) & (err > 0)
        st = style[scheme]
        every = max(1, int(keep.sum()) // 12)
        ax.loglog(t[keep] - t[0], err[keep], color=st["color"], marker=st["marker"], markevery=every, ms=4,
                  lw=0.9, label=f"{scheme} {setting(row)}")
    ax.set_xlabel("t - t0")
    ax.set_ylabel(f"relative error of {curves[0][4]}")
    ax.grid(True, which="both", alpha=0.3)
    _legend_outside(ax)
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
.failed,.timeout{background:#ffebee}.flag{color:#b71c1c;font-weight:bold}
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


def _growth_table(rows: list[dict]) -> str | None:
    """One line per scheme: per invariant (and the error), the growth classes over its
    settings and the range of the fitted exponents."""
    names = sorted({k[: -len(".growth_class")] for r in rows for k in r
                    if k.endswith(".growth_class") and r.get(k)})
    if not names:
        return None
    body = []
    ok = [r for r in rows if r.get("status") == "ok"]
    for scheme in sorted({r["integrator"] for r in ok}):
        mine = [r for r in ok if r["integrator"] == scheme]
        cells = []
        for n in names:
            classes = sorted({str(r[f"{n}.growth_class"]) for r in mine if r.get(f"{n}.growth_class")})
            exps = [r[f"{n}.growth"] for r in mine if positive(abs(r.get(f"{n}.growth") or 0))
                    or r.get(f"{n}.growth") == 0]
            span = "" if not exps else (f" {_num(min(exps))}" if min(exps) == max(exps)
                                        else f" {_num(min(exps))}..{_num(max(exps))}")
            cells.append(("/".join(classes) or "-") + span)
        body.append([scheme, str(len(mine)), *cells])
    return ('<p class="note">Growth law of each drift (and of the solution error) fitted over time: its class, '
            'and the fitted exponent (range over the settings).</p>'
            + _table(["scheme", "settings", *[f"{n}: class exponent" for n in names]], body))


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
    None), "drift_notes"}."""
    field = pareto_field(rows)
    out: dict[str, Any] = {"field": field, "work_precision": None, "drift": None, "drift_notes": []}
    if field:
        out["work_precision"] = work_precision_svg(rows, field, style)
    if drift:
        out["drift"], out["drift_notes"] = drift_svg(rows, style)
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
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    # spawn: the caller may hold threads (numba, heyoka, a Dask client) that fork would copy
    with ProcessPoolExecutor(max_workers=jobs, mp_context=multiprocessing.get_context("spawn")) as pool:
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
               stability: bool = True, jobs: int = 1, ahead: FiguresAhead | None = None) -> str:
    """The page's HTML for ``rows`` (of the ``runs`` whose metadata heads it); the figures are
    drawn on ``jobs`` processes, but for those ``ahead`` drew from the same rows."""
    problems = sorted({r["problem"] for r in rows})
    style = styles(sorted({r["integrator"] for r in rows}))
    # the heaviest problems first, so the processes finish together
    by_problem = dict(sorted(((p, [r for r in rows if r["problem"] == p]) for p in problems),
                             key=lambda item: -len(item[1])))
    from .stability import interval_texts

    builtin, plugins = _stability_schemes(rows) if stability else ({}, {})
    figures, intervals = _all_figures(by_problem, style, drift, jobs, builtin, ahead)
    fits = observed_orders(rows)
    counts = status_counts(rows)
    out = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
           '<meta name="viewport" content="width=device-width, initial-scale=1">',
           "<title>longtime results</title>", f"<style>{CSS}</style>", "</head><body>",
           "<h1>longtime: results</h1>", _meta(runs),
           f"<p><b>{len(rows)} cells:</b> " + _e(format_counts(counts)) + "</p>",
           "<nav>" + "".join(f'<a href="#{_slug(p)}">{_e(p)}</a>' for p in problems)
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
                           f"Relative error of the invariant, log-log (a slope is a growth law), for each "
                           f"scheme's setting of median CPU time (the upper envelope each row keeps)."
                           f"{_e(' ' + '; '.join(notes)) if notes else ''}</figcaption></figure>")
        growth = _growth_table(mine)
        if growth:
            out.append("<h3>Growth classes</h3>" + growth)
        orders = _orders_table([f for f in fits if f["problem"] == p])
        if orders:
            out.append("<h3>Observed order</h3><p class=\"note\">Least-squares slope of log error against "
                       "log step over the asymptotic range (floors and pre-asymptotic points dropped), "
                       "with its 95 % interval.</p>" + orders)
        folded = _not_ok(mine)
        if folded:
            out.append("<h3>Not run to the end, or the solution lost</h3><ul>" + "".join(
                f"<li>{_e(why)}: {_e(', '.join(s))}</li>" for why, s in sorted(folded.items())) + "</ul>")
    out.append('<h2 id="capabilities">Capability matrix</h2>' + _capability_matrix(rows))
    stab = _stability_table({**interval_texts(plugins), **intervals}) if stability else None
    if stab:
        out.append('<h2 id="stability">Linear stability</h2>' + stab)
    out.append(f'<p class="note">Written {datetime.now(timezone.utc).isoformat(timespec="seconds")} by '
               f"<code>longtime report --html</code>.</p>")
    out.append(f"<script>{SCRIPT}</script></body></html>")
    return "\n".join(out)


def write_page(out_dir: str | Path, rows: list[dict[str, Any]], runs: list[dict[str, Any]],
               drift: bool = True, jobs: int = 1, ahead: FiguresAhead | None = None) -> Path:
    """Write ``out_dir``/index.html (figures drawn on ``jobs`` processes, or ``ahead``);
    return its path."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = out / PAGE_NAME
    path.write_text(build_page(rows, runs, drift=drift, jobs=jobs, ahead=ahead), encoding="utf-8")
    return path
