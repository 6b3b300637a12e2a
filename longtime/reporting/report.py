"""Reports of stored rows (pandas): the full per-cell tables (``--full``, csv, json,
markdown, parquet) and the summary per problem (status counts, the verdict, the Pareto front
of accuracy against cost, the fitted orders and growth classes); the first screen the
report prints by default is longtime.reporting.screen.

In Python: ``frame(Store("longtime.sqlite").rows())`` is one pandas row per cell."""
from __future__ import annotations

import io
from typing import Any, Iterable

import pandas as pd

from longtime.core import jsontext
from longtime.core.files import write_atomic
from longtime.core.fmt import positive
from longtime.core.roles import ROW_PARAMETERS, row_columns
from longtime.core.rowschema import formatted
from longtime.core.rowtext import main_t_final, setting  # noqa: F401 (their home; read from here too)
from longtime.core.status import STATUSES, Status, bounded
from longtime.measure.lyapunov import past_predictability
from longtime.predict.need import PARETO_FIELDS, pareto_field  # noqa: F401 (their home; read from here too)
from longtime.predict.settings import SOLUTION_FIELDS
from longtime.reporting.recommend import map_verdicts
from longtime.reporting.verdict import verdict_lines

# the JSON contract (README.md, `--format json`): every row carries these keys (null where not applicable)
CONTRACT_FIELDS = ("problem", "integrator", "status", "message", *ROW_PARAMETERS,
                   "t_final", "steps", "rhs_evals", "cpu_s", "wall_s", "mean_dt")
# a row's parameters: its parameter fields by role (step, accuracy, order), then the rest
PARAMETER_COLUMNS = (*row_columns(), "settings")
ACCURACY_COLUMNS = ("H.mean", "H.max", "L.max", "I.max", "constraint.max", "l2_error", "final_error")
COST_COLUMNS = ("cpu_s", "steps", "rhs_evals", "nl_iters", "mean_dt", "instructions_per_step")


def complete(row: dict[str, Any]) -> dict[str, Any]:
    return {**{k: None for k in CONTRACT_FIELDS}, **row}


def frame(rows: Iterable[dict[str, Any]]) -> pd.DataFrame:
    return pd.DataFrame([complete(r) for r in rows])


def _formatted(table: pd.DataFrame) -> pd.DataFrame:
    """Each column's values as text, as their row field formats them (rowschema.formatted)."""
    return table.apply(lambda column: column.map(lambda v: formatted(column.name, v)))


def problem_table(df: pd.DataFrame) -> pd.DataFrame:
    """One problem's rows, sorted by cost: parameters, status, accuracy, cost."""
    cols = ["integrator"]
    cols += [c for c in PARAMETER_COLUMNS if c in df and df[c].notna().any() and (df[c] != "").any()]
    cols += ["status"]
    cols += [c for c in ACCURACY_COLUMNS if c in df and df[c].notna().any()]
    cols += [c for c in COST_COLUMNS if c in df and df[c].notna().any()]
    out = df[cols].copy()
    return out.sort_values(["status", "cpu_s"] if "cpu_s" in out else ["status"],
                           key=lambda s: s.map(lambda v: v != Status.OK) if s.name == "status" else s,
                           na_position="last")


def _object_frame(rows: list[dict[str, Any]]) -> pd.DataFrame:
    """The rows for output: every value as stored, so that each float round-trips bitwise
    and a count stays an integer beside nulls (object columns: ``frame`` would make it a
    float), and a list or dict (a confidence interval, the drift curve) as JSON text."""
    import json

    df = pd.DataFrame([complete(r) for r in rows], dtype=object)
    for c in df.columns:
        if df[c].map(lambda v: isinstance(v, (list, dict))).any():
            df[c] = df[c].map(lambda v: json.dumps(v) if isinstance(v, (list, dict)) else v)
    return df


def render(rows: list[dict[str, Any]], fmt: str = "table") -> str:
    """The rows as text. csv and json hold every stored value at full precision (floats
    as repr: they read back bitwise); table and markdown are for reading: 4 significant
    digits, exponent notation below 1e-2 (so a tiny value never shows as 0), '-' for null."""
    if not rows:
        return "[]" if fmt == "json" else "no rows"
    if fmt == "json":

        return jsontext.dumps([complete(r) for r in rows])
    if fmt == "csv":
        return _object_frame(rows).to_csv(index=False)
    df = _object_frame(rows)
    parts = []
    for problem, sub in df.groupby("problem", sort=True):
        table = problem_table(sub)
        if fmt == "markdown":
            text = _formatted(table).to_markdown(index=False)
        else:
            text = _formatted(table).to_string(index=False)
        parts.append(f"== {problem}: accuracy against cost ({len(sub)} rows) ==\n{text}")
        notes = sub[sub["status"].isin([Status.SKIPPED, Status.FAILED, Status.DIVERGED, Status.TIMEOUT])]
        for _, r in notes.iterrows():
            parts.append(f"  {r['status']}: {r['integrator']}: {r['message']}")
    return "\n\n".join(parts)


