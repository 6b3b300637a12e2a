"""Timing by need (longtime.predict.need, longtime.execution.processes.by_need): which cells
the fresh timing processes time again, what a row says of how it was timed, and how compare
and history judge a cell timed in its own process. Synthetic rows and timing processes
replaced by a stub: nothing is integrated, nothing is timed."""
import dataclasses

import pytest

from longtime.execution import processes
from longtime.execution.cells import Cell
from longtime.execution.child import RunSpec
from longtime.predict.need import FACTOR, need
from longtime.reporting.compare_cells import compare_rows
from longtime.reporting.history import process_factor


def _row(scheme: str, dt: float, error: float, cpu: float, problem: str = "harmonic", t_final: float = 10.0):
    return {"problem": problem, "integrator": scheme, "dt": dt, "t_final": t_final, "status": "ok",
            "l2_error": error, "cpu_s": cpu, "wall_s": cpu, "samples_digest": f"{scheme}-{dt}"}


# one problem's front of l2_error against CPU: verlet 0.1 and 0.05, rk4 0.05 and gauss4 (within
# x1.17 of rk4 0.05, whose error is smaller); rk4 0.1 no more accurate than verlet 0.1 at 4.2 times
# its CPU; euler cheapest but meets no target (0.5 > 0.1); a longer run of another problem alone
ROWS = [_row("verlet", 0.1, 1e-3, 0.10), _row("verlet", 0.05, 2.5e-4, 0.20), _row("rk4", 0.1, 1e-3, 0.42),
        _row("rk4", 0.05, 1e-5, 0.30), _row("gauss4", 0.1, 2e-4, 0.35), _row("euler", 0.1, 0.5, 0.01),
        _row("verlet", 0.1, 1e-2, 0.7, problem="kepler")]


def test_the_cells_timed_again_are_the_fronts_neighbourhood():
    found = need(ROWS)
    assert [n.retime for n in found] == [True, True, False, True, True, False, True]
    dominated = found[2]
    assert dominated.factor == pytest.approx(4.2) and dominated.factor > FACTOR
    assert dominated.why == "not on the front by x4.2"
    assert found[4].factor == pytest.approx(0.35 / 0.30)
    assert found[5].factor is None and "meets no target" in found[5].why


def test_the_factor_moves_the_neighbourhood():
    assert need(ROWS, factor=5.0)[2].retime  # x4.2 is within x5
    assert not need(ROWS, factor=1.1)[4].retime  # gauss4's x1.17 is not within x1.1


def test_a_problem_with_no_front_is_timed_again_whole():
    rows = [{**_row("verlet", dt, 1e-3, cpu), "l2_error": None} for dt, cpu in ((0.1, 0.1), (0.05, 0.9))]
    assert all(n.retime for n in need(rows))


def _timed(monkeypatch, retime: str):
    """The rows of ROWS after the timing processes (a stub that gives every cell it is handed
    the row's time) under ``retime``, and the cells handed to them."""
    handed = []

    def children(cells, count, spec, jobs, timeout, paired=False, on_progress=None):
        handed.extend(cells)
        return [([{"status": "ok", "cpu_s": 0.09, "wall_s": 0.09, "cpu_s_samples": [0.09],
                   "samples_digest": f"{c.integrator}-{c.integrator_settings['dt']}"} for c in cells], "")] * count

    monkeypatch.setattr(processes, "run_children", children)
    rows = [dict(r) for r in ROWS]
    pairs = [(Cell(r["problem"], r["integrator"], {}, {"dt": r["dt"]}, r["t_final"]), r) for r in rows]
    processes.across_processes(pairs, 3, RunSpec(1000, processes.Timing(), None, None),
                               alone=processes.by_need(rows, pairs, retime))
    return rows, handed


def test_timing_by_need_leaves_the_dominated_cells_in_their_own_process(monkeypatch):
    rows, handed = _timed(monkeypatch, "need")
    assert len(handed) == 5  # the 5 contenders, handed to the 2 fresh processes
    assert rows[2]["timed_in"] == "its own process: not on the front by x4.2"
    assert rows[2]["cpu_s"] == 0.42 and rows[2]["cpu_s_process_spread"] is None
    assert rows[2]["cpu_s_processes"] == [0.42]
    assert rows[0]["timed_in"] == "3 processes" and rows[0]["cpu_s_processes"] == [0.10, 0.09, 0.09]
    assert rows[5]["timed_in"].startswith("its own process: on no front")


def test_timing_all_times_every_cell_again(monkeypatch):
    rows, handed = _timed(monkeypatch, "all")
    assert len(handed) == len(ROWS)
    assert all(r["timed_in"] == "3 processes" for r in rows)


def test_a_cell_timed_in_its_own_process_is_judged_against_the_single_cell_factor():
    three = {**_row("verlet", 0.1, 1e-3, 1.0), "cpu_s_process_spread": 1.05, "timed_in": "3 processes"}
    slower = {**three, "cpu_s": 1.5, "cpu_s_process_spread": 1.02}
    assert compare_rows(three, slower)["time_verdict"] == "slower"  # x1.5 beyond x1.2 and the spread
    alone = {**slower, "cpu_s_process_spread": None, "timed_in": "its own process: not on the front by x4.2"}
    c = compare_rows(three, alone)
    assert c["time_verdict"] == "within" and c["time_threshold"] == 2.0
    why = compare_rows(three, {**alone, "cpu_s": 2.5})["regressions"][0]
    assert "cell beyond x2: timed in its own process in B (no spread between processes)" in why
    # history: a series with a run timed in its own process passes the single-cell factor
    points = [{"status": "ok", "cpu_s_process_spread": 1.05}, {"status": "ok", "timed_in": alone["timed_in"]}]
    assert process_factor(points, 1.2) == 2.0
    assert process_factor(points[:1], 1.2) == 1.2


