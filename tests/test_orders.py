"""Observed order: a least-squares slope over the automatically chosen asymptotic range."""
import numba
import numpy as np
import pytest

from longtime.core.params import Param
from longtime.core.problem import Problem
from longtime.integrators import Splitting, compose
from longtime.integrators.explicit_rk import ExplicitRungeKutta
from longtime.measure.orders import asymptotic_points, fit_slope, left_out, observed_orders


def rows(scheme, dts, errors, **extra):
    return [{"run_id": 1, "problem": "harmonic", "integrator": scheme, "status": "ok", "dt": dt, "mean_dt": dt,
             "tol": None, "eps_res": None, "order": None, "t_final": 10.0, "settings": "", "l2_error": e,
             "reference_error": extra.get("reference_error")} for dt, e in zip(dts, errors)]


def test_slope_and_interval_of_exact_power_law():
    slope, ci = fit_slope([0.1, 0.05, 0.025, 0.0125], [3e-4 * (h / 0.1) ** 4 for h in [0.1, 0.05, 0.025, 0.0125]])
    assert slope == pytest.approx(4.0, abs=1e-12) and ci == pytest.approx(0.0, abs=1e-9)
    assert fit_slope([0.1, 0.05], [1e-3, 1e-4])[1] is None  # no interval from two points


def test_interval_is_students_t_on_the_slope_standard_error():
    import numpy as np
    from scipy import stats

    x, y = [1.0, 2.0, 4.0, 8.0, 16.0], [1.0, 4.5, 15.0, 70.0, 250.0]
    fit = stats.linregress(np.log(x), np.log(y))
    slope, ci = fit_slope(x, y)
    assert slope == pytest.approx(fit.slope, rel=1e-12)
    assert ci == pytest.approx(stats.t.ppf(0.975, len(x) - 2) * fit.stderr, rel=1e-12)


def test_floors_and_pre_asymptotic_points_are_dropped():
    dts = [0.8, 0.4, 0.2, 0.1, 0.05, 0.025, 0.0125]
    errors = [0.5, 0.09, 1.6e-2 * 1.05, 1e-3, 1e-3 / 16, 1e-3 / 256, 4e-15]
    # 0.8: above MAX_ERROR; 0.4: pre-asymptotic (slope from it far off 4); 0.0125: round-off floor
    used = asymptotic_points([(h, e, None) for h, e in zip(dts, errors)])
    assert [h for h, _ in used] == [0.025, 0.05, 0.1, 0.2]
    fit = observed_orders(rows("rk4", dts, errors))[0]
    assert fit["observed_order"] == pytest.approx(4.0, abs=0.15)
    assert fit["declared_order"] == 4 and not fit["order_flag"]
    assert len(fit["order_points"]) == 4 and fit["order_variable"] == "dt"


def test_reference_floor_and_a_missed_order_is_flagged():
    dts = [0.1, 0.05, 0.025, 0.0125]
    errors = [1e-3, 1e-3 / 8, 1e-3 / 64, 2e-8]  # third order, last point at the reference's accuracy
    fit = observed_orders(rows("rk4", dts, errors, reference_error=1e-8))[0]
    assert [p[0] for p in fit["order_points"]] == [0.025, 0.05, 0.1]
    assert fit["observed_order"] == pytest.approx(3.0, abs=1e-9)
    assert fit["order_flag"]  # rk4 declares 4: 3 misses by more than the interval
    # the floor in l2_error's units (error_floor) is the one compared, where the row has it
    swept = rows("rk4", dts, errors, reference_error=1e-12)
    for r in swept:
        r["error_floor"] = 1e-8
    assert [p[0] for p in observed_orders(swept)[0]["order_points"]] == [0.025, 0.05, 0.1]


def _errors_with_slopes(dts, slopes, smallest=1e-10):
    """Errors at the steps ``dts`` (decreasing) whose local slopes, from the largest step to
    the smallest, are ``slopes``."""
    errors = [smallest]
    for (small, large), slope in zip(zip(dts[::-1], dts[-2::-1]), slopes[::-1]):
        errors.append(errors[-1] * (large / small) ** slope)
    return errors[::-1]


