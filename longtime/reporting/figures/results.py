"""The results page's figures of one problem: work-precision (error against the minimum
CPU time of the repeats, a bar to the slowest repeat), the drift of every invariant and the
change of every diagnostic against time for a representative setting of each scheme (log-log,
one panel per quantity), and a run's calibrations against time.

The drift curves come from the rows: each keeps the upper envelope of every invariant's
error (and every diagnostic's change) at 80 log-spaced times (``drift_curves``,
``diag_curves``, metrics.drift_envelope), so the page runs nothing; a row stored when rows
kept only the first invariant's (``drift_curve``) shows that one. Only a row stored before
rows kept any is run again, untimed, skipped when its stored CPU time exceeds
``DRIFT_BUDGET_S`` or once a problem's re-runs add up to ``DRIFT_PROBLEM_BUDGET_S``
(cheapest first); the caption says which setting was drawn and names those left out.
"""
from __future__ import annotations

import contextlib
import math
from typing import Any, Callable, Iterator

import numpy as np

from longtime.core.fmt import positive
from longtime.core.phases import phase
from longtime.core.status import Status
from longtime.reporting.figures import pyplot
from longtime.reporting.figures.style import (
    GREY,
    LEGEND_BESIDE,
    LINE_STYLES,
    emphasis,
    family,
    front_schemes,
    legend_columns,
    legend_outside,
    svg,
)
from longtime.reporting.report import (
    main_t_final,
    pareto_field,
    setting,
)

DRIFT_BUDGET_S = 2.0  # stored cpu_s above which a drift curve is not recomputed for the page
DRIFT_PROBLEM_BUDGET_S = 10.0  # and the stored cpu_s of the curves re-run for one problem, in all
DRIFT_SAMPLES = 2001
# figures_drawing's estimate of its work, seconds of one process: a work-precision figure (a
# winner map costs about as much), a problem's drift figures in work-precision figures, a
# stability interval not cached, and the start of a pool's process (an interpreter importing
# longtime, then matplotlib: docs/performance.md, "The page and its figures")
FIGURE_S, DRIFT_FIGURES, INTERVAL_S, POOL_START_S = 0.3, 2.0, 1.0, 1.5
MAX_PANELS = 12  # invariants (or diagnostics) a drift figure draws; the caption names the rest


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


def work_precision_svg(rows: list[dict], field: str, style: dict, cost: str = "cpu_s") -> str | None:
    """``field`` against the cost of each ok row: ``cpu_s`` (the minimum of the repeats, a
    bar to the slowest) or ``instructions`` (the count under Valgrind, --cost instructions)."""
    ok = [r for r in rows if r.get("status") == Status.OK and positive(r.get(cost)) and positive(r.get(field))]
    if not ok:
        return None
    from matplotlib.collections import LineCollection

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7.0, 4.2))
    t_main = main_t_final(ok)
    style, greyed = emphasis(style, sorted({r["integrator"] for r in ok}), front_schemes(rows))
    bars, bar_colours = [], []  # every sweep's bars in one collection, beneath the lines as errorbar draws them
    for (scheme, t_final, settings, order), mine in sweeps(ok).items():
        pts = sorted((r[cost], r[field], (r.get("cpu_s_max") or r["cpu_s"]) if cost == "cpu_s" else r[cost])
                     for r in mine)
        x, y, x_max = (np.array(v) for v in zip(*pts))
        st, other_t = style[scheme], t_final != t_main
        label = f"{scheme} ({family(scheme)})" + (f" t_final={t_final:.4g}" if other_t else "") \
            + (f" N={order}" if order is not None else "") + (f" {settings}" if settings else "")
        grey = scheme in greyed
        ax.plot(x, y, color=st["color"], marker=st["marker"], ms=5, lw=0.8 if grey else 1.1,
                ls="--" if other_t or settings else "-", alpha=0.9, zorder=1.9 if grey else 2.1,
                label="_" + label if grey else label)
        spread = x_max > x
        bars += [[(a, b), (c, b)] for a, b, c in zip(x[spread], y[spread], x_max[spread])]
        bar_colours += [st["color"]] * int(spread.sum())
    if bars:  # autolim: the axis reaches the slowest repeat
        ax.add_collection(LineCollection(bars, colors=bar_colours, linewidths=2.2, alpha=0.9, zorder=2.0))
    if greyed:
        ax.plot([], [], color=GREY, lw=0.8, label=f"{len(greyed)} other schemes (grey: off the Pareto front)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("CPU seconds (minimum of repeats; bar to the slowest)" if cost == "cpu_s" else
                  "instructions of the integration (Valgrind's count)")
    ax.set_ylabel(field)
    ax.grid(True, which="both", alpha=0.3)
    legend_outside(ax)
    return svg(fig)


