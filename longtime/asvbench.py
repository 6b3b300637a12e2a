"""asv (airspeed velocity) benchmarks of a selection, for a scheme author's repository.

In the repository's ``benchmarks/`` (``longtime asv-init DIR`` writes one), a module holds

    from longtime.asvbench import benchmarks
    globals().update(benchmarks(["kepler"], ["my-scheme"], dt=[0.01, 0.005]))

and asv finds four parametrized classes (problem x scheme x setting, every parameter
a value or a list, as ``longtime.sweep`` takes them):

- ``Integration.time_integrate``: the whole call ``integrator.integrate(problem, t_final)``
  (its kernel compiled in setup): the compiled step loop and the Python work around it
  (the output arrays, a one-step warm-up call, the first invariant's growth judged over the
  samples, the samples' digest), timed by asv in ``processes`` separate processes (``DEFAULT_PROCESSES``, asv's own
  benchmark attribute: its samples pool every process's, so the spread asv judges a change
  against is the spread between processes, as longtime's verdicts are), in CPU time of
  the process (``timer = time.process_time``, as longtime's ``cpu_s``): asv's default
  clock is the wall clock, which counts the time a neighbour holds the core;
- ``Integration.track_cpu_s``: the same integration's CPU seconds as longtime's timing
  processes take them (a row's ``cpu_s``): the compiled step loop alone, without the
  Python work around it, the minimum of its runs spread over a few seconds in rounds
  (longtime.execution.processes.time_cells). The two differ by that work, which grows with
  the samples (a few thousand samples cost a few hundred microseconds), and by asv's median
  against this minimum: for a run of under a millisecond (verlet on kepler's default span:
  about 0.3 ms of loop, 6285 samples) ``time_integrate`` is two to ten times
  ``track_cpu_s``, the more the busier the machine; for a run of a second they meet within
  the samples' share. asv's samples of ``time_integrate`` are bursts
  whose median a slow moment of the machine (it comes and goes within a second or two on a
  shared virtual machine) can move by more than a slowdown; this minimum holds within a
  few percent across invocations (docs/performance.md, "Two speeds");
- ``Speed.track_cpu_ratio``: the integration's CPU time in units of the calibration's
  reference workload (longtime.execution.calibration), the two timed in pairs (one run of
  the integration, then one of the reference) over ``SPREAD_S`` seconds in each of
  ``DEFAULT_PROCESSES`` fresh processes (``setup_cache``): each process's ratio of the
  minima, the smallest over the processes (longtime.execution.processes.paired_ratio).
  Judge a change of speed by this one: asv compares two commits' values by a fixed factor
  (1.1) from runs minutes apart, and the load and the core's speed change between them;
  the reference timed beside the integration divides them out, and a slow moment of the
  machine must cover every process's seconds to move the minimum (docs/performance.md,
  "A time asv can judge"). ``time_integrate`` and ``track_cpu_s`` stay, in seconds, for
  the size of a change and for the history asv already holds;
- ``Cost.track_instructions``: the instructions of the integration alone, counted under
  Valgrind (``--cost instructions``; all cells in one Valgrind process, in
  ``setup_cache``). The count is deterministic: a ratio between two commits is the code's,
  on a loaded machine too, where ``time_integrate`` may move by more than a slowdown.
  Without Valgrind (Debian package ``valgrind``) the cells are skipped (n/a);
- ``Accuracy.track_l2_error`` (relative L2 error against the exact solution or the
  trusted reference), ``track_drift`` (the first invariant's maximum relative error,
  ``NAME.max``) and ``track_growth_class`` (its growth class as a number, ``GROWTH_RANKS``:
  1 bounded, 2 sqrt, 3 linear, 4 quadratic, 5 faster, 6 saturated, 7 diverged), each with
  its unit, from one untimed run of every cell (``setup_cache``).

asv judges a tracked value by the ratio of two commits' values, so each tracked value is
one a ratio can judge: an error (a digit lost is x10), a count, a class rank (bounded to
linear is x3). The growth exponent itself is not tracked: two bounded runs have exponents
near 0 (1e-6 and 8e-5), whose ratio (x80) says nothing.

A pair that cannot run is skipped (asv shows n/a), as a failed or diverged cell's
accuracy is. Problems and schemes are registered names, or classes (registered for the
session in every asv process that imports the module).
"""
from __future__ import annotations

