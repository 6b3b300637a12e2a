"""Series recurrences against heyoka's own Taylor coefficients, and the series building blocks."""
from __future__ import annotations

import math

import numpy as np
import pytest

from longtime.core import registry
from longtime.core.problem import Problem
from longtime.numerics import series

ORDER = 20  # heyoka's order at machine-epsilon tolerance


def heyoka_coefficients(problem, system=None, t0=None):
    """heyoka's normalised Taylor coefficients (order+1, dim) at the problem's initial point."""
    import heyoka as hy

    variables, rhs = system if system is not None else problem.heyoka_system()
    ta = hy.taylor_adaptive(list(zip(variables, rhs)), problem.u0.copy(), tol=np.finfo(float).eps,
                            time=problem.t0 if t0 is None else t0, compact_mode=True)
    assert ta.order == ORDER
    ta.step(write_tc=True)
    return ta.tc.T.copy()


def our_coefficients(problem, order=ORDER, t0=None):
    coeffs = np.full((order + 1, problem.dim), np.nan)
    work = np.full(problem.taylor_work_shape(order), np.nan)  # no reliance on zeroed scratch
    problem.taylor(problem.t0 if t0 is None else t0, problem.u0.copy(), problem.params, coeffs, work)
    return coeffs


def assert_coefficients_match(ours, theirs, rtol=1e-12):
    """Order by order, relative to the size of that order's coefficients over the state
    (a component-wise ratio is meaningless where a coefficient cancels to near zero)."""
    scale = np.max(np.abs(theirs), axis=1)
    err = np.max(np.abs(ours - theirs), axis=1)
    bad = err > rtol * np.maximum(scale, 1e-300)
    assert not np.any(bad), f"orders {np.flatnonzero(bad).tolist()}: rel. errors {(err / scale)[bad]}"


def harmonic_system(omega):
    import heyoka as hy

    q, p = hy.make_vars("q", "p")
    return [q, p], [p, -omega * omega * q]


def test_harmonic_matches_heyoka():
    problem = registry.problem_class("harmonic")(omega=1.7, q0=0.3, p0=-1.1)
    assert_coefficients_match(our_coefficients(problem), heyoka_coefficients(problem, harmonic_system(1.7)))


@pytest.mark.parametrize("d", [3, 5])
def test_toda_matches_heyoka(d):
    problem = registry.problem_class("toda")(d=d)
    assert_coefficients_match(our_coefficients(problem), heyoka_coefficients(problem))


def test_building_blocks_against_closed_forms():
    n = 15
    k = np.arange(n + 1)
    fact = np.array([math.factorial(i) for i in k], dtype=float)
    a = np.zeros(n + 1)
    a[0], a[1] = 2.0, 3.0  # a(s) = 2 + 3 s
    out = np.zeros(n + 1)
    for i in range(n + 1):  # exp(2 + 3 s)
        out[i] = series.exp_coeff(a, out, i)
    np.testing.assert_allclose(out, np.exp(2.0) * 3.0**k / fact, rtol=1e-14)
    for i in range(n + 1):  # (2 + 3 s)^(-3/2)
        out[i] = series.power_coeff(a, out, -1.5, i)
    binom = np.array([math.prod(-1.5 - j for j in range(i)) / math.factorial(i) for i in k])
    np.testing.assert_allclose(out, 2.0**-1.5 * binom * 1.5**k, rtol=1e-13)
    for i in range(n + 1):  # sqrt(2 + 3 s)
        out[i] = series.sqrt_coeff(a, out, i)
    binom = np.array([math.prod(0.5 - j for j in range(i)) / math.factorial(i) for i in k])
    np.testing.assert_allclose(out, 2.0**0.5 * binom * 1.5**k, rtol=1e-13)
    one = np.zeros(n + 1)
    one[0] = 1.0
    for i in range(n + 1):  # 1 / (2 + 3 s)
        out[i] = series.divide_coeff(one, a, out, i)
    np.testing.assert_allclose(out, 0.5 * (-1.5) ** k, rtol=1e-14)
    sq = np.array([series.square(out, i) for i in range(n + 1)])
    pr = np.array([series.product(out, out, i) for i in range(n + 1)])
    np.testing.assert_allclose(sq, pr, rtol=1e-14)
    np.testing.assert_allclose(pr, 0.25 * (k + 1) * (-1.5) ** k, rtol=1e-13)
    t0, w = 0.7, 1.2
    cw = np.array([series.cos_wt_coeff(math.cos(w * t0), math.sin(w * t0), w**i / fact[i], i) for i in k])
    s = 0.05
    assert abs(np.polyval(cw[::-1], s) - math.cos(w * (t0 + s))) < 1e-15


