"""``longtime compare RUN_A RUN_B``: regressions in accuracy as well as speed, cell by cell.

The runs are ids in one store (``--db``), or in two (``--db`` for RUN_A, ``--db-b`` for
RUN_B). Cells are matched by problem, scheme, t_final and every setting. Per common cell:

- time: the ratio B / A of ``cpu_s_calibrated`` (the cell's CPU time in units of the
  machine's reference workload measured beside it, longtime.execution.calibration; ``--raw-time``:
  of ``cpu_s``). Runs of identical code move by more than one process's repeats show: a
  cell keeps one speed in a process and may take another in the next (docs/performance.md,
  "Two speeds"), so a time change is judged against the spread between processes, never
  by a test on the repeats within one. Where both rows were timed in several processes
  (``cpu_s_process_spread``, longtime.execution.processes), a cell is slower when its ratio
  exceeds both ``--factor`` and the larger of the two rows' spreads between processes
  (``time_threshold``); a row timed in one process only (a store from before, or
  ``--processes 1``) is judged against ``--cell-factor`` (``CELL_FACTOR``). A scheme (or a
  problem) is slower when the median ratio of its batches over at least ``MIN_BATCHES``
  problems (schemes) exceeds ``--factor`` (``TIME_FACTOR``), and then each of its cells
  beyond ``--factor`` is slower. Cells whose CPU time is below ``SHORT_CPU_S`` are too short
  to time: they say so instead of a verdict. The Mann-Whitney p-value of the repeats
  (``p_slower``) is still given, for reading only;
- the machine: the reference workload's CPU time in each run (the median of its
  calibrations), and whether it differed;
- accuracy: the ratio B / A of every error and drift field both rows have (``l2_error``,
  ``final_error``, ``NAME.max``, ``NAME.mean``, ``NAME.final``, ``constraint.max``, ``error.*``);
  a loss counts when the ratio exceeds ``--error-factor`` (2) and B's error is above
  ``ROUND_OFF`` (errors at round-off move by such factors with any change of compiler);
- instructions (``--cost instructions`` in both runs, counted by the same Valgrind): the
  ratio B / A of the cell's count. The count is deterministic (runs of identical code agree
  within 1e-4, beside CPU-bound processes too), so a cell whose count grows
  beyond ``--instruction-factor`` (``INSTRUCTION_FACTOR``) regressed, whatever the time
  says. A cell whose counts agree within that factor did the same work: its time is
  judged against ``--cell-factor`` (and the spread between processes, if larger), and it
  takes no verdict from its scheme's or problem's median, since identical code beside a
  neighbour's load moves by up to 1.6x on a shared machine (docs/performance.md, "Hogs,
  identical code and a slower plugin"). Those cells measure the load between the runs: a
  cell whose count rose (fell) is also slower (faster) when its time ratio over their
  median passes its threshold (``time_ratio_against_unchanged``; at least ``MIN_BATCHES``
  such cells);
- growth classes (``NAME.growth_class``) and observed orders (longtime.measure.orders), per
  problem x scheme: every change is listed; a status that was ok and is not any more is a
  regression.

Exit code 1 when anything regressed, 0 otherwise (2: bad input), so CI can use it.
"""
from __future__ import annotations

import json
import math
import sys
from typing import Any

import numpy as np

from longtime.core import jsontext
from longtime.core.params import InputError
from longtime.core.roles import row_columns
from longtime.reporting import machines

# set above the spread measured between runs of identical code, alone and beside CPU-bound
# processes (README, "compare")
TIME_FACTOR = 1.2  # a scheme's (a problem's) median batch ratio beyond this: slower
CELL_FACTOR = 2.0  # a single cell's ratio beyond this: slower
MIN_BATCHES = 3  # batches a scheme's (a problem's) median needs
SHORT_CPU_S = 2e-5  # cells below this CPU time (shorter than any measured) get no time verdict
MACHINE_FACTOR = 1.03  # reference workloads further apart than this: the machine's speed differed
ROUND_OFF = 1e-13
# instruction counts of identical code agree within 1e-4 (docs/performance.md): a change
# beyond 1 % is the code's
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


