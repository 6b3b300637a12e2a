"""Cells of the matrix: one problem x scheme x parameter point, and how one is run.

``expand`` validates everything up front (names, flags, --set keys, values), so bad input
fails before anything runs; ``run_cell`` never raises: whatever happens becomes a row with
a status (ok, diverged, failed, skipped).
"""
from __future__ import annotations

import itertools
import json
import math
import numbers
import os
import time
import traceback
from dataclasses import dataclass, field
from typing import Any, Iterable, Mapping

from longtime.core import contract, phases, registry, roles, rowschema
from longtime.core.cache import no_space
from longtime.core.integrator import Integrator
from longtime.core.outputs import to_stderr
from longtime.core.params import InputError, check_time_span, unknown_parameter
from longtime.core.problem import Problem
from longtime.core.roles import ROW_PARAMETERS
from longtime.core.status import Status
from longtime.core.stepping import FixedStepIntegrator
from longtime.core.timing import Timing
from longtime.core.trajectory import Trajectory
from longtime.execution import limits
from longtime.execution.sizes import DEFAULT_MAX_SAMPLES, cell_size, check_size, check_step, sweep_steps, working_set  # noqa: F401 (their home is sizes; read from here too)
from longtime.execution.tempdirs import disk_full
from longtime.measure import lyapunov, metrics
from longtime.measure.metrics import O1_ERROR
from longtime.measure.reference import has_reference, trusted_reference
from longtime.measure.reference_runs import ReferenceUnavailable, budget_seconds

# a cell stops (a 'timeout' row) after this many seconds unless --time-limit says otherwise
DEFAULT_TIME_LIMIT = 600.0


@dataclass(frozen=True)
class RunSpec:
    """How each cell runs, wherever cells cross a module or a process: at most
    ``max_samples`` samples, timed as ``timing`` says, stopped by the integration itself past
    ``time_limit`` seconds (None: never; the hard limit follows from it, ``limits.hard_limit``),
    its process under ``memory_limit`` bytes of data (None: no limit)."""

    max_samples: int = DEFAULT_MAX_SAMPLES
    timing: Timing = field(default_factory=Timing)
    time_limit: float | None = DEFAULT_TIME_LIMIT
    memory_limit: int | None = None

    def to_dict(self) -> dict[str, Any]:
        return {"max_samples": int(self.max_samples), "timing": self.timing.to_dict(),
                "time_limit": None if self.time_limit is None else float(self.time_limit),
                "memory_limit": None if self.memory_limit is None else int(self.memory_limit)}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> "RunSpec":
        return cls(max_samples=data["max_samples"], timing=Timing.from_dict(data["timing"]),
                   time_limit=data.get("time_limit"), memory_limit=data.get("memory_limit"))


# the fields that say how a cell runs, not what it is: in its dict where set, never in its key
HOW = ("time_limit", "bound", "cpu_bound", "bound_reason", "limit_reason", "pace")


@dataclass(frozen=True)
class Cell:
    problem: str
    integrator: str
    problem_settings: dict[str, Any] = field(default_factory=dict)
    integrator_settings: dict[str, Any] = field(default_factory=dict)
    t_final: float | None = None
    skip_reason: str | None = None
    # why the cell's settings differ from the default sweep's (the default matrix's budget,
    # longtime.execution.budget): its row's message ends with it; not part of the key
    note: str | None = None
    # the cell's own time limit in seconds (the budget's: a setting estimated too slow for the
    # default matrix, a library peer's cell), below the run's: past it the row is ``timeout``,
    # and ``limit_reason`` says whose limit it is; ``pace`` (a setting estimated too slow): the
    # multiple of it past which its pace may not put its end (integrate's pace_bound); not in the key
    time_limit: float | None = None
    # a library peer's cell of the default matrix that runs in its chain (the cells of its
    # problem, library and t_final, cheapest first: longtime.execution.batches): the factor
    # of the CPU seconds of an earlier setting of the chain that keeps the target past which it
    # stops (``cpu_bound`` then, and ``bound_reason`` says why); not part of the key
    bound: float | None = None
    cpu_bound: float | None = None
    bound_reason: str | None = None
    limit_reason: str | None = None
    pace: float | None = None

    def to_dict(self) -> dict[str, Any]:
        d = {"problem": self.problem, "integrator": self.integrator,
             "problem_settings": dict(sorted(self.problem_settings.items())),
             "integrator_settings": dict(sorted(self.integrator_settings.items())),
             "t_final": self.t_final, "skip_reason": self.skip_reason}
        if self.note:
            d["note"] = self.note
        d.update({name: getattr(self, name) for name in HOW if getattr(self, name) is not None})
        return d

    @property
    def key(self) -> str:
        d = self.to_dict()
        d.pop("skip_reason")
        for name in ("note", *HOW):
            d.pop(name, None)
        return json.dumps(d, sort_keys=True)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "Cell":
        return cls(d["problem"], d["integrator"], dict(d["problem_settings"]),
                   dict(d["integrator_settings"]), d["t_final"], d.get("skip_reason"), d.get("note"),
                   **{name: d.get(name) for name in HOW})


