"""Running many cells: executors and the loop that stores each row as it finishes.

An executor is a function ``(cells, options) -> iterator of (cell, row)`` yielding rows as
they complete, in any order. ``serial`` runs in this process; ``process`` (the default)
on local long-lived worker processes (``longtime.execution.resident.ResidentPool``), each keeping
its compiled kernels across cells.
Rows are written to the store one transaction each, so an interruption loses nothing
already measured.
"""
from __future__ import annotations

import contextlib
import dataclasses
from concurrent.futures import FIRST_COMPLETED, Future, wait
from dataclasses import dataclass, field
from typing import Any, Callable, Iterator

from longtime.core import phases, registry
from longtime.core.params import InputError, check_choice
from longtime.core.progress import Progress
from longtime.core.status import Status
from longtime.core.timing import Timing
from longtime.execution import budget, calibration
from longtime.execution.batches import Chains, batches_by_pair, calibrated_row
from longtime.execution.cells import (
    DEFAULT_MAX_SAMPLES,
    DEFAULT_TIME_LIMIT,
    Cell,
    RunSpec,
    base_row,
    run_cell,
)
from longtime.execution.limits import default_memory_limit, hard_limit, memory_limited, signal_relay
from longtime.execution.pool import workers as pool_workers
from longtime.execution.processes import (
    RETIME,
    across_processes,
    by_need,
    default_processes,
    row_timing,
    timed_elsewhere,
)
from longtime.execution.resident import ResidentPool
from longtime.execution.store import Store
from longtime.execution.tempdirs import disk_full, out_of_space


@dataclass
class ExecOptions:
    jobs: int = 0  # 0: one per core
    max_samples: int = DEFAULT_MAX_SAMPLES
    cell_timeout: float | None = None  # a hard limit: each cell in a process, killed past it
    time_limit: float | None = DEFAULT_TIME_LIMIT  # the integration stops itself past it (None: never)
    # bytes a cell's worker process may allocate (None: no limit); see longtime.execution.limits
    memory_limit: int | None = field(default_factory=default_memory_limit)
    scheduler: str | None = None  # Dask scheduler address
    timing: Timing = field(default_factory=Timing)
    # what each cell's cost is measured by besides time: "time" (only) or "instructions"
    # (also counted under Valgrind: longtime.execution.valgrind)
    cost: str = "time"
    # processes that time each cell (longtime.execution.processes); the repeats of ``timing``
    # are split among them
    processes: int = field(default_factory=default_processes)
    # which cells those processes time again: "all", or "need" (those whose time could change
    # an answer, longtime.execution.processes.by_need: the main job's default)
    retime: str = "all"
    # called with each cell as it starts in this process (the store marks it started)
    on_start: Callable[[Cell], None] | None = None
    # work for a worker process that has no cell left to run (the results page's figures and
    # stability intervals): returns (picklable function, its arguments, a callback taking
    # its result), or None when there is none for now; the process executor asks again as
    # rows come in
    idle_work: Callable[[], "IdleTask | None"] | None = None

    def workers(self) -> int:
        return pool_workers(self.jobs)

    def run_spec(self) -> RunSpec:
        """How each cell runs, as a child process receives it."""
        return RunSpec(self.max_samples, self.timing, self.time_limit, self.memory_limit)


Executor = Callable[[list[Cell], ExecOptions], Iterator[tuple[Cell, dict]]]
IdleTask = tuple[Callable, tuple, Callable[[Any], None]]


def serial(cells: list[Cell], options: ExecOptions) -> Iterator[tuple[Cell, dict]]:
    """The cells in this process, one after the other, without the hard limit; a first stop
    signal ends the process within limits.SIGNAL_GRACE_S even in a compiled step that never
    returns, a second at once (limits.signal_relay)."""
    here = calibration.here()
    here.start()
    spec = options.run_spec()
    chains = Chains()  # a chain's bound holds in any order of its cells (longtime.execution.batches)
    with signal_relay():
        for cell in cells:
            if options.on_start is not None and not cell.skip_reason:
                options.on_start(cell)
            # the cell runs in this process (a script's, a notebook's): under the memory limit a
            # worker has, lifted again before the row is handed on
            with memory_limited(options.memory_limit):
                row = calibrated_row(here, chains.bounded(cell), spec)
            chains.saw(cell, row)
            yield cell, row


