"""SUNDIALS' CVODE (Hindmarsh et al. 2005) through scikit-sundae (``sksundae.cvode.CVODE``,
whose wheels carry SUNDIALS): ``cvode-adams`` (variable-order Adams-Moulton 1-12, functional
iteration replaced by CVODE's Newton with the dense linear solver, as scikit-sundae sets it)
and ``cvode-bdf`` (variable-order BDF 1-5, Newton with the dense linear solver and the
problem's Jacobian where it has one, else CVODE's difference quotients).

Called as its best users call it: the right-hand side ``f(t, y, yp, params)`` and the
Jacobian ``J(t, y, yp, JJ, params)`` are compiled (numba) wrappers around the problem's
compiled functions, writing into SUNDIALS' own arrays (no allocation per call), with the
problem's params (in a 1-tuple) as scikit-sundae's ``userdata``. CVODE steps from Python one internal step
at a time (``step(t_final, method='onestep', tstop=t_final)``), which records every
accepted step and checks the cell's deadline as it goes; the CPU time includes that call and
the calls of the wrappers from C. ``peer_overhead_s`` (longtime.integrators.peer_common)
says how much of a step that boundary is. Without the package the rows are skipped and name
the extra ``longtime[sundials]``.
"""
from __future__ import annotations

import time

import numba
import numpy as np

from longtime.core.integrator import Integrator
from longtime.core.params import Param
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
    sweep = {"tol": (1e-6, 1e-9)}
    python_step_s = 3e-5  # a Python call per step and the wrappers' calls from C
    cell_budget_s = 0.03  # the default matrix's estimated seconds of one run (execution.budget)

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
        solver = self._solver(problem, problem.rhs, problem.jac)
        solver.init_step(problem.t0, problem.u0.copy())
        solver.step(t_final, method="onestep", tstop=t_final)  # compiles the wrappers outside the timing
        overhead = self.overhead(problem)
        deadline = self._deadline
        solver = self._solver(problem, problem.rhs, problem.jac)

        def run():
            solver.init_step(problem.t0, problem.u0.copy())
            return _steps(solver, t_final, deadline)

        (ts, ys, last, timed_out), cpu, wall = peer_common.timed(run)
        t, u = np.array([problem.t0, *ts]), np.vstack([problem.u0[None, :], *ys]) if ys else problem.u0[None, :]
        counters = {"rhs_evals": int(last.nfev), "nl_iters": 0, "rejected": 0, "fallbacks": 0,
                    "jac_evals": int(last.njev)}
        return peer_common.trajectory(
            problem, f"CVODE {self.method}", t, u, cpu, wall, counters, max_samples,
            failure=None if last.success else f"{last.message} (status {last.status})", timed_out=timed_out,
            extra={"peer_overhead_s": overhead})


def _steps(solver, t_final: float, deadline: float | None):
    """Step an initialised CVODE solver to t_final one internal step at a time: (times,
    states, the last result, whether it stopped at the deadline)."""
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
