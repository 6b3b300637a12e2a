"""A recorded run's life (longtime.execution.lifecycle): done, interrupted, rejected, and the command
line it records."""
import sys

import pytest

from longtime.commands.cli import main
from longtime.core.params import InputError
from longtime.execution.cells import Cell
from longtime.execution.lifecycle import recorded_run
from longtime.execution.store import Store

CELL = Cell("harmonic", "rk4", {}, {"dt": 0.1}, 1.0)


def test_done_and_interrupted(tmp_path):
    store = Store(tmp_path / "s.sqlite")
    with recorded_run(store, "run x", [CELL]) as first:
        pass
    with pytest.raises(KeyboardInterrupt):
        with recorded_run(store, "run y", [CELL]) as second:
            raise KeyboardInterrupt
    assert store.run(first)["status"] == "done" and store.run(first)["command"] == "run x"
    assert store.run(second)["status"] == "interrupted" and store.run(second)["planned"] == 1


def test_rejected_run_is_discarded_unless_it_stored_a_row(tmp_path):
    store = Store(tmp_path / "s.sqlite")
    with pytest.raises(InputError):
        with recorded_run(store, "run x", [CELL]):
            raise InputError("bad executor setting")
    assert store.runs() == []
    with pytest.raises(InputError):
        with recorded_run(store, "run y", [CELL]) as run_id:
            store.add_row(run_id, CELL, {"problem": "harmonic", "integrator": "rk4", "status": "ok"})
            raise InputError("late")
    assert [r["status"] for r in store.runs()] == ["interrupted"]


def test_resumed_run_is_kept_when_rejected(tmp_path):
    store = Store(tmp_path / "s.sqlite")
    run_id = store.begin_run("matrix", [CELL])
    with pytest.raises(InputError):
        with recorded_run(store, "ignored", [], run_id) as same:
            assert same == run_id
            raise InputError("bad")
    assert store.run(run_id)["status"] == "interrupted" and store.run(run_id)["command"] == "matrix"


def test_no_store_records_nothing():
    with recorded_run(None, "run x", [CELL]) as run_id:
        assert run_id is None


def test_run_records_the_argv_given_to_main(tmp_path, monkeypatch, capsys):
    """The stored command is main's argv (the subcommand first), never sys.argv."""
    monkeypatch.setattr(sys, "argv", ["pytest", "-q", "something"])
    db = str(tmp_path / "s.sqlite")
    argv = ["run", "-p", "harmonic", "-i", "rk4", "--dt", "0.1", "--t-final", "1", "--repeats", "1",
            "--min-time", "0", "--format", "csv", "--db", db]
    assert main(argv) == 0
    (run,) = Store(db).runs()
    assert run["command"] == "run -p harmonic -i rk4 --dt 0.1 --t-final 1 --repeats 1 --min-time 0 " \
                             f"--format csv --db {db}"
    assert run["status"] == "done"
