"""``longtime history``: every cell's calibrated time and errors over every stored run, with
the commit and date of each run, and the steps in each series.

A cell is identified as ``longtime compare`` matches cells (problem, scheme, t_final, every
setting). Its series are ``cpu_s_calibrated`` (the CPU time in units of the machine's
reference workload, longtime.execution.calibration) and every error and drift field (``l2_error``,
``final_error``, ``NAME.max``, ...). Steps are found with asv's step detection
(``asv.step_detect.detect_steps``: a piecewise-constant fit, the Potts model asv uses for
its regression reports), then read as a benchmark suite reads them:

- neighbouring pieces closer than the factor are one level. For time the factor is the
  series' spread between processes (the median over its runs of ``cpu_s_process_spread``:
  how far one cell's time moves from one process to the next, longtime.execution.processes)
  and at least ``compare_cells.TIME_FACTOR``; where a run was timed in its own process only
  (its ``timed_in``: the main job's timing by need left it out of the fresh processes, or
  ``--processes 1``), at least ``compare_cells.CELL_FACTOR``, as compare judges such a cell;
  older runs stored without ``timed_in`` and no spread leave it at
  ``compare_cells.TIME_FACTOR``; the repeats within one process never set it. Errors:
  ``ERROR_FACTOR``;
- for time, a level held by fewer than ``MIN_RUNS`` runs between two levels that agree is a
  run's chance (one batch of cells keeps one speed in its process: README, "compare"),
  not a step, unless it is the latest run; errors are deterministic, so every level counts;
- a step is where one level ends and the next begins: the run (and commit) that first has
  the new level, its ratio to the level before, and whether that is slower / faster or
  less / more accurate. Errors at round-off (below ``compare_cells.ROUND_OFF`` on both sides)
  make no step.

Where runs calibrated with the streaming workload (longtime.execution.calibration), each
run's memory bandwidth (its streaming, the median over its calibrations) is set against the
cell's other runs of its machine
(``mark_bandwidth``): a run whose streaming differed beyond the time factor, either way, had
a neighbour that streamed memory (or lost one), and its time takes no part in the time
series' steps (the table says so); its errors and instruction count still do.

Each series is one entry of ``series_specs``: its field, how its factor is found and how
its steps are named. Where runs counted instructions (``--cost instructions``),
``instructions`` is a series too: deterministic, so every level counts, and neighbouring
levels within ``compare_cells.INSTRUCTION_FACTOR`` (more for a count so small that the counts'
noise passes it: longtime.measure.instructions.count_factor) are one level.
A store that holds runs of several machines (``longtime merge``) gives each run its
machine (``machine``: M1, M2, ..., longtime.reporting.machines); a time step is looked for
only between runs of one machine, an instruction step only between counts of one target,
Valgrind and versions; the table ends with the cross-machine table.
The header of a cell names every setting that tells two cells apart (``label``), t_final
included; each run shows the commit of longtime and of the code under test
(longtime.execution.provenance).
"""
from __future__ import annotations

import json
import math
from typing import Any

from longtime.core.roles import ROW_PARAMETERS
from longtime.core.rowschema import formatted
from longtime.core.status import Status
from longtime.execution.calibration import stream_median
from longtime.measure.instructions import count_factor
from longtime.reporting import machines
from longtime.reporting.compare import cross_machine_table
from longtime.reporting.compare_cells import (
    CELL_FACTOR,
    INSTRUCTION_FACTOR,
    MATCH_KEYS,
    ROUND_OFF,
    TIME_FACTOR,
    cell_key,
    error_fields,
    one_process,
)
from longtime.reporting.compare_text import label

TIME_FIELD = "cpu_s_calibrated"
SPREAD_FIELD = "cpu_s_process_spread"
INSTRUCTIONS_FIELD = "instructions"
ERROR_FACTOR = 2.0
MIN_RUNS = 2
# the error fields the table shows (every field is in --format json and has its steps found)
SHOWN_ERRORS = ("l2_error", "final_error", "H.max", "I.max", "constraint.max")