def check_set_keys(sets: Mapping[str, Any], problem_names: Iterable[str],
                   integrator_names: Iterable[str], spelling: str = "--set {key}") -> None:
    """Every --set key (``spelling``: how the front end names the argument) must be a
    parameter of a selected problem or scheme: else the closest names and the full list."""
    problem_names, integrator_names = list(problem_names), list(integrator_names)
    pclasses = [registry.problem_class(n) for n in problem_names]
    iclasses = [registry.integrator_class(n) for n in integrator_names]
    for key in sets:
        if not any(key in c.parameters for c in pclasses + iclasses):
            valid = {k for c in pclasses + iclasses for k in c.parameters}
            raise unknown_parameter(spelling.format(key=key), key, valid, ", ".join(problem_names + integrator_names))


def _horizons(t_final: float | Iterable[float] | None) -> list[float | None]:
    """The final times of a sweep: one, several, or none (the problem's)."""
    if t_final is None:
        return [None]
    if isinstance(t_final, numbers.Real):
        return [t_final]
    values = list(dict.fromkeys(t_final))
    return values or [None]


def _check_sweeps(sweeps: Mapping[str, list], sets: Mapping[str, Any], problem_names: list[str],
                  integrator_names: list[str]) -> None:
    """Every swept name is a parameter of a selected problem or scheme, and given once."""
    for name in sweeps:
        option = roles.flag(name)
        if name in ROW_PARAMETERS:  # a flag of its own: it names the schemes that take it
            if not any(name in registry.integrator_class(n).parameters for n in integrator_names):
                takers = sorted(n for n, c in registry.integrators().items() if name in c.parameters)
                raise InputError(f"{option} is not a parameter of any selected integrator "
                                 f"({', '.join(integrator_names)}); it applies to {', '.join(takers) or 'none'}")
        else:
            check_set_keys({name: None}, problem_names, integrator_names)
        if name in sets:  # both would set it: one would silently win
            raise InputError(f"{option} and --set {name}= both give {name}: give one of them"
                             if name in ROW_PARAMETERS else
                             f"{name} is given both as a sweep and as one value: give one of them")


def _axes(cls: type, sweeps: Mapping[str, list], defaults: Mapping[str, Iterable]) -> list[list[tuple]]:
    """The sweep axes of one class: a list of (name, value) per swept parameter, nested by role."""
    names = [n for n in cls.parameters if n in sweeps or defaults.get(n)]
    return [[(n, v) for v in (sweeps[n] if n in sweeps else defaults[n])]
            for n in roles.order_axes(names, [cls])]


