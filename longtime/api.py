"""longtime from Python (docs/api.md): ``solve`` one cell, ``sweep`` a matrix into a pandas
DataFrame, ``convergence`` (the observed order of a sweep), ``work_precision`` (the
Pareto table) and ``main_job`` (`longtime matrix`'s run, results page and report). A
problem or a scheme is a registered name, a class or an instance: a class defined in memory
is registered for the session (``registry.register``, checked as an entry point is) and
found by the process executor's workers too.

``longtime run`` is a layer over this module: its cells come from ``cells_for`` and run
through ``run_cells``, as ``sweep``'s do, and ``solve`` runs a cell with the arguments the
serial executor passes, so ``solve(...).row`` is the row ``longtime run --format json``
prints (timings aside).
"""
from __future__ import annotations

import contextlib
import shlex
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from longtime.core import registry
from longtime.core.integrator import Integrator
from longtime.core.params import MAX_SECONDS, InputError, check_number, check_values
from longtime.core.problem import Problem
from longtime.core.roles import ROW_PARAMETERS
from longtime.core.timing import Timing
from longtime.execution import calibration, limits
from longtime.execution.answers import DEFAULT_BUDGET_S
from longtime.execution.cells import (
    DEFAULT_MAX_SAMPLES,
    DEFAULT_TIME_LIMIT,
    Cell,
    check_set_keys,
    check_size,
    expand,
    run_cell,
)
from longtime.measure.orders import Order

# the memory a cell may use unless memory_limit= says otherwise: longtime run's default
DEFAULT_MEMORY_LIMIT = f"{limits.MEMORY_SHARE:.0%}"
# ``schemes=ALL`` (solve, sweep, ...): every registered scheme that applies to the problems
ALL = "all"


def check_options(*, max_samples: Any, repeats: Any, min_time: Any, time_limit: Any, memory_limit: Any,
                  allow_large: Any, jobs: Any = 0, executor: str | None = None, default_sweep: Any = False,
                  progress: Any = False) -> int | None:
    """The options of ``solve`` and ``sweep``, checked as the command line checks its flags;
    returns the memory limit in bytes (None: none)."""
    check_number("max_samples", max_samples, integer=True, minimum=2)
    check_number("repeats", repeats, integer=True, minimum=1)
    check_number("min_time", min_time, minimum=0, maximum=MAX_SECONDS)
    check_number("time_limit", time_limit, minimum=0, maximum=MAX_SECONDS, none=True)  # 0 or None: no limit
    check_number("jobs", jobs, integer=True, minimum=0)
    for name, value in (("allow_large", allow_large), ("default_sweep", default_sweep), ("progress", progress)):
        if not isinstance(value, (bool, np.bool_)):
            raise InputError(f"{name}={value!r} is not valid: expected True or False")
    if executor is not None:
        from longtime.execution.matrix import get_executor

        get_executor(executor)
    return limits.memory_argument_api(memory_limit)


# ------------------------------------------------------------------ names, classes, instances
def _registered_name(cls: type) -> str:
    """The name ``cls`` is found under: its registered name, else registered now."""
    found = registry.problems() if issubclass(cls, Problem) else registry.integrators()
    own = vars(cls).get("name")
    if own and found.get(own) is cls:
        return own
    return registry.register(cls)


def resolve(thing: Any, kind: str) -> tuple[str, dict[str, Any]]:
    """(registered name, settings) of a problem or scheme given as a name, a class or an
    instance (whose settings that differ from the defaults are carried over)."""
    base = Problem if kind == "problem" else Integrator
    if isinstance(thing, str):
        return thing, {}
    if isinstance(thing, type) and issubclass(thing, base):
        return _registered_name(thing), {}
    if isinstance(thing, base):
        cls = type(thing)
        given = {k: v for k, v in thing.settings.items()
                 if k in cls.parameters and v is not None and v != cls.parameters[k].default}
        return _registered_name(cls), given
    raise InputError(f"{kind} {thing!r}: expected a registered name, a subclass of longtime.{base.__name__} "
                     f"or an instance of one")


