"""The compiled loops every scheme runs through (longtime.core.drivers), tested directly on
hand-written steps whose results are known exactly."""
import math

import numba
import numpy as np
import pytest

from longtime.core import drivers


@numba.njit
def _add_h(t, u, h, params, work, counters, first):
    """u' = 1: one step adds h, exactly (h is a power of two below)."""
    u[0] += h
    counters[drivers.RHS_EVALS] += 1
    return drivers.OK


@numba.njit
def _double(t, u, h, params, work, counters, first):
    u[0] *= 2.0
    return drivers.OK


@numba.njit
def _fail_at_three(t, u, h, params, work, counters, first):
    u[0] += 1.0
    return drivers.FAILED if u[0] >= 3.0 else drivers.OK


def _run(step, nsteps, dt, t0=0.0, blowup=1e300, chunks=1):
    loop = drivers.fixed_step_loop(step)
    sample_at = drivers.sample_steps(nsteps, 10_000)
    out_t = np.zeros(sample_at.size + 1)
    out_u = np.zeros((sample_at.size + 1, 1))
    u = np.zeros(1)
    counters = drivers.new_counters()
    t_final = t0 + nsteps * dt
    bounds = np.linspace(0, nsteps, chunks + 1).astype(np.int64)
    j, n_out, status = 0, 1, drivers.OK
    for k_start, k_stop in zip(bounds[:-1], bounds[1:]):
        status, n_out, j, t = loop(u, t0, t_final, dt, k_start, k_stop, nsteps, sample_at, j, n_out,
                                   np.zeros(0), np.zeros(0), out_t, out_u, counters, blowup)
        if status != drivers.OK:
            break
    return status, u, out_t[:n_out], out_u[:n_out], counters


def test_fixed_step_loop_takes_every_step_and_records_the_last():
    status, u, t, U, counters = _run(_add_h, nsteps=1000, dt=0.125)
    assert status == drivers.OK
    assert u[0] == 125.0  # 1000 exact additions of 1/8
    assert counters[drivers.STEPS] == 1000 and counters[drivers.RHS_EVALS] == 1000
    assert t[-1] == 125.0 and U[-1, 0] == 125.0
    np.testing.assert_array_equal(U[1:, 0], t[1:])  # every sample is u = t


def test_chunks_give_the_same_run_bit_for_bit():
    one = _run(_add_h, nsteps=997, dt=0.1, chunks=1)
    seven = _run(_add_h, nsteps=997, dt=0.1, chunks=7)
    assert one[0] == seven[0] == drivers.OK
    np.testing.assert_array_equal(one[1], seven[1])
    np.testing.assert_array_equal(one[2], seven[2])
    np.testing.assert_array_equal(one[4], seven[4])


def test_blow_up_stops_the_loop_with_diverged_and_the_state_reached():
    loop = drivers.fixed_step_loop(_double)
    sample_at = drivers.sample_steps(100, 1000)
    out_t, out_u = np.zeros(sample_at.size + 1), np.zeros((sample_at.size + 1, 1))
    u = np.ones(1)
    counters = drivers.new_counters()
    status, n_out, j, t = loop(u, 0.0, 100.0, 1.0, 0, 100, 100, sample_at, 0, 1, np.zeros(0), np.zeros(0),
                               out_t, out_u, counters, 1e3)
    assert status == drivers.DIVERGED
    assert u[0] == 1024.0 and counters[drivers.STEPS] == 10  # 2^10 > 1e3 after the 10th step
    assert out_t[n_out - 1] == 10.0 and out_u[n_out - 1, 0] == 1024.0


def test_a_failing_step_ends_the_run_as_failed():
    status, u, t, U, counters = _run(_fail_at_three, nsteps=10, dt=1.0)
    assert status == drivers.FAILED
    assert u[0] == 3.0 and counters[drivers.STEPS] == 3


@pytest.mark.parametrize("nsteps, max_samples", [(1, 10), (10, 10_000), (10**6, 1001), (10**8, 100_001)])
def test_sample_steps_are_sorted_end_at_nsteps_and_respect_the_budget(nsteps, max_samples):
    s = drivers.sample_steps(nsteps, max_samples)
    assert s[-1] == nsteps + 1  # the sentinel
    body = s[:-1]
    assert body[-1] == nsteps and np.all(np.diff(body) > 0) and body[0] >= 1
    assert body.size <= max_samples
    if max_samples >= 1000 and nsteps >= 10**6:  # log-spaced points in every decade of steps
        for decade in range(int(math.log10(nsteps))):
            assert np.any((body >= 10**decade) & (body < 10 ** (decade + 1)))


