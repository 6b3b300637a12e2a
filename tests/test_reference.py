"""The reference check: error estimates, horizons, the exact solutions' own accuracy, caching
and the time budget (longtime.measure.reference)."""
import itertools
import json
import time

import numpy as np
import pytest

from longtime.core import registry
from longtime.execution.cells import Cell, run_cell
from longtime.measure import reference, reference_runs
from longtime.problems.kepler import Kepler


@pytest.fixture
def fresh_cache(monkeypatch, tmp_path):
    monkeypatch.setenv("LONGTIME_CACHE_DIR", str(tmp_path))
    return tmp_path


def test_long_double_is_extended_and_the_ladder_has_three_rungs():
    assert np.finfo(np.longdouble).eps < 1e-18  # x86_64: 80-bit, 64-bit mantissa
    assert reference._ladder() == ["double", "long double", "real128"]


def test_chaotic_double_pendulum_is_measured_only_up_to_the_horizon():
    row = run_cell(Cell("double-pendulum", "rk4", {}, {"dt": 0.01}, 100.0))
    assert row["status"] == "ok" and row["t_reached"] == 100.0
    # double leaves long double at t ~ 17; long double, checked against real128, holds to ~25
    assert 10 < row["reference_horizon"] < 50
    assert row["reference"] == "heyoka long double"
    assert row["reference_error"] <= row["reference_rtol"] == reference.REFERENCE_RTOL
    assert row["final_error"] is None and row["l2_error"] is not None
    assert row["reference_horizon"] - 0.01 < row["error_horizon"] <= row["reference_horizon"]
    assert "only up to t = " in row["message"] and "real128" in row["message"]
    json.dumps(row, allow_nan=False)


def test_toda_reference_holds_to_5000():
    row = run_cell(Cell("toda", "rk4", {}, {"dt": 0.1}, 5000.0))
    assert row["reference_horizon"] == 5000.0 and row["error_horizon"] == 5000.0
    assert row["reference"] == "heyoka double" and row["reference_error"] < 1e-9
    # no note on the reference (the message may say that rk4's phase error is O(1) by t = 5000)
    assert row["final_error"] is not None and "reference" not in row["message"]


def test_rows_without_a_reference_have_null_reference_fields():
    row = run_cell(Cell("duffing-forced", "rk4", {}, {"dt": 0.01}, 1.0), reference=False)
    for key in ("reference", "reference_error", "reference_horizon", "reference_rtol",
                "error_horizon", "l2_error", "final_error"):
        assert row[key] is None, key


def _pericentre_errors(p, states, orbits=16):
    """Max relative error around the pericentre passage after ``orbits`` orbits."""
    t = np.r_[0.0, orbits * 2 * np.pi + np.linspace(-2e-3, 2e-3, 41)]
    exact = p.exact(t)[1:]
    return [np.max(np.linalg.norm(exact - U[1:], axis=1) / np.linalg.norm(U[1:], axis=1))
            for U in (states(t, fp) for fp in ("long double", "real128"))]


def test_kepler_exact_solution_is_the_orbit_of_the_rounded_state():
    # e = 0.99: the rounded u0 has a period 1.5e-14 shorter than the formula's 2 pi; the formula's
    # orbit is 1.06e-9 off at the 16th pericentre, the orbit of the elements of u0 itself 6e-13
    p = Kepler(e=0.99)

    def states(t, precision):
        return reference.propagate(p, t, precision)[0]

    vs_long_double, vs_real128 = _pericentre_errors(p, states)
    assert vs_real128 < 2e-12
    assert vs_long_double < 3e-11  # long double's own error after 16 orbits: ~1e-11
    trust = reference.reference_check(p, 40 * np.pi)
    assert trust.source == "exact" and trust.horizon == pytest.approx(40 * np.pi)
    assert trust.error < 1e-10


