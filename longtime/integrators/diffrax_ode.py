"""diffrax's ODE solvers (Kidger 2021; JAX) as external peers, on the problems that give a
right-hand side in jax.numpy (the ``jax_rhs`` capability): ``diffrax-tsit5`` (Tsitouras
5(4)), ``diffrax-dopri5`` (Dormand-Prince 5(4)), ``diffrax-dopri8`` (Dormand-Prince 8(7)),
``diffrax-kvaerno5`` (Kvaerno's ESDIRK 5(4), L-stable, Newton with the Jacobian from JAX's
autodiff of the rhs), ``diffrax-reversible-heun`` (the reversible Heun method, order 2 on
ODEs, with its embedded error estimate) under diffrax's ``PIDController`` (rtol = atol =
``tol``), and ``diffrax-semi-implicit-euler`` (symplectic Euler on a separable problem,
q from p_n first, then p from q_{n+1}: our ``symplectic-euler-b``, at a constant step ``dt``).

Called as its best users call it: one ``diffeqsolve`` from t0 to t_final under ``jax.jit``,
in double precision (``jax_enable_x64``), saving at an evenly spaced grid of SAMPLES times
(heyoka's count) through diffrax's dense output. The jitted solve is compiled ahead of time
(``jit(...).lower(...).compile()``) once per (scheme settings, problem, number of samples) in a
process, through JAX's persistent compilation cache in $LONGTIME_CACHE_DIR/jax; the seconds
that took (compiling, or loading from that cache) are the row's ``compile_s``, outside ``cpu_s``: the timing covers the
compiled call and its wait for the result (``block_until_ready``). ``peer_overhead_s``
(longtime.integrators.peer_common) is the per-step cost of the same solver on u' = 0, its
own compile excluded. The compiled loop cannot be stopped from outside: the cell's deadline
is looked at before the call and after it (a run past it is ``timeout``). Without diffrax
and jax the rows are skipped and name the extra ``longtime[diffrax]``.
"""
from __future__ import annotations

import dataclasses
import time

import numpy as np

from longtime.core import phases
from longtime.core.cache import cache_dir
from longtime.core.integrator import Integrator
from longtime.core.params import Param
from longtime.core.status import Status, time_limit_at
from longtime.core.trajectory import Trajectory
from longtime.integrators import peer_common

EXTRA = "diffrax"  # pip install "longtime[diffrax]"
SAMPLES = peer_common.SAMPLES  # the samples of a row: heyoka's count (docs/metrics.md)
MAX_STEPS = 2**31 - 1  # diffrax's bound on the steps of one solve
MIN_STEP_OF_SPAN = 1e-12  # the smallest step of an adaptive solve, as a share of its span (as CVODE's)

# compiled solves by (scheme, settings, problem identity, t0, t_final, samples):
# (compiled function, its compile seconds)
_COMPILED: dict[tuple, tuple] = {}


def _jax():
    """jax with 64-bit floats switched on (the peers integrate in double precision) and its
    persistent compilation cache in $LONGTIME_CACHE_DIR/jax (unless one is set already), so
    that the timing processes of a cell load the compiled solve instead of compiling it."""
    import jax

    jax.config.update("jax_enable_x64", True)
    if not jax.config.jax_compilation_cache_dir:
        jax.config.update("jax_compilation_cache_dir", str(cache_dir("jax")))
    return jax