_FAMILY_PACKAGES = ("longtime.integrators.", "longtime.problems.")


def shared_code(batch: list[Cell]) -> frozenset[str]:
    """The modules whose compiled functions the batch's kernels may share with other batches:
    the problem class's module (kdv's spectral helpers, nbody's forces, the Taylor series
    other schemes of the problem reuse) and the scheme class's own modules (bpl's Pade and
    Laplace sums, which bpl-exp inherits). Unknown names give none: run_cell reports them."""
    from longtime.core import registry

    cell = batch[0]
    try:
        modules = {registry.problem_class(cell.problem).__module__}
        modules.update(k.__module__ for k in registry.integrator_class(cell.integrator).__mro__)
    except Exception:
        return frozenset()
    return frozenset(m for m in modules if _family_module(m))


def _family_module(module: str) -> bool:
    """A module of problems or schemes (longtime's own, or a plugin's); the base classes'
    modules (longtime.core's, abc, builtins) are every batch's, so never a key."""
    return module.startswith(_FAMILY_PACKAGES) or module.split(".")[0] not in ("longtime", "abc", "builtins")


class CompileOnce:
    """Hands out batches, largest first, so that two workers do not compile the same function
    at once: numba's disk cache is per function, and two processes that both miss it both
    compile (a cold default matrix compiled 24 functions twice, bpl's Pade among them). A
    batch waits while a running batch shares a module with it that no finished batch has
    compiled yet, unless every waiting batch is in that case: a worker never idles."""

    def __init__(self, batches: list[list[Cell]]):
        self.queue = [(b, shared_code(b)) for b in batches]
        self.compiled: set[str] = set()
        self.running: dict[int, frozenset[str]] = {}

    def __bool__(self) -> bool:
        return bool(self.queue)

    def take(self) -> list[Cell]:
        busy = set().union(*self.running.values()) - self.compiled
        index = next((i for i, (_, keys) in enumerate(self.queue) if not keys & busy), 0)
        batch, keys = self.queue.pop(index)
        self.running[id(batch)] = keys
        return batch

    def finished(self, batch: list[Cell]) -> None:
        self.compiled |= self.running.pop(id(batch), frozenset())


def scheduled(pool, workers: int, batches: list[list[Cell]], submit: Callable[[list[Cell]], Future],
              idle_work: Callable[[], IdleTask | None] | None = None) -> Iterator[tuple[list[Cell], Future]]:
    """(batch, its finished future, ``submit(batch)``) as they complete, the batches handed
    out in CompileOnce's order, one per idle worker: each worker gets its next batch before
    the caller sees the last one's result. Once every batch is handed out, a worker that
    would idle runs ``idle_work``'s tasks instead (``pool.submit(function, *arguments)``;
    never beside a waiting batch, so they take no time from a timed cell); their results go
    to their callbacks, and the caller sees only the batches."""
    order, futures = CompileOnce(batches), {}
    idle: dict[Future, Callable[[Any], None]] = {}

    def fill() -> None:
        while order and len(futures) + len(idle) < workers:
            batch = order.take()
            futures[submit(batch)] = batch
        while idle_work is not None and not order and len(futures) + len(idle) < workers:
            task = idle_work()
            if task is None:
                break
            work, work_args, callback = task
            idle[pool.submit(work, *work_args)] = callback

    fill()
    while futures or idle:
        ready, _ = wait([*futures, *idle], return_when=FIRST_COMPLETED)
        finished = [(futures.pop(fut), fut) for fut in ready if fut in futures]
        for batch, fut in finished:
            order.finished(batch)
        for fut in (f for f in ready if f in idle):
            callback = idle.pop(fut)
            if fut.exception() is None:  # a failed task is only not done ahead: its owner does it later
                callback(fut.result())
        fill()  # ahead of the caller's turn: no worker idles while it stores rows
        yield from finished
        fill()  # idle work the caller's new rows made ready


def worker_failed(cell: Cell, exc: BaseException) -> dict:
    """The ``failed`` row of a cell whose worker gave no row back (the batch or the call could
    not be written or read back, or the worker died): it measured nothing."""
    return {**base_row(cell), "status": Status.FAILED, "message": f"worker process failed: {exc!r}"}


