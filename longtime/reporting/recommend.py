"""``longtime recommend``'s answer (``recommend``; from a store, ``stored_recommendation``):
the cheapest stored setting predicted to keep an error up to a horizon on one problem, with
its runner-up and evidence, or why the store determines no answer and the run that would
decide it."""
from __future__ import annotations

import math
import shlex
from dataclasses import dataclass
from typing import Any, Iterable

from longtime.core.fmt import positive
from longtime.core.params import InputError
from longtime.core.rowtext import setting
from longtime.core.status import Status
from longtime.measure.instability import Growth
from longtime.predict.checks import CHECK_COST_FACTOR, CHECK_ERROR_FACTOR, check_holds
from longtime.predict.decision import (
    Decision,
    Verdict,
    decide,
    predictability,
    run_command,
    run_settings,
    verdicts,
)
from longtime.predict.settings import LOST, Measure, Setting, measure, settings

# ``longtime recommend``'s exit code where the store determines no answer (no setting is
# predicted to keep the target, or no pointwise answer exists): the answer names why and the
# run that would decide it (2 stays bad input)
NO_ANSWER_EXIT = 3


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
    # "measured at T": the setting was run to the horizon (``measured_error``, ``measured_cpu_s``);
    # "predicted": read from the stored runs and their laws
    basis: str = "predicted"
    measured_error: float | None = None
    measured_cpu_s: float | None = None

    @property
    def scheme(self) -> str | None:
        return self.decision.best.scheme if self.decision.best else None

    @property
    def setting(self) -> str | None:
        return setting(self.decision.best.row) if self.decision.best else None

    @property
    def parameters(self) -> dict[str, Any]:
        """The answer's setting as keywords of ``longtime.solve`` (``dt``, ``tol``, ``order``,
        and its other settings), to run it again; {} without an answer."""
        if not self.decision.best:
            return {}
        given, others = run_settings(self.decision.best.row)
        return {**others, **given}

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
              checks: Iterable[dict[str, Any]] = (), ensembles: Iterable[dict[str, Any]] = (),
              growth: Growth | None = None, budget: float = 0.0, library: str | None = None) -> Recommendation:
    """The cheapest setting predicted to keep ``error`` up to ``horizon`` on ``problem``
    from ``rows`` (a store's), with the runner-up and the evidence. Bad input (an unknown
    problem, a non-positive error or horizon) raises InputError. Rows that determine no
    answer give a Recommendation whose ``answered`` is False and whose lines say why and name
    the command that would decide it: no rows, no setting predicted to keep the target, or a
    horizon past the problem's predictability horizon (no pointwise answer: the reason, the
    invariants the rows keep, and on a chaotic problem the ensemble distances of
    ``ensembles`` where the store has them). ``growth`` (``measured_growth``) is the growth of
    a perturbation measured on the problem's reference: where a rounding of the state grows to
    ``error`` before ``horizon``, no pointwise answer exists. Where the answer lies beyond
    what the stored runs show (a law extrapolated past its run, a cheaper setting whose law
    is undetermined there, a reference that stopped short), the best predicted candidates
    run to ``horizon`` within ``budget`` wall seconds (longtime.execution.answers) and the
    cheapest that keeps ``error`` there is the answer, "measured at T"; where the budget runs
    none, the predicted answer says "predicted, not run" and the command that runs them.
    ``library`` (scipy, sundials, ...; ``library_of``) limits the candidates to that library's
    schemes."""
    known = list(known) if known is not None else None
    where = f" --db {shlex.quote(db)}" if db else ""
    if known is not None and problem not in known:
        raise InputError(f"-p {problem}: unknown problem; known: {', '.join(sorted(known))}")
    for name, value in (("--error", error), ("--horizon", horizon)):
        if not positive(value):
            raise InputError(f"{name} {value}: must be a finite number > 0")
    mine = [r for r in rows if r.get("problem") == problem]
    if library is not None:
        mine, why = _of_library(mine, library, problem)
        if why:
            return Recommendation(problem, error, horizon, None, Decision(error, horizon), {},
                                  [f"{problem}: no answer from {library}: {why}"], answered=False)

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
    limit = predictability(mine, error, growth) if m.solution else None
    d = decide(cands, error, horizon, limit)
    # a limit set by the stored rows' reference alone is lifted by runs checked against a
    # reference to T; one set by the growth of a rounding is not
    kept = d.limit.kept_until if d.limit is not None else None
    free = decide(cands, error, horizon) if d.limit is not None and (kept is None or kept >= horizon) else d
    not_run = f"--budget {budget:g} s ran none of its candidates to T"
    if free.limit is None and _beyond(free, horizon):
        run, why = _measured(problem, error, horizon, m, cands, budget, db)
        if run is not None:
            return run
        not_run = f"nothing ran: {why}" if why else not_run
    if d.limit is not None:
        rec = unanswered(d.limit.text(), m, d)
        rec.lines += _invariant_lines(mine)
        if any("lyapunov_time" in r for r in mine):
            rec.lines += _statistical_lines(problem, ensembles, where)
        return rec
    if d.best is None:
        if d.open:
            s = d.open[0]
            return unanswered(f"no setting is predicted to keep it; {s.text} keeps it to t = {s.span:.4g} but "
                              f"{s.undetermined_text(horizon)}; predicted, not run ({not_run}): "
                              f"{_runs_it(s, horizon, db)}", m, d)
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
                     f"{s.undetermined_text(horizon)}: {_runs_it(s, horizon, db)}")
    if _beyond(d, horizon):
        lines.append(f"  predicted, not run: the answer lies past the stored runs and {not_run}; "
                     f"{_runs_it(b, horizon, db)}")
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


