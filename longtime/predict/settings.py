"""A stored setting as a candidate of the verdict: the error it reads (``measure``), each
setting's measured error, law and cost (``settings``), and how far its law is trusted.

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
invariant's error), not past the run where its windows' slopes are steepening or the run
spans under SHORT_RUN of its problem's default horizon, and at most
as far as its latest window's slope would move the prediction by CHECK_ERROR_FACTOR. An
undetermined law whose windows' slopes do not rise is bounded by its steepest slope for
BOUND_FACTOR times its run. Past its reach a setting predicts nothing. A predicted error of
``LOST`` or more is O(1): ``lost``, not a number.

The predicted cost is ``CostModel.at(T)``: fixed + per-time parts fitted on runs of two
lengths of the setting (set-up and dense-output sampling apart from the stepping), else
per-time from one run; each prediction says which.

A setting "keeps E up to T" where its error over [t0, T] stays at most E: the largest
error up to T, never an average (``error_kept``, the one definition that recommend, the
verdict, its checks and the results page read). The error read is the solution error
``max_error`` (the largest error of any block of the state over [0, T], each block relative
to its own motion, longtime.measure.metrics; law ``error.growth_class``) where the
problem's rows have a reference (``l2_error``, the RMS over [0, T], only from a store
whose rows predate ``max_error``), else the energy error ``H.max`` (law
``H.growth_class``), else the first invariant's: ``measure`` says which.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, Iterable

import numpy as np

from longtime.core.fmt import positive
from longtime.core.rowtext import setting
from longtime.core.status import Status
from longtime.measure.growth import SATURATION
from longtime.predict.checks import CHECK_ERROR_FACTOR

# classes whose exponent extrapolates past the run (a power law), and the flat one
POWER_LAWS = ("sqrt", "linear", "quadratic")
EXPONENTS = {"bounded": 0.0, "sqrt": 0.5, "linear": 1.0, "quadratic": 2.0}
FLAT = ("bounded",)
# how far each class is trusted, for a solution error and for an invariant's: up to this
# many times its run's span (t_final - t0), read from settings re-run at 10, 100 and 1000
# times their span (benchmarks/verdict_reach.py; the table is in docs/metrics.md, "How far a
# class is trusted"). A solution error's power law held within x3 up to 100 times the run
# wherever its prediction stayed below LOST; at 1000 times a quadratic one held, a linear one
# did not (taylor N=10 on Lotka-Volterra, 17 times its prediction: the phase error turns
# faster once the invariant's slow drift tells), so linear is trusted 100 times its run,
# quadratic 1000. A solution error classed bounded or sqrt can be the transient
# before a phase error grows (at least linearly; round-off's phase walks like t^1.5): some
# held to 100 times the run, others were off by 3 to 40 at 10 times, so neither class of a
# solution error is extrapolated. An invariant's error of every class held to 1000 times.
# A solution error growing like t^k whose setting lets the energy drift like t^a with
# k < 1 + a is trusted ten times its run only: a drifting energy moves the frequencies, and
# the phase error then turns to t^(1 + a) (the quadratic growth of a non-symplectic method's
# error on an integrable system) at a time its run need not show (rk4 on the rigid body:
# linear to t = 1e3, off by 2.4 at 1e4 and by 17 at 1e5).
TRUST_FACTORS = {
    "solution": {"bounded": 1.0, "sqrt": 1.0, "linear": 100.0, "quadratic": 1000.0},
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
# a run shorter than this fraction of its problem's default horizon (``default_t_final``,
# which spans many of the problem's periods: kepler's 20 orbits) is not extrapolated: a law
# fitted within a few periods is the error's course along one orbit, not its secular growth
# (scipy-lsoda on kepler, its run cut by the budget to t = 2.5, 0.4 of an orbit: linear over
# the run, 9.5 times that prediction at ten times its run)
SHORT_RUN = 0.1


# the solution error's fields, in the order ``measure`` takes them: max_error (the largest
# error over [0, T]); l2_error (its RMS) only where no row has max_error (an older store)
SOLUTION_FIELDS = ("max_error", "l2_error")
SOLUTION_TEXTS = {"max_error": "the largest error of any block of the state (a body's position, its momentum, ...) "
                               "over [0, T], relative to that block's motion",
                  "l2_error": "the RMS error of the solution over [0, T] relative to its motion (rows stored "
                              "without max_error)"}


@dataclass
class Measure:
    """The error a problem's verdict reads: ``field`` of the rows, the growth law ``law``
    (``LAW.growth``, ``LAW.growth_class``) and words for a reader."""
    field: str
    law: str
    text: str

    @property
    def solution(self) -> bool:
        """Whether it is the solution error (against a reference), not an invariant's."""
        return self.field in SOLUTION_FIELDS


def solution_measure(rows: Iterable[dict[str, Any]], with_law: bool = False) -> Measure | None:
    """The solution error's Measure where ok rows have one (the first of SOLUTION_FIELDS
    that one has; ``with_law``: with its growth class too), else None."""
    ok = [r for r in rows if r.get("status") == Status.OK]
    for name in SOLUTION_FIELDS:
        if any(positive(r.get(name)) and (r.get("error.growth_class") or not with_law) for r in ok):
            ref = next((r.get("reference") for r in ok if r.get("reference")), None)
            return Measure(name, "error", f"{SOLUTION_TEXTS[name]}, against the "
                                          f"{'exact solution' if ref == 'exact' else 'reference'}")
    return None


