"""Where does a warm matrix spend its time? Integration against everything around it.

The goal: in a warm `longtime matrix` (kernels and references cached), the timed
integration (every timed repeat of every cell) is at least 60 % of the core-seconds. This
script runs a matrix's cells in one process, as a pool worker would, and splits that
process's time into

    integration   the timed runs (the figures the rows report, every repeat)
    untimed run   the rest of the scheme's calls: warm-up call, allocation, sample buffers
    reference     loading (or computing) the trusted reference at the samples
    metrics       invariants, errors, growth-law fits
    other         building problems and schemes, rows, everything else

It runs the cells twice and reports the second pass (the first fills the caches: a warm
run). With ``--cold`` the first pass starts from empty numba, longtime and heyoka caches
(temporary folders), and its breakdown is printed too: there "untimed run" is mostly
compilation (numba's and heyoka's LLVM) and "reference" computes each reference. The main
job adds worker start-up and store writes on top, and after the cells the terminal summary
and the results page, whose wall seconds it prints last.

    python benchmarks/bench_harness.py                        # the default matrix
    python benchmarks/bench_harness.py -p toda,kepler -i rk4,verlet,gauss4,rk45,bpl
    python benchmarks/bench_harness.py --cold                 # and where a cold pass goes
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from collections import defaultdict
from contextlib import contextmanager

GOAL = 0.60


@contextmanager
def accounting():
    """Patch the phases' entry points with timers; yields the per-phase totals (seconds)."""
    from longtime.core import integrator
    from longtime.execution import cells
    from longtime.measure import metrics

    totals: dict[str, float] = defaultdict(float)
    originals = {}

    def timed(owner, name, phase):
        original = getattr(owner, name)
        originals[(owner, name)] = original

        def wrapper(*args, **kwargs):
            start = time.perf_counter()
            try:
                return original(*args, **kwargs)
            finally:
                totals[phase] += time.perf_counter() - start

        setattr(owner, name, wrapper)

    def timed_integrate(self, *args, **kwargs):
        start = time.perf_counter()
        traj = original_integrate(self, *args, **kwargs)
        totals["scheme"] += time.perf_counter() - start
        totals["integration"] += sum(_timed_walls(traj))
        return traj

    original_integrate = integrator.Integrator.integrate
    integrator.Integrator.integrate = timed_integrate
    timed(cells, "trusted_reference", "reference")
    timed(cells, "has_reference", "reference")
    timed(metrics, "evaluate", "metrics")
    try:
        yield totals
    finally:
        integrator.Integrator.integrate = original_integrate
        for (owner, name), original in originals.items():
            setattr(owner, name, original)


def _timed_walls(traj) -> list[float]:
    """Wall seconds of every timed run of a trajectory (repeats of about the median)."""
    repeats = int(traj.extra.get("repeats", 1))
    median = float(traj.extra.get("wall_s_median", traj.wall_s))
    return [median] * repeats


def breakdown(cells) -> tuple[dict[str, float], float, list[dict]]:
    from longtime.execution.cells import run_cell

    with accounting() as totals:
        start = time.perf_counter()
        rows = [run_cell(cell) for cell in cells]
        total = time.perf_counter() - start
    return dict(totals), total, rows


def after_the_cells(rows: list[dict]) -> dict[str, float]:
    """Wall seconds of what `longtime matrix` does once the cells are done: the terminal
    summary, and the results page (figures on one process per core, as the matrix draws them)."""
    import os

    from longtime.reporting.page import build_page
    from longtime.reporting.screen import report_text

    start = time.perf_counter()
    report_text(rows, "table")
    summary = time.perf_counter() - start
    start = time.perf_counter()
    build_page(rows, [], jobs=os.cpu_count() or 1)
    return {"summary": summary, "results page": time.perf_counter() - start}


def print_parts(title: str, totals: dict[str, float], total: float) -> float:
    """Print one pass's breakdown; returns its integration share."""
    integration = totals.get("integration", 0.0)
    parts = {
        "integration": integration,
        "untimed run": totals.get("scheme", 0.0) - integration,
        "reference": totals.get("reference", 0.0),
        "metrics": totals.get("metrics", 0.0),
    }
    parts["other"] = total - sum(parts.values())
    print(f"{title} {total:.1f} s in one process")
    for name, seconds in parts.items():
        print(f"  {name:12s} {seconds:8.2f} s  {100 * seconds / total:5.1f} %")
    return integration / total


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-p", "--problem", default=None, help="problems (default: all)")
    parser.add_argument("-i", "--integrator", default=None, help="schemes (default: all)")
    parser.add_argument("--cold", action="store_true",
                        help="first pass from empty caches (temporary folders); print its breakdown too")
    args = parser.parse_args(argv)
    if args.cold:
        if "numba" in sys.modules:
            parser.error("--cold: numba is already imported, its cache folder can no longer change")
        from bench_main_job import CACHE_VARIABLES  # a sibling script: imports no longtime, no numba

        folder = tempfile.mkdtemp(prefix="bench_harness_cold_")
        for name in CACHE_VARIABLES:
            os.environ[name] = os.path.join(folder, name.lower())
    from longtime.core import registry
    from longtime.execution.cells import expand

    problems = args.problem.split(",") if args.problem else registry.default_problems()
    schemes = args.integrator.split(",") if args.integrator else sorted(registry.integrators())
    cells = expand(problems, schemes, default_sweep=True)
    first, first_total, _ = breakdown(cells)  # fills the kernel and reference caches
    if args.cold:
        print_parts(f"{len(cells)} cells, cold pass", first, first_total)
    totals, total, rows = breakdown(cells)
    share = print_parts(f"{len(cells)} cells, warm pass", totals, total)
    print(f"integration share {100 * share:.1f} % (goal >= {100 * GOAL:.0f} %)")
    for name, seconds in after_the_cells(rows).items():
        print(f"after the cells: {name} {seconds:.2f} s wall")
    return 0 if share >= GOAL else 1


if __name__ == "__main__":
    sys.exit(main())
