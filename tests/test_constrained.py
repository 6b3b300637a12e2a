"""Constrained mechanics: the Cartesian double pendulum, dirac-1/2/midpoint and RATTLE."""
from __future__ import annotations

import numpy as np
import pytest

from longtime.core import registry
from longtime.core.params import InputError
from longtime.measure.reference import reference_states
from longtime.problems.double_pendulum import DoublePendulum

CONSTRAINED = ("dirac-1", "dirac-2", "dirac-midpoint", "rattle")


def run(name, problem, dt, t_final, max_samples=100_001, **settings):
    return registry.integrator_class(name)(dt=dt, **settings).integrate(problem, t_final, max_samples=max_samples)


def final_position_error(name, problem, dt, t_final):
    traj = run(name, problem, dt, t_final, max_samples=2)
    assert traj.status == "ok", traj.message
    ref = reference_states(problem, np.array([problem.t0, traj.t[-1]]))[1]
    return float(np.max(np.abs(traj.u[-1, :4] - ref[:4])))


@pytest.mark.parametrize("name", CONSTRAINED)
def test_convergence_order_against_reference(name):
    problem = DoublePendulum()
    dts = np.array([2e-3, 1e-3, 5e-4, 2.5e-4])
    errors = np.array([final_position_error(name, problem, dt, 1.0) for dt in dts])
    slope = np.polyfit(np.log(dts), np.log(errors), 1)[0]
    declared = registry.integrator_class(name).order
    assert abs(slope - declared) < 0.1, (name, slope, errors)


def test_constraints_stay_small_over_a_long_run_while_euler_drifts():
    problem = DoublePendulum()
    runs = {name: run(name, problem, 1e-3, 50.0) for name in ("dirac-2", "rattle", "dirac-midpoint", "euler")}
    phi = {name: float(np.max(problem.violations(None, tr.u)["constraint"])) for name, tr in runs.items()}
    for name in ("rattle", "dirac-midpoint"):  # nonlinear solves are counted: 1 to 6 per step
        assert runs[name].steps <= runs[name].counters["nl_iters"] <= 6 * runs[name].steps
    assert runs["dirac-2"].counters["nl_iters"] == 0  # linear: one m x m solve per step
    assert phi["rattle"] < 1e-13
    assert phi["dirac-midpoint"] < 1e-12  # quadratic constraints kept to round-off
    assert phi["dirac-2"] < 1e-3  # O(dt^2), bounded
    assert phi["euler"] > 0.1  # the index-1 ODE drifts off the manifold
    assert phi["euler"] > 1000 * phi["dirac-2"]


def test_dirac2_constraint_error_is_second_order_in_dt():
    problem = DoublePendulum()
    err = [float(np.max(problem.violations(None, run("dirac-2", problem, dt, 10.0).u)["constraint"]))
           for dt in (1e-3, 5e-4)]
    assert 3.5 < err[0] / err[1] < 4.5, err


def _tangent_basis(problem, x, eps=1e-6):
    """Orthonormal basis of the tangent space of {phi(q) = 0, G(q) M^{-1} p = 0} at x."""
    def cons(y):
        phi, gv = problem.constraint_values(y[None, :])
        return np.r_[phi[0], gv[0]]

    C = np.array([(cons(x + eps * e) - cons(x - eps * e)) / (2 * eps) for e in np.eye(8)]).T
    _, s, vt = np.linalg.svd(C)
    assert s[-1] > 1e-3  # the four constraints are independent
    return vt[4:]


def _symplecticity_defect(name, dt, steps, eps=1e-6):
    """max |Xi^T J' Xi - Xi^T J Xi| of the map over `steps` steps, on the tangent space."""
    problem = DoublePendulum(theta1=1.0, theta2=2.0, omega1=0.5, omega2=-1.0)
    x0 = problem.u0.copy()
    basis = _tangent_basis(problem, x0)

    def flow(x):
        problem.u0 = x
        traj = run(name, problem, dt, steps * dt, max_samples=2)
        assert traj.status == "ok"
        return traj.u[-1]

    D = np.array([(flow(x0 + eps * xi) - flow(x0 - eps * xi)) / (2 * eps) for xi in basis]).T
    J = np.block([[np.zeros((4, 4)), np.eye(4)], [-np.eye(4), np.zeros((4, 4))]])
    before = basis @ J @ basis.T
    after = D.T @ J @ D
    return float(np.max(np.abs(after - before))), float(np.max(np.abs(before)))


