"""How schemes look in every figure: one colour per scheme family (the module of
longtime.integrators that defines it, or the built-in family it subclasses), a marker per
scheme within it, legends outside the axes; and a figure as inline SVG."""
from __future__ import annotations

import io
from typing import Sequence

from longtime.reporting.figures import collect_minor_ticks, plain_log_ticks, pyplot

LINE_STYLES = ("-", "--", ":", "-.")
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "<", ">", "*", "h")
FAMILY_COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2",
                  "#17becf", "#7f7f7f", "#bcbd22")


def family(scheme: str) -> str:
    """The family of a scheme: the module of longtime.integrators that defines it or the
    built-in family it subclasses ('explicit_rk', 'splitting', ...; a plugin's Splitting is
    'splitting'), else the module that defines it."""
    from longtime.core import registry

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
    collect_minor_ticks(fig)
    x0, y0, x1, y1 = fig.get_tightbbox(fig.canvas.get_renderer()).extents
    box = Bbox.from_extents(x0 - 0.1, y0 - 0.1, x1 + 0.3, y1 + 0.1)  # inches
    buf = io.StringIO()
    with matplotlib.rc_context({"svg.fonttype": "none"}):
        fig.savefig(buf, format="svg", bbox_inches=box)
    pyplot().close(fig)
    text = buf.getvalue()
    return text[text.index("<svg"):]


# a legend of more entries than this goes below the axes, in columns, rather than beside them
# (beside, 30 entries stand taller than the axes and squeeze them)
LEGEND_BESIDE = 14


def legend_columns(width_in: float, labels) -> int:
    """How many columns of ``labels`` fit across ``width_in`` inches at font size 7."""
    longest = max((len(str(x)) for x in labels), default=10)
    return max(1, int(width_in / (0.3 + 0.065 * longest)))


def legend_outside(ax, handles=None, labels=None) -> None:
    """The legend outside the axes: beside them up to LEGEND_BESIDE entries, else below them in
    as many columns as the figure's width holds."""
    if handles is None:
        handles, labels = ax.get_legend_handles_labels()
    if len(handles) <= LEGEND_BESIDE:
        ax.legend(handles, labels, fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0,
                  frameon=False)
        return
    width = ax.figure.get_figwidth()
    ax.legend(handles, labels, fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.16), borderaxespad=0.0,
              frameon=False, ncol=legend_columns(width, labels))
