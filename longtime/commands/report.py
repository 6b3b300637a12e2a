"""``longtime report``: tables of stored rows (and the results page with --html)."""
from __future__ import annotations

import sys

from longtime.commands.common import notices, wrapped
from longtime.core import cli_args
from longtime.core.files import write_atomic
from longtime.core.params import InputError
from longtime.execution.calibration import drift_text
from longtime.execution.store import Store


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("report", help="tables of stored rows: accuracy against cost per problem")
    p.add_argument("--db", default=None)
    p.add_argument("--run", default=None, help="run id, or 'all' (default: the latest run)")
    p.add_argument("-p", "--problem", type=cli_args.names, default=None)
    p.add_argument("--format", choices=["table", "csv", "json", "markdown", "parquet"], default="table",
                   help="table: the summary (status counts, Pareto front per problem); csv, json, "
                        "markdown: every cell; parquet: every cell into --out")
    p.add_argument("--full", action="store_true", help="the full per-cell tables after the summary")
    p.add_argument("--html", default=None, type=cli_args.out_folder("--html"), metavar="DIR",
                   help="also write the results page DIR/index.html")
    p.add_argument("--out", default=None, type=cli_args.out_file("--out"), metavar="FILE",
                   help="write the report to FILE (parquet: default longtime.parquet)")
    p.set_defaults(func=cmd_report)


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
    notices(r["integrator"] for r in rows)
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
            print("\n" + wrapped(f"calibration: {drift_text(store.calibrations(run_id))}"))
        if args.format == "table":  # rows of several machines (a merged store): side by side
            from longtime.reporting import compare, machines

            table = compare.cross_machine_table(store, rows)
            if table:
                print(f"\n{machines.text(table)}")
    return 0
