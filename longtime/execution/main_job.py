"""The main job: the cells of a selection planned (or an interrupted run resumed), run and
timed into the store, then a few of the verdicts' predictions checked and the chaotic
problems' ensembles measured: what `longtime matrix` runs before its results page and
report (longtime.commands.matrix), and what a script runs with ``run_main_job``.

The job is one frozen value, ``MainJobSpec``; what it ran comes back as ``MainJobResult``:
the run id, its rows, its checks and its ensembles, read from the store."""
from __future__ import annotations

import contextlib
import dataclasses
import os
import sys
from dataclasses import dataclass, field
from typing import Any, Callable, Iterator, Mapping

from longtime.core import cli_args, phases, registry
from longtime.core.params import InputError
from longtime.core.progress import Progress
from longtime.execution import budget, ensembles
from longtime.execution.cells import Cell, check_size, expand
from longtime.execution.checks import run_checks
from longtime.execution.lifecycle import recorded_run
from longtime.execution.matrix import PHASES_FIELD, ExecOptions, complete_phases, run_matrix
from longtime.execution.pool import Queued, worker_pool
from longtime.execution.run_environment import this_machine
from longtime.execution.store import Store, as_read, machine_text, other_machine, recorded_machine
from longtime.predict.checks import CHECKS, check_budget, check_summary


@dataclass(frozen=True)
class Selection:
    """The cells of a new main job: ``problems`` x ``schemes`` (None: every default problem,
    every scheme) over the default sweep, ``sweeps`` (parameter: values) replacing a
    parameter's, ``sets`` (parameter: one value) and ``t_final`` (final times, one cell
    each; None: the problems'); fitted to the budget (longtime.execution.budget) unless
    ``full_sweep``, and refused where a cell is estimated too large unless ``allow_large``."""
    problems: tuple[str, ...] | None = None
    schemes: tuple[str, ...] | None = None
    sweeps: Mapping[str, Any] = field(default_factory=dict)
    sets: Mapping[str, Any] = field(default_factory=dict)
    t_final: tuple[float, ...] | None = None
    full_sweep: bool = False
    allow_large: bool = False


@dataclass(frozen=True)
class MainJobSpec:
    """One main job. ``selection``: its cells, or ``resume``: the run to finish (a run id, 0:
    the newest incomplete run of matrix or run) instead. ``executor`` and ``options`` run
    the cells into the store ``db`` (None: $LONGTIME_DB or longtime.sqlite) under the
    command line ``command``; the default options time by need (``ExecOptions.retime``).
    ``baseline``: a stored run the job is to be compared with, refused up front when it has
    no cell in common. ``checks``: how many of the verdicts' predictions are re-run (0:
    none); ``ensembles``: whether the chaotic problems' ensemble
    distances are measured. ``writable``: (flag, folder) pairs refused before the first
    cell where the folder cannot be written. ``list_moves``: each setting the budget moved on
    a line of its own as the job starts (else one line says how many and why)."""
    selection: Selection = field(default_factory=Selection)
    resume: int | None = None
    executor: str = "process"
    options: ExecOptions = field(default_factory=lambda: ExecOptions(retime="need"))
    db: str | None = None
    command: str = "matrix"
    baseline: int | None = None
    checks: int = CHECKS
    ensembles: bool = True
    writable: tuple[tuple[str, str], ...] = ()
    list_moves: bool = False


@dataclass(frozen=True)
class MainJobResult:
    """What a main job ran, read from its ``store`` after it: its ``run_id``, ``rows``,
    ``checks`` and ``ensembles``. ``ran`` is False for a resumed run whose cells were all
    stored (it is marked done; nothing ran). ``ahead``: what the ``ahead`` argument of
    ``run_main_job`` made (None where nothing was made)."""
    store: Store
    run_id: int
    rows: list[dict[str, Any]]
    checks: list[dict[str, Any]]
    ensembles: list[dict[str, Any]]
    ran: bool = True
    ahead: Any = None


