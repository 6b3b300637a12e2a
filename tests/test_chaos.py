"""Chaos measured as chaos: the Lyapunov time of the chaotic problems from the reference, each
row's predictability horizon in Lyapunov times, and lost solutions kept out of orders and
Pareto fronts."""

import numpy as np
import pytest

from longtime.core import registry
from longtime.measure import lyapunov
from longtime.measure.orders import observed_orders
from longtime.reporting.report import pareto

pytest.importorskip("heyoka")


@pytest.mark.slow
def test_double_pendulum_is_chaotic_with_a_lyapunov_time_near_one():
    """The double pendulum (released from rest, far from equilibrium) separates nearby
    states at lambda ~ 1 per unit time: about 100 e-foldings over t = 100."""
    found = lyapunov.measure(registry.problem_class("double-pendulum")())
    lo, hi = found["lyapunov_exponent_ci"]
    assert 0.6 < lo < found["lyapunov_exponent"] < hi < 1.8, found
    assert found["lyapunov_time"] == pytest.approx(1 / found["lyapunov_exponent"])


@pytest.mark.slow
def test_forced_duffing_at_c_half_is_chaotic():
    found = lyapunov.measure(registry.problem_class("duffing-forced")())
    assert found["lyapunov_time"] is not None and 4 < found["lyapunov_time"] < 30, found


def test_a_regular_orbit_gets_no_lyapunov_time():
    """Kepler's orbits are regular: the separation grows like t (shear), so the finite-time
    exponent is positive but no Lyapunov time is stated."""
    found = lyapunov.measure(registry.problem_class("kepler")(), t_span=2000.0)
    assert found["lyapunov_time"] is None
    assert found["lyapunov_note"].startswith("undetermined")


def test_summary_of_synthetic_separations():
    """A separation growing like e^(0.5 t) gives lambda 0.5; one growing like t gives none."""
    tau, n = 0.25, lyapunov.INTERVALS
    rng = np.random.default_rng(3)
    chaotic = lyapunov.summarise(0.5 * tau + 0.01 * rng.standard_normal(n), tau, n * tau)
    assert chaotic["lyapunov_exponent"] == pytest.approx(0.5, rel=0.01)
    assert chaotic["lyapunov_time"] == pytest.approx(2.0, rel=0.01)
    t = tau * np.arange(1, n + 1)
    shear = np.diff(np.log(np.r_[tau / 2, t]))  # ln(d_k / d_(k-1)) for d ~ t
    regular = lyapunov.summarise(shear, tau, n * tau)
    assert regular["lyapunov_time"] is None


@pytest.mark.slow
def test_chaotic_rows_carry_the_lyapunov_time_and_predictability_horizon():
    from longtime import solve

    lost = solve("double-pendulum", "rk4", t_final=30.0, dt=0.01).row
    assert lost["lyapunov_time"] == pytest.approx(lyapunov.measure(registry.problem_class("double-pendulum")())
                                                  ["lyapunov_time"])
    assert lost["predictability_t"] is not None and lost["predictability_t"] <= lost["error_horizon"]
    assert lost["predictability_lyapunov"] == pytest.approx(lost["predictability_t"] / lost["lyapunov_time"])
    assert "Lyapunov times" in lost["predictability_note"]
    kept = solve("duffing-forced", "rk4", t_final=30.0, dt=0.01).row
    assert kept["predictability_t"] is None and kept["predictability_lyapunov"] is None
    assert "beyond" in kept["predictability_note"]
    regular = solve("kepler", "rk4", t_final=5.0, dt=0.01).row
    assert "predictability_t" not in regular and "lyapunov_time" not in regular


def _row(dt, l2, lost, integrator="rk4", cpu=1.0):
    return {"problem": "double-pendulum", "integrator": integrator, "status": "ok", "dt": dt, "t_final": 30.0,
            "l2_error": l2, "cpu_s": cpu, "predictability_t": 12.0 if lost else None, "order": None, "tol": None,
            "eps_res": None, "settings": "", "steps": int(30 / dt)}


@pytest.mark.slow
def test_lost_chaotic_rows_enter_no_order_fit_and_no_pareto_front():
    rows = [_row(0.01, 1e-4, False), _row(0.005, 6.25e-6, False), _row(0.0025, 6.25e-6 / 16, False),
            _row(0.02, 0.9, True, cpu=0.1)]
    front = pareto(rows, "l2_error")
    assert all(entry["best"]["dt"] != 0.02 for entry in front)
    fits = observed_orders(rows)
    fit = next(f for f in fits if f.get("integrator") == "rk4")
    assert fit["observed_order"] == pytest.approx(4.0, abs=1e-9), fit
    assert [p[0] for p in fit["order_points"]] == [0.0025, 0.005, 0.01]  # the lost dt 0.02 left out


