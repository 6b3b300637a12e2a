"""How schemes look in every figure: one colour and one marker per scheme, no two schemes of
a figure alike, one look per scheme across the figures of a page; legends outside the axes;
and a figure as inline SVG with ids of its own.

A look is a (colour, marker) pair of PALETTE x MARKERS. The schemes of one figure, or of one
page (which draws all its figures with one ``styles`` of all its schemes), take the pairs in
turn by name (the k-th: colour k mod 20, marker k mod 11): up to twenty schemes have twenty
distinct colours, up to ten the ten farthest apart, and the first 220 pairs are distinct. A
scheme drawn alone (``scheme_style``) has a look of its own by a fixed rule: longtime's own
schemes, sorted by name, take the pairs in turn; a scheme that is not longtime's (a plugin's)
takes a pair by a hash of its name (md5) among those the built-in schemes leave free. A
figure of more than MAX_CURVES schemes greys all but the schemes on the problem's Pareto
front, the fastest and the next fastest at each accuracy decade (``emphasis``), so that its
legend stays legible; the greyed schemes are one legend entry."""
from __future__ import annotations

import functools
import hashlib
import io
import itertools
import re
from typing import Iterable, Sequence

from longtime.reporting.figures import collect_minor_ticks, plain_log_ticks, pyplot

LINE_STYLES = ("-", "--", ":", "-.")
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "<", ">", "*", "h")
# twenty colours told apart on screen and in print, each two at least 23 apart in CIELAB
# (CIE76 delta E; 2 is a just-noticeable difference), the first ten at least 27: tab10 with
# black for its grey, then ten chosen greedily from matplotlib's qualitative maps for their
# distance to those before; none near white or GREY (grey marks the schemes a crowded figure
# sets back, and undetermined map cells)
PALETTE = ("#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf", "#bcbd22",
           "#000000", "#ffbb78", "#637939", "#1b9e77", "#98df8a", "#a6761d", "#e7298a", "#b15928", "#393b79",
           "#d6616b", "#e6ab02")
# a figure with more schemes than this draws the Pareto front's in colour and the rest grey
MAX_CURVES = 10
GREY = "#c8c8c8"


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


@functools.lru_cache(maxsize=1)
def _built_in_schemes() -> tuple[str, ...]:
    from longtime.core import registry

    return tuple(sorted(n for n, cls in registry.integrators().items() if cls.__module__.startswith("longtime.")))


def _pair(k: int) -> dict[str, str]:
    return {"color": PALETTE[k % len(PALETTE)], "marker": MARKERS[k % len(MARKERS)]}


def scheme_style(scheme: str) -> dict[str, str]:
    """{color, marker} of ``scheme`` drawn alone, the same in every run (the module's rule:
    longtime's own schemes by their sorted names, another by a hash of its name)."""
    own = _built_in_schemes()
    if scheme in own:
        return _pair(own.index(scheme))
    pairs = len(PALETTE) * len(MARKERS)  # distinct for k < 220 (20 and 11 are coprime)
    free = max(1, pairs - len(own))
    digest = int(hashlib.md5(scheme.encode()).hexdigest(), 16)
    return _pair(len(own) + digest % free)


def styles(schemes: Iterable[str]) -> dict[str, dict[str, str]]:
    """scheme -> {color, marker} for the schemes of one figure or one page: the k-th by name
    takes pair k, so that no two of up to len(PALETTE) schemes share a colour."""
    return {s: _pair(k) for k, s in enumerate(sorted(set(schemes)))}


def emphasis(style: dict[str, dict[str, str]], schemes: Sequence[str], front: Iterable[str]) \
        -> tuple[dict[str, dict[str, str]], set[str]]:
    """(style, greyed): with more than MAX_CURVES ``schemes``, those not in ``front`` (the
    problem's Pareto front) grey and without a marker; else ``style`` as it is."""
    front = set(front)
    if len(set(schemes)) <= MAX_CURVES or not front:
        return style, set()
    greyed = {s for s in schemes if s not in front}
    return {**style, **{s: {"color": GREY, "marker": ""} for s in greyed}}, greyed


def front_schemes(rows: list[dict]) -> set[str]:
    """The schemes fastest, or next fastest of another scheme, at some accuracy decade of
    one problem's rows (report.pareto)."""
    from longtime.reporting.report import pareto, pareto_field

    field = pareto_field(rows)
    return {r["integrator"] for p in (pareto(rows, field) if field else []) for r in (p["best"], p["next"]) if r}


def svg(fig) -> str:
    """The figure as SVG markup (no XML prolog; the page writes it as a file beside itself);
    closes the figure.

    Text stays text (``svg.fonttype`` none): a figure can be searched for a scheme's name, and
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
    return unique_ids(text[text.index("<svg"):])


_FIGURES = itertools.count()


def unique_ids(text: str) -> str:
    """The SVG with every element id (and every reference to one: url(#..), href="#..")
    prefixed by one of its own: a digest of the figure and a count of this process's
    figures, so that many inline figures on one page share no id."""
    prefix = f"f{hashlib.md5(text.encode()).hexdigest()[:6]}{next(_FIGURES)}-"
    ids = set(re.findall(r'\bid="([^"]+)"', text))
    if not ids:
        return text
    text = re.sub(r'\bid="([^"]+)"', lambda m: f'id="{prefix}{m.group(1)}"', text)
    text = re.sub(r"url\(#([^)]+)\)", lambda m: f"url(#{prefix}{m.group(1)})" if m.group(1) in ids else m.group(0),
                  text)
    return re.sub(r'((?:xlink:)?href)="#([^"]+)"',
                  lambda m: f'{m.group(1)}="#{prefix}{m.group(2)}"' if m.group(2) in ids else m.group(0), text)


# a legend of more entries than this goes below the axes, in columns, rather than beside them
# (beside, 30 entries stand taller than the axes and squeeze them)
LEGEND_BESIDE = 14


def legend_columns(width_in: float, labels) -> int:
    """How many columns of ``labels`` fit across ``width_in`` inches at font size 8."""
    longest = max((len(str(x)) for x in labels), default=10)
    return max(1, int(width_in / (0.3 + 0.075 * longest)))


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
    ax.legend(handles, labels, fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.16), borderaxespad=0.0,
              frameon=False, ncol=legend_columns(width, labels))
