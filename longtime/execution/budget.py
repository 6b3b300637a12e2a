"""The default matrix's budget: each default cell's integration is estimated before it runs,
and a pair whose default sweep would pass the budget runs fewer settings (a scheme that
chooses its own steps) or a shorter horizon (a fixed-step scheme).

The estimate is the size ``check_size`` refuses oversized runs by (steps of the cell's dt, or
of the problem's default step for a scheme that chooses its own), times a cost per step:
``step_cost`` x the state dimension x COMPONENT_STEP_S in compiled code, plus the seconds
``python_step_s`` a step spends in Python (a peer stepped by a Python loop, scipy's
RK45: about a tenth of a millisecond a step whatever the problem; a library's compiled loop
calling a Python rhs, scipy's DOP853: 3e-5 s). It is rough, a factor
of a few either way, and only decides which pairs move.

What moves: the sweep of a fixed-step pair whose costliest cell is estimated above
CELL_BUDGET_S runs at the longest of the shorter horizons HORIZON_FRACTIONS of its problem's
sweep horizon at which every cell of the sweep fits (never shorter than its largest step);
the long-time cell of such a pair (a problem's ``long_t_final``) is left out when it is
estimated above LONG_CELL_BUDGET_S. Every pair keeps its sweep's rows; nothing else changes.
Each moved cell carries a note (``Cell.note``, kept in its row's message) naming the setting
it had, and the report lists them; ``longtime matrix --full-sweep`` runs the default sweep as
it is.

A scheme that chooses its own steps (``adaptive``: a library peer, scipy's, SUNDIALS' and
diffrax's, with its own ``cell_budget_s`` so that its many rows do not lengthen the main job
much, or an adaptive scheme, under CELL_BUDGET_S) is never moved to a shorter horizon, so
that it is compared with the other schemes over the same run: the settings of its sweep
estimated above its budget are left out instead (a scheme of order p at tolerance tol is
estimated at the problem's default step's count times PEER_TOL ** (1 / 5) / tol ** (1 / p):
a 5th-order method at PEER_TOL takes about the default step; p is 5 where the method's order
is variable), always keeping its cheapest setting. Where even that one is estimated above
CELL_BUDGET_S, it runs the horizon under a time limit of SLOW_LIMIT_S (``Cell.time_limit``)
and the others are left out: a run that cannot reach the horizon within it is a ``timeout``
row saying how far it got in how many seconds, which "Which library" shows as too slow (a
scheme that stops at a CPU bound stops sooner, where its pace puts its end past PACE_FACTOR
times that limit: ``Cell.pace``). A scheme whose run cannot be stopped at a time limit
(``stops_at_deadline`` False: CVODE's and diffrax's one compiled call) is skipped there
instead, its rows giving the estimate.
Horizons and sweeps given on the command line (--t-final, --dt, ...) are never moved.

Chained (CHAINED, under timing by need, the main job's default): the cells of the library
peers whose run stops at a CPU bound (``stops_at_cpu_bound``: scipy's) are marked
``Cell.bound`` = ``need.FACTOR``, and each (problem, library, t_final) runs as one chain in
one worker, cheapest estimated first (longtime.execution.batches): once a setting keeps
"Which library"'s target (``need.TARGET``), each later one stops at FACTOR times that
setting's CPU seconds (a ``timeout`` row that says so: it cannot be the library's
cheapest), or sooner, once it has spent that setting's CPU seconds, where its pace puts its
end past ``limits.CHAIN_PACE`` times that bound (the row says so too). ``--timing all``
(measure everything) and --full-sweep run every setting to its end.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any, Iterable

from longtime.core import registry
from longtime.core.fmt import number
from longtime.core.status import TOO_SLOW
from longtime.core.stepping import FixedStepIntegrator
from longtime.execution.cells import Cell
from longtime.execution.sizes import cell_size
from longtime.predict.need import FACTOR, TARGET, library_of

# seconds a compiled RK4 step costs per state component (measured on the main job's problems:
# docs/performance.md)
COMPONENT_STEP_S = 3e-8
# the estimated seconds of one run of a default cell (its timed repeats come on top)
CELL_BUDGET_S = 5.0
# the estimated seconds of one run of a long-time cell (a problem's paper-scale final time)
LONG_CELL_BUDGET_S = 30.0
# the shorter horizons a moved sweep may take, as fractions of the problem's sweep horizon
HORIZON_FRACTIONS = (0.5, 0.2, 0.1, 0.05, 0.02, 0.01)
# the tolerance at which a 5th-order adaptive peer's steps are estimated as the problem's default
# step's (a rough size: the runs of kepler and toda take from a third to ten times as many)
PEER_TOL = 1e-10
# the wall seconds a cell takes besides its runs (the problem and its kernels loaded, the
# metrics), as ``cell_seconds`` counts them
CELL_OVERHEAD_S = 0.5
# the start of every note the budget leaves in a row's message (the report finds them by it)
NOTE = "budget:"
# how a move changes a pair: its sweep to a shorter t_final, its long-time cell left out,
# fewer settings, only its cheapest under SLOW_LIMIT_S, or skipped as too slow; and a
# library's peers on a problem run as a chain under a CPU bound (the module's text)
SHORTER, LONG_OUT, FEWER, LIMITED, SKIPPED = "shorter", "long-time cell out", "fewer", "limited", "skipped"
CHAINED = "chained"
# the time limit of a run of that cheapest setting: one cell's budget, so that a library too slow
# for the default matrix costs it no more than one cell (the estimates are rough, off by a factor
# of a few either way, and the limit is on the wall clock of a possibly loaded machine)
SLOW_LIMIT_S = CELL_BUDGET_S
# such a run of a scheme that stops on its pace (``stops_at_cpu_bound``) stops once its pace
# (its CPU seconds per unit of t, after its first CPU second: ``peer_common.Pace``) puts its end
# past this many times SLOW_LIMIT_S: it would pass its limit anyway, and where a library is too
# slow, the limit's seconds of it confirm only that. The pace of a default cell's run after
# its first second puts its end within x1.25 of where it ends (docs/performance.md): a run
# that ends within its limit is stopped only if its pace quadruples past its first second
PACE_FACTOR = 4.0
# the time limit of every other default cell of a library peer (``peer_limited``): its estimate
# can be off by far more than a factor of a few (a peer's adaptive control, or its JIT compile,
# which the limit counts), and a run that cannot be stopped (CVODE's, diffrax's one compiled
# call) would otherwise go on to the run's --time-limit; past it the cell is a ``timeout`` row, or
# is killed at its hard limit (longtime.execution.limits) where its run cannot stop itself
PEER_LIMIT_S = 60.0


@dataclasses.dataclass(frozen=True)
class Move:
    """One pair's setting that the budget moved: ``setting`` what it was and is now,
    ``reason`` the estimate that moved it, ``kind`` how (SHORTER, LONG_OUT, FEWER, LIMITED or SKIPPED)."""
    problem: str
    integrator: str
    setting: str
    reason: str
    kind: str

    def text(self) -> str:
        return f"{self.problem} x {self.integrator}: {self.setting} ({self.reason})"


def run_seconds(cell: Cell, dims: dict[str, int] | None = None) -> float:
    """The estimated seconds of one run of ``cell``'s integration (see the module's text)."""
    dim, steps, _ = cell_size(cell, {} if dims is None else dims)
    icls = registry.integrator_class(cell.integrator)
    tol = cell.integrator_settings.get("tol")
    if adaptive(cell.integrator) and tol and "dt" not in cell.integrator_settings:
        steps *= PEER_TOL ** 0.2 / float(tol) ** (1.0 / (icls.order or 5))
    return steps * (icls.python_step_s + dim * icls.step_cost * COMPONENT_STEP_S)


def cell_seconds(cell: Cell, timing: Any, dims: dict[str, int] | None = None) -> float:
    """The estimated wall seconds of ``cell`` in a worker: CELL_OVERHEAD_S, its warm-up run
    and its timed runs as ``timing`` (a longtime.core.timing.Timing) repeats them; a skipped
    cell costs nothing. As rough as ``run_seconds``: the progress line's time left weighs
    the cells by it."""
    if cell.skip_reason:
        return 0.0
    try:
        run = run_seconds(cell, dims)
    except Exception:  # a problem that cannot be built here fails in its worker, in its row
        return CELL_OVERHEAD_S
    if not math.isfinite(run):
        return CELL_OVERHEAD_S
    timed = run if run > timing.ONCE_ABOVE else max(timing.least_runs * run, min(timing.min_time, timing.repeats * run))
    return CELL_OVERHEAD_S + run + timed


def adaptive(scheme: str) -> bool:
    """Whether ``scheme`` chooses its own steps (a library peer or an adaptive scheme): its
    sweep is never moved to a shorter horizon, its costly settings are left out instead."""
    icls = registry.integrator_class(scheme)
    return icls.cell_budget_s is not None or not issubclass(icls, FixedStepIntegrator)


def cell_budget(scheme: str) -> float:
    """The estimated seconds one run of a default cell of ``scheme`` may take."""
    return registry.integrator_class(scheme).cell_budget_s or CELL_BUDGET_S


def fit(cells: list[Cell], given_t_final: bool = False, given: frozenset[str] = frozenset(),
        chained: bool = False) -> tuple[list[Cell], list[Move]]:
    """The default matrix's ``cells`` (``cells.expand`` with ``default_sweep``) within the
    budget, and what it moved. ``given_t_final``: the final times were given (nothing moves
    then but the long-time cells, which such a matrix does not have). ``given``: the
    parameters whose values were given (a peer's settings of a parameter given are never
    left out). ``chained``: the peers' cells that stop at a CPU bound run as chains (the
    module's text)."""
    dims: dict[str, int] = {}
    groups: dict[tuple, list[int]] = {}
    for i, c in enumerate(cells):
        if not c.skip_reason:
            key = (c.problem, repr(sorted(c.problem_settings.items())), c.integrator)
            groups.setdefault(key, []).append(i)
    out: list[Cell | None] = list(cells)
    moves: list[Move] = []
    for (problem, _, scheme), members in groups.items():
        pcls = registry.problem_class(problem)
        main = pcls.sweep_t_final or pcls.default_t_final
        long_tf = pcls.long_t_final if pcls.long_t_final and pcls.long_t_final != main else None
        sweep = [i for i in members if long_tf is None or cells[i].t_final != long_tf]
        long_ = [i for i in members if i not in sweep]
        worst = max((run_seconds(cells[i], dims) for i in sweep), default=0.0)
        budget = cell_budget(scheme)
        if adaptive(scheme):  # a library peer or an adaptive scheme: fewer settings, the same horizon
            swept = set(registry.integrator_class(scheme).sweep)
            if not given_t_final and not (given & swept) and worst > budget:
                _fewer_settings(problem, scheme, sweep, cells, out, moves, dims, budget)
        elif not given_t_final and worst > budget and all(cells[i].t_final == main for i in sweep):
            horizon = _shorter_horizon([cells[i] for i in sweep], main, dims)
            if horizon is not None:
                setting = f"t_final {number(main)} -> {number(horizon)}"
                reason = (f"about {worst:.3g} s a run at t_final {number(main)}, over the default "
                          f"matrix's {budget:g} s a cell")
                moves.append(Move(problem, scheme, setting, reason, SHORTER))
                note = f"{NOTE} {setting} ({reason}; --full-sweep runs {number(main)})"
                for i in sweep:
                    out[i] = dataclasses.replace(cells[i], t_final=horizon, note=note)
        for i in long_:
            cost = run_seconds(cells[i], dims)
            if cost > LONG_CELL_BUDGET_S:
                setting = f"long-time cell at t_final {number(cells[i].t_final)} left out"
                reason = f"about {cost:.3g} s a run, over the {LONG_CELL_BUDGET_S:g} s of a long-time cell"
                moves.append(Move(problem, scheme, setting, reason, LONG_OUT))
                out[i] = None
                note = f"{NOTE} {setting} ({reason}; --full-sweep runs it)"
                _say(out, sweep, note)  # the pair's rows say it
    kept = peer_limited([c for c in out if c is not None])
    return (_chained(kept, moves) if chained else kept), moves


