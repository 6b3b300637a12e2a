"""``longtime merge A.sqlite B.sqlite ... --into C.sqlite``: the runs of several stores (of
several machines, usually) in one store, each run with its own machine, versions and
calibrations (longtime.execution.store_merge.merge_stores): rows of two machines are never pooled
as if measured in one place. ``report``, ``compare``, ``history`` and the results page of
the merged store show the cross-machine table (longtime.reporting.machines).

A run keeps its id unless the target holds that id already (then it gets the next free
one: the line of each run says where it went); a run merged before is brought up to date
(rows added or completed since, its status), never copied twice. A run still running in its
source is copied as it stands (status running) and completed by a later merge. Every row is
checked as the store checks a row it adds, and every check and ensemble record as it checks
one of those: a refused row or record is not copied, and one line on stderr per reason says
how many. Where two copies of one run hold different rows, one line
on stderr names the run and the count, the copy already in the target is kept, and the exit
status is 1. Prints one line per run (``--format json``: one record per run).
"""
from __future__ import annotations

import json
import sys


def cmd_merge(args) -> int:
    from longtime.execution.store_merge import merge_stores

    merged = merge_stores(args.stores, args.into)
    if args.format == "json":
        print(json.dumps(merged, indent=1))
    else:
        for m in merged:
            print(f"{m['store']} run {m['run']} ({m['status']}) -> {_where(m, args.into)}")
    for m in merged:
        for reason, count in m["refused"].items():
            print(f"warning: {m['store']} run {m['run']}: {count} row(s) not copied, refused by the row check: "
                  f"{reason}", file=sys.stderr)
        for reason, count in m.get("refused_records", {}).items():
            print(f"warning: {m['store']} run {m['run']}: {count} record(s) not copied, refused by the record "
                  f"check: {reason}", file=sys.stderr)
        if m["differ"]:
            print(f"warning: {m['store']} run {m['run']}: {m['differ']} row(s) differ from the copy in {args.into} "
                  f"(run {m['copy']}): the copy's rows are kept", file=sys.stderr)
        if m["status"] == "running":
            print(f"note: {m['store']} run {m['run']} is still running there (not marked finished): copied as it "
                  f"stands; merge again when it ends", file=sys.stderr)
    copied = sum(m["merged"] == "copied" for m in merged)
    updated = sum(m["merged"] == "updated" for m in merged)
    print(f"{len(merged)} run(s) merged into {args.into}: {copied} copied, {updated} updated, "
          f"{len(merged) - copied - updated} unchanged", file=sys.stderr)
    return 1 if any(m["differ"] for m in merged) else 0


def _where(m: dict, into: str) -> str:
    """Where the run of the record ``m`` went, and what changed there."""
    if m["merged"] == "copied":
        return f"run {m['copy']}" + (f" ({m['added']} row(s) copied)" if m["refused"] else "")
    if m["merged"] == "unchanged":
        return f"already in {into} as run {m['copy']}: unchanged"
    changes = [f"{m[k]} row(s) {said}" for k, said in (("added", "added"), ("replaced", "completed")) if m[k]]
    if m["status_was"] is not None:
        changes.append(f"status {m['status_was']} -> {m['status']}")
    return f"run {m['copy']} updated: {', '.join(changes)}"


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("merge", help="the runs of several stores (several machines) in one store, each run "
                                            "keeping its machine", description=__doc__.split("\n\n")[0])
    p.add_argument("stores", nargs="+", metavar="STORE", help="the stores to merge (left as they are)")
    p.add_argument("--into", required=True, metavar="STORE", help="the store that receives them (created if missing)")
    p.add_argument("--format", choices=["table", "json"], default="table")
    p.set_defaults(func=cmd_merge)
