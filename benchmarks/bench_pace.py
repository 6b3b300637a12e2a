"""How well does a run's pace after its first CPU second say where it ends? The default
matrix's settings estimated too slow (longtime.execution.budget: their cheapest setting runs
under a time limit of SLOW_LIMIT_S, and stops once its pace puts its end past PACE_FACTOR
times that limit: ``Cell.pace``).

For each such cell whose scheme stops on its pace, the run's projection at
``peer_common.PACE_AFTER_S`` (a run under a pace bound of 0 s stops at its first look and
keeps it, ``pace_cpu_s``) beside the CPU seconds of its whole run (cut at --cap seconds: then
"> cap"), and their ratio. The goal: no cell whose whole run ends within its time limit is
projected past PACE_FACTOR times it (it would be stopped wrongly); the ratios say how much room
the factor leaves.

    python benchmarks/bench_pace.py             # the table, exit 1 past the goal
    python benchmarks/bench_pace.py --cap 30    # whole runs cut at 30 CPU seconds
"""
from __future__ import annotations

import argparse
import sys


def measure(cap: float) -> list[tuple[str, float | None, float, bool, float]]:
    """(cell, projection at the first look, whole run's CPU seconds, whether the cap cut it,
    its time limit) per paced cell of the default matrix."""
    from longtime.core.status import Status
    from longtime.execution.cells import build
    from longtime.execution.main_job import Selection, plan
    from longtime.execution.matrix import ExecOptions

    cells, _ = plan(Selection(), ExecOptions(retime="need"))
    out = []
    for cell in cells:
        if not cell.pace or cell.skip_reason:
            continue
        problem, integrator = build(cell)
        t_final = problem.default_t_final if cell.t_final is None else cell.t_final
        integrator.integrate(problem, min(t_final, problem.t0 + 1e-3 * (t_final - problem.t0)))  # warm
        first = integrator.integrate(problem, t_final, pace_bound=0.0)
        whole = integrator.integrate(problem, t_final, cpu_bound=cap)
        name = f"{cell.problem} x {cell.integrator} {cell.integrator_settings}"
        out.append((name, first.extra.get("pace_cpu_s"), whole.cpu_s, whole.status != Status.OK, cell.time_limit))
    return out


def main(argv: list[str] | None = None) -> int:
    from longtime.execution.budget import PACE_FACTOR

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cap", type=float, default=60.0, help="CPU seconds a whole run may take (default 60)")
    args = parser.parse_args(argv)
    rows = measure(args.cap)
    wrong = 0
    print(f"{'cell':60s} {'projected':>10s} {'whole run':>10s} {'ratio':>6s}")
    for name, projected, whole, cut, limit in rows:
        ratio = "" if projected is None or cut else f"{projected / whole:.2f}"
        whole_text = f"> {whole:.3g}" if cut else f"{whole:.3g}"
        projected_text = "ended" if projected is None else f"{projected:.3g}"
        print(f"{name:60s} {projected_text:>10s} {whole_text:>10s} {ratio:>6s}")
        if not cut and whole <= limit and projected is not None and projected > PACE_FACTOR * limit:
            wrong += 1
    print(f"{wrong} cell(s) ending within their time limit projected past {PACE_FACTOR:g} x it")
    return 1 if wrong else 0


if __name__ == "__main__":
    sys.exit(main())
