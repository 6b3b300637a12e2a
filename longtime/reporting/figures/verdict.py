"""The verdict's figures on the results page: a problem's winner map (target error against
horizon, each cell coloured by the scheme of the cheapest setting predicted to keep the
target up to the horizon, its setting written in it, the checked predictions marked), and
the checks of every problem (predicted against measured error)."""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from longtime.core.fmt import positive
from longtime.core.rowtext import setting
from longtime.predict.checks import CHECK_COST_FACTOR, CHECK_ERROR_FACTOR, check_holds
from longtime.predict.decision import Verdict
from longtime.reporting.figures import pyplot
from longtime.reporting.figures.style import legend_columns, scheme_style, svg

UNDETERMINED = "#d9d9d9"
NONE = "#ffffff"


def scheme_colours(schemes: list[str], style: dict | None = None) -> dict[str, Any]:
    """Each winning scheme's colour: its colour in ``style`` (the page's, as in its other
    figures), else its own (style.scheme_style)."""
    return {s: ((style or {}).get(s) or scheme_style(s))["color"] for s in schemes}


# two fills closer than this (RGB distance, 0 to sqrt 3) read as one colour in a map
ALIKE = 0.3
HATCHES = ("", "//", "\\\\", "..", "xx", "++")


def hatches(schemes: list[str], colours: dict[str, Any]) -> dict[str, str]:
    """A hatch for each scheme of one map: none, unless its colour is alike to that of a
    scheme before it in ``schemes`` (the palette repeats past its twenty colours), then the
    first hatch none of those alike has, so that no two winners of the map look the same."""
    from matplotlib.colors import to_rgb

    out: dict[str, str] = {}
    for k, s in enumerate(schemes):
        mine = np.array(to_rgb(colours[s]))
        taken = {out[o] for o in schemes[:k] if np.linalg.norm(mine - to_rgb(colours[o])) < ALIKE}
        out[s] = next((h for h in HATCHES if h not in taken), HATCHES[-1])
    return out


def text_colour(fill: Any) -> str:
    """Dark text on a light fill, white on a dark or middle one (luminance below 0.5)."""
    from matplotlib.colors import to_rgb

    r, g, b = to_rgb(fill)
    return "#ffffff" if 0.2126 * r + 0.7152 * g + 0.0722 * b < 0.5 else "#111111"


# the text of a winner map's cells, points: legible at 100 % zoom
CELL_FONT = 9.5


def _edges(values: list[float]) -> np.ndarray:
    """Cell edges on a log axis around ``values`` (ascending): the geometric midpoints."""
    v = np.log10(np.asarray(values, dtype=float))
    step = np.diff(v).mean() if v.size > 1 else 1.0
    mids = (v[:-1] + v[1:]) / 2
    return 10 ** np.r_[v[0] - step / 2, mids, v[-1] + step / 2]


def check_marks(checks: list[dict], limits: tuple[float, float]) -> list[tuple[float, float, bool]]:
    """(horizon, measured error, held) of each judged check, the error clamped to ``limits``
    (an error off the map sits on its edge). A check judged neither way (an open rival run
    without a prediction, a check that measured no error) gets no mark: it neither held
    nor missed."""
    marks = []
    for c in checks:
        held = check_holds(c)
        if held is None or not positive(c.get("t_final")) or not positive(c.get("measured_error")):
            continue
        marks.append((float(c["t_final"]), min(max(float(c["measured_error"]), limits[0]), limits[1]), held))
    return marks


