"""Trigonometric integrators for oscillatory problems (Hairer, Lubich, Wanner, Geometric
Numerical Integration, chapter XIII.2).

For q'' = -Omega^2 q + g(q), g = -grad U, Omega diagonal (the ``oscillatory`` capability:
``frequencies(params, out)`` gives diag(Omega), ``grad_U(q, params, out)`` the slow potential's
gradient; unit masses, p = q'), the one-step formulation (HLW XIII.2.2) with filter
functions psi, psi0, psi1, phi of xi = h Omega:

    q+ = cos(h Omega) q + Omega^-1 sin(h Omega) p + h^2/2 Psi g_n,
    p+ = -Omega sin(h Omega) q + cos(h Omega) p + h/2 (Psi0 g_n + Psi1 g_{n+1}),
    g_n = g(Phi q_n).

The linear oscillation is solved exactly (a zero frequency gives q+ = q + h p), so the step
is not limited by h omega < 2 as Verlet's is; the filters keep the slow force from exciting
the fast modes at resonances h omega near multiples of pi. The coefficients are computed in
the compiled step when h differs from the step they were computed for (a fixed-step run:
at most twice, for the clipped last step). g_{n+1} is the next step's g_n: one slow force a
step (counted as one rhs evaluation).
"""
from __future__ import annotations

import math
from typing import Callable

import numba

from longtime.core.drivers import OK, RHS_EVALS
from longtime.core.stepping import FixedStepIntegrator

# rows of the work array, each of length n = dim/2
COS, SIN_OVER, OMEGA_SIN, PSI, PSI0, PSI1, PHI, FREQ, FORCE, FILTERED, META = range(11)


@numba.njit(cache=True)
def sinc(x):
    return 1.0 if x == 0.0 else math.sin(x) / x


@numba.njit(cache=True)
def mollified_impulse_filters(xi):
    """(psi, psi0, psi1, phi) of the mollified impulse method: phi = sinc, psi = sinc phi,
    psi0 = cos phi, psi1 = phi (Garcia-Archilla, Sanz-Serna, Skeel 1999; HLW XIII.2.2)."""
    phi = sinc(xi)
    return sinc(xi) * phi, math.cos(xi) * phi, phi, phi


class Trigonometric(FixedStepIntegrator):
    """The one-step trigonometric family of HLW XIII.2.2; a subclass names the published
    method by its compiled ``filters(xi) -> (psi, psi0, psi1, phi)``."""

    requires = frozenset({"oscillatory"})
    order = 2
    filters: Callable

    def work_shape(self, problem):
        return (META + 1, problem.dim // 2)

    def make_step(self, problem):
        frequencies, grad_U = problem.frequencies, problem.grad_U
        filters = self.filters

        @numba.njit
        def step(t, u, h, params, work, counters, first):
            n = u.size // 2
            evals = 0
            fresh = not first
            if work[META, 0] != h:  # the coefficients of xi = h omega for this h
                frequencies(params, work[FREQ])
                for i in range(n):
                    w = work[FREQ, i]
                    xi = h * w
                    work[COS, i] = math.cos(xi)
                    work[SIN_OVER, i] = h * sinc(xi)  # sin(h w) / w, h at w = 0
                    work[OMEGA_SIN, i] = w * math.sin(xi)
                    psi, psi0, psi1, phi = filters(xi)
                    work[PSI, i], work[PSI0, i], work[PSI1, i], work[PHI, i] = psi, psi0, psi1, phi
                work[META, 0] = h
                fresh = False  # Phi changed: the stored force is another step's
            if not fresh:  # g_n = -grad U(Phi q_n)
                for i in range(n):
                    work[FILTERED, i] = work[PHI, i] * u[i]
                grad_U(work[FILTERED], params, work[FORCE])
                evals += 1
            for i in range(n):  # the exact rotation of the fast part, plus the slow force's share
                q, p, g = u[i], u[n + i], -work[FORCE, i]
                c = work[COS, i]
                u[i] = c * q + work[SIN_OVER, i] * p + 0.5 * h * h * work[PSI, i] * g
                u[n + i] = -work[OMEGA_SIN, i] * q + c * p + 0.5 * h * work[PSI0, i] * g
            for i in range(n):  # g_{n+1}, kept for the next step
                work[FILTERED, i] = work[PHI, i] * u[i]
            grad_U(work[FILTERED], params, work[FORCE])
            evals += 1
            for i in range(n):
                u[n + i] -= 0.5 * h * work[PSI1, i] * work[FORCE, i]
            counters[RHS_EVALS] += evals
            return OK

        return step


class MollifiedImpulse(Trigonometric):
    name = "mollified-impulse"
    summary = ("mollified impulse method (Garcia-Archilla, Sanz-Serna, Skeel 1999): kick with the "
               "force averaged by phi = sinc(h Omega), exact fast rotation, kick (order 2)")
    symplectic = True  # Verlet's splitting of H_fast + U(Phi q): a symplectic map
    long_runs = True  # one slow force a step, as Verlet
    filters = staticmethod(mollified_impulse_filters)
