"""Adaptive explicit Runge-Kutta schemes: embedded pairs as tableaus over one compiled stepper.

A scheme is a tableau (A, c), the weights b of the propagated solution and the error
weights e (err = h sum_i e_i k_i estimates the local error of that solution), the order q
of that error estimate's leading term (err ~ h^(q+1)) and whether the last stage is the
first stage of the next step (FSAL). The stepper (``embedded_try_step``) is shared.

Error norm (Hairer, Norsett and Wanner, I, II.4): ||err / (atol + rtol max(|u|, |u_new|))||
in the root-mean-square norm, with rtol = ``tol`` and atol = ``atol`` (default: tol); the
step is accepted when the norm is <= 1. Step control: "standard" h *= safety err^(-1/(q+1)),
or "pi", Gustafsson's PI controller as in Hairer's DOPRI5 (err^(-1/(q+1) + 0.75 beta)
err_prev^beta, beta = 0.04), which damps the accept/reject oscillation of a step limited
by stability, as on stiff problems (KdV). Growth is bounded by [0.2, 10] per step, and no
growth right after a rejection.
"""
from __future__ import annotations

import math

import numba
import numpy as np

from longtime.core.drivers import RHS_EVALS
from longtime.core.params import Param
from longtime.core.stepping import AdaptiveIntegrator
from longtime.integrators.tableau import checked_on_definition

SAFETY, FAC_MIN, FAC_MAX, PI_BETA = 0.9, 0.2, 10.0, 0.04
# meta row of the work array
M_RTOL, M_ATOL, M_K1_VALID, M_ERR_PREV, M_REJECTED, M_PI = range(6)
META_SIZE = 6
# the smallest relative tolerance taken: 10 x the unit round-off of double precision (2**-53),
# below which no step's error estimate can be met; Hairer and Wanner's RADAU5 refuses an
# rtol at or below the same floor ("tolerances are too small")
TOL_FLOOR = 10 * 2.0**-53
TOL_FLOOR_REASON = (f"below what double precision can meet (10 x its unit round-off, {TOL_FLOOR:.2g}; "
                    f"a smaller relative tolerance only ends in a step-size underflow)")


def embedded_try_step(rhs, A, b, e, c, q, fsal):
    """Compiled ``try_step`` for the tableau; work rows: k_0..k_{s-1}, stage state, meta."""
    A, b, e, c = (np.ascontiguousarray(x, dtype=np.float64) for x in (A, b, e, c))
    s = b.size
    expo = 1.0 / (q + 1.0)

    @numba.njit
    def try_step(t, u, h, params, work, counters, u_new):
        n = u.size
        meta = work[s + 1]
        y = work[s, :n]
        if meta[M_K1_VALID] == 0.0:
            rhs(t, u, params, work[0, :n])
            counters[RHS_EVALS] += 1
            meta[M_K1_VALID] = 1.0
        for i in range(1, s):
            for m in range(n):
                acc = 0.0
                for j in range(i):
                    if A[i, j] != 0.0:
                        acc += A[i, j] * work[j, m]
                y[m] = u[m] + h * acc
            rhs(t + c[i] * h, y, params, work[i, :n])
        counters[RHS_EVALS] += s - 1
        rtol, atol = meta[M_RTOL], meta[M_ATOL]
        total = 0.0
        for m in range(n):
            acc = 0.0
            err = 0.0
            for j in range(s):
                acc += b[j] * work[j, m]
                err += e[j] * work[j, m]
            un = u[m] + h * acc
            u_new[m] = un
            sc = atol + rtol * max(abs(u[m]), abs(un))
            r = h * err / sc
            total += r * r
        norm = math.sqrt(total / n)
        if not norm <= 1.0:  # rejected (a NaN norm too)
            fac = SAFETY * norm ** (-expo) if norm < 1e300 else FAC_MIN
            fac = min(1.0, max(FAC_MIN, fac)) if fac == fac else FAC_MIN
            meta[M_REJECTED] = 1.0
            return 0, h, h * fac
        if fsal:  # the last stage is f(t + h, u_new): the next step's first stage
            for m in range(n):
                u_new[m] = y[m]
                work[0, m] = work[s - 1, m]
        else:
            meta[M_K1_VALID] = 0.0
        norm = max(norm, 1e-10)
        if meta[M_PI] != 0.0:
            fac = SAFETY * norm ** (-expo + 0.75 * PI_BETA) * meta[M_ERR_PREV] ** PI_BETA
        else:
            fac = SAFETY * norm ** (-expo)
        fac = min(FAC_MAX, max(FAC_MIN, fac))
        if meta[M_REJECTED] != 0.0:
            fac = min(1.0, fac)
        meta[M_REJECTED] = 0.0
        meta[M_ERR_PREV] = max(norm, 1e-4)
        return 1, h, h * fac

    return try_step


