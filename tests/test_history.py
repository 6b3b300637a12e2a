"""longtime history: steps in time and in accuracy, found at the commit that made them."""
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from longtime.commands import cli
from longtime.reporting.history import levels, steps


def test_steps_of_a_series():
    # a level change of x1.5 that stays, and a digit of accuracy lost later
    assert [s["index"] for s in steps([1.0, 1.02, 1.5, 1.48, 1.52], 1.2, 2)] == [2]
    found = steps([1e-6, 1e-6, 1e-6, 1e-5, 1e-5], 2.0, 1, 1e-13)
    assert [(s["index"], round(s["ratio"], 6)) for s in found] == [(3, 10.0)]
    # one run's excursion between two agreeing levels is no step; the latest run's is
    assert steps([1.0, 1.6, 1.0, 1.01, 0.99], 1.2, 2) == []
    assert [s["index"] for s in steps([1.0, 1.0, 1.01, 0.99, 1.6], 1.2, 2)] == [4]
    # a change that is undone: both steps
    assert [s["index"] for s in steps([1.0, 1.6, 1.6, 1.0, 1.0], 1.2, 2)] == [1, 3]
    # within the factor: one level; errors at round-off make no step
    assert len(levels([1.0, 1.1, 0.95, 1.05], 1.2, 2)) == 1
    assert steps([1e-16, 1e-14, 1e-14], 2.0, 1, 1e-13) == []
    # runs without a value (a failed cell) are skipped, not a step
    assert [s["index"] for s in steps([1.0, None, 1.0, 3.0, 3.0], 1.2, 1)] == [3]


def _git(repo, *args):
    return subprocess.run(["git", *args], cwd=repo, check=True, capture_output=True, text=True).stdout.strip()


@pytest.mark.slow
def test_five_commits_slower_at_3_less_accurate_at_4(tmp_path, capsys):
    """A scheme's repository of five commits, each measured into one store: commit 3 repeats
    its stages 1.2 times a step (1.5x the time of this cell), commit 4 adds a bias that costs
    a digit of the solution's accuracy. The commits are measured in a process of their own,
    as a scheme author's CI measures them: a long test session's process can run this small
    kernel at another speed than a fresh one does."""
    repo, db = tmp_path / "repo", tmp_path / "history.sqlite"
    repo.mkdir()
    _git(repo, "init", "-q")
    _git(repo, "config", "user.email", "a@b.c")
    _git(repo, "config", "user.name", "test")
    tests = Path(__file__).parent
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(tests), os.environ.get("PYTHONPATH")]))}
    done = subprocess.run([sys.executable, "-c",
                           f"import _slowed; _slowed.measure_commits({str(repo)!r}, {str(db)!r})"],
                          env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    commits = json.loads(done.stdout)
    capsys.readouterr()
    assert cli.main(["history", "--db", str(db), "-i", "slowed-rk4", "--format", "json"]) == 0
    (cell,) = json.loads(capsys.readouterr().out)
    assert [p["commit"] for p in cell["runs"]] == commits  # found from the module's repository
    assert all(len(p["cpu_s_processes"]) == 3 and p["cpu_s_process_spread"] >= 1 for p in cell["runs"])
    assert all(c["commit"] == commit and c["dirty"] is False for p, commit in zip(cell["runs"], commits)
               for c in p["code"])
    # a time step must pass the spread between processes (at least --factor's 1.2)
    spreads = sorted(p["cpu_s_process_spread"] for p in cell["runs"])
    assert cell["time_factor"] == max(1.2, spreads[2])
    by_field = {}
    for s in cell["steps"]:
        by_field.setdefault(s["field"], []).append(s)
    series = [p["cpu_s_calibrated"] for p in cell["runs"]]
    time_steps = by_field.pop("cpu_s_calibrated", [])
    # commits 1 and 2 run the same code, and so do commits 3, 4 and 5 (the bias costs no
    # time): within each group the calibrated times say how far this machine's speed moved
    # between runs. Where that is within the factor history judges by, the 1.5x step of
    # commit 3 is found and nothing else. Where all three processes of a run landed on the
    # slow one of this machine's two speeds (x1.5 to x1.8 apart, docs/performance.md, "Two
    # speeds"), identical commits differ by more than the step itself and no time verdict
    # can be asked of these five runs: the error steps below are still checked
    noise = max(max(group) / min(group) for group in (series[:2], series[2:]))
    if noise < cell["time_factor"]:
        assert [(s["commit"], s["kind"]) for s in time_steps] == [(commits[2], "slower")], series
    l2 = by_field["l2_error"]
    assert [(s["commit"], s["kind"]) for s in l2] == [(commits[3], "less accurate")]
    assert 8 < l2[0]["ratio"] < 20  # a digit
    # every error step is at commit 4: the repeated stages leave the results bit for bit
    assert {s["commit"] for steps_ in by_field.values() for s in steps_} == {commits[3]}
    assert cli.main(["history", "--db", str(db), "-p", "harmonic", "--set", "dt=0.01"]) == 0
    text = capsys.readouterr().out
    timed = noise < cell["time_factor"]  # the time step is told from the noise (above)
    assert ("STEP time x" in text and f"at run 3, commit {commits[2][:10]}" in text) or not timed
    assert "STEP l2_error x" in text and f"at run 4, commit {commits[3][:10]}" in text
    # the results page of the latest run gains the history: one panel, the steps marked
    assert cli.main(["report", "--db", str(db), "--html", str(tmp_path / "page")]) == 0
    page = (tmp_path / "page" / "index.html").read_text()
    assert 'id="history-harmonic"' in page and ("1 cell, 2 steps marked" in page or not timed)


@pytest.mark.slow
def test_bad_selection_is_one_line(tmp_path, capsys):
    db = tmp_path / "empty.sqlite"
    assert cli.main(["run", "-p", "harmonic", "-i", "verlet", "--t-final", "1", "--db", str(db)]) == 0
    capsys.readouterr()
    assert cli.main(["history", "--db", str(db), "-i", "rk4"]) == 2
    assert "no stored cell" in capsys.readouterr().err
