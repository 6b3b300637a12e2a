"""The fields of a row (one cell's measurement): for each its name, type, unit, meaning and
formatter, in one registry. The store checks every row it adds against it (``check``) and
docs/metrics.md's list of row fields is this registry as text (``markdown``).

A field is declared by its exact name (``cpu_s``) or as one of a family that a problem or
a scheme names (``NAME.max`` for each invariant and constraint violation, ``NAME.growth`` for
each invariant and for the solution error, ``diag.NAME.max`` for each diagnostic). The
parameters with a row field of their own are longtime.core.roles.ROW_PARAMETERS; a scheme's
own counters are its ``extra_counters``.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any, Callable, Iterable, Mapping

from longtime.core.fmt import missing, number
from longtime.core.params import ROLES
from longtime.core.roles import ROW_PARAMETERS
from longtime.core.status import STATUSES

# the growth classes of an error (longtime.measure.growth): the power law's classes by
# increasing exponent, then the verdicts that are not a power law
POWER_CLASSES = ("bounded", "sqrt", "linear", "quadratic", "faster")
GROWTH_CLASSES = (*POWER_CLASSES, "saturated", "diverged", "undetermined")
# the largest count a row holds: a 64-bit counter of steps (or evaluations) stays below it
MAX_COUNT = 2**62


def _text(value: Any) -> str:
    return str(value)


def _numbers(value: Any) -> str:
    return ", ".join(number(v) for v in value)


def _texts(value: Any) -> str:
    return ", ".join(map(str, value))


def _json(value: Any) -> str:
    return json.dumps(value, sort_keys=True, default=str)


def _flag(value: Any) -> str:
    return "yes" if value else "no"


# each type: what a value of it is, its check (None passes as null where the field allows it)
# and its formatter
def _is_int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


TYPES: dict[str, tuple[str, Callable[[Any], bool], Callable[[Any], str]]] = {
    "int": ("an integer", _is_int, number),
    "float": ("a number", _is_number, number),
    "str": ("a text", lambda v: isinstance(v, str), _text),
    "bool": ("true or false", lambda v: isinstance(v, bool), _flag),
    "floats": ("a list of numbers", lambda v: isinstance(v, list) and all(map(_is_number, v)), _numbers),
    "strs": ("a list of texts", lambda v: isinstance(v, list) and all(isinstance(x, str) for x in v), _texts),
    "mapping": ("a JSON object", lambda v: isinstance(v, dict), _json),
    "mappings": ("a list of JSON objects", lambda v: isinstance(v, list) and all(isinstance(x, dict) for x in v),
                 _json),
}


@dataclass(frozen=True)
class Field:
    """One row field: ``name`` (for a family, with NAME where the problem's or scheme's name
    goes), ``kind`` (a key of TYPES), ``unit`` ("1": a ratio or relative error, "time": the
    problem's time unit, "s": seconds of CPU or wall time, "" for a text), ``meaning``, and
    whether it may be null (``optional``; a required field is present in every row)."""

    name: str
    kind: str
    unit: str
    meaning: str
    optional: bool = True
    values: tuple[str, ...] = ()  # the values a text may take (empty: any)
    bounds: tuple[float, float] | None = None  # the range [low, high] a number must lie in
    spec: str = ""  # a number's format spec (".2f"); empty: longtime.core.fmt.number's 4 significant digits

    def __post_init__(self) -> None:
        if self.kind not in TYPES:
            raise ValueError(f"row field {self.name}: type {self.kind!r} is not one of {', '.join(TYPES)}")

    def holds(self, value: Any) -> bool:
        """Whether ``value`` is of this field's type and values (null where the field is optional)."""
        return self.wrong(value) is None

    def wrong(self, value: Any) -> str | None:
        """Why ``value`` cannot be this field's (None: it can): its type, a text outside the
        field's values, a number outside its bounds."""
        if value is None:
            return None if self.optional else f"required ({TYPES[self.kind][0]}), got None"
        if not TYPES[self.kind][1](value):
            return f"{type(value).__name__} {_short(value)}, not {TYPES[self.kind][0]}"
        if self.values and value not in self.values:
            return f"{_short(value)} is not one of {', '.join(self.values)}"
        if self.bounds is not None and (value < self.bounds[0] or value > self.bounds[1]):
            return f"{_short(value)} is outside [{number(self.bounds[0])}, {number(self.bounds[1])}]"
        return None

    def format(self, value: Any) -> str:
        """``value`` as text, the one way every report shows this field: a dash for null or a
        non-finite number, a number (or each of a list) in the field's ``spec`` where it has one."""
        if missing(value):
            return "-"
        if self.spec and _is_number(value):
            return format(value, self.spec)
        if self.spec and self.kind == "floats" and isinstance(value, list):
            return ", ".join("-" if missing(v) else format(v, self.spec) for v in value)
        return TYPES[self.kind][2](value)


def _count(name: str, unit: str, meaning: str) -> Field:
    """A field that counts (steps, evaluations, bytes): an integer in [0, MAX_COUNT]."""
    return Field(name, "int", unit, meaning, bounds=(0, MAX_COUNT))


def _seconds(name: str, meaning: str) -> Field:
    """A time the run took: a number of seconds, never negative."""
    return Field(name, "float", "s", meaning, bounds=(0.0, math.inf))


def _parameter_fields() -> list[Field]:
    """The row fields of ROW_PARAMETERS: an integer for an order, a number for the rest."""
    units = {"step": "time", "accuracy": "1", "order": "1"}
    return [Field(name, "int" if role == "order" else "float", units.get(role, ""),
                  f"{text} (the {role} parameter; null where the scheme has none)")
            for name, (role, text) in sorted(ROW_PARAMETERS.items(), key=lambda kv: ROLES.index(kv[1][0]))]


FIELDS: tuple[Field, ...] = (
    Field("problem", "str", "", "the problem's name", optional=False),
    Field("integrator", "str", "", "the scheme's name", optional=False),
    Field("status", "str", "", "what became of the cell", optional=False, values=STATUSES),
    Field("message", "str", "", "what the row must say: a failure, a skip's reason, the reference's limits"),
    *_parameter_fields(),
    Field("t_final", "float", "time", "the final time asked for"),
    Field("settings", "str", "", "the problem's and the scheme's other settings (JSON text; empty: none)"),
    Field("parameters", "str", "", "every parameter the run used, defaults included (JSON text)"),
    Field("run_id", "int", "", "the run that stored the row (added when the store reads it)"),
    # the run
    Field("t_reached", "float", "time", "the time the run reached (where a diverged run stopped)"),
    _count("samples", "", "the number of samples of the state measured"),
    _count("steps", "", "steps taken"),
    _count("rhs_evals", "", "right-hand side evaluations"),
    _count("nl_iters", "", "nonlinear (fixed-point or Newton) iterations"),
    _count("rejected", "", "rejected steps (adaptive schemes)"),
    _count("fallbacks", "", "steps that fell back to a safer method"),
    _count("jac_evals", "", "Jacobian evaluations"),
    _count("residual_evals", "", "residual evaluations (bpl)"),
    _count("pade_degenerate", "", "steps whose Pade approximant was degenerate (bpl)"),
    _count("series_evals", "", "Taylor series evaluations (taylor)"),
    Field("fallback_fraction", "float", "1", "fallbacks / steps (bpl)"),
    Field("mean_dt", "float", "time", "(t_reached - t0) / steps"),
    Field("min_dt", "float", "time", "the smallest step taken (adaptive schemes)"),
    Field("max_dt", "float", "time", "the largest step taken (adaptive schemes)"),
    _count("working_set_bytes", "bytes", "the bytes the run touches: samples, state and scratch"),
    # cost
    _seconds("cpu_s", "process time of the integration: the minimum over every timed run"),
    _seconds("wall_s", "wall time of the integration: the minimum over every timed run"),
    _count("repeats", "", "the number of timed runs"),
    _seconds("cpu_s_median", "the median process time of the timed runs"),
    _seconds("cpu_s_max", "the largest process time of the timed runs"),
    _seconds("wall_s_median", "the median wall time of the timed runs"),
    _seconds("wall_s_max", "the largest wall time of the timed runs"),
    Field("cpu_s_samples", "floats", "s", "the process time of every timed run, in order"),
    Field("samples_digest", "str", "", "a digest of the run's samples, which every timed run must reproduce"),
    Field("cpu_s_processes", "floats", "s", "each timing process's minimum (the row's own process first)"),
    Field("cpu_s_process_spread", "float", "1", "max / min of the fresh timing processes' minima"),
    Field("timed_in", "str", "", "how the cell was timed: 'N processes', or 'its own process, N runs: ' and why "
                                 "(a cell whose time changes no answer: by how much a front dominates it)"),
    Field("phases_missing", "strs", "", "the phases after the cell's run that have not run for it yet"),
    Field("cpu_s_calibrated", "float", "1", "cpu_s over the calibration workload that fits the row"),
    Field("calibration_cpu_s", "float", "s", "the CPU time of that calibration workload"),
    Field("calibration_workload", "str", "", "the calibration workload: compute or memory"),
    Field("calibration_t", "float", "s", "the time (seconds since the epoch) of that calibration"),
    Field("peer_overhead_s", "float", "s", "a library peer's CPU time per step on the trivial rhs"),
    Field("compile_s", "float", "s", "the CPU time JAX took to compile or load the solve (diffrax)"),
    Field("pace_cpu_s", "float", "s", "a run stopped on its pace: the CPU time its pace so far puts its t_final at"),
    _count("instructions", "", "instructions of the integration under Callgrind"),
    Field("instructions_per_step", "float", "", "instructions / steps"),
    Field("instructions_tool", "str", "", "Valgrind's version and the count's target"),
    Field("instructions_target", "str", "", "the CPU the counted kernels were compiled for"),
    Field("instructions_versions", "mapping", "", "the versions that can move a count (Python, numba, ...)"),
    Field("instructions_skipped", "str", "", "why the row has no count"),
    # errors
    Field("l2_error", "float", "1", "the largest block's RMS solution error over the run, relative to its motion"),
    Field("final_error", "float", "1", "the largest block's solution error at the last sample, relative to its motion"),
    Field("max_error", "float", "1", "the largest block's largest solution error over the samples up to error_horizon"),
    Field("l2_error_state", "float", "1", "the whole state's RMS solution error over the run, relative to its motion"),
    Field("final_error_state", "float", "1",
          "the whole state's solution error at the last sample, relative to its motion"),
    Field("error_block", "str", "", "the block of the state (Problem.blocks) whose l2_error is the row's"),
    Field("error_horizon", "float", "time", "the last sample time the solution errors cover"),
    Field("error_curve", "mapping", "", "the largest block's error: upper envelope (t, error) and l2 at 80 times"),
    _count("drifting_components", "", "the reference's components that drift"),
    Field("solution_lost", "bool", "", "l2_error or final_error is 0.5 or more: a block of the state is lost"),
    Field("drift_curve", "mapping", "", "the first invariant's drift curve (invariant, t, error)"),
    Field("drift_curves", "mappings", "", "every invariant's drift curve, in the problem's order"),
    Field("diag_curves", "mappings", "", "every diagnostic's curve (diagnostic, t, error)"),
    Field("reference", "str", "", "what the errors are measured against: exact, heyoka double/long double, "
                                  "or integrating factor (a discretised system's own solution)"),
    Field("reference_error", "float", "1", "the reference's own error, as checked (relative to the state)"),
    Field("error_floor", "float", "1", "the reference's error in l2_error's units: errors below it are not measured"),
    Field("error_below_floor", "bool", "", "l2_error or final_error is below error_floor: not measured, only bounded"),
    Field("discretisation_error", "float", "1",
          "a discretised PDE's: its solution's l2_error against the system's (the space discretisation's error)"),
    Field("reference_horizon", "float", "time", "the time up to which the reference is trusted"),
    Field("reference_rtol", "float", "1", "the relative tolerance the reference is trusted to"),
    # chaos
    Field("predictability_t", "float", "time", "the first time the solution error reaches 0.5 (chaotic problems)"),
    Field("predictability_lyapunov", "float", "1", "predictability_t / lyapunov_time"),
    Field("predictability_note", "str", "", "what bounds the predictability horizon"),
    Field("lyapunov_time", "float", "time", "the Lyapunov time of the initial state"),
    Field("lyapunov_exponent", "float", "1/time", "the largest Lyapunov exponent of the initial state"),
    Field("lyapunov_note", "str", "", "how the Lyapunov time was measured, or why not"),
    # `longtime match`
    Field("match_role", "str", "", "search (a point of the search) or matched (the setting found)"),
    Field("match_target", "float", "1", "the error the search aims at"),
    Field("match_parameter", "str", "", "the parameter searched"),
    Field("match_value", "float", "", "the value found"),
    Field("match_note", "str", "", "why the value found misses the target, where it does"),
    _count("match_evals", "", "the settings the search ran"),
    Field("match_mean_steps", "mapping", "time", "each value tried -> the mean step it took"),
    _count("cpu_runs", "", "the runs the matched setting's CPU time is the best of"),
)

# the families: a field NAME.SUFFIX (diag.NAME.SUFFIX) for each NAME of the kind
_INVARIANT = "an invariant's (or a constraint violation's) relative error"
_GROWTH = "the invariant's (or, NAME = error, the solution's) error"
FAMILIES: tuple[Field, ...] = (
    Field("NAME.max", "float", "1", f"the largest value over the samples of {_INVARIANT}"),
    Field("NAME.mean", "float", "1", f"the time mean of {_INVARIANT}"),
    Field("NAME.final", "float", "1", f"the last sample's value of {_INVARIANT}"),
    Field("NAME.t_1pct", "float", "time", f"the first time {_INVARIANT} passes 1 %"),
    Field("NAME.t_50pct", "float", "time", f"the first time {_INVARIANT} passes 50 %"),
    # an exponent is shown to two decimals
    Field("NAME.growth", "float", "1", f"alpha, the power law's exponent fitted to {_GROWTH}", spec=".2f"),
    Field("NAME.growth_ci", "floats", "1", "alpha's interval [low, high]", spec=".2f"),
    Field("NAME.growth_class", "str", "", f"the growth class of {_GROWTH}: bounded, sqrt, linear, ...",
          values=GROWTH_CLASSES),
    Field("NAME.growth_reason", "str", "", "what the growth class rests on, or why it is undetermined"),
    Field("NAME.growth_windows", "floats", "1", f"the local slopes of {_GROWTH}, earliest first", spec=".2f"),
    Field("NAME.saturated_t", "float", "time", f"the first time {_GROWTH} reached saturation"),
    Field("diag.NAME.max", "float", "1", "the largest change of the diagnostic NAME"),
    Field("diag.NAME.final", "float", "1", "the change of the diagnostic NAME at the last sample"),
)

_BY_NAME: dict[str, Field] = {f.name: f for f in FIELDS}
_BY_SUFFIX: dict[str, Field] = {f.name.removeprefix("NAME."): f for f in FAMILIES if not f.name.startswith("diag.")}
_DIAG_BY_SUFFIX: dict[str, Field] = {f.name.removeprefix("diag.NAME."): f for f in FAMILIES
                                     if f.name.startswith("diag.")}
_COUNTER = "a counter of the scheme's own (extra_counters)"


def field(name: str, counters: Iterable[str] = ()) -> Field | None:
    """The declaration of the row field ``name`` (None: undeclared); ``counters``: the
    scheme's own counters, integers."""
    if name in _BY_NAME:
        return _BY_NAME[name]
    if name in counters:
        return _count(name, "", _COUNTER)
    head, _, suffix = name.rpartition(".")
    if not head:
        return None
    if head.startswith("diag."):
        return _DIAG_BY_SUFFIX.get(suffix) if head != "diag." else None
    return _BY_SUFFIX.get(suffix)


def formatted(name: str, value: Any) -> str:
    """Field ``name``'s ``value`` as a person reads it (its ``Field.format``: a dash for null):
    a row field's, else a check's or an ensemble record's (CHECK_FIELDS, ENSEMBLE_FIELDS); a
    value of a field none declares, as a number (longtime.core.fmt.number)."""
    declared = field(name) or _RECORD_FIELDS.get(name)
    return number(value) if declared is None else declared.format(value)


# the store's records beside the rows (longtime.execution.store_records), each field the row
# declares held as the row's: a check is the row of a re-run with its prediction beside it
CHECK_ROLES = ("best", "runner-up", "open", "chaos", "growth")
CHECK_FIELDS: tuple[Field, ...] = (
    Field("check_of", "str", "", "the key of the cell whose row made the prediction"),
    Field("check_of_run", "int", "", "the run of that row"),
    Field("check_field", "str", "", "the row field the prediction is about (l2_error, H.max, ...)"),
    Field("check_law", "str", "", "the law the prediction extrapolates, as text"),
    Field("check_role", "str", "", "what the re-run tests", values=CHECK_ROLES),
    Field("check_group", "str", "", "the decision the group's re-runs test"),
    Field("check_kind", "str", "", "the class of problem the check covers"),
    Field("check_target", "float", "1", "the target error of the decision (a decade: 1e-06)", spec="g"),
    Field("predicted_error", "float", "1", "the error predicted at the horizon (null: no prediction)"),
    Field("predicted_bound", "bool", "", "whether the predicted error is an upper bound"),
    Field("predicted_cpu_s", "float", "s", "the CPU time predicted at the horizon", bounds=(0.0, math.inf)),
    Field("predicted_cpu_s_calibrated", "float", "s", "the predicted CPU time in the machine's calibrated units "
          "(the prediction rescaled by its row's calibration)", bounds=(0.0, math.inf)),
    Field("predicted_cpu_model", "str", "", "the cost model the CPU time is predicted by"),
    Field("measured_error", "float", "1", "the error the re-run measured at the horizon"),
    Field("from_t_final", "float", "time", "the span of the row that made the prediction"),
    Field("from_error", "float", "1", "that row's error"),
    Field("rank_rivals", "strs", "", "the settings measured against the best one"),
    Field("rank_lost_to", "strs", "", "the rivals that kept the target more cheaply"),
    Field("rank_held", "bool", "", "whether the best setting held its rank (null: no rival measured)"),
)
# an ensemble record: one scheme's distance to heyoka's ensemble on a chaotic problem
ENSEMBLE_FIELDS: tuple[Field, ...] = (
    Field("problem_settings", "mapping", "", "the settings of the problem's chaotic state"),
    Field("members", "int", "", "the ensemble's members", bounds=(0, MAX_COUNT)),
    Field("size", "float", "1", "the perturbation's size"),
    Field("window", "float", "1", "the share of the run the distribution is read over"),
    Field("seed", "int", "", "the perturbations' seed"),
    Field("lyapunov_time", "float", "time", "1/lambda (null: no chaos measured)"),
    Field("lyapunov_note", "str", "", "what the Lyapunov time rests on"),
    Field("span_lyapunov", "float", "1", "the run's span in Lyapunov times"),
    Field("observable", "str", "", "the observable whose distribution is compared"),
    Field("floor", "float", "1", "the distance between heyoka's ensembles (the floor)", bounds=(0.0, math.inf)),
    Field("floors", "floats", "1", "each of those distances"),
    Field("row_t_final", "float", "time", "the final time of the row the setting comes from"),
    Field("note", "str", "", "why there is no distance, or what it rests on"),
    Field("member_status", "mapping", "", "how many members ended in each status"),
    Field("distance", "float", "1", "the distance between the distributions", bounds=(0.0, math.inf)),
    Field("distinguishable", "bool", "", "whether the distance stands above the floor"),
)

# the fields of the records beside the rows that the row does not declare, by name
_RECORD_FIELDS: dict[str, Field] = {f.name: f for f in (*CHECK_FIELDS, *ENSEMBLE_FIELDS)}


def record_problems(record: Any, fields: Iterable[Field], counters: Iterable[str] | None = None) -> list[str]:
    """What is wrong with a record the store keeps beside the rows (a check: CHECK_FIELDS, an
    ensemble: ENSEMBLE_FIELDS), one line per field (none: it holds): no problem or integrator,
    a field neither ``fields`` nor the row declares, a value that is not its field's (type,
    values, bounds: ``Field.wrong``). A field the row declares holds as the row's."""
    if not isinstance(record, Mapping):
        return [f"a record must be a mapping of fields, not {type(record).__name__}"]
    out = [f"{name}: required (a text), got {record.get(name)!r}" for name in ("problem", "integrator")
           if not isinstance(record.get(name), str) or not record.get(name)]
    own = {f.name: f for f in fields}
    counters = scheme_counters(record.get("integrator")) if counters is None else tuple(counters)
    return out + _value_problems(record.items(), lambda name: own.get(name) or field(name, counters), "field")


def _value_problems(items: Iterable[tuple[Any, Any]], declared_as: Any, what: str) -> list[str]:
    """One line per item whose name ``declared_as`` does not declare (a ``what``), or whose
    value is not its field's (``Field.wrong``); a null value holds."""
    out = []
    for name, value in items:
        declared = declared_as(name) if isinstance(name, str) else None
        if declared is None:
            out.append(f"{name}: not a declared {what} (longtime.core.rowschema)")
        elif value is not None:
            wrong = declared.wrong(value)
            if wrong:
                out.append(f"{name}: {wrong}")
    return out


class RowError(ValueError):
    """A row that is not of the declared fields and types (its message names the field)."""


def problems(row: Mapping[str, Any], counters: Iterable[str] = (), only: Iterable[str] | None = None) -> list[str]:
    """What is wrong with ``row`` against the registry, one line per field (none: it holds):
    an undeclared field, a value of the wrong type, a text outside its field's values, a
    number outside its bounds, a required field missing or empty. ``counters``: the scheme's
    own counters; ``only``: the names of the fields to check (None: every field)."""
    counters = tuple(counters)
    only = None if only is None else set(only)
    out = []
    for f in FIELDS:
        value = row.get(f.name)
        empty = value is None or (isinstance(value, str) and not value)
        if not f.optional and (only is None or f.name in only) and empty:
            out.append(f"{f.name}: required ({TYPES[f.kind][0]}), got {value!r}")
    items = [(name, value) for name, value in row.items() if only is None or name in only]
    return out + _value_problems(items, lambda name: field(name, counters), "row field")


def scheme_counters(integrator: Any) -> tuple[str, ...]:
    """The own counters (``extra_counters``) of the scheme named ``integrator``: none where no
    installed scheme has the name."""
    from longtime.core import registry  # the registry loads the plugins: only when a row is checked

    scheme = registry.integrators().get(integrator) if isinstance(integrator, str) else None
    return tuple(getattr(scheme, "extra_counters", ()))


def validate_row(row: Any, counters: Iterable[str] | None = None) -> list[str]:
    """What is wrong with ``row`` (``problems``), one line per field, the first line naming a
    row that is not a mapping; none: it holds. ``counters``: the scheme's own counters (None:
    those of the scheme the row names, ``scheme_counters``). The one check of a row, wherever
    one is made or read: a cell's row (longtime.execution.cells), the store's, a merged row."""
    if not isinstance(row, Mapping):
        return [f"a row must be a mapping of fields, not {type(row).__name__}"]
    return problems(row, scheme_counters(row.get("integrator")) if counters is None else counters)


def check(row: Mapping[str, Any], counters: Iterable[str] | None = None) -> None:
    """Refuse (RowError naming every wrong field) a row that ``validate_row`` finds wrong:
    an undeclared field, a value of the wrong type or outside its field's values or bounds,
    no problem, integrator or status."""
    wrong = validate_row(row, counters)
    if wrong:
        if not isinstance(row, Mapping):
            raise RowError(wrong[0])
        raise RowError(f"row of {row.get('problem')} x {row.get('integrator')}: " + "; ".join(wrong))


def _short(value: Any) -> str:
    try:
        text = repr(value)
    except RecursionError:  # nested deeper than repr goes
        return f"a {type(value).__name__} nested too deep to show"
    return text if len(text) <= 60 else text[:57] + "..."


def markdown() -> str:
    """The list of row fields as a Markdown table (docs/metrics.md holds it)."""
    lines = ["| field | type | unit | meaning |", "|---|---|---|---|"]
    for f in (*FIELDS, *FAMILIES):
        kind = TYPES[f.kind][0] + ("" if f.optional else ", required")
        if f.values:
            kind += ": " + ", ".join(f.values)
        elif f.bounds == (0, MAX_COUNT):
            kind += ", 0 to 2^62"
        elif f.bounds is not None:
            kind += f", >= {number(f.bounds[0])}"
        lines.append(f"| `{f.name}` | {kind} | {f.unit} | {f.meaning} |")
    return "\n".join(lines)


if __name__ == "__main__":  # the table docs/metrics.md holds
    print(markdown())
