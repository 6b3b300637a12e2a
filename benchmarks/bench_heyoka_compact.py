"""heyoka's compact mode against its straight-line code: compile time and run time per unit t.

heyoka's LLVM compile of a taylor_adaptive object is the costliest single compile of a cold
main job on the mid-sized systems (lennard-jones, outer-solar-system). Compact mode compiles
them in a fraction of the time but runs each step slower. This script measures both sides, in
the same run, for the tolerances the ``heyoka`` scheme sweeps and for the reference's settings
(tolerance at double's epsilon, high accuracy), so the choice in longtime.core.heyoka_build
(COMPACT_ABOVE, REFERENCE_COMPACT_ABOVE) rests on figures.

Each build is a fresh Python process with its own empty ``XDG_CACHE_HOME`` (heyoka's compiled
code cache): the compile figures are heyoka's ``taylor_adaptive`` construction (wall seconds, and
the process's CPU seconds, LLVM's threads included: on a loaded machine the wall is mostly the
wait for a core), the
run figure the minimum CPU seconds of ``--repeats`` ``propagate_grid`` calls over the problem's
default time span on the scheme's grid of 10,001 points, per unit of t. The last columns are the
ratios compact / straight-line of the same run, and the largest difference between the two
builds' states over the first tenth of the grid (compact mode is the same Taylor method: the
difference is round-off, grown by the problem's own instability).

    python benchmarks/bench_heyoka_compact.py
    python benchmarks/bench_heyoka_compact.py -p lennard-jones --tol 1e-12 --opt-level 1
    python benchmarks/bench_heyoka_compact.py -p lennard-jones,outer-solar-system --parjit
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

PROBLEMS = ("lennard-jones", "outer-solar-system", "pythagorean-three-body")
TOLS = ("1e-9", "1e-12", "eps")

# run in the child: build one taylor_adaptive object, then time its grid runs
_CHILD = r"""
import json, sys, time
import numpy as np
from longtime.core import heyoka_build, registry
name, tol, compact, high, repeats = sys.argv[1], sys.argv[2], sys.argv[3] == "1", sys.argv[4] == "1", int(sys.argv[5])
opt_level = int(sys.argv[6])
extra = {} if sys.argv[7] == "default" else {"parjit": sys.argv[7] == "1"}
problem = registry.problems()[name]()
tol = float(np.finfo(float).eps) if tol == "eps" else float(tol)
w0, c0 = time.perf_counter(), time.process_time()
ta = heyoka_build.taylor_adaptive(problem, problem.u0.astype(float), None, tol=tol, time=float(problem.t0),
                                  high_accuracy=high, compact_mode=compact, opt_level=opt_level, **extra)
compile_s, compile_cpu = time.perf_counter() - w0, time.process_time() - c0
t_final = float(problem.default_t_final)
grid = np.linspace(problem.t0, t_final, 10_001)
runs = []
for _ in range(repeats):
    ta.time = float(problem.t0)
    ta.state[:] = problem.u0
    c0 = time.process_time()
    outcome, _, _, nsteps, _, states = ta.propagate_grid(grid)
    runs.append(time.process_time() - c0)
early = np.asarray(states[:1001], dtype=float)
print(json.dumps({"compile_s": compile_s, "compile_cpu": compile_cpu, "run_s": min(runs),
                  "span": t_final - float(problem.t0), "steps": int(nsteps), "order": int(ta.order),
                  "decomposition": len(ta.decomposition),
                  "dim": problem.dim, "early": early.tolist()}))
