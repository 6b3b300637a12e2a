"""How far each growth class extrapolates: stored settings re-run at 10, 100 and 1000 times
their run's span, the error measured there against the class's prediction.

    python benchmarks/verdict_reach.py --db STORE [--run ID] [--factors 10,100,1000]
        [--per-class 3] [--budget 4] [-p PROBLEM,..] [--kind solution|drifting|invariant]

For every problem that is not chaotic (no row with a Lyapunov time), and every growth class that
extrapolates, the cheapest settings of distinct schemes whose run at the largest factor
costs at most ``--budget`` predicted CPU seconds are re-run (one repeat: the errors, not
the times, are compared) at each factor f, and the line says measured / predicted error
with the prediction e(t_f) f^k of the class's exponent k, uncapped ("lost" where that
prediction is O(1), ``LOST`` or more; "-" where the reference did not reach), and the
setting's trust factor (how many times its run the verdict extrapolates it). The reference gets
$LONGTIME_REFERENCE_SECONDS (default here 60 s) per run. The table in docs/metrics.md
("How far a class is trusted") is its output; the reach factors of the verdict
(``TRUST_FACTORS``) are read from it.
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import sys


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--db", required=True)
    ap.add_argument("--run", type=int, default=None, help="the run (default: the latest)")
    ap.add_argument("--factors", default="10,100,1000")
    ap.add_argument("--per-class", type=int, default=3, help="settings per problem and class")
    ap.add_argument("--budget", type=float, default=4.0, help="predicted CPU seconds of the longest re-run")
    ap.add_argument("-p", "--problems", default="", help="only these problems (comma-separated)")
    ap.add_argument("--kind", default="", help="only settings of this kind (solution, drifting, invariant)")
    args = ap.parse_args(argv)
    os.environ.setdefault("LONGTIME_REFERENCE_SECONDS", "60")

    from longtime.core.timing import Timing
    from longtime.execution.cells import cell_of_row
    from longtime.execution.matrix import ExecOptions, run_matrix
    from longtime.execution.store import Store
    from longtime.predict import decision as D
    from longtime.predict import settings as S

    store = Store(args.db)
    run = args.run if args.run is not None else max(r["id"] for r in store.runs())
    rows = store.rows(run)
    factors = [float(f) for f in args.factors.split(",")]
    opts = ExecOptions(jobs=1, timing=Timing(repeats=1, min_time=0.0), processes=1)
    print("| problem | kind | setting | class | t_f | e(t_f) | " + " | ".join(f"x{f:g}" for f in factors)
          + " | trusted |")
    print("|" + "---|" * (7 + len(factors)))
    for v in D.verdicts(rows).values():
        chaotic = any(r.get("lyapunov_time") for r in rows if r["problem"] == v.problem)  # no power law there
        if v.measure is None or chaotic or (args.problems and v.problem not in args.problems.split(",")):
            continue
        for law in S.EXPONENTS:
            seen, picks = set(), []
            for s in v.candidates:  # cheapest first
                if (s.law != law or s.scheme in seen or (args.kind and s.kind != args.kind)
                        or s.cpu_at(max(factors) * s.span) > args.budget):
                    continue
                seen.add(s.scheme)
                picks.append(s)
                if len(picks) >= args.per_class:
                    break
            for s in picks:
                cells = [cell_of_row(s.row, t_final=f * s.span) for f in factors]
                out = []
                for f, row in zip(factors, run_matrix(cells, None, None, "serial", dataclasses.replace(opts))):
                    measured = row.get(v.measure.field) if row.get("status") == "ok" else None
                    if v.measure.solution and measured is not None and \
                            not (row.get("error_horizon") or 0) >= f * s.span * (1 - 1e-9):
                        measured = None  # the reference stopped short
                    predicted = s.error * f ** S.EXPONENTS[law]
                    if not measured:
                        out.append("-")
                    elif predicted >= S.LOST:  # an O(1) prediction: lost, not a number
                        out.append(f"lost ({measured:.1e})")
                    else:
                        out.append(f"{measured / predicted:.2g} ({measured:.1e})")
                trusted = f"{s.factor:.3g}" + (" (steepening)" if s.steepening else "")
                print(f"| {v.problem} | {s.kind} | {s.text} | {law} | {s.span:.4g} | {s.error:.2g} | "
                      + " | ".join(out) + f" | {trusted} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
