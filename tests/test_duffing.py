"""Duffing problems: exact solution, first integrals, parameters; series schemes on them."""
from __future__ import annotations

import numpy as np
import pytest

from longtime.core import registry
from longtime.core.params import InputError
from longtime.measure.reference import reference_states


def rhs_of(problem, t, U):
    out = np.empty_like(U)
    for i in range(U.shape[0]):
        problem.rhs(t[i], U[i], problem.params, out[i])
    return out


def test_duffing2_exact_solves_the_ode_and_keeps_H():
    problem = registry.problem_class("duffing-2")()
    t = np.linspace(0.0, 3000.0, 30001)
    U = problem.exact(t)
    np.testing.assert_allclose(U[0], [1.0, 0.0], atol=1e-15)
    # the exact state's time derivative (central differences) is the ODE's right-hand side
    ts = t[t <= 30.0]
    F = rhs_of(problem, ts, U[: ts.size])
    h = 1e-4
    dU = (problem.exact(ts + h) - problem.exact(ts - h)) / (2 * h)
    assert np.max(np.abs(dU - F)) < 1e-7
    H = problem.invariants(t, U)["H"]
    assert np.max(np.abs(H - 0.75)) < 5e-14


@pytest.mark.parametrize("amplitude", [0.3, 2.5])
def test_duffing2_exact_other_amplitudes_against_heyoka(amplitude):
    problem = registry.problem_class("duffing-2")(amplitude=amplitude)
    t = np.linspace(0.0, 20.0, 41)
    import heyoka as hy

    variables, rhs = problem.heyoka_system()
    ta = hy.taylor_adaptive(list(zip(variables, rhs)), problem.u0.copy(), tol=1e-16)
    ref = ta.propagate_grid(t)[-1]
    assert np.max(np.abs(problem.exact(t) - ref)) < 1e-11 * max(1.0, amplitude**2)


def test_duffing1_first_integral_is_conserved_by_the_reference():
    problem = registry.problem_class("duffing-1")()
    t = np.linspace(0.0, 20.0, 201)
    U = reference_states(problem, t)
    I = problem.invariants(t, U)["I"]
    assert abs(I[0] - (1 / 9 + 1 / 2)) < 1e-15
    assert np.max(np.abs(I / I[0] - 1)) < 1e-10
    assert np.max(np.abs(U[:, 0])) > 20  # the amplitude does grow (the hard case)


def test_duffing_forced_parameter_and_capabilities():
    cls = registry.problem_class("duffing-forced")
    assert cls().params[3] == 0.5
    assert cls(c="0.37").params[3] == 0.37
    assert cls(c=-2.0).params[3] == -2.0
    with pytest.raises(InputError, match="c"):
        cls(c="nan")
    with pytest.raises(InputError, match="c"):
        cls(c="abc")
    caps = cls.capabilities()
    assert "autonomous" not in caps and "separable" not in caps and {"taylor", "heyoka"} <= caps
    assert "separable" in registry.problem_class("duffing-2").capabilities()
    assert "separable" not in registry.problem_class("duffing-1").capabilities()


def test_duffing_forced_rhs_matches_heyoka_reference():
    """The forcing enters with the right phase: rk4 at a small step against heyoka."""
    problem = registry.problem_class("duffing-forced")(c=0.37)
    rk4 = registry.integrator_class("rk4")(dt=1e-3)
    traj = rk4.integrate(problem, 10.0, max_samples=11)
    ref = reference_states(problem, traj.t)
    assert np.max(np.abs(traj.u - ref)) < 1e-9


def test_series_schemes_on_duffing():
    """taylor-adaptive keeps duffing-1's first integral through the growth of the amplitude;
    taylor and heyoka follow duffing-2's exact solution."""
    d1 = registry.problem_class("duffing-1")()
    traj = registry.integrator_class("taylor-adaptive")(tol=1e-12).integrate(d1, 20.0)
    assert traj.status == "ok" and traj.t[-1] == 20.0
    I = d1.invariants(traj.t, traj.u)["I"]
    assert np.max(np.abs(I / I[0] - 1)) < 1e-8
    assert np.max(np.abs(traj.u[:, 0])) > 100  # the amplitude did grow

    d2 = registry.problem_class("duffing-2")()
    for scheme, bound in ((registry.integrator_class("taylor")(dt=0.1, order=12), 1e-10),
                          (registry.integrator_class("heyoka")(), 1e-12)):
        traj = scheme.integrate(d2, 200.0, max_samples=1001)
        assert traj.status == "ok"
        assert np.max(np.abs(traj.u - d2.exact(traj.t))) < bound


def test_duffing1_bound_follows_the_growing_solution():
    # the true state passes 1e10 x its initial size near t = 36; the bound follows size_bound
    problem = registry.problem_class("duffing-1")()
    assert problem.grows and problem.blowup >= 1e200  # the drivers stop only near overflow
    t = np.linspace(0.0, 38.0, 77)
    true = reference_states(problem, t)
    size = np.sum(np.abs(true), axis=1)
    bound = problem.size_bound(t)
    assert np.all(size <= bound) and np.max(size / bound) > 0.3  # a bound, and not a loose one
    assert size[-1] > 1e10 * np.max(np.abs(problem.u0))  # beyond a constant bound of 1e10 |u0|
    assert problem.first_blowup(true, t) is None
    wild = true.copy()
    wild[50] *= 2e10  # 1e10 x the bound, at t = 24.7: far below a constant bound's value at t = 36
    assert problem.first_blowup(wild, t) == 50
    assert problem.first_blowup(wild) is None  # without the times only overflow counts


@pytest.mark.slow
def test_a_run_past_the_growing_bound_is_diverged_and_an_o1_error_is_flagged(monkeypatch):
    from longtime.execution.cells import Cell, run_cell
    from longtime.measure import reference
    from longtime.reporting.report import LOST, not_ok

    # past t = 35 double leaves long double, so the full ladder would also run real128, which
    # spends its whole time budget (120 s) on duffing-1 and ends before t = 35 (the horizon
    # stays double vs long double's): the same rows without it. test_reference covers real128.
    ladder = reference._ladder()
    monkeypatch.setattr(reference, "_ladder", lambda: [p for p in ladder if p != "real128"])
    # accurate to t = 38 (the solution's 1-norm reaches 1e11): ok, solution kept
    row = run_cell(Cell("duffing-1", "taylor-adaptive", {}, {"tol": 1e-12}, 38.0))
    assert row["status"] == "ok" and row["solution_lost"] is False, row["message"]
    assert row["reference_horizon"] > 30.0  # errors measured far into the growth (to t = 35.09)
    # RK4 at the paper's step loses I and the solution (|dI/I| reaches 100 %)
    lost = run_cell(Cell("duffing-1", "rk4", {}, {"dt": 4e-4}, 30.0))
    assert lost["status"] == "ok" and lost["solution_lost"] is True
    assert "error O(1)" in lost["message"]
    assert not_ok([row, lost]) == {LOST: ["rk4 (1 of 1)"]}
    # a step far too long leaves the true solution's bound: diverged, where it happened
    wild = run_cell(Cell("duffing-1", "euler", {}, {"dt": 0.25}, 38.0))
    assert wild["status"] == "diverged" and wild["t_reached"] < 38.0, wild["message"]
