"""heyoka under limits: the scheme keeps the cell's time limit without cutting its grid, large
systems compile in compact mode, and a compile past its time is given up, not waited for."""
import time

import numpy as np
import pytest

from longtime.core import heyoka_build, registry
from longtime.execution.cells import Cell, run_cell

pytest.importorskip("heyoka")


@pytest.fixture
def no_heyoka_cache():
    """heyoka without its compiled-code caches (in memory, and on disk since heyoka 1.0): a
    system compiled before, in this process or an earlier one, would build at once."""
    import heyoka as hy

    state = hy.llvm_state
    on_disk = state.get_diskcache_enabled() if hasattr(state, "get_diskcache_enabled") else None
    if on_disk:
        state.set_diskcache_enabled(False)
    state.clear_memcache()
    yield
    if on_disk:
        state.set_diskcache_enabled(True)


def test_heyoka_scheme_stops_at_the_cell_time_limit():
    # duffing-1 needs ever shorter steps towards its blow-up: to t = 60 heyoka ran for ever
    cell = Cell("duffing-1", "heyoka", {}, {}, 60.0)
    start = time.monotonic()
    # no reference: its check of duffing-1 to t = 60 has a budget of its own (minutes)
    row = run_cell(cell, reference=False, time_limit=2.0)
    took = time.monotonic() - start
    assert row["status"] == "timeout", row["message"]
    assert "time limit reached at t=" in row["message"] and "--time-limit" in row["message"]
    assert 20.0 < row["t_reached"] < 60.0
    # what it did is measured, not zero (the limit is wall time: on a loaded machine the run's
    # share of a core, and so its CPU time, can be a fraction of the limit)
    assert row["steps"] > 1000 and row["cpu_s"] > 0.05
    assert took < 15.0  # the limit and the compile


def test_heyoka_scheme_within_its_limit_is_timed_without_the_guard():
    # the timed runs repeat the guarded one bitwise (else the row would be 'non-deterministic')
    # and the row matches a run without any limit
    cell = Cell("kepler", "heyoka", {}, {}, 200.0)
    limited, free = run_cell(cell, time_limit=60.0), run_cell(cell, time_limit=None)
    assert limited["status"] == free["status"] == "ok", (limited["message"], free["message"])
    assert limited["steps"] == free["steps"] and limited["l2_error"] == free["l2_error"]
    assert limited["repeats"] >= 3


def test_large_systems_compile_in_compact_mode(no_heyoka_cache):
    # toda d = 200 as straight-line code takes minutes to compile (docs/performance.md)
    problem = registry.problems()["toda"](d=200)
    assert heyoka_build.compact_mode(problem)
    assert not heyoka_build.compact_mode(registry.problems()["toda"](d=3))
    start = time.perf_counter()
    ta = heyoka_build.taylor_adaptive(problem, problem.u0.copy(), timeout_s=60.0)
    assert time.perf_counter() - start < 30.0
    ta.propagate_until(1.0)
    assert np.isfinite(ta.state).all()


def test_a_compile_past_its_time_is_given_up(no_heyoka_cache):
    # toda d = 40 as straight-line code compiles for longer than the time given below
    problem = registry.problems()["toda"](d=40)
    start = time.perf_counter()
    with pytest.raises(heyoka_build.CompileTimeout, match="toda"):
        heyoka_build.taylor_adaptive(problem, problem.u0.copy(), timeout_s=0.3, compact_mode=False)
    assert time.perf_counter() - start < 2.0


def test_a_deadline_already_past_gives_up_at_once_and_says_so():
    # a caller passes the seconds left before its deadline: past it, that is negative
    problem = registry.problems()["kepler"]()
    with pytest.raises(heyoka_build.CompileTimeout) as info:
        heyoka_build.taylor_adaptive(problem, problem.u0.copy(), timeout_s=-1.2)
    assert "time limit was reached before heyoka's compile of kepler" in str(info.value)
    assert "-1.2" not in str(info.value)


@pytest.mark.parametrize("name", ["kepler", "figure-eight"])
def test_compact_mode_is_the_same_taylor_method(name):
    # compact mode changes how heyoka's code is laid out, not the method: at the reference's
    # settings (tolerance at double's epsilon, high accuracy) both builds take the same steps
    # and agree to round-off, so a reference built either way is the same reference
    problem = registry.problems()[name]()
    eps = float(np.finfo(float).eps)
    runs = []
    for compact in (False, True):
        ta = heyoka_build.taylor_adaptive(problem, problem.u0.copy(), None, tol=eps, high_accuracy=True,
                                          time=float(problem.t0), compact_mode=compact)
        grid = np.linspace(problem.t0, problem.t0 + 5.0, 51)
        outcome, _, _, steps, _, states = ta.propagate_grid(grid)
        runs.append((ta.order, int(steps), np.asarray(states)))
    (order_s, steps_s, straight), (order_c, steps_c, compact_states) = runs
    assert order_s == order_c and abs(steps_s - steps_c) <= 1
    scale = np.abs(straight).max()
    assert np.abs(straight - compact_states).max() <= 1e-13 * scale
