"""REBOUND's leapfrog, WHFast, MERCURIUS, JANUS, SABA(10,6,4) and IAS15 on the n-body family, beside the
built-in schemes.

The outer solar system's figures are asserted at 1e5 days here (a test stays short); the
1e6-day figures and their command are in docs/schemes.md.
"""
import sys

import numpy as np
import pytest

from longtime.core import registry
from longtime.core.timing import Timing
from longtime.execution.cells import expand, run_cell
from longtime.integrators.rebound_nbody import _rebound
from longtime.problems.nbody import NBody

# rebound is in the test extra; without it the rows are skipped (tested below, either way)
needs_rebound = pytest.mark.skipif(_rebound() is None, reason="rebound is not installed")

DAYS = 1e5


def energy_error(scheme, problem, t_final, **settings):
    traj = registry.integrator_class(scheme)(**settings).integrate(problem, t_final, max_samples=10_001)
    assert traj.status == "ok", traj.message
    H = problem.invariants(traj.t, traj.u)["H"]
    return np.abs(H - H[0]) / abs(H[0]), traj


@pytest.fixture(scope="module")
def oss():
    return registry.problem_class("outer-solar-system")()


@needs_rebound
def test_leapfrog_agrees_with_verlet_at_the_same_step(oss):
    # REBOUND's leapfrog (drift-kick-drift) against our verlet (kick-drift-kick), dt = 10 days:
    # the same order, error constants of the same size (measured: 4.0e-6 against 8.3e-6)
    ours, verlet = energy_error("verlet", oss, DAYS, dt=10.0)
    theirs, leapfrog = energy_error("rebound-leapfrog", oss, DAYS, dt=10.0)
    assert 1 / 3 < theirs.max() / ours.max() < 3
    assert leapfrog.steps == verlet.steps == 10_000 and leapfrog.counters["rhs_evals"] == 10_000
    assert np.array_equal(leapfrog.t, verlet.t)  # recorded after the same steps as the drivers
    assert np.max(np.abs(leapfrog.u - verlet.u)) < 1e-2 * np.max(np.abs(verlet.u))


@needs_rebound
def test_whfast_energy_error_at_ten_days(oss):
    error, traj = energy_error("rebound-whfast", oss, DAYS, dt=10.0)
    assert error.max() < 1e-8  # measured 5.4e-9 (and 5.3e-9 over 1e6 days)
    assert traj.min_dt == traj.max_dt == 10.0


@needs_rebound
def test_ias15_keeps_energy_to_round_off_without_drift(oss):
    from longtime.measure.growth import fit_power_law

    error, traj = energy_error("rebound-ias15", oss, DAYS)
    assert error.max() < 1e-14  # measured 2.9e-15 over 852 steps
    alpha = fit_power_law(traj.t - traj.t[0], np.maximum.accumulate(error))[0]
    assert alpha < 0.75  # no linear drift: a random walk at most (Brouwer's law)
    assert traj.t[0] == 0.0 and traj.t[-1] == DAYS and "rhs_evals" not in traj.counters
    assert traj.t.size == traj.steps + 1  # every step recorded (below the sample budget)
    # a looser epsilon takes fewer steps: the tolerance is IAS15's
    loose = registry.integrator_class("rebound-ias15")(tol=1e-4).integrate(oss, DAYS, max_samples=101)
    assert loose.status == "ok" and loose.steps < traj.steps


@needs_rebound
def test_the_last_step_is_clipped_and_steps_are_rebounds_count():
    problem = registry.problem_class("figure-eight")()
    traj = registry.integrator_class("rebound-leapfrog")(dt=0.07).integrate(problem, 1.0, timing=Timing(repeats=3))
    assert traj.status == "ok" and traj.steps == 15 and traj.t[-1] == 1.0
    assert traj.extra["repeats"] == 3  # the timed repeats reproduce the sampled run bitwise


@needs_rebound
def test_a_planar_problem_and_its_units_reach_rebound():
    # the figure-eight: planar, G = 1, unit masses; at a small step leapfrog follows verlet
    problem = registry.problem_class("figure-eight")()
    t_final = problem.period
    _, ours = energy_error("verlet", problem, t_final, dt=1e-3)
    _, theirs = energy_error("rebound-leapfrog", problem, t_final, dt=1e-3)
    assert np.max(np.abs(theirs.u - ours.u)) < 1e-5


class TwoBodies(NBody):
    """A plugin's n-body problem: a circular binary in the plane, G = 2, masses 1 and 3."""

    name = "two-bodies"
    G = 2.0
    default_t_final = 10.0
    default_dt = 0.01

    def masses(self):
        return np.array([1.0, 3.0])

    def initial_state(self):
        # separation 1, circular: relative speed sqrt(G M) with M = 4; centre of mass at rest
        v = np.sqrt(self.G * 4.0)
        return np.r_[0.75, 0.0, -0.25, 0.0, 0.0, 1.0 * 0.75 * v, 0.0, -3.0 * 0.25 * v]


