"""The scheme contract and the two shared drivers (fixed step, adaptive); the whole plugin
contract, as a checklist, is docs/plugins.md.

A scheme declares what it needs from a problem (``requires``), its order, whether it is
symplectic and its parameters, and implements ``integrate``. Most schemes only implement
the compiled step: ``FixedStepIntegrator.make_step`` or ``AdaptiveIntegrator.make_try_step``,
and inherit validation, allocation, warm-up (compilation outside the timing), timing and
counters. Failures come back as a status in the ``Trajectory``, never as an exception
from inside the loop.
"""
from __future__ import annotations

import functools
import math
import os
import sys
import time
import weakref
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any, Callable, ClassVar

import numpy as np

from longtime.core import drivers
from longtime.core.jitcache import Unfreezable, cacheable, fingerprint
from longtime.core.params import InputError, Param, check_time_span, resolve
from longtime.core.problem import BLOWUP_MESSAGE, Problem

SAMPLE_BUDGET = 10_000_000  # float64 values of recorded states per run
STATUS_NAMES = {drivers.OK: "ok", drivers.DIVERGED: "diverged", drivers.FAILED: "failed",
                drivers.TIMEOUT: "timeout"}
# fixed-step runs go in chunks: the first of FIRST_CHUNK steps, then sized to take about
# CHUNK_SECONDS each (a call into compiled code costs microseconds: no measurable slowdown)
FIRST_CHUNK = 10_000
CHUNK_SECONDS = 0.25
# a run still going after this many wall seconds prints a progress line to stderr every
# PROGRESS_SECONDS ($LONGTIME_PROGRESS=0 turns it off)
PROGRESS_SECONDS = 10.0


class _Progress:
    """A line on stderr now and then while a long run goes on (never for short ones)."""

    def __init__(self, integrator: "Integrator", problem: Problem, t_final: float) -> None:
        self.label = f"{problem.name} x {integrator.name}"
        self.t0, self.t_final = problem.t0, t_final
        self.start = self.last = time.monotonic()
        self.on = os.environ.get("LONGTIME_PROGRESS", "1") != "0"
        self.shown = False

    def update(self, t: float) -> None:
        now = time.monotonic()
        if self.on and now - self.last >= PROGRESS_SECONDS:
            self.last, self.shown = now, True
            done = (t - self.t0) / (self.t_final - self.t0)
            print(f"longtime: {self.label}: t = {t:.6g} of {self.t_final:.6g} ({100 * done:.0f} %, "
                  f"{now - self.start:.0f} s)", file=sys.stderr, flush=True)

    def close(self) -> None:
        if self.shown:
            print(f"longtime: {self.label}: done in {time.monotonic() - self.start:.0f} s",
                  file=sys.stderr, flush=True)


@dataclass(frozen=True)
class Timing:
    """How one process times a run, timeit-style: after the warm-up the integration runs at
    least ``min_runs`` times (default ``MIN_RUNS``, or ``repeats`` if fewer), then again
    while its timing is not settled and the timed wall total is below ``min_time`` seconds,
    at most ``repeats`` times. Settled: the two fastest runs agree within ``SETTLED`` (the
    minimum has been seen twice, so more runs would not move it), which a long run reaches
    at once and a short one on a quiet core after a few. The minimum is the figure (noise
    only ever adds time); the median and the maximum show the spread within the process.
    The spread between processes is measured by running the cell in several
    (longtime.execution.processes); ``per_process`` splits the repeats among them."""

    repeats: int = 7
    min_time: float = 0.2
    min_runs: int | None = None  # None: MIN_RUNS
    MIN_RUNS: ClassVar[int] = 3
    # the two fastest runs within this (relative) of each other: the minimum is known
    SETTLED: ClassVar[float] = 0.02
    # a run longer than this (wall seconds, 5x timeit's whole autorange budget) is timed
    # once: repeating a 10^8-step cell would cost minutes for a spread that is small at that
    # length (the row says so)
    ONCE_ABOVE: ClassVar[float] = 1.0

    def __post_init__(self) -> None:
        if isinstance(self.repeats, bool) or not isinstance(self.repeats, (int, np.integer)) \
                or self.repeats < 1:
            raise InputError(f"repeats={self.repeats!r} is not valid: expected an integer >= 1")
        if not (isinstance(self.min_time, (int, float)) and math.isfinite(self.min_time)
                and self.min_time >= 0):
            raise InputError(f"min_time={self.min_time!r} is not valid: expected a finite number "
                             f"of seconds >= 0")
        if self.min_runs is not None and (isinstance(self.min_runs, bool) or not isinstance(
                self.min_runs, (int, np.integer)) or self.min_runs < 1):
            raise InputError(f"min_runs={self.min_runs!r} is not valid: expected an integer >= 1")

    @property
    def least_runs(self) -> int:
        """The runs a process times at least: ``min_runs`` (default ``MIN_RUNS``), at most
        ``repeats``."""
        return min(self.repeats, self.MIN_RUNS if self.min_runs is None else self.min_runs)

    def wants_another(self, wall_times: list[float]) -> bool:
        n = len(wall_times)
        if n and wall_times[0] > self.ONCE_ABOVE:
            return False
        if n >= self.repeats:
            return False
        if n < self.least_runs:
            return True
        return not self.settled(wall_times) and sum(wall_times) < self.min_time

    @classmethod
    def settled(cls, times: list[float]) -> bool:
        """The two fastest of ``times`` agree within ``SETTLED``."""
        if len(times) < 2:
            return False
        a, b = sorted(times)[:2]
        return b <= a * (1 + cls.SETTLED)

    def per_process(self, processes: int) -> "Timing":
        """The timing of each of ``processes`` processes that time one cell: the repeats, the
        minimum runs and the time budget split among them (rounded up), so that timing a cell
        in several processes costs about what timing it in one did."""
        if processes <= 1:
            return self
        runs = self.MIN_RUNS if self.min_runs is None else self.min_runs
        return Timing(repeats=max(1, math.ceil(self.repeats / processes)), min_time=self.min_time / processes,
                      min_runs=max(1, math.ceil(runs / processes)))

    def to_dict(self) -> dict[str, Any]:
        """The timing as JSON for a child process (``from_dict`` reads it back whole)."""
        return {"repeats": int(self.repeats), "min_time": float(self.min_time),
                "min_runs": None if self.min_runs is None else int(self.min_runs)}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> "Timing":
        return cls(repeats=data["repeats"], min_time=data["min_time"], min_runs=data.get("min_runs"))


