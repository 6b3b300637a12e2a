"""Discrete Dirac integrators for constrained mechanics (docs/schemes.md).

For L(q, v) = v^T M v / 2 - U(q) with holonomic constraints phi(q) = 0, constraint 1-forms
alpha^a = d phi^a and G(q) the rows grad phi^a(q), a step reads

    p_{n+1} = M v_n,   p_n - M v_n - dt grad U(q_n) = G(q_d)^T lambda,   G(q_d) v_n = 0,

with v_n = (q_{n+1} - q_n)/dt (dirac-1), v_n = (q_{n+1} - q_{n-1})/(2 dt) (dirac-2, a
two-step scheme started by one dirac-1 step), and q_d = q_n for both: the step is then
linear, M v_n is the M-orthogonal projection of p_n - dt grad U(q_n) onto ker G(q_n), one
m x m solve. ``dirac-midpoint`` evaluates the discrete 1-form at the midpoint
q_d = (q_n + q_{n+1})/2: for quadratic phi, phi(q_{n+1}) - phi(q_n) = dt G(q_d) v_n
exactly, so the constraints hold to round-off; the step is a nonlinear solve (fixed-point
iteration on q_d, each sweep one projection; contraction factor O(dt |v| |phi''|), sweeps
counted in ``nl_iters``).

State u = (q, p), p = M v (the problem's ``constraints`` contract, see
longtime/problems/double_pendulum.py). Counters: ``rhs_evals`` counts force (grad U)
evaluations, ``jac_evals`` evaluations of G.

The m x m systems (m = 2 for the double pendulum) are solved by a hand-written Gaussian
elimination with partial pivoting on scratch rows: numba's np.linalg.solve allocates its
result and a copy of the matrix on every call and goes through LAPACK, which costs more
than the whole step at this size.
"""
from __future__ import annotations

import numba
import numpy as np

from longtime.core.drivers import (
    FAILED,
    JAC_EVALS,
    NL_ITERS,
    OK,
    RHS_EVALS,
    reached_round_off,
    state_scale,
    track_increment,
)
from longtime.core.params import InputError, Param
from longtime.core.problem import Problem
from longtime.core.stepping import FixedStepIntegrator


@numba.njit(cache=True)
def solve_small(A, b, m):
    """Solve A[:m, :m] x = b[:m] in place (x in b, A overwritten): partial pivoting."""
    for k in range(m):
        piv = k
        big = abs(A[k, k])
        for i in range(k + 1, m):
            if abs(A[i, k]) > big:
                big = abs(A[i, k])
                piv = i
        if big == 0.0:
            return False
        if piv != k:
            for j in range(m):
                A[k, j], A[piv, j] = A[piv, j], A[k, j]
            b[k], b[piv] = b[piv], b[k]
        for i in range(k + 1, m):
            f = A[i, k] / A[k, k]
            for j in range(k, m):
                A[i, j] -= f * A[k, j]
            b[i] -= f * b[k]
    for k in range(m - 1, -1, -1):
        acc = b[k]
        for j in range(k + 1, m):
            acc -= A[k, j] * b[j]
        b[k] = acc / A[k, k]
    return True


@numba.njit(cache=True, inline="always")
def constraint_gram(G1, minv, G0, A, m, n):
    """A = G1 M^{-1} G0^T (m x m), with M diagonal: the matrix of every multiplier solve."""
    for a in range(m):
        for b in range(m):
            acc = 0.0
            for i in range(n):
                acc += G1[a, i] * minv[i] * G0[b, i]
            A[a, b] = acc


@numba.njit(cache=True)
def project_velocity(G, minv, w, A, lam, m, n):
    """w <- w - M^{-1} G^T lam with G w = 0 afterwards (M-orthogonal projection onto ker G).

    Solves (G M^{-1} G^T) lam = G w; returns False on a singular G M^{-1} G^T.
    """
    for a in range(m):
        acc = 0.0
        for i in range(n):
            acc += G[a, i] * w[i]
        lam[a] = acc
    constraint_gram(G, minv, G, A, m, n)
    if not solve_small(A, lam, m):
        return False
    for i in range(n):
        acc = 0.0
        for a in range(m):
            acc += G[a, i] * lam[a]
        w[i] -= minv[i] * acc
    return True


