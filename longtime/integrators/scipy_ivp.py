"""scipy's DOP853 (Hairer's 8(5,3) pair) as an external peer, stepped as solve_ivp steps it.

It runs scipy's own Python step loop and calls the problem's compiled rhs through a Python
wrapper once per evaluation, so its CPU time includes that interpreter overhead (tens of
microseconds per step): it measures what a user of scipy pays, not the cost of the method
itself, and is labelled so. Every accepted step is recorded (thinned to max_samples).
"""
from __future__ import annotations

import time

import numpy as np

from longtime.core.integrator import Integrator, Trajectory, cached_kernel
from longtime.core.params import Param
from longtime.core.problem import BLOWUP_MESSAGE

DEADLINE_EVERY = 256  # steps between two looks at the cell's deadline


class DOP853(Integrator):
    name = "dop853"
    summary = ("scipy solve_ivp(method='DOP853'), external peer: CPU includes scipy's Python "
               "overhead per step and per rhs call")
    kind = "external"
    order = 8
    parameters = {
        "tol": Param(1e-8, "relative tolerance rtol", float, positive=True, role="accuracy"),
        "atol": Param(None, "absolute tolerance (default: tol)", float, positive=True),
    }
    sweep = {"tol": (1e-6, 1e-9, 1e-12)}
    python_step_s = 1e-4  # solve_ivp's step in Python and its twelve Python calls of the rhs

    def _integrate(self, problem, t_final, max_samples):
        from scipy.integrate import DOP853 as Solver

        # the cached twin of the rhs: a problem's closure rhs would compile in every process
        rhs, params = cached_kernel(self, problem, lambda: problem.rhs), problem.params

        def fun(t, y):
            out = np.empty_like(y)
            rhs(t, y, params, out)
            return out

        fun(problem.t0, problem.u0.copy())  # compile outside the timing
        tol = self.settings["tol"]
        atol = tol if self.settings["atol"] is None else self.settings["atol"]
        # solve_ivp's own loop, written out (it records every step alike) so that the cell's
        # deadline is checked as it goes: solve_ivp cannot be stopped from outside
        c0, w0 = time.process_time(), time.perf_counter()
        solver = Solver(fun, problem.t0, problem.u0.copy(), t_final, rtol=tol, atol=atol)
        ts, ys, failure, timed_out = [problem.t0], [problem.u0.copy()], None, False
        while solver.status == "running":
            failure = solver.step()
            ts.append(solver.t)
            ys.append(solver.y.copy())
            if len(ts) % DEADLINE_EVERY == 0 and self._deadline is not None and time.monotonic() > self._deadline:
                timed_out = True
                break
        cpu, wall = time.process_time() - c0, time.perf_counter() - w0
        if solver.status == "failed":  # a failed step leaves t and y where they were
            ts.pop(), ys.pop()
        t, u = np.array(ts), np.array(ys)
        status, message = "ok", ""
        first = problem.first_blowup(u)
        if first is not None:
            t, u = t[:first + 1], u[:first + 1]
            status, message = "diverged", BLOWUP_MESSAGE.format(t=t[-1])
        elif timed_out:
            status, message = "timeout", f"stopped at t={t[-1]:.6g}: past the cell's time limit"
        elif solver.status == "failed":
            status, message = "failed", f"DOP853: {failure} (t={t[-1]:.6g})"
        steps = t.size - 1
        dts = np.diff(t)
        if t.size > max_samples:
            stride = -(-(t.size - 1) // (max_samples - 1))
            keep = np.r_[np.arange(0, t.size - 1, stride), t.size - 1]
            t, u = t[keep], u[keep]
        counters = {"steps": steps, "rhs_evals": int(solver.nfev), "nl_iters": 0, "rejected": 0,
                    "fallbacks": 0, "jac_evals": int(solver.njev)}
        return Trajectory(status=status, message=message, t=np.ascontiguousarray(t),
                          u=np.ascontiguousarray(u), cpu_s=cpu, wall_s=wall, counters=counters,
                          min_dt=float(dts.min()) if steps else None,
                          max_dt=float(dts.max()) if steps else None)
