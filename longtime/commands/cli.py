"""The ``longtime`` command: list | run | matrix | report (and commands added by modules).

Exit codes: 0 done; 1 a requested cell failed (``run``) or a failure that changing the
command does not fix; 2 bad input; 3 ``run --cost instructions`` counted no row (stderr
says why); 130, 143, 129 stopped by SIGINT, SIGTERM, SIGHUP (longtime.commands.guard).
"""
from __future__ import annotations

import argparse
import dataclasses
import importlib
import sys
from pathlib import Path

from longtime.commands import guard
from longtime.core import cli_args, jsontext, phases, registry
from longtime.core.cache import check_cache_root
from longtime.core.files import write_atomic
from longtime.core.params import InputError
from longtime.core.progress import Progress
from longtime.core.roles import ROW_PARAMETERS, flag
from longtime.core.timing import Timing
from longtime.execution import budget, limits
from longtime.execution.calibration import drift_text
from longtime.execution.cells import DEFAULT_TIME_LIMIT, check_size, expand
from longtime.execution.lifecycle import command_line, recorded_run
from longtime.execution.matrix import (
    COSTS,
    EXECUTORS,
    PHASES_FIELD,
    ExecOptions,
    check_cost,
    complete_phases,
    run_matrix,
)
from longtime.execution.processes import DEFAULT_PROCESSES, default_processes, max_processes
from longtime.execution.store import Store, default_path
from longtime.measure import stability
from longtime.measure.reference import budget_seconds
from longtime.reporting.report import render

# modules that add subcommands: each defines add_parser(subparsers) and sets func
COMMAND_MODULES: tuple[str, ...] = ("longtime.commands.asv_init", "longtime.commands.cache_cmd", "longtime.commands.card", "longtime.reporting.compare", "longtime.reporting.history",
                                   "longtime.commands.horizon", "longtime.commands.ensemble", "longtime.commands.matched", "longtime.plot",
                                   "longtime.commands.recommend", "longtime.commands.reproduce", "longtime.commands.roundoff",
                                   "longtime.commands.warmup",
                                   "longtime.commands.merge")


# argument types: one set for every command (longtime.core.cli_args)
_names, _key_value = cli_args.names, cli_args.key_value


def _floats(flag: str):
    """run and matrix: the cells' validation refuses a non-finite value up front, naming it as a setting."""
    return cli_args.floats(flag, finite=False)


_seconds = cli_args.seconds("--cell-timeout")
_limit = cli_args.seconds("--time-limit", allow_zero=True)


class _SchedulerAction(argparse.Action):
    """--scheduler ADDRESS selects the dask executor unless --executor says otherwise."""

    def __call__(self, parser, namespace, values, option_string=None):
        setattr(namespace, self.dest, values)
        if getattr(namespace, "executor", None) is None:
            namespace.executor = "dask"