@to_stderr  # plugin code runs here: its output is not the contract's
def expand(problem_names: list[str], integrator_names: list[str], *,
           sweeps: Mapping[str, list] | None = None,
           t_final: float | Iterable[float] | None = None,
           sets: Mapping[str, Any] | None = None, default_sweep: bool = False,
           strict: bool = False, time_limit: float | None = DEFAULT_TIME_LIMIT,
           memory_limit: int | None = limits.default_memory_limit()) -> list[Cell]:
    """All cells of problems x integrators x the sweep.

    ``sweeps`` maps any declared parameter of a selected problem or scheme to its values
    (one cell per value; a problem's parameter varies the problem), ``t_final`` is one final
    time or a list of them, ``sets`` fixes single values. Without values for a parameter
    that sweeps (``Param.sweeps``), a cell takes the parameter's default (or, with
    ``default_sweep``, the problem's ``sweep_dt`` for the step and the scheme's ``sweep``
    for the rest). An incompatible pair becomes one cell with a skip reason, or an error
    when ``strict``. A plugin's problem is checked first (its functions on the initial state)
    under the limits of a cell, ``time_limit`` and ``memory_limit``.
    """
    # a name or value given twice is one cell (a repeat would be run twice and stored once)
    problem_names, integrator_names = list(dict.fromkeys(problem_names)), list(dict.fromkeys(integrator_names))
    sweeps = {k: list(dict.fromkeys(v)) for k, v in (sweeps or {}).items() if v}
    registry.check_names("problem", problem_names)  # every unknown name at once
    registry.check_names("integrator", integrator_names)
    sets = dict(sets or {})
    check_set_keys(sets, problem_names, integrator_names)
    _check_sweeps(sweeps, sets, problem_names, integrator_names)
    horizons = _horizons(t_final)
    cells = []
    for pname in problem_names:
        pcls = registry.problem_class(pname)
        pfixed = {k: v for k, v in sets.items() if k in pcls.parameters}
        for ppoint in itertools.product(*_axes(pcls, sweeps, {})):
            psets = {**pfixed, **dict(ppoint)}
            try:
                problem = pcls(**psets)  # validates the problem's settings
            except MemoryError:
                raise InputError(f"problem {pname} with {psets}: out of memory while building it") from None
            psets = {k: problem.settings[k] for k in psets}  # typed: "0.5" from the command line is 0.5
            t_finals = [horizon if horizon is not None else (
                pcls.sweep_t_final if default_sweep and pcls.sweep_t_final else pcls.default_t_final)
                for horizon in horizons]
            for tf in t_finals:
                check_time_span(pcls.t0, tf, f"problem {pname}")
            if not contract.built_in(pcls):  # a plugin: its functions once, under a cell's limits, before any cell
                _check_plugin_problem(problem, t_finals, time_limit, memory_limit)
            for tf in t_finals:
                for iname in integrator_names:
                    cells += _scheme_cells(pname, pcls, problem, psets, iname, tf, sets, sweeps, default_sweep,
                                           strict, given_t_final=horizons != [None])
    return cells


def _plugin_problem_checks(problem: Problem, t_finals: list[float]) -> None:
    contract.probe_problem_kernels(problem)  # its compiled functions, once with bounds checked
    for tf in t_finals:  # the shapes of what its Python functions return
        contract.check_problem_outputs(problem, tf)


def _check_plugin_problem(problem: Problem, t_finals: list[float], time_limit: float | None,
                          memory_limit: int | None) -> None:
    """The contract checks of a plugin's problem (``contract.probe_problem_kernels``,
    ``check_problem_outputs``) under the limits of a cell (``limits.call_limited``): one that
    raises or does not return is an InputError naming the problem."""
    try:
        limits.call_limited(_plugin_problem_checks, problem, t_finals, time_limit=time_limit, memory_limit=memory_limit)
    except InputError:
        raise
    except limits.PastLimit as exc:
        raise InputError(f"problem {problem.name}: its contract check (rhs, exact, invariants, violations, "
                         f"diagnostics on the initial state) failed: {exc}") from None
    except MemoryError as exc:
        raise InputError(f"problem {problem.name}: out of memory in its contract check ({exc})") from None
    except Exception as exc:
        first = (str(exc).strip().splitlines() or [""])[0]
        raise InputError(f"problem {problem.name}: its contract check (rhs, exact, invariants, violations, "
                         f"diagnostics on the initial state) raised {type(exc).__name__}: {first}") from None


