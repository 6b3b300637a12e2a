"""Compiled step loops shared by every scheme (the step contracts: docs/plugins.md, C).

A scheme supplies one compiled step function; a factory here closes the loop over it, so
the whole run is one call into compiled code (numba inlines the step). Factories are
plain Python: nothing compiles until a loop is first called.

Step contracts
--------------
fixed step:     step(t, u, h, params, work, counters, first) -> status
                advances u in place by h; ``first`` is True on the first step of a run
                (multi-step and FSAL schemes re-initialise their memory then).
adaptive step:  try_step(t, u, h, params, work, counters, u_new) -> (code, h_taken, h_next)
                code 1: accepted, u_new holds the state at t + h_taken (h_taken <= h);
                code 0: rejected, retry with h_next; code < 0: failure.
"""
from __future__ import annotations

import math

import numba
import numpy as np

from longtime.core.status import Code

# counters: one int64 array per run, filled by the compiled code
STEPS, RHS_EVALS, NL_ITERS, REJECTED, FALLBACKS, JAC_EVALS, EXTRA1, EXTRA2 = range(8)
N_COUNTERS = 8
COUNTER_NAMES = ("steps", "rhs_evals", "nl_iters", "rejected", "fallbacks", "jac_evals")

# status codes returned by loops and steps (longtime.core.status.Code: their home)
OK, DIVERGED, FAILED, BUFFER_FULL, TIMEOUT = Code.OK, Code.DIVERGED, Code.FAILED, Code.BUFFER_FULL, Code.TIMEOUT
EPS = float(np.finfo(float).eps)


@numba.njit(cache=True, inline="always")
def is_blown_up(u, blowup):
    """True when a component is non-finite or the state's 1-norm exceeds ``blowup``.

    A branch-free sum (NaN and inf propagate into it) rather than a test per component:
    this runs every step, and for cheap steps a per-component branch is a visible cost.
    """
    total = 0.0
    for i in range(u.size):
        total += abs(u[i])
    return not total <= blowup


@numba.njit(cache=True, inline="always")
def state_scale(x):
    """max(1, max |x_i|): the scale of reached_round_off for a state x."""
    scale = 1.0
    for i in range(x.size):
        scale = max(scale, abs(x[i]))
    return scale


# an increment below ROUND_OFF_ULPS eps scale ends an iteration: what is left of it is below
# the rounding of the state's largest component (2 ulps leave an error of one sign in every
# step, a visible drift of quadratic invariants over 1e4 steps of rk4sym). STALL_SWEEPS
# sweeps in a row without a new smallest increment make an iteration "stalled", accepted
# when its smallest increment is below STALL_LEVEL scale
ROUND_OFF_ULPS = 0.5
STALL_SWEEPS = 3
STALL_LEVEL = 1e-8


@numba.njit(cache=True, inline="always")
def track_increment(delta, best, stale):
    """(best, stale) after an iteration's increment ``delta``: the smallest increment so far
    and the number of sweeps in a row that did not go below it (start from (inf, 0))."""
    if delta < best:
        return delta, 0
    return best, stale + 1


@numba.njit(cache=True, inline="always")
def stalled(best, stale, scale):
    """The increments stopped decreasing at round-off level: STALL_SWEEPS sweeps in a row
    without a new smallest increment, the smallest being below STALL_LEVEL scale. A sequence
    that decreases but not monotonically (a fixed-point iteration whose error turns from one
    component to another; an increment that rises for one sweep) sets a new smallest within
    STALL_SWEEPS sweeps and goes on converging; only a floor of round-off does not."""
    return stale >= STALL_SWEEPS and best <= STALL_LEVEL * scale


@numba.njit(cache=True, inline="always")
def reached_round_off(delta, best, stale, scale):
    """Stopping rule of every iteration "solved to round-off", after ``track_increment``: the
    increment is at machine precision, or the increments have ``stalled`` (a round-off floor
    above machine precision)."""
    return delta <= ROUND_OFF_ULPS * EPS * scale or stalled(best, stale, scale)


@numba.njit(cache=True, inline="always")
def copy_into(dst, src):
    """dst[:] = src element by element. A slice assignment makes numba compile its
    shape-mismatch error message (string formatting), a large share of every cold kernel
    compile (``python benchmarks/bench_compile.py --events`` lists it)."""
    for i in range(src.size):
        dst[i] = src[i]


def inlined(dispatcher):
    """The same compiled function, inlined where it is called (numba IR inlining). A step
    compiled apart is a call the optimiser cannot see into, a visible share of a cheap
    step's run (``python benchmarks/bench_kernels.py`` compares against hand-written loops)."""
    options = dict(dispatcher.targetoptions)
    if options.get("inline") == "always":
        return dispatcher
    options.pop("cache", None)  # a closure cannot be cached by numba (longtime.core.jitcache does)
    options.pop("nopython", None)
    return numba.njit(**{**options, "inline": "always"})(dispatcher.py_func)


