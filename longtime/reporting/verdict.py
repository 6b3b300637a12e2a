"""The verdict: which setting (scheme and step or tolerance) keeps a target error up to a
horizon T at the least cost, predicted from what each stored setting measured.

Each ok setting of a problem gives its cost per unit of simulated time, ``cpu_s / (t_final
- t0)``, and its error at its final time with the growth law fitted to it
(longtime.measure.growth). Its predicted error at a horizon T beyond its run is

    e(T) = e(t_final) (T / t_final)^k     (class sqrt, linear or quadratic: k = 1/2, 1, 2)
    e(T) = e(t_final)                     (class bounded: flat)

with k the exponent of the class, not the fitted alpha: the law is the class, whose windows
agree on it, not the digits of a fit that still carries the run's transient (alpha 1.32 of
a linear error overpredicts it by 4 at a hundred times the run). Its predicted cost is ``T
* cpu_s / t_final``. Up to its own t_final a setting predicts its measured error. A class
is fitted on the last decades of its run, and is trusted only up to
``TRUST_FACTORS[kind][class]`` times that run's span (its ``reach``; kind: a solution
error, one whose energy drift will steepen it, or an invariant's error), not past the run
where its windows' slopes are steepening, and at most as far as its latest window's slope
would move the prediction by CHECK_ERROR_FACTOR: a bounded solution error can be the
transient before a phase error's growth, and a power law's exponent can still be changing.
Past its reach, and past t_final for a setting whose law is undetermined (or faster than
quadratic, which no power law of the run's span extrapolates), a setting predicts nothing:
where it could have won, the verdict says "not determined past t = X" and names the run
that would decide it. A predicted relative error of ``LOST`` or more is O(1): the solution
is lost there, and the prediction is ``lost``, not a number.

The error read is the solution error ``l2_error`` (the relative RMS error over [0, T]; law
``error.growth_class``) where the problem's rows have a reference, else the energy error
``H.max`` (the largest relative error of H up to T; law ``H.growth_class``), else the first
invariant's: ``measure`` says which. An error averaged over the run follows the law of the
pointwise one (the RMS of C t^k over [0, T] is C T^k / sqrt(2k + 1)), and does not depend
on where in an oscillation the run stops, as the error at the last sample (``final_error``)
does. Predictions are checked: the main job re-runs a few of them at the longest horizon
its budget affords (``plan_checks``, ``run_checks``) and stores the predicted beside the
measured error and cost (``Store.add_check``).
"""
from __future__ import annotations

import contextlib
import math
import shlex
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, Iterable

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
        return Measure("l2_error", "error", f"the relative RMS error of the solution over [0, T] against the "
                                            f"{'exact solution' if ref == 'exact' else 'reference'}")
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
    def extrapolates(self) -> bool:
        return self.law in EXPONENTS and self.factor > 1

    @property
    def reach(self) -> float:
        """The horizon up to which its error is determined: its run's span times its
        class's trust factor."""
        return self.span * self.factor

    def state_at(self, horizon: float) -> str:
        """What it says of its error at ``horizon``: "measured" (within its run),
        "predicted" (its class, within its reach), "lost" (a predicted error of LOST or
        more: O(1)) or "undetermined" (past its reach)."""
        if horizon <= self.span * (1 + 1e-9):
            return "measured"
        if not self.extrapolates or horizon > self.reach * (1 + 1e-9):
            return "undetermined"
        return "lost" if self._law_at(horizon) >= LOST else "predicted"

    def _law_at(self, horizon: float) -> float:
        return self.error * (horizon / self.span) ** EXPONENTS[self.law]

    def error_at(self, horizon: float) -> float | None:
        """The measured or predicted error at ``horizon`` (None: undetermined there, or lost)."""
        state = self.state_at(horizon)
        if state == "measured":
            return self.error
        return self._law_at(horizon) if state == "predicted" else None

    def cpu_at(self, horizon: float) -> float:
        return self.cpu_per_t * horizon

    def law_text(self) -> str:
        if self.extrapolates:
            reach = f", trusted to t = {self.reach:.4g}" + (", the energy drifts" if self.kind == "drifting" else "")
        elif self.steepening:
            reach = (f", not trusted past its run (window slopes {', '.join(f'{w:.2f}' for w in self.windows)} "
                     f"rise past t^{EXPONENTS[self.law]:g})")
        else:
            reach = f", not trusted past its run (a solution error's {self.law} class)"
        if self.law in FLAT:
            return "bounded: flat" + reach
        if self.law in POWER_LAWS:
            fit = f", alpha {self.alpha:.2f}" if self.alpha is not None else ""
            ci = f" [{self.ci[0]:.2f}, {self.ci[1]:.2f}]" if self.ci and fit else ""
            return f"{self.law}: t^{EXPONENTS[self.law]:g}{fit}{ci} fitted" + reach
        return f"{self.law}: {self.reason}" if self.reason else self.law

    def undetermined_text(self, horizon: float) -> str:
        """Why it predicts nothing at ``horizon``: its law, or its law's reach."""
        if self.extrapolates:
            return (f"its law ({self.law}) is not determined past t = {self.reach:.4g} "
                    f"({self.factor:g} times its run)")
        return f"its growth is {self.law_text()}"


