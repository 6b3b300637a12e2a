"""``longtime compare RUN_A RUN_B``: regressions in accuracy as well as speed, cell by cell.

The runs are ids in one store (``--db``), or in two (``--db`` for RUN_A, ``--db-b`` for
RUN_B). Cells are matched by problem, scheme, t_final and every setting. Per common cell:

- time: the ratio of the minimum CPU times (B / A) and a one-sided Mann-Whitney U test of
  the repeats' CPU times (``cpu_s_samples``), as asv compare does; a slowdown counts when
  the ratio exceeds ``--factor`` (1.1) and the test gives p <= ``--alpha`` (0.05) (rows
  without samples: the ratio alone);
- accuracy: the ratio B / A of every error and drift field both rows have (``l2_error``,
  ``final_error``, ``NAME.max``, ``NAME.mean``, ``NAME.final``, ``constraint.max``, ``error.*``);
  a loss counts when the ratio exceeds ``--error-factor`` (2) and B's error is above
  ``ROUND_OFF`` (errors at round-off move by such factors with any change of compiler);
- growth classes (``NAME.growth_class``): every change is listed; a status that was ok
  and is not any more is a regression.

Exit code 1 when anything regressed, 0 otherwise (2: bad input), so CI can use it.
"""
from __future__ import annotations

import json
import math
import sys
from typing import Any

from .params import InputError
from .roles import row_columns

ROUND_OFF = 1e-13
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


def compare_rows(a: dict, b: dict, factor: float = 1.1, error_factor: float = 2.0,
                 alpha: float = 0.05) -> dict[str, Any]:
    """One common cell: its time ratio and test, its error ratios, growth-class changes
    and the list of regressions (text)."""
    out: dict[str, Any] = {k: a.get(k) for k in MATCH_KEYS}
    out.update(status_a=a.get("status"), status_b=b.get("status"), regressions=[], improvements=[])
    if a.get("status") == "ok" and b.get("status") != "ok":
        out["regressions"].append(f"status ok -> {b.get('status')}")
    if _number(a.get("cpu_s")) and _number(b.get("cpu_s")) and a["cpu_s"] > 0:
        ratio = b["cpu_s"] / a["cpu_s"]
        p = slower_p(a.get("cpu_s_samples") or [], b.get("cpu_s_samples") or [])
        p_faster = slower_p(b.get("cpu_s_samples") or [], a.get("cpu_s_samples") or [])
        out.update(cpu_a=a["cpu_s"], cpu_b=b["cpu_s"], cpu_ratio=ratio, p_slower=p)
        if ratio > factor and (p is None or p <= alpha):
            out["regressions"].append(f"cpu x{ratio:.3g}" + (f" (p={p:.3g})" if p is not None else ""))
        elif ratio < 1 / factor and (p_faster is None or p_faster <= alpha):
            out["improvements"].append(f"cpu x{ratio:.3g}")
    errors = {}
    for f in sorted(set(error_fields(a)) & set(error_fields(b))):
        ea, eb = a[f], b[f]
        ratio = eb / ea if ea > 0 else (math.inf if eb > 0 else 1.0)
        errors[f] = {"a": ea, "b": eb, "ratio": ratio}
        if ratio > error_factor and eb > ROUND_OFF:
            out["regressions"].append(f"{f} x{ratio:.3g} ({ea:.3g} -> {eb:.3g})")
        elif ratio < 1 / error_factor and ea > ROUND_OFF:
            out["improvements"].append(f"{f} x{ratio:.3g}")
    out["errors"] = errors
    changes = {}
    for k in sorted(set(a) | set(b)):
        if k.endswith(".growth_class") and a.get(k) != b.get(k):
            changes[k] = [a.get(k), b.get(k)]
    out["growth_class_changes"] = changes
    return out


def compare(rows_a: list[dict], rows_b: list[dict], factor: float = 1.1, error_factor: float = 2.0,
            alpha: float = 0.05) -> dict[str, Any]:
    """Every common cell compared, and the cells only one side has."""
    if not factor > 1 or not error_factor > 1:
        raise InputError(f"--factor {factor} / --error-factor {error_factor}: expected numbers > 1")
    by_a = {cell_key(r): r for r in rows_a}
    by_b = {cell_key(r): r for r in rows_b}
    common = [k for k in by_a if k in by_b]
    cells = [compare_rows(by_a[k], by_b[k], factor, error_factor, alpha) for k in common]
    return {"cells": cells, "only_a": len(set(by_a) - set(by_b)), "only_b": len(set(by_b) - set(by_a)),
            "regressed": sum(bool(c["regressions"]) for c in cells), **compare_orders(rows_a, rows_b)}


ORDER_KEYS = ("problem", "integrator", "t_final", "order", "settings")