class Diffrax(Integrator):
    """A diffrax solver under jax.jit (the module's docstring)."""

    kind = "external"
    library = "diffrax"
    requires = frozenset({"jax_rhs"})
    solver: str = ""  # the solver class in diffrax
    parameters = {
        "tol": Param(1e-8, "relative and absolute tolerance of diffrax's PIDController", float, positive=True,
                     role="accuracy"),
    }
    sweep = {"tol": peer_common.TOLERANCES}
    python_step_s = 2e-6  # a compiled step (no Python per step); its compile is outside the timing
    cell_budget_s = peer_common.CELL_BUDGET_S  # the default matrix's budget of a peer (execution.budget)
    stops_at_deadline = False  # one compiled call: the deadline is looked at after it

    def incompatibility(self, problem):
        reason = super().incompatibility(problem)
        if reason:
            return reason
        if not peer_common.installed("jax", "diffrax"):
            return peer_common.missing(self.name, "diffrax", EXTRA)
        return None

    # what the solve needs: overridden by the fixed-step separable solver
    def terms(self, problem, rhs):
        """diffrax's terms, the initial state's shape for them and its flattening back to u."""
        import diffrax

        return diffrax.ODETerm(lambda t, y, args: rhs(t, y, args)), (lambda u: u), (lambda y: y)

    def step_control(self, problem):
        """(dt0, stepsize_controller)."""
        import diffrax

        tol = self.settings["tol"]
        return None, diffrax.PIDController(rtol=tol, atol=tol)

    def make_solver(self):
        """The diffrax solver object."""
        import diffrax

        return getattr(diffrax, self.solver)()

    def build(self, problem, rhs, samples: int, dt0=None, controller=None):
        """The ahead-of-time compiled solve(u0, params, t0, t1, ts) -> (ys at the ``samples``
        times ts, steps, accepted, rejected, success) and its compile seconds."""
        import diffrax

        jax = _jax()
        import jax.numpy as jnp

        term, shape, flat = self.terms(problem, rhs)
        solver = self.make_solver()
        if controller is None:
            dt0, controller = self.step_control(problem)

        def solve(u0, params, t0, t1, ts):
            control = controller
            if isinstance(control, diffrax.PIDController) and control.dtmin is None:
                # a step below MIN_STEP_OF_SPAN of the span ends the solve (dt_min_reached): a
                # right-hand side that turns NaN fails there, not after MAX_STEPS rejected steps
                control = dataclasses.replace(control, dtmin=MIN_STEP_OF_SPAN * jnp.abs(t1 - t0), force_dtmin=False)
            sol = diffrax.diffeqsolve(term, solver, t0, t1, dt0, shape(u0), args=params,
                                      stepsize_controller=control, saveat=diffrax.SaveAt(ts=ts),
                                      max_steps=MAX_STEPS, adjoint=diffrax.ForwardMode(), throw=False)
            return (flat(sol.ys), sol.stats["num_steps"], sol.stats["num_accepted_steps"],
                    sol.stats["num_rejected_steps"], sol.result == diffrax.RESULTS.successful)

        example = (jnp.asarray(problem.u0), jnp.asarray(problem.params), 0.0, 1.0, jnp.linspace(0.0, 1.0, samples))
        with phases.compiling():
            c0 = time.process_time()
            compiled = jax.jit(solve).lower(*example).compile()
            seconds = time.process_time() - c0
        return compiled, seconds

    def compiled(self, problem, samples: int):
        """The compiled solve for this problem and scheme settings and its compile seconds,
        built once (any t0, t_final and grid of ``samples`` times)."""
        key = (self.name, tuple(sorted(self.settings.items())), problem.identity(), samples)
        found = _COMPILED.get(key)
        if found is None:
            found = _COMPILED[key] = self.build(problem, problem.jax_rhs, samples)
        return found

    def overhead(self, problem) -> float:
        """Seconds a step costs on u' = 0 of the problem's dimension (peer_common), compile excluded."""
        import diffrax

        def zero(t, u, params):
            return u * 0.0

        built = []
        u0, params = np.zeros(problem.dim), np.asarray(problem.params)

        def measure():
            if not built:  # compiled on the first (untimed) call
                h = 1.0 / peer_common.OVERHEAD_STEPS
                built.append(self.build(problem, zero, 2, dt0=h, controller=diffrax.ConstantStepSize())[0])
            out, cpu, _ = peer_common.timed(lambda: _ready(built[0](u0, params, 0.0, 1.0, np.array([0.0, 1.0]))))
            return cpu, int(out[1])

        key = (self.name, problem.dim, tuple(sorted(self.settings.items())))
        return peer_common.per_step_overhead(key, measure)

    def grid(self, problem, t_final, max_samples):
        return peer_common.grid(problem.t0, t_final, max_samples)

    def _integrate(self, problem, t_final, max_samples):
        grid = self.grid(problem, t_final, max_samples)
        solve, compile_s = self.compiled(problem, grid.size)
        overhead = self.overhead(problem)
        deadline = self._deadline
        if deadline is not None and time.monotonic() > deadline:
            return Trajectory(status=Status.TIMEOUT, message=time_limit_at(None), t=grid[:1],
                              u=problem.u0[None, :].copy(), cpu_s=0.0, wall_s=0.0,
                              extra={"compile_s": compile_s, "peer_overhead_s": overhead})
        u0, params = np.asarray(problem.u0), np.asarray(problem.params)
        short = problem.t0 + 1e-6 * (t_final - problem.t0)  # the first call of the compiled solve, untimed
        peer_common.warm_once((self.name, tuple(sorted(self.settings.items())), problem.identity(), grid.size),
                              lambda: _ready(solve(u0, params, problem.t0, short,
                                                   np.linspace(problem.t0, short, grid.size))))
        (ys, steps, accepted, rejected, success), cpu, wall = peer_common.timed(
            lambda: _ready(solve(u0, params, problem.t0, t_final, grid)))
        ys = np.asarray(ys, dtype=float)
        accepted, rejected = int(accepted), int(rejected)
        # diffrax fills the grid points past a failure with inf
        reached = int(np.argmin(np.all(np.isfinite(ys), axis=1))) if not np.all(np.isfinite(ys)) else grid.size
        failure = None if bool(success) else "diffeqsolve did not succeed (a step size or Newton failure)"
        n = max(1, reached)
        if failure is not None and reached < grid.size:
            ys, grid = ys[:n], grid[:n]
        timed_out = deadline is not None and time.monotonic() > deadline
        traj = peer_common.trajectory(problem, f"diffrax {self.solver}", grid, ys, cpu, wall,
                                      {"rejected": rejected}, max_samples, failure=failure, timed_out=timed_out,
                                      stoppable=False,
                                      extra={"compile_s": compile_s, "peer_overhead_s": overhead})
        traj.counters["steps"] = accepted  # the solver's steps, not the grid's samples
        traj.min_dt = traj.max_dt = None  # diffrax does not report its step sizes
        if isinstance(self, DiffraxSemiImplicitEuler):
            traj.min_dt = traj.max_dt = self.dt_for(problem)
        return traj