def process_pool(cells: list[Cell], options: ExecOptions) -> Iterator[tuple[Cell, dict]]:
    """Batches of cells on ``workers`` long-lived worker processes (a ``ResidentPool``: one
    child each, ``python -m longtime.execution.child``, keeping its compiled kernels from
    batch to batch), each under the memory limit and the hard time limit of a cell. A worker
    that dies (a segfault, os.abort, SIGKILL, out of memory) or is killed past the hard limit
    costs that worker and its one cell (a ``failed`` or ``timeout`` row naming what
    happened): a fresh worker takes the batch's other cells, and the other workers go on."""
    runnable = [c for c in cells if not c.skip_reason]
    for cell in cells:
        if cell.skip_reason:
            yield cell, run_cell(cell)
    if not runnable:
        return
    workers = min(options.workers(), len(runnable))
    if workers == 1 and hard_limit(options.time_limit) is None:  # no limit to enforce: this process is the worker
        yield from serial(runnable, options)
        return
    with phases.phase("pool"), ResidentPool(workers, options.run_spec()) as pool:  # storing rows, waiting
        for batch, fut in scheduled(pool, workers, batches_by_pair(runnable), pool.submit_cells,
                                    idle_work=options.idle_work):
            try:
                rows = fut.result()
            except Exception as exc:  # the batch could not be written or read back
                rows = _handed_again(pool, batch, exc)
            yield from zip(batch, rows)


def _handed_again(pool: ResidentPool, batch: list[Cell], exc: Exception) -> list[dict]:
    """The rows of a batch that could not be handed to its worker or read back (``exc``),
    handed once more: that is this process's fault, not the cells', and it may pass (a
    moment of the machine); failed rows naming it only where it happens again. A full temp
    folder is the machine's: DiskFull, no row."""
    try:
        if not out_of_space(exc):  # a full disk is not handed again
            return pool.submit_cells(batch).result()
    except Exception as again:
        exc = again
    if out_of_space(exc):
        raise disk_full(exc, "a worker wrote its cell's files") from None
    return [worker_failed(c, exc) for c in batch]


def isolated(cells: list[Cell], options: ExecOptions) -> Iterator[tuple[Cell, dict]]:
    """Each cell in a fresh child process, killed past ``cell_timeout`` (else the hard limit of
    ``time_limit``, longtime.execution.limits) (a ``timeout`` row); a child that dies (os._exit,
    segfault) gives a ``failed`` row. See longtime.execution.isolation."""
    from longtime.execution.isolation import run_isolated

    timeout = options.cell_timeout or hard_limit(options.time_limit)
    yield from run_isolated(cells, options.run_spec(), timeout, options.workers())


def dask_cluster(cells: list[Cell], options: ExecOptions) -> Iterator[tuple[Cell, dict]]:
    """Cells as batched tasks on a Dask cluster (``options.scheduler``, or a local one of
    ``jobs`` workers); see longtime.execution.dask_executor, imported only when used."""
    from longtime.execution.dask_executor import dask_cluster as run_on_dask

    in_memory = registry.session_only(sorted({n for c in cells for n in (c.problem, c.integrator)}))
    if in_memory:
        raise InputError(f"{', '.join(in_memory)}: defined in this process (registered in memory), which Dask "
                         f"workers cannot load: install it as a plugin on every worker (docs/plugins.md), "
                         f"or use executor='process'")
    yield from run_on_dask(cells, options)


def _with_limits(default: Executor) -> Executor:
    """``default`` unless a time limit is set: a pool worker or this process cannot stop a
    hung cell, so the cells then run isolated (one process each)."""

    def run(cells: list[Cell], options: ExecOptions) -> Iterator[tuple[Cell, dict]]:
        if options.cell_timeout:
            return isolated(cells, options)
        return default(cells, options)

    run.__doc__ = default.__doc__
    return run


EXECUTORS: dict[str, Executor] = {"serial": _with_limits(serial), "process": _with_limits(process_pool),
                                  "isolated": isolated, "dask": dask_cluster}


COSTS = ("time", "instructions")