def peer_limited(cells: list[Cell]) -> list[Cell]:
    """``cells`` with each library peer's that has no time limit of its own under PEER_LIMIT_S."""
    return [dataclasses.replace(c, time_limit=PEER_LIMIT_S, limit_reason="of a library peer's cell")
            if c.time_limit is None and not c.skip_reason and registry.integrator_class(c.integrator).cell_budget_s
            else c for c in cells]


def _chained(cells: list[Cell], moves: list[Move]) -> list[Cell]:
    """``cells`` with the library peers' that stop at a CPU bound marked ``bound`` = FACTOR, a
    CHAINED move per problem and library."""
    out, chains = [], {}
    for c in cells:
        icls = registry.integrator_class(c.integrator)
        if c.skip_reason or not icls.stops_at_cpu_bound or library_of(c.integrator) == "longtime":
            out.append(c)
            continue
        out.append(dataclasses.replace(c, bound=FACTOR))
        chains.setdefault((c.problem, library_of(c.integrator)), set()).add(c.integrator)
    for (problem, library), schemes in sorted(chains.items()):
        setting = f"{', '.join(sorted(schemes))} run as one chain, cheapest estimated first"
        reason = (f"a setting stops at x{FACTOR:g} the CPU of an earlier one that keeps {TARGET:g}: it cannot be "
                  f"{library}'s cheapest; --timing all runs it to the end")
        moves.append(Move(problem, library, setting, reason, CHAINED))
    return out


