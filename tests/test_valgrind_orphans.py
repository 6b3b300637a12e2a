"""Children die with their parent: a matrix killed with SIGKILL while Valgrind counts leaves no
Valgrind running (reparented to init) and no vgdb files in the temp folder."""
import os
import shutil
import signal
import subprocess
import sys
import time

import pytest
from _procs import alive, descendants

pytestmark = pytest.mark.skipif(shutil.which("valgrind") is None, reason="needs Valgrind")

PARENT = """
import sys
from longtime.execution.cells import Cell
from longtime.execution.valgrind import instruction_fields
cell = Cell("harmonic", "verlet", {}, {"dt": 0.01}, 5.0)
row = {"status": "ok", "wall_s": 0.001, "cpu_s": 0.001, "steps": 500}
print("counting", flush=True)
instruction_fields([(cell, row)], 100, None)
"""


def test_a_killed_parent_leaves_no_valgrind_and_no_vgdb_files(tmp_path):
    env = {**os.environ, "TMPDIR": str(tmp_path)}
    parent = subprocess.Popen([sys.executable, "-c", PARENT], env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE)
    deadline = time.monotonic() + 60
    valgrinds = {}
    while not valgrinds:
        assert parent.poll() is None, parent.stderr.read().decode()
        assert time.monotonic() < deadline, "no Valgrind process started"
        valgrinds = {p: c for p, c in descendants(parent.pid).items() if "valgrind" in c or "memcheck" in c
                     or "callgrind" in c}
        time.sleep(0.05)
    time.sleep(1.0)  # Valgrind has begun the interpreter
    parent.send_signal(signal.SIGKILL)
    parent.wait()
    deadline = time.monotonic() + 10
    while any(alive(p) for p in valgrinds) and time.monotonic() < deadline:
        time.sleep(0.05)
    survivors = [p for p in valgrinds if alive(p)]
    for pid in survivors:  # the test leaves none behind either
        os.kill(pid, signal.SIGKILL)
    assert not survivors, f"Valgrind outlived its parent: {valgrinds}"
    assert not list(tmp_path.rglob("vgdb-pipe*"))
