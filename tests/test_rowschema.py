"""The declared row: one registry of fields (longtime.core.rowschema) that the store checks
every row it adds against, and that docs/metrics.md's list of row fields is."""
import json
import re
import sqlite3
from pathlib import Path

import pytest

from longtime.commands.cli import main
from longtime.core import rowschema
from longtime.core.roles import ROW_PARAMETERS
from longtime.execution.cells import Cell, run_cell
from longtime.execution.store import Store, StoreError

CELL = Cell("harmonic", "rk4", {}, {"dt": 0.1}, 1.0)
ROW = {"problem": "harmonic", "integrator": "rk4", "status": "ok", "message": "", "dt": 0.1, "t_final": 1.0,
       "steps": 10, "cpu_s": 1e-4, "H.max": 1e-9, "H.growth_ci": [0.9, 1.1], "settings": ""}
METRICS = Path(__file__).resolve().parents[1] / "docs" / "metrics.md"


def _stored(store):
    return [{k: v for k, v in r.items() if k != "run_id"} for r in store.rows()]


@pytest.mark.parametrize("bad, field", [
    ({"stpes": 10}, "stpes"),  # an undeclared field
    ({"H.maximum": 1e-9}, "H.maximum"),  # a family's NAME with a suffix it does not have
    ({"steps": "10"}, "steps"),  # a wrong type: text for an integer
    ({"cpu_s": True}, "cpu_s"),  # a bool is no number
    ({"solution_lost": 0}, "solution_lost"),
    ({"H.growth_ci": [0.9, "1.1"]}, "H.growth_ci"),
    ({"order": 4.5}, "order"),  # an order is an integer
    ({"status": ""}, "status"),  # a required field empty
    ({"status": "sucess"}, "status"),  # a text outside its field's values
    ({"H.growth_class": "fast"}, "H.growth_class"),
    ({"steps": -5}, "steps"),  # a count outside [0, MAX_COUNT]
    ({"steps": 2**70}, "steps"),
    ({"cpu_s": -1e-3}, "cpu_s"),  # a time taken is never negative
    ({"_calibrations": [{"t": 1.0, "cpu_s": 1e-3}]}, "_calibrations"),  # the run's, never stored on a row
])
def test_store_refuses_a_row_with_an_undeclared_field_or_a_wrong_type(tmp_path, bad, field):
    store = Store(tmp_path / "s.sqlite")
    run_id = store.begin_run("test", [CELL])
    with pytest.raises(StoreError, match=re.escape(field) + r"\b") as refused:
        store.add_row(run_id, CELL, {**ROW, **bad})
    assert "refused the row of harmonic x rk4" in str(refused.value)
    assert store.rows() == []  # nothing written
    store.add_row(run_id, CELL, ROW)
    with pytest.raises(StoreError, match=re.escape(field)):
        store.update_row(run_id, CELL, {**ROW, **bad})
    assert _stored(store) == [ROW]  # the stored row is kept as it was


def test_values_are_checked_and_the_store_reads_past_a_row_of_another_status(tmp_path, capsys):
    assert rowschema.problems({**ROW, "status": "sucess", "H.growth_class": "linear"}) == [
        "status: 'sucess' is not one of ok, diverged, failed, timeout, skipped"]
    assert rowschema.validate_row({**ROW, "steps": 10**30})[0].startswith("steps: 1000")
    assert rowschema.validate_row([1, 2]) == ["a row must be a mapping of fields, not list"]
    deep: list = []
    for _ in range(100_000):  # deeper than repr goes: still one line naming the field
        deep = [deep]
    assert rowschema.validate_row({**ROW, "settings": deep}) == [
        "settings: list a list nested too deep to show, not a text"]
    # the store's reader derives its check from the same fields: a stored row of no status it
    # knows is skipped with the reason, the others are read
    store = Store(tmp_path / "s.sqlite")
    run_id = store.begin_run("test", [CELL])
    store.add_row(run_id, CELL, ROW)
    with sqlite3.connect(store.path) as con:
        con.execute("UPDATE rows SET row = ?", (json.dumps({**ROW, "status": "sucess"}),))
    assert store.rows() == []
    assert "skipped: status: 'sucess' is not one of ok" in capsys.readouterr().err


