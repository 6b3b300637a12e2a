"""A cell's time from several processes.

Where a process's code and data land in memory (address randomisation, the heap's state,
which core and which neighbour it shares) and what else the machine runs while it lives
can hold a cell at one speed for the whole process and at another in the next
(docs/performance.md, "Two speeds"): the minimum of the repeats within one process cannot
see that. So a timed cell runs in ``processes`` processes (``DEFAULT_PROCESSES``,
``--processes``): the process that measures its row (metrics, reference, samples), then
``processes - 1`` fresh interpreters started here that only time its integration
(``time_cells``), loading its kernel from the kernel cache, with the determinism check
alone: each must reproduce the row's run bit for bit (``samples_digest``), else the row is
``failed`` (non-deterministic). The repeats are split among the processes
(``Timing.per_process``), so the timed runs cost about what one process's did.

The row then keeps each process's minimum (``cpu_s_processes``, the row's own process
first) and their spread (``cpu_s_process_spread`` = max / min, a factor >= 1); ``cpu_s`` is
the minimum over the processes, as within a process: noise and an unlucky placement only
ever add time, so the fastest process is the one least disturbed, and the minimum of
several processes holds across invocations where one process's does not. The fresh
processes time their cells in rounds spread over at least ``SPREAD_S`` seconds
(``time_cells``), because the machine's slow moments last about a second; the spread is
taken between them where there are two or more (the row's own process times a burst). ``repeats`` and
``cpu_s_samples`` count every timed run of every process. Verdicts (compare, history,
``--baseline``) judge a change against the spread between processes.

A cell whose single run takes longer than ``Timing.ONCE_ABOVE`` is timed once, in its own
process only (its cost dwarfs the spread; the row says so); a cell that did not end ``ok``
is not timed again. Timing by need (``by_need``, the main job's default: ``RETIME``,
``--timing``) leaves out, besides, the cells whose timing could change no answer
(longtime.predict.need: dominated by more than its FACTOR on every front of error against
CPU), and the rows' own processes then time a run only as far as that factor-2 decision
needs (``row_timing``); ``--timing all`` times every cell again, at the split timing in
every process. Each row says how it was timed (``timed_in``: "3 processes", or "its own
process, N runs: " and why).
"""
from __future__ import annotations

import math
import os
import sys
import time
from typing import Any, Callable, Iterable

from longtime.core import phases
from longtime.core.params import InputError
from longtime.core.status import Status
from longtime.core.timing import Timing
from longtime.execution import child as children
from longtime.execution import tempdirs
from longtime.execution.cells import Cell, build
from longtime.execution.child import Child, RunSpec

DEFAULT_PROCESSES = 3
# $LONGTIME_PROCESSES sets the default of --processes (a test session sets 1)
ENV = "LONGTIME_PROCESSES"
# a child that times cells may take this long beyond the timed runs it repeats (an
# interpreter start, imports, kernels loaded from the cache)
START_S = 120.0
POLL_S = 0.05
# a timing process spreads each cell's runs over at least this many seconds (time_cells)
SPREAD_S = 3.0
MAX_ROUNDS = 100
# which cells the timing processes time again: "need" (those whose timing could change an
# answer: ``by_need``) or "all"
RETIME = ("need", "all")
# the row field that says how its cell was timed: "N processes", or ALONE + ": why"
TIMED_IN = "timed_in"
ALONE = "its own process"
# the statuses of a timing process's run that end it before its end (a time limit passed, the
# process paused or killed): a lost sample, never evidence that the run differs
LOST = (Status.TIMEOUT,)


def max_processes() -> int:
    """The most processes that may time a cell: four per core, at least 16, at most 256 (each
    is an interpreter started per batch of cells)."""
    return min(256, max(16, 4 * (os.cpu_count() or 1)))


def check_processes(value: Any, name: str = "--processes") -> int:
    """A process count: an integer from 1 to ``max_processes()`` (one line naming ``name``
    otherwise)."""
    allowed = f"expected an integer from 1 to {max_processes()} (processes that time each cell)"
    if isinstance(value, bool) or not isinstance(value, int):
        try:
            value = int(str(value), 10)
        except ValueError:
            raise InputError(f"{name} {value!r}: {allowed}") from None
    if not 1 <= value <= max_processes():
        raise InputError(f"{name} {value}: {allowed}")
    return value


def default_processes() -> int:
    """``$LONGTIME_PROCESSES`` or ``DEFAULT_PROCESSES``."""
    value = os.environ.get(ENV)
    return DEFAULT_PROCESSES if not value else check_processes(value, f"${ENV}")


