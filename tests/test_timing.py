"""Repeated timing: timeit-style autorange, minimum as the figure, bitwise-equal repeats."""
import numpy as np
import pytest

from longtime.core.integrator import Integrator
from longtime.core.params import InputError
from longtime.core.timing import Timing
from longtime.core.trajectory import Trajectory, same_run
from longtime.execution.cells import Cell, run_cell
from longtime.problems.harmonic import Harmonic


class Scripted(Integrator):
    """A scheme whose runs take scripted times and return scripted states."""

    name = "scripted"

    def __init__(self, walls, states=None):
        super().__init__()
        self.walls, self.states, self.calls = list(walls), states, 0

    def _integrate(self, problem, t_final, max_samples):
        k = self.calls
        self.calls += 1
        u = np.array([[1.0, 0.0], self.states[k] if self.states else [0.5, 0.5]])
        wall = self.walls[min(k, len(self.walls) - 1)]
        return Trajectory("ok", "", np.array([0.0, t_final]), u, cpu_s=0.9 * wall, wall_s=wall,
                          counters={"steps": 10})


UNSETTLED = [0.010 + 0.002 * k for k in range(60)]  # no two runs within Timing.SETTLED of each other


@pytest.mark.parametrize("walls, timing, runs", [
    (UNSETTLED, Timing(), 7),                  # fast and never settled: up to --repeats
    ([0.01], Timing(), 3),                     # settled (the minimum seen twice) after the 3 runs
    ([0.1], Timing(), 3),                      # 0.3 s after the minimum of 3 runs
    ([0.05, 0.06, 0.07, 0.08], Timing(), 4),   # unsettled: 0.18 s after 3, 0.26 s after 4: stop
    ([1.0], Timing(), 3),                      # slow: the minimum of 3 runs
    ([0.01], Timing(repeats=2), 2),            # fewer than 3 when --repeats says so
    ([0.01], Timing(repeats=1), 1),
    ([0.001 + 0.0001 * k for k in range(60)], Timing(repeats=50, min_time=0.02), 13),
    ([0.01], Timing().per_process(3), 2),      # a third of the repeats: settled after 2
    (UNSETTLED, Timing().per_process(3), 3),   # ceil(7 / 3) repeats at most
    ([0.1], Timing().per_process(3), 1),       # past a third of --min-time after one run
])
def test_autorange(walls, timing, runs):
    scheme = Scripted(walls)
    traj = scheme.integrate(Harmonic(), 1.0, timing=timing)
    assert scheme.calls == runs and traj.extra["repeats"] == runs
    assert traj.status == "ok"


def test_minimum_median_maximum():
    walls = [0.05, 0.03, 0.04, 0.06, 0.02]
    traj = Scripted(walls).integrate(Harmonic(), 1.0, timing=Timing(repeats=5, min_time=10))
    assert traj.wall_s == 0.02 and traj.extra["wall_s_median"] == 0.04 and traj.extra["wall_s_max"] == 0.06
    assert traj.cpu_s == pytest.approx(0.018) and traj.extra["cpu_s_max"] == pytest.approx(0.054)


def test_a_repeat_that_differs_in_one_bit_fails_the_row():
    x = 0.5
    y = np.nextafter(x, 1.0)
    traj = Scripted([0.01], states=[[x, x], [x, x], [x, y]]).integrate(Harmonic(), 1.0, timing=Timing())
    assert traj.status == "failed"
    assert "non-deterministic" in traj.message and "run 3" in traj.message


@pytest.mark.parametrize("kwargs, message", [
    (dict(repeats=0), "repeats=0 is not valid"),
    (dict(repeats=2.5), "repeats=2.5 is not valid"),
    (dict(min_time=-1.0), "min_time=-1.0 is not valid"),
    (dict(min_time=float("nan")), "min_time=nan is not valid"),
    (dict(min_runs=0), "min_runs=0 is not valid"),
])
def test_bad_timing_settings(kwargs, message):
    with pytest.raises(InputError, match=message):
        Timing(**kwargs)


def test_rows_carry_the_spread_and_real_schemes_repeat_bitwise():
    """Compiled fixed-step and adaptive schemes and heyoka reproduce themselves bitwise."""
    for scheme, settings in [("rk4", {"dt": 0.01}), ("rk45", {"tol": 1e-8}), ("heyoka", {})]:
        row = run_cell(Cell("kepler", scheme, {}, settings, 20.0), timing=Timing(repeats=4, min_time=0.0))
        assert row["status"] == "ok", row["message"]
        assert row["repeats"] == 3
        assert 0 < row["cpu_s"] <= row["cpu_s_median"] <= row["cpu_s_max"]
        assert 0 < row["wall_s"] <= row["wall_s_median"] <= row["wall_s_max"]


def test_per_process_splits_the_repeats():
    t = Timing(repeats=7, min_time=0.3).per_process(3)
    assert (t.repeats, t.min_runs) == (3, 1) and t.min_time == pytest.approx(0.1)
    assert Timing().per_process(1) == Timing()
    assert Timing.settled([0.0100, 0.0101, 0.5]) and not Timing.settled([0.0100, 0.0105]) and not Timing.settled([1.0])


def test_same_run_compares_bits():
    """Repeats are compared bit for bit: the same NaN is equal, -0.0 is not 0.0, one ulp
    apart is not equal, and a strided view compares by its values."""
    def traj(u):
        return Trajectory("ok", "", np.arange(u.shape[0], dtype=float), u, 0.0, 0.0, {"steps": 1})

    u = np.array([[1.0, np.nan], [0.0, 2.0]])
    assert same_run(traj(u), traj(u.copy()))
    assert not same_run(traj(u), traj(np.array([[1.0, np.nan], [-0.0, 2.0]])))
    assert not same_run(traj(u), traj(np.array([[np.nextafter(1.0, 2.0), np.nan], [0.0, 2.0]])))
    assert not same_run(traj(u), traj(u[:1]))
    wide = np.array([[1.0, 9.0, np.nan], [0.0, 9.0, 2.0]])
    assert same_run(traj(u), traj(wide[:, ::2]))