class ConstrainedIntegrator(FixedStepIntegrator):
    """Base of the schemes that read a problem's ``constraints`` (state u = (q, p), p = M v).

    Scratch: a (2 m + 7, n) array; rows 0..m-1 hold G, then the named rows of ``rows``
    (grad U, M^{-1}, the velocity w, q_{n-1} for dirac-2 -- the midpoint for
    dirac-midpoint, the multipliers for rattle --, a spare row, the multipliers, scalars);
    the m x m matrix lives in the first m columns of rows A..A+m-1.
    """

    requires = frozenset({"constraints"})
    # max |phi| and max |G v| of the initial state above this (relative to the scales
    # |q|^2 and |q| |v|) is an inconsistent start
    consistency_tol = 1e-8

    @staticmethod
    def sizes(problem: Problem) -> tuple[int, int]:
        m = int(problem.constraints.n_constraints)
        n = problem.dim // 2
        if problem.dim != 2 * n or not 0 < m < n:
            raise InputError(f"problem '{problem.name}': the constraints contract needs a state "
                             f"(q, p) of even size and 0 < m < n, got dim={problem.dim}, m={m}")
        return m, n

    @staticmethod
    def rows(m: int) -> dict[str, int]:
        names = ("gradU", "minv", "w", "qprev", "tmp", "lam", "scal")
        out = {k: m + i for i, k in enumerate(names)}
        out["A"] = m + len(names)
        return out

    def work_shape(self, problem):
        m, n = self.sizes(problem)
        return (m + 7 + m, n)

    def check_consistent(self, problem: Problem) -> None:
        """An InputError when the initial state is off the constraint manifold."""
        c = problem.constraints
        m, n = self.sizes(problem)
        q, p = problem.u0[:n].copy(), problem.u0[n:].copy()
        phi, G, mass = np.zeros(m), np.zeros((m, n)), np.zeros(n)
        c.phi(q, problem.params, phi)
        c.grad_phi(q, problem.params, G)
        c.mass(problem.params, mass)
        if np.any(mass <= 0):
            raise InputError(f"problem '{problem.name}': the mass matrix must be positive, got {mass}")
        v = p / mass
        qs = max(1.0, float(np.max(np.abs(q))))
        vs = max(1.0, float(np.max(np.abs(v))))
        err_phi, err_gv = float(np.max(np.abs(phi))), float(np.max(np.abs(G @ v)))
        if err_phi > self.consistency_tol * qs * qs or err_gv > self.consistency_tol * qs * vs:
            hint = " (problem.project(u) gives the nearest consistent state)" if hasattr(problem, "project") else ""
            raise InputError(f"initial state of problem '{problem.name}' violates its constraints: "
                             f"max|phi| = {err_phi:.3g}, max|G v| = {err_gv:.3g}; {self.name} needs a "
                             f"consistent start{hint}")

    def _integrate(self, problem, t_final, max_samples):
        self.check_consistent(problem)
        return super()._integrate(problem, t_final, max_samples)