def _beyond(d: Decision, horizon: float) -> bool:
    """Whether a decision's answer lies beyond what the stored runs show: a winner
    extrapolated past its run, or a cheaper setting (or, without a winner, any) whose law is
    undetermined there."""
    if d.best is None:
        return bool(d.open)
    return horizon > d.best.span * (1 + 1e-9) or bool(d.open)


def _runs_it(s: Setting, horizon: float, db: str | None) -> str:
    """The command that runs ``s`` to ``horizon`` (where its predicted CPU is finite and fits
    a cell's time limit), else why no run of it can finish."""
    from longtime.execution.cells import DEFAULT_TIME_LIMIT

    cpu = s.cpu_at(horizon)
    if not cpu < DEFAULT_TIME_LIMIT:
        return f"a run of {s.text} to T is predicted to take {cpu:.3g} s, past a cell's time limit"
    return f"`{shlex.join(run_command(s, horizon, db))}` runs it to T (predicted {cpu:.3g} s)"


def _measured(problem: str, error: float, horizon: float, m: Measure, cands: list[Setting], budget: float,
              db: str | None) -> tuple[Recommendation | None, str]:
    """The answer measured at ``horizon``: the candidates (longtime.execution.answers) run
    within ``budget`` seconds, the cheapest measured that keeps ``error``; None where the
    budget runs none of them (the predicted answer stands, saying so), with the reason where
    it is not the budget's size alone."""
    from longtime.execution import answers

    todo = answers.candidates(cands, error, horizon)
    if budget <= 0 or not todo:
        return None, ""
    done, skipped, spent, why = answers.measure_at(todo, m.field, error, horizon, budget)
    if not done:
        return None, why
    keep = sorted((x for x in done if x.keeps), key=lambda x: (x.cpu_s if x.cpu_s is not None else math.inf,
                                                              x.setting.text))
    head = f"{problem}: keep {m.field} <= {error:g} up to T = {horizon:g} ({m.text}), measured at T"
    unrun = len(todo) - len(done) - len(skipped)
    foot = (f"  measured at T = {horizon:g}: {len(done)} of {len(todo)} candidate{'s' if len(todo) != 1 else ''} run "
            f"to T against a reference checked to T, in {spent:.3g} s of the --budget {budget:g} s"
            + (f"; {unrun} not run, predicted over x{answers.RIVAL_FACTOR:g} the winner's CPU" if unrun else ""))
    rest = [f"  predicted, not run: {s.text} (the budget ran out); {_runs_it(s, horizon, db)}" for s in skipped][:3]
    evidence = {"measured": len(done), "candidates": len(todo), "spent_s": spent, "budget_s": budget}
    if not keep:
        why = "; ".join(x.text() + ("" if x.error is None else f" (misses {error:g})") for x in done)
        return Recommendation(problem, error, horizon, m, Decision(error, horizon), evidence,
                              [f"{problem}: no answer for {m.field} <= {error:g} up to T = {horizon:g}, measured at T: "
                               f"no candidate keeps it ({why})", *rest, foot], answered=False,
                              basis="measured at T"), ""
    w = keep[0]
    runner = next((x for x in keep[1:] if x.setting.scheme != w.setting.scheme), None)
    lines = [head + ":", f"  use      {w.text()}"]
    if runner is not None:
        ratio = f", x{runner.cpu_s / w.cpu_s:.3g} the CPU" if runner.cpu_s and w.cpu_s else ""
        lines.append(f"  runner-up {runner.text()}{ratio}")
    else:
        lines.append("  runner-up: none measured (no other scheme's candidate kept the target at T)")
    for x in done:
        if x is not w and x is not runner:
            lines.append(f"  measured {x.text()}" + ("" if x.keeps or x.error is None else f" (misses {error:g})"))
    lines += rest + [foot]
    d = Decision(error, horizon, w.setting, runner.setting if runner else None)
    return Recommendation(problem, error, horizon, m, d, evidence, lines, basis="measured at T",
                          measured_error=w.error, measured_cpu_s=w.cpu_s), ""


