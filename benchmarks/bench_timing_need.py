"""How long do the main job's timing processes take by need, against timing every cell?

A stored run's cells are timed again in fresh processes as the main job's timing phase does
(longtime.execution.processes.across_processes, ``--processes`` 3), alternately with
``--timing all`` and ``--timing need`` (longtime.predict.need), in the same period; each
round starts from the rows as their own process measured them (the first of
``cpu_s_processes``). Printed per round: the cells timed in 3 processes and in their own
process only, the timing phase's wall seconds, and the ratio need / all; then how the
contenders' ``cpu_s`` agree between the two ways (max / min: the share within x1.15).

    python -m longtime matrix -p kepler,toda,henon-heiles --db /tmp/t.sqlite   # a stored run
    python benchmarks/bench_timing_need.py --db /tmp/t.sqlite [--run ID] [--rounds 2] [-p kepler,toda]
"""
from __future__ import annotations

import argparse
import dataclasses
import statistics
import sys
import time

HOLD = 1.15  # the hold of a cell's cpu_s between invocations
PROCESS_FIELDS = ("cpu_s_processes", "cpu_s_process_spread", "timed_in")


def own_process(row: dict) -> dict:
    """``row`` as its own process measured it (before the timing processes)."""
    out = {k: v for k, v in row.items() if k not in PROCESS_FIELDS}
    mins = row.get("cpu_s_processes") or []
    if mins:
        out["cpu_s"] = mins[0]
    return out


def timing_phase(pairs, retime: str, processes: int = 3) -> tuple[float, list[dict]]:
    """Wall seconds of the timing phase of ``pairs`` (cell, row) under ``retime``, and the rows."""
    from longtime.execution.matrix import ExecOptions
    from longtime.execution.processes import across_processes, by_need

    options = ExecOptions(processes=processes)
    spec = dataclasses.replace(options.run_spec(), timing=options.timing.per_process(processes))
    mine = [(c, own_process(r)) for c, r in pairs]
    rows = [r for _, r in mine]
    start = time.perf_counter()
    alone = by_need(rows, mine, retime)
    across_processes(mine, processes, spec, options.workers(), alone=alone)
    return time.perf_counter() - start, rows


def main(argv: list[str] | None = None) -> int:
    from longtime.execution.store import Store

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--db", required=True, help="a store holding a main job's run")
    parser.add_argument("--run", type=int, default=None, help="its run id (default: the newest)")
    parser.add_argument("--rounds", type=int, default=2, help="rounds of (all, need) (default: 2)")
    parser.add_argument("-p", "--problem", default=None, help="only these problems' rows (comma-separated)")
    args = parser.parse_args(argv)
    store = Store(args.db, readonly=True)
    run_id = args.run or max(r["id"] for r in store.runs())
    pairs = store.incomplete_rows(run_id, "status")  # every stored row with its cell
    if args.problem:
        pairs = [(c, r) for c, r in pairs if c.problem in args.problem.split(",")]
    print(f"run {run_id} of {args.db}: {len(pairs)} rows")
    print(f"{'round':>5s} {'timing':>7s} {'3 processes':>12s} {'own process':>12s} {'wall s':>8s}")
    ratios, last = [], {}
    for k in range(args.rounds):
        walls = {}
        for retime in ("all", "need"):
            wall, rows = timing_phase(pairs, retime)
            walls[retime] = wall
            last[retime] = rows
            three = sum(1 for r in rows if str(r.get("timed_in") or "").endswith("processes"))
            alone = sum(1 for r in rows if str(r.get("timed_in") or "").startswith("its own process"))
            print(f"{k + 1:5d} {retime:>7s} {three:12d} {alone:12d} {wall:8.1f}", flush=True)
        ratios.append(walls["need"] / walls["all"])
        print(f"{'':5s} need / all: {ratios[-1]:.2f}")
    print(f"timing phase need / all: median {statistics.median(ratios):.2f} over {len(ratios)} round(s)")
    held = [max(a["cpu_s"], b["cpu_s"]) / min(a["cpu_s"], b["cpu_s"])
            for a, b in zip(last["all"], last["need"])
            if str(b.get("timed_in") or "").endswith("processes") and a.get("cpu_s") and b.get("cpu_s")]
    if held:
        print(f"the contenders' cpu_s, need against all (last round): median x{statistics.median(held):.3f}, "
              f"{sum(h <= HOLD for h in held) / len(held):.0%} within x{HOLD:g} ({len(held)} cells)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
