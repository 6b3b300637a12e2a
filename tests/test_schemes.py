"""Issue-2 schemes: convergence orders fitted from dt sweeps, symplecticity, counters."""
import numpy as np
import pytest

from longtime.core import registry
from longtime.integrators.implicit_rk import RK4Sym

T_FINAL = 2.0  # not a period of the orbit: at a full period some errors cancel (superconvergence)

# scheme, expected order, dt sweep (chosen in the asymptotic range, above round-off)
SWEEPS = [
    ("euler", 1, [T_FINAL / n for n in (1000, 2000, 4000)]),
    ("symplectic-euler", 1, [T_FINAL / n for n in (1000, 2000, 4000)]),
    ("symplectic-euler-b", 1, [T_FINAL / n for n in (1000, 2000, 4000)]),
    ("verlet", 2, [T_FINAL / n for n in (200, 400, 800)]),
    ("midpoint", 2, [T_FINAL / n for n in (200, 400, 800)]),
    ("rk4", 4, [T_FINAL / n for n in (50, 100, 200)]),
    ("rk4sym", 4, [T_FINAL / n for n in (50, 100, 200)]),
    ("gauss4", 4, [T_FINAL / n for n in (25, 50, 100)]),
    ("gauss6", 6, [T_FINAL / n for n in (10, 20, 40)]),
    ("yoshida6", 6, [T_FINAL / n for n in (20, 40, 80)]),
    ("yoshida8", 8, [T_FINAL / n for n in (40, 80, 160)]),
]


def final_error(scheme, dt, problem):
    traj = registry.integrator_class(scheme)(dt=dt).integrate(problem, T_FINAL, max_samples=3)
    assert traj.status == "ok", traj.message
    return np.linalg.norm(traj.u[-1] - problem.exact(traj.t[-1:])[0])


@pytest.mark.parametrize("scheme, order, dts", SWEEPS, ids=[s[0] for s in SWEEPS])
def test_convergence_order_on_kepler(scheme, order, dts):
    problem = registry.problem_class("kepler")(e=0.5)
    errors = [final_error(scheme, dt, problem) for dt in dts]
    fitted = np.polyfit(np.log(dts), np.log(errors), 1)[0]
    assert abs(fitted - order) < 0.15, f"{scheme}: fitted order {fitted:.3f}, expected {order}"


def test_declared_orders_match_sweeps():
    for scheme, order, _ in SWEEPS:
        assert registry.integrator_class(scheme).order == order


def symplectic_defect(A, b):
    """max |b_i b_j - b_i a_ij - b_j a_ji|: zero for a symplectic Runge-Kutta tableau."""
    M = np.outer(b, b) - b[:, None] * A - (b[:, None] * A).T
    return np.max(np.abs(M))


def test_rk4sym_tableau_is_symplectic_and_corrected():
    assert RK4Sym.b[0] == pytest.approx(1.3512071919596578, abs=1e-15)
    assert symplectic_defect(RK4Sym.A, RK4Sym.b) < 1e-14
    # order-4 conditions: sum b = 1, b.c = 1/2, b.c^2 = 1/3, b.A.c = 1/6, ...
    A, b, c = RK4Sym.A, RK4Sym.b, RK4Sym.c
    for value, expected in [(b.sum(), 1), (b @ c, 1 / 2), (b @ c**2, 1 / 3), (b @ A @ c, 1 / 6),
                            (b @ c**3, 1 / 4), (b @ (c * (A @ c)), 1 / 8), (b @ A @ c**2, 1 / 12),
                            (b @ A @ A @ c, 1 / 24)]:
        assert value == pytest.approx(expected, abs=1e-13)
    # the composition is of order 4 iff 2 b^3 + (1 - 2b)^3 = 0: true for the corrected b,
    # false for the paper's misprint (2^(1/2) for 2^(1/3))
    b = RK4Sym.b[0]
    assert abs(2 * b**3 + (1 - 2 * b) ** 3) < 1e-14
    b_misprint = (2 + 2 ** 0.5 + 2 ** -0.5) / 3
    assert abs(2 * b_misprint**3 + (1 - 2 * b_misprint) ** 3) > 1e-2


