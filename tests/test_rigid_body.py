"""rigid-body (HLW IV.1): the elliptic-function solution against heyoka, and the invariants
under midpoint, the Gauss schemes and rk4 (docs/problems.md)."""
import numpy as np
import pytest

from longtime.core import registry
from longtime.measure import metrics


def rigid_body(**settings):
    return registry.problem_class("rigid-body")(**settings)


def heyoka_states(p, t):
    import heyoka as hy

    variables, rhs = p.heyoka_system()
    ta = hy.taylor_adaptive(list(zip(variables, rhs)), p.u0, tol=np.finfo(float).eps, high_accuracy=True)
    return ta.propagate_grid(t)[-1]


# HLW's body and start (about axis 3), a start about axis 1, and moments in other orders
# (an odd and an even permutation of the sorted axes), one of them a symmetric top
CASES = [{}, {"angle": 0.3}, {"I1": 1.0, "I2": 2.0, "I3": 3.0}, {"I1": 3.0, "I2": 1.0, "I3": 2.0, "angle": 0.5},
         {"I1": 1.0, "I2": 3.0, "I3": 2.0, "angle": 0.2}, {"I1": 2.0, "I2": 2.0, "I3": 1.0, "angle": 0.7}]


@pytest.mark.parametrize("settings", CASES, ids=lambda s: ",".join(f"{k}={v}" for k, v in s.items()) or "hlw")
def test_exact_solution_agrees_with_heyoka_to_1e_11_at_t_100(settings):
    p = rigid_body(**settings)
    t = np.linspace(0.0, 100.0, 201)
    exact, ref = p.exact(t), heyoka_states(p, t)
    assert np.max(np.abs(exact - ref)) < 1e-11  # measured: 5e-14 or less
    assert np.max(np.abs(exact[-1] - ref[-1])) < 1e-11
    inv = p.invariants(t, exact)
    assert np.ptp(inv["C"]) < 1e-12 and np.ptp(inv["H"]) < 1e-12  # scipy's ellipj: measured 1.2e-13
    assert np.ptp(exact[:, 1]) > 0.1 or settings.get("I1") == settings.get("I2")  # it moves


def test_hlw_initial_values():
    p = rigid_body()
    assert p.u0 == pytest.approx([np.cos(1.1), 0.0, np.sin(1.1)], abs=0)
    inv = p.invariants(np.zeros(1), p.u0[None, :])
    assert inv["C"][0] == pytest.approx(1.0, rel=1e-15)
    assert inv["H"][0] == pytest.approx(0.5 * (np.cos(1.1) ** 2 / 2 + 1.5 * np.sin(1.1) ** 2), rel=1e-15)


@pytest.mark.parametrize("scheme", ["midpoint", "gauss4", "gauss6"])
def test_quadratic_invariants_kept_to_round_off(scheme):
    """Both invariants are quadratic: every Gauss collocation scheme keeps them exactly.
    Measured over 2e4 steps (C.max): midpoint 2.7e-14, gauss4 9.1e-15, gauss6 6.2e-15."""
    p = rigid_body()
    traj = registry.integrator_class(scheme)(dt=0.05).integrate(p, 1000.0)
    row = metrics.evaluate(p, traj, None, None)
    assert traj.status == "ok"
    assert row["C.max"] < 1e-13 and row["H.max"] < 1e-13, (row["C.max"], row["H.max"])


def test_rk4_energy_drifts_linearly():
    """Measured at dt 0.1: H.final 1.44e-6 at t = 1000, 1.39e-5 at t = 10^4, growth 0.94."""
    p = rigid_body()
    rk4 = registry.integrator_class("rk4")(dt=0.1)
    row = metrics.evaluate(p, rk4.integrate(p, 10_000.0), None, None)
    assert row["H.growth_class"] == "linear" and 0.75 < row["H.growth"] < 1.25
    assert row["C.growth_class"] == "linear"
    early = metrics.evaluate(p, rk4.integrate(p, 1000.0), None, None)
    assert 7 < row["H.final"] / early["H.final"] < 13  # ten times longer, ten times larger


@pytest.mark.parametrize("settings, word", [({"I1": 0.0}, "I1"), ({"I3": -1.0}, "I3"), ({"angle": "x"}, "angle")])
def test_bad_settings(settings, word):
    from longtime.core.params import InputError

    with pytest.raises(InputError, match=word):
        rigid_body(**settings)