import itertools
import math
import time
from dataclasses import dataclass
from typing import Any, ClassVar, Sequence

from longtime.core.status import Status

ALL = "default"  # the label of the setting when no parameter is given
# a growth class as a number for asv (worse is larger); undetermined is not tracked (n/a)
GROWTH_RANKS = {"bounded": 1, "sqrt": 2, "linear": 3, "quadratic": 4, "faster": 5, "saturated": 6, "diverged": 7}


def _combinations(settings: dict[str, Any]) -> list[tuple[str, dict[str, Any]]]:
    keys = sorted(settings)
    values = [list(v) if isinstance(v, (list, tuple)) else [v] for v in (settings[k] for k in keys)]
    out = []
    for combo in itertools.product(*values):
        point = dict(zip(keys, combo))
        out.append((" ".join(f"{k}={v}" for k, v in point.items()) or ALL, point))
    return out


def _cell(problem: str, scheme: str, point: dict[str, Any], t_final):
    from longtime.api import cells_for

    cells = cells_for([problem], [scheme], t_final, point)
    if len(cells) != 1:
        raise NotImplementedError(f"{problem} x {scheme} with {point}: {len(cells)} cells")
    if cells[0].skip_reason:
        raise NotImplementedError(cells[0].skip_reason)
    return cells[0]


def _first_invariant(row: dict[str, Any]) -> str | None:
    curve = row.get("drift_curve")
    return curve.get("invariant") if isinstance(curve, dict) else None


@dataclass(frozen=True)
class Selection:
    """The cells of a suite: registered problem and scheme names, the settings as (label,
    point) pairs, the final time (None: each problem's default)."""

    problems: tuple[str, ...]
    schemes: tuple[str, ...]
    combos: tuple[tuple[str, dict[str, Any]], ...]
    t_final: float | None = None

    @property
    def params(self) -> list[list[str]]:
        """asv's parameters: problems, schemes, setting labels."""
        return [list(self.problems), list(self.schemes), [label for label, _ in self.combos]]

    def cell(self, problem: str, scheme: str, setting: str):
        """The cell of one parameter combination (NotImplementedError, asv's skip, where the
        scheme cannot run the problem)."""
        return _cell(problem, scheme, dict(self.combos)[setting], self.t_final)

    def runnable(self):
        """(cell, "problem|scheme|setting") of each parameter combination a scheme can run."""
        for p, s, (label, point) in itertools.product(self.problems, self.schemes, self.combos):
            try:
                cell = _cell(p, s, point, self.t_final)
            except NotImplementedError:
                continue
            yield cell, f"{p}|{s}|{label}"


class _Suite:
    """What the four benchmark classes share: the selection ``benchmarks`` binds and asv's
    parameters over it."""

    selection: ClassVar[Selection]
    params: ClassVar[list[list[str]]]
    param_names = ["problem", "scheme", "setting"]


class Integration(_Suite):
    """The integration of each cell alone (its kernel compiled in setup)."""

    timer = time.process_time

    def setup(self, problem, scheme, setting):
        from longtime.execution.cells import build

        cell = self.selection.cell(problem, scheme, setting)
        self.problem, self.integrator = build(cell)
        self.t_final = self.problem.default_t_final if cell.t_final is None else cell.t_final
        # compiled here, not in the timing: ten default steps (the loop is the same for any span)
        self.integrator.integrate(self.problem, self.problem.t0 + 10 * float(self.problem.default_dt), max_samples=16)

    def time_integrate(self, problem, scheme, setting):
        """CPU seconds of the whole call integrator.integrate(problem, t_final): the compiled step loop and the
        Python work on its samples (output arrays, the invariant's growth, the samples' digest), the median of
        asv's samples. track_cpu_s is the loop alone, the minimum of runs spread over seconds: for a run of a
        millisecond the Python work and the machine's load make this one several times that one."""
        self.integrator.integrate(self.problem, self.t_final)

    def track_cpu_s(self, problem, scheme, setting):
        """CPU seconds of the integration's compiled step loop alone (a row's cpu_s): the minimum of its runs
        spread over longtime's SPREAD_S seconds (longtime.execution.processes.time_cells), so that a slow
        moment of the machine does not make the figure. time_integrate adds the Python work on the samples and
        takes asv's median: on a short run it is several times this one."""
        from longtime.core.timing import Timing
        from longtime.execution.processes import time_cells

        cell = self.selection.cell(problem, scheme, setting)
        record = time_cells([cell], 100_001, Timing(repeats=3))[0]
        return float(record["cpu_s"]) if record.get("status") == Status.OK else math.nan

    track_cpu_s.unit = "seconds"


