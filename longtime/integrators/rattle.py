"""RATTLE: the standard symplectic, second-order scheme for holonomic constraints.

State u = (q, p), p = M v (the problem's ``constraints`` contract). One step of size h:

    p_half  = p_n - h/2 (grad U(q_n) + G(q_n)^T lambda)
    q_{n+1} = q_n + h M^{-1} p_half,          phi(q_{n+1}) = 0        (SHAKE)
    p_{n+1} = p_half - h/2 (grad U(q_{n+1}) + G(q_{n+1})^T mu),  G(q_{n+1}) M^{-1} p_{n+1} = 0

The position multipliers solve phi(q_{n+1}(lambda)) = 0 by Newton's method with the exact
Jacobian -(h^2/2) G(q_{n+1}) M^{-1} G(q_n)^T, to round-off: until the residual is at
round-off level or the Newton corrections stop shrinking at round-off (residual
evaluations counted in ``nl_iters``; no convergence in ``max_iter`` fails the step).
The momentum multipliers are one M-orthogonal projection onto ker G(q_{n+1}) (a linear m x m solve).
grad U and G at q_{n+1} are kept for the next step (one force evaluation per step), and
the Newton iteration starts from the previous step's multipliers.
"""
from __future__ import annotations

import numba
import numpy as np

from longtime.core.drivers import (
    EPS,
    FAILED,
    JAC_EVALS,
    NL_ITERS,
    OK,
    RHS_EVALS,
    reached_round_off,
    state_scale,
    track_increment,
)
from longtime.core.params import Param
from longtime.integrators.dirac import (
    ConstrainedIntegrator,
    constraint_gram,
    project_velocity,
    solve_small,
)


class Rattle(ConstrainedIntegrator):
    name = "rattle"
    summary = "RATTLE (SHAKE positions by Newton to round-off, velocity projection); symplectic"
    order = 2
    symplectic = True
    parameters = {
        **ConstrainedIntegrator.parameters,
        "max_iter": Param(50, "Newton iterations allowed per step", int, positive=True, maximum=10**6),
    }

    def work_shape(self, problem):
        m, n = self.sizes(problem)
        return (m + 7 + m + m + 1, n)  # the base rows, then G(q_{n+1}) and phi

    def make_step(self, problem):
        c = problem.constraints
        phi, grad_phi, mass, grad_U = c.phi, c.grad_phi, c.mass, c.grad_U
        m, n = self.sizes(problem)
        R = self.rows(m)
        r_gu, r_minv, r_w, r_qprev, r_tmp, r_lam, r_scal, r_A = (
            R["gradU"], R["minv"], R["w"], R["qprev"], R["tmp"], R["lam"], R["scal"], R["A"])
        r_G1, r_phi = r_A + m, r_A + 2 * m
        max_iter = int(self.settings["max_iter"])

        @numba.njit
        def step(t, u, h, params, work, counters, first):
            q, p = u[:n], u[n:]
            G0, G1, A = work[0:m], work[r_G1:r_G1 + m], work[r_A:r_A + m]
            minv, gu, qtil, qnew = work[r_minv], work[r_gu], work[r_w], work[r_tmp]
            lam, res, scal = work[r_lam], work[r_phi], work[r_scal]
            if first:
                mass(params, minv)
                for i in range(n):
                    minv[i] = 1.0 / minv[i]
                grad_U(q, params, gu)
                grad_phi(q, params, G0)
                counters[RHS_EVALS] += 1
                counters[JAC_EVALS] += 1
            # Newton on Lambda (= h^2/2 lambda): phi(qtil - M^{-1} G0^T Lambda) = 0, started
            # from the previous step's Lambda (rescaled to h): one Newton step fewer
            Lam = work[r_qprev]
            ratio = (h / scal[0]) ** 2 if not first and scal[0] > 0 else 0.0
            scal[0] = h
            for a in range(m):
                Lam[a] *= ratio
            # unconstrained half kick and drift: qtil = q + h M^{-1} (p - h/2 grad U)
            for i in range(n):
                p[i] -= 0.5 * h * gu[i]
                qtil[i] = q[i] + h * minv[i] * p[i]
                acc = 0.0
                for a in range(m):
                    acc += G0[a, i] * Lam[a]
                qnew[i] = qtil[i] - minv[i] * acc
            scale = state_scale(q)
            converged = False
            best, stale = np.inf, 0
            for it in range(max_iter):
                phi(qnew, params, res)
                counters[NL_ITERS] += 1
                small = True
                for a in range(m):
                    small = small and abs(res[a]) <= 4.0 * EPS * scale * scale
                if small:  # residual at round-off: no Newton step needed
                    converged = True
                    break
                grad_phi(qnew, params, G1)
                counters[JAC_EVALS] += 1
                # J dLambda = phi with J = G1 M^{-1} G0^T (Newton: Lambda += dLambda)
                for a in range(m):
                    lam[a] = res[a]
                constraint_gram(G1, minv, G0, A, m, n)
                if not solve_small(A, lam, m):
                    return FAILED
                delta = 0.0
                for a in range(m):
                    Lam[a] += lam[a]
                for i in range(n):
                    acc = 0.0
                    for a in range(m):
                        acc += G0[a, i] * Lam[a]
                    new = qtil[i] - minv[i] * acc
                    delta = max(delta, abs(new - qnew[i]))
                    qnew[i] = new
                best, stale = track_increment(delta, best, stale)
                if reached_round_off(delta, best, stale, scale):
                    converged = True
                    break
            if not converged:
                return FAILED
            # p_half = p - h/2 grad U - G0^T Lambda / h; then q_{n+1}
            for i in range(n):
                acc = 0.0
                for a in range(m):
                    acc += G0[a, i] * Lam[a]
                p[i] -= acc / h
                q[i] = qnew[i]
            # second half kick and projection onto ker G(q_{n+1}); keep grad U, G for the next step
            grad_U(q, params, gu)
            grad_phi(q, params, G0)
            counters[RHS_EVALS] += 1
            counters[JAC_EVALS] += 1
            w = qtil  # reuse as scratch: the velocity
            for i in range(n):
                w[i] = minv[i] * (p[i] - 0.5 * h * gu[i])
            if not project_velocity(G0, minv, w, A, lam, m, n):
                return FAILED
            for i in range(n):
                p[i] = w[i] / minv[i]
            return OK

        return step
