"""What does the main job's ensemble step cost?

``longtime matrix`` ends (before its report) with the ensemble step
(longtime.execution.ensembles): on the chaotic problems it covers, each scheme's ensemble
against heyoka's. This script runs that step again on a stored run's rows, in this process
as the matrix does, and prints its CPU and wall seconds and the records' statuses:

    python benchmarks/bench_ensemble_step.py --db longtime.sqlite --run RUN_ID

The first call on a machine also computes heyoka's ensembles and the chaotic states'
Lyapunov times (cached in $LONGTIME_CACHE_DIR's reference folder after); run it twice to
see both. Nothing is stored.
"""
from __future__ import annotations

import argparse
import collections
import time


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--db", default="longtime.sqlite")
    parser.add_argument("--run", type=int, default=None, help="run id (default: the newest)")
    args = parser.parse_args()
    from longtime.execution import ensembles
    from longtime.execution.store import Store

    store = Store(args.db, readonly=True)
    run_id = args.run or store.latest_run()
    rows = store.rows(run_id)
    cpu, wall = time.process_time(), time.perf_counter()
    records = ensembles.run(None, None, rows)
    cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
    print(f"ensemble step on run {run_id}: {cpu:.2f} s CPU, {wall:.2f} s wall")
    for problem in sorted({r["problem"] for r in records}):
        mine = [r for r in records if r["problem"] == problem]
        counts = collections.Counter(r["status"] for r in mine)
        members = sum(r.get("cpu_s") or 0.0 for r in mine)
        print(f"  {problem}: {', '.join(f'{k} {v}' for k, v in sorted(counts.items()))}; "
              f"the schemes' members {members:.2f} s CPU")


if __name__ == "__main__":
    main()
