"""``--cost instructions``: each measured cell's integration run once more under Callgrind,
all cells of a run in one Valgrind process (importing numba under Valgrind costs about a
minute of CPU; loading a cell's kernels from the cache, a few seconds).

``instruction_fields(pairs, ...)`` is the parent's side: it decides which cells can be
counted, writes them to a job file of kind ``count`` (longtime.execution.child), runs
``python -m longtime.execution.child FOLDER`` under Valgrind
(longtime.measure.instructions.command) and reads the counts back. ``run_job`` is the
worker's side: per cell it builds the problem and the scheme, loads and warms up the
kernel uncounted (the counted path itself run WARM_CALLS times on the warm-up's throw-away
state), then counts only the calls into the compiled loop
(longtime.measure.instructions.counted_call), in one chunk.

The counted kernels are compiled for one fixed target (instructions.COUNT_TARGET,
x86-64-v3) whatever the host, in a numba cache of their own (instructions.target_cache_dir):
a first process, outside Valgrind and with the target's environment, runs the cells once
(compiling and caching their kernels), then the Valgrind process loads them from that
cache. The timed runs keep the host's own kernels. So a count does not depend on the host
CPU (an AVX-512 host's kernels would stop Valgrind with SIGILL), and counts from two x86-64
machines with the same versions compare.

Fields a row gains (only when instructions are asked for): ``instructions`` (the count of
the integration, an integer), ``instructions_per_step``, ``instructions_tool`` (the
Valgrind that counted and the target the kernels were compiled for),
``instructions_target`` (that target), ``instructions_versions`` (the versions that can
still move a count: Python, numba, llvmlite, numpy) and ``instructions_skipped`` (why a
cell has no count; null when it has one).
"""
from __future__ import annotations

import re
import shutil
import signal
import time
from pathlib import Path
from typing import Any, Iterable

from longtime.core import registry
from longtime.core.status import Status
from longtime.core.stepping import AdaptiveIntegrator, FixedStepIntegrator
from longtime.execution import child as children
from longtime.execution import jobfiles, tempdirs
from longtime.execution.cells import Cell, build
from longtime.execution.child import RunSpec
from longtime.measure import instructions

FIELDS = ("instructions", "instructions_per_step", "instructions_tool", "instructions_target", "instructions_versions",
          "instructions_skipped")
# the exit code of `longtime run --cost instructions` when no row has a count
EXIT_NOTHING_COUNTED = 3
# what the worker may spend before its first cell: Python, numpy, numba, longtime and the
# request function under Valgrind (about a minute of CPU on an idle machine; a loaded one
# takes longer)
STARTUP_SECONDS = 600.0
# per cell besides the integration: building the problem, loading its kernels from the cache
PER_CELL_SECONDS = 60.0
# the shared drivers whose loop calls are counted: the first call is the warm-up
_COUNTED_DRIVERS = (FixedStepIntegrator._integrate, AdaptiveIntegrator._integrate)
# uncounted runs of the counted path on the warm-up's throw-away state before a cell's count
WARM_CALLS = 3


def skipped(reason: str) -> dict[str, Any]:
    return {"instructions": None, "instructions_per_step": None, "instructions_tool": None,
            "instructions_target": None, "instructions_versions": None, "instructions_skipped": reason}


def nothing_counted(rows: Iterable[dict[str, Any]]) -> str | None:
    """Why none of ``rows`` (asked to be counted) has a count, in one line; None when one has."""
    rows = list(rows)
    if any(r.get("instructions") is not None for r in rows):
        return None
    reasons = sorted({r.get("instructions_skipped") or "no reason given" for r in rows})
    more = f" (and {len(reasons) - 1} other reason(s))" if len(reasons) > 1 else ""
    return f"--cost instructions: no row was counted: {reasons[0] if reasons else 'no row'}{more}"