def check_cost(cost: str) -> None:
    """A known cost; "instructions" also needs Valgrind (InputError naming its Debian package)."""
    check_choice("cost", cost, COSTS)
    if cost == "instructions":
        from longtime.measure.instructions import require

        require()


def get_executor(name: str) -> Executor:
    check_choice("executor", name, EXECUTORS)
    return EXECUTORS[name]


def run_matrix(cells: list[Cell], store: Store | None, run_id: int | None, executor: str = "process",
               options: ExecOptions | None = None, progress: "bool | Progress" = False,
               on_row: Callable[[Cell, dict], None] | None = None,
               on_timed: Callable[[list[dict]], None] | None = None) -> list[dict]:
    """Run the cells, storing each row as it completes (then ``on_row(cell, row)``), then
    time them in ``options.processes - 1`` more processes (longtime.execution.processes), each
    stored row updated with their times (``on_timed(rows)`` is given the rows as they are
    then stored, once the timing processes and the calibration after them are done, before
    the store is updated); returns the rows in cell order. ``progress`` (True, or a
    longtime.core.progress.Progress) shows each phase on stderr: the cells, the timing
    processes, the instruction counts."""
    options = options or ExecOptions()
    # the timing processes start on this machine: a Dask cluster's rows are timed where they
    # ran, in one process
    processes = 1 if executor == "dask" else options.processes
    if options.max_samples < 2:
        raise InputError(f"max_samples={options.max_samples} is not valid: must be >= 2")
    check_cost(options.cost)
    check_choice("retime", options.retime, RETIME)
    # the rows' processes time as row_timing says; the fresh timing processes, the split timing
    first = row_timing(options.timing, processes, options.retime)
    options = dataclasses.replace(options, timing=options.timing.per_process(processes))
    run = get_executor(executor)
    if store is not None and run_id is not None and options.on_start is None:
        options = dataclasses.replace(options, on_start=lambda cell: store.mark_started(run_id, cell))
    rows: dict[str, dict] = {}
    shown = progress if isinstance(progress, Progress) else Progress(on=bool(progress))
    storing = store is not None and run_id is not None
    later = [PROCESSES_PHASE] + ([COUNTS_PHASE] if options.cost == "instructions" else [])
    dims: dict[str, int] = {}
    cost = {c.key: budget.cell_seconds(c, first, dims) for c in cells}  # the time left weighs them
    with shown.phase("cells", total=len(cells), unit="cells", costs=sum(cost.values())):
        here = calibration.here(reset=True)  # the machine's speed ahead of the cells, and after them
        if storing:
            store.add_calibrations(run_id, [here.take("before")])
            here.handed()
        for cell, row in run(cells, dataclasses.replace(options, timing=first)):
            points = calibration.take_points(row)
            rows[cell.key] = row
            if storing:
                row[PHASES_FIELD] = list(later)  # stored before them: a resume knows what it lacks
                store.add_calibrations(run_id, points)
                store.add_row(run_id, cell, row)
            if on_row is not None:
                on_row(cell, row)
            shown.advance(last=f"{cell.problem} x {cell.integrator}: {row['status']}", cost=cost.get(cell.key))
    found = [(cell, rows[cell.key]) for cell in cells if cell.key in rows]
    alone = by_need([r for _, r in found], found, options.retime) if processes > 1 else {}
    again = [r for _, r in found if processes > 1 and timed_elsewhere(r) and id(r) not in alone]
    left = sum(1 for _, r in found if processes > 1 and timed_elsewhere(r) and id(r) in alone)
    timing_phase = shown.phase("timing processes", total=len(again) * (processes - 1), unit="cells timed",
                               estimate_s=timing_estimate(again, processes, options.workers()),
                               detail=f"{len(again)} cells timed again in each of {processes - 1} fresh processes"
                                      + (f" ({left} whose timing changes no answer left out: --timing all)"
                                         if left else "")) \
        if again else contextlib.nullcontext()
    with timing_phase:
        across_processes(found, processes, options.run_spec(), options.workers(), on_progress=shown.advance,
                         alone=alone)
    if storing:  # the machine's speed after the cells, before any other work starts
        store.add_calibrations(run_id, [here.take("after")])
    for _, row in found:
        phase_done(row, PROCESSES_PHASE)
    if on_timed is not None:
        on_timed([row for _, row in found])
    if storing:
        with phases.phase("store"):
            for cell, row in found:
                store.update_row(run_id, cell, row)
    if options.cost == "instructions":  # after every timed run: Valgrind's process times nothing
        with shown.phase("instruction counts", detail=f"{len(found)} cells under Valgrind"):
            _add_instructions(cells, rows, store if storing else None, run_id, options)
    return [rows[c.key] for c in cells if c.key in rows]


