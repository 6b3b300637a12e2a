"""REBOUND's integrators (Rein and Liu 2012; pip package ``rebound``) as external schemes on
the n-body family: ``rebound-leapfrog`` (drift-kick-drift, order 2), ``rebound-whfast``
(Wisdom-Holman in Jacobi coordinates, Rein and Tamayo 2015), ``rebound-mercurius`` (hybrid
Wisdom-Holman and IAS15 at close encounters, Rein et al. 2019), ``rebound-janus`` (the
bit-reversible integer composition, Rein and Tamayo 2018), ``rebound-saba1064`` (SABA(10,6,4),
Rein, Tamayo and Brown 2019) and ``rebound-ias15`` (the adaptive 15th-order Gauss-Radau
integrator, Rein and Spiegel 2015, with its tolerance epsilon as ``tol``). REBOUND's
defaults otherwise (WHFast and SABA: safe mode, no symplectic correctors; MERCURIUS: its
switching radius; JANUS: order 6, scales 1e-16; IAS15: its default step-size criterion).

The n-body family is every problem that subclasses ``longtime.problems.nbody.NBody``,
plugins included: its ``masses()``, ``G`` and ``space_dim`` and the state u = (q, p) with
momenta p_k = m_k v_k are what REBOUND needs (a planar problem has z = 0). Other problems
are skipped with that reason; without the package the rows are skipped and name the extra
``longtime[rebound]``.

Each run is two REBOUND runs from the same initial state:
- the timed run: one call to t_final and nothing else (``sim.steps`` for the fixed-step
  schemes, whose last step is clipped to t_final as the compiled drivers clip it;
  ``sim.integrate(t_final)`` for IAS15). Its CPU and wall time are the row's, and its
  ``sim.steps_done`` is the row's ``steps``;
- the sampled run, untimed: the fixed-step schemes stop after the steps the compiled drivers
  record at (``drivers.sample_steps``, for at most ``SAMPLES`` samples, heyoka's count: each
  sample is a call into REBOUND from Python); IAS15 runs the same single
  ``integrate(t_final)`` and records every step from REBOUND's heartbeat (thinned evenly to
  the row's sample budget, as scipy's DOP853 rows). Its samples are the row's; they are
  recorded once per cell and reused by the timed repeats.
The timed run's final state must equal the sampled run's bitwise, or the row is ``failed``
(non-deterministic): the samples are then those of the run that was timed.
"""
from __future__ import annotations

import math
import time
import warnings

import numpy as np

from longtime.core.integrator import Integrator
from longtime.core.params import Param
from longtime.core.problem import BLOWUP_MESSAGE
from longtime.core.status import Status, time_limit_at
from longtime.core.stepping import cached_sample_steps
from longtime.core.trajectory import Trajectory

EXTRA = "rebound"  # pip install "longtime[rebound]"
SAMPLES = 10_001  # the fixed-step schemes' sample budget, heyoka's (docs/metrics.md)
DEADLINE_EVERY = 64  # samples between two looks at the cell's deadline


def _rebound():
    """The rebound module, or None when it is not installed."""
    try:
        import rebound
    except ImportError:
        return None
    return rebound


