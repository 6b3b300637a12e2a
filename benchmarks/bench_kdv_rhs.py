"""Time of one KdV rhs evaluation (the nonlinear term's FFTs dominate), per d.

    python benchmarks/bench_kdv_rhs.py [d ...]

Calls the compiled ``rhs`` in a compiled loop (so no Python call overhead is timed) and
prints microseconds per call, the best of several repeats. Used to check that the FFT
library (rocket-fft, pocketfft inside) is no slower than the hand-written radix-2 FFT it
replaced. Measured on the shared 2-core build machine (3/2 rule), best of 7 x 2000 calls:

    d                          64     128    256    512
    radix-2 (before)         2.04    4.25   8.98  19.75  us   (one after the other, quiet)
    rocket-fft               1.02    2.70   5.11  11.73  us
    radix-2, interleaved     4.08    9.33  16.64  37.07  us   (alternating runs, loaded machine:
    rocket-fft, interleaved  1.01    2.93   2.97   7.94  us    the old tree on PYTHONPATH)
"""
from __future__ import annotations

import sys
import time

import numba
import numpy as np

from longtime.problems.kdv import KdV


def _loop_for(rhs):
    @numba.njit
    def loop(u, params, out, n):
        for _ in range(n):
            rhs(0.0, u, params, out)
        return out[0]

    return loop


def rhs_microseconds(d: int, calls: int = 2000, repeats: int = 7) -> float:
    problem = KdV(d=d)
    out = np.empty(problem.dim)
    loop = _loop_for(type(problem).rhs)
    loop(problem.u0, problem.params, out, 1)  # compile
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        loop(problem.u0, problem.params, out, calls)
        best = min(best, time.perf_counter() - t0)
    return 1e6 * best / calls


class TimeKdVRhs:
    """asv: 1000 rhs evaluations per d."""
    params = [64, 128, 256, 512]
    param_names = ["d"]

    def setup(self, d):
        self.problem = KdV(d=d)
        self.out = np.empty(self.problem.dim)
        self.loop = _loop_for(type(self.problem).rhs)
        self.loop(self.problem.u0, self.problem.params, self.out, 1)

    def time_rhs_1000_calls(self, d):
        self.loop(self.problem.u0, self.problem.params, self.out, 1000)


if __name__ == "__main__":
    sizes = [int(a) for a in sys.argv[1:]] or [64, 128, 256, 512]
    for d in sizes:
        print(f"d = {d:4d}: {rhs_microseconds(d):8.2f} us per rhs")
