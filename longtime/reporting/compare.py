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
  (``time_threshold``); a row timed in one process only (a store from before, ``--processes
  1``, or a cell the main job's timing by need left in its own process: its ``timed_in``)
  is judged against ``--cell-factor`` (``CELL_FACTOR``), never ``--factor``. A scheme (or a
  problem) is slower when the median ratio of its batches over at least ``MIN_BATCHES``
  problems (schemes) exceeds ``--factor`` (``TIME_FACTOR``), and then each of its cells
  beyond ``--factor`` is slower. Cells whose CPU time is below ``SHORT_CPU_S`` are too short
  to time: they say so instead of a verdict. The Mann-Whitney p-value of the repeats
  (``p_slower``) is still given, for reading only;
- the machine: the reference workload's CPU time in each run (the median of its
  calibrations), and whether it differed; the streaming workload's (a triad over arrays
  beyond the last-level cache): where it differed between the runs beyond a cell's
  ``--factor`` and spread between processes, either way, a neighbour streamed memory in one run and not in
  the other, and the cell's time gets no verdict ("not comparable", with the ratio;
  longtime.reporting.compare_machine). Its instruction counts, where both runs have them,
  still judge it. A run stored before the bandwidth check (calibrated without the streaming
  workload, or not calibrated) is judged as it is: the machine line says it lacks it, a line
  counts the time verdicts given without the check (``time_unchecked``; why:
  ``bandwidth_unchecked``, also on each such cell), and each such time regression or
  improvement ends "[without the memory-bandwidth check]";
- accuracy: the ratio B / A of every error and drift field both rows have (``l2_error``,
  ``final_error``, ``NAME.max``, ``NAME.mean``, ``NAME.final``, ``constraint.max``, ``error.*``);
  a loss counts when the ratio exceeds ``--error-factor`` (2) and B's error is above
  ``ROUND_OFF`` (errors at round-off move by such factors with any change of compiler);
- instructions (``--cost instructions`` in both runs, counted by the same Valgrind): the
  ratio B / A of the cell's count. The count is deterministic (identical code counted in any
  batch, order or process, beside CPU-bound processes too, agrees within
  longtime.measure.instructions.COUNT_NOISE instructions a call; a cell's threshold rises
  above the factor where that noise is a larger share of its count,
  ``instruction_threshold``), so a cell whose count grows
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
from longtime.reporting import machines
from longtime.reporting.compare_cells import (
    CELL_FACTOR,
    INSTRUCTION_FACTOR,
    SHORT_CPU_S,
    TIME_FACTOR,
    apply_group_verdicts,
    batch_ratios,
    cell_key,
    compare_rows,
)
from longtime.reporting.compare_machine import bandwidth_unchecked, machine
from longtime.reporting.compare_text import label, render


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
    machine_ab = machine(*calibrations)
    cells = [compare_rows(by_a[k], by_b[k], factor, error_factor, alpha, raw, cell_factor, short,
                          instruction_factor, machine_ab["bandwidth_ratio"]) for k in common]
    groups = apply_group_verdicts(cells, factor)
    _mark_unchecked(cells, bandwidth_unchecked(machine_ab))
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
        "time": _count(cells, "time_verdict", ("slower", "faster", "within", "too short", "not comparable", None)),
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
            "machine": machine_ab, "bandwidth_unchecked": bandwidth_unchecked(machine_ab),
            "time_unchecked": sum(bool(c.get("bandwidth_unchecked")) for c in cells), **_left_out(rows_a, rows_b)}


def _mark_unchecked(cells: list[dict], reason: str | None) -> None:
    """Where the runs' bandwidths were not compared (``reason``), each cell with a time verdict
    (slower, faster, within) gains ``bandwidth_unchecked`` (the reason), and its time
    regression or improvement says it was judged without the check."""
    for c in cells:
        c["bandwidth_unchecked"] = None
        if reason is None or c["time_verdict"] not in ("slower", "faster", "within"):
            continue
        c["bandwidth_unchecked"] = reason
        said = c["regressions"] if c["time_verdict"] == "slower" else c["improvements"]
        for i, text in enumerate(said if c["time_verdict"] != "within" else []):
            if text.startswith(("time x", "cpu x")):  # the cell's time verdict (compare_cells._slower)
                said[i] = f"{text} [without the memory-bandwidth check]"
                break


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
    result["provenance"] = {"a": provenance(_store(db_a).run(int(run_a))),
                            "b": provenance(_store(db_b).run(int(run_b)))}
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
