"""Bad input refused up front, in one line (exit 2), before any cell
runs; Ctrl-C while the command is still importing ends it without a traceback."""
import json
import subprocess
import sys
from pathlib import Path

import pytest
from _permissions import unprivileged

from longtime.commands.cli import main
from longtime.execution.cells import Cell
from longtime.execution.store import Store

FAST = ["--repeats", "1", "--min-time", "0", "--no-progress", "--no-html", "--no-report", "--executor", "serial"]


@pytest.fixture
def store_with_run(tmp_path):
    db = tmp_path / "s.sqlite"
    assert main(["matrix", "-p", "harmonic", "-i", "verlet", "--dt", "0.1", "--t-final", "1", "--db", str(db),
                 *FAST]) == 0
    return db


def test_baseline_without_common_cells_is_refused_before_the_first_cell(store_with_run, capsys, monkeypatch):
    from longtime.execution import matrix

    ran = []
    monkeypatch.setattr(matrix, "run_cell", lambda *a, **k: ran.append(a) or {})
    capsys.readouterr()
    code = main(["matrix", "-p", "kepler", "-i", "rk4", "--dt", "0.1", "--t-final", "1", "--db", str(store_with_run),
                 "--baseline", "1", *FAST])
    err = capsys.readouterr().err
    assert code == 2 and "--baseline 1" in err and "no cell in common" in err, err
    assert [r["id"] for r in Store(store_with_run).runs()] == [1]  # no run recorded
    assert not ran


def test_baseline_without_rows_is_refused_before_the_first_cell(store_with_run, capsys):
    store = Store(store_with_run)
    empty = store.begin_run("matrix -p harmonic", [Cell("harmonic", "verlet", {}, {"dt": 0.1}, 1.0)])
    store.finish_run(empty, "interrupted")
    capsys.readouterr()
    code = main(["matrix", "-p", "harmonic", "-i", "verlet", "--dt", "0.1", "--t-final", "1",
                 "--db", str(store_with_run), "--baseline", str(empty), *FAST])
    err = capsys.readouterr().err
    assert code == 2 and f"run {empty} has no stored row" in err, err
    assert len(Store(store_with_run).runs()) == 2


@pytest.mark.parametrize("value, text", [("1e-12", "below the smallest limit"), ("1e-300%", "below the smallest limit"),
                                         ("1e308", "beyond any machine's memory")])
def test_memory_limit_that_rounds_to_nothing_or_overflows_is_refused(value, text, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["run", "-p", "harmonic", "-i", "verlet", "--memory-limit", value, "--no-store"])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and text in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_read_only_folders_are_refused_up_front(store_with_run, tmp_path):
    prefix = unprivileged()
    if prefix is None:
        pytest.skip("running as root without user namespaces: file permissions cannot be enforced")
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o555)
    try:
        def cli(*args):
            return subprocess.run([*prefix, sys.executable, "-m", "longtime.commands.cli", *args],
                                  capture_output=True, text=True, timeout=300)

        res = cli("report", "--db", str(store_with_run), "--html", str(locked / "page"))
        assert res.returncode == 2 and "--html" in res.stderr and "cannot write there" in res.stderr, res.stderr
        res = cli("run", "-p", "harmonic", "-i", "verlet", "--dt", "0.1", "--t-final", "1",
                  "--db", str(locked / "s.sqlite"))
        assert res.returncode == 2 and "cannot write it" in res.stderr, res.stderr
        assert not list(locked.iterdir())
    finally:
        locked.chmod(0o755)


def test_a_matrix_whose_page_cannot_be_written_makes_no_store(tmp_path):
    prefix = unprivileged()
    if prefix is None:
        pytest.skip("running as root without user namespaces: file permissions cannot be enforced")
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o555)
    new = tmp_path / "new.sqlite"
    try:
        res = subprocess.run([*prefix, sys.executable, "-m", "longtime.commands.cli", "matrix", "-p", "harmonic",
                              "-i", "verlet", "--dt", "0.1", "--t-final", "1", "--db", str(new),
                              "--html", str(locked / "page"), "--no-progress"], capture_output=True, text=True,
                             timeout=300)
    finally:
        locked.chmod(0o755)
    assert res.returncode == 2 and "--html" in res.stderr and "cannot write there" in res.stderr, res.stderr
    assert not new.exists()  # refused before the store is made


INTERRUPT_IMPORT = """
import sys


class CtrlC:  # Ctrl-C arriving while numba is being imported, the slowest import of the command
    def find_spec(self, name, path=None, target=None):
        if name == "numba":
            raise KeyboardInterrupt
        return None


sys.meta_path.insert(0, CtrlC())
sys.argv = ["longtime", "list", "--format", "json"]
from longtime.commands.entry import main

sys.exit(main())
"""


def test_ctrl_c_during_imports_prints_no_traceback():
    """Ctrl-C in the command's imports (the first second) is exit 130 and one line. (Python's
    own start-up, before any of longtime's code runs, is the interpreter's: not covered.)"""
    res = subprocess.run([sys.executable, "-c", INTERRUPT_IMPORT], capture_output=True, text=True, timeout=120)
    assert res.returncode == 130, res.stderr
    assert res.stderr.strip() == "longtime: interrupted by SIGINT"


def test_the_console_script_enters_through_the_guarded_entry_point():
    text = (Path(__file__).parents[1] / "pyproject.toml").read_text()
    assert 'longtime = "longtime.commands.entry:main"' in text
    script = Path(sys.executable).with_name("longtime")
    if script.exists():
        assert "longtime.commands.entry" in script.read_text()


def test_rk45_tolerance_below_double_precision_is_refused(capsys):
    code = main(["run", "-p", "kepler", "-i", "rk45", "--tol", "1e-300", "--t-final", "1", "--no-store"])
    err = capsys.readouterr().err
    assert code == 2 and "below what double precision can meet" in err and "nonlinear" not in err, err
    assert main(["run", "-p", "harmonic", "-i", "rk45", "--tol", "1e-14", "--t-final", "1", "--no-store",
                 "--format", "json"]) == 0
    assert json.loads(capsys.readouterr().out)[0]["status"] == "ok"
