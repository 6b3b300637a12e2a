"""Explicit symplectic splitting schemes for separable H = T(p) + V(q).

A scheme is a sequence of (kick, drift) coefficient pairs: kick p -= b_i h grad V(q), then
drift q += a_i h grad T(p). Compositions (Yoshida) are built as loops over coefficient
arrays, with adjacent kicks merged. grad V is evaluated only when q has moved since the
last evaluation, so velocity Verlet costs one force per step (first same as last).
"""
from __future__ import annotations

import numba
import numpy as np

from longtime.core.contract import check_splitting
from longtime.core.drivers import OK, RHS_EVALS, compensated_add
from longtime.core.stepping import COMPENSATED, FixedStepIntegrator


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
    step_cost = 2.5  # 15 forces a step (the budget's estimate)
    kicks, drifts = _yoshida([0.102799849391985, -1.96061023297549, 1.93813913762276,
                              -0.158240635368243, -1.44485223686048, 0.253693336566229,
                              0.914844246229740])


# Blanes and Moan, "Practical symplectic partitioned Runge-Kutta and Runge-Kutta-Nystrom
# methods", J. Comput. Appl. Math. 142 (2002) 313-330, Table 2, method S6 (order 4): the
# PRK form q first, e^{a1 h A} e^{b1 h B} ... e^{b1 h B} e^{a1 h A} with A the drift (T) and
# B the kick (V); 7 drifts a1 a2 a3 a4 a3 a2 a1 and 6 kicks b1 b2 b3 b3 b2 b1.
_BM_A = (0.0792036964311957, 0.353172906049774, -0.0420650803577195)
_BM_B = (0.209515106613362, -0.143851773179818)


def _blanes_moan_s6():
    a1, a2, a3 = _BM_A
    a4 = 1.0 - 2.0 * (a1 + a2 + a3)
    b1, b2 = _BM_B
    b3 = 0.5 - (b1 + b2)
    # (kick, drift) pairs: the step opens with a drift (a kick of 0), ends with a drift
    return (np.array([0.0, b1, b2, b3, b3, b2, b1]),
            np.array([a1, a2, a3, a4, a3, a2, a1]))


class BlanesMoanS6(Splitting):
    name = "blanes-moan-s6"
    summary = "Blanes-Moan S6: 6-stage symmetric PRK splitting, drift first (order 4, 2002)"
    order = 4
    long_runs = False  # verlet and yoshida carry the family's paper-scale cells
    kicks, drifts = _blanes_moan_s6()


# Suzuki, "Fractal decomposition of exponential operators...", Phys. Lett. A 146 (1990)
# 319-323: S4(h) = S2(p h)^2 S2((1 - 4p) h) S2(p h)^2 with p = 1/(4 - 4^(1/3)), S2 = Verlet
SUZUKI_P = 1.0 / (4.0 - 4.0 ** (1.0 / 3.0))


class Suzuki4(Splitting):
    name = "suzuki4"
    summary = "Suzuki's fractal composition of 5 Verlet steps p, p, 1-4p, p, p (order 4, 1990)"
    order = 4
    long_runs = False  # verlet and yoshida carry the family's paper-scale cells
    kicks, drifts = compose([SUZUKI_P, SUZUKI_P, 1.0 - 4.0 * SUZUKI_P, SUZUKI_P, SUZUKI_P])


# The order-8 composition of 15 Verlet steps (HLW's p8s15) that Hairer-Lubich-Wanner,
# Geometric Numerical Integration, V.3.2, credit to Suzuki and Umeno (1993) and McLachlan,
# "On the numerical integration of ordinary differential equations by symmetric composition
# methods", SIAM J. Sci. Comput. 16 (1995) 151-168, whose digits HLW print (and Hairer's
# gni_comp): gamma_1..gamma_7 (gamma_15..gamma_9 by symmetry) and the middle gamma_8.
MCLACHLAN_8 = (0.74167036435061295345, -0.40910082580003159400, 0.19075471029623837995,
               -0.57386247111608226666, 0.29906418130365592384, 0.33462491824529818378,
               0.31529309239676659663, -0.79688793935291635402)


class McLachlan8(Splitting):
    name = "mclachlan-8"
    summary = ("McLachlan's (Suzuki-Umeno's) p8s15: symmetric composition of 15 Verlet steps "
               "(order 8, 1995)")
    order = 8
    long_runs = False  # verlet and yoshida carry the family's paper-scale cells
    kicks, drifts = compose(list(MCLACHLAN_8) + list(MCLACHLAN_8[-2::-1]))


# Kahan and Li, "Composition constants for raising the orders of unconventional schemes for
# ordinary differential equations", Math. Comp. 66 (1997) 1089-1099: the order-8 composition
# of 17 Verlet steps, HLW's p8s17 (V.3.2, and Hairer's gni_comp): gamma_1..gamma_8
# (gamma_17..gamma_10 by symmetry) and the middle gamma_9.
KAHAN_LI_8 = (0.13020248308889008087881763, 0.56116298177510838456196441,
              -0.38947496264484728640807860, 0.15884190655515560089621075,
              -0.39590389413323757733623154, 0.18453964097831570709183254,
              0.25837438768632204729397911, 0.29501172360931029887096624,
              -0.60550853383003451169892108)


class KahanLi8(Splitting):
    name = "kahan-li-8"
    summary = "Kahan-Li p8s17: symmetric composition of 17 Verlet steps (order 8, 1997)"
    order = 8
    step_cost = 2.5  # 17 forces a step (the budget's estimate)
    long_runs = False  # verlet and yoshida carry the family's paper-scale cells
    # rows stored under this name by longtime 0.1.0 before the correction are McLachlan's p8s15
    notice = ("until the correction of its coefficients, rows stored as kahan-li-8 (15 forces a step) "
              "are McLachlan's p8s15, now mclachlan-8; kahan-li-8 is Kahan and Li's p8s17 (17 forces a step)")
    kicks, drifts = compose(list(KAHAN_LI_8) + list(KAHAN_LI_8[-2::-1]))