def _fewer_settings(problem: str, scheme: str, sweep: list[int], cells: list[Cell], out: list,
                    moves: list[Move], dims: dict[str, int], budget: float) -> None:
    """Leave out the cells of a peer's ``sweep`` estimated above ``budget`` (all but the
    cheapest when none fits); the cells kept say which were left out."""
    cost = {i: run_seconds(cells[i], dims) for i in sweep}
    over = [i for i in sweep if cost[i] > budget]
    if len(over) == len(sweep):
        cheapest = min(sweep, key=lambda i: cost[i])
        if cost[cheapest] > CELL_BUDGET_S:  # past what a cell of the suite's own may take: too slow here
            _too_slow(problem, scheme, sweep, cells, out, moves, cost)
            return
        over.remove(cheapest)
    if not over:
        return
    left = ", ".join(setting_text(cells[i]) for i in over)
    horizon = _horizon_text(cells[over[0]])
    setting = f"{left} left out"
    reason = (f"about {max(cost[i] for i in over):.3g} s a run at t_final {horizon}, over the "
              f"{budget:g} s a cell of a library peer")
    moves.append(Move(problem, scheme, setting, reason, FEWER))
    note = f"{NOTE} {setting} ({reason}; --full-sweep runs them)"
    for i in over:
        out[i] = None
    _say(out, sweep, note)


