"""``longtime warmup``: compile the kernels of a selection into the disk caches, in parallel.

Compilation, not integration, is most of a cold first run (benchmarks/bench_compile.py). A
warm-up before CI's tests, an asv run or a cluster sweep pays it once, on every core, and
leaves each kernel in ``$LONGTIME_CACHE_DIR/kernels`` and numba's cache, where every later
process loads it in a fraction of a second. It compiles exactly the kernels the same
selection of ``longtime matrix`` would run: the cells of the default sweep, each integrated
over two steps (no reference, no metrics). Kernels are keyed by what they run, so cells
that differ only in a run-time value (dt, a tolerance) share one compilation.
"""
from __future__ import annotations

import sys
import time
from typing import Any

from longtime.core import cli_args, registry, roles
from longtime.core.stepping import FixedStepIntegrator
from longtime.core.timing import Timing
from longtime.execution.cells import Cell, build, expand
from longtime.execution.pool import worker_pool
from longtime.execution.pool import workers as pool_workers


def distinct_kernels(cells: list[Cell]) -> list[Cell]:
    """One runnable cell per (problem, problem settings, scheme, compile-time settings): the
    settings a kernel reads at run time (``roles.run_time``: the step, the tolerances) are not
    closed over, so cells that differ only in them compile one kernel and one is warmed."""
    seen: dict[str, Cell] = {}
    for cell in cells:
        if cell.skip_reason:
            continue
        run_time = roles.run_time([registry.integrator_class(cell.integrator)])
        fixed = {k: v for k, v in cell.integrator_settings.items() if k not in run_time}
        key = repr((cell.problem, sorted(cell.problem_settings.items()), cell.integrator, sorted(fixed.items())))
        seen.setdefault(key, cell)
    return list(seen.values())


def warm_cell(cell: Cell) -> dict[str, Any]:
    """Compile ``cell``'s kernel by integrating two steps; seconds taken, or the error."""
    start = time.perf_counter()
    try:
        problem, integrator = build(cell)
        step = (integrator.dt_for(problem) if isinstance(integrator, FixedStepIntegrator)
                else float(problem.default_dt))
        integrator.integrate(problem, problem.t0 + 2 * step, max_samples=16, timing=Timing(repeats=1))
        error = None
    except Exception as exc:  # reported, never fatal: the matrix would report it as a row
        error = f"{type(exc).__name__}: {exc}"
    return {"problem": cell.problem, "integrator": cell.integrator, "seconds": time.perf_counter() - start,
            "error": error}


def _warm_batch(cells: list[Cell]) -> list[dict[str, Any]]:
    return [warm_cell(c) for c in cells]


def warmup(cells: list[Cell], jobs: int = 0) -> list[dict[str, Any]]:
    """Warm the distinct kernels of ``cells`` on ``jobs`` processes (0: one per core); one
    batch per problem x scheme pair, so a worker compiles what that pair's cells share once."""
    from longtime.execution.batches import batches_by_pair
    from longtime.execution.matrix import scheduled

    batches = batches_by_pair(distinct_kernels(cells))
    workers = pool_workers(jobs, len(batches))
    if workers <= 1:
        return [r for batch in batches for r in _warm_batch(batch)]
    results = []
    with worker_pool(workers) as pool:
        # no function compiled twice at once
        for _, future in scheduled(pool, workers, batches, lambda batch: pool.submit(_warm_batch, batch)):
            results.extend(future.result())
    return results


def cmd_warmup(args) -> int:
    from longtime.commands.common import warn_broken
    from longtime.core import registry

    warn_broken()
    problems = args.problem or registry.default_problems()
    schemes = args.integrator or sorted(registry.integrators())
    sets, sweeps = cli_args.settings(args.set)
    cells = expand(problems, schemes, sweeps=sweeps, sets=sets, default_sweep=True)
    start = time.perf_counter()
    results = warmup(cells, args.jobs)
    wall = time.perf_counter() - start
    failed = [r for r in results if r["error"]]
    if args.verbose:
        for r in sorted(results, key=lambda r: -r["seconds"]):
            print(f"{r['seconds']:7.2f} s  {r['problem']} x {r['integrator']}"
                  + (f"  ({r['error']})" if r["error"] else ""))
    print(f"warmed {len(results) - len(failed)} kernels in {wall:.1f} s wall "
          f"({sum(r['seconds'] for r in results):.1f} s over the workers)", file=sys.stderr)
    for r in failed:
        print(f"warning: {r['problem']} x {r['integrator']} did not compile: {r['error']}", file=sys.stderr)
    return 0


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("warmup", help="compile the kernels of a selection into the caches, in parallel")
    p.add_argument("-p", "--problem", type=cli_args.names, default=None, metavar="PROBLEM[,..]",
                   help="problems (default: all)")
    p.add_argument("-i", "--integrator", type=cli_args.names, default=None, metavar="SCHEME[,..]",
                   help="schemes (default: all)")
    p.add_argument("--set", type=cli_args.key_value, action="append", default=[], metavar="KEY=VALUE[,..]",
                   help="a problem or scheme parameter, as for `longtime matrix` (repeatable, once per key)")
    p.add_argument("--jobs", type=cli_args.jobs, default=0, help="worker processes (default: one per core)")
    p.add_argument("-v", "--verbose", action="store_true", help="list every kernel and its seconds")
    p.set_defaults(func=cmd_warmup)
