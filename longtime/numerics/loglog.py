"""Least-squares slope of log y against log x, with its 95 % interval: the one fit behind
the observed convergence orders (longtime.measure.orders) and the growth laws (longtime.measure.growth)."""
from __future__ import annotations

import functools
import math
from typing import Iterable

import numpy as np


def _floats(v: Iterable[float]) -> np.ndarray:
    """``v`` as a float array: a 1-D float array as it is (the values list() would give)."""
    if isinstance(v, np.ndarray) and v.dtype == np.float64 and v.ndim == 1:
        return v
    return np.asarray(list(v), float)


@functools.lru_cache(maxsize=None)
def _t975(dof: int) -> float:
    """Student's t quantile 0.975 of ``dof`` degrees of freedom, from scipy.special: the same
    values as scipy.stats.t.ppf (tested), without importing scipy.stats, a slow import on
    the report's critical path."""
    from scipy.special import stdtrit

    return float(stdtrit(dof, 0.975))


def fit_slope(x: Iterable[float], y: Iterable[float]) -> tuple[float, float | None]:
    """(slope, half-width of its 95 % interval) of log y = a + slope log x, all x, y > 0.
    The interval is Student's t on the slope's standard error from the residuals, so with
    two points (no residual) it is None."""
    lx, ly = np.log(_floats(x)), np.log(_floats(y))
    n = lx.size
    # np.mean of a float array is its sum over the count (numpy's _methods._mean): the
    # same bits, without mean's overhead on a few dozen points
    xm, ym = lx - lx.sum() / n, ly - ly.sum() / n
    sxx = float(xm @ xm)
    slope = float(xm @ ym / sxx)
    if n < 3:
        return slope, None
    resid = ym - slope * xm
    se = math.sqrt(float(resid @ resid) / (n - 2) / sxx)
    return slope, _t975(n - 2) * se