def compare_rows(a: dict, b: dict, factor: float = TIME_FACTOR, error_factor: float = 2.0,
                 alpha: float = 0.05, raw: bool = False, cell_factor: float = CELL_FACTOR,
                 short: float = SHORT_CPU_S, instruction_factor: float = INSTRUCTION_FACTOR) -> dict[str, Any]:
    """One common cell: its time ratios, its error ratios, growth-class changes and the
    list of regressions (text). The time verdict is the cell's own (``--cell-factor``);
    ``compare`` adds the verdicts of its scheme and problem. ``alpha`` is unused: the
    repeats' p-value (``p_slower``) is reported, not judged."""
    out: dict[str, Any] = {k: a.get(k) for k in MATCH_KEYS}
    out.update(status_a=a.get("status"), status_b=b.get("status"), regressions=[], improvements=[])
    if a.get("status") == "ok" and b.get("status") != "ok":
        out["regressions"].append(f"status ok -> {b.get('status')}")
    if _number(a.get("cpu_s")) and _number(b.get("cpu_s")) and a["cpu_s"] > 0:
        out.update(cpu_a=a["cpu_s"], cpu_b=b["cpu_s"], cpu_ratio=b["cpu_s"] / a["cpu_s"],
                   p_slower=slower_p(a.get("cpu_s_samples") or [], b.get("cpu_s_samples") or []))
    _judge_instructions(out, a, b, instruction_factor)
    timed = _timed(a, b, raw)
    out["time_verdict"] = None
    if _number(a.get("cpu_s_calibrated")) and _number(b.get("cpu_s_calibrated")) and a["cpu_s_calibrated"] > 0:
        out["cpu_calibrated_ratio"] = b["cpu_s_calibrated"] / a["cpu_s_calibrated"]
    if timed is not None and timed[1] > 0 and a.get("status") == "ok" and b.get("status") == "ok":
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
        out.update(process_spread=spread, time_threshold=threshold)
        if min(a["cpu_s"], b["cpu_s"]) < short:
            out["time_verdict"] = "too short"
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
    """The cell's instruction counts (both ok rows counted by the same tool): their ratio
    and ``instruction_verdict`` (more / fewer / within; "other tool" when two Valgrind
    versions counted; None when a run has no count)."""
    out["instruction_verdict"] = None
    ia, ib = a.get("instructions"), b.get("instructions")
    if not (_number(ia) and _number(ib) and ia > 0 and a.get("status") == "ok" and b.get("status") == "ok"):
        return
    if a.get("instructions_tool") != b.get("instructions_tool"):
        out["instruction_verdict"] = "other tool"
        return
    ratio = ib / ia
    out.update(instructions_a=ia, instructions_b=ib, instruction_ratio=ratio)
    per_step = ""
    if _number(a.get("instructions_per_step")) and _number(b.get("instructions_per_step")):
        per_step = f", {a['instructions_per_step']:.4g} -> {b['instructions_per_step']:.4g} a step"
    text = f"instructions x{ratio:.4g} ({ia:.4g} -> {ib:.4g}{per_step}; beyond x{factor:g})"
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


def machine(cal_a: list[dict] | None, cal_b: list[dict] | None) -> dict[str, Any]:
    """The reference workload's CPU time in each run and whether the machine's speed differed."""
    from longtime.execution.calibration import drift

    da, db = drift(cal_a or []), drift(cal_b or [])
    out: dict[str, Any] = {"reference_cpu_s_a": da and da["reference_cpu_s"],
                           "reference_cpu_s_b": db and db["reference_cpu_s"], "ratio": None, "differed": None}
    if da and db:
        ratio = db["reference_cpu_s"] / da["reference_cpu_s"]
        out.update(ratio=ratio, differed=bool(ratio > MACHINE_FACTOR or ratio < 1 / MACHINE_FACTOR))
    return out


