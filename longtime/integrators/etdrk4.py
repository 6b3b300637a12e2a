"""ETDRK4: exponential time differencing Runge-Kutta 4 (Cox and Matthews, J. Comput. Phys.
2002) with the phi-function coefficients of Kassam and Trefethen (SIAM J. Sci. Comput. 2005).

For u' = L u + N(t, u) with L diagonal:
    a = E2 u + Q N(u),   b = E2 u + Q N(a),   c = E2 a + Q (2 N(b) - N(u)),
    u+ = E u + f1 N(u) + 2 f2 (N(a) + N(b)) + f3 N(c),
E = e^{hL}, E2 = e^{hL/2}, Q = h (e^{z/2} - 1)/z, and with z = hL
    f1 = h (-4 - z + e^z (4 - 3z + z^2)) / z^3,  f2 = h (2 + z + e^z (z - 2)) / z^3,
    f3 = h (-4 - 3z - z^2 + e^z (4 - z)) / z^3.
These cancel catastrophically for small |z| and are 0/0 at z = 0, so each is evaluated as
the mean over 64 points of the circle of radius 1 about z (Cauchy's formula, trapezoid rule:
geometric convergence); at L = 0 they reduce to the RK4 weights (Q = h/2, f1 = f3 = h/6,
f2 = h/6). KdV's L is imaginary (dispersion), so the whole circle is used, not the
half circle of the real (dissipative) case.

Capability contract ("linear_part", provided by a problem as compiled functions):
    linear_part(params, out)    out (length dim) receives the diagonal of L in the complex
                                view of the state, z_k = u[2k] + i u[2k+1], as (Re, Im)
                                pairs (a real diagonal entry acting on two real components
                                is the pair (lambda, 0)); dim is even.
    nonlinear(t, u, params, out)    out = N(t, u), with u' = L u + N(t, u) = rhs.
The coefficients are computed in the compiled step when h differs from the step they were
computed for (the first step, and a clipped last step): a fixed-step run computes them at
most twice. One nonlinear evaluation is counted as one rhs evaluation (4 per step).
"""
from __future__ import annotations

import cmath

import numba

from longtime.core.contract import pairs_incompatibility
from longtime.core.drivers import OK, RHS_EVALS
from longtime.core.stepping import FixedStepIntegrator

CONTOUR_POINTS = 64
# rows of the work array (each of length dim, complex quantities as (Re, Im) pairs)
E, E2, Q, F1, F2, F3, LAM, NU, NA, NB, NC, A, B, C, META = range(15)


@numba.njit(cache=True)
def _phi_coefficients(h, work):
    """E, E2, Q, f1, f2, f3 for step h from the diagonal in work[LAM] (contour means)."""
    lam = work[LAM]
    for k in range(lam.size // 2):
        z = h * complex(lam[2 * k], lam[2 * k + 1])
        sq = s1 = s2 = s3 = 0j
        for j in range(CONTOUR_POINTS):
            zz = z + cmath.exp(2j * cmath.pi * (j + 0.5) / CONTOUR_POINTS)
            ez = cmath.exp(zz)
            zz2 = zz * zz
            zz3 = zz2 * zz
            sq += (cmath.exp(0.5 * zz) - 1.0) / zz
            s1 += (-4.0 - zz + ez * (4.0 - 3.0 * zz + zz2)) / zz3
            s2 += (2.0 + zz + ez * (zz - 2.0)) / zz3
            s3 += (-4.0 - 3.0 * zz - zz2 + ez * (4.0 - zz)) / zz3
        real = lam[2 * k + 1] == 0.0  # a real z: the symmetric contour's mean is real
        for row, value in ((E, cmath.exp(z)), (E2, cmath.exp(0.5 * z)),
                           (Q, h * sq / CONTOUR_POINTS), (F1, h * s1 / CONTOUR_POINTS),
                           (F2, h * s2 / CONTOUR_POINTS), (F3, h * s3 / CONTOUR_POINTS)):
            work[row, 2 * k] = value.real
            work[row, 2 * k + 1] = 0.0 if real else value.imag


class ETDRK4(FixedStepIntegrator):
    name = "etdrk4"
    summary = "exponential time differencing RK4 (Cox-Matthews), Kassam-Trefethen contour coefficients"
    requires = frozenset({"linear_part"})
    order = 4

    def incompatibility(self, problem):
        return super().incompatibility(problem) or pairs_incompatibility(self.name, problem)

    def work_shape(self, problem):
        return (META + 1, problem.dim)

    def make_step(self, problem):
        nonlinear, linear_part = problem.nonlinear, problem.linear_part

        @numba.njit
        def step(t, u, h, params, work, counters, first):
            n = u.size
            if work[META, 0] != h:
                linear_part(params, work[LAM])
                _phi_coefficients(h, work)
                work[META, 0] = h
            e, e2, q = work[E], work[E2], work[Q]
            f1, f2, f3 = work[F1], work[F2], work[F3]
            nu, na, nb, nc = work[NU], work[NA], work[NB], work[NC]
            a, b, c = work[A], work[B], work[C]
            nonlinear(t, u, params, nu)
            for i in range(0, n, 2):  # a = E2 u + Q N(u)
                a[i] = e2[i] * u[i] - e2[i + 1] * u[i + 1] + q[i] * nu[i] - q[i + 1] * nu[i + 1]
                a[i + 1] = e2[i] * u[i + 1] + e2[i + 1] * u[i] + q[i] * nu[i + 1] + q[i + 1] * nu[i]
            nonlinear(t + 0.5 * h, a, params, na)
            for i in range(0, n, 2):  # b = E2 u + Q N(a)
                b[i] = e2[i] * u[i] - e2[i + 1] * u[i + 1] + q[i] * na[i] - q[i + 1] * na[i + 1]
                b[i + 1] = e2[i] * u[i + 1] + e2[i + 1] * u[i] + q[i] * na[i + 1] + q[i + 1] * na[i]
            nonlinear(t + 0.5 * h, b, params, nb)
            for i in range(0, n, 2):  # c = E2 a + Q (2 N(b) - N(u))
                gr, gi = 2.0 * nb[i] - nu[i], 2.0 * nb[i + 1] - nu[i + 1]
                c[i] = e2[i] * a[i] - e2[i + 1] * a[i + 1] + q[i] * gr - q[i + 1] * gi
                c[i + 1] = e2[i] * a[i + 1] + e2[i + 1] * a[i] + q[i] * gi + q[i + 1] * gr
            nonlinear(t + h, c, params, nc)
            for i in range(0, n, 2):
                sr, si = 2.0 * (na[i] + nb[i]), 2.0 * (na[i + 1] + nb[i + 1])
                ur = (e[i] * u[i] - e[i + 1] * u[i + 1]
                      + f1[i] * nu[i] - f1[i + 1] * nu[i + 1]
                      + f2[i] * sr - f2[i + 1] * si
                      + f3[i] * nc[i] - f3[i + 1] * nc[i + 1])
                ui = (e[i] * u[i + 1] + e[i + 1] * u[i]
                      + f1[i] * nu[i + 1] + f1[i + 1] * nu[i]
                      + f2[i] * si + f2[i + 1] * sr
                      + f3[i] * nc[i + 1] + f3[i + 1] * nc[i])
                u[i], u[i + 1] = ur, ui
            counters[RHS_EVALS] += 4
            return OK

        return step
