"""Child processes started one way (longtime.execution.child): a versioned job file with the run
options whole, and the timing of a cell arriving in an isolated child as it was sent."""
import importlib
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from longtime.core import registry
from longtime.core.integrator import Timing
from longtime.execution import child as children
from longtime.execution import tempdirs
from longtime.execution.cells import Cell
from longtime.execution.child import Child, JobVersionError, RunSpec
from longtime.execution.isolation import run_cell_isolated
from longtime.execution.jobfiles import JOB as JOB_FILE
from longtime.execution.jobfiles import RESULT as RESULT_FILE
from longtime.integrators.splitting import Verlet


class TimingSeen(Verlet):
    """Verlet that writes the timing it is given where $CHILD_TIMING_FILE says."""

    name = "child-timing-seen"
    summary = "Verlet that records the timing it receives"

    def integrate(self, problem, t_final, max_samples=100_001, timing=None, deadline=None):
        with open(os.environ["CHILD_TIMING_FILE"], "w") as f:
            json.dump({"timing": timing.to_dict(), "pid": os.getpid()}, f)
        return super().integrate(problem, t_final, max_samples=max_samples, timing=timing, deadline=deadline)


def test_a_job_file_carries_its_version_the_cells_and_the_run_options_whole(tmp_path):
    cells = [Cell("harmonic", "verlet", {}, {"dt": 0.05}, 5.0), Cell("kepler", "rk4", {}, {"dt": 0.01}, 2.0)]
    spec = RunSpec(1234, Timing().per_process(3), 7.5, 2**30)
    children.write_job(tmp_path, "time", cells, spec, paired=True)
    job = children.read_job(tmp_path)
    assert job.kind == "time" and job.parent == os.getpid() and job.options == {"paired": True}
    assert [c.key for c in job.cells] == [c.key for c in cells]
    assert job.spec == spec and job.spec.timing.least_runs == 1
    data = json.loads((tmp_path / JOB_FILE).read_text())
    data["version"] = children.JOB_VERSION + 1
    (tmp_path / JOB_FILE).write_text(json.dumps(data))
    with pytest.raises(JobVersionError, match="format version"):
        children.read_job(tmp_path)


def test_every_kind_of_job_names_the_function_its_child_runs():
    for kind, target in children.KINDS.items():
        module, _, name = target.partition(":")
        assert callable(getattr(importlib.import_module(module), name)), kind
    with pytest.raises(ValueError, match="job kind 'nope'"):
        children.write_job(Path("/nonexistent"), "nope", [], RunSpec())


def test_a_call_job_returns_its_outcome_pickled():
    """A one-off child of a ``call`` job runs the pickled function and writes what it returned
    (or raised) beside the job."""
    import pickle

    from longtime.execution import jobfiles

    folder = tempdirs.make("cell")
    children.write_job(folder, "call", [], RunSpec())
    jobfiles.write(folder / jobfiles.CALL, pickle.dumps((divmod, (7, 2))))
    child = children.start(folder)
    assert child.wait(120)
    assert pickle.loads((folder / jobfiles.OUTCOME).read_bytes()) == ("returned", (3, 1))
    child.remove()


def test_a_child_that_dies_is_named_by_its_signal_and_leaves_no_file(tmp_path):
    """A job of a kind the child does not run (a child of another longtime): it exits with
    code 1, its one line naming the kind, and the parent says so."""
    folder = tempdirs.make("cell")
    children.write_job(folder, "cell", [], RunSpec())
    data = json.loads((folder / JOB_FILE).read_text())
    (folder / JOB_FILE).write_text(json.dumps({**data, "kind": "no-such-kind"}))
    child = children.start(folder)
    assert child.wait(60)
    assert child.result() is None
    assert child.failure("the child").startswith("the child exited with code 1 without a result; stderr: ")
    assert "has kind 'no-such-kind'; this longtime runs time, cell, count, batches" in child.failure("the child")
    child.remove()
    assert not folder.exists()
    assert children.how_it_ended(-9) == "killed by SIGKILL"


def test_timing_per_process_arrives_in_an_isolated_child_whole(tmp_path, monkeypatch):
    """Timing().per_process(3) asks at least 1 run; the isolated child must read at least 1,
    not the default 3 (a job that carried only repeats and min_time would lose min_runs)."""
    registry.register(TimingSeen)
    seen = tmp_path / "timing.json"
    monkeypatch.setenv("CHILD_TIMING_FILE", str(seen))
    timing = Timing().per_process(3)
    assert timing.least_runs == 1 and Timing(repeats=timing.repeats, min_time=timing.min_time).least_runs == 3
    row = run_cell_isolated(Cell("harmonic", "child-timing-seen", {}, {"dt": 0.05}, 5.0),
                            RunSpec(1000, timing, 60.0), timeout=120)
    assert row["status"] == "ok", row["message"]
    received = json.loads(seen.read_text())
    assert received["pid"] != os.getpid()  # read in the child
    assert Timing.from_dict(received["timing"]) == timing
    assert Timing.from_dict(received["timing"]).least_runs == 1


def test_a_result_that_cannot_be_read_is_a_named_failure(tmp_path):
    """A child whose result file is a folder (or not JSON) gave no result: its failure says
    why, and the parent goes on."""
    (tmp_path / RESULT_FILE).mkdir()
    child = Child(tmp_path, subprocess.Popen([sys.executable, "-c", "pass"]))
    child.wait(60)
    assert child.result() is None
    assert child.failure("the timing process").startswith(
        f"the timing process exited with code 0 without a result; its {RESULT_FILE} cannot be read (IsADirectoryError")
    (tmp_path / RESULT_FILE).rmdir()
    (tmp_path / RESULT_FILE).write_text("{half")
    assert child.result() is None and "(JSONDecodeError" in child.failure("the timing process")