def machine_text(m: dict[str, Any]) -> str:
    if m["ratio"] is None:
        missing = " and ".join(x for x, v in (("A", m["reference_cpu_s_a"]), ("B", m["reference_cpu_s_b"])) if v is None)
        return f"machine: no calibration in {missing} (a run stored before calibrations): times compared raw"
    text = (f"machine: reference workload {1e3 * m['reference_cpu_s_a']:.3g} ms in A, "
            f"{1e3 * m['reference_cpu_s_b']:.3g} ms in B (x{m['ratio']:.3g})")
    if m["differed"]:
        return text + f": its speed differed between the runs (beyond x{MACHINE_FACTOR:g}); calibrated times allow for it"
    return text + f": the same speed (within x{MACHINE_FACTOR:g})"


def _fit_key(f: dict) -> tuple:
    return tuple(str(f.get(k)) for k in ("problem", "integrator", "t_final", "order", "settings"))


def order_changes(rows_a: list[dict], rows_b: list[dict]) -> list[dict[str, Any]]:
    """Observed orders (longtime.measure.orders) of the sweeps both runs have: A's, B's and whether
    they differ by more than their combined 95 % intervals and ORDER_TOLERANCE."""
    from longtime.measure.orders import ORDER_TOLERANCE, observed_orders

    fits_b = {_fit_key(f): f for f in observed_orders(rows_b)}
    out = []
    for fa in observed_orders(rows_a):
        fb = fits_b.get(_fit_key(fa))
        if fb is None:
            continue
        cis = [c for c in (fa["observed_order_ci"], fb["observed_order_ci"]) if c is not None]
        bound = max(ORDER_TOLERANCE, math.sqrt(sum(c * c for c in cis)))
        delta = fb["observed_order"] - fa["observed_order"]
        out.append({k: fa.get(k) for k in ("problem", "integrator", "t_final", "order", "settings")}
                   | {"observed_order_a": fa["observed_order"], "observed_order_b": fb["observed_order"],
                      "observed_order_ci_a": fa["observed_order_ci"], "observed_order_ci_b": fb["observed_order_ci"],
                      "declared_order": fa["declared_order"], "order_changed": bool(abs(delta) > bound)})
    return out


