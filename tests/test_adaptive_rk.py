"""Adaptive Runge-Kutta: tableaus, classical orders (fixed steps through the compiled
stepper), tolerance met against exact solutions, and scipy's DOP853 peer."""
from __future__ import annotations

import math

import numpy as np
import pytest

from longtime.core.drivers import new_counters
from longtime.core.params import InputError
from longtime.integrators.embedded_rk import AdaptiveRK4, DormandPrince45
from longtime.integrators.scipy_ivp import DOP853
from longtime.problems.harmonic import Harmonic
from longtime.problems.kepler import Kepler


@pytest.mark.parametrize("cls", [DormandPrince45, AdaptiveRK4])
def test_tableau_consistency(cls):
    A, b, e, c = cls.A, cls.b, cls.e, cls.c
    assert np.allclose(A.sum(axis=1), c, atol=1e-15)
    assert np.allclose(np.triu(A), 0)  # explicit
    assert abs(b.sum() - 1) < 1e-15 and abs(e.sum()) < 1e-15
    if cls.fsal:
        assert np.allclose(A[-1], b) and c[-1] == 1


def fixed_step_error(cls, problem, h, t_end):
    """Global error at t_end with constant steps h through the compiled try_step (every
    step accepted: a huge tolerance), against the exact solution."""
    scheme = cls(tol=1e10)
    try_step = scheme.make_try_step(problem)
    work = np.zeros(scheme.work_shape(problem))
    scheme.prepare_work(problem, work)
    u, u_new, counters = problem.u0.copy(), np.empty(problem.dim), new_counters()
    n = round(t_end / h)
    for k in range(n):
        code, taken, _ = try_step(k * h, u, h, problem.params, work, counters, u_new)
        assert code == 1 and taken == h
        u[:] = u_new
    return np.linalg.norm(u - problem.exact(np.array([n * h]))[0])


@pytest.mark.parametrize("cls,order", [(DormandPrince45, 5), (AdaptiveRK4, 4)])
def test_classical_order(cls, order):
    problem = Kepler(e=0.3)
    t_end = 2 * math.pi
    hs = t_end / np.array([128, 256, 512])
    errs = [fixed_step_error(cls, problem, h, t_end) for h in hs]
    slope = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert abs(slope - order) < 0.35, (errs, slope)


@pytest.mark.parametrize("problem,factor", [(Harmonic(), 10), (Kepler(e=0.6), 1000)],
                         ids=["harmonic", "kepler"])
def test_rk45_meets_its_tolerance(problem, factor):
    """The local error per step is <= tol; over one period the global error against the exact
    solution stays within a problem-dependent multiple of tol (the pericentre passage of the
    e = 0.6 orbit amplifies local errors: scipy's RK45, the same pair, is as far off) and is
    proportional to tol."""
    errs = []
    for tol in (1e-6, 1e-9):
        traj = DormandPrince45(tol=tol).integrate(problem, 2 * math.pi, max_samples=100_001)
        assert traj.status == "ok"
        err = np.linalg.norm(traj.u - problem.exact(traj.t), axis=1).max()
        assert err < factor * tol, (tol, err)
        assert traj.counters["rejected"] < traj.steps  # the controller is not thrashing
        errs.append(err)
    assert 0.1 < (errs[1] / errs[0]) / 1e-3 < 10  # tolerance proportionality


@pytest.mark.parametrize("cls", [DormandPrince45, AdaptiveRK4])
def test_work_precision_order(cls):
    """Error against the number of steps over a tolerance sweep follows the order."""
    problem = Kepler(e=0.6)
    steps, errs = [], []
    for tol in (1e-7, 1e-9, 1e-11):
        traj = cls(tol=tol).integrate(problem, 2 * math.pi, max_samples=3)
        steps.append(traj.steps)
        errs.append(np.linalg.norm(traj.u[-1] - problem.exact(traj.t[-1:])[0]))
    slope = -np.polyfit(np.log(steps), np.log(errs), 1)[0]
    assert abs(slope - cls.order) < 0.8, (steps, errs, slope)


def test_fsal_saves_one_evaluation_per_step():
    traj = DormandPrince45(tol=1e-8).integrate(Harmonic(), 20.0)
    c = traj.counters
    assert c["rhs_evals"] == 1 + 6 * (traj.steps + c["rejected"])
    traj = AdaptiveRK4(tol=1e-8).integrate(Harmonic(), 20.0)
    c = traj.counters
    assert c["rhs_evals"] == 11 * traj.steps + 10 * c["rejected"]


def test_controllers_and_bad_input():
    for controller in ("pi", "standard"):
        traj = DormandPrince45(tol=1e-8, controller=controller).integrate(Kepler(e=0.9), 2 * math.pi)
        assert traj.status == "ok"
    with pytest.raises(InputError, match="controller"):
        DormandPrince45(controller="pid")
    with pytest.raises(InputError, match="tol"):
        AdaptiveRK4(tol=-1.0)


def test_dop853_peer():
    problem = Kepler(e=0.6)
    traj = DOP853(tol=1e-10).integrate(problem, 2 * math.pi)
    assert traj.status == "ok" and DOP853.kind == "external" and "overhead" in DOP853.summary
    err = np.linalg.norm(traj.u - problem.exact(traj.t), axis=1).max()
    assert err < 1e-8
    assert traj.counters["rhs_evals"] >= 12 * traj.steps
