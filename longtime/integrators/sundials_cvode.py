"""SUNDIALS' CVODE (Hindmarsh et al. 2005) through scikit-sundae (``sksundae.cvode.CVODE``,
whose wheels carry SUNDIALS): ``cvode-adams`` (variable-order Adams-Moulton 1-12, functional
iteration replaced by CVODE's Newton with the dense linear solver, as scikit-sundae sets it)
and ``cvode-bdf`` (variable-order BDF 1-5, Newton with the dense linear solver and the
problem's Jacobian where it has one, else CVODE's difference quotients).

Called as its best users call it: the right-hand side ``f(t, y, yp, params)`` and the
Jacobian ``J(t, y, yp, JJ, params)`` are compiled (numba) wrappers around the problem's
compiled functions, writing into SUNDIALS' own arrays (no allocation per call), with the
problem's params (in a 1-tuple) as scikit-sundae's ``userdata``. CVODE runs its own loop
in one ``solve(tspan, y0)`` call with ``tspan`` at the row's sample times (``SAMPLES`` evenly
spaced, as diffrax's; CVODE's normal mode, interpolating its steps at each); the CPU time is
that call's, the calls of the wrappers from C included. The loop cannot be stopped from
outside: the cell's deadline is looked at after the call (a run past it is ``timeout``,
and a run past the hard limit is killed as any stuck cell). CVODE does not report its step
count through ``solve``: the steps are counted once per (settings, problem, horizon) in a
process by an untimed run of the same solver over the same horizon that saves every internal
step (``tspan`` of two times), which also warms the library before the first timed call.
``peer_overhead_s`` (longtime.integrators.peer_common) is a step's cost on u' = 0 stepped one
step at a time (``method='onestep'``). Without the package the rows are skipped and name
the extra ``longtime[sundials]``.
"""
from __future__ import annotations

import time

import numba
import numpy as np

from longtime.core.integrator import Integrator
from longtime.core.params import Param
from longtime.core.status import Status, time_limit_at
from longtime.core.trajectory import Trajectory
from longtime.integrators import peer_common
from longtime.integrators.peer_common import compiled

EXTRA = "sundials"  # pip install "longtime[sundials]"


def rhs_function(problem_rhs):
    """scikit-sundae's rhsfn(t, y, yp, (params,)) around a problem's rhs(t, u, params, out)."""
    @numba.njit
    def rhsfn(t, y, yp, userdata):
        problem_rhs(t, y, userdata[0], yp)
    return rhsfn


def jac_function(problem_jac):
    """scikit-sundae's jacfn(t, y, yp, JJ, (params,)) around a problem's jac(t, u, params, out)."""
    @numba.njit
    def jacfn(t, y, yp, JJ, userdata):
        problem_jac(t, y, userdata[0], JJ)
    return jacfn