def _dirac_kernels(problem: Problem, two_step: bool, midpoint: bool, max_iter: int):
    """Compiled step of dirac-1 / dirac-2 / dirac-midpoint, closed over the problem's constraints."""
    c = problem.constraints
    phi_grad, mass, grad_U = c.grad_phi, c.mass, c.grad_U
    m, n = ConstrainedIntegrator.sizes(problem)
    R = ConstrainedIntegrator.rows(m)
    r_gu, r_minv, r_w, r_qprev, r_tmp, r_lam, r_scal, r_A = (
        R["gradU"], R["minv"], R["w"], R["qprev"], R["tmp"], R["lam"], R["scal"], R["A"])

    @numba.njit(inline="always")
    def dirac1_velocity(q, p, h, params, work, counters):
        """work[w] <- v_n = projection of M^{-1}(p_n - h grad U(q_n)) onto ker G(q_n)."""
        G = work[0:m]
        minv, w, gu = work[r_minv], work[r_w], work[r_gu]
        grad_U(q, params, gu)
        phi_grad(q, params, G)
        counters[RHS_EVALS] += 1
        counters[JAC_EVALS] += 1
        for i in range(n):
            w[i] = minv[i] * (p[i] - h * gu[i])
        return project_velocity(G, minv, w, work[r_A:r_A + m], work[r_lam], m, n)

    @numba.njit
    def step(t, u, h, params, work, counters, first):
        q, p = u[:n], u[n:]
        minv, w, qprev, scal = work[r_minv], work[r_w], work[r_qprev], work[r_scal]
        if first:
            mass(params, minv)
            for i in range(n):
                minv[i] = 1.0 / minv[i]
        if not dirac1_velocity(q, p, h, params, work, counters):
            return FAILED
        if midpoint:
            # fixed point on the midpoint 1-form: G((q_n + q_{n+1})/2) v_n = 0
            G, qd, wold, gu = work[0:m], work[r_qprev], work[r_tmp], work[r_gu]
            scale = state_scale(q)
            converged = False
            best, stale = np.inf, 0
            for it in range(max_iter):
                for i in range(n):
                    qd[i] = q[i] + 0.5 * h * w[i]
                    wold[i] = w[i]
                    w[i] = minv[i] * (p[i] - h * gu[i])
                phi_grad(qd, params, G)
                counters[JAC_EVALS] += 1
                counters[NL_ITERS] += 1
                if not project_velocity(G, minv, w, work[r_A:r_A + m], work[r_lam], m, n):
                    return FAILED
                delta = 0.0
                for i in range(n):
                    delta = max(delta, abs(h * (w[i] - wold[i])))
                best, stale = track_increment(delta, best, stale)
                if reached_round_off(delta, best, stale, scale):
                    converged = True
                    break
            if not converged:
                return FAILED
        if two_step:
            # central difference, q_{n+1} = q_{n-1} + 2 h v_n; restart with a dirac-1 step
            # when the step size changes (first step, or a clipped last step)
            central = (not first) and abs(h - scal[0]) <= 1e-9 * h
            for i in range(n):
                qn = q[i]
                q[i] = (qprev[i] + 2.0 * h * w[i]) if central else (qn + h * w[i])
                qprev[i] = qn
            scal[0] = h
        else:
            for i in range(n):
                q[i] += h * w[i]
        for i in range(n):
            p[i] = w[i] / minv[i]
        return OK

    return step


class Dirac1(ConstrainedIntegrator):
    name = "dirac-1"
    summary = "discrete Dirac integrator, one-step (v_n forward difference; linear m x m solve)"
    order = 1

    def make_step(self, problem):
        return _dirac_kernels(problem, two_step=False, midpoint=False, max_iter=1)


class Dirac2(ConstrainedIntegrator):
    name = "dirac-2"
    summary = "discrete Dirac integrator, two-step (v_n central difference), started by dirac-1"
    order = 1

    def make_step(self, problem):
        return _dirac_kernels(problem, two_step=True, midpoint=False, max_iter=1)


class DiracMidpoint(ConstrainedIntegrator):
    name = "dirac-midpoint"
    summary = "dirac-1 with the constraint 1-form at the midpoint: keeps quadratic constraints exactly"
    order = 1
    parameters = {
        **ConstrainedIntegrator.parameters,
        "max_iter": Param(50, "fixed-point sweeps allowed per step", int, positive=True, maximum=10**6),
    }

    def make_step(self, problem):
        return _dirac_kernels(problem, two_step=False, midpoint=True, max_iter=int(self.settings["max_iter"]))
