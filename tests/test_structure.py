"""Structure of a scheme's step map: symplecticity and reversibility defects, invariants kept."""
import numpy as np
import pytest

from longtime.integrators import Splitting, compose
from longtime.integrators.implicit_rk import Gauss4
from longtime.measure import structure
from longtime.testing import assert_reversible, assert_symplectic


class PerturbedGauss4(Gauss4):
    """Gauss4 with A[0, 1] perturbed by 1e-3 (c kept the row sums): no longer symplectic."""
    name = "structure-perturbed-gauss4"
    A = Gauss4.A.copy()
    A[0, 1] += 1e-3
    c = A.sum(axis=1)


class PerturbedVerletComposition(Splitting):
    """Three Verlet steps with coefficients off any published set: a composition of
    symplectic maps, symplectic still."""
    name = "structure-perturbed-composition"
    order = 2
    kicks, drifts = compose([0.3 + 1e-3, 0.4 - 2e-3, 0.3 + 1e-3])


@pytest.mark.parametrize("scheme", ["verlet", "symplectic-euler", "gauss4", "blanes-moan-s6",
                                    PerturbedVerletComposition])
def test_symplectic_schemes_pass(scheme):
    found = assert_symplectic(scheme)
    # the defect is round-off, far inside the stated error (a failing scheme's is ~1e-4)
    assert found.symplecticity_defect < found.symplecticity_error < 1e-8 and found.problem == "kepler"


@pytest.mark.parametrize("scheme", ["rk4", PerturbedGauss4])
def test_non_symplectic_schemes_fail(scheme):
    with pytest.raises(AssertionError,
                       match=r"symplecticity defect \|\|M\^T J M - J\|\| = \d\.\d+e-0[45], expected at most"):
        assert_symplectic(scheme)


@pytest.mark.parametrize("scheme", ["verlet", "gauss4"])
def test_symmetric_schemes_are_reversible(scheme):
    found = assert_reversible(scheme)
    assert found.reversibility_defect <= 4 * np.finfo(float).eps


@pytest.mark.parametrize("scheme, low", [("rk4", 1e-7), ("symplectic-euler", 1e-3)])
def test_non_symmetric_schemes_are_not_reversible(scheme, low):
    with pytest.raises(AssertionError, match=r"then one of -h misses the start by") as info:
        assert_reversible(scheme)
    assert structure.measure(scheme).reversibility_defect > low, str(info.value)


def test_invariants_kept_to_round_off():
    # kepler's angular momentum is quadratic: kept by symplectic partitioned and Gauss schemes, not by rk4
    assert structure.measure("verlet").kept == ["L"] and structure.measure("gauss4").kept == ["L"]
    rk4 = structure.measure("rk4")
    assert rk4.kept == [] and rk4.changes["L"] > 1e-7


def test_a_scheme_that_cannot_step_a_canonical_problem_says_why():
    found = structure.measure("etdrk4")
    assert found.reason and found.symplectic is None and "linear_part" in found.reason
    with pytest.raises(AssertionError, match="structure not measured"):
        assert_symplectic("etdrk4")
