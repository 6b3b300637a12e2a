"""What the library peers share (scipy's ``solve_ivp`` family, SUNDIALS' CVODE, diffrax): the
message naming the extra to install, the trajectory built from the steps a library recorded,
and the per-call overhead measured once on a trivial right-hand side.

A peer's row carries ``peer_overhead_s`` (docs/metrics.md): the CPU seconds a step of the
same method and settings costs on u' = 0 of the problem's dimension, stepped at a fixed step
(first and largest step h = 1/OVERHEAD_STEPS over [0, 1]). It is the library's boundary and
step machinery without the work of a right-hand side, measured once per (scheme, settings,
dimension) in a process, outside the timing, so that a reader can tell the method's cost
from its Python boundary.
"""
from __future__ import annotations

import importlib
import importlib.util
import math
import time
from typing import Any, Callable

import numba
import numpy as np

from longtime.core.jitcache import Unfreezable, cacheable, fingerprint
from longtime.core.problem import BLOWUP_MESSAGE
from longtime.core.status import PACED, Status
from longtime.core.trajectory import Trajectory

# the default matrix's tolerances of an adaptive peer: from the table's 1e-6 to the 1e-10 at
# the horizon that the report asks about (which the peers keep from about 1e-9 to 1e-13)
TOLERANCES = (1e-7, 1e-10, 1e-13)
# the default matrix's estimated seconds of one run of a peer's cell (longtime.execution.budget):
# the settings of a sweep estimated above it are left out, never the horizon shortened
CELL_BUDGET_S = 2.0
SAMPLES = 10_001  # the samples of a row of a peer that saves at given times: heyoka's count
OVERHEAD_STEPS = 200  # steps of the trivial run that measures the per-step overhead
DEADLINE_EVERY = 256  # steps between two looks at the cell's deadline
BOUND_EVERY = 16  # steps between two looks at a run's CPU bound (a multiple divides DEADLINE_EVERY)

# a run under a pace bound is judged on its pace once it has run this many CPU seconds (its
# first steps pay a library's caches and an adaptive start, which say little of its pace)
PACE_AFTER_S = 1.0


class Pace:
    """A run's pace against its pace bound (``Integrator.integrate``'s ``pace_bound``, CPU
    seconds): once it has run ``after_s`` CPU seconds (None: PACE_AFTER_S), ``beyond(t)``
    says whether the CPU seconds it spent per unit of t so far put its end, ``t_end``, past
    the bound, and keeps that projection (``projected``; infinite where the run has not moved
    past t0) for its row. It counts from its making: make it where the run starts."""

    def __init__(self, bound_s: float, t0: float, t_end: float, after_s: float | None = None) -> None:
        self.bound_s, self.t0, self.t_end = bound_s, t0, t_end
        self.after_s = PACE_AFTER_S if after_s is None else after_s
        self.start = time.process_time()
        self.projected: float | None = None
        self.stopped = False

    def beyond(self, t: float) -> bool:
        spent = time.process_time() - self.start
        if spent < self.after_s:
            return False
        done = (t - self.t0) / (self.t_end - self.t0)
        self.projected = spent / done if done > 0 else math.inf
        self.stopped = self.projected > self.bound_s
        return self.stopped

    def message(self, t: float, cpu: float) -> str:
        """The row's message where ``beyond`` stopped the run at ``t`` after ``cpu`` seconds."""
        ahead = (f"which puts t_final at about {self.projected:.3g} s CPU" if math.isfinite(self.projected)
                 else "no progress past t0, which puts t_final beyond any CPU time")
        return f"{PACED} t={t:.6g} of {self.t_end:g} reached in {cpu:.3g} s CPU, {ahead}, past {self.bound_s:g} s"


def stop_here(steps: int, cpu_end: float | None, deadline: float | None, pace: Pace | None = None,
              t: float = 0.0) -> bool:
    """Whether a peer's Python loop, at ``steps`` recorded and time ``t``, stops: every
    BOUND_EVERY steps it looks at the run's CPU bound (``cpu_end``, a ``time.process_time()``
    value) and its ``pace``, every DEADLINE_EVERY at the cell's deadline (a
    ``time.monotonic()`` value)."""
    if steps % BOUND_EVERY:
        return False
    if cpu_end is not None and time.process_time() >= cpu_end:
        return True
    if pace is not None and pace.beyond(t):
        return True
    return steps % DEADLINE_EVERY == 0 and deadline is not None and time.monotonic() > deadline


_OVERHEAD: dict[tuple, float] = {}
# compiled wrappers of a problem's functions, by the fingerprint of their closure
_WRAPPERS: dict[str, object] = {}


def compiled(closure):
    """``closure`` (a compiled wrapper around a problem's rhs or jac) from numba's disk cache
    (jitcache.cacheable), built once per process and kernel."""
    try:
        key = fingerprint(closure)
    except Unfreezable:
        return closure
    if key not in _WRAPPERS:
        _WRAPPERS[key] = cacheable(closure)
    return _WRAPPERS[key]


