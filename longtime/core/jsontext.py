"""JSON as the commands print it: strict JSON, where a value that is not a finite number (NaN,
an infinity, as a stored row or a fit may hold) is ``null``; Python's ``json`` would write
``NaN`` or ``Infinity``, which no JSON reader takes."""
from __future__ import annotations

import json
import math
from typing import Any, Callable


def finite(value: Any) -> Any:
    """``value`` with every non-finite float (at any depth of dicts, lists and tuples) as None;
    numpy scalars as Python numbers."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite(v) for v in value]
    if type(value).__module__ == "numpy" and hasattr(value, "item") and getattr(value, "ndim", 0) == 0:
        return finite(value.item())
    return value


def dumps(value: Any, indent: int | None = 1, default: Callable[[Any], Any] | None = None) -> str:
    """``json.dumps`` of ``finite(value)``; ``default`` as json's, its results made finite too."""
    convert = (lambda obj: finite(default(obj))) if default is not None else None
    return json.dumps(finite(value), indent=indent, default=convert, allow_nan=False)
