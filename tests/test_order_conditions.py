"""Order conditions of schemes with coefficients (longtime.numerics.order_conditions): every
built-in splitting and tableau satisfies those of its declared order and fails one of the
next order; assert_order's failure on a perturbed Forest-Ruth names the broken condition."""
from fractions import Fraction

import pytest

from longtime.core import registry
from longtime.integrators import Splitting, compose
from longtime.numerics.order_conditions import (
    bracket,
    lyndon_words,
    scheme_conditions,
    splitting_conditions,
    tableau_conditions,
    trees,
)
from longtime.testing import assert_order

G = 1.0 / (2.0 - 2.0 ** (1.0 / 3.0))


def test_tree_and_word_counts():
    assert [len(trees(p)) for p in range(1, 9)] == [1, 1, 2, 4, 9, 20, 48, 115]
    assert [len(lyndon_words(d)) for d in range(1, 7)] == [2, 1, 2, 3, 6, 9]
    assert bracket("AAB") == "[A,[A,B]]" and bracket("ABB") == "[[A,B],B]"


def test_rk4_conditions_are_the_eight_classical_ones():
    rk4 = registry.integrator_class("rk4")
    conds = tableau_conditions(rk4.A, rk4.b, 4)
    assert len(conds) == 8 and all(c.satisfied for c in conds)
    assert "sum b AAc = 1/24" in conds[-1].name or any("sum b AAc = 1/24" in c.name for c in conds)
    # Euler's weights on RK4's stages: order 1 only, the c condition is off by 1/2
    bad = tableau_conditions(rk4.A, [1.0, 0, 0, 0], 2)
    assert not bad[1].satisfied and abs(bad[1].residual + Fraction(1, 2)) < 1e-15


@pytest.mark.parametrize("name", sorted(n for n, c in registry.integrators().items()
                                        if scheme_conditions(c, getattr(c, "order", None))))
def test_builtin_schemes_meet_their_declared_order_and_no_more(name):
    cls = registry.integrator_class(name)
    conds, _ = scheme_conditions(cls, cls.order)
    worst = max(abs(c.residual) for c in conds)
    assert worst < 1e-10, (name, worst)
    more, _ = scheme_conditions(cls, cls.order + 1)
    assert any(not c.satisfied for c in more if c.order == cls.order + 1)


def test_verlet_third_order_terms():
    kicks, drifts = compose([1.0])
    conds = {c.name.split()[0]: c.residual for c in splitting_conditions(kicks, drifts, 3)}
    # log(e^{B/2} e^{A} e^{B/2}) = A + B + [A,[A,B]]/12 ... on the Lyndon words AAB, ABB
    assert abs(abs(conds["[A,[A,B]]"]) - 1 / 12) < 1e-15 and conds["[[A,B],B]"] != 0


class PerturbedForestRuth(Splitting):  # the first coefficient + 1e-4, the middle one takes up the rest
    order = 4
    kicks, drifts = compose([G + 1e-4, 1.0 - 2.0 * G - 1e-4, G])


def test_assert_order_on_a_perturbed_forest_ruth_names_the_failing_condition():
    with pytest.raises(AssertionError) as info:
        assert_order(PerturbedForestRuth, "kepler", 4, dts=[0.02, 0.01, 0.005, 0.0025])
    msg = str(info.value)
    assert "order conditions of the splitting" in msg and "up to order 4" in msg
    assert "first not satisfied: order 3, [A,[A,B]] (word AAB)" in msg
    assert "order 1: sum of drifts = 1 +0.00e+00" in msg