def cells_for(problems: Any, schemes: Any, t_final: Any = None, settings: dict[str, Any] | None = None,
              *, strict: bool = False, default_sweep: bool = False, caller: str = "sweep",
              limits: dict[str, Any] | None = None) -> list[Cell]:
    """The cells of problems x schemes x settings, through ``cells.expand`` as the command
    line builds them: a parameter with a flag of its own (dt, tol, eps_res, order) or given
    as several values is swept (``sweeps``); any other single value is a ``--set``.

    Every argument is checked here, before any cell runs, by the rules of
    longtime.core.params (the command line's): a list is not empty; a keyword is a
    parameter of a selected problem or scheme (else the closest names and the full list);
    a value has its parameter's type (a number is not a string, nor a bool) and range; a
    final time is a finite number. ``caller`` names the function in the messages.
    ``schemes="all"``: every registered scheme, each on the problems it applies to (the
    pairs it cannot treat, or whose package is not installed, are left out, not skipped rows)."""
    every = isinstance(schemes, str) and schemes == ALL
    if every:
        schemes = sorted(registry.integrators())
    pnames, inames, sets, sweeps = [], [], {}, {}
    for p in check_values("problems", problems):
        name, given = resolve(p, "problem")
        pnames.append(name)
        sets.update(given)
    for s in check_values("schemes", schemes):
        name, given = resolve(s, "scheme")
        inames.append(name)
        sets.update(given)
    registry.check_names("problem", pnames)
    registry.check_names("integrator", inames)
    if t_final is not None:
        t_final = [check_number("t_final", v) for v in check_values("t_final", t_final)]
        t_final = t_final[0] if len(t_final) == 1 else t_final
    settings = dict(settings or {})
    check_set_keys(settings, pnames, inames, spelling=caller + ": keyword {key}")
    classes = [registry.problem_class(n) for n in pnames] + [registry.integrator_class(n) for n in inames]
    for key, value in settings.items():
        values = check_values(key, value)
        for cls in classes:
            if key in cls.parameters:
                for v in values:
                    cls.parameters[key].parse(key, v, strict=True)
        if key in ROW_PARAMETERS or len(values) != 1:
            sweeps[key] = values
            sets.pop(key, None)  # the keyword overrides an instance's own setting
        else:
            sets[key] = values[0]
    cells = expand(pnames, inames, sweeps=sweeps, t_final=t_final, sets=sets, strict=strict and not every,
                   default_sweep=default_sweep, **(limits or {}))  # a plugin's checks under a cell's limits
    return [c for c in cells if not c.skip_reason] if every else cells


def run_cells(cells: list[Cell], *, store=None, command: str = "", executor: str = "serial",
              options=None, progress: bool = False) -> tuple[list[dict], int | None]:
    """Run ``cells`` on ``executor``, each row appended to ``store`` (a Store, a path or None)
    as ``longtime run`` does: the plan first, each row as it finishes, the run marked done,
    or interrupted (an input error as it starts discards it). Returns (rows, run id)."""
    from longtime.execution.lifecycle import recorded_run
    from longtime.execution.matrix import ExecOptions, run_matrix
    from longtime.execution.store import Store

    options = options or ExecOptions()
    if store is not None and not isinstance(store, Store):
        store = Store(store)
    with recorded_run(store, command, cells) as run_id:
        rows = run_matrix(cells, store, run_id, executor, options, progress=progress)
    return rows, run_id


# ------------------------------------------------------------------ solve
@dataclass
class Result:
    """One cell: ``row`` (the fields of ``longtime run --format json``), the samples ``t``
    (n,) and ``u`` (n, dim), ``invariants`` (name -> values at ``t``) and ``reference`` (the
    reference states at ``t[:len(reference)]``, the times up to which it is trusted; None
    without a trusted reference). ``t`` and ``u`` are None when the cell failed before it
    ran (``row["message"]`` says why)."""

    row: dict[str, Any]
    t: np.ndarray | None = None
    u: np.ndarray | None = None
    invariants: dict[str, np.ndarray] = field(default_factory=dict)
    reference: np.ndarray | None = None
    problem: Problem | None = None
    scheme: Integrator | None = None

    @property
    def status(self) -> str:
        return self.row["status"]

    def __repr__(self) -> str:
        r = self.row
        return (f"Result({r['problem']} x {r['integrator']}: {r['status']}, {len(self.t) if self.t is not None else 0} "
                f"samples, l2_error={r.get('l2_error')!r})")