def test_the_report_counts_the_cells_timed_in_their_own_process(monkeypatch):
    from longtime.reporting.screen import count_lines

    rows, _ = _timed(monkeypatch, "need")
    text = "\n".join(count_lines(rows, orders=False))
    assert "timed in its own process only 2 (dominated by more than x2" in text


def test_the_main_job_times_by_need_and_a_run_of_named_cells_times_all():
    from longtime.execution.main_job import MainJobSpec
    from longtime.execution.matrix import ExecOptions

    assert MainJobSpec().options.retime == "need" and ExecOptions().retime == "all"


def test_a_setting_the_verdict_picks_past_its_run_is_timed_again_though_off_the_measured_front():
    # energy errors only (no reference): verlet's is bounded, rk4's grows linearly. At t = 100
    # rk4 is more accurate for 1 / 2.5 of verlet's CPU (verlet: x2.5 off the measured front),
    # but 1000 times further rk4's error is 1e-3 and verlet's still 1e-5: the verdict's best there
    def energy(scheme, error, law, cpu):
        return {**_row(scheme, 0.01, None, cpu, t_final=100.0), "H.max": error, "H.growth_class": law}

    rows = [energy("verlet", 1e-5, "bounded", 0.25), energy("rk4", 1e-6, "linear", 0.10)]
    verlet, rk4 = need(rows)
    assert rk4.retime and verlet.retime
    assert not need([rows[0], {**rows[1], "H.growth_class": "bounded"}])[0].retime  # x2.5 off every front


def _timings(monkeypatch, options):
    """The timing the rows' processes get and the one the fresh timing processes get, from
    run_matrix under ``options`` (the executor and the timing processes replaced by stubs:
    nothing runs)."""
    from longtime.execution import matrix

    seen = {}

    def executor(cells, opts):
        seen["rows"] = opts.timing
        for cell in cells:  # one contender row, timed again in the fresh processes
            yield cell, {**_row("verlet", 0.1, 1e-3, 0.1), "repeats": 1, "cpu_s_samples": [0.1]}

    def fresh(pairs, count, spec, jobs=1, on_progress=None, alone=None):
        seen["fresh"] = spec.timing
        return []

    monkeypatch.setitem(matrix.EXECUTORS, "serial", executor)
    monkeypatch.setattr(matrix, "across_processes", fresh)
    matrix.run_matrix([Cell("harmonic", "verlet", {}, {"dt": 0.1}, 10.0)], None, None, "serial", options)
    return seen["rows"], seen["fresh"]


def test_the_rows_processes_screen_under_timing_by_need_and_time_in_full_under_timing_all(monkeypatch):
    from longtime.core.timing import Timing
    from longtime.execution.main_job import MainJobSpec
    from longtime.execution.matrix import ExecOptions

    split = Timing().per_process(3)  # 7 repeats and 0.2 s split among 3 processes
    assert (split.repeats, split.least_runs) == (3, 1) and split.min_time == pytest.approx(0.2 / 3)
    # the main job's default: one run in the row's process, a few where the runs are under 0.01 s
    rows, fresh = _timings(monkeypatch, dataclasses.replace(MainJobSpec().options, processes=3))
    assert rows == Timing(repeats=3, min_time=0.01, min_runs=1) == split.screening()
    assert (rows.least_runs, rows.wants_another([0.02]), rows.wants_another([0.002])) == (1, False, True)
    assert not rows.wants_another([0.002, 0.002, 0.002])  # at most SCREEN_RUNS
    assert fresh == split  # the contenders, timed again at today's rules
    # --timing all: every process times at the split timing, the row's own as well
    rows, fresh = _timings(monkeypatch, ExecOptions(processes=3, retime="all"))
    assert rows == fresh == split
    # the command line: matrix times by need unless --timing all; run times all
    from longtime.commands.cli import build_parser
    from longtime.commands.matrix import matrix_options

    parser = build_parser()
    assert matrix_options(parser.parse_args(["matrix", "--processes", "3"]), "process").retime == "need"
    full = matrix_options(parser.parse_args(["matrix", "--processes", "3", "--timing", "all"]), "process")
    assert full.retime == "all" and _timings(monkeypatch, full)[0] == split
    # one process (--processes 1): nothing is timed again, so the row's process times in full
    rows, _ = _timings(monkeypatch, ExecOptions(processes=1, retime="need"))
    assert rows == Timing()
    # a screening never asks for more than the timing it screens for
    assert Timing(repeats=1, min_time=0.0).screening() == Timing(repeats=1, min_time=0.0, min_runs=1)


def test_a_row_left_in_its_own_process_says_how_many_runs_timed_it():
    row = {**_row("rk4", 0.1, 1e-3, 0.42), "repeats": 1}
    processes.one_process(row, "not on the front by x4.2")
    assert row["timed_in"] == "its own process, 1 run: not on the front by x4.2"
    row = {**_row("rk4", 0.1, 1e-3, 0.42), "repeats": 3}
    processes.one_process(row, "one process asked (--processes 1)")
    assert row["timed_in"] == "its own process, 3 runs: one process asked (--processes 1)"