def _say(out: list, members: list[int], note: str) -> None:
    """Add ``note`` to the notes of the cells of ``members`` still in ``out``."""
    for i in members:
        if out[i] is not None:
            out[i] = dataclasses.replace(out[i], note="; ".join(n for n in (out[i].note, note) if n))


def _horizon_text(cell: Cell) -> str:
    return number(cell.t_final) if cell.t_final is not None else "the default"


def _too_slow(problem: str, scheme: str, sweep: list[int], cells: list[Cell], out: list, moves: list[Move],
              cost: dict[int, float]) -> None:
    """A scheme none of whose settings is estimated to run the horizon within CELL_BUDGET_S:
    its cheapest setting runs the horizon under a time limit of SLOW_LIMIT_S (past it a
    ``timeout`` row that says how far it got, so that a measured row, not the estimate, says
    whether it is too slow; stopped sooner where its pace puts its end past PACE_FACTOR times
    that limit), the others are left out, never a shorter horizon. A scheme whose
    run cannot be stopped at its deadline (``stops_at_deadline``) would run on past that
    limit: its cells are skipped rows giving the estimate instead. --full-sweep runs them
    all without either."""
    cheapest = min(sweep, key=lambda i: cost[i])
    reason = (f"{TOO_SLOW} about {cost[cheapest]:.3g} s a run estimated for t_final {_horizon_text(cells[cheapest])} "
              f"at its cheapest setting ({setting_text(cells[cheapest])}), over the default matrix's "
              f"{CELL_BUDGET_S:g} s a cell")
    if not registry.integrator_class(scheme).stops_at_deadline:
        moves.append(Move(problem, scheme, "left out of the default matrix", reason, SKIPPED))
        for i in sweep:
            out[i] = dataclasses.replace(cells[i], skip_reason=f"{reason} (its run cannot be stopped at a time "
                                                                f"limit); --full-sweep runs it")
        return
    others = [i for i in sweep if i != cheapest]
    left = f"; {', '.join(setting_text(cells[i]) for i in others)} left out" if others else ""
    setting = f"{setting_text(cells[cheapest])} under a time limit of {SLOW_LIMIT_S:g} s{left}"
    moves.append(Move(problem, scheme, setting, reason, LIMITED))
    for i in others:
        out[i] = None
    paced = PACE_FACTOR if registry.integrator_class(scheme).stops_at_cpu_bound else None
    out[cheapest] = dataclasses.replace(cells[cheapest], time_limit=SLOW_LIMIT_S,
                                        limit_reason="for a setting estimated too slow", pace=paced)
    _say(out, [cheapest], f"{NOTE} {setting} ({reason}; --full-sweep runs {'them' if others else 'it'} unlimited)")


