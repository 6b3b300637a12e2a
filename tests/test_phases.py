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
