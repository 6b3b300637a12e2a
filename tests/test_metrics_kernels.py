"""The compiled passes of a row's curves and growth laws (longtime.measure.metrics,
longtime.measure.growth, longtime.numerics.loglog) give the values of the plain numpy and
Python formulation they replace, bit for bit: the drift envelope's peaks, the curves' 6
significant digits, the running maximum, the points the growth fits read, the fit itself."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import stdtrit

from longtime.measure import growth
from longtime.measure.metrics import drift_envelope, six_digits
from longtime.numerics.loglog import fit_slope


def _bits(a, b) -> bool:
    return np.array_equal(np.asarray(a, dtype=float).view(np.int64), np.asarray(b, dtype=float).view(np.int64))


def _numpy_envelope(t, err, points):
    tau = t - t[0]
    keep = (tau > 0) & np.isfinite(err)
    if keep.sum() < 2:
        return None
    tau, e = tau[keep], err[keep]
    edges = np.logspace(np.log10(tau[0]), np.log10(tau[-1]), points + 1)
    bins = np.clip(np.searchsorted(edges, tau, side="right") - 1, 0, points - 1)
    starts = np.flatnonzero(np.r_[True, bins[1:] != bins[:-1]])
    peaks = [int(a + np.argmax(e[a:b])) for a, b in zip(starts, np.r_[starts[1:], tau.size])]
    return {"invariant": "H", "t": [float(f"{tau[i]:.6g}") for i in peaks],
            "error": [float(f"{e[i]:.6g}") for i in peaks]}


@pytest.mark.parametrize("samples", [2, 3, 50, 4001])
def test_drift_envelope_has_the_values_of_numpy(samples):
    rng = np.random.default_rng(samples)
    t = 3.0 + np.sort(rng.uniform(0.0, 1e3, samples))
    t[: samples // 3] = np.linspace(3.0, t[samples // 3], samples // 3, endpoint=False)  # dense early samples
    err = np.abs(rng.standard_normal(samples)) * 10.0 ** rng.uniform(-12, -2, samples)
    err[rng.random(samples) < 0.05] = np.nan  # skipped, as non-finite
    err[::7] = err[3] if samples > 3 else err[0]  # equal peaks: the first
    for points in (1, 5, 80):
        assert drift_envelope("H", t, err, points) == _numpy_envelope(t, err, points)
    err[:] = np.nan
    assert drift_envelope("H", t, err) is None


def test_six_digits_are_the_formatting_s():
    rng = np.random.default_rng(5)
    near_ties = np.round(rng.uniform(1e5, 1e6, 20000)) + 0.5
    values = np.concatenate([
        rng.standard_normal(50000) * 10.0 ** rng.uniform(-30, 30, 50000),
        near_ties / 10.0 ** rng.integers(-3, 12, near_ties.size),
        np.nextafter(near_ties, 0) / 1e6, np.nextafter(near_ties, np.inf) / 1e3,
        10.0 ** np.arange(-25, 30), np.nextafter(10.0 ** np.arange(-25, 30), 0),
        [0.0, -0.0, np.inf, -np.inf, np.nan, 5e-324, 1.7e308, 999999.5, 123456.5, 0.1234565, -2.5e-7],
    ])
    got = six_digits(values)
    assert isinstance(got, list) and all(type(v) is float for v in got)
    assert _bits(got, [float(f"{v:.6g}") for v in values.tolist()])


def test_running_max_is_numpys_accumulate():
    rng = np.random.default_rng(1)
    err = np.abs(rng.standard_normal(500)) * 0.3
    err[::5] = 0.0
    err[:12] = [0.0, -0.0, -0.0, 0.0, 0.0, -0.0, 0.0, -0.0, -0.0, -0.0, 0.0, 0.2]  # signed zeros: the later
    err[17] = err[16]
    running = np.empty(err.size)
    assert growth._running_max(err, growth.SATURATION, running) == (500, int(np.argmax(err >= 0.5)))
    assert _bits(running, np.maximum.accumulate(err))
    err[300] = np.inf
    assert growth._running_max(err, 10.0, running)[0] == 300
    assert _bits(running[:300], np.maximum.accumulate(err[:300]))


def _numpy_read(tau, m, start, end, points):
    grid = np.logspace(math.log10(start), math.log10(end), points)
    idx = np.unique(np.clip(np.searchsorted(tau, grid * (1 + 1e-12), side="right") - 1, 0, tau.size - 1))
    x, y = tau[idx], m[idx]
    return x[y > 0], y[y > 0]


def test_growth_reads_the_points_of_numpy():
    rng = np.random.default_rng(2)
    tau = np.concatenate([[-1.0, 0.0], np.sort(rng.uniform(0.0, 1e4, 3000))])
    m = np.maximum.accumulate(np.abs(rng.standard_normal(tau.size)) * 1e-9 * (1 + np.abs(tau)))
    m[:400] = 0.0  # zeros before the first nonzero value are dropped
    kept = tau > 0
    assert all(_bits(a, b) for a, b in zip(growth._positive(tau, m), (tau[kept], m[kept])))
    for start, end, points in ((1.0, 1e4, 40), (tau[500], tau[501], 20), (1e3, 1e4, 20), (1e-3, 1.0, 20)):
        assert all(_bits(a, b) for a, b in zip(growth._read(tau[kept], m[kept], start, end, points),
                                                _numpy_read(tau[kept], m[kept], start, end, points)))
    for lo, hi in ((0.0, 1.0), (tau[300], tau[390]), (tau[300], tau[401]), (1e4, math.inf)):
        window = (tau >= lo) & (tau <= hi)
        assert growth._any_positive(tau, m, lo, hi) == bool(np.any(m[window] > 0))
    shuffled = tau.copy()
    shuffled[5], shuffled[6] = -shuffled[5], -shuffled[6]  # a sample with tau <= 0 among later ones
    kept = shuffled > 0
    assert all(_bits(a, b) for a, b in zip(growth._positive(shuffled, m), (shuffled[kept], m[kept])))


def _numpy_fit(x, y):
    lx, ly = np.log(np.asarray(list(x), float)), np.log(np.asarray(list(y), float))
    n = lx.size
    xm = lx - lx.mean()
    sxx = float(xm @ xm)
    slope = float(xm @ (ly - ly.mean()) / sxx)
    if n < 3:
        return slope, None
    resid = ly - ly.mean() - slope * xm
    se = math.sqrt(float(resid @ resid) / (n - 2) / sxx)
    return slope, float(stdtrit(n - 2, 0.975) * se)


@pytest.mark.parametrize("n", [2, 3, 7, 8, 9, 20, 40, 130])
def test_fit_slope_is_the_numpy_fit(n):
    rng = np.random.default_rng(n)
    x = np.sort(rng.uniform(1.0, 1e4, n))
    y = 1e-8 * x**0.7 * np.exp(0.1 * rng.standard_normal(n))
    assert fit_slope(x, y) == _numpy_fit(x, y)
    assert fit_slope(list(x), iter(y.tolist())) == _numpy_fit(x, y)  # any iterables
