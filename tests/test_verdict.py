"""The verdict (longtime.predict, its text longtime.reporting.verdict) on synthetic rows whose laws are known, and
`longtime recommend` on a store of them: who wins where, what is left undetermined and the
run that would decide it, and bad input as one line with exit 2."""
import json
import math
import re

import pytest

from longtime.commands import cli
from longtime.execution import checks as XC
from longtime.execution.cells import Cell
from longtime.execution.store import Store
from longtime.predict import checks as PC
from longtime.predict import decision as D
from longtime.predict import settings as S
from longtime.reporting import recommend as R
from longtime.reporting import verdict as T


def _row(scheme, dt, error, cpu_s, law, alpha, t_final=100.0, problem="harmonic", reason="slopes ..."):
    return {"problem": problem, "integrator": scheme, "status": "ok", "dt": dt, "order": None, "tol": None,
            "eps_res": None, "t_final": t_final, "settings": "", "cpu_s": cpu_s, "repeats": 3,
            "l2_error": error, "final_error": error, "reference": "exact", "solution_lost": False,
            "error.growth": alpha, "error.growth_ci": [alpha - 0.05, alpha + 0.05], "error.growth_class": law,
            "error.growth_reason": reason, "H.max": 1e-6, "H.growth_class": "bounded", "H.growth": 0.0}


# verlet: linear from 1e-4, 1e-4 s per unit time; rk4: linear from 1e-6, half verlet's cost;
# gauss4: the most accurate and the cheapest, but its growth is undetermined
SLOW = _row("verlet", 0.1, 1e-4, 0.01, "linear", 1.0)
LINEAR = _row("rk4", 0.1, 1e-6, 0.005, "linear", 1.3)  # a fitted alpha of 1.3: the class says 1
OPEN = _row("gauss4", 0.1, 1e-8, 0.001, "undetermined", 0.6, reason="pre-asymptotic: slopes 0.2, 0.6, 1.1")
ROWS = [SLOW, LINEAR, OPEN]
# the same settings judged by an invariant's error (no reference), verlet's bounded
BOUNDED = _row("verlet", 0.1, 1e-4, 0.01, "bounded", 0.02)


def _invariant(rows):
    return [{**r, "l2_error": None, "final_error": None, "error.growth_class": None, "H.max": r["l2_error"],
             "H.growth_class": r["error.growth_class"], "H.growth": r["error.growth"]} for r in rows]


def test_the_linear_scheme_wins_short_the_bounded_one_long():
    rows = _invariant([BOUNDED, LINEAR, OPEN])
    cands = S.settings(rows, S.measure(rows))
    short = D.decide(cands, 1e-3, 1e3)
    assert short.best.scheme == "rk4" and short.runner_up.scheme == "verlet"
    # rk4's error at T is its error at its t_final times (T / t_final)^1, the class's exponent
    assert short.best.error_at(1e3) == pytest.approx(1e-5) and short.best.cpu_at(1e3) == pytest.approx(0.05)
    assert short.best.error_at(1e5) == pytest.approx(1e-3)
    long = D.decide(cands, 5e-4, 1e5)  # rk4 predicts 1e-3 there: the bounded scheme is the only one
    assert long.best.scheme == "verlet" and long.runner_up is None
    assert long.best.error_at(1e5) == pytest.approx(1e-4) and long.best.cpu_at(1e5) == pytest.approx(10.0)


def test_a_class_is_trusted_only_to_its_reach():
    # an invariant's classes: 1000 times the run; past it, undetermined with the deciding run
    inv = _invariant([BOUNDED, LINEAR, OPEN])
    verlet, rk4 = (next(s for s in S.settings(inv, S.measure(inv)) if s.scheme == k) for k in ("verlet", "rk4"))
    assert verlet.reach == 100.0 * S.TRUST_FACTORS["invariant"]["bounded"] == 1e5
    assert verlet.error_at(1e5) == 1e-4 and verlet.state_at(1e5) == "predicted"
    assert verlet.error_at(1.01e5) is None and verlet.state_at(1.01e5) == "undetermined"
    d = D.decide(S.settings(inv, S.measure(inv)), 1e-3, 1e6)
    assert d.best is None and {s.scheme for s in d.open} == {"verlet", "rk4", "gauss4"}
    assert "not determined past t = 1e+05 (1000 times its run)" in verlet.undetermined_text(1e6)
    # a solution error classed bounded is not extrapolated past its run at all
    sol = [{**BOUNDED}, LINEAR]
    bounded = next(s for s in S.settings(sol, S.measure(sol)) if s.scheme == "verlet")
    assert S.TRUST_FACTORS["solution"]["bounded"] == 1.0 and not bounded.extrapolates
    assert bounded.error_at(100.0) == 1e-4 and bounded.error_at(101.0) is None
    assert "not trusted past its run" in bounded.law_text()
    d = D.decide(S.settings(sol, S.measure(sol)), 1e-3, 1e4)  # verlet would have predicted 1e-4 flat
    assert d.best.scheme == "rk4" and d.runner_up is None
    coarser = {**LINEAR, "l2_error": 1e-5, "final_error": 1e-5}  # rk4 predicts 1e-3 at 1e4
    rec = R.recommend([{**BOUNDED}, coarser], "harmonic", 2e-4, 1e4)  # no answer, the run that decides
    assert not rec.answered and rec.scheme is None
    assert re.search(r"verlet dt=0.1 keeps it to t = 100 but its growth is bounded: flat, not trusted past its run.*"
                     r"`longtime run -p harmonic -i verlet --dt 0.1 --t-final 10000`", str(rec))
    # a linear solution error: 100 times its run; every horizon of the map past it is undetermined
    rk4 = next(s for s in S.settings(ROWS, S.measure(ROWS)) if s.scheme == "rk4")
    assert rk4.reach == 100.0 * S.TRUST_FACTORS["solution"]["linear"] == 1e4
    assert "not determined past t = 1e+04 (100 times its run)" in rk4.undetermined_text(1e5)
    v = D.problem_verdict("harmonic", ROWS)
    assert all(v.grid[(t, h)].best is None for t in v.targets for h in v.horizons if h > 1e4)


