"""Rows of a fixed selection of cells, compared with rows stored in tests/data/golden_rows.json,
timings and machine-dependent fields aside: on any x86-64 machine, not only the one that wrote them.

What is exact: the keys, every count, status, text, bool and null, the length of every list,
and the floats that are inputs or pure step-size arithmetic (``EXACT_FLOATS``).
What has a tolerance: every other float, because its last bits depend on the CPU through
  - glibc's libm (exp, pow, sin ... pick an FMA or a non-FMA kernel at load time, and the two
    differ by an ulp in rare arguments; compiled kernels call them, so the states of a problem
    with exp, like Toda, differ after a few hundred steps),
  - numpy's SIMD loops (the blocking of pairwise sums, so ``NAME.mean``, depends on the SIMD
    width) and OpenBLAS/LAPACK kernels (eigenvalues ``eigN.*``, the least-squares slope fits
    ``NAME.growth*``), chosen per CPU at run time.
The tolerances (``RTOL``, ``ATOL``, ``SLOPE_ATOL``) are round-off bounds with a margin, not fits:
see their comments. Measured: rows rebuilt here with numpy limited to its baseline
(NPY_DISABLE_CPU_FEATURES=X86_V3), OpenBLAS as Prescott or Sandybridge (OPENBLAS_CORETYPE),
numba compiling for a generic x86-64 (NUMBA_CPU_NAME=generic) and glibc's non-FMA kernels
(GLIBC_TUNABLES=glibc.cpu.hwcaps=-AVX2,-FMA,-AVX) differ from the stored ones (written on an
AVX-512 machine) by at most 4.3e-13 relatively (Toda's l2_error), 1e-14 absolutely
(deviations near round-off, and curves stored to 6 digits), 1.1e-6 in a slope.

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
    """Timings and how they were taken (``timed_in`` follows the processes the session asks
    for), and the digest of the states' bits (which differ by an ulp between CPUs: see above;
    the states themselves are compared within the tolerances through the metrics)."""
    return key.startswith(("cpu_s", "wall_s", "calibration_")) or key in ("repeats", "samples_digest", "timed_in")


def rows_of(argv: list[str]) -> list[dict]:
    out = io.StringIO()
    with redirect_stdout(out):
        code = main(["run", *argv, *FAST])
    assert code == 0, argv
    return [{k: v for k, v in r.items() if not machine_dependent(k)} for r in json.loads(out.getvalue())]


# Inputs and step-size arithmetic (parsed numbers, sums of dt): IEEE arithmetic without libm or
# SIMD reductions, compiled without fast-math (no FMA contraction, no reassociation), so the
# same bits on every x86-64; compared bit for bit.
EXACT_FLOATS = {"dt", "tol", "eps_res", "t_final", "mean_dt", "min_dt", "max_dt", "t_reached",
                "error_horizon", "reference_horizon", "reference_rtol"}
# Relative: an ulp (1.1e-16) of difference in a libm call or a summation order, carried by a
# flow whose condition number over these short runs is far below 1e5, over at most 1e4 steps:
# under 1e-16 * 1e4 * 1e5 = 1e-7 in the worst case; observed 4.3e-13. 1e-9 keeps a margin of
# 2000 over the observation while any change of scheme or metric moves a field by far more.
RTOL = 1e-9
# Absolute, in units of the states and invariants (all of order one in the selection): a
# deviation near round-off (an error of 1e-15 in an invariant of order 1) has no relative
# accuracy at all; 1e-12 is 4500 ulps of 1, 100 times the largest observed difference (1e-14).
ATOL = 1e-12
# Fitted log-log slopes (NAME.growth, _ci, _windows): a deviation e moved by ATOL moves log e by
# ATOL / e, and the slope by that over the window's log-span; for the deviations of order 1e-10
# in the selection that is 1e-2 at most, observed 1.1e-6. 1e-4 is kept: it is under the 0.005
# that would change a slope printed in a reason text (texts are compared exactly).
SLOPE_ATOL = 1e-4
# Sweeps of an implicit stage iteration stopped at half an ulp of the state (and the rhs
# evaluations they make): the stop sees the last bit of an increment, which another libm or
# SIMD dispatch may round apart, so a sweep in a thousand may differ (observed 18 of 17,559)
# while the state stays within RTOL; a change of the stopping rule moves them by far more.
ITERATION_COUNTS = {"nl_iters", "rhs_evals"}
ITERATION_RTOL = 3e-3


def tolerance(key: str) -> tuple[float, float] | None:
    """(rtol, atol) of a float field, None where it must match bit for bit."""
    if key in EXACT_FLOATS:
        return None
    if key.endswith((".growth", ".growth_ci", ".growth_windows")):
        return RTOL, SLOPE_ATOL
    return RTOL, ATOL


def same(a, b, tol: tuple[float, float] | None = None, key: str = "") -> bool:
    """Equal: floats bit for bit where ``tol`` is None (nan equals nan), else within
    ``atol + rtol * max(|a|, |b|)``; a dict's fields each with their own tolerance (``key``
    names the field whose curve a nested dict is, for its floats); anything else exactly."""
    if isinstance(a, float) and isinstance(b, float):
        if a.hex() == b.hex() or (math.isnan(a) and math.isnan(b)):
            return True
        if tol is None or not (math.isfinite(a) and math.isfinite(b)):
            return False
        rtol, atol = tol
        return abs(a - b) <= atol + rtol * max(abs(a), abs(b))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k], tolerance(k if not key else key), k) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(same(x, y, tol, key) for x, y in zip(a, b))
    if key in ITERATION_COUNTS and isinstance(a, int) and isinstance(b, int):
        return abs(a - b) <= ITERATION_RTOL * max(abs(a), abs(b))
    return type(a) is type(b) and a == b


@pytest.mark.parametrize("index", range(len(SELECTION)))
def test_rows_unchanged(index):
    stored = json.loads(DATA.read_text())[index]
    assert stored["argv"] == SELECTION[index]
    rows = rows_of(SELECTION[index])
    assert len(rows) == len(stored["rows"])
    for got, want in zip(rows, stored["rows"]):
        differ = sorted(k for k in got.keys() | want.keys()
                        if k not in got or k not in want or not same(got[k], want[k], tolerance(k), k))
        assert not differ, {k: (want.get(k), got.get(k)) for k in differ}


if __name__ == "__main__":
    DATA.parent.mkdir(exist_ok=True)
    DATA.write_text(json.dumps([{"argv": a, "rows": rows_of(a)} for a in SELECTION], indent=1) + "\n")
    print(f"wrote {DATA}", file=sys.stderr)