def representative(rows: list[dict]) -> dict[str, dict]:
    """scheme -> the ok row of median cost among its rows (the drawn setting): cost as its
    steps, a count that the timing processes' new CPU times leave as it is (so that a drift
    figure drawn ahead stays the page's), ties ordered by final time and setting; by CPU
    time where a row has no step count."""
    from longtime.core.rowtext import setting as setting_text

    out = {}
    for scheme in sorted({r["integrator"] for r in rows}):
        ok = [r for r in rows if r["integrator"] == scheme and r.get("status") == Status.OK
              and positive(r.get("cpu_s"))]
        if all(isinstance(r.get("steps"), int) and r["steps"] > 0 for r in ok):
            ok.sort(key=lambda r: (r["steps"], str(r.get("t_final")), setting_text(r), str(r.get("parameters"))))
        else:
            ok.sort(key=lambda r: r["cpu_s"])
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
    from longtime.execution.cells import cell_of_row, integrate_cell
    from longtime.measure.metrics import relative_error

    problem, traj = integrate_cell(cell_of_row(row), max_samples=DRIFT_SAMPLES)
    with np.errstate(all="ignore"):
        return {kind: [(name, traj.t, relative_error(values)) for name, values in found.items()]
                for kind, found in (("invariant", problem.invariants(traj.t, traj.u)),
                                    ("diagnostic", problem.diagnostics(traj.t, traj.u)))}


def drawn_settings(rows: list[dict]) -> list[tuple[str, dict]]:
    """(scheme, its representative row) in the order the drift figures draw them and list
    them: by scheme, so that a CPU time measured again, which may swap two schemes' order
    by cost, leaves the figure as it is."""
    return sorted(representative(rows).items())


def _reruns(settings: list[tuple[str, dict]]) -> tuple[set[str], list[str]]:
    """The schemes whose representative row keeps no curves (a row of an older store) run
    again for the drift figure: the cheapest first, within ``DRIFT_BUDGET_S`` a run and
    ``DRIFT_PROBLEM_BUDGET_S`` in all, so that the budget leaves out the fewest; and the
    notes naming those left out."""
    chosen, notes, spent = set(), [], 0.0
    for scheme, row in sorted(((s, r) for s, r in settings if "drift_curve" not in r), key=lambda x: x[1]["cpu_s"]):
        if row["cpu_s"] > DRIFT_BUDGET_S or spent + row["cpu_s"] > DRIFT_PROBLEM_BUDGET_S:
            notes.append(f"{scheme}: not drawn (its run takes {row['cpu_s']:.3g} s)")
            continue
        spent += row["cpu_s"]
        chosen.add(scheme)
    return chosen, notes


