"""The default matrix's budget (longtime.execution.budget): what it moves, that every pair
keeps its rows, that --full-sweep runs the sweep as it is, and that the report says it.
Only cells are planned here: nothing is integrated."""
import pytest

from longtime.commands.cli import build_parser
from longtime.commands.matrix import matrix_cells
from longtime.core import registry
from longtime.execution import budget
from longtime.execution.cells import Cell, base_row, expand
from longtime.reporting.report import summary


@pytest.fixture(autouse=True)
def _installed_only(monkeypatch):
    """The default matrix of what is installed: classes other tests registered from Python
    (some break the contract on purpose) are not in it."""
    monkeypatch.setattr(registry, "_session", {"problems": {}, "integrators": {}})


@pytest.fixture
def python_stepped_dop853(monkeypatch):
    """dop853 costed as a peer stepped by a Python loop (solve_ivp's, about a tenth of a
    millisecond a step): on fpu its costliest tolerance is then over a cell's budget, the
    example of a peer that runs fewer settings."""
    monkeypatch.setattr(registry.integrator_class("dop853"), "python_step_s", 1e-4)


def plan(*argv: str):
    return matrix_cells(build_parser().parse_args(["matrix", *argv]))


def pairs(cells):
    return {(c.problem, c.integrator) for c in cells}


def test_a_python_stepped_peer_costs_more_per_step_than_a_compiled_loop(python_stepped_dop853):
    dop, verlet = (Cell("fpu", s, {}, {}, 1000.0) for s in ("dop853", "verlet"))
    assert budget.run_seconds(dop) > 100 * budget.run_seconds(verlet)
    assert budget.run_seconds(dop) > budget.CELL_BUDGET_S  # fpu's sweep horizon is over the budget


def test_fpu_dop853_on_hairers_code_runs_its_whole_sweep():
    cells, moves = budget.fit(expand(["fpu"], ["dop853"], default_sweep=True))
    assert moves == [] and [c.integrator_settings["tol"] for c in cells] == [1e-6, 1e-9, 1e-12]
    assert {c.t_final for c in cells} == {1000.0} and all(c.time_limit is None for c in cells)


def test_fpu_dop853_runs_fewer_settings_at_the_full_horizon_the_rest_of_fpu_does_not_move(python_stepped_dop853):
    full = expand(["fpu"], ["dop853", "verlet", "gauss6"], default_sweep=True)
    cells, moves = budget.fit(full)
    assert [(m.problem, m.integrator) for m in moves] == [("fpu", "dop853")]
    assert moves[0].setting == "tol=1e-12 left out"  # the costliest tolerance, never the horizon
    dop = [c for c in cells if c.integrator == "dop853"]
    assert [c.integrator_settings["tol"] for c in dop] == [1e-6, 1e-9] and {c.t_final for c in dop} == {1000.0}
    assert all(c.note.startswith(budget.NOTE) and "--full-sweep" in c.note for c in dop)
    assert all(budget.run_seconds(c) <= budget.CELL_BUDGET_S for c in dop)
    others = [c for c in cells if c.integrator != "dop853"]
    assert others == [c for c in full if c.integrator != "dop853"]  # settings and keys unchanged
    assert all(c.note is None for c in others)


def test_a_fixed_step_sweep_over_the_budget_runs_a_shorter_horizon(monkeypatch):
    full = expand(["fpu"], ["verlet"], default_sweep=True)
    worst = max(budget.run_seconds(c) for c in full)
    monkeypatch.setattr(budget, "CELL_BUDGET_S", worst / 3)
    cells, moves = budget.fit(full)
    assert len(moves) == 1 and moves[0].setting == "t_final 1000 -> 200"
    assert {c.t_final for c in cells} == {200.0} and len(cells) == len(full)
    assert all(budget.run_seconds(c) <= budget.CELL_BUDGET_S for c in cells)


def test_every_pair_of_the_default_matrix_keeps_a_row():
    budgeted, moves = plan()
    full, none = plan("--full-sweep")
    assert none == [] and moves
    assert pairs(budgeted) == pairs(full)
    ran = {(c.problem, c.integrator) for c in budgeted if not c.skip_reason}
    slow = {(c.problem, c.integrator) for c in budgeted if c.skip_reason and c.skip_reason.startswith(budget.TOO_SLOW)}
    assert ran | slow == {(c.problem, c.integrator) for c in full if not c.skip_reason}
    assert ("fpu", "dop853") in ran
    # a scheme that chooses its own steps runs its problem's sweep horizon, whatever the budget left out
    for c in budgeted:
        pcls = registry.problem_class(c.problem)
        if budget.adaptive(c.integrator) and c.t_final != pcls.long_t_final:
            assert c.t_final == (pcls.sweep_t_final or pcls.default_t_final), c
    moved = {(m.problem, m.integrator) for m in moves}
    # cells of unmoved pairs are exactly the full sweep's
    keep = [c.key for c in budgeted if (c.problem, c.integrator) not in moved]
    assert keep == [c.key for c in full if (c.problem, c.integrator) not in moved]