@needs_rebound
def test_a_plugin_of_the_nbody_family_runs_on_ias15():
    problem = TwoBodies()
    traj = registry.integrator_class("rebound-ias15")().integrate(problem, 2 * np.pi / np.sqrt(8.0))
    assert traj.status == "ok"
    assert np.max(np.abs(traj.u[-1] - problem.u0)) < 1e-12  # one period of the circular orbit


def test_other_problems_are_skipped_naming_the_family():
    cells = expand(["kepler"], ["rebound-whfast"])
    assert cells[0].skip_reason.startswith("rebound-whfast needs an n-body problem")
    assert run_cell(cells[0])["status"] == "skipped"


def test_without_rebound_the_rows_are_skipped_and_name_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "rebound", None)  # import rebound raises ImportError
    cells = expand(["outer-solar-system"], ["rebound-leapfrog", "rebound-ias15", "verlet"])
    rows = [run_cell(c, timing=Timing(repeats=1)) for c in cells if c.integrator != "verlet"]
    assert [r["status"] for r in rows] == ["skipped", "skipped"]
    assert all('pip install "longtime[rebound]"' in r["message"] for r in rows)


@needs_rebound
def test_default_matrix_runs_rebound_on_the_outer_solar_system_to_1e6_days():
    cells = expand(["outer-solar-system", "figure-eight"], ["rebound-leapfrog", "rebound-whfast", "rebound-ias15"],
                   default_sweep=True)
    long = {c.integrator: c.integrator_settings for c in cells if c.t_final == 1e6}
    assert long == {"rebound-leapfrog": {"dt": 10.0}, "rebound-whfast": {"dt": 10.0}, "rebound-ias15": {}}
    # the figure-eight's sweep only: its 2200 periods cost IAS15 minutes
    eight = {c.t_final for c in cells if c.problem == "figure-eight"}
    assert eight == {registry.problem_class("figure-eight").sweep_t_final}


@needs_rebound
@pytest.mark.parametrize("scheme, settings", [("rebound-leapfrog", {"dt": 10.0}), ("rebound-ias15", {})])
def test_a_deadline_stops_the_run_where_it_got(oss, scheme, settings):
    import time

    traj = registry.integrator_class(scheme)(**settings).integrate(oss, 1e6, deadline=time.monotonic() - 1.0)
    assert traj.status == "timeout" and "time limit" in traj.message
    assert traj.t[-1] < 1e5 and traj.steps < 10_000  # stopped at the first look, 64 samples or steps in


@needs_rebound
def test_rebounds_warnings_reach_the_row():
    # WHFast on the figure-eight: body 2 falls radially from rest towards body 1 in Jacobi
    # coordinates, a Kepler orbit REBOUND's solver cannot take
    problem = registry.problem_class("figure-eight")()
    traj = registry.integrator_class("rebound-whfast")(dt=0.0253).integrate(problem, 1.0)
    assert traj.status == "diverged" and traj.t[-1] == pytest.approx(0.0253)
    assert "REBOUND: Possible convergence issue" in traj.message


@needs_rebound
def test_saba_and_mercurius_energy_at_ten_days(oss):
    # 1e4 steps of 10 days: SABA(10,6,4)'s error is of order eps h^10 + eps^3 h^4 (measured
    # 4.1e-14), MERCURIUS is WHFast's order 2 in democratic heliocentric coordinates (8.7e-9)
    saba, traj = energy_error("rebound-saba1064", oss, DAYS, dt=10.0)
    assert saba.max() < 1e-12 and traj.steps == 10_000
    mercurius, _ = energy_error("rebound-mercurius", oss, DAYS, dt=10.0)
    assert 1e-10 < mercurius.max() < 1e-7


@needs_rebound
def test_janus_returns_bit_for_bit():
    # JANUS runs on integers (positions and velocities in units of 1e-16): forward 1000 steps,
    # then back 1000 with -dt, it returns to the start bit for bit. The start is the initial
    # state as JANUS holds it: its first conversion to integers rounds the velocities (their
    # doubles carry bits below 1e-16), so a first forward-and-back run sets it.
    oss = registry.problem_class("outer-solar-system")()
    sim = registry.integrator_class("rebound-janus")(dt=10.0).simulation(oss)

    def state():
        x, v = np.zeros((sim.N, 3)), np.zeros((sim.N, 3))
        sim.serialize_particle_data(xyz=x, vxvyvz=v)
        return np.concatenate([x, v]).view(np.int64)

    u0 = oss.u0.copy()
    sim.steps(1000)
    sim.dt = -sim.dt
    sim.steps(1000)
    start = state()
    x0, v0 = oss.split_state(u0[None, :])[1][0], oss.split_state(u0[None, :])[2][0] / oss.masses()[:, None]
    x, v = start.view(float)[:sim.N], start.view(float)[sim.N:]
    assert np.array_equal(x, x0) and np.max(np.abs(v - v0)) <= 1e-16  # rounded to JANUS's scale only
    sim.dt = -sim.dt
    sim.steps(1000)
    ahead = state()
    assert np.abs(ahead.view(float) - start.view(float)).max() > 1  # it moved (Jupiter: 1e4 days)
    sim.dt = -sim.dt
    sim.steps(1000)
    assert np.array_equal(state(), start)