def test_trending_slopes_are_undetermined_and_never_flagged():
    # the perturbed Forest-Ruth on kepler (below): 3.65, 3.11, 2.49 from the largest step down
    dts = [0.02, 0.01, 0.005, 0.0025]
    errors = _errors_with_slopes(dts, [3.65, 3.11, 2.49])
    assert observed_orders(rows("rk4", dts, errors)) == []
    (why,) = left_out(rows("rk4", dts, errors))
    assert why["reason"].startswith("pre-asymptotic: local slopes 3.65, 3.11, 2.49 (dt 0.02 to 0.0025) still fall")
    assert "1.16 apart, beyond the 0.79 that" in why["reason"]  # the 4 points' interval: 2.80 +- 0.79
    assert [round(s, 2) for s in why["slopes"]] == [2.49, 3.11, 3.65]


def test_a_drift_within_a_tenth_of_the_order_is_an_order():
    # kahan-li-8 on harmonic, dt 0.8 to 0.3: local slopes 8.14, 8.08, 7.97 drift by 0.17,
    # beyond SLOPE_BAND but a fiftieth of the order: order 8, not pre-asymptotic
    dts = [0.8, 0.6, 0.4, 0.3]
    (fit,) = observed_orders(rows("kahan-li-8", dts, _errors_with_slopes(dts, [8.14, 8.08, 7.97])))
    assert abs(fit["observed_order"] - 8) < 0.5 and len(fit["order_points"]) == 4 and not fit["order_flag"]
    assert fit["observed_order_ci"] < 0.2 and fit["order_dropped"] == []
    from longtime import sweep
    from longtime.api import convergence

    found = convergence(sweep("harmonic", "kahan-li-8", dt=dts, executor="serial", repeats=1, min_time=0.0))
    assert abs(found.value - 8) < 0.5 and len(found.points) == 4 and not found.flag, str(found)  # 8.05 +- 0.03


def test_slopes_still_rising_toward_the_declared_order_are_undetermined():
    # rk4's 3.20, 3.65, 3.85 on the pendulum: 3.65 and 3.85 agree within a tenth of their
    # order, but they still rise toward 4 as the step shrinks: their fit, 3.75, is not rk4's
    # order, and no order is determined (neither 3.75 nor a flag)
    dts = [0.1, 0.05, 0.025, 0.0125]
    swept = rows("rk4", dts, [1.2288e-06, 1.3336e-07, 1.0636e-08, 7.3962e-10])
    assert observed_orders(swept) == []
    (why,) = left_out(swept)
    assert why["reason"].startswith("pre-asymptotic: local slopes 3.65, 3.85 (dt 0.05 to 0.0125) still rise "
                                    "toward the declared order 4 as the step shrinks"), why["reason"]
    assert "(3.75) is not the order" in why["reason"]
    # a converged sweep's curvature near its order is not a rise: 3.97, 3.99 is an order 4
    errors = _errors_with_slopes(dts[1:], [3.97, 3.99])
    (fit,) = observed_orders(rows("rk4", dts[1:], errors))
    assert fit["observed_order"] == pytest.approx(3.98, abs=0.01)
    # nor is a drift away from the declared order (a crossover, below), nor one that stops short
    # of it by less than a tenth (kahan-li-8's 7.97, 8.08, 8.14)