def test_exact_solutions_are_checked_or_declared():
    harmonic = reference.reference_check(registry.problem_class("harmonic")(), 200.0)
    assert harmonic.error < 1e-13 and harmonic.horizon == 200.0 and harmonic.note == ""
    duffing = reference.reference_check(registry.problem_class("duffing-2")(), 200.0)
    assert duffing.error < 1e-12 and "vs heyoka long double" in duffing.basis


def test_kdv_reference_is_the_galerkin_systems_own_solution():
    """KdV's reference is the solution of the Galerkin system its schemes integrate (the
    integrating factor by DOP853, checked against the system integrated directly), not the
    PDE's soliton: rk4 at a small step agrees with it far below the soliton's distance
    from the system (about 2.5e-7), which the row gives apart as discretisation_error."""
    row = run_cell(Cell("kdv", "rk4", {}, {"dt": 0.002}, 3.0))
    assert row["status"] == "ok" and row["reference"] == "integrating factor"
    assert row["reference_error"] < 1e-11 and row["reference_horizon"] == 3.0
    assert 3e-10 < row["l2_error"] < 1e-8  # rk4's own error (3.3e-9 to t = 10)
    assert 1.5e-7 < row["discretisation_error"] < 4e-7
    assert row["error_floor"] < 1e-11 and row["error_below_floor"] is False
    # the reference itself, at other times than its check's, against the system run directly
    kdv = registry.problem_class("kdv")(d=64)
    times = np.linspace(0.0, 3.0, 7)
    ref = reference.reference_states(kdv, times)
    direct, stopped = reference.system_states(kdv, times, "direct")
    assert stopped is None and np.max(reference._relative(ref, direct)) < 1e-11
    # and the PDE's soliton is not it
    assert np.max(reference._relative(kdv.pde_solution(times)[1:], ref[1:])) > 1e-7


def test_an_error_below_the_references_is_not_reported_as_measured():
    from longtime.measure.metrics import floor_fields

    trust = reference.Trust("double", 1e-8, 10.0, 1e-10, "heyoka double vs long double")
    states = np.ones((5, 2))  # RMS size sqrt(2)
    notes: list[str] = []
    out = floor_fields({"l2_error": 1e-11, "final_error": 3e-10}, trust, states, 2 ** 0.5, notes)
    assert out == {"error_floor": pytest.approx(1e-10), "error_below_floor": True}
    assert notes and "l2_error 1e-11 below the reference's error 1e-10" in notes[0] and "final_error" not in notes[0]
    notes.clear()
    assert floor_fields({"l2_error": 1e-9}, trust, states, 2 ** 0.5, notes)["error_below_floor"] is False
    assert not notes
    unchecked = reference.Trust("double", 1e-8, 10.0, None, "unchecked")
    assert floor_fields({"l2_error": 1e-20}, unchecked, states, 1.0, notes) == {
        "error_floor": None, "error_below_floor": None}


def test_a_cached_check_is_reused(fresh_cache, monkeypatch):
    p = registry.problem_class("henon-heiles")()
    start = time.perf_counter()
    first = reference.reference_check(p, 300.0)
    elapsed = time.perf_counter() - start
    assert list(fresh_cache.glob("reference/henon-heiles-*.npz"))
    reference._CHECKS.clear()  # from disk, as another process would

    def no_heyoka(*args, **kwargs):
        raise AssertionError("the check ran again")

    monkeypatch.setattr(reference, "_stepped_run", no_heyoka)
    monkeypatch.setattr(reference, "propagate", no_heyoka)
    start = time.perf_counter()
    assert reference.reference_check(p, 300.0) == first
    assert time.perf_counter() - start < max(0.1, elapsed / 2)


