"""The finite-time growth of a perturbation, measured on every problem, and the
predictability horizon it sets for a target error.

A double-precision run starts from the initial state rounded to INITIAL_ROUNDING (relative)
and rounds again at every step: whatever the scheme, its error is at least that rounding
grown by the flow. ``measure`` follows a perturbation along the problem's reference
(heyoka in double at tolerance eps, the Lyapunov exponent's runs:
``longtime.measure.lyapunov.separations``): two runs SEPARATION apart, renormalised at the
end of each of INTERVALS intervals, whose logarithmic growths sum to ln G(t), the growth of
a perturbation from t0 to t. It is measured over the span ``growth_span`` (the problem's
default final time times 1, 2 or 5 times a power of ten, the first that covers the horizon
asked) and cached beside the references.

G(t) holds for every problem, chaotic or not: an unstable periodic orbit (Arenstorf's) grows
a perturbation by a factor each period, close encounters (the Pythagorean problem) by a jump
at each, a regular orbit (Kepler's) only linearly (shear). The predictability horizon of a
target E (``Growth.horizon``) is the first time INITIAL_ROUNDING * G(t) reaches E: past it
no double-precision run keeps a pointwise error of E. Where G stays below E / INITIAL_ROUNDING
over the span measured, the horizon lies beyond it (None).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from longtime.core.problem import Problem

# the relative rounding of a double initial state (and of every step's state)
INITIAL_ROUNDING = 1e-16
# the growth span is the problem's default final time times one of these times 10^k
SPAN_STEPS = (1.0, 2.0, 5.0)
# the wall seconds the growth runs of one span may take (the heyoka compile included)
GROWTH_BUDGET_S = 60.0


def growth_span(problem: Problem, horizon: float) -> float:
    """The span the growth is measured over for a question up to ``horizon``: the problem's
    default final time times the first of 1, 2, 5, 10, 20, ... that reaches ``horizon``
    (a few spans, each cached, serve every horizon)."""
    base = float(problem.default_t_final)
    k = 0
    while True:
        for step in SPAN_STEPS:
            span = base * step * 10.0**k
            if span >= horizon * (1 - 1e-9):
                return span
        k += 1


@dataclass(frozen=True, eq=False)  # arrays: compared by identity
class Growth:
    """ln G(t) of a perturbation on ``problem`` from ``t0``, at the ends ``t`` of the
    intervals (NaN past ``measured_to``, where the budget ran out), and the problem's
    ``period`` where it has one."""
    problem: str
    t: np.ndarray
    log_growth: np.ndarray
    t0: float = 0.0
    period: float | None = None

    @property
    def measured_to(self) -> float:
        ok = np.isfinite(self.log_growth)
        n = int(np.argmin(ok)) if not ok.all() else ok.size
        return float(self.t[n - 1]) if n else 0.0

    def factor_at(self, t: float) -> float | None:
        """G(t), the largest growth reached by ``t`` (None past ``measured_to``)."""
        if t > self.measured_to * (1 + 1e-9):
            return None
        k = int(np.searchsorted(self.t, t * (1 - 1e-12), side="left"))
        upto = self.log_growth[: k + 1]
        return float(math.exp(max(0.0, float(np.nanmax(upto))))) if upto.size else 1.0

    def horizon(self, target: float) -> float | None:
        """The first time INITIAL_ROUNDING * G(t) reaches ``target`` (interpolated in ln G
        between the interval ends); None where it stays below up to ``measured_to``."""
        if target <= INITIAL_ROUNDING:
            return self.t0
        need = math.log(target / INITIAL_ROUNDING)
        lg = np.where(np.isfinite(self.log_growth), self.log_growth, -np.inf)
        above = np.flatnonzero(lg >= need)
        if not above.size:
            return None
        k = int(above[0])
        t1, g1 = float(self.t[k]), float(lg[k])
        t0, g0 = (float(self.t[k - 1]), float(lg[k - 1])) if k else (self.t0, 0.0)
        return t0 + (t1 - t0) * (need - g0) / (g1 - g0) if g1 > g0 else t1

    def per_period(self, upto: float) -> float | None:
        """The mean growth factor per period over [t0, ``upto``]: G(upto)^(period / upto)
        (None without a period, or past the span measured)."""
        g = self.factor_at(upto)
        if self.period is None or g is None or upto <= self.t0:
            return None
        return g ** (self.period / (upto - self.t0))

    def rate_text(self, upto: float) -> str:
        """'grows x285 a period (x4.4e+10 by t = 51.1, 2.99 periods)' or 'grows x3.2e+04 by t = 100'."""
        upto = min(upto, self.measured_to)
        per = self.per_period(upto)
        if per is not None and upto - self.t0 >= self.period * (1 - 1e-9):
            return (f"grows x{per:.3g} a period (x{self.factor_at(upto):.3g} by t = {upto:.4g}, "
                    f"{(upto - self.t0) / self.period:.3g} periods)")
        return f"grows x{self.factor_at(upto):.3g} by t = {upto:.4g}"

    def reason(self, target: float) -> str:
        """How a rounding of the state grows up to the horizon of ``target`` (or over the
        span measured, where it stays below ``target``)."""
        h = self.horizon(target)
        grown = self.rate_text(self.measured_to if h is None else h)
        tail = f", below {target:g}" if h is None else f" and reaches {target:g} there"
        return f"a {INITIAL_ROUNDING:g} rounding of the state {grown} along the reference{tail}"

    def text(self, target: float) -> str:
        """Why no double-precision run keeps ``target`` past the horizon (or how far the
        growth was measured without reaching it)."""
        h = self.horizon(target)
        if h is None:
            return self.reason(target)
        return f"{self.reason(target)}: no double-precision run keeps {target:g} past t = {h:.4g}"


# measured growths of this process, by problem identity, initial state and span
_MEASURED: dict[tuple, Growth] = {}


def measure(problem: Problem, horizon: float, budget_s: float = GROWTH_BUDGET_S) -> Growth:
    """The growth of a perturbation on ``problem`` from its initial state over
    ``growth_span(problem, horizon)`` (cached). Raises ValueError for a problem without a
    heyoka system, ReferenceUnavailable where its compile passes the budget."""
    return _growth(problem, growth_span(problem, horizon), budget_s, cached_only=False)  # type: ignore[return-value]


def measured(problem: Problem, horizon: float) -> Growth | None:
    """The growth of a perturbation on ``problem`` over the longest span (``growth_span`` of
    a horizon up to ``horizon``) that is measured already, in this process or cached on disk
    (by ``recommend``, the checks of a main job): None where none is. It integrates nothing:
    for a reader, such as the results page's winner maps, that must not wait for a run."""
    spans, k, base = [], 0, float(problem.default_t_final)
    while base * 10.0**k <= horizon * (1 + 1e-9) or not spans:
        spans += [base * step * 10.0**k for step in SPAN_STEPS]
        k += 1
    for span in sorted({s for s in spans if s <= growth_span(problem, horizon)}, reverse=True):
        growth = _growth(problem, span, 0.0, cached_only=True)
        if growth is not None:
            return growth
    return None


def _growth(problem: Problem, span: float, budget_s: float, cached_only: bool) -> Growth | None:
    """The growth over ``span`` (measured within ``budget_s``; never None unless
    ``cached_only``, where it is None if neither this process nor the disk holds it)."""
    from longtime.measure import lyapunov

    key = (problem.identity(), problem.u0.tobytes(), span)
    if key not in _MEASURED:
        if cached_only and problem.heyoka_system is None:
            return None
        logs = lyapunov.separations(problem, span, budget_s, cached_only=cached_only)
        if logs is None:
            return None
        logs = np.asarray(logs, dtype=float)
        t = problem.t0 + span * np.arange(1, logs.size + 1) / logs.size
        period = getattr(problem, "period", None)
        _MEASURED[key] = Growth(problem.name, t, np.cumsum(logs), float(problem.t0),
                                float(period) if period and np.isfinite(period) else None)
    return _MEASURED[key]
