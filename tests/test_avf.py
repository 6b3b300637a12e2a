"""The averaged vector field method: energy to round-off for polynomial H, order 2."""
import numpy as np
import pytest

from longtime.core import registry
from longtime.core.timing import Timing
from longtime.execution.cells import Cell, run_cell
from longtime.integrators.avf import gauss_legendre
from longtime.measure.orders import observed_orders


def energy_error(scheme, **settings):
    problem = registry.problem_class("henon-heiles")()
    traj = registry.integrator_class(scheme)(**settings).integrate(problem, 1000.0, max_samples=10_001)
    assert traj.status == "ok", traj.message
    H = problem.invariants(traj.t, traj.u)["H"]
    return float(np.max(np.abs(H - H[0])) / abs(H[0])), traj


def test_energy_of_cubic_henon_heiles_is_kept_to_round_off():
    # 10^4 steps of h = 0.1 on a chaotic orbit: 2 nodes integrate the quadratic f exactly
    error, traj = energy_error("avf", dt=0.1)
    assert error < 5e-13, error  # measured 1.7e-13
    assert traj.counters["nl_iters"] >= traj.steps  # implicit: at least one sweep a step
    assert traj.counters["rhs_evals"] == traj.steps + 2 * traj.counters["nl_iters"]
    # the stopping rule without a tolerance leaves no systematic iteration error: 8.7e-15
    assert energy_error("avf", dt=0.1, stop="brouwer")[0] < 5e-14
    # one node is the implicit midpoint rule: the quadrature misses the cubic term
    midpoint = energy_error("avf", dt=0.1, nodes=1)[0]
    assert midpoint > 1e-5 and midpoint == pytest.approx(energy_error("midpoint", dt=0.1)[0], rel=1e-6)


def test_observed_order_two_on_kepler():
    rows = []
    for n in (50, 100, 200, 400):
        row = run_cell(Cell("kepler", "avf", {"e": 0.5}, {"dt": 2.0 / n}, 2.0), max_samples=201,
                       timing=Timing(repeats=1))
        assert row["status"] == "ok", row["message"]
        rows.append({**row, "run_id": 1})
    fit = observed_orders(rows)[0]
    assert abs(fit["observed_order"] - 2) < 0.05 and not fit["order_flag"], fit


def test_quadrature_rule():
    c, w = gauss_legendre(2)
    assert np.allclose(c, [0.5 - np.sqrt(3) / 6, 0.5 + np.sqrt(3) / 6], rtol=0, atol=1e-15)
    assert w.sum() == pytest.approx(1.0, abs=1e-15)
    for degree in range(4):  # exact up to degree 2 * 2 - 1
        assert w @ c**degree == pytest.approx(1 / (degree + 1), abs=1e-15)


def test_a_bad_node_count_is_one_line():
    from longtime.core.params import InputError

    with pytest.raises(InputError, match="nodes"):
        registry.integrator_class("avf")(nodes=0)
