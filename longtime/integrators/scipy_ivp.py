"""scipy's integrators as external peers: ``dop853`` (Hairer's 8(5,3) pair, his code behind
``scipy.integrate.ode``: the class's docstring) and solve_ivp's methods, stepped as solve_ivp
steps them: ``scipy-rk23`` (Bogacki-Shampine 3(2)), ``scipy-rk45``
(Dormand-Prince 5(4)), ``scipy-radau`` (Radau IIA, order 5), ``scipy-bdf`` (variable-order
NDF/BDF 1-5) and ``scipy-lsoda`` (ODEPACK's LSODA: Adams/BDF switching).

Each is called as its best users call it: the right-hand side is the problem's compiled
(numba) rhs behind one compiled wrapper that returns a new array (solve_ivp's calling
convention), and the implicit methods (Radau, BDF, LSODA) get the problem's compiled
Jacobian the same way where the problem has one (else scipy's finite differences). Their loop
is scipy's own Python step loop (``OdeSolver.step``, what solve_ivp runs when it is called
without ``t_eval``, keeping every accepted step), written out so that the cell's deadline is
checked as it goes; every accepted step is recorded (thinned to max_samples). Before the
first timed run in a process, WARM_STEPS untimed steps of the same method on the same problem
pay scipy's lazy imports and the wrappers' compiles for the arrays scipy passes them. CPU
time therefore includes scipy's Python overhead per step and per rhs call: it measures what a
user of scipy pays. ``peer_overhead_s`` (longtime.integrators.peer_common) says how much of a
step that overhead is.
"""
from __future__ import annotations

import time

import numba
import numpy as np

from longtime.core.integrator import Integrator
from longtime.core.params import Param
from longtime.integrators import peer_common
from longtime.integrators.peer_common import compiled


def rhs_function(problem_rhs):
    """A compiled f(t, y, params) -> new array around a problem's rhs(t, u, params, out)."""
    @numba.njit
    def fun(t, y, params):
        out = np.empty_like(y)
        problem_rhs(t, y, params, out)
        return out
    return fun


def jac_function(problem_jac):
    """A compiled J(t, y, params) -> new (dim, dim) array around a problem's jac."""
    @numba.njit
    def jac(t, y, params):
        out = np.zeros((y.size, y.size))
        problem_jac(t, y, params, out)
        return out
    return jac


WARM_STEPS = 20  # the untimed steps that warm a method on a problem in a process


class ScipyIVP(Integrator):
    """A scipy ``OdeSolver`` stepped to t_final (the module's docstring)."""

    kind = "external"
    library = "scipy"
    method: str = ""  # the OdeSolver class in scipy.integrate
    uses_jacobian = False  # the method solves implicit stages with a Jacobian
    parameters = {
        "tol": Param(1e-8, "relative tolerance rtol", float, positive=True, role="accuracy"),
        "atol": Param(None, "absolute tolerance (default: tol)", float, positive=True),
    }
    sweep = {"tol": peer_common.TOLERANCES}
    python_step_s = 1e-4  # solve_ivp's step in Python and its Python calls of the rhs
    cell_budget_s = peer_common.CELL_BUDGET_S  # the default matrix's budget of a peer (execution.budget)
    stops_at_cpu_bound = True  # its Python loop looks at the run's CPU seconds with the deadline

    def _functions(self, problem, rhs, jac):
        """solve_ivp's fun(t, y) and jac(t, y) (or None) around compiled rhs and jac."""
        params = problem.params
        fun = compiled(rhs_function(rhs))
        jac_of = None
        if self.uses_jacobian and jac is not None:
            compiled_jac = compiled(jac_function(jac))
            jac_of = lambda t, y: compiled_jac(t, y, params)  # noqa: E731
        return (lambda t, y: fun(t, y, params)), jac_of

    def _solver(self, fun, jac, t0, u0, t_final, **options):
        import scipy.integrate

        solver_cls = getattr(scipy.integrate, self.method)
        tol = self.settings["tol"]
        atol = tol if self.settings["atol"] is None else self.settings["atol"]
        if jac is not None:
            options["jac"] = jac
        return solver_cls(fun, t0, u0, t_final, rtol=tol, atol=atol, **options)

    def overhead(self, problem) -> float:
        """Seconds a step costs on u' = 0 of the problem's dimension (peer_common)."""
        def measure():
            fun, jac = self._functions(problem, peer_common.zero_rhs, peer_common.zero_jac)
            h = 1.0 / peer_common.OVERHEAD_STEPS
            solver = self._solver(fun, jac, 0.0, np.zeros(problem.dim), 1.0, first_step=h, max_step=h)
            fun(0.0, np.zeros(problem.dim))
            steps, cpu, _ = peer_common.timed(lambda: _step_all(solver))
            return cpu, steps

        key = (self.name, problem.dim, tuple(sorted(self.settings.items())))
        return peer_common.per_step_overhead(key, measure)

    def _integrate(self, problem, t_final, max_samples):
        fun, jac = self._functions(problem, problem.rhs, problem.jac)
        u0 = problem.u0.copy()
        fun(problem.t0, u0)  # compile outside the timing
        if jac is not None:
            jac(problem.t0, u0)
        peer_common.warm_once((self.name, tuple(sorted(self.settings.items())), problem.identity()),
                              lambda: _step_all(self._solver(fun, jac, problem.t0, u0.copy(), t_final), WARM_STEPS))
        overhead = self.overhead(problem)
        deadline, bound, paced, after = self._deadline, self._cpu_bound, self._pace_bound, self._pace_after
        ts, ys = [problem.t0], [u0.copy()]
        pace = None

        def run():
            nonlocal pace
            # the bound and the pace count from here, after the timer's start: a run stopped at
            # the bound has at least ``bound`` CPU seconds
            cpu_end = None if bound is None else time.process_time() + bound
            pace = None if paced is None else peer_common.Pace(paced, problem.t0, t_final, after)
            solver = self._solver(fun, jac, problem.t0, u0.copy(), t_final)
            failure, timed_out = None, False
            with np.errstate(all="ignore"):  # a state gone non-finite is the row's status, not a warning
                while solver.status == "running":
                    failure = solver.step()
                    ts.append(solver.t)
                    ys.append(solver.y.copy())
                    if peer_common.stop_here(len(ts), cpu_end, deadline, pace, solver.t):
                        timed_out = True
                        break
            return solver, failure, timed_out

        (solver, failure, timed_out), cpu, wall = peer_common.timed(run)
        if solver.status == "failed":  # a failed step leaves t and y where they were
            ts.pop(), ys.pop()
        counters = {"rhs_evals": int(solver.nfev), "nl_iters": 0, "rejected": 0, "fallbacks": 0,
                    "jac_evals": int(solver.njev)}
        return peer_common.trajectory(
            problem, self.method, np.array(ts), np.array(ys), cpu, wall, counters, max_samples,
            failure=failure if solver.status == "failed" else None, timed_out=timed_out,
            extra={"peer_overhead_s": overhead}, pace=pace)