class EmbeddedRungeKutta(AdaptiveIntegrator):
    A: np.ndarray
    b: np.ndarray
    e: np.ndarray
    c: np.ndarray
    error_order: int  # q: the error estimate is O(h^(q+1))
    fsal: bool = False
    default_controller = "pi"
    sweep = {"tol": (1e-4, 1e-6, 1e-8)}

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        checked_on_definition(cls, explicit=True, error_weights=True)  # a broken tableau fails at import

    @classmethod
    def _parameters(cls, controller):
        return {
            "tol": Param(1e-6, "relative tolerance rtol", float, positive=True, role="accuracy",
                         minimum=TOL_FLOOR, minimum_reason=TOL_FLOOR_REASON),
            "atol": Param(None, "absolute tolerance (default: tol)", float, positive=True),
            "controller": Param(controller, "step-size control", str, choices=("pi", "standard")),
        }

    def work_shape(self, problem):
        return (len(self.b) + 2, max(problem.dim, META_SIZE))

    def prepare_work(self, problem, work):
        meta = work[len(self.b) + 1]
        tol = self.settings["tol"]
        atol = self.settings["atol"]
        meta[M_RTOL] = tol
        meta[M_ATOL] = tol if atol is None else atol
        meta[M_K1_VALID] = 0.0
        meta[M_ERR_PREV] = 1e-4
        meta[M_REJECTED] = 0.0
        meta[M_PI] = 1.0 if self.settings["controller"] == "pi" else 0.0

    def make_try_step(self, problem):
        return embedded_try_step(problem.rhs, self.A, self.b, self.e, self.c, self.error_order, self.fsal)


class DormandPrince45(EmbeddedRungeKutta):
    name = "rk45"
    summary = "Dormand-Prince 5(4), FSAL, local extrapolation, PI step control (rtol = tol, atol)"
    order = 5
    error_order = 4
    fsal = True
    parameters = EmbeddedRungeKutta._parameters("pi")
    c = np.array([0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1, 1])
    A = np.array([
        [0, 0, 0, 0, 0, 0, 0],
        [1 / 5, 0, 0, 0, 0, 0, 0],
        [3 / 40, 9 / 40, 0, 0, 0, 0, 0],
        [44 / 45, -56 / 15, 32 / 9, 0, 0, 0, 0],
        [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729, 0, 0, 0],
        [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656, 0, 0],
        [35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84, 0],
    ])
    b = np.array([35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84, 0])
    b_hat = np.array([5179 / 57600, 0, 7571 / 16695, 393 / 640, -92097 / 339200, 187 / 2100, 1 / 40])
    e = b - b_hat


def _step_doubling_rk4():
    """RK4 step doubling as one 11-stage tableau: stages 0-3 and 4-7 are two RK4 steps of
    h/2 (the propagated solution), stages 0, 8, 9, 10 one RK4 step of h (stage 0 shared);
    the difference of the two results over 2^4 - 1 estimates the error of the first."""
    A = np.zeros((11, 11))
    c = np.zeros(11)
    w = np.array([1, 2, 2, 1]) / 6
    half = np.array([[0, 0, 0, 0], [0.5, 0, 0, 0], [0, 0.5, 0, 0], [0, 0, 1, 0]])
    A[:4, :4] = 0.5 * half
    c[:4] = 0.5 * np.array([0, 0.5, 0.5, 1])
    A[4:8, :4] = 0.5 * w  # second half step starts from the first half step's result
    A[4:8, 4:8] = 0.5 * half
    c[4:8] = 0.5 + 0.5 * np.array([0, 0.5, 0.5, 1])
    A[8, 0], A[9, 8], A[10, 9] = 0.5, 0.5, 1.0  # the full step's stages 2..4
    c[8:] = (0.5, 0.5, 1.0)
    b = np.r_[0.5 * w, 0.5 * w, 0, 0, 0]
    b_full = np.zeros(11)
    b_full[[0, 8, 9, 10]] = w
    return A, b, (b - b_full) / 15.0, c


class AdaptiveRK4(EmbeddedRungeKutta):
    name = "adaptive-rk4"
    summary = "classical RK4 with step doubling (error of two h/2 steps against one h step; 11 rhs/step)"
    order = 4
    error_order = 4
    fsal = False
    parameters = EmbeddedRungeKutta._parameters("standard")
    A, b, e, c = _step_doubling_rk4()
