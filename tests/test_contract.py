"""The plugin contract (docs/plugins.md) is checked when a class is defined or registered:
each broken class fails with a one-line reason naming what to fix."""
import numba
import numpy as np
import pytest

from longtime import FixedStepIntegrator, Problem
from longtime.core.contract import ContractError, check_registered
from longtime.integrators import ExplicitRungeKutta, Splitting, TableauError, compose


@numba.njit
def _grad(x, params, out):
    out[0] = x[0]


def _plain(t, u, params, out):
    out[0] = u[0]


def _define(base, **attrs):
    return type("Plugin", (base,), {"initial_state": lambda self: [1.0, 0.0], **attrs})


@pytest.mark.parametrize("attrs,message", [
    ({"rhs": staticmethod(_plain)}, "rhs = _plain is not compiled: decorate it with @numba.njit"),
    ({"rhs": _grad}, r"must be attached as staticmethod\(_grad\)"),
    ({"grad_T": staticmethod(_grad)}, "capability 'separable' needs grad_T and grad_V; grad_V missing"),
    ({"parameters": {"w": 1.0}}, "parameters must map names to longtime.Param"),
])
def test_problem_definition_errors(attrs, message):
    with pytest.raises(ContractError, match=message) as info:
        _define(Problem, **attrs)
    assert "\n" not in str(info.value)  # one line, as `longtime list` shows it


def test_problem_registration_needs_rhs_and_no_abstract_method():
    with pytest.raises(ContractError, match="has no rhs"):
        check_registered(_define(Problem))
    with pytest.raises(ContractError, match="abstract: implement initial_state"):
        check_registered(type("NoState", (Problem,), {"rhs": staticmethod(_grad)}))
    check_registered(_define(Problem, rhs=staticmethod(_grad)))  # complete: passes


def test_scheme_definition_errors():
    with pytest.raises(ContractError, match="unknown capabilities separabel"):
        type("Typo", (FixedStepIntegrator,), {"requires": frozenset({"separabel"})})
    with pytest.raises(ContractError, match="kind = 'implicit'"):
        type("Kind", (FixedStepIntegrator,), {"kind": "implicit"})
    with pytest.raises(TableauError, match=r"row 1 of A sums to 0.5 but c\[1\] = 1.0"):
        type("Bad", (ExplicitRungeKutta,), {"A": np.array([[0, 0], [0.5, 0]]), "b": np.array([0.5, 0.5]),
                                            "c": np.array([0.0, 1.0])})
    with pytest.raises(ContractError, match="drifts sum to 0.5"):
        type("Half", (Splitting,), {"kicks": np.array([1.0]), "drifts": np.array([0.5])})


def test_family_members_must_set_what_the_family_declares():
    no_kicks = type("NoKicks", (Splitting,), {"summary": "forgot its coefficients"})
    with pytest.raises(ContractError, match="does not set drifts, which its family Splitting declares|"
                                            "does not set kicks, which its family Splitting declares"):
        check_registered(no_kicks)
    with pytest.raises(ContractError, match="does not set A, which its family ExplicitRungeKutta declares"):
        check_registered(type("NoTableau", (ExplicitRungeKutta,), {}))
    k, d = compose([1.0])
    check_registered(type("Leapfrog", (Splitting,), {"kicks": k, "drifts": d}))


def test_every_builtin_passes_the_contract():
    from longtime.core import registry

    registry.reload()
    assert registry.broken() == []
    for cls in [*registry.problems().values(), *registry.integrators().values()]:
        check_registered(cls)
