"""Do cells whose working set leaves the caches slow beside a memory-bandwidth hog, and which
calibration workload sees it?

Cells (toda at d = 2000, kdv at d = 512, a long sample array, and a small cell for
contrast) and both calibration workloads (the compute-bound reference workload and the
memory workload, longtime.execution.calibration) are timed alone and beside two processes
that copy 64 MiB arrays, the phases interleaved in the same minutes; each line is the
minimum of a phase and the ratio hogs / alone (docs/performance.md, "Calibration and
memory"). A calibration fits a cell when their ratios agree.

    python benchmarks/bench_memory_calibration.py             # 4 rounds of each phase
    python benchmarks/bench_memory_calibration.py --rounds 2
"""
from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time

CASES = [("toda", {"d": 2000}, "rk4", {"dt": 0.1}, 50.0), ("toda", {"d": 2000}, "gauss4", {"dt": 0.1}, 20.0),
         ("kdv", {"d": 512}, "etdrk4", {}, 0.5), ("kepler", {}, "rk4", {"dt": 0.001}, 200.0),
         ("toda", {}, "rk4", {}, 500.0)]
HOG = "import numpy as np; a = np.ones(8 << 20); b = np.empty_like(a)\nwhile True: np.copyto(b, a); np.copyto(a, b)"


def main() -> int:
    from longtime.core import registry
    from longtime.core.timing import Timing
    from longtime.execution import calibration
    from longtime.execution.sizes import working_set

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=4)
    args = parser.parse_args()
    runs = []
    for p, ps, s, ss, tf in CASES:
        problem, scheme = registry.problem_class(p)(**ps), registry.integrator_class(s)(**ss)
        traj = scheme.integrate(problem, tf)
        label = f"{p}{' d=' + str(ps['d']) if 'd' in ps else ''} {s} t={tf:g}"
        runs.append((label, problem, scheme, tf, working_set(scheme, problem, traj)))
    res: dict[tuple[str, str], list[float]] = {}
    for _ in range(args.rounds):
        for phase in ("alone", "hogs"):
            hogs = [subprocess.Popen([sys.executable, "-c", HOG]) for _ in range(2)] if phase == "hogs" else []
            try:
                if hogs:
                    time.sleep(1.0)
                point = calibration.measure(phase)
                res.setdefault(("reference workload", phase), []).append(point["cpu_s"])
                res.setdefault(("memory workload", phase), []).append(point["memory_cpu_s"])
                for label, problem, scheme, tf, _ in runs:
                    traj = scheme.integrate(problem, tf, timing=Timing(repeats=3, min_time=0))
                    res.setdefault((label, phase), []).append(traj.cpu_s)
            finally:
                for h in hogs:
                    h.kill()
                    h.wait()
    sizes = {label: size for label, *_, size in runs}
    print(f"{'workload':34s} {'working set':>12s} {'alone':>10s} {'hogs':>10s} {'ratio':>6s} (medians)  calibrated by")
    for name in dict.fromkeys(k[0] for k in res):
        a, b = res[(name, "alone")], res[(name, "hogs")]
        size = sizes.get(name)
        which = calibration.workload_for({"working_set_bytes": size}) if size is not None else "-"
        print(f"{name:34s} {f'{size / 2**20:.2f} MiB' if size else '-':>12s} "
              f"{1e3 * min(a):8.3f}ms {1e3 * min(b):8.3f}ms "
              f"{min(b) / min(a):6.2f} ({statistics.median(b) / statistics.median(a):.2f})  {which}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
