"""Isolation: a cell that hangs or kills its interpreter becomes a row; the matrix goes on.

The misbehaving schemes are a tiny third-party-style plugin registered through a real
entry point: a module and a ``*.dist-info`` folder in a temporary directory put on the
path (PYTHONPATH for the child processes), as an installed package would be.
"""
from __future__ import annotations

import sys
import textwrap
import time

import pytest

from longtime.commands.cli import main
from longtime.core import registry
from longtime.execution.cells import expand, run_cell
from longtime.execution.matrix import ExecOptions, run_matrix
from longtime.execution.store import Store

PLUGIN = '''
"""Schemes that misbehave on purpose (tests of longtime's isolation)."""
import os
import signal
import time

from longtime.core.stepping import FixedStepIntegrator


class _Misbehaving(FixedStepIntegrator):
    summary = "test plugin"

    def make_step(self, problem):
        raise NotImplementedError


class Hang(_Misbehaving):
    def _integrate(self, problem, t_final, max_samples):
        while True:
            time.sleep(0.1)


class ExitHard(_Misbehaving):
    def _integrate(self, problem, t_final, max_samples):
        os._exit(3)


class Segfault(_Misbehaving):
    def _integrate(self, problem, t_final, max_samples):
        os.kill(os.getpid(), signal.SIGSEGV)
        time.sleep(10)
'''

ENTRY_POINTS = """
[longtime.integrators]
test-hang = misbehaving_plugin:Hang
test-exit = misbehaving_plugin:ExitHard
test-segfault = misbehaving_plugin:Segfault
"""


@pytest.fixture
def plugin(tmp_path, monkeypatch):
    (tmp_path / "misbehaving_plugin.py").write_text(textwrap.dedent(PLUGIN))
    info = tmp_path / "misbehaving_plugin-0.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: misbehaving-plugin\nVersion: 0.0\n")
    (info / "entry_points.txt").write_text(ENTRY_POINTS)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("PYTHONPATH", str(tmp_path))
    registry.reload()
    yield tmp_path
    monkeypatch.undo()
    sys.modules.pop("misbehaving_plugin", None)
    registry.reload()


@pytest.mark.slow
def test_hang_and_crashes_become_rows_and_the_matrix_goes_on(plugin, tmp_path):
    assert {"test-hang", "test-exit", "test-segfault"} <= set(registry.integrators())
    cells = expand(["harmonic"], ["test-hang", "test-exit", "test-segfault", "verlet"], t_final=1.0)
    store = Store(tmp_path / "iso.sqlite")
    run_id = store.begin_run("matrix isolation test", cells)
    timeout = 20.0  # room for the ok cell to start an interpreter and compile on a busy machine
    start = time.perf_counter()
    rows = run_matrix(cells, store, run_id, "isolated", ExecOptions(jobs=2, cell_timeout=timeout))
    elapsed = time.perf_counter() - start
    by_name = {r["integrator"]: r for r in rows}
    assert by_name["test-hang"]["status"] == "timeout", by_name["test-hang"]
    assert "time limit" in by_name["test-hang"]["message"]
    assert by_name["test-exit"]["status"] == "failed"
    assert "exited with code 3" in by_name["test-exit"]["message"]
    assert by_name["test-segfault"]["status"] == "failed"
    assert "SIGSEGV" in by_name["test-segfault"]["message"]
    assert by_name["verlet"]["status"] == "ok" and by_name["verlet"]["steps"] > 0
    # a healthy cell gives the same numbers isolated as in this process
    here = run_cell(cells[-1])
    for key in ("status", "steps", "rhs_evals", "H.max", "l2_error", "final_error"):
        assert by_name["verlet"][key] == here[key], key
    # every row is in the store, nothing planned is left pending
    stored = {r["integrator"]: r["status"] for r in store.rows(run_id)}
    assert stored == {k: v["status"] for k, v in by_name.items()}
    assert store.pending(run_id) == []
    assert elapsed < timeout + 60  # the hung cell was killed, not waited for


@pytest.mark.slow
def test_cli_matrix_with_cell_timeout_completes_with_a_timeout_row(plugin, tmp_path, capsys):
    db = tmp_path / "cli.sqlite"
    code = main(["matrix", "-p", "harmonic", "-i", "test-hang,test-exit", "--t-final", "1",
                 "--cell-timeout", "4", "--jobs", "2", "--db", str(db), "--no-progress", "--no-report"])
    assert code == 0
    rows = {r["integrator"]: r for r in Store(db).rows()}
    assert rows["test-hang"]["status"] == "timeout"
    assert rows["test-exit"]["status"] == "failed"


def test_cell_timeout_must_be_positive(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["run", "-p", "harmonic", "-i", "rk4", "--cell-timeout", "0", "--no-store"])
    assert exc.value.code == 2
    assert "--cell-timeout" in capsys.readouterr().err
