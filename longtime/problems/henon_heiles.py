"""Henon-Heiles, H = (px^2 + py^2 + x^2 + y^2)/2 + x^2 y - y^3/3: chaotic near E = 1/6.

State (x, y, px, py). The orbit starts at x = 0, y = y0, py = 0 with px > 0 fixed by the
energy E (below the escape energy 1/6). At the default E = 1/6 - 1e-3 the default y0 = 0.1
starts on a regular orbit (an island: no exponential separation over t = 1e4); y0 = 0
(``chaotic_settings``) starts in the chaotic sea (docs/problems.md gives the exponents).
"""
from __future__ import annotations

import math

import numba
import numpy as np

from longtime.core.params import InputError, Param
from longtime.core.problem import Problem, qp_blocks, separable_rhs


@numba.njit(cache=True)
def _grad_V(q, params, out):
    out[0] = q[0] + 2.0 * q[0] * q[1]
    out[1] = q[1] + q[0] * q[0] - q[1] * q[1]


@numba.njit(cache=True)
def _grad_T(p, params, out):
    out[0] = p[0]
    out[1] = p[1]


def potential(x, y):
    return 0.5 * (x * x + y * y) + x * x * y - y**3 / 3


def _jax_rhs(t, u, params):
    """The rhs in jax.numpy (the diffrax peers)."""
    import jax.numpy as jnp

    x, y, px, py = u[0], u[1], u[2], u[3]
    return jnp.stack([px, py, -(x + 2.0 * x * y), -(y + x * x - y * y)])


class HenonHeiles(Problem):
    name = "henon-heiles"
    summary = "Henon-Heiles potential near the escape energy 1/6 (default orbit regular; chaotic sea from y0 = 0)"
    chaotic = True
    lyapunov_span = 10_000.0
    chaotic_settings = {"y0": 0.0}
    parameters = {
        "energy": Param(1 / 6 - 1e-3, "energy E, 0 < E < 1/6 (bounded motion)", float, positive=True,
                        maximum=1 / 6, role="physical"),
        "y0": Param(0.1, "initial y (x = 0, py = 0, px > 0 from E)", float, role="physical"),
    }
    default_t_final = 1000.0
    default_dt = 0.05
    sweep_dt = (0.1, 0.05)
    sweep_t_final = 500.0
    long_t_final = 10_000.0  # over 10^3 oscillation periods, for the schemes that can afford it

    rhs = staticmethod(separable_rhs(_grad_T, _grad_V))
    jax_rhs = staticmethod(_jax_rhs)
    grad_T = staticmethod(_grad_T)
    grad_V = staticmethod(_grad_V)

    def blocks(self):
        return qp_blocks(["particle"], 2)

    def initial_state(self):
        E, y0 = self.settings["energy"], self.settings["y0"]
        kinetic = E - potential(0.0, y0)
        if kinetic < 0:
            raise InputError(f"y0={y0} is not valid for energy={E}: the potential there exceeds E")
        return [0.0, y0, math.sqrt(2 * kinetic), 0.0]

    def inverse_masses(self):
        return np.ones(self.dim // 2)

    def invariants(self, t, U):
        x, y, px, py = U.T
        return {"H": 0.5 * (px**2 + py**2) + potential(x, y)}

    def heyoka_system(self):
        import heyoka as hy

        x, y, px, py = hy.make_vars("x", "y", "px", "py")
        return [x, y, px, py], [px, py, -(x + 2.0 * x * y), -(y + x * x - y * y)]
