"""The second canon's problems and the Boris method: the Pythagorean three-body problem's
close encounters, the charged particle in a non-uniform magnetic field, Lotka-Volterra as a
Poisson system and Arenstorf's orbit of the restricted three-body problem (docs/problems.md)."""
import math

import numpy as np
import pytest

from longtime.core import registry
from longtime.integrators.rebound_nbody import _rebound

P, I = registry.problem_class, registry.integrator_class


def relative_energy_error(problem, traj, name="H"):
    H = problem.invariants(traj.t, traj.u)[name]
    return np.abs(H - H[0]) / abs(H[0])


# ------------------------------------------------------------------ pythagorean-three-body
def test_pythagorean_data_and_energy():
    problem = P("pythagorean-three-body")()
    inv = problem.invariants(np.zeros(1), problem.u0[None, :])
    # at rest: H = -(3*4/5 + 3*5/4 + 4*5/3), L = P = 0
    assert inv["H"][0] == pytest.approx(-(12 / 5 + 15 / 4 + 20 / 3), rel=1e-15)
    assert inv["L"][0] == 0 and np.all(inv["P"] == 0)
    _, q, _ = problem.split_state(problem.u0[None, :])
    sides = sorted(np.hypot(*(q[0, k] - q[0, l])) for k, l in ((0, 1), (0, 2), (1, 2)))
    assert sides == [3.0, 4.0, 5.0]


def _pair_potential_floor(problem, states):
    """|H(u rounded to double) - H(u)| / |H0| per state, all in long double: what storing
    a state in double alone costs the energy (docs/problems.md)."""
    m = problem.masses().astype(np.longdouble)

    def energy(U):
        U = np.asarray(U, dtype=np.longdouble)
        q, p = U[:, :6].reshape(-1, 3, 2), U[:, 6:].reshape(-1, 3, 2)
        H = (np.sum(p ** 2, axis=2) / (2 * m)).sum(axis=1)
        for k, l in ((0, 1), (0, 2), (1, 2)):
            H = H - m[k] * m[l] / np.sqrt(((q[:, k] - q[:, l]) ** 2).sum(axis=1))
        return H

    H0 = energy(problem.u0[None, :])[0]
    return np.abs((energy(np.asarray(states).astype(np.float64)) - energy(states)) / H0).astype(float)


@pytest.mark.parametrize("scheme, settings", [
    pytest.param("rebound-ias15", {}, marks=pytest.mark.skipif(_rebound() is None, reason="rebound is not installed")),
    ("heyoka", {}), ("heyoka", {"precision": "long-double"})])
def test_ias15_and_heyoka_get_through_the_close_encounters(scheme, settings):
    # the closest encounter, r = 4.14e-4 at t = 15.830: a state stored in double there (eps |q|,
    # |q| ~ 1) moves H by up to 7.9e-10 of |H| (test_the_double_precision_floor_of_the_encounter)
    problem = P("pythagorean-three-body")()
    traj = I(scheme)(**settings).integrate(problem, 70.0, max_samples=100_001)
    assert traj.status == "ok" and traj.t[-1] == 70.0, traj.message
    error = relative_energy_error(problem, traj)
    r = problem.diagnostics(traj.t, traj.u)["r_min"]
    assert error[traj.t <= 15.0].max() < 1e-11  # before the first close encounter (measured 1.7e-12, 1.5e-12)
    if scheme == "rebound-ias15":
        # IAS15 carries its state with compensated summation: H is kept to 1e-10 wherever the
        # sampled state is not inside an encounter (measured 4.1e-11); the samples inside the
        # closest one show the rounding of the state read out in double (measured 6.5e-10)
        assert error[r > 0.01].max() < 1e-10
        assert error.max() < 1e-9
        # a sample every step: the closest encounter is seen
        assert r.min() == pytest.approx(4.14e-4, rel=0.01) and traj.t[np.argmin(r)] == pytest.approx(15.830, abs=1e-3)
    elif settings.get("precision") == "long-double":
        # the same tolerance (eps of double) with the state in long double: H to 1e-10 and better
        # throughout (measured 4.7e-12: the double evaluation of states rounded to double)
        assert error.max() < 1e-10
    else:
        # heyoka in double keeps the rounding of its double state at each step of the encounter:
        # measured 9.6e-10 (high_accuracy off, the default), 3.0e-10 (on); initial states moved by
        # one ulp give 1.2e-10 .. 2.3e-9
        assert error.max() < 3e-9
    L = problem.invariants(traj.t, traj.u)["L"]
    assert np.abs(L).max() < 1e-9
    # the escape: the lightest body (3) leaves towards +y, the others as a binary towards -y
    _, q, _ = problem.split_state(traj.u[-1:])
    assert q[0, 0, 1] > 15 and q[0, 1, 1] < -5 and q[0, 2, 1] < -5
    assert np.hypot(*(q[0, 1] - q[0, 2])) < 1.0


