"""Least-squares slope of log y against log x, with its 95 % interval: the one fit behind
the observed convergence orders (longtime.measure.orders) and the growth laws (longtime.measure.growth)."""
from __future__ import annotations

import math
from typing import Iterable

import numpy as np


def fit_slope(x: Iterable[float], y: Iterable[float]) -> tuple[float, float | None]:
    """(slope, half-width of its 95 % interval) of log y = a + slope log x, all x, y > 0.
    The interval is Student's t on the slope's standard error from the residuals, so with
    two points (no residual) it is None."""
    lx, ly = np.log(np.asarray(list(x), float)), np.log(np.asarray(list(y), float))
    n = lx.size
    xm = lx - lx.mean()
    sxx = float(xm @ xm)
    slope = float(xm @ (ly - ly.mean()) / sxx)
    if n < 3:
        return slope, None
    # Student's t quantile from scipy.special: the same values as scipy.stats.t.ppf (tested),
    # without importing scipy.stats, a slow import on the report's critical path
    from scipy.special import stdtrit

    resid = ly - ly.mean() - slope * xm
    se = math.sqrt(float(resid @ resid) / (n - 2) / sxx)
    return slope, float(stdtrit(n - 2, 0.975) * se)