class Rebound(Integrator):
    """A REBOUND integrator on an n-body problem (the module's docstring)."""

    kind = "external"
    library = "rebound"
    integrator: str = ""  # REBOUND's name of the integrator
    symplectic = True
    # the default matrix's paper-scale cell on the outer solar system (1e6 days), where
    # astronomers compare these; on the figure-eights IAS15 takes about 1e3 steps a period
    # (2.4e6 steps, minutes, for their 2200 periods)
    long_runs = frozenset({"outer-solar-system"})
    needs = "an n-body problem (longtime.problems.nbody.NBody)"

    def incompatibility(self, problem):
        from longtime.problems.nbody import NBody

        reason = super().incompatibility(problem)
        if reason:
            return reason
        if not isinstance(problem, NBody):
            return (f"{self.name} needs an n-body problem (a subclass of longtime.problems.nbody.NBody), "
                    f"which {problem.name} is not")
        if _rebound() is None:
            return f'{self.name} needs the package rebound: pip install "longtime[{EXTRA}]"'
        return None

    def configure(self, sim, problem) -> None:
        """Set the integrator and its settings on ``sim``."""
        sim.integrator = self.integrator

    def simulation(self, problem):
        """A REBOUND simulation holding the problem's initial state, in its units (G, masses)."""
        sim = _rebound().Simulation()
        sim.G = float(problem.G)
        sim.t = float(problem.t0)
        m, q, p = problem.split_state(problem.u0[None, :])
        s = problem.space_dim
        for k, mass in enumerate(m):
            x, v = np.zeros(3), np.zeros(3)
            x[:s], v[:s] = q[0, k], p[0, k] / mass
            sim.add(m=float(mass), x=x[0], y=x[1], z=x[2], vx=v[0], vy=v[1], vz=v[2])
        self.configure(sim, problem)
        return sim

    @staticmethod
    def states(problem, xyz: np.ndarray, vxvyvz: np.ndarray) -> np.ndarray:
        """States u = (q, p) from REBOUND's positions and velocities, (n, N, 3) each."""
        s, n = problem.space_dim, xyz.shape[0]
        m = problem.masses()
        return np.concatenate([xyz[:, :, :s].reshape(n, -1),
                               (m[None, :, None] * vxvyvz[:, :, :s]).reshape(n, -1)], axis=1)

    # the sampled run of the last cell: (problem, t_final, max_samples) -> its outcome
    _samples: tuple | None = None

    def _integrate(self, problem, t_final, max_samples):
        key = (problem, t_final, max_samples)
        if self._samples is None or self._samples[0] != key:
            # REBOUND's warnings (a Kepler solver's convergence, ...) go into the row's message
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                sampled = self._sampled(problem, t_final, max_samples)
            said = list(dict.fromkeys(f"REBOUND: {w.message}" for w in caught))
            if said:
                t, u, status, message, cpu, wall, steps = sampled
                sampled = (t, u, status, "; ".join(m for m in [message, *said] if m), cpu, wall, steps)
            self._samples = (key, sampled)
        t, u, status, message, cpu, wall, steps = self._samples[1]
        t, u = t.copy(), u.copy()
        first = problem.first_blowup(u)
        if first is not None:
            t, u = t[:first + 1], u[:first + 1]
            status, message = Status.DIVERGED, "; ".join(m for m in (BLOWUP_MESSAGE.format(t=t[-1]), message) if m)
        # a run that did not finish reports the REBOUND calls and steps of its sampled run
        dt_range = (None, None)
        if status == Status.OK:
            with warnings.catch_warnings():  # said once, from the sampled run
                warnings.simplefilter("ignore")
                sim, cpu, wall, dt_range = self._timed(problem, t_final)
            steps = sim.steps_done
            xyz, v = np.zeros((1, sim.N, 3)), np.zeros((1, sim.N, 3))
            sim.serialize_particle_data(xyz=xyz[0], vxvyvz=v[0])
            if not np.array_equal(self.states(problem, xyz, v)[0].view(np.int64), u[-1].view(np.int64)):
                status = Status.FAILED
                message = ("non-deterministic: REBOUND's timed run to t_final did not reproduce the "
                           "sampled run's final state bitwise")
        counters = {"steps": int(steps)}
        if self.integrator != "ias15":
            counters["rhs_evals"] = int(steps)  # one force evaluation a step
        return Trajectory(status=status, message=message, t=t, u=u, cpu_s=cpu, wall_s=wall,
                          counters=counters, min_dt=dt_range[0], max_dt=dt_range[1])

    def _sampled(self, problem, t_final, max_samples):
        """(t, u, status, message, cpu_s, wall_s, steps): the run that records the samples (its
        REBOUND calls timed, for a row that does not finish)."""
        raise NotImplementedError

    def _timed(self, problem, t_final):
        """(sim, cpu_s, wall_s, (min_dt, max_dt)): the timed run, one REBOUND call to t_final."""
        raise NotImplementedError