def compare(rows_a: list[dict], rows_b: list[dict], factor: float = TIME_FACTOR, error_factor: float = 2.0,
            alpha: float = 0.05, raw: bool = False, cell_factor: float = CELL_FACTOR,
            calibrations: tuple[list[dict] | None, list[dict] | None] = (None, None),
            short: float = SHORT_CPU_S, instruction_factor: float = INSTRUCTION_FACTOR) -> dict[str, Any]:
    """Every common cell compared, the cells only one side has, the verdicts per scheme and
    per problem, the observed orders and growth classes per problem x scheme, the counts
    under each heading (a cell counts once under each it belongs to) and the machine."""
    if not factor > 1 or not error_factor > 1 or not cell_factor >= factor:
        raise InputError(f"--factor {factor} / --error-factor {error_factor} / --cell-factor {cell_factor}: "
                         f"expected numbers > 1, with --cell-factor >= --factor")
    by_a = {cell_key(r): r for r in rows_a}
    by_b = {cell_key(r): r for r in rows_b}
    common = [k for k in by_a if k in by_b]
    if not instruction_factor > 1:
        raise InputError(f"--instruction-factor {instruction_factor}: expected a number > 1")
    cells = [compare_rows(by_a[k], by_b[k], factor, error_factor, alpha, raw, cell_factor, short,
                          instruction_factor) for k in common]
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
    keys = sorted({(c["problem"], c["integrator"]) for c in cells})
    used_a = [by_a[k] for k in common]
    used_b = [by_b[k] for k in common]
    orders = order_changes(used_a, used_b)
    pairs = []
    ratios = batch_ratios(cells)
    for problem, scheme in keys:
        mine = [c for c in cells if c["problem"] == problem and c["integrator"] == scheme]
        growth: dict[str, int] = {}
        for c in mine:
            for k, (x, y) in c["growth_class_changes"].items():
                growth[f"{k} {x} -> {y}"] = growth.get(f"{k} {x} -> {y}", 0) + 1
        pairs.append({"problem": problem, "integrator": scheme, "cells": len(mine),
                      "time_ratio": ratios.get((problem, scheme)),
                      "error_ratios": _error_medians(mine),
                      "orders": [o for o in orders if o["problem"] == problem and o["integrator"] == scheme],
                      "growth_class_changes": growth})
    heading = {
        "time": _count(cells, "time_verdict", ("slower", "faster", "within", "too short", None)),
        "accuracy": _count(cells, "error_verdict", ("less accurate", "more accurate", "same", None)),
        "status": {"no longer ok": sum(any(r.startswith("status ") for r in c["regressions"]) for c in cells)},
        "growth class": {"changed": sum(bool(c["growth_class_changes"]) for c in cells)},
        "observed order": {"changed": sum(o["order_changed"] for o in orders), "compared": len(orders)},
        "instructions": _count(cells, "instruction_verdict", ("more", "fewer", "within", "other tool", None)),
    }
    bases = {c.get("time_basis") for c in cells} - {None}
    return {"cells": cells, "only_a": len(set(by_a) - set(by_b)), "only_b": len(set(by_b) - set(by_a)),
            "regressed": sum(bool(c["regressions"]) for c in cells),
            "improved": sum(bool(c["improvements"]) for c in cells), "counts": heading,
            "time_basis": "/".join(sorted(bases)) or None, "factor": factor, "cell_factor": cell_factor,
            "error_factor": error_factor, "instruction_factor": instruction_factor,
            "short_cpu_s": short, "schemes": groups["schemes"], "problems": groups["problems"], "pairs": pairs,
            "machine": machine(*calibrations), **_left_out(rows_a, rows_b)}


def _left_out(rows_a: list[dict], rows_b: list[dict]) -> dict[str, list[dict]]:
    """Every problem x scheme left out of either run's order table, with why."""
    from longtime.measure.orders import left_out

    return {f"left_out_{side}": [{k: m[k] for k in ("problem", "integrator", "reason")} for m in left_out(rows)]
            for side, rows in (("a", rows_a), ("b", rows_b))}


def _count(cells: list[dict], key: str, values: tuple) -> dict[str, int]:
    return {str(v) if v is not None else "not compared": sum(c.get(key) == v for c in cells) for v in values}


def _error_medians(cells: list[dict]) -> dict[str, float]:
    """Per error field, the median ratio B / A over the cells (finite ratios only)."""
    by: dict[str, list[float]] = {}
    for c in cells:
        for f, e in c["errors"].items():
            if math.isfinite(e["ratio"]):
                by.setdefault(f, []).append(e["ratio"])
    return {f: float(np.median(v)) for f, v in sorted(by.items())}


def label(cell: dict) -> str:
    """Every setting that tells two cells apart (``compare.MATCH_KEYS``), t_final included,
    each value to full precision: two cells never share a header."""
    parts = [str(cell.get("problem")), str(cell.get("integrator"))]
    for k in MATCH_KEYS[2:]:
        v = cell.get(k)
        if v is None or v == "":
            continue
        if k == "settings":
            parts.append(str(v))
        elif isinstance(v, float):
            parts.append(f"{k}={v:.17g}" if float(f"{v:.6g}") != v else f"{k}={v:g}")
        else:
            parts.append(f"{k}={v}")
    return " ".join(parts)


