"""The verdict of one problem: per target error and horizon T, the cheapest setting predicted
to keep the target (``decide``), over a map of targets and horizons (``problem_verdict``).

Where a setting could have won past its reach, the verdict says "not determined past t = X"
and names the run that would decide it (``deciding_run``).

No pointwise error is predicted past the predictability horizon of the target E
(``predictability``): on a chaotic problem (rows with a Lyapunov time)
lyapunov_time * ln(E / INITIAL_ROUNDING); on any problem whose growth of a perturbation was
measured (longtime.measure.instability), the time a rounding of the state grows to E; at
most the reference's trusted horizon. The answer there is "no double-precision scheme keeps
a pointwise error of E past t = X" with the reason, and the ensembles' statistical answer
where the store has them.
"""
from __future__ import annotations

import math
import shlex
from dataclasses import dataclass, field
from typing import Any, Iterable

from longtime.core.fmt import positive
from longtime.core.roles import ROW_PARAMETERS, flag
from longtime.core.rowtext import main_t_final
from longtime.measure.instability import INITIAL_ROUNDING, Growth
from longtime.predict.settings import Measure, Setting, measure, settings

# targets of the winner map: the decades 1e-1 .. 1e-14
TARGETS = tuple(10.0 ** -k for k in range(1, 15))
# horizons of the winner map: the problem's main final time times these (integer multiples
# keep the phase of a periodic orbit, as the check runs do)
HORIZON_FACTORS = tuple(10**k for k in range(0, 7))


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
    """How far a pointwise error ``target`` can be kept: ``horizon`` = the least of
    lyapunov_time * ln(target / INITIAL_ROUNDING) on a chaotic problem, the time a rounding
    of the state measured growing on the reference reaches ``target`` (``growth``, on every
    problem: longtime.measure.instability) and the reference's trusted horizon, and the
    reason in words."""
    target: float
    horizon: float
    lyapunov_time: float | None
    reference_horizon: float | None
    growth: Growth | None = field(default=None, compare=False)

    @property
    def growth_horizon(self) -> float | None:
        return self.growth.horizon(self.target) if self.growth is not None else None

    @property
    def reason(self) -> str:
        parts = []
        if self.growth_horizon is not None:
            parts.append(self.growth.reason(self.target))
        if self.lyapunov_time is not None:
            parts.append(f"Lyapunov time {self.lyapunov_time:.3g}: a rounding of {INITIAL_ROUNDING:g} in the initial "
                         f"state grows e-fold each {self.lyapunov_time:.3g} and reaches {self.target:g} by t = "
                         f"{self.lyapunov_bound:.3g}")
        return "; ".join(parts)

    @property
    def kept_until(self) -> float | None:
        """Where the growth of a rounding (measured, or the Lyapunov bound) reaches the
        target: past it no double-precision run of any scheme keeps it (None: not bounded)."""
        bounds = [b for b in (self.growth_horizon, self.lyapunov_bound) if b is not None]
        return min(bounds) if bounds else None

    @property
    def lyapunov_bound(self) -> float | None:
        if self.lyapunov_time is None:
            return None
        return self.lyapunov_time * math.log(self.target / INITIAL_ROUNDING) if self.target > INITIAL_ROUNDING else 0.0

    def text(self) -> str:
        """Why no pointwise answer exists past ``horizon``: the growth of a rounding (no
        double-precision scheme keeps the target past it), and the reference's end where it
        comes first (no error is measured past it)."""
        parts = []
        kept = self.kept_until
        if kept is not None:
            parts.append(f"no double-precision scheme keeps a pointwise error of {self.target:g} past t = "
                         f"{kept:.4g} ({self.reason})")
        if self.reference_horizon is not None and (kept is None or self.reference_horizon < kept):
            parts.append(f"no error is measured past t = {self.reference_horizon:.4g}: the reference is trusted only "
                         f"up to t = {self.reference_horizon:.4g}")
        return "; ".join(parts)


def predictability(rows: Iterable[dict[str, Any]], target: float,
                   growth: Growth | None = None) -> Predictability | None:
    """The predictability horizon of ``target`` on the problem of ``rows`` (one problem's):
    the least of the Lyapunov bound where its rows carry a measured Lyapunov time, the time
    the measured ``growth`` of a rounding reaches ``target`` (any problem), and the end of the
    reference's trusted horizon where a row's check found it before the row's t_final (any
    problem: an error is measured only as far as its reference is trusted). None where
    nothing bounds it."""
    rows = list(rows)
    times = [float(r["lyapunov_time"]) for r in rows if "lyapunov_time" in r and positive(r.get("lyapunov_time"))]
    t_l = min(times) if times else None
    # the reference's trusted horizon where a row's check found its end before the row's t_final
    ends = [float(r["reference_horizon"]) for r in rows if positive(r.get("reference_horizon"))
            and r["reference_horizon"] < float(r.get("t_final") or 0) * (1 - 1e-9)]
    ref = min(ends) if ends else None
    grown = growth.horizon(target) if growth is not None else None
    lyap = (t_l * math.log(target / INITIAL_ROUNDING) if target > INITIAL_ROUNDING else 0.0) if t_l is not None \
        else None
    bounds = [b for b in (lyap, grown, ref) if b is not None]
    if not bounds:
        return None
    return Predictability(target, min(bounds), t_l, ref, growth if grown is not None else None)


