"""A charged particle (unit charge and mass) in a non-uniform static magnetic field and an
electric field, x'' = x' x B(x) + E(x), with

    B(x) = curl A(x) = (0, 0, r),   A(x) = (1/3) (-x2 r, x1 r, 0),   r = sqrt(x1^2 + x2^2),
    E(x) = -grad U(x) = (x1, x2, 0) / (100 r^3),   U(x) = 1 / (100 r),

the field and potential of Hairer and Lubich's charged-particle experiments (docs/problems.md
says where the data come from and what was not verified). State u = (x, v) in R^6, from
x(0) = (0, 0.2, 0.1), v(0) = (0.09, 0.05, 0.2). Invariant: the energy
H = |v|^2 / 2 + U(x) (the magnetic force does no work). Diagnostic: the magnetic moment
mu = |v_perp|^2 / (2 |B(x)|), v_perp the velocity across B, an adiabatic invariant only.
"""
from __future__ import annotations

import math

import numba
import numpy as np

from longtime.core.params import Param
from longtime.core.problem import Problem, qp_blocks

X0 = (0.0, 0.2, 0.1)
V0 = (0.09, 0.05, 0.2)


@numba.njit(cache=True)
def _field_B(x, params, out):
    out[0] = 0.0
    out[1] = 0.0
    out[2] = math.sqrt(x[0] * x[0] + x[1] * x[1])


@numba.njit(cache=True)
def _field_E(x, params, out):
    # params[0] is the strength c of U = c / r (1/100)
    r2 = x[0] * x[0] + x[1] * x[1]
    f = params[0] / (r2 * math.sqrt(r2))
    out[0] = f * x[0]
    out[1] = f * x[1]
    out[2] = 0.0


@numba.njit(cache=True)
def _rhs(t, u, params, out):
    # x' = v, v' = v x B(x) + E(x) with B = (0, 0, r): v x B = (v2 r, -v1 r, 0)
    r2 = u[0] * u[0] + u[1] * u[1]
    r = math.sqrt(r2)
    f = params[0] / (r2 * r)
    out[0] = u[3]
    out[1] = u[4]
    out[2] = u[5]
    out[3] = u[4] * r + f * u[0]
    out[4] = -u[3] * r + f * u[1]
    out[5] = 0.0


class ChargedParticle(Problem):
    name = "charged-particle"
    summary = ("charged particle in the non-uniform field B = (0, 0, r), E = -grad 1/(100 r) "
               "(Hairer-Lubich's example; Lorentz force)")
    parameters = {"c": Param(0.01, "strength of the electric potential U = c / r", float, positive=True,
                             role="physical")}
    default_t_final = 1000.0
    default_dt = 0.1
    sweep_dt = (0.2, 0.1)
    sweep_t_final = 1000.0
    long_t_final = 100_000.0  # 10^6 Boris steps: where rk4's energy drift shows

    rhs = staticmethod(_rhs)
    field_B = staticmethod(_field_B)
    field_E = staticmethod(_field_E)

    def blocks(self):
        return qp_blocks(["particle"], 3)  # its position x and its velocity v

    def initial_state(self):
        return [*X0, *V0]

    def kernel_params(self):
        return np.array([self.settings["c"]])

    def potential(self, X: np.ndarray) -> np.ndarray:
        return self.settings["c"] / np.hypot(X[:, 0], X[:, 1])

    def invariants(self, t, U):
        return {"H": 0.5 * np.sum(U[:, 3:6] ** 2, axis=1) + self.potential(U[:, :3])}

    def diagnostics(self, t, U):
        # B is along e3: v_perp = (v1, v2, 0), |B| = r
        return {"mu": 0.5 * (U[:, 3] ** 2 + U[:, 4] ** 2) / np.hypot(U[:, 0], U[:, 1])}

    def heyoka_system(self):
        import heyoka as hy

        x1, x2, x3, v1, v2, v3 = hy.make_vars("x1", "x2", "x3", "v1", "v2", "v3")
        r2 = x1 * x1 + x2 * x2
        r = hy.sqrt(r2)
        f = self.settings["c"] / (r2 * r)
        return [x1, x2, x3, v1, v2, v3], [v1, v2, v3, v2 * r + f * x1, -v1 * r + f * x2, 0.0 * x3]
