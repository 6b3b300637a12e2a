"""The growth of a perturbation measured on every problem (longtime.measure.instability), and
the predictability horizon it gives `longtime recommend`: Arenstorf's unstable orbit grows a
rounding of the state by about a hundred a period, Kepler's regular orbit only linearly; a
question past the horizon gets no pointwise answer, with the reason."""
import math

import numpy as np
import pytest

from longtime.core import registry
from longtime.measure import instability as I
from longtime.predict import decision as D
from longtime.predict.decision import predictability
from longtime.reporting import recommend as R

ARENSTORF = 17.0652165601579625588917206249
TWO_PI = 2 * math.pi


def _row(problem, t_final, error, **extra):
    """A stored row whose linear law predicts ``error`` times the horizon's ratio past its run."""
    return {"problem": problem, "integrator": "dop853", "tol": 1e-12, "status": "ok", "l2_error": error,
            "error.growth_class": "linear", "error.growth": 1.0, "error.growth_ci": [0.9, 1.1],
            "cpu_s": 0.05, "t_final": t_final, "settings": "", "reference": "heyoka double",
            "reference_horizon": t_final, "run_id": 1, **extra}


def test_growth_horizon_reads_the_first_time_a_rounding_reaches_the_target():
    t = np.arange(1.0, 11.0)
    g = I.Growth("synthetic", t, np.log(10.0) * t, t0=0.0, period=2.0)  # x10 each unit of t
    assert g.horizon(1e-6) == pytest.approx(10.0)  # 1e-16 * 10^10
    assert g.horizon(1e-10) == pytest.approx(6.0)
    assert g.horizon(1e-3) is None  # not reached over the span measured
    assert g.per_period(10.0) == pytest.approx(100.0)
    assert "x100 a period" in g.text(1e-6) and "past t = 10" in g.text(1e-6)


def test_growth_span_covers_the_horizon_in_steps_of_the_default_final_time():
    p = registry.problem_class("kepler")()
    base = p.default_t_final
    assert I.growth_span(p, 0.5 * base) == base
    assert I.growth_span(p, 3 * base) == pytest.approx(5 * base)
    assert I.growth_span(p, 12566.0) == pytest.approx(200 * base)


def test_arenstorf_grows_a_rounding_about_a_hundred_a_period_and_kepler_only_linearly():
    arenstorf = I.measure(registry.problem_class("restricted-three-body")(), 10 * ARENSTORF)
    per = arenstorf.per_period(10 * ARENSTORF)
    assert 30 < per < 3000, per  # unstable: order a hundred each period
    kepler = I.measure(registry.problem_class("kepler")(), 100 * TWO_PI)
    # regular: a shear, the growth linear in t (ten times the orbits, about ten times the growth)
    assert 3 < kepler.factor_at(100 * TWO_PI) / kepler.factor_at(10 * TWO_PI) < 30
    assert kepler.per_period(100 * TWO_PI) < 1.3
    assert kepler.horizon(1e-7) is None  # a rounding stays far below 1e-7 over a hundred orbits


def test_kepler_keeps_a_rounding_below_1e7_up_to_two_thousand_orbits():
    g = I.measure(registry.problem_class("kepler")(), 12566.0)
    assert g.horizon(1e-7) is None
    rows = [_row("kepler", 100 * TWO_PI, 1e-10)]
    assert predictability(rows, 1e-7, g) is None  # nothing bounds kepler's answer there


def test_recommend_refuses_arenstorf_past_its_horizon_naming_the_growth():
    rows = [_row("restricted-three-body", ARENSTORF, 1e-9, **{"J.max": 2.5e-12, "J.growth_class": "bounded"})]
    # without the growth the linear law answers: 1e-8 predicted at ten periods
    assert R.recommend(rows, "restricted-three-body", 1e-6, 10 * ARENSTORF).answered
    growth = R.measured_growth(rows, "restricted-three-body", 10 * ARENSTORF)
    rec = R.recommend(rows, "restricted-three-body", 1e-6, 10 * ARENSTORF, growth=growth)
    assert not rec.answered
    text = str(rec)
    assert "rounding of the state grows" in text and "a period" in text
    assert rec.decision.limit.horizon < 4 * ARENSTORF
    assert "what can be said: the invariants" in text and "J: 2.5e-12" in text  # what can be said instead
    assert "longtime run" not in text  # the growth forbids every run: none is named to decide it
    # within the horizon it still answers
    assert R.recommend(rows, "restricted-three-body", 1e-6, ARENSTORF, growth=growth).answered