class Accuracy(_Suite):
    """Accuracy of each cell, from one untimed run."""

    timeout = 900

    def setup_cache(self):
        from longtime.core.timing import Timing
        from longtime.execution.cells import run_cell
        from longtime.testing import accuracy_fields

        rows = {}
        for cell, label in self.selection.runnable():
            row = run_cell(cell, timing=Timing(repeats=1))
            rows[label] = {**accuracy_fields(row), "invariant": _first_invariant(row), "message": row.get("message")}
        return rows

    def setup(self, rows, problem, scheme, setting):
        if f"{problem}|{scheme}|{setting}" not in rows:
            raise NotImplementedError(f"{scheme} cannot run {problem}")

    @staticmethod
    def _field(rows, problem, scheme, setting, name):
        row = rows[f"{problem}|{scheme}|{setting}"]
        if row.get("status") != Status.OK or name is None or row.get(name) is None:
            return math.nan  # shown as n/a: a failed or diverged run has nothing to track
        return float(row[name])

    def track_l2_error(self, rows, problem, scheme, setting):
        """Relative L2 error against the exact solution or the trusted reference."""
        return self._field(rows, problem, scheme, setting, "l2_error")

    def track_drift(self, rows, problem, scheme, setting):
        """max_t |I(t) - I(0)| / |I(0)| of the problem's first invariant (H where there is one)."""
        inv = rows[f"{problem}|{scheme}|{setting}"].get("invariant")
        return self._field(rows, problem, scheme, setting, inv and f"{inv}.max")

    def track_growth_class(self, rows, problem, scheme, setting):
        """The growth class of the first invariant's error, e_I(t) ~ C t^alpha, as a number (1 bounded, 2 sqrt,
        3 linear, 4 quadratic, 5 faster, 6 saturated, 7 diverged; undetermined: n/a)."""
        row = rows[f"{problem}|{scheme}|{setting}"]
        inv = row.get("invariant")
        if row.get("status") != Status.OK or inv is None:
            return math.nan
        return float(GROWTH_RANKS.get(row.get(f"{inv}.growth_class"), math.nan))

    track_l2_error.unit = "relative error"
    track_drift.unit = "relative error"
    track_growth_class.unit = "growth class (1 bounded .. 7 diverged)"


class Cost(_Suite):
    """Instructions of each cell's integration, all cells counted in one Valgrind process."""

    timeout = 3600

    def setup_cache(self):
        from longtime.core.params import InputError
        from longtime.core.timing import Timing
        from longtime.execution.cells import DEFAULT_MAX_SAMPLES, run_cell
        from longtime.execution.valgrind import instruction_fields

        pairs, labels = [], {}
        for cell, label in self.selection.runnable():
            pairs.append((cell, run_cell(cell, timing=Timing(repeats=1))))  # fills the kernel cache
            labels[cell.key] = label
        try:
            fields = instruction_fields(pairs, DEFAULT_MAX_SAMPLES, None)
        except InputError as exc:  # no Valgrind: every cell is skipped, saying why
            return {labels[c.key]: {"instructions": None, "instructions_skipped": str(exc)} for c, _ in pairs}
        return {labels[c.key]: fields[c.key] for c, _ in pairs}

    def setup(self, counts, problem, scheme, setting):
        found = counts.get(f"{problem}|{scheme}|{setting}")
        if found is None:
            raise NotImplementedError(f"{scheme} cannot run {problem}")
        if found.get("instructions") is None:
            raise NotImplementedError(found.get("instructions_skipped") or "not counted")

    def track_instructions(self, counts, problem, scheme, setting):
        """Instructions of the integration alone, counted by Valgrind's Callgrind with the kernels compiled for
        one fixed target (x86-64-v3, docs/machines.md) whatever the host: the same code gives the same count on
        a loaded machine and on another x86-64 machine with the same Python, numba, llvmlite and numpy."""
        return counts[f"{problem}|{scheme}|{setting}"]["instructions"]

    track_instructions.unit = "instructions"


