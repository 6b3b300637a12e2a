"""The averaged vector field method (Quispel and McLaren, J. Phys. A 41 (2008) 045206):

    u_{n+1} = u_n + h int_0^1 f((1 - s) u_n + s u_{n+1}) ds.

For f = J grad H with a constant skew J it conserves H exactly, since
H(u_{n+1}) - H(u_n) = int_0^1 grad H((1-s) u_n + s u_{n+1}) ds . (u_{n+1} - u_n) =
h g^T J g = 0 with g the averaged gradient. Order 2, symmetric, B-series but not symplectic.

The integral is taken by Gauss-Legendre quadrature in s with ``nodes`` points (default 2):
exact for an integrand of degree 2 nodes - 1 in s. Along the segment, f of a polynomial H of
degree d is a polynomial of degree d - 1 in s, so 2 nodes are exact up to quartic H (the
harmonic oscillator, Henon-Heiles' cubic H, FPU's quartic springs): energy is then
conserved to round-off and the solver's stopping rule. For a non-polynomial H (kepler,
n-body, toda) the quadrature adds an O(h^(2 nodes + 1)) local error: the order stays 2, the
energy is no longer exact.

The equation for u_{n+1} is solved by fixed-point iteration on the averaged slope
g = sum_j w_j f(u_n + c_j h g), with implicit_rk's stopping rules (``stop``, ``max_iter``)
and its count of sweeps (``nl_iters``); a solve that does not converge fails the step.
"""
from __future__ import annotations

import numba
import numpy as np

from longtime.core.drivers import FAILED, OK, state_scale
from longtime.core.params import Param
from longtime.core.stepping import FixedStepIntegrator
from longtime.integrators.implicit_rk import ImplicitRungeKutta, sweep_done, sweeps_status


def gauss_legendre(nodes: int) -> tuple[np.ndarray, np.ndarray]:
    """Nodes c_j in (0, 1) and weights w_j (summing to 1) of the Gauss-Legendre rule."""
    x, w = np.polynomial.legendre.leggauss(nodes)
    return (x + 1.0) / 2.0, w / 2.0


class AVF(FixedStepIntegrator):
    name = "avf"
    summary = ("averaged vector field (Quispel-McLaren 2008): energy-preserving for polynomial H "
               "(order 2, implicit)")
    order = 2
    symplectic = False
    step_cost = 10.0  # the fixed-point sweeps over the quadrature nodes (the budget's estimate)
    parameters = {
        **FixedStepIntegrator.parameters,
        "nodes": Param(2, "Gauss-Legendre nodes of the integral over the segment (exact for "
                       "polynomial H of degree up to 2 nodes)", int, minimum=1, maximum=10),
        "max_iter": ImplicitRungeKutta.parameters["max_iter"],
        "stop": ImplicitRungeKutta.parameters["stop"],
    }

    def work_shape(self, problem):
        return (4, problem.dim)  # averaged slope g, its next iterate, a node's state and slope

    def make_step(self, problem):
        rhs = problem.rhs
        c, w = gauss_legendre(int(self.settings["nodes"]))
        nodes = c.size
        max_iter = int(self.settings["max_iter"])
        brouwer = self.settings["stop"] == "brouwer"

        @numba.njit
        def step(t, u, h, params, work, counters, first):
            n = u.size
            g, total, y, k = work[0], work[1], work[2], work[3]
            scale = state_scale(u)
            rhs(t, u, params, g)  # the first guess: u_{n+1} = u_n + h f(u_n)
            evals = 1
            done, best, stale = False, np.inf, 0
            for sweep in range(max_iter):
                for m in range(n):
                    total[m] = 0.0
                for j in range(nodes):
                    for m in range(n):
                        y[m] = u[m] + c[j] * h * g[m]
                    rhs(t + c[j] * h, y, params, k)
                    for m in range(n):
                        total[m] += w[j] * k[m]
                evals += nodes
                delta = 0.0
                for m in range(n):
                    delta = max(delta, abs(h * (total[m] - g[m])))
                    g[m] = total[m]
                done, best, stale = sweep_done(delta, best, stale, scale, brouwer, counters)
                if done:
                    break
            if sweeps_status(done, evals, counters) != OK:
                return FAILED
            for m in range(n):
                u[m] += h * g[m]
            return OK

        return step
