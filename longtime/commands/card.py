"""``longtime card SCHEME``: the scheme's card (longtime.reporting.card) from a stored run."""
from __future__ import annotations

import sys

from longtime.core import cli_args, jsontext
from longtime.core.params import InputError
from longtime.execution.cells import DEFAULT_TIME_LIMIT
from longtime.execution.limits import PastLimit, call_limited, default_memory_limit


def add_parser(subparsers) -> None:
    from longtime.execution.store import default_path

    p = subparsers.add_parser("card", help="one scheme's card: orders, growth, cost, Pareto place, stability, "
                                           "structure")
    p.add_argument("scheme", metavar="SCHEME", help="a scheme name (see `longtime list`)")
    p.add_argument("--run", default=None, help="run id, or 'all' (default: every run of the store, as recommend "
                                                "reads it)")
    p.add_argument("--db", default=None, help=f"SQLite store (default: $LONGTIME_DB or {default_path()})")
    p.add_argument("--format", choices=["table", "json", "markdown"], default="table")
    p.add_argument("--full", action="store_true",
                   help="each undetermined order with its reason and slopes, and each problem the scheme does not "
                        "apply to, on a line of its own (by default each kind summarised in one line)")
    p.add_argument("--time-limit", type=cli_args.seconds("--time-limit", allow_zero=True), default=DEFAULT_TIME_LIMIT,
                   metavar="SECONDS", help=f"seconds the card (the scheme's runs it measures) may take, as a cell's "
                                           f"limit (default {DEFAULT_TIME_LIMIT:g}; 0: no limit)")
    p.set_defaults(func=cmd_card)


def stored_rows(db, run: str | None) -> tuple[list[dict], str]:
    """(rows of ``run`` in the store ``db`` (every run by default or for 'all', as
    ``longtime recommend`` reads them; a run id narrows), what they are); no rows when the
    store has none."""
    from pathlib import Path

    from longtime.execution.store import Store, default_path

    path = Path(db) if db else Path(default_path())
    if run is not None and run != "all" and not (run.isascii() and run.isdigit()):
        raise InputError(f"--run {run!r}: expected a run id (a positive integer) or 'all'")
    if not path.exists():
        if run is not None:
            raise InputError(f"--db {path}: no such store, so no run {run}")
        return [], f"no store at {path}"
    store = Store(path, readonly=True)
    if run is None or run == "all":
        return store.rows(), f"every run of {path}"
    store.run(int(run))  # InputError naming the runs there are
    return store.rows(int(run)), f"run {run} of {path}"


def cmd_card(args) -> int:
    from longtime.core import registry
    from longtime.reporting.card import card, card_markdown, card_text

    registry.integrator_class(args.scheme)  # an unknown name: one line naming the known ones
    rows, source = stored_rows(args.db, args.run)
    try:  # the scheme's code runs here (its structure): under a cell's limits
        limit = getattr(args, "time_limit", DEFAULT_TIME_LIMIT) or None
        found = call_limited(card, args.scheme, rows, time_limit=limit, memory_limit=default_memory_limit())
    except PastLimit as exc:
        raise PastLimit(f"the card of {args.scheme}: {exc}") from None
    found["rows_from"] = source
    if args.format == "json":
        print(jsontext.dumps(found, default=str))
    elif args.format == "markdown":
        print(card_markdown(found))
    else:
        print(card_text(found, full=args.full))
    print(f"card of {args.scheme} from {source}", file=sys.stderr)
    return 0