def test_the_double_precision_floor_of_the_encounter():
    """The energy error of a double-precision run through the closest encounter is round-off
    of the stored state, not the tolerance: heyoka in long double keeps H to 1e-12 at its own
    tolerance and at double's (2^-52), and rounding the long-double states of the encounter
    to double alone moves H by up to 7.9e-10 of |H|."""
    from longtime.core import heyoka_build

    problem = P("pythagorean-three-body")()
    ld = np.longdouble
    grid = np.linspace(0.0, 70.0, 7001)
    for tol in (None, 2.0 ** -52):  # None: heyoka's default, long double's epsilon
        extra = {} if tol is None else {"tol": ld(tol)}
        ta = heyoka_build.taylor_adaptive(problem, problem.u0.astype(ld), None, high_accuracy=True, fp_type=ld,
                                          time=ld(0.0), **extra)
        outcome, *_, states = ta.propagate_grid(grid.astype(ld))
        H = problem.invariants(grid, np.asarray(states, dtype=float))["H"]
        # measured 5.3e-12 and 5.1e-12 (the double evaluation of long-double states rounded
        # to double; in long double: 8.0e-13 and 1.3e-13)
        assert np.abs(H / H[0] - 1).max() < 1e-10, tol
    # the rounding to double of states sampled densely through the closest encounter
    ta = heyoka_build.taylor_adaptive(problem, problem.u0.astype(ld), None, high_accuracy=True, fp_type=ld,
                                      time=ld(0.0))
    ta.propagate_until(ld(15.8297))
    states = np.asarray(ta.propagate_grid(np.linspace(15.8297, 15.8302, 2001).astype(ld))[-1])
    floor = _pair_potential_floor(problem, states)
    assert 3e-10 < floor.max() < 2e-9  # measured 7.9e-10: 1e-10 is out of reach of a double state there


# ------------------------------------------------------------------ charged-particle, boris
def test_charged_particle_field_is_the_curl_of_its_potential():
    problem = P("charged-particle")()
    x = np.array([0.3, -0.2, 0.5])
    B, E = np.zeros(3), np.zeros(3)
    problem.field_B(x, problem.params, B)
    problem.field_E(x, problem.params, E)
    r = math.hypot(x[0], x[1])
    assert np.allclose(B, [0, 0, r], rtol=0, atol=1e-16)

    def A(y):  # (1/3) (-y2 r, y1 r, 0): B = curl A
        rr = math.hypot(y[0], y[1])
        return np.array([-y[1] * rr, y[0] * rr, 0.0]) / 3

    d = 1e-6
    J = np.array([(A(x + d * e) - A(x - d * e)) / (2 * d) for e in np.eye(3)]).T  # J[i, j] = dA_i/dx_j
    curl = np.array([J[2, 1] - J[1, 2], J[0, 2] - J[2, 0], J[1, 0] - J[0, 1]])
    assert np.allclose(curl, B, atol=1e-9)
    def U(y):
        return 0.01 / math.hypot(y[0], y[1])

    grad = np.array([(U(x + d * e) - U(x - d * e)) / (2 * d) for e in np.eye(3)])
    assert np.allclose(E, -grad, atol=1e-9)
    H0 = problem.invariants(np.zeros(1), problem.u0[None, :])["H"][0]
    assert H0 == pytest.approx(0.5 * (0.09**2 + 0.05**2 + 0.2**2) + 0.01 / 0.2, rel=1e-15)