def _step_all(solver, most: int | None = None) -> int:
    """Step ``solver`` to its end (or ``most`` steps); the steps taken."""
    steps = 0
    with np.errstate(all="ignore"):
        while solver.status == "running" and (most is None or steps < most):
            solver.step()
            steps += 1
    return steps


class DOP853(ScipyIVP):
    """Hairer's DOP853 code as scipy ships it, ``scipy.integrate.ode(f).set_integrator('dop853')``:
    the published 8(5,3) pair with Hairer's own step-size control, stiffness test and
    counters, its whole run in one call of compiled code. Its calls back into Python are the
    rhs (12 a step: the compiled wrapper, its params bound by a Python function that turns an
    exception, which scipy's dop853 would wait on forever, into NaN and a failed step) and the
    ``solout`` callback after every accepted
    step, which records the step and returns -1 past the cell's deadline (looked at every
    DEADLINE_EVERY steps).

    ``scipy-rk45`` stays ``solve_ivp``'s RK45 (the ``OdeSolver`` class its name says), not
    ``ode('dopri5')``: Hairer's DOPRI5 chooses its steps by a stabilised (PI) controller
    (beta = 0.04), RK45 by the standard one, so the two are different step sequences of the
    same tableau, and RK45 is the class scipy's documentation points its users to.
    """

    name = "dop853"
    summary = ("scipy ode(f).set_integrator('dop853'): Hairer's DOP853 code, external peer: CPU includes the "
               "overhead of a Python call of the rhs per stage and of the step callback per step")
    method = "DOP853"
    order = 8
    sweep = {"tol": (1e-6, 1e-9, 1e-12)}
    cell_budget_s = None  # the default matrix's budget for every scheme
    python_step_s = 3e-5  # 12 Python calls of the compiled rhs and one of the step callback
    NSTEPS = 2**31 - 1  # Hairer's NMAX: the cell's deadline, not a step count, ends a long run

    def _ode(self, fun, params, t0: float, u0: np.ndarray, solout, **options):
        """scipy's ode on the dop853 code at the scheme's tolerances, from (t0, u0)."""
        from scipy.integrate import ode

        tol = self.settings["tol"]
        atol = tol if self.settings["atol"] is None else self.settings["atol"]
        raised = []

        def f(t, y):  # scipy would pass set_f_params's params to solout too
            try:
                return fun(t, y, params)
            except Exception as error:  # scipy's dop853 never returns from a raising f
                raised.append(error)
                return np.full_like(y, np.nan)  # the step fails: "step size becomes too small"

        r = ode(f).set_integrator("dop853", rtol=tol, atol=atol, nsteps=self.NSTEPS, **options)
        r.raised = raised
        r.set_solout(solout)
        return r.set_initial_value(u0, t0)

    def _run(self, fun, params, t0, u0, t_final, record=None, most=None, **options):
        """Integrate from (t0, u0) to t_final; ``record(t, y)`` after each accepted step (and at
        t0) returns True to stop. (ode, steps accepted)."""
        import warnings

        accepted = [-1]  # Hairer's code calls solout at t0 too

        def solout(t, y):
            accepted[0] += 1
            if record is not None and record(t, y):
                return -1
            return -1 if most is not None and accepted[0] >= most else 0

        r = self._ode(fun, params, t0, u0, solout, **options)
        with warnings.catch_warnings():  # a failure is the row's message, not a warning
            warnings.simplefilter("ignore")
            r.integrate(t_final)
        return r, accepted[0]

    def overhead(self, problem) -> float:
        """Seconds a step costs on u' = 0 of the problem's dimension (peer_common)."""
        fun = compiled(rhs_function(peer_common.zero_rhs))
        h = 1.0 / peer_common.OVERHEAD_STEPS

        def measure():
            (_, steps), cpu, _ = peer_common.timed(lambda: self._run(
                fun, problem.params, 0.0, np.zeros(problem.dim), 1.0, first_step=h, max_step=h))
            return cpu, steps

        key = (self.name, problem.dim, tuple(sorted(self.settings.items())))
        return peer_common.per_step_overhead(key, measure)

    def _integrate(self, problem, t_final, max_samples):
        fun = compiled(rhs_function(problem.rhs))
        params, u0 = problem.params, problem.u0.copy()
        fun(problem.t0, u0, params)  # compile outside the timing
        peer_common.warm_once((self.name, tuple(sorted(self.settings.items())), problem.identity()),
                              lambda: self._run(fun, params, problem.t0, u0.copy(), t_final, most=WARM_STEPS))
        overhead = self.overhead(problem)
        deadline, bound, paced, after = self._deadline, self._cpu_bound, self._pace_bound, self._pace_after
        ts, ys = [], []
        late = [False]
        cpu_end: list[float | None] = [None]
        pace: list[peer_common.Pace | None] = [None]

        def record(t, y):
            ts.append(t)
            ys.append(y.copy())
            if peer_common.stop_here(len(ts), cpu_end[0], deadline, pace[0], t):
                late[0] = True
            return late[0]

        def run():
            # the bound and the pace count from here, after the timer's start (as ScipyIVP's loop counts them)
            cpu_end[0] = None if bound is None else time.process_time() + bound
            pace[0] = None if paced is None else peer_common.Pace(paced, problem.t0, t_final, after)
            return self._run(fun, params, problem.t0, u0.copy(), t_final, record)

        (r, _), cpu, wall = peer_common.timed(run)
        code = r.get_return_code()
        failure = None if r.successful() else r._integrator.messages.get(code, f"return code {code}")
        if r.raised:
            failure = f"the rhs raised {r.raised[0]!r}"
        nfev, _, _, rejected = (int(n) for n in r._integrator.iwork[16:20])  # NFCN, NSTEP, NACCPT, NREJCT
        counters = {"rhs_evals": nfev, "nl_iters": 0, "rejected": rejected, "fallbacks": 0, "jac_evals": 0}
        return peer_common.trajectory(
            problem, "scipy dop853", np.array(ts), np.array(ys), cpu, wall, counters, max_samples,
            failure=failure, timed_out=late[0], extra={"peer_overhead_s": overhead}, pace=pace[0])


