"""The suite's compiled kernels against hand-written, allocation-free numba loops.

The goal: a fixed-step kernel of the suite costs at most 1.2x
a hand-written loop of the same scheme on the same problem. The hand-written loops below are what one would
write for that one problem and scheme: the right-hand side spelled out, scratch allocated
once, no sample storage. The suite's side runs through ``Integrator.integrate`` with
``max_samples=2`` (so it stores only the end points, like the hand loop) and its own CPU
measurement of the compiled loop. Both sides run in the same process, interleaved,
``repeat`` times; the ratio is of the minima (the least disturbed runs on a busy machine).

Cases: RK4 on the Toda lattice; velocity Verlet on the figure-eight; RK4sym on the Toda
lattice with its stages solved to round-off by the same fixed-point sweeps and stopping
rule as the suite (same iteration counts, checked).
"""
from __future__ import annotations

import math
import time

import numba
import numpy as np

RATIO_GOAL = 1.2

_EPS = np.finfo(float).eps
_B = (2 + 2 ** (1 / 3) + 2 ** (-1 / 3)) / 3
_RK4SYM_A = np.array([[_B / 2, 0, 0], [_B, 0.5 - _B, 0], [_B, 1 - 2 * _B, _B / 2]])
_RK4SYM_W = np.array([_B, 1 - 2 * _B, _B])


@numba.njit(cache=True)
def toda_rhs(u, out):
    """u' for the periodic Toda lattice, written out (q' = p, p' = -dV/dq)."""
    d = u.size // 2
    for k in range(d):
        out[k] = u[d + k]
        out[d + k] = 0.0
    for k in range(d):
        kp = k + 1 if k + 1 < d else 0
        e = math.exp(u[k] - u[kp])
        out[d + k] -= e
        out[d + kp] += e


@numba.njit(cache=True)
def rk4_toda(u, dt, nsteps, k1, k2, k3, k4, y):
    n = u.size
    for _ in range(nsteps):
        toda_rhs(u, k1)
        for m in range(n):
            y[m] = u[m] + 0.5 * dt * k1[m]
        toda_rhs(y, k2)
        for m in range(n):
            y[m] = u[m] + 0.5 * dt * k2[m]
        toda_rhs(y, k3)
        for m in range(n):
            y[m] = u[m] + dt * k3[m]
        toda_rhs(y, k4)
        for m in range(n):
            u[m] += dt / 6.0 * (k1[m] + 2.0 * k2[m] + 2.0 * k3[m] + k4[m])


@numba.njit(cache=True)
def gravity_grad_V(q, f):
    """dV/dq of planar bodies with m = G = 1."""
    nb = q.size // 2
    for i in range(q.size):
        f[i] = 0.0
    for k in range(nb):
        for l in range(k + 1, nb):
            dx = q[2 * k] - q[2 * l]
            dy = q[2 * k + 1] - q[2 * l + 1]
            r2 = dx * dx + dy * dy
            c = 1.0 / (r2 * math.sqrt(r2))
            f[2 * k] += c * dx
            f[2 * k + 1] += c * dy
            f[2 * l] -= c * dx
            f[2 * l + 1] -= c * dy


@numba.njit(cache=True)
def verlet_planar_nbody(u, dt, nsteps, f):
    """Velocity Verlet (kick, drift, kick), one force evaluation per step."""
    n = u.size // 2
    q, p = u[:n], u[n:]
    gravity_grad_V(q, f)
    for _ in range(nsteps):
        for m in range(n):
            p[m] -= 0.5 * dt * f[m]
        for m in range(n):
            q[m] += dt * p[m]
        gravity_grad_V(q, f)
        for m in range(n):
            p[m] -= 0.5 * dt * f[m]


@numba.njit(cache=True)
def rk4sym_toda(u, dt, nsteps, K, y, k_new, max_iter):
    """RK4sym; stages by Gauss-Seidel fixed-point sweeps until the increment reaches
    round-off (or stalls there). Returns the number of sweeps (-1: no convergence)."""
    n = u.size
    A, w = _RK4SYM_A, _RK4SYM_W
    sweeps = 0
    for _ in range(nsteps):
        scale = 1.0
        for m in range(n):
            scale = max(scale, abs(u[m]))
        toda_rhs(u, K[0])
        for m in range(n):
            K[1, m] = K[0, m]
            K[2, m] = K[0, m]
        best, stale = np.inf, 0
        converged = False
        for _sweep in range(max_iter):
            delta = 0.0
            for i in range(3):
                for m in range(n):
                    y[m] = u[m] + dt * (A[i, 0] * K[0, m] + A[i, 1] * K[1, m] + A[i, 2] * K[2, m])
                toda_rhs(y, k_new)
                for m in range(n):
                    delta = max(delta, abs(dt * (k_new[m] - K[i, m])))
                    K[i, m] = k_new[m]
            sweeps += 1
            # the suite's stop: half an ulp of the state's scale, or three sweeps in a row
            # without a new smallest increment, that smallest below 1e-8 of the scale
            if delta < best:
                best, stale = delta, 0
            else:
                stale += 1
            if delta <= 0.5 * _EPS * scale or (stale >= 3 and best <= 1e-8 * scale):
                converged = True
                break
        if not converged:
            return -1
        for m in range(n):
            u[m] += dt * (w[0] * K[0, m] + w[1] * K[1, m] + w[2] * K[2, m])
    return sweeps