def test_boris_keeps_the_energy_bounded_where_rk4_drifts():
    # dt = 0.1 to t = 1e4 (1e5 steps): boris's error reaches its plateau in the first
    # gyrations (measured 1.42e-4 at t = 10, 100, 1e3 and 1e4); rk4's grows linearly
    # (measured 6.1e-8, 4.3e-7, 4.2e-6, 4.2e-5): ten times more each decade
    problem = P("charged-particle")()
    maxima = {}
    for scheme in ("boris", "rk4"):
        traj = I(scheme)(dt=0.1).integrate(problem, 1e4, max_samples=4001)
        assert traj.status == "ok"
        H = problem.invariants(traj.t, traj.u)["H"]
        maxima[scheme] = [np.abs(H - H[0])[traj.t <= T].max() for T in (100.0, 1e3, 1e4)]
    boris, rk4 = maxima["boris"], maxima["rk4"]
    assert boris[2] / boris[0] < 1.1  # bounded: no growth over two decades
    assert 50 < rk4[2] / rk4[0] < 200  # linear drift: a factor 100 over two decades


def canonical_angular_momentum(U):
    """x1 p2 - x2 p1 with p = v + A(x): conserved by the exact flow (B and U depend on r alone)."""
    x1, x2, v1, v2 = U[:, 0], U[:, 1], U[:, 3], U[:, 4]
    return x1 * v2 - x2 * v1 + np.hypot(x1, x2) ** 3 / 3


def test_boris_energy_error_is_a_flat_plateau_of_order_two_to_1e5():
    # Hairer and Lubich (BIT 2018) prove near-conservation for a constant B or a quadratic U;
    # this example has neither, and their examples of that kind may drift or random-walk. Here
    # Boris's error is one O(h^2) plateau over five decades of t: the largest |H - H0| of each
    # decade [10^k, 10^(k+1)] is the same to 1 % (measured 1.42e-4, 5.65e-4, 2.20e-3 at
    # h = 0.1, 0.2, 0.4, each to 3 digits in every decade), a factor 4 per doubling of h; the
    # canonical angular momentum behaves alike (4.77e-4 at h = 0.1), where rk4's drifts
    problem = P("charged-particle")()
    plateaus = []
    for h in (0.1, 0.2, 0.4):
        traj = I("boris")(dt=h).integrate(problem, 1e5, max_samples=20_001)
        assert traj.status == "ok"
        H = problem.invariants(traj.t, traj.u)["H"]
        L = canonical_angular_momentum(traj.u)
        for err in (np.abs(H - H[0]), np.abs(L - L[0])):
            decades = [err[(traj.t > T / 10) & (traj.t <= T)].max() for T in (1e2, 1e3, 1e4, 1e5)]
            assert max(decades) / min(decades) < 1.01, (h, decades)
        plateaus.append(np.abs(H - H[0]).max())
    ratios = np.array(plateaus[1:]) / np.array(plateaus[:-1])
    assert np.all(np.abs(ratios - 4) < 0.3), ratios  # measured 3.98, 3.89
    traj = I("rk4")(dt=0.1).integrate(problem, 1e5, max_samples=20_001)
    L = canonical_angular_momentum(traj.u)
    err = np.abs(L - L[0])
    assert err[traj.t > 1e4].max() / err[traj.t <= 1e3].max() > 50  # measured 6.9e-5 / 7.4e-7


def test_boris_is_order_two_and_costs_one_field_evaluation_a_step():
    problem = P("charged-particle")()
    exact = I("heyoka")().integrate(problem, 10.0, max_samples=2).u[-1]
    errors = []
    for dt in (0.04, 0.02, 0.01):
        traj = I("boris")(dt=dt).integrate(problem, 10.0, max_samples=2)
        errors.append(np.abs(traj.u[-1] - exact).max())
        assert traj.counters["rhs_evals"] == round(10.0 / dt) + 1  # one a step, and the first
    slopes = np.diff(np.log(errors)) / np.log(0.5)
    assert np.all(np.abs(slopes - 2) < 0.05), slopes


def boris_step_jacobian(problem, u, h):
    """The one-step map's Jacobian at u, by central differences through the compiled step."""
    scheme = I("boris")(dt=h)

    def step(y):
        saved = problem.u0
        problem.u0 = y
        try:
            return scheme.integrate(problem, problem.t0 + h, max_samples=2).u[-1]
        finally:
            problem.u0 = saved

    d = 1e-6
    return np.array([(step(u + d * e) - step(u - d * e)) / (2 * d) for e in np.eye(u.size)]).T, step(u)