def not_isolated(scheme: str) -> str | None:
    """Why the integration of ``scheme`` cannot be counted apart (None when it can)."""
    try:
        cls = registry.integrator_class(scheme)
    except Exception as exc:  # an unknown name: the cell's own row says so
        return f"scheme not found: {exc}"
    if cls._integrate not in _COUNTED_DRIVERS:
        return (f"{scheme} integrates outside longtime's compiled drivers (its own driver, or a library such as "
                f"scipy, REBOUND or heyoka): its integration cannot be counted apart from the Python around it")
    return None


def _budget(row: dict[str, Any]) -> float:
    """Seconds the cell's integration may take under Callgrind: its timed run's wall time
    times instructions.SLOWDOWN."""
    wall = row.get("wall_s") or row.get("cpu_s") or 0.0
    return float(wall) * instructions.SLOWDOWN


def instruction_fields(pairs: Iterable[tuple[Cell, dict[str, Any]]], max_samples: int,
                       time_limit: float | None) -> dict[str, dict[str, Any]]:
    """The instruction fields of each (cell, its timed row), by cell key. A cell is counted
    when its timed run ended ``ok``, its scheme runs on the shared drivers, and its
    integration under Callgrind fits ``time_limit`` (estimated from the timed run); any
    other cell gets a reason in ``instructions_skipped``. Raises InputError without Valgrind."""
    valgrind = instructions.require()
    out: dict[str, dict[str, Any]] = {}
    todo: list[Cell] = []
    wanted: dict[str, dict[str, Any]] = {}
    for cell, row in pairs:
        status = row.get("status")
        reason = None
        if status != Status.OK:
            reason = f"the timed run's status is {status}: only a complete run is counted"
        else:
            reason = not_isolated(cell.integrator)
        if reason is None and time_limit and _budget(row) > time_limit:
            reason = (f"too long to count under Valgrind: about {_budget(row):.3g} s (the timed run's "
                      f"{row.get('wall_s') or row.get('cpu_s'):.3g} s x {instructions.SLOWDOWN:g}), over the cell "
                      f"time limit of {time_limit:g} s (--time-limit)")
        if reason is not None:
            out[cell.key] = skipped(reason)
        else:
            todo.append(cell)
            wanted[cell.key] = row
    if todo:
        out.update(_count(valgrind, todo, wanted, max_samples))
    return out