def add_selection(p: argparse.ArgumentParser, required: bool) -> None:
    p.add_argument("-p", "--problem", type=_names, required=required, metavar="PROBLEM[,..]",
                   help="problem names (see `longtime list`)")
    p.add_argument("-i", "--integrator", type=_names, required=required, metavar="SCHEME[,..]",
                   help="scheme names (see `longtime list`)")
    for name, (role, text) in ROW_PARAMETERS.items():  # the swept parameters with a flag of their own
        if role == "order":
            p.add_argument(flag(name), type=cli_args.ints(flag(name)), metavar="N[,..]", help=text + " (or A..B)")
        else:
            p.add_argument(flag(name), type=_floats(flag(name)), metavar="X[,..]", help=text)
    p.add_argument("--t-final", type=_floats("--t-final"), metavar="T[,..]",
                   help="final times, one cell each (default: the problem's)")
    p.add_argument("--set", type=_key_value, action="append", default=[], metavar="KEY=VALUE[,..]",
                   help="any other parameter of a problem or scheme (repeatable, once per key); "
                        "several values sweep it, one cell each")
    p.add_argument("--executor", choices=sorted(EXECUTORS), help="where cells run")
    p.add_argument("--scheduler", action=_SchedulerAction, type=cli_args.scheduler, default=None, metavar="ADDRESS",
                   help="run the cells on this Dask cluster (implies --executor dask)")
    p.add_argument("--cell-timeout", type=_seconds, default=None, metavar="SECONDS",
                   help="time limit per cell: each cell runs in its own process and one that "
                        "passes the limit becomes a 'timeout' row")
    p.add_argument("--time-limit", type=_limit, default=DEFAULT_TIME_LIMIT, metavar="SECONDS",
                   help=f"a cell's integration stops past this, keeping what it reached: a 'timeout' "
                        f"row (default {DEFAULT_TIME_LIMIT:g}; 0: no limit); a cell stuck elsewhere is "
                        f"killed {limits.GRACE_S:g} s + {100 * limits.GRACE_SHARE:g} %% of it later (a 'timeout' row)")
    p.add_argument("--memory-limit", type=limits.memory_argument, default=f"{limits.MEMORY_SHARE:.0%}",
                   metavar="GIB|PERCENT",
                   help=f"memory a cell's process may allocate, in GiB or as a share of the machine's "
                        f"(default {100 * limits.MEMORY_SHARE:g}%%; 0: no limit); past it the cell fails with "
                        f"'memory limit', and a cell estimated beyond it is refused up front")
    p.add_argument("--allow-large", action="store_true",
                   help="run cells estimated beyond 1e9 steps or 4 GiB of samples (refused by default)")
    p.add_argument("--jobs", type=cli_args.jobs, default=0,
                   help="worker processes of the process, isolated and dask executors (default: one per core)")
    p.add_argument("--max-samples", type=int, default=100_001,
                   help="states kept per run for the metrics (every step below this)")
    p.add_argument("--repeats", type=cli_args.integer("--repeats", 1), default=Timing.repeats, metavar="N",
                   help=f"timed runs of each cell after the warm-up, split among --processes: in each, at "
                        f"least {Timing.MIN_RUNS} / processes (rounded up), more while its two fastest differ by "
                        f"more than {100 * Timing.SETTLED:g} %% and their total is below --min-time / processes, "
                        f"at most N / processes (rounded up); cpu_s is the minimum (default {Timing.repeats})")
    p.add_argument("--processes", type=cli_args.integer("--processes", 1, maximum=max_processes()),
                   default=None, metavar="N",
                   help=f"processes that time each cell: the one that measures its row and N - 1 fresh "
                        f"ones that time its integration alone, the repeats split among them; cpu_s is "
                        f"the minimum over them, cpu_s_processes each one's and cpu_s_process_spread "
                        f"their spread, which compare and history judge (default {DEFAULT_PROCESSES}, "
                        f"or $LONGTIME_PROCESSES)")
    p.add_argument("--min-time", type=cli_args.seconds("--min-time", allow_zero=True), default=Timing.min_time,
                   metavar="SECONDS",
                   help=f"repeat a cell's timed run until the timed total passes this "
                        f"(default {Timing.min_time})")
    p.add_argument("--db", default=None, help=f"SQLite store (default: $LONGTIME_DB or {default_path()})")
    p.add_argument("--cost", choices=COSTS, default="time",
                   help="instructions: also count each ok cell's integration under Valgrind (Callgrind; "
                        "Debian package valgrind), a deterministic cost beside the time, with kernels compiled "
                        "for x86-64-v3 whatever the host (rows gain instructions, instructions_per_step, "
                        "instructions_target, instructions_versions); `run` exits 3 when no row was counted")