def solve(problem: Any, scheme: Any, *, t_final: float | None = None, max_samples: int = DEFAULT_MAX_SAMPLES,
          repeats: int = Timing.repeats, min_time: float = Timing.min_time,
          time_limit: float | None = DEFAULT_TIME_LIMIT, allow_large: bool = False,
          memory_limit: float | str | None = DEFAULT_MEMORY_LIMIT, processes: int | None = None,
          cost: str = "time", **settings: Any) -> Result:
    """Run ``scheme`` on ``problem`` once (timed as every row is) and return its Result.
    ``settings`` are the parameters of --dt, --tol, --eps-res, --order and --set (one value
    each). A pair that cannot run (a capability missing) raises InputError naming it.
    ``memory_limit`` is longtime run's --memory-limit: GiB, a share of the machine's memory
    ("25%"), 0 or None for none; this process is held to it while the cell runs.
    ``processes`` (default ``$LONGTIME_PROCESSES`` or 3): the processes that time it
    (longtime.execution.processes: this one and ``processes - 1`` fresh ones).
    ``cost="instructions"`` also counts the integration under Valgrind (``--cost
    instructions``: the row's ``instructions`` and ``instructions_per_step``)."""
    from longtime.execution.child import RunSpec
    from longtime.execution.matrix import check_cost
    from longtime.execution.processes import across_processes, check_processes, default_processes
    from longtime.reporting.report import complete

    memory = check_options(max_samples=max_samples, repeats=repeats, min_time=min_time, time_limit=time_limit,
                           memory_limit=memory_limit, allow_large=allow_large)
    check_cost(cost)
    processes = default_processes() if processes is None else check_processes(processes, "processes")
    cells = cells_for(problem, scheme, t_final, settings, strict=True, caller="solve",
                      limits={"time_limit": time_limit or None, "memory_limit": memory})
    if len(cells) != 1:
        raise InputError(f"solve runs one cell; these settings give {len(cells)}: give one value per "
                         f"parameter (longtime.sweep takes lists)")
    check_size(cells, max_samples, memory, allow_large=allow_large)
    keep: dict[str, Any] = {}
    here = calibration.here()  # the machine's speed beside the time, as every stored row has it
    here.start()
    t0 = time.time()
    timing = Timing(repeats=repeats, min_time=min_time).per_process(processes)
    with limits.memory_limited(memory):
        row = run_cell(cells[0], max_samples, timing=timing, time_limit=time_limit or None, keep=keep)
    if not cells[0].skip_reason:
        here.cell(row, t0, time.time())
        calibration.take_points(row)  # the calibrations themselves belong to a stored run
    across_processes([(cells[0], row)], processes, RunSpec(max_samples, timing, time_limit or None, None))
    if cost == "instructions":  # after the timed runs: Valgrind's process times nothing
        from longtime.execution.valgrind import instruction_fields

        row.update(instruction_fields([(cells[0], row)], max_samples, time_limit or None)[cells[0].key])
    row = complete(row)
    traj = keep.get("trajectory")
    if traj is None:
        return Result(row, problem=keep.get("problem"), scheme=keep.get("integrator"))
    prob = keep["problem"]
    return Result(row, traj.t, traj.u, prob.invariants(traj.t, traj.u), keep.get("reference"), prob,
                  keep["integrator"])


