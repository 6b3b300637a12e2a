"""Growth laws of errors over long runs: e(t) ~ C t^alpha, and a class for alpha.

The fit is on the running maximum M(t) = max_{s <= t} e(s), which is monotone and does not
alias with the oscillation of a bounded error (a Verlet energy error peaks once a period),
over the late part of the run: the last ``DECADES`` decades of t - t0, or the part with
samples if the run is shorter. M is read at ``FIT_POINTS`` log-spaced times of that window
(the last sample at or before each), so dense even samples do not outweigh the early
decade, and log M = log C + alpha log(t - t0) is fitted by least squares. ``growth_ci`` is
the 95 % interval of the slope from the fit's residuals (Student t); the running maximum's
points are correlated, so read it as the fit's own spread, not a sampling interval.

Classes (alpha rounded to the nearest law): ``bounded`` (alpha < 0.25), ``sqrt`` (0.25 to
0.75: a random walk, Brouwer's law for round-off), ``linear`` (0.75 to 1.5), ``quadratic``
(1.5 to 2.5), ``faster``; ``saturated`` when the error reached ``SATURATION`` (O(1): past
that it measures nothing; alpha is then fitted before that time and ``NAME.saturated_t``
says when), ``diverged`` when the run blew up. An error that stays exactly 0 is bounded.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from .numerics.loglog import fit_slope

DECADES = 2.0
FIT_POINTS = 40
SATURATION = 0.5  # the relative error of "O(1)": also where NAME.t_50pct is set
# upper ends of alpha for each class, in order
LIMITS = ((0.25, "bounded"), (0.75, "sqrt"), (1.5, "linear"), (2.5, "quadratic"), (math.inf, "faster"))
CLASSES = tuple(name for _, name in LIMITS) + ("saturated", "diverged")


def classify(alpha: float) -> str:
    for limit, name in LIMITS:
        if alpha < limit:
            return name
    return LIMITS[-1][1]


def fit_power_law(tau: np.ndarray, running_max: np.ndarray) -> tuple[float, float, float] | None:
    """(alpha, ci_low, ci_high) of log M = a + alpha log tau at log-spaced points of the
    window [tau_end / 10^DECADES, tau_end] (tau > 0, M nondecreasing); None with fewer than
    three distinct points. Zeros of M before its first nonzero value are dropped; an M that
    is 0 throughout is bounded (alpha 0)."""
    keep = tau > 0
    tau, m = tau[keep], running_max[keep]
    if tau.size < 3:
        return None
    t_end = float(tau[-1])
    start = max(float(tau[0]), t_end / 10**DECADES)
    if not t_end > start:
        return None
    grid = np.logspace(math.log10(start), math.log10(t_end), FIT_POINTS)
    idx = np.unique(np.clip(np.searchsorted(tau, grid * (1 + 1e-12), side="right") - 1, 0, tau.size - 1))
    x, y = tau[idx], m[idx]
    if np.all(y == 0):
        return 0.0, 0.0, 0.0
    nonzero = y > 0
    x, y = x[nonzero], y[nonzero]
    if x.size < 3 or np.ptp(x) == 0:
        return None
    alpha, half = fit_slope(x, y)
    return alpha, alpha - half, alpha + half


def growth_fields(name: str, t: np.ndarray, err: np.ndarray, t0: float,
                  diverged: bool = False) -> dict[str, Any]:
    """``NAME.growth`` (alpha), ``NAME.growth_ci`` ([low, high]), ``NAME.growth_class`` and
    ``NAME.saturated_t`` (the first time the error reached SATURATION, else null) of the
    error ``err`` sampled at ``t`` (non-finite values end the usable part)."""
    out: dict[str, Any] = {f"{name}.growth": None, f"{name}.growth_ci": None,
                           f"{name}.growth_class": "diverged" if diverged else None,
                           f"{name}.saturated_t": None}
    t, err = np.asarray(t, dtype=float), np.asarray(err, dtype=float)
    finite = np.isfinite(err)
    upto = err.size if finite.all() else int(np.argmin(finite))
    t, err = t[:upto], err[:upto]
    if err.size < 3:
        return out
    running = np.maximum.accumulate(err)
    above = np.flatnonzero(running >= SATURATION)
    end = err.size
    if above.size:
        out[f"{name}.saturated_t"] = float(t[above[0]])
        end = int(above[0])  # fit the part before the error meant nothing
    fit = fit_power_law(t[:end] - t0, running[:end])
    if fit is not None:
        alpha, low, high = fit
        out[f"{name}.growth"] = float(alpha)  # full precision: formats round, rows do not
        out[f"{name}.growth_ci"] = [float(low), float(high)]
    if not diverged:
        if above.size:
            out[f"{name}.growth_class"] = "saturated"
        elif fit is not None:
            out[f"{name}.growth_class"] = classify(fit[0])
    return out