def winner_map_svg(v: Verdict, style: dict | None = None) -> str | None:
    """The winner map of one problem's verdict, as inline SVG (None without a map); the
    winners in their colours of ``style`` (the page's), else their own."""
    if not v.grid or not v.targets:
        return None
    from matplotlib.collections import LineCollection, PolyCollection
    from matplotlib.patches import Patch

    targets = sorted(v.targets)  # ascending: the finest at the bottom
    horizons = list(v.horizons)
    winners = list(dict.fromkeys(d.best.scheme for d in v.grid.values() if d.best is not None))
    colours = scheme_colours(winners, style)
    hatched = hatches(winners, colours)
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(1.0 + 1.7 * len(horizons), 0.8 + 0.4 * len(targets)))
    xe, ye = _edges(horizons), _edges(targets)
    cells, fills, hatch = [], [], []  # the cells as collections (one per hatch), the edges between them as two
    for i, t in enumerate(targets):
        for j, h in enumerate(horizons):
            d = v.grid[(t, h)]
            cells.append([(xe[j], ye[i]), (xe[j + 1], ye[i]), (xe[j + 1], ye[i + 1]), (xe[j], ye[i + 1])])
            fills.append(colours[d.best.scheme] if d.best is not None else (UNDETERMINED if d.open else NONE))
            hatch.append(hatched[d.best.scheme] if d.best is not None else "")
            if d.best is not None:
                text = setting(d.best.row) or d.best.scheme
                # inside its cell, hence inside the axes: the layout need not measure it
                ax.text(math.sqrt(xe[j] * xe[j + 1]), math.sqrt(ye[i] * ye[i + 1]), text, ha="center",
                        va="center", fontsize=CELL_FONT, color=text_colour(fills[-1])).set_in_layout(False)
    for h in sorted(set(hatch)):
        mine = [k for k, x in enumerate(hatch) if x == h]
        ax.add_collection(PolyCollection([cells[k] for k in mine], facecolors=[fills[k] for k in mine], linewidths=0,
                                         hatch=h or None, edgecolor="white", zorder=1), autolim=False)
    ax.add_collection(LineCollection([[(x, 0), (x, 1)] for x in xe], colors="white", linewidths=0.6, zorder=2,
                                     transform=ax.get_xaxis_transform()), autolim=False)
    ax.add_collection(LineCollection([[(0, y), (1, y)] for y in ye], colors="white", linewidths=0.6, zorder=2,
                                     transform=ax.get_yaxis_transform()), autolim=False)
    ax.axvline(v.t_main, color="#333", lw=1.0, ls="--")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlim(xe[0], xe[-1])
    ax.set_ylim(ye[0], ye[-1])
    ax.set_xticks(horizons)
    ax.set_yticks(targets)
    ax.minorticks_off()
    ax.set_xlabel(f"horizon T (dashed: the runs' t_final {v.t_main:.4g})")
    ax.set_ylabel(f"target: {v.measure.field} <=")
    handles = [Patch(facecolor=colours[s], hatch=hatched[s] or None, edgecolor="white", label=s) for s in winners]
    handles += [Patch(facecolor=UNDETERMINED, edgecolor="#9e9e9e", label="undetermined: a cheaper law not known"),
                Patch(facecolor=NONE, edgecolor="#9e9e9e", label="no setting predicted to reach it")]
    marks = check_marks(v.checks, (ye[0] * 1.05, ye[-1] / 1.05))
    for t, y, held in marks:
        ax.plot([t], [y], marker="o" if held else "X", ms=8, mfc="none" if held else "#b71c1c",
                mec="#111" if held else "#b71c1c", mew=1.6, ls="none", zorder=5, clip_on=False)
    if marks:
        from matplotlib.lines import Line2D

        handles += [Line2D([], [], marker="o", mfc="none", mec="#111", mew=1.6, ls="none",
                           label="checked: held (at the measured error)"),
                    Line2D([], [], marker="X", mfc="#b71c1c", mec="#b71c1c", ls="none",
                           label="checked: missed (on the edge: off the map)")]
    # below the map, so that the figure is no wider than the map and the page shows it at full size
    below = 0.7 / (0.4 * len(targets))  # inches under the axes for the tick labels and the axis label
    ax.legend(handles=handles, fontsize=9, loc="upper center", bbox_to_anchor=(0.5, -below), borderaxespad=0.0,
              frameon=False, ncol=legend_columns(fig.get_figwidth(), [h.get_label() for h in handles]))
    return svg(fig)


def checks_svg(checks: list[dict[str, Any]]) -> str | None:
    """Predicted against measured error of every stored check (one marker per problem;
    filled: the CPU time within CHECK_COST_FACTOR of the predicted), with the diagonal and
    the band of CHECK_ERROR_FACTOR; None without a check that measured an error."""
    judged = [c for c in checks if positive(c.get("measured_error")) and positive(c.get("predicted_error"))]
    if not judged:
        return None
    from longtime.reporting.figures.style import MARKERS

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(4.6, 4.0))
    problems = sorted({c["problem"] for c in judged})
    for k, p in enumerate(problems):
        mine = [c for c in judged if c["problem"] == p]
        for c in mine:
            cheap = positive(c.get("cpu_s")) and c["cpu_s"] <= CHECK_COST_FACTOR * c["predicted_cpu_s"]
            ax.loglog([c["predicted_error"]], [c["measured_error"]], marker=MARKERS[k % len(MARKERS)], ms=7,
                      color=f"C{k % 10}", mfc=f"C{k % 10}" if cheap else "none", ls="none")
        ax.plot([], [], marker=MARKERS[k % len(MARKERS)], color=f"C{k % 10}", ls="none", label=p)
    lo = min(min(c["predicted_error"], c["measured_error"]) for c in judged) / 10
    hi = max(max(c["predicted_error"], c["measured_error"]) for c in judged) * 10
    x = np.array([lo, hi])
    ax.plot(x, x, color="#333", lw=0.8)
    ax.fill_between(x, x / CHECK_ERROR_FACTOR, x * CHECK_ERROR_FACTOR, color="#4caf50", alpha=0.15,
                    label=f"within x{CHECK_ERROR_FACTOR:g}")
    ax.plot([], [], marker="o", mfc="none", color="#555", ls="none",
            label=f"open: CPU above x{CHECK_COST_FACTOR:g} the predicted")
    ax.set_xlim(lo, hi)
    ax.set_ylim(lo, hi)
    ax.set_xlabel("predicted error at the check's horizon")
    ax.set_ylabel("measured error")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0, frameon=False)
    return svg(fig)
