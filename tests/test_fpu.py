"""fpu (HLW I.5): the Hamiltonian in the book's two sets of variables, the initial values,
and the oscillatory energy I over [0, 5000] at dt = 0.005 (docs/problems.md): symplectic
schemes keep it as the true solution does, rk4 loses most of it."""
import numpy as np
import pytest

from longtime.core import registry
from longtime.measure import metrics
from longtime.measure.reference import reference_states

T_FINAL, DT = 5000.0, 0.005


def fpu(**settings):
    return registry.problem_class("fpu")(**settings)


def chain_potential(x, m, omega):
    """V in the chain's coordinates q_1..q_2m (HLW I.5.1), from the rotated variables."""
    x0, x1 = x[:m], x[m:]
    q = np.zeros(2 * m + 2)  # q_0 = q_{2m+1} = 0
    q[1:2 * m:2] = (x0 - x1) / np.sqrt(2)  # q_{2i-1}
    q[2:2 * m + 1:2] = (x0 + x1) / np.sqrt(2)  # q_{2i}
    stiff = sum((q[2 * i] - q[2 * i - 1]) ** 2 for i in range(1, m + 1))
    soft = sum((q[2 * i + 1] - q[2 * i]) ** 4 for i in range(m + 1))
    return omega**2 / 4 * stiff + soft


@pytest.mark.parametrize("m, omega", [(3, 50.0), (1, 7.0), (5, 20.0)])
def test_potential_gradient_and_heyoka_system_agree_with_the_chain(m, omega):
    import heyoka as hy

    p = fpu(m=m, omega=omega)
    rng = np.random.default_rng(m)
    x = rng.normal(size=2 * m)
    U = np.r_[x, np.zeros(2 * m)][None, :]
    assert p.invariants(np.zeros(1), U)["H"][0] == pytest.approx(chain_potential(x, m, omega), rel=1e-13)
    grad = np.empty(2 * m)
    p.grad_V(x, p.params, grad)
    fd = [(chain_potential(x + 1e-6 * e, m, omega) - chain_potential(x - 1e-6 * e, m, omega)) / 2e-6
          for e in np.eye(2 * m)]
    assert grad == pytest.approx(fd, rel=1e-6, abs=1e-6)
    slow = np.empty(2 * m)  # the oscillatory capability: V = omega^2 |x1|^2 / 2 + U
    p.grad_U(x, p.params, slow)
    freq = np.empty(2 * m)
    p.frequencies(p.params, freq)
    assert np.all(freq[:m] == 0) and np.all(freq[m:] == omega)
    assert slow + freq**2 * x == pytest.approx(grad, rel=1e-14, abs=1e-13)
    u = rng.normal(size=4 * m)
    out = np.empty(4 * m)
    p.rhs(0.0, u, p.params, out)
    variables, rhs = p.heyoka_system()
    assert hy.cfunc(rhs, variables)(u) == pytest.approx(out, rel=1e-13, abs=1e-12)


def test_initial_values_and_energies():
    p = fpu()
    assert list(p.u0) == [1, 0, 0, 1 / 50, 0, 0, 1, 0, 0, 1, 0, 0]
    u0 = p.u0[None, :]
    # H0 = 1 (kinetic) + 1/2 (stiff spring 1) + (0.98^4 + 1.02^4) / 4 (soft springs 0 and 1)
    assert p.invariants(np.zeros(1), u0)["H"][0] == pytest.approx(2.00120008, rel=1e-14)
    assert p.invariants(np.zeros(1), u0)["I"][0] == 1.0
    diag = p.diagnostics(np.zeros(1), u0)
    assert set(diag) == {"I1", "I2", "I3", "I"} and diag["I1"][0] == 1.0 and diag["I2"][0] == 0.0
    assert "I" not in fpu(oscillatory_energy=False).invariants(np.zeros(1), u0)
    assert "oscillatory" in p.capabilities() and "separable" in p.capabilities()


def max_deviation_of_I(p, t, U):
    I = p.diagnostics(t, U)["I"]
    return float(np.max(np.abs(I - I[0])))


@pytest.mark.slow
def test_oscillatory_energy_over_5000():
    """Measured (100,001 samples): the reference (heyoka) 0.0820, verlet 0.0900, mollified
    impulse 0.0762, rk4 0.977."""
    p = fpu()
    runs = {s: registry.integrator_class(s)(dt=DT).integrate(p, T_FINAL)
            for s in ("verlet", "mollified-impulse", "rk4")}
    t = runs["verlet"].t
    true = max_deviation_of_I(p, t, reference_states(p, t))
    assert 0.07 < true < 0.1  # I is a near-invariant: O(1/omega) along the true solution
    for scheme in ("verlet", "mollified-impulse"):
        traj = runs[scheme]
        assert traj.status == "ok" and np.array_equal(traj.t, t)
        assert abs(max_deviation_of_I(p, t, traj.u) - true) < 0.02, scheme
        row = metrics.evaluate(p, traj, None, None)
        assert row["I.growth_class"] == "bounded", (scheme, row["I.growth"])
        assert row["I.max"] == pytest.approx(max_deviation_of_I(p, t, traj.u), rel=1e-12)  # I(0) = 1
    # rk4 damps the stiff springs: |R(i h omega)|^2 = 1 - (h omega)^6 / 72 a step
    rk4 = runs["rk4"]
    assert rk4.status == "ok" and max_deviation_of_I(p, rk4.t, rk4.u) > 0.5
    assert metrics.evaluate(p, rk4, None, None)["I.growth_class"] == "saturated"


@pytest.mark.parametrize("settings, word", [({"m": 0}, "m"), ({"omega": 0.0}, "omega"),
                                            ({"oscillatory_energy": "maybe"}, "oscillatory_energy")])
def test_bad_settings(settings, word):
    from longtime.core.params import InputError

    with pytest.raises(InputError, match=word):
        fpu(**settings)


@pytest.mark.parametrize("dt", [0.01, 0.005])
def test_rk4_loses_I_at_its_amplification_factor(dt):
    """Each step multiplies the stiff springs' energy by |R(i h omega)|^2 = 1 - y^6/72 + y^8/576
    (y = h omega): measured I(t) - |R|^(2n) within 0.017 at t = 50, 100, 200, 400."""
    p = fpu()
    traj = registry.integrator_class("rk4")(dt=dt).integrate(p, 400.0, max_samples=401)
    y = dt * p.settings["omega"]
    R2 = abs(1 - y**2 / 2 + y**4 / 24 + 1j * (y - y**3 / 6)) ** 2
    assert R2 == pytest.approx(1 - y**6 / 72 + y**8 / 576, rel=1e-14)
    I = p.diagnostics(traj.t, traj.u)["I"]
    k = np.searchsorted(traj.t, [50.0, 100.0, 200.0, 400.0])
    assert np.max(np.abs(I[k] - R2 ** (traj.t[k] / dt))) < 0.03
