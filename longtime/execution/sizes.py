"""How big a cell is, and what is refused for its size before anything runs: a fixed step
larger than the span (``check_step``), a final time no run can count its steps to
(``check_span``), and a cell whose steps pass MAX_STEPS, or whose samples pass
MAX_SAMPLE_BYTES or its memory limit (``check_size``); the steps of a scheme's default sweep
(``sweep_steps``) and the bytes a run touches (``working_set``). A cell is a
longtime.execution.cells.Cell."""
from __future__ import annotations

import json
import math
from typing import Any, Iterable, Mapping

from longtime.core import registry, rowschema
from longtime.core.integrator import Integrator
from longtime.core.outputs import to_stderr
from longtime.core.params import InputError
from longtime.core.problem import Problem
from longtime.core.stepping import FixedStepIntegrator
from longtime.core.trajectory import Trajectory
from longtime.execution import limits

# the samples a run keeps at the most, unless --max-samples says otherwise
DEFAULT_MAX_SAMPLES = 100_001
# the problems' sweep_dt put a scheme of up to this order in its asymptotic range; one of a
# higher order p also sweeps p - SWEEP_ORDER doublings of the largest step (``sweep_steps``)
SWEEP_ORDER = 5
# a cell beyond these is refused up front, unless --allow-large
MAX_STEPS = 10**9
# beyond this many steps a run's 64-bit step counters overflow: refused even with --allow-large
MAX_COUNTED_STEPS = rowschema.MAX_COUNT
MAX_SAMPLE_BYTES = 4 * 2**30


def sweep_steps(pcls: type[Problem], icls: type[Integrator], t_final: float) -> list[float]:
    """The default sweep's steps of ``icls`` on ``pcls``: the problem's ``sweep_dt``, and for a
    scheme of declared order p above SWEEP_ORDER its largest step doubled p - SWEEP_ORDER
    times more (those within the span), so that the sweep crosses the scheme's asymptotic
    range above the round-off floor: kahan-li-8 on kepler is on the floor from dt 0.005 to
    0.02, where it has no order, and its local slopes from 0.02 to 0.16 are 7.9, 8.05, 8.34."""
    steps = [float(x) for x in pcls.sweep_dt]
    order = icls.order
    if not steps or order is None or order <= SWEEP_ORDER:
        return steps
    span = float(t_final) - pcls.t0
    larger = [max(steps) * 2**k for k in range(1, int(order) - SWEEP_ORDER + 1)]
    return [h for h in larger[::-1] if h <= span] + steps


def check_step(problem: str, scheme: str, settings: Mapping[str, Any], t_final: float) -> None:
    """A fixed step larger than the span is refused: one step of the span would be taken and
    the row labelled with the larger dt (dt 1, 5 and 10 over a span of 1 give one row thrice)."""
    pcls, icls = registry.problem_class(problem), registry.integrator_class(scheme)
    if not issubclass(icls, FixedStepIntegrator):
        return
    given = settings.get("dt")
    dt = float(pcls.default_dt if given is None else given)
    span = float(t_final) - pcls.t0
    if dt > span * (1 + 1e-9):
        what = f"--dt {dt:g}" if given is not None else f"the default step dt={dt:g} of {problem}"
        raise InputError(f"{what}: larger than the span t_final - t0 = {span:g} ({problem} x {scheme}); "
                         f"a fixed step must be <= the span (pass a smaller --dt or a larger --t-final)")


def check_span(problem: str, t_final: float, argument: str) -> None:
    """A final time a run can reach: one whose span at the problem's default step is more
    steps than a run can count (MAX_COUNTED_STEPS, which ``check_size`` refuses even with
    --allow-large) is an InputError naming ``argument`` (how the front end spells it)."""
    pcls = registry.problem_class(problem)
    try:
        steps = (float(t_final) - pcls.t0) / pcls.default_dt
    except OverflowError:
        steps = math.inf
    if not steps <= MAX_COUNTED_STEPS:
        raise InputError(f"{argument}: about {steps:.3g} steps of {problem}'s step dt={pcls.default_dt:g}, more than "
                         f"a run can count ({MAX_COUNTED_STEPS:.3g}): no run reaches it")


