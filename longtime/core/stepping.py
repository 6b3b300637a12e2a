"""The two shared drivers: ``FixedStepIntegrator`` (a constant step) and
``AdaptiveIntegrator`` (steps it chooses), the Python side of the compiled loops of
``longtime.core.drivers``. A scheme that derives from one implements only its compiled step
(``make_step`` or ``make_try_step``) and inherits allocation, warm-up (compilation outside the
timing), the run in chunks (Ctrl-C, the deadline and progress lines between them) and the
counters."""
from __future__ import annotations

import functools
import math
import time
from abc import abstractmethod
from typing import Any, Callable

import numpy as np

from longtime.core import drivers
from longtime.core.integrator import Integrator
from longtime.core.kernel_cache import cached_kernel
from longtime.core.params import Param
from longtime.core.problem import Problem
from longtime.core.progress import RunProgress
from longtime.core.status import STATUS_OF_CODE, blew_up_at, step_failed_at, time_limit_at
from longtime.core.trajectory import Trajectory

# fixed-step runs go in chunks: the first of FIRST_CHUNK steps, then sized to take about
# CHUNK_SECONDS each (a call into compiled code costs microseconds: no measurable slowdown)
FIRST_CHUNK = 10_000
CHUNK_SECONDS = 0.25

# the setting of the fixed-step families that sum the state update with Kahan's compensated
# summation (drivers.compensated_add); off by default: the published schemes round plainly
COMPENSATED = Param(False, "Kahan-compensated summation of the state update (round-off studies)", bool)


@functools.lru_cache(maxsize=32)
def cached_sample_steps(nsteps: int, max_samples: int) -> np.ndarray:
    """drivers.sample_steps, once per run length (the repeats of a cell share it; no loop
    writes into it)."""
    return drivers.sample_steps(nsteps, max_samples)


class FixedStepIntegrator(Integrator):
    """A one-step (or self-starting multi-step) scheme with a constant step dt."""

    kind = "fixed"
    parameters = {"dt": Param(None, "time step (default: the problem's)", float, positive=True, role="step")}

    @abstractmethod
    def make_step(self, problem: Problem) -> Callable:
        """Compiled ``step(t, u, h, params, work, counters, first) -> status``."""

    def work_shape(self, problem: Problem) -> tuple[int, ...]:
        """Shape of the scratch array handed to every step."""
        return (1, problem.dim)

    def prepare_work(self, problem: Problem, work: np.ndarray) -> None:
        """Fill constant data (coefficients) into the scratch array before the run."""

    def dt_for(self, problem: Problem) -> float:
        dt = self.settings.get("dt")
        return float(problem.default_dt if dt is None else dt)

    def compiled_loop(self, problem: Problem) -> Callable:
        """The compiled step loop (drivers.fixed_step_loop) runs and stability measurements use."""
        return cached_kernel(self, problem, lambda: drivers.fixed_step_loop(self.make_step(problem)))

    def _integrate(self, problem, t_final, max_samples):
        dt = self.dt_for(problem)
        span = t_final - problem.t0
        nsteps = max(1, math.ceil(span / dt - 1e-9))
        sample_at = cached_sample_steps(nsteps, max_samples)
        loop = self.compiled_loop(problem)
        work = np.zeros(self.work_shape(problem))
        self.prepare_work(problem, work)
        n_out = sample_at.size + 1  # the initial state, the samples, a blow-up or a stop
        out_t = np.empty(n_out)
        out_u = np.empty((n_out, problem.dim))
        counters = drivers.new_counters()
        # warm-up: compile outside the timing, on a throw-away state
        loop(problem.u0.copy(), problem.t0, problem.t0 + dt, dt, 0, 1, 1, np.array([1, 2]), 0, 1,
             problem.params, work.copy(), np.empty(2), np.empty((2, problem.dim)), counters.copy(),
             problem.blowup)
        u = problem.u0.copy()
        out_t[0], out_u[0] = problem.t0, u
        deadline, watch = self._deadline, RunProgress(f"{problem.name} x {self.name}", problem.t0, t_final)
        status, n, j, k, t_end, chunk = drivers.OK, 1, 0, 0, problem.t0, FIRST_CHUNK
        cpu = wall = 0.0
        while k < nsteps:
            # chunks of about CHUNK_SECONDS: Python sees Ctrl-C, the deadline and progress
            # between them; the samples do not depend on where the chunks end
            stop = min(nsteps, k + chunk)
            c0, w0 = time.process_time(), time.perf_counter()
            status, n, j, t_end = loop(u, problem.t0, t_final, dt, k, stop, nsteps, sample_at, j, n,
                                       problem.params, work, out_t, out_u, counters, problem.blowup)
            c1, w1 = time.process_time() - c0, time.perf_counter() - w0
            cpu, wall, k = cpu + c1, wall + w1, stop
            if status != drivers.OK:
                break
            if k < nsteps and deadline is not None and time.monotonic() > deadline:
                status = drivers.TIMEOUT
                if out_t[n - 1] != t_end:  # what it reached, unless a sample holds it already
                    out_t[n], out_u[n] = t_end, u
                    n += 1
                break
            watch.update(t_end)
            chunk = max(FIRST_CHUNK, int(chunk * CHUNK_SECONDS / max(w1, 1e-9)))
        watch.close()
        return Trajectory(
            status=STATUS_OF_CODE[status], message=_status_message(status, t_end, _solves(self)), t=out_t[:n],
            u=out_u[:n], cpu_s=cpu, wall_s=wall, counters=self._counters(counters),
            min_dt=dt, max_dt=dt)