# ------------------------------------------------------------------ sweep
def sweep(problems: Any, schemes: Any, *, t_final: Any = None, executor: str = "process", jobs: int = 0,
          store=None, max_samples: int = DEFAULT_MAX_SAMPLES, repeats: int = Timing.repeats,
          min_time: float = Timing.min_time, time_limit: float | None = DEFAULT_TIME_LIMIT,
          default_sweep: bool = False, allow_large: bool = False,
          memory_limit: float | str | None = DEFAULT_MEMORY_LIMIT, processes: int | None = None,
          cost: str = "time", progress: bool = True, **sweeps: Any):
    """The matrix problems x schemes x every value of each parameter (a value or a list) as
    a pandas DataFrame, one row per cell. ``executor`` is serial, process (default), isolated
    or dask; ``store`` a path (or Store) appends the run to that store as ``longtime run``
    does, and the rows then come back as stored (with ``run_id``). ``memory_limit`` is
    longtime run's --memory-limit (GiB, "25%", 0 or None for none). ``processes`` (default
    ``$LONGTIME_PROCESSES`` or 3): the processes that time each cell, as ``--processes``.
    ``cost="instructions"`` also counts each ok cell's integration under Valgrind, all cells
    in one Valgrind process (``--cost instructions``). ``progress`` shows the cells' progress
    on stderr as ``longtime run`` does (a bar on a terminal; elsewhere a line as each phase
    starts, one every 30 s and one as it ends); ``progress=False``: nothing.

    A script that calls ``sweep`` outside ``if __name__ == "__main__":`` would be run again
    by each worker of a local Dask cluster (spawned by multiprocessing): there the cells
    run serially, and one line on stderr says why (``pool.unguarded_main``); a notebook
    keeps the cluster. The process executor's workers (``python -m
    longtime.execution.child``) never run the script."""
    import sys

    from longtime.execution.matrix import ExecOptions, check_cost
    from longtime.execution.pool import unguarded_main
    from longtime.execution.processes import check_processes, default_processes
    from longtime.execution.store import Store
    from longtime.reporting.report import frame

    memory = check_options(max_samples=max_samples, repeats=repeats, min_time=min_time, time_limit=time_limit,
                           memory_limit=memory_limit, allow_large=allow_large, jobs=jobs, executor=executor,
                           default_sweep=default_sweep, progress=progress)
    check_cost(cost)
    processes = default_processes() if processes is None else check_processes(processes, "processes")
    cells = cells_for(problems, schemes, t_final, sweeps, default_sweep=default_sweep, caller="sweep",
                      limits={"time_limit": time_limit or None, "memory_limit": memory})
    check_size(cells, max_samples, memory, allow_large=allow_large)
    if store is not None and not isinstance(store, Store):
        store = Store(store)
    if executor == "dask":
        why = unguarded_main()
        if why:
            print(f"longtime.sweep: running the cells serially: {why} (put the call under that guard for "
                  f"the Dask cluster)", file=sys.stderr)
            executor = "serial"
    options = ExecOptions(jobs=jobs if executor != "serial" else 0, max_samples=max_samples,
                          timing=Timing(repeats=repeats, min_time=min_time), time_limit=time_limit or None,
                          memory_limit=memory, cost=cost, processes=processes)
    command = "sweep " + shlex.join([f"{k}={v}" for k, v in
                                     {"problems": problems, "schemes": schemes, "t_final": t_final,
                                      **sweeps}.items() if v is not None])
    rows, run_id = run_cells(cells, store=store, command=command, executor=executor, options=options,
                             progress=progress)
    return frame(store.rows(run_id) if store is not None else rows)


# ------------------------------------------------------------------ orders and the Pareto table
# the fields every row of longtime.sweep has, which the order fit and the tables read
ROW_KEYS = ("problem", "integrator", "status")


