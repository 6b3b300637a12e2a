"""What a cell's reference and metrics cost in the cell's own process (each timed cell runs in
a new one): the cell is integrated once, then, in each of ``--processes`` fresh processes, the
trusted reference at its samples is loaded or computed and the row's metrics measured, timed
apart (wall seconds; the disk caches as a warm main job leaves them, the in-process ones
empty). ``--profile`` prints cProfile's costliest calls of the last process.

    python benchmarks/bench_cell_metrics.py                          # kepler x verlet, 1000 periods
    python benchmarks/bench_cell_metrics.py -p toda -i rk4 -t 5000 --processes 5
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import time


def child(problem: str, scheme: str, t_final: float, profile: bool) -> None:
    from longtime.execution.cells import DEFAULT_MAX_SAMPLES, Cell, build
    from longtime.measure import metrics
    from longtime.measure.reference import trusted_reference

    built, integrator = build(Cell(problem, scheme))
    traj = integrator.integrate(built, t_final, max_samples=DEFAULT_MAX_SAMPLES)
    if profile:
        import cProfile

        prof = cProfile.Profile()
        prof.enable()
    start = time.perf_counter()
    ref, trust = trusted_reference(built, traj.t, t_final)
    middle = time.perf_counter()
    metrics.evaluate(built, traj, ref, trust)
    end = time.perf_counter()
    print(f"{traj.t.size} {middle - start:.4f} {end - middle:.4f}")
    if profile:
        import pstats

        prof.disable()
        pstats.Stats(prof, stream=sys.stderr).sort_stats("cumulative").print_stats(20)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("-p", "--problem", default="kepler")
    parser.add_argument("-i", "--integrator", default="verlet")
    parser.add_argument("-t", "--t-final", type=float, default=2000 * 3.141592653589793)
    parser.add_argument("--processes", type=int, default=3)
    parser.add_argument("--profile", action="store_true")
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args.problem, args.integrator, args.t_final, args.profile)
        return
    command = [sys.executable, __file__, "--child", "-p", args.problem, "-i", args.integrator,
               "-t", repr(args.t_final)]
    subprocess.run(command, check=True, capture_output=True)  # fills the disk caches: a warm run
    print(f"{args.problem} x {args.integrator} to t = {args.t_final:g}: seconds in a fresh process")
    print("samples  reference  metrics")
    for k in range(args.processes):
        last = k == args.processes - 1
        out = subprocess.run(command + (["--profile"] if args.profile and last else []), check=True,
                             capture_output=True, text=True)
        samples, reference, measured = out.stdout.split()
        print(f"{samples:>7}  {float(reference):9.3f}  {float(measured):7.3f}")
        if args.profile and last:
            print(out.stderr, file=sys.stderr)


if __name__ == "__main__":
    main()
