"""The verdict: which setting (scheme and step or tolerance) keeps a target error up to a
horizon T at the least cost, predicted from what each stored setting measured.

A setting is one scheme and its parameters; its longest usable run gives its error and law,
all its runs' lengths its cost model. Up to its run's final time t_f its error at T is the
error reached by T (read on its ``error_curve``: never an average over a different span).
Past t_f, with the growth law fitted to it (longtime.measure.growth),

    e(T) = e(t_f) (T / t_f)^k     (class sqrt, linear or quadratic: k = 1/2, 1, 2)
    e(T) = e(t_f)                 (class bounded: flat)

with k the exponent of the class, not the fitted alpha: the law is the class, whose windows
agree on it, not the digits of a fit that still carries the run's transient. A class is
trusted only up to ``TRUST_FACTORS[kind][class]`` times that run's span (its ``reach``;
kind: a solution error, one whose energy drift will steepen it, a chaotic problem's, or an
invariant's error), not past the run where its windows' slopes are steepening, and at most
as far as its latest window's slope would move the prediction by CHECK_ERROR_FACTOR. An
undetermined law whose windows' slopes do not rise is bounded by its steepest slope for
BOUND_FACTOR times its run. Past its reach a setting predicts nothing: where it could have
won, the verdict says "not determined past t = X" and names the run that would decide it. A
predicted error of ``LOST`` or more is O(1): ``lost``, not a number.

On a chaotic problem (rows with a Lyapunov time) no pointwise error is predicted past the
predictability horizon of the target E, lyapunov_time * ln(E / INITIAL_ROUNDING), at most
the reference's trusted horizon (``predictability``): the answer there is "no
double-precision scheme keeps a pointwise error of E past t = X" with the reason, and the
ensembles' statistical answer where the store has them.

The predicted cost is ``CostModel.at(T)``: fixed + per-time parts fitted on runs of two
lengths of the setting (set-up and dense-output sampling apart from the stepping), else
per-time from one run; each prediction says which.

The error read is the solution error ``l2_error`` (the RMS error over [0, T] relative to the
motion, longtime.measure.metrics; law ``error.growth_class``) where the problem's rows have
a reference, else the energy error ``H.max`` (law ``H.growth_class``), else the first
invariant's: ``measure`` says which. Predictions are checked: the main job re-runs groups of
them, a winner with its runner-up and open rivals so that the rank is tested, covering
every class of problem it ran (``plan_checks``, ``run_checks``), and stores the predicted
beside the measured error and cost (``Store.add_check``).
"""
from __future__ import annotations

import contextlib
import math
import shlex
import time
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, Iterable

import numpy as np
from longtime.core.fmt import positive
from longtime.core.params import InputError
from longtime.core.roles import ROW_PARAMETERS, flag
from longtime.measure.growth import SATURATION
from longtime.reporting.rowtext import main_t_final, setting

# classes whose exponent extrapolates past the run (a power law), and the flat one
POWER_LAWS = ("sqrt", "linear", "quadratic")
EXPONENTS = {"bounded": 0.0, "sqrt": 0.5, "linear": 1.0, "quadratic": 2.0}
FLAT = ("bounded",)
# how far each class is trusted, for a solution error and for an invariant's: up to this
# many times its run's span (t_final - t0), read from settings re-run at 10, 100 and 1000
# times their span (benchmarks/verdict_reach.py; the table is in docs/metrics.md, "How far a
# class is trusted"). A power law held within x3 up to 1000 times the run wherever its
# prediction stayed below LOST. A solution error classed bounded or sqrt can be the transient
# before a phase error grows (at least linearly; round-off's phase walks like t^1.5): some
# held to 100 times the run, others were off by 3 to 40 at 10 times, so neither class of a
# solution error is extrapolated. An invariant's bounded or sqrt error held to 1000 times.
# A solution error growing like t^k whose setting lets the energy drift like t^a with
# k < 1 + a is trusted ten times its run only: a drifting energy moves the frequencies, and
# the phase error then turns to t^(1 + a) (the quadratic growth of a non-symplectic method's
# error on an integrable system) at a time its run need not show (rk4 on the rigid body:
# linear to t = 1e3, off by 2.1 at 1e4 and by 14 at 1e5).
TRUST_FACTORS = {
    "solution": {"bounded": 1.0, "sqrt": 1.0, "linear": 1000.0, "quadratic": 1000.0},
    "drifting": {"bounded": 1.0, "sqrt": 1.0, "linear": 10.0, "quadratic": 10.0},
    "invariant": {"bounded": 1000.0, "sqrt": 1000.0, "linear": 1000.0, "quadratic": 1000.0},
    # a solution error on a problem with a measured Lyapunov time grows exponentially: no
    # power law extrapolates it past its run
    "chaotic": {"bounded": 1.0, "sqrt": 1.0, "linear": 1.0, "quadratic": 1.0},
}
# the energy error classes that drift, and their exponents a
DRIFTS = {"linear": 1.0, "quadratic": 2.0, "faster": math.inf, "saturated": math.inf, "diverged": math.inf}
# a class is trusted past its run only where its last decades agree with it: windows' slopes
# (longtime.measure.growth) that rise from each to the next and end more than this above the
# class's exponent are steepening (an energy drift feeding a phase error, a bounded error
# giving way to a phase error's growth): not extrapolated. Otherwise the reach is also at
# most where the latest window's slope, if it held, would move the prediction by
# CHECK_ERROR_FACTOR
STEEPENING = 0.1
# an undetermined law whose window slopes do not rise is bounded by its steepest slope over
# this many times its run (Setting.bound_exponent)
BOUND_FACTOR = 10.0
# a predicted relative error this large is O(1) (the growth fit's saturation): lost
LOST = SATURATION
# targets of the winner map: the decades 1e-1 .. 1e-14
TARGETS = tuple(10.0 ** -k for k in range(1, 15))
# horizons of the winner map: the problem's main final time times these (integer multiples
# keep the phase of a periodic orbit, as the check runs do)
HORIZON_FACTORS = tuple(10**k for k in range(0, 7))
# the predictions the main job re-runs, and each one's predicted CPU budget (seconds)
CHECKS = 6
CHECK_BUDGET_S = 3.0
# a check's heyoka reference (to a horizon past the runs', so not cached) gets this many
# seconds of wall time: it is trusted as far as it got, and a check whose reference stops
# short of the horizon is not judged
CHECK_REFERENCE_S = 10.0
# what a check must meet to count as confirmed: error within this factor, cost within that
CHECK_ERROR_FACTOR = 3.0
CHECK_COST_FACTOR = 1.5
# the relative rounding of a double initial state: on a chaotic problem it grows e-fold each
# Lyapunov time, so a pointwise error E is kept at most lyapunov_time * ln(E / INITIAL_ROUNDING)
INITIAL_ROUNDING = 1e-16
# ``longtime recommend``'s exit code where the store determines no answer (no setting is
# predicted to keep the target, or no pointwise answer exists): the answer names why and the
# run that would decide it (2 stays bad input)
NO_ANSWER_EXIT = 3


@dataclass
class Measure:
    """The error a problem's verdict reads: ``field`` of the rows, the growth law ``law``
    (``LAW.growth``, ``LAW.growth_class``) and words for a reader."""
    field: str
    law: str
    text: str