def test_rattle_is_symplectic_on_the_constraint_manifold():
    defect, size = _symplecticity_defect("rattle", 0.01, 20)
    assert size > 0.1  # omega restricted to the tangent space is not degenerate
    assert defect < 1e-7, defect
    # the same check fails for a scheme that is not symplectic
    euler_defect, _ = _symplecticity_defect("euler", 0.01, 20)
    assert euler_defect > 1e-3, euler_defect


def _angle_reference(problem, times):
    """heyoka on the Lagrangian in angles (theta from the downward vertical), mapped to Cartesian."""
    import heyoka as hy

    s = problem.settings
    m1, m2, l1, l2, g = s["m1"], s["m2"], s["l1"], s["l2"], s["g"]
    th1, th2, w1, w2 = hy.make_vars("th1", "th2", "w1", "w2")
    d = th1 - th2
    # mass matrix [[a, b], [b, c]] (theta'') = (f1, f2), from the Euler-Lagrange equations
    a, b, c = (m1 + m2) * l1 * l1, m2 * l1 * l2 * hy.cos(d), m2 * l2 * l2
    f1 = -m2 * l1 * l2 * w2 * w2 * hy.sin(d) - (m1 + m2) * g * l1 * hy.sin(th1)
    f2 = m2 * l1 * l2 * w1 * w1 * hy.sin(d) - m2 * g * l2 * hy.sin(th2)
    det = a * c - b * b
    sys = [(th1, w1), (th2, w2), (w1, (c * f1 - b * f2) / det), (w2, (a * f2 - b * f1) / det)]
    ta = hy.taylor_adaptive(sys, [s["theta1"], s["theta2"], s["omega1"], s["omega2"]],
                            tol=np.finfo(float).eps, high_accuracy=True)
    # max_delta_t: at the default release theta2'' vanishes with many of its Taylor
    # coefficients, and heyoka's step control then takes a first step of 0.32 that
    # loses 0.05 of energy; bounding the step avoids it (the Cartesian form is unaffected)
    out = ta.propagate_grid(np.asarray(times, dtype=float), max_delta_t=0.01)[-1]
    t1, t2, o1, o2 = out.T
    x1, y1 = l1 * np.sin(t1), -l1 * np.cos(t1)
    x2, y2 = x1 + l2 * np.sin(t2), y1 - l2 * np.cos(t2)
    vx1, vy1 = l1 * o1 * np.cos(t1), l1 * o1 * np.sin(t1)
    vx2, vy2 = vx1 + l2 * o2 * np.cos(t2), vy1 + l2 * o2 * np.sin(t2)
    return np.stack([x1, y1, x2, y2, m1 * vx1, m1 * vy1, m2 * vx2, m2 * vy2], axis=1)


@pytest.mark.parametrize("settings", [{}, {"m1": 2.0, "l2": 0.7, "theta1": 0.3, "theta2": -1.2, "omega2": 2.0}])
def test_cartesian_reference_agrees_with_the_angle_formulation(settings):
    problem = DoublePendulum(**settings)
    times = np.linspace(0.0, 3.0, 61)
    cartesian = reference_states(problem, times)
    angles = _angle_reference(problem, times)
    assert np.max(np.abs(cartesian - angles)) < 1e-10


def test_all_schemes_agree_with_the_reference_over_a_short_time():
    problem = DoublePendulum()
    t_final, dt = 0.5, 1e-4
    bound = {"dirac-1": 2e-3, "dirac-2": 2e-3, "dirac-midpoint": 2e-3, "rattle": 1e-7,
             "euler": 2e-3, "rk4": 1e-12, "midpoint": 1e-7}
    for name, tol in bound.items():
        traj = run(name, problem, dt, t_final)
        ref = reference_states(problem, traj.t)
        err = float(np.max(np.abs(traj.u[:, :4] - ref[:, :4])))
        assert err < tol, (name, err)