def working_set(integrator: Integrator, problem: Problem, traj: Trajectory) -> int:
    """The bytes a run touches, roughly: its samples, its state and the scratch array its
    steps use (``work_shape``); the calibration of a row beyond the caches takes the memory
    workload (longtime.execution.calibration)."""
    size = traj.t.nbytes + traj.u.nbytes + 2 * 8 * problem.dim
    shape = getattr(integrator, "work_shape", None)
    if shape is not None:
        try:
            size += 8 * int(math.prod(shape(problem)))
        except Exception:  # a scheme whose scratch depends on more than the problem: its samples count
            pass
    return int(size)


def cell_size(cell: Any, dims: dict[str, int]) -> tuple[int, float, float]:
    """(state dimension, estimated steps, step) of a cell: steps = (t_final - t0) / dt with
    the cell's dt, or the problem's default step for adaptive schemes (a rough size).
    ``dims`` caches the dimension of each problem setting across calls."""
    pcls = registry.problem_class(cell.problem)
    key = json.dumps(cell.problem_settings, sort_keys=True, default=str) + cell.problem
    if key not in dims:
        dims[key] = pcls(**cell.problem_settings).dim
    dt = float(cell.integrator_settings.get("dt") or pcls.default_dt)
    span = float(cell.t_final if cell.t_final is not None else pcls.default_t_final) - pcls.t0
    try:
        steps = span / dt
    except OverflowError:  # 1e308 / 1e-300
        steps = math.inf
    return dims[key], steps, dt


@to_stderr  # plugin code runs here: its output is not the contract's
def check_size(cells: Iterable[Any], max_samples: int = DEFAULT_MAX_SAMPLES,
               memory_limit: int | None = None, allow_large: bool = False) -> None:
    """Refuse, before anything runs, a cell whose estimated step count passes MAX_STEPS,
    whose recorded samples pass MAX_SAMPLE_BYTES, or whose samples and what its metrics
    allocate (``Problem.metrics_bytes``) pass ``memory_limit`` (the cell's, --memory-limit)
    (``--allow-large`` skips this). Steps are (t_final - t0) / dt, with the problem's default
    step for adaptive schemes (a rough size); samples as the integrator keeps them (see
    Integrator.integrate). A cell of more than MAX_COUNTED_STEPS steps is refused even with
    ``allow_large``."""
    from longtime.core.integrator import SAMPLE_BUDGET

    dims: dict[str, int] = {}
    problems: dict[str, Problem] = {}
    for cell in cells:
        if cell.skip_reason:
            continue
        dim, steps, dt = cell_size(cell, dims)
        given = cell.integrator_settings.get("dt")
        step = f"dt={dt:g}" if given else f"steps of about the problem's dt={dt:g}"
        what = f"{cell.problem} x {cell.integrator} ({step}, t_final={cell.t_final:g})"
        if not steps <= MAX_COUNTED_STEPS:
            raise InputError(f"{what}: about {steps:.3g} steps, more than a run can count ({MAX_COUNTED_STEPS:.3g}, "
                             f"even with --allow-large): lower --t-final or raise the step")
        if allow_large:
            continue
        if not steps <= MAX_STEPS:
            raise InputError(f"{what}: about {steps:.3g} steps, over the limit of {MAX_STEPS:.0e}; "
                             f"pass --allow-large to run it anyway")
        samples = min(steps + 1, max_samples, max(2001, SAMPLE_BUDGET // dim))
        size = samples * (dim + 1) * 8
        if size > MAX_SAMPLE_BYTES:
            raise InputError(f"{what}: its samples need about {size / 2**30:.3g} GiB (dimension {dim}), over "
                             f"the limit of {MAX_SAMPLE_BYTES / 2**30:g} GiB; pass --allow-large to run it "
                             f"anyway (or lower --max-samples)")
        if memory_limit:
            key = json.dumps(cell.problem_settings, sort_keys=True, default=str) + cell.problem
            if key not in problems:
                problems[key] = registry.problem_class(cell.problem)(**cell.problem_settings)
            need = size + problems[key].metrics_bytes(int(samples))
            if need > memory_limit:
                raise InputError(f"{what}: its samples and metrics need about {limits.gib(need)} (dimension {dim}, "
                                 f"{int(samples)} samples), over the cell's memory limit of "
                                 f"{limits.gib(memory_limit)} (--memory-limit); lower --max-samples, raise "
                                 f"--memory-limit or pass --allow-large to run it anyway")
