"""Numbers and tables as text, one way for every report (tables, Markdown, match)."""
from __future__ import annotations

import math
from typing import Any

import numpy as np


def positive(x: Any) -> bool:
    """A finite number > 0 (not a bool, None or NaN): a field that can go on a log axis."""
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) and x > 0


def missing(x: Any) -> bool:
    """None, or a float that is NaN or infinite: shown as a dash, never as a number."""
    return x is None or (isinstance(x, (float, np.floating)) and not math.isfinite(x))


def number(x: Any, digits: int = 4, dash: str = "-") -> str:
    """x in ``digits`` significant digits, exponent notation outside [1e-2, 1e4)."""
    if missing(x):
        return dash
    if isinstance(x, (int, np.integer)) and not isinstance(x, bool):
        return str(int(x))
    if isinstance(x, (float, np.floating)):
        x = float(x)
        if x != 0 and (abs(x) < 1e-2 or abs(x) >= 1e4):
            return f"{x:.{digits - 1}e}"
        return f"{x:.{digits}g}"
    return str(x)


def column(x: Any, spec: str) -> str:
    """x in the format ``spec`` (e.g. "10.3e"), or a dash right-aligned to its width."""
    if missing(x):
        width = "".join(ch for ch in spec.split(".")[0] if ch.isdigit())
        return "-".rjust(int(width or 0))
    return format(x, spec)


def markdown_table(headers: list[str], rows: list[list[Any]], dash: str = "–") -> str:
    """A Markdown table; numbers through ``number``, strings as they are."""
    lines = ["| " + " | ".join(headers) + " |", "|" + "|".join("---" for _ in headers) + "|"]
    for r in rows:
        lines.append("| " + " | ".join(x if isinstance(x, str) else number(x, dash=dash) for x in r) + " |")
    return "\n".join(lines)
