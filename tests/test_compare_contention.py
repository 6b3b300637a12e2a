"""compare and history beside a neighbour that streams memory: where the streaming workload
of the calibrations (longtime.execution.calibration) differed between two runs beyond what a
cell's time verdict can attribute, the cell's time gets no verdict and says why; a real
slowdown with equal streaming is still a regression, and instruction counts still judge.

These tests judge stated times. Identical code run beside real memory hogs is
benchmarks/bench_hogs.py's: what it measures depends on the machine's load, so it is a
benchmark, not a test."""
import pytest

from longtime.execution import calibration
from longtime.reporting.compare import compare
from longtime.reporting.compare_cells import compare_rows
from longtime.reporting.compare_machine import machine, machine_text
from longtime.reporting.compare_text import render
from longtime.reporting.history import mark_bandwidth

STREAM = 64 * 2**20


def _row(cpu: float, spread: float | None = None, count: int | None = None, t: float = 1.0, dt: float = 0.1) -> dict:
    return {"problem": "toda", "integrator": "rk4sym", "status": "ok", "dt": dt, "t_final": 50.0, "settings": "",
            "cpu_s": cpu, "cpu_s_calibrated": cpu / 2e-3, "calibration_cpu_s": 2e-3, "calibration_t": t,
            "cpu_s_process_spread": spread, "instructions": count,
            "instructions_tool": "callgrind 3.19" if count else None}


def _points(stream_s: float | None, t: float = 1.0) -> list[dict]:
    point = {"t": t, "cpu_s": 2e-3, "cpu_s_max": 2.1e-3}
    if stream_s is not None:
        point.update(stream_bytes=STREAM, stream_cpu_s=stream_s)
    return [point]


def test_a_real_slowdown_with_equal_streaming_is_still_a_regression():
    a, b = _row(0.1, 1.05), _row(0.2, 1.05)
    for same in (None, 1.0, 1.1, 1 / 1.1):
        c = compare_rows(a, b, bandwidth=same)
        assert c["time_verdict"] == "slower" and c["regressions"][0].startswith("time x2 (calibrated"), same
    assert compare_rows(b, a, bandwidth=1.0)["time_verdict"] == "faster"


def test_streaming_that_differed_beyond_the_factor_gives_no_time_verdict():
    a, b = _row(0.1, 1.05), _row(0.172, 1.05)
    for differed in (1.7, 1 / 1.7):
        c = compare_rows(a, b, bandwidth=differed)
        assert c["time_verdict"] == "not comparable" and not c["regressions"] and not c["improvements"]
        assert c["not_comparable"].startswith("memory bandwidth differed x1.7 between the runs")
    # a spread between processes that covers the streaming's change: the time is judged
    wide = compare_rows(_row(0.1, 1.8), _row(0.2, 1.8), bandwidth=1.7)
    assert wide["time_verdict"] == "slower" and wide["time_threshold"] == pytest.approx(1.8)
    # too short to time stays too short
    assert compare_rows(_row(1e-5), _row(2e-5), bandwidth=1.7)["time_verdict"] == "too short"


def test_instruction_counts_still_judge_where_the_bandwidth_differed():
    more = compare_rows(_row(0.1, 1.05, 1_000_000), _row(0.3, 1.05, 1_500_000), bandwidth=1.7)
    assert more["time_verdict"] == "not comparable" and more["instruction_verdict"] == "more"
    assert len(more["regressions"]) == 1 and more["regressions"][0].startswith("instructions x1.5")
    same = compare_rows(_row(0.1, 1.05, 1_000_000), _row(0.3, 1.05, 1_000_010), bandwidth=1.7)
    assert same["instruction_verdict"] == "within" and not same["regressions"]


def test_compare_reads_the_streaming_beside_each_cell_from_the_calibrations():
    rows_a = [_row(0.1, 1.05, dt=dt) for dt in (0.1, 0.05)]
    rows_b = [_row(0.172, 1.05, dt=dt) for dt in (0.1, 0.05)]
    hogged = compare(rows_a, rows_b, calibrations=(_points(0.010), _points(0.017)))
    assert hogged["regressed"] == 0 and hogged["improved"] == 0
    assert hogged["counts"]["time"]["not comparable"] == 2
    assert hogged["machine"]["bandwidth_ratio"] == pytest.approx(1.7)
    text = render(hogged, show_all=True)
    assert "2 not comparable" in text and "not comparable: memory bandwidth differed x1.7 between the runs" in text
    assert "memory streaming 10 ms in A, 17 ms in B (x1.7)" in text
    # the same streaming in both runs: the slowdown is the code's
    slowed = compare(rows_a, [_row(0.2, 1.05, dt=dt) for dt in (0.1, 0.05)],
                     calibrations=(_points(0.010), _points(0.0102)))
    assert slowed["regressed"] == 2 and slowed["counts"]["time"]["slower"] == 2
    # a run calibrated without the streaming workload is judged by its compute calibration alone,
    # and says it lacks the streaming one
    old = compare(rows_a, [_row(0.2, 1.05, dt=dt) for dt in (0.1, 0.05)],
                  calibrations=(_points(None), _points(0.017)))
    assert old["regressed"] == 2 and old["machine"]["bandwidth_ratio"] is None
    assert "no memory-bandwidth calibration in A" in machine_text(old["machine"])