# not e = 0: on the circle r^2 = 1 exactly, its series is pure round-off from cancellation,
# which r^-3's recurrence amplifies; heyoka's coefficients then differ from the closed form
# as much as ours (about 1e-9 at order 18), so neither is a 1e-12 reference there
@pytest.mark.parametrize("e", [0.1, 0.3, 0.6, 0.9])
def test_kepler_matches_heyoka(e):
    problem = registry.problem_class("kepler")(e=e)
    assert_coefficients_match(our_coefficients(problem), heyoka_coefficients(problem))


@pytest.mark.parametrize("name", ["figure-eight", "figure-eight-perturbed", "outer-solar-system"])
def test_figure_eight_matches_heyoka(name):
    problem = registry.problem_class(name)()
    assert_coefficients_match(our_coefficients(problem), heyoka_coefficients(problem))


def test_spatial_nbody_unequal_masses_matches_heyoka():
    from longtime.problems.nbody import NBody

    class FourBodies(NBody):
        name = "four-bodies"
        space_dim = 3
        G = 0.7

        def masses(self):
            return np.array([1.0, 0.3, 2.0, 0.05])

        def initial_state(self):
            rng = np.random.default_rng(7)
            return np.r_[rng.normal(size=12) * 2.0, rng.normal(size=12)]

    problem = FourBodies()
    assert_coefficients_match(our_coefficients(problem), heyoka_coefficients(problem))


@pytest.mark.parametrize("name, settings", [
    ("duffing-1", {}), ("duffing-2", {}), ("duffing-2", {"amplitude": 2.5}),
    ("duffing-forced", {}), ("duffing-forced", {"c": 0.29}), ("duffing-forced", {"c": 0.0})])
def test_duffing_matches_heyoka(name, settings):
    problem = registry.problem_class(name)(**settings)
    assert_coefficients_match(our_coefficients(problem), heyoka_coefficients(problem))


@pytest.mark.parametrize("t0", [0.0, 3.7, 41.0])
def test_duffing_forced_away_from_t0(t0):
    """The forcing's series depends on the expansion time: check it away from t = 0."""
    problem = registry.problem_class("duffing-forced")(c=0.65)
    assert_coefficients_match(our_coefficients(problem, t0=t0), heyoka_coefficients(problem, t0=t0))


@pytest.mark.parametrize("name", ["harmonic", "toda", "kepler", "duffing-2", "figure-eight"])
def test_lower_orders_are_a_prefix(name):
    """A short series is the start of a long one (the recurrence is order by order)."""
    problem = registry.problem_class(name)()
    full = our_coefficients(problem, 20)
    for order in (0, 1, 4, 9):
        np.testing.assert_array_equal(our_coefficients(problem, order), full[: order + 1])


# ---------------------------------------------------------------- the taylor schemes


def final_error(problem, scheme, t_final):
    traj = scheme.integrate(problem, t_final, max_samples=3)
    assert traj.status == "ok", traj.message
    return float(np.max(np.abs(traj.u[-1] - problem.exact(traj.t[-1:])[0]))), traj


@pytest.mark.parametrize("order", [4, 6])
def test_taylor_fixed_step_converges_with_order_N(order):
    """Fitted order of the final error over one Kepler period (e = 0.6) against dt."""
    problem = registry.problem_class("kepler")(e=0.6)
    dts = np.array([0.04, 0.02, 0.01])
    errors = [final_error(problem, registry.integrator_class("taylor")(dt=dt, order=order), 2 * np.pi)[0]
              for dt in dts]
    slope = np.polyfit(np.log(dts), np.log(errors), 1)[0]
    assert abs(slope - order) < 0.3, (slope, errors)


