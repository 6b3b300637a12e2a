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
from dataclasses import dataclass
from typing import Any, Callable, Iterable, Mapping

from longtime.core.fmt import missing, number
from longtime.core.params import ROLES
from longtime.core.roles import ROW_PARAMETERS


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

    def __post_init__(self) -> None:
        if self.kind not in TYPES:
            raise ValueError(f"row field {self.name}: type {self.kind!r} is not one of {', '.join(TYPES)}")

    def holds(self, value: Any) -> bool:
        """Whether ``value`` is of this field's type (null where the field is optional)."""
        if value is None:
            return self.optional
        return TYPES[self.kind][1](value)

    def format(self, value: Any) -> str:
        """``value`` as text: a dash for null or a non-finite number."""
        if missing(value):
            return "-"
        return TYPES[self.kind][2](value)


def _parameter_fields() -> list[Field]:
    """The row fields of ROW_PARAMETERS: an integer for an order, a number for the rest."""
    units = {"step": "time", "accuracy": "1", "order": "1"}
    return [Field(name, "int" if role == "order" else "float", units.get(role, ""),
                  f"{text} (the {role} parameter; null where the scheme has none)")
            for name, (role, text) in sorted(ROW_PARAMETERS.items(), key=lambda kv: ROLES.index(kv[1][0]))]