def _ready(out):
    """``out`` once JAX has computed it (its calls are asynchronous)."""
    for leaf in out:
        leaf.block_until_ready()
    return out


class DiffraxTsit5(Diffrax):
    name = "diffrax-tsit5"
    summary = "diffrax Tsit5 (Tsitouras 5(4)) under jax.jit, external peer; needs longtime[diffrax] and a jax_rhs"
    solver = "Tsit5"
    order = 5


class DiffraxDopri5(Diffrax):
    name = "diffrax-dopri5"
    summary = "diffrax Dopri5 (Dormand-Prince 5(4)) under jax.jit, external peer; needs longtime[diffrax] and a jax_rhs"
    solver = "Dopri5"
    order = 5


class DiffraxDopri8(Diffrax):
    name = "diffrax-dopri8"
    summary = "diffrax Dopri8 (Dormand-Prince 8(7)) under jax.jit, external peer; needs longtime[diffrax] and a jax_rhs"
    solver = "Dopri8"
    order = 8


class DiffraxKvaerno5(Diffrax):
    name = "diffrax-kvaerno5"
    summary = ("diffrax Kvaerno5 (ESDIRK 5(4), Jacobian by autodiff) under jax.jit, external peer; needs "
               "longtime[diffrax] and a jax_rhs")
    solver = "Kvaerno5"
    order = 5
    python_step_s = 2e-5  # Newton iterations with a dense LU per stage

    def make_solver(self):
        """Kvaerno5 with its Newton (chord) iterations at the run's tolerance, which a constant
        step (the overhead's run) does not supply."""
        import diffrax

        tol = self.settings["tol"]
        return diffrax.Kvaerno5(root_finder=diffrax.VeryChord(rtol=tol, atol=tol))


class DiffraxReversibleHeun(Diffrax):
    name = "diffrax-reversible-heun"
    summary = ("diffrax ReversibleHeun (reversible, order 2 on ODEs) under jax.jit, external peer; needs "
               "longtime[diffrax] and a jax_rhs")
    solver = "ReversibleHeun"
    order = 2


class DiffraxSemiImplicitEuler(Diffrax):
    """Symplectic Euler through diffrax's SemiImplicitEuler on u = (q, p): its two terms are
    q' = f(p) and p' = g(q), the halves of ``jax_rhs`` of a separable problem (the half that
    a term does not depend on is evaluated at ones and discarded)."""

    name = "diffrax-semi-implicit-euler"
    summary = ("diffrax SemiImplicitEuler (symplectic Euler, order 1, constant step) under jax.jit on "
               "separable problems, external peer; needs longtime[diffrax] and a jax_rhs")
    solver = "SemiImplicitEuler"
    order = 1
    symplectic = True
    requires = frozenset({"jax_rhs", "separable"})
    parameters = {"dt": Param(None, "time step (default: the problem's)", float, positive=True, role="step")}
    sweep = {}

    def dt_for(self, problem) -> float:
        dt = self.settings.get("dt")
        return float(problem.default_dt if dt is None else dt)

    def terms(self, problem, rhs):
        import diffrax
        import jax.numpy as jnp

        n = problem.dim // 2
        ones = jnp.ones(n)

        def q_dot(t, p, args):
            return rhs(t, jnp.concatenate([ones, p]), args)[:n]

        def p_dot(t, q, args):
            return rhs(t, jnp.concatenate([q, ones]), args)[n:]

        terms = (diffrax.ODETerm(q_dot), diffrax.ODETerm(p_dot))
        return terms, (lambda u: (u[:n], u[n:])), (lambda ys: jnp.concatenate(ys, axis=-1))

    def step_control(self, problem):
        import diffrax

        return self.dt_for(problem), diffrax.ConstantStepSize()