def test_a_high_order_schemes_default_sweep_crosses_its_asymptotic_range():
    """kahan-li-8's default sweep on kepler was the problem's dt 0.005 to 0.02, all on the
    round-off floor (no order); an order-8 scheme now sweeps three doublings of the largest
    step too, and its order is determined there."""
    from longtime.execution.cells import expand
    from longtime.problems.kepler import Kepler

    def steps(scheme):
        cells = expand(["kepler"], [scheme], default_sweep=True)
        return sorted(c.integrator_settings["dt"] for c in cells if c.t_final == Kepler.sweep_t_final)

    dts = steps("kahan-li-8")
    assert dts == [0.005, 0.01, 0.02, 0.04, 0.08, 0.16]
    assert steps("rk4") == [0.005, 0.01, 0.02] and steps("yoshida6") == [0.005, 0.01, 0.02, 0.04]
    # its l2_errors at T = 40 pi (longtime.sweep("kepler", "kahan-li-8", default_sweep=True))
    errors = [1.2731e-11, 8.4376e-13, 3.0063e-11, 7.1968e-09, 1.9053e-06, 6.1890e-04]
    (fit,) = observed_orders(rows("kahan-li-8", dts, errors))
    assert [p[0] for p in fit["order_points"]] == [0.04, 0.08, 0.16] and not fit["order_flag"]
    assert abs(fit["observed_order"] - 8) <= fit["observed_order_ci"]
    assert all("round-off floor" in why for _, _, why in fit["order_dropped"])


def test_a_pre_asymptotic_sweep_of_a_problem_not_tuned_to_is_undetermined():
    """yoshida8 (order 8) on henon-heiles at dt 0.4 to 0.1: its local slopes 6.71, 7.38, 7.80
    still rise toward 8; the old rule fitted 7.66 +- 1.39 over the three smallest steps and
    returned it as a determined order, unflagged."""
    from longtime import sweep
    from longtime.api import convergence

    dts = [0.4, 0.3, 0.2, 0.1]
    found = convergence(sweep("henon-heiles", "yoshida8", t_final=100.0, dt=dts, executor="serial", repeats=1,
                              min_time=0.0))
    assert not found.determined and not found.flag, str(found)
    assert found.reason.startswith("pre-asymptotic: local slopes") and "toward the declared order 8" in found.reason
    assert [round(x, 1) for x in found.slopes] == [7.8, 7.4, 6.7]


def test_fewer_than_three_points_give_no_order_and_every_left_out_says_why():
    from longtime.measure.orders import order_text
    from longtime.reporting.report import summary

    # kahan-li-8 on kepler at its sweep's steps: the smallest step is on the round-off floor
    # (its error grows again), which leaves 2 points and one slope (5.16): not an order
    dts, errors = [0.02, 0.01, 0.005], [2.4803e-11, 6.9603e-13, 1.0501e-11]
    swept = rows("kahan-li-8", dts, errors)
    for r in swept:
        r.update(steps=round(10 / r["dt"]), cpu_s=1e-3 / r["dt"], rhs_evals=17 * round(10 / r["dt"]))
    assert observed_orders(swept) == []
    (why,) = left_out(swept)
    assert why["reason"].startswith("2 points only (dt 0.01 and 0.02, local slope 5.16)")
    assert [d[0] for d in why["dropped"]] == [0.005] and why["dropped"][0][2].startswith("on the round-off floor")
    text = summary(swept)
    assert "observed/declared order" not in text and "left out of the order table: kahan-li-8 (2 points only" in text
    # whatever holds an order from two points prints it flagged
    assert order_text(5.16, None, 2) == "5.16 (2 points: not an order)"
    assert order_text(8.07, 0.1, 4, [7.97, 8.08, 8.14]) == "8.07 +- 0.10, local slopes 7.97 to 8.14"
    # rows that give no point say why: no "0 of 0 points left: " with nothing after it
    lost = rows("rk4", dts, [1.2, 1.1, 0.9])
    for r in lost:
        r["predictability_t"] = 3.0
    (why,) = left_out(lost)
    assert why["reason"] == ("0 of 0 points left, fewer than 3: 3 rows past its predictability horizon "
                             "(a chaotic solution lost)")