def same_run(a: "Trajectory", b: "Trajectory") -> bool:
    """Bitwise equality of two runs of one cell: outcome, counters and every sample."""
    return (a.status == b.status and a.counters == b.counters and _same_bits(a.t, b.t)
            and _same_bits(a.u, b.u))


def run_digest(traj: "Trajectory") -> str:
    """A hash of what ``same_run`` compares (outcome, counters, the bits of every sample):
    equal digests from two processes mean the same run, without sending the samples."""
    import hashlib
    import json

    h = hashlib.sha1(json.dumps([traj.status, sorted(traj.counters.items())]).encode())
    for x in (traj.t, traj.u):
        x = np.ascontiguousarray(x)
        h.update(repr((x.shape, x.dtype.str)).encode())
        h.update(x.view(np.uint8).reshape(-1) if x.size else b"")
    return h.hexdigest()


def _same_bits(x: np.ndarray, y: np.ndarray) -> bool:
    """Bit-for-bit equality (NaN equals the same NaN, 0.0 differs from -0.0), comparing the
    float64 samples as 64-bit integers, a view: no copy of the samples is made
    (docs/performance.md)."""
    if x.shape != y.shape or x.dtype != y.dtype:
        return False
    x, y = np.ascontiguousarray(x), np.ascontiguousarray(y)
    if x.dtype.itemsize not in (1, 2, 4, 8):
        return x.tobytes() == y.tobytes()
    as_int = np.dtype(f"u{x.dtype.itemsize}")
    return bool(np.array_equal(x.view(as_int), y.view(as_int)))


@dataclass
class Trajectory:
    """What a scheme returns: samples of the state, the outcome and the cost."""

    status: str  # ok | diverged | failed | timeout
    message: str
    t: np.ndarray  # (n,)
    u: np.ndarray  # (n, dim)
    cpu_s: float
    wall_s: float
    counters: dict[str, int] = field(default_factory=dict)
    min_dt: float | None = None
    max_dt: float | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def t_reached(self) -> float:
        return float(self.t[-1])

    @property
    def steps(self) -> int:
        return int(self.counters.get("steps", 0))


