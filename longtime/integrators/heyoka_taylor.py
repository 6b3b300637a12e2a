"""heyoka's adaptive Taylor integrator as a scheme: the high-precision peer of ``taylor``/``bpl``.

heyoka picks its order from the tolerance (p = ceil(-ln(tol)/2 + 1): 20 at machine epsilon)
and its step from the last two coefficients (Jorba-Zou). Its LLVM compilation happens once
per (problem identity, tol, high_accuracy), outside the timing (large systems in compact
mode: longtime.core.heyoka_build); the timing covers ``propagate_grid`` alone, whose dense output
gives the samples without clipping heyoka's own steps.

The cell's time limit: the compiled drivers check it between chunks, but heyoka's grid must
not be cut into pieces (each piece clips a step and changes the round-off). So when a
deadline is set, the first run of a cell is a guard: the same ``propagate_grid`` with a
callback after every step that stops it at the deadline (and lets Ctrl-C in). Only a guard
that finishes is followed by the timed runs, without the callback (a Python call per step
would be timed too); they repeat the guard's steps bitwise, so they take about as long.
"""
from __future__ import annotations

import math
import time

import numpy as np

from longtime.core import heyoka_build
from longtime.core.integrator import Integrator
from longtime.core.params import Param
from longtime.core.problem import BLOWUP_MESSAGE
from longtime.core.status import Status, time_limit_at
from longtime.core.trajectory import Trajectory

# compiled taylor_adaptive objects, by (problem identity, tol, high_accuracy)
_COMPILED: dict[tuple, object] = {}
SAMPLES = 10_001  # docs/metrics.md: time means over at least 1e4 evenly spaced samples


