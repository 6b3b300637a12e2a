"""What every asv benchmark family shares: parameters read from the registries, one short
run per problem x scheme, and skips (NotImplementedError) for pairs that cannot run.

Parameters are plain strings (asv stores them as text). A family names the problems it
benchmarks and a filter over the registered schemes, so a scheme or problem that lands
later joins its family without an edit here; a name not registered in the checked-out
version of longtime is left out (asv also runs these benchmarks on old commits).
"""
from __future__ import annotations

import math
from typing import Callable

# one benchmark run: this many steps of the problem's default dt (or that span for
# adaptive schemes), capped by the problem's default final time; short enough that
# `asv run --quick` over every family stays within a few minutes
BENCH_STEPS = 5000

try:  # an old commit may predate the registry: then every family is empty
    from longtime.core import registry
except Exception:  # pragma: no cover - depends on the checked-out history
    registry = None


def scheme_names(accept: Callable[[type], bool]) -> list[str]:
    if registry is None:
        return ["none"]
    names = [n for n, cls in sorted(registry.integrators().items()) if accept(cls)]
    return names or ["none"]


def problem_names(wanted: tuple[str, ...]) -> list[str]:
    if registry is None:
        return ["none"]
    found = registry.problems()
    names = [n for n in wanted if n in found]
    return names or ["none"]


def needs(cls: type) -> frozenset:
    return frozenset(getattr(cls, "requires", ()))


def bench_t_final(problem) -> float:
    span = BENCH_STEPS * float(problem.default_dt)
    return problem.t0 + min(span, float(problem.default_t_final) - problem.t0)


def make_pair(problem_name: str, scheme_name: str):
    """(problem, integrator, t_final) of the benchmark run; NotImplementedError skips."""
    if registry is None or "none" in (problem_name, scheme_name):
        raise NotImplementedError("nothing registered under these names in this version")
    try:
        problem = registry.problem_class(problem_name)()
        integrator = registry.integrator_class(scheme_name)()
    except Exception as exc:  # broken plugin in this version
        raise NotImplementedError(f"cannot load {problem_name} x {scheme_name}: {exc}") from None
    reason = integrator.incompatibility(problem)
    if reason:
        raise NotImplementedError(reason)
    return problem, integrator, bench_t_final(problem)


def warm_up(problem, integrator) -> None:
    """Compile the scheme's kernel for this problem (one short integration)."""
    span = 10 * float(problem.default_dt)
    integrator.integrate(problem, problem.t0 + span, max_samples=16)


def rows_of_pairs(problems: list[str], schemes: list[str]) -> dict[str, dict]:
    """Metric rows of every compatible pair (for track_ benchmarks; skipped pairs left out),
    run through the suite's own matrix runner on local worker processes."""
    from longtime.execution.cells import Cell
    from longtime.execution.matrix import ExecOptions, run_matrix

    cells = []
    for p in problems:
        for s in schemes:
            try:
                _, _, t_final = make_pair(p, s)
            except NotImplementedError:
                continue
            cells.append(Cell(p, s, {}, {}, t_final))
    rows = run_matrix(cells, None, None, "process", ExecOptions(max_samples=20_001))
    return {f"{r['problem']}|{r['integrator']}": r for r in rows}


def tracked(rows: dict[str, dict], problem: str, scheme: str, field: str) -> float:
    row = rows.get(f"{problem}|{scheme}")
    if row is None:
        raise NotImplementedError(f"{scheme} cannot run {problem}")
    value = row.get(field)
    if row.get("status") != "ok" or value is None:
        return math.nan  # shown as n/a: a failed or diverged run has no drift to track
    return float(value)


class _PairSetup:
    """``params = [problems, schemes]`` (strings); setup builds the pair and compiles it."""

    param_names = ["problem", "scheme"]
    params: list = [["none"], ["none"]]

    def setup(self, problem, scheme):
        self.problem, self.integrator, self.t_final = make_pair(problem, scheme)
        warm_up(self.problem, self.integrator)  # compiled here, not in the timing


class _PairFamily(_PairSetup):
    """Base of a family's time_ benchmarks: the integration alone."""

    def time_integrate(self, problem, scheme):
        self.integrator.integrate(self.problem, self.t_final)


class _PairMemory(_PairSetup):
    """Base of peakmem_ benchmarks (a few pairs: memory hardly depends on the scheme)."""

    def peakmem_integrate(self, problem, scheme):
        self.integrator.integrate(self.problem, self.t_final)


class _PairAccuracy:
    """Base of a family's track_ benchmarks: the metrics of one run of every pair, computed
    once (setup_cache) and read per parameter."""

    param_names = ["problem", "scheme"]
    params: list = [["none"], ["none"]]
    timeout = 900

    def rows(self):
        """Every pair's row; each subclass calls this from its own ``setup_cache``."""
        return rows_of_pairs(*self.params)

    def setup(self, rows, problem, scheme):
        if f"{problem}|{scheme}" not in rows:
            raise NotImplementedError(f"{scheme} cannot run {problem}")

    def track_energy_drift(self, rows, problem, scheme):
        """max_t |H(t) - H(0)| / |H(0)| over the benchmark run."""
        return tracked(rows, problem, scheme, "H.max")

    track_energy_drift.unit = "relative error"

    def track_energy_mean(self, rows, problem, scheme):
        """E_mean of the energy error (time average) over the benchmark run."""
        return tracked(rows, problem, scheme, "H.mean")

    track_energy_mean.unit = "relative error"

    def track_l2_error(self, rows, problem, scheme):
        """Relative L2 error against the exact solution or the heyoka reference."""
        return tracked(rows, problem, scheme, "l2_error")

    track_l2_error.unit = "relative error"

    def track_cpu(self, rows, problem, scheme):
        """CPU seconds of the integration alone, as the suite measures it."""
        return tracked(rows, problem, scheme, "cpu_s")

    track_cpu.unit = "seconds"