def fixed_step_loop(step):
    """Compiled loop over steps k_start .. k_stop - 1 of a run of ``nsteps`` steps of size dt
    (the last one clipped to t_final), so that Python regains control between chunks
    (Ctrl-C, a deadline, progress) and a run of 10^8 steps needs no more than one call's
    worth of anything. Step k goes from t0 + k dt; ``first`` is k == 0.

    ``sample_at`` is the sorted array of step counts after which the state is recorded
    (evenly and log-spaced, ending with nsteps); ``j`` indexes the next one and ``n_out``
    the next free row of out_t/out_u (row 0, the initial state, is the caller's). Returns
    (status, samples written, next j, time reached).
    """

    step = inlined(step)

    @numba.njit
    def loop(u, t0, t_final, dt, k_start, k_stop, nsteps, sample_at, j, n_out, params, work,
             out_t, out_u, counters, blowup):
        t = t0 + k_start * dt
        next_sample = sample_at[j]  # the next sampled step, compared once per step
        for k in range(k_start, k_stop):
            t = t0 + k * dt
            h = dt if k < nsteps - 1 else t_final - t
            status = step(t, u, h, params, work, counters, k == 0)
            t = t0 + (k + 1) * dt if k < nsteps - 1 else t_final
            if status != OK or is_blown_up(u, blowup):
                counters[STEPS] += k + 1 - k_start
                out_t[n_out] = t
                copy_into(out_u[n_out], u)
                return (FAILED if status != OK else DIVERGED), n_out + 1, j, t
            if k + 1 == next_sample:
                out_t[n_out] = t
                copy_into(out_u[n_out], u)
                n_out += 1
                j += 1
                next_sample = sample_at[j]
        counters[STEPS] += k_stop - k_start
        return OK, n_out, j, t

    return loop


def sample_steps(nsteps: int, max_samples: int, per_decade: int = 20) -> np.ndarray:
    """Step counts after which a fixed-step run records its state: every ``stride``-th step
    (stride = ceil(nsteps / (max_samples - 1))) and, when max_samples allows,
    ``per_decade`` log-spaced steps in every decade of time from the first step, so a long
    run has points in every decade (growth-law fits) and no aliasing with a period. Sorted,
    unique, ending with nsteps, followed by a sentinel (nsteps + 1) the loop never reaches.
    """
    n_log = 0
    if max_samples >= 1000 and nsteps > 1:
        n_log = min(max_samples // 10, per_decade * max(1, math.ceil(math.log10(nsteps))))
    stride = max(1, math.ceil(nsteps / (max(2, max_samples - n_log) - 1)))
    even = np.arange(stride, nsteps + 1, stride, dtype=np.int64)
    parts = [even, np.array([nsteps], dtype=np.int64)]
    if n_log:
        parts.append(np.unique(np.round(np.logspace(0, math.log10(nsteps), n_log)).astype(np.int64)))
    steps = np.unique(np.concatenate(parts))
    return np.append(steps[(steps >= 1) & (steps <= nsteps)], np.int64(nsteps + 1))


@numba.njit(cache=True, inline="always")
def compensated_add(u, i, increment, comp, j):
    """u[i] += increment with Kahan's compensated summation: comp[j] carries the low-order
    part that rounding u[i] + increment drops and feeds it into the next update, so the
    sum of many small updates is rounded once, not once per step (round-off studies; the
    schemes' ``compensated`` setting)."""
    y = increment - comp[j]
    s = u[i] + y
    comp[j] = (s - u[i]) - y
    u[i] = s


def adaptive_loop(try_step):
    """Compiled loop over accepted steps from t to t_end, at most ``h_max`` each.

    Writes every ``stride``-th accepted state (and the last) to out_t/out_u, and returns
    BUFFER_FULL when they are full so that the caller can continue with fresh buffers.
    hstats holds (min, max) of accepted steps. Returns (status, samples, t, next h).
    """

    @numba.njit
    def loop(u, t, t_end, h, h_max, stride, params, work, u_new, out_t, out_u, counters,
             hstats, blowup):
        n_out = 0
        cap = out_t.size
        span = abs(t_end) + 1.0
        while t < t_end:
            hh = min(h, h_max, t_end - t)
            if hh <= 1e-15 * span:
                return FAILED, n_out, t, h
            code, h_taken, h_next = try_step(t, u, hh, params, work, counters, u_new)
            if code < 0:
                return FAILED, n_out, t, h_next
            if code == 1:
                t = t_end if t_end - (t + h_taken) <= 1e-14 * span else t + h_taken
                copy_into(u, u_new)
                counters[STEPS] += 1
                if h_taken < hstats[0]:
                    hstats[0] = h_taken
                if h_taken > hstats[1]:
                    hstats[1] = h_taken
                diverged = is_blown_up(u, blowup)
                if counters[STEPS] % stride == 0 or t >= t_end or diverged:
                    out_t[n_out] = t
                    copy_into(out_u[n_out], u)
                    n_out += 1
                if diverged:
                    return DIVERGED, n_out, t, h_next
                if n_out == cap and t < t_end:
                    return BUFFER_FULL, n_out, t, h_next
            else:
                counters[REJECTED] += 1
            h = h_next
        return OK, n_out, t, h

    return loop


def new_counters() -> np.ndarray:
    return np.zeros(N_COUNTERS, dtype=np.int64)