def plan(selection: Selection, options: ExecOptions) -> tuple[list[Cell], list]:
    """The cells of ``selection`` under ``options``' limits, and what the budget moved."""
    problems = list(selection.problems) if selection.problems else registry.default_problems()
    schemes = list(selection.schemes) if selection.schemes else sorted(registry.integrators())
    cells = expand(problems, schemes, sweeps=dict(selection.sweeps), sets=dict(selection.sets),
                   t_final=list(selection.t_final) if selection.t_final is not None else None,
                   time_limit=options.time_limit, memory_limit=options.memory_limit, default_sweep=True)
    moves = []
    if not selection.full_sweep:
        # timing by need (the default) also bounds the library peers' chains; --timing all measures everything
        cells, moves = budget.fit(cells, given_t_final=selection.t_final is not None,
                                  given=frozenset(selection.sweeps) | frozenset(selection.sets),
                                  chained=options.retime == "need")
    check_size(cells, options.max_samples, options.memory_limit, allow_large=selection.allow_large)
    return cells, moves


def run_main_job(spec: MainJobSpec, progress: Progress | None = None,
                 ahead: Callable[..., Any] | None = None,
                 keep_workers: contextlib.ExitStack | None = None) -> MainJobResult:
    """Run ``spec``: plan its cells (or take a resumed run's left cells, the rows that lack a
    phase, and the cells its process ended inside, each again in a process of its own), run
    them into the store, re-run ``spec.checks`` predictions and measure the ensembles (each
    of these extra: a failure is a warning on stderr, the rows stay stored). ``progress``
    shows its phases (default: none). ``ahead(cells, run_id, timed_again=...)``, for a new run
    on the process executor, makes the work the pool's idle workers take (``task``) and is
    given each stored row (``add``), then the rows once timed (``timed``), after which its
    tasks run beside the checks: the results page's figures drawn ahead. With
    ``keep_workers``, the workers of the checks stay up in it after the job, as what ``ahead``
    made's ``workers``, for the page's last figures (they have drawn figures already: no
    process starts for them)."""
    shown = progress or Progress(on=False)
    options = spec.options
    for name, folder in spec.writable:  # refused before the store is opened (or made) and any cell runs
        cli_args.writable_folder(name, folder)
    if spec.resume is not None:
        store = Store(spec.db, create=False)  # resuming never creates an empty store
        if spec.resume < 0:
            raise InputError(f"--resume {spec.resume}: a run id is > 0 (or none: the newest incomplete run)")
        here = this_machine()
        run_id = spec.resume or store.latest_incomplete_run(("matrix", "run"), machine=here) \
            or store.latest_incomplete_run(("matrix", "run"))  # another machine's: refused below
        if run_id is None:
            raise InputError(f"--resume: no incomplete run in {store.path} (give a run id to pick one)")
        check_same_machine(store, store.run(run_id), here)  # an unknown id is an error, not "0 cells left"
        cells = store.pending(run_id)
        lacking = [row for _, row in store.incomplete_rows(run_id, PHASES_FIELD)]
        if lacking:  # rows stored before their timing processes or counts ran: run them
            phases_lacked = sorted({p for row in lacking for p in row[PHASES_FIELD]})
            print(f"run {run_id}: {len(lacking)} stored row(s) lack a phase ({', '.join(phases_lacked)}): "
                  f"it runs for them", file=sys.stderr)
        elif not cells:  # every planned row is stored (only its end mark was lost): nothing to run
            store.finish_run(run_id, "done")
            print(f"run {run_id}: every planned cell is stored; marked done", file=sys.stderr)
            return _result(store, run_id, ran=False)
        if cells:
            print(f"resuming run {run_id}: {len(cells)} cells left", file=sys.stderr)
        died = store.died_in(run_id)
        if died:  # perhaps killed, perhaps the cell's crash: each runs again in a process of its own
            print(f"run {run_id} ended inside {len(died)} cell(s): they run again one process each", file=sys.stderr)
            keys = {c.key for c in died}
            cells = [c for c in cells if c.key not in keys]
    else:
        with phases.phase("plan"), shown.phase("plan", detail="the cells of the selection, fitted to the budget",
                                                         announce=False):
            cells, moves = plan(spec.selection, options)
        say_moves(moves, spec.list_moves)
        store, run_id, died = Store(spec.db), None, []
    if spec.baseline is not None:
        store.run(spec.baseline)  # an unknown baseline is bad input, caught up front
        check_baseline(store, spec.baseline, cells)
    made = None
    with recorded_run(store, spec.command, cells, run_id) as run_id, contextlib.ExitStack() as workers_held:
        after = _AfterTiming(spec, options, workers_held, run_id)
        if spec.resume is None:
            print(f"run {run_id}: {len(cells)} cells into {store.path}", file=sys.stderr)
        if died:
            run_matrix(died, store, run_id, "isolated", options)
        pooled = spec.executor == "process" and spec.resume is None
        if ahead is not None and pooled:  # what workers that have no cell left do: the page's figures
            made = ahead(cells, run_id, timed_again=options.processes > 1)
            options = dataclasses.replace(options, idle_work=made.task)
        run_matrix(cells, store, run_id, spec.executor, options, progress=shown,
                   on_row=made.add if made is not None else None, on_timed=after.timed if pooled else None)
        if spec.resume is not None:  # the rows stored before the interruption, timed and counted
            complete_phases(store, run_id, options)
        # the rows as timed, read once: what the checks, the ensembles, the last figures and the result read
        with phases.phase("store"):
            rows = store.rows(run_id)
        # the checks' runs, the ensembles, the page's last figures
        queued = after.workers(rows)
        early = after.ensembles
        kept = keep_workers is not None and queued is not None and made is not None
        # the workers end with the checks, the ensembles and the figures, or with the page
        with contextlib.nullcontext() if kept else workers_held:
            if queued is not None:
                if made is not None:
                    made.timed(rows)
                    queued.take(made)
            if spec.checks:  # a few of the verdicts' predictions re-run past the rows' final times
                _check(store, run_id, rows, options, spec.checks, shown, queued.pool if queued is not None else None)
            if queued is not None:
                with phases.phase("ensembles"):  # waiting for the workers' ensembles and figures
                    queued.finish()
        if kept:
            made.workers = queued.pool
            keep_workers.enter_context(workers_held.pop_all())
        if spec.ensembles:  # chaotic problems: each scheme's ensemble distance to heyoka's
            try:
                with phases.phase("ensembles"), shown.phase("ensembles", detail="chaotic problems' ensembles"):
                    ensembles.run(store, run_id, rows, ahead=early)
            except (InputError, OSError, ValueError, RuntimeError) as exc:  # the rows are stored; this is extra
                print(f"warning: ensembles not measured: {type(exc).__name__}: {exc}", file=sys.stderr)
    return _result(store, run_id, ahead=made, rows=rows)


