"""A long command is never silent: every phase of a main job (the cells, the timing
processes, the checks, the ensembles, the page, the report) says what it does and how far
it is, under a terminal (a tqdm bar redrawn every few seconds) and in a pipe (plain lines,
each newline-terminated, at least every interval)."""
import io
import os
import subprocess
import sys
import threading
import time

import pytest

from longtime.core import progress

MATRIX = ["-m", "longtime", "matrix", "-p", "harmonic", "-i", "verlet,rk4"]


def _env(tmp_path, **extra):
    # three timing processes, as a main job's (the suite's default is one)
    return {**os.environ, "LONGTIME_DB": str(tmp_path / "p.sqlite"), "LONGTIME_PROCESSES": "3", **extra}


def test_plain_lines_in_a_pipe_carry_the_phase_the_count_and_the_time(monkeypatch):
    monkeypatch.setenv(progress.ENV_SECONDS, "0.2")
    out = io.StringIO()
    shown = progress.Progress(stream=out)
    assert not shown.terminal and shown.every == 0.2
    with shown.phase("cells", total=4, unit="cells"):
        shown.advance(last="kepler x rk4: ok")
        time.sleep(0.5)
    with shown.phase("page", estimate_s=3):
        time.sleep(0.5)
    lines = out.getvalue().splitlines()
    assert lines[0] == "longtime: cells: started, 0 of 4 cells (0 %), 0 s"
    beats = [line for line in lines if line.startswith("longtime: cells: 1 of 4 cells (25 %)")]
    assert len(beats) >= 1 and "last: kepler x rk4: ok" in beats[0] and "left" in beats[0]
    assert "longtime: cells: done (1 cells, 1 s)" in lines or "longtime: cells: done (1 cells, 0 s)" in lines
    assert any(line.startswith("longtime: page: ") and "of about 3 s" in line for line in lines)
    assert out.getvalue().endswith("\n") and "\r" not in out.getvalue()
    quiet = io.StringIO()
    with progress.Progress(on=False, stream=quiet).phase("cells", total=1):
        time.sleep(0.3)
    assert quiet.getvalue() == ""


def test_the_time_left_weighs_the_units_by_their_estimated_costs(monkeypatch):
    """One cheap cell of four done (cost 1 of 10): the time left is nine times the time
    spent, not three times, as a count of cells would say."""
    monkeypatch.setattr(progress.time, "monotonic", lambda: 100.0)
    state = {"total": 4, "done": 1, "start": 90.0, "costs": 10.0, "cost_done": 1.0}
    assert progress.Progress._left(state) == pytest.approx(90.0)
    assert progress.Progress._left({**state, "costs": None}) == pytest.approx(30.0)
    assert progress.Progress._left({**state, "done": 0, "cost_done": 0.0}) is None
    out = io.StringIO()
    shown = progress.Progress(stream=out)
    with shown.phase("cells", total=4, unit="cells", costs=10.0):
        shown.advance(last="kepler x rk4: ok", cost=1.0)
        shown._state["start"] = 90.0
        shown._line(shown._state)
    assert "about 1:30 left" in out.getvalue()


def test_the_default_intervals_meet_the_promise(monkeypatch):
    monkeypatch.delenv(progress.ENV_SECONDS, raising=False)
    assert progress.interval(terminal=True) <= 15 and progress.interval(terminal=False) <= 60


def _gaps(stamps, start, end):
    times = [start, *stamps, end]
    return max(b - a for a, b in zip(times, times[1:]))


@pytest.mark.slow
def test_a_matrix_in_a_pipe_prints_a_line_at_least_every_interval(tmp_path):
    proc = subprocess.Popen([sys.executable, *MATRIX, "--db", str(tmp_path / "p.sqlite")], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=_env(tmp_path, LONGTIME_PROGRESS_SECONDS="1"),
                            cwd=tmp_path)
    stamps, lines = [], []
    for line in proc.stderr:
        stamps.append(time.monotonic())
        lines.append(line)
    proc.wait(timeout=600)
    end = time.monotonic()
    assert proc.returncode == 0, "".join(lines)[-2000:]
    phases = {line.split(":")[1].strip() for line in lines if line.startswith("longtime: ")}
    assert {"cells", "timing processes", "checks", "page", "report"} <= phases, phases
    assert not any("\r" in line for line in lines)
    # after the first line (the interpreter's start and imports before it), a line at least
    # every interval, with room for a loaded machine
    assert _gaps(stamps[1:], stamps[0], end) <= 12, "".join(lines)


@pytest.mark.slow
def test_a_matrix_under_a_terminal_prints_something_at_least_every_15_seconds(tmp_path):
    import fcntl
    import pty
    import struct
    import termios

    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 100, 0, 0))  # 100 columns: tqdm's bars
    start = time.monotonic()
    proc = subprocess.Popen([sys.executable, *MATRIX, "--db", str(tmp_path / "p.sqlite")], stdout=subprocess.PIPE,
                            stderr=slave, stdin=subprocess.DEVNULL, env=_env(tmp_path), cwd=tmp_path)
    os.close(slave)
    stamps, chunks = [], []

    def read():
        while True:
            try:
                data = os.read(master, 4096)
            except OSError:
                return
            if not data:
                return
            stamps.append(time.monotonic())
            chunks.append(data)

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    proc.communicate(timeout=600)
    end = time.monotonic()
    reader.join(timeout=5)
    os.close(master)
    text = b"".join(chunks).decode(errors="replace")
    assert proc.returncode == 0, text[-2000:]
    assert "cells" in text and "timing processes" in text and "page" in text
    assert _gaps(stamps, start, end) <= 15, text[-3000:]


def test_a_quiet_phase_speaks_only_once_it_outlasts_an_interval(monkeypatch):
    monkeypatch.setenv(progress.ENV_SECONDS, "0.3")
    quick, slow = io.StringIO(), io.StringIO()
    with progress.Progress(stream=quick).phase("compare", announce=False):
        pass
    with progress.Progress(stream=slow).phase("compare", detail="runs 1 and 2", announce=False):
        time.sleep(0.8)
    assert quick.getvalue() == ""
    lines = slow.getvalue().splitlines()
    assert lines[0].startswith("longtime: compare: 0 s, runs 1 and 2")
    assert lines[-1].startswith("longtime: compare: done")


def test_a_phase_that_fails_says_no_done(monkeypatch):
    monkeypatch.setenv(progress.ENV_SECONDS, "5")
    out = io.StringIO()
    with pytest.raises(ValueError):
        with progress.Progress(stream=out).phase("page"):
            raise ValueError("no space")
    assert out.getvalue() == "longtime: page: started, 0 s\n"
