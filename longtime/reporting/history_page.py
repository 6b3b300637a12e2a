"""The results page's history section: the cells of the page that more than one stored run
holds, read with ``longtime history``'s step detection (longtime.reporting.history).

A reader asks of it what moved: the section names how many repeated cells held their
level, lists every cell whose calibrated time or main error stepped (a table per problem,
the largest step first, with the runs and commits it lies between), and draws the series of
the cells with the largest steps, one panel each. A store of many runs holds every cell of
every run: a panel per cell (or per scheme, with every cell in it) would draw hundreds of
axes that show nothing but levels held, so the figure keeps ``FIGURE_CELLS`` panels and
``longtime history`` lists the rest.
"""
from __future__ import annotations

import math
from typing import Any

from longtime.predict.need import PARETO_FIELDS
from longtime.reporting.compare_cells import cell_key
from longtime.reporting.compare_text import label
from longtime.reporting.history import TIME_FIELD, history
from longtime.reporting.markup import escape, slug, table

FIGURE_CELLS = 12  # the panels of the section's one figure: the cells with the largest steps
TABLE_ROWS = 15  # the steps a problem's table lists (the largest first); the rest are counted


def repeated(store, rows: list[dict]) -> list[dict[str, Any]]:
    """The history of the cells of ``rows`` that more than one stored run holds."""
    if len(store.runs()) < 2:  # no cell is in two runs: the store's rows are not read
        return []
    keys = {cell_key(r) for r in rows}
    problems = sorted({r["problem"] for r in rows})
    schemes = sorted({r["integrator"] for r in rows})
    return [c for c in history(store, problems, schemes, fields=(TIME_FIELD, *PARETO_FIELDS))
            if len(c["runs"]) > 1 and cell_key(c["cell"]) in keys]


def main_error(cell: dict) -> str | None:
    """The first error field of the report's Pareto fields that a run of ``cell`` has."""
    return next((f for f in PARETO_FIELDS if any(isinstance(p.get(f), (int, float)) for p in cell["runs"])), None)


def marked(cell: dict) -> list[dict[str, Any]]:
    """The steps of ``cell``'s calibrated time and main error."""
    err = main_error(cell)
    return [s for s in cell["steps"] if s["field"] in (TIME_FIELD, err)]


def _size(step: dict) -> float:
    ratio = step["ratio"]
    return math.inf if not math.isfinite(ratio) or ratio <= 0 else abs(math.log(ratio))


def _between(cell: dict, step: dict) -> str:
    """The runs (and commits) a step lies between; a step between runs of one commit is the
    machine's or the cell's noise, not a change of code, and says so."""
    ids = [p["run_id"] for p in cell["runs"]]
    i = ids.index(step["run_id"])
    before = cell["runs"][i - 1] if i > 0 else None
    after = cell["runs"][i]
    if before is None:
        return f"run {after['run_id']}"
    b, a = (before.get("commit") or "-")[:7], (after.get("commit") or "-")[:7]
    same = " (same commit)" if before.get("commit") and before.get("commit") == after.get("commit") else ""
    return f"run {before['run_id']} ({b}) -> {after['run_id']} ({a}){same}"


