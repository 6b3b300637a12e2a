"""The frozen argon crystal (Hairer, Lubich, Wanner, Geometric Numerical Integration, I.4):
seven argon atoms in the plane, a hexagon about a central atom, under the Lennard-Jones pair
potential

    H = sum_k |p_k|^2 / (2 m) + sum_{k<l} V(|q_k - q_l|),   V(r) = 4 eps ((sigma/r)^12 - (sigma/r)^6),

with the book's data: eps / k_B = 119.8 K, sigma = 0.341 nm, m = 66.34e-27 kg, positions in
nm and velocities in nm/ns. The state is in the book's length and time units, nm and ns, with
the atom's mass as the unit of mass: p_k = v_k (nm/ns), energies in m nm^2/ns^2
(1 m nm^2/ns^2 = 66.34e-27 J), eps = 119.8 k_B / m = 119.8 x 1.380658e-23 / 66.34e-27
= 24,932.59 nm^2/ns^2.
State u = (x_1, y_1, ..., x_7, y_7, p_1, ..., p_7). Invariants: H, the angular momentum L
and the linear momentum P (0 initially: an absolute error).
"""
from __future__ import annotations

import numba
import numpy as np

from longtime.core.problem import Problem, qp_blocks, separable_rhs

K_B = 1.380658e-23  # J / K, the value HLW use
ARGON_MASS = 66.34e-27  # kg
EPS = 119.8 * K_B / ARGON_MASS  # nm^2 / ns^2 (J/kg = m^2/s^2 = nm^2/ns^2)
SIGMA = 0.341  # nm
POSITIONS = np.array([[0.00, 0.00], [0.02, 0.39], [0.34, 0.17], [0.36, -0.21],
                      [-0.02, -0.40], [-0.35, -0.16], [-0.31, 0.21]])  # nm
VELOCITIES = np.array([[-30.0, -20.0], [50.0, -90.0], [-70.0, -60.0], [90.0, 40.0],
                       [80.0, 90.0], [-40.0, 100.0], [-80.0, -60.0]])  # nm / ns


@numba.njit(cache=True)
def _grad_V(q, params, out):
    eps4, sigma2 = 4.0 * params[0], params[1] * params[1]
    n = q.size // 2
    for i in range(q.size):
        out[i] = 0.0
    for k in range(n):
        for l in range(k + 1, n):
            dx = q[2 * k] - q[2 * l]
            dy = q[2 * k + 1] - q[2 * l + 1]
            r2 = dx * dx + dy * dy
            s6 = (sigma2 / r2) ** 3
            f = eps4 * (6.0 * s6 - 12.0 * s6 * s6) / r2  # V'(r) / r
            out[2 * k] += f * dx
            out[2 * k + 1] += f * dy
            out[2 * l] -= f * dx
            out[2 * l + 1] -= f * dy


@numba.njit(cache=True)
def _grad_T(p, params, out):
    for i in range(p.size):
        out[i] = p[i]


class LennardJones(Problem):
    name = "lennard-jones"
    summary = "frozen argon crystal (HLW I.4): 7 atoms in the plane, Lennard-Jones potential (nm, ns)"
    check_class = "many-body"
    chaotic = True
    default_t_final = 0.2  # ns
    default_dt = 1e-5  # 10 fs
    sweep_dt = (4e-5, 2e-5, 1e-5)
    # the crystal is chaotic (verlet at 20 fs: l2 error 8.5e-3 over 5 ps, 0.79 over 20 ps;
    # heyoka double holds 1e-8 to about 0.033 ns): orders are read over 5 ps
    sweep_t_final = 0.005

    rhs = staticmethod(separable_rhs(_grad_T, _grad_V))
    grad_T = staticmethod(_grad_T)
    grad_V = staticmethod(_grad_V)

    def blocks(self):
        return qp_blocks([f"atom {k + 1}" for k in range(POSITIONS.shape[0])], 2)

    def initial_state(self):
        return np.r_[POSITIONS.ravel(), VELOCITIES.ravel()]

    def kernel_params(self):
        return np.array([EPS, SIGMA])

    def inverse_masses(self):
        return np.ones(self.dim // 2)

    def invariants(self, t, U):
        n = POSITIONS.shape[0]
        q = U[:, :2 * n].reshape(-1, n, 2)
        p = U[:, 2 * n:].reshape(-1, n, 2)
        potential = np.zeros(U.shape[0])
        for k in range(n):
            for l in range(k + 1, n):
                d = q[:, k] - q[:, l]
                s6 = (SIGMA**2 / np.einsum("ij,ij->i", d, d)) ** 3
                potential += 4 * EPS * (s6 * s6 - s6)
        return {"H": 0.5 * np.sum(p**2, axis=(1, 2)) + potential,
                "L": np.sum(q[:, :, 0] * p[:, :, 1] - q[:, :, 1] * p[:, :, 0], axis=1),
                "P": np.sum(p, axis=1)}

    def heyoka_system(self):
        import heyoka as hy

        n = POSITIONS.shape[0]
        q = hy.make_vars(*[f"q{k}_{c}" for k in range(n) for c in "xy"])
        p = hy.make_vars(*[f"p{k}_{c}" for k in range(n) for c in "xy"])
        dp = [[] for _ in range(2 * n)]
        for k in range(n):
            for l in range(k + 1, n):
                dx, dy = q[2 * k] - q[2 * l], q[2 * k + 1] - q[2 * l + 1]
                s6 = (SIGMA**2 / (dx * dx + dy * dy)) ** 3
                f = 4 * EPS * (12.0 * s6 * s6 - 6.0 * s6) / (dx * dx + dy * dy)  # -V'(r) / r
                dp[2 * k] += [f * dx]
                dp[2 * k + 1] += [f * dy]
                dp[2 * l] += [-f * dx]
                dp[2 * l + 1] += [-f * dy]
        return list(q) + list(p), list(p) + [hy.sum(terms) for terms in dp]