def drift_svg(rows: list[dict], style: dict, kind: str = "invariant") -> tuple[str | None, list[str]]:
    """The drift figure of one problem, one panel per invariant (``kind`` "diagnostic": per
    diagnostic, their change), and the notes on what it leaves out."""
    settings = drawn_settings(rows)
    reruns, notes = _reruns(settings)
    curves = []
    for scheme, row in settings:
        rerun = "drift_curve" not in row  # a row of an older store keeps none: run it again
        if not rerun and not (row.get("drift_curves") or row.get("drift_curve") or row.get("diag_curves")):
            continue  # nothing to draw (a row measured since rows keep their curves)
        if rerun and scheme not in reruns:
            continue  # past the budget: noted by _reruns
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
    style, greyed = emphasis(style, sorted({c[0] for c in curves}), front_schemes(rows))
    plt = pyplot()
    # small multiples sized to their number: panels of a legible size (3.4 x 2.7 in), at most
    # three across, the figure growing with their rows
    cols = min(len(names), 3)
    rows_ = -(-len(names) // cols)
    size = (7.0, 4.2) if len(names) == 1 else (3.4 * cols, 2.7 * rows_ + 0.2)
    fig, axes = plt.subplots(rows_, cols, figsize=size, squeeze=False, sharex=True)
    _space_panels(fig, rows_, cols)
    what = "relative error" if kind == "invariant" else "relative change"
    handles: dict[str, Any] = {}
    for k, ax in enumerate(axes.flat):
        if k >= len(names):
            ax.set_visible(False)
            continue
        mine = [c for c in curves if c[2] == names[k]]
        ax.set_xscale("log")  # once a panel: every loglog call would set both scales again
        ax.set_yscale("log")
        for i, (scheme, row, name, t, err) in enumerate(mine):
            keep = (t > t[0]) & (err > 0)
            st = style[scheme]
            every = max(1, int(keep.sum()) // 12)
            grey = scheme in greyed
            label = f"{len(greyed)} other schemes (grey: off the Pareto front)" if grey else f"{scheme} {setting(row)}"
            # curves that coincide (a diagnostic the schemes all follow) stay apart: a dash
            # pattern and the markers shifted per curve
            (line,) = ax.plot(t[keep] - t[0], err[keep], color=st["color"], marker=st["marker"],
                              markevery=(i % every, every), ms=4 if len(names) == 1 else 3, lw=0.6 if grey else 0.9,
                              ls="-" if grey else LINE_STYLES[i % len(LINE_STYLES)], label=label,
                              zorder=1.5 if grey else 2.0)
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
    labels = list(handles)
    if len(names) == 1 and len(labels) <= LEGEND_BESIDE:
        legend_outside(axes[0, 0], list(handles.values()), labels)
    else:  # below every panel, in as many columns as the figure's width holds
        fig.legend(list(handles.values()), labels, fontsize=8, loc="upper center", bbox_to_anchor=(0.5, 0.0),
                   frameon=False, ncol=legend_columns(fig.get_figwidth(), labels))
    return svg(fig), notes


# the margins and the gaps between the panels of a drift figure, inches: room for the tick
# labels ('2×10⁻¹⁵' at 8 pt), a panel's title and the axis labels, as matplotlib's tight
# layout leaves them, set rather than measured (measuring lays every panel out once more,
# ticks and labels included, before ``svg`` lays it out again); what reaches past the
# figure's edge stays in the picture (``svg`` crops to what is drawn)
PANEL_MARGINS = {"left": 0.72, "right": 0.15, "top": 0.34, "bottom": 0.55, "wgap": 0.6, "hgap": 0.42}
ONE_PANEL_MARGINS = {"left": 0.82, "right": 0.15, "top": 0.15, "bottom": 0.58, "wgap": 0.0, "hgap": 0.0}


def _space_panels(fig, rows: int, cols: int) -> None:
    """Place ``fig``'s rows x cols panels by ``PANEL_MARGINS`` (one panel: ``ONE_PANEL_MARGINS``)."""
    m = ONE_PANEL_MARGINS if rows * cols == 1 else PANEL_MARGINS
    width, height = fig.get_size_inches()
    panel_w = (width - m["left"] - m["right"] - (cols - 1) * m["wgap"]) / cols
    panel_h = (height - m["top"] - m["bottom"] - (rows - 1) * m["hgap"]) / rows
    fig.subplots_adjust(left=m["left"] / width, right=1 - m["right"] / width, bottom=m["bottom"] / height,
                        top=1 - m["top"] / height, wspace=m["wgap"] / panel_w, hspace=m["hgap"] / panel_h)


# a problem's figures in two groups, each drawn from its own inputs: the work-precision
# figures read every row's error and CPU time, the drift figures only the representative
# settings' kept curves
FIGURE_GROUPS = {"work_precision": ("field", "work_precision", "work_precision_instructions"),
                 "drift": ("drift", "drift_notes", "diagnostics", "diagnostics_notes")}
# the curves a row keeps, which the work-precision figures never read (its points are the rows'
# errors and costs, its front the rows' fields): most of a row's bytes, left out of that
# group's digest
CURVE_FIELDS = ("drift_curve", "drift_curves", "diag_curves", "error_curve")


def figure_inputs(rows: list[dict[str, Any]], style: dict, drift: bool = True) -> dict[str, str]:
    """group -> a digest of what problem_figures reads to draw that group of figures: equal
    digests, the same figures. The drift group's is the representative settings, each as its
    scheme's style, its setting and the curves it keeps (a row that keeps none is run again:
    the whole row), so a row's CPU time measured again leaves the drift figures as drawn
    (the representative settings are chosen by their steps, not their CPU times)."""
    from longtime.core.rowtext import setting as setting_text

    def drawn(row):
        if "drift_curve" not in row:
            return row
        return [setting_text(row), *(row.get(k) for k in ("drift_curve", "drift_curves", "diag_curves"))]

    settings = [[scheme, style.get(scheme), drawn(row)] for scheme, row in drawn_settings(rows)] if drift else []
    points = [{k: v for k, v in r.items() if k not in CURVE_FIELDS} for r in rows]
    return {"work_precision": _digest([points, style]),
            "drift": _digest([drift, any(r.get("diag_curves") for r in rows), settings])}


def _digest(value: Any) -> str:
    import hashlib
    import json

    return hashlib.sha256(json.dumps(value, sort_keys=True, default=str).encode()).hexdigest()


def problem_figures(rows: list[dict[str, Any]], style: dict, drift: bool = True,
                    groups: tuple[str, ...] = tuple(FIGURE_GROUPS)) -> dict[str, Any]:
    """One problem's figures: {"field", "work_precision" (SVG or None), "drift" (SVG or
    None), "drift_notes", "diagnostics" (SVG or None: the problem's diagnostics, where its
    rows keep them), "diagnostics_notes"}, of the ``groups`` (of FIGURE_GROUPS) asked for."""
    out: dict[str, Any] = {}
    with phase("figures", f"{rows[0]['problem'] if rows else '?'}: {', '.join(groups)}"):
        if "work_precision" in groups:
            field = pareto_field(rows)
            out.update({"field": field, "work_precision": None, "work_precision_instructions": None})
            if field:
                out["work_precision"] = work_precision_svg(rows, field, style)
                if any(positive(r.get("instructions")) for r in rows):  # a run with --cost instructions
                    out["work_precision_instructions"] = work_precision_svg(rows, field, style, "instructions")
        if "drift" in groups:
            out.update({"drift": None, "drift_notes": [], "diagnostics": None, "diagnostics_notes": []})
            if drift:
                out["drift"], out["drift_notes"] = drift_svg(rows, style)
                if any(r.get("diag_curves") for r in rows):
                    out["diagnostics"], out["diagnostics_notes"] = drift_svg(rows, style, "diagnostic")
    return out


def drawn_figure(fn: Callable[..., Any], *args: Any) -> Any:
    """``fn(*args)``, a figure the page hands its figure processes, recorded as a "figures"
    phase named by ``fn``."""
    with phase("figures", fn.__name__):
        return fn(*args)


def matplotlib_loaded() -> None:
    """Import pyplot (a figure process's first work)."""
    pyplot()


@contextlib.contextmanager
def figures_drawing(by_problem: dict[str, list[dict]], style: dict, drift: bool, jobs: int,
                    stability: dict[str, list | None], ahead: Any = None, later: int = 0
                    ) -> Iterator[tuple[Callable[[], tuple[dict[str, dict], dict[str, str]]], Callable[..., Callable]]]:
    """Start problem_figures of every problem, and the interval texts of the ``stability``
    schemes (measured where not cached); yield (the function that returns them ({problem:
    figures}, {scheme: text}), ``draw``), so that the caller does its own work meanwhile.
    ``draw(fn, *args)`` hands one of the ``later`` figures the caller makes once it has their
    inputs (the winner maps) to the same processes and returns the function that gives its
    result (drawn by the caller where no process has started it by then). The groups of
    figures ``ahead`` drew from the same inputs (``figure_inputs``) are taken as they are,
    and the intervals it found at the same N. matplotlib spends
    about a third of a second a figure, and a scheme's stability interval about a second
    when not cached, all of it in Python, so only processes run them beside the caller:
    ``ahead``'s ``workers`` where it holds them (a main job's, up already), else up to ``jobs``
    processes started here, where the work outweighs their start-up; else the work is done
    here."""
    from longtime.measure.stability import cached_texts, interval_texts

    with contextlib.ExitStack() as stack:
        # the main job's workers, where ``ahead`` holds them; else the processes start first
        # where the later figures alone are work enough for them: they boot while this one
        # finds what was drawn ahead
        pool = getattr(ahead, "workers", None)
        early = 0 if pool is not None else _processes(FIGURE_S * later, jobs)
        if early:
            pool = stack.enter_context(_figure_pool(early))
        figures, todo = {}, {}
        for p, rows in by_problem.items():
            figures[p] = (ahead.figures(p, rows, style, drift) if ahead is not None else None) or {}
            groups = tuple(g for g, fields in FIGURE_GROUPS.items() if not all(f in figures[p] for f in fields))
            if groups:
                todo[p] = (rows, groups)
        texts = {s: ahead.interval(s, o) for s, o in stability.items()} if ahead is not None else {}
        texts = {s: text for s, text in texts.items() if text is not None}
        found, missing = cached_texts({s: o for s, o in stability.items() if s not in texts})
        texts.update(found)
        # the work in seconds, as a process's start-up is: a problem's drift figures (one to a
        # dozen panels) cost a few work-precision figures
        work = INTERVAL_S * len(missing) + sum(FIGURE_S * (1 + DRIFT_FIGURES * ("drift" in g))
                                               for _, g in todo.values()) + FIGURE_S * later
        processes = 0 if pool is not None else _processes(work, jobs)
        if processes:
            pool = stack.enter_context(_figure_pool(processes))
        if pool is None:
            def here():
                for p, (rows, groups) in todo.items():
                    figures[p].update(problem_figures(rows, style, drift, groups))
                texts.update(interval_texts(missing, compute=True))
                return figures, texts

            def now(fn, *args):
                result = drawn_figure(fn, *args)
                return lambda: result

            yield here, now
            return
        intervals = [pool.submit(interval_texts, {s: o}, True) for s, o in missing.items()]
        drawn = {p: pool.submit(problem_figures, rows, style, drift, groups) for p, (rows, groups) in todo.items()}

        def collected():
            for f in intervals:
                texts.update(f.result())
            for p, f in drawn.items():
                figures[p].update(f.result())
            return figures, texts

        def draw(fn, *args):
            future = pool.submit(drawn_figure, fn, *args)
            # a figure no process has started when its result is wanted is drawn here, where
            # the caller would only wait
            return lambda: drawn_figure(fn, *args) if future.cancel() else future.result()

        yield collected, draw


def _processes(work: float, jobs: int) -> int:
    """The figure processes for ``work`` seconds: one where it has at least twice a process's
    start-up to do, up to ``jobs``; 0 below one start-up (the caller draws it)."""
    return 0 if jobs <= 1 or work < POOL_START_S else min(jobs, math.ceil(work / (2 * POOL_START_S)))


@contextlib.contextmanager
def _figure_pool(processes: int):
    from longtime.execution.pool import worker_pool

    with worker_pool(processes) as pool:
        for _ in range(processes):  # each process starts and imports matplotlib now, not at its first figure
            pool.submit(matplotlib_loaded)
        yield pool


def calibration_svg(points: list[dict[str, Any]]) -> str | None:
    """The run's calibrations against time (one marker per calibration, a bar to its
    slowest repeat; one colour per process), as inline SVG; None with fewer than two."""
    if len(points) < 2:
        return None
    t0 = min(p["t"] for p in points)
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7.0, 2.2))
    pids = sorted({p.get("pid") for p in points}, key=str)
    for k, pid in enumerate(pids):
        mine = sorted((p for p in points if p.get("pid") == pid), key=lambda p: p["t"])
        x = np.array([p["t"] - t0 for p in mine])
        y = np.array([1e3 * p["cpu_s"] for p in mine])
        top = np.array([1e3 * p["cpu_s_max"] for p in mine])
        ax.errorbar(x, y, yerr=[np.zeros_like(y), top - y], marker="o", ms=3, lw=0.8, capsize=0,
                    label=f"process {pid}"
                    + (" (this run's own)" if k == 0 and mine[0].get("phase") == "before" else ""))
    ax.set_xlabel("seconds since the first calibration")
    ax.set_ylabel("reference workload, ms")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0, frameon=False)
    return svg(fig)
