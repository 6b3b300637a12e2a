"""What the commands that run cells share (run, matrix), and report: the selection and
execution flags, the execution options they give, plugin warnings and scheme notices on
stderr, and a line of the report's text wrapped."""
from __future__ import annotations

import argparse
import sys

from longtime.core import cli_args, registry
from longtime.core.cache import check_cache_root
from longtime.core.integrator import Timing
from longtime.core.params import InputError
from longtime.core.roles import ROW_PARAMETERS, flag
from longtime.execution import limits
from longtime.execution.cells import DEFAULT_TIME_LIMIT
from longtime.execution.matrix import COSTS, EXECUTORS, ExecOptions, check_cost
from longtime.execution.processes import DEFAULT_PROCESSES, RETIME, default_processes, max_processes
from longtime.execution.store import default_path
from longtime.measure.reference_runs import budget_seconds
from longtime.predict.need import FACTOR as NEED_FACTOR

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
    p.add_argument("--timing", choices=RETIME, default=None,
                   help="which cells those fresh processes time again: need, those whose time could change an "
                        f"answer (within x{NEED_FACTOR:g} of a front of error against CPU of their problem, or named "
                        "by a verdict or a check; the rest keep their own process's time, a run or a few, and each "
                        "row's timed_in says which and why), or all (default: need for matrix, all for run)")
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


def selection(args) -> dict:
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


def exec_options(args, executor: str) -> ExecOptions:
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
                       processes=args.processes or default_processes(), retime=getattr(args, "timing", None) or "all",
                       cell_timeout=getattr(args, "cell_timeout", None),
                       time_limit=getattr(args, "time_limit", DEFAULT_TIME_LIMIT) or None,
                       memory_limit=getattr(args, "memory_limit", limits.default_memory_limit()),
                       scheduler=getattr(args, "scheduler", None))


def warn_broken() -> None:
    for b in registry.broken():
        print(f"warning: plugin {b.group} '{b.name}' ({b.target}) failed to load: {b.error}", file=sys.stderr)


def notices(schemes) -> None:
    """The notice of each named scheme that has one (``Integrator.notice``), on stderr."""
    known = registry.integrators()
    for name in sorted(set(schemes)):
        notice = getattr(known.get(name), "notice", "")
        if notice:
            print(f"notice: {name}: {notice}", file=sys.stderr)


def wrapped(text: str) -> str:
    """A line of the report's text wrapped at the report's width, continued indented."""
    import textwrap

    from longtime.reporting.screen import WIDTH

    return "\n".join(textwrap.wrap(text, width=WIDTH, subsequent_indent="  ", break_on_hyphens=False))
