"""Growth laws of errors over long runs: e(t) ~ C t^alpha, and a class for alpha only where
the data support one.

The fit is on the running maximum M(t) = max_{s <= t} e(s), which is monotone and does not
alias with the oscillation of a bounded error (a Verlet energy error peaks once a period),
over the late part of the run: the last ``DECADES`` decades of t - t0, or the part with
samples if the run is shorter. M is read at ``FIT_POINTS`` log-spaced times of that window
(the last sample at or before each), so dense even samples do not outweigh the early
decade, and log M = log C + alpha log(t - t0) is fitted by least squares: ``NAME.growth``.

The same fit on ``WINDOWS`` successive windows of one decade each, half a decade apart
(they span the fit's window), gives the local slopes ``NAME.growth_windows``, each with its
residuals' 95 % interval. ``NAME.growth_ci`` spans the whole fit's interval and every
window's slope: a curved log-log plot gets a wide interval, not a tight wrong one.

Classes (alpha to the nearest law): ``bounded`` (alpha < 0.25), ``sqrt`` (0.25 to 0.75: a
random walk, Brouwer's law for round-off), ``linear`` (0.75 to 1.5), ``quadratic`` (1.5 to
2.5), ``faster``; ``saturated`` when the error reached ``SATURATION`` (O(1): past that it
measures nothing; alpha is then fitted before that time and ``NAME.saturated_t`` says
when), ``diverged`` when the run blew up. An error that stays exactly 0 is bounded.
The class of alpha holds only where the data support it, else it is ``undetermined`` and
``NAME.growth_reason`` says why (for a class, what it rests on). With ``R`` =
``ROUNDOFF_FACTOR`` eps sqrt(steps), the size of Brouwer's random walk of a relative
rounding of a few eps per step:

- an error above R whose windows' slopes fall in different classes, two of them apart by
  more than their intervals, is ``undetermined``: "pre-asymptotic: slopes 0.26, 0.51, 0.75"
  where they rise or fall in turn, "slopes disagree: ..." otherwise (slopes that differ
  but share a class give that class: the law is the class, not the digits);
- an error at most R is round-off: the running maximum of a random walk moves in jumps,
  so its windows disagree by chance and the class is the whole fit's;
- ``sqrt`` needs an error at most R: a larger error growing like t^0.5 is no walk of
  round-off, and is ``undetermined`` ("not round-off: ...");
- a run whose samples span under 1.5 decades of t (two windows) is ``undetermined``.

Without ``steps`` R is unknown: every error is held to the windows, and sqrt is not checked.

The passes over every sample (the running maximum, the samples with tau > 0, whether M is
positive in a window) and the reading of M at the log-spaced times are compiled loops
(numba), written by hand where numpy makes a mask, a copy or a sort of the whole arrays
for each; they select the same samples, so the fits see the same values.
"""
from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np

from longtime.core.rowschema import GROWTH_CLASSES, POWER_CLASSES
from longtime.numerics.loglog import fit_slope

DECADES = 2.0
FIT_POINTS = 40
WINDOWS = 3  # windows of WINDOW_DECADES, WINDOW_SHIFT decades apart, ending at the last sample
WINDOW_DECADES = 1.0
WINDOW_SHIFT = 0.5
WINDOW_POINTS = 20
ROUNDOFF_FACTOR = 10.0
EPS = float(np.finfo(float).eps)
SATURATION = 0.5  # the relative error of "O(1)": also where NAME.t_50pct is set
# upper ends of alpha for each power-law class (bounded, sqrt, linear, quadratic, faster), in order
LIMITS = tuple(zip((0.25, 0.75, 1.5, 2.5, math.inf), POWER_CLASSES, strict=True))
CLASSES = GROWTH_CLASSES


def classify(alpha: float) -> str:
    for limit, name in LIMITS:
        if alpha < limit:
            return name
    return LIMITS[-1][1]


@numba.njit(cache=True)
def _running_max(err, level, running):
    """(upto, above): ``upto`` the first sample where ``err`` is not finite (its size if
    none); over the samples before it the running maximum into ``running``, as
    np.maximum.accumulate (the later of two equal values, as numpy takes it); ``above`` the
    first sample where it reaches ``level``, -1 if none. One pass instead of numpy's five."""
    upto, above = err.size, -1
    r = 0.0
    for i in range(err.size):
        v = err[i]
        if not np.isfinite(v):
            upto = i
            break
        r = r if i > 0 and r > v else v
        running[i] = r
        if above < 0 and r >= level:
            above = i
    return upto, above