def test_compensated_add_keeps_what_plain_summation_loses():
    @numba.njit
    def sums(n, inc):
        plain = np.ones(1)
        comp_u = np.ones(1)
        comp = np.zeros(1)
        for _ in range(n):
            plain[0] += inc
            drivers.compensated_add(comp_u, 0, inc, comp, 0)
        return plain[0], comp_u[0]

    n, inc = 10**6, 1e-16  # each increment is below half an ulp of 1: plain adds nothing
    plain, compensated = sums(n, inc)
    assert plain == 1.0
    assert compensated == pytest.approx(1.0 + n * inc, rel=1e-15)


def test_adaptive_loop_reaches_t_end_and_counts_rejections():
    @numba.njit
    def try_step(t, u, h, params, work, counters, u_new):
        if h > 0.5:  # reject anything larger than 0.5, accept the rest exactly
            return 0, 0.0, 0.5
        u_new[0] = u[0] + h
        return 1, h, h

    loop = drivers.adaptive_loop(try_step)
    u, u_new = np.zeros(1), np.zeros(1)
    out_t, out_u = np.zeros(64), np.zeros((64, 1))
    counters, hstats = drivers.new_counters(), np.array([np.inf, 0.0])
    status, n_out, t, h = loop(u, 0.0, 10.0, 1.0, 10.0, 1, np.zeros(0), np.zeros(0), u_new, out_t, out_u,
                               counters, hstats, 1e300)
    assert status == drivers.OK and t == 10.0 and u[0] == 10.0
    assert counters[drivers.STEPS] == 20 and counters[drivers.REJECTED] == 1
    assert hstats[0] == hstats[1] == 0.5
    assert n_out == 20 and out_t[n_out - 1] == 10.0


def _stop_sweep(increments, scale=1.0):
    """The sweep (1-based) at which drivers.reached_round_off ends an iteration with these
    increments, or None when it never does."""
    best, stale = np.inf, 0
    for sweep, delta in enumerate(increments, start=1):
        best, stale = drivers.track_increment(delta, best, stale)
        if drivers.reached_round_off(delta, best, stale, scale):
            return sweep
    return None


def test_a_non_monotone_convergence_is_not_a_stall():
    # implicit midpoint on kepler (e = 0.6, h = 0.1) at its first step: the increment's
    # largest component alternates, so every other sweep rises, down to round-off
    pairs = [(0.14, 0.043), (6.2e-3, 3.6e-3), (2.1e-4, 2.8e-4), (1.4e-5, 2.3e-5), (1.1e-6, 1.8e-6),
             (9.1e-8, 1.5e-7), (7.4e-9, 1.2e-8), (6e-10, 1e-9), (5e-11, 8e-11), (4e-12, 6e-12),
             (3e-13, 5e-13), (2.5e-14, 4e-14), (2e-15, 3e-15), (1e-16, 0.0)]
    increments = [d for pair in pairs for d in pair]
    assert _stop_sweep(increments) == len(increments) - 1  # the first increment below round-off


def test_a_round_off_floor_is_a_stall_and_a_large_one_is_not():
    floor = [1e-3, 1e-6, 1e-9, 1e-12, 1e-14, 3e-14, 2e-14, 1.5e-14, 4e-14]
    assert _stop_sweep(floor) == 5 + drivers.STALL_SWEEPS  # three sweeps without a new smallest
    assert _stop_sweep([1e-3, 1e-4, 1e-5, 2e-5, 3e-5, 2e-5, 5e-5, 1e-4]) is None  # stuck far above round-off
    assert _stop_sweep([1e-3, 1e-7, 1e-16]) == 3  # at machine precision (below half an ulp of the scale)
    assert _stop_sweep([1e-3, 1e-7, 4e-16], scale=4.0) == 3 and _stop_sweep([1e-3, 1e-7, 2e-16]) is None


def test_a_failed_step_names_a_nonlinear_solve_only_for_a_scheme_that_solves_one():
    from longtime.core import drivers
    from longtime.core.registry import integrator_class
    from longtime.core.stepping import _solves, _status_message

    rk45, gauss4 = integrator_class("rk45")(), integrator_class("gauss4")()
    assert not _solves(rk45) and _solves(gauss4)
    assert _status_message(drivers.FAILED, 2.0, _solves(rk45)) == "step failed at t=2 (step size underflow)"
    assert "nonlinear solve did not converge" in _status_message(drivers.FAILED, 2.0, _solves(gauss4))