def measure(rows: Iterable[dict[str, Any]]) -> Measure | None:
    """The solution error where ok rows have one and its growth class, else H's drift, else
    the first invariant's with a growth class; None when no ok row has any."""
    ok = [r for r in rows if r.get("status") == "ok"]
    if any(positive(r.get("l2_error")) and r.get("error.growth_class") for r in ok):
        ref = next((r.get("reference") for r in ok if r.get("reference")), None)
        return Measure("l2_error", "error", f"the RMS error of the solution over [0, T] relative to its motion, "
                                            f"against the {'exact solution' if ref == 'exact' else 'reference'}")
    names = [k[: -len(".growth_class")] for r in ok for k in r if k.endswith(".growth_class")
             and r.get(k) and k != "error.growth_class" and positive(r.get(k[: -len(".growth_class")] + ".max"))]
    if not names:
        return None
    name = "H" if "H" in names else names[0]
    return Measure(f"{name}.max", name, f"the largest relative error of {name} up to T; no reference "
                                        f"solution")


@dataclass
class Setting:
    """One stored row as a candidate: its measured error and cost, and its law."""
    row: dict[str, Any] = field(repr=False)
    error: float  # measured at t_final
    span: float  # t_final - t0 of its run (the rows' t_final: t0 is 0 for every problem)
    cpu_per_t: float
    law: str  # the growth class
    alpha: float | None  # the fitted exponent (evidence; a prediction uses the class's)
    ci: tuple[float, float] | None
    reason: str
    # the error's kind: "solution" (l2_error), "drifting" (l2_error of a setting whose
    # energy drift will steepen it, see TRUST_FACTORS) or "invariant" (NAME.max)
    kind: str = "solution"
    windows: tuple[float, ...] = ()  # the slopes of the growth fit's windows, earliest first
    # the error reached up to each time of its run, (t, error) earliest first: the row's
    # error_curve (l2_error up to t) or its invariant's envelope (running maximum); () for a
    # row stored without it
    curve: tuple[tuple[float, float], ...] = ()
    cost: "CostModel | None" = None  # CPU seconds against T (default: per-time, from this run)
    lost_at: float = math.inf  # the span of a longer run of the same setting that lost the solution

    @property
    def scheme(self) -> str:
        return self.row["integrator"]

    # text and factor are read for every cell of the winner map: computed once (a Setting is
    # not changed once made)
    @cached_property
    def text(self) -> str:
        return " ".join(x for x in (self.scheme, setting(self.row)) if x)

    @property
    def steepening(self) -> bool:
        """Whether its windows' slopes rise from each to the next and end more than
        STEEPENING above its class's exponent: the law is still changing."""
        return self.law in EXPONENTS and _rising(self.windows) and self.windows[-1] - EXPONENTS[self.law] > STEEPENING

    @cached_property
    def factor(self) -> float:
        """How many times its run's span its class is trusted (1: not past its run): its
        class's TRUST_FACTORS, 1 where its slopes are steepening, and at most the factor
        over which its latest window's slope would move the prediction by
        CHECK_ERROR_FACTOR."""
        if self.bound_exponent is not None:
            return BOUND_FACTOR
        base = TRUST_FACTORS[self.kind].get(self.law, 1.0)
        if base <= 1 or not self.windows:
            return base
        if self.steepening:
            return 1.0
        off = abs(self.windows[-1] - EXPONENTS[self.law])
        if off * math.log(base) <= math.log(CHECK_ERROR_FACTOR):
            return base
        return math.exp(math.log(CHECK_ERROR_FACTOR) / off)

    @cached_property
    def bound_exponent(self) -> float | None:
        """For an undetermined law whose window slopes (two at least) do not rise from each
        to the next: its steepest window's slope (at least 1 for a solution error, whose
        phase error grows at least linearly), an upper bound of its growth over a decade
        past its run (BOUND_FACTOR); None otherwise (and on a chaotic problem)."""
        if self.law != "undetermined" or len(self.windows) < 2 or _rising(self.windows) or self.kind == "chaotic":
            return None
        return max(max(self.windows), 1.0 if self.kind != "invariant" else 0.0)

    @property
    def exponent(self) -> float | None:
        """The exponent its error is extrapolated with: its class's, or its bound's."""
        return EXPONENTS.get(self.law, self.bound_exponent)

    @property
    def extrapolates(self) -> bool:
        return self.exponent is not None and self.factor > 1

    @property
    def reach(self) -> float:
        """The horizon up to which its error is determined: its run's span times its
        class's trust factor."""
        return self.span * self.factor

    def error_reached(self, horizon: float) -> float:
        """The error measured up to ``horizon`` within its run: read on its error curve (the
        larger of the two curve points around ``horizon``), else the error of its whole run."""
        if not self.curve or horizon >= self.span * (1 - 1e-9):
            return self.error
        after = next((k for k, (t, _) in enumerate(self.curve) if t >= horizon * (1 - 1e-9)), None)
        if after is None:
            return self.error
        return max(self.curve[after][1], self.curve[after - 1][1] if after > 0 else 0.0)

    def state_at(self, horizon: float) -> str:
        """What it says of its error at ``horizon``: "measured" (within its run),
        "predicted" (its class, within its reach), "lost" (a predicted error of LOST or
        more: O(1)) or "undetermined" (past its reach)."""
        if horizon >= self.lost_at * (1 - 1e-9):
            return "lost"
        if horizon <= self.span * (1 + 1e-9):
            return "measured"
        if not self.extrapolates or horizon > self.reach * (1 + 1e-9):
            return "undetermined"
        return "lost" if self._law_at(horizon) >= LOST else "predicted"

    def _law_at(self, horizon: float) -> float:
        return self.error * (horizon / self.span) ** self.exponent

    def error_at(self, horizon: float) -> float | None:
        """The measured or predicted error at ``horizon`` (None: undetermined there, or lost)."""
        state = self.state_at(horizon)
        if state == "measured":
            return self.error_reached(horizon)
        return self._law_at(horizon) if state == "predicted" else None

    def cpu_at(self, horizon: float) -> float:
        """Its predicted CPU seconds to ``horizon`` (its cost model)."""
        return (self.cost or CostModel(0.0, self.cpu_per_t, "per-time", (self.span,))).at(horizon)

    def law_text(self) -> str:
        if self.extrapolates:
            reach = f", trusted to t = {self.reach:.4g}" + (", the energy drifts" if self.kind == "drifting" else "")
        elif self.steepening:
            reach = (f", not trusted past its run (window slopes {', '.join(f'{w:.2f}' for w in self.windows)} "
                     f"rise past t^{EXPONENTS[self.law]:g})")
        elif self.kind == "chaotic":
            reach = (f", not trusted past its run (a chaotic problem: Lyapunov time "
                     f"{self.row['lyapunov_time']:.3g}, the error grows exponentially)")
        else:
            reach = f", not trusted past its run (a solution error's {self.law} class)"
        if self.law in FLAT:
            return "bounded: flat" + reach
        if self.law in POWER_LAWS:
            fit = f", alpha {self.alpha:.2f}" if self.alpha is not None else ""
            ci = f" [{self.ci[0]:.2f}, {self.ci[1]:.2f}]" if self.ci and fit else ""
            return f"{self.law}: t^{EXPONENTS[self.law]:g}{fit}{ci} fitted" + reach
        if self.bound_exponent is not None:
            return (f"at most t^{self.bound_exponent:.2f} (its steepest window; {self.law}: {self.reason})" + reach)
        return f"{self.law}: {self.reason}" if self.reason else self.law

    def undetermined_text(self, horizon: float) -> str:
        """Why it predicts nothing at ``horizon``: its law, or its law's reach."""
        if self.extrapolates:
            return (f"its law ({self.law}) is not determined past t = {self.reach:.4g} "
                    f"({self.factor:g} times its run)")
        return f"its growth is {self.law_text()}"


