"""Metrics of docs/metrics.md on known signals, and divergence as a status."""
import json

import numpy as np
import pytest

from longtime.core import registry
from longtime.execution.cells import Cell, run_cell
from longtime.measure.metrics import first_crossing, relative_error, time_mean


def test_relative_error_scalar_vector_and_zero_initial_value():
    assert relative_error(np.array([2.0, 2.2, 1.0])) == pytest.approx([0, 0.1, 0.5])
    v = np.array([[3.0, 4.0], [3.0, 4.5], [0.0, 0.0]])
    assert relative_error(v) == pytest.approx([0, 0.1, 1.0])
    # I(u0) = 0: the absolute error
    assert relative_error(np.array([0.0, 1e-3, -2e-3])) == pytest.approx([0, 1e-3, 2e-3])


def test_time_mean_is_the_trapezoid_average():
    t = np.linspace(0, 10, 1001)
    assert time_mean(t, 3 * t) == pytest.approx(15.0, rel=1e-12)
    t = np.r_[0.0, 1.0, 4.0]  # uneven samples
    assert time_mean(t, np.array([0.0, 2.0, 2.0])) == pytest.approx((1.0 + 6.0) / 4)


def test_first_crossing():
    t = np.arange(5.0)
    err = np.array([0, 0.005, 0.02, 0.6, 0.7])
    assert first_crossing(t, err, 0.01) == 2.0
    assert first_crossing(t, err, 0.5) == 3.0
    assert first_crossing(t, err, 0.9) is None


def test_blow_up_is_a_diverged_row_without_nan():
    # explicit Euler amplifies the harmonic oscillator by sqrt(1 + dt^2) per step
    row = run_cell(Cell("harmonic", "euler", {}, {"dt": 1.5}, 1000.0))
    assert row["status"] == "diverged"
    assert "blew up" in row["message"]
    assert row["t_reached"] < 1000.0
    assert row["steps"] == pytest.approx(row["t_reached"] / 1.5)
    json.dumps(row, allow_nan=False)  # every number is finite or null


def test_overflow_to_inf_is_diverged_and_measured_until_then():
    row = run_cell(Cell("toda", "euler", {}, {"dt": 0.5}, 5000.0))
    assert row["status"] == "diverged"
    assert row["H.max"] is not None and row["H.t_50pct"] is not None
    assert row["H.t_50pct"] <= row["t_reached"]
    json.dumps(row, allow_nan=False)


def test_a_raising_cell_is_a_failed_row():
    row = run_cell(Cell("harmonic", "no-such-scheme", {}, {}, 1.0))
    assert row["status"] == "failed" and "no-such-scheme" in row["message"]


def test_l2_error_against_exact_solution_decreases_with_dt():
    rows = [run_cell(Cell("kepler", "rk4", {}, {"dt": dt}, 20.0)) for dt in (0.02, 0.01)]
    assert rows[1]["l2_error"] < rows[0]["l2_error"] / 10  # order 4: a factor ~16
    assert rows[0]["final_error"] > 0
    assert rows[0]["L.max"] < 1e-5 and rows[0]["A.max"] < 1e-3


def test_errors_cover_only_the_samples_up_to_the_reference_horizon():
    from longtime.core.trajectory import Trajectory
    from longtime.measure.metrics import evaluate
    from longtime.measure.reference import Trust

    p = registry.problem_class("harmonic")()
    t = np.linspace(0.0, 4.0, 5)
    ref = p.exact(t)
    U = ref * np.array([1.0, 1.0, 1.0, 2.0, 5.0])[:, None]  # wrong from t = 3 on
    traj = Trajectory("ok", "", t, U, 0.0, 0.0, {"steps": 4})
    trust = Trust("exact", 1e-8, 2.5, 1e-12, "test")
    row = evaluate(p, traj, ref[:3], trust)  # the samples up to the horizon
    assert row["l2_error"] == 0.0 and row["error_horizon"] == 2.0 and row["final_error"] is None
    assert row["reference_horizon"] == 2.5 and row["reference_error"] == 1e-12
    row = evaluate(p, traj, ref, Trust("exact", 1e-8, 4.0, 1e-12, "test"))
    # against the size of the reference's motion about its least-squares line in t
    fit = [np.polyval(np.polyfit(t, ref[:, j], 1), t) for j in range(2)]
    scale = np.sqrt(np.mean(sum((ref[:, j] - fit[j]) ** 2 for j in range(2))))
    dev = np.linalg.norm(U - ref, axis=1) / scale
    assert row["final_error_state"] == pytest.approx(dev[-1]) and row["error_horizon"] == 4.0
    assert row["l2_error_state"] == pytest.approx(np.sqrt(np.mean(dev**2)))
    # harmonic's blocks are q and p: each against its own motion, the row's error the larger
    scales = [np.sqrt(np.mean((ref[:, j] - fit[j]) ** 2)) for j in range(2)]
    each = np.abs(U - ref) / np.array(scales)
    assert row["final_error"] == pytest.approx(each[-1].max())
    assert row["l2_error"] == pytest.approx(np.sqrt(np.mean(each**2, axis=0)).max())
    assert row["error_block"] == ["q oscillator", "p oscillator"][int(np.argmax(np.mean(each**2, axis=0)))]
    assert row["error_curve"]["l2"][-1] == pytest.approx(row["l2_error"], rel=1e-5)
    row = evaluate(p, traj, None)
    assert row["l2_error"] is None and row["error_horizon"] is None and row["reference_horizon"] is None