@pytest.mark.slow
def test_ensemble_tells_euler_from_rk4_on_the_double_pendulum_past_its_horizon():
    """Past 100 Lyapunov times pointwise errors are O(1) for every scheme, but the distribution
    of the first coordinate over the last half of the run is heyoka's for rk4 (within twice
    the spread between two reference ensembles) and not for explicit Euler."""
    from longtime.commands.ensemble import study

    rows = study(["double-pendulum"], ["rk4", "euler"], dt=0.001, t_final=100.0, members=8)
    by = {r["integrator"]: r for r in rows}
    assert by["rk4"]["span_lyapunov"] > 50
    floor = by["rk4"]["ensemble.floor"]
    assert 0 < floor < 0.2
    assert by["rk4"]["ensemble.distance"] <= 2 * floor, by["rk4"]
    assert by["euler"]["ensemble.distance"] > 5 * floor, by["euler"]
    assert by["euler"]["verdict"].startswith("told apart")


def test_ensemble_refuses_a_regular_problem_and_bad_sizes():
    from longtime.commands.ensemble import study
    from longtime.core.params import InputError

    with pytest.raises(InputError, match="not a chaotic problem"):
        study(["kepler"], ["rk4"])
    with pytest.raises(InputError, match="--size"):
        study(["double-pendulum"], ["rk4"], size=0.0)


@pytest.mark.slow
def test_a_chaotic_figure_is_given_with_its_round_off_spread(capsys):
    """Past its predictability horizon the double pendulum's H.max under rk4 depends on
    round-off: perturbing u0 by a relative 1e-14 moves it, and the spread brackets a range."""
    from longtime.commands.cli import main

    code = main(["roundoff", "--spread", "H.max", "-p", "double-pendulum", "-i", "rk4", "--dt", "0.002",
                 "--t-final", "60", "--ensemble", "4", "--format", "json"])
    assert code == 0
    import json

    out = json.loads(capsys.readouterr().out)
    assert out["field"] == "H.max" and len(out["values"]) == 4
    assert out["min"] < out["max"]  # chaos: round-off moves the figure
    assert main(["roundoff", "--spread", "H.max", "-p", "double-pendulum", "-i", "rk4", "--dt", "0.002"]) == 2


# the chaotic problems measured from their default state (docs/problems.md, "Chaos from the
# default states"): the exponent's 95 % interval, or None where no Lyapunov time is determined
FROM_THE_DEFAULT_STATE = {
    "double-pendulum": (0.82, 1.19),  # over t = 100
    "duffing-forced": (0.076, 0.141),  # over t = 1000
    "fpu": (0.087, 0.117),  # over t = 2000
    "lennard-jones": (390.0, 466.0),  # per ns, over 0.2 ns
    "henon-heiles": None,  # y0 = 0.1 at E = 1/6 - 1e-3: a regular orbit over t = 1e4
    "figure-eight-perturbed": None,  # shift 80: regular over 200 periods (and over t = 1e4)
}


def _chaotic_problems():
    return sorted(name for name, cls in registry.problems().items()
                  if cls.chaotic and cls.__module__.startswith("longtime.problems."))


@pytest.mark.slow
def test_every_chaotic_problem_is_measured_from_its_default_state():
    assert _chaotic_problems() == sorted(FROM_THE_DEFAULT_STATE)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(FROM_THE_DEFAULT_STATE))
def test_which_chaotic_problems_are_chaotic_from_their_default_state(name):
    cls = registry.problem_class(name)
    found = lyapunov.measure(cls())
    expected = FROM_THE_DEFAULT_STATE[name]
    if expected is None:
        # regular: no Lyapunov time, and the problem names the settings where it is chaotic
        assert found["lyapunov_time"] is None and found["lyapunov_note"].startswith("undetermined"), found
        assert cls.chaotic_settings, name
    else:
        lo, hi = found["lyapunov_exponent_ci"]
        assert found["lyapunov_time"] is not None, found
        # the measured interval, each end to 10 %
        assert lo == pytest.approx(expected[0], rel=0.1) and hi == pytest.approx(expected[1], rel=0.1), found
        assert cls.chaotic_settings is None, name


@pytest.mark.slow
@pytest.mark.parametrize("name, lam", [("henon-heiles", (0.101, 0.136)), ("figure-eight-perturbed", (0.0443, 0.109))])
def test_the_chaotic_settings_are_chaotic(name, lam):
    """Henon-Heiles from y0 = 0 (the chaotic sea at E = 1/6 - 1e-3; measured lambda 0.118
    [0.101, 0.136] over t = 1e4) and the figure-eight broken up by shift = 10 (0.0766
    [0.0443, 0.109] over 200 periods): a Lyapunov time, each end of the interval to 10 %."""
    cls = registry.problem_class(name)
    problem = cls(**cls.chaotic_settings)
    found = lyapunov.measure(problem)
    assert found["lyapunov_time"] is not None, found
    lo, hi = found["lyapunov_exponent_ci"]
    assert lo == pytest.approx(lam[0], rel=0.1) and hi == pytest.approx(lam[1], rel=0.1), found


def test_a_regular_default_state_says_where_the_problem_is_chaotic():
    problem = registry.problem_class("henon-heiles")()
    fields = lyapunov.row_fields(problem, {"error_horizon": 100.0, "predictability_t": None})
    assert fields["lyapunov_time"] is None
    assert fields["lyapunov_note"].endswith("; the motion is measured chaotic with --set y0=0 (docs/problems.md)")
    chaotic = registry.problem_class("henon-heiles")(y0=0.0)
    assert "--set" not in lyapunov.row_fields(chaotic, {"error_horizon": 100.0})["lyapunov_note"]