class Speed(_Suite):
    """The integration's CPU time against a reference workload timed beside it, in fresh processes."""

    timeout = 1800

    def setup_cache(self):
        from longtime.core.timing import Timing
        from longtime.execution.cells import DEFAULT_MAX_SAMPLES
        from longtime.execution.child import RunSpec
        from longtime.execution.processes import DEFAULT_PROCESSES, SPREAD_S, START_S, run_children

        cells, labels = [], []
        for cell, label in self.selection.runnable():
            cells.append(cell)
            labels.append(label)
        spec = RunSpec(DEFAULT_MAX_SAMPLES, Timing(repeats=3), time_limit=None)
        results = run_children(cells, DEFAULT_PROCESSES, spec, 1, START_S + 60 * SPREAD_S, paired=True)
        out = {}
        for k, label in enumerate(labels):
            records = [res[k] for res, _ in results if res is not None and res[k].get("status") == Status.OK]
            ratios = [r["cpu_ratio"] for r in records if not math.isnan(r.get("cpu_ratio", math.nan))]
            why = "; ".join(err or res[k].get("message") or res[k].get("status") for res, err in results
                            if res is None or res[k].get("status") != Status.OK)
            # each process's ratio is kept beside the track (the smallest) for a reader of the cache
            out[label] = {"cpu_ratio": min(ratios) if ratios else None, "processes": ratios, "why": why}
        return out

    def setup(self, ratios, problem, scheme, setting):
        found = ratios.get(f"{problem}|{scheme}|{setting}")
        if found is None:
            raise NotImplementedError(f"{scheme} cannot run {problem}")
        if found["cpu_ratio"] is None:
            raise NotImplementedError(found["why"] or "not timed")

    def track_cpu_ratio(self, ratios, problem, scheme, setting):
        """CPU time of the integration in units of the calibration's reference workload, timed in pairs (one run
        of the integration, then one of the reference) over longtime's SPREAD_S seconds in each of
        DEFAULT_PROCESSES fresh processes: each process's ratio of the minima, the smallest over the processes
        (longtime.execution.processes.paired_ratio). The time to judge a change of speed by: the load and the
        core's speed between two commits' runs divide out, and a slow moment of the machine has to cover every
        process's seconds to move it."""
        return ratios[f"{problem}|{scheme}|{setting}"]["cpu_ratio"]

    track_cpu_ratio.unit = "x reference"


SUITES = (Integration, Accuracy, Cost, Speed)


def benchmarks(problems: Sequence[Any], schemes: Sequence[Any], *, t_final: float | None = None,
               prefix: str = "", **settings: Any) -> dict[str, type]:
    """{class name: asv benchmark class} for problems x schemes x settings; put them into
    the benchmark module's namespace (``globals().update(...)``): asv looks a class up by
    its name there. Each class is a subclass of ``Integration``, ``Accuracy``, ``Cost`` or
    ``Speed`` named ``prefix`` + its name, bound to the selection."""
    from longtime.api import resolve
    from longtime.core.params import check_values
    from longtime.execution.processes import DEFAULT_PROCESSES

    selection = Selection(problems=tuple(resolve(p, "problem")[0] for p in check_values("problems", problems)),
                          schemes=tuple(resolve(s, "scheme")[0] for s in check_values("schemes", schemes)),
                          combos=tuple(_combinations(settings)), t_final=t_final)
    out = {}
    for suite in SUITES:
        bound = {"selection": selection, "params": selection.params, "__doc__": suite.__doc__}
        if suite is Integration:
            # asv's own attribute: its samples pool every process's (longtime's timing processes likewise)
            bound["processes"] = DEFAULT_PROCESSES
        out[f"{prefix}{suite.__name__}"] = type(f"{prefix}{suite.__name__}", (suite,), bound)
    return out