def settings(rows: Iterable[dict[str, Any]], m: Measure) -> list[Setting]:
    """The candidates of one problem's rows: ok rows that kept the solution, with the
    measured error, a CPU time, a final time and a growth class."""
    out = []
    for r in rows:
        if r.get("status") != "ok" or r.get("solution_lost") or r.get("check_of"):
            continue
        err, cpu, span = r.get(m.field), r.get("cpu_s"), r.get("t_final")
        law = r.get(f"{m.law}.growth_class")
        if not (positive(err) and positive(cpu) and positive(span) and law) or law in ("saturated", "diverged"):
            continue
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
                           and all(isinstance(w, (int, float)) for w in windows) else ()))
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

    @property
    def state(self) -> str:
        if self.best is not None:
            return "predicted"
        return "undetermined" if self.open else "none"


def decide(candidates: list[Setting], target: float, horizon: float) -> Decision:
    """The cheapest candidate predicted to keep ``target`` up to ``horizon``; the runner-up
    is the cheapest of another scheme; ``open`` the undetermined ones cheaper than the best
    (or any, without a best) that keep the target over their own run."""
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
    row = s.row
    t_final = max(horizon, 10 * s.span)
    parts = ["longtime", "run", "-p", row["problem"], "-i", row["integrator"]]
    for k in ROW_PARAMETERS:
        v = row.get(k)
        if positive(v):
            parts += [flag(k), f"{int(v)}" if k == "order" else f"{v:g}"]
    if row.get("settings"):
        import json

        for k, v in json.loads(row["settings"]).items():
            parts += ["--set", f"{k}={v}"]
    parts += ["--t-final", f"{t_final:g}"]
    if db:
        parts += ["--db", db]
    return shlex.join(parts)


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
    grid = {(t, h): decide(cands, t, h) for t in TARGETS for h in horizons}
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
    measure: Measure
    decision: Decision
    evidence: dict[str, Any]
    lines: list[str]

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
    how = "measured" if horizon <= s.span * (1 + 1e-9) else s.law_text()
    return (f"{s.text}: error {e:.2g} at T ({how}; {s.error:.2g} measured at t = {s.span:.4g}), "
            f"CPU {s.cpu_at(horizon):.3g} s ({s.cpu_per_t:.3g} s per unit time, measured)")


def recommend(rows: list[dict[str, Any]], problem: str, error: float, horizon: float,
              db: str | None = None, known: Iterable[str] | None = None,
              checks: Iterable[dict[str, Any]] = ()) -> Recommendation:
    """The cheapest setting predicted to keep ``error`` up to ``horizon`` on ``problem``
    from ``rows`` (a store's), with the runner-up and the evidence. Bad input (an unknown
    problem, a non-positive error or horizon) and rows that cannot decide (none of the
    problem, no setting predicted to keep the target) raise InputError: one line naming
    what is missing and the command that would measure it."""
    known = list(known) if known is not None else None
    where = f" --db {shlex.quote(db)}" if db else ""
    if known is not None and problem not in known:
        raise InputError(f"-p {problem}: unknown problem; known: {', '.join(sorted(known))}")
    for name, value in (("--error", error), ("--horizon", horizon)):
        if not positive(value):
            raise InputError(f"{name} {value}: must be a finite number > 0")
    mine = [r for r in rows if r.get("problem") == problem]
    if not mine:
        raise InputError(f"no rows of {problem} in the store: `longtime matrix -p {problem}{where}` measures them")
    m = measure(mine)
    cands = settings(mine, m) if m else []
    if m is None or not cands:
        raise InputError(f"no ok row of {problem} with an error, a growth class and a CPU time in the store: "
                         f"`longtime matrix -p {problem}{where}` measures them")
    d = decide(cands, error, horizon)
    if d.best is None:
        if d.open:
            s = d.open[0]
            raise InputError(f"{problem}: no setting is predicted to keep {m.field} <= {error:g} up to T = {horizon:g}; "
                             f"{s.text} keeps it to t = {s.span:.4g} but {s.undetermined_text(horizon)}; "
                             f"`{deciding_run(s, horizon, db)}` would decide it")
        finest = min(cands, key=lambda s: s.error)
        lost = sum(1 for s in cands if s.state_at(horizon) == "lost")
        lost_text = (f"; {lost} setting{'s' if lost != 1 else ''} predicted lost there (error >= {LOST:g})"
                     if lost else "")
        raise InputError(f"{problem}: no stored setting keeps {m.field} <= {error:g} up to T = {horizon:g} (the "
                         f"smallest measured is {finest.error:.2g}, {finest.text}, at t = {finest.span:.4g}{lost_text}); "
                         f"smaller steps or tolerances would: `longtime matrix -p {problem} -i {finest.scheme} "
                         f"--t-final {finest.span:g}{where}` with a finer sweep (--dt or --tol)")
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


