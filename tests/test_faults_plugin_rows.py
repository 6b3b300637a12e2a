"""A plugin scheme whose row the declared row refuses (an undeclared field, a value of the
wrong type, a count no run takes) costs its own cell: the cell's row is a ``failed`` row
naming the field and why, every other row is stored and ``--resume`` finds nothing left."""
import json

import numpy as np
import pytest
from _plugins import install_plugin, longtime

from longtime.commands.cli import main
from longtime.core import registry, rowschema
from longtime.execution.cells import Cell, run_cell
from longtime.execution.store import Store
from longtime.integrators.explicit_rk import RK4

# name -> (what the scheme's run puts in its trajectory, the field the failed row names)
SPOILS = {
    "evil-field": (("extra", "evil_field", 1), "evil_field"),
    "evil-cpu": (("extra", "cpu_s", "fast"), "cpu_s"),
    "evil-dict": (("extra", "reference", {"a": 1}), "reference"),
    "evil-float-count": (("counters", "rhs_evals", 1.5), "rhs_evals"),
    "evil-own-count": (("counters", "my_count", 3), "my_count"),
    "evil-numpy-count": (("counters", "rhs_evals", np.int64(7)), "rhs_evals"),  # not JSON's integer
    "evil-negative-steps": (("counters", "steps", -5), "steps"),
    "evil-huge-steps": (("counters", "steps", 10**30), "steps"),
    "evil-many-steps": (("counters", "steps", 10**6), "steps"),  # 10 steps of dt 0.1 reach t = 1
    "evil-no-steps": (("counters", "steps", 0), "steps"),  # no step reaches t = 1
    "evil-status": (("status", None, "sucess"), "status"),
}


def _spoiled(name: str) -> type:
    (where, key, value), _ = SPOILS[name]

    def _integrate(self, problem, t_final, max_samples):
        traj = RK4._integrate(self, problem, t_final, max_samples)
        if where == "status":
            traj.status = value
        else:
            getattr(traj, where)[key] = value
        return traj

    return type(name.title().replace("-", ""), (RK4,), {"name": name, "_integrate": _integrate,
                                                         "__module__": __name__})


@pytest.fixture(scope="module", autouse=True)
def spoiled_schemes():
    for name in SPOILS:
        registry.register(_spoiled(name))


@pytest.mark.parametrize("name", list(SPOILS))
def test_a_refused_row_is_its_cells_failed_row_naming_the_field(name):
    row = run_cell(Cell("harmonic", name, {}, {"dt": 0.1}, 1.0))
    assert row["status"] == "failed", row
    assert row["message"].startswith("the scheme's row is refused: " + SPOILS[name][1] + ":"), row["message"]
    assert rowschema.validate_row(row) == []  # the failed row itself holds: the store keeps it
    assert row["dt"] == 0.1 and json.loads(row["parameters"])["dt"] == 0.1


def test_the_healthy_schemes_rows_are_checked_and_kept():
    row = run_cell(Cell("harmonic", "rk4", {}, {"dt": 0.1}, 1.0))
    assert row["status"] == "ok" and row["steps"] == 10


@pytest.mark.parametrize("executor", ["serial", "process"])
def test_a_matrix_with_a_refused_row_stores_every_other_row_and_completes(executor, tmp_path, capsys):
    db = tmp_path / "m.sqlite"
    argv = ["matrix", "-p", "harmonic", "-i", "evil-field,rk4,verlet", "--dt", "0.1", "--t-final", "2",
            "--db", str(db), "--executor", executor, "--no-progress", "--no-html", "--no-report",
            "--repeats", "1", "--min-time", "0", "--processes", "1"]
    assert main(argv) == 0, capsys.readouterr().err
    rows = {r["integrator"]: r for r in Store(db).rows()}
    assert {k: r["status"] for k, r in rows.items()} == {"evil-field": "failed", "rk4": "ok", "verlet": "ok"}
    assert "evil_field: not a declared row field" in rows["evil-field"]["message"]
    run = Store(db).runs()[-1]
    assert run["status"] == "done" and run["done"] == run["planned"] == 3  # nothing left for --resume


EVIL_PLUGIN = """
from longtime.integrators.explicit_rk import RK4


class EvilField(RK4):
    name = "evil-field"
    summary = "RK4 whose trajectory carries a field the row does not declare"

    def _integrate(self, problem, t_final, max_samples):
        traj = super()._integrate(problem, t_final, max_samples)
        traj.extra["evil_field"] = 1
        return traj
"""


@pytest.mark.slow  # a local Dask cluster and an installed plugin
def test_on_dask_a_refused_row_costs_its_cell_only(tmp_path):
    """The same matrix on a local Dask cluster (the plugin installed, as Dask's workers need)."""
    env, _ = install_plugin(tmp_path / "plugin", "longtime-evil-field",
                            {"integrators": {"evil-field": "evil_field:EvilField"}}, {"evil_field.py": EVIL_PLUGIN})
    db = tmp_path / "m.sqlite"
    res = longtime(env, "matrix", "-p", "harmonic", "-i", "evil-field,rk4,verlet", "--dt", "0.1", "--t-final", "2",
                   "--db", str(db), "--executor", "dask", "--jobs", "2", "--no-progress", "--no-html", "--no-report",
                   "--repeats", "1", "--min-time", "0", "--processes", "1", "--checks", "0")
    assert res.returncode == 0, res.stderr
    rows = {r["integrator"]: r for r in Store(db).rows()}
    assert {k: r["status"] for k, r in rows.items()} == {"evil-field": "failed", "rk4": "ok", "verlet": "ok"}
    assert "evil_field: not a declared row field" in rows["evil-field"]["message"]
    run = Store(db).runs()[-1]
    assert run["status"] == "done" and run["done"] == run["planned"] == 3
