"""Every Python example of docs/api.md runs as it stands: a block is run as a script in a
fresh folder, or, when its first line names a test file (``# test_....py``), with pytest
(and ``--benchmark-json``, which must then carry l2_error in extra_info). So does
docs/own_problem.md's script, which checks its own answer."""
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

DOC = Path(__file__).resolve().parents[1] / "docs" / "api.md"
BLOCKS = re.findall(r"```python\n(.*?)```", DOC.read_text(), flags=re.S)
OWN = re.findall(r"```python\n(.*?)```", (DOC.parent / "own_problem.md").read_text(), flags=re.S)


def test_the_page_has_its_examples():
    assert len(BLOCKS) >= 6
    script = next(b for b in BLOCKS if "convergence(rows)" in b)
    assert len(script.strip().splitlines()) <= 15  # the in-memory scheme's order, in at most 15 lines


@pytest.mark.parametrize("index", range(len(BLOCKS)))
def test_example_runs(index, tmp_path):
    block = BLOCKS[index]
    first = block.splitlines()[0]
    # without pytest-xdist's worker variables, under which pytest-benchmark would not time
    env = {**{k: v for k, v in os.environ.items() if not k.startswith("PYTEST_XDIST")}, "MPLBACKEND": "Agg"}
    test_file = re.match(r"# (test_\w+\.py)", first)
    if test_file:
        path = tmp_path / test_file.group(1)
        path.write_text(block)
        res = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(path),
                              f"--benchmark-json={tmp_path / 'bench.json'}", "-o", "addopts="],
                             capture_output=True, text=True, timeout=600, cwd=tmp_path, env=env)
        assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
        extra = [b["extra_info"] for b in json.loads((tmp_path / "bench.json").read_text())["benchmarks"]]
        assert extra and all(e["l2_error"] > 0 for e in extra)
        return
    path = tmp_path / f"example_{index}.py"
    path.write_text(block)
    res = subprocess.run([sys.executable, str(path)], capture_output=True, text=True, timeout=600, cwd=tmp_path,
                         env=env)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    if "convergence(rows)" in block:
        value = float(re.search(r"observed order (\d+\.\d+)", res.stdout).group(1))
        assert abs(value - 4) < 0.1, res.stdout


@pytest.mark.slow
def test_own_problem_goes_from_a_class_to_a_checked_answer(tmp_path):
    """docs/own_problem.md: a class in a script, its default sweep, recommend's answer, and
    the answer run to the horizon keeps the error it was asked for (the script asserts it)."""
    assert len(OWN) == 1
    path = tmp_path / "own.py"
    path.write_text(OWN[0])
    res = subprocess.run([sys.executable, str(path)], capture_output=True, text=True, timeout=900, cwd=tmp_path,
                         env={**os.environ, "MPLBACKEND": "Agg"})
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    assert "quartic: keep max_error <= 1e-06 up to T = 1000" in res.stdout
    measured, predicted = map(float, re.search(r"max_error (\S+) \(predicted (\S+)\)", res.stdout).groups())
    assert measured <= 1e-6 and predicted / 3 <= measured <= 3 * predicted, res.stdout
    assert "cells: done" in res.stderr  # the sweep said how far it was
