"""docs/paper.md: the paper's Toda figures at t_f = 5000, dt = 0.1, through the CLI."""
import json

import numpy as np
import pytest

from longtime.commands.cli import main
from longtime.core import registry
from longtime.measure.metrics import relative_error

PAPER_H_MEAN = {"rk4": 3.7902e-1, "rk4sym": 2.261e-3}


@pytest.fixture(scope="module")
def rows(capsys_module=None):
    import contextlib
    import io

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(["run", "-p", "toda", "-i", "rk4,rk4sym", "--dt", "0.1", "--t-final", "5000",
                     "--format", "json", "--no-store"])
    assert code == 0
    return {r["integrator"]: r for r in json.loads(out.getvalue())}


@pytest.mark.parametrize("scheme", sorted(PAPER_H_MEAN))
def test_toda_energy_mean_matches_paper(rows, scheme):
    row = rows[scheme]
    assert row["status"] == "ok"
    assert row["steps"] == 50000 and row["mean_dt"] == pytest.approx(0.1)
    assert row["H.mean"] == pytest.approx(PAPER_H_MEAN[scheme], rel=0.01)


def test_json_contract_fields(rows):
    required = ["problem", "integrator", "status", "message", "dt", "order", "tol", "eps_res",
                "t_final", "steps", "rhs_evals", "cpu_s", "wall_s", "mean_dt", "l2_error",
                "final_error"]
    for row in rows.values():
        for key in required:
            assert key in row
        for name in ["H", "eig1", "eig2", "eig3"]:
            for stat in ["max", "mean", "final", "t_1pct", "t_50pct"]:
                assert f"{name}.{stat}" in row
    # RK4's energy error crosses 1 % (it reaches ~50 %); RK4sym's never does
    assert rows["rk4"]["H.t_1pct"] is not None and rows["rk4"]["H.t_1pct"] < 500
    assert rows["rk4sym"]["H.t_1pct"] is None


def energy_error_window_maxima(scheme):
    """Max of e_H over each tenth of [0, 5000]."""
    problem = registry.problem_class("toda")()
    traj = registry.integrator_class(scheme)(dt=0.1).integrate(problem, 5000.0)
    err = relative_error(problem.invariants(traj.t, traj.u)["H"])
    return np.array([w.max() for w in np.array_split(err[1:], 10)])


def test_rk4sym_energy_error_does_not_grow_while_rk4_grows():
    sym = energy_error_window_maxima("rk4sym")
    assert sym.max() < 1.02 * sym.min(), sym  # bounded oscillation: every tenth alike
    rk4 = energy_error_window_maxima("rk4")
    assert np.all(np.diff(rk4) > 0), rk4  # grows all along
    assert rk4[-1] > 2.5 * rk4[0], rk4