def test_drift_envelope_keeps_the_peaks_at_log_spaced_times():
    from longtime.measure.metrics import DRIFT_POINTS, drift_envelope

    t = np.linspace(0.0, 1000.0, 200_001)
    err = 1e-6 * np.abs(np.sin(t)) * (1 + t)  # oscillating, growing linearly
    curve = drift_envelope("H", t, err)
    tau, e = np.array(curve["t"]), np.array(curve["error"])
    assert curve["invariant"] == "H" and len(tau) <= DRIFT_POINTS
    assert np.all(np.diff(tau) > 0) and tau[0] > 0
    assert e.max() == pytest.approx(err.max(), rel=1e-5)  # the largest error is kept
    late = tau > 100  # bins wider than the period pi there
    # each kept point is its bin's peak: the envelope 1e-6 (1 + t), not a random phase
    assert np.all(e[late] >= 0.9e-6 * (1 + tau[late]))


def test_a_drifting_component_does_not_hide_a_lost_planar_motion():
    """charged-particle's shape: a circle of radius 0.4 in the plane and x3 = 0.1 + 0.2 t.
    A scheme that keeps x3 exactly but walks the circle's phase off by 0.3 rad at t = 1e3
    is off by a chord of up to 0.12 of a motion of size 0.4, while against the state
    (dominated by x3 ~ 200) its error is 1e-3."""
    from longtime.measure.metrics import motion_scale, solution_errors

    t = np.linspace(0.0, 1000.0, 10_001)
    phase = 0.3 * t / t[-1]
    ref = np.column_stack([0.4 * np.cos(t), 0.4 * np.sin(t), 0.1 + 0.2 * t])
    u = np.column_stack([0.4 * np.cos(t + phase), 0.4 * np.sin(t + phase), 0.1 + 0.2 * t])
    state = np.sqrt(np.sum((u - ref) ** 2) / np.sum(ref**2))
    assert state < 2e-3
    e, l2, scale = solution_errors(t, u, ref)
    assert scale == pytest.approx(0.4, rel=1e-3)  # the circle's; the drift is taken out
    assert e[-1] == pytest.approx(2 * np.sin(0.15), rel=1e-3)  # the chord over the radius
    assert l2[-1] == pytest.approx(np.sqrt(np.mean((2 * np.sin(phase / 2)) ** 2)), rel=1e-3)
    assert l2[-1] > 50 * state
    assert l2[len(t) // 2] == pytest.approx(l2[-1] / 2, rel=0.05)  # the l2_error of the first half
    # a constant component adds nothing to the motion; nothing moving at all: the state's size
    const = np.column_stack([ref[:, :2], np.full(t.size, 5.0)])
    assert motion_scale(t, const) == pytest.approx(0.4, rel=1e-3)
    assert motion_scale(t, np.full((t.size, 2), 3.0)) == pytest.approx(np.sqrt(18))


def test_samples_a_period_apart_take_the_motion_from_the_window():
    """Samples evenly spaced by the period see a periodic motion at one phase: it does not
    move at them; the window's log-spaced times see the whole orbit."""
    from longtime.measure.metrics import motion_scale

    t = 2 * np.pi * np.arange(10_001)
    strobe = np.column_stack([np.cos(t), np.sin(t)])
    w = np.logspace(-3, 0, 1001) * t[-1] / 100
    window = (w, np.column_stack([np.cos(w), np.sin(w)]))
    assert motion_scale(t, strobe, window) == pytest.approx(1.0, rel=0.15)
    assert motion_scale(t, strobe) == pytest.approx(1.0)  # nothing moves: the state's size


def test_a_component_that_follows_a_line_in_t_drifts():
    from longtime.measure.metrics import drifting_components

    t = np.linspace(0.0, 1000.0, 10_001)
    ref = np.column_stack([0.4 * np.cos(t), 0.4 * np.sin(t), 0.1 + 0.2 * t, np.full(t.size, 3.0)])
    assert drifting_components(t, ref) == 1  # x3; the circle oscillates, the constant does not move
    assert drifting_components(t, ref[:, :2]) == 0