class ReboundFixed(Rebound):
    parameters = {"dt": Param(None, "time step (default: the problem's)", float, positive=True, role="step")}
    order = 2

    def dt_for(self, problem) -> float:
        dt = self.settings.get("dt")
        return float(problem.default_dt if dt is None else dt)

    def configure(self, sim, problem):
        super().configure(sim, problem)
        sim.dt = self.dt_for(problem)

    def _plan(self, problem, t_final):
        dt = self.dt_for(problem)
        nsteps = max(1, math.ceil((t_final - problem.t0) / dt - 1e-9))
        return dt, nsteps, t_final - (problem.t0 + (nsteps - 1) * dt)  # the last step, clipped

    @staticmethod
    def _advance(sim, done, k, nsteps, dt, last):
        """Steps done + 1 .. k, the last one of the run clipped to t_final (as the drivers)."""
        full = min(k, nsteps - 1) - done
        if full > 0:
            sim.steps(full)
        if k == nsteps:
            if last != dt:
                sim.dt = last
            sim.steps(1)

    def _sampled(self, problem, t_final, max_samples):
        dt, nsteps, last = self._plan(problem, t_final)
        sim = self.simulation(problem)
        at = cached_sample_steps(nsteps, min(max_samples, SAMPLES))[:-1]  # without the sentinel
        xyz, v = np.zeros((at.size + 1, sim.N, 3)), np.zeros((at.size + 1, sim.N, 3))
        ts = [problem.t0]
        cpu = wall = 0.0
        status, message, done = "ok", "", 0
        try:
            for j, k in enumerate(at):
                k = int(k)
                c0, w0 = time.process_time(), time.perf_counter()
                self._advance(sim, done, k, nsteps, dt, last)
                cpu += time.process_time() - c0
                wall += time.perf_counter() - w0
                done = k
                ts.append(problem.t0 + k * dt if k < nsteps else t_final)
                sim.serialize_particle_data(xyz=xyz[j + 1], vxvyvz=v[j + 1])
                if not (np.all(np.isfinite(xyz[j + 1])) and np.all(np.isfinite(v[j + 1]))):
                    break
                if (j + 1) % DEADLINE_EVERY == 0 and k < nsteps and self._deadline is not None \
                        and time.monotonic() > self._deadline:
                    status, message = Status.TIMEOUT, time_limit_at(ts[-1])
                    break
        except Exception as exc:  # REBOUND raises on an integration error
            status, message = Status.FAILED, f"REBOUND {self.integrator}: {exc} (t={ts[-1]:.6g})"
        n = len(ts)
        u = self.states(problem, xyz[:n], v[:n])
        u[0] = problem.u0
        return np.array(ts), u, status, message, cpu, wall, sim.steps_done

    def _timed(self, problem, t_final):
        dt, nsteps, last = self._plan(problem, t_final)
        sim = self.simulation(problem)
        c0, w0 = time.process_time(), time.perf_counter()
        self._advance(sim, 0, nsteps, nsteps, dt, last)
        cpu, wall = time.process_time() - c0, time.perf_counter() - w0
        return sim, cpu, wall, (dt, dt)


class ReboundLeapfrog(ReboundFixed):
    name = "rebound-leapfrog"
    summary = "REBOUND's leapfrog (drift-kick-drift, order 2) on n-body problems; external, needs rebound"
    integrator = "leapfrog"


class ReboundWHFast(ReboundFixed):
    name = "rebound-whfast"
    summary = ("REBOUND's WHFast (Wisdom-Holman, Jacobi coordinates, order 2) on n-body problems; external, "
               "needs rebound")
    integrator = "whfast"


class ReboundMercurius(ReboundFixed):
    """MERCURIUS (Rein et al. 2019): Wisdom-Holman in democratic heliocentric coordinates,
    switching smoothly to IAS15 for the close encounters of any pair (within REBOUND's default
    switching radius, 3 Hill radii). The central body is the problem's first."""

    name = "rebound-mercurius"
    summary = ("REBOUND's MERCURIUS (hybrid Wisdom-Holman / IAS15 at close encounters, order 2) on n-body "
               "problems; external, needs rebound")
    integrator = "mercurius"


