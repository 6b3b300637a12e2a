"""The problems of docs/problems.md: initial data, invariants, references, bad settings."""
import numpy as np
import pytest

from longtime.core import registry
from longtime.core.params import InputError
from longtime.measure.reference import reference_states


def problem(name, **settings):
    return registry.problem_class(name)(**settings)


def invariant_drift(p, t):
    U = reference_states(p, t)
    return {k: np.max(np.abs(np.asarray(v) - np.asarray(v)[0])) for k, v in p.invariants(t, U).items()}


def test_toda_initial_energy_and_lax_spectrum():
    p = problem("toda")
    inv = p.invariants(np.zeros(1), p.u0[None, :])
    assert inv["H"][0] == pytest.approx(22.338751647595720, rel=1e-15)
    assert [inv[f"eig{i}"][0] for i in (1, 2, 3)] == pytest.approx([-5.24393147, 1.3125236, 3.93140787], abs=1e-7)


@pytest.mark.parametrize("d", [3, 6])
def test_toda_invariants_conserved_by_reference(d):
    p = problem("toda", d=d)
    drift = invariant_drift(p, np.linspace(0, 50, 201))
    assert set(drift) == {"H"} | {f"eig{i + 1}" for i in range(d)}
    assert max(drift.values()) < 1e-11


def test_figure_eight_initial_data_and_period():
    p = problem("figure-eight")
    inv = p.invariants(np.zeros(1), p.u0[None, :])
    assert inv["H"][0] == pytest.approx(-1.2871419917663258, rel=1e-14)
    assert inv["L"][0] == 0.0 and np.all(inv["P"][0] == 0.0)
    U = reference_states(p, np.array([0.0, p.period]))
    assert np.max(np.abs(U[-1] - p.u0)) < 1e-6  # 8-digit initial data: periodic to ~1e-7
    drift = invariant_drift(p, np.linspace(0, 10 * p.period, 501))
    assert drift["H"] < 1e-13 and drift["L"] < 1e-13 and drift["P"] < 1e-13


def test_figure_eight_perturbed_moves_body_three_only():
    base, pert = problem("figure-eight"), problem("figure-eight-perturbed")
    changed = np.flatnonzero(base.u0 != pert.u0)
    assert set(changed) <= {4, 5, 10, 11} and len(changed) == 4
    # body 3 sits where the exact orbit puts it at T/80
    U = reference_states(base, np.array([0.0, base.period / 80]))
    assert pert.u0[[4, 5, 10, 11]] == pytest.approx(U[-1][[4, 5, 10, 11]], abs=1e-14)


@pytest.mark.parametrize("e", [0.0, 0.6, 0.9])
def test_kepler_exact_solution_matches_heyoka(e):
    import heyoka as hy

    p = problem("kepler", e=e)
    t = np.linspace(0, 4 * np.pi, 101)
    variables, rhs = p.heyoka_system()
    ta = hy.taylor_adaptive(list(zip(variables, rhs)), p.u0, tol=np.finfo(float).eps)
    U = ta.propagate_grid(t)[-1]
    assert np.max(np.abs(p.exact(t) - U)) < 1e-10
    inv = p.invariants(t, p.exact(t))
    for name in ("H", "L", "A"):
        assert np.max(np.abs(inv[name] - inv[name][0])) < 1e-12
    assert p.exact(np.array([2 * np.pi]))[0] == pytest.approx(p.u0, abs=1e-12)


def test_harmonic_exact_solution_conserves_energy():
    p = problem("harmonic", omega=2.0, q0=0.3, p0=-1.0)
    t = np.linspace(0, 10, 50)
    U = p.exact(t)
    assert U[0] == pytest.approx(p.u0)
    H = p.invariants(t, U)["H"]
    assert np.ptp(H) < 1e-14


def test_outer_solar_system_and_henon_heiles_invariants():
    oss = problem("outer-solar-system")
    drift = invariant_drift(oss, np.linspace(0, 20_000, 101))
    assert drift["H"] < 1e-16 and drift["L"] < 1e-16  # |H| ~ 3e-8: relative 1e-9 or better
    hh = problem("henon-heiles")
    assert hh.invariants(np.zeros(1), hh.u0[None, :])["H"][0] == pytest.approx(1 / 6 - 1e-3, rel=1e-14)
    assert invariant_drift(hh, np.linspace(0, 200, 401))["H"] < 1e-13


@pytest.mark.parametrize("name, settings, word", [
    ("toda", {"d": 2}, "d"), ("kepler", {"e": 1.0}, "e"), ("harmonic", {"omega": 0.0}, "omega"),
    ("henon-heiles", {"energy": 0.2}, "energy"), ("henon-heiles", {"y0": -0.6}, "y0"),
    ("figure-eight-perturbed", {"shift": -1}, "shift"), ("toda", {"n": 3}, "unknown parameter n"),
])
def test_bad_problem_settings(name, settings, word):
    with pytest.raises(InputError, match=word):
        problem(name, **settings)


def test_capabilities_read_off_what_a_problem_provides():
    assert {"rhs", "separable", "exact", "heyoka", "invariants"} <= problem("kepler").capabilities()
    assert "exact" not in problem("toda").capabilities()


def test_reference_on_a_grid_that_starts_after_t0():
    p = problem("toda")
    t = np.linspace(0, 5, 11)
    assert reference_states(p, t[3:]) == pytest.approx(reference_states(p, t)[3:], abs=1e-13)


def test_reference_past_its_time_budget_is_unavailable_not_a_hang():
    from longtime.measure.reference import ReferenceUnavailable

    p = problem("duffing-1")
    with pytest.raises(ReferenceUnavailable, match="time budget"):
        reference_states(p, np.linspace(0, 60, 7), budget_s=0.2)


def test_a_cell_without_reference_keeps_its_status_and_says_why(monkeypatch, tmp_path):
    from longtime.execution import cells

    monkeypatch.setattr("longtime.measure.reference_runs.DEFAULT_BUDGET_S", 0.0)
    monkeypatch.setenv("LONGTIME_CACHE_DIR", str(tmp_path))  # nothing cached: heyoka must run
    row = cells.run_cell(cells.Cell("toda", "rk4", {}, {"dt": 0.1}, 50.0))
    assert row["status"] == "ok" and row["l2_error"] is None and row["H.max"] is not None
    assert "no reference" in row["message"] and "time budget" in row["message"]