class _AfterTiming:
    """The workers of the work after the timing processes (the checks' runs, the ensembles,
    the page's last figures), held by ``held``: started as the timing processes end
    (``timed``, run_matrix's ``on_timed``), the chaotic problems' ensembles queued on them
    first (the longest tasks), while the rows are stored; or at ``workers``."""

    def __init__(self, spec: MainJobSpec, options: ExecOptions, held: contextlib.ExitStack, run_id: int):
        self.spec, self.options, self.held, self.run_id = spec, options, held, run_id
        self.queued: Queued | None = None
        self.started = False
        self.ensembles: ensembles.Ahead | None = None

    def timed(self, fresh: list[dict[str, Any]]) -> None:
        """The timing processes are done (``fresh``: the rows as they are being stored)."""
        self._start(lambda: as_stored(fresh, self.run_id), boot=True)

    def workers(self, rows: list[dict[str, Any]]) -> Queued | None:
        """The workers, started now where the timing processes did not (``rows``: as stored)."""
        if not self.started:
            self._start(lambda: rows, boot=False)
        return self.queued

    def _start(self, rows: Callable[[], list[dict[str, Any]]], boot: bool) -> None:
        self.started = True
        self.queued = self.held.enter_context(_workers(self.spec, self.options, boot=boot))
        if self.queued is not None and self.spec.ensembles:
            self.ensembles = ensembles.Ahead(rows())
            self.queued.take(self.ensembles)


def as_stored(rows: list[dict[str, Any]], run_id: int) -> list[dict[str, Any]]:
    """The rows of the chaotic problems (what the ensembles read) among ``rows``, as the store
    gives them back once it holds them (``store.as_read``), without reading the store."""
    chaotic = set(ensembles.chaotic_problems(rows))
    return [as_read(r, run_id) for r in rows if r["problem"] in chaotic]


