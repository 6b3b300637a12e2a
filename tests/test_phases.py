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
