"""Explicit symplectic splitting schemes for separable H = T(p) + V(q).

A scheme is a sequence of (kick, drift) coefficient pairs: kick p -= b_i h grad V(q), then
drift q += a_i h grad T(p). Compositions (Yoshida) are built as loops over coefficient
arrays, with adjacent kicks merged. grad V is evaluated only when q has moved since the
last evaluation, so velocity Verlet costs one force per step (first same as last).
"""
from __future__ import annotations

import numba
import numpy as np

from ..drivers import OK, RHS_EVALS, compensated_add
from ..contract import check_splitting
from ..integrator import COMPENSATED, FixedStepIntegrator


def compose(gammas) -> tuple[np.ndarray, np.ndarray]:
    """(kick, drift) coefficients of Verlet steps of sizes gamma_k h, adjacent kicks merged."""
    kicks, drifts = [], []
    for g in gammas:
        if kicks and drifts[-1] == 0.0:
            kicks[-1] += g / 2
        else:
            kicks.append(g / 2)
            drifts.append(0.0)
        drifts[-1] = g
        kicks.append(g / 2)
        drifts.append(0.0)
    return np.array(kicks), np.array(drifts)


class Splitting(FixedStepIntegrator):
    requires = frozenset({"separable"})
    symplectic = True
    kicks: np.ndarray
    drifts: np.ndarray
    parameters = {**FixedStepIntegrator.parameters, "compensated": COMPENSATED}
    long_runs = True  # a few forces a step: paper-scale final times in the matrix

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        check_splitting(cls)  # inconsistent coefficients fail at import

    def work_shape(self, problem):
        # force, velocity, diag(M^-1) when T is quadratic, compensation of q and of p
        return (5, problem.dim // 2)

    def prepare_work(self, problem, work):
        inverse = problem.inverse_masses()
        if inverse is not None:
            work[2] = inverse

    def make_step(self, problem):
        grad_T, grad_V = problem.grad_T, problem.grad_V
        kicks = np.ascontiguousarray(self.kicks, dtype=np.float64)
        drifts = np.ascontiguousarray(self.drifts, dtype=np.float64)
        stages = kicks.size
        # the step ends on a force evaluated at the final q, valid at the next step's start
        last = max(i for i in range(stages) if kicks[i] != 0 or drifts[i] != 0)
        ends_fresh = drifts[last] == 0.0
        # T = p.M^-1 p / 2: drift with the stored diag(M^-1), no call to grad_T
        quadratic = problem.inverse_masses() is not None
        compensated = bool(self.settings["compensated"])  # every kick and drift, when set

        @numba.njit
        def step(t, u, h, params, work, counters, first):
            # index u and work directly: a view per array per step costs reference counting
            n = u.size // 2
            fresh = ends_fresh and not first
            evals = 0
            for i in range(stages):
                if kicks[i] != 0.0:
                    if not fresh:
                        grad_V(u[:n], params, work[0])
                        evals += 1
                        fresh = True
                    for m in range(n):
                        if compensated:
                            compensated_add(u, n + m, -(kicks[i] * h * work[0, m]), work[4], m)
                        else:
                            u[n + m] -= kicks[i] * h * work[0, m]
                if drifts[i] != 0.0:
                    if quadratic:
                        for m in range(n):
                            if compensated:
                                compensated_add(u, m, drifts[i] * h * work[2, m] * u[n + m], work[3], m)
                            else:
                                u[m] += drifts[i] * h * work[2, m] * u[n + m]
                    else:
                        grad_T(u[n:], params, work[1])
                        for m in range(n):
                            if compensated:
                                compensated_add(u, m, drifts[i] * h * work[1, m], work[3], m)
                            else:
                                u[m] += drifts[i] * h * work[1, m]
                    fresh = False
            counters[RHS_EVALS] += evals
            return OK

        return step


class SymplecticEuler(Splitting):
    name = "symplectic-euler"
    summary = "symplectic Euler A: p_{n+1} from (q_n, p_{n+1}), then q (order 1)"
    order = 1
    kicks, drifts = np.array([1.0]), np.array([1.0])


class SymplecticEulerB(Splitting):
    name = "symplectic-euler-b"
    summary = "symplectic Euler B, the adjoint: q first from (q_{n+1}, p_n), then p (order 1)"
    order = 1
    kicks, drifts = np.array([0.0, 1.0]), np.array([1.0, 0.0])


class Verlet(Splitting):
    name = "verlet"
    summary = "Stormer-Verlet, velocity form: kick h/2, drift h, kick h/2 (order 2)"
    order = 2
    kicks, drifts = compose([1.0])


def _yoshida(w):
    """Yoshida's symmetric product S(w_m)...S(w_1) S(w_0) S(w_1)...S(w_m), w_0 = 1 - 2 sum w."""
    w = list(w)
    w0 = 1.0 - 2.0 * sum(w)
    return compose(w[::-1] + [w0] + w)


class Yoshida6(Splitting):
    name = "yoshida6"
    summary = "Yoshida's order-6 composition of 7 Verlet steps (solution A, 1990)"
    order = 6
    kicks, drifts = _yoshida([-1.17767998417887, 0.235573213359357, 0.784513610477560])


class Yoshida8(Splitting):
    name = "yoshida8"
    summary = "Yoshida's order-8 composition of 15 Verlet steps (solution D, 1990)"
    order = 8
    kicks, drifts = _yoshida([0.102799849391985, -1.96061023297549, 1.93813913762276,
                              -0.158240635368243, -1.44485223686048, 0.253693336566229,
                              0.914844246229740])
