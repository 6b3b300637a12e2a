"""The metrics phase of a store's cells (``metrics.evaluate`` and, for a chaotic problem,
``lyapunov.row_fields``: what ``run_cell`` times as "metrics"), CPU seconds, of two copies
of the code on the same trajectories, alternated in fresh processes, and whether every row
has the same bits.

``--prepare``: integrate up to ``--per`` cells of each problem of the store (spread over its
rows) once and keep each trajectory and its reference in ``--dir``. Then each round runs one
process per code (the order alternates) that measures every kept trajectory.

    git archive BASE longtime | tar -x -C /tmp/base      # the code to compare against
    python benchmarks/bench_metrics_ab.py --prepare --db STORE --dir /tmp/set
    python benchmarks/bench_metrics_ab.py --dir /tmp/set --base /tmp/base --rounds 4
"""
from __future__ import annotations

import argparse
import collections
import hashlib
import json
import os
import pickle
import subprocess
import sys
import time
from pathlib import Path


def prepare(db: str, folder: Path, per: int) -> None:
    from longtime.core.status import Status
    from longtime.core.timing import Timing
    from longtime.execution.cells import build, cell_of_row
    from longtime.execution.store import Store
    from longtime.measure.reference import has_reference, trusted_reference

    by_problem = collections.defaultdict(list)
    for r in Store(db, readonly=True).rows():
        if r.get("samples") and r["status"] in (Status.OK, Status.DIVERGED, Status.TIMEOUT):
            by_problem[r["problem"]].append(r)
    folder.mkdir(parents=True, exist_ok=True)
    k = 0
    for rows in by_problem.values():
        for r in rows[::max(1, len(rows) // per)][:per]:
            cell = cell_of_row(r)
            problem, scheme = build(cell)
            traj = scheme.integrate(problem, cell.t_final, timing=Timing(repeats=1, min_time=0))
            ref = trust = None
            if has_reference(problem):
                try:
                    ref, trust = trusted_reference(problem, traj.t, cell.t_final)
                except Exception as exc:
                    print(f"{cell.problem} x {cell.integrator}: no reference ({exc})", file=sys.stderr)
            (folder / f"{k:04d}.pkl").write_bytes(pickle.dumps((cell.to_dict(), traj, ref, trust)))
            k += 1


def measure(folder: Path) -> None:
    from longtime.execution.cells import Cell, build
    from longtime.measure import lyapunov, metrics

    per, digests = collections.Counter(), []
    for path in sorted(folder.glob("*.pkl")):
        cell_dict, traj, ref, trust = pickle.loads(path.read_bytes())[:4]
        problem, _ = build(Cell.from_dict(cell_dict))
        start = time.process_time()
        row = metrics.evaluate(problem, traj, ref, trust)
        if problem.chaotic:
            row.update(lyapunov.row_fields(problem, row))
        per[problem.name] += time.process_time() - start
        digests.append(hashlib.sha1(json.dumps(row, sort_keys=True, default=repr).encode()).hexdigest())
    print(json.dumps({"per": per, "digests": digests}))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--dir", required=True, type=Path)
    parser.add_argument("--prepare", action="store_true")
    parser.add_argument("--db")
    parser.add_argument("--per", type=int, default=10)
    parser.add_argument("--base", help="the folder holding the other copy of the longtime package")
    parser.add_argument("--rounds", type=int, default=4)
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.prepare:
        prepare(args.db, args.dir, args.per)
        return
    if args.child:
        measure(args.dir)
        return
    codes = {"base": args.base, "this": str(Path(__file__).resolve().parents[1])}
    found: dict[str, list] = {k: [] for k in codes}
    for r in range(args.rounds):
        for name in (list(codes) if r % 2 == 0 else list(codes)[::-1]):
            env = {**os.environ, "PYTHONPATH": codes[name]}
            out = subprocess.run([sys.executable, __file__, "--child", "--dir", str(args.dir)], env=env,
                                 capture_output=True, text=True, check=True)
            found[name].append(json.loads(out.stdout))
    base, this = found["base"], found["this"]
    same = sum(a == b for a, b in zip(base[0]["digests"], this[0]["digests"]))
    print(f"rows with the same bits: {same} of {len(base[0]['digests'])}")
    print("problem              base CPU s (each round)          this CPU s")
    for p in base[0]["per"]:
        each = [" ".join(f"{x['per'][p]:6.3f}" for x in found[k]) for k in codes]
        print(f"{p:20s} {each[0]:32s} {each[1]}")
    totals = [sorted(sum(x["per"].values()) for x in found[k]) for k in codes]
    print(f"total: base {totals[0]}, this {totals[1]}; median this / base "
          f"{totals[1][len(totals[1]) // 2] / totals[0][len(totals[0]) // 2]:.3f}")


if __name__ == "__main__":
    main()
