"""asv (airspeed velocity) benchmarks of a selection, for a scheme author's repository.

In the repository's ``benchmarks/`` (``longtime asv-init DIR`` writes one), a module holds

    from longtime.asvbench import benchmarks
    globals().update(benchmarks(["kepler"], ["my-scheme"], dt=[0.01, 0.005]))

and asv finds two parametrized classes (problem x scheme x setting, every parameter
a value or a list, as ``longtime.sweep`` takes them):

- ``Integration.time_integrate``: the integration alone (its kernel compiled in setup);
- ``Accuracy.track_l2_error`` (relative L2 error against the exact solution or the
  trusted reference), ``track_drift`` (the first invariant's maximum relative error,
  ``NAME.max``) and ``track_growth`` (its growth exponent alpha, e(t) ~ t^alpha), each
  with its unit, from one untimed run of every cell (``setup_cache``).

A pair that cannot run is skipped (asv shows n/a), as a failed or diverged cell's
accuracy is. Problems and schemes are registered names, or classes (registered for the
session in every asv process that imports the module).
"""
from __future__ import annotations

import itertools
import math
from typing import Any, Sequence

ALL = "default"  # the label of the setting when no parameter is given


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


def benchmarks(problems: Sequence[Any], schemes: Sequence[Any], *, t_final: float | None = None,
               prefix: str = "", **settings: Any) -> dict[str, type]:
    """{class name: asv benchmark class} for problems x schemes x settings; put them into
    the benchmark module's namespace (``globals().update(...)``): asv looks a class up by
    its name there."""
    from longtime.api import resolve
    from longtime.core.params import check_values

    pnames = [resolve(p, "problem")[0] for p in check_values("problems", problems)]
    inames = [resolve(s, "scheme")[0] for s in check_values("schemes", schemes)]
    combos = _combinations(settings)
    points = dict(combos)
    params = [pnames, inames, [label for label, _ in combos]]
    names = ["problem", "scheme", "setting"]

    def setup(self, problem, scheme, setting):
        from longtime.execution.cells import build

        cell = _cell(problem, scheme, points[setting], t_final)
        self.problem, self.integrator = build(cell)
        self.t_final = self.problem.default_t_final if cell.t_final is None else cell.t_final
        # compiled here, not in the timing: ten default steps (the loop is the same for any span)
        self.integrator.integrate(self.problem, self.problem.t0 + 10 * float(self.problem.default_dt), max_samples=16)

    def time_integrate(self, problem, scheme, setting):
        self.integrator.integrate(self.problem, self.t_final)

    integration = type(f"{prefix}Integration", (), {
        "params": params, "param_names": names, "setup": setup, "time_integrate": time_integrate,
        "__doc__": "The integration of each cell alone (its kernel compiled in setup)."})

    def setup_cache(self):
        from longtime.core.integrator import Timing
        from longtime.execution.cells import run_cell
        from longtime.testing import accuracy_fields

        rows = {}
        for p, s, (label, point) in itertools.product(pnames, inames, combos):
            try:
                cell = _cell(p, s, point, t_final)
            except NotImplementedError:
                continue
            row = run_cell(cell, timing=Timing(repeats=1))
            rows[f"{p}|{s}|{label}"] = {**accuracy_fields(row), "invariant": _first_invariant(row),
                                        "message": row.get("message")}
        return rows

    def acc_setup(self, rows, problem, scheme, setting):
        if f"{problem}|{scheme}|{setting}" not in rows:
            raise NotImplementedError(f"{scheme} cannot run {problem}")

    def field(rows, problem, scheme, setting, name):
        row = rows[f"{problem}|{scheme}|{setting}"]
        if row.get("status") != "ok" or name is None or row.get(name) is None:
            return math.nan  # shown as n/a: a failed or diverged run has nothing to track
        return float(row[name])

    def track_l2_error(self, rows, problem, scheme, setting):
        return field(rows, problem, scheme, setting, "l2_error")

    def track_drift(self, rows, problem, scheme, setting):
        inv = rows[f"{problem}|{scheme}|{setting}"].get("invariant")
        return field(rows, problem, scheme, setting, inv and f"{inv}.max")

    def track_growth(self, rows, problem, scheme, setting):
        inv = rows[f"{problem}|{scheme}|{setting}"].get("invariant")
        return field(rows, problem, scheme, setting, inv and f"{inv}.growth")

    track_l2_error.unit = "relative error"
    track_drift.unit = "relative error"
    track_growth.unit = "exponent alpha"
    track_l2_error.__doc__ = "Relative L2 error against the exact solution or the trusted reference."
    track_drift.__doc__ = "max_t |I(t) - I(0)| / |I(0)| of the problem's first invariant (H where there is one)."
    track_growth.__doc__ = "alpha of e_I(t) ~ C t^alpha, fitted over the last two decades of the run."
    accuracy = type(f"{prefix}Accuracy", (), {
        "params": params, "param_names": names, "setup_cache": setup_cache, "setup": acc_setup,
        "track_l2_error": track_l2_error, "track_drift": track_drift, "track_growth": track_growth,
        "timeout": 900, "__doc__": "Accuracy of each cell, from one untimed run."})
    return {integration.__name__: integration, accuracy.__name__: accuracy}