def levels(values: list[float | None], factor: float, min_runs: int) -> list[dict[str, Any]]:
    """The levels of a series (``None``: no value in that run): asv's pieces, neighbours
    within ``factor`` joined, short levels between two that agree dropped (see the module
    docstring). Each level: ``start`` and ``end`` (indices into ``values``), ``value`` (the
    median of its values)."""
    present = [v for v in values if v is not None and math.isfinite(v)]
    if not present:
        return []
    if len(set(present)) == 1:  # one value throughout (an error, bit for bit): one level
        pieces = [[0, len(values)]]
    else:  # asv is imported only here: a store of one run never needs it
        from asv.step_detect import detect_steps

        pieces = [[left, right] for left, right, *_ in detect_steps([v if v is not None and math.isfinite(v) else None
                                                       for v in values])]
    limit = math.log(factor)

    def value(piece: list[int]) -> float:
        vs = sorted(v for v in values[piece[0]:piece[1]] if v is not None and math.isfinite(v))
        return vs[len(vs) // 2] if len(vs) % 2 else math.sqrt(max(vs[len(vs) // 2 - 1] * vs[len(vs) // 2], 0.0))

    def size(piece: list[int]) -> int:
        return sum(v is not None for v in values[piece[0]:piece[1]])

    def close(x: float, y: float) -> bool:
        if x <= 0 or y <= 0:
            return x == y
        return abs(math.log(y / x)) <= limit

    changed = True
    while changed:
        changed = False
        for i in range(len(pieces) - 1):  # neighbours within the factor: one level
            if close(value(pieces[i]), value(pieces[i + 1])):
                pieces[i:i + 2] = [[pieces[i][0], pieces[i + 1][1]]]
                changed = True
                break
        if changed:
            continue
        for i in range(1, len(pieces) - 1):  # a short excursion between two agreeing levels
            if size(pieces[i]) < min_runs and close(value(pieces[i - 1]), value(pieces[i + 1])):
                pieces[i - 1:i + 2] = [[pieces[i - 1][0], pieces[i + 1][1]]]
                changed = True
                break
    return [{"start": left, "end": right, "value": value([left, right])} for left, right in pieces]


def steps(values: list[float | None], factor: float, min_runs: int, floor: float = 0.0) -> list[dict[str, Any]]:
    """Where the level of ``values`` changes: ``index`` (the first value of the new level),
    ``before``, ``after``, ``ratio``. Both levels at or below ``floor``: no step."""
    found = levels(values, factor, min_runs)
    out = []
    for a, b in zip(found, found[1:]):
        if a["value"] <= floor and b["value"] <= floor:
            continue
        ratio = b["value"] / a["value"] if a["value"] > 0 else math.inf
        start = next(i for i in range(b["start"], b["end"]) if values[i] is not None)
        out.append({"index": start, "before": a["value"], "after": b["value"], "ratio": ratio})
    return out


def selected(row: dict, problems, schemes, sets: dict[str, str]) -> bool:
    if problems and row.get("problem") not in problems:
        return False
    if schemes and row.get("integrator") not in schemes:
        return False
    if sets:
        settings = json.loads(row["settings"]) if row.get("settings") else {}
        for k, v in sets.items():
            have = row.get(k) if k in ROW_PARAMETERS else settings.get(k)
            if have is None or not _same(have, v):
                return False
    return True


def _same(have, text: str) -> bool:
    try:
        return float(have) == float(text)
    except (TypeError, ValueError):
        return str(have).lower() == text.lower()


def process_factor(points: list[dict[str, Any]], factor: float) -> float:
    """The factor a time step must pass in a cell's series: the median over its runs of the
    spread between processes (``cpu_s_process_spread``), at least ``factor``, and at least
    ``CELL_FACTOR`` where a run was timed in its own process (``timed_in``)."""
    spreads = sorted(p[SPREAD_FIELD] for p in points
                     if p.get("status") == Status.OK and isinstance(p.get(SPREAD_FIELD), (int, float)))
    if any(p.get("status") == Status.OK and one_process(p) for p in points):
        factor = max(factor, CELL_FACTOR)  # a run timed in its own process has no spread to judge by
    if not spreads:
        return factor
    return max(factor, _median(spreads))


def series_specs(points: list[dict[str, Any]], errors: list[str], factor: float,
                 error_factor: float) -> list[dict[str, Any]]:
    """The series of one cell whose steps are found: per series its ``field``, the
    ``factor`` a step must pass, ``min_runs`` (a shorter level between two that agree is
    chance), ``floor`` (both levels at or below it: no step), ``kinds`` (the names of a
    rise and of a fall) and, for time, the ``basis`` of its factor."""
    time_factor = process_factor(points, factor)
    specs = [{"field": TIME_FIELD, "factor": time_factor, "min_runs": MIN_RUNS, "floor": 0.0,
              "kinds": ("slower", "faster"),
              "basis": "spread between processes" if time_factor > factor else f"x{factor:g}"}]
    specs += [{"field": f, "factor": error_factor, "min_runs": 1, "floor": ROUND_OFF,
               "kinds": ("less accurate", "more accurate")} for f in errors]
    if any(isinstance(p.get(INSTRUCTIONS_FIELD), int) for p in points):  # deterministic: every level counts
        counts = [p[INSTRUCTIONS_FIELD] for p in points if isinstance(p.get(INSTRUCTIONS_FIELD), int)]
        specs.append({"field": INSTRUCTIONS_FIELD, "factor": count_factor(INSTRUCTION_FACTOR, counts), "min_runs": 1,
                      "floor": 0.0,
                      "kinds": ("more instructions", "fewer instructions")})
    return specs


def history(store, problems=None, schemes=None, sets: dict[str, str] | None = None,
            factor: float = TIME_FACTOR, error_factor: float = ERROR_FACTOR,
            fields: tuple[str, ...] | None = None) -> list[dict[str, Any]]:
    """Per cell identity (in the store's order of first appearance): ``cell`` (the matched
    keys), ``runs`` (per run holding the cell, by run id: run_id, commit, code (the commit and
    dirty flag of the code under test), date, status, cpu_s, cpu_s_calibrated, each process's
    minimum and their spread, and every error field), ``time_factor`` (the factor a time step
    had to pass) and ``steps`` (field, run_id, commit, date, before, after, ratio, factor,
    kind) of every series, or of ``fields`` only."""
    from longtime.execution.provenance import run_code

    runs = {r["id"]: r for r in store.runs()}
    machine_of = machines.machines(list(runs.values()), store.calibrations)
    streams = {rid: _streamed(store.calibrations(rid)) for rid in runs}
    only = fields
    cells: dict[tuple, dict[int, dict]] = {}
    for row in store.rows():
        if selected(row, problems, schemes, sets or {}):
            cells.setdefault(cell_key(row), {})[row["run_id"]] = row
    out = []
    for by_run in cells.values():
        ids = sorted(by_run)
        first = by_run[ids[0]]
        errors = sorted({f for r in by_run.values() for f in error_fields(r)})
        points = []
        for rid in ids:
            r, run = by_run[rid], runs.get(rid, {})
            points.append({"run_id": rid, "commit": run.get("git_commit"), "code": run_code(run),
                           "date": run.get("started"), "status": r.get("status"), "cpu_s": r.get("cpu_s"),
                           TIME_FIELD: r.get(TIME_FIELD), "cpu_s_processes": r.get("cpu_s_processes"),
                           SPREAD_FIELD: r.get(SPREAD_FIELD), "timed_in": r.get("timed_in"),
                           **{f: r.get(f) for f in errors},
                           INSTRUCTIONS_FIELD: r.get(INSTRUCTIONS_FIELD),
                           "machine": machine_of[rid]["label"] if rid in machine_of else None,
                           "instructions_counted_by": json.dumps([r.get("instructions_tool"),
                                                                  r.get("instructions_versions")]),
                           **streams.get(rid, _streamed([]))})
        found = []
        specs = series_specs(points, errors, factor, error_factor)
        mark_bandwidth(points, specs[0]["factor"])
        for spec in specs:
            field = spec["field"]
            if only is not None and field not in only:
                continue
            values = [p[field] if p["status"] == Status.OK and isinstance(p.get(field), (int, float))
                      and not (field == TIME_FIELD and p.get("not_comparable")) else None for p in points]
            for s in _steps_apart(values, points, field, spec):
                p = points[s["index"]]
                kind = spec["kinds"][0] if s["ratio"] > 1 else spec["kinds"][1]
                found.append({"field": field, "run_id": p["run_id"], "commit": p["commit"], "code": p["code"],
                              "date": p["date"], "before": s["before"], "after": s["after"], "ratio": s["ratio"],
                              "factor": spec["factor"], "kind": kind})
        out.append({"cell": {k: first.get(k) for k in MATCH_KEYS}, "runs": points,
                    "time_factor": specs[0]["factor"], "time_factor_basis": specs[0]["basis"], "steps": found})
    return out


def _streamed(points: list[dict]) -> dict[str, Any]:
    """A run's streaming workload (the median over its calibrations, ``stream_cpu_s``) and
    the size it streamed (None: calibrated without it)."""
    median = stream_median(points)
    return {"stream_cpu_s": median and median[0], "stream_bytes": median and median[1]}


def mark_bandwidth(points: list[dict[str, Any]], factor: float) -> None:
    """Each run's memory bandwidth against the cell's other runs of its machine that streamed
    the same size: ``bandwidth_ratio``, the run's streaming workload over the median of those
    runs'; beyond ``factor`` either way, ``not_comparable`` says why and the run's time takes
    no part in the time series' steps (its errors and instruction count still do). Needs two
    such runs; a run without the streaming workload is judged as it is."""
    groups: dict[tuple, list[dict[str, Any]]] = {}
    for p in points:
        p.update(bandwidth_ratio=None, not_comparable=None)
        if p["stream_cpu_s"] and p["status"] == Status.OK:
            groups.setdefault((p.get("machine"), p["stream_bytes"]), []).append(p)
    for members in groups.values():
        if len(members) < 2:
            continue
        usual = _median([p["stream_cpu_s"] for p in members])
        for p in members:
            ratio = p["bandwidth_ratio"] = p["stream_cpu_s"] / usual
            if not 1 / factor <= ratio <= factor:
                p["not_comparable"] = (f"memory bandwidth differed x{max(ratio, 1 / ratio):.3g} from the cell's other "
                                       f"runs (streaming {'slower' if ratio > 1 else 'faster'}; beyond x{factor:.3g})")


def _median(values: list[float]) -> float:
    """The median; of an even count, the geometric mean of the middle two."""
    v = sorted(values)
    n = len(v)
    return v[n // 2] if n % 2 else math.sqrt(v[n // 2 - 1] * v[n // 2])


def _steps_apart(values: list, points: list[dict[str, Any]], field: str, spec: dict) -> list[dict[str, Any]]:
    """The steps of one series, looked for apart among the runs that compare: a time only
    with the times of its own machine, a count only with the counts of its own target,
    Valgrind and versions (every run of an error series compares)."""
    group = "machine" if field == TIME_FIELD else "instructions_counted_by" if field == INSTRUCTIONS_FIELD else None
    kinds = sorted({str(p.get(group)) for p in points}) if group else [None]
    found = []
    for kind in kinds:
        mine = values if group is None else [v if str(p.get(group)) == kind else None for v, p in zip(values, points)]
        found += steps(mine, spec["factor"], spec["min_runs"], spec["floor"])
    return sorted(found, key=lambda s: s["index"])


def _short(commit: str | None) -> str:
    return (commit or "-")[:10]


def _code(code: list[dict] | None) -> str:
    """The commits of the code under test outside longtime ('-' for longtime's own), dirty marked."""
    return ",".join(f"{_short(c.get('commit'))}{'+dirty' if c.get('dirty') else ''}" for c in code or []) or "-"


def _bandwidth(point: dict[str, Any]) -> str:
    """A run's streaming workload beside the cell against the cell's other runs ('-': not measured)."""
    ratio = point.get("bandwidth_ratio")
    if ratio is None:
        return "-"
    return f"x{ratio:.3g}" + (" (not comparable)" if point.get("not_comparable") else "")


def render(found: list[dict[str, Any]]) -> str:
    from longtime.core.fmt import number

    parts = []
    for c in found:
        shown = [f for f in (*SHOWN_ERRORS, INSTRUCTIONS_FIELD) if any(p.get(f) is not None for p in c["runs"])]
        streamed = any(p.get("bandwidth_ratio") is not None for p in c["runs"])
        header = ["run", "machine", "commit", "code", "date", "status", "time (calibrated)", "cpu_s", "processes",
                  "spread", *(["memory streaming"] if streamed else []), *shown]
        body = [[str(p["run_id"]), str(p.get("machine") or "-"), _short(p["commit"]), _code(p.get("code")),
                 (p["date"] or "-")[:19], str(p["status"]),
                 formatted(TIME_FIELD, p[TIME_FIELD]), formatted("cpu_s", p["cpu_s"]),
                 str(len(p.get("cpu_s_processes") or []) or "-"),
                 f"x{p[SPREAD_FIELD]:.3g}" if isinstance(p.get(SPREAD_FIELD), (int, float)) else "-",
                 *([_bandwidth(p)] if streamed else []), *(formatted(f, p.get(f)) for f in shown)] for p in c["runs"]]
        widths = [max(len(h), *(len(r[i]) for r in body)) for i, h in enumerate(header)]
        lines = [f"== {label(c['cell'])}: {len(c['runs'])} run{'s' if len(c['runs']) != 1 else ''}; a time "
                 f"step passes x{c['time_factor']:.3g} ({c['time_factor_basis']}) =="]
        lines += ["  " + "  ".join(x.ljust(w) for x, w in zip(row, widths)) for row in [header, *body]]
        lines += [f"  run {p['run_id']}: time not compared: {p['not_comparable']}" for p in c["runs"]
                  if p.get("not_comparable")]
        for s in c["steps"]:
            name = "time" if s["field"] == TIME_FIELD else s["field"]
            lines.append(f"  STEP {name} x{s['ratio']:.3g} ({s['kind']}: {number(s['before'])} -> "
                         f"{number(s['after'])}) at run {s['run_id']}, commit {_short(s['commit'])}")
        if not c["steps"]:
            lines.append("  no step")
        parts.append("\n".join(lines))
    return "\n\n".join(parts) if parts else "no stored cell matches"


# ------------------------------------------------------------------ the results page
def machines_section(store, rows: list[dict]) -> str:
    """The results page's cross-machine section (longtime.reporting.machines): empty when
    ``rows`` come from one machine."""
    return machines.html(cross_machine_table(store, rows))