def test_boris_preserves_phase_space_volume():
    # in (x^n, v^(n-1/2)) the Boris step preserves volume; in the state (x^n, v^n) its
    # determinant is (1 + h^2 |B(x^n)|^2/4) / (1 + h^2 |B(x^(n+1))|^2/4): it telescopes over a
    # run and never accumulates.
    problem = P("charged-particle")()
    h = 0.3
    u = problem.u0.copy()
    u[:3] = [0.4, -0.7, 0.2]
    J, after = boris_step_jacobian(problem, u, h)
    quotient = (1 + h * h * np.hypot(*u[:2]) ** 2 / 4) / (1 + h * h * np.hypot(*after[:2]) ** 2 / 4)
    assert abs(quotient - 1) > 1e-4  # the positions' fields differ: the test can tell
    assert np.linalg.det(J) == pytest.approx(quotient, abs=1e-9)


# ------------------------------------------------------------------ lotka-volterra
def test_lotka_volterra_first_integral_and_poisson_flow():
    problem = P("lotka-volterra")()
    H0 = problem.invariants(np.zeros(1), problem.u0[None, :])["H"][0]
    assert H0 == pytest.approx(4 * math.log(2) - 6, rel=1e-15)  # ln 4 - 4 + 2 ln 2 - 2
    traj = I("heyoka")().integrate(problem, 100.0, max_samples=2001)
    assert np.abs(problem.invariants(traj.t, traj.u)["H"] - H0).max() < 1e-13
    # rk4 drifts off the level curve (measured 9.4e-5 at dt = 0.05 over t = 100)
    rk4 = I("rk4")(dt=0.05).integrate(problem, 100.0, max_samples=2001)
    assert 1e-5 < np.abs(problem.invariants(rk4.t, rk4.u)["H"] - H0).max() < 1e-3
    # the Taylor coefficients are those of the flow: taylor agrees with heyoka
    tay = I("taylor")().integrate(problem, 10.0, max_samples=2)
    ref = I("heyoka")().integrate(problem, 10.0, max_samples=2)
    assert np.abs(tay.u[-1] - ref.u[-1]).max() < 1e-10


# ------------------------------------------------------------------ restricted-three-body
def test_arenstorf_orbit_closes_after_one_period():
    from longtime.measure.reference import reference_states

    problem = P("restricted-three-body")()
    T = problem.period
    # the orbit through the data rounded to double does not close exactly: in long double it
    # returns to 4.9e-11 (the rounding of 1 - mu and of 0.994, amplified along the orbit)
    closure = np.abs(reference_states(problem, np.array([0.0, T]), "long double")[-1] - problem.u0).max()
    assert closure < 1e-10
    traj = I("heyoka")().integrate(problem, T, max_samples=1001)
    assert np.abs(traj.u[-1] - problem.u0).max() < 1e-10  # measured 4.0e-11
    # at half the period the orbit is at its far point, mirrored: y2 = 0 and y1' = 0
    J = problem.invariants(traj.t, traj.u)["J"]
    mu = 0.012277471
    x, v = 0.994, -2.00158510637908252240537862224
    J0 = x * x + 2 * (1 - mu) / (x + mu) + 2 * mu / abs(x - 1 + mu) - v * v
    assert J[0] == pytest.approx(J0, rel=1e-15) and np.abs(J - J0).max() < 1e-12


def test_the_new_problems_and_schemes_are_in_the_default_matrix():
    from longtime.execution.cells import expand

    new = ["pythagorean-three-body", "charged-particle", "lotka-volterra", "restricted-three-body"]
    assert set(new) <= set(registry.default_problems())
    cells = expand(new, ["boris", "rk4", "kahan-li-8", "mclachlan-8", "rebound-janus", "rebound-mercurius",
                         "rebound-saba1064"], default_sweep=True)
    runnable = {(c.problem, c.integrator) for c in cells
                if I(c.integrator)().incompatibility(P(c.problem)()) is None}
    assert ("charged-particle", "boris") in runnable and ("lotka-volterra", "rk4") in runnable
    assert {("pythagorean-three-body", s) for s in ("kahan-li-8", "mclachlan-8")} <= runnable
    if _rebound() is not None:
        assert {("pythagorean-three-body", s) for s in ("rebound-janus", "rebound-mercurius",
                                                         "rebound-saba1064")} <= runnable
    # boris's paper-scale cell: 1e5 on the charged particle, where rk4's drift shows
    assert {c.t_final for c in cells if (c.problem, c.integrator) == ("charged-particle", "boris")} == {1000.0, 1e5}