def compare_orders(rows_a: list[dict], rows_b: list[dict]) -> dict[str, Any]:
    """The observed orders of both runs side by side ("orders": each sweep with its order in
    A and in B, None where that run has no fit; "changed" when they differ by more than
    either interval and 0.1), and every problem x scheme left out of either run's order
    table, with why ("left_out_a", "left_out_b")."""
    from .orders import ORDER_TOLERANCE, left_out, observed_orders

    fits = [{tuple(str(f.get(k)) for k in ORDER_KEYS): f for f in observed_orders(rows)} for rows in (rows_a, rows_b)]
    out = []
    for key in sorted(set(fits[0]) | set(fits[1])):
        a, b = fits[0].get(key), fits[1].get(key)
        first = a or b
        entry = {k: first.get(k) for k in ORDER_KEYS}
        entry.update(declared_order=first["declared_order"],
                     order_a=a and a["observed_order"], ci_a=a and a["observed_order_ci"],
                     order_b=b and b["observed_order"], ci_b=b and b["observed_order_ci"])
        entry["changed"] = bool(a and b and abs(a["observed_order"] - b["observed_order"]) > max(
            a["observed_order_ci"] or 0.0, b["observed_order_ci"] or 0.0, ORDER_TOLERANCE))
        out.append(entry)
    return {"orders": out,
            "left_out_a": [{k: m[k] for k in ("problem", "integrator", "reason")} for m in left_out(rows_a)],
            "left_out_b": [{k: m[k] for k in ("problem", "integrator", "reason")} for m in left_out(rows_b)]}


def _label(c: dict) -> str:
    from .report import setting

    return f"{c['problem']} {c['integrator']} {setting(c)}".strip()


def render(result: dict[str, Any], show_all: bool = False) -> str:
    cells = result["cells"]
    lines = [f"{len(cells)} common cells ({result['only_a']} only in A, {result['only_b']} only in B): "
             f"{result['regressed']} regressed, {sum(bool(c['improvements']) for c in cells)} improved"]
    for c in cells:
        if c["regressions"] or c["improvements"] or c["growth_class_changes"] or show_all:
            cpu = f"cpu x{c['cpu_ratio']:.3g}" if c.get("cpu_ratio") is not None else "cpu -"
            text = f"  {'REGRESSED' if c['regressions'] else 'ok':9s} {_label(c)}: {cpu}"
            if c["regressions"]:
                text += "; " + "; ".join(c["regressions"])
            if c["improvements"]:
                text += "; better: " + ", ".join(c["improvements"])
            for k, (x, y) in c["growth_class_changes"].items():
                text += f"; {k} {x} -> {y}"
            lines.append(text)
    for o in result.get("orders", []):
        if o["changed"] or show_all:
            lines.append(f"  {'CHANGED' if o['changed'] else 'ok':9s} {o['problem']} {o['integrator']}: observed order "
                         f"{_order(o['order_a'], o['ci_a'])} -> {_order(o['order_b'], o['ci_b'])}"
                         + (f" (declared {o['declared_order']})" if o["declared_order"] is not None else ""))
    for side in ("a", "b"):
        for m in result.get(f"left_out_{side}", []):
            lines.append(f"  left out of {side.upper()}'s order table: {m['problem']} {m['integrator']} ({m['reason']})")
    return "\n".join(lines)


def _order(value: float | None, ci: float | None) -> str:
    if value is None:
        return "-"
    return f"{value:.2f}" + (f"+-{ci:.2f}" if ci is not None else "")


def _rows(db, run: str) -> list[dict]:
    from .store import Store

    store = Store(db, readonly=True)
    if not str(run).isdigit():
        raise InputError(f"run {run!r}: expected a run id (a positive integer) in {store.path}")
    rows = store.rows(int(run))
    if not rows:
        raise InputError(f"run {run} has no rows in {store.path}")
    return rows


def cmd_compare(args) -> int:
    rows_a = _rows(args.db, args.run_a)
    rows_b = _rows(args.db_b or args.db, args.run_b)
    result = compare(rows_a, rows_b, args.factor, args.error_factor, args.alpha)
    if not result["cells"]:
        raise InputError(f"runs {args.run_a} and {args.run_b} have no cell in common")
    if args.format == "json":
        print(json.dumps(result, indent=1))
    else:
        print(render(result, show_all=args.all))
    if result["regressed"]:
        print(f"{result['regressed']} cell(s) regressed beyond x{args.factor:g} (time) or "
              f"x{args.error_factor:g} (errors)", file=sys.stderr)
    return 1 if result["regressed"] else 0


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("compare", help="two runs cell by cell: time and accuracy regressions (exit 1)",
                              description=__doc__.split("\n\n")[0])
    p.add_argument("run_a", metavar="RUN_A", help="the baseline run id")
    p.add_argument("run_b", metavar="RUN_B", help="the run compared with it")
    p.add_argument("--db", default=None, help="the store of RUN_A (and RUN_B unless --db-b)")
    p.add_argument("--db-b", default=None, help="the store of RUN_B")
    p.add_argument("--factor", type=float, default=1.1, help="CPU ratio that counts as slower (default 1.1)")
    p.add_argument("--error-factor", type=float, default=2.0,
                   help="error ratio that counts as less accurate (default 2)")
    p.add_argument("--alpha", type=float, default=0.05,
                   help="significance of the Mann-Whitney U test on the repeats (default 0.05)")
    p.add_argument("--all", action="store_true", help="list every common cell, not only the changed ones")
    p.add_argument("--format", choices=["table", "json"], default="table")
    p.set_defaults(func=cmd_compare)