def test_a_crossover_is_never_a_determined_order_between_its_two_orders():
    # e = h^4 + c h^2: order 4 at large steps, 2 at small ones; every sweep of five halvings
    # across the crossover is either undetermined or determined within a tenth of the order
    # of 2 or 4 (the drift the range accepts), never in between; one near 2 is flagged
    determined = 0
    for c in (1e-4, 1e-3, 1e-2):
        for top in np.geomspace(0.5, 1e-3, 25):
            dts = [top / 2 ** k for k in range(5)]
            fits = observed_orders(rows("rk4", dts, [h ** 4 + c * h ** 2 for h in dts]))
            for f in fits:
                determined += 1
                order = f["observed_order"]
                assert min(abs(order - 2), abs(order - 4)) <= 0.1 * order, (c, dts, f)
                assert f["order_flag"] == (order < 3), (c, dts, f)
    assert determined > 30


def test_the_round_off_floor_flattening_the_smallest_step_is_dropped():
    dts = [0.1, 0.05, 0.025, 0.0125, 0.00625]
    errors = [1e-6, 1e-6 / 16, 1e-6 / 256, 1e-6 / 4096, 5e-11]  # the last within 1e3 x round-off: slope 2.3
    fit = observed_orders(rows("rk4", dts, errors))[0]
    assert fit["observed_order"] == pytest.approx(4.0, abs=1e-9) and not fit["order_flag"]
    assert [d[0] for d in fit["order_dropped"]] == [0.00625]
    assert fit["order_dropped"][0][2].startswith("on the round-off floor: it flattens the slope to 2.29")


def test_str_of_an_order_shows_its_flag():
    from longtime.api import orders

    dts = [0.1, 0.05, 0.025]
    (flagged,) = orders(rows("rk4", dts, [1e-3, 1e-3 / 8, 1e-3 / 64]))
    assert flagged.flag and "MISSES the declared order" in str(flagged)
    assert "observed order 3.000 +- 0.000" in str(flagged)
    (fine,) = orders(rows("rk4", dts, [1e-3, 1e-3 / 16, 1e-3 / 256]))
    assert not fine.flag and "MISSES" not in str(fine)


# ------------------------------------------------------------------ the cases of docs/metrics.md, measured
@numba.njit
def _pendulum_rhs(t, u, params, out):
    out[0] = u[1]
    out[1] = -np.sin(u[0])


@numba.njit
def _pendulum_grad_T(p, params, out):
    out[0] = p[0]


@numba.njit
def _pendulum_grad_V(q, params, out):
    out[0] = np.sin(q[0])


class OrdersPendulum(Problem):
    """The nonlinear pendulum H = p^2/2 - cos q, q(0) = q0, p(0) = 0."""
    name = "orders-pendulum"
    summary = "nonlinear pendulum"
    parameters = {"q0": Param(2.0, "initial angle", float, role="physical")}
    default_t_final = 20.0
    default_dt = 0.1
    sweep_dt = (0.1, 0.05, 0.025, 0.0125)
    rhs = staticmethod(_pendulum_rhs)
    grad_T = staticmethod(_pendulum_grad_T)
    grad_V = staticmethod(_pendulum_grad_V)

    def initial_state(self):
        return [self.settings["q0"], 0.0]

    def inverse_masses(self):
        return np.ones(1)

    def invariants(self, t, U):
        return {"H": 0.5 * U[:, 1] ** 2 - np.cos(U[:, 0])}

    def heyoka_system(self):
        import heyoka as hy

        q, p = hy.make_vars("q", "p")
        return [q, p], [p, -hy.sin(q)]


class OrdersKutta38(ExplicitRungeKutta):
    """Kutta's 3/8 rule (1901)."""
    name = "orders-kutta-38"
    summary = "Kutta's 3/8 rule"
    order = 4
    A = np.array([[0, 0, 0, 0], [1 / 3, 0, 0, 0], [-1 / 3, 1, 0, 0], [1, -1, 1, 0]], dtype=float)
    b = np.array([1, 3, 3, 1], dtype=float) / 8
    c = np.array([0, 1 / 3, 2 / 3, 1.0])


G = 1 / (2 - 2 ** (1 / 3))


class OrdersPerturbedForestRuth(Splitting):
    """Forest-Ruth with its coefficient perturbed by 1e-4: order 2 with a small h^2 term."""
    name = "orders-perturbed-forest-ruth"
    order = 4
    kicks, drifts = compose([G + 1e-4, 1 - 2 * (G + 1e-4), G + 1e-4])