PROCESS_START_S = 5.0


def timing_estimate(rows: list[dict], processes: int, jobs: int) -> float | None:
    """The seconds the timing processes are expected to take: each of the ``processes - 1``
    processes times every row's cell again (its runs spread over at least SPREAD_S seconds,
    each run about the row's wall time), ``jobs`` processes at a time, after its start
    (``PROCESS_START_S``: an interpreter, its imports, its kernels loaded from the cache)."""
    from longtime.execution.processes import SPREAD_S

    if not rows or processes < 2:
        return None
    one = sum(float(r.get("wall_s") or 0.0) * max(1, len(r.get("cpu_s_samples") or [1])) for r in rows)
    waves = -(-(processes - 1) // max(1, jobs))
    return waves * (PROCESS_START_S + max(SPREAD_S, one))


def _add_instructions(cells: list[Cell], rows: dict[str, dict], store: Store | None, run_id: int | None,
                      options: ExecOptions) -> None:
    """Each row's instruction fields (longtime.execution.valgrind), stored over its row."""
    from longtime.execution.valgrind import instruction_fields

    measured = [(c, rows[c.key]) for c in cells if c.key in rows]
    fields = instruction_fields(measured, options.max_samples, options.time_limit)
    for cell, row in measured:
        row.update(fields[cell.key])
        phase_done(row, COUNTS_PHASE)
        if store is not None:
            store.add_row(run_id, cell, row)


# a row's phases after its cell's own run, each named in the row's PHASES_FIELD (the phases it
# still lacks) from when it is stored until the phase has run for it: a run killed in a later
# phase leaves rows that say what they lack, and ``complete_phases`` (``matrix --resume``) runs it
PROCESSES_PHASE = "timing processes"
COUNTS_PHASE = "counts"
PHASES_FIELD = "phases_missing"


def phase_done(row: dict[str, Any], phase: str) -> None:
    """``phase`` has run for ``row``: the row loses it from its missing phases (and the field
    once none is missing)."""
    missing = [p for p in row.get(PHASES_FIELD) or [] if p != phase]
    if missing:
        row[PHASES_FIELD] = missing
    else:
        row.pop(PHASES_FIELD, None)


def complete_phases(store: Store, run_id: int, options: ExecOptions) -> int:
    """Run, for each stored row of ``run_id`` that lacks them, the phases after its cell's run
    (the timing processes, the instruction counts), each row updated in the store; a phase
    that cannot run here (no Valgrind) stays in the row's missing phases and its message says
    so. Returns the number of rows that lacked a phase."""
    incomplete = store.incomplete_rows(run_id, PHASES_FIELD)
    if not incomplete:
        return 0
    timed = [(c, r) for c, r in incomplete if PROCESSES_PHASE in r[PHASES_FIELD]]
    if timed:
        spec = dataclasses.replace(options.run_spec(), timing=options.timing.per_process(options.processes))
        # judged on the run's rows: those stored before, with these
        alone = by_need(store.rows(run_id), timed, options.retime) if options.processes > 1 else {}
        across_processes(timed, options.processes, spec, options.workers(), alone=alone)
        for cell, row in timed:
            phase_done(row, PROCESSES_PHASE)
            store.update_row(run_id, cell, row)
    counted = [(c, r) for c, r in incomplete if COUNTS_PHASE in r.get(PHASES_FIELD, ())]
    if counted:
        try:
            check_cost("instructions")
            _add_instructions([c for c, _ in counted], {c.key: r for c, r in counted}, store, run_id, options)
        except InputError as exc:
            for cell, row in counted:
                note = f"not counted: {exc}"
                row["message"] = f"{row['message']}; {note}" if row.get("message") else note
                store.update_row(run_id, cell, row)
    return len(incomplete)