def _selection(args) -> dict:
    """expand's sweeps, single settings and final times from the flags and the --set pairs."""
    sets, swept = cli_args.settings(args.set)
    sweeps = {k: getattr(args, k) for k in ROW_PARAMETERS if getattr(args, k, None)}
    for k in swept:
        if k in sweeps:
            raise InputError(f"{flag(k)} and --set {k}= both give {k}: give one of them")
    return {"sweeps": {**sweeps, **swept}, "sets": sets, "t_final": args.t_final,
            # a plugin's up-front checks run under a cell's limits
            "time_limit": getattr(args, "time_limit", DEFAULT_TIME_LIMIT) or None,
            "memory_limit": getattr(args, "memory_limit", limits.default_memory_limit())}


def _options(args, executor: str) -> ExecOptions:
    """The execution options of ``args`` for ``executor`` (checked before a run is recorded:
    bad input leaves nothing to resume)."""
    if args.jobs and executor == "serial" and not getattr(args, "cell_timeout", None):
        raise InputError(f"--jobs {args.jobs}: the serial executor runs one cell at a time; --jobs applies to "
                         f"--executor process, isolated or dask (or with --cell-timeout)")
    if args.max_samples < 2:
        raise InputError(f"--max-samples {args.max_samples}: must be >= 2")
    budget_seconds()  # $LONGTIME_REFERENCE_SECONDS: a bad value is bad input, caught up front
    check_cache_root()  # $LONGTIME_CACHE_DIR: one error now, not one per cell
    cost = getattr(args, "cost", "time")
    check_cost(cost)  # --cost instructions without Valgrind: one line, before a run is recorded
    if executor == "dask" and getattr(args, "scheduler", None):  # no run is recorded for an address that is not Dask
        from longtime.execution.dask_executor import check_scheduler

        check_scheduler(args.scheduler)
    return ExecOptions(cost=cost, jobs=args.jobs, max_samples=args.max_samples,
                       timing=Timing(repeats=args.repeats, min_time=args.min_time),
                       processes=args.processes or default_processes(),
                       cell_timeout=getattr(args, "cell_timeout", None),
                       time_limit=getattr(args, "time_limit", DEFAULT_TIME_LIMIT) or None,
                       memory_limit=getattr(args, "memory_limit", limits.default_memory_limit()),
                       scheduler=getattr(args, "scheduler", None))


def _warn_broken() -> None:
    for b in registry.broken():
        print(f"warning: plugin {b.group} '{b.name}' ({b.target}) failed to load: {b.error}", file=sys.stderr)


def _notices(schemes) -> None:
    """The notice of each named scheme that has one (``Integrator.notice``), on stderr."""
    known = registry.integrators()
    for name in sorted(set(schemes)):
        notice = getattr(known.get(name), "notice", "")
        if notice:
            print(f"notice: {name}: {notice}", file=sys.stderr)


def cmd_list(args) -> int:
    problems, schemes = registry.problems(), registry.integrators()
    data = {
        "problems": [{"name": n, "summary": c.summary, "capabilities": sorted(c.capabilities()),
                      "parameters": {k: p.default for k, p in c.parameters.items()}}
                     for n, c in problems.items()],
        "integrators": [{"name": n, "summary": c.summary, "kind": c.kind, "order": c.order,
                         "symplectic": c.symplectic, "requires": sorted(c.requires),
                         "parameters": {k: p.default for k, p in c.parameters.items()},
                         "imaginary_interval": stability.intervals(n, compute=args.stability),
                         "notice": c.notice}
                        for n, c in schemes.items()],
        "broken": [vars(b) for b in registry.broken()],
    }
    if args.format == "json":
        print(jsontext.dumps(data))
        return 0
    print("problems:")
    for p in data["problems"]:
        print(f"  {p['name']:24s} {p['summary']}\n  {'':24s} provides: {', '.join(p['capabilities'])}")
    print("integrators:")
    for i in data["integrators"]:
        needs = ", ".join(i["requires"]) or "-"
        sym = " symplectic" if i["symplectic"] else ""
        print(f"  {i['name']:24s} {i['kind']:8s} order {i['order']}{sym}; needs {needs}\n"
              f"  {'':24s} {i['summary']}; parameters: {', '.join(i['parameters']) or '-'}")
        if i["notice"]:
            print(f"  {'':24s} notice: {i['notice']}")
        if i["imaginary_interval"]:
            print(f"  {'':24s} stable on the imaginary axis (|R(iy)| <= 1), y in: " + "; ".join(
                f"{label} {stability.format_interval(r)}".strip() for label, r in i["imaginary_interval"].items()))
    if data["broken"]:
        print("broken plugins:")
        for b in data["broken"]:
            print(f"  {b['group']} '{b['name']}' ({b['target']}): {b['error']}")
    return 0