def test_a_check_that_passes_its_budget_trusts_only_what_it_checked(fresh_cache, monkeypatch):
    # a clock that moves one second per reading: the budget is a number of heyoka steps
    ticks, clock = itertools.count(), time.perf_counter
    monkeypatch.setattr(reference.time, "perf_counter", lambda: float(next(ticks)))
    p = registry.problem_class("toda")()
    trust = reference.reference_check(p, 50.0, budget_s=100)
    assert 0 < trust.horizon < 50 and "time budget" in trust.note
    assert trust.error < reference.REFERENCE_RTOL
    monkeypatch.setattr(reference.time, "perf_counter", clock)  # the cell's own run: 100 s
    t = np.linspace(0, 50, 501)
    states, again = reference.trusted_reference(p, t, 50.0, budget_s=100)
    assert again == trust and len(states) == np.searchsorted(t, trust.horizon, side="right")


def test_a_cell_whose_check_passes_its_budget_at_once_has_no_errors(fresh_cache, monkeypatch):
    monkeypatch.setattr(reference_runs, "DEFAULT_BUDGET_S", 0.0)
    row = run_cell(Cell("double-pendulum", "rk4", {}, {"dt": 0.01}, 5.0))
    assert row["status"] == "ok" and row["l2_error"] is None and row["final_error"] is None
    assert row["reference_horizon"] is None and row["error_horizon"] is None
    assert row["message"].startswith("no reference:") and "time budget" in row["message"]


def test_exact_states_are_evaluated_once_per_grid_and_setting(monkeypatch):
    """reference_states keeps the exact solution of a grid in the process: the cells of a
    problem share their sample times. Another grid or another setting is evaluated anew."""
    import numpy as np

    from longtime.core import registry
    from longtime.measure import reference

    calls = []
    kepler_cls = registry.problems()["kepler"]
    real = kepler_cls.exact

    def counted(self, t):
        calls.append(self.settings["e"])
        return real(self, t)

    monkeypatch.setattr(kepler_cls, "exact", counted)
    monkeypatch.setattr(reference, "_EXACT", {})
    times = np.linspace(0.0, 5.0, 50)
    low, high = kepler_cls(e=0.3), kepler_cls(e=0.9)
    first = reference.reference_states(low, times)
    first[0, 0] = 123.0  # the caller's copy: the kept states stay as computed
    again = reference.reference_states(low, times)
    assert calls == [0.3] and again[0, 0] == low.u0[0]
    np.testing.assert_array_equal(again[1:], first[1:])
    other = reference.reference_states(high, times)
    reference.reference_states(low, times[:-1])
    assert calls == [0.3, 0.9, 0.3]
    np.testing.assert_allclose(other, kepler_cls(e=0.9).exact(times), rtol=0, atol=0)


def test_exact_states_of_a_large_grid_are_read_back_from_disk(monkeypatch, tmp_path):
    """A grid of at least EXACT_DISK_SAMPLES times keeps the exact solution on disk: a new
    process (an empty in-process cache) reads back the same states without evaluating it; a
    solution that is not finite is never kept."""
    import numpy as np

    from longtime.core import registry
    from longtime.measure import reference

    monkeypatch.setenv("LONGTIME_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(reference, "EXACT_DISK_SAMPLES", 40)
    calls = []
    kepler_cls = registry.problems()["kepler"]
    real = kepler_cls.exact

    def counted(self, t):
        calls.append(len(t))
        return real(self, t)

    monkeypatch.setattr(kepler_cls, "exact", counted)
    problem, times = kepler_cls(e=0.7), np.linspace(0.0, 30.0, 50)
    monkeypatch.setattr(reference, "_EXACT", {})
    first = reference.reference_states(problem, times)
    monkeypatch.setattr(reference, "_EXACT", {})
    again = reference.reference_states(problem, times)
    assert calls == [50]
    np.testing.assert_array_equal(again, first)
    np.testing.assert_array_equal(first, real(problem, times))
    reference.reference_states(problem, times[:30])  # below the threshold: evaluated, not kept
    assert calls == [50, 30]

    def broken(self, t):
        out = real(self, t)
        out[-1] = np.nan
        return out

    monkeypatch.setattr(kepler_cls, "exact", broken)
    for _ in range(2):
        monkeypatch.setattr(reference, "_EXACT", {})
        assert np.isnan(reference.reference_states(problem, times + 1.0)[-1]).all()