def row_timing(timing: Timing, processes: int, retime: str) -> Timing:
    """How the process that measures a cell's row times its run, for a cell timed in
    ``processes`` processes under ``retime``: ``timing`` split among them
    (``Timing.per_process``), as each fresh process times it; under timing by need ("need",
    with fresh processes) the split timing's screening (``Timing.screening``: a run or a
    few), since that time only decides by a factor of 2 whether the cell is within reach of
    a front (longtime.predict.need), and a contender's time is taken again in the fresh
    processes, at the split timing."""
    split = timing.per_process(processes)
    return split.screening() if retime == "need" and processes > 1 else split


def timed_elsewhere(row: dict[str, Any]) -> bool:
    """Whether other processes time this row's cell: an ``ok`` run with a time and a digest,
    short enough to have been repeated (``Timing.ONCE_ABOVE``)."""
    wall = row.get("wall_s")
    return (row.get("status") == Status.OK and isinstance(row.get("cpu_s"), (int, float))
            and bool(row.get("samples_digest")) and isinstance(wall, (int, float)) and wall <= Timing.ONCE_ABOVE)


def time_cells(cells: list[Cell], max_samples: int, timing: Timing, time_limit: float | None = None,
               reference: Callable[[], float] | None = None,
               on_cell: Callable[[int, int], None] | None = None) -> list[dict[str, Any]]:
    """In this process, each cell's integration alone: per cell its ``cpu_s`` (the minimum),
    ``wall_s``, ``cpu_s_samples``, ``samples_digest``, ``status`` and ``pid``; a cell that
    raises gives ``status`` failed and its ``message``.

    With ``reference`` (a baseline workload: a call runs it once and returns its CPU
    seconds), each timed run of a cell is followed at once by one run of the baseline, so
    the two meet the same moment of the machine; each record then has
    ``reference_s_samples`` (the baseline's run after each of ``cpu_s_samples``) and
    ``cpu_ratio`` (``paired_ratio``: the cell's time in units of the baseline's).

    The cells are timed in rounds, one run of each cell a round: a cell runs again while it
    has fewer than ``timing.least_runs``, while its timed total is under ``timing.min_time``
    (at most ``timing.repeats`` runs), and while the rounds span less than ``SPREAD_S``
    seconds (at most ``MAX_ROUNDS`` rounds). A state of the machine that slows work through
    the caches by up to twice comes and goes within a second or two (docs/performance.md,
    "Two speeds"), so the runs of a small batch, spread over seconds, meet a quiet moment where
    a burst of repeats may not; a large batch spans SPREAD_S in one round and costs one run a
    cell. Every run must reproduce the first bit for bit. ``on_cell(k, finished)`` is called
    before the k-th cell is built and before each of its runs, ``finished`` the number of
    cells whose timing is done (a timing process marks the cell it is in and how far it is)."""
    prepared: list[tuple[Any, Any, float] | None] = []
    out: list[dict[str, Any]] = []
    for k, cell in enumerate(cells):
        try:
            if on_cell is not None:
                on_cell(k, 0)
            problem, integrator = build(cell)
            t_final = problem.default_t_final if cell.t_final is None else cell.t_final
            prepared.append((problem, integrator, t_final))
            out.append({"status": Status.OK, "message": None, "cpu_s_samples": [], "wall_s_samples": [],
                        "samples_digest": None, "pid": os.getpid()})
            if reference is not None:
                out[-1]["reference_s_samples"] = []
        except (Exception, SystemExit) as exc:
            prepared.append(None)
            out.append({"status": Status.FAILED, "message": f"{type(exc).__name__}: {exc}", "pid": os.getpid()})
    start, rounds, stopped = time.monotonic(), 0, set()
    while rounds < MAX_ROUNDS:
        spreading = time.monotonic() - start < SPREAD_S
        active = [k for k, p in enumerate(prepared) if p is not None and out[k]["status"] == Status.OK
                  and k not in stopped and (
            len(out[k]["cpu_s_samples"]) < timing.least_runs or spreading
            or (len(out[k]["cpu_s_samples"]) < timing.repeats and sum(out[k]["wall_s_samples"]) < timing.min_time))]
        if not active:
            break
        for k in active:
            problem, integrator, t_final = prepared[k]
            record = out[k]
            try:
                if on_cell is not None:
                    on_cell(k, len(cells) - len(active))
                deadline = time.monotonic() + time_limit if time_limit else None
                with phases.phase("timing", f"{cells[k].problem} x {cells[k].integrator}"):
                    traj = integrator.integrate(problem, t_final, max_samples=max_samples, timing=Timing(repeats=1),
                                                deadline=deadline)
            except (Exception, SystemExit) as exc:
                record.update(status=Status.FAILED, message=f"{type(exc).__name__}: {exc}")
                continue
            digest = traj.extra.get("samples_digest")
            if traj.status == Status.TIMEOUT:  # stopped, not finished: no sample, and nothing to compare
                if not record["cpu_s_samples"]:
                    record.update(status=Status.TIMEOUT, message=f"the run passed the time limit in this process "
                                                            f"({traj.message})", samples_digest=None)
                else:
                    stopped.add(k)  # the runs timed so far stand
                continue
            if traj.status != Status.OK or (record["samples_digest"] is not None
                                            and digest != record["samples_digest"]):
                if not record["cpu_s_samples"]:
                    record.update(status=traj.status, message=traj.message, samples_digest=digest)
                else:  # a repeat that differs from the first run: the first run's digest stands
                    record.update(status=Status.FAILED, message=(
                        f"non-deterministic: timed run {len(record['cpu_s_samples']) + 1} did not "
                        f"reproduce the first run's states bitwise ({traj.status})"))
                continue
            record["samples_digest"] = digest
            record["cpu_s_samples"].append(float(traj.cpu_s))
            record["wall_s_samples"].append(float(traj.wall_s))
            if reference is not None:
                record["reference_s_samples"].append(float(reference()))
        rounds += 1
    for record in out:
        walls = record.pop("wall_s_samples", None)
        if record["status"] == Status.OK and walls:
            record.update(cpu_s=min(record["cpu_s_samples"]), wall_s=min(walls))
            if reference is not None:
                record["cpu_ratio"] = paired_ratio(record["cpu_s_samples"], record["reference_s_samples"])
    return out


