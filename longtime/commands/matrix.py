"""``longtime matrix``: the main job (longtime.execution.main_job) of a selection, or an
interrupted run resumed, then its results page and report (longtime.reporting.main_job_report),
and with --baseline its comparison with a stored run (exit 1 on a regression)."""
from __future__ import annotations

import contextlib
import dataclasses
import sys

from longtime.commands.common import add_selection, exec_options, selection, warn_broken, wrapped
from longtime.core import cli_args, phases
from longtime.core.params import InputError
from longtime.core.progress import Progress
from longtime.execution import budget
from longtime.execution.calibration import drift_text
from longtime.execution.lifecycle import command_line
from longtime.execution.main_job import MainJobSpec, Selection, plan, run_main_job
from longtime.execution.matrix import ExecOptions
from longtime.predict.checks import CHECKS

# ``longtime matrix --quick``: a first answer in about a minute (warm caches): two problems
# whose answers the report states, the schemes of the main families (splitting, explicit and
# implicit Runge-Kutta, adaptive, the Taylor reference), each over its default sweep. Its cells
# cost little next to the fixed work of a run, so what it leaves out is that work: the fresh
# processes that time cells again (each cell is timed in the worker that ran it) and the
# results page (`--html DIR` asks for it; `longtime report --html DIR` writes it later)
QUICK_PROBLEMS = ("harmonic", "kepler")
QUICK_SCHEMES = ("verlet", "yoshida6", "rk4", "gauss4", "rk45", "dop853", "heyoka")


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("matrix", help="every scheme on every problem over the default sweep")
    add_selection(p, required=False)
    p.add_argument("--quick", action="store_true",
                   help=f"a first answer in about a minute: {', '.join(QUICK_PROBLEMS)} x "
                        f"{', '.join(QUICK_SCHEMES)} over the default sweep (-p and -i replace them), each "
                        f"cell timed in its worker only unless --processes asks for more, no results page "
                        f"unless --html asks, no ensembles and no checks unless --checks asks; `longtime "
                        f"matrix` without it runs the full matrix")
    p.add_argument("--resume", type=int, nargs="?", const=0, default=None, metavar="RUN_ID",
                   help="finish an interrupted run (default: the newest incomplete run of matrix or run)")
    p.add_argument("--no-progress", action="store_true")
    p.add_argument("--no-report", action="store_true", help="do not print the report at the end")
    p.add_argument("--full", action="store_true",
                   help="the full per-cell tables after the summary, and each setting the budget moved as the "
                        "job starts (else one line says how many and why)")
    p.add_argument("--html", default=None, type=cli_args.out_folder("--html"), metavar="DIR",
                   help="folder of the results page (default: longtime-report/run-RUN_ID beside the store)")
    p.add_argument("--no-html", action="store_true", help="do not write the results page")
    p.add_argument("--full-sweep", action="store_true",
                   help=f"run the default sweep as it is: without it, a fixed-step pair whose default cells are "
                        f"estimated above {budget.CELL_BUDGET_S:g} s a run runs them over a shorter horizon, "
                        f"an adaptive scheme's or a library peer's settings estimated above its budget are left out "
                        f"(never its horizon; its cheapest runs under a {budget.SLOW_LIMIT_S:g} s time limit where "
                        f"even that one is estimated above {budget.CELL_BUDGET_S:g} s), and a long-time cell above "
                        f"{budget.LONG_CELL_BUDGET_S:g} s is left out (the report names each move)")
    p.add_argument("--checks", type=cli_args.integer("--checks", 0), default=None, metavar="N",
                   help="re-run N of the verdicts' predictions past the rows' final times and store predicted "
                        "against measured error and cost (default 6; 0: none)")
    p.add_argument("--no-ensemble", action="store_true",
                   help="do not measure the chaotic problems' ensemble distances (each scheme's late-time "
                        "distribution against heyoka's: henon-heiles, figure-eight-perturbed; docs/metrics.md)")
    p.add_argument("--baseline", type=cli_args.integer("--baseline", 1), default=None, metavar="RUN",
                   help="end with `longtime compare RUN` against this run (same store) and exit 1 on a regression")
    p.set_defaults(func=cmd_matrix)