def _scheme_cells(pname: str, pcls, problem: Problem, psets: dict, iname: str, tf: float, sets: Mapping[str, Any],
                  sweeps: Mapping[str, list], default_sweep: bool, strict: bool,
                  given_t_final: bool) -> list[Cell]:
    """The cells of one scheme on one problem setting and final time."""
    icls = registry.integrator_class(iname)
    isets = {k: v for k, v in sets.items() if k in icls.parameters}
    scheme = icls(**isets)
    isets = {k: scheme.settings[k] for k in isets}  # typed, as the problem's
    reason = scheme.incompatibility(problem)
    if reason:
        if strict:
            raise InputError(f"incompatible pair {iname} x {pname}: {reason}")
        return [Cell(pname, iname, psets, isets, tf, skip_reason=reason)]
    defaults: dict[str, list] = {}
    if default_sweep:
        for name, param in icls.parameters.items():
            if name in isets:
                continue
            values = sweep_steps(pcls, icls, tf) if param.role == "step" else list(icls.sweep.get(name, ()))
            if param.role == "accuracy" and pcls.sweep_min_tolerance:
                values = [v for v in values if v >= pcls.sweep_min_tolerance]
            defaults[name] = values
    cells = []
    for point in itertools.product(*_axes(icls, sweeps, defaults)):
        settings = {**isets, **dict(point)}
        built = icls(**settings)  # validates dt > 0, tol > 0, ...
        settings = {k: built.settings[k] for k in settings}
        check_step(pname, iname, settings, tf)
        cells.append(Cell(pname, iname, psets, settings, tf))
    # the default matrix's long-time cell: the problem's paper-scale final time at its
    # default step, for the schemes that can afford it (``long_runs``)
    # (a scheme without a step, an adaptive external one, runs it at its default settings)
    long_tf = pcls.long_t_final
    step = roles.with_role([icls], "step")
    runs_long = icls.long_runs if isinstance(icls.long_runs, bool) else pname in icls.long_runs
    if default_sweep and not given_t_final and long_tf and runs_long and not any(n in sweeps for n in step):
        cells.append(Cell(pname, iname, psets, {**isets, **{n: pcls.default_dt for n in step}}, long_tf))
    return cells


def base_row(cell: Cell) -> dict[str, Any]:
    s = cell.integrator_settings
    row = {"problem": cell.problem, "integrator": cell.integrator, "status": "", "message": "",
           **{k: s.get(k) for k in ROW_PARAMETERS}, "t_final": cell.t_final}
    extra = {k: v for k, v in {**cell.problem_settings, **s}.items() if k not in ROW_PARAMETERS}
    row["settings"] = json.dumps(extra, sort_keys=True) if extra else ""
    return row


def cell_of_row(row: dict[str, Any], t_final: float | None = None) -> Cell:
    """The cell a stored row measured (its settings split back into the problem's and the
    scheme's, base_row's inverse), at ``t_final`` where given (else the row's)."""
    settings = json.loads(row["settings"]) if row.get("settings") else {}
    pcls, icls = registry.problem_class(row["problem"]), registry.integrator_class(row["integrator"])
    psets = {k: v for k, v in settings.items() if k in pcls.parameters}
    isets = {k: v for k, v in settings.items() if k in icls.parameters}
    for k in ROW_PARAMETERS:  # the parameters with a row field of their own
        value = row.get(k)
        if k in icls.parameters and isinstance(value, (int, float)) and not isinstance(value, bool) \
                and math.isfinite(value) and value > 0:
            isets[k] = int(value) if icls.parameters[k].kind is int else value
    return Cell(row["problem"], row["integrator"], psets, isets, row["t_final"] if t_final is None else t_final)


def build(cell: Cell) -> tuple[Problem, Integrator]:
    """The problem and the scheme a cell names, with its settings (validated): the one
    place they are made from names, for the matrix, the searches and the figures."""
    problem = registry.problem_class(cell.problem)(**cell.problem_settings)
    integrator = registry.integrator_class(cell.integrator)(**cell.integrator_settings)
    return problem, integrator


def integrate_cell(cell: Cell, max_samples: int = DEFAULT_MAX_SAMPLES) -> tuple[Problem, Trajectory]:
    """Build and run one cell once, for a caller that needs the trajectory itself (a
    figure): an incompatible pair is an InputError; a run that diverges or fails is a
    trajectory with that status, as in ``run_cell`` (which also measures and times)."""
    problem, integrator = build(cell)
    reason = integrator.incompatibility(problem)
    if reason:
        raise InputError(reason)
    t_final = problem.default_t_final if cell.t_final is None else cell.t_final
    return problem, integrator.integrate(problem, t_final, max_samples=max_samples)


@to_stderr  # plugin code runs here: its output is not the contract's
def run_cell(cell: Cell, max_samples: int = DEFAULT_MAX_SAMPLES, reference: bool = True,
             timing: Timing | None = None, time_limit: float | None = DEFAULT_TIME_LIMIT,
             keep: dict[str, Any] | None = None, reference_budget_s: float | None = None) -> dict[str, Any]:
    """Run one cell, timed by ``timing`` (default: ``Timing()``, the repeated timing of every
    row); every outcome is a row, nothing raises. Its heyoka reference gets ``reference_budget_s``
    wall seconds (default: reference_runs.budget_seconds). Past ``time_limit`` seconds (None: no
    limit) the integration stops where it got: a ``timeout`` row. ``keep``, a dict, receives what
    the row was measured from (``problem``, ``integrator``, ``trajectory``, ``reference``: the
    trusted reference states, ``trust``), for ``longtime.solve``. A row that does not hold against
    the declared row (a scheme's undeclared field, a value of the wrong type, a count out of
    range) is the cell's ``failed`` row naming each wrong field (``declared``): it costs its cell."""
    return declared(cell, _measured_row(cell, max_samples, reference, timing, time_limit, keep, reference_budget_s))