def _counts_text(counts: dict[str, dict[str, int]], result: dict) -> str:
    t, acc = counts["time"], counts["accuracy"]
    basis = result["time_basis"] or "not timed"
    return (f"time ({basis}): {t['slower']} slower, {t['faster']} faster, {t['within']} within the spread, "
            f"{t['too short']} too short to time (< {1e6 * result['short_cpu_s']:g} us); "
            f"accuracy: {acc['less accurate']} less accurate, {acc['more accurate']} more accurate, "
            f"{acc['same']} within x{result['error_factor']:g}; status: {counts['status']['no longer ok']} no longer ok; "
            f"growth class: {counts['growth class']['changed']} changed; observed order: "
            f"{counts['observed order']['changed']} of {counts['observed order']['compared']} changed")


def _instructions_text(result: dict) -> list[str]:
    """The instruction counts' verdict line (none when no cell was counted in both runs)."""
    n = result["counts"].get("instructions")
    if not n or n["not compared"] == len(result["cells"]):
        return []
    other = f", {n['other tool']} counted by another tool (Valgrind or CPU)" if n["other tool"] else ""
    return [f"instructions (beyond x{result['instruction_factor']:g}): {n['more']} more, {n['fewer']} fewer, "
            f"{n['within']} within{other}, {n['not compared']} not counted in both runs"]


def render(result: dict[str, Any], show_all: bool = False) -> str:
    cells = result["cells"]
    lines = [f"{len(cells)} common cells ({result['only_a']} only in A, {result['only_b']} only in B): "
             f"{result['regressed']} regressed, {result['improved']} improved",
             _counts_text(result["counts"], result), machine_text(result["machine"])]
    lines += _instructions_text(result)
    if result.get("provenance"):
        lines += provenance_lines(result["provenance"])
    for kind, over in (("schemes", "problems"), ("problems", "schemes")):
        judged = [f"{name} x{g['median_ratio']:.3g} ({g['verdict']}, {g['batches']} {over})"
                  for name, g in result[kind].items() if g["verdict"] is not None
                  and (show_all or g["verdict"] != "within")]
        if judged:
            lines.append(f"time per {kind[:-1]} (median over its {over}, beyond x{result['factor']:g}): "
                         + "; ".join(judged))
    pair_lines = []
    for p in result["pairs"]:
        notes = [f"{o['integrator']} order {o['observed_order_a']:.2f} -> {o['observed_order_b']:.2f}"
                 + (" CHANGED" if o["order_changed"] else "") for o in p["orders"]
                 if show_all or o["order_changed"]]
        notes += [f"{k} ({n} cell{'s' if n > 1 else ''})" for k, n in p["growth_class_changes"].items()]
        if notes or show_all:
            time = f"time x{p['time_ratio']:.3g}" if p["time_ratio"] is not None else "time -"
            ef = result["error_factor"]
            errs = ", ".join(f"{f} x{r:.3g}" for f, r in p["error_ratios"].items()
                             if show_all or not 1 / ef <= r <= ef) or f"errors within x{ef:g}"
            pair_lines.append(f"  {p['problem']} {p['integrator']} ({p['cells']} cells): {time}; {errs}; "
                              + "; ".join(notes))
    if pair_lines:
        lines.append("per problem x scheme (observed order, growth class):")
        lines += pair_lines
    for c in cells:
        if c["regressions"] or c["improvements"] or c["growth_class_changes"] or show_all:
            if c.get("time_ratio") is not None:
                cpu = f"{'time' if c['time_basis'] == 'calibrated' else 'cpu'} x{c['time_ratio']:.3g}"
                if c["time_verdict"] == "too short":
                    cpu += " (too short to time)"
            else:
                cpu = f"cpu x{c['cpu_ratio']:.3g}" if c.get("cpu_ratio") is not None else "cpu -"
            text = f"  {'REGRESSED' if c['regressions'] else 'ok':9s} {label(c)}"
            if c["time_verdict"] not in ("slower", "faster"):  # those say it below
                text += f": {cpu}"
            if c["regressions"]:
                text += ("; " if c["time_verdict"] not in ("slower", "faster") else ": ") + "; ".join(c["regressions"])
            if c["improvements"]:
                text += "; better: " + ", ".join(c["improvements"])
            for k, (x, y) in c["growth_class_changes"].items():
                text += f"; {k} {x} -> {y}"
            lines.append(text)
    for side in ("a", "b"):
        for m in result.get(f"left_out_{side}", []):
            lines.append(f"  left out of {side.upper()}'s order table: {m['problem']} {m['integrator']} ({m['reason']})")
    if result.get("cross_machine"):
        lines.append("runs A and B ran on different machines: their times compare only calibrated and roughly; "
                     "their instruction counts where the table says they agree")
        lines.append(machines.text(result["cross_machine"]))
    return "\n".join(lines)


