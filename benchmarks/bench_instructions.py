"""Instructions against CPU time over a sub-matrix (docs/performance.md, "Instructions").

    python benchmarks/bench_instructions.py [-p kepler,toda,henon-heiles] [-i rk4,verlet,...]
        [--t-final 500] [--runs 2]

Runs the cells ``--runs`` times with ``--cost instructions`` (each run: timed cells, then
one Valgrind process counting them) and prints per cell its CPU time (the minimum over the
runs), its instruction count, the spread of the count between runs, and nanoseconds of CPU
per instruction: where that varies from cell to cell, the count does not rank the cells
as time does (memory stalls, divisions, the state's size). Needs Valgrind.
"""
from __future__ import annotations

import argparse
import math
import statistics

import longtime


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-p", default="kepler,toda,henon-heiles")
    ap.add_argument("-i", default="rk4,verlet,yoshida6,gauss4,rk45,dop853")
    ap.add_argument("--t-final", type=float, default=500.0)
    ap.add_argument("--runs", type=int, default=2)
    args = ap.parse_args()
    runs = [longtime.sweep(args.p.split(","), args.i.split(","), t_final=args.t_final, executor="serial",
                           cost="instructions").to_dict("records") for _ in range(args.runs)]
    print(f"{'problem':14s} {'scheme':9s} {'steps':>8s} {'cpu_ms':>9s} {'instructions':>14s} "
          f"{'count spread':>12s} {'ns/instr':>8s}  skipped")
    per_instruction = []
    for rows in zip(*runs):
        r = rows[0]
        counts = [x.get("instructions") for x in rows]
        cpu = min(x["cpu_s"] for x in rows if x.get("cpu_s") is not None) if r.get("cpu_s") is not None else math.nan
        if all(isinstance(c, (int, float)) and c == c for c in counts):
            spread = (max(counts) - min(counts)) / min(counts)
            ns = 1e9 * cpu / counts[0]
            per_instruction.append(ns)
            print(f"{r['problem']:14s} {r['integrator']:9s} {r['steps']:8.0f} {1e3 * cpu:9.3f} {counts[0]:14.0f} "
                  f"{spread:12.1e} {ns:8.3f}")
        else:
            print(f"{r['problem']:14s} {r['integrator']:9s} {r['steps']:8.0f} {1e3 * cpu:9.3f} {'-':>14s} "
                  f"{'-':>12s} {'-':>8s}  {r.get('instructions_skipped')}")
    if per_instruction:
        print(f"\nns of CPU per instruction over {len(per_instruction)} counted cells: min "
              f"{min(per_instruction):.3f}, median {statistics.median(per_instruction):.3f}, max "
              f"{max(per_instruction):.3f} (x{max(per_instruction) / min(per_instruction):.2f} apart)")


if __name__ == "__main__":
    main()
