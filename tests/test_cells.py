"""Cells of the matrix (longtime.execution.cells.expand): any declared parameter sweeps, and the final
time; bad sweeps are input errors. Nothing here integrates."""
import pytest
from _rtol_scheme import NAME as RTOL
from _rtol_scheme import register

from longtime.core.params import InputError
from longtime.execution.cells import expand


def test_problem_parameter_and_final_time_sweep():
    cells = expand(["kepler"], ["verlet"], sweeps={"dt": [0.01], "e": ["0.5", "0.9", "0.99"]},
                   t_final=[10.0, 100.0])
    assert [(c.problem_settings["e"], c.t_final) for c in cells] == [
        (0.5, 10.0), (0.5, 100.0), (0.9, 10.0), (0.9, 100.0), (0.99, 10.0), (0.99, 100.0)]  # typed
    assert all(c.integrator_settings == {"dt": 0.01} for c in cells)


def test_scalar_final_time_and_sets_still_work():
    (cell,) = expand(["toda"], ["rk4"], sweeps={"dt": [0.1]}, t_final=50.0, sets={"d": "4"})
    assert cell.t_final == 50.0 and cell.problem_settings == {"d": 4}
    (cell,) = expand(["toda"], ["rk4"])
    assert cell.t_final is not None and cell.integrator_settings == {}


def test_scheme_option_sweeps_nested_inside_the_step():
    cells = expand(["harmonic"], ["gauss4"], sweeps={"max_iter": [5, 50], "dt": [0.1, 0.2]})
    assert [c.integrator_settings for c in cells] == [
        {"dt": 0.1, "max_iter": 5}, {"dt": 0.1, "max_iter": 50},
        {"dt": 0.2, "max_iter": 5}, {"dt": 0.2, "max_iter": 50}]


def test_axes_nest_by_role():
    """bpl's accuracy parameter varies outside its order, whatever the order of the sweeps."""
    cells = expand(["toda"], ["bpl"], sweeps={"order": [8, 10], "eps_res": [1e-6, 1e-8]})
    assert [(c.integrator_settings["eps_res"], c.integrator_settings["order"]) for c in cells] == [
        (1e-6, 8), (1e-6, 10), (1e-8, 8), (1e-8, 10)]


def test_a_sweep_reaches_only_the_classes_that_declare_it():
    cells = expand(["toda", "kepler"], ["rk4"], sweeps={"d": ["3", "4"]})
    assert [(c.problem, c.problem_settings) for c in cells] == [
        ("toda", {"d": 3}), ("toda", {"d": 4}), ("kepler", {})]


def test_bad_sweeps_are_input_errors():
    with pytest.raises(InputError, match="--set nope: unknown parameter"):
        expand(["toda"], ["rk4"], sweeps={"nope": [1, 2]})
    with pytest.raises(InputError, match="--tol is not a parameter of any selected integrator"):
        expand(["toda"], ["rk4"], sweeps={"tol": [1e-6]})
    with pytest.raises(InputError, match="--dt and --set dt= both give dt"):
        expand(["toda"], ["rk4"], sweeps={"dt": [0.1]}, sets={"dt": "0.2"})
    with pytest.raises(InputError, match="d is given both"):
        expand(["toda"], ["rk4"], sweeps={"d": [3, 4]}, sets={"d": "5"})
    with pytest.raises(InputError, match="kepler.*e="):
        expand(["kepler"], ["rk4"], sweeps={"e": ["0.5", "1.5"]})
    with pytest.raises(InputError, match="t_final"):
        expand(["kepler"], ["rk4"], t_final=[10.0, -1.0])


def test_default_sweep_of_a_plugin_accuracy_parameter(monkeypatch):
    """A plugin's own accuracy parameter sweeps from its ``sweep`` and from sweeps."""
    register(monkeypatch)
    cells = expand(["harmonic"], [RTOL], default_sweep=True)
    assert [c.integrator_settings for c in cells] == [{"rtol": 1e-4}, {"rtol": 1e-7}]
    cells = expand(["harmonic"], [RTOL], sweeps={"rtol": ["1e-5", "1e-9"]}, default_sweep=True)
    assert [c.integrator_settings for c in cells] == [{"rtol": 1e-5}, {"rtol": 1e-9}]


def test_default_sweep_of_the_builtins():
    cells = expand(["harmonic"], ["rk45", "bpl"], default_sweep=True)
    rk45 = [c.integrator_settings for c in cells if c.integrator == "rk45"]
    bpl = [c.integrator_settings for c in cells if c.integrator == "bpl"]
    assert rk45 == [{"tol": t} for t in (1e-4, 1e-6, 1e-8)]
    assert bpl == [{"eps_res": e} for e in (1e-4, 1e-6, 1e-8, 1e-10)]
