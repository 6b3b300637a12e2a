"""``longtime merge A.sqlite B.sqlite ... --into C.sqlite``: the runs of several stores (of
several machines, usually) in one store, each run with its own machine, versions and
calibrations (longtime.execution.store_merge.merge_stores): rows of two machines are never pooled
as if measured in one place. ``report``, ``compare``, ``history`` and the results page of
the merged store show the cross-machine table (longtime.reporting.machines).

A run keeps its id unless the target holds that id already (then it gets the next free
one: the line of each run says where it went); a run merged before is not copied again.
Prints one line per run (``--format json``: one record per run).
"""
from __future__ import annotations

import json
import sys


def cmd_merge(args) -> int:
    from longtime.execution.store_merge import merge_stores

    merged = merge_stores(args.stores, args.into)
    if args.format == "json":
        print(json.dumps(merged, indent=1))
        return 0
    for m in merged:
        where = f"run {m['id']}" if m["id"] is not None else f"already in {args.into}: not copied"
        print(f"{m['store']} run {m['run']} ({m['status']}) -> {where}")
    copied = sum(m["id"] is not None for m in merged)
    print(f"{copied} of {len(merged)} run(s) merged into {args.into}", file=sys.stderr)
    return 0


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("merge", help="the runs of several stores (several machines) in one store, each run "
                                            "keeping its machine", description=__doc__.split("\n\n")[0])
    p.add_argument("stores", nargs="+", metavar="STORE", help="the stores to merge (left as they are)")
    p.add_argument("--into", required=True, metavar="STORE", help="the store that receives them (created if missing)")
    p.add_argument("--format", choices=["table", "json"], default="table")
    p.set_defaults(func=cmd_merge)