def test_a_row_without_a_required_field_is_refused():
    row = {k: v for k, v in ROW.items() if k != "integrator"}
    with pytest.raises(rowschema.RowError, match="integrator: required"):
        rowschema.check(row)
    with pytest.raises(rowschema.RowError, match="a mapping"):
        rowschema.check([("problem", "harmonic")])


def test_families_and_a_schemes_own_counters():
    for name in ("H.max", "eig3.t_50pct", "constraint.final", "error.growth_windows", "diag.r_min.max"):
        assert rowschema.field(name) is not None, name
    for name in ("H.maximum", "diag.max_", "diag.r_min.mean", ".max", "my_count", "error"):
        assert rowschema.field(name) is None, name
    row = {**ROW, "my_count": 3}
    assert rowschema.problems(row) == ["my_count: not a declared row field (longtime.core.rowschema)"]
    assert rowschema.problems(row, counters=("my_count",)) == []
    assert rowschema.problems({**row, "my_count": 3.5}, counters=("my_count",)) == [
        "my_count: float 3.5, not an integer"]


def test_row_parameters_are_declared_from_roles():
    """ROW_PARAMETERS is the one home of the parameters with a row field: each is a declared
    field, an integer for the order role and a number for the rest."""
    for name, (role, _) in ROW_PARAMETERS.items():
        declared = rowschema.field(name)
        assert declared is not None and declared.kind == ("int" if role == "order" else "float"), name
        assert declared.optional and declared.holds(None)


def test_formatters():
    assert rowschema.field("cpu_s").format(1.23456e-5) == "1.235e-05"
    assert rowschema.field("steps").format(120) == "120"
    assert rowschema.field("solution_lost").format(True) == "yes"
    assert rowschema.field("settings").format("dt=0.1") == "dt=0.1"
    # a field with a format spec of its own: an exponent to two decimals, each of a list too
    assert rowschema.field("H.growth").format(1.0234) == "1.02"
    assert rowschema.field("H.growth_ci").format([0.5, 1.25]) == "0.50, 1.25"
    assert rowschema.field("l2_error").format(None) == "-" and rowschema.field("l2_error").format(float("nan")) == "-"
    # a field by its name, as the reports format a row's fields; an undeclared one as a number
    assert rowschema.formatted("error.growth_ci", [0.5, float("nan")]) == "0.50, -"
    # a check's and an ensemble record's fields too
    assert rowschema.formatted("members", 8) == "8" and rowschema.formatted("predicted_error", 8.9e-6) == "8.900e-06"
    assert rowschema.formatted("solution_lost", False) == "no" and rowschema.formatted("cpu_s", None) == "-"
    assert rowschema.formatted("not_a_field", 0.001234) == "1.234e-03"


def test_the_report_table_formats_through_the_fields():
    from longtime.reporting.report import render

    rows = [{"problem": "kepler", "integrator": "verlet", "status": "ok", "dt": 0.1, "l2_error": 1.234567e-5,
             "H.max": float("nan"), "cpu_s": 12345.6, "steps": 1000},
            {"problem": "kepler", "integrator": "rk4", "status": "ok", "dt": 0.05, "l2_error": None,
             "H.max": 3.2e-9, "cpu_s": 20.5, "steps": 20}]
    table = render(rows, "table").splitlines()
    assert table[1].split() == ["integrator", "dt", "status", "H.max", "l2_error", "cpu_s", "steps"]
    assert table[2].split() == ["rk4", "0.05", "ok", "3.200e-09", "-", "20.5", "20"]
    assert table[3].split() == ["verlet", "0.1", "ok", "-", "1.235e-05", "1.235e+04", "1000"]


@pytest.mark.parametrize("cell", [
    CELL,
    Cell("kepler", "verlet", {"e": 0.5}, {"dt": 0.05}, 2.0),  # settings, invariants, a reference
    Cell("harmonic", "rk4", {}, {}, 1.0, skip_reason="rk4 needs nothing it lacks (a test's skip)"),
    Cell("no-such-problem", "rk4", {}, {}, 1.0),  # a failed row
])
def test_rows_of_real_cells_hold(cell):
    row = run_cell(cell)
    assert row["status"] == ("skipped" if cell.skip_reason else "failed" if cell.problem == "no-such-problem" else "ok")
    assert rowschema.problems(row) == []