def cmd_run(args) -> int:
    from longtime.api import run_cells

    _warn_broken()
    cells = expand(args.problem, args.integrator, **_selection(args), strict=True)
    _notices(c.integrator for c in cells)
    check_size(cells, args.max_samples, args.memory_limit, allow_large=args.allow_large)
    # by default one cell at a time in one worker process, under the hard limits (longtime.execution.limits);
    # --executor serial runs them in this process
    executor = args.executor or "process"
    options = _options(args, executor)
    if not args.executor and not args.jobs:
        options = dataclasses.replace(options, jobs=1)
    store = None if args.no_store else Store(args.db)
    rows, _ = run_cells(cells, store=store, command=command_line(args), executor=executor,
                        options=options)
    print(render(rows, args.format))  # json: every row with the contract's keys (report.complete)
    if any(r["status"] == "failed" for r in rows):
        return 1
    if options.cost == "instructions":  # asked for counts and got none: said, and exit 3
        from longtime.execution.valgrind import EXIT_NOTHING_COUNTED, nothing_counted

        why = nothing_counted(rows)
        if why:
            print(f"error: {why}", file=sys.stderr)
            return EXIT_NOTHING_COUNTED
    return 0


def cmd_matrix(args) -> int:
    phases.since_process_start("startup")  # the interpreter, the imports, the plugins
    _warn_broken()
    executor = args.executor or "process"
    options = _options(args, executor)
    shown = Progress(on=not args.no_progress)
    if args.resume is not None:
        store = Store(args.db, create=False)  # resuming never creates an empty store
        if args.resume < 0:
            raise InputError(f"--resume {args.resume}: a run id is > 0 (or none: the newest incomplete run)")
        run_id = args.resume or store.latest_incomplete_run(("matrix", "run"))
        if run_id is None:
            raise InputError(f"--resume: no incomplete run in {store.path} (give a run id to pick one)")
        store.run(run_id)  # an unknown id is an error, not "0 cells left"
        cells = store.pending(run_id)
        lacking = [row for _, row in store.incomplete_rows(run_id, PHASES_FIELD)]
        if lacking:  # rows stored before their timing processes or counts ran: run them
            phases_lacked = sorted({p for row in lacking for p in row[PHASES_FIELD]})
            print(f"run {run_id}: {len(lacking)} stored row(s) lack a phase ({', '.join(phases_lacked)}): "
                  f"it runs for them", file=sys.stderr)
        elif not cells:  # every planned row is stored (only its end mark was lost): nothing to run
            store.finish_run(run_id, "done")
            print(f"run {run_id}: every planned cell is stored; marked done", file=sys.stderr)
            return 0
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
            cells, moves = matrix_cells(args)
        _say_moves(moves)
        store, run_id, died = Store(args.db), None, []
    if args.baseline is not None:
        store.run(args.baseline)  # an unknown baseline is bad input, caught up front
        _check_baseline(store, args.baseline, cells)
    if args.html and not args.no_report and not args.no_html:
        cli_args.writable_folder("--html", args.html)  # refused before the first cell
    ahead = None
    with recorded_run(store, command_line(args), cells, run_id) as run_id:
        if args.resume is None:
            print(f"run {run_id}: {len(cells)} cells into {store.path}", file=sys.stderr)
        if died:
            run_matrix(died, store, run_id, "isolated", options)
        if executor == "process" and args.resume is None and not args.no_report and not args.no_html:
            from longtime.reporting.figures_ahead import FiguresAhead

            # the page's figures on workers that have no cell left
            ahead = FiguresAhead(cells, run_id, timed_again=options.processes > 1)
            options = dataclasses.replace(options, idle_work=ahead.task)
        run_matrix(cells, store, run_id, executor, options,
                   progress=shown, on_row=ahead.add if ahead is not None else None)
        if args.resume is not None:  # the rows stored before the interruption, timed and counted
            complete_phases(store, run_id, options)
        if args.checks is None:
            from longtime.reporting.verdict import CHECKS

            args.checks = CHECKS
        if args.checks:  # a few of the verdicts' predictions re-run past the rows' final times
            from longtime.reporting.verdict import check_budget, check_summary, run_checks

            rows = store.rows(run_id)
            try:
                with shown.phase("checks", detail=f"up to {args.checks} predictions re-run past the rows' final times"):
                    checks = run_checks(store, run_id, rows, options, limit=args.checks, budget_s=check_budget(rows))
            except (InputError, OSError, ValueError) as exc:  # the rows are stored; the checks are extra
                print(f"warning: predictions not checked: {type(exc).__name__}: {exc}", file=sys.stderr)
                checks = []
            if checks:
                print(f"checks: {check_summary(checks)}", file=sys.stderr)
        if not args.no_ensemble:  # chaotic problems: each scheme's ensemble distance to heyoka's
            from longtime.execution import ensembles

            try:
                with phases.phase("ensembles"), shown.phase("ensembles", detail="chaotic problems' ensembles"):
                    ensembles.run(store, run_id, store.rows(run_id))
            except (InputError, OSError, ValueError, RuntimeError) as exc:  # the rows are stored; this is extra
                print(f"warning: ensembles not measured: {type(exc).__name__}: {exc}", file=sys.stderr)
    page_error = None
    if not args.no_report:
        from longtime.reporting.page import write_html
        from longtime.reporting.screen import report_text

        rows = store.rows(run_id)
        page = None
        if not args.no_html:  # the results page first, so that a long report ends with its path
            try:
                with phases.phase("page"), shown.phase("page", detail="figures and the results page"):
                    page = write_html(args.html or store.path.parent / "longtime-report" / f"run-{run_id}", rows,
                                      store, [run_id], ahead=ahead, writer="matrix")  # default: beside the store
            except Exception as exc:  # the rows are stored; `longtime report --html DIR` can retry (exit 1 below)
                page_error = f"results page not written: {type(exc).__name__}: {exc}"
                print(f"warning: {page_error}", file=sys.stderr)
        with phases.phase("report"), shown.phase("report"):
            text = report_text(rows, "table", full=args.full, checks=store.checks(run_id),
                               ensembles=store.ensembles(run_id), page=str(page) if page is not None else None)
        print(text)
        print("\n" + _wrapped(f"calibration: {drift_text(store.calibrations(run_id))}"))
        if page is not None and args.full:  # the first screen names it; the full text ends with it
            print(f"\nresults page: {page}")
    code = 0
    if args.baseline is not None:  # CI's gate: this run against the baseline, exit 1 on a regression
        from longtime.reporting import compare

        print(f"\n== compared with run {args.baseline} (longtime compare {args.baseline} {run_id}) ==")
        code = compare.report(compare.run_compare(store.path, str(args.baseline), store.path, str(run_id)))
    if page_error:  # the rows are stored and reported; the page the command owes is not there
        print(f"longtime matrix: error: {page_error}", file=sys.stderr)
        return max(code, 1)
    return code


