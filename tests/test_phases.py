"""longtime.core.phases: the breakdown bench_main_job prints is only as good as these records."""
import time

from longtime.core import phases


def test_nested_phases_count_their_own_time_and_compiles_are_named_by_where_they_happen(tmp_path, monkeypatch):
    monkeypatch.setattr(phases, "_FOLDER", str(tmp_path))
    monkeypatch.setattr(phases, "_OUT", None)
    with phases.phase("integration", "fpu x verlet"):
        time.sleep(0.05)
        with phases.compiling():
            time.sleep(0.1)
    with phases.phase("page"):
        pass
    phases._OUT.close()
    events = {e["phase"]: e for e in phases.read(str(tmp_path))}
    assert set(events) == {"integration", "compile:integration", "page"}
    compile_, outer = events["compile:integration"], events["integration"]
    assert compile_["detail"] == outer["detail"] == "fpu x verlet"
    assert compile_["s"] >= 0.1
    assert 0.05 <= outer["s"] < 0.1  # the nested compile is not the integration's
    assert outer["end"] - outer["start"] >= 0.15
    assert "detail" not in events["page"]


def test_nothing_is_recorded_without_the_variable(tmp_path, monkeypatch):
    monkeypatch.setattr(phases, "_FOLDER", None)
    with phases.phase("integration"):
        with phases.compiling():
            pass
    phases.since_process_start("startup")
    assert phases.read(str(tmp_path)) == []


def test_a_phase_counts_its_own_cpu_seconds_apart_from_its_wall_and_its_nested_phases(tmp_path, monkeypatch):
    monkeypatch.setattr(phases, "_FOLDER", str(tmp_path))
    monkeypatch.setattr(phases, "_OUT", None)

    def spin(seconds):
        end = time.process_time() + seconds
        while time.process_time() < end:
            pass

    with phases.phase("timing processes"):
        time.sleep(0.2)  # waiting: wall, no CPU
        with phases.phase("timing"):
            spin(0.2)
    phases._OUT.close()
    events = {e["phase"]: e for e in phases.read(str(tmp_path))}
    waiting, working = events["timing processes"], events["timing"]
    assert working["cpu"] >= 0.2 and working["cpu"] <= working["s"] + 0.05
    assert waiting["s"] >= 0.2 and waiting["cpu"] < 0.1  # the nested phase's CPU is not its own


def test_the_hold_table_tells_the_row_process_from_the_fresh_ones():
    """bench_main_job's hold table: cells whose row's process moved x1.3 between two runs while
    their fresh processes held are beyond x1.15 for the row's process alone, not for cpu_s."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    import bench_main_job

    first = {("p", f"s{k}", 0.1, None, 10.0, ""): [0.005, 0.0051, 0.0052] for k in range(10)}
    second = {key: [0.005 * 1.3, 0.00505, 0.0052] for key in first}
    lines = bench_main_job.hold_table([first, second])
    band = next(line for line in lines if line.startswith("0 to 0.01 s"))
    cpu_s, row, fresh = band.split()[5:8], band.split()[8:11], band.split()[11:14]
    assert band.split()[4] == "10"  # cells
    assert cpu_s == ["x1.01", "x1.01", "0%"]  # the minimum moved from 5 to 5.05 ms
    assert row == ["x1.30", "x1.30", "100%"]
    assert fresh[2] == "0%"
    assert not any(line.startswith("0.01 to") for line in lines)  # an empty band is left out