class KernelCase:
    """One scheme on one problem: the suite's integrator and the hand-written loop."""

    def __init__(self, name, problem, scheme, dt, t_final, hand):
        self.name, self.problem_name, self.scheme_name = name, problem, scheme
        self.dt, self.t_final, self._hand = dt, t_final, hand

    def build(self):
        from longtime.core import registry

        self.problem = registry.problem_class(self.problem_name)()
        self.integrator = registry.integrator_class(self.scheme_name)(dt=self.dt)
        self.nsteps = round((self.t_final - self.problem.t0) / self.dt)
        self.run_suite(short=True)  # compile both outside the timing
        self.run_hand(short=True)
        return self

    def run_suite(self, short=False):
        t_final = self.problem.t0 + (10 * self.dt if short else self.t_final - self.problem.t0)
        traj = self.integrator.integrate(self.problem, t_final, max_samples=2)
        assert traj.status == "ok", traj.message
        return traj.cpu_s, traj.u[-1], traj.counters

    def run_hand(self, short=False):
        u = self.problem.u0.copy()
        c0 = time.process_time()
        extra = self._hand(u, self.dt, 10 if short else self.nsteps)
        return time.process_time() - c0, u, extra

    def measure(self, repeat=5):
        """Minimum CPU seconds of each side over ``repeat`` interleaved runs, their ratio, and
        the agreement of the two final states (the same scheme, step for step)."""
        suite_s, hand_s = math.inf, math.inf
        for _ in range(repeat):
            s, u_suite, counters = self.run_suite()
            h, u_hand, extra = self.run_hand()
            suite_s, hand_s = min(suite_s, s), min(hand_s, h)
        scale = max(1.0, float(np.max(np.abs(u_hand))))
        return {
            "case": self.name, "steps": self.nsteps, "suite_cpu_s": suite_s, "hand_cpu_s": hand_s,
            "ratio": suite_s / hand_s, "state_difference": float(np.max(np.abs(u_suite - u_hand))) / scale,
            "suite_nl_iters": counters.get("nl_iters"), "hand_nl_iters": extra,
        }


def _rk4_toda(u, dt, nsteps):
    n = u.size
    k1, k2, k3, k4, y = (np.empty(n) for _ in range(5))
    rk4_toda(u, dt, nsteps, k1, k2, k3, k4, y)


def _verlet_figure_eight(u, dt, nsteps):
    verlet_planar_nbody(u, dt, nsteps, np.empty(u.size // 2))


def _rk4sym_toda(u, dt, nsteps):
    n = u.size
    return int(rk4sym_toda(u, dt, nsteps, np.empty((3, n)), np.empty(n), np.empty(n), 100))


_T8 = 6.32591398  # the figure-eight's period
CASES = {
    "rk4-toda": lambda: KernelCase("rk4-toda", "toda", "rk4", 0.1, 20000.0, _rk4_toda),
    "verlet-figure-eight": lambda: KernelCase("verlet-figure-eight", "figure-eight", "verlet",
                                              0.002 * _T8, 1000 * _T8, _verlet_figure_eight),
    "rk4sym-toda": lambda: KernelCase("rk4sym-toda", "toda", "rk4sym", 0.1, 1000.0, _rk4sym_toda),
}


class KernelRatio:
    """Suite kernel CPU / hand-written loop CPU (goal: at most RATIO_GOAL, 1.2)."""

    timeout = 300

    def setup(self):
        try:
            from longtime.core import registry

            for make in CASES.values():
                case = make()
                registry.problem_class(case.problem_name)
                registry.integrator_class(case.scheme_name)
        except Exception as exc:  # an old version without these schemes or problems
            raise NotImplementedError(str(exc)) from None

    def _ratio(self, name):  # compiles here: a track_ benchmark times nothing itself
        return CASES[name]().build().measure(repeat=5)["ratio"]

    def track_ratio_rk4_toda(self):
        return self._ratio("rk4-toda")

    def track_ratio_verlet_figure_eight(self):
        return self._ratio("verlet-figure-eight")

    def track_ratio_rk4sym_toda(self):
        return self._ratio("rk4sym-toda")

    track_ratio_rk4_toda.unit = "ratio"
    track_ratio_verlet_figure_eight.unit = "ratio"
    track_ratio_rk4sym_toda.unit = "ratio"


if __name__ == "__main__":  # python benchmarks/bench_kernels.py: the ratios, for a note
    for name, make in CASES.items():
        figures = make().build().measure(repeat=7)
        print(f"{name:22s} ratio {figures['ratio']:.2f} (goal <= {RATIO_GOAL})  "
              + "  ".join(f"{k} {v:.4g}" for k, v in figures.items() if k != "ratio" and isinstance(v, float)))