def matrix_cells(args) -> tuple[list, list]:
    """The cells of ``longtime matrix``'s selection (default: every default problem x every
    scheme) over the default sweep, within the budget unless --full-sweep (longtime.execution.budget),
    sized (--allow-large aside), and what the budget moved."""
    problems = args.problem or registry.default_problems()
    schemes = args.integrator or sorted(registry.integrators())
    cells = expand(problems, schemes, **_selection(args), default_sweep=True)
    moves = []
    if not args.full_sweep:
        cells, moves = budget.fit(cells, given_t_final=args.t_final is not None)
    check_size(cells, args.max_samples, args.memory_limit, allow_large=args.allow_large)
    return cells, moves


def _say_moves(moves: list) -> None:
    """What the default matrix's budget moved, on stderr as the run starts (each moved row's
    message and the report's summary say it too)."""
    if moves:
        print(f"the default matrix's budget moved {len(moves)} setting(s) (--full-sweep runs the "
              f"default sweep as it is):", file=sys.stderr)
        for m in moves:
            print(f"  {m.text()}", file=sys.stderr)

def _check_baseline(store: Store, baseline: int, cells) -> None:
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


def _wrapped(text: str) -> str:
    """A line of the report's text wrapped at the report's width, continued indented."""
    import textwrap

    from longtime.reporting.screen import WIDTH

    return "\n".join(textwrap.wrap(text, width=WIDTH, subsequent_indent="  ", break_on_hyphens=False))


