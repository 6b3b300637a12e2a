"""Harmonic oscillator H = (p^2 + omega^2 q^2)/2: the sanity baseline with an exact solution."""
from __future__ import annotations

import numba
import numpy as np

from longtime.core.params import Param
from longtime.core.problem import Problem, qp_blocks


@numba.njit(cache=True)
def _rhs(t, u, params, out):
    out[0] = u[1]
    out[1] = -params[0] * params[0] * u[0]


@numba.njit(cache=True)
def _grad_T(p, params, out):
    out[0] = p[0]


@numba.njit(cache=True)
def _taylor(t0, u, params, coeffs, work):
    # q' = p, p' = -omega^2 q: linear, no auxiliary series
    w2 = params[0] * params[0]
    coeffs[0, 0], coeffs[0, 1] = u[0], u[1]
    for k in range(coeffs.shape[0] - 1):
        coeffs[k + 1, 0] = coeffs[k, 1] / (k + 1)
        coeffs[k + 1, 1] = -w2 * coeffs[k, 0] / (k + 1)


@numba.njit(cache=True)
def _grad_V(q, params, out):
    out[0] = params[0] * params[0] * q[0]


def _jax_rhs(t, u, params):
    """The rhs in jax.numpy (the diffrax peers)."""
    import jax.numpy as jnp

    return jnp.stack([u[1], -params[0] * params[0] * u[0]])


class Harmonic(Problem):
    name = "harmonic"
    summary = "harmonic oscillator, exact solution"
    parameters = {
        "omega": Param(1.0, "angular frequency", float, positive=True, role="physical"),
        "q0": Param(1.0, "initial position", float, role="physical"),
        "p0": Param(0.0, "initial momentum", float, role="physical"),
    }
    default_t_final = 100.0
    default_dt = 0.1
    sweep_dt = (0.2, 0.1, 0.05)
    sweep_t_final = 200.0

    rhs = staticmethod(_rhs)
    jax_rhs = staticmethod(_jax_rhs)
    grad_T = staticmethod(_grad_T)
    grad_V = staticmethod(_grad_V)
    taylor = staticmethod(_taylor)

    def blocks(self):
        return qp_blocks(["oscillator"], 1)

    def initial_state(self):
        return [self.settings["q0"], self.settings["p0"]]

    def kernel_params(self):
        return np.array([self.settings["omega"]])

    def inverse_masses(self):
        return np.ones(self.dim // 2)

    def hamiltonian(self, t, U):
        w = self.settings["omega"]
        return 0.5 * (U[:, 1] ** 2 + w**2 * U[:, 0] ** 2)

    def invariants(self, t, U):
        return {"H": self.hamiltonian(t, U)}

    def heyoka_system(self):
        import heyoka as hy

        q, p = hy.make_vars("q", "p")
        return [q, p], [p, -self.settings["omega"] ** 2 * q]

    def exact(self, t):
        w, q0, p0 = self.settings["omega"], self.settings["q0"], self.settings["p0"]
        t = np.asarray(t, dtype=float) - self.t0
        c, s = np.cos(w * t), np.sin(w * t)
        return np.stack([q0 * c + p0 / w * s, -q0 * w * s + p0 * c], axis=1)