def records(rows: Any, caller: str = "rows") -> list[dict[str, Any]]:
    """Rows as a list of dicts from a DataFrame (missing values as None), a Result, or dicts;
    each must be a row of ``sweep`` (``ROW_KEYS``), else an InputError naming ``caller``."""
    if isinstance(rows, Result):
        return [rows.row]
    if hasattr(rows, "to_dict") and hasattr(rows, "columns"):
        out = [{k: (None if _missing(v) else v) for k, v in r.items()} for r in rows.to_dict("records")]
    elif not isinstance(rows, (str, bytes, dict)) and hasattr(rows, "__iter__"):
        out = list(rows)
    else:
        out = None
    if out is None or not all(isinstance(r, dict) for r in out):
        raise InputError(f"{caller}: rows={type(rows).__name__} is not valid: expected the DataFrame of "
                         f"longtime.sweep, a Result or a list of row dicts")
    out = [dict(r) for r in out]
    for i, r in enumerate(out):
        lacking = [k for k in ROW_KEYS if k not in r]
        if lacking:
            raise InputError(f"{caller}: rows[{i}] is not a row of longtime.sweep: it lacks {', '.join(lacking)} "
                             f"(it has {', '.join(map(str, r)) or 'no field'})")
    return out


def _missing(v: Any) -> bool:
    return v is None or (isinstance(v, float) and v != v)


def orders(rows: Any) -> list[Order]:
    """An Order per sweep in ``rows``, and one without a value (its ``reason``) per
    problem x scheme that has no fit."""
    from longtime.measure.orders import left_out, observed_orders

    rows = records(rows, "convergence")
    out = [Order(f["problem"], f["integrator"], f["observed_order"], f["observed_order_ci"],
                 [tuple(p) for p in f["order_points"]], [tuple(p) for p in f["order_dropped"]],
                 f["declared_order"], f["order_flag"], f["order_error_field"], f["order_variable"],
                 f["t_final"], f["settings"], slopes=f["order_slopes"]) for f in observed_orders(rows)]
    out += [Order(m["problem"], m["integrator"], None, None, [], [tuple(p) for p in m["dropped"]],
                  m["declared_order"], error_field=m["error_field"], variable=m["variable"], reason=m["reason"],
                  slopes=m["slopes"]) for m in left_out(rows)]
    return sorted(out, key=lambda o: (o.problem, o.scheme, str(o.t_final)))


def convergence(rows: Any) -> Order | list[Order]:
    """The observed order of the sweep in ``rows`` (a DataFrame from ``sweep``, or row
    dicts): an Order, or a list of them (one per problem x scheme and setting) when the
    rows hold several sweeps."""
    found = orders(rows)
    if not found:
        raise InputError("convergence: no rows")
    return found[0] if len(found) == 1 else found


def work_precision(rows: Any):
    """The Pareto table of ``rows`` as a DataFrame: per problem and accuracy decade, the
    fastest ok row meeting it (minimum CPU of its repeats) and the fastest of another
    scheme (``next``, ``slower`` = its time / the fastest's), as ``longtime report`` shows."""
    import pandas as pd

    from longtime.reporting.report import pareto, pareto_field, setting

    rows = records(rows, "work_precision")
    out = []
    for problem in sorted({r["problem"] for r in rows}):
        mine = [r for r in rows if r["problem"] == problem]
        field_ = pareto_field(mine)
        for p in pareto(mine, field_) if field_ else []:
            b, n = p["best"], p["next"]
            out.append({"problem": problem, "target": p["target"], "field": p["field"],
                        "scheme": b["integrator"], "setting": setting(b), "cpu_s": b["cpu_s"],
                        "error": b[p["field"]], "t_final": b.get("t_final"),
                        "next": n["integrator"] if n else None, "next_setting": setting(n) if n else None,
                        "slower": p["slower"]})
    columns = ["problem", "target", "field", "scheme", "setting", "cpu_s", "error", "t_final", "next",
               "next_setting", "slower"]
    return pd.DataFrame(out, columns=columns)


# ------------------------------------------------------------------ a scheme's card
def card(scheme: Any, rows: Any = None, *, structure: bool = True, stability: bool = True) -> dict[str, Any]:
    """The card of ``scheme`` (a registered name, a class or an instance: an in-memory
    class is registered for the session) as a dict, the JSON of ``longtime card``: declared
    and observed order per problem, growth classes, cost per step, place on each Pareto
    front, stability interval and structure (longtime.reporting.card). ``rows``: a
    DataFrame from ``sweep``, row dicts, a Store or a store's path (its latest run), or None
    (the scheme alone). ``longtime.reporting.card.card_text(card)`` renders it."""
    from pathlib import Path

    from longtime.execution.store import Store
    from longtime.reporting.card import card as build

    name, _ = resolve(scheme, "scheme")  # an in-memory class is registered for the session
    if isinstance(rows, (str, Path)):
        rows = Store(rows, readonly=True)
    if isinstance(rows, Store):
        run = rows.latest_run()
        rows = rows.rows(run) if run is not None else []
    # an instance keeps its settings (the structure is measured with them); otherwise the name
    return build(scheme if isinstance(scheme, Integrator) else name,
                 records(rows) if rows is not None else None, structure=structure, stability=stability)

