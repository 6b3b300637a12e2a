"""Implicit Runge-Kutta schemes (tableaus) with stages solved to round-off.

The stage equations K_i = f(t + c_i h, u + h sum_j a_ij K_j) are solved by fixed-point
iteration with Gauss-Seidel sweeps (for a diagonally implicit tableau such as rk4sym this
solves the stages one after another). Iteration stops when the increment vanishes, reaches
round-off, or stops decreasing at round-off level (``drivers.stalled``: no new smallest
increment for a few sweeps, so a non-monotone convergence is not taken for a stall); the
sweeps are counted in ``nl_iters``.
A solve that does not converge in ``max_iter`` sweeps fails the step (status ``failed``).

For round-off studies (Brouwer's law), ``stop=brouwer`` is the stopping rule of Hairer,
McLachlan and Razakarivony (BIT 2008): sweep until the increment is exactly 0 or stops
decreasing (``drivers.stalled``), never stop on a tolerance; ``compensated=true`` sums the update u + h sum b_i K_i
with Kahan's compensation. Both are opt-in settings: the default is the published scheme.
"""
from __future__ import annotations

import numba
import numpy as np

from longtime.core.drivers import (
    FAILED,
    NL_ITERS,
    OK,
    RHS_EVALS,
    copy_into,
    reached_round_off,
    stalled,
    state_scale,
    track_increment,
)
from longtime.core.params import Param
from longtime.core.stepping import COMPENSATED, FixedStepIntegrator
from longtime.integrators.tableau import add_weighted_slopes, checked_on_definition


@numba.njit(cache=True, inline="always")
def settled(delta, best, stale, scale):
    """The stopping rule that does not bias the increments (Hairer, McLachlan, Razakarivony
    2008): the increment is exactly 0, or the increments have stopped decreasing
    (drivers.stalled: only round-off is left; its STALL_LEVEL guard keeps a stalled,
    unconverged iteration from counting). Stopping on a tolerance instead leaves an
    iteration error of the same sign step after step, which adds up to a linear drift of
    the invariants."""
    return delta == 0.0 or stalled(best, stale, scale)


@numba.njit(cache=True, inline="always")
def iteration_done(delta, best, stale, scale, brouwer):
    """The fixed-point iteration's stopping rule of the ``stop`` setting, after
    drivers.track_increment: Brouwer's (``settled``) or round-off's (drivers.reached_round_off)."""
    return settled(delta, best, stale, scale) if brouwer else reached_round_off(delta, best, stale, scale)


@numba.njit(cache=True, inline="always")
def sweep_done(delta, best, stale, scale, brouwer, counters):
    """The tail of a fixed-point sweep (the stages here, avf's averaged slope): the sweep
    counted in ``nl_iters``, its increment ``delta`` tracked (drivers.track_increment) and the
    ``stop`` setting's rule applied (``iteration_done``). Returns (done, best, stale)."""
    counters[NL_ITERS] += 1
    best, stale = track_increment(delta, best, stale)
    return iteration_done(delta, best, stale, scale, brouwer), best, stale


@numba.njit(cache=True, inline="always")
def sweeps_status(done, evals, counters):
    """The end of a step's fixed-point sweeps (the stages here, avf's averaged slope): its
    ``evals`` right-hand side evaluations counted; OK where the last sweep ended the
    iteration (``done``: ``sweep_done``), else FAILED (the step is not taken)."""
    counters[RHS_EVALS] += evals
    return OK if done else FAILED


