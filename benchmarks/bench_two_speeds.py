"""Is a cell's speed a property of its process, or of the moment? Workers take turns.

N fresh worker processes each load kepler x rk45 (and rk4) from the kernel cache, then take
turns for R rounds, each timing (minimum of 7): the cells, the calibration's reference
workload (a dependent chain on two scalars in registers), an eight-chain register workload
(throughput-bound, no memory) and a load/store workload on a 16-element array (L1-resident,
as a kernel's state and work arrays). If the speed belonged to the process (code placement,
array alignment, address randomisation), a worker would keep its speed over the rounds; if
it belongs to the machine's state at the moment, every worker moves, and the workloads
that move show which kind of work it slows (docs/performance.md, "Two speeds").

    python benchmarks/bench_two_speeds.py               # 4 workers x 10 rounds
    python benchmarks/bench_two_speeds.py --workers 3 --rounds 12
"""
from __future__ import annotations

import argparse
import multiprocessing as mp
import time

import numba
import numpy as np

SCHEMES = ("rk45", "rk4")
T_FINAL = 500.0


@numba.njit(cache=True)
def registers(n):
    """Eight independent multiply-add chains in registers: throughput-bound, no memory."""
    a = b = c = d = e = f = g = h = 1.0
    for _ in range(n):
        a = a * 0.9999999 + 1e-9
        b = b * 0.9999998 + 1e-9
        c = c * 0.9999997 + 1e-9
        d = d * 0.9999996 + 1e-9
        e = e * 0.9999995 + 1e-9
        f = f * 0.9999994 + 1e-9
        g = g * 0.9999993 + 1e-9
        h = h * 0.9999992 + 1e-9
    return a + b + c + d + e + f + g + h


@numba.njit(cache=True)
def loads_stores(n, x):
    """Loads and stores on a small array that stays in L1, as a kernel's state and work."""
    for _ in range(n):
        for i in range(x.size - 1):
            x[i + 1] = 0.5 * x[i] + 0.25 * x[i + 1]
    return x[0]


def _best(fn, *args, repeats=7):
    fn(*args)
    times = []
    for _ in range(repeats):
        c0 = time.process_time()
        fn(*args)
        times.append(time.process_time() - c0)
    return min(times)


def _worker(conn):
    from longtime.core import registry
    from longtime.core.timing import Timing
    from longtime.execution import calibration

    problem = registry.problem_class("kepler")()
    schemes = {n: registry.integrator_class(n)() for n in SCHEMES}
    for s in schemes.values():
        s.integrate(problem, T_FINAL)
    x = np.ones(16)
    while conn.recv():
        out = {n: s.integrate(problem, T_FINAL, timing=Timing(repeats=7, min_time=0)).cpu_s
               for n, s in schemes.items()}
        out["reference"] = calibration.measure(repeats=7, memory_bytes=0)["cpu_s"]
        out["registers"] = _best(registers, 250_000)
        out["loads/stores"] = _best(loads_stores, 60_000, x)
        conn.send(out)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, default=4)
    parser.add_argument("--rounds", type=int, default=10)
    args = parser.parse_args()
    ctx = mp.get_context("spawn")
    pipes = []
    for _ in range(args.workers):
        a, b = ctx.Pipe()
        ctx.Process(target=_worker, args=(b,), daemon=True).start()
        pipes.append(a)
    table: dict[str, list[list[float]]] = {}
    for _ in range(args.rounds):
        for w, conn in enumerate(pipes):
            conn.send(True)
            for name, value in conn.recv().items():
                table.setdefault(name, [[] for _ in pipes])[w].append(value)
    for conn in pipes:
        conn.send(False)
    print(f"minimum of 7 runs (ms), per worker (rows) and round (columns); kepler at t_final {T_FINAL:g}")
    for name, rows in table.items():
        flat = [v for r in rows for v in r]
        own = max(max(r) / min(r) for r in rows)
        print(f"{name}: max/min over everything x{max(flat) / min(flat):.2f}, within one worker up to x{own:.2f}")
        for w, r in enumerate(rows):
            print(f"  worker {w} " + " ".join(f"{1e3 * v:6.2f}" for v in r))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
