"""Every figure kind of ``longtime plot`` lives in this package, one module per family, and
is registered by name in ``longtime.plot.PLOT_KINDS`` ("module:function", imported only
when drawn). A kind function takes keyword arguments (see ``longtime.plot``) and returns
the paths it wrote through ``save``.
"""
from __future__ import annotations

import io
import math
from pathlib import Path
from typing import Sequence

from longtime.core.files import write_atomic
from longtime.core.params import InputError

FORMATS = ("png", "svg", "pdf")


def pyplot():
    """matplotlib's pyplot on the Agg backend (files only, no display). Text is drawn as
    given, never parsed as mathtext: a name or setting with '$' shows as typed (a label
    that wants mathematics passes ``parse_math=True``)."""
    import matplotlib

    matplotlib.use("Agg")
    matplotlib.rcParams["text.parse_math"] = False
    import matplotlib.pyplot as plt

    return plt


_SUPERSCRIPT = str.maketrans("-0123456789", "\u207b\u2070\u00b9\u00b2\u00b3\u2074\u2075\u2076\u2077\u2078\u2079")


def decade_label(value: float, _pos=None) -> str:
    """'10⁻⁵' for a power of ten, in plain Unicode text (else a short number)."""
    if value <= 0:
        return ""
    exponent = round(math.log10(value))
    if abs(value / 10.0**exponent - 1.0) > 1e-9:
        return f"{value:.2g}"
    return "1" if exponent == 0 else "10" + str(exponent).translate(_SUPERSCRIPT)


def _minor_labels(axis):
    """Labels of the minor ticks 2 and 5 x 10^k ('2×10⁻⁵', and '0.5', '2', '50' near 1) on an
    axis spanning less than two decades, where the decades alone leave one label or none; none
    on a wider axis."""

    def label(value: float, _pos=None) -> str:
        low, high = sorted(axis.get_view_interval())
        if value <= 0 or not (0 < low and high / low < 100.0):
            return ""
        exponent = math.floor(math.log10(value) + 1e-9)
        mantissa = round(value / 10.0**exponent)
        if mantissa not in (2, 5) or abs(value / (mantissa * 10.0**exponent) - 1.0) > 1e-6:
            return ""
        if -1 <= exponent <= 2:
            return f"{mantissa * 10.0**exponent:g}"
        return f"{mantissa}×" + decade_label(10.0**exponent)

    return label


def plain_log_ticks(ax) -> None:
    """Tick labels of ``ax``'s log axes as plain text: the decades, and 2 and 5 times them on
    an axis narrower than two decades. matplotlib's default labels are mathtext ($10^{-5}$),
    whose parsing and path layout would dominate the time the results page takes."""
    from matplotlib.ticker import FuncFormatter

    for axis in (ax.xaxis, ax.yaxis):
        if axis.get_scale() == "log":
            axis.set_major_formatter(FuncFormatter(decade_label))
            axis.set_minor_formatter(FuncFormatter(_minor_labels(axis)))


def _wide_log_axes(ax):
    """(axis, its minor tick locations in view) of ``ax``'s log axes that span two decades or
    more: their minor ticks carry no label (``_minor_labels``)."""
    import numpy as np

    out = []
    for axis in (ax.xaxis, ax.yaxis):
        if axis.get_scale() != "log":
            continue
        low, high = sorted(axis.get_view_interval())
        if not 0 < low or high / low < 100.0:
            continue
        locs = np.asarray(axis.get_minorticklocs(), dtype=float)  # without those on a major tick
        locs = locs[locs > 0]
        inside = np.abs(np.log10(locs) - np.clip(np.log10(locs), math.log10(low), math.log10(high))) < 1e-9
        if inside.any():
            out.append((axis, locs[inside]))
    return out


