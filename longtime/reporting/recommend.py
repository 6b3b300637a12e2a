"""``longtime recommend``'s answer (``recommend``; from a store, ``stored_recommendation``):
the cheapest stored setting predicted to keep an error up to a horizon on one problem, with
its runner-up and evidence, or why the store determines no answer and the run that would
decide it."""
from __future__ import annotations

import shlex
from dataclasses import dataclass
from typing import Any, Iterable

from longtime.core.fmt import positive
from longtime.core.params import InputError
from longtime.core.rowtext import setting
from longtime.predict.checks import CHECK_COST_FACTOR, CHECK_ERROR_FACTOR, check_holds
from longtime.predict.decision import Decision, decide, deciding_run, predictability
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
    limit = predictability(mine, error) if m.solution else None
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


def stored_recommendation(problem: str, error: float, horizon: float, db: str | None, run: str | None):
    """The Recommendation from the store ``db`` (its rows of ``run``: an id, 'all', or by
    default every run), and the checks stored beside them."""
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
                     known=registry.problems(), checks=checks, ensembles=ensembles)