def declared(cell: Cell, row: dict[str, Any]) -> dict[str, Any]:
    """``row`` where it holds against the declared row (longtime.core.rowschema.validate_row)
    and its counts are ones the run could take (``implausible``); else the cell's ``failed``
    row (its names, parameters and settings) whose message names each wrong field."""
    wrong = rowschema.validate_row(row) or implausible(cell, row)
    if not wrong:
        return row
    failed = base_row(cell)
    if isinstance(row.get("parameters"), str):
        failed["parameters"] = row["parameters"]
    refused = f"the scheme's row is refused: {'; '.join(wrong)}"
    failed.update(status=Status.FAILED, message="; ".join(m for m in (refused, cell.note) if m))
    return failed


def implausible(cell: Cell, row: Mapping[str, Any]) -> list[str]:
    """The counts of a row that its run cannot have taken (none: they can): a run that reached
    past t0 in no step, a fixed-step run of more steps than its span holds at its step."""
    if row.get("status") in (Status.SKIPPED, Status.FAILED) or not isinstance(row.get("steps"), int):
        return []
    pcls = registry.problem_class(cell.problem)
    steps, reached = row["steps"], row.get("t_reached")
    if steps == 0 and isinstance(reached, float) and reached > pcls.t0:
        return [f"steps: 0 steps reached t = {reached:g} past t0 = {pcls.t0:g}"]
    dt = row.get("dt")
    if issubclass(registry.integrator_class(cell.integrator), FixedStepIntegrator) and isinstance(dt, float) \
            and dt > 0 and isinstance(reached, float):
        most = math.ceil((reached - pcls.t0) / dt * (1 + 1e-9)) + 1
        if steps > most:
            return [f"steps: {steps} steps of dt = {dt:g} over the span {reached - pcls.t0:g} (at most {most})"]
    return []