FIELDS: tuple[Field, ...] = (
    Field("problem", "str", "", "the problem's name", optional=False),
    Field("integrator", "str", "", "the scheme's name", optional=False),
    Field("status", "str", "", "ok, diverged, failed, timeout or skipped", optional=False),
    Field("message", "str", "", "what the row must say: a failure, a skip's reason, the reference's limits"),
    *_parameter_fields(),
    Field("t_final", "float", "time", "the final time asked for"),
    Field("settings", "str", "", "the problem's and the scheme's other settings (JSON text; empty: none)"),
    Field("parameters", "str", "", "every parameter the run used, defaults included (JSON text)"),
    Field("run_id", "int", "", "the run that stored the row (added when the store reads it)"),
    # the run
    Field("t_reached", "float", "time", "the time the run reached (where a diverged run stopped)"),
    Field("samples", "int", "", "the number of samples of the state measured"),
    Field("steps", "int", "", "steps taken"),
    Field("rhs_evals", "int", "", "right-hand side evaluations"),
    Field("nl_iters", "int", "", "nonlinear (fixed-point or Newton) iterations"),
    Field("rejected", "int", "", "rejected steps (adaptive schemes)"),
    Field("fallbacks", "int", "", "steps that fell back to a safer method"),
    Field("jac_evals", "int", "", "Jacobian evaluations"),
    Field("residual_evals", "int", "", "residual evaluations (bpl)"),
    Field("pade_degenerate", "int", "", "steps whose Pade approximant was degenerate (bpl)"),
    Field("series_evals", "int", "", "Taylor series evaluations (taylor)"),
    Field("fallback_fraction", "float", "1", "fallbacks / steps (bpl)"),
    Field("mean_dt", "float", "time", "(t_reached - t0) / steps"),
    Field("min_dt", "float", "time", "the smallest step taken (adaptive schemes)"),
    Field("max_dt", "float", "time", "the largest step taken (adaptive schemes)"),
    Field("working_set_bytes", "int", "bytes", "the bytes the run touches: samples, state and scratch"),
    # cost
    Field("cpu_s", "float", "s", "process time of the integration: the minimum over every timed run"),
    Field("wall_s", "float", "s", "wall time of the integration: the minimum over every timed run"),
    Field("repeats", "int", "", "the number of timed runs"),
    Field("cpu_s_median", "float", "s", "the median process time of the timed runs"),
    Field("cpu_s_max", "float", "s", "the largest process time of the timed runs"),
    Field("wall_s_median", "float", "s", "the median wall time of the timed runs"),
    Field("wall_s_max", "float", "s", "the largest wall time of the timed runs"),
    Field("cpu_s_samples", "floats", "s", "the process time of every timed run, in order"),
    Field("samples_digest", "str", "", "a digest of the run's samples, which every timed run must reproduce"),
    Field("cpu_s_processes", "floats", "s", "each timing process's minimum (the row's own process first)"),
    Field("cpu_s_process_spread", "float", "1", "max / min of the fresh timing processes' minima"),
    Field("phases_missing", "strs", "", "the phases after the cell's run that have not run for it yet"),
    Field("cpu_s_calibrated", "float", "1", "cpu_s over the calibration workload that fits the row"),
    Field("calibration_cpu_s", "float", "s", "the CPU time of that calibration workload"),
    Field("calibration_workload", "str", "", "the calibration workload: compute or memory"),
    Field("calibration_t", "float", "s", "the time (seconds since the epoch) of that calibration"),
    Field("peer_overhead_s", "float", "s", "a library peer's CPU time per step on the trivial rhs"),
    Field("compile_s", "float", "s", "the CPU time JAX took to compile or load the solve (diffrax)"),
    Field("instructions", "int", "", "instructions of the integration under Callgrind"),
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
    Field("drifting_components", "int", "", "the reference's components that drift"),
    Field("solution_lost", "bool", "", "l2_error or final_error is 0.5 or more: a block of the state is lost"),
    Field("drift_curve", "mapping", "", "the first invariant's drift curve (invariant, t, error)"),
    Field("drift_curves", "mappings", "", "every invariant's drift curve, in the problem's order"),
    Field("diag_curves", "mappings", "", "every diagnostic's curve (diagnostic, t, error)"),
    Field("reference", "str", "", "what the errors are measured against: exact, or heyoka double/long double"),
    Field("reference_error", "float", "1", "the reference's own error, as checked"),
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
    Field("match_evals", "int", "", "the settings the search ran"),
    Field("match_mean_steps", "mapping", "time", "each value tried -> the mean step it took"),
    Field("cpu_runs", "int", "", "the runs the matched setting's CPU time is the best of"),
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
    Field("NAME.growth", "float", "1", f"alpha, the power law's exponent fitted to {_GROWTH}"),
    Field("NAME.growth_ci", "floats", "1", "alpha's interval [low, high]"),
    Field("NAME.growth_class", "str", "", f"the growth class of {_GROWTH}: bounded, sqrt, linear, ..."),
    Field("NAME.growth_reason", "str", "", "what the growth class rests on, or why it is undetermined"),
    Field("NAME.growth_windows", "floats", "1", f"the local slopes of {_GROWTH}, earliest first"),
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
        return Field(name, "int", "", _COUNTER)
    head, _, suffix = name.rpartition(".")
    if not head:
        return None
    if head.startswith("diag."):
        return _DIAG_BY_SUFFIX.get(suffix) if head != "diag." else None
    return _BY_SUFFIX.get(suffix)


class RowError(ValueError):
    """A row that is not of the declared fields and types (its message names the field)."""


def problems(row: Mapping[str, Any], counters: Iterable[str] = ()) -> list[str]:
    """What is wrong with ``row`` against the registry, one line per field (none: it holds)."""
    counters = tuple(counters)
    out = []
    for f in FIELDS:
        if not f.optional and not (f.name in row and f.holds(row[f.name]) and row[f.name] != ""):
            out.append(f"{f.name}: required ({TYPES[f.kind][0]}), got {row.get(f.name)!r}")
    for name, value in row.items():
        declared = field(name, counters) if isinstance(name, str) else None
        if declared is None:
            out.append(f"{name}: not a declared row field (longtime.core.rowschema)")
        elif declared.optional and not declared.holds(value):
            out.append(f"{name}: {type(value).__name__} {_short(value)}, not {TYPES[declared.kind][0]}")
    return out


def check(row: Mapping[str, Any], counters: Iterable[str] = ()) -> None:
    """Refuse (RowError naming every wrong field) a row that has an undeclared field, a value
    of the wrong type or no problem, integrator or status."""
    if not isinstance(row, Mapping):
        raise RowError(f"a row must be a mapping of fields, not {type(row).__name__}")
    wrong = problems(row, counters)
    if wrong:
        raise RowError(f"row of {row.get('problem')} x {row.get('integrator')}: " + "; ".join(wrong))


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def markdown() -> str:
    """The list of row fields as a Markdown table (docs/metrics.md holds it)."""
    lines = ["| field | type | unit | meaning |", "|---|---|---|---|"]
    for f in (*FIELDS, *FAMILIES):
        kind = TYPES[f.kind][0] + ("" if f.optional else ", required")
        lines.append(f"| `{f.name}` | {kind} | {f.unit} | {f.meaning} |")
    return "\n".join(lines)


if __name__ == "__main__":  # the table docs/metrics.md holds
    print(markdown())
