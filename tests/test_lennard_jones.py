"""lennard-jones (HLW I.4's frozen argon crystal): the data, the forces against the energy,
verlet's bounded energy error, the heyoka reference and the schemes' orders against it
(docs/problems.md)."""
import numpy as np
import pytest

from longtime.core import registry
from longtime.core.timing import Timing
from longtime.execution import cells
from longtime.measure import metrics
from longtime.measure.reference import reference_check


def crystal():
    return registry.problem_class("lennard-jones")()


def test_data_and_forces():
    p = crystal()
    inv = p.invariants(np.zeros(1), p.u0[None, :])
    assert np.all(inv["P"][0] == 0.0)  # the book's velocities carry no momentum
    assert inv["H"][0] == pytest.approx(-262272.28754699, rel=1e-12)  # m_Ar nm^2/ns^2
    assert inv["H"][0] * 66.34e-27 == pytest.approx(-1.73991436e-20, rel=1e-8)  # J

    def V(q):
        return p.invariants(np.zeros(1), np.r_[q, np.zeros(14)][None, :])["H"][0]

    q = p.u0[:14]
    grad = np.empty(14)
    p.grad_V(q, p.params, grad)
    fd = [(V(q + 1e-7 * e) - V(q - 1e-7 * e)) / 2e-7 for e in np.eye(14)]
    assert grad == pytest.approx(fd, rel=1e-7, abs=1e-7 * np.max(np.abs(grad)))


def test_verlet_energy_error_bounded_and_second_order():
    """Measured: H.max 1.53e-4 over 2 ns (2e5 steps of 10 fs); over 0.2 ns 1.49e-4 at 10 fs
    and 1.86e-3 at 40 fs."""
    p = crystal()
    verlet = registry.integrator_class("verlet")
    row = metrics.evaluate(p, verlet(dt=1e-5).integrate(p, 2.0), None, None)
    assert row["H.growth_class"] == "bounded" and row["H.max"] < 3e-4, (row["H.growth"], row["H.max"])
    assert row["L.max"] < 1e-9 and row["P.max"] < 1e-8  # verlet keeps both momenta exactly
    fine = metrics.evaluate(p, verlet(dt=1e-5).integrate(p, 0.2), None, None)["H.max"]
    coarse = metrics.evaluate(p, verlet(dt=4e-5).integrate(p, 0.2), None, None)["H.max"]
    assert 8 < coarse / fine < 20  # h^2: 16 for a step four times larger


def test_reference_trusted_over_the_sweep_and_schemes_converge_to_it():
    """heyoka double against long double: 4.8e-14 up to t = 0.005 ns (measured). The
    crystal is chaotic: errors grow fast (verlet at 20 fs: l2 error 8.5e-3 at 0.005 ns, 0.79
    at 0.02 ns), so orders are read over 0.005 ns: verlet 3.53e-2, 8.47e-3, 2.10e-3
    (steps 40, 20, 10 fs: ratios 4.16, 4.04), rk4 9.43e-4, 4.33e-5, 2.48e-6."""
    trust = reference_check(crystal(), 0.005)
    assert trust.horizon == pytest.approx(0.005) and trust.error < 1e-12
    for scheme, order in (("verlet", 2), ("rk4", 4)):
        errors = []
        for dt in (2e-5, 1e-5):
            cell = cells.Cell("lennard-jones", scheme, {}, {"dt": dt}, 0.005)
            row = cells.run_cell(cell, timing=Timing(repeats=1))
            assert row["status"] == "ok" and row["reference"] == "heyoka double", row["message"]
            errors.append(row["l2_error"])
        assert abs(np.log2(errors[0] / errors[1]) - order) < 0.4, (scheme, errors)
        assert errors[1] < 1e-2  # converging to heyoka's system: the same equations