# ------------------------------------------------------------------ checking predictions
def check_holds(c: dict[str, Any]) -> bool | None:
    """Whether a stored check confirms its prediction: the measured error within
    CHECK_ERROR_FACTOR of the predicted, the measured CPU at most CHECK_COST_FACTOR times
    the predicted; None where the check measured no error."""
    pe, me, pc, mc = (c.get(k) for k in ("predicted_error", "measured_error", "predicted_cpu_s", "cpu_s"))
    if not (positive(pe) and positive(me) and positive(pc) and positive(mc)):
        return None
    return (1 / CHECK_ERROR_FACTOR <= me / pe <= CHECK_ERROR_FACTOR) and mc <= CHECK_COST_FACTOR * pc


def plan_checks(rows: list[dict[str, Any]], limit: int = CHECKS, budget_s: float = CHECK_BUDGET_S,
                reference_rate=None) -> list[tuple[Setting, float, Measure]]:
    """The predictions to re-run: per problem whose checks can be measured (``_checkable``),
    each setting the map names as the winner somewhere past its run (so within its class's
    reach: the check tests a prediction the verdict makes), at the longest horizon where it
    wins within ``budget_s`` of predicted CPU and where the check's reference can be
    measured (``reference_rate(verdict)``: the reference's wall seconds per unit of t, at
    most half of CHECK_REFERENCE_S in all; default ``reference_seconds_per_t``); one problem
    at a time in turn (each problem's distinct schemes first, the farthest horizon first),
    at most ``limit`` in all."""
    rate_of = reference_seconds_per_t if reference_rate is None else reference_rate
    per_problem: list[list[tuple[Setting, float, Measure]]] = []
    for v in verdicts(rows).values():
        if not _checkable(v, rows):
            continue
        rate = None  # measured once a problem, when a pick needs it
        picks: dict[int, tuple[Setting, float, Measure]] = {}
        for d in sorted(v.grid.values(), key=lambda d: -d.horizon):
            s = d.best
            if s is None or d.horizon <= s.span * (1 + 1e-9) or s.cpu_at(d.horizon) > budget_s:
                continue
            if id(s) in picks and d.horizon <= picks[id(s)][1]:
                continue
            if rate is None:
                rate = rate_of(v)
            if rate * d.horizon > CHECK_REFERENCE_S / 2:
                continue  # the reference would not reach the horizon within its budget
            picks[id(s)] = (s, d.horizon, v.measure)
        mine = sorted(picks.values(), key=lambda p: (-p[1] / p[0].span, p[0].cpu_at(p[1]), p[0].text))
        schemes, first, rest = set(), [], []
        for p in mine:
            (rest if p[0].scheme in schemes else first).append(p)
            schemes.add(p[0].scheme)
        per_problem.append(first + rest)
    out: list[tuple[Setting, float, Measure]] = []
    while len(out) < limit and any(per_problem):
        for picks in per_problem:
            if picks and len(out) < limit:
                out.append(picks.pop(0))
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
        with _reference_budget(CHECK_REFERENCE_S):
            return check_seconds_per_t(problem, 10 * v.t_main, budget_s=CHECK_REFERENCE_S / 5)
    except ReferenceUnavailable:
        return math.inf  # its reference cannot be run here: no check of it is planned


def _checkable(v: Verdict, rows: list[dict[str, Any]]) -> bool:
    """Whether a check of ``v``'s predictions can be measured past the runs: its error needs
    no heyoka reference there (an invariant's drift, or an exact solution), and the problem
    is not chaotic (a solution error predicted past the predictability horizon is not a
    prediction a check can judge)."""
    if v.measure is None:
        return False
    mine = [r for r in rows if r.get("problem") == v.problem]
    if any("lyapunov_time" in r for r in mine):
        return False
    if v.measure.field != "l2_error":
        return True
    return any(r.get("reference") == "exact" for r in mine if r.get("status") == "ok")


def check_budget(rows: list[dict[str, Any]], limit: int = CHECKS) -> float:
    """The predicted CPU seconds each check may take: CHECK_BUDGET_S, but the checks together
    at most a quarter of the rows' own CPU time (a small matrix gets small checks)."""
    total = sum(r["cpu_s"] * (r.get("repeats") or 1) for r in rows if positive(r.get("cpu_s")))
    return min(CHECK_BUDGET_S, total / 4 / max(limit, 1))