def collect_minor_ticks(fig) -> None:
    """The minor ticks and minor grid lines of every log axis of ``fig`` that spans two decades
    or more, drawn as one artist each instead of a tick object apiece: the same marks and lines
    where matplotlib puts them (its locator's locations, its tick's style), laid out and drawn
    at a fraction of the cost (a wide log-log panel has dozens of minor ticks, each a tick
    object with a mark, a grid line and an empty label, measured and drawn on every layout
    pass). Called once the axes' limits are final; narrower axes keep their labelled minor
    ticks."""
    import numpy as np
    from matplotlib.collections import LineCollection
    from matplotlib.lines import Line2D
    from matplotlib.ticker import NullLocator

    # every axis's locations first: shared axes share one locator, which the second step replaces
    plans = [(ax, axis, locs) for ax in fig.axes for axis, locs in _wide_log_axes(ax)]
    for ax, axis, locs in plans:
        tick = axis.get_minor_ticks(1)[0]  # the style matplotlib would give each minor tick
        is_x = axis is ax.xaxis
        place = ax.get_xaxis_transform if is_x else ax.get_yaxis_transform
        grid = tick.gridline
        if grid.get_visible():
            segments = [[(v, 0.0), (v, 1.0)] if is_x else [(0.0, v), (1.0, v)] for v in locs]
            lines = LineCollection(segments, transform=place(which="grid"), colors=[grid.get_color()],
                                   linewidths=grid.get_linewidth(), linestyles=grid.get_linestyle(),
                                   alpha=grid.get_alpha(), zorder=grid.get_zorder())
            ax.add_artist(lines)  # add_artist: the axes' limits stay as they are
        for mark, edge, which in ((tick.tick1line, 0.0, "tick1"), (tick.tick2line, 1.0, "tick2")):
            if not mark.get_visible():
                continue
            edges = np.full(locs.size, edge)
            line = Line2D(locs if is_x else edges, edges if is_x else locs, transform=place(which=which),
                          ls="none", marker=mark.get_marker(), ms=mark.get_markersize(),
                          mew=mark.get_markeredgewidth(), mec=mark.get_markeredgecolor(),
                          zorder=mark.get_zorder(), clip_on=False)
            line.set_in_layout(False)
            ax.add_artist(line)
    for _ax, axis, _locs in plans:
        axis.set_minor_locator(NullLocator())


def plain_ticks(fig) -> None:
    """``plain_log_ticks`` on every axes of ``fig``: with mathtext off (``pyplot``), matplotlib's
    own log labels would print as their source ($\\mathdefault{10^{-2}}$). Called before the
    layout, so that the layout measures the labels that are drawn."""
    for ax in fig.axes:
        plain_log_ticks(ax)


def check_formats(formats: Sequence[str]) -> None:
    bad = [f for f in formats if f not in FORMATS]
    if bad:
        raise InputError(f"formats: {', '.join(bad)} not valid: expected {', '.join(FORMATS)}")


def save(fig, out: str | Path, formats: Sequence[str] = ("png", "svg")) -> list[Path]:
    """Write ``fig`` as out.<format> for each format; close it; return the paths."""
    check_formats(formats)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    paths = []
    for fmt in formats:
        path = out.with_name(f"{out.name}.{fmt}")
        buffer = io.BytesIO()
        fig.savefig(buffer, format=fmt, dpi=130, bbox_inches="tight")
        paths.append(write_atomic(path, buffer.getvalue()))
    pyplot().close(fig)
    return paths


def run(problem: str, scheme: str, dt: float | None, t_final: float | None,
        problem_settings: dict | None = None, max_samples: int = 20_001):
    """(problem, trajectory) of one run for a figure, through ``cells.integrate_cell``:
    ``dt`` applies to schemes that have it, settings to the problem's own parameters."""
    from longtime.core import registry
    from longtime.execution.cells import Cell, integrate_cell

    pcls, icls = registry.problem_class(problem), registry.integrator_class(scheme)
    psets = {k: v for k, v in (problem_settings or {}).items() if k in pcls.parameters}
    isets = {"dt": dt} if dt is not None and "dt" in icls.parameters else {}
    return integrate_cell(Cell(problem, scheme, psets, isets, t_final), max_samples=max_samples)
