"""The counting phase under faults: a plugin that ends the counting process costs only its
own row its count (the cells after it are counted again without it); a count is accepted only
for a run that reproduces the timed run bit for bit. Valgrind is stood in for by a process
that runs the worker natively (its client requests are no-ops there), the counts by fixed
numbers: what is tested is the bookkeeping, not Callgrind."""
import os
import sys

from longtime.core import registry
from longtime.core.timing import Timing
from longtime.execution import valgrind
from longtime.execution.cells import Cell, run_cell
from longtime.integrators.explicit_rk import RK4
from longtime.measure import instructions

SHIM = [sys.executable, "-c", "import os, sys; os.execv(sys.argv[2], sys.argv[2:])"]


class ExitsWhenCounted(RK4):
    name = "faulty-exits-when-counted"
    summary = "RK4 that ends the counting process"

    def make_step(self, problem):
        if os.path.basename(sys.argv[-1]).startswith("longtime-valgrind-"):  # a counting process's folder
            os._exit(3)
        return super().make_step(problem)


def test_a_crash_is_its_own_row_and_a_count_needs_the_same_digest(monkeypatch):
    registry.register(ExitsWhenCounted)
    monkeypatch.setattr(instructions, "require", lambda: "valgrind")
    monkeypatch.setattr(instructions, "command", lambda valgrind_path, prefix: SHIM)
    monkeypatch.setattr(instructions, "read_dumps", lambda prefix: {f"cell {i}": 1000 + i for i in range(10)})
    monkeypatch.setattr(instructions, "tool_version", lambda: "callgrind (stand-in)")
    cells = [Cell("harmonic", "faulty-exits-when-counted", {}, {"dt": 0.05}, 5.0),
             Cell("harmonic", "verlet", {}, {"dt": 0.05}, 5.0),
             Cell("harmonic", "rk4", {}, {"dt": 0.05}, 5.0)]
    pairs = [(c, run_cell(c, 1000, timing=Timing(repeats=1))) for c in cells]
    for _, row in pairs:
        assert row["status"] == "ok", row["message"]
    pairs[2][1]["samples_digest"] = "0" * 40  # as if the timed run had been another
    fields = valgrind.instruction_fields(pairs, 1000, None)
    crashed, healthy, other = (fields[c.key] for c in cells)
    assert crashed["instructions"] is None and "exited with 3" in crashed["instructions_skipped"]
    assert "in this cell" in crashed["instructions_skipped"]
    assert healthy["instructions"] is not None and healthy["instructions_skipped"] is None
    assert other["instructions"] is None and "did not reproduce the timed run" in other["instructions_skipped"]