def cross_machine_table(store, rows: list[dict]) -> dict[str, Any] | None:
    """The cross-machine table (longtime.reporting.machines) of ``rows`` of ``store``, cells
    matched as compare matches them; None when the rows come from one machine."""
    return machines.cross_machine(rows, store.runs(), store.calibrations, cell_key, label)


def _cross_machine_pair(store_a, rows_a: list[dict], store_b, rows_b: list[dict]) -> dict[str, Any] | None:
    """The cross-machine table of the two compared runs (None on one machine); runs of two
    stores are told apart by giving B's run ids negated."""
    if store_a.path.absolute() == store_b.path.absolute():
        return cross_machine_table(store_a, rows_a + rows_b)
    runs = store_a.runs() + [{**r, "id": -r["id"]} for r in store_b.runs()]
    rows = rows_a + [{**r, "run_id": -r["run_id"]} for r in rows_b]
    return machines.cross_machine(rows, runs, lambda i: store_a.calibrations(i) if i > 0 else store_b.calibrations(-i),
                                  cell_key, label)


def _store(db, readonly: bool = True):
    from longtime.execution.store import Store

    return Store(db, readonly=readonly)


def _rows(db, run: str) -> list[dict]:
    store = _store(db)
    if not (str(run).isascii() and str(run).isdigit()):
        raise InputError(f"run {run!r}: expected a run id (a positive integer) in {store.path}")
    rows = store.rows(int(run))
    if not rows:
        raise InputError(f"run {run} has no rows in {store.path}")
    return rows


def run_compare(db_a, run_a, db_b, run_b, factor: float = TIME_FACTOR, error_factor: float = 2.0,
                alpha: float = 0.05, raw: bool = False, cell_factor: float = CELL_FACTOR,
                instruction_factor: float = INSTRUCTION_FACTOR) -> dict[str, Any]:
    """``compare`` of two stored runs, with their calibrations."""
    rows_a, rows_b = _rows(db_a, run_a), _rows(db_b, run_b)
    cals = (_store(db_a).calibrations(int(run_a)), _store(db_b).calibrations(int(run_b)))
    result = compare(rows_a, rows_b, factor, error_factor, alpha, raw, cell_factor, cals,
                     instruction_factor=instruction_factor)
    if not result["cells"]:
        raise InputError(f"runs {run_a} and {run_b} have no cell in common")
    result["provenance"] = {"a": provenance(_store(db_a).run(int(run_a))), "b": provenance(_store(db_b).run(int(run_b)))}
    result["cross_machine"] = _cross_machine_pair(_store(db_a), rows_a, _store(db_b), rows_b)
    return result


def provenance(run: dict[str, Any]) -> dict[str, Any]:
    """What a stored run measured: its commit, longtime's commit and dirty flag, and the code
    under test (longtime.execution.provenance)."""
    from longtime.execution.provenance import run_code

    try:
        versions = json.loads(run.get("versions") or "{}")
    except ValueError:
        versions = {}
    own = versions.get("longtime_git") if isinstance(versions, dict) else None
    return {"git_commit": run.get("git_commit"), "longtime": versions.get("longtime") if isinstance(versions, dict)
            else None, "longtime_git": own if isinstance(own, dict) else None, "code": run_code(run)}


