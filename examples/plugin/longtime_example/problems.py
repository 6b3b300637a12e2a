"""The plane pendulum q'' = -w2 sin q as a separable Hamiltonian, u = (q, p):

    H(q, p) = p^2 / 2 - w2 cos q,   q' = dH/dp = p,   p' = -dH/dq = -w2 sin q.
"""
import numba
import numpy as np

from longtime import Param, Problem
from longtime.core.problem import separable_rhs


# compiled functions: (input, params, out), write into out, allocate nothing
@numba.njit(cache=True)
def _grad_T(p, params, out):
    out[0] = p[0]


@numba.njit(cache=True)
def _grad_V(q, params, out):
    out[0] = params[0] * np.sin(q[0])


class Pendulum(Problem):
    name = "example-pendulum"  # must equal the entry-point name
    summary = "plane pendulum from the example plugin (separable H)"
    parameters = {
        "w2": Param(1.0, "squared small-oscillation frequency g / l", float, positive=True),
        "q0": Param(2.0, "initial angle (rad); the pendulum starts at rest", float),
    }
    default_t_final = 100.0
    default_dt = 0.05
    sweep_dt = (0.1, 0.05, 0.025)  # the default matrix's steps

    # capabilities: attached with staticmethod, compiled with numba
    rhs = staticmethod(separable_rhs(_grad_T, _grad_V))  # required
    grad_T = staticmethod(_grad_T)  # with grad_V: the "separable" capability
    grad_V = staticmethod(_grad_V)

    def initial_state(self):
        return [self.settings["q0"], 0.0]

    def kernel_params(self):
        return np.array([self.settings["w2"]])  # constants only: the kernels never write params

    def invariants(self, t, U):
        H = 0.5 * U[:, 1] ** 2 - self.settings["w2"] * np.cos(U[:, 0])
        return {"H": H}