# ------------------------------------------------------------------ the summary read first
# the accuracy a Pareto front ranks by is the first of PARETO_FIELDS present (the solution
# error where a reference exists, the largest error over the run first, else the energy
# drift): longtime.predict.need
DECADES = tuple(10.0 ** -k for k in range(1, 16))


def status_counts(rows: Iterable[dict[str, Any]]) -> dict[str, int]:
    counts = {s: 0 for s in STATUSES}
    for r in rows:
        counts[r.get("status") or "unknown"] = counts.get(r.get("status") or "unknown", 0) + 1
    return counts


def format_counts(counts: dict[str, int], stopped: int = 0) -> str:
    """'5 ok, 3 timeout (2 stopped at their library's bound)': ``stopped`` of the timeouts
    are library peers' runs stopped at their chain's bound (``status.bounded``)."""
    shown = [f"{n} {s}" + (f" ({stopped} stopped at their library's bound)" if stopped and s == Status.TIMEOUT else "")
             for s, n in counts.items() if n]
    return ", ".join(shown) or "no rows"


def counts_text(rows: list[dict[str, Any]]) -> str:
    """The statuses of ``rows`` counted, as format_counts says them."""
    return format_counts(status_counts(rows), sum(map(bounded, rows)))


def pareto(rows: list[dict[str, Any]], field: str | None = None) -> list[dict[str, Any]]:
    """For one problem's rows at its main final time (errors over different spans do not
    compare): per accuracy decade 10^-k, the fastest ok row whose ``field`` is at most 10^-k
    (minimum CPU of its repeats), and the fastest row of another scheme meeting the same
    target (``next``, with ``slower`` = its time / the fastest's). Only decades some row
    meets, from the coarsest to the finest. A chaotic problem's row whose solution error
    reached O(1) has no L2 accuracy to offer (``lyapunov.past_predictability``)."""
    field = field or pareto_field(rows)
    t_main = main_t_final(rows)
    ok = [r for r in rows if r.get("status") == Status.OK and positive(r.get("cpu_s")) and positive(r.get(field))
          and r.get("t_final") == t_main and not (field in SOLUTION_FIELDS and past_predictability(r))]
    out = []
    for target in DECADES:
        meets = sorted((r for r in ok if r[field] <= target), key=lambda r: r["cpu_s"])
        if not meets:
            break
        best = meets[0]
        runner = next((r for r in meets if r["integrator"] != best["integrator"]), None)
        out.append({"target": target, "field": field, "best": best, "next": runner,
                    "slower": runner["cpu_s"] / best["cpu_s"] if runner else None})
    return out