class Heyoka(Integrator):
    name = "heyoka"
    summary = "heyoka's adaptive Taylor integrator (order from tol), compiled outside the timing"
    kind = "external"
    library = "heyoka"
    requires = frozenset({"heyoka"})
    parameters = {
        "tol": Param(float(np.finfo(float).eps), "heyoka's tolerance (order p = ceil(-ln(tol)/2 + 1))",
                     float, positive=True, role="accuracy"),
        "high_accuracy": Param(False, "compensated summation and more careful step (long runs)", bool),
        # the same method and tolerance with the state carried in x86's 80-bit long double:
        # what a run through close encounters needs where a double state's rounding is the
        # floor (docs/problems.md, pythagorean-three-body)
        "precision": Param("double", "the floating type heyoka integrates in", str,
                           choices=("double", "long-double")),
    }
    sweep = {"tol": (1e-9, 1e-12, float(np.finfo(float).eps))}

    def __init__(self, **settings):
        super().__init__(**settings)
        self.order = max(1, math.ceil(-math.log(self.settings["tol"]) / 2 + 1))

    @property
    def fp(self):
        """The floating type of the integration: numpy's float64 or longdouble."""
        return np.longdouble if self.settings["precision"] == "long-double" else np.float64

    def compiled(self, problem, timeout_s: float | None = None):
        """The taylor_adaptive object for this problem and these settings (built once);
        heyoka_build.CompileTimeout past ``timeout_s``."""
        key = (problem.identity(), self.settings["tol"], self.settings["high_accuracy"], self.settings["precision"])
        ta = _COMPILED.get(key)
        if ta is None:
            fp = self.fp
            extra = {} if fp is np.float64 else {"fp_type": fp}
            ta = heyoka_build.taylor_adaptive(problem, problem.u0.astype(fp), timeout_s, tol=fp(self.settings["tol"]),
                                              time=fp(problem.t0), high_accuracy=self.settings["high_accuracy"],
                                              **extra)
            _COMPILED[key] = ta
        return ta

    def grid(self, problem, t_final, max_samples):
        """Evenly spaced sample times: SAMPLES of them (at most max_samples). Dense output
        costs a polynomial evaluation per sample inside the timed call, so the grid is not
        refined with the run's length; 1e4 evenly spaced samples are what docs/metrics.md asks of
        the time means."""
        return np.linspace(problem.t0, t_final, min(max_samples, SAMPLES))

    def _integrate(self, problem, t_final, max_samples):
        import heyoka as hy

        grid = self.grid(problem, t_final, max_samples)
        deadline = self._deadline
        try:
            ta = self.compiled(problem, None if deadline is None else deadline - time.monotonic())
        except heyoka_build.CompileTimeout as exc:
            return Trajectory(status=Status.TIMEOUT, message=f"time limit reached before the first step: {exc}",
                              t=grid[:1], u=problem.u0[None, :].copy(), cpu_s=0.0, wall_s=0.0)
        if deadline is not None:
            stopped = self._guard(ta, problem, grid, deadline, self.fp)
            if stopped is not None:
                return stopped
            # the timed runs of this cell repeat the guard's steps: no second guard
            self._deadline = None
        ta.time = self.fp(problem.t0)
        ta.state[:] = problem.u0.astype(self.fp)
        try:
            c0, w0 = time.process_time(), time.perf_counter()
            outcome, min_h, max_h, nsteps, _, states = ta.propagate_grid(grid.astype(self.fp))
            cpu, wall = time.process_time() - c0, time.perf_counter() - w0
        except Exception as exc:  # heyoka raises on invalid grids or states
            return Trajectory(status=Status.FAILED, message=f"heyoka: {exc}", t=grid[:1],
                              u=problem.u0[None, :].copy(), cpu_s=0.0, wall_s=0.0)
        states = np.asarray(states, dtype=float)
        # heyoka fills the grid points it did not reach with NaN; beyond the problem's bound
        # counts as a blow-up too, as in the compiled drivers
        first = problem.first_blowup(states)
        n, status, message = grid.size, "ok", ""
        if first is not None:
            n = first + 1  # keep the first bad sample, as the drivers do
            status = Status.DIVERGED
            message = BLOWUP_MESSAGE.format(t=grid[n - 1])
        if outcome != hy.taylor_outcome.time_limit and status == Status.OK:
            status, message = Status.FAILED, f"heyoka stopped with outcome {outcome} at t={float(ta.time):.6g}"
            n = max(1, min(n, int(np.searchsorted(grid, float(ta.time), side="right"))))
        steps = int(nsteps)
        return Trajectory(
            status=status, message=message, t=grid[:n], u=states[:n], cpu_s=cpu, wall_s=wall,
            counters={"steps": steps}, min_dt=float(min_h) if steps else None,
            max_dt=float(max_h) if steps else None, extra={"order": ta.order, "tol": self.settings["tol"]})

    @staticmethod
    def _guard(ta, problem, grid, deadline: float, fp=np.float64) -> Trajectory | None:
        """The untimed guard run (see the module): None when it finished by ``deadline`` (a
        time.monotonic() value), else the ``timeout`` trajectory up to where it got."""
        import heyoka as hy

        ta.time = fp(problem.t0)
        ta.state[:] = problem.u0.astype(fp)
        try:
            c0, w0 = time.process_time(), time.perf_counter()
            outcome, min_h, max_h, nsteps, _, states = ta.propagate_grid(
                grid.astype(fp), callback=lambda _: time.monotonic() < deadline)
            cpu, wall = time.process_time() - c0, time.perf_counter() - w0
        except Exception:  # the timed run meets the same error and reports it
            return None
        if outcome != hy.taylor_outcome.cb_stop:
            return None
        reached, steps = float(ta.time), int(nsteps)
        n = max(1, int(np.searchsorted(grid, reached, side="right")))
        t, u = grid[:n], np.asarray(states, dtype=float)[:n]
        if reached > grid[n - 1]:  # where it got, between grid times
            t, u = np.r_[t, reached], np.vstack([u, np.asarray(ta.state, dtype=float)])
        # the cost of what it did, timed with the guard's callback (the row is a timeout)
        return Trajectory(status=Status.TIMEOUT, message=time_limit_at(reached), t=t, u=u,
                          cpu_s=cpu, wall_s=wall, counters={"steps": steps},
                          min_dt=float(min_h) if steps else None, max_dt=float(max_h) if steps else None)