def page_section(store, rows: list[dict], style: dict) -> str | None:
    """The section's HTML; None when no cell of ``rows`` is in more than one stored run."""
    found = repeated(store, rows)
    if not found:
        return None
    steps_of = {id(c): marked(c) for c in found}
    moved = [c for c in found if steps_of[id(c)]]
    runs = sorted({p["run_id"] for c in found for p in c["runs"]})
    out = ['<h2 id="history">History</h2>'
           f'<p class="note">{len(found)} cell{"s" if len(found) != 1 else ""} of this page '
           f'{"are" if len(found) != 1 else "is"} in more than one of {len(runs)} stored runs; '
           f'{len(found) - len(moved)} held the level of their calibrated CPU time and of their main error, '
           f'{len(moved)} stepped (<code>longtime history</code>: a time step passes the cell\'s spread between '
           'processes, an error step x2). A step between runs of one commit is the machine\'s noise, '
           'not a change of code.</p>']
    if not moved:
        return "\n".join(out)
    top = sorted(moved, key=lambda c: -max(map(_size, steps_of[id(c)])))[:FIGURE_CELLS]
    out.append(f'<figure class="plot">{_small_multiples(top, style)}<figcaption>The '
               f'{len(top)} cell{"s" if len(top) != 1 else ""} with the largest steps: calibrated CPU time (solid) '
               'and main error (dashed) relative to the first run, against the runs (labelled by commit); a '
               'marker at a step (triangle up: slower or less accurate; down: faster or more accurate).'
               '</figcaption></figure>')
    for problem in sorted({c["cell"]["problem"] for c in moved}):
        mine = [c for c in moved if c["cell"]["problem"] == problem]
        steps = sorted(((c, s) for c in mine for s in steps_of[id(c)]), key=lambda cs: -_size(cs[1]))
        body = [[label(c["cell"], digits=4, problem=False), "time" if s["field"] == TIME_FIELD else s["field"],
                 f"x{s['ratio']:.3g}", s["kind"], _between(c, s)] for c, s in steps[:TABLE_ROWS]]
        more = len(steps) - len(body)
        out.append(f'<h3 id="history-{slug(problem)}">{escape(problem)}</h3><p class="note">{len(mine)} '
                   f'cell{"s" if len(mine) != 1 else ""}, {len(steps)} step{"s" if len(steps) != 1 else ""} marked'
                   + (f", the {len(body)} largest listed" if more else "")
                   + f' (<code>longtime history -p {escape(problem)}</code> lists every field\'s).</p>'
                   + table(["cell", "series", "ratio", "kind", "between"], body))
    return "\n".join(out)


def _small_multiples(cells: list[dict], style: dict) -> str:
    """One panel per cell: its calibrated time and main error over the runs, relative to its
    first run, its steps marked."""
    from longtime.reporting.figures import pyplot
    from longtime.reporting.figures.style import svg

    run_ids = sorted({p["run_id"] for c in cells for p in c["runs"]})
    commits = {p["run_id"]: p["commit"] for c in cells for p in c["runs"]}
    x_of = {rid: i for i, rid in enumerate(run_ids)}
    cols = min(3, len(cells))
    rows = math.ceil(len(cells) / cols)
    plt = pyplot()
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.3 * rows), squeeze=False, sharex=True)
    for ax, c in zip(axes.flat, cells):
        colour = style.get(c["cell"]["integrator"], {}).get("color", "#1f77b4")
        for field, ls in ((TIME_FIELD, "-"), (main_error(c), "--")):
            if field is None:
                continue
            pts = [(x_of[p["run_id"]], p[field]) for p in c["runs"]
                   if isinstance(p.get(field), (int, float)) and p[field] > 0]
            if not pts:
                continue
            base = pts[0][1]
            ax.plot([x for x, _ in pts], [v / base for _, v in pts], ls=ls, color=colour, lw=0.9, alpha=0.8)
            for s in c["steps"]:
                if s["field"] == field:
                    ax.plot([x_of[s["run_id"]]], [s["after"] / base], marker="^" if s["ratio"] > 1 else "v",
                            color="#b71c1c", ms=6, ls="none")
        ax.set_yscale("log")
        ax.set_title(f"{c['cell']['problem']}\n{label(c['cell'], digits=4, problem=False)}", fontsize=7)
        ax.tick_params(which="both", labelsize=6)
        ax.grid(True, which="both", alpha=0.3)
    for ax in list(axes.flat)[len(cells):]:
        ax.set_visible(False)
    for ax in axes[-1]:
        ax.set_xticks(range(len(run_ids)))
        ax.set_xticklabels([(commits.get(r) or str(r))[:7] for r in run_ids], rotation=60, fontsize=6)
    axes[0][0].set_ylabel("relative to first run", fontsize=7)
    return svg(fig)
