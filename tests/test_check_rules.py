"""The rules that judge and plan the main job's checks (longtime.predict.checks,
longtime.execution.checks), on synthetic rows: a bound is judged as an upper bound, a class
as a point estimate; a class of problem keeps its turn until one of its groups fits, and a
drift-dominated problem's groups come first in the drifting class."""
import pytest

from longtime.execution import checks as XC
from longtime.predict import checks as PC
from longtime.predict import settings as S
from longtime.reporting.verdict import check_text


def _row(scheme, error, law, t_final=100.0, problem="kepler", windows=None, **extra):
    return {"problem": problem, "integrator": scheme, "status": "ok", "dt": 0.1, "order": None, "tol": None,
            "eps_res": None, "t_final": t_final, "settings": "", "cpu_s": 0.01, "repeats": 3,
            "l2_error": error, "final_error": error, "reference": "heyoka", "solution_lost": False,
            "error.growth": 1.0, "error.growth_class": law, "error.growth_reason": "slopes ...",
            "error.growth_windows": windows, "H.max": 1e-6, "H.growth_class": "bounded", **extra}


def _setting(row):
    return S.settings([row], S.measure([row]))[0]


def _check(setting, horizon, measured, role="best", kind="adaptive", problem="kepler"):
    planned = XC.PlannedCheck(setting, horizon, S.measure([setting.row]), role, 1e-3, f"{problem} g", kind)
    row = {**setting.row, "t_final": horizon, "l2_error": measured, "cpu_s": setting.cpu_at(horizon),
           "error_horizon": horizon}
    return XC.check_row(planned, row)


def test_a_bound_is_judged_as_at_most_and_a_class_as_a_point_estimate():
    # heyoka on kepler, undetermined with window slopes 2.25, 1.36, 2.21 that do not rise:
    # at most t^2.25 for a decade past its run
    bounded = _setting(_row("heyoka", 5e-8, "undetermined", windows=[2.25, 1.36, 2.21]))
    c = _check(bounded, 1e3, 1e-6)
    assert c["predicted_bound"] is True and c["predicted_error"] == pytest.approx(5e-8 * 10**2.25)
    assert PC.check_holds(c) is True  # 1e-6, nine times below the bound of 8.9e-6: the bound holds
    assert "error at most 8.891e-06 predicted, 1.000e-06 measured" in check_text(c)
    assert PC.check_holds({**c, "measured_error": 3.1 * c["predicted_error"]}) is False  # past x3 the bound
    assert PC.check_holds({**c, "measured_error": 2.9 * c["predicted_error"]}) is True
    # a linear class is a point estimate: nine times below it is a miss
    linear = _setting(_row("yoshida8", 5e-8, "linear", windows=[1.0, 1.0, 1.0]))
    p = _check(linear, 1e3, 5e-7 / 9)
    assert p["predicted_bound"] is False and p["predicted_error"] == pytest.approx(5e-7)
    assert PC.check_holds(p) is False
    assert PC.check_holds({**p, "measured_error": 5e-7 / 2.9}) is True
    # within its run the error is measured, not bounded
    assert _check(bounded, 100.0, 5e-8)["predicted_bound"] is False


def test_a_class_keeps_its_turn_until_a_group_fits(monkeypatch):
    # charged-particle's first winner wins only where its reference is too long to run
    # (1e5 time units at 1e-4 s each); its next winner's group (1e4) fits: the drifting class
    # gets that group on its first turn, before the chaotic class gets its second
    rows = [_row("rk4", 1e-6, "linear", problem=p, windows=[1.0, 1.0, 1.0], drifting_components=d)
            for p, d in (("a-chaos", 0), ("charged-particle", 1), ("other", 0))]
    verdict_settings = {r["problem"]: _setting(r) for r in rows}

    def group(problem, horizon, kind):
        s = verdict_settings[problem]
        return [XC.PlannedCheck(s, horizon, S.measure([s.row]), "best", 1e-3, f"{problem} {horizon:g}", kind)]

    entries = {"a-chaos": [[group("a-chaos", 1e3, "chaotic")], [group("a-chaos", 2e3, "chaotic")]],
               "charged-particle": [[group("charged-particle", 1e5, "drifting")],
                                    [group("charged-particle", 1e4, "drifting")]],
               "other": [[group("other", 1e3, "other")]]}
    monkeypatch.setattr(XC, "_chaos_group", lambda v, rows, budget_s: [])
    monkeypatch.setattr(XC, "_decision_groups", lambda v, budget_s: entries[v.problem])
    rate = {"charged-particle": 1e-4}
    plan = XC.plan_checks(rows, limit=2, budget_s=1.0, reference_rate=lambda v: rate.get(v.problem, 0.0),
                          total_s=1e3)
    assert [(c.setting.row["problem"], c.horizon) for c in plan] == [("a-chaos", 1e3), ("charged-particle", 1e4)]
    # the total time bounds it still: the group at 1e4 (its reference 1 s) does not fit 0.5 s
    plan = XC.plan_checks(rows, limit=2, budget_s=1.0, reference_rate=lambda v: rate.get(v.problem, 0.0),
                          total_s=0.5)
    assert "charged-particle" not in {c.setting.row["problem"] for c in plan}


