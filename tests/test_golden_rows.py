"""Rows of a fixed selection of cells, compared bit for bit with rows stored in
tests/data/golden_rows.json, timings and machine-dependent fields aside.

Regenerate the stored rows (only when a change of numbers is intended and explained):
    python tests/test_golden_rows.py
"""
import io
import json
import math
import sys
from contextlib import redirect_stdout
from pathlib import Path

import pytest

from longtime.commands.cli import main

DATA = Path(__file__).parent / "data" / "golden_rows.json"

# the selection: fixed steps, a symplectic DIRK, an implicit collocation, BPL with its residual
# bound and order, adaptive schemes with a tolerance, a problem parameter set
SELECTION = [
    ["-p", "kepler", "-i", "verlet,rk4", "--dt", "0.01,0.005", "--t-final", "20"],
    ["-p", "kepler", "-i", "rk45", "--tol", "1e-8", "--t-final", "20", "--set", "e=0.9"],
    ["-p", "toda", "-i", "rk4sym", "--dt", "0.1", "--t-final", "50"],
    ["-p", "harmonic", "-i", "gauss4", "--dt", "0.1", "--t-final", "50"],
    ["-p", "harmonic", "-i", "taylor-adaptive", "--tol", "1e-10", "--order", "12", "--t-final", "20"],
    ["-p", "toda", "-i", "bpl", "--eps-res", "1e-6", "--order", "10", "--t-final", "5"],
]
FAST = ["--repeats", "1", "--min-time", "0", "--format", "json", "--no-store"]


def machine_dependent(key: str) -> bool:
    return key.startswith(("cpu_s", "wall_s", "calibration_")) or key == "repeats"


def rows_of(argv: list[str]) -> list[dict]:
    out = io.StringIO()
    with redirect_stdout(out):
        code = main(["run", *argv, *FAST])
    assert code == 0, argv
    return [{k: v for k, v in r.items() if not machine_dependent(k)} for r in json.loads(out.getvalue())]


def same(a, b) -> bool:
    """Equal bit for bit: floats by their 64-bit pattern (nan equals nan), containers item by item."""
    if isinstance(a, float) and isinstance(b, float):
        return a.hex() == b.hex() or (math.isnan(a) and math.isnan(b))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    return type(a) is type(b) and a == b


@pytest.mark.parametrize("index", range(len(SELECTION)))
def test_rows_unchanged(index):
    stored = json.loads(DATA.read_text())[index]
    assert stored["argv"] == SELECTION[index]
    rows = rows_of(SELECTION[index])
    assert len(rows) == len(stored["rows"])
    for got, want in zip(rows, stored["rows"]):
        differ = sorted(k for k in got.keys() | want.keys() if not same(got.get(k), want.get(k)))
        assert not differ, {k: (want.get(k), got.get(k)) for k in differ}


if __name__ == "__main__":
    DATA.parent.mkdir(exist_ok=True)
    DATA.write_text(json.dumps([{"argv": a, "rows": rows_of(a)} for a in SELECTION], indent=1) + "\n")
    print(f"wrote {DATA}", file=sys.stderr)