def decide(candidates: list[Setting], target: float, horizon: float,
           limit: Predictability | None = None) -> Decision:
    """The cheapest candidate predicted to keep ``target`` up to ``horizon``; the runner-up
    is the cheapest of another scheme; ``open`` the undetermined ones cheaper than the best
    (or any, without a best) that keep the target over their own run. Past ``limit`` (a
    chaotic problem's predictability horizon of ``target``) nothing is predicted."""
    if limit is not None and horizon > limit.horizon * (1 + 1e-9):
        return Decision(target, horizon, limit=limit)
    keeps = keepers(candidates, target, horizon)
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


def keepers(candidates: list[Setting], target: float, horizon: float) -> list[Setting]:
    """The candidates whose measured or predicted error at ``horizon`` keeps ``target``,
    cheapest first (their predicted CPU to ``horizon``)."""
    keeps = [s for s in candidates if (e := s.error_at(horizon)) is not None and e <= target]
    return sorted(keeps, key=lambda s: (s.cpu_at(horizon), s.text))


def deciding_run(s: Setting, horizon: float, db: str | None = None) -> str:
    """The command that would measure ``s``'s law up to ``horizon`` (at least a decade past
    its run: a growth law needs 1.5 decades of t past the early transient)."""
    return shlex.join(run_command(s, max(horizon, 10 * s.span), db))


def run_settings(row: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """The parameters that run ``row``'s setting again: its swept ones that its scheme takes
    (a recorded one it does not, heyoka's order, is left out) and its other settings."""
    from longtime.core import registry

    try:
        takes = set(registry.integrator_class(row["integrator"]).parameters)
    except Exception:  # a scheme no longer registered: every recorded parameter
        takes = set(ROW_PARAMETERS)
    given = {k: int(row[k]) if k == "order" else row[k] for k in ROW_PARAMETERS
             if positive(row.get(k)) and k in takes}
    if not row.get("settings"):
        return given, {}
    import json

    return given, dict(json.loads(row["settings"]))


def run_command(s: Setting, t_final: float, db: str | None = None) -> list[str]:
    """``longtime run`` of ``s``'s setting to ``t_final``, as arguments: the row's parameters
    that its scheme takes (a recorded one it does not, heyoka's order, is left out), its
    other settings."""
    parts = ["longtime", "run", "-p", s.row["problem"], "-i", s.row["integrator"]]
    given, others = run_settings(s.row)
    for k, v in given.items():
        parts += [flag(k), f"{v}" if k == "order" else f"{v:g}"]
    for k, v in others.items():
        parts += ["--set", f"{k}={v}"]
    parts += ["--t-final", f"{t_final:g}"]
    if db:
        parts += ["--db", db]
    return parts


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


def problem_verdict(problem: str, rows: list[dict[str, Any]], checks: Iterable[dict[str, Any]] = (),
                    growth: Growth | None = None) -> Verdict:
    """One problem's verdict over the map of TARGETS and horizons; no cell is predicted past
    the predictability horizon of its target (``predictability``: the Lyapunov bound, the
    reference's end, and where ``growth`` is given the growth of a rounding measured on the
    problem, as ``longtime recommend`` bounds its answer)."""
    mine = [r for r in rows if r.get("problem") == problem]
    m = measure(mine)
    t_main = main_t_final(mine)
    if m is None or t_main is None:
        return Verdict(problem, m, [], t_main)
    cands = settings(mine, m)
    horizons = tuple(t_main * f for f in HORIZON_FACTORS)
    # a target's predictability horizon is the same at every horizon of the map
    limits = {t: predictability(mine, t, growth) if m.solution else None for t in TARGETS}
    grid = {(t, h): decide(cands, t, h, limits[t]) for t in TARGETS for h in horizons}
    v = Verdict(problem, m, cands, t_main, TARGETS, horizons, grid,
                [c for c in checks if c.get("problem") == problem])
    keep = v.reachable_targets()
    if keep:  # the map spans the targets some setting reaches, and one decade past them
        lo = TARGETS.index(keep[-1])
        v.targets = TARGETS[TARGETS.index(keep[0]): lo + 2]
        v.grid = {k: d for k, d in grid.items() if k[0] in v.targets}
    return v


def verdicts(rows: list[dict[str, Any]], checks: Iterable[dict[str, Any]] = (),
             growths: dict[str, Growth] | None = None) -> dict[str, Verdict]:
    """Every problem's verdict (``problem_verdict``), each bounded by its problem's growth in
    ``growths`` where it has one."""
    checks, growths = list(checks), growths or {}
    return {p: problem_verdict(p, rows, checks, growths.get(p)) for p in sorted({r["problem"] for r in rows})}