class CVODE(Integrator):
    """CVODE through scikit-sundae (the module's docstring)."""

    kind = "external"
    library = "sundials"
    method: str = ""  # CVODE's linear multistep method: "Adams" or "BDF"
    parameters = {
        "tol": Param(1e-8, "relative tolerance rtol", float, positive=True, role="accuracy"),
        "atol": Param(None, "absolute tolerance (default: tol)", float, positive=True),
    }
    sweep = {"tol": peer_common.TOLERANCES}
    python_step_s = 5e-6  # CVODE's step in C and its calls of the compiled wrappers
    cell_budget_s = peer_common.CELL_BUDGET_S  # the default matrix's budget of a peer (execution.budget)
    stops_at_deadline = False  # one compiled call: the deadline is looked at after it

    def incompatibility(self, problem):
        reason = super().incompatibility(problem)
        if reason:
            return reason
        if not peer_common.installed("sksundae"):
            return peer_common.missing(self.name, "scikit-sundae", EXTRA)
        return None

    def _solver(self, problem, rhs, jac, **options):
        from sksundae.cvode import CVODE as Solver

        tol = self.settings["tol"]
        atol = tol if self.settings["atol"] is None else self.settings["atol"]
        if self.method == "BDF" and jac is not None:
            options["jacfn"] = compiled(jac_function(jac))
        # userdata is a 1-tuple: scikit-sundae tests its truth, which an array of several has not
        return Solver(compiled(rhs_function(rhs)), userdata=(problem.params,), method=self.method, rtol=tol,
                      atol=atol, max_num_steps=2**31 - 1, **options)

    def overhead(self, problem) -> float:
        """Seconds a step costs on u' = 0 of the problem's dimension (peer_common)."""
        def measure():
            h = 1.0 / peer_common.OVERHEAD_STEPS
            solver = self._solver(problem, peer_common.zero_rhs, peer_common.zero_jac, first_step=h, max_step=h)
            solver.init_step(0.0, np.zeros(problem.dim))
            steps, cpu, _ = peer_common.timed(lambda: len(_steps(solver, 1.0, None)[0]))
            return cpu, steps

        key = (self.name, problem.dim, tuple(sorted(self.settings.items())))
        return peer_common.per_step_overhead(key, measure)

    def _integrate(self, problem, t_final, max_samples):
        span = abs(float(t_final) - problem.t0)  # scikit-sundae takes a min_step only under a max_step
        solver = self._solver(problem, problem.rhs, problem.jac, min_step=MIN_STEP_OF_SPAN * span, max_step=span)
        grid = peer_common.grid(problem.t0, t_final, max_samples)
        key = (self.name, tuple(sorted(self.settings.items())), problem.identity(), float(t_final))
        if key not in _STEPS:  # untimed: the step count, and the library warmed on this problem
            counted = solver.solve(np.array([problem.t0, t_final]), problem.u0.copy())
            _STEPS[key] = len(counted.t) - 1
        overhead = self.overhead(problem)
        deadline = self._deadline
        if deadline is not None and time.monotonic() > deadline:
            return Trajectory(status=Status.TIMEOUT, message=time_limit_at(None), t=grid[:1],
                              u=problem.u0[None, :].copy(), cpu_s=0.0, wall_s=0.0,
                              extra={"peer_overhead_s": overhead})
        result, cpu, wall = peer_common.timed(lambda: solver.solve(grid, problem.u0.copy()))
        t, u = np.asarray(result.t, dtype=float), np.asarray(result.y, dtype=float)
        timed_out = deadline is not None and time.monotonic() > deadline
        counters = {"rhs_evals": int(result.nfev), "nl_iters": 0, "rejected": 0, "fallbacks": 0,
                    "jac_evals": int(result.njev)}
        traj = peer_common.trajectory(
            problem, f"CVODE {self.method}", t, u, cpu, wall, counters, max_samples,
            failure=None if result.success else f"{result.message} (status {result.status})", timed_out=timed_out,
            stoppable=False,
            extra={"peer_overhead_s": overhead})
        traj.counters["steps"] = _STEPS[key] if result.success else traj.counters["steps"]
        traj.min_dt = traj.max_dt = None  # the samples' spacing, not CVODE's steps
        return traj


# CVODE's smallest step, as a share of the span: a right-hand side that turns NaN makes CVODE
# shrink its step without end (t + h = t, its steps unbounded here); at this step it stops with
# its error-test failure instead, and no run of the default matrix comes near it (a span of
# 1e12 steps)
MIN_STEP_OF_SPAN = 1e-12
# CVODE's step counts by (scheme, settings, problem identity, t_final), counted once in a process
_STEPS: dict[tuple, int] = {}


def _steps(solver, t_final: float, deadline: float | None):
    """Step an initialised CVODE solver to t_final one internal step at a time (the overhead's
    run): (times, states, the last result, whether it stopped at the deadline)."""
    ts, ys = [], []
    while True:
        result = solver.step(t_final, method="onestep", tstop=t_final)
        if not result.success:
            return ts, ys, result, False
        ts.append(result.t)
        ys.append(result.y.copy())
        if result.t >= t_final:
            return ts, ys, result, False
        if len(ts) % peer_common.DEADLINE_EVERY == 0 and deadline is not None and time.monotonic() > deadline:
            return ts, ys, result, True


class CVODEAdams(CVODE):
    name = "cvode-adams"
    summary = ("SUNDIALS CVODE, variable-order Adams-Moulton 1-12 (scikit-sundae), external peer; needs "
               "longtime[sundials]")
    method = "Adams"


class CVODEBDF(CVODE):
    name = "cvode-bdf"
    summary = ("SUNDIALS CVODE, variable-order BDF 1-5 with the problem's Jacobian where it has one "
               "(scikit-sundae), external peer; needs longtime[sundials]")
    method = "BDF"