"""


def measure(problem: str, tol: str, compact: bool, high_accuracy: bool, repeats: int, opt_level: int = 3,
            parjit: str = "default") -> dict:
    """One fresh process's figures (see the module); ``parjit``: "0", "1" or heyoka's default."""
    with tempfile.TemporaryDirectory(prefix="bench-heyoka-") as cache:
        env = dict(os.environ, XDG_CACHE_HOME=cache)
        out = subprocess.run([sys.executable, "-c", _CHILD, problem, tol, "1" if compact else "0",
                              "1" if high_accuracy else "0", str(repeats), str(opt_level), parjit],
                             env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("-p", "--problems", default=",".join(PROBLEMS), help="comma-separated problem names")
    parser.add_argument("--tol", default=",".join(TOLS), help="comma-separated tolerances (eps: double's epsilon)")
    parser.add_argument("--reference", action="store_true",
                        help="also the reference's settings (tolerance eps, high accuracy)")
    parser.add_argument("--repeats", type=int, default=3, help="grid runs per build (their minimum is kept)")
    parser.add_argument("--opt-level", type=int, default=None,
                        help="also straight-line code at this LLVM optimisation level (heyoka's default: 3)")
    parser.add_argument("--parjit", action="store_true",
                        help="compact mode only, with heyoka's parallel compile (parjit) off and on: compile wall "
                             "and CPU seconds (all threads), run per unit t")
    args = parser.parse_args(argv)
    if args.parjit:
        return _parjit(args)
    settings = [(tol, False) for tol in args.tol.split(",")]
    if args.reference:
        settings.append(("eps", True))
    print(f"{'problem':24s} {'dim':>3s} {'tol':>6s} {'ha':>2s} {'ops s/c':>11s} {'compile s/c':>13s} "
          f"{'cpu s/c':>13s} {'run us/t s/c':>17s} {'compile c/s':>11s} {'cpu c/s':>7s} {'run c/s':>7s} "
          f"{'max |diff|':>10s}")
    for problem in args.problems.split(","):
        for tol, high in settings:
            straight = measure(problem, tol, False, high, args.repeats)
            compact = measure(problem, tol, True, high, args.repeats)
            per_t = [1e6 * r["run_s"] / r["span"] for r in (straight, compact)]
            diff = max(abs(a - b) for ra, rb in zip(straight["early"], compact["early"]) for a, b in zip(ra, rb))
            print(f"{problem:24s} {straight['dim']:3d} {tol:>6s} {'y' if high else 'n':>2s} "
                  f"{straight['decomposition']:5d}/{compact['decomposition']:<5d} "
                  f"{straight['compile_s']:6.2f}/{compact['compile_s']:<6.2f} "
                  f"{straight['compile_cpu']:6.2f}/{compact['compile_cpu']:<6.2f} "
                  f"{per_t[0]:8.3g}/{per_t[1]:<8.3g} "
                  f"{compact['compile_s'] / straight['compile_s']:11.3f} "
                  f"{compact['compile_cpu'] / straight['compile_cpu']:7.3f} {per_t[1] / per_t[0]:7.2f} {diff:10.2e}",
                  flush=True)
            if args.opt_level is not None:
                low = measure(problem, tol, False, high, args.repeats, args.opt_level)
                print(f"{'':24s} straight-line at opt_level {args.opt_level}: compile {low['compile_s']:.2f} s "
                      f"(x{low['compile_s'] / straight['compile_s']:.3f}), run "
                      f"x{low['run_s'] / straight['run_s']:.2f} of opt_level 3's", flush=True)
    return 0


def _parjit(args) -> int:
    """Compact mode's compile with parjit off and on (see --parjit)."""
    print(f"{'problem':24s} {'dim':>3s} {'tol':>6s} {'parjit':>6s} {'compile wall s':>14s} {'compile cpu s':>13s} "
          f"{'run us/t':>9s}")
    for problem in args.problems.split(","):
        for tol in args.tol.split(","):
            for parjit in ("0", "1"):
                r = measure(problem, tol, True, False, args.repeats, parjit=parjit)
                print(f"{problem:24s} {r['dim']:3d} {tol:>6s} {parjit:>6s} {r['compile_s']:14.2f} "
                      f"{r['compile_cpu']:13.2f} {1e6 * r['run_s'] / r['span']:9.3g}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