@dataclass(frozen=True)
class CostModel:
    """CPU seconds to a horizon T: ``fixed + per_t * T``. ``basis`` says which model:
    "fixed + per-time" (fitted by least squares on runs of at least two lengths of the same
    setting, ``spans``: set-up and dense-output sampling, whose count does not grow with T,
    apart from the stepping), or "per-time" (one run's CPU over its span: its fixed costs
    are scaled with T too, an upper bound past the run)."""
    fixed: float
    per_t: float
    basis: str
    spans: tuple[float, ...]

    def at(self, horizon: float) -> float:
        return self.fixed + self.per_t * horizon

    def text(self) -> str:
        runs = ", ".join(f"{t:.4g}" for t in self.spans)
        if self.basis == "per-time":
            return f"per-time, from one run to t = {runs}"
        return f"{self.fixed:.3g} s fixed + {self.per_t:.3g} s per unit time, fitted on runs to t = {runs}"


def cost_model(runs: list[tuple[float, float]]) -> CostModel:
    """The CostModel of one setting from its runs' (span, cpu_s): fixed + per-time where
    they span two lengths (a factor 2 at least) and the fit gives a positive per-time part
    and a fixed part >= 0; else per-time from the longest run."""
    spans = sorted({t for t, _ in runs})
    longest = max(runs)
    if len(spans) >= 2 and spans[-1] >= 2 * spans[0]:
        t = np.array([x for x, _ in runs])
        c = np.array([y for _, y in runs])
        per_t, fixed = np.polyfit(t, c, 1)
        if per_t > 0 and fixed >= 0:
            return CostModel(float(fixed), float(per_t), "fixed + per-time", tuple(spans))
        if per_t > 0:  # a fit with a negative fixed part: the timing noise of the short run
            return CostModel(0.0, longest[1] / longest[0], "per-time", (longest[0],))
    return CostModel(0.0, longest[1] / longest[0], "per-time", (longest[0],))


def _curve(row: dict[str, Any], m: Measure) -> tuple[tuple[float, float], ...]:
    """The error reached up to each time of the row's run, (t, error) earliest first: its
    error_curve's l2 (the l2_error up to t) for the solution error, the running maximum of
    the invariant's envelope for NAME.max; () where the row keeps none."""
    t0 = 0.0  # the curves' times are t - t0
    if m.field == "l2_error":
        c = row.get("error_curve")
        if isinstance(c, dict) and c.get("l2"):
            return tuple((t0 + float(t), float(e)) for t, e in zip(c["t"], c["l2"]))
        return ()
    name = m.field[: -len(".max")]
    for c in row.get("drift_curves") or ([row["drift_curve"]] if row.get("drift_curve") else []):
        if isinstance(c, dict) and c.get("invariant") == name:
            running = np.maximum.accumulate(np.asarray(c["error"], dtype=float))
            return tuple((t0 + float(t), float(e)) for t, e in zip(c["t"], running))
    return ()


def settings(rows: Iterable[dict[str, Any]], m: Measure) -> list[Setting]:
    """The candidates of one problem's rows: ok rows that kept the solution, with the
    measured error, a CPU time, a final time and a growth class; one per setting (scheme and
    parameters), its longest run, with a cost model from all its runs' lengths."""
    rows = [r for r in rows if r.get("status") == "ok" and not r.get("check_of")
            and positive(r.get("cpu_s")) and positive(r.get("t_final"))]
    by_setting: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for r in rows:
        by_setting.setdefault((r["integrator"], setting(r)), []).append(r)
    def usable(r: dict[str, Any]) -> bool:
        law = r.get(f"{m.law}.growth_class")
        return (not r.get("solution_lost") and positive(r.get(m.field)) and bool(law)
                and law not in ("saturated", "diverged"))

    costs = {k: cost_model([(float(r["t_final"]), float(r["cpu_s"])) for r in v]) for k, v in by_setting.items()}
    out = []
    for key, runs in by_setting.items():
        kept = [r for r in runs if usable(r)]
        if not kept:
            continue
        r = max(kept, key=lambda r: (r["t_final"], r.get("run_id") or 0))
        # a longer run of the setting that lost the solution (or saturated): lost from there on
        lost_at = min((float(x["t_final"]) for x in runs if not usable(x) and x["t_final"] > r["t_final"]
                       and (x.get("solution_lost") or x.get(f"{m.law}.growth_class") in ("saturated", "diverged"))),
                      default=math.inf)
        err, cpu, span = r.get(m.field), r.get("cpu_s"), r.get("t_final")
        law = r.get(f"{m.law}.growth_class")
        alpha = r.get(f"{m.law}.growth")
        ci = r.get(f"{m.law}.growth_ci")
        reason = str(r.get(f"{m.law}.growth_reason") or "")
        windows = r.get(f"{m.law}.growth_windows")
        if law == "faster":
            reason = f"faster than t^2.5 (alpha {alpha:.2f}): no power law of the run's span is extrapolated"
        out.append(Setting(r, float(err), float(span), float(cpu) / float(span), str(law),
                           float(alpha) if isinstance(alpha, (int, float)) else None,
                           (float(ci[0]), float(ci[1])) if isinstance(ci, list) and len(ci) == 2
                           and all(isinstance(c, (int, float)) for c in ci) else None, reason,
                           _kind(r, m, str(law)),
                           tuple(float(w) for w in windows) if isinstance(windows, list)
                           and all(isinstance(w, (int, float)) for w in windows) else (),
                           _curve(r, m), costs[key], lost_at))
    return sorted(out, key=lambda s: (s.cpu_per_t, s.text))


def _rising(windows) -> bool:
    """Whether growth windows' slopes (earliest first, at least two) rise from each to the next."""
    return len(windows) >= 2 and all(b > a for a, b in zip(windows, windows[1:]))


def _kind(row: dict[str, Any], m: Measure, law: str) -> str:
    """"invariant" for an invariant's error; for the solution error of class ``law`` (t^k)
    "drifting" where the row's energy error drifts like t^a (DRIFTS; an undetermined one
    whose window slopes rise past 0.25: a its latest slope) with k < 1 + a, else
    "solution"."""
    if m.field != "l2_error":
        return "invariant"
    if positive(row.get("lyapunov_time")):
        return "chaotic"
    a = DRIFTS.get(row.get("H.growth_class"))
    w = row.get("H.growth_windows")
    if a is None and row.get("H.growth_class") == "undetermined" and isinstance(w, list) \
            and all(isinstance(x, (int, float)) for x in w) and _rising(w) and w[-1] > 0.25:
        a = float(w[-1])  # an energy error still steepening grows at least like its latest slope
    return "drifting" if a is not None and law in EXPONENTS and EXPONENTS[law] < 1 + a else "solution"


