"""``--cost instructions`` counts kernels compiled for one fixed target (x86-64-v3) whatever
the host CPU: the same count under two host CPU names; a Valgrind killed by a signal is
named, and a run that counted nothing exits 3."""
import json
import os
import shutil
import signal
import subprocess
import sys

import pytest

from longtime.execution.valgrind import EXIT_NOTHING_COUNTED, _last_line
from longtime.measure.instructions import COUNT_TARGET, counting_environment, failure_text

needs_valgrind = pytest.mark.skipif(shutil.which("valgrind") is None
                                    and not os.environ.get("LONGTIME_REQUIRE_VALGRIND"),
                                    reason="valgrind is not installed (Debian package valgrind)")
RUN = [sys.executable, "-m", "longtime.commands.cli", "run", "-p", "toda", "--t-final", "100", "--cost", "instructions",
       "--no-store", "--format", "json"]


def _count(cpu_name: str, schemes: str) -> dict[str, dict]:
    """The rows of toda x ``schemes`` counted with the host's kernels compiled for ``cpu_name``."""
    env = {**os.environ, "NUMBA_CPU_NAME": cpu_name}
    env.pop("NUMBA_CPU_FEATURES", None)
    res = subprocess.run([*RUN, "-i", schemes], capture_output=True, text=True, env=env, timeout=600)
    assert res.returncode == 0, res.stderr
    return {r["integrator"]: r for r in json.loads(res.stdout)}


@pytest.fixture(scope="module")
def haswell_host():
    return _count("haswell", "rk4,gauss4")


@needs_valgrind
@pytest.mark.slow
def test_counted_for_the_fixed_target(haswell_host):
    rk4, gauss4 = haswell_host["rk4"], haswell_host["gauss4"]
    for row in (rk4, gauss4):
        assert row["status"] == "ok" and row["instructions_skipped"] is None
        assert row["instructions_target"] == COUNT_TARGET and f"({COUNT_TARGET} kernels)" in row["instructions_tool"]
        assert set(row["instructions_versions"]) == {"python", "numba", "llvmlite", "numpy"}
    assert 0 < rk4["instructions"] < gauss4["instructions"]  # four stages against Newton's iterations


@needs_valgrind
@pytest.mark.slow
def test_the_same_count_under_another_host_cpu(haswell_host):
    # (the same count beside CPU-bound processes: tests/test_instructions.py)
    znver2_host = _count("znver2", "rk4")
    a, b = haswell_host["rk4"]["instructions"], znver2_host["rk4"]["instructions"]
    assert abs(b / a - 1) < 1e-3, (a, b)


def test_the_counting_environment_is_the_target_whatever_the_host():
    env = counting_environment({"NUMBA_CPU_NAME": "skylake-avx512", "NUMBA_CPU_FEATURES": "+avx512f",
                                "NUMBA_OPT": "0", "HOME": "/h"})
    assert env["NUMBA_CPU_NAME"] == COUNT_TARGET and "avx512" not in env["NUMBA_CPU_FEATURES"]
    assert "+avx2" in env["NUMBA_CPU_FEATURES"] and "NUMBA_OPT" not in env and env["HOME"] == "/h"
    assert env["NUMBA_CACHE_DIR"].endswith(f"counted-{COUNT_TARGET}")


def test_a_signal_is_named():
    said = _last_line("==12870== \n==12870== Process terminating with default action of signal 4 (SIGILL)\n"
                      "==12870==  Illegal opcode at address 0x54AF03C\n==12870==    at 0x54AF03C: ???\n")
    text = failure_text(-signal.SIGILL, said)
    assert text.startswith("the Valgrind process was killed by SIGILL: "
                           "the kernel uses instructions Valgrind cannot run")
    assert text.endswith("it said: Illegal opcode at address 0x54AF03C")
    assert "killed by SIGKILL" in failure_text(-signal.SIGKILL, "")
    assert failure_text(1, "") == "the Valgrind process exited with 1: no message on stderr"


def test_a_valgrind_killed_by_sigill_is_said_and_the_run_exits_3(tmp_path):
    fake = tmp_path / "valgrind"  # a Valgrind whose guest dies on an instruction it cannot run
    fake.write_text("#!/bin/sh\n"
                    "if [ \"$1\" = --version ]; then echo valgrind-3.19.0; exit 0; fi\n"
                    "echo '==7== Process terminating with default action of signal 4 (SIGILL)' >&2\n"
                    "echo '==7==  Illegal opcode at address 0x4A1B2C3' >&2\n"
                    "kill -ILL $$\n")
    fake.chmod(0o755)
    env = {**os.environ, "PATH": f"{tmp_path}{os.pathsep}{os.environ.get('PATH', '')}"}
    res = subprocess.run([*RUN[:4], "-p", "toda", "-i", "rk4", "--t-final", "1", "--cost", "instructions", "--no-store",
                          "--format", "json", "--executor", "serial"],
                         capture_output=True, text=True, env=env, timeout=300)
    assert res.returncode == EXIT_NOTHING_COUNTED == 3
    row = json.loads(res.stdout)[0]
    assert row["status"] == "ok" and row["instructions"] is None
    assert "killed by SIGILL: the kernel uses instructions Valgrind cannot run" in row["instructions_skipped"]
    assert "Illegal opcode at address 0x4A1B2C3" in row["instructions_skipped"]
    assert "no row was counted" in res.stderr and "SIGILL" in res.stderr and "-4" not in res.stderr