def measure(rows: Iterable[dict[str, Any]]) -> Measure | None:
    """The solution error where ok rows have one and its growth class (SOLUTION_FIELDS),
    else H's drift, else the first invariant's with a growth class; None when no ok row has
    any."""
    rows = list(rows)
    found = solution_measure(rows, with_law=True)
    if found is not None:
        return found
    ok = [r for r in rows if r.get("status") == Status.OK]
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
    # the error's kind: "solution" (max_error), "drifting" (max_error of a setting whose
    # energy drift will steepen it, see TRUST_FACTORS) or "invariant" (NAME.max)
    kind: str = "solution"
    windows: tuple[float, ...] = ()  # the slopes of the growth fit's windows, earliest first
    # the error reached up to each time of its run, (t, error) earliest first: the row's
    # error_curve (its running maximum) or its invariant's envelope (running maximum); () for a
    # row stored without it
    curve: tuple[tuple[float, float], ...] = ()
    cost: "CostModel | None" = None  # CPU seconds against T (default: per-time, from this run)
    lost_at: float = math.inf  # the span of a longer run of the same setting that lost the solution
    default_span: float | None = None  # its problem's default horizon (None: the problem is not installed)

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
        if self.short:
            return 1.0
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

    @property
    def short(self) -> bool:
        """Whether its run spans less than SHORT_RUN of its problem's default horizon."""
        return self.default_span is not None and self.span < SHORT_RUN * self.default_span

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
        """The error measured up to ``horizon`` within its run (``error_kept``, on the curve
        kept once per setting)."""
        return _reached(self.curve, self.error, self.span, horizon)

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
        elif self.short and self.exponent is not None:
            reach = (f", not trusted past its run (t = {self.span:.4g}, under {SHORT_RUN:g} of the problem's "
                     f"default horizon {self.default_span:.4g}: too short to show a secular law)")
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


def error_kept(row: dict[str, Any], m: Measure, horizon: float | None = None) -> float | None:
    """What "keeps E up to T" reads, the one definition: the error of ``row`` over [t0, T]
    (T = ``horizon``; None, or at or past the row's run: its whole run), E kept where it is
    at most E. For the solution error (max_error) and an invariant's (NAME.max): the largest
    error up to T, read within the run on the running maximum of the row's error envelope
    (``_curve``); for l2_error (an older row) its RMS up to T. None where the row has no
    such error."""
    whole = row.get(m.field)
    if not isinstance(whole, (int, float)) or isinstance(whole, bool) or not math.isfinite(whole):
        return None
    if horizon is None:
        return float(whole)
    return _reached(_curve(row, m), float(whole), float(row.get("t_final") or 0), horizon)


def _reached(curve: tuple[tuple[float, float], ...], whole: float, span: float, horizon: float) -> float:
    """The error up to ``horizon`` of a run of ``span`` whose error is ``whole``: read on
    its curve of the error reached (the larger of the two points around ``horizon``), else
    ``whole``."""
    if not curve or horizon >= span * (1 - 1e-9):
        return whole
    after = next((k for k, (t, _) in enumerate(curve) if t >= horizon * (1 - 1e-9)), None)
    if after is None:
        return whole
    return max(curve[after][1], curve[after - 1][1] if after > 0 else 0.0)


def _curve(row: dict[str, Any], m: Measure) -> tuple[tuple[float, float], ...]:
    """The error reached up to each time of the row's run, (t, error) earliest first: for
    max_error the running maximum of its error_curve's envelope (the largest error up to
    t), for l2_error its error_curve's l2 (the l2_error up to t), for NAME.max the running
    maximum of the invariant's envelope; () where the row keeps none."""
    t0 = 0.0  # the curves' times are t - t0
    if m.solution:
        c = row.get("error_curve")
        key = "l2" if m.field == "l2_error" else "error"
        if not (isinstance(c, dict) and c.get(key)):
            return ()
        values = np.asarray(c[key], dtype=float)
        if key == "error":
            values = np.maximum.accumulate(values)
        return tuple((t0 + float(t), float(e)) for t, e in zip(c["t"], values))
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
    rows = [r for r in rows if r.get("status") == Status.OK and not r.get("check_of")
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
                           _curve(r, m), costs[key], lost_at, _default_span(r["problem"])))
    return sorted(out, key=lambda s: (s.cpu_per_t, s.text))


def _default_span(problem: str) -> float | None:
    """The problem's default horizon, None where it is not installed here."""
    from longtime.core import registry
    from longtime.core.params import InputError

    try:
        return float(registry.problem_class(problem).default_t_final)
    except InputError:  # a store's problem that is not installed here (or broken): no such rule
        return None


def _rising(windows) -> bool:
    """Whether growth windows' slopes (earliest first, at least two) rise from each to the next."""
    return len(windows) >= 2 and all(b > a for a, b in zip(windows, windows[1:]))


def _kind(row: dict[str, Any], m: Measure, law: str) -> str:
    """"invariant" for an invariant's error; for the solution error of class ``law`` (t^k)
    "drifting" where the row's energy error drifts like t^a (DRIFTS; an undetermined one
    whose window slopes rise past 0.25: a its latest slope) with k < 1 + a, else
    "solution"."""
    if not m.solution:
        return "invariant"
    if positive(row.get("lyapunov_time")):
        return "chaotic"
    a = DRIFTS.get(row.get("H.growth_class"))
    w = row.get("H.growth_windows")
    if a is None and row.get("H.growth_class") == "undetermined" and isinstance(w, list) \
            and all(isinstance(x, (int, float)) for x in w) and _rising(w) and w[-1] > 0.25:
        a = float(w[-1])  # an energy error still steepening grows at least like its latest slope
    return "drifting" if a is not None and law in EXPONENTS and EXPONENTS[law] < 1 + a else "solution"