def pareto_groups(front: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Consecutive decades with the same fastest row and the same runner-up folded into one
    entry: ``target`` the loosest, ``finest`` the tightest of them."""
    out: list[dict[str, Any]] = []
    for p in front:
        last = out[-1] if out else None
        if last and last["best"] is p["best"] and last["next"] is p["next"]:
            last["finest"] = p["target"]
        else:
            out.append({**p, "finest": p["target"]})
    return out


def target_text(p: dict[str, Any]) -> str:
    return f"{p['target']:.0e}" if p["finest"] == p["target"] else f"{p['target']:.0e}..{p['finest']:.0e}"


def growth_names(rows: list[dict[str, Any]]) -> list[str]:
    """The names with a growth class in ``rows``: the invariants in the order the rows give
    them, then ``error``."""
    names = list(dict.fromkeys(k[: -len(".growth_class")] for r in rows for k in r
                               if k.endswith(".growth_class") and r.get(k)))
    return [n for n in names if n != "error"] + (["error"] if "error" in names else [])


def growth_settings(rows: list[dict[str, Any]]) -> list[tuple[str, list[dict[str, Any]]]]:
    """One scheme's ok rows with a growth class, as (setting text, rows): the longest run
    first (then the smallest step). The setting names t_final where the scheme ran to
    more than one."""
    mine = [r for r in rows if r.get("status") == Status.OK
            and any(k.endswith(".growth_class") and r.get(k) for k in r)]
    several = len({r.get("t_final") for r in mine}) > 1
    mine.sort(key=lambda r: (-(r.get("t_final") or 0.0), r.get("dt") or 0.0, r.get("tol") or 0.0, setting(r)))
    out: list[tuple[str, list[dict[str, Any]]]] = []
    for r in mine:
        text = " ".join(x for x in (setting(r), f"t={r['t_final']:.4g}" if several and r.get("t_final") else "") if x)
        if out and out[-1][0] == text:
            out[-1][1].append(r)
        else:
            out.append((text, [r]))
    return out


def _growth_summary(rows: list[dict[str, Any]]) -> list[str]:
    """Per scheme, the growth class of the energy H (else the first invariant) and of the
    solution error at each of its settings, the longest run first; settings with the same
    classes share a group ('rk4: H linear, error quadratic (dt=0.01, dt=0.02)'); then each
    undetermined class with its reason."""
    names = growth_names(rows)
    drift = "H" if "H" in names else next((n for n in names if n != "error"), None)
    shown = [n for n in (drift, "error") if n in names]
    if not shown:
        return []
    lines, why = [], {}
    for scheme in sorted({r["integrator"] for r in rows}):
        groups: dict[str, list[str]] = {}
        for text, mine in growth_settings([r for r in rows if r["integrator"] == scheme]):
            r = mine[0]
            classes = ", ".join(f"{n} {r.get(f'{n}.growth_class') or '-'}" for n in shown)
            groups.setdefault(classes, []).append(text or "-")
            for n in shown:
                if r.get(f"{n}.growth_class") == "undetermined":
                    kind, _, detail = str(r.get(f"{n}.growth_reason") or "-").partition(": ")
                    why.setdefault((kind, scheme, n), []).append(f"{text or '-'} ({detail})" if detail else text)
        if groups:
            lines.append(f"{scheme}: " + "; ".join(f"{c} ({', '.join(t)})" for c, t in groups.items()))
    out = [f"growth of {', '.join(shown)} per setting (the longest run first):"]
    out += [f"  {line}" for line in lines]
    # each undetermined class with its reason: one line per scheme, name and kind of reason
    out += [f"  undetermined, {kind}: {scheme} {n} at {'; '.join(settings)}"
            for (kind, scheme, n), settings in sorted(why.items(), key=lambda kv: (kv[0][1], kv[0][2], kv[0][0]))]
    return out if lines else []


def _order_text(f: dict[str, Any]) -> str:
    """'rk4 4.70 +- 0.53/4 MISSES': observed +- 95 % / declared."""
    from longtime.measure.orders import fit_text

    text = f"{f['integrator']}{'' if f['order'] is None else ' N=' + str(f['order'])} {fit_text(f)}"
    text += f"/{f['declared_order']}" if f["declared_order"] is not None else ""
    return text + (" MISSES" if f["order_flag"] else "")


# the default report's lines per problem at most (``--full`` prints every line)
MAX_PROBLEM_LINES = 60


def _growth_counts(rows: list[dict[str, Any]]) -> list[str]:
    """'growth classes of error: 7 linear, 7 quadratic, 39 undetermined (--full: per setting)'
    for the solution error and the energy H (else the first invariant)."""
    names = growth_names(rows)
    drift = "H" if "H" in names else next((n for n in names if n != "error"), None)
    out = []
    for n in (x for x in ("error", drift) if x in names):
        counts: dict[str, int] = {}
        for r in rows:
            c = r.get(f"{n}.growth_class")
            if r.get("status") == Status.OK and c:
                counts[c] = counts.get(c, 0) + 1
        text = ", ".join(f"{k} {counts[k]}" for k in sorted(counts, key=lambda k: -counts[k]))
        out.append(f"growth of {'the solution error' if n == 'error' else n} per setting: {text}")
    return out + (["(`--full`: each setting's class and each undetermined one's reason)"] if out else [])


def summary(rows: list[dict[str, Any]], orders: bool = True, full: bool = False,
            checks: Iterable[dict[str, Any]] = (), ensembles: Iterable[dict[str, Any]] = ()) -> str:
    """The terminal report read first: status counts, then per problem the verdict (the
    cheapest setting predicted per target and horizon, longtime.reporting.verdict), its
    Pareto front at the run's final time (one line per accuracy decade), fitted orders that
    miss their declared order, growth classes (counted; ``full``: per setting, with the
    reasons), what did not run to the end and the settings the default matrix's budget moved
    (one line per pair), a chaotic problem's ensemble distances (one line, from the stored
    ``ensembles``), at most MAX_PROBLEM_LINES lines a problem unless ``full``."""
    from longtime.execution.budget import notes
    from longtime.execution.ensembles import summary as ensemble_summary
    from longtime.measure.orders import left_out, left_out_text, observed_orders

    if not rows:
        return "no rows"
    parts = [f"{len(rows)} cells: {counts_text(rows)}"]
    fits = observed_orders(rows) if orders else []
    missing = left_out(rows) if orders else []
    moved = notes(rows)
    found = map_verdicts(rows, checks)
    chaos = ensemble_summary(list(ensembles))
    for problem in sorted({r["problem"] for r in rows}):
        mine = [r for r in rows if r["problem"] == problem]
        lines = [f"== {problem}: {counts_text(mine)} =="]
        lines += verdict_lines(found[problem], full)
        failed = [f"  {why}: {', '.join(schemes)}" for why, schemes in sorted(not_ok(mine).items())]
        lines += failed  # what failed comes right after the verdict: it never falls to the cut below
        if problem in chaos:
            lines.append(f"  ensemble distance to heyoka's (W1 / std, late window): {chaos[problem]}")
        lines += [f"  moved by the default matrix's budget: {scheme} {note}"
                  for (p, scheme), note in sorted(moved.items()) if p == problem]
        field = pareto_field(mine)
        front = pareto(mine, field) if field else []
        if front:
            lines.append(f"  fastest scheme per accuracy ({field} <= target at t_final {main_t_final(mine):.6g}; "
                         f"CPU s, minimum of repeats):")
            for p in pareto_groups(front):
                b, n = p["best"], p["next"]
                nxt = f"next {n['integrator']} x{p['slower']:.3g}" if n else "no other scheme"
                lines.append(f"  {target_text(p):>14s}  {b['integrator']:<16s} {setting(b):<20s} "
                             f"{b['cpu_s']:9.3g} s  {nxt}")
        else:
            lines.append("  no ok row with an error and a CPU time")
        mine_fits = [f for f in fits if f["problem"] == problem]
        if mine_fits:
            lines.append("  observed/declared order (+- 95 %): " + "; ".join(_order_text(f) for f in mine_fits))
        mine_missing = [m for m in missing if m["problem"] == problem]
        if mine_missing:
            lines.append("  left out of the order table: " + left_out_text(mine_missing))
        lines += [f"  {g}" for g in (_growth_summary(mine) if full else _growth_counts(mine))]
        if not full and len(lines) > MAX_PROBLEM_LINES:
            cut = len(lines) - MAX_PROBLEM_LINES + 1
            lines = lines[:MAX_PROBLEM_LINES - 1] + [f"  ... {cut} more lines: `--full` prints them"]
        parts.append("\n".join(lines))
    return "\n\n".join(parts)


# an ok row whose error reached O(1) (metrics.O1_ERROR): it ran to the end, but lost the solution
LOST = "ok but error O(1), the solution not followed"
# a library peer's run stopped at its chain's CPU bound (status.bounded): no failure
STOPPED = "stopped at its library's bound (a cheaper setting of its library keeps the target: not its answer)"


def not_ok(rows: list[dict[str, Any]]) -> dict[str, list[str]]:
    """Rows that did not run to the end, or lost the solution, folded: 'skipped (needs
    constraints, which toda does not provide)' -> schemes; 'diverged' -> ['rk4 (2 of 3)', ...];
    a run stopped at its chain's bound under STOPPED, not a timeout."""
    kinds = [(s, lambda r, s=s: r.get("status") == s and not bounded(r))
             for s in (Status.SKIPPED, Status.DIVERGED, Status.FAILED, Status.TIMEOUT)]
    kinds.append((LOST, lambda r: r.get("status") == Status.OK and bool(r.get("solution_lost"))))
    kinds.append((STOPPED, bounded))
    out: dict[str, list[str]] = {}
    for kind, of_kind in kinds:
        for scheme in sorted({r["integrator"] for r in rows if of_kind(r)}):
            mine = [r for r in rows if r["integrator"] == scheme]
            bad = [r for r in mine if of_kind(r)]
            if kind == Status.SKIPPED:
                why = str(bad[0].get("message") or "").removeprefix(scheme + " ")
                out.setdefault(f"skipped ({why})", []).append(scheme)
            else:
                out.setdefault(kind, []).append(f"{scheme} ({len(bad)} of {len(mine)})")
    return out


# ------------------------------------------------------------------ the tables as a file
def to_parquet(rows: list[dict[str, Any]], path) -> None:
    """Every row as one parquet table (list values, such as confidence intervals, as JSON text)."""
    df = _object_frame(rows).infer_objects()  # typed columns: a float column stays float64
    try:
        buffer = io.BytesIO()
        df.to_parquet(buffer, index=False)
    except ImportError as exc:
        from longtime.core.params import InputError

        raise InputError(f"--format parquet needs a parquet engine: pip install pyarrow "
                         f"(the extra longtime[parquet]); {str(exc).splitlines()[0]}") from None
    write_atomic(path, buffer.getvalue())