@numba.njit(cache=True)
def _positive_from(tau):
    """k where the samples with tau > 0 are exactly tau[k:] (sorted times), else -1."""
    k = 0
    while k < tau.size and not tau[k] > 0:
        k += 1
    for i in range(k, tau.size):
        if not tau[i] > 0:
            return -1
    return k


def _positive(tau: np.ndarray, m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``tau`` and ``m`` where tau > 0: views where those samples are a suffix, else copies."""
    tau, m = np.ascontiguousarray(tau, dtype=float), np.ascontiguousarray(m, dtype=float)
    k = _positive_from(tau)
    if k >= 0:
        return tau[k:], m[k:]
    keep = tau > 0
    return tau[keep], m[keep]


@numba.njit(cache=True)
def _any_positive(tau, m, lo, hi):
    """Whether m > 0 at any sample with lo <= tau <= hi (stops at the first)."""
    for i in range(tau.size):
        if tau[i] >= lo and tau[i] <= hi and m[i] > 0:
            return True
    return False


@numba.njit(cache=True)
def _points_at(tau, m, grid):
    """(tau, m) at the last sample at or before each of ``grid`` (times ascending), clipped
    to the samples, each sample once in order (np.unique), where m > 0."""
    idx = np.unique(np.minimum(np.maximum(np.searchsorted(tau, grid * (1 + 1e-12), side="right") - 1, 0),
                               tau.size - 1))
    x, y = tau[idx], m[idx]
    return x[y > 0], y[y > 0]


def _read(tau: np.ndarray, m: np.ndarray, start: float, end: float, points: int) -> tuple[np.ndarray, np.ndarray]:
    """M at ``points`` log-spaced times of [start, end] (the last sample at or before each),
    each sample once, zeros dropped."""
    return _points_at(tau, m, np.logspace(math.log10(start), math.log10(end), points))


def fit_power_law(tau: np.ndarray, running_max: np.ndarray) -> tuple[float, float, float] | None:
    """(alpha, ci_low, ci_high) of log M = a + alpha log tau at log-spaced points of the
    window [tau_end / 10^DECADES, tau_end] (tau > 0, M nondecreasing); None with fewer than
    three distinct points. Zeros of M before its first nonzero value are dropped; an M that
    is 0 throughout is bounded (alpha 0). The interval is the residuals' alone."""
    return _fit_power_law(*_positive(tau, running_max))


def _fit_power_law(tau: np.ndarray, m: np.ndarray) -> tuple[float, float, float] | None:
    """``fit_power_law`` of the samples with tau > 0 (``_positive``)."""
    if tau.size < 3:
        return None
    t_end = float(tau[-1])
    start = max(float(tau[0]), t_end / 10**DECADES)
    if not t_end > start:
        return None
    if not _any_positive(tau, m, start, math.inf):
        return 0.0, 0.0, 0.0
    x, y = _read(tau, m, start, t_end, FIT_POINTS)
    if x.size < 3 or np.ptp(x) == 0:
        return None
    alpha, half = fit_slope(x, y)
    return alpha, alpha - half, alpha + half


def window_slopes(tau: np.ndarray, running_max: np.ndarray) -> list[tuple[float, float]]:
    """(slope, 95 % half-width) of the running maximum on each of the last ``WINDOWS``
    windows of WINDOW_DECADES, WINDOW_SHIFT decades apart (earliest first) that lie within
    the samples; a window where M is 0 throughout has slope 0."""
    return _window_slopes(*_positive(tau, running_max))


def _window_slopes(tau: np.ndarray, m: np.ndarray) -> list[tuple[float, float]]:
    """``window_slopes`` of the samples with tau > 0 (``_positive``)."""
    out: list[tuple[float, float]] = []
    if tau.size < 3:
        return out
    end = float(tau[-1])
    for k in range(WINDOWS):
        hi = end / 10 ** (k * WINDOW_SHIFT)
        lo = hi / 10**WINDOW_DECADES
        if lo < float(tau[0]) * (1 - 1e-12):
            break
        x, y = _read(tau, m, lo, hi, WINDOW_POINTS)
        if x.size == 0 and not _any_positive(tau, m, lo, hi):
            out.append((0.0, 0.0))
            continue
        if x.size < 3 or np.ptp(x) == 0:
            break
        out.append(fit_slope(x, y))
    return out[::-1]


def _verdict(alpha: float, windows: list[tuple[float, float]], level: float,
             steps: int | None) -> tuple[str, str]:
    """(class, reason): the class of ``alpha`` where the windows and the error ``level``
    support it, else ``undetermined`` and why; for a class, the reason says what it rests on."""
    # round(a, 2) + 0.0 turns a slope that rounds to -0.00 (round-off about zero) into 0.00
    slopes = ", ".join(f"{round(a, 2) + 0.0:.2f}" for a, _ in windows)
    if len(windows) < 2:
        return "undetermined", f"too short: the samples span under {WINDOW_DECADES + WINDOW_SHIFT:g} decades of t"
    bound = ROUNDOFF_FACTOR * EPS * math.sqrt(steps) if steps else None
    name = classify(alpha)
    if bound is not None and level <= bound:
        return name, (f"round-off: error {level:.2g} <= {ROUNDOFF_FACTOR:g} eps sqrt(steps) = {bound:.2g}, "
                      f"whole fit; slopes {slopes}")
    classes = {classify(a) for a, _ in windows}
    disagree = any(abs(a - b) > ha + hb for i, (a, ha) in enumerate(windows) for b, hb in windows[i + 1:])
    if len(classes) > 1 and disagree:
        rises = np.diff([a for a, _ in windows])
        monotone = bool(np.all(rises > 0) or np.all(rises < 0))
        return "undetermined", f"{'pre-asymptotic: slopes' if monotone else 'slopes disagree:'} {slopes}"
    if name == "sqrt" and bound is not None:
        return "undetermined", (f"not round-off: alpha {alpha:.2f} as a random walk, but the error {level:.2g} is "
                                f"above {ROUNDOFF_FACTOR:g} eps sqrt(steps) = {bound:.2g}")
    return name, f"slopes {slopes}"


def growth_fields(name: str, t: np.ndarray, err: np.ndarray, t0: float,
                  diverged: bool = False, steps: int | None = None) -> dict[str, Any]:
    """``NAME.growth`` (alpha), ``NAME.growth_ci`` ([low, high]), ``NAME.growth_class``,
    ``NAME.growth_reason`` (what the class rests on, or why it is undetermined),
    ``NAME.growth_windows`` (the windows' slopes) and ``NAME.saturated_t`` (the first time
    the error reached SATURATION, else null) of the error ``err`` sampled at ``t``
    (non-finite values end the usable part) of a run of ``steps`` steps."""
    out: dict[str, Any] = {f"{name}.growth": None, f"{name}.growth_ci": None,
                           f"{name}.growth_class": "diverged" if diverged else None,
                           f"{name}.growth_reason": None, f"{name}.growth_windows": None,
                           f"{name}.saturated_t": None}
    t, err = np.asarray(t, dtype=float), np.ascontiguousarray(err, dtype=float)
    running = np.empty(err.size)
    upto, above = _running_max(err, SATURATION, running)  # err up to its first non-finite value
    if upto < 3:
        return out
    end = upto
    if above >= 0:
        out[f"{name}.saturated_t"] = float(t[above])
        end = above  # fit the part up to where the error meant nothing
    tau, m = t[:end] - t0, running[:end]
    late = _positive(tau, m)
    fit = _fit_power_law(*late)
    if fit is None:
        return out
    alpha, low, high = fit
    windows = _window_slopes(*late)
    out[f"{name}.growth"] = float(alpha)  # full precision: formats round, rows do not
    out[f"{name}.growth_ci"] = [float(min([low, *(a for a, _ in windows)])),
                                float(max([high, *(a for a, _ in windows)]))]
    out[f"{name}.growth_windows"] = [float(a) for a, _ in windows]
    if diverged:
        return out
    if above >= 0:
        out[f"{name}.growth_class"] = "saturated"
        out[f"{name}.growth_reason"] = f"the error reached {SATURATION:g} at t = {t[above]:.4g}"
        return out
    if float(m[-1]) == 0.0:
        out[f"{name}.growth_class"], out[f"{name}.growth_reason"] = "bounded", "the error stays 0"
        return out
    cls, reason = _verdict(alpha, windows, float(m[-1]), steps)
    out[f"{name}.growth_class"], out[f"{name}.growth_reason"] = cls, reason
    return out