def matrix_selection(args) -> Selection:
    """The cells ``longtime matrix``'s flags select (default: every default problem x every
    scheme over the default sweep)."""
    flags = selection(args)
    return Selection(problems=tuple(args.problem) if args.problem else None,
                     schemes=tuple(args.integrator) if args.integrator else None,
                     sweeps=flags["sweeps"], sets=flags["sets"],
                     t_final=tuple(args.t_final) if args.t_final is not None else None,
                     full_sweep=args.full_sweep, allow_large=args.allow_large)


def matrix_cells(args) -> tuple[list, list]:
    """The cells of ``longtime matrix``'s selection, within the budget unless --full-sweep
    (longtime.execution.budget), sized (--allow-large aside), and what the budget moved."""
    return plan(matrix_selection(args), matrix_options(args, args.executor or "process"))


def matrix_options(args, executor: str) -> ExecOptions:
    """How ``longtime matrix`` runs its cells: the run options of its flags, timing by need
    (longtime.execution.processes.by_need) unless ``--timing`` says otherwise."""
    options = exec_options(args, executor)
    if args.timing is None:
        options = dataclasses.replace(options, retime="need")
    return options


def quick(args) -> None:
    """--quick: the quick matrix's problems and schemes where -p and -i do not name them, one
    timing process where --processes does not ask for more, no results page where --html
    does not ask for one, no checks where --checks does not ask for them, no ensembles."""
    if args.resume is not None:
        raise InputError("--quick and --resume: --resume finishes the run it names as it was planned")
    args.problem = args.problem or list(QUICK_PROBLEMS)
    args.integrator = args.integrator or list(QUICK_SCHEMES)
    args.checks = 0 if args.checks is None else args.checks
    args.no_ensemble = True
    args.processes = args.processes or 1
    args.no_html = args.no_html or args.html is None


def quick_text(args) -> str:
    """What --quick runs and what it leaves out, and where the rest is."""
    left = [what for what, out in (("timing processes (--processes N)", args.processes == 1),
                                   ("results page (--html DIR)", args.no_html),
                                   ("checks (--checks N)", not args.checks)) if out]
    return (f"quick matrix: {', '.join(args.problem)} x {', '.join(args.integrator)}"
            + (f"; no {', no '.join(left)}" if left else "") + "; `longtime matrix` runs the full one")


def cmd_matrix(args) -> int:
    phases.since_process_start("startup")  # the interpreter, the imports, the plugins
    if args.quick:
        quick(args)
    warn_broken()
    executor = args.executor or "process"
    options = matrix_options(args, executor)
    shown = Progress(on=not args.no_progress)
    if args.quick:
        shown.say(quick_text(args))
    page_wanted = not args.no_report and not args.no_html
    spec = MainJobSpec(selection=matrix_selection(args) if args.resume is None else Selection(), resume=args.resume,
                       executor=executor, options=options, db=args.db, command=command_line(args),
                       baseline=args.baseline, checks=CHECKS if args.checks is None else args.checks,
                       ensembles=not args.no_ensemble, list_moves=args.full,
                       writable=(("--html", args.html),) if args.html and page_wanted else ())
    ahead = None
    if page_wanted:  # the page's figures, drawn on the pool's idle workers
        from longtime.reporting.figures_ahead import FiguresAhead as ahead
    out = None
    # the workers of the checks draw the page's last figures, then end
    with contextlib.ExitStack() as workers:
        job = run_main_job(spec, progress=shown, ahead=ahead, keep_workers=workers)
        if not job.ran:  # a resumed run whose cells were all stored: marked done
            return 0
        if not args.no_report:
            from longtime.reporting.main_job_report import page_and_report

            out = page_and_report(job, args.html, page=not args.no_html, full=args.full, progress=shown)
    page_error = None
    if out is not None:
        page_error = out.page_error
        print(out.text)
        print("\n" + wrapped(f"calibration: {drift_text(job.store.calibrations(job.run_id))}"))
        if out.page is not None and args.full:  # the first screen names it; the full text ends with it
            print(f"\nresults page: {out.page}")
    code = 0
    if args.baseline is not None:  # CI's gate: this run against the baseline, exit 1 on a regression
        from longtime.reporting import compare

        print(f"\n== compared with run {args.baseline} (longtime compare {args.baseline} {job.run_id}) ==")
        code = compare.report(compare.run_compare(job.store.path, str(args.baseline), job.store.path,
                                                  str(job.run_id)))
    if page_error:  # the rows are stored and reported; the page the command owes is not there
        print(f"longtime matrix: error: {page_error}", file=sys.stderr)
        return max(code, 1)
    return code