def test_full_sweep_restores_the_default_sweep(python_stepped_dop853):
    full, moves = plan("-p", "fpu", "-i", "dop853,scipy-rk23", "--full-sweep")
    assert moves == [] and {c.t_final for c in full} == {1000.0} and len(full) == 6
    assert all(c.note is None and c.time_limit is None for c in full)
    budgeted, moves = plan("-p", "fpu", "-i", "dop853,scipy-rk23")
    assert {c.t_final for c in budgeted} == {1000.0} and len(budgeted) == 3
    # two settings moved, and scipy's peers run as one chain (timing by need, the default)
    assert [m.kind for m in moves].count(budget.CHAINED) == 1 and len(moves) == 3
    assert all(c.bound is None for c in full) and all(c.bound == 2.0 for c in budgeted)


def test_a_given_final_time_is_never_moved():
    cells, moves = plan("-p", "fpu", "-i", "dop853", "--t-final", "1000")
    assert [m.kind for m in moves] == [budget.CHAINED] and {c.t_final for c in cells} == {1000.0}
    # --timing all measures every setting to its end: no chain
    cells, moves = plan("-p", "fpu", "-i", "dop853", "--t-final", "1000", "--timing", "all")
    assert moves == [] and all(c.bound is None for c in cells)


def test_a_long_time_cell_over_its_budget_is_left_out_and_said(monkeypatch):
    full = expand(["toda"], ["rk4"], default_sweep=True)
    long_tf = registry.problem_class("toda").long_t_final
    assert any(c.t_final == long_tf for c in full)
    monkeypatch.setattr(budget, "LONG_CELL_BUDGET_S", 1e-6)
    cells, moves = budget.fit(full)
    assert not any(c.t_final == long_tf for c in cells) and cells  # the sweep stays
    assert len(moves) == 1 and "long-time cell" in moves[0].setting
    assert all("long-time cell" in c.note for c in cells)


def test_the_note_and_time_limit_are_not_part_of_the_key_and_survive_the_store():
    cell = Cell("fpu", "dop853", {}, {"tol": 1e-6}, 200.0, note="budget: t_final 1000 -> 200", time_limit=15.0)
    assert cell.key == Cell("fpu", "dop853", {}, {"tol": 1e-6}, 200.0).key
    assert Cell.from_dict(cell.to_dict()) == cell
    assert not {"note", "time_limit"} & set(Cell("fpu", "dop853", {}, {"tol": 1e-6}, 200.0).to_dict())


def test_the_report_names_what_the_budget_moved(python_stepped_dop853):
    cells, _ = budget.fit(expand(["fpu"], ["dop853"], default_sweep=True))
    rows = [{**base_row(c), "status": "ok", "message": c.note} for c in cells]
    text = summary(rows, orders=False)
    assert "moved by the default matrix's budget: dop853 tol=1e-12 left out" in text
    assert "--full-sweep runs them" in text


def test_the_moves_are_one_line_as_the_job_starts_and_each_with_full(capsys, python_stepped_dop853):
    from longtime.execution.main_job import say_moves

    full = expand(["fpu"], ["dop853", "verlet"], default_sweep=True)
    _, moves = budget.fit(full)
    left = budget.Move("fpu", "verlet", "long-time cell at t_final 1e+06 left out", "about 40 s a run", budget.LONG_OUT)
    say_moves(moves + [left])
    short = capsys.readouterr().err.strip().splitlines()
    assert len(short) == 1 and "moved 2 setting(s)" in short[0] and "1 long-time cell(s) left out" in short[0]
    assert "1 pair(s) run fewer settings" in short[0] and "--full" in short[0]
    say_moves(moves + [left], full=True)
    listed = capsys.readouterr().err.strip().splitlines()
    assert len(listed) == 3 and listed[1].strip() == moves[0].text() and listed[2].strip() == left.text()


def test_a_cells_estimated_wall_time_weighs_its_runs():
    """The progress line's weights: a skipped cell costs nothing, every other cell the
    overhead and more, a cell of ten times the steps more than a cell of one."""
    from longtime.core.timing import Timing
    from longtime.execution.budget import CELL_OVERHEAD_S, cell_seconds
    from longtime.execution.cells import Cell

    timing = Timing()
    short = cell_seconds(Cell("kepler", "rk4", {}, {"dt": 0.01}, 100.0), timing)
    long = cell_seconds(Cell("kepler", "rk4", {}, {"dt": 0.01}, 1e6), timing)
    assert cell_seconds(Cell("kepler", "verlet", skip_reason="needs x"), timing) == 0.0
    assert CELL_OVERHEAD_S < short < long