@dataclass
class Decision:
    """The verdict for one target and horizon: ``best`` (None: no setting is predicted to
    keep the target), its predicted error and cost, the runner-up of another scheme, and
    ``open``: cheaper settings whose law is undetermined past their run but whose measured
    error keeps the target, each with the run that would decide it."""
    target: float
    horizon: float
    best: Setting | None = None
    runner_up: Setting | None = None
    open: list[Setting] = field(default_factory=list)
    # past a chaotic problem's predictability horizon: that horizon and why (no pointwise answer)
    limit: Predictability | None = None

    @property
    def state(self) -> str:
        if self.limit is not None:
            return "chaotic"
        if self.best is not None:
            return "predicted"
        return "undetermined" if self.open else "none"


@dataclass(frozen=True)
class Predictability:
    """How far a pointwise error ``target`` can be kept on a chaotic problem: ``horizon`` =
    min(lyapunov_time * ln(target / INITIAL_ROUNDING), the reference's trusted horizon), and
    the reason in words."""
    target: float
    horizon: float
    lyapunov_time: float | None
    reference_horizon: float | None

    @property
    def reason(self) -> str:
        parts = []
        if self.lyapunov_time is not None:
            parts.append(f"Lyapunov time {self.lyapunov_time:.3g}: a rounding of {INITIAL_ROUNDING:g} in the initial "
                         f"state grows e-fold each {self.lyapunov_time:.3g} and reaches {self.target:g} by t = "
                         f"{self.lyapunov_time * math.log(self.target / INITIAL_ROUNDING):.3g}")
        if self.reference_horizon is not None:
            parts.append(f"the reference is trusted only up to t = {self.reference_horizon:.4g}")
        return "; ".join(parts)

    def text(self) -> str:
        return (f"no double-precision scheme keeps a pointwise error of {self.target:g} past t = "
                f"{self.horizon:.4g} ({self.reason})")


def predictability(rows: Iterable[dict[str, Any]], target: float) -> Predictability | None:
    """The predictability horizon of ``target`` on the problem of ``rows`` (one problem's),
    where its rows carry a measured Lyapunov time or a chaotic problem's reference horizon
    (``lyapunov_time`` set, even null): None for a problem that is not chaotic."""
    mine = [r for r in rows if "lyapunov_time" in r]
    if not mine:
        return None
    times = [float(r["lyapunov_time"]) for r in mine if positive(r.get("lyapunov_time"))]
    t_l = min(times) if times else None
    # the reference's trusted horizon where a row's check found its end before the row's t_final
    ends = [float(r["reference_horizon"]) for r in mine if positive(r.get("reference_horizon"))
            and r["reference_horizon"] < float(r.get("t_final") or 0) * (1 - 1e-9)]
    ref = min(ends) if ends else None
    bounds = [b for b in ((t_l * math.log(target / INITIAL_ROUNDING)) if t_l is not None and target > INITIAL_ROUNDING
                          else (0.0 if t_l is not None else None), ref) if b is not None]
    if not bounds:
        return None
    return Predictability(target, min(bounds), t_l, ref)


def decide(candidates: list[Setting], target: float, horizon: float,
           limit: Predictability | None = None) -> Decision:
    """The cheapest candidate predicted to keep ``target`` up to ``horizon``; the runner-up
    is the cheapest of another scheme; ``open`` the undetermined ones cheaper than the best
    (or any, without a best) that keep the target over their own run. Past ``limit`` (a
    chaotic problem's predictability horizon of ``target``) nothing is predicted."""
    if limit is not None and horizon > limit.horizon * (1 + 1e-9):
        return Decision(target, horizon, limit=limit)
    keeps = [s for s in candidates if (e := s.error_at(horizon)) is not None and e <= target]
    keeps.sort(key=lambda s: (s.cpu_at(horizon), s.text))
    best = keeps[0] if keeps else None
    runner = next((s for s in keeps if best is not None and s.scheme != best.scheme), None)
    cap = best.cpu_per_t if best is not None else math.inf
    open_ = [s for s in candidates if s.state_at(horizon) == "undetermined" and s.error <= target
             and s.cpu_per_t < cap]
    # one per scheme, the cheapest: the run that decides it is named once
    seen, unique = set(), []
    for s in sorted(open_, key=lambda s: (s.cpu_per_t, s.text)):
        if s.scheme not in seen:
            seen.add(s.scheme)
            unique.append(s)
    return Decision(target, horizon, best, runner, unique)


def deciding_run(s: Setting, horizon: float, db: str | None = None) -> str:
    """The command that would measure ``s``'s law up to ``horizon`` (at least a decade past
    its run: a growth law needs 1.5 decades of t past the early transient)."""
    return shlex.join(run_command(s, max(horizon, 10 * s.span), db))


def run_command(s: Setting, t_final: float, db: str | None = None) -> list[str]:
    """``longtime run`` of ``s``'s setting to ``t_final``, as arguments: the row's parameters
    that its scheme takes (a recorded one it does not, heyoka's order, is left out), its
    other settings."""
    from longtime.core import registry

    row = s.row
    try:
        takes = set(registry.integrator_class(row["integrator"]).parameters)
    except Exception:  # a scheme no longer registered: every recorded parameter
        takes = set(ROW_PARAMETERS)
    parts = ["longtime", "run", "-p", row["problem"], "-i", row["integrator"]]
    for k in ROW_PARAMETERS:
        v = row.get(k)
        if positive(v) and k in takes:
            parts += [flag(k), f"{int(v)}" if k == "order" else f"{v:g}"]
    if row.get("settings"):
        import json

        for k, v in json.loads(row["settings"]).items():
            parts += ["--set", f"{k}={v}"]
    parts += ["--t-final", f"{t_final:g}"]
    if db:
        parts += ["--db", db]
    return parts


# ------------------------------------------------------------------ a problem's verdict
@dataclass
class Verdict:
    """One problem's verdict: the measure, the candidates, the winner map (decisions per
    target and horizon), the stored checks of its predictions."""
    problem: str
    measure: Measure | None
    candidates: list[Setting]
    t_main: float | None
    targets: tuple[float, ...] = ()
    horizons: tuple[float, ...] = ()
    grid: dict[tuple[float, float], Decision] = field(default_factory=dict)
    checks: list[dict[str, Any]] = field(default_factory=list)

    def reachable_targets(self) -> list[float]:
        """The targets some decision of the map predicts or leaves open (the rest: none)."""
        return [t for t in self.targets if any(self.grid[(t, h)].state != "none" for h in self.horizons)]


def problem_verdict(problem: str, rows: list[dict[str, Any]], checks: Iterable[dict[str, Any]] = ()) -> Verdict:
    mine = [r for r in rows if r.get("problem") == problem]
    m = measure(mine)
    t_main = main_t_final(mine)
    if m is None or t_main is None:
        return Verdict(problem, m, [], t_main)
    cands = settings(mine, m)
    horizons = tuple(t_main * f for f in HORIZON_FACTORS)
    grid = {(t, h): decide(cands, t, h, predictability(mine, t) if m.field == "l2_error" else None)
            for t in TARGETS for h in horizons}
    v = Verdict(problem, m, cands, t_main, TARGETS, horizons, grid,
                [c for c in checks if c.get("problem") == problem])
    keep = v.reachable_targets()
    if keep:  # the map spans the targets some setting reaches, and one decade past them
        lo = TARGETS.index(keep[-1])
        v.targets = TARGETS[TARGETS.index(keep[0]): lo + 2]
        v.grid = {k: d for k, d in grid.items() if k[0] in v.targets}
    return v


