"""The golden rows hold on any x86-64 machine, not only the one that wrote
them. Counts, statuses and texts exact; floats within the round-off tolerances stated in
tests/test_golden_rows.py; rows rebuilt with numpy, OpenBLAS and glibc limited to their
baseline kernels pass."""
import copy
import json
import os
import platform
import subprocess
import sys
from pathlib import Path

import pytest
from test_golden_rows import DATA, RTOL, same, tolerance

TESTS = Path(__file__).parent


def _stored_row(index=2):
    return json.loads(DATA.read_text())[index]["rows"][0]


def _matches(got, want):
    return all(k in got and k in want and same(got[k], want[k], tolerance(k), k)
               for k in got.keys() | want.keys())


def test_cpu_round_off_in_golden_fields_is_tolerated():
    """The differences another CPU makes (an ulp in libm and LAPACK, amplified) pass."""
    want = _stored_row()
    got = copy.deepcopy(want)
    got["l2_error"] *= 1 + 4.3e-13          # Toda rk4sym: glibc's non-FMA exp
    got["H.mean"] += 3e-18                   # numpy's pairwise sum at another SIMD width
    got["eig1.max"] += 3.4e-16               # LAPACK's eigenvalues
    got["eig2.growth"] += 1.1e-6             # a least-squares slope through LAPACK
    got["eig1.growth_windows"][0] = -1.5e-31 # a slope of round-off about zero
    got["drift_curves"][1]["error"][2] += 1e-14  # a curve stored to 6 digits, last digit flipped
    assert _matches(got, want)


@pytest.mark.parametrize("field, change", [
    ("l2_error", lambda r: r["l2_error"] * (1 + 10 * RTOL)),
    ("steps", lambda r: r["steps"] + 1),
    ("status", lambda r: "failed"),
    ("dt", lambda r: r["dt"] * (1 + 1e-16) + 1e-17),
    ("eig1.growth_reason", lambda r: r["eig1.growth_reason"] + " "),
    ("H.growth", lambda r: r["H.growth"] + 1e-3),
])
def test_changes_beyond_round_off_still_fail(field, change):
    want = _stored_row()
    got = copy.deepcopy(want)
    got[field] = change(got)
    assert not _matches(got, want)


def test_a_slope_about_zero_prints_as_zero():
    from longtime.measure.growth import _verdict
    _, reason = _verdict(1e-31, [(-1.5e-31, 0.0), (1e-31, 0.0), (0.03, 0.01)], 1e-3, None)
    assert "-0.00" not in reason and "slopes 0.00, 0.00, 0.03" in reason


@pytest.mark.slow
@pytest.mark.skipif(platform.machine() not in ("x86_64", "AMD64"), reason="x86-64 SIMD dispatch")
def test_golden_rows_hold_with_simd_dispatch_limited(tmp_path):
    """Rows rebuilt with numpy at its baseline SIMD, OpenBLAS as a pre-AVX CPU and glibc's
    non-FMA libm (the Toda selection calls exp) match the stored ones."""
    env = dict(os.environ, NPY_DISABLE_CPU_FEATURES="X86_V3 X86_V4 AVX512_ICL AVX512_SPR",
               OPENBLAS_CORETYPE="Sandybridge", GLIBC_TUNABLES="glibc.cpu.hwcaps=-AVX2,-FMA,-AVX512F")
    check = subprocess.run([sys.executable, "-c", "import numpy; print(numpy.show_runtime())"],
                           env=env, capture_output=True, text=True)
    assert "X86_V3" not in check.stdout.split("'found'")[1].split("]")[0], check.stdout
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                           str(TESTS / "test_golden_rows.py") + "::test_rows_unchanged[2]",
                           str(TESTS / "test_golden_rows.py") + "::test_rows_unchanged[5]"],
                          env=env, capture_output=True, text=True, cwd=tmp_path, timeout=900)
    assert done.returncode == 0, done.stdout[-3000:]