def test_the_runs_median_streaming_is_compared_not_one_calibration():
    a_points = _points(0.010, t=1.0) + _points(0.010, t=2.0) + _points(0.010, t=3.0)
    burst = _points(0.010, t=1.0) + _points(0.010, t=2.0) + _points(0.018, t=3.0)  # one calibration in a burst
    assert machine(a_points, burst)["bandwidth_ratio"] == pytest.approx(1.0)
    hogged = _points(0.016, t=1.0) + _points(0.017, t=2.0) + _points(0.018, t=3.0)  # a neighbour throughout
    assert machine(a_points, hogged)["bandwidth_ratio"] == pytest.approx(1.7)
    # another size streamed, or none: not compared
    other = [{**p, "stream_bytes": 2 * STREAM} for p in hogged]
    assert machine(a_points, other)["bandwidth_ratio"] is None
    assert machine(a_points, _points(None))["bandwidth_ratio"] is None
    assert "streamed over arrays of other sizes" in machine_text(machine(a_points, other))


def test_history_leaves_out_the_times_of_runs_whose_streaming_differed():
    def point(run, stream):
        return {"run_id": run, "status": "ok", "machine": "M1", "stream_cpu_s": stream, "stream_bytes": STREAM}

    points = [point(1, 0.010), point(2, 0.0101), point(3, 0.021), point(4, 0.0099), point(5, None)]
    mark_bandwidth(points, 1.2)
    assert [p["not_comparable"] is not None for p in points] == [False, False, True, False, False]
    assert points[2]["bandwidth_ratio"] == pytest.approx(0.021 / (0.010 * 0.0101) ** 0.5)  # over the median
    assert points[4]["bandwidth_ratio"] is None
    assert points[2]["not_comparable"].startswith("memory bandwidth differed x2.09 from the cell's other runs")
    lone = [point(1, 0.010), {**point(2, 0.030), "machine": "M2"}]  # one run a machine: nothing to set it against
    mark_bandwidth(lone, 1.2)
    assert all(p["not_comparable"] is None for p in lone)


def test_a_calibration_streams_beyond_the_last_level_cache(tmp_path):
    for level, size in ((1, "32K"), (2, "512K"), (3, "32768K")):
        index = tmp_path / f"index{level}"
        index.mkdir()
        (index / "level").write_text(f"{level}\n")
        (index / "size").write_text(f"{size}\n")
    assert calibration.last_level_cache_bytes(str(tmp_path)) == 32 * 2**20
    assert calibration.last_level_cache_bytes(str(tmp_path / "absent")) is None
    assert calibration.STREAM_MIN_BYTES <= calibration.stream_bytes() <= calibration.STREAM_MAX_BYTES
    p = calibration.measure("batch", repeats=1, steps=1000, memory_bytes=0, streamed_bytes=2**22, stream_repeats=2)
    assert p["stream_bytes"] == 2**22 and p["stream_cpu_s"] == min(p["stream_cpu_s_samples"]) > 0
    assert len(p["stream_cpu_s_samples"]) == 2
    assert "stream_cpu_s" not in calibration.measure("batch", repeats=1, steps=1000, memory_bytes=0, streamed_bytes=0)
    d = calibration.drift([p])
    assert d["stream_cpu_s"] == p["stream_cpu_s"] and d["stream_bytes"] == 2**22
    assert "memory streamed 4 MiB in" in calibration.drift_text([p])


def test_time_verdicts_without_the_bandwidth_check_say_so():
    rows_a = [_row(0.1, 1.05, dt=dt) for dt in (0.1, 0.05)]
    rows_b = [_row(0.2, 1.05, dt=dt) for dt in (0.1, 0.05)]
    for calibrations, why in (((_points(None), _points(None)), "no memory-bandwidth calibration in A and B"),
                              ((None, None), "no calibration in A and B")):
        old = compare(rows_a, rows_b, calibrations=calibrations)
        assert old["regressed"] == 2 and old["time_unchecked"] == 2
        assert old["bandwidth_unchecked"].startswith(why)
        assert all(c["regressions"][0].endswith("[without the memory-bandwidth check]") for c in old["cells"])
        text = render(old)
        assert "time verdicts without the memory-bandwidth check: 2 cell(s) (" + why in text
    checked = compare(rows_a, rows_b, calibrations=(_points(0.010), _points(0.0101)))
    assert checked["time_unchecked"] == 0 and checked["bandwidth_unchecked"] is None
    assert "without the memory-bandwidth check" not in render(checked)