# ------------------------------------------------------------------ the verdict
def recommend(problem: Any, error: float, horizon: float, rows: Any = None, *, db: str | None = None,
              run: Any = None, budget: float = DEFAULT_BUDGET_S, library: str | None = None):
    """The cheapest stored setting predicted to keep ``error`` up to ``horizon`` on
    ``problem``, as ``longtime recommend`` answers it (a
    longtime.reporting.recommend.Recommendation: ``scheme``, ``setting``, ``predicted_error``,
    ``predicted_cpu_s``, ``runner_up``, ``evidence``; ``str()`` gives the command's lines).
    From ``rows`` (a DataFrame from ``sweep``, or row dicts) where given, else from the store
    ``db`` (default: $LONGTIME_DB or longtime.sqlite), its run ``run`` (default: every run);
    ``library`` (scipy, sundials, diffrax, ...): the cheapest setting of that library's schemes.
    What cannot be decided raises InputError naming the run that would decide it.
    ``budget``: the wall seconds (>= 0; 0 runs nothing) for running the best predicted
    candidates to ``horizon`` where the answer lies beyond the stored runs (``basis``
    "measured at T", ``measured_error``, ``measured_cpu_s``), as ``longtime recommend --budget``."""
    from longtime.execution.sizes import check_span
    from longtime.reporting.recommend import measured_growth, stored_recommendation
    from longtime.reporting.recommend import recommend as decide

    name, _ = resolve(problem, "problem")
    check_number("error", error, positive=True)
    check_number("horizon", horizon, positive=True)
    if name in registry.problems():  # an unknown one is named by the decision, with the known ones
        check_span(name, horizon, f"horizon={horizon!r}")
    check_number("budget", budget, minimum=0, maximum=MAX_SECONDS)
    if rows is not None:
        mine = records(rows)
        return decide(mine, name, error, horizon, known=registry.problems(),
                      growth=measured_growth(mine, name, horizon), budget=float(budget), library=library)
    return stored_recommendation(name, error, horizon, db, None if run is None else str(run), budget=float(budget),
                                 library=library)


# ------------------------------------------------------------------ the main job
def main_job(spec: Any = None, *, html: Any = None, page: bool = True, full: bool = False, progress: bool = True):
    """Run the main job ``spec`` (a longtime.execution.main_job.MainJobSpec; default: every
    default problem x every scheme over the default sweep), then its results page (into
    ``html``, default longtime-report/run-RUN_ID beside the store; ``page=False``: none) and
    its report, as `longtime matrix` does: a longtime.reporting.main_job_report.MainJobReport
    (``job``: the run id, rows, checks and ensembles; ``page``; ``text``). ``progress``
    shows each phase on stderr as `longtime matrix` does; ``progress=False``: nothing."""
    from longtime.core.progress import Progress
    from longtime.execution.main_job import MainJobSpec, run_main_job
    from longtime.reporting.figures_ahead import FiguresAhead
    from longtime.reporting.main_job_report import page_and_report

    if not isinstance(progress, (bool, np.bool_)):
        raise InputError(f"progress={progress!r} is not valid: expected True or False")
    shown = Progress(on=bool(progress))
    with contextlib.ExitStack() as workers:  # the checks' workers draw the page's last figures
        job = run_main_job(spec if spec is not None else MainJobSpec(), progress=shown,
                           ahead=FiguresAhead if page else None, keep_workers=workers)
        return page_and_report(job, html, page=page, full=full, progress=shown)
