"""heyoka's adaptive Taylor integrator as a scheme: the high-precision peer of ``taylor``/``bpl``.

heyoka picks its order from the tolerance (p = ceil(-ln(tol)/2 + 1): 20 at machine epsilon)
and its step from the last two coefficients (Jorba-Zou). Its LLVM compilation happens once
per (problem identity, tol, high_accuracy), outside the timing; the timing covers
``propagate_grid`` alone, whose dense output gives the samples without clipping heyoka's
own steps.
"""
from __future__ import annotations

import math
import time

import numpy as np

from ..integrator import Integrator, Trajectory
from ..params import Param
from ..problem import BLOWUP_MESSAGE

# compiled taylor_adaptive objects, by (problem identity, tol, high_accuracy)
_COMPILED: dict[tuple, object] = {}
SAMPLES = 10_001  # docs/metrics.md: time means over at least 1e4 evenly spaced samples
PIECES = 16  # propagate_grid calls per run: the deadline and Ctrl-C are checked between them


class Heyoka(Integrator):
    name = "heyoka"
    summary = "heyoka's adaptive Taylor integrator (order from tol), compiled outside the timing"
    kind = "external"
    requires = frozenset({"heyoka"})
    parameters = {
        "tol": Param(float(np.finfo(float).eps), "heyoka's tolerance (order p = ceil(-ln(tol)/2 + 1))",
                     float, positive=True),
        "high_accuracy": Param(False, "compensated summation and more careful step (long runs)", bool),
    }
    sweep = {"tol": (1e-9, 1e-12, float(np.finfo(float).eps))}

    def __init__(self, **settings):
        super().__init__(**settings)
        self.order = max(1, math.ceil(-math.log(self.settings["tol"]) / 2 + 1))

    def compiled(self, problem):
        """The taylor_adaptive object for this problem and these settings (built once)."""
        key = (problem.identity(), self.settings["tol"], self.settings["high_accuracy"])
        ta = _COMPILED.get(key)
        if ta is None:
            import heyoka as hy

            variables, rhs = problem.heyoka_system()
            ta = hy.taylor_adaptive(list(zip(variables, rhs)), problem.u0.copy(),
                                    tol=self.settings["tol"], time=problem.t0,
                                    high_accuracy=self.settings["high_accuracy"])
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

        ta = self.compiled(problem)
        grid = self.grid(problem, t_final, max_samples)
        ta.time = problem.t0
        ta.state[:] = problem.u0
        # the grid in PIECES pieces, each starting where the last ended (heyoka wants a grid
        # from the current time): between two, Python checks the cell's deadline and Ctrl-C.
        # A fixed count, so the steps (each piece's last is clipped to its end) never depend
        # on how long a run takes.
        bounds = np.unique(np.linspace(0, grid.size - 1, PIECES + 1).round().astype(int))
        parts, min_h, max_h, nsteps, cpu, wall, timed_out = [], math.inf, 0.0, 0, 0.0, 0.0, False
        try:
            for a, b in zip(bounds[:-1], bounds[1:]):
                c0, w0 = time.process_time(), time.perf_counter()
                outcome, lo, hi, steps, _, states = ta.propagate_grid(grid[a:b + 1])
                cpu, wall = cpu + time.process_time() - c0, wall + time.perf_counter() - w0
                parts.append(np.asarray(states, dtype=float)[0 if a == 0 else 1:])
                min_h, max_h, nsteps = min(min_h, lo), max(max_h, hi), nsteps + int(steps)
                if outcome != hy.taylor_outcome.time_limit:
                    break
                if self._deadline is not None and time.monotonic() > self._deadline and b < grid.size - 1:
                    timed_out = True
                    break
        except Exception as exc:  # heyoka raises on invalid grids or states
            return Trajectory(status="failed", message=f"heyoka: {exc}", t=grid[:1],
                              u=problem.u0[None, :].copy(), cpu_s=0.0, wall_s=0.0)
        states = np.concatenate(parts)
        if timed_out:
            return Trajectory(status="timeout", message=f"stopped at t={grid[len(states) - 1]:.6g}: past the "
                              f"cell's time limit", t=grid[:len(states)], u=states, cpu_s=cpu, wall_s=wall,
                              counters={"steps": nsteps}, min_dt=float(min_h), max_dt=float(max_h),
                              extra={"order": ta.order, "tol": self.settings["tol"]})
        grid = grid[:len(states)] if outcome != hy.taylor_outcome.time_limit else grid
        # heyoka fills the grid points it did not reach with NaN; beyond the problem's bound
        # counts as a blow-up too, as in the compiled drivers
        first = problem.first_blowup(states)
        n, status, message = grid.size, "ok", ""
        if first is not None:
            n = first + 1  # keep the first bad sample, as the drivers do
            status = "diverged"
            message = BLOWUP_MESSAGE.format(t=grid[n - 1])
        if outcome != hy.taylor_outcome.time_limit and status == "ok":
            status, message = "failed", f"heyoka stopped with outcome {outcome} at t={ta.time:.6g}"
            n = max(1, min(n, int(np.searchsorted(grid, ta.time, side="right"))))
        steps = nsteps
        return Trajectory(
            status=status, message=message, t=grid[:n], u=states[:n], cpu_s=cpu, wall_s=wall,
            counters={"steps": steps}, min_dt=float(min_h) if steps else None,
            max_dt=float(max_h) if steps else None, extra={"order": ta.order, "tol": self.settings["tol"]})