class ReboundJanus(ReboundFixed):
    """JANUS (Rein and Tamayo 2018): a symplectic composition run on integers (positions and
    velocities in units of ``scale_pos`` and ``scale_vel``, REBOUND's 1e-16), so that each
    step is bit-reversible: a run forward, then back with -dt, returns to its start bit for
    bit. REBOUND's default order, 6."""

    name = "rebound-janus"
    summary = ("REBOUND's JANUS (bit-reversible symplectic composition on integers, order 6) on n-body "
               "problems; external, needs rebound")
    integrator = "janus"
    order = 6


class ReboundSABA1064(ReboundFixed):
    """SABA(10,6,4) (Blanes et al. 2013; Rein, Tamayo and Brown 2019): a Wisdom-Holman
    splitting in Jacobi coordinates with error O(eps h^10 + eps^2 h^6 + eps^3 h^4) for a
    perturbation of size eps; its ``order`` is 4, what it keeps without a dominant mass."""

    name = "rebound-saba1064"
    summary = ("REBOUND's SABA(10,6,4) (Wisdom-Holman splitting, Jacobi coordinates, order 4 in h, 10 in "
               "eps h) on n-body problems; external, needs rebound")
    integrator = "saba"
    order = 4

    def configure(self, sim, problem):
        super().configure(sim, problem)
        sim.integrator.type = "10_6_4"


class ReboundIAS15(Rebound):
    name = "rebound-ias15"
    summary = ("REBOUND's IAS15 (adaptive Gauss-Radau, order 15, tol = epsilon) on n-body problems; external, "
               "needs rebound")
    integrator = "ias15"
    order = 15
    symplectic = False
    parameters = {"tol": Param(1e-9, "IAS15's epsilon: the step-size control's tolerance (accuracy)",
                               float, positive=True, role="accuracy")}

    def configure(self, sim, problem):
        super().configure(sim, problem)
        sim.integrator.epsilon = float(self.settings["tol"])

    def _sampled(self, problem, t_final, max_samples):
        sim = self.simulation(problem)
        ts, xs, vs = [], [], []
        deadline = self._deadline
        outcome = {"timeout": False}

        def heartbeat(pointer):  # after every step (and once at the start)
            here = pointer.contents
            if ts and here.t == ts[-1]:
                return
            x, v = np.empty((here.N, 3)), np.empty((here.N, 3))
            here.serialize_particle_data(xyz=x, vxvyvz=v)
            ts.append(here.t)
            xs.append(x)
            vs.append(v)
            if deadline is not None and len(ts) % DEADLINE_EVERY == 0 and time.monotonic() > deadline:
                outcome["timeout"] = True
                here.stop()  # REBOUND stops after this step

        sim.heartbeat = heartbeat
        status, message = Status.OK, ""
        c0, w0 = time.process_time(), time.perf_counter()
        try:
            sim.integrate(float(t_final), exact_finish_time=1)
        except Exception as exc:  # REBOUND raises on an integration error
            if not outcome["timeout"]:
                status, message = Status.FAILED, f"REBOUND ias15: {exc} (t={float(sim.t):.6g})"
        cpu, wall = time.process_time() - c0, time.perf_counter() - w0
        if outcome["timeout"]:
            status, message = Status.TIMEOUT, time_limit_at(ts[-1])
        t, xyz, v = np.array(ts), np.array(xs), np.array(vs)
        if t.size > max_samples:  # every stride-th step and the last
            stride = -(-(t.size - 1) // (max_samples - 1))
            keep = np.r_[np.arange(0, t.size - 1, stride), t.size - 1]
            t, xyz, v = t[keep], xyz[keep], v[keep]
        u = self.states(problem, xyz, v)
        u[0] = problem.u0
        return t, u, status, message, cpu, wall, sim.steps_done

    def _timed(self, problem, t_final):
        sim = self.simulation(problem)
        c0, w0 = time.process_time(), time.perf_counter()
        sim.integrate(float(t_final), exact_finish_time=1)
        cpu, wall = time.process_time() - c0, time.perf_counter() - w0
        return sim, cpu, wall, (None, None)