def _measured_row(cell: Cell, max_samples: int, reference: bool, timing: Timing | None, time_limit: float | None,
                  keep: dict[str, Any] | None, reference_budget_s: float | None) -> dict[str, Any]:
    """run_cell's row as measured (before it is checked against the declared row)."""
    row = base_row(cell)
    own = cell.time_limit is not None and (not time_limit or cell.time_limit < time_limit)
    if own:  # the cell's own limit is the tighter one
        time_limit = cell.time_limit
    deadline = time.monotonic() + time_limit if time_limit else None
    if cell.skip_reason:
        row.update(status=Status.SKIPPED, message=cell.skip_reason)
        return row
    try:
        problem, integrator = build(cell)
        if isinstance(integrator, FixedStepIntegrator):
            row["dt"] = integrator.dt_for(problem)
        # every parameter actually used, defaults included (a default tol is not null)
        row.update({k: v for k, v in integrator.settings.items() if k in ROW_PARAMETERS and row.get(k) is None})
        used = {**problem.settings, **integrator.settings}
        if isinstance(integrator, FixedStepIntegrator):
            used["dt"] = row["dt"]  # the step taken, also where it is the problem's default
        row["parameters"] = json.dumps(used, sort_keys=True, default=str)
        unsafe = _probe_step(integrator, problem)
        if unsafe:
            row.update(status=Status.FAILED, message=unsafe)
            return row
        with phases.phase("integration", f"{cell.problem} x {cell.integrator}"):
            traj = integrator.integrate(problem, cell.t_final, max_samples=max_samples, timing=timing or Timing(),
                                        deadline=deadline, **limits.run_bounds(cell, integrator))
        t_end = problem.default_t_final if cell.t_final is None else cell.t_final
        if traj.status == Status.TIMEOUT:
            traj.message = limits.stopped_message(cell, t_end, traj, time_limit, own)
        if traj.status == Status.DIVERGED:
            traj.message = "; ".join(m for m in (traj.message, contract.nan_note(problem, traj.t, traj.u)) if m)
        wrong = contract.check_samples(cell.integrator, problem, traj, t_end)
        if wrong:  # samples that cannot be measured are a fault, never a row that reads ok
            row.update(status=Status.FAILED, message=wrong)
            return row
        ref, trust, note = None, None, ""
        if reference and has_reference(problem):
            # the reference check is part of the cell: it gets what is left of the cell's hard
            # limit (the time limit and its grace, where the worker's watchdog would kill the cell)
            full = budget_seconds() if reference_budget_s is None else reference_budget_s
            hard = None if deadline is None else deadline + limits.grace(time_limit)
            left = None if hard is None else max(hard - time.monotonic(), 0.0)
            budget = full if left is None or left >= full else max(left, 1e-3)
            try:
                with phases.phase("reference", cell.problem):
                    ref, trust = trusted_reference(problem, traj.t, cell.t_final, budget)
                note = trust.message(float(traj.t[-1]))
            except ReferenceUnavailable as exc:
                note = f"no reference: {exc}"
            if budget < full and time.monotonic() >= hard and traj.status != Status.TIMEOUT:
                traj.status = Status.TIMEOUT
                traj.message = "; ".join(m for m in (traj.message, (
                    f"the reference check passed the cell's hard time limit of {limits.hard_limit(time_limit):g} s "
                    f"(--time-limit {time_limit:g} s + grace) after the integration")) if m)
        if keep is not None:
            keep.update(problem=problem, integrator=integrator, trajectory=traj, reference=ref, trust=trust)
        with phases.phase("metrics"):
            row.update(metrics.evaluate(problem, traj, ref, trust))
            if problem.chaotic and reference:
                row.update(lyapunov.row_fields(problem, row))
        row["working_set_bytes"] = working_set(integrator, problem, traj)
        row["status"] = traj.status
        row["solution_lost"], worst = metrics.solution_lost(row)
        if row["solution_lost"]:  # finite but wrong: never a plain "ok" (the report folds it too)
            block = f" of {row['error_block']}" if row.get("error_block") else ""
            note = "; ".join(m for m in (note, f"error O(1) (relative error{block} {worst:.3g} >= {O1_ERROR:g}): "
                                               f"the solution is not followed") if m)
        row["message"] = "; ".join(m for m in (traj.message, note, row["message"]) if m)  # + metrics' notes
    except MemoryError as exc:  # past the worker's memory limit (longtime.execution.limits), or the machine's
        row["status"] = Status.FAILED
        row["message"] = limits.memory_message(exc)
    except OSError as exc:
        if no_space(exc):  # the machine's fault, not the cell's: never stored as its row
            raise disk_full(exc, f"running {cell.problem} x {cell.integrator}") from None
        row["status"] = Status.FAILED
        row["message"] = "".join(traceback.format_exception_only(type(exc), exc)).strip()
    except OverflowError as exc:  # Python's float arithmetic past double precision (omega=1e308, squared)
        row["status"] = Status.FAILED
        where = traceback.extract_tb(exc.__traceback__)[-1]
        settings = json.dumps({**cell.problem_settings, **cell.integrator_settings}, sort_keys=True, default=str)
        row["message"] = (f"OverflowError: {exc} in {where.name} ({os.path.basename(where.filename)}:{where.lineno}): "
                          f"the settings {settings} of {cell.problem} x {cell.integrator} pass the range of "
                          f"double precision there")
    except (Exception, SystemExit) as exc:  # a failing cell never takes the matrix down
        # (a plugin's sys.exit too; os.abort or a segfault need a process per cell)
        row["status"] = Status.FAILED
        row["message"] = "".join(traceback.format_exception_only(type(exc), exc)).strip()
    if cell.note:  # the settings the default matrix's budget moved, said where the row is read
        row["message"] = "; ".join(m for m in (row["message"], cell.note) if m)
    return row


# (scheme class, problem class, dimension) -> why the plugin's step cannot run, or None
_PROBED: dict[tuple, str | None] = {}


def _probe_step(integrator: Integrator, problem: Problem) -> str | None:
    """A plugin's own step kernel (fixed or adaptive), run once per process and problem
    with bounds checked (contract.probe_step_kernel) the first time it is built."""
    make = getattr(type(integrator), "make_step", None) or getattr(type(integrator), "make_try_step", None)
    if make is None or contract.built_in(make):
        return None
    key = (type(integrator), type(problem), problem.dim)
    if key not in _PROBED:
        _PROBED[key] = contract.probe_step_kernel(integrator, problem)
    return _PROBED[key]