def test_a_timed_out_row_holds():
    row = run_cell(Cell("harmonic", "rk4", {}, {"dt": 1e-5}, 1e3), time_limit=1e-6)
    assert row["status"] == "timeout" and rowschema.problems(row) == []


def test_a_run_stores_and_reads_back_declared_rows(tmp_path, capsys):
    db = tmp_path / "r.sqlite"
    argv = ["run", "-p", "harmonic,kepler", "-i", "rk4,verlet", "--t-final", "2", "--db", str(db), "--format", "json"]
    assert main(argv) == 0
    capsys.readouterr()
    rows = Store(db).rows()
    assert len(rows) == 4 and {r["status"] for r in rows} == {"ok"}
    for row in rows:
        assert rowschema.problems(row) == [], row["problem"]


def _documented() -> str:
    text = METRICS.read_text()
    found = re.search(r"<!-- row fields: from longtime.core.rowschema -->\n(.*?)\n<!-- end of row fields -->",
                      text, re.DOTALL)
    assert found, "docs/metrics.md has no list of row fields between its markers"
    return found.group(1)


def test_docs_list_every_declared_field_and_no_other():
    documented = re.findall(r"^\| `([^`]+)` \|", _documented(), re.MULTILINE)
    declared = [f.name for f in (*rowschema.FIELDS, *rowschema.FAMILIES)]
    assert sorted(set(declared) - set(documented)) == [], "declared but not documented in docs/metrics.md"
    assert sorted(set(documented) - set(declared)) == [], "documented in docs/metrics.md but not declared"
    # the whole table as the registry writes it (python -m longtime.core.rowschema prints it)
    assert _documented() == rowschema.markdown()


def test_the_store_checks_checks_and_ensemble_records_against_their_fields(tmp_path):
    """A check (a row with its prediction beside it) and an ensemble record are refused by the
    store, nothing written, where a field is undeclared or not its field's: a status outside
    the statuses, a role outside the check roles, text where a number goes."""
    store = Store(tmp_path / "s.sqlite")
    run_id = store.begin_run("test", [CELL])
    check = {**ROW, "check_of": "harmonic|rk4", "check_role": "best", "check_target": 1e-6, "predicted_error": 1e-7,
             "predicted_bound": False, "measured_error": 2e-7, "rank_rivals": ["rk4 dt=0.2"], "rank_held": True}
    store.add_check(run_id, CELL, check)
    for bad, named in [({"status": "sucess"}, "status: 'sucess' is not one of"),
                       ({"check_role": "winner"}, "check_role: 'winner' is not one of"),
                       ({"predicted_error": "1e-7"}, "predicted_error: str '1e-7', not a number"),
                       ({"check_colour": "red"}, "check_colour: not a declared field")]:
        with pytest.raises(StoreError, match=re.escape(named)):
            store.add_check(run_id, CELL, {**check, **bad})
    ensemble = {"problem": "henon-heiles", "integrator": "verlet", "status": "ok", "dt": 0.1, "settings": "dt=0.1",
                "problem_settings": {"state": "chaotic"}, "members": 8, "size": 1e-6, "window": 0.5, "seed": 1,
                "lyapunov_time": 20.0, "lyapunov_note": "", "t_final": 400.0, "span_lyapunov": 20.0,
                "observable": "u[0]", "floor": 0.01, "floors": [0.01, 0.008], "row_t_final": 100.0,
                "member_status": {"ok": 8}, "cpu_s": 1.5, "distance": 0.012, "distinguishable": False}
    store.add_ensemble(run_id, ensemble)
    for bad, named in [({"status": "sucess", "distance": None}, "status: 'sucess' is not one of"),
                       ({"members": 8.0}, "members: float 8.0, not an integer"),
                       ({"distance": -1.0}, "distance: -1.0 is outside"),
                       ({"colour": "red"}, "colour: not a declared field")]:
        with pytest.raises(StoreError, match=re.escape(named)):
            store.add_ensemble(run_id, {**ensemble, **bad})
    assert len(store.checks(run_id)) == 1 and len(store.ensembles(run_id)) == 1
