"""The Lotka-Volterra predator-prey model as a Poisson system (Hairer-Lubich-Wanner, Geometric
Numerical Integration, I.1 and VII.2):

    u' = u (v - 2),   v' = v (1 - u),   i.e.  (u, v)' = B(u, v) grad H,  B = [[0, -uv], [uv, 0]],

with H(u, v) = ln u - u + 2 ln v - v, a first integral (the invariant ``H``; HLW's I). The
structure matrix B depends on the state: the system is not canonical, and the orbits are
the closed level curves of H around the equilibrium (1, 2).
"""
from __future__ import annotations

import numba
import numpy as np

from longtime.core.params import Param
from longtime.core.problem import Problem
from longtime.numerics.series import product


@numba.njit(cache=True)
def _rhs(t, u, params, out):
    out[0] = u[0] * (u[1] - 2.0)
    out[1] = u[1] * (1.0 - u[0])


@numba.njit(cache=True)
def _jac(t, u, params, out):
    out[0, 0] = u[1] - 2.0
    out[0, 1] = u[0]
    out[1, 0] = -u[1]
    out[1, 1] = 1.0 - u[0]


@numba.njit(cache=True)
def _taylor(t0, u, params, coeffs, work):
    coeffs[0, 0] = u[0]
    coeffs[0, 1] = u[1]
    for n in range(coeffs.shape[0] - 1):
        uv = product(coeffs[:, 0], coeffs[:, 1], n)
        coeffs[n + 1, 0] = (uv - 2.0 * coeffs[n, 0]) / (n + 1)
        coeffs[n + 1, 1] = (coeffs[n, 1] - uv) / (n + 1)


def _jax_rhs(t, u, params):
    """The rhs in jax.numpy (the diffrax peers)."""
    import jax.numpy as jnp

    return jnp.stack([u[0] * (u[1] - 2.0), u[1] * (1.0 - u[0])])


class LotkaVolterra(Problem):
    name = "lotka-volterra"
    summary = "Lotka-Volterra u' = u(v - 2), v' = v(1 - u): a Poisson system (HLW I.1), first integral H"
    parameters = {
        "u0": Param(4.0, "initial prey u(0) > 0", float, positive=True, role="physical"),
        "v0": Param(2.0, "initial predators v(0) > 0", float, positive=True, role="physical"),
    }
    default_t_final = 100.0
    default_dt = 0.05
    sweep_dt = (0.1, 0.05)
    sweep_t_final = 100.0
    long_t_final = 10_000.0

    rhs = staticmethod(_rhs)
    jax_rhs = staticmethod(_jax_rhs)
    jac = staticmethod(_jac)
    taylor = staticmethod(_taylor)

    def initial_state(self):
        return [self.settings["u0"], self.settings["v0"]]

    def invariants(self, t, U):
        with np.errstate(invalid="ignore", divide="ignore"):  # a run that left u, v > 0 reads nan
            return {"H": np.log(U[:, 0]) - U[:, 0] + 2 * np.log(U[:, 1]) - U[:, 1]}

    def heyoka_system(self):
        import heyoka as hy

        u, v = hy.make_vars("u", "v")
        return [u, v], [u * (v - 2.0), v * (1.0 - u)]