def test_a_solution_error_is_trusted_less_where_an_invariant_drifts_or_its_slopes_steepen():
    # rk4's energy drifts linearly: its linear solution error (t^1, 1 < 1 + 1) is trusted
    # ten times its run
    drifting = {**LINEAR, "H.growth_class": "linear", "H.growth": 1.0}
    s = S.settings([drifting], S.measure([drifting]))[0]
    assert s.kind == "drifting" and s.reach == 100.0 * S.TRUST_FACTORS["drifting"]["linear"] == 1e3
    assert s.error_at(1e3) == pytest.approx(1e-5) and s.error_at(1.01e3) is None
    assert "trusted to t = 1000, the energy drifts" in s.law_text()
    # a quadratic solution error of a linear energy drift already grows like t^(1 + 1)
    quad = {**drifting, "error.growth_class": "quadratic"}
    assert S.settings([quad], S.measure([quad]))[0].kind == "solution"
    rising = {**LINEAR, "H.growth_class": "undetermined", "H.growth_windows": [0.45, 0.69, 0.88]}
    assert S.settings([rising], S.measure([rising]))[0].kind == "drifting"  # the energy still steepening
    level = {**LINEAR, "H.growth_class": "undetermined", "H.growth_windows": [0.3, 0.1, 0.2]}
    assert S.settings([level], S.measure([level]))[0].kind == "solution"
    other = {**LINEAR, "L.growth_class": "linear"}  # another invariant's drift (a precession) does not count
    assert S.settings([other], S.measure([other]))[0].kind == "solution"
    # window slopes rising past the class's exponent: not extrapolated
    steep = {**LINEAR, "error.growth_windows": [1.16, 1.28, 1.46]}
    s = S.settings([steep], S.measure([steep]))[0]
    assert s.steepening and not s.extrapolates and s.error_at(101.0) is None
    assert "window slopes 1.16, 1.28, 1.46 rise past t^1" in s.law_text()
    # slopes that fall toward the class: trusted, at most as far as the latest slope (1.3)
    # would move the prediction by 3: 3^(1 / 0.3) = 38.9 times the run
    falling = {**LINEAR, "error.growth_windows": [1.43, 1.40, 1.3]}
    s = S.settings([falling], S.measure([falling]))[0]
    assert not s.steepening and s.factor == pytest.approx(3 ** (1 / 0.3))
    near = {**LINEAR, "error.growth_windows": [1.43, 1.40, 1.06]}
    assert S.settings([near], S.measure([near]))[0].factor == 100.0


def test_a_predicted_error_of_o1_is_lost():
    coarse = _row("euler", 0.1, 1e-2, 1e-4, "linear", 1.0)  # 1 at 100 times its run
    s = S.settings([coarse], S.measure([coarse]))[0]
    assert s.state_at(1e3) == "predicted" and s.error_at(1e3) == pytest.approx(0.1)
    assert s.state_at(5e3) == "lost" and s.error_at(5e3) is None  # 0.5: O(1)
    assert s.state_at(1e4) == "lost"
    assert s.state_at(2e4) == "undetermined"  # past its reach nothing is predicted, not even lost
    d = D.decide([s], 0.9, 1e4)
    assert d.best is None and d.open == [] and d.state == "none"
    rec = R.recommend([coarse], "harmonic", 0.9, 1e4)
    assert not rec.answered and "1 setting predicted lost there (error >= 0.5)" in str(rec)


def test_undetermined_predicts_nothing_past_its_run_and_names_the_run_that_decides():
    cands = S.settings(ROWS, S.measure(ROWS))
    gauss = next(s for s in cands if s.scheme == "gauss4")
    assert gauss.error_at(100.0) == 1e-8 and gauss.error_at(50.0) == 1e-8  # its own run: measured
    assert gauss.error_at(101.0) is None and not gauss.extrapolates
    d = D.decide(cands, 1e-2, 1e4)
    assert d.best.scheme == "rk4" and [s.scheme for s in d.open] == ["gauss4"]  # cheaper than rk4, law unknown
    assert D.decide(cands, 1e-3, 100.0).best.scheme == "gauss4"  # within its run it is measured
    # a target only gauss4 keeps over its run: undetermined, not a winner
    d = D.decide(cands, 1e-7, 1e4)
    assert d.best is None and d.state == "undetermined"
    assert D.deciding_run(gauss, 1e4) == "longtime run -p harmonic -i gauss4 --dt 0.1 --t-final 10000"
    assert D.deciding_run(gauss, 10.0).endswith("--t-final 1000")  # at least a decade past its run
    assert D.decide(cands, 1e-12, 1e4).state == "none"


