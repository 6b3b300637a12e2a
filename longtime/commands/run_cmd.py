"""``longtime run``: problems x schemes, one row per cell printed (and stored)."""
from __future__ import annotations

import dataclasses
import sys

from longtime.commands.common import add_selection, exec_options, notices, selection, warn_broken
from longtime.core.status import Status
from longtime.execution.cells import expand
from longtime.execution.lifecycle import command_line
from longtime.execution.sizes import check_size
from longtime.execution.store import Store
from longtime.reporting.report import render


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("run", help="run problems x schemes and print one row per cell")
    add_selection(p, required=True)
    p.add_argument("--format", choices=["table", "csv", "json", "markdown"], default="table")
    p.add_argument("--no-store", action="store_true", help="do not append the rows to the store")
    p.set_defaults(func=cmd_run)


def cmd_run(args) -> int:
    from longtime.api import run_cells

    warn_broken()
    cells = expand(args.problem, args.integrator, **selection(args), strict=True)
    notices(c.integrator for c in cells)
    check_size(cells, args.max_samples, args.memory_limit, allow_large=args.allow_large)
    # by default one cell at a time in one worker process, under the hard limits (longtime.execution.limits);
    # --executor serial runs them in this process
    executor = args.executor or "process"
    options = exec_options(args, executor)
    if not args.executor and not args.jobs:
        options = dataclasses.replace(options, jobs=1)
    store = None if args.no_store else Store(args.db)
    rows, _ = run_cells(cells, store=store, command=command_line(args), executor=executor,
                        options=options)
    print(render(rows, args.format))  # json: every row with the contract's keys (report.complete)
    if any(r["status"] == Status.FAILED for r in rows):
        return 1
    if options.cost == "instructions":  # asked for counts and got none: said, and exit 3
        from longtime.execution.valgrind import EXIT_NOTHING_COUNTED, nothing_counted

        why = nothing_counted(rows)
        if why:
            print(f"error: {why}", file=sys.stderr)
            return EXIT_NOTHING_COUNTED
    return 0
