"""``longtime recommend``: the cheapest stored setting predicted to keep an error up to a
horizon on a problem, with the runner-up and the evidence (longtime.reporting.verdict)."""
from __future__ import annotations

from longtime.core import cli_args
from longtime.execution.store import default_path


def cmd_recommend(args) -> int:
    from longtime.api import recommend

    print(recommend(args.problem, args.error, args.horizon, db=args.db, run=args.run))
    return 0


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("recommend", help="which scheme and setting keep an error up to a horizon, cheapest")
    p.add_argument("-p", "--problem", required=True, metavar="PROBLEM", help="a problem name (see `longtime list`)")
    p.add_argument("--error", type=cli_args.positive_number("--error"), required=True, metavar="E",
                   help="the target error (the solution error where the problem has a reference, else the "
                        "relative energy error)")
    p.add_argument("--horizon", type=cli_args.positive_number("--horizon"), required=True, metavar="T",
                   help="the final time the error must hold to")
    p.add_argument("--db", default=None, help=f"SQLite store (default: $LONGTIME_DB or {default_path()})")
    p.add_argument("--run", default=None, help="run id, or 'all' (default: every run of the store)")
    p.set_defaults(func=cmd_recommend)
