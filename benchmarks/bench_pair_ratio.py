"""Which statistic of paired runs holds across processes: the ratio of the minima or the
median of the pairs' ratios?

Fresh processes, one after another (versions of the author's scheme of
bench_author_repo.py in turn: 1 baseline, 2 refactoring, 3 1.3x slower), each time the
cells harmonic and duffing-2 x author-rk4 and verlet (dt 0.01, t = 1000) paired with the
calibration's reference workload (longtime.execution.processes.time_cells with
``reference``: one run of the cell, then one of the reference, in rounds over SPREAD_S),
and print per process and cell both statistics. Identical code should give the same
figure in every process; version 3 should stand 1.25 to 1.45x above 1 and 2.

    python benchmarks/bench_pair_ratio.py               # versions 1,2,3,1,2,3 beside one CPU hog
    python benchmarks/bench_pair_ratio.py --versions 2,2,2,2 --hogs 0

docs/performance.md ("A time asv can judge") has the results.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
CELLS = [("harmonic", "author-rk4"), ("harmonic", "verlet"), ("duffing-2", "author-rk4"), ("duffing-2", "verlet")]


def child(version: int) -> None:
    import importlib.util

    sys.path.insert(0, str(HERE))
    import bench_author_repo as bench

    from longtime.api import cells_for
    from longtime.core import registry
    from longtime.core.timing import Timing
    from longtime.execution.calibration import reference_seconds, reference_workload
    from longtime.execution.processes import time_cells

    path = Path(tempfile.mkdtemp()) / f"author_scheme_{version}.py"
    path.write_text(bench.VERSIONS[version - 1][1])
    spec = importlib.util.spec_from_file_location(path.stem, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    registry.register(module.AuthorRK4)
    cells = [cells_for([p], [s], bench.T_FINAL, {"dt": bench.DT})[0] for p, s in CELLS]
    reference_workload(10, 0.01)
    time_cells(cells, 100_001, Timing(repeats=1, min_time=0, min_runs=1))  # compiles or loads the kernels
    out = {}
    for (p, s), rec in zip(CELLS, time_cells(cells, 100_001, Timing(repeats=3), reference=reference_seconds)):
        pairs = list(zip(rec["cpu_s_samples"], rec["reference_s_samples"]))
        out[f"{p} {s}"] = {"pairs": len(pairs), "min_ratio": rec["cpu_ratio"],
                           "median_ratio": statistics.median(c / r for c, r in pairs), "cpu_s": rec["cpu_s"]}
    print(json.dumps(out))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--versions", default="1,2,3,1,2,3", help="the author's versions, one process each")
    parser.add_argument("--hogs", type=int, default=1, help="CPU hogs running throughout (default 1)")
    parser.add_argument("--child", type=int, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args.child)
        return 0
    hogs = [subprocess.Popen([sys.executable, "-c", "while 1: pass"]) for _ in range(args.hogs)]
    rows = []
    try:
        for v in (int(x) for x in args.versions.split(",")):
            done = subprocess.run([sys.executable, __file__, "--child", str(v)], capture_output=True, text=True,
                                  env=os.environ)
            if done.returncode:
                raise SystemExit(done.stderr[-2000:])
            rows.append((v, json.loads(done.stdout.strip().splitlines()[-1])))
    finally:
        for h in hogs:
            h.kill()
            h.wait()
    print(f"{'cell':22s} " + " ".join(f"v{v}:min/med".rjust(14) for v, _ in rows))
    for p, s in CELLS:
        key = f"{p} {s}"
        print(f"{key:22s} " + " ".join(f"{r[key]['min_ratio']:.3f}/{r[key]['median_ratio']:.3f}".rjust(14)
                                       for _, r in rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
