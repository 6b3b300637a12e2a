"""A worker folder's files (longtime.execution.jobfiles): named once, written whole, read back
as the pool's recovery and the resident child read them."""
import os

from longtime.execution import jobfiles


def test_markers_and_rows_round_trip_and_clear_leaves_only_the_job(tmp_path):
    cell = {"problem": "harmonic", "integrator": "verlet"}
    marker = jobfiles.running_marker(tmp_path, 4242)
    jobfiles.write_json(marker, cell)
    assert marker.name == "running-4242" and jobfiles.marker_pid(marker) == 4242
    assert jobfiles.running_cells(tmp_path) == [cell]
    jobfiles.write_row(tmp_path, "a key", cell, {"status": "ok"})
    assert jobfiles.row_file(tmp_path, "a key").name == f"row-{jobfiles.key_digest('a key')}.json"
    assert jobfiles.finished_rows(tmp_path) == [(cell, {"status": "ok"})]
    marker.rename(jobfiles.killed_marker(marker))
    assert jobfiles.running_cells(tmp_path) == [] and (tmp_path / "killed-4242").exists()
    # a writer killed mid-write leaves a hidden temporary file, which no reader takes for a marker
    (tmp_path / f".running-7.{os.getpid()}.0.tmp").write_text("{half")
    assert jobfiles.running_cells(tmp_path) == []
    jobfiles.write_json(tmp_path / jobfiles.JOB, {"version": 1})
    jobfiles.write(tmp_path / jobfiles.MARK, "0 0")
    jobfiles.clear(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == [jobfiles.JOB]