def _invariant_lines(rows: list[dict[str, Any]]) -> list[str]:
    """What can be said past the predictability horizon without a pointwise error: each
    invariant's smallest stored relative error (the largest over its run), with its setting and
    how far it ran."""
    ok = [r for r in rows if r.get("status") == Status.OK]
    names = sorted({k[: -len(".growth_class")] for r in ok for k in r if k.endswith(".growth_class")
                    and k != "error.growth_class" and positive(r.get(k[: -len(".growth_class")] + ".max"))})
    out = []
    for name in names:
        best = min((r for r in ok if positive(r.get(f"{name}.max"))), key=lambda r: (r[f"{name}.max"], -r["t_final"]))
        out.append(f"{name}: {best[f'{name}.max']:.2g} ({best['integrator']} {setting(best)} to t = "
                   f"{best['t_final']:.4g})")
    if not out:
        return ["  what can be said: the invariants (no ok row of the store measured one)"]
    return ["  what can be said: the invariants (each one's smallest stored relative error, the largest over its "
            "run): " + "; ".join(out)]


def measured_growth(rows: list[dict[str, Any]], problem: str, horizon: float,
                    cached_only: bool = False) -> Growth | None:
    """The growth of a perturbation on ``problem`` (at the settings of its first stored row)
    up to ``horizon`` (longtime.measure.instability, cached); None where it cannot be measured
    (no rows, no heyoka system, a compile past its budget). ``cached_only``: the growth over
    the longest span up to ``horizon`` measured already (``instability.measured``), nothing
    run."""
    from longtime.execution.cells import build, cell_of_row
    from longtime.measure import instability

    row = next((r for r in rows if r.get("problem") == problem and r.get("status") == Status.OK
                and positive(r.get("l2_error"))), None)
    if row is None or not positive(horizon):  # no pointwise error to bound
        return None
    try:
        problem_ = build(cell_of_row(row))[0]
        return instability.measured(problem_, horizon) if cached_only else instability.measure(problem_, horizon)
    except Exception:  # no heyoka system, a compile past its budget: nothing bounds the answer
        return None


def map_growths(rows: list[dict[str, Any]]) -> dict[str, Growth]:
    """Per problem of ``rows``, the growth of a perturbation already measured over its
    winner map's horizons (``measured_growth``, cached only: the page and the report wait
    for no run), which bounds the map as it bounds ``recommend``'s answer."""
    from longtime.core.rowtext import main_t_final
    from longtime.predict.decision import HORIZON_FACTORS

    out = {}
    for p in sorted({r["problem"] for r in rows}):
        t_main = main_t_final([r for r in rows if r["problem"] == p])
        g = measured_growth(rows, p, t_main * max(HORIZON_FACTORS), cached_only=True) if t_main else None
        if g is not None:
            out[p] = g
    return out


