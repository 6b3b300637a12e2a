"""The verdicts of ``longtime compare`` on one common cell (time, instructions, errors, growth
classes) and on the batches of a scheme or a problem; the rules are in longtime.reporting.compare."""
from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

from longtime.core.roles import row_columns
from longtime.core.status import Status
from longtime.measure.instructions import count_factor

# set above the spread measured between runs of identical code, alone and beside CPU-bound
# processes (README, "compare")
TIME_FACTOR = 1.2  # a scheme's (a problem's) median batch ratio beyond this: slower
CELL_FACTOR = 2.0  # a single cell's ratio beyond this: slower
MIN_BATCHES = 3  # batches a scheme's (a problem's) median needs
SHORT_CPU_S = 2e-5  # cells below this CPU time (shorter than any measured) get no time verdict
ROUND_OFF = 1e-13
# instruction counts of identical code agree within COUNT_NOISE instructions (docs/machines.md):
# a change beyond 1 % is the code's (beyond more where that noise is a larger share of the
# count: longtime.measure.instructions.count_factor)
INSTRUCTION_FACTOR = 1.01
# a cell is its problem, scheme, final time and every parameter (row fields and settings)
MATCH_KEYS = ("problem", "integrator", *row_columns(), "t_final", "settings")
ERROR_SUFFIXES = (".max", ".mean", ".final")
ERROR_FIELDS = ("l2_error", "final_error")


def cell_key(row: dict[str, Any]) -> tuple:
    return tuple(json.dumps(row.get(k), sort_keys=True) for k in MATCH_KEYS)


def error_fields(row: dict[str, Any]) -> list[str]:
    return sorted(k for k, v in row.items()
                  if (k in ERROR_FIELDS or k.endswith(ERROR_SUFFIXES)) and _number(v))


def _number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def slower_p(a: list[float], b: list[float]) -> float | None:
    """One-sided Mann-Whitney U p-value that B's times are larger than A's (None without samples)."""
    if not a or not b:
        return None
    from scipy.stats import mannwhitneyu

    return float(mannwhitneyu(b, a, alternative="greater").pvalue)


def _timed(a: dict, b: dict, raw: bool) -> tuple[str, float, float] | None:
    """(basis, time of A, time of B) of a cell: calibrated where both rows have it."""
    if not raw and _number(a.get("cpu_s_calibrated")) and _number(b.get("cpu_s_calibrated")) \
            and (a.get("calibration_workload") or "compute") == (b.get("calibration_workload") or "compute"):
        return "calibrated", a["cpu_s_calibrated"], b["cpu_s_calibrated"]
    if _number(a.get("cpu_s")) and _number(b.get("cpu_s")):
        return "raw", a["cpu_s"], b["cpu_s"]
    return None


def process_spread(a: dict, b: dict) -> float | None:
    """The larger spread between processes (max / min of their minima) of two rows, where
    both were timed in several processes (None otherwise)."""
    spreads = [r.get("cpu_s_process_spread") for r in (a, b)]
    if not all(_number(x) and x >= 1 for x in spreads):
        return None
    return max(spreads)


def one_process(row: dict) -> bool:
    """Whether a row's time was taken in its own process only (its ``timed_in``, where the
    main job's timing by need left it out of the fresh timing processes, or ``--processes
    1``): it has no spread between processes."""
    from longtime.execution.processes import ALONE, TIMED_IN

    return str(row.get(TIMED_IN) or "").startswith(ALONE)