class AdaptiveIntegrator(Integrator):
    """A one-step scheme that chooses its own steps; runs in chunks of recorded samples."""

    kind = "adaptive"
    chunk = 4096  # samples per compiled call

    @abstractmethod
    def make_try_step(self, problem: Problem) -> Callable:
        """Compiled ``try_step(t, u, h, params, work, counters, u_new) -> (code, h_taken, h_next)``."""

    def work_shape(self, problem: Problem) -> tuple[int, ...]:
        return (1, problem.dim)

    def prepare_work(self, problem: Problem, work: np.ndarray) -> None:
        """Fill constant data (coefficients, tolerances) into the scratch array."""

    def initial_step(self, problem: Problem, t_final: float) -> float:
        return float(self.settings.get("dt") or problem.default_dt)

    def max_step(self, problem: Problem, t_final: float) -> float:
        return float(self.settings.get("max_dt") or (t_final - problem.t0))

    def compiled_loop(self, problem: Problem) -> Callable:
        """The compiled step loop (drivers.adaptive_loop) runs and stability measurements use."""
        return cached_kernel(self, problem, lambda: drivers.adaptive_loop(self.make_try_step(problem)))

    def _integrate(self, problem, t_final, max_samples):
        loop = self.compiled_loop(problem)
        work = np.zeros(self.work_shape(problem))
        self.prepare_work(problem, work)
        h0, h_max = self.initial_step(problem, t_final), self.max_step(problem, t_final)
        dim, t0 = problem.dim, problem.t0

        def fresh():
            return np.empty(self.chunk), np.empty((self.chunk, dim))

        # warm-up: compile outside the timing
        bt, bu = fresh()
        loop(problem.u0.copy(), t0, t0 + 1e-3 * h0, h0, h_max, 1, problem.params, work.copy(),
             np.empty(dim), bt, bu, drivers.new_counters(), np.array([np.inf, 0.0]), problem.blowup)

        u, u_new = problem.u0.copy(), np.empty(dim)
        counters, hstats = drivers.new_counters(), np.array([np.inf, 0.0])
        ts, us = [np.array([t0])], [u[None, :].copy()]
        total, stride, t, h = 1, 1, t0, h0
        cpu = wall = 0.0
        watch = RunProgress(f"{problem.name} x {self.name}", problem.t0, t_final)
        while True:
            bt, bu = fresh()
            c0, w0 = time.process_time(), time.perf_counter()
            status, n, t, h = loop(u, t, t_final, h, h_max, stride, problem.params, work, u_new,
                                   bt, bu, counters, hstats, problem.blowup)
            cpu += time.process_time() - c0
            wall += time.perf_counter() - w0
            ts.append(bt[:n].copy())
            us.append(bu[:n].copy())
            total += n
            while total > max_samples:  # keep every other sample, record half as often
                tt, uu = np.concatenate(ts), np.concatenate(us)
                keep = np.r_[np.arange(0, tt.size - 1, 2), tt.size - 1]
                ts, us, total, stride = [tt[keep]], [uu[keep]], keep.size, 2 * stride
            if status != drivers.BUFFER_FULL:
                break
            if self._deadline is not None and time.monotonic() > self._deadline:
                status = drivers.TIMEOUT  # the last sample is where it got
                break
            watch.update(t)
        watch.close()
        steps = int(counters[drivers.STEPS])
        message = _status_message(status, t, _solves(self))
        if status == drivers.FAILED and np.isfinite(u).all():  # say why where it is plain
            f = np.empty(dim)
            problem.rhs(t, u, problem.params, f)
            if not np.isfinite(f).all():
                message = step_failed_at(t, "the right-hand side is not finite there (NaN or inf)")
            elif not np.isfinite(u_new).all():
                message = step_failed_at(t, "the steps tried from there gave a non-finite state (a right-hand "
                                            "side that is not finite within the step, or a diverging iteration)")
        return Trajectory(
            status=STATUS_OF_CODE[status], message=message, t=np.concatenate(ts),
            u=np.concatenate(us), cpu_s=cpu, wall_s=wall, counters=self._counters(counters),
            min_dt=float(hstats[0]) if steps else None, max_dt=float(hstats[1]) if steps else None)


def _solves(scheme: Any) -> bool:
    """Whether ``scheme``'s step solves a nonlinear system: it declares an iteration limit
    (``max_iter``: the implicit Runge-Kutta, AVF, Dirac and RATTLE steps)."""
    return "max_iter" in scheme.parameters


def _status_message(status: int, t: float, solves: bool = True) -> str:
    """The row's message of a loop's ``status`` at ``t``; ``solves``: the scheme's step solves
    a nonlinear system (an implicit stage, whose solve can fail), else only a step size
    underflow fails a step."""
    if status == drivers.TIMEOUT:
        return time_limit_at(t)
    if status == drivers.DIVERGED:
        return blew_up_at(t)
    if status == drivers.FAILED:
        why = "nonlinear solve did not converge or step size underflow" if solves else "step size underflow"
        return step_failed_at(t, f"({why})")
    return ""
