"""The suite's figures by kind, saved as PNG and SVG (matplotlib, Agg): what ``longtime plot
KIND`` draws (longtime.commands.plot), and Axes helpers for a Python session.

Kinds are a registry, ``PLOT_KINDS``: name -> "module:function" of the package
``longtime.reporting.figures`` (one module per family), imported only when drawn, so a module adds a
kind with one line. A kind function takes keyword arguments and
returns the paths it wrote; ``draw`` (and ``longtime plot``) passes it only the options below that its
signature accepts (and that were given, except ``out`` and ``formats``, always given):

    out: Path               file stem to write (<--out>/<kind>; suffixes are added)
    formats: tuple[str]     ("png", "svg") by default
    problems, schemes       -p / -i lists
    dt, t_final             --dt (first value), --t-final
    problem_settings        --set key=value of the problem's parameters
    db, run, metric         the store, the run id ("all": every run), the drift metric
    invariant               --invariant: the invariant (or diagnostic) a drift figure draws

Every curve a kind draws from integration is computed in that call; work-precision
draws the rows of the store (the measurements of a `longtime matrix` or `run`).
"""
from __future__ import annotations

import importlib
import inspect
from pathlib import Path
from typing import Any, Callable

from longtime.core.params import InputError, check_choice
from longtime.core.status import Status
from longtime.reporting.figures import FORMATS, save  # noqa: F401  (the helpers every kind uses)

PLOT_KINDS: dict[str, str] = {
    "work-precision": "longtime.reporting.figures.work_precision:work_precision",
    "drift": "longtime.reporting.figures.drift:drift",
    "toda-eigenvalues": "longtime.reporting.figures.drift:toda_eigenvalues",
    "duffing-phase": "longtime.reporting.figures.duffing:duffing_phase",
    "pendulum-region": "longtime.reporting.figures.pendulum:pendulum_region",
    "stability": "longtime.reporting.figures.stability:stability_regions",
}


def kind_function(kind: str) -> Callable[..., list[Path]]:
    check_choice("plot kind", kind, PLOT_KINDS)
    module, _, name = PLOT_KINDS[kind].partition(":")
    try:
        return getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError) as exc:
        raise InputError(f"plot kind '{kind}' is not available: {PLOT_KINDS[kind]} failed to load ({exc})") from None


def draw(kind: str, out_dir: str | Path = "figures", **options: Any) -> list[Path]:
    """Draw one kind into ``out_dir``; options as in the module docstring (None: not given)."""
    fn = kind_function(kind)
    accepted = inspect.signature(fn).parameters
    takes_all = any(p.kind is inspect.Parameter.VAR_KEYWORD for p in accepted.values())
    given = {k: v for k, v in options.items() if v is not None and (takes_all or k in accepted)}
    given.setdefault("formats", ("png", "svg"))
    return [Path(p) for p in fn(out=Path(out_dir) / kind, **given)]


# ------------------------------------------------------------------ from Python: Axes
# The API's figures live in the user's session (a script, a notebook): they change no global
# matplotlib state (no backend switch, no rcParams; their own style only inside rc_context),
# draw the user's text (scheme names, settings) as typed (each Text with parse_math off,
# not the process-wide switch), and label log axes in plain Unicode (10⁻²), which renders
# whatever the session's text.parse_math.
RC = {"legend.fontsize": 8, "legend.frameon": False, "axes.grid": True, "grid.alpha": 0.3}
# a legend column holds this many entries; more make another column
LEGEND_ROWS = 20
def _axes(ax):
    if ax is not None:
        return ax
    import matplotlib.pyplot as plt

    return plt.subplots(figsize=(9, 4.6), layout="constrained")[1]


def scheme_styles(schemes) -> dict[str, dict[str, str]]:
    """The results page's style of ``schemes`` drawn together: a colour and a marker each, no
    two alike (longtime.reporting.figures.style.styles)."""
    from longtime.reporting.figures.style import styles

    return styles(schemes)


def _literal(*texts) -> None:
    for t in texts:
        t.set_parse_math(False)


