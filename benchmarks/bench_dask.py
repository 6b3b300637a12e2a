"""Does Dask keep up? Throughput of a sweep of short cells on a local Dask cluster against the process pool.

The goal: a LocalCluster of 2 single-threaded workers reaches at least 80 % of the process
pool's throughput (cells per wall second) on the same sweep of short cells, with the default
time and memory limits in force (on Dask each worker runs its batches in a long-lived child
process, longtime.execution.resident.Resident). The sweep is toda, kepler, henon-heiles,
harmonic and duffing-2 x rk4, verlet, gauss4 and yoshida6 x ``cells / 20`` steps from 0.005
to 0.05, to t = 20: short cells, where an executor's own cost (task dispatch, process
starts, pickling) shows. Timing is cut to three repeats (no --min-time) and each executor
times in one process (``processes=1``) for the same reason.

Both executors are timed warm: a first, untimed pass of the pool fills the kernel and
reference caches, so neither pays for what the other compiled. Each timed pass includes
starting its workers (the pool's processes, the cluster and its children).

    python benchmarks/bench_dask.py                 # 200 cells, prints the ratio
    python benchmarks/bench_dask.py --cells 2000    # the large form
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np

GOAL = 0.80
PROBLEMS = ["toda", "kepler", "henon-heiles", "harmonic", "duffing-2"]
SCHEMES = ["rk4", "verlet", "gauss4", "yoshida6"]
T_FINAL = 20.0


def sweep(cells: int):
    """``cells`` cells (rounded to a multiple of the problem x scheme pairs)."""
    from longtime.execution.cells import expand

    steps = [float(x) for x in np.geomspace(0.005, 0.05, max(1, cells // (len(PROBLEMS) * len(SCHEMES))))]
    return expand(PROBLEMS, SCHEMES, sweeps={"dt": steps}, t_final=T_FINAL)


def throughput(cells, executor: str, jobs: int) -> tuple[float, float]:
    """(cells per wall second, wall seconds) of one pass; every row must come back ok."""
    from longtime.core.timing import Timing
    from longtime.execution.matrix import ExecOptions, run_matrix

    options = ExecOptions(jobs=jobs, timing=Timing(repeats=3, min_time=0.0), max_samples=2001, processes=1)
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
    parser.add_argument("--cells", type=int, default=200, help="cells of the sweep (a multiple of 20)")
    parser.add_argument("--jobs", type=int, default=2, help="workers of each executor")
    args = parser.parse_args(argv)
    if not 20 <= args.cells <= 100_000 or not 1 <= args.jobs <= 64:
        print("bench_dask: --cells takes 20 to 100000, --jobs 1 to 64", file=sys.stderr)
        return 2
    cells = sweep(args.cells)
    print(f"{len(cells)} cells ({len(PROBLEMS)} problems x {len(SCHEMES)} schemes x "
          f"{len(cells) // (len(PROBLEMS) * len(SCHEMES))} dt, t = {T_FINAL:g}), {args.jobs} workers")
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