def test_pendulum_rk4_and_the_3_8_rule_still_rise_toward_4_and_are_undetermined():
    from longtime import sweep
    from longtime.api import orders

    found = orders(sweep(OrdersPendulum, ["rk4", OrdersKutta38], dt=[0.1, 0.05, 0.025, 0.0125], t_final=20,
                         executor="serial", repeats=1, min_time=0.0))
    assert len(found) == 2
    for o in found:
        # the slopes rise toward 4 as the step shrinks and stop short of it: no order (neither
        # their fit, 3.75 or 3.56, nor a flag)
        assert not o.flag and o.value is None and len(o.slopes) == 3, str(o)
        assert o.slopes[0] > o.slopes[-1] and 3.1 < min(o.slopes) and max(o.slopes) < 4.0
        assert "toward the declared order 4 as the step shrinks" in o.reason and "MISSES" not in str(o)
    rk4 = next(o for o in found if o.scheme == "rk4")
    assert [round(s, 1) for s in reversed(rk4.slopes)] == [3.2, 3.6, 3.8]
    assert [d[0] for d in rk4.dropped] == [0.1] and "(3.75) is not the order" in rk4.reason  # 3.20: beyond a tenth
    rule = next(o for o in found if o.scheme != "rk4")  # 3.45, 3.47, 3.78: within a tenth of the order
    assert rule.reason.startswith("pre-asymptotic: local slopes 3.45, 3.47, 3.78 (dt 0.1 to 0.0125)"), rule.reason


def test_perturbed_composition_is_undetermined_then_order_two():
    from longtime import sweep
    from longtime.api import convergence

    crossing = convergence(sweep("kepler", OrdersPerturbedForestRuth, dt=[0.02, 0.01, 0.005, 0.0025],
                                 executor="serial", repeats=1, min_time=0.0))
    assert crossing.value is None and not crossing.flag and "still fall toward small steps" in crossing.reason
    small = convergence(sweep("kepler", OrdersPerturbedForestRuth, dt=[0.00125, 0.000625, 0.0003125],
                              executor="serial", repeats=1, min_time=0.0))
    assert abs(small.value - 2) < 0.1 and small.flag, str(small)  # 2.03 +- 0.11, flagged against 4


def test_report_and_compare_name_an_undetermined_order_with_its_slopes_and_flag_nothing():
    from longtime.reporting.compare import compare
    from longtime.reporting.compare_text import render
    from longtime.reporting.report import summary

    dts = [0.02, 0.01, 0.005, 0.0025]
    trending = rows("rk4", dts, _errors_with_slopes(dts, [3.65, 3.11, 2.49]))
    for r in trending:
        r.update(steps=round(10 / r["dt"]), cpu_s=1e-3 / r["dt"], rhs_evals=4 * round(10 / r["dt"]))
    text = summary(trending)
    assert "left out of the order table: rk4 (pre-asymptotic: local slopes 3.65, 3.11, 2.49" in text
    assert "MISSES" not in text
    assert "left out of A's order table: harmonic rk4 (pre-asymptotic: local slopes 3.65" in render(
        compare(trending, trending))


def test_a_pair_swept_at_two_final_times_names_the_sweep_its_reason_is_about():
    """The default sweep (2 points left) and a long-time sweep as long (every point lost): the
    reason is the default sweep's, the shorter run's, and says its final time."""
    dts = [0.1, 0.05, 0.025]
    short = rows("rk4", dts, [2e-2, 1.25e-3, 0.5])
    long = [{**r, "t_final": 1000.0, "l2_error": 0.6 + i / 10} for i, r in enumerate(rows("rk4", dts, dts))]
    for both in (short + long, long + short):
        (why,) = left_out(both)
        assert why["reason"].startswith("2 points only") and why["reason"].endswith("(its sweep to t = 10)"), why
    (why,) = left_out(long)
    assert why["reason"] == "every point above 0.1"  # one final time: nothing to name
