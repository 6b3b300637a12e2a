"""Truncated Taylor series from the problem's recurrence: fixed step, and adaptive (Jorba-Zou).

One step: the problem's ``taylor`` writes the normalised coefficients u_0..u_N at (t, u)
(u_k = u^(k)(t)/k!), then u(t + h) = sum_k u_k h^k by Horner's rule. No resummation (that
is ``bpl``). The adaptive variant sizes each step a priori from the last two coefficients
(Jorba and Zou 2005, section 3.2): with eps = tol * max(1, |u|_inf),

    h = exp(-0.7 / (N - 1)) * min_{k in {N-1, N}} (eps / |u_k|_inf)^(1/k),

so that the next terms of the series, whose size those two coefficients predict, stay
below eps. By default N follows tol as in Jorba-Zou and heyoka (N = ceil(-ln(tol)/2 + 1)),
which keeps the step near the series' radius of convergence for every tol. Every step is
accepted; where all coefficients beyond u_0 vanish (an
equilibrium) nothing limits the step and it is the largest allowed, h_max.

The scratch array is flat: a header (N, the tolerance, the step's safety factor, where
the problem's scratch starts and its shape), the coefficients (N+1, dim), then the
problem's own scratch of shape ``taylor_work_shape(N)``. The compiled step reads N and the
shapes from the header at run time, so one compiled kernel per problem serves every N and
every tol: taylor-adaptive's tolerance sweep (N follows tol) would compile one kernel per
tolerance if N were closed over.
"""
from __future__ import annotations

import math

import numba
import numpy as np

from longtime.core.drivers import EXTRA1, OK
from longtime.core.params import Param
from longtime.core.stepping import AdaptiveIntegrator, FixedStepIntegrator
from longtime.numerics.series import header_view, horner

# header of the flat work array, written by prepare_work and read by the compiled step
_ORDER, _TOL, _SAFETY, _O_SCRATCH, _SHAPE0 = range(5)  # the scratch shape: slots _SHAPE0.. (1 to 4)
_HEADER = _SHAPE0 + 4

ORDER = Param(10, "series order N (degree of the truncated Taylor polynomial)", int, minimum=1, maximum=60,
              role="order")


class _SeriesLayout:
    """Flat scratch layout shared by both schemes (see the module's docstring)."""

    extra_counters = ("series_evals",)
    requires = frozenset({"taylor"})

    def _layout(self, problem):
        N = self.settings["order"]
        tshape = tuple(int(x) for x in problem.taylor_work_shape(N))
        return N, problem.dim, tshape

    def _integrate(self, problem, t_final, max_samples):
        traj = super()._integrate(problem, t_final, max_samples)
        # the row's order (and tol) fields, also when defaulted
        traj.extra.update({k: self.settings[k] for k in ("order", "tol") if k in self.settings})
        return traj

    def work_shape(self, problem):
        N, dim, tshape = self._layout(problem)
        return (_HEADER + (N + 1) * dim + max(1, int(np.prod(tshape))),)

    def prepare_work(self, problem, work):
        N, dim, tshape = self._layout(problem)
        work[_ORDER], work[_O_SCRATCH] = N, _HEADER + (N + 1) * dim
        work[_SHAPE0:_SHAPE0 + len(tshape)] = tshape

    def _views(self, problem):
        """Compiled ``views(work) -> (coeffs, taylor scratch)``, sizes from the header."""
        _, dim, tshape = self._layout(problem)
        scratch = header_view(len(tshape), _O_SCRATCH, _SHAPE0)

        @numba.njit(inline="always")
        def views(work):
            rows = int(work[_ORDER]) + 1
            return work[_HEADER:_HEADER + rows * dim].reshape((rows, dim)), scratch(work)

        return views


class Taylor(_SeriesLayout, FixedStepIntegrator):
    name = "taylor"
    summary = "truncated Taylor series of order N from the problem's recurrence, fixed step"
    parameters = {**FixedStepIntegrator.parameters, "order": ORDER}

    def __init__(self, **settings):
        super().__init__(**settings)
        self.order = self.settings["order"]  # convergence order = series order

    def make_step(self, problem):
        taylor, views = problem.taylor, self._views(problem)

        @numba.njit
        def step(t, u, h, params, work, counters, first):
            coeffs, scratch = views(work)
            taylor(t, u, params, coeffs, scratch)
            horner(coeffs, h, u)
            counters[EXTRA1] += 1
            return OK

        return step


class AdaptiveTaylor(_SeriesLayout, AdaptiveIntegrator):
    name = "taylor-adaptive"
    summary = "Taylor series of order N, step from the last two coefficients (Jorba-Zou)"
    parameters = {
        "order": Param(None, "series order N >= 2 (default: Jorba-Zou's ceil(-ln(tol)/2 + 1), "
                       "the order that minimises the work per unit time at that tolerance)",
                       int, minimum=2, maximum=60, role="order"),
        "tol": Param(1e-12, "local tolerance (absolute below |u| = 1, relative above)", float,
                     positive=True, role="accuracy"),
    }
    sweep = {"tol": (1e-6, 1e-9, 1e-12)}

    def __init__(self, **settings):
        super().__init__(**settings)
        if self.settings["order"] is None:
            self.settings["order"] = min(60, max(2, math.ceil(-math.log(self.settings["tol"]) / 2 + 1)))
        self.order = self.settings["order"]

    def prepare_work(self, problem, work):
        super().prepare_work(problem, work)
        N = self.settings["order"]
        work[_TOL], work[_SAFETY] = self.settings["tol"], math.exp(-0.7 / (N - 1))

    def initial_step(self, problem, t_final):
        return self.max_step(problem, t_final)  # every step sizes itself

    def make_try_step(self, problem):
        taylor, views = problem.taylor, self._views(problem)

        @numba.njit
        def try_step(t, u, h, params, work, counters, u_new):
            coeffs, scratch = views(work)
            taylor(t, u, params, coeffs, scratch)
            counters[EXTRA1] += 1
            size = 0.0
            for i in range(u.size):
                size = max(size, abs(u[i]))
            eps = work[_TOL] * max(1.0, size)
            N = coeffs.shape[0] - 1
            rho = math.inf
            for k in range(N - 1, N + 1):
                norm = 0.0
                for i in range(u.size):
                    norm = max(norm, abs(coeffs[k, i]))
                if norm > 0.0:  # a vanishing coefficient sets no bound (equilibrium)
                    rho = min(rho, (eps / norm) ** (1.0 / k))
            h_taken = min(h, work[_SAFETY] * rho)
            if not h_taken > 1e-15 * (abs(t) + 1.0):  # huge or non-finite coefficients
                return -1, h_taken, h_taken
            horner(coeffs, h_taken, u_new)
            return 1, h_taken, math.inf

        return try_step