def cmd_report(args) -> int:
    store = Store(args.db, readonly=True)  # a report writes nothing, not even an empty store
    if args.html:
        cli_args.writable_folder("--html", args.html)  # refused before the rows are read and drawn
    if args.run == "all":
        rows = store.rows()
    else:
        if args.run and not (args.run.isascii() and args.run.isdigit()):  # isdigit alone takes '¹'
            raise InputError(f"--run {args.run!r}: expected a run id (a positive integer) or 'all'")
        run_id = int(args.run) if args.run else store.latest_run()
        if run_id is None:
            raise InputError(f"no runs in {store.path}: run `longtime matrix` first")
        run = store.run(run_id)
        if run["status"] != "done" or run["done"] < run["planned"]:
            died = ", ".join(f"{c.problem} x {c.integrator}" for c in store.died_in(run_id)[:3])
            print(f"note: run {run_id} is incomplete ({run['status']}, {run['done']} of {run['planned']} "
                  f"cells stored)" + (f"; its process ended inside {died}" if died else "")
                  + f"; `longtime matrix --resume {run_id}` completes it", file=sys.stderr)
        rows = store.rows(run_id)
    checks = store.checks() if args.run == "all" else store.checks(run_id)
    ensembles = store.ensembles() if args.run == "all" else store.ensembles(run_id)
    if args.problem:
        rows = [r for r in rows if r["problem"] in args.problem]
        ensembles = [e for e in ensembles if e["problem"] in args.problem]
    _notices(r["integrator"] for r in rows)
    from longtime.reporting.page import write_html
    from longtime.reporting.report import to_parquet
    from longtime.reporting.screen import report_text

    page = None
    if args.html:
        page = str(write_html(args.html, rows, store, writer='report --html'))
        print(f"results page: {page}", file=sys.stderr)
    if args.format == "parquet":
        with cli_args.writing("--out", args.out or "longtime.parquet"):
            to_parquet(rows, args.out or "longtime.parquet")
        print(f"wrote {len(rows)} rows to {args.out or 'longtime.parquet'}", file=sys.stderr)
    elif args.out:
        text = report_text(rows, args.format, full=args.full, checks=checks, ensembles=ensembles)
        with cli_args.writing("--out", args.out):
            write_atomic(args.out, text)
    else:
        print(report_text(rows, args.format, full=args.full, checks=checks, ensembles=ensembles, page=page))
        if args.format == "table" and args.run != "all":
            print("\n" + _wrapped(f"calibration: {drift_text(store.calibrations(run_id))}"))
        if args.format == "table":  # rows of several machines (a merged store): side by side
            from longtime.reporting import compare, machines

            table = compare.cross_machine_table(store, rows)
            if table:
                print(f"\n{machines.text(table)}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = guard.Parser(prog="longtime", description=__doc__.splitlines()[0])  # errors in one line
    parser.add_argument("--debug", action="store_true",
                        help="an error's traceback too, not only its one-line message")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("list", help="problems, schemes, their capabilities and broken plugins")
    p.add_argument("--format", choices=["table", "json"], default="table")
    p.add_argument("--stability", action="store_true",
                   help="measure each scheme's imaginary-axis stability interval where it is not "
                        "cached (compiles every step kernel: about a minute the first time)")
    p.set_defaults(func=cmd_list)

    p = sub.add_parser("run", help="run problems x schemes and print one row per cell")
    add_selection(p, required=True)
    p.add_argument("--format", choices=["table", "csv", "json", "markdown"], default="table")
    p.add_argument("--no-store", action="store_true", help="do not append the rows to the store")
    p.set_defaults(func=cmd_run)

    p = sub.add_parser("matrix", help="every scheme on every problem over the default sweep")
    add_selection(p, required=False)
    p.add_argument("--resume", type=int, nargs="?", const=0, default=None, metavar="RUN_ID",
                   help="finish an interrupted run (default: the newest incomplete run of matrix or run)")
    p.add_argument("--no-progress", action="store_true")
    p.add_argument("--no-report", action="store_true", help="do not print the report at the end")
    p.add_argument("--full", action="store_true", help="the full per-cell tables after the summary")
    p.add_argument("--html", default=None, type=cli_args.out_folder("--html"), metavar="DIR",
                   help="folder of the results page (default: longtime-report/run-RUN_ID beside the store)")
    p.add_argument("--no-html", action="store_true", help="do not write the results page")
    p.add_argument("--full-sweep", action="store_true",
                   help=f"run the default sweep as it is: without it, a pair whose default cells are "
                        f"estimated above {budget.CELL_BUDGET_S:g} s a run runs them over a shorter horizon, "
                        f"and a long-time cell above {budget.LONG_CELL_BUDGET_S:g} s is left out (the "
                        f"report names each move)")

    p.add_argument("--checks", type=cli_args.integer("--checks", 0), default=None, metavar="N",
                   help="re-run N of the verdicts' predictions past the rows' final times and store predicted "
                        "against measured error and cost (default 6; 0: none)")
    p.add_argument("--no-ensemble", action="store_true",
                   help="do not measure the chaotic problems' ensemble distances (each scheme's late-time "
                        "distribution against heyoka's: henon-heiles, figure-eight-perturbed; docs/metrics.md)")
    p.add_argument("--baseline", type=cli_args.integer("--baseline", 1), default=None, metavar="RUN",
                   help="end with `longtime compare RUN` against this run (same store) and exit 1 on a regression")
    p.set_defaults(func=cmd_matrix)

    p = sub.add_parser("report", help="tables of stored rows: accuracy against cost per problem")
    p.add_argument("--db", default=None)
    p.add_argument("--run", default=None, help="run id, or 'all' (default: the latest run)")
    p.add_argument("-p", "--problem", type=_names, default=None)
    p.add_argument("--format", choices=["table", "csv", "json", "markdown", "parquet"], default="table",
                   help="table: the summary (status counts, Pareto front per problem); csv, json, "
                        "markdown: every cell; parquet: every cell into --out")
    p.add_argument("--full", action="store_true", help="the full per-cell tables after the summary")
    p.add_argument("--html", default=None, type=cli_args.out_folder("--html"), metavar="DIR",
                   help="also write the results page DIR/index.html")
    p.add_argument("--out", default=None, type=cli_args.out_file("--out"), metavar="FILE",
                   help="write the report to FILE (parquet: default longtime.parquet)")
    p.set_defaults(func=cmd_report)

    for name in COMMAND_MODULES:
        importlib.import_module(name).add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(argv)
    args.argv = argv  # the command a run records (lifecycle.command_line)
    return guard.run_command(args)  # every failure caught there: one line, its exit code


if __name__ == "__main__":
    sys.exit(main())
