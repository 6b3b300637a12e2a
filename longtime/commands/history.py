"""``longtime history``: every cell's calibrated time and errors over every stored run, with
the commit and date of each run, and the steps in each series.

The series and their steps: longtime.reporting.history.
"""
from __future__ import annotations

from longtime.core import jsontext
from longtime.core.params import InputError
from longtime.reporting import machines
from longtime.reporting.compare import cross_machine_table
from longtime.reporting.history import history, render, selected


def cmd_history(args) -> int:
    from longtime.execution.store import Store

    store = Store(args.db, readonly=True)
    sets = dict(args.set)
    from longtime.core.progress import Progress

    with Progress().phase("history", detail="every stored run's rows of the selection", announce=False):
        found = history(store, args.problem, args.integrator, sets)
    if not found:
        raise InputError(f"no stored cell in {store.path} matches -p/-i/--set")
    if args.format == "json":  # each run's point names its machine
        print(jsontext.dumps(found))
        return 0
    table = cross_machine_table(store, [r for r in store.rows() if selected(r, args.problem, args.integrator, sets)])
    print(render(found) + (f"\n\n{machines.text(table)}" if table else ""))
    return 0


def add_parser(subparsers) -> None:
    from longtime.core import cli_args

    p = subparsers.add_parser("history", help="each cell's calibrated time and errors over every stored run, "
                                              "with the steps marked",
                              description=__doc__.split("\n\n")[0])
    p.add_argument("-p", "--problem", type=cli_args.names, default=None, metavar="PROBLEM[,..]")
    p.add_argument("-i", "--integrator", type=cli_args.names, default=None, metavar="SCHEME[,..]")
    p.add_argument("--set", type=cli_args.key_value, action="append", default=[], metavar="KEY=VALUE",
                   help="only cells with this setting (dt, tol, eps_res, order or any --set parameter)")
    p.add_argument("--db", default=None, help="the store (default: $LONGTIME_DB or longtime.sqlite)")
    p.add_argument("--format", choices=["table", "json"], default="table")
    p.set_defaults(func=cmd_history)