def paired_ratio(cell_s: list[float], reference_s: list[float]) -> float:
    """A cell's CPU time in units of a baseline's, from runs taken in pairs (one run of the
    cell, then one of the baseline): the ratio of their minima.

    The minimum of each, not the median of the pairs' ratios: the machine's slow moments
    slow work that goes through the caches by up to twice while the compute-bound
    reference workload does not move, and a scheme's kernel may be slowed more or less
    than any baseline, so a pair's ratio rises with the moment and the median of the
    ratios moves with the share of slow moments in the window (docs/performance.md, "A time
    asv can judge": measured). The minimum of each side is its fastest, least disturbed
    run, as ``cpu_s`` is; the pairs' spread over the same seconds gives both the same
    moments to meet a fast one, and the ratio divides out the speed of the core (its clock
    and what the host gives it) over the minutes between two commits' runs. NaN where
    either side has no positive time."""
    if not cell_s or not reference_s or not min(reference_s) > 0 or not min(cell_s) > 0:
        return math.nan
    return min(cell_s) / min(reference_s)


def merge(row: dict[str, Any], others: list[dict[str, Any]], processes: int) -> None:
    """Fold the timings of other processes (``time_cells``' results for this row's cell) into
    ``row``: each process's minimum, their spread, ``cpu_s`` the minimum, every sample; a
    process whose run differs from the row's makes the row ``failed``."""
    if not isinstance(row.get("cpu_s"), (int, float)):
        return
    mins, walls, samples = [row["cpu_s"]], [row.get("wall_s")], list(row.get("cpu_s_samples") or [row["cpu_s"]])
    missing = []
    for o in others:
        if o.get("status") == Status.OK and o.get("samples_digest") == row.get("samples_digest"):
            mins.append(o["cpu_s"])
            walls.append(o["wall_s"])
            samples += o["cpu_s_samples"]
        elif o.get("status") not in LOST and (o.get("status") == Status.OK or o.get("samples_digest")):
            row["status"] = Status.FAILED
            row["message"] = "; ".join(m for m in (
                row.get("message"), f"non-deterministic: the run timed in another process (pid {o.get('pid')}) did "
                                    f"not reproduce this row's run bitwise ({o.get('status')})") if m)
            break
        else:
            missing.append(o.get("message") or o.get("status") or "no result")
    row["cpu_s_processes"] = mins
    # the spread between the processes that spread their runs over seconds (the row's own
    # process times a burst, which the machine's slow moments can cover whole)
    spread = mins[1:] if len(mins) > 2 else mins
    row["cpu_s_process_spread"] = max(spread) / min(spread) if len(spread) > 1 and min(spread) > 0 else None
    if len(mins) > 1:
        row["cpu_s"] = min(mins)
        row["wall_s"] = min(w for w in walls if isinstance(w, (int, float)))
        samples.sort()
        n = len(samples)
        row.update(cpu_s_samples=samples, repeats=n, cpu_s_max=samples[-1],
                   cpu_s_median=samples[n // 2] if n % 2 else 0.5 * (samples[n // 2 - 1] + samples[n // 2]))
        if isinstance(row.get("calibration_cpu_s"), (int, float)) and row["calibration_cpu_s"] > 0:
            row["cpu_s_calibrated"] = row["cpu_s"] / row["calibration_cpu_s"]
    if len(mins) < processes and row.get("status") == Status.OK:
        why = f": {missing[0]}" if missing else ""
        note = f"timed in {len(mins)} of {processes} processes{why}"
        row["message"] = f"{row['message']}; {note}" if row.get("message") else note
    if len(mins) > 1:
        row[TIMED_IN] = f"{len(mins)} processes"
    else:
        timed_alone(row, missing[0] if missing else "the others gave no time")


def one_process(row: dict[str, Any], why: str) -> None:
    """The process fields of a row timed in its own process only, and ``why`` in its
    ``timed_in``."""
    if isinstance(row.get("cpu_s"), (int, float)):
        row.setdefault("cpu_s_processes", [row["cpu_s"]])
        row.setdefault("cpu_s_process_spread", None)
        timed_alone(row, why)


def timed_alone(row: dict[str, Any], why: str) -> None:
    """``row``'s ``timed_in`` for a time taken in its own process only: how many timed runs
    (its ``repeats``, where it has them) and ``why``."""
    runs = row.get("repeats")
    counted = f", {runs} run{'' if runs == 1 else 's'}" if isinstance(runs, int) and runs > 0 else ""
    row[TIMED_IN] = f"{ALONE}{counted}: {why}"


def alone_why(row: dict[str, Any], processes: int) -> str:
    """Why a row that is not timed elsewhere (``timed_elsewhere``) is timed in its own
    process only."""
    if processes <= 1:
        return "one process asked (--processes 1)"
    if row.get("status") != Status.OK:
        return f"the run ended {row.get('status')}"
    wall = row.get("wall_s")
    if isinstance(wall, (int, float)) and wall > Timing.ONCE_ABOVE:
        return f"a run over {Timing.ONCE_ABOVE:g} s, timed once"
    return "no digest of its samples to check another process's run against"


def by_need(rows: list[dict[str, Any]], pairs: Iterable[tuple[Cell, dict[str, Any]]],
            retime: str = "need") -> dict[int, str]:
    """The rows of ``pairs`` that the timing processes leave out under ``retime``: "all"
    none; "need" those whose timing could change no answer (longtime.predict.need, judged on
    ``rows``, the run's rows), each (by ``id``) with why, for its ``timed_in``."""
    if retime == "all":
        return {}
    from longtime.predict.need import need, setting_key

    def ident(r: dict[str, Any]) -> tuple:
        return (*setting_key(r), r.get("t_final"))

    why = {ident(r): n.why for r, n in zip(rows, need(rows)) if not n.retime}
    return {id(r): why[ident(r)] for _, r in pairs if ident(r) in why}


def across_processes(pairs: Iterable[tuple[Cell, dict[str, Any]]], processes: int, spec: RunSpec, jobs: int = 1,
                     on_progress: Callable[[int], None] | None = None,
                     alone: dict[int, str] | None = None) -> list[Cell]:
    """Time the cells of ``pairs`` (cell, its row as measured) in ``processes - 1`` fresh
    processes, ``jobs`` at a time, each cell run as ``spec`` says, and fold their times into
    the rows (``merge``); rows not timed elsewhere, and those of ``alone`` (``id`` of a row:
    why it is left out, ``by_need``), get their own process's fields. Returns the cells whose
    rows changed. ``on_progress(k)``: k more cells timed, summed over the processes (a
    progress display)."""
    pairs = list(pairs)
    alone = alone or {}
    todo = [(c, r) for c, r in pairs if processes > 1 and timed_elsewhere(r) and id(r) not in alone]
    chosen = {id(r) for _, r in todo}
    for _, row in pairs:
        if id(row) not in chosen:
            timed = processes > 1 and timed_elsewhere(row)  # else a reason of its own comes first
            one_process(row, alone[id(row)] if timed and id(row) in alone else alone_why(row, processes))
    if not todo:
        return []
    cells = [c for c, _ in todo]
    # each fresh process runs a cell up to ``spec.timing.repeats`` times, however few runs its
    # row's own process took (a screening: ``row_timing``)
    budget = START_S + 10 * sum(float(r["wall_s"]) * max(spec.timing.repeats, len(r.get("cpu_s_samples") or [1]))
                                for _, r in todo)
    with phases.phase("timing processes"):  # this process while they run
        results = run_children(cells, processes - 1, spec, jobs, budget, on_progress=on_progress)
    for k, (cell, row) in enumerate(todo):
        merge(row, [res[k] if res is not None else {"status": Status.FAILED, "message": err}
                    for res, err in results], processes)
    return cells


def run_children(cells: list[Cell], count: int, spec: RunSpec, jobs: int, timeout: float, paired: bool = False,
                 on_progress: Callable[[int], None] | None = None) -> list[tuple[list[dict] | None, str]]:
    """``count`` fresh interpreters, ``jobs`` at a time, each timing every cell of ``cells``
    (``time_cells``, as ``spec`` says; ``paired``: each run followed by one of the
    calibration's reference workload, ``calibration.reference_seconds``), each stopped past
    ``timeout`` seconds: per child (its results, "") or (None, why it gave none).
    ``on_progress(k)``: k more cells timed (each child's mark counts the cells it has
    finished), called as the count grows."""
    waiting, running, done = list(range(count)), [], {}
    started: list[Child] = []
    culprits = {}
    reported = 0
    try:
        while waiting or running:
            while waiting and len(running) < max(1, jobs):
                index = waiting.pop(0)
                folder = tempdirs.make("timing")
                children.write_job(folder, "time", cells, spec, paired=paired)
                child = children.start(folder)
                started.append(child)
                running.append((index, child, time.monotonic() + timeout))
            still = []
            for index, child, deadline in running:
                if child.ended():
                    result = child.result()
                    done[index] = (result, "") if result is not None else \
                        (None, child.failure("the timing process"))
                    if result is None and len(cells) > 1:
                        culprits[index] = child.current_cell()
                elif time.monotonic() > deadline:
                    child.kill()
                    done[index] = (None, f"the timing process passed {timeout:.0f} s and was stopped")
                    if len(cells) > 1:
                        culprits[index] = child.current_cell()
                else:
                    still.append((index, child, deadline))
            if on_progress is not None:  # the cells timed so far: the ended children's and each running one's
                timed = len(done) * len(cells) + sum(_finished_cells(c) for _, c, _ in still)
                if timed > reported:
                    on_progress(timed - reported)
                    reported = timed
            if len(still) == len(running):
                time.sleep(POLL_S)
            running = still
    finally:
        for child in started:
            child.remove()
    for index, culprit in culprits.items():
        if culprit is not None:
            done[index] = _without(cells, culprit, done[index][1], spec, timeout, paired)
    return [done[i] for i in range(count)]


def _finished_cells(child: Child) -> int:
    """The cells a running timing process has finished timing (its mark)."""
    marks = child.marks()
    return marks[1] if len(marks) > 1 else 0


def _without(cells: list[Cell], culprit: int, why: str, spec: RunSpec, timeout: float,
             paired: bool) -> tuple[list[dict] | None, str]:
    """The results of a timing process that ended in cell ``culprit`` without a result: the
    other cells timed again in a fresh process without it, and the culprit's record naming
    ``why`` (one plugin's crash costs the other cells of its batch nothing)."""
    rest = [c for i, c in enumerate(cells) if i != culprit]
    ((results, again),) = run_children(rest, 1, spec, 1, timeout, paired)
    if results is None:
        return None, again
    results.insert(culprit, {"status": Status.FAILED, "message": f"{why}, in this cell", "pid": None})
    return results, ""


def run_job(folder: str, job: children.Job) -> None:
    """The child's side of a ``time`` job (longtime.execution.child.KINDS): each cell timed,
    the results as its result."""
    phases.since_process_start("timing start")  # an interpreter and its imports
    children.enter(folder, job)  # a registered class that cannot be restored: its cells fail alone
    reference = None
    if job.options.get("paired"):
        from longtime.execution.calibration import reference_seconds, reference_workload

        reference_workload(10, 0.01)  # loaded (or compiled) before the first timed call
        reference = reference_seconds
    marked = [""]

    def on_cell(k: int, finished: int) -> None:  # the parent knows which cell a process that dies was in
        text = f"{k} {finished}"
        if text != marked[0]:  # a cell timed alone is marked once, not before each of its runs
            children.mark(folder, k, finished)
            marked[0] = text

    results = time_cells(job.cells, job.spec.max_samples, job.spec.timing, job.spec.time_limit, reference, on_cell)
    children.write_result(folder, results)
    sys.stderr.flush()
    os._exit(0)  # skip interpreter teardown (numba's and LLVM's)