def verdicts(rows: list[dict[str, Any]], checks: Iterable[dict[str, Any]] = ()) -> dict[str, Verdict]:
    checks = list(checks)
    return {p: problem_verdict(p, rows, checks) for p in sorted({r["problem"] for r in rows})}


# ------------------------------------------------------------------ recommend
@dataclass
class Recommendation:
    """``longtime recommend``'s answer: the decision and its evidence, as lines."""
    problem: str
    error: float
    horizon: float
    measure: Measure | None
    decision: Decision
    evidence: dict[str, Any]
    lines: list[str]
    answered: bool = True  # False: the store determines no answer (the lines say why)

    @property
    def scheme(self) -> str | None:
        return self.decision.best.scheme if self.decision.best else None

    @property
    def setting(self) -> str | None:
        return setting(self.decision.best.row) if self.decision.best else None

    @property
    def predicted_error(self) -> float | None:
        b = self.decision.best
        return b.error_at(self.horizon) if b else None

    @property
    def predicted_cpu_s(self) -> float | None:
        b = self.decision.best
        return b.cpu_at(self.horizon) if b else None

    @property
    def runner_up(self) -> str | None:
        r = self.decision.runner_up
        return r.text if r else None

    def __str__(self) -> str:
        return "\n".join(self.lines)


def _pick(s: Setting, horizon: float) -> str:
    e = s.error_at(horizon)
    if horizon <= s.span * (1 + 1e-9):
        how = f"reached by t = {horizon:.4g} in its run to t = {s.span:.4g}"
        how += "" if s.curve else " (no curve: the run's)"
    else:
        how = f"{s.law_text()}; {s.error:.2g} measured at t = {s.span:.4g}"
    cost = s.cost.text() if s.cost else "per-time"
    return f"{s.text}: error {e:.2g} at T ({how}), CPU {s.cpu_at(horizon):.3g} s ({cost})"


def recommend(rows: list[dict[str, Any]], problem: str, error: float, horizon: float,
              db: str | None = None, known: Iterable[str] | None = None,
              checks: Iterable[dict[str, Any]] = (), ensembles: Iterable[dict[str, Any]] = ()) -> Recommendation:
    """The cheapest setting predicted to keep ``error`` up to ``horizon`` on ``problem``
    from ``rows`` (a store's), with the runner-up and the evidence. Bad input (an unknown
    problem, a non-positive error or horizon) raises InputError. Rows that determine no
    answer give a Recommendation whose ``answered`` is False and whose lines say why and name
    the command that would decide it: no rows, no setting predicted to keep the target, or a
    horizon past a chaotic problem's predictability horizon (no pointwise answer; the
    ensemble distances of ``ensembles`` where the store has them)."""
    known = list(known) if known is not None else None
    where = f" --db {shlex.quote(db)}" if db else ""
    if known is not None and problem not in known:
        raise InputError(f"-p {problem}: unknown problem; known: {', '.join(sorted(known))}")
    for name, value in (("--error", error), ("--horizon", horizon)):
        if not positive(value):
            raise InputError(f"{name} {value}: must be a finite number > 0")
    mine = [r for r in rows if r.get("problem") == problem]

    def unanswered(why: str, m: Measure | None = None, d: Decision | None = None) -> Recommendation:
        return Recommendation(problem, error, horizon, m, d or Decision(error, horizon), {},
                              [f"{problem}: no answer for {m.field if m else 'the error'} <= {error:g} up to T = "
                               f"{horizon:g}: {why}"], answered=False)

    if not mine:
        return unanswered(f"no rows of {problem} in the store; `longtime matrix -p {problem}{where}` measures them")
    m = measure(mine)
    cands = settings(mine, m) if m else []
    if m is None or not cands:
        return unanswered(f"no ok row of {problem} with an error, a growth class and a CPU time in the store; "
                          f"`longtime matrix -p {problem}{where}` measures them", m)
    limit = predictability(mine, error) if m.field == "l2_error" else None
    d = decide(cands, error, horizon, limit)
    if d.limit is not None:
        rec = unanswered(d.limit.text(), m, d)
        rec.lines += _statistical_lines(problem, ensembles, where)
        return rec
    if d.best is None:
        if d.open:
            s = d.open[0]
            return unanswered(f"no setting is predicted to keep it; {s.text} keeps it to t = {s.span:.4g} but "
                              f"{s.undetermined_text(horizon)}; `{deciding_run(s, horizon, db)}` would decide it", m, d)
        finest = min(cands, key=lambda s: s.error)
        lost = sum(1 for s in cands if s.state_at(horizon) == "lost")
        lost_text = (f"; {lost} setting{'s' if lost != 1 else ''} predicted lost there (error >= {LOST:g})"
                     if lost else "")
        return unanswered(f"no stored setting keeps {m.field} <= {error:g} up to T = {horizon:g} (the smallest "
                          f"measured is {finest.error:.2g}, {finest.text}, at t = {finest.span:.4g}{lost_text}); "
                          f"smaller steps or tolerances would: `longtime matrix -p {problem} -i {finest.scheme} "
                          f"--t-final {finest.span:g}{where}` with a finer sweep (--dt or --tol)", m, d)
    b, r = d.best, d.runner_up
    lines = [f"{problem}: keep {m.field} <= {error:g} up to T = {horizon:g} ({m.text}):",
             f"  use      {_pick(b, horizon)}"]
    lines.append(f"  runner-up {_pick(r, horizon)}, x{r.cpu_at(horizon) / b.cpu_at(horizon):.3g} the CPU"
                 if r else "  runner-up: none (no other scheme is predicted to keep the target)")
    for s in d.open[:2]:
        lines.append(f"  open     {s.text} might be cheaper ({s.cpu_at(horizon):.3g} s) but "
                     f"{s.undetermined_text(horizon)}: `{deciding_run(s, horizon, db)}` decides it")
    runs = sorted({c.row.get("run_id") for c in cands if c.row.get("run_id") is not None})
    mine_checks = [c for c in checks if c.get("problem") == problem]
    held = [c for c in mine_checks if check_holds(c)]
    determined = sum(1 for c in cands if c.extrapolates)
    lines.append(f"  evidence: {len(cands)} settings ({determined} with a growth law that extrapolates) from "
                 f"run{'s' if len(runs) != 1 else ''} {', '.join(map(str, runs)) or '-'}; "
                 + (f"{len(held)} of {len(mine_checks)} checked predictions held (error within x"
                    f"{CHECK_ERROR_FACTOR:g}, CPU within x{CHECK_COST_FACTOR:g})" if mine_checks
                    else "no prediction of this problem checked yet (`longtime matrix` checks a few)"))
    evidence = {"settings": len(cands), "extrapolating": determined, "runs": runs,
                "checks": len(mine_checks), "checks_held": len(held)}
    return Recommendation(problem, error, horizon, m, d, evidence, lines)