@pytest.mark.parametrize("scheme", ["midpoint", "rk4sym", "gauss4", "gauss6"])
def test_implicit_tableaus_symplectic(scheme):
    cls = registry.integrator_class(scheme)
    assert cls.symplectic
    assert symplectic_defect(cls.A, cls.b) < 1e-14


def test_rk4_tableau_is_not_symplectic():
    cls = registry.integrator_class("rk4")
    assert not cls.symplectic
    assert symplectic_defect(cls.A, cls.b) > 1e-2


def step_jacobian(scheme, problem, u, dt, eps=1e-6):
    """Jacobian of one step map by central differences."""
    integ = registry.integrator_class(scheme)(dt=dt)
    n = u.size
    J = np.empty((n, n))
    for k in range(n):
        cols = []
        for sign in (1, -1):
            p = type(problem)(**problem.settings)
            p.u0 = u.copy()
            p.u0[k] += sign * eps
            cols.append(integ.integrate(p, p.t0 + dt, max_samples=2).u[-1])
        J[:, k] = (cols[0] - cols[1]) / (2 * eps)
    return J


@pytest.mark.parametrize("scheme, symplectic", [("rk4sym", True), ("verlet", True),
                                                ("symplectic-euler", True), ("gauss4", True),
                                                ("rk4", False), ("euler", False)])
def test_step_map_symplecticity(scheme, symplectic):
    problem = registry.problem_class("kepler")(e=0.5)
    u = problem.u0 + np.array([0.05, 0.1, -0.2, 0.1])
    J = step_jacobian(scheme, problem, u, dt=0.05)
    Omega = np.block([[np.zeros((2, 2)), np.eye(2)], [-np.eye(2), np.zeros((2, 2))]])
    defect = np.max(np.abs(J.T @ Omega @ J - Omega))
    if symplectic:
        assert defect < 1e-8, defect
    else:
        assert defect > 1e-6, defect


def test_implicit_solve_counts_iterations_and_reaches_round_off():
    problem = registry.problem_class("toda")()
    traj = registry.integrator_class("midpoint")(dt=0.1).integrate(problem, 10.0)
    assert traj.counters["nl_iters"] >= 2 * traj.steps  # at least two sweeps a step
    assert traj.counters["rhs_evals"] > traj.counters["nl_iters"]
    # solved to round-off: the implicit midpoint conserves the quadratic invariant of the
    # harmonic oscillator to round-off
    h = registry.problem_class("harmonic")()
    tr = registry.integrator_class("midpoint")(dt=0.3).integrate(h, 300.0)
    H = h.invariants(tr.t, tr.u)["H"]
    assert np.max(np.abs(H - H[0])) < 1e-13


def test_implicit_solve_failure_is_a_status():
    problem = registry.problem_class("harmonic")(omega=100.0)
    traj = registry.integrator_class("gauss4")(dt=0.5, max_iter=20).integrate(problem, 10.0)
    assert traj.status == "failed"
    assert "nonlinear solve" in traj.message


def test_verlet_costs_one_force_per_step():
    problem = registry.problem_class("figure-eight")()
    traj = registry.integrator_class("verlet")(dt=0.01).integrate(problem, 1.0)
    assert traj.counters["rhs_evals"] == traj.steps + 1


@pytest.mark.parametrize("scheme", ["midpoint", "rk4sym", "gauss4"])
def test_implicit_stages_to_round_off_keep_keplers_angular_momentum(scheme):
    # a symplectic Runge-Kutta method keeps a quadratic invariant exactly: over 1e4 steps
    # of h = 0.1 only round-off is left when every step's stages are solved to round-off
    # (a stop short of it leaves an error of one sign per step: a linear drift, ~1e-6)
    problem = registry.problem_class("kepler")()
    traj = registry.integrator_class(scheme)(dt=0.1).integrate(problem, 1000.0)
    assert traj.status == "ok" and traj.steps == 10_000
    L = problem.invariants(traj.t, traj.u)["L"]
    assert np.max(np.abs(L - L[0])) / abs(L[0]) <= 1e-13