def compare_rows(a: dict, b: dict, factor: float = TIME_FACTOR, error_factor: float = 2.0,
                 alpha: float = 0.05, raw: bool = False, cell_factor: float = CELL_FACTOR,
                 short: float = SHORT_CPU_S, instruction_factor: float = INSTRUCTION_FACTOR,
                 bandwidth: float | None = None) -> dict[str, Any]:
    """One common cell: its time ratios, its error ratios, growth-class changes and the
    list of regressions (text). The time verdict is the cell's own (``--cell-factor``);
    ``compare`` adds the verdicts of its scheme and problem. ``alpha`` is unused: the
    repeats' p-value (``p_slower``) is reported, not judged. ``bandwidth``: B / A of the
    runs' streaming workload (longtime.reporting.compare_machine.machine; None: not measured
    in both runs); beyond ``factor`` and the spread between processes
    either way, the time gets no verdict ("not comparable", ``not_comparable`` says why)."""
    out: dict[str, Any] = {k: a.get(k) for k in MATCH_KEYS}
    out.update(status_a=a.get("status"), status_b=b.get("status"), regressions=[], improvements=[])
    if a.get("status") == Status.OK and b.get("status") != Status.OK:
        out["regressions"].append(f"status ok -> {b.get('status')}")
    if _number(a.get("cpu_s")) and _number(b.get("cpu_s")) and a["cpu_s"] > 0:
        out.update(cpu_a=a["cpu_s"], cpu_b=b["cpu_s"], cpu_ratio=b["cpu_s"] / a["cpu_s"],
                   p_slower=slower_p(a.get("cpu_s_samples") or [], b.get("cpu_s_samples") or []))
    _judge_instructions(out, a, b, instruction_factor)
    timed = _timed(a, b, raw)
    out["time_verdict"] = None
    if _number(a.get("cpu_s_calibrated")) and _number(b.get("cpu_s_calibrated")) and a["cpu_s_calibrated"] > 0:
        out["cpu_calibrated_ratio"] = b["cpu_s_calibrated"] / a["cpu_s_calibrated"]
    if timed is not None and timed[1] > 0 and a.get("status") == Status.OK and b.get("status") == Status.OK:
        basis, ta, tb = timed
        ratio = tb / ta
        out.update(time_basis=basis, time_a=ta, time_b=tb, time_ratio=ratio)
        spread = process_spread(a, b)
        if out["instruction_verdict"] == "within":
            # the same work, instruction for instruction: a time step below --cell-factor is the
            # machine's (a neighbour's load slows identical code by up to 1.6x), not the code's
            threshold = max(cell_factor, spread or 0.0)
            why = f"beyond x{threshold:.3g}: --cell-factor, the instructions within x{instruction_factor:g}"
        elif spread is not None:  # the spread between processes, measured in both runs
            threshold = max(factor, spread)
            why = f"beyond x{threshold:.3g}: the spread between processes x{spread:.3g} and --factor x{factor:g}"
        else:
            threshold, why = cell_factor, f"cell beyond x{cell_factor:g}"
            alone = [side for side, r in (("A", a), ("B", b)) if one_process(r)]
            if alone:  # no spread between processes to judge by: --cell-factor, never --factor
                why += f": timed in its own process in {' and '.join(alone)} (no spread between processes)"
        out.update(process_spread=spread, time_threshold=threshold, bandwidth_ratio=bandwidth)
        attributable = max(factor, spread or 0.0)  # the smallest time ratio any verdict of this cell rests on
        if min(a["cpu_s"], b["cpu_s"]) < short:
            out["time_verdict"] = "too short"
        elif bandwidth is not None and not 1 / attributable <= bandwidth <= attributable:
            out.update(time_verdict="not comparable",
                       not_comparable=f"memory bandwidth differed x{max(bandwidth, 1 / bandwidth):.3g} between the "
                                      f"runs (streaming {'slower' if bandwidth > 1 else 'faster'} in B; beyond "
                                      f"x{attributable:.3g})")
        elif ratio > threshold:
            _slower(out, why)
        elif ratio < 1 / threshold:
            _faster(out, why)
        else:
            out["time_verdict"] = "within"
    errors = {}
    worse = better = False
    for f in sorted(set(error_fields(a)) & set(error_fields(b))):
        ea, eb = a[f], b[f]
        ratio = eb / ea if ea > 0 else (math.inf if eb > 0 else 1.0)
        errors[f] = {"a": ea, "b": eb, "ratio": ratio}
        if ratio > error_factor and eb > ROUND_OFF:
            out["regressions"].append(f"{f} x{ratio:.3g} ({ea:.3g} -> {eb:.3g})")
            worse = True
        elif ratio < 1 / error_factor and ea > ROUND_OFF:
            out["improvements"].append(f"{f} x{ratio:.3g}")
            better = True
    out["errors"] = errors
    out["error_verdict"] = "less accurate" if worse else "more accurate" if better else "same" if errors else None
    changes = {}
    for k in sorted(set(a) | set(b)):
        if k.endswith(".growth_class") and a.get(k) != b.get(k):
            changes[k] = [a.get(k), b.get(k)]
    out["growth_class_changes"] = changes
    return out


def _judge_instructions(out: dict, a: dict, b: dict, factor: float) -> None:
    """The cell's instruction counts (both ok rows counted by the same tool): their ratio,
    the ratio it must pass (``instruction_threshold``: ``factor``, or more for a count so
    small that the counts' noise passes it: longtime.measure.instructions.count_factor) and
    ``instruction_verdict`` (more / fewer / within; "other tool" when two Valgrind versions
    counted; None when a run has no count)."""
    out["instruction_verdict"] = None
    ia, ib = a.get("instructions"), b.get("instructions")
    if not (_number(ia) and _number(ib) and ia > 0 and a.get("status") == Status.OK and b.get("status") == Status.OK):
        return
    if a.get("instructions_tool") != b.get("instructions_tool"):
        out["instruction_verdict"] = "other tool"
        return
    ratio = ib / ia
    factor = count_factor(factor, (ia, ib))
    out.update(instructions_a=ia, instructions_b=ib, instruction_ratio=ratio, instruction_threshold=factor)
    per_step = ""
    if _number(a.get("instructions_per_step")) and _number(b.get("instructions_per_step")):
        per_step = f", {a['instructions_per_step']:.4g} -> {b['instructions_per_step']:.4g} a step"
    text = f"instructions x{ratio:.4g} ({ia:.4g} -> {ib:.4g}{per_step}; beyond x{factor:.4g})"
    if ratio > factor:
        out["instruction_verdict"] = "more"
        out["regressions"].append(text)
    elif ratio < 1 / factor:
        out["instruction_verdict"] = "fewer"
        out["improvements"].append(text)
    else:
        out["instruction_verdict"] = "within"