def _statistical_lines(problem: str, ensembles: Iterable[dict[str, Any]], where: str) -> list[str]:
    """The statistical answer past the predictability horizon: the schemes whose ensemble
    distance to heyoka's is not told apart from the floor (longtime.measure.ensemble), or the
    command that measures them."""
    from longtime.measure.ensemble import distinguishable

    ok = [e for e in ensembles if e.get("problem") == problem and e.get("status") == "ok"
          and e.get("distance") is not None]
    if not ok:
        return [f"  statistically: no ensemble of {problem} in the store; `longtime ensemble -p {problem}{where}` "
                f"measures which schemes keep the distribution the orbit visits"]
    same = sorted((e for e in ok if distinguishable(e["distance"], e.get("floor")) is False),
                  key=lambda e: e["distance"])
    text = (", ".join(f"{e['integrator']} (distance {e['distance']:.2g}, floor {e['floor']:.2g})" for e in same)
            if same else "none of the measured schemes")
    return [f"  statistically: {text} keep{'s' if len(same) == 1 else ''} the distribution heyoka's ensemble visits"]


# ------------------------------------------------------------------ checking predictions
def check_holds(c: dict[str, Any]) -> bool | None:
    """Whether a stored check confirms its prediction. A "chaos" check: its measured error
    exceeds its target (no pointwise error is kept past the predictability horizon). A
    prediction ("best", "runner-up", or a check stored without a role): the measured error
    within CHECK_ERROR_FACTOR of the predicted and the measured CPU at most CHECK_COST_FACTOR
    times the predicted, and for the best its rank (``rank_held`` not False). None where the
    check measured no error, or made no prediction (an "open" rival)."""
    role = c.get("check_role")
    me = c.get("measured_error")
    if role == "chaos":
        return None if not positive(me) else bool(me > c["check_target"])
    if role == "open":
        return None
    pe, pc, mc = (c.get(k) for k in ("predicted_error", "predicted_cpu_s", "cpu_s"))
    if not (positive(pe) and positive(me) and positive(pc) and positive(mc)):
        return None
    held = (1 / CHECK_ERROR_FACTOR <= me / pe <= CHECK_ERROR_FACTOR) and mc <= CHECK_COST_FACTOR * pc
    return held and c.get("rank_held") is not False


@dataclass
class PlannedCheck:
    """One run of a check: ``setting`` re-run to ``horizon``. ``role``: "best" (the decision's
    winner: its predicted error and cost, and its rank), "runner-up" (its prediction), "open"
    (a cheaper setting whose law is undetermined: measured, so that the rank is tested) or
    "chaos" (the most accurate setting past the predictability horizon of ``target``: its
    error must exceed ``target`` there). ``group`` names the decision the runs test and
    ``kind`` the class of problem it covers (CHECK_KINDS)."""
    setting: Setting
    horizon: float
    measure: Measure
    role: str
    target: float
    group: str
    kind: str

    def predicted_cpu(self) -> float:
        return self.setting.cpu_at(self.horizon)


# the classes of problem the checks cover, each before a second check of any: a chaotic
# problem (its predictability horizon), a drift-dominated one (a state component that drifts,
# ``drifting_components``, or a solution error whose energy drifts), an adaptive
# scheme (heyoka, a tolerance), a splitting (a scheme that needs a separable H), the rest
CHECK_KINDS = ("chaotic", "drifting", "adaptive", "splitting", "other")
# the checks' total wall-time estimate (seconds): each run's predicted CPU times TIMED_RUNS
# (its warm-up and timed repeats) plus its reference's time to the horizon
CHECKS_TOTAL_S = 6.0
TIMED_RUNS = 4
# a chaos check runs past the predictability horizon by this many Lyapunov times (e^5: the
# pointwise error grows 150 times past the target)
CHAOS_MARGIN_LYAPUNOV = 5.0


def _group_kind(v: Verdict, runs: list[Setting]) -> str:
    from longtime.core import registry

    if any(s.kind == "drifting" or (s.row.get("drifting_components") or 0) > 0 for s in runs):
        return "drifting"  # an energy that drifts, or a state with a drifting component
    if any(positive(s.row.get("tol")) for s in runs):
        return "adaptive"
    for s in runs:
        with contextlib.suppress(Exception):
            if "separable" in getattr(registry.integrator_class(s.scheme), "requires", ()):
                return "splitting"
    return "other"


def _chaos_group(v: Verdict, rows: list[dict[str, Any]], budget_s: float) -> list[PlannedCheck]:
    """A check of a chaotic problem's predictability horizon: its most accurate setting, at
    the finest map target E that it keeps over its run and whose horizon lies past its run,
    re-run CHAOS_MARGIN_LYAPUNOV Lyapunov times past that horizon (within ``budget_s``)."""
    mine = [r for r in rows if r.get("problem") == v.problem]
    if v.measure is None or v.measure.field != "l2_error" or not v.candidates:
        return []
    s = min(v.candidates, key=lambda c: (c.error, c.cpu_per_t))
    for target in sorted(TARGETS):
        limit = predictability(mine, target)
        if limit is None or limit.lyapunov_time is None or target < 10 * s.error or limit.horizon <= s.span:
            continue
        h = limit.horizon + CHAOS_MARGIN_LYAPUNOV * limit.lyapunov_time
        if s.cpu_at(h) > budget_s:
            return []
        return [PlannedCheck(s, h, v.measure, "chaos", target, f"{v.problem} {target:g} chaos", "chaotic")]
    return []


def _decision_groups(v: Verdict, budget_s: float) -> list[list[list[PlannedCheck]]]:
    """Per setting the map names as the winner past its run (within its reach), its groups:
    at each horizon where it wins, the winner, its runner-up and its open rivals (at most
    two), within ``budget_s`` of predicted CPU together; the farthest horizon first (the
    planner takes the first that fits the checks' time)."""
    best: dict[int, list[list[PlannedCheck]]] = {}
    # at each horizon the decision with the most rivals first (the rank tested against most)
    for d in sorted(v.grid.values(), key=lambda d: (-d.horizon, -(d.runner_up is not None) - len(d.open[:2]),
                                                    d.target)):
        b = d.best
        if b is None or d.horizon <= b.span * (1 + 1e-9):
            continue
        if any(g[0].horizon == d.horizon for g in best.get(id(b), [])):
            continue
        runs = [(b, "best")] + ([(d.runner_up, "runner-up")] if d.runner_up else []) + [(o, "open") for o in d.open[:2]]
        if sum(x.cpu_at(d.horizon) for x, _ in runs) > budget_s:
            continue
        group = f"{v.problem} {d.target:g} T={d.horizon:g}"
        kind = _group_kind(v, [x for x, _ in runs])
        best.setdefault(id(b), []).append([PlannedCheck(x, d.horizon, v.measure, role, d.target, group, kind)
                                           for x, role in runs])
    return sorted(best.values(), key=lambda gs: (-gs[0][0].horizon / gs[0][0].setting.span, gs[0][0].setting.text))