def test_an_error_is_not_claimed_past_the_reference_horizon_of_any_problem():
    rows = [_row("pythagorean-three-body", 70.0, 1e-9, reference_horizon=29.8)]
    rec = R.recommend(rows, "pythagorean-three-body", 1e-6, 70.0)
    assert not rec.answered and "no error is measured past t = 29.8" in str(rec)


def _harmonic(scheme, dt, error, cpu_s, law, alpha):
    return {"problem": "harmonic", "integrator": scheme, "status": "ok", "dt": dt, "t_final": 100.0, "settings": "",
            "cpu_s": cpu_s, "repeats": 3, "l2_error": error, "reference": "exact", "solution_lost": False,
            "error.growth": alpha, "error.growth_ci": [alpha - 0.05, alpha + 0.05], "error.growth_class": law,
            "error.growth_reason": "slopes ...", "run_id": 1}


# rk4 predicted to keep 1e-3 at T = 1000 by its linear law; gauss4 cheaper but its law undetermined
HARMONIC = [_harmonic("verlet", 0.1, 1e-4, 0.01, "linear", 1.0), _harmonic("rk4", 0.1, 1e-6, 0.005, "linear", 1.3),
            _harmonic("gauss4", 0.1, 1e-8, 0.001, "undetermined", 0.6)]


def test_recommend_runs_its_candidates_to_the_horizon_and_answers_measured_at_t():
    predicted = R.recommend(HARMONIC, "harmonic", 1e-3, 1e3)  # no budget: nothing runs
    assert predicted.basis == "predicted" and predicted.scheme == "rk4"
    assert "predicted, not run" in str(predicted)
    assert "`longtime run -p harmonic -i rk4 --dt 0.1 --t-final 1000` runs it to T" in str(predicted)
    rec = R.recommend(HARMONIC, "harmonic", 1e-3, 1e3, budget=30.0)
    assert rec.answered and rec.basis == "measured at T", str(rec)
    assert "measured at T" in rec.lines[0] and "against a reference checked to T" in rec.lines[-1]
    # the candidates run to T keep the target; the answer is the one measured cheapest there (which
    # of gauss4 and rk4 that is, the machine's speed decides), its error measured at T
    assert rec.scheme in ("gauss4", "rk4") and rec.measured_error is not None and rec.measured_error <= 1e-3
    assert rec.measured_cpu_s is not None and rec.measured_cpu_s > 0
    assert "error" in rec.lines[1] and "measured at T" in rec.lines[1]


