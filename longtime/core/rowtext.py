"""A stored row's setting as text, and the final time most of a problem's rows ran to: read
by the report, the page, its figures and the verdict."""
from __future__ import annotations

from typing import Any

from longtime.core.fmt import positive
from longtime.core.roles import row_fields
from longtime.core.status import Status


def setting(row: dict[str, Any]) -> str:
    """The swept parameters of a row as text: 'dt=0.01', 'tol=1e-08', 'eps_res=1e-06 N=10'
    (the step only where no accuracy parameter is set), then its other settings."""
    accuracy = any(row.get(k) for k in row_fields("accuracy"))
    parts = [f"{k}={row[k]:.3g}" for k in (*row_fields("step"), *row_fields("accuracy"))
             if positive(row.get(k)) and not (k in row_fields("step") and accuracy)]
    for k in row_fields("order"):
        order = row.get(k)
        if positive(order):
            parts.append(f"N={int(order)}")
        elif order is not None and order == order:  # a stored value that is not a number: shown as it is
            parts.append(f"N={order}")
    if row.get("settings"):
        parts.append(str(row["settings"]))
    return " ".join(parts)


def main_t_final(rows: list[dict[str, Any]]) -> float | None:
    """The final time most of a problem's ok rows ran to (a sweep may add a few long runs)."""
    counts: dict[float, int] = {}
    for r in rows:
        if r.get("status") == Status.OK and positive(r.get("t_final")):
            counts[r["t_final"]] = counts.get(r["t_final"], 0) + 1
    return max(sorted(counts), key=lambda t: counts[t]) if counts else None