def _count(valgrind: str, cells: list[Cell], rows: dict[str, dict], max_samples: int) -> dict[str, dict]:
    """Count ``cells`` in one Valgrind process; a cell it did not finish gets a reason."""
    folder = tempdirs.make("valgrind")
    try:
        # PYTHONHASHSEED: the same dict layouts in every run, the same dispatch path; PYTHONMALLOC:
        # Python's objects from the C allocator, whose per-size caches give the objects of a
        # counted call's dispatch the same path whatever was allocated before (Python's own
        # allocator takes a longer path where a block empties or starts a pool)
        env = {**instructions.counting_environment(), "LONGTIME_PROGRESS": "0", "PYTHONHASHSEED": "0",
               "PYTHONMALLOC": "malloc"}
        prepared = _prepare(env, folder, cells, rows, max_samples)
        if prepared:
            cells = [c for c in cells if c.key not in prepared]
            if not cells:
                return prepared
        children.write_job(folder, "count", cells, RunSpec(max_samples, time_limit=None))
        limit = STARTUP_SECONDS + sum(PER_CELL_SECONDS + _budget(rows[c.key]) for c in cells)
        prefix = folder / "callgrind.out"
        # no gdb server: a killed Valgrind leaves no vgdb-pipe files in the temp folder
        child = children.start(folder, prefix=[*instructions.command(valgrind, prefix), "--vgdb=no"], env=env)
        started = time.monotonic()
        try:
            if child.wait(limit):
                code = child.proc.returncode
                trouble = "" if code == 0 else instructions.failure_text(code, _last_line(child.stderr()))
            else:
                trouble = f"the Valgrind process was stopped after {time.monotonic() - started:.0f} s (its limit)"
        finally:
            child.kill()  # an interruption here: no Valgrind counts on
        counts = instructions.read_dumps(prefix)
        done = child.records()
        # the kernels counted are compiled for the fixed target, and counted as COUNT_METHOD says:
        # another target's or another way's count is another tool's
        tool = (f"{instructions.tool_version()}, counting {instructions.COUNT_METHOD} "
                f"({instructions.COUNT_TARGET} kernels)")
        out = dict(prepared)
        lost = next((i for i, c in enumerate(cells) if c.key not in done), None)
        if trouble and lost is not None and lost + 1 < len(cells):
            # Valgrind ended in cell ``lost``: the cells after it are counted again without it,
            # so one plugin's crash costs only its own row its count
            out.update(_count(valgrind, cells[lost + 1:], rows, max_samples))
        for i, cell in enumerate(cells):
            if cell.key in out:
                continue
            item, count = done.get(cell.key), counts.get(f"cell {i}")
            steps = rows[cell.key].get("steps")
            if item is None or (count is None and item.get("reason") is None):
                where = ", in this cell" if i == lost and trouble else ""
                out[cell.key] = skipped(f"not counted: {trouble or 'the Valgrind process gave no count for it'}{where}")
            elif item.get("reason"):
                out[cell.key] = skipped(item["reason"])
            elif item["steps"] != steps:
                out[cell.key] = skipped(f"the run under Valgrind took {item['steps']} steps, the timed run {steps}: "
                                        f"not the same integration")
            elif item.get("digest") != rows[cell.key].get("samples_digest"):
                out[cell.key] = skipped("the run under Valgrind did not reproduce the timed run bitwise (another "
                                        "samples_digest): not the same integration")
            else:
                out[cell.key] = {"instructions": count,
                                 "instructions_per_step": count / steps if steps else None,
                                 "instructions_tool": tool, "instructions_target": instructions.COUNT_TARGET,
                                 "instructions_versions": instructions.count_versions(), "instructions_skipped": None}
        return out
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def _prepare(env: dict[str, str], folder: Path, cells: list[Cell], rows: dict[str, dict],
             max_samples: int) -> dict[str, dict]:
    """Run ``cells`` once outside Valgrind with the counting environment: their kernels,
    compiled for the fixed target, land in its cache, where the Valgrind process loads them
    (compiling them under Valgrind would take minutes each). Returns the skipped fields of
    the cells that cannot be counted (every cell when this process fails)."""
    limit = STARTUP_SECONDS + sum(PER_CELL_SECONDS + 2 * _budget(rows[c.key]) / instructions.SLOWDOWN for c in cells)
    what = f"compiling the kernels for {instructions.COUNT_TARGET} (outside Valgrind)"
    (folder / jobfiles.RECORDS).unlink(missing_ok=True)
    children.write_job(folder, "count", cells, RunSpec(max_samples, time_limit=None), prepare=True)
    child = children.start(folder, env=env)
    try:
        if not child.wait(limit):
            trouble = f"{what} was stopped after {limit:.0f} s (its limit)"
        elif child.proc.returncode == -signal.SIGILL:  # natively: this CPU lacks an instruction of the target
            trouble = (f"{what}: its process was killed by SIGILL: this CPU cannot run {instructions.COUNT_TARGET} "
                       f"code (AVX2, FMA, BMI2): counting needs an x86-64 CPU of Haswell's generation or newer")
        else:
            code = child.proc.returncode
            trouble = "" if code == 0 else \
                f"{what}: {instructions.failure_text(code, _last_line(child.stderr()), 'its process')}"
    finally:
        child.kill()
    done = child.records()
    (folder / jobfiles.RECORDS).unlink(missing_ok=True)
    out = {}
    lost = next((i for i, c in enumerate(cells) if c.key not in done), None)
    if trouble and lost is not None and lost + 1 < len(cells):
        # the process ended in cell ``lost``: the cells after it are prepared again without it,
        # so one plugin's crash costs only its own row its count
        out.update(_prepare(env, folder, cells[lost + 1:], rows, max_samples))
        cells = cells[:lost + 1]  # the rest has its answer from the second process
    for i, cell in enumerate(cells):
        item = done.get(cell.key)
        if item is None:
            where = ", in this cell" if i == lost and trouble else ""
            out[cell.key] = skipped(f"not counted: {trouble or what + ' gave nothing for it'}{where}")
        elif item.get("reason"):
            out[cell.key] = skipped(item["reason"])
    return out