def plan_checks(rows: list[dict[str, Any]], limit: int = CHECKS, budget_s: float = CHECK_BUDGET_S,
                reference_rate=None, total_s: float = CHECKS_TOTAL_S) -> list[PlannedCheck]:
    """The checks to run, as groups of runs (PlannedCheck): per problem, a chaos check where
    it is chaotic (``_chaos_group``) and its decisions' groups (``_decision_groups``: the
    winner with its runner-up and open rivals, each group's predicted CPU within
    ``budget_s``); at most ``limit`` groups whose estimated wall time (TIMED_RUNS times the
    predicted CPU, plus the reference: ``reference_rate(verdict)`` wall seconds per unit of
    t, default ``reference_seconds_per_t``) totals at most ``total_s``. Each class of
    problem (CHECK_KINDS) present gets a group before any class gets a second."""
    rate_of = reference_seconds_per_t if reference_rate is None else reference_rate
    pool: dict[str, list[list[PlannedCheck]]] = {k: [] for k in CHECK_KINDS}
    found = verdicts(rows)
    per_problem = []
    for v in found.values():
        if v.measure is None:
            continue
        groups = ([[g]] if (g := _chaos_group(v, rows, budget_s)) else []) + _decision_groups(v, budget_s)
        per_problem.append((v, groups))
    # round-robin over problems within each kind, so one problem does not take a kind's turns
    depth = max((len(g) for _, g in per_problem), default=0)
    for k in range(depth):
        for v, groups in per_problem:
            if k < len(groups):
                pool[groups[k][0][0].kind].append(groups[k])
    rates: dict[str, float] = {}
    out: list[PlannedCheck] = []
    chosen, spent = 0, 0.0
    while chosen < limit and any(pool.values()):
        for kind in CHECK_KINDS:
            if not pool[kind] or chosen >= limit:
                continue
            alternatives = pool[kind].pop(0)
            v = found[alternatives[0][0].setting.row["problem"]]
            if v.problem not in rates:
                started = time.perf_counter()
                rates[v.problem] = rate_of(v)
                spent += time.perf_counter() - started  # timing the reference is part of the checks' time
            for group in alternatives:  # the farthest horizon whose runs and reference fit
                reference = rates[v.problem] * group[0].horizon
                cost = TIMED_RUNS * sum(c.predicted_cpu() for c in group) + reference
                if math.isfinite(cost) and spent + cost <= total_s and reference <= CHECK_REFERENCE_S / 2:
                    out += group
                    chosen += 1
                    spent += cost
                    break
    return out


def reference_seconds_per_t(v: Verdict) -> float:
    """The wall seconds per unit of t that a check of ``v``'s problem spends on its
    reference: 0 for an invariant's error (no reference), else the reference check's
    heyoka runs timed over ten times the problem's main final time
    (longtime.measure.reference.check_seconds_per_t)."""
    if v.measure is None or v.measure.field != "l2_error":
        return 0.0
    from longtime.execution.cells import build, cell_of_row
    from longtime.measure.reference import ReferenceUnavailable, check_seconds_per_t

    row = next(s.row for s in v.candidates)
    problem = build(cell_of_row(row))[0]
    try:
        return check_seconds_per_t(problem, 10 * v.t_main, budget_s=CHECK_REFERENCE_S / 10)
    except ReferenceUnavailable:
        return math.inf  # its reference cannot be run here: no check of it is planned


def check_budget(rows: list[dict[str, Any]], limit: int = CHECKS) -> float:
    """The predicted CPU seconds each check may take: CHECK_BUDGET_S, but the checks together
    at most a quarter of the rows' own CPU time (a small matrix gets small checks)."""
    total = sum(r["cpu_s"] * (r.get("repeats") or 1) for r in rows if positive(r.get("cpu_s")))
    return min(CHECK_BUDGET_S, total / 4 / max(limit, 1))


def check_row(c: PlannedCheck, row: dict[str, Any]) -> dict[str, Any]:
    """A check's stored record: the re-run's row with the prediction beside it (a rival with
    no prediction, an "open" one, has predicted_error null)."""
    s, horizon, m = c.setting, c.horizon, c.measure
    measured = row.get(m.field) if row.get("status") == "ok" else None
    if m.field == "l2_error" and measured is not None and not (row.get("error_horizon") or 0) >= horizon * (1 - 1e-9):
        measured = None  # the reference stopped short of the horizon: an error over less than the prediction's span
    from longtime.execution.cells import cell_of_row

    predicted = s.error_at(horizon) if c.role in ("best", "runner-up") else None
    return {**row, "check_of": cell_of_row(s.row).key, "check_of_run": s.row.get("run_id"), "check_field": m.field,
            "check_law": s.law_text() if c.role != "chaos" else f"chaotic: error above {c.target:g} past t = "
                                                                 f"{horizon:.4g}",
            "check_role": c.role, "check_group": c.group, "check_kind": c.kind, "check_target": c.target,
            "predicted_error": predicted, "predicted_cpu_s": s.cpu_at(horizon),
            "predicted_cpu_model": s.cost.text() if s.cost else "per-time",
            "measured_error": measured if positive(measured) else None,
            "from_t_final": s.span, "from_error": s.error}


def judge_ranks(records: list[dict[str, Any]]) -> None:
    """Set ``rank_held`` on each group's "best" record: whether its measured CPU is at most
    CHECK_COST_FACTOR times that of every rival of its group (runner-up, open) whose measured
    error keeps the target (None: no rival measured one that keeps it)."""
    for best in (r for r in records if r.get("check_role") == "best"):
        rivals = [r for r in records if r.get("check_group") == best["check_group"] and r is not best
                  and positive(r.get("measured_error")) and r["measured_error"] <= r["check_target"]
                  and positive(r.get("cpu_s"))]
        best["rank_rivals"] = [f"{r['integrator']} {setting(r)}" for r in rivals]
        best["rank_held"] = (all(best.get("cpu_s", math.inf) <= CHECK_COST_FACTOR * r["cpu_s"] for r in rivals)
                             if rivals else None)


def run_checks(store, run_id: int, rows: list[dict[str, Any]], options=None,
               limit: int = CHECKS, budget_s: float = CHECK_BUDGET_S,
               reference_s: float = CHECK_REFERENCE_S, total_s: float = CHECKS_TOTAL_S) -> list[dict[str, Any]]:
    """Run ``plan_checks``'s checks of ``rows`` (each a cell at its horizon, one at a time in
    this process, under ``options``' time limit, timed by at most TIMED_RUNS - 1 runs after
    its warm-up, its reference given
    ``reference_s`` wall seconds), judge each group's rank (``judge_ranks``) and store each
    with its prediction (``Store.add_check``); returns the stored checks."""
    from longtime.core.timing import Timing
    from longtime.execution.cells import cell_of_row, run_cell
    from longtime.execution.matrix import ExecOptions

    plan = plan_checks(rows, limit, budget_s, total_s=total_s)
    if not plan:
        return []
    options = options or ExecOptions()
    # the warm-up and TIMED_RUNS - 1 timed runs at most (the checks' time estimate), no minimum time
    timing = Timing(repeats=min(options.timing.repeats, TIMED_RUNS - 1), min_time=0.0)
    records, cells = [], []
    for c in plan:
        cell = cell_of_row(c.setting.row, t_final=c.horizon)
        row = run_cell(cell, options.max_samples, timing=timing, time_limit=options.time_limit,
                       reference_budget_s=reference_s)
        records.append(check_row(c, row))
        cells.append(cell)
    judge_ranks(records)
    if store is not None:
        for cell, record in zip(cells, records):
            store.add_check(run_id, cell, record)
    return records