def test_winner_map_spans_the_horizons_past_the_runs():
    v = D.problem_verdict("harmonic", ROWS)
    assert v.horizons[0] == 100.0 and v.horizons[-1] == 1e8
    assert v.grid[(1e-3, 1e3)].best.scheme == "rk4" and v.grid[(1e-3, 1e4)].best.scheme == "rk4"
    assert v.grid[(1e-3, 1e5)].state == "undetermined"  # past rk4's reach
    assert v.grid[(1e-4, 1e4)].best.scheme == "rk4" and v.grid[(1e-4, 1e5)].state == "undetermined"
    # the targets some setting reaches, and one decade finer
    assert v.targets[0] == 1e-1 and v.targets[-1] == 1e-9
    text = "\n".join(T.verdict_lines(v))
    assert "rk4 dt=0.1" in text
    assert "`longtime run -p harmonic -i gauss4 --dt 0.1 --t-final 1000`" in text
    assert ("trusted: solution error: bounded x1, sqrt x1, linear x100, quadratic x1000; the energy drifting: "
            "bounded x1, sqrt x1, linear x10, quadratic x10") in text
    assert ("not determined past t = 1e+04 (the farthest reach; the most accurate there, rk4 dt=0.1): "
            "`longtime run -p harmonic -i rk4 "
            "--dt 0.1 --t-final 1e+08` would decide it") in text


def test_rows_without_a_reference_are_judged_by_the_energy_error():
    rows = _invariant([BOUNDED, LINEAR, OPEN])
    m = S.measure(rows)
    assert (m.field, m.law) == ("H.max", "H") and "no reference" in m.text
    assert D.decide(S.settings(rows, m), 5e-4, 1e5).best.scheme == "verlet"


def test_a_lost_or_saturated_row_is_no_candidate():
    lost = {**LINEAR, "integrator": "euler", "solution_lost": True}
    saturated = {**LINEAR, "integrator": "midpoint", "error.growth_class": "saturated"}
    assert {s.scheme for s in S.settings([lost, saturated, *ROWS], S.measure(ROWS))} == {"verlet", "rk4", "gauss4"}


def test_checks_are_planned_as_groups_that_test_the_rank_within_budget():
    # rk4 wins past its run; a check runs it with its runner-up (verlet) and its cheaper open
    # rival (gauss4) at the farthest horizon whose predicted CPU (1e-4 + 5e-5 + 1e-5 s per
    # unit time) fits the budget: 1e4 within 2 s, 1e5 not
    free = lambda v: 0.0  # no reference to pay for  # noqa: E731
    plan = XC.plan_checks(ROWS, limit=6, budget_s=2.0, reference_rate=free, total_s=1e9)
    assert {(c.setting.scheme, c.role, c.horizon) for c in plan} == {
        ("rk4", "best", 1e4), ("verlet", "runner-up", 1e4), ("gauss4", "open", 1e4)}
    assert len({c.group for c in plan}) == 1 and plan[0].kind == "splitting"  # verlet needs a separable H
    assert all(c.horizon <= c.setting.reach for c in plan if c.role == "best")
    wide = XC.plan_checks(ROWS, limit=6, budget_s=1e3, reference_rate=free, total_s=1e9)
    assert {c.horizon for c in wide} == {1e4}  # not past rk4's reach (1e4)
    # the total time bounds the checks: TIMED_RUNS x the predicted CPU, plus the reference's;
    # a group that does not fit is planned at a nearer horizon where rk4 still wins past its run
    near = XC.plan_checks(ROWS, budget_s=2.0, reference_rate=free, total_s=1.0)
    assert {c.horizon for c in near} == {1e3} and XC.TIMED_RUNS * sum(c.predicted_cpu() for c in near) <= 1.0
    assert XC.plan_checks(ROWS, budget_s=2.0, reference_rate=free, total_s=0.1) == []
    assert XC.plan_checks(ROWS, budget_s=1e-4, reference_rate=free) == []
    slow = XC.plan_checks(ROWS, limit=6, budget_s=2.0, reference_rate=lambda v: 1e-3, total_s=1e9)
    assert {c.horizon for c in slow} == {1e3}  # its reference would take 10 s to 1e4: past half of CHECK_REFERENCE_S
    assert XC.plan_checks(ROWS, budget_s=2.0, reference_rate=lambda v: float("inf"), total_s=1e9) == []
    # a bounded solution error is not extrapolated, so never checked past its run
    assert XC.plan_checks([BOUNDED], budget_s=1e3, reference_rate=free) == []
    best = next(c for c in plan if c.role == "best")
    row = {**LINEAR, "t_final": 1e4, "l2_error": 2.5e-4, "cpu_s": 0.6, "error_horizon": 1e4}
    assert XC.check_row(best, {**row, "error_horizon": 5e3})["measured_error"] is None  # the reference stopped short
    c = XC.check_row(best, row)
    assert c["predicted_error"] == pytest.approx(1e-4) and c["predicted_cpu_s"] == pytest.approx(0.5)
    assert c["check_role"] == "best" and c["check_target"] == best.target
    assert PC.check_holds(c) is True  # within x3 and x1.5
    assert PC.check_holds({**c, "measured_error": 4e-4}) is False
    assert PC.check_holds({**c, "cpu_s": 0.8}) is False
    assert PC.check_holds({**c, "measured_error": None}) is None
    # the rule: error within [1/3, 3] of the predicted, CPU at most x1.5 the predicted
    assert (PC.CHECK_ERROR_FACTOR, PC.CHECK_COST_FACTOR) == (3.0, 1.5)
    p = {**c, "predicted_error": 1e-4, "predicted_cpu_s": 0.5}
    assert PC.check_holds({**p, "measured_error": 2.99e-4, "cpu_s": 0.7499}) is True
    assert PC.check_holds({**p, "measured_error": 1e-4 / 3.01}) is False
    assert PC.check_holds({**p, "cpu_s": 0.7501}) is False
    # the rank: an open rival that kept the target at less than 1 / 1.5 of the winner's CPU fails it
    opener = next(x for x in plan if x.role == "open")
    cheap = XC.check_row(opener, {**OPEN, "t_final": 1e4, "l2_error": best.target / 2, "cpu_s": 0.3,
                                 "error_horizon": 1e4})
    dear = {**cheap, "cpu_s": 0.5}
    records = [dict(c), cheap]
    PC.judge_ranks(records)
    assert records[0]["rank_held"] is False and PC.check_holds(records[0]) is False and PC.check_holds(cheap) is None
    records = [dict(c), dear]
    PC.judge_ranks(records)
    assert records[0]["rank_held"] is True and PC.check_holds(records[0]) is True
    missed = {**cheap, "l2_error": best.target * 2, "measured_error": best.target * 2}  # it did not keep the target
    records = [dict(c), missed]
    PC.judge_ranks(records)
    assert records[0]["rank_held"] is None and PC.check_holds(records[0]) is True
    failed = {**c, "measured_error": 4e-4}
    assert PC.check_counts([c, failed, cheap]) == {"held": 1, "failed": 1, "unjudged": 1}
    assert T.failed_first([c, cheap, failed]) == [failed, cheap, c]
    assert PC.check_summary([c, failed]).startswith("1 of 2 checked predictions held")
    assert "; 1 failed" in PC.check_summary([c, failed])


