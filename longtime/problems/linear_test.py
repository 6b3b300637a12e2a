"""Dahlquist's test equation u' = lambda u (complex lambda = re + i im) as the real 2x2
system x' = re x - im y, y' = im x + re y for u = x + i y: the problem on which
longtime.measure.stability measures each scheme's amplification factor R(z)."""
from __future__ import annotations

import numba
import numpy as np

from longtime.core.params import Param
from longtime.core.problem import Problem, whole_state


@numba.njit(cache=True)
def _rhs(t, u, params, out):
    out[0] = params[0] * u[0] - params[1] * u[1]
    out[1] = params[1] * u[0] + params[0] * u[1]


@numba.njit(cache=True)
def _jac(t, u, params, out):
    out[0, 0], out[0, 1] = params[0], -params[1]
    out[1, 0], out[1, 1] = params[1], params[0]


@numba.njit(cache=True)
def _taylor(t0, u, params, coeffs, work):
    # u^(k+1) = lambda u^(k) / (k + 1) in complex arithmetic on (x, y)
    a, b = params[0], params[1]
    coeffs[0, 0], coeffs[0, 1] = u[0], u[1]
    for k in range(coeffs.shape[0] - 1):
        x, y = coeffs[k, 0], coeffs[k, 1]
        coeffs[k + 1, 0] = (a * x - b * y) / (k + 1)
        coeffs[k + 1, 1] = (b * x + a * y) / (k + 1)


def _jax_rhs(t, u, params):
    """The rhs in jax.numpy (the diffrax peers)."""
    import jax.numpy as jnp

    return jnp.stack([params[0] * u[0] - params[1] * u[1], params[1] * u[0] + params[0] * u[1]])


class LinearTest(Problem):
    """Dahlquist's test equation u' = lambda u as a real 2x2 system (u = x + i y)."""

    name = "linear-test"
    summary = "test equation u' = lambda u (complex lambda, as a real 2x2 system), exact solution"
    parameters = {
        "re": Param(0.0, "real part of lambda", float, role="physical"),
        "im": Param(1.0, "imaginary part of lambda", float, role="physical"),
    }
    default_t_final = 20.0
    default_dt = 0.1
    sweep_dt = (0.2, 0.1, 0.05)
    sweep_t_final = 20.0
    in_default_matrix = False  # a diagnostic: `longtime list --stability` uses it

    rhs = staticmethod(_rhs)
    jax_rhs = staticmethod(_jax_rhs)
    jac = staticmethod(_jac)
    taylor = staticmethod(_taylor)

    def blocks(self):
        return whole_state(self)  # one complex number (re, im)

    def initial_state(self):
        return [1.0, 0.0]

    def kernel_params(self):
        return np.array([self.settings["re"], self.settings["im"]])

    def invariants(self, t, U):
        # |u|^2 e^(-2 re t) is constant along the exact solution
        return {"H": 0.5 * (U[:, 0] ** 2 + U[:, 1] ** 2) * np.exp(-2.0 * self.settings["re"] * (t - self.t0))}

    def heyoka_system(self):
        import heyoka as hy

        x, y = hy.make_vars("x", "y")
        a, b = self.settings["re"], self.settings["im"]
        return [x, y], [a * x - b * y, b * x + a * y]

    def exact(self, t):
        t = np.asarray(t, dtype=float) - self.t0
        a, b = self.settings["re"], self.settings["im"]
        r = np.exp(a * t)
        return np.stack([r * np.cos(b * t), r * np.sin(b * t)], axis=1)