def test_the_checks_cover_each_class_of_question_where_answers_went_wrong():
    from longtime.execution import checks as XC
    from longtime.predict import checks as PC

    def rows(problem, scale=1.0, t_short=None):
        """HARMONIC's laws over runs ``scale`` times as long (the same CPU per unit time)."""
        out = []
        for r in HARMONIC:
            r = {**r, "problem": problem, "t_final": r["t_final"] * scale, "cpu_s": r["cpu_s"] * scale}
            if t_short is not None and r["integrator"] == "gauss4":  # a short run: its law is not extrapolated
                r.update(t_final=t_short, cpu_s=r["cpu_s"] * t_short / r["t_final"])
            out.append(r)
        return out

    unstable = [_row("restricted-three-body", ARENSTORF, 1e-10)]
    store = unstable + rows("kdv", 0.1) + rows("figure-eight", 20.0) + rows("kepler", t_short=5.0)
    plan = XC.plan_checks(store, limit=10, budget_s=2.0, reference_rate=lambda v: 0.0, total_s=1e9)
    kinds = {c.kind for c in plan}
    assert {"unstable orbit", "discretised PDE", "many-body", "short run"} <= kinds, kinds
    # the unstable orbit's growth check: its most accurate setting run to where a rounding of the
    # state has grown to GROWTH_CHECK_MARGIN times the target; it holds when the error there exceeds it
    growth = next(c for c in plan if c.role == "growth")
    assert growth.kind == "unstable orbit" and growth.target >= XC.GROWTH_MIN_TARGET
    g = I.measure(registry.problem_class("restricted-three-body")(), 10 * ARENSTORF)
    # (no farther than its reference is trusted, rounded down to 3 figures)
    assert g.horizon(growth.target) < growth.horizon <= g.horizon(XC.GROWTH_CHECK_MARGIN * growth.target)
    assert 1e-16 * g.factor_at(growth.horizon) >= XC.GROWTH_CHECK_MARGIN / 10 * growth.target
    # judged by the pointwise error at T (final_error), not the RMS over [0, T]
    c = XC.check_row(growth, {**unstable[0], "t_final": growth.horizon, "l2_error": 3e-7, "final_error": 3e-4,
                              "error_horizon": growth.horizon})
    assert PC.check_holds(c) is True and PC.check_holds({**c, "measured_error": growth.target / 10}) is False
    # a reference that stopped before the growth check's horizon: no growth check (it would not be judged)
    short_ref = [{**unstable[0], "reference_horizon": 20.0, "t_final": ARENSTORF * 2}]
    assert not [c for c in XC.plan_checks(short_ref, limit=10, budget_s=2.0, reference_rate=lambda v: 0.0,
                                          total_s=1e9) if c.role == "growth"]


def test_a_budget_that_cannot_pay_the_reference_to_t_runs_nothing_and_says_so(monkeypatch):
    from longtime.execution import answers

    monkeypatch.setattr(answers, "reference_seconds", lambda s, horizon, budget_s: 1e3)
    rec = R.recommend(HARMONIC, "harmonic", 1e-3, 1e3, budget=5.0)
    assert rec.basis == "predicted" and rec.scheme == "rk4"
    assert "predicted, not run: the answer lies past the stored runs and nothing ran: its reference check to T is " \
           "estimated at 1e+03 s" in str(rec)


def test_the_winner_map_honours_the_growth_as_recommend_does():
    rows = [_row("restricted-three-body", ARENSTORF, 1e-9)]
    t = ARENSTORF * np.arange(1.0, 11.0)
    grown = I.Growth("restricted-three-body", t, np.log(100.0) * np.arange(1.0, 11.0))  # x100 a period
    cell = (1e-6, 10 * ARENSTORF)  # a rounding reaches 1e-6 after five periods
    assert D.problem_verdict("restricted-three-body", rows).grid[cell].state == "predicted"
    bounded = D.verdicts(rows, growths={"restricted-three-body": grown})["restricted-three-body"]
    assert bounded.grid[cell].state == "chaotic" and bounded.grid[cell].best is None
    assert bounded.grid[cell].limit.horizon == pytest.approx(5 * ARENSTORF)
    assert bounded.grid[(1e-6, ARENSTORF)].state == "predicted"  # within it, the law answers
    # the same cell as `longtime recommend` answers it
    assert not R.recommend(rows, "restricted-three-body", *cell, growth=grown).answered


def test_a_measured_growth_is_read_back_and_nothing_is_run_for_the_map(tmp_path, monkeypatch):
    monkeypatch.setenv("LONGTIME_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(I, "_MEASURED", {})
    p = registry.problem_class("kepler")()
    rows = [_row("kepler", p.default_t_final, 1e-10)]
    assert I.measured(p, 1e6 * p.default_t_final) is None  # nothing measured yet: none, and no run
    assert R.map_growths(rows) == {}
    g = I.measure(p, 3 * p.default_t_final)  # over five times the default final time
    monkeypatch.setattr(I, "_MEASURED", {})  # a later process: read back from the disk
    back = I.measured(p, 1e6 * p.default_t_final)
    assert back is not None and back.t[-1] == pytest.approx(5 * p.default_t_final)
    assert np.array_equal(back.log_growth, g.log_growth)
    assert I.measured(p, 2 * p.default_t_final) is None  # the span measured lies past what is asked
    assert np.array_equal(R.map_growths(rows)["kepler"].log_growth, g.log_growth)