@pytest.fixture
def store(tmp_path):
    db = tmp_path / "v.sqlite"
    s = Store(db)
    cells = [Cell(r["problem"], r["integrator"], {}, {"dt": r["dt"]}, r["t_final"]) for r in ROWS]
    run = s.begin_run("matrix -p harmonic", cells)
    for c, r in zip(cells, ROWS):
        s.add_row(run, c, r)
    s.finish_run(run, "done")
    return str(db)


def test_recommend_answers_in_a_few_lines(store, capsys):
    assert cli.main(["recommend", "-p", "harmonic", "--error", "1e-3", "--horizon", "1e3", "--db", store,
                     "--budget", "0"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) <= 6
    assert lines[0].startswith("harmonic: keep l2_error <= 0.001 up to T = 1000")
    assert lines[1].startswith("  use      rk4 dt=0.1: error 1e-05 at T") and "CPU 0.05 s" in lines[1]
    assert lines[2].startswith("  runner-up verlet dt=0.1") and "x2 the CPU" in lines[2]
    assert lines[-1].startswith("  evidence: 3 settings (2 with a growth law that extrapolates)")
    assert cli.main(["recommend", "-p", "harmonic", "--error", "0.02", "--horizon", "1e4", "--db", store,
                     "--budget", "0"]) == 0
    out = capsys.readouterr().out
    assert ("use      rk4 dt=0.1: error 0.0001 at T (linear: t^1, alpha 1.30 [1.25, 1.35] fitted, "
            "trusted to t = 1e+04") in out
    assert "runner-up verlet dt=0.1: error 0.01 at T" in out
    assert "open     gauss4 dt=0.1" in out and "--t-final 10000 --db" in out
    # past every setting's reach nothing is predicted: no answer (exit 3), naming the run that decides
    assert cli.main(["recommend", "-p", "harmonic", "--error", "0.02", "--horizon", "1e5", "--db", store,
                     "--budget", "0"]) == 3
    assert "`longtime run -p harmonic -i gauss4 --dt 0.1 --t-final 100000" in capsys.readouterr().out


def test_recommend_library_is_the_cheapest_setting_of_one_library(store, capsys):
    import longtime

    assert longtime.recommend("harmonic", 1e-3, 1e3, db=store, library="longtime", budget=0).scheme == "rk4"
    assert cli.main(["recommend", "-p", "harmonic", "--error", "1e-3", "--horizon", "1e3", "--db", store,
                     "--library", "scipy"]) == R.NO_ANSWER_EXIT
    out = capsys.readouterr().out
    assert out.startswith("harmonic: no answer from scipy: no rows of its schemes in the store; "
                          "`longtime matrix -p harmonic -i ")
    assert "scipy-rk45" in out
    assert cli.main(["recommend", "-p", "harmonic", "--error", "1e-3", "--horizon", "1e3", "--db", store,
                     "--library", "nope"]) == 2
    err = capsys.readouterr().err
    assert "--library nope: unknown library; known:" in err and len(err.strip().splitlines()) == 1


def test_recommend_from_python_is_the_same_answer(store):
    import longtime

    rec = longtime.recommend("harmonic", 1e-3, 1e3, db=store, budget=0)
    assert (rec.scheme, rec.setting, rec.runner_up) == ("rk4", "dt=0.1", "verlet dt=0.1")
    assert rec.predicted_error == pytest.approx(1e-5) and rec.predicted_cpu_s == pytest.approx(0.05)
    # from rows in memory: the same answer (the deciding runs name no store)
    assert longtime.recommend("harmonic", 1e-3, 1e3, rows=ROWS, budget=0).lines[:3] == rec.lines[:3]


@pytest.mark.parametrize("args, message", [
    (["-p", "nope", "--error", "1e-3", "--horizon", "1e3"], "-p nope: unknown problem; known:"),
    (["-p", "harmonic", "--error", "0", "--horizon", "1e3"], "--error takes a finite number > 0, got '0'"),
    (["-p", "harmonic", "--error", "1e-3", "--horizon", "-5"], "--horizon takes a finite number > 0, got '-5'"),
    (["-p", "harmonic", "--error", "1e-3", "--horizon", "1e3", "--budget", "-1"],
     "--budget takes a number of seconds >= 0 and <= 1e+09, got '-1'"),
])
def test_recommend_bad_input_is_one_line_exit_2(store, capsys, args, message):
    try:
        code = cli.main(["recommend", *args, "--db", store])
    except SystemExit as exc:  # argparse's errors (the guard's parser: one line)
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1, err


@pytest.mark.parametrize("args, message", [
    (["-p", "kepler", "--error", "1e-3", "--horizon", "1e3"],
     "no rows of kepler in the store; `longtime matrix -p kepler"),
    (["-p", "harmonic", "--error", "1e-7", "--horizon", "1e4"],
     "`longtime run -p harmonic -i gauss4 --dt 0.1 --t-final 10000"),
    (["-p", "harmonic", "--error", "1e-12", "--horizon", "1e4"], "no stored setting keeps l2_error <= 1e-12"),
])
def test_recommend_without_a_determined_answer_says_why_exit_3(store, capsys, args, message):
    assert cli.main(["recommend", *args, "--db", store, "--budget", "0"]) == R.NO_ANSWER_EXIT == 3
    out = capsys.readouterr()
    assert message in out.out and out.out.startswith(f"{args[1]}: no answer for ") and out.err == ""


def test_recommend_without_a_store_names_the_command(tmp_path, capsys):
    missing = str(tmp_path / "none.sqlite")
    assert cli.main(["recommend", "-p", "kepler", "--error", "1e-6", "--horizon", "1e5", "--db", missing]) == 2
    err = capsys.readouterr().err
    assert f"no such file; `longtime matrix -p kepler --db {missing}`" in err
    assert not (tmp_path / "none.sqlite").exists()


def test_recommend_on_a_store_of_no_verdict_names_the_command(tmp_path):
    rec = R.recommend([{**LINEAR, "status": "diverged"}], "harmonic", 1e-3, 1e3)
    assert not rec.answered
    assert re.search(r"no ok row of harmonic with an error.*`longtime matrix -p harmonic`", str(rec))


def test_checks_are_stored_apart_from_the_rows(store):
    s = Store(store)
    cell = Cell("harmonic", "rk4", {}, {"dt": 0.1}, 1e4)
    s.add_check(1, cell, {"problem": "harmonic", "integrator": "rk4", "predicted_error": 1e-4})
    assert [c["predicted_error"] for c in s.checks(1)] == [1e-4] and s.checks(2) == []
    assert len(s.rows(1)) == 3  # no row of the run is added
    assert json.loads(json.dumps(s.checks()))[0]["run_id"] == 1


def test_checks_of_a_real_run_hold_and_are_stored(tmp_path):
    """rk4 on the harmonic oscillator: its solution error grows linearly (the phase), so the
    RMS error predicted at 100 and 1000 times the run holds within x3 when run there; the
    checks are stored beside the run, the report and the page show them."""
    from longtime.reporting.page import build_page
    from longtime.reporting.report import summary

    db = str(tmp_path / "c.sqlite")
    assert cli.main(["matrix", "-p", "harmonic", "-i", "rk4", "--dt", "0.1,0.05", "--t-final", "50", "--repeats", "3",
                     "--min-time", "0", "--db", db, "--executor", "serial", "--no-progress", "--no-report",
                     "--checks", "0"]) == 0
    store = Store(db)
    rows = store.rows(1)
    assert store.checks(1) == [] and all(r["error.growth_class"] == "linear" for r in rows)
    planned = {(c.setting.row["dt"], c.horizon) for c in XC.plan_checks(rows, budget_s=0.05)}  # from the rows' CPU
    checks = XC.run_checks(store, 1, rows, budget_s=0.05)
    assert {(c["dt"], c["t_final"]) for c in checks} == planned and len(planned) == 2
    assert all(c["t_final"] >= 10 * c["from_t_final"] for c in checks)  # well past the run
    for c in checks:
        assert PC.check_holds(c) is not None
        assert c["measured_error"] == pytest.approx(c["predicted_error"], rel=0.5)  # the law holds that far
        assert c["check_field"] == "max_error" and c["from_t_final"] == 50.0  # the largest error up to T
    assert store.checks(1) == [{"run_id": 1, **c} for c in checks] and len(store.rows(1)) == 2
    text = summary(rows, checks=store.checks(1))
    assert "  checks: " in text and "2 checked predictions held" in text
    page = build_page(rows, [], drift=False, stability=False, checks=store.checks(1))
    assert '<h2 id="checks">' in page and "checked: held" in page


def test_a_checks_reference_cost_is_known_before_it_runs():
    """The reference check's runs are timed per unit of t before a check is planned: a finite
    rate for KdV's integrating-factor reference and for one checked against long double
    (the harmonic oscillator)."""
    from longtime.execution.cells import build
    from longtime.measure.reference import check_seconds_per_t

    # a budget that a loaded machine does not exhaust: the rate is finite wherever the run
    # reaches anything, and this test asks only that it does
    kdv = build(Cell("kdv", "rk4", {"d": 32}, {"dt": 0.01}, 1.0))[0]
    assert 0 < check_seconds_per_t(kdv, 1.0, budget_s=120.0) < float("inf")
    harmonic = build(Cell("harmonic", "rk4", {}, {"dt": 0.1}, 10.0))[0]
    rate = check_seconds_per_t(harmonic, 100.0, budget_s=120.0)
    assert 0 < rate < float("inf")
    v = D.problem_verdict("harmonic", ROWS)
    assert XC.reference_seconds_per_t(v) > 0
    inv = _invariant(ROWS)
    assert XC.reference_seconds_per_t(D.problem_verdict("harmonic", inv)) == 0.0  # no reference needed


def test_a_checks_reference_rate_is_measured_once_a_machine(tmp_path, monkeypatch):
    """The rate is measured on the first main job of a machine and read back by the next ones
    (its measure is seconds of the main process on every run); another machine measures it again."""
    from longtime.execution import run_environment
    from longtime.measure import reference

    monkeypatch.setenv("LONGTIME_CACHE_DIR", str(tmp_path))
    calls = []
    monkeypatch.setattr(reference, "check_seconds_per_t", lambda *a, **k: calls.append(a) or 2.5e-4)
    v = D.problem_verdict("harmonic", ROWS)
    assert XC.reference_seconds_per_t(v) == 2.5e-4 and XC.reference_seconds_per_t(v) == 2.5e-4
    assert len(calls) == 1
    here = run_environment.this_machine()
    monkeypatch.setattr(run_environment, "this_machine", lambda: {**here, "node": "another-host"})
    assert XC.reference_seconds_per_t(v) == 2.5e-4 and len(calls) == 2


def test_a_horizon_within_the_run_reads_the_error_reached_there():
    # rk4's error curve: the l2_error up to t grows linearly to its run's 1e-6 at t = 100
    curve = {"curve": "solution", "t": [1.0, 10.0, 50.0, 100.0], "error": [1e-8, 1e-7, 5e-7, 1e-6],
             "l2": [1e-8, 1e-7, 5e-7, 1e-6]}
    row = {**LINEAR, "error_curve": curve}
    s = S.settings([row], S.measure([row]))[0]
    assert s.error_at(10.0) == pytest.approx(1e-7)  # not the run's 1e-6 over [0, 100]
    assert s.error_at(30.0) == pytest.approx(5e-7)  # between two points: the larger
    assert s.error_at(100.0) == 1e-6 and s.error_at(1e3) == pytest.approx(1e-5)  # past the run: the law
    # a target the run keeps to t = 10 but not over its whole span wins at 10, not at 100
    assert D.decide([s], 2e-7, 10.0).best is s and D.decide([s], 2e-7, 100.0).best is None
    bare = S.settings([LINEAR], S.measure([LINEAR]))[0]  # a row stored without a curve: the run's error
    assert bare.error_at(10.0) == 1e-6


def test_the_cost_model_has_fixed_and_per_time_parts_from_runs_of_two_lengths():
    # heyoka-like: 1.4 ms fixed (set-up, 10,001 samples) + 1e-6 s per unit time
    short = {**LINEAR, "integrator": "heyoka", "dt": None, "tol": 1e-12, "t_final": 1e3, "cpu_s": 0.0024,
             "l2_error": 1e-7}
    long = {**short, "t_final": 1e4, "cpu_s": 0.0114, "l2_error": 1e-6}
    s = S.settings([short, long], S.measure([short, long]))
    assert len(s) == 1 and s[0].span == 1e4  # one setting: its longest run
    m = s[0].cost
    assert m.basis == "fixed + per-time" and m.fixed == pytest.approx(0.0014) and m.per_t == pytest.approx(1e-6)
    assert s[0].cpu_at(1e5) == pytest.approx(0.1014)  # a per-time model from the long run alone: 0.114
    assert "0.0014 s fixed + 1e-06 s per unit time, fitted on runs to t = 1000, 1e+04" in m.text()
    one = S.settings([long], S.measure([long]))[0].cost
    assert one.basis == "per-time" and one.at(1e5) == pytest.approx(0.114) and "one run to t = 1e+04" in one.text()
    # a fit with a negative fixed part (timing noise) falls back to per-time from the longest run
    noisy = S.cost_model([(1e3, 0.0020), (1e4, 0.0300)])
    assert noisy.basis == "per-time" and noisy.at(1e4) == pytest.approx(0.03)
    assert S.cost_model([(1e3, 0.001), (1.5e3, 0.0012)]).basis == "per-time"  # lengths too close


def _chaotic(rows, t_lyap=0.99, ref_horizon=None):
    return [{**r, "problem": "double-pendulum", "reference": "heyoka long double", "lyapunov_time": t_lyap,
             "reference_horizon": ref_horizon if ref_horizon is not None else r["t_final"]} for r in rows]


def test_no_pointwise_prediction_past_the_predictability_horizon():
    rows = _chaotic([_row("gauss6", 0.004, 8e-12, 0.002, "quadratic", 2.0, t_final=10.0),
                     _row("rk4", 0.004, 1e-4, 0.0005, "linear", 1.0, t_final=10.0)])
    p = D.predictability(rows, 1e-5)
    assert p.horizon == pytest.approx(0.99 * math.log(1e-5 / 1e-16)) and p.lyapunov_time == 0.99
    assert D.predictability([LINEAR], 1e-5) is None  # not chaotic
    # the reference's trusted horizon caps it where a row's check ended before its run
    capped = _chaotic([{**rows[0], "t_final": 40.0}], ref_horizon=20.0)
    assert D.predictability(capped, 1e-5).horizon == 20.0
    rec = R.recommend(rows, "double-pendulum", 1e-5, 1e4)
    assert not rec.answered and rec.scheme is None and rec.decision.state == "chaotic"
    text = str(rec)
    assert "no double-precision scheme keeps a pointwise error of 1e-05 past t = 25.08 (" in text
    assert "Lyapunov time 0.99" in text and "`longtime ensemble -p double-pendulum`" in text
    # a statistical answer where the store holds ensembles
    ens = [{"problem": "double-pendulum", "integrator": "gauss6", "status": "ok", "distance": 0.01, "floor": 0.01},
           {"problem": "double-pendulum", "integrator": "rk4", "status": "ok", "distance": 0.5, "floor": 0.01}]
    rec = R.recommend(rows, "double-pendulum", 1e-5, 1e4, ensembles=ens)
    assert "statistically: gauss6 (distance 0.01, floor 0.01) keeps the distribution" in str(rec)
    # below the horizon, a chaotic solution error is not extrapolated past its run
    s = next(c for c in S.settings(rows, S.measure(rows)) if c.scheme == "gauss6")
    assert s.kind == "chaotic" and not s.extrapolates and s.error_at(20.0) is None
    assert "a chaotic problem: Lyapunov time 0.99" in s.law_text()
    assert R.recommend(rows, "double-pendulum", 1e-5, 10.0).scheme == "gauss6"  # measured over its run
    # the map: every cell past the horizon says so; the page's headline cell included
    v = D.problem_verdict("double-pendulum", rows)
    d = v.grid[(1e-6, 1e3)]
    assert d.state == "chaotic" and d.best is None and "past t = 22.8 (" in d.limit.text()
    assert T.decision_text(d) == "no pointwise answer past t = 22.8 (chaos; a finer target: sooner)"


def test_a_chaos_check_is_planned_and_judged():
    rows = _chaotic([_row("gauss6", 0.004, 8e-12, 0.002, "quadratic", 2.0, t_final=10.0)])
    plan = XC.plan_checks(rows, budget_s=1.0, reference_rate=lambda v: 0.0)
    assert [(c.role, c.kind, c.target) for c in plan] == [("chaos", "chaotic", 1e-10)]
    # the finest target 10 times above its error whose horizon lies past its run, 5 t_L past it
    assert plan[0].horizon == pytest.approx(0.99 * math.log(1e-10 / 1e-16) + 5 * 0.99)
    c = XC.check_row(plan[0], {**rows[0], "t_final": plan[0].horizon, "l2_error": 3e-9,
                              "error_horizon": plan[0].horizon})
    assert PC.check_holds(c) is True and PC.check_holds({**c, "measured_error": 5e-11}) is False
    assert "error above 1e-10 predicted" in T.check_text(c)


def test_a_longer_run_that_lost_the_solution_makes_the_setting_lost_from_there():
    short = {**LINEAR, "t_final": 100.0}
    lost = {**LINEAR, "t_final": 1e4, "l2_error": 0.9, "solution_lost": True}
    s = S.settings([short, lost], S.measure([short]))
    assert len(s) == 1 and s[0].span == 100.0 and s[0].lost_at == 1e4
    assert s[0].error_at(1e3) == pytest.approx(1e-5) and s[0].state_at(1e4) == "lost" and s[0].error_at(2e4) is None


def test_an_undetermined_law_whose_slopes_do_not_rise_is_bounded_by_its_steepest_for_a_decade():
    # heyoka on kepler to 1e4 periods: slopes 2.25, 1.36, 2.21 (round-off and a phase error in turn)
    row = {**OPEN, "error.growth_windows": [2.25, 1.36, 2.21], "l2_error": 5e-8, "t_final": 100.0}
    s = S.settings([row], S.measure([row]))[0]
    assert s.bound_exponent == 2.25 and s.reach == 1e3 and s.extrapolates
    assert s.error_at(200.0) == pytest.approx(5e-8 * 2 ** 2.25) and s.error_at(1.1e3) is None
    assert "at most t^2.25 (its steepest window" in s.law_text()
    # slopes that rise are no bound (the law is still steepening); a solution error's bound is at least t^1
    rising = S.settings([{**row, "error.growth_windows": [0.2, 0.6, 1.1]}], S.measure([row]))[0]
    assert rising.bound_exponent is None and not rising.extrapolates
    flat = S.settings([{**row, "error.growth_windows": [0.3, 0.1, 0.2]}], S.measure([row]))[0]
    assert flat.bound_exponent == 1.0


def test_a_drift_dominated_problem_is_a_class_the_checks_cover():
    free = lambda v: 0.0  # noqa: E731
    drifting = [{**r, "drifting_components": 1} for r in ROWS]
    plan = XC.plan_checks(drifting, budget_s=2.0, reference_rate=free, total_s=1e9)
    assert plan and {c.kind for c in plan} == {"drifting"}
    # with a chaotic problem beside it, each class gets a group before any gets a second
    chaotic = _chaotic([_row("gauss6", 0.004, 8e-12, 0.002, "quadratic", 2.0, t_final=10.0)])
    both = XC.plan_checks(drifting + chaotic, limit=2, budget_s=2.0, reference_rate=free, total_s=1e9)
    assert {c.kind for c in both} == {"drifting", "chaotic"}


def test_the_page_and_the_report_show_checks_of_every_role():
    from longtime.reporting.page import build_page
    from longtime.reporting.report import summary

    rows = _chaotic([_row("gauss6", 0.004, 8e-12, 0.002, "quadratic", 2.0, t_final=10.0)])
    chaos = XC.plan_checks(rows, budget_s=1.0, reference_rate=lambda v: 0.0)[0]
    unmeasured = XC.check_row(chaos, {**rows[0], "t_final": chaos.horizon, "l2_error": None, "error_horizon": 5.0})
    plan = XC.plan_checks(ROWS, budget_s=2.0, reference_rate=lambda v: 0.0, total_s=1e9)
    records = [XC.check_row(c, {**c.setting.row, "t_final": c.horizon, "l2_error": 1e3 * c.setting.error,
                               "error_horizon": c.horizon}) for c in plan]
    PC.judge_ranks(records)
    checks = [unmeasured, *records]
    assert PC.check_counts(checks)["unjudged"] >= 2  # the unmeasured chaos check, the open rival
    text = summary(rows + ROWS, checks=checks)
    assert "checks: " in text and "failed" in text
    page = build_page(rows + ROWS, [], drift=False, stability=False, checks=checks)
    assert "not judged" in page


def test_the_page_puts_failed_checks_first_and_says_no_pointwise_answer_past_chaos():
    from longtime.reporting.page import build_page

    rows = _chaotic([_row("gauss6", 0.004, 8e-12, 0.002, "quadratic", 2.0, t_final=10.0)])
    plan = XC.plan_checks(ROWS, budget_s=2.0, reference_rate=lambda v: 0.0, total_s=1e9)
    # every winner measured 1e3 times its predicted error: each best's check fails
    records = [XC.check_row(c, {**c.setting.row, "t_final": c.horizon, "l2_error": 1e3 * c.setting.error,
                               "error_horizon": c.horizon}) for c in plan]
    PC.judge_ranks(records)
    assert PC.check_counts(records)["failed"] >= 1
    page = build_page(rows + ROWS, [], drift=False, stability=False, checks=records)
    section = page[page.index('id="checks"'):]
    assert "Failed:</p><ul><li>" in section and "failed" in section
    failed_list = section[section.index("Failed:"):section.index("</ul>", section.index("Failed:"))]
    assert "MISSED" in failed_list and ": held" not in failed_list
    # the chaotic problem's headline: no pointwise answer, with the predictability horizon's reason
    assert "No pointwise answer up to T = " in page and "Lyapunov time" in page


def test_a_run_short_against_its_problems_horizon_is_not_extrapolated():
    # harmonic's default horizon is 100: a linear law fitted on a run to t = 5 (under a tenth
    # of it) is the error's course within an orbit, not its secular growth
    short = _row("rk4", 0.1, 1e-6, 5e-4, "linear", 1.0, t_final=5.0)
    s = S.settings([short], S.measure([short]))[0]
    assert s.default_span == 100.0 and s.short and not s.extrapolates and s.reach == 5.0
    assert s.error_at(5.0) == 1e-6 and s.error_at(6.0) is None
    assert "under 0.1 of the problem's default horizon 100" in s.law_text()
    long = _row("rk4", 0.1, 1e-6, 1e-3, "linear", 1.0, t_final=10.0)  # a tenth: extrapolated
    assert S.settings([long], S.measure([long]))[0].reach == 1e3
    # a problem not installed here: no horizon to judge by, the class's factor alone
    elsewhere = {**short, "problem": "not-installed-here"}
    assert S.settings([elsewhere], S.measure([elsewhere]))[0].reach == 500.0


def test_an_answers_parameters_run_it_again_as_its_run_command_does():
    """``Recommendation.parameters``: the answer's setting as keywords of longtime.solve, the
    parameters its `longtime run` command names (a recorded one its scheme does not take left
    out), its other settings beside them; {} without an answer."""
    rec = R.recommend([LINEAR], "harmonic", 1e-3, 1e3)
    assert rec.answered and rec.scheme == "rk4" and rec.parameters == {"dt": 0.1}
    assert D.run_command(rec.decision.best, 1e3) == ["longtime", "run", "-p", "harmonic", "-i", "rk4",
                                                     "--dt", "0.1", "--t-final", "1000"]
    other = {**LINEAR, "order": 12.0, "settings": '{"w": 2.0}'}  # rk4 takes no order
    rec = R.recommend([other], "harmonic", 1e-3, 1e3)
    assert rec.parameters == {"dt": 0.1, "w": 2.0}
    assert D.run_command(rec.decision.best, 1e3)[6:] == ["--dt", "0.1", "--set", "w=2.0", "--t-final", "1000"]
    assert not R.recommend([{**LINEAR, "status": "diverged"}], "harmonic", 1e-3, 1e3).parameters
