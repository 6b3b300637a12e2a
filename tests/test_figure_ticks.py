"""The page's figures draw a wide log axis's minor ticks and minor grid as one artist each:
the same locations and style matplotlib's tick objects would have; a narrow one labels its
minor ticks, plainly near 1."""
import numpy as np
import pytest

from longtime.reporting.figures import collect_minor_ticks, pyplot


def _axes(x, y):
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(5, 3))
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.plot(x, y, marker="o")
    ax.grid(True, which="both", alpha=0.3)
    return plt, fig, ax


def test_wide_log_axes_minor_ticks_become_collections():
    from matplotlib.collections import LineCollection
    from matplotlib.lines import Line2D
    from matplotlib.ticker import NullLocator

    plt, fig, ax = _axes([1e-3, 1e2], [1e-12, 1e-2])
    fig.canvas.draw()
    low, high = ax.get_xlim()
    expected = [v for v in ax.xaxis.get_minorticklocs() if low <= v <= high]
    tick = ax.xaxis.get_minor_ticks(1)[0]
    collect_minor_ticks(fig)
    assert isinstance(ax.xaxis.get_minor_locator(), NullLocator)
    grids = [a for a in ax.get_children() if isinstance(a, LineCollection)]
    marks = [a for a in ax.get_children() if isinstance(a, Line2D) and a.get_marker() != "o"]
    xs = sorted(seg[0][0] for g in grids for seg in g.get_segments() if seg[0][0] == seg[1][0])
    assert xs == pytest.approx(sorted(expected))
    assert len(expected) >= 20  # five decades: 2..9 in each
    vertical = next(g for g in grids if g.get_segments()[0][0][0] == g.get_segments()[0][1][0])
    assert vertical.get_alpha() == pytest.approx(tick.gridline.get_alpha())
    assert vertical.get_linewidth()[0] == pytest.approx(tick.gridline.get_linewidth())
    x_marks = next(m for m in marks if np.allclose(m.get_ydata(), 0.0))
    assert sorted(x_marks.get_xdata()) == pytest.approx(sorted(expected))
    assert x_marks.get_markersize() == pytest.approx(tick.tick1line.get_markersize())
    fig.canvas.draw()  # and the limits stay as they were
    assert ax.get_xlim() == pytest.approx((low, high))
    plt.close(fig)


def test_narrow_log_axis_keeps_its_labelled_minor_ticks():
    from matplotlib.ticker import NullLocator

    plt, fig, ax = _axes([1.0, 30.0], [2e-5, 6e-5])  # under two decades on both axes
    before = len(ax.get_children())
    collect_minor_ticks(fig)
    assert not isinstance(ax.xaxis.get_minor_locator(), NullLocator)
    assert not isinstance(ax.yaxis.get_minor_locator(), NullLocator)
    assert len(ax.get_children()) == before
    plt.close(fig)


def test_narrow_log_axis_labels_its_minor_ticks_plainly_near_one():
    from longtime.reporting.figures import plain_log_ticks

    plt, fig, ax = _axes([1.0, 30.0], [0.3, 6.0])
    plain_log_ticks(ax)
    fig.canvas.draw()
    minor = {t.get_text() for t in ax.yaxis.get_ticklabels(minor=True)} - {""}
    assert {"0.5", "2", "5"} <= minor and not any("×" in t for t in minor)
    small = _minor_label_of(ax.yaxis, 2e-5)
    assert small == "2×10⁻⁵"
    plt.close(fig)


def _minor_label_of(axis, value):
    from longtime.reporting.figures import _minor_labels

    axis.axes.set_ylim(1e-5, 9e-5)
    return _minor_labels(axis)(value)
