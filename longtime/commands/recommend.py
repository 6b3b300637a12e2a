"""``longtime recommend``: the cheapest stored setting predicted to keep an error up to a
horizon on a problem, with the runner-up and the evidence (longtime.reporting.verdict)."""
from __future__ import annotations

from pathlib import Path

from longtime.core import cli_args, registry
from longtime.core.params import InputError
from longtime.execution.store import Store, default_path


def answer(problem: str, error: float, horizon: float, db: str | None = None, run: str | None = None):
    """The Recommendation from the store ``db`` (its rows of ``run``: an id, 'all', or by
    default every run), and the checks stored beside them."""
    from longtime.reporting.verdict import recommend

    if problem not in registry.problems():
        raise InputError(f"-p {problem}: unknown problem; known: {', '.join(sorted(registry.problems()))}")
    path = Path(db or default_path())
    if not path.exists():
        raise InputError(f"store {path}: no such file; `longtime matrix -p {problem} --db {path}` measures the cells "
                         f"to decide")
    store = Store(path, readonly=True)
    if run in (None, "all"):
        rows, checks = store.rows(), store.checks()
    else:
        if not (str(run).isascii() and str(run).isdigit()):
            raise InputError(f"--run {run!r}: expected a run id (a positive integer) or 'all'")
        store.run(int(run))
        rows, checks = store.rows(int(run)), store.checks(int(run))
    return recommend(rows, problem, error, horizon, db=str(store.path) if db else None,
                     known=registry.problems(), checks=checks)


def cmd_recommend(args) -> int:
    print(answer(args.problem, args.error, args.horizon, args.db, args.run))
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
