"""What does a fresh timing process pay beyond its timed runs? Loading the cells' kernels.

A fresh timing process (longtime.execution.processes) builds every cell it times, and a
cell's first build in a process loads its compiled kernel from the kernel cache. This script
is such a process: it times ``--cells`` cells drawn from the default matrix (seeded) twice,
as a main job's timing process does (``time_cells``, the default samples, the default timing
split among 3 processes), and prints the CPU seconds of each pass and of the timed runs in
the first. The first pass less the second is what loading the kernels costs; run it over
warm caches (a main job's, or this script run once before), or the first pass also compiles.

    python benchmarks/bench_kernel_load.py [--cells 120] [--seed 1]
"""
from __future__ import annotations

import argparse
import random
import time


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", type=int, default=120, help="cells drawn from the default matrix")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)

    from longtime.commands.cli import build_parser
    from longtime.commands.matrix import matrix_cells
    from longtime.core.timing import Timing
    from longtime.execution.cells import DEFAULT_MAX_SAMPLES
    from longtime.execution.processes import DEFAULT_PROCESSES, time_cells

    cells = [c for c in matrix_cells(build_parser().parse_args(["matrix"]))[0] if not c.skip_reason]
    sample = random.Random(args.seed).sample(cells, min(args.cells, len(cells)))
    timing = Timing().per_process(DEFAULT_PROCESSES)
    passes = []
    for _ in range(2):
        start = time.process_time()
        records = time_cells(sample, DEFAULT_MAX_SAMPLES, timing)
        passes.append((time.process_time() - start, sum(sum(r.get("cpu_s_samples") or []) for r in records)))
    (first, timed), (second, _) = passes
    print(f"{len(sample)} cells: first pass {first:.1f} CPU s ({timed:.1f} s of it timed runs), "
          f"second pass {second:.1f} CPU s; loading the kernels about {first - second:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