def test_a_drift_dominated_problems_group_comes_first_in_the_drifting_class(monkeypatch):
    # "a-energy" is drifting by its energy only; "b-moving" has a drifting state component
    rows = [_row("rk4", 1e-6, "linear", problem=p, windows=[1.0, 1.0, 1.0], drifting_components=d)
            for p, d in (("a-energy", 0), ("b-moving", 1))]
    made = {r["problem"]: _setting(r) for r in rows}

    def entry(problem):
        s = made[problem]
        return [[XC.PlannedCheck(s, 1e3, S.measure([s.row]), "best", 1e-3, problem, "drifting")]]

    monkeypatch.setattr(XC, "_chaos_group", lambda v, rows, budget_s: [])
    monkeypatch.setattr(XC, "_decision_groups", lambda v, budget_s: [entry(v.problem)])
    plan = XC.plan_checks(rows, limit=1, budget_s=1.0, reference_rate=lambda v: 0.0, total_s=1e3)
    assert [c.setting.row["problem"] for c in plan] == ["b-moving"]
    assert XC._drift_dominated(plan) and not XC._drift_dominated(entry("a-energy")[0])
    assert len(XC.plan_checks(rows, limit=2, budget_s=1.0, reference_rate=lambda v: 0.0, total_s=1e3)) == 2


def test_a_lost_rank_names_the_rival_it_lost_to():
    # henon-heiles in the default main job: blanes-moan-s6 kept 1e-4 in 0.098 s, its open rival
    # yoshida6 dt 0.1 (law undetermined) in 0.057 s, its runner-up yoshida6 dt 0.05 in 0.114 s
    best = _check(_setting(_row("blanes-moan-s6", 1.4e-7, "linear", windows=[1.0, 1.0, 1.0])), 1e4, 1.4e-5)
    runner = _check(_setting(_row("yoshida6", 2.5e-8, "linear", windows=[1.0, 1.0, 1.0])), 1e4, 1.2e-6,
                    role="runner-up")
    opened = _check(_setting(_row("yoshida6", 8.2e-7, "undetermined", windows=[0.29, 0.51, 0.91])), 1e4, 7.9e-5,
                    role="open")
    records = [{**best, "cpu_s": 0.098}, {**runner, "cpu_s": 0.114}, {**opened, "dt": 0.2, "cpu_s": 0.057}]
    for r in records:
        r["check_group"], r["check_target"] = "henon-heiles 1e-4", 1e-4
    PC.judge_ranks(records)
    assert records[0]["rank_held"] is False and PC.check_holds(records[0]) is False
    assert records[0]["rank_lost_to"] == ["yoshida6 dt=0.2 (open, 0.057 s)"]
    assert "(cheaper by more than x1.5: yoshida6 dt=0.2 (open, 0.057 s))" in check_text(records[0])
    records[2]["cpu_s"] = 0.066  # 0.098 <= 1.5 x 0.066: the rank holds
    PC.judge_ranks(records)
    assert records[0]["rank_held"] is True and records[0]["rank_lost_to"] == []


def test_the_winner_map_marks_only_judged_checks():
    from longtime.reporting.figures.verdict import check_marks

    held = _check(_setting(_row("rk4", 1e-6, "linear", windows=[1.0, 1.0, 1.0])), 1e3, 1.1e-5)
    missed = _check(_setting(_row("verlet", 1e-6, "linear", windows=[1.0, 1.0, 1.0])), 1e3, 1e-3)
    opened = _check(_setting(_row("gauss4", 1e-8, "undetermined", windows=[0.29, 0.51, 0.91])), 1e3, 0.9,
                    role="open")
    assert PC.check_holds(opened) is None  # an open rival predicted nothing: neither held nor missed
    marks = check_marks([held, missed, opened], (1e-12, 1e-1))
    assert marks == [(1e3, 1.1e-5, True), (1e3, 1e-3, False)]
    assert check_marks([{**missed, "measured_error": 5.0}], (1e-12, 1e-1)) == [(1e3, 1e-1, False)]  # on the edge


def test_a_check_cpu_is_judged_in_calibrated_time_where_both_carry_a_calibration():
    """A machine twice as slow while the checks ran (twice the CPU seconds, and twice the
    calibration): the prediction holds in calibrated time; without calibrations, in seconds."""
    from longtime.execution.checks import _calibrated
    from longtime.predict.checks import check_holds

    row = {"cpu_s": 0.5, "cpu_s_calibrated": 100.0}  # timed when the reference workload took 5 ms
    check = {"check_role": "best", "predicted_error": 1e-6, "measured_error": 1e-6, "predicted_cpu_s": 1.0,
             "cpu_s": 2.0, "predicted_cpu_s_calibrated": _calibrated(1.0, row), "cpu_s_calibrated": 2.0 / 0.01}
    assert check["predicted_cpu_s_calibrated"] == 200.0
    assert check_holds(check) is True
    raw = {k: v for k, v in check.items() if not k.endswith("_calibrated")}
    assert check_holds(raw) is False
    assert check_holds({**check, "cpu_s_calibrated": 400.0}) is False  # slower in calibrated time too
