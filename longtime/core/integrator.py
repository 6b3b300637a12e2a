"""The scheme contract (``Integrator``): what a scheme declares (``requires``, its order,
whether it is symplectic, its parameters) and the run it implements (``_integrate``), timed and
checked by ``integrate``. The shared fixed-step and adaptive drivers are in
``longtime.core.stepping``; the whole plugin contract, as a checklist, is docs/plugins.md.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any, ClassVar

import numpy as np

from longtime.core import drivers
from longtime.core.params import InputError, Param, check_time_span, resolve
from longtime.core.problem import Problem
from longtime.core.status import Status, blew_up_at
from longtime.core.timing import Timing, timed_runs
from longtime.core.trajectory import Trajectory, run_digest

SAMPLE_BUDGET = 10_000_000  # float64 values of recorded states per run


class Integrator(ABC):
    """Base class of every scheme: the contract a new scheme implements.

    A scheme is a subclass registered under the entry-point group ``longtime.integrators``
    (docs/plugins.md is the whole contract as a checklist; ``longtime.core.contract`` checks
    it when the class is defined, so a class that breaks it fails at import).

    Most schemes derive from one of the two shared drivers of ``longtime.core.stepping`` and
    implement only a compiled step:

    - ``FixedStepIntegrator.make_step(problem)`` returns a numba-compiled
      ``step(t, u, h, params, work, counters, first) -> status``;
    - ``AdaptiveIntegrator.make_try_step(problem)`` returns a compiled
      ``try_step(t, u, h, params, work, counters, u_new) -> (code, h_taken, h_next)``;

    and, where they need scratch space or constants, ``work_shape`` and ``prepare_work``.
    The drivers allocate the outputs, compile outside the timing, run the loop in chunks
    and fill the counters. A scheme that runs elsewhere (a library peer) derives from this
    class directly and implements ``_integrate``.

    Class attributes a scheme sets:

    - ``name``: the registered name (set by the registry from the entry point when empty);
      ``summary``: one line for ``longtime list``;
    - ``requires``: the capabilities it needs from a problem (``Problem.capabilities``);
      a pair whose needs are not met is skipped, saying which are missing;
    - ``order``: the order of the published method (None where there is none);
      ``symplectic``: whether it is;
    - ``parameters``: ``{name: Param}``, the settings it takes (``self.settings`` holds them
      resolved); ``sweep``: the default matrix's sweep of parameters other than dt;
    - ``kind``: ``fixed``, ``adaptive`` or ``external``; ``library``: whose method runs;
    - ``extra_counters``, ``long_runs``, ``step_cost``, ``python_step_s``,
      ``cell_budget_s``, ``stops_at_deadline`` and ``notice``: see their comments below.

    Methods a subclass implements:

    - ``_integrate(problem, t_final, max_samples) -> Trajectory``: one run from
      ``problem.u0`` at ``problem.t0`` to ``t_final``, at most ``max_samples`` samples of the
      state, its CPU and wall seconds, its counters. It checks ``self._deadline`` (a
      time.monotonic() value or None) where it can, and a failure comes back as the status
      of the ``Trajectory`` (``diverged``, ``failed``, ``timeout``) with a message, never as
      an exception from inside the loop.

    What the base class does around it (``integrate``): checks the time span, the
    compatibility with the problem and ``max_samples``; bounds the samples' memory; times
    the run (``longtime.core.timing``), each repeat a bitwise copy of the first; judges a
    growing problem's samples against its bound; and records the spread of the repeats and
    the samples' digest in ``Trajectory.extra``.
    """

    name: ClassVar[str] = ""  # the registry sets it from the entry point when empty
    summary: ClassVar[str] = ""
    requires: ClassVar[frozenset[str]] = frozenset()
    # what it needs of a problem beyond ``requires``, in words (what its ``incompatibility``
    # checks besides the capabilities); ``longtime list`` shows it beside them
    needs: ClassVar[str] = ""
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
    # whether a run stops at the deadline (``self._deadline``) where it got; False for a
    # library whose loop cannot be stopped from outside: it is looked at after the call
    stops_at_deadline: ClassVar[bool] = True
    # whether a run stops where it got once its own CPU seconds reach ``self._cpu_bound``: the
    # default matrix bounds such a library peer's costlier settings (longtime.execution.batches)
    stops_at_cpu_bound: ClassVar[bool] = False

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
    # the CPU seconds one run may take (None: no bound), read by a scheme that stops at it
    _cpu_bound: float | None = None
    # the CPU seconds past which a run's pace may not put its end (None: no bound), and the
    # CPU seconds after which its pace is judged (None: peer_common.PACE_AFTER_S), read by
    # the same schemes (longtime.integrators.peer_common.Pace)
    _pace_bound: float | None = None
    _pace_after: float | None = None

    def integrate(self, problem: Problem, t_final: float, max_samples: int = 100_001,
                  timing: Timing | None = None, deadline: float | None = None,
                  cpu_bound: float | None = None, pace_bound: float | None = None,
                  pace_after: float | None = None) -> Trajectory:
        """Run the scheme from problem.u0 at t0 to t_final, timed by ``timing`` (default:
        a single run). Every timed repeat must reproduce the first run bitwise; one that
        does not turns the result into a ``failed`` trajectory ("non-deterministic").

        ``deadline`` is a time.monotonic() value: the shared drivers check it between
        chunks of compiled steps, and a run past it comes back with status ``timeout`` and
        the samples up to where it got (no further repeats are timed). ``cpu_bound``: the CPU
        seconds one run may take, where the scheme ``stops_at_cpu_bound`` (a run stopped at
        it is ``timeout`` with at least that many CPU seconds; a repeat stopped at it ends
        the repeats, the first run standing). ``pace_bound``: for the same schemes, the CPU
        seconds past which the pace of a run (its CPU seconds per unit of t so far, once it
        has run ``pace_after`` CPU seconds, default ``peer_common.PACE_AFTER_S``) may not put
        t_final: a run whose pace does is stopped there, ``timeout``."""
        check_time_span(problem.t0, t_final)
        reason = self.incompatibility(problem)
        if reason:
            raise InputError(reason)
        if max_samples < 2:
            raise InputError(f"max_samples={max_samples} is not valid: must be >= 2")
        timing = timing or Timing(repeats=1)
        # keep the samples under ~80 MB whatever the dimension (KdV at d = 512: ~19k samples)
        max_samples = min(int(max_samples), max(2001, SAMPLE_BUDGET // problem.dim))
        self._deadline, self._cpu_bound, self._pace_bound = deadline, cpu_bound, pace_bound
        self._pace_after = pace_after
        try:
            first, cpu, wall = timed_runs(lambda: self._integrate(problem, float(t_final), max_samples), timing,
                                          deadline)
        finally:
            self._deadline = self._cpu_bound = self._pace_bound = self._pace_after = None
        _judge_growth(problem, first)
        if len(cpu) == 1 < timing.repeats and first.status == Status.OK and wall[0] > Timing.ONCE_ABOVE:
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


def _judge_growth(problem: Problem, traj: Trajectory) -> None:
    """A problem whose solution grows bounds the compiled loops only near overflow; its samples
    are judged here against the bound that follows the solution (Problem.size_bound): past
    it, the run diverged there (the samples end at the first state beyond, as the drivers')."""
    if not problem.grows or traj.status not in (Status.OK, Status.TIMEOUT):
        return
    k = problem.first_blowup(traj.u, traj.t)
    if k is not None:
        traj.t, traj.u = traj.t[:k + 1], traj.u[:k + 1]
        traj.status, traj.message = Status.DIVERGED, blew_up_at(traj.t[-1])
