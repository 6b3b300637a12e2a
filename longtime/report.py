"""Tables of stored rows: accuracy against cost, per problem (pandas)."""
from __future__ import annotations

from typing import Any, Iterable

import pandas as pd

# the JSON contract of DESIGN.md: every row carries these keys (null where not applicable)
CONTRACT_FIELDS = ("problem", "integrator", "status", "message", "dt", "order", "tol", "eps_res",
                   "t_final", "steps", "rhs_evals", "cpu_s", "wall_s", "mean_dt")
PARAMETER_COLUMNS = ("dt", "tol", "eps_res", "order", "settings")
ACCURACY_COLUMNS = ("H.mean", "H.max", "L.max", "I.max", "constraint.max", "l2_error", "final_error")
COST_COLUMNS = ("cpu_s", "steps", "rhs_evals", "nl_iters", "mean_dt")


def complete(row: dict[str, Any]) -> dict[str, Any]:
    return {**{k: None for k in CONTRACT_FIELDS}, **row}


def frame(rows: Iterable[dict[str, Any]]) -> pd.DataFrame:
    return pd.DataFrame([complete(r) for r in rows])


def _fmt(x) -> str:
    if x is None or (isinstance(x, float) and pd.isna(x)):
        return "-"
    if isinstance(x, float):
        return f"{x:.3e}" if (x != 0 and (abs(x) < 1e-2 or abs(x) >= 1e4)) else f"{x:.4g}"
    return str(x)


def problem_table(df: pd.DataFrame) -> pd.DataFrame:
    """One problem's rows, sorted by cost: parameters, status, accuracy, cost."""
    cols = ["integrator"]
    cols += [c for c in PARAMETER_COLUMNS if c in df and df[c].notna().any() and (df[c] != "").any()]
    cols += ["status"]
    cols += [c for c in ACCURACY_COLUMNS if c in df and df[c].notna().any()]
    cols += [c for c in COST_COLUMNS if c in df and df[c].notna().any()]
    out = df[cols].copy()
    return out.sort_values(["status", "cpu_s"] if "cpu_s" in out else ["status"],
                           key=lambda s: s.map(lambda v: v != "ok") if s.name == "status" else s,
                           na_position="last")


def render(rows: list[dict[str, Any]], fmt: str = "table") -> str:
    df = frame(rows)
    if df.empty:
        return "no rows"
    if fmt == "csv":
        return df.to_csv(index=False)
    if fmt == "json":
        return df.to_json(orient="records", indent=1)
    parts = []
    for problem, sub in df.groupby("problem", sort=True):
        table = problem_table(sub)
        if fmt == "markdown":
            text = table.map(_fmt).to_markdown(index=False)
        else:
            text = table.to_string(index=False, formatters={c: _fmt for c in table.columns}, na_rep="-")
        parts.append(f"== {problem}: accuracy against cost ({len(sub)} rows) ==\n{text}")
        notes = sub[sub["status"].isin(["skipped", "failed", "diverged", "timeout"])]
        for _, r in notes.iterrows():
            parts.append(f"  {r['status']}: {r['integrator']}: {r['message']}")
    return "\n\n".join(parts)
