"""Roles derived from declarations (longtime.core.roles), for the built-ins as for a plugin."""
from longtime.core import registry, roles
from longtime.core.params import ROLES


def test_builtins_declare_the_contract_roles():
    """Each row parameter (dt, order, tol, eps_res) has its contract role wherever declared,
    and every declared role is known."""
    for cls in [*registry.integrators().values(), *registry.problems().values()]:
        for name, param in cls.parameters.items():
            assert param.role in ROLES, (cls.name, name)
            if name in roles.ROW_PARAMETERS:
                assert param.role == roles.ROW_PARAMETERS[name][0], (cls.name, name)


def test_problem_parameters_do_not_sweep_by_default():
    for cls in registry.problems().values():
        assert not roles.swept([cls]), cls.name


def test_swept_and_accuracy_by_role():
    bpl, rk4, rk45, tay = (registry.integrator_class(n) for n in ("bpl", "rk4", "rk45", "taylor-adaptive"))
    assert roles.swept([rk4]) == ["dt"]
    assert roles.swept([bpl]) == ["eps_res", "order"]  # accuracy nests outside order
    assert roles.swept([tay]) == ["tol", "order"]
    assert roles.accuracy(bpl) == ["eps_res"]
    assert roles.accuracy(rk45) == ["tol"]
    assert roles.accuracy(rk4) == ["dt"]
    assert roles.run_time([bpl]) == ["eps_res"]
    assert roles.run_time([rk4, rk45]) == ["dt", "tol"]
    assert roles.search_range(bpl.parameters["eps_res"]) == (1e-14, 1.0)
    assert roles.search_range(rk45.parameters["tol"]) == roles.DEFAULT_SEARCH


def test_row_columns_and_flags():
    assert roles.row_columns() == ["dt", "tol", "eps_res", "order"]
    assert roles.flag("eps_res") == "--eps-res" and roles.flag("e") == "--set e"