def check_counts(checks: list[dict[str, Any]]) -> dict[str, int]:
    """{"held", "failed", "unjudged"}: the checks whose prediction held, failed, or could not
    be judged (check_holds None). The results page reads it."""
    held = [check_holds(c) for c in checks]
    return {"held": sum(h is True for h in held), "failed": sum(h is False for h in held),
            "unjudged": sum(h is None for h in held)}


def failed_first(checks: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The checks in the order a reader needs them: failed, then not judged, then held."""
    order = {False: 0, None: 1, True: 2}
    return sorted(checks, key=lambda c: order[check_holds(c)])


def check_summary(checks: list[dict[str, Any]]) -> str:
    """'4 of 5 checked predictions held (error within x3, CPU within x1.5, the winner's rank
    tested against its rivals); 1 failed; 2 not judged (...)'."""
    n = check_counts(checks)
    judged = n["held"] + n["failed"]
    text = (f"{n['held']} of {judged} checked predictions held (error within x{CHECK_ERROR_FACTOR:g} of the "
            f"predicted, CPU within x{CHECK_COST_FACTOR:g}, the winner no costlier than x{CHECK_COST_FACTOR:g} a "
            f"rival that kept the target)")
    if n["failed"]:
        text += f"; {n['failed']} failed"
    if n["unjudged"]:
        text += f"; {n['unjudged']} not judged (no error measured, or a rival run without a prediction)"
    return text


def check_text(c: dict[str, Any]) -> str:
    """One check as a line: 'rk4 dt=0.01 to t = 1.26e4 (best; ...): error 3e-6 predicted,
    2.5e-6 measured; CPU ...: held'."""
    holds = check_holds(c)
    verdict = {True: "held", False: "MISSED", None: "not judged"}[holds]
    me, pe = c.get("measured_error"), c.get("predicted_error")
    role = c.get("check_role")
    if role == "chaos":
        error = f"error above {c['check_target']:g} predicted, {'-' if me is None else f'{me:.2g}'} measured"
    else:
        error = f"error {'-' if pe is None else f'{pe:.2g}'} predicted, {'-' if me is None else f'{me:.2g}'} measured"
    rank = ""
    if c.get("rank_held") is not None:
        rank = f"; rank {'held' if c['rank_held'] else 'MISSED'} against {', '.join(c.get('rank_rivals') or [])}"
    return (f"{c['integrator']} {setting(c)} to t = {c['t_final']:.4g} ({role + '; ' if role else ''}"
            f"{c.get('check_law')}): {error}; CPU {c['predicted_cpu_s']:.3g} s predicted, "
            f"{c.get('cpu_s') or float('nan'):.3g} s measured{rank}: {verdict}")


# ------------------------------------------------------------------ the verdict as text
def horizon_groups(v: Verdict, horizon: float) -> list[tuple[float, float, Decision]]:
    """The map's column at ``horizon`` folded: consecutive targets with the same decision
    (the same best setting, or the same state) as (loosest target, finest target, decision)."""
    out: list[tuple[float, float, Decision]] = []
    for t in v.targets:
        d = v.grid[(t, horizon)]
        key = (d.state, id(d.best) if d.best else None)
        if out and (out[-1][2].state, id(out[-1][2].best) if out[-1][2].best else None) == key:
            out[-1] = (out[-1][0], t, out[-1][2])
        else:
            out.append((t, t, d))
    return out


def _range(lo: float, hi: float) -> str:
    return f"{lo:.0e}" if lo == hi else f"{lo:.0e}..{hi:.0e}"


def decision_text(d: Decision) -> str:
    if d.limit is not None:
        return f"no pointwise answer past t = {d.limit.horizon:.3g} (chaos; a finer target: sooner)"
    if d.best is not None:
        return d.best.text
    if d.open:
        return "undetermined (" + ", ".join(s.scheme for s in d.open[:3]) + ")"
    return "none measured"


def verdict_lines(v: Verdict, full: bool = False) -> list[str]:
    """The verdict of one problem as report lines: what is read, one line per horizon (the
    winners per target range), the open questions and the checks."""
    if v.measure is None or not v.candidates:
        return [f"  verdict: none (no ok row with an error, a growth class and a CPU time; "
                f"`longtime matrix -p {v.problem}` measures them)"]
    lines = [f"  verdict: the cheapest setting predicted to keep {v.measure.field} <= target up to T "
             f"({v.measure.text}; `longtime recommend -p {v.problem} --error E --horizon T`):"]
    for h in v.horizons:
        groups = [g for g in horizon_groups(v, h) if g[2].state != "none"]
        mark = "(run)" if h == v.t_main else ""
        text = "; ".join(f"{_range(lo, hi)} {decision_text(d)}" for lo, hi, d in groups) or "none predicted"
        lines.append(f"    T = {h:<9.3g}{mark:<6s}{text}")
    kinds = ("invariant",) if v.candidates[0].kind == "invariant" else ("solution", "drifting")
    chaotic = any(s.kind == "chaotic" for s in v.candidates)
    if chaotic:
        kinds = ("chaotic",)
    lines.append("  trusted: " + "; ".join(
        ("the energy drifting: " if kind == "drifting" else "a chaotic problem's solution error: "
         if kind == "chaotic" else f"{kind} error: ")
        + ", ".join(f"{k} x{f:g}" for k, f in TRUST_FACTORS[kind].items()) for kind in kinds)
        + f" its run's span; past it, and at a predicted error >= {LOST:g} (lost), nothing is predicted")
    far = max((s.reach for s in v.candidates), default=0.0)
    if chaotic:
        lines.append(f"  chaotic: past the predictability horizon no run decides a pointwise error; `longtime ensemble "
                     f"-p {v.problem}` measures which schemes keep the distribution the orbit visits")
    elif v.horizons and v.horizons[-1] > far * (1 + 1e-9):
        # of the settings reaching farthest, the most accurate there
        s = min((s for s in v.candidates if s.reach == far),
                key=lambda s: (s._law_at(far) if s.extrapolates else s.error, s.cpu_per_t, s.text))
        lines.append(f"  not determined past t = {far:.4g} (the farthest reach; the most accurate there, {s.text}): "
                     f"`{deciding_run(s, v.horizons[-1])}` would decide it")
    stuck = [s for s in v.candidates if not s.extrapolates]
    if stuck:
        first = sorted(stuck, key=lambda s: s.cpu_per_t)[0]
        lines.append(f"  not extrapolated: {len(stuck)} of {len(v.candidates)} settings (growth undetermined, faster, "
                     f"or a class not trusted past the run); the cheapest, {first.text} ({first.law_text()}), is decided by "
                     f"`{deciding_run(first, 10 * first.span)}`")
    if v.checks:
        lines.append(f"  checks: {check_summary(v.checks)}")
        shown = failed_first(v.checks if full else [c for c in v.checks if check_holds(c) is not True])
        lines += [f"    {check_text(c)}" for c in shown]
    return lines