class ImplicitRungeKutta(FixedStepIntegrator):
    A: np.ndarray
    b: np.ndarray
    c: np.ndarray
    step_cost = 10.0  # the stages' fixed-point sweeps: about ten RK4 steps' work (the budget's estimate)
    parameters = {
        **FixedStepIntegrator.parameters,
        "max_iter": Param(100, "fixed-point sweeps allowed per step", int, positive=True, maximum=10**6),
        "stop": Param("round-off", "stopping rule of the stage iteration: round-off (increment at "
                      "machine precision or stalled) or brouwer (exactly 0 or stalled, no tolerance)",
                      str, choices=("round-off", "brouwer")),
        "compensated": COMPENSATED,
    }

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        checked_on_definition(cls, explicit=False)  # a broken tableau fails at import

    def work_shape(self, problem):
        return (len(self.b) + 3, problem.dim)  # stage slopes K, stage state, new slope, compensation

    def make_step(self, problem):
        rhs = problem.rhs
        A, b, c = (np.ascontiguousarray(x, dtype=np.float64) for x in (self.A, self.b, self.c))
        s = b.size
        max_iter = int(self.settings["max_iter"])
        brouwer = self.settings["stop"] == "brouwer"
        compensated = bool(self.settings["compensated"])

        @numba.njit
        def step(t, u, h, params, work, counters, first):
            n = u.size
            y, k_new = work[s], work[s + 1]
            scale = state_scale(u)
            rhs(t, u, params, work[0])
            for i in range(1, s):
                copy_into(work[i], work[0])
            evals = 1
            done, best, stale = False, np.inf, 0
            for sweep in range(max_iter):
                delta = 0.0
                for i in range(s):
                    for m in range(n):
                        acc = 0.0
                        for j in range(s):
                            acc += A[i, j] * work[j, m]
                        y[m] = u[m] + h * acc
                    rhs(t + c[i] * h, y, params, k_new)
                    for m in range(n):
                        delta = max(delta, abs(h * (k_new[m] - work[i, m])))
                        work[i, m] = k_new[m]
                evals += s
                done, best, stale = sweep_done(delta, best, stale, scale, brouwer, counters)
                if done:
                    break
            if sweeps_status(done, evals, counters) != OK:
                return FAILED
            add_weighted_slopes(u, h, b, work, compensated, work[s + 2])
            return OK

        return step


class Midpoint(ImplicitRungeKutta):
    name = "midpoint"
    summary = "implicit midpoint (order 2, symplectic)"
    order = 2
    symplectic = True
    A = np.array([[0.5]])
    b = np.array([1.0])
    c = np.array([0.5])


_B = (2 + 2 ** (1 / 3) + 2 ** (-1 / 3)) / 3  # 1.3512071919596578 (the paper prints 2^(1/2): docs/paper.md)


class RK4Sym(ImplicitRungeKutta):
    name = "rk4sym"
    summary = "3-stage symplectic DIRK of order 4: midpoint steps b h, (1-2b) h, b h"
    order = 4
    symplectic = True
    A = np.array([[_B / 2, 0, 0], [_B, 0.5 - _B, 0], [_B, 1 - 2 * _B, _B / 2]])
    b = np.array([_B, 1 - 2 * _B, _B])
    c = A.sum(axis=1)


_S3, _S15 = np.sqrt(3.0), np.sqrt(15.0)


class Gauss4(ImplicitRungeKutta):
    name = "gauss4"
    summary = "2-stage Gauss-Legendre collocation (order 4, symplectic)"
    order = 4
    symplectic = True
    A = np.array([[0.25, 0.25 - _S3 / 6], [0.25 + _S3 / 6, 0.25]])
    b = np.array([0.5, 0.5])
    c = np.array([0.5 - _S3 / 6, 0.5 + _S3 / 6])


class Gauss6(ImplicitRungeKutta):
    name = "gauss6"
    summary = "3-stage Gauss-Legendre collocation (order 6, symplectic)"
    order = 6
    symplectic = True
    A = np.array([
        [5 / 36, 2 / 9 - _S15 / 15, 5 / 36 - _S15 / 30],
        [5 / 36 + _S15 / 24, 2 / 9, 5 / 36 - _S15 / 24],
        [5 / 36 + _S15 / 30, 2 / 9 + _S15 / 15, 5 / 36],
    ])
    b = np.array([5 / 18, 4 / 9, 5 / 18])
    c = np.array([0.5 - _S15 / 10, 0.5, 0.5 + _S15 / 10])
