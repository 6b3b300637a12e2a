"""Does Dask pay? Throughput of a 2,000-cell sweep on a local Dask cluster against the process pool.

The goal: on a 2-core machine, a LocalCluster of 2 workers reaches at least 80 % of
the process pool's throughput (cells per wall second) on the same sweep of short cells, so
that a cluster run costs nothing on one machine and scales past it. The sweep is Toda's
lattice with d = 3, 4, ... (one problem instance per d) x six fixed-step schemes x 34 steps
from 0.02 to 0.1, to t = 10: short cells, where the executor's own overhead (task dispatch,
pickling, per-cell process start) shows. Timing is cut to three repeats (no --min-time) for
the same reason.

Both executors are timed warm: a first, untimed pass fills the kernel and reference caches
(the reference of each d is a heyoka build), so neither pays for what the other compiled.
Each timed pass includes starting its workers (the pool's processes, the cluster).

    python benchmarks/bench_dask.py                 # 2,040 cells, prints the ratio
    python benchmarks/bench_dask.py --dims 2        # a smaller sweep (408 cells)
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np

GOAL = 0.80
SCHEMES = ["rk4", "verlet", "yoshida6", "gauss4", "midpoint", "symplectic-euler"]
STEPS = [float(x) for x in np.geomspace(0.02, 0.1, 34)]


def sweep(dims: int):
    from longtime.execution.cells import expand

    cells = []
    for d in range(3, 3 + dims):
        cells += expand(["toda"], SCHEMES, sweeps={"dt": STEPS}, t_final=10.0, sets={"d": d})
    return cells


def throughput(cells, executor: str, jobs: int) -> tuple[float, float]:
    """(cells per wall second, wall seconds) of one pass; every row must come back ok."""
    from longtime.core.timing import Timing
    from longtime.execution.matrix import ExecOptions, run_matrix

    options = ExecOptions(jobs=jobs, timing=Timing(repeats=3, min_time=0.0), max_samples=2001)
    start = time.perf_counter()
    rows = run_matrix(cells, None, None, executor, options)
    wall = time.perf_counter() - start
    bad = [r for r in rows if r["status"] != "ok"]
    if len(rows) != len(cells) or bad:
        raise SystemExit(f"{executor}: {len(rows)} rows for {len(cells)} cells, {len(bad)} not ok: "
                         f"{bad[:1]}")
    return len(cells) / wall, wall


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dims", type=int, default=10, help="values of d (cells = 204 x dims)")
    parser.add_argument("--jobs", type=int, default=2, help="workers of each executor")
    args = parser.parse_args(argv)
    cells = sweep(args.dims)
    print(f"{len(cells)} cells (toda d = 3..{2 + args.dims} x {len(SCHEMES)} schemes x {len(STEPS)} dt), "
          f"{args.jobs} workers")
    throughput(cells, "process", args.jobs)  # untimed: fills the kernel and reference caches
    pool, pool_wall = throughput(cells, "process", args.jobs)
    dask, dask_wall = throughput(cells, "dask", args.jobs)
    ratio = dask / pool
    print(f"process pool  {pool:8.1f} cells/s  ({pool_wall:.1f} s)")
    print(f"dask          {dask:8.1f} cells/s  ({dask_wall:.1f} s)")
    print(f"dask / pool   {ratio:8.2f}  (goal >= {GOAL})")
    return 0 if ratio >= GOAL else 1


if __name__ == "__main__":
    sys.exit(main())