def _finish(ax, xlabel: str, ylabel: str, title: str) -> None:
    """Labels and title as typed, plain log tick labels, the legend outside the axes (right
    of them, in columns of LEGEND_ROWS entries)."""
    from longtime.reporting.figures import plain_log_ticks

    _literal(ax.set_xlabel(xlabel), ax.set_ylabel(ylabel), ax.set_title(title))
    plain_log_ticks(ax)
    handles, labels = ax.get_legend_handles_labels()
    if handles:
        legend = ax.legend(handles, labels, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0,
                           ncols=1 + (len(handles) - 1) // LEGEND_ROWS)
        _literal(*legend.get_texts())


def work_precision(rows: Any, ax=None, *, field: str | None = None, problem: str | None = None):
    """Error (``field``, default the Pareto table's: l2_error, else H.max, ...) against CPU
    seconds of the ok rows of one problem (a DataFrame from ``longtime.sweep``, or row
    dicts), log-log, one curve per scheme, a colour per family (a scheme that is not built
    in: a colour of its own); a bar reaches each point's slowest repeat. Returns the
    matplotlib Axes (a new figure's unless ``ax``)."""
    import matplotlib

    from longtime.api import records
    from longtime.core.fmt import positive
    from longtime.reporting.figures.work_precision import curves
    from longtime.reporting.report import pareto_field

    rows = [r for r in records(rows) if r.get("status") == Status.OK and positive(r.get("cpu_s"))
            and (problem is None or r["problem"] == problem)]
    problems = sorted({r["problem"] for r in rows})
    if len(problems) != 1:
        raise InputError(f"work_precision draws one problem's ok rows; these hold "
                         f"{', '.join(problems) or 'none'}: pass problem=")
    field = field or pareto_field(rows)
    if field is None:
        raise InputError("work_precision: no ok row has an error to draw")
    with matplotlib.rc_context(RC):
        ax = _axes(ax)
        curves(ax, rows, field, scheme_styles(sorted({r["integrator"] for r in rows})))
        _finish(ax, "CPU seconds (minimum of repeats, bar to the maximum)", field,
                f"{problems[0]}: error against cost")
    return ax


def drift(result_or_rows: Any, invariant: str = "H", ax=None):
    """The relative error of ``invariant`` against t - t0, log-log: every sample of a
    ``longtime.solve`` Result, or for rows (a DataFrame or dicts) the upper envelope each ok
    row keeps (``drift_curves``, ``diag_curves``; a row without them is run again, untimed). Returns the Axes."""
    import matplotlib

    from longtime.api import Result, records
    from longtime.measure.metrics import relative_error
    from longtime.reporting.figures.results import row_curves
    from longtime.reporting.figures.style import scheme_style
    from longtime.reporting.report import setting

    with matplotlib.rc_context(RC):
        ax = _axes(ax)
        if isinstance(result_or_rows, Result):
            res = result_or_rows
            if invariant not in res.invariants:
                raise InputError(f"drift: no invariant {invariant!r}; this result has "
                                 f"{', '.join(res.invariants) or 'none'}")
            err = relative_error(res.invariants[invariant])
            t = res.t - res.t[0]
            shown = (t > 0) & (err > 0)
            scheme = res.row["integrator"]
            ax.loglog(t[shown], err[shown], lw=0.8, color=scheme_style(scheme)["color"],
                      label=f"{scheme} {setting(res.row)}".strip())
            title = res.row["problem"]
        else:
            rows = [r for r in records(result_or_rows) if r.get("status") == Status.OK]
            style = scheme_styles(sorted({r["integrator"] for r in rows}))
            drawn = 0
            for r in rows:
                curves = row_curves(r)
                found = [(t, e) for name, t, e in curves["invariant"] + curves["diagnostic"] if name == invariant]
                if not found:
                    continue
                t, err = found[0]
                shown = (t > 0) & (err > 0)
                ax.loglog(t[shown], err[shown], lw=0.8, color=style[r["integrator"]]["color"],
                          label=f"{r['problem']} {r['integrator']} {setting(r)}".strip())
                drawn += 1
            if not drawn:
                raise InputError(f"drift: no ok row keeps a drift curve of {invariant!r}")
            title = ", ".join(sorted({r["problem"] for r in rows}))
        _finish(ax, "t - t0", f"relative error of {invariant}", f"{title}: drift of {invariant}")
    return ax
