"""Timing processes under faults: a run that passes its time limit in a fresh process is a lost
sample, never evidence of non-determinism; the timing options reach every child whole."""
import os
import signal
import threading
import time

import pytest

from longtime.core.timing import Timing
from longtime.execution import child as child_processes
from longtime.execution import isolation
from longtime.execution.cells import Cell
from longtime.execution.child import RunSpec
from longtime.execution.matrix import ExecOptions, run_matrix
from longtime.execution.processes import merge, time_cells
from longtime.integrators.explicit_rk import RK4


def test_timing_round_trips_through_its_dict_with_min_runs():
    timing = Timing().per_process(3)
    assert Timing.from_dict(timing.to_dict()) == timing
    assert Timing.from_dict(Timing(repeats=4, min_time=0.5).to_dict()).min_runs is None


def test_an_isolated_child_gets_the_timing_whole_min_runs_included(monkeypatch):
    written = {}
    real = child_processes.write_job

    def spy(folder, kind, cells, spec, **options):
        real(folder, kind, cells, spec, **options)
        written.update(child_processes.read_job(folder).spec.to_dict())

    monkeypatch.setattr(child_processes, "write_job", spy)
    timing = Timing(repeats=3, min_time=0.0, min_runs=1)
    row = isolation.run_cell_isolated(Cell("harmonic", "verlet", {}, {"dt": 0.05}, 5.0), RunSpec(1000, timing),
                                      timeout=60)
    assert row["status"] == "ok", row["message"]
    assert Timing.from_dict(written["timing"]) == timing
    # min_runs 1 and no time budget: one run after the warm-up (at least 3 if min_runs were dropped)
    assert row["repeats"] == 1


def test_a_timed_out_run_in_a_timing_process_drops_its_sample_only():
    row = {"status": "ok", "message": "", "cpu_s": 1.0, "wall_s": 1.0, "cpu_s_samples": [1.0], "samples_digest": "a"}
    merge(row, [{"status": "ok", "cpu_s": 0.9, "wall_s": 0.9, "cpu_s_samples": [0.9], "samples_digest": "a"},
                {"status": "timeout", "message": "time limit", "samples_digest": "partial", "pid": 9}], 3)
    assert row["status"] == "ok", row["message"]
    assert row["cpu_s_processes"] == [1.0, 0.9]
    assert "timed in 2 of 3 processes" in row["message"] and "time limit" in row["message"]


def test_a_run_past_the_time_limit_within_a_timing_process_ends_its_timing_not_its_row():
    cell = Cell("harmonic", "rk4", {}, {"dt": 0.0005}, 50.0)
    first = time_cells([cell], 1000, Timing(repeats=1, min_time=0.0, min_runs=1), time_limit=60)[0]
    assert first["status"] == "ok"
    # a time limit the run cannot meet: the fresh process gives no sample and no digest
    cut = time_cells([cell], 1000, Timing(repeats=1, min_time=0.0, min_runs=1), time_limit=1e-4)[0]
    assert cut["status"] == "timeout" and not cut.get("samples_digest")
    row = {"status": "ok", "message": "", "cpu_s": first["cpu_s"], "wall_s": first["wall_s"],
           "cpu_s_samples": [first["cpu_s"]], "samples_digest": first["samples_digest"]}
    merge(row, [cut], 2)
    assert row["status"] == "ok" and "timed in 1 of 2 processes" in row["message"]


class PausedWhenTimedElsewhere(RK4):
    """RK4 that, in a timing process, writes its pid to ``$PAUSE_PID_FILE`` once its first run
    has begun and waits there, so that the test pauses it (SIGSTOP) inside that run."""
    name = "paused-in-timing"
    summary = "paused inside its run in a timing process"

    def _integrate(self, *args, **kwargs):
        import sys
        from pathlib import Path

        marker = Path(os.environ.get("PAUSE_PID_FILE", ""))
        in_timing = os.path.basename(sys.argv[-1]).startswith("longtime-timing-")  # a timing process's folder
        if in_timing and marker.name and not marker.exists():
            marker.write_text(str(os.getpid()))
            time.sleep(1.0)  # the pause lands here, inside the run: its deadline is already set
        return super()._integrate(*args, **kwargs)