@numba.njit(cache=True)
def zero_rhs(t, u, params, out):
    """The trivial right-hand side u' = 0 the per-step overhead is measured on."""
    out[:] = 0.0


@numba.njit(cache=True)
def zero_jac(t, u, params, out):
    """Its Jacobian."""
    out[:, :] = 0.0


def installed(*modules: str) -> bool:
    """Whether every module is installed, found without importing it (importing jax for a
    check that a scheme's card or a skip reason makes would cost seconds)."""
    for module in modules:
        try:
            if importlib.util.find_spec(module) is None:
                return False
        except (ImportError, ValueError):
            return False
    return True


def missing(scheme: str, package: str, extra: str) -> str:
    """The skip reason of a peer whose library is not installed: the extra to install."""
    return f'{scheme} needs the package {package}: pip install "longtime[{extra}]"'


def per_step_overhead(key: tuple, measure: Callable[[], tuple[float, int]]) -> float:
    """The seconds a step costs on the trivial rhs, from ``measure()`` -> (cpu seconds, steps),
    measured once per ``key`` in this process."""
    found = _OVERHEAD.get(key)
    if found is None:
        measure()  # the first run pays the library's imports and caches, not the step
        cpu, steps = measure()
        found = _OVERHEAD[key] = cpu / max(steps, 1)
    return found


def grid(t0: float, t_final: float, max_samples: int) -> np.ndarray:
    """The sample times of a peer that saves at given times (CVODE, diffrax): SAMPLES evenly
    spaced, fewer where ``max_samples`` says so."""
    return np.linspace(t0, t_final, min(max_samples, SAMPLES))


_WARMED: set = set()


def warm_once(key: tuple, run: Callable[[], Any]) -> None:
    """``run()`` (a short untimed call of a library) the first time ``key`` is seen in this
    process: a library's first call pays its lazy imports and the compiles of the wrappers'
    other signatures, which the timed calls must not."""
    if key not in _WARMED:
        run()
        _WARMED.add(key)


def timed(run: Callable[[], Any]) -> tuple[Any, float, float]:
    """(run(), CPU seconds, wall seconds)."""
    c0, w0 = time.process_time(), time.perf_counter()
    out = run()
    return out, time.process_time() - c0, time.perf_counter() - w0


def thin(t: np.ndarray, u: np.ndarray, max_samples: int) -> tuple[np.ndarray, np.ndarray]:
    """Every stride-th sample and the last, at most ``max_samples`` of them."""
    if t.size <= max_samples:
        return t, u
    stride = -(-(t.size - 1) // (max_samples - 1))
    keep = np.r_[np.arange(0, t.size - 1, stride), t.size - 1]
    return t[keep], u[keep]


def trajectory(problem, library: str, t: np.ndarray, u: np.ndarray, cpu: float, wall: float,
               counters: dict[str, int], max_samples: int, failure: str | None = None,
               timed_out: bool = False, extra: dict[str, Any] | None = None, stoppable: bool = True,
               pace: Pace | None = None) -> Trajectory:
    """The row's trajectory from the accepted steps (t, u) a library recorded: cut at a
    blow-up, else ``timeout`` (stopped at the cell's deadline, or on its ``pace``: its message
    and ``pace_cpu_s`` say so) or ``failed`` (the library's ``failure`` message), thinned
    evenly to ``max_samples``; ``counters['steps']`` is set from the steps recorded.
    ``stoppable``: the library's loop stops at the deadline (else a run past it ran on to
    where it ended, and its message says so)."""
    extra = dict(extra or {})
    status, message = Status.OK, ""
    first = problem.first_blowup(u)
    if first is not None:
        t, u = t[:first + 1], u[:first + 1]
        status, message = Status.DIVERGED, BLOWUP_MESSAGE.format(t=t[-1])
    elif timed_out and pace is not None and pace.stopped:
        status, message = Status.TIMEOUT, pace.message(float(t[-1]), cpu)
        extra["pace_cpu_s"] = pace.projected if math.isfinite(pace.projected) else None  # a row holds no inf
    elif timed_out:
        status, message = Status.TIMEOUT, (f"stopped at t={t[-1]:.6g}: past the cell's time limit" if stoppable else
                                      f"ran to t={t[-1]:.6g} past the cell's time limit ({library}'s loop cannot "
                                      f"be stopped from outside)")
    elif failure is not None:
        status, message = Status.FAILED, f"{library}: {failure} (t={t[-1]:.6g})"
    steps = t.size - 1
    dts = np.diff(t)
    t, u = thin(t, u, max_samples)
    return Trajectory(status=status, message=message, t=np.ascontiguousarray(t), u=np.ascontiguousarray(u),
                      cpu_s=cpu, wall_s=wall, counters={"steps": int(steps), **counters},
                      min_dt=float(dts.min()) if steps else None, max_dt=float(dts.max()) if steps else None,
                      extra=extra)