def test_taylor_on_non_autonomous_problem_against_reference():
    from longtime.measure.reference import reference_states

    problem = registry.problem_class("duffing-forced")(c=0.37)
    errors = []
    for dt in (0.04, 0.02):
        traj = registry.integrator_class("taylor")(dt=dt, order=6).integrate(problem, 5.0, max_samples=3)
        errors.append(np.max(np.abs(traj.u[-1] - reference_states(problem, traj.t)[-1])))
    assert 2**5.6 < errors[0] / errors[1] < 2**6.4  # order 6 in t as well (the forcing's series)


@pytest.mark.parametrize("tol", [1e-6, 1e-9, 1e-12])
@pytest.mark.parametrize("order", [None, 10, 20])
def test_taylor_adaptive_meets_its_tolerance(tol, order):
    """Over one Kepler period the global error stays within a small multiple of tol, and
    the step count grows as tol shrinks (the tolerance is read at run time)."""
    problem = registry.problem_class("kepler")(e=0.6)
    settings = {"tol": tol} if order is None else {"tol": tol, "order": order}
    scheme = registry.integrator_class("taylor-adaptive")(**settings)
    if order is None:  # Jorba-Zou's order for this tolerance
        assert scheme.settings["order"] == {1e-6: 8, 1e-9: 12, 1e-12: 15}[tol]
    err, traj = final_error(problem, scheme, 2 * np.pi)
    assert err < 20 * tol
    loose_err, loose = final_error(
        problem, registry.integrator_class("taylor-adaptive")(**{**settings, "tol": tol * 1e3}), 2 * np.pi)
    assert loose_err > err
    if order is not None:  # at a fixed order the step shrinks with tol (else the order grows)
        assert loose.steps < traj.steps


def test_equilibrium_does_not_break_the_taylor_schemes():
    """All coefficients beyond u_0 vanish: no division by zero, the adaptive step is h_max."""
    problem = registry.problem_class("harmonic")(q0=0.0, p0=0.0)
    traj = registry.integrator_class("taylor")(dt=0.5, order=8).integrate(problem, 10.0)
    assert traj.status == "ok" and np.all(traj.u == 0.0)
    traj = registry.integrator_class("taylor-adaptive")(tol=1e-12).integrate(problem, 10.0)
    assert traj.status == "ok" and traj.steps == 1 and traj.t[-1] == 10.0 and np.all(traj.u == 0.0)
    assert traj.max_dt == 10.0


def test_taylor_order_is_reported_and_validated():
    from longtime.core.params import InputError
    from longtime.execution.cells import Cell, run_cell

    row = run_cell(Cell("harmonic", "taylor", {}, {"dt": 0.1}, 10.0))
    assert row["status"] == "ok" and row["order"] == 10
    row = run_cell(Cell("toda", "taylor-adaptive", {}, {"order": 12, "tol": 1e-9}, 10.0))
    assert row["status"] == "ok" and row["order"] == 12 and row["H.max"] < 1e-8
    for bad in ({"order": 0}, {"order": "x"}, {"order": 61}, {"dt": -1.0}):
        with pytest.raises(InputError, match="order|dt"):
            registry.integrator_class("taylor")(**bad)
    with pytest.raises(InputError, match="order"):
        registry.integrator_class("taylor-adaptive")(order=1)
    with pytest.raises(InputError, match="tol"):
        registry.integrator_class("taylor-adaptive")(tol=0.0)