@pytest.mark.slow
def test_a_deterministic_cell_paused_in_its_timing_process_is_not_failed(tmp_path, monkeypatch):
    """The timing process is stopped (SIGSTOP) inside its run for longer than the time limit,
    as a host's preemption does: the row stays ok, missing that process's sample."""
    from longtime.core import registry

    registry.register(PausedWhenTimedElsewhere)
    marker = tmp_path / "paused.pid"
    monkeypatch.setenv("PAUSE_PID_FILE", str(marker))
    stop = threading.Event()
    paused = []

    def pause_child():
        while not stop.is_set():
            if marker.exists() and marker.read_text():
                pid = int(marker.read_text())
                os.kill(pid, signal.SIGSTOP)
                paused.append(pid)
                time.sleep(2.5)
                os.kill(pid, signal.SIGCONT)
                return
            time.sleep(0.02)

    thread = threading.Thread(target=pause_child, daemon=True)
    thread.start()
    try:
        cell = Cell("harmonic", "paused-in-timing", {}, {"dt": 0.0005}, 50.0)
        rows = run_matrix([cell], None, None, "serial",
                          ExecOptions(processes=2, time_limit=1.0, timing=Timing(repeats=2, min_time=0)))
    finally:
        stop.set()
        thread.join()
    assert paused, "the timing process never began its run"
    row = rows[0]
    assert row["status"] == "ok", row["message"]
    assert len(row["cpu_s_processes"]) == 1  # the row's own process; the paused one gave no sample
    assert "timed in 1 of 2 processes" in row["message"] and "passed the time limit" in row["message"]


class DiesWhenTimedElsewhere(RK4):
    """RK4 that ends a timing process (exit code 3) when it is timed there."""
    name = "faulty-dies-in-timing"
    summary = "exits in a timing process"

    def _integrate(self, *args, **kwargs):
        import sys

        if os.path.basename(sys.argv[-1]).startswith("longtime-timing-"):  # a timing process's folder
            os._exit(3)
        return super()._integrate(*args, **kwargs)


def test_a_plugin_that_kills_its_timing_process_is_named_on_its_own_row_only():
    from longtime.core import registry

    registry.register(DiesWhenTimedElsewhere)
    cells = [Cell("harmonic", "faulty-dies-in-timing", {}, {"dt": 0.05}, 5.0),
             Cell("harmonic", "verlet", {}, {"dt": 0.05}, 5.0)]
    bad, good = run_matrix(cells, None, None, "serial", ExecOptions(processes=2, timing=Timing(repeats=2, min_time=0)))
    assert good["status"] == "ok" and len(good["cpu_s_processes"]) == 2, good["message"]
    assert "exited with code 3" not in (good["message"] or "")
    assert bad["status"] == "ok" and len(bad["cpu_s_processes"]) == 1
    assert "timed in 1 of 2 processes" in bad["message"] and "exited with code 3" in bad["message"]


@pytest.mark.parametrize("executor", ["serial", "process"])
def test_rows_of_one_process_are_stored_with_the_process_fields_they_print(tmp_path, executor):
    from longtime.core.timing import Timing
    from longtime.execution.cells import Cell
    from longtime.execution.matrix import ExecOptions, run_matrix
    from longtime.execution.store import Store

    store = Store(tmp_path / "one.sqlite")
    cells = [Cell("harmonic", "verlet", {}, {"dt": 0.05}, 5.0), Cell("harmonic", "rk4", {}, {"dt": 0.05}, 5.0)]
    run_id = store.begin_run("test", cells)
    printed = run_matrix(cells, store, run_id, executor, ExecOptions(processes=1, jobs=1, timing=Timing(repeats=2)))
    stored = {(r["integrator"]): r for r in store.rows(run_id)}
    for row in printed:
        kept = stored[row["integrator"]]
        assert kept["cpu_s_processes"] == row["cpu_s_processes"] == [row["cpu_s"]]
        assert "cpu_s_process_spread" in kept and "phases_missing" not in kept