def setting_text(cell: Cell) -> str:
    """A cell's settings as text: 'tol=1e-13'."""
    return " ".join(f"{k}={v:.3g}" if isinstance(v, float) else f"{k}={v}"
                    for k, v in sorted(cell.integrator_settings.items())) or "the default setting"


def _shorter_horizon(sweep: list[Cell], main: float, dims: dict[str, int]) -> float | None:
    """The longest horizon of HORIZON_FRACTIONS x ``main`` at which every cell of ``sweep``
    fits the budget (else the shortest one allowed), none shorter than a fixed step of the
    sweep; None when no shorter horizon is allowed."""
    pcls = registry.problem_class(sweep[0].problem)
    fixed = issubclass(registry.integrator_class(sweep[0].integrator), FixedStepIntegrator)
    largest_step = max((float(c.integrator_settings.get("dt") or pcls.default_dt) for c in sweep), default=0.0)
    allowed = []
    for f in HORIZON_FRACTIONS:
        horizon = pcls.t0 + f * (main - pcls.t0)
        if fixed and horizon - pcls.t0 < largest_step * (1 + 1e-9):
            break
        allowed.append(_round(horizon))
    budget = cell_budget(sweep[0].integrator)
    for horizon in allowed:
        if all(run_seconds(dataclasses.replace(c, t_final=horizon), dims) <= budget for c in sweep):
            return horizon
    return allowed[-1] if allowed else None


def _round(t: float) -> float:
    """``t`` to 12 significant digits: 0.2 x 1000 is 200, not 200.00000000000003."""
    return float(f"{t:.12g}") if math.isfinite(t) else t


def notes(rows: Iterable[dict[str, Any]]) -> dict[tuple[str, str], str]:
    """(problem, scheme) -> the budget's note in its rows' messages, for the report."""
    out: dict[tuple[str, str], str] = {}
    for r in rows:
        message = r.get("message") or ""
        at = message.find(NOTE)
        if at >= 0:
            out.setdefault((r["problem"], r["integrator"]), message[at + len(NOTE):].strip())
    return out


def summary(moves: list[Move]) -> str:
    """What the budget moved, in one line: how many pairs' sweeps run to a shorter horizon,
    by the budget they passed, how many pairs run fewer settings, how many run only their
    cheapest setting under SLOW_LIMIT_S, how many are skipped as too slow, and how many
    long-time cells are left out."""
    shorter: dict[float, int] = {}
    for m in moves:
        if m.kind == SHORTER:
            budget = cell_budget(m.integrator)
            shorter[budget] = shorter.get(budget, 0) + 1
    fewer, limited, skipped, long_out = (sum(m.kind == k for m in moves) for k in (FEWER, LIMITED, SKIPPED, LONG_OUT))
    parts = []
    if shorter:
        over = ", ".join(f"{n} over {b:g} s" for b, n in sorted(shorter.items(), key=lambda kv: -kv[0]))
        parts.append(f"{sum(shorter.values())} pair(s)' sweeps to a shorter t_final (a run estimated "
                     f"over its cell budget: {over})")
    if fewer:
        parts.append(f"{fewer} pair(s) run fewer settings (the settings estimated over their cell budget left out)")
    if limited:
        parts.append(f"{limited} pair(s) run only their cheapest setting under a time limit of {SLOW_LIMIT_S:g} s "
                     f"(estimated over {CELL_BUDGET_S:g} s)")
    if skipped:
        parts.append(f"{skipped} pair(s) skipped (estimated over {CELL_BUDGET_S:g} s at their cheapest setting, and "
                     f"their run cannot be stopped at a time limit)")
    if long_out:
        parts.append(f"{long_out} long-time cell(s) left out (a run estimated over {LONG_CELL_BUDGET_S:g} s)")
    chained = sum(m.kind == CHAINED for m in moves)
    if chained:
        parts.append(f"{chained} (problem, library) chain(s) of peers run cheapest first, a later setting stopped "
                     f"at x{FACTOR:g} the CPU of one that keeps {TARGET:g} (--timing all runs them to the end)")
    moved = len(moves) - chained
    return f"the default matrix's budget moved {moved} setting(s): " + "; ".join(parts)