@pytest.mark.parametrize("name, settings", [
    ("taylor-adaptive", [{"tol": 1e-6}, {"tol": 1e-9}, {"tol": 1e-12}, {"tol": 1e-9, "order": 20}]),
    ("taylor", [{"order": 4}, {"order": 10}, {"order": 20}]),
    ("bpl", [{"order": 10}, {"order": 15}]),
])
def test_one_compiled_kernel_serves_every_series_order(name, settings):
    """N and the scratch shapes are read from the work array's header, not closed over: a
    tolerance sweep (N follows tol) or an N sweep compiles one kernel per problem, and each
    run still uses its own N (different final states; at a fixed step, more terms give a
    smaller error)."""
    from longtime.core.jitcache import fingerprint

    problem = registry.problem_class("toda")()
    kernels, finals, errors = set(), [], []
    for s in settings:
        scheme = registry.integrator_class(name)(**s)
        build = scheme.make_step if hasattr(scheme, "make_step") else scheme.make_try_step
        kernels.add(fingerprint(build(problem)))
        traj = scheme.integrate(problem, 2.0, max_samples=3)
        assert traj.status == "ok"
        finals.append(traj.u[-1].tobytes())
        H = problem.invariants(traj.t, traj.u)["H"]
        errors.append(abs(H[-1] - H[0]))
    assert len(kernels) == 1
    assert len(set(finals)) == len(settings)  # each run summed its own number of terms
    if name == "taylor":  # fixed step: the error falls with N (orders 4, 10, 20)
        assert errors[0] > 10 * errors[1] and errors[1] >= errors[2]


def test_taylor_is_skipped_without_a_recurrence():
    from longtime.core.problem import Problem

    class NoSeries(Problem):
        name = "no-series"
        rhs = staticmethod(registry.problem_class("harmonic").rhs)

        def initial_state(self):
            return [1.0, 0.0]

    assert "taylor" in registry.integrator_class("taylor")().incompatibility(NoSeries())


# ---------------------------------------------------------------- the heyoka scheme


def test_heyoka_scheme_reproduces_kepler_and_harmonic():
    from longtime.problems.harmonic import Harmonic

    class HarmonicWithSystem(Harmonic):  # harmonic.py has no heyoka system of its own
        def heyoka_system(self):
            return harmonic_system(self.settings["omega"])

    scheme = registry.integrator_class("heyoka")()
    for problem, t_final, bound in ((registry.problem_class("kepler")(e=0.6), 20 * np.pi, 1e-12),
                                    (HarmonicWithSystem(omega=1.3), 100.0, 2e-13)):
        traj = scheme.integrate(problem, t_final, max_samples=2001)
        assert traj.status == "ok" and traj.t.size == 2001 and traj.t[-1] == t_final
        assert np.max(np.abs(traj.u - problem.exact(traj.t))) < bound
        assert traj.steps > 10 and traj.cpu_s >= 0.0
        assert traj.extra["order"] == 20


def test_heyoka_scheme_tolerance_and_divergence():
    from longtime.execution.cells import Cell, run_cell
    from longtime.problems.duffing import Duffing1

    loose = run_cell(Cell("kepler", "heyoka", {}, {"tol": 1e-6}, 10.0))
    tight = run_cell(Cell("kepler", "heyoka", {}, {"tol": 1e-15, "high_accuracy": True}, 10.0))
    assert loose["status"] == tight["status"] == "ok"
    # heyoka raises the order as tol shrinks, which keeps its step near the series' radius
    # of convergence: the step count hardly changes, the error does
    assert tight["final_error"] < 1e-12 < loose["final_error"] < 1e-5
    assert (loose["order"], tight["order"]) == (8, 19)
    assert abs(loose["mean_dt"] - 10.0 / loose["steps"]) < 1e-12

    class Bounded(Duffing1):  # the growing amplitude passes a low constant bound: a divergence
        blowup_factor = 10.0
        size_bound = Problem.size_bound  # 10 x the initial size, not the solution's growth

    traj = registry.integrator_class("heyoka")().integrate(Bounded(), 20.0)
    assert traj.status == "diverged" and traj.t[-1] < 20.0
    # the drivers' rule for every scheme: the 1-norm passes the bound (Problem.first_blowup)
    assert np.sum(np.abs(traj.u[-1])) > 10.0 and np.all(np.sum(np.abs(traj.u[:-1]), axis=1) <= 10.0)
