"""Exponentially long times: the breakdown time T*(dt) from censored ensembles, the fits of
ln T* against 1/dt and ln dt, and the measurement on Henon-Heiles below its escape energy."""
import math

import numpy as np
import pytest

from longtime.measure.horizon import breakdown_time, estimate, fit_law, judge, local_slopes, verdict_text


def test_estimate_is_the_censored_maximum_likelihood_rate():
    """4 breakdowns at t = 1, 2, 3, 4 and 4 members censored at 10: S = 10 + 40, r = 4 / 50."""
    b = estimate(0.1, [1.0, 2.0, 3.0, 4.0, None, None, None, None], t_final=10.0)
    assert b.events == 4 and b.exposure == 50.0 and b.t_star == pytest.approx(12.5)
    lo, hi = b.t_star_ci
    assert lo < 12.5 < hi
    assert b.median_t is None  # half broke down, not more
    none = estimate(0.1, [None] * 5, t_final=10.0)
    assert none.t_star is None and none.t_star_ci[0] == pytest.approx(50 / 2.9957, rel=1e-3)


def test_breakdown_is_the_escape_or_the_first_threshold_crossing():
    t = np.linspace(0, 10, 11)
    err = np.r_[np.zeros(6), np.full(5, 0.2)]
    assert breakdown_time(t, err, None, None) is None
    assert breakdown_time(t, err, None, 7.5) == 7.5
    assert breakdown_time(t, err, 0.1, 7.5) == 6.0
    assert breakdown_time(t, err, 0.1, 3.0) == 3.0


def _points(law):
    out = []
    for k, dt in enumerate([0.9, 0.85, 0.8, 0.75, 0.7, 0.65]):
        t_star = law(dt) * (1.0 + 0.05 * (-1) ** k)
        out.append(estimate(dt, [t_star] * 20, t_final=1e12))
    return out


def test_fit_finds_gamma_of_an_exponential_law_and_rejects_a_bend():
    exp_fit = fit_law(_points(lambda dt: math.exp(3.0 / dt)), "exponential")
    assert exp_fit["verdict"] == "holds" and exp_fit["slope_ci"][0] < 3.0 < exp_fit["slope_ci"][1]
    bent = fit_law(_points(lambda dt: math.exp(3.0 / dt + 8.0 / dt**2)), "exponential")
    assert bent["verdict"] == "does not hold", bent
    assert fit_law(_points(lambda dt: math.exp(3.0 / dt))[:3], "exponential")["verdict"] == "undetermined"


def test_a_law_that_steps_outside_its_range_contradict_does_not_hold():
    # T* = e^(3/dt) measured at dt 0.9 .. 0.75, then no breakdown of 20 members over 1e9 at
    # dt 0.6 (T* >= 6.7e9), where the fit predicts e^5 = 148: the law does not hold
    points = _points(lambda dt: math.exp(3.0 / dt))[:4] + [estimate(0.6, [None] * 20, t_final=1e9)]
    fit = fit_law(points, "exponential")
    assert fit["verdict"] == "does not hold" and fit["contradicted"][0].startswith("dt 0.6: no breakdown of 20")
    assert "fitted over 1/dt 1.11 to 1.33" in fit["reason"]
    # the same step with a lower bound the law respects does not contradict it
    ok = _points(lambda dt: math.exp(3.0 / dt))[:4] + [estimate(0.6, [None] * 20, t_final=5.0)]
    assert fit_law(ok, "exponential")["verdict"] == "holds"
    slopes = local_slopes(points)
    dx = [1 / x["to"] - 1 / x["from"] for x in slopes[:3]]
    # the three slopes add up to the end points' (their noise: 1.05 at dt 0.9, 0.95 at 0.75)
    assert sum(x["slope"] * d for x, d in zip(slopes[:3], dx)) / sum(dx) == pytest.approx(
        3.0 + math.log(0.95 / 1.05) / (1 / 0.75 - 1 / 0.9), rel=1e-12)
    assert [x["bound"] for x in slopes[:3]] == [None] * 3 and [x["to"] for x in slopes] == [0.85, 0.8, 0.75, 0.6]
    assert slopes[-1]["bound"] == "at least" and slopes[-1]["slope"] > 20


def test_the_exponential_law_holds_only_where_it_is_told_from_a_power_law_and_escapes_are_breakdowns():
    points = _points(lambda dt: math.exp(3.0 / dt))
    exp_fit, power_fit = fit_law(points, "exponential"), fit_law(points, "power")
    assert exp_fit["verdict"] == "holds"
    both = judge(exp_fit, dict(power_fit, verdict="holds"))
    assert both["verdict"] == "undetermined" and both["reason"].startswith("not told apart from a power law")
    swung = judge(exp_fit, power_fit, swing=0.035, gap=0.02)
    assert swung["verdict"] == "undetermined" and "already swing by |H - H0| = 0.035" in swung["reason"]
    text = verdict_text("verlet", exp_fit, power_fit, swung, local_slopes(points))
    assert text.startswith("verlet: ln T* = a + gamma/dt undetermined (an escape is not a breakdown")
    assert "local slopes d ln T*/d(1/dt), dt 0.9 -> 0.85: " in text


@pytest.mark.slow
def test_verlet_escapes_give_no_law_that_steps_outside_the_fit_contradict():
    """Henon-Heiles at energy 1/6 - 0.02, 24 members to t = 5e6 each, dt 0.9 down to 0.6
    (measured: T* from 4.6e5 at dt 0.9 to 2.1e7 at 0.7; no escape at 0.65 and 0.6, T* >= 4.0e7).
    The exponential law fitted over dt 0.9 .. 0.7 (gamma 9.4) predicts 2.4e7 at 0.65: the
    lower bound there contradicts it, and a power law likewise; the orbits that never escape
    swing by |H - H0| = 0.02 to 0.04, as much as the gap: the escape is no breakdown of the
    O(dt^2) bound, and the verdict is undetermined. (About a minute of CPU.)"""
    from longtime.commands.horizon import study

    result = study(schemes=("verlet",), progress=False)["schemes"]["verlet"]
    assert result["exponential"]["verdict"] != "holds" and result["power"]["verdict"] != "holds"
    assert any(c.startswith("dt 0.65: no breakdown") for c in result["exponential"]["contradicted"])
    assert result["judged"]["verdict"] == "undetermined"
    assert result["judged"]["reason"].startswith("an escape is not a breakdown of the O(dt^r) energy bound")
    points = result["points"]
    assert points[-1]["t_star"] is None and points[-1]["held_swing"] > 0.01  # dt 0.6: none escaped (0.021)
    assert points[0]["t_star"] < 1e6 and points[0]["held_swing"] > 0.03
    assert result["local_slopes"][-1]["bound"] == "at least"