def map_verdicts(rows: list[dict[str, Any]], checks: Iterable[dict[str, Any]] = ()) -> dict[str, Verdict]:
    """Every problem's verdict as the page and the reports show it: each winner map bounded by
    its problem's growth already measured (``map_growths``), as ``recommend`` bounds its answer."""
    return verdicts(rows, checks, map_growths(rows))


def _of_library(rows: list[dict[str, Any]], library: str, problem: str) -> tuple[list[dict[str, Any]], str]:
    """The rows of ``library``'s schemes, and why there are none ('' where there are)."""
    from longtime.core import registry
    from longtime.reporting.libraries import library_of

    known = {library_of(s) for s in registry.integrators()}
    if library not in known:
        raise InputError(f"--library {library}: unknown library; known: {', '.join(sorted(known))}")
    mine = [r for r in rows if library_of(r.get("integrator", "")) == library]
    if mine:
        return mine, ""
    schemes = sorted(s for s in registry.integrators() if library_of(s) == library)
    return [], (f"no rows of its schemes in the store; `longtime matrix -p {problem} -i {','.join(schemes)}` "
                f"measures them")


def _statistical_lines(problem: str, ensembles: Iterable[dict[str, Any]], where: str) -> list[str]:
    """The statistical answer past the predictability horizon: the schemes whose ensemble
    distance to heyoka's is not told apart from the floor (longtime.measure.ensemble), or the
    command that measures them."""
    from longtime.measure.ensemble import distinguishable

    ok = [e for e in ensembles if e.get("problem") == problem and e.get("status") == Status.OK
          and e.get("distance") is not None]
    if not ok:
        return [f"  statistically: no ensemble of {problem} in the store; `longtime ensemble -p {problem}{where}` "
                f"measures which schemes keep the distribution the orbit visits"]
    same = sorted((e for e in ok if distinguishable(e["distance"], e.get("floor")) is False),
                  key=lambda e: e["distance"])
    text = (", ".join(f"{e['integrator']} (distance {e['distance']:.2g}, floor {e['floor']:.2g})" for e in same)
            if same else "none of the measured schemes")
    return [f"  statistically: {text} keep{'s' if len(same) == 1 else ''} the distribution heyoka's ensemble visits"]


def stored_recommendation(problem: str, error: float, horizon: float, db: str | None, run: str | None,
                          budget: float = 0.0, library: str | None = None):
    """The Recommendation from the store ``db`` (its rows of ``run``: an id, 'all', or by
    default every run), and the checks stored beside them; ``budget`` wall seconds for the
    runs that measure it at the horizon (``recommend``); ``library``: of that library's
    schemes only."""
    from pathlib import Path

    from longtime.core import registry
    from longtime.execution.store import Store, default_path

    if problem not in registry.problems():
        raise InputError(f"-p {problem}: unknown problem; known: {', '.join(sorted(registry.problems()))}")
    path = Path(db or default_path())
    if not path.exists():
        raise InputError(f"store {path}: no such file; `longtime matrix -p {problem} --db {path}` measures the cells "
                         f"to decide")
    store = Store(path, readonly=True)
    if run in (None, "all"):
        rows, checks, ensembles = store.rows(), store.checks(), store.ensembles()
    else:
        if not (str(run).isascii() and str(run).isdigit()):
            raise InputError(f"--run {run!r}: expected a run id (a positive integer) or 'all'")
        store.run(int(run))
        rows, checks, ensembles = store.rows(int(run)), store.checks(int(run)), store.ensembles(int(run))
    return recommend(rows, problem, error, horizon, db=str(store.path) if db else None,
                     known=registry.problems(), checks=checks, ensembles=ensembles,
                     growth=measured_growth(rows, problem, horizon), budget=budget,
                     library=library)
