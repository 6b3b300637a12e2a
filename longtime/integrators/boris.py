"""The Boris method (Boris 1970) for charged particles, x'' = x' x B(x) + E(x) (the
``lorentz`` capability), in the one-step form Hairer and Lubich analyse ("Energy behaviour
of the Boris method for charged-particle dynamics", BIT 58 (2018) 969-979, eqs. (1.2)-(1.4)):
the two-step scheme

    (x^{n+1} - 2 x^n + x^{n-1}) / h^2 = (x^{n+1} - x^{n-1}) / (2h) x B(x^n) + E(x^n)

with the velocities v^{n+1/2} = (x^{n+1} - x^n) / h and v^n = (v^{n+1/2} + v^{n-1/2}) / 2.
One step from (x^n, v^n), per particle:

    v^{n+1/2} = v^n + h/2 (v^n x B(x^n) + E(x^n))                     (explicit)
    x^{n+1}   = x^n + h v^{n+1/2}
    v^{n+1} - h/2 v^{n+1} x B(x^{n+1}) = v^{n+1/2} + h/2 E(x^{n+1})     (a 3 x 3 linear solve)

The solve has the closed form v = (r + r x t + (r.t) t) / (1 + |t|^2), t = h/2 B, r the
right side. Between the half-step velocities this is Boris's kick, Cayley rotation, kick,
which preserves phase-space volume in (x^n, v^{n-1/2}); in (x^n, v^n) the step's Jacobian
determinant is (1 + h^2 |B(x^n)|^2 / 4) / (1 + h^2 |B(x^{n+1})|^2 / 4), a quotient that
telescopes over a run (tests/test_boris.py measures both). Symmetric, order 2, one field
evaluation a step (the fields at x^{n+1} are the next step's first), not symplectic.
"""
from __future__ import annotations

import numba

from longtime.core.drivers import OK, RHS_EVALS
from longtime.core.stepping import FixedStepIntegrator

# rows of ``work``: B and E at the current positions (valid unless the run just started)
B_ROW, E_ROW = 0, 1


@numba.njit(inline="always")
def half_kick(u, n3, k, h, work):
    """v_k += h/2 (v_k x B + E), B and E of particle k in work: the explicit half step."""
    b0, b1, b2 = work[B_ROW, 3 * k], work[B_ROW, 3 * k + 1], work[B_ROW, 3 * k + 2]
    i = n3 + 3 * k
    v0, v1, v2 = u[i], u[i + 1], u[i + 2]
    u[i] = v0 + 0.5 * h * (v1 * b2 - v2 * b1 + work[E_ROW, 3 * k])
    u[i + 1] = v1 + 0.5 * h * (v2 * b0 - v0 * b2 + work[E_ROW, 3 * k + 1])
    u[i + 2] = v2 + 0.5 * h * (v0 * b1 - v1 * b0 + work[E_ROW, 3 * k + 2])


@numba.njit(inline="always")
def implicit_half_kick(u, n3, k, h, work):
    """Solve v - h/2 v x B = v_k + h/2 E for v (B, E of particle k in work), into v_k."""
    t0, t1, t2 = 0.5 * h * work[B_ROW, 3 * k], 0.5 * h * work[B_ROW, 3 * k + 1], 0.5 * h * work[B_ROW, 3 * k + 2]
    i = n3 + 3 * k
    r0 = u[i] + 0.5 * h * work[E_ROW, 3 * k]
    r1 = u[i + 1] + 0.5 * h * work[E_ROW, 3 * k + 1]
    r2 = u[i + 2] + 0.5 * h * work[E_ROW, 3 * k + 2]
    rt = r0 * t0 + r1 * t1 + r2 * t2
    scale = 1.0 / (1.0 + t0 * t0 + t1 * t1 + t2 * t2)
    u[i] = (r0 + (r1 * t2 - r2 * t1) + rt * t0) * scale
    u[i + 1] = (r1 + (r2 * t0 - r0 * t2) + rt * t1) * scale
    u[i + 2] = (r2 + (r0 * t1 - r1 * t0) + rt * t2) * scale


class Boris(FixedStepIntegrator):
    name = "boris"
    summary = ("Boris's method for x'' = v x B(x) + E(x): half kick, drift, implicit half kick "
               "(order 2, volume-preserving, 1970)")
    requires = frozenset({"lorentz"})
    order = 2
    symplectic = False
    long_runs = True  # one field evaluation a step: paper-scale final times in the matrix
    needs = "a state (x, v) of particles in space (dimension a multiple of 6)"

    def incompatibility(self, problem):
        reason = super().incompatibility(problem)
        if reason is None and problem.dim % 6:
            return (f"{self.name} needs a state (x, v) of particles in space (dimension a multiple of 6); "
                    f"{problem.name} has dimension {problem.dim}")
        return reason

    def work_shape(self, problem):
        return (2, problem.dim // 2)  # B and E at each particle's position

    def make_step(self, problem):
        field_B, field_E = problem.field_B, problem.field_E

        @numba.njit
        def step(t, u, h, params, work, counters, first):
            n3 = u.size // 2
            particles = n3 // 3
            evals = 0
            if first:  # otherwise work holds the fields at x^n from the last step's end
                for k in range(particles):
                    field_B(u[3 * k:3 * k + 3], params, work[B_ROW, 3 * k:3 * k + 3])
                    field_E(u[3 * k:3 * k + 3], params, work[E_ROW, 3 * k:3 * k + 3])
                evals += 1
            for k in range(particles):
                half_kick(u, n3, k, h, work)
            for i in range(n3):
                u[i] += h * u[n3 + i]
            for k in range(particles):
                field_B(u[3 * k:3 * k + 3], params, work[B_ROW, 3 * k:3 * k + 3])
                field_E(u[3 * k:3 * k + 3], params, work[E_ROW, 3 * k:3 * k + 3])
            evals += 1
            for k in range(particles):
                implicit_half_kick(u, n3, k, h, work)
            counters[RHS_EVALS] += evals
            return OK

        return step
