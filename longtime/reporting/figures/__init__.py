"""Every figure kind of ``longtime plot`` lives in this package, one module per family, and
is registered by name in ``longtime.plot.PLOT_KINDS`` ("module:function", imported only
when drawn). A kind function takes keyword arguments (see ``longtime.plot``) and returns
the paths it wrote through ``save``.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Sequence

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
    """Labels of the minor ticks 2 and 5 x 10^k ('2×10⁻⁵') on an axis spanning less than two
    decades, where the decades alone leave one label or none; none on a wider axis."""

    def label(value: float, _pos=None) -> str:
        low, high = sorted(axis.get_view_interval())
        if value <= 0 or not (0 < low and high / low < 100.0):
            return ""
        exponent = math.floor(math.log10(value) + 1e-9)
        mantissa = round(value / 10.0**exponent)
        if mantissa not in (2, 5) or abs(value / (mantissa * 10.0**exponent) - 1.0) > 1e-6:
            return ""
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
        fig.savefig(path, dpi=130, bbox_inches="tight")
        paths.append(path)
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