class ScipyRK23(ScipyIVP):
    name = "scipy-rk23"
    summary = ("scipy solve_ivp(method='RK23'), Bogacki-Shampine 3(2), external peer: CPU includes scipy's "
               "Python overhead per step")
    method = "RK23"
    order = 3


class ScipyRK45(ScipyIVP):
    name = "scipy-rk45"
    summary = ("scipy solve_ivp(method='RK45'), Dormand-Prince 5(4), external peer: CPU includes scipy's "
               "Python overhead per step")
    method = "RK45"
    order = 5


class ScipyRadau(ScipyIVP):
    name = "scipy-radau"
    summary = ("scipy solve_ivp(method='Radau'), Radau IIA order 5 with the problem's Jacobian where it has "
               "one, external peer")
    method = "Radau"
    order = 5
    uses_jacobian = True
    python_step_s = 4e-4  # Newton iterations and LU factorisations driven from Python
    step_cost = 300.0  # finite-difference Jacobians (a Python rhs call per component) and dense LUs


class ScipyBDF(ScipyIVP):
    name = "scipy-bdf"
    summary = ("scipy solve_ivp(method='BDF'), variable-order NDF 1-5 with the problem's Jacobian where it "
               "has one, external peer")
    method = "BDF"
    order = None  # variable, 1 to 5
    uses_jacobian = True
    python_step_s = 2e-4
    step_cost = 300.0  # as Radau's


class ScipyLSODA(ScipyIVP):
    name = "scipy-lsoda"
    summary = ("scipy solve_ivp(method='LSODA'), ODEPACK's Adams/BDF switching with the problem's Jacobian "
               "where it has one, external peer")
    method = "LSODA"
    order = None  # variable: Adams 1 to 12, BDF 1 to 5
    uses_jacobian = True
    python_step_s = 5e-5
    step_cost = 300.0  # as Radau's, when it switches to BDF
