"""Long fixed-step runs: chunks of compiled steps, a deadline, log-spaced samples."""
from __future__ import annotations

import time

import numpy as np

from longtime.core import stepping
from longtime.core.drivers import sample_steps
from longtime.core.registry import integrator_class, problem_class
from longtime.core.timing import Timing


def test_samples_are_evenly_and_log_spaced_and_bounded():
    at = sample_steps(10**8, 100_001)
    steps = at[:-1]
    assert at[-1] == 10**8 + 1 and steps[-1] == 10**8  # the sentinel, then the last step
    assert np.all(np.diff(steps) > 0) and steps.size <= 100_001
    for decade in range(8):  # points in every decade of time, not only at the stride
        inside = steps[(steps >= 10**decade) & (steps < 10 ** (decade + 1))]
        assert inside.size >= 9, decade
    assert np.array_equal(sample_steps(50, 2), [50, 51])  # max_samples=2: the end point only


def test_chunks_do_not_change_a_single_bit(monkeypatch):
    problem = problem_class("toda")()
    scheme = integrator_class("rk4")(dt=0.1)
    whole = scheme.integrate(problem, 500.0, max_samples=1001)
    monkeypatch.setattr(stepping, "FIRST_CHUNK", 7)
    monkeypatch.setattr(stepping, "CHUNK_SECONDS", 0.0)  # every chunk 7 steps
    pieces = scheme.integrate(problem, 500.0, max_samples=1001)
    assert whole.steps == pieces.steps == 5000
    assert np.array_equal(whole.t, pieces.t) and np.array_equal(whole.u, pieces.u)


def test_a_deadline_stops_a_run_between_chunks(monkeypatch):
    monkeypatch.setattr(stepping, "FIRST_CHUNK", 1000)
    monkeypatch.setattr(stepping, "CHUNK_SECONDS", 0.0)
    problem = problem_class("toda")()
    scheme = integrator_class("rk4")(dt=0.1)
    scheme.integrate(problem, 1.0)  # compiled
    traj = scheme.integrate(problem, 1e6, deadline=time.monotonic() - 1.0, timing=Timing())
    assert traj.status == "timeout" and "time limit" in traj.message
    assert traj.steps == 1000 and abs(traj.t[-1] - 100.0) < 1e-9  # one chunk, then stopped
    assert traj.extra["repeats"] == 1


def test_default_matrix_has_paper_scale_cells_for_the_schemes_that_can_afford_them():
    from longtime.execution.cells import expand

    cells = expand(["toda", "kepler"], ["rk4", "verlet", "gauss4", "rk45"], default_sweep=True)
    long = {(c.problem, c.integrator): c for c in cells if c.t_final in (5000.0, 2000 * np.pi)}
    assert set(long) == {("toda", "rk4"), ("toda", "verlet"), ("kepler", "rk4"), ("kepler", "verlet")}
    assert long["toda", "rk4"].integrator_settings == {"dt": 0.1}
    assert long["kepler", "verlet"].integrator_settings == {"dt": 0.01}
    # an explicit --dt or --t-final is the user's matrix: no extra cells
    assert all(c.t_final == 500.0 for c in expand(["toda"], ["rk4"], sweeps={"dt": [0.1]}, default_sweep=True))
    assert all(c.t_final == 10.0 for c in expand(["toda"], ["rk4"], t_final=10.0, default_sweep=True))


def test_dop853_stops_at_the_deadline_and_matches_hairers_code_called_directly():
    from scipy.integrate import ode

    problem = problem_class("kepler")()
    scheme = integrator_class("dop853")(tol=1e-10)
    whole = scheme.integrate(problem, 50.0, max_samples=10**6)

    def fun(t, y):
        out = np.empty_like(y)
        problem.rhs(t, y, problem.params, out)
        return out

    ts, ys = [], []
    r = ode(fun).set_integrator("dop853", rtol=1e-10, atol=1e-10, nsteps=10**6)
    r.set_solout(lambda t, y: ts.append(t) or ys.append(y.copy()))
    r.set_initial_value(problem.u0.copy(), problem.t0).integrate(50.0)
    assert r.successful() and whole.status == "ok"
    assert np.array_equal(whole.t, ts) and np.array_equal(whole.u, np.array(ys))
    assert whole.counters["rhs_evals"] == r._integrator.iwork[16]  # Hairer's NFCN
    cut = scheme.integrate(problem, 50.0, max_samples=10**6, deadline=time.monotonic() - 1.0)
    assert cut.status == "timeout" and cut.steps == 255  # stopped at the first look
    assert np.array_equal(cut.u, whole.u[:256])
