"""Children die with their parent: a matrix killed with SIGKILL while Valgrind counts leaves no
Valgrind running (reparented to init) and no vgdb files in the temp folder."""
import os
import shutil
import signal
import subprocess
import sys
import time

import pytest

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


def _descendants(root: int) -> dict[int, str]:
    """pid -> command line of every process below ``root``."""
    parents, commands = {}, {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as f:
                    parents[int(entry)] = int(f.read().rsplit(")", 1)[1].split()[1])
                with open(f"/proc/{entry}/cmdline", "rb") as f:
                    commands[int(entry)] = f.read().replace(b"\0", b" ").decode(errors="replace")
            except OSError:
                pass
    out, frontier = {}, [root]
    while frontier:
        pid = frontier.pop()
        for child, parent in parents.items():
            if parent == pid and child not in out:
                out[child] = commands.get(child, "")
                frontier.append(child)
    return out


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def test_a_killed_parent_leaves_no_valgrind_and_no_vgdb_files(tmp_path):
    env = {**os.environ, "TMPDIR": str(tmp_path)}
    parent = subprocess.Popen([sys.executable, "-c", PARENT], env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE)
    deadline = time.monotonic() + 60
    valgrinds = {}
    while not valgrinds:
        assert parent.poll() is None, parent.stderr.read().decode()
        assert time.monotonic() < deadline, "no Valgrind process started"
        valgrinds = {p: c for p, c in _descendants(parent.pid).items() if "valgrind" in c or "memcheck" in c
                     or "callgrind" in c}
        time.sleep(0.05)
    time.sleep(1.0)  # Valgrind has begun the interpreter
    parent.send_signal(signal.SIGKILL)
    parent.wait()
    deadline = time.monotonic() + 10
    while any(_alive(p) for p in valgrinds) and time.monotonic() < deadline:
        time.sleep(0.05)
    survivors = [p for p in valgrinds if _alive(p)]
    for pid in survivors:  # the test leaves none behind either
        os.kill(pid, signal.SIGKILL)
    assert not survivors, f"Valgrind outlived its parent: {valgrinds}"
    assert not list(tmp_path.rglob("vgdb-pipe*"))