def _slower(cell: dict, why: str) -> None:
    cell["time_verdict"] = "slower"
    cell["regressions"].insert(0, f"{'cpu' if cell['time_basis'] == 'raw' else 'time'} x{cell['time_ratio']:.3g} "
                                  f"({cell['time_basis']}; {why})")


def _faster(cell: dict, why: str) -> None:
    cell["time_verdict"] = "faster"
    cell["improvements"].insert(0, f"{'cpu' if cell['time_basis'] == 'raw' else 'time'} x{cell['time_ratio']:.3g} "
                                   f"({cell['time_basis']}; {why})")


def _against_unchanged(cells: list[dict], min_cells: int = MIN_BATCHES) -> None:
    """A cell whose instruction count rose (fell) and whose time is within its threshold is
    judged again against the cells whose counts did not change: they did the same work in
    both runs, so the median of their time ratios is what the machine's load did to time
    between the runs (the reference workload, all in registers, does not see it). The
    cell's ratio over that median (``time_ratio_against_unchanged``) beyond its threshold,
    in the direction of its count, makes it slower (faster). Needs ``min_cells`` such cells."""
    same = [c["time_ratio"] for c in cells if c["instruction_verdict"] == "within"
            and c["time_verdict"] in ("within", "slower", "faster")]
    if len(same) < min_cells:
        return
    load = float(np.median(same))
    for c in cells:
        if c["time_verdict"] != "within" or c["instruction_verdict"] not in ("more", "fewer"):
            continue
        ratio = c["time_ratio"] / load
        c["time_ratio_against_unchanged"] = ratio
        why = (f"x{ratio:.3g} against the {len(same)} cells whose instructions did not change (their median "
               f"x{load:.3g}); beyond x{c['time_threshold']:.3g}")
        if c["instruction_verdict"] == "more" and ratio > c["time_threshold"]:
            _slower(c, why)
        elif c["instruction_verdict"] == "fewer" and ratio < 1 / c["time_threshold"]:
            _faster(c, why)


def _lower_median(values: list[float]) -> float:
    """The median; of an even count, the middle value nearer 1 (a verdict needs most of them)."""
    v = sorted(values)
    n = len(v)
    if n % 2:
        return v[n // 2]
    lo, hi = v[n // 2 - 1], v[n // 2]
    return lo if abs(math.log(lo)) < abs(math.log(hi)) else hi


def batch_ratios(cells: list[dict]) -> dict[tuple[str, str], float]:
    """(problem, scheme) -> the geometric mean time ratio of its cells long enough to time."""
    logs: dict[tuple[str, str], list[float]] = {}
    for c in cells:
        if c.get("time_verdict") in ("within", "slower", "faster") and c["time_ratio"] > 0:
            logs.setdefault((c["problem"], c["integrator"]), []).append(math.log(c["time_ratio"]))
    return {k: math.exp(sum(v) / len(v)) for k, v in logs.items()}


def group_verdicts(cells: list[dict], factor: float, min_batches: int = MIN_BATCHES) -> dict[str, dict]:
    """Per scheme (over its problems) and per problem (over its schemes): the median of the
    batch ratios, how many batches, and "slower"/"faster"/"within" (None: too few batches)."""
    ratios = batch_ratios(cells)
    out: dict[str, dict] = {"schemes": {}, "problems": {}}
    for kind, index in (("schemes", 1), ("problems", 0)):
        by: dict[str, list[float]] = {}
        for key, r in ratios.items():
            by.setdefault(key[index], []).append(r)
        for name, values in sorted(by.items()):
            median = _lower_median(values)
            verdict = None
            if len(values) >= min_batches:
                verdict = "slower" if median > factor else "faster" if median < 1 / factor else "within"
            out[kind][name] = {"median_ratio": median, "batches": len(values), "verdict": verdict}
    return out


def apply_group_verdicts(cells: list[dict], factor: float) -> dict[str, dict]:
    """The verdicts per scheme and per problem (``group_verdicts``), applied to ``cells``: a
    cell whose count changed is judged against the cells whose count did not
    (``_against_unchanged``), and a cell within its own threshold is slower (faster) beyond
    ``factor`` where its scheme's or problem's median is."""
    groups = group_verdicts(cells, factor)
    _against_unchanged(cells)
    for c in cells:  # a scheme's or a problem's change of speed: its cells beyond --factor
        if c["time_verdict"] != "within" or c["instruction_verdict"] == "within":  # the same work: the cell's own
            continue
        for kind, name in (("schemes", c["integrator"]), ("problems", c["problem"])):
            g = groups[kind][name]
            why = f"{kind[:-1]} {name}: median x{g['median_ratio']:.3g} over {g['batches']} " \
                  f"{'problems' if kind == 'schemes' else 'schemes'}"
            if g["verdict"] == "slower" and c["time_ratio"] > factor:
                _slower(c, why)
                break
            if g["verdict"] == "faster" and c["time_ratio"] < 1 / factor:
                _faster(c, why)
                break
    return groups