@contextlib.contextmanager
def _workers(spec: MainJobSpec, options: ExecOptions, boot: bool = False) -> Iterator[Queued | None]:
    """On the process executor, once the timing processes are done: a pool of workers (one
    per core) for the checks' runs, each timed in a worker as the cells were, and the tasks
    queued beside them (``Queued``); else None (the checks and the ensembles run in this
    process). ``boot``: each worker started now (an interpreter and its imports), not at its
    first task."""
    if spec.executor != "process" or not (spec.checks or spec.ensembles):
        yield None
        return
    with worker_pool(options.workers(), options.run_spec()) as pool:
        if boot:
            for _ in range(options.workers()):
                pool.submit(os.getpid)
        yield Queued(pool)


def check_same_machine(store: Store, run: dict, here: dict) -> None:
    """Refuse to resume ``run`` (a record of ``store.runs``) on a machine other than the one it
    is recorded on (a run another machine's store brought in by ``longtime merge``): this
    machine's rows would be stored under the other machine's record."""
    recorded = recorded_machine(run)
    if other_machine(recorded, here):
        raise InputError(f"--resume: run {run['id']} of {store.path} ran on {machine_text(recorded)}, this is "
                         f"{machine_text(here)}: resume it on its own machine, or run the cells as a new run "
                         f"here (matrix without --resume)")


def _check(store: Store, run_id: int, rows: list[dict], options: ExecOptions, limit: int, shown: Progress,
           pool=None) -> None:
    """Re-run up to ``limit`` of the verdicts' predictions of the run's stored ``rows``
    (longtime.execution.checks), each within the rows' check budget, on ``pool``'s workers
    (None: in this process); the summary on stderr, a failure a warning."""
    try:
        with phases.phase("checks"), shown.phase("checks", detail=f"up to {limit} predictions re-run past the "
                                                                  f"rows' final times"):
            checks = run_checks(store, run_id, rows, options, limit=limit, budget_s=check_budget(rows), pool=pool)
    except (InputError, OSError, ValueError) as exc:  # the rows are stored; the checks are extra
        print(f"warning: predictions not checked: {type(exc).__name__}: {exc}", file=sys.stderr)
        checks = []
    if checks:
        print(f"checks: {check_summary(checks)}", file=sys.stderr)


def _result(store: Store, run_id: int, ran: bool = True, ahead: Any = None,
            rows: list[dict[str, Any]] | None = None) -> MainJobResult:
    """The job's result read from the store (``rows``: its rows, read already)."""
    rows = store.rows(run_id) if rows is None else rows
    return MainJobResult(store, run_id, rows, store.checks(run_id), store.ensembles(run_id), ran, ahead)


def say_moves(moves: list, full: bool = False) -> None:
    """What the default matrix's budget moved, on stderr as the run starts: one line
    (``budget.summary``), and with ``full`` each move on a line of its own (each moved row's
    message and the report name them too)."""
    if moves:
        where = ":" if full else " (`--full` lists them here; the report names each)"
        print(f"{budget.summary(moves)}; --full-sweep runs the default sweep as it is{where}", file=sys.stderr)
        if full:
            for m in moves:
                print(f"  {m.text()}", file=sys.stderr)


def check_baseline(store: Store, baseline: int, cells) -> None:
    """Refuse, before the first cell, a --baseline run that cannot be compared with the matrix:
    one with no stored row, or none of whose problem x scheme pairs the matrix runs (then no
    cell can be in common; the comparison of the cells themselves comes after the run)."""
    rows = store.rows(baseline)
    if not rows:
        raise InputError(f"--baseline {baseline}: run {baseline} has no stored row: nothing to compare with")
    pairs = {(r["problem"], r["integrator"]) for r in rows}
    if cells and not any((c.problem, c.integrator) in pairs for c in cells):
        have = ", ".join(f"{p} x {i}" for p, i in sorted(pairs)[:4]) + (", ..." if len(pairs) > 4 else "")
        raise InputError(f"--baseline {baseline}: run {baseline} has no cell in common with this matrix "
                         f"(it holds {have})")