def provenance_lines(prov: dict[str, Any]) -> list[str]:
    from longtime.execution.provenance import text

    lines = []
    for side in ("a", "b"):
        p = prov[side]
        own = p.get("longtime_git") or {}
        mine = f"{(own.get('commit') or '-')[:10]}{'+dirty' if own.get('dirty') else ''}"
        lines.append(f"run {side.upper()}: commit {(p.get('git_commit') or '-')[:10]}; longtime {p.get('longtime') or '-'} "
                     f"({mine}); code under test: {text(p.get('code') or [])}")
    return lines


def report(result: dict[str, Any], fmt: str = "table", show_all: bool = False) -> int:
    """Print ``result`` (stdout) and the verdict (stderr); the exit code: 1 if anything regressed."""
    print(jsontext.dumps(result) if fmt == "json" else render(result, show_all=show_all))
    if result["regressed"]:
        print(f"{result['regressed']} cell(s) regressed: slower beyond the spread between processes and "
              f"x{result['factor']:g} (x{result['cell_factor']:g} a cell timed in one process, x{result['factor']:g} "
              f"a scheme or problem), more instructions beyond "
              f"x{result.get('instruction_factor', INSTRUCTION_FACTOR):g}, less accurate "
              f"beyond the error factor, or no longer ok", file=sys.stderr)
    return 1 if result["regressed"] else 0


def cmd_compare(args) -> int:
    from longtime.core.progress import Progress

    with Progress().phase("compare", detail=f"runs {args.run_a} and {args.run_b}, cell by cell", announce=False):
        result = run_compare(args.db, args.run_a, args.db_b or args.db, args.run_b, args.factor, args.error_factor,
                             args.alpha, args.raw_time, args.cell_factor, args.instruction_factor)
    return report(result, args.format, args.all)


def add_time_flags(p) -> None:
    """The flags that judge times and errors."""
    p.add_argument("--factor", type=float, default=TIME_FACTOR,
                   help=f"time ratio of a scheme or a problem (median over its batches) that counts as slower "
                        f"(default {TIME_FACTOR:g}: beyond the measured spread of identical runs)")
    p.add_argument("--cell-factor", type=float, default=CELL_FACTOR,
                   help=f"time ratio of a single cell timed in one process that counts as slower (default "
                        f"{CELL_FACTOR:g}); a cell timed in several processes is judged against the spread "
                        f"between them and --factor")
    p.add_argument("--error-factor", type=float, default=2.0,
                   help="error ratio that counts as less accurate (default 2)")
    p.add_argument("--raw-time", action="store_true",
                   help="compare raw CPU seconds instead of calibrated times")


def add_instruction_flag(p) -> None:
    p.add_argument("--instruction-factor", type=float, default=INSTRUCTION_FACTOR,
                   help=f"ratio of a cell's instruction count (--cost instructions in both runs) that counts as "
                        f"more work (default {INSTRUCTION_FACTOR:g}: counts of identical code agree within 1e-4)")


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("compare", help="two runs cell by cell: time and accuracy regressions (exit 1)",
                              description=__doc__.split("\n\n")[0])
    p.add_argument("run_a", metavar="RUN_A", help="the baseline run id")
    p.add_argument("run_b", metavar="RUN_B", help="the run compared with it")
    p.add_argument("--db", default=None, help="the store of RUN_A (and RUN_B unless --db-b)")
    p.add_argument("--db-b", default=None, help="the store of RUN_B")
    add_time_flags(p)
    add_instruction_flag(p)
    p.add_argument("--alpha", type=float, default=0.05,
                   help="kept for scripts that pass it: the repeats' p-value is reported (p_slower), not judged")
    p.add_argument("--all", action="store_true", help="list every common cell, not only the changed ones")
    p.add_argument("--format", choices=["table", "json"], default="table")
    p.set_defaults(func=cmd_compare)