def check_row(s: Setting, horizon: float, m: Measure, row: dict[str, Any]) -> dict[str, Any]:
    """A check's stored record: the re-run's row with the prediction beside it."""
    measured = row.get(m.field) if row.get("status") == "ok" else None
    if m.field == "l2_error" and measured is not None and not (row.get("error_horizon") or 0) >= horizon * (1 - 1e-9):
        measured = None  # the reference stopped short of the horizon: an error over less than the prediction's span
    from longtime.execution.cells import cell_of_row

    return {**row, "check_of": cell_of_row(s.row).key, "check_of_run": s.row.get("run_id"), "check_field": m.field, "check_law": s.law_text(),
            "predicted_error": s.error_at(horizon), "predicted_cpu_s": s.cpu_at(horizon),
            "measured_error": measured if positive(measured) else None,
            "from_t_final": s.span, "from_error": s.error}


def run_checks(store, run_id: int, rows: list[dict[str, Any]], options=None,
               limit: int = CHECKS, budget_s: float = CHECK_BUDGET_S) -> list[dict[str, Any]]:
    """Re-run ``plan_checks``'s predictions of ``rows`` (each a cell at its horizon, on the
    serial executor under ``options``' timing and limits: one at a time, so they do not
    share the cores) and store each with its prediction (``Store.add_check``); returns the
    stored checks."""
    from longtime.execution.cells import cell_of_row
    from longtime.execution.matrix import ExecOptions, run_matrix

    plan = plan_checks(rows, limit, budget_s)
    if not plan:
        return []
    cells = [cell_of_row(s.row, t_final=h) for s, h, _ in plan]
    options = options or ExecOptions()
    import dataclasses

    opts = dataclasses.replace(options, jobs=1, on_start=None, idle_work=None)
    out = []
    with _reference_budget(CHECK_REFERENCE_S):
        for (s, h, m), cell, row in zip(plan, cells, run_matrix(cells, None, None, "serial", opts)):
            record = check_row(s, h, m, row)
            if store is not None:
                store.add_check(run_id, cell, record)
            out.append(record)
    return out


@contextlib.contextmanager
def _reference_budget(seconds: float):
    """$LONGTIME_REFERENCE_SECONDS at most ``seconds`` while the checks run in this process
    (a smaller one set by the user stays)."""
    import os

    from longtime.measure.reference import BUDGET_VARIABLE, budget_seconds

    before = os.environ.get(BUDGET_VARIABLE)
    os.environ[BUDGET_VARIABLE] = repr(min(seconds, budget_seconds()))
    try:
        yield
    finally:
        if before is None:
            os.environ.pop(BUDGET_VARIABLE, None)
        else:
            os.environ[BUDGET_VARIABLE] = before


def check_summary(checks: list[dict[str, Any]]) -> str:
    """'4 of 5 checked predictions held (error within x3, CPU within x1.5); 1 measured no error'."""
    held = [check_holds(c) for c in checks]
    judged = [h for h in held if h is not None]
    text = (f"{sum(judged)} of {len(judged)} checked predictions held (error within x{CHECK_ERROR_FACTOR:g} of the "
            f"predicted, CPU within x{CHECK_COST_FACTOR:g})")
    if len(judged) < len(held):
        text += f"; {len(held) - len(judged)} measured no error (not ok, or no reference that far)"
    return text


def check_text(c: dict[str, Any]) -> str:
    """One check as a line: 'rk4 dt=0.01 to t = 1.26e4: error 3e-6 predicted, 2.5e-6 measured; CPU ...'."""
    holds = check_holds(c)
    verdict = {True: "held", False: "MISSED", None: "no error measured"}[holds]
    me = c.get("measured_error")
    return (f"{c['integrator']} {setting(c)} to t = {c['t_final']:.4g} ({c.get('check_law')}): error "
            f"{c['predicted_error']:.2g} predicted, {'-' if me is None else f'{me:.2g}'} measured; CPU "
            f"{c['predicted_cpu_s']:.3g} s predicted, {c.get('cpu_s') or float('nan'):.3g} s measured: {verdict}")


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
    lines.append("  trusted: " + "; ".join(
        ("the energy drifting: " if kind == "drifting" else f"{kind} error: ")
        + ", ".join(f"{k} x{f:g}" for k, f in TRUST_FACTORS[kind].items()) for kind in kinds)
        + f" its run's span; past it, and at a predicted error >= {LOST:g} (lost), nothing is predicted")
    far = max((s.reach for s in v.candidates), default=0.0)
    if v.horizons and v.horizons[-1] > far * (1 + 1e-9):
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
        shown = v.checks if full else [c for c in v.checks if check_holds(c) is not True]
        lines += [f"    {check_text(c)}" for c in shown]
    return lines