def test_energy_is_measured_from_the_rest_state():
    problem = DoublePendulum()
    assert problem.energy(problem.u0)[0] == pytest.approx(9.81 * 3.0, rel=1e-14)
    rest = DoublePendulum(theta1=0.0, theta2=0.0)
    assert abs(rest.energy(rest.u0)[0]) < 1e-13


def test_dirac2_runs_a_million_steps_in_under_two_cpu_seconds():
    traj = run("dirac-2", DoublePendulum(), 1e-4, 100.0)
    assert traj.status == "ok" and traj.steps == 1_000_000
    assert traj.cpu_s < 2.0, traj.cpu_s


def test_dirac2_with_a_clipped_last_step():
    problem = DoublePendulum()
    full = problem.violations(None, run("dirac-2", problem, 1e-3, 1.0).u)["constraint"]
    traj = run("dirac-2", problem, 1e-3, 1.0005)  # the last step is half a step: restart
    assert traj.status == "ok" and traj.t[-1] == pytest.approx(1.0005)
    clipped = problem.violations(None, traj.u)["constraint"]
    assert clipped[-1] < 2 * np.max(full) and np.max(clipped) < 1.5 * np.max(full)


@pytest.mark.parametrize("key,value", [("l1", 0.0), ("l2", -1.0), ("m1", 0.0), ("m2", -2.0)])
def test_nonpositive_lengths_and_masses_are_rejected(key, value):
    with pytest.raises(InputError, match=key):
        DoublePendulum(**{key: value})


@pytest.mark.parametrize("name", CONSTRAINED)
def test_inconsistent_start_is_an_error_and_project_repairs_it(name):
    problem = DoublePendulum(theta1=0.4, omega1=1.0)
    problem.u0 = problem.u0 + np.array([0.05, 0.0, 0.0, -0.02, 0.1, 0.0, 0.0, 0.0])
    with pytest.raises(InputError, match="violates its constraints"):
        run(name, problem, 1e-3, 0.01)
    problem.u0 = problem.project(problem.u0)
    phi, gv = problem.constraint_values(problem.u0)
    assert np.max(np.abs(phi)) < 1e-14 and np.max(np.abs(gv)) < 1e-13
    assert run(name, problem, 1e-3, 0.01).status == "ok"


def test_index1_rhs_keeps_the_constraints_to_second_order():
    # the multipliers make phi'' = G a + d2phi[v, v] vanish along the ODE
    problem = DoublePendulum(m1=2.0, theta1=0.7, theta2=-0.4, omega1=1.3, omega2=0.2)
    u, f = problem.u0, np.zeros(8)
    problem.rhs(0.0, u, problem.params, f)
    mass = np.array([2.0, 2.0, 1.0, 1.0])
    v, a = f[:4], f[4:] / mass
    G = np.zeros((2, 4))
    problem.constraints.grad_phi(u[:4].copy(), problem.params, G)
    def phi(q):
        return problem.constraint_values(np.r_[q, u[4:]])[0][0]

    # phi is quadratic: phi(q + d) = phi(q) + G d + Q(d), and phi'' = G a + 2 Q(v)
    second = G @ a + 2 * (phi(u[:4] + v) - phi(u[:4]) - G @ v)
    assert np.max(np.abs(second)) < 1e-12 * np.max(np.abs(G @ a))


def test_region_figure_is_written(tmp_path):
    from longtime.reporting.figures.pendulum import pendulum_region

    paths = pendulum_region(schemes=("dirac-2", "rattle"), dt=1e-3, times=(1.0, 2.0), out=tmp_path / "region")
    assert [p.suffix for p in paths] == [".png", ".svg"]
    assert all(p.stat().st_size > 10_000 for p in paths)
    with pytest.raises(InputError, match="space"):
        pendulum_region(space="polar", out=tmp_path / "bad")