class Integrator(ABC):
    name: ClassVar[str] = ""  # the registry sets it from the entry point when empty
    summary: ClassVar[str] = ""
    requires: ClassVar[frozenset[str]] = frozenset()
    order: ClassVar[int | None] = None
    symplectic: ClassVar[bool] = False
    kind: ClassVar[str] = "fixed"  # fixed | adaptive | external
    # the library whose method runs: "longtime" for the suite's own kernels, else the peer's
    # (scipy, sundials, diffrax, heyoka, rebound); the results page groups schemes by it
    library: ClassVar[str] = "longtime"
    parameters: ClassVar[dict[str, Param]] = {}
    # default matrix sweep of parameters other than dt, e.g. {"tol": (1e-6, 1e-9)}
    sweep: ClassVar[dict[str, tuple]] = {}
    # names of counters EXTRA1, EXTRA2 when a scheme uses them
    extra_counters: ClassVar[tuple[str, ...]] = ()
    # cheap enough per step for the default matrix's paper-scale final times (a problem's
    # ``long_t_final``): one more cell at the problem's default step; a set of problem names
    # limits those cells to these problems
    long_runs: ClassVar[bool | frozenset[str]] = False
    # what a step costs, roughly, for the default matrix's budget (longtime.execution.budget):
    # ``step_cost`` per state component, relative to a compiled RK4 step (an implicit scheme's
    # Newton iterations make it about ten), and ``python_step_s``, the seconds each step
    # spends in Python whatever the problem (a peer stepped by a Python loop)
    step_cost: ClassVar[float] = 1.0
    python_step_s: ClassVar[float] = 0.0
    # the default matrix's estimated seconds of one run of a cell for this scheme, where it is
    # shorter than the budget's CELL_BUDGET_S (the library peers: many rows, a short budget each)
    cell_budget_s: ClassVar[float | None] = None

    # what a reader of stored rows must know about the name (rows it meant before a
    # correction): `longtime list` shows it, and `run` and `report` say it on stderr
    notice: ClassVar[str] = ""

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        from longtime.core.contract import check_integrator_definition

        check_integrator_definition(cls)  # a plugin that breaks the contract fails at import

    def __init__(self, **settings: Any) -> None:
        self.settings = resolve(self.parameters, settings, owner=f"integrator '{self.name}'")

    def incompatibility(self, problem: Problem) -> str | None:
        """Why this scheme cannot treat ``problem`` (None when it can)."""
        missing = sorted(set(self.requires) - problem.capabilities())
        if missing:
            return f"{self.name} needs {', '.join(missing)}, which {problem.name} does not provide"
        return None

    # the caller's deadline during integrate(), read by the drivers between chunks
    _deadline: float | None = None

    def integrate(self, problem: Problem, t_final: float, max_samples: int = 100_001,
                  timing: Timing | None = None, deadline: float | None = None) -> Trajectory:
        """Run the scheme from problem.u0 at t0 to t_final, timed by ``timing`` (default:
        a single run). Every timed repeat must reproduce the first run bitwise; one that
        does not turns the result into a ``failed`` trajectory ("non-deterministic").

        ``deadline`` is a time.monotonic() value: the shared drivers check it between
        chunks of compiled steps, and a run past it comes back with status ``timeout`` and
        the samples up to where it got (no further repeats are timed)."""
        check_time_span(problem.t0, t_final)
        reason = self.incompatibility(problem)
        if reason:
            raise InputError(reason)
        if max_samples < 2:
            raise InputError(f"max_samples={max_samples} is not valid: must be >= 2")
        timing = timing or Timing(repeats=1)
        # keep the samples under ~80 MB whatever the dimension (KdV at d = 512: ~19k samples)
        max_samples = min(int(max_samples), max(2001, SAMPLE_BUDGET // problem.dim))
        self._deadline = deadline
        try:
            first = self._integrate(problem, float(t_final), max_samples)
            cpu, wall = [first.cpu_s], [first.wall_s]
            while first.status != "timeout" and timing.wants_another(wall) and not (
                    deadline is not None and time.monotonic() > deadline):
                again = self._integrate(problem, float(t_final), max_samples)
                if again.status == "timeout":
                    break  # the deadline cut a repeat short: the first run stands
                if not same_run(first, again):
                    first.status = "failed"
                    first.message = (f"non-deterministic: timed run {len(cpu) + 1} did not reproduce "
                                     f"the first run's states bitwise")
                    break
                cpu.append(again.cpu_s)
                wall.append(again.wall_s)
        finally:
            self._deadline = None
        _judge_growth(problem, first)
        if len(cpu) == 1 < timing.repeats and first.status == "ok" and wall[0] > Timing.ONCE_ABOVE:
            note = f"timed once: one run takes {wall[0]:.3g} s"
            first.message = f"{first.message}; {note}" if first.message else note
        first.cpu_s, first.wall_s = min(cpu), min(wall)
        first.extra.update(repeats=len(cpu), cpu_s_median=float(np.median(cpu)), cpu_s_max=max(cpu),
                           wall_s_median=float(np.median(wall)), wall_s_max=max(wall),
                           cpu_s_samples=[float(c) for c in cpu],  # for `longtime compare`'s rank test
                           samples_digest=run_digest(first))  # the other timing processes must reproduce it
        return first

    @abstractmethod
    def _integrate(self, problem: Problem, t_final: float, max_samples: int) -> Trajectory: ...

    def _counters(self, raw: np.ndarray) -> dict[str, int]:
        out = {n: int(raw[i]) for i, n in enumerate(drivers.COUNTER_NAMES)}
        for i, n in enumerate(self.extra_counters):
            out[n] = int(raw[drivers.EXTRA1 + i])
        return out


# compiled loops by the fingerprint of their closure: whatever a make_step closes over (a
# dimension, a tableau, the problem's rhs) is part of the key, so a loop built for one
# setting never runs another, and equal settings share one compilation
_LOOPS: dict[str, Callable] = {}
# loops over values that have no fingerprint (an arbitrary object): never shared, one per
# scheme instance (weak key) and problem instance
_UNSHARED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


# the loop each (scheme instance, problem instance) pair runs, found once: the timed repeats of
# a cell (and the chunks of a run) reuse it without building and fingerprinting the closure
# again (docs/performance.md)
_PAIRS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def cached_kernel(integrator: Integrator, problem: Problem, build: Callable[[], Callable]) -> Callable:
    """The jitted function ``build()`` returns (a loop, or a problem's closure rhs that a Python
    loop calls), from numba's disk cache through ``jitcache.cacheable``, found once per
    (scheme, problem) pair: a closure compiled anew in every process costs up to a second."""
    pairs = _PAIRS.setdefault(integrator, {})
    found = pairs.get(id(problem))
    if found is not None and found[0] is problem:
        return found[1]
    closure = build()  # cheap: numba compiles on the first call, not here
    try:
        key = fingerprint(closure)
    except Unfreezable:
        own = _UNSHARED.setdefault(integrator, {})
        if id(problem) not in own:  # the entry holds the problem, so its id stays its own
            own[id(problem)] = (problem, closure)
        loop = own[id(problem)][1]
    else:
        if key not in _LOOPS:
            _LOOPS[key] = cacheable(closure)
        loop = _LOOPS[key]
    pairs[id(problem)] = (problem, loop)  # the entry holds the problem: its id stays its own
    return loop


# the setting of the fixed-step families that sum the state update with Kahan's compensated
# summation (drivers.compensated_add); off by default: the published schemes round plainly
COMPENSATED = Param(False, "Kahan-compensated summation of the state update (round-off studies)", bool)


@functools.lru_cache(maxsize=32)
def _sample_steps(nsteps: int, max_samples: int) -> np.ndarray:
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
        sample_at = _sample_steps(nsteps, max_samples)
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
        deadline, watch = self._deadline, _Progress(self, problem, t_final)
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
            status=STATUS_NAMES[status], message=_status_message(status, t_end), t=out_t[:n],
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
        watch = _Progress(self, problem, t_final)
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
        message = _status_message(status, t)
        if status == drivers.FAILED and np.isfinite(u).all():  # say why where it is plain
            f = np.empty(dim)
            problem.rhs(t, u, problem.params, f)
            if not np.isfinite(f).all():
                message = f"step failed at t={t:.6g}: the right-hand side is not finite there (NaN or inf)"
            elif not np.isfinite(u_new).all():
                message = (f"step failed at t={t:.6g}: the steps tried from there gave a non-finite state (a right-hand "
                           f"side that is not finite within the step, or a diverging iteration)")
        return Trajectory(
            status=STATUS_NAMES[status], message=message, t=np.concatenate(ts),
            u=np.concatenate(us), cpu_s=cpu, wall_s=wall, counters=self._counters(counters),
            min_dt=float(hstats[0]) if steps else None, max_dt=float(hstats[1]) if steps else None)


def _judge_growth(problem: Problem, traj: Trajectory) -> None:
    """A problem whose solution grows bounds the compiled loops only near overflow; its samples
    are judged here against the bound that follows the solution (Problem.size_bound): past
    it, the run diverged there (the samples end at the first state beyond, as the drivers')."""
    if not problem.grows or traj.status not in ("ok", "timeout"):
        return
    k = problem.first_blowup(traj.u, traj.t)
    if k is not None:
        traj.t, traj.u = traj.t[:k + 1], traj.u[:k + 1]
        traj.status, traj.message = "diverged", BLOWUP_MESSAGE.format(t=traj.t[-1])


def _status_message(status: int, t: float) -> str:
    if status == drivers.TIMEOUT:
        return f"time limit reached at t={t:.6g}"
    if status == drivers.DIVERGED:
        return BLOWUP_MESSAGE.format(t=t)
    if status == drivers.FAILED:
        return f"step failed at t={t:.6g} (nonlinear solve did not converge or step size underflow)"
    return ""