_VALGRIND_PREFIX = re.compile(r"^==\d+==\s*")
# Valgrind's own lines that say why the process it ran ended
_VALGRIND_REASONS = ("unhandled instruction bytes", "Illegal opcode", "Process terminating")


def _last_line(text: str) -> str:
    """What the counting process said last on stderr: Valgrind's line on why the process
    ended where there is one (an instruction it cannot decode, an illegal opcode), else
    the last line that is not Valgrind's own."""
    lines = [ln.strip() for ln in (text or "").splitlines() if ln.strip()]
    for reason in _VALGRIND_REASONS:
        found = [ln for ln in lines if reason in ln]
        if found:
            return _VALGRIND_PREFIX.sub("", found[-1])
    own = [ln for ln in lines if not ln.startswith("==")]
    return own[-1] if own else ""


# ------------------------------------------------------------------ the worker, under Valgrind
def _counted_loops(integrator) -> None:
    """Make ``integrator`` count its calls into the compiled loop: the first call of a run
    (the drivers' warm-up on a throw-away state: it loads the kernel) is not counted, every
    later one is. The warm-up runs the counted path itself WARM_CALLS times, uncounted, so
    that a count finds the dispatch into the loop as the same cell in any batch finds it
    (its caches filled, whichever cells ran before)."""
    build_loop = integrator.compiled_loop

    def compiled_loop(problem):
        loop = build_loop(problem)
        calls = [0]

        def call(*args):
            calls[0] += 1
            if calls[0] == 1:
                for _ in range(WARM_CALLS):
                    result = instructions.counted_call(loop, args)
                instructions.begin_cell()
                return result
            return instructions.counted_call(loop, args)

        return call

    integrator.compiled_loop = compiled_loop


def _run_one(cell: Cell, max_samples: int, where: str) -> dict[str, Any]:
    """Run ``cell`` as the count runs it; ``where`` names the run in a reason."""
    problem, integrator = build(cell)
    reason = integrator.incompatibility(problem)
    if reason:
        return {"reason": reason}
    _counted_loops(integrator)
    t_final = problem.default_t_final if cell.t_final is None else cell.t_final
    traj = integrator.integrate(problem, t_final, max_samples=max_samples)
    if traj.status != Status.OK:
        return {"reason": f"the run {where} ended {traj.status}: {traj.message}"}
    return {"steps": traj.steps, "digest": traj.extra.get("samples_digest")}


def run_job(folder: str, job: children.Job) -> None:
    """The child's side of a ``count`` job (longtime.execution.child.KINDS): count its cells
    (under Valgrind); for a job with ``prepare``, run them once outside it to compile and
    cache their kernels."""
    from longtime.core import stepping

    preparing = bool(job.options.get("prepare"))
    where = f"compiled for {instructions.COUNT_TARGET}" if preparing else "under Valgrind"
    children.enter(folder, job)
    # one call into the compiled loop per run: the chunks that let a timed run see its
    # deadline would each add a call's dispatch to the count, and their number follows the
    # wall clock
    stepping.FIRST_CHUNK = 2**62
    if not preparing:
        instructions.running()  # the request function is compiled before any cell
    for i, cell in enumerate(job.cells):
        try:
            item = _run_one(cell, job.spec.max_samples, where)
        except Exception as exc:  # a cell that fails here has no count, the others go on
            item = {"reason": f"the run {where} failed: {type(exc).__name__}: {exc}"}
        if not preparing:
            instructions.dump(f"cell {i}")  # the count since the warm-up (zero for a failed cell)
        else:
            instructions.end_cell()
        children.add_record(folder, cell.key, item)
