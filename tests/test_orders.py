"""Observed order: a least-squares slope over the automatically chosen asymptotic range."""
import pytest

from longtime.measure.orders import asymptotic_points, fit_slope, observed_orders


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
