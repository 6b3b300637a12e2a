"""Explicit Runge-Kutta schemes as Butcher tableaus over one shared compiled stepper."""
from __future__ import annotations

import numba
import numpy as np

from longtime.core.drivers import OK, RHS_EVALS
from longtime.core.stepping import COMPENSATED, FixedStepIntegrator
from longtime.integrators.tableau import add_weighted_slopes, checked_on_definition


class ExplicitRungeKutta(FixedStepIntegrator):
    """u_{n+1} = u_n + h sum_i b_i k_i, k_i = f(t + c_i h, u_n + h sum_{j<i} a_ij k_j)."""

    A: np.ndarray
    b: np.ndarray
    c: np.ndarray
    parameters = {**FixedStepIntegrator.parameters, "compensated": COMPENSATED}
    long_runs = True  # a few right-hand sides a step: paper-scale final times in the matrix

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        checked_on_definition(cls, explicit=True)  # a broken tableau fails at import

    def work_shape(self, problem):
        return (len(self.b) + 2, problem.dim)  # stage slopes, the stage state, compensation

    def make_step(self, problem):
        rhs = problem.rhs
        A, b, c = (np.ascontiguousarray(x, dtype=np.float64) for x in (self.A, self.b, self.c))
        s = b.size
        compensated = bool(self.settings["compensated"])

        @numba.njit
        def step(t, u, h, params, work, counters, first):
            y = work[s]
            for i in range(s):
                for m in range(u.size):
                    acc = 0.0
                    for j in range(i):
                        acc += A[i, j] * work[j, m]
                    y[m] = u[m] + h * acc
                rhs(t + c[i] * h, y, params, work[i])
            add_weighted_slopes(u, h, b, work, compensated, work[s + 1])
            counters[RHS_EVALS] += s
            return OK

        return step


class Euler(ExplicitRungeKutta):
    name = "euler"
    summary = "explicit Euler (order 1, not symplectic)"
    order = 1
    A = np.zeros((1, 1))
    b = np.array([1.0])
    c = np.array([0.0])


class RK4(ExplicitRungeKutta):
    name = "rk4"
    summary = "classical Runge-Kutta 4"
    order = 4
    A = np.array([[0, 0, 0, 0], [0.5, 0, 0, 0], [0, 0.5, 0, 0], [0, 0, 1, 0]], dtype=float)
    b = np.array([1, 2, 2, 1], dtype=float) / 6
    c = np.array([0, 0.5, 0.5, 1.0])
