"""Does a chain's run stopped on its pace hold its claim? In the main job's chains of a
library's settings (longtime.execution.batches), a later setting is judged on its pace once
it has spent the CPU seconds of a setting that keeps the target, and stops where its pace
puts its end past ``limits.CHAIN_PACE`` times its bound: its row says it cannot be its
library's cheapest. This runs each such row of a store again to its end (in this process,
capped at --cap CPU seconds) and prints its whole CPU against the keeper's (the claim: more
than once) and the pace's projection against the whole run.

    python benchmarks/bench_chain_pace.py --db longtime.sqlite [--cap 5]

Exit 1 where a whole run took less than the keeper's CPU seconds.
"""
from __future__ import annotations

import argparse
import re
import statistics
import sys


def main() -> int:
    from longtime.core.status import BOUNDED
    from longtime.execution.cells import build, cell_of_row
    from longtime.execution.store import Store

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--db", default="longtime.sqlite")
    parser.add_argument("--cap", type=float, default=5.0, help="CPU seconds a whole run may take (default 5)")
    args = parser.parse_args()
    ratios, projections, capped, wrong = [], [], 0, 0
    for r in Store(args.db, readonly=True).rows():
        message = r.get("message") or ""
        if not (r["status"] == "timeout" and message.startswith(BOUNDED) and "(on its pace:" in message):
            continue
        kept = float(re.search(r"CPU of .*? \(([\d.e+-]+) s\), which keeps", message).group(1))
        problem, integrator = build(cell_of_row(r))
        t_final = problem.default_t_final if r.get("t_final") is None else r["t_final"]
        whole = integrator.integrate(problem, t_final, cpu_bound=args.cap)
        done = whole.status != "timeout"
        ratio = whole.cpu_s / kept
        capped += not done
        wrong += ratio <= 1.0
        if done:
            ratios.append(ratio)
            projections.append(r["pace_cpu_s"] / whole.cpu_s)
        print(f"{r['problem']:22s} {r['integrator']:12s} tol={r.get('tol'):<8g} keeper {kept:.3g} s, stopped at "
              f"{r['cpu_s']:.3g} s, projected {r.get('pace_cpu_s') or float('nan'):.3g} s; whole "
              f"{'>' if not done else ''}{whole.cpu_s:.3g} s: x{ratio:.3g} the keeper's", flush=True)
    if ratios:
        print(f"{len(ratios) + capped} rows stopped on their pace: {len(ratios)} ended within {args.cap:g} s, "
              f"{capped} passed it; whole / keeper's CPU at least x{min(ratios):.3g} (median "
              f"x{statistics.median(ratios):.3g}); projection / whole x{min(projections):.3g} to "
              f"x{max(projections):.3g} (median x{statistics.median(projections):.3g})")
    return 1 if wrong else 0


if __name__ == "__main__":
    sys.exit(main())
