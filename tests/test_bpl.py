"""Borel-Pade-Laplace: accuracy, its hard cases (a Borel pole on the positive axis, a rank-deficient
Toeplitz block, a quadrature that fails, a growing state, a blow-up), and the paper's Toda figure."""
from __future__ import annotations

import math

import numba
import numpy as np
import pytest

from longtime.core import registry
from longtime.core.params import InputError
from longtime.core.problem import Problem
from longtime.execution.cells import Cell, run_cell
from longtime.integrators.bpl import BorelPadeLaplace


# ---------------------------------------------------------------- tiny test problems
# One compiled kernel serves every scalar test equation (a compile costs seconds):
# u' = a u + b u^2 + c (u - t) / t^2, params (a, b, c).
@numba.njit(cache=True)
def _scalar_rhs(t, u, params, out):
    out[0] = params[0] * u[0] + params[1] * u[0] * u[0]
    if params[2] != 0.0:
        out[0] += params[2] * (u[0] - t) / (t * t)


@numba.njit(cache=True)
def _g_coeff(coeffs, params, n):
    """Coefficient n of G = a u + b u^2 (zero for n < 0)."""
    if n < 0:
        return 0.0
    square = 0.0
    for j in range(n + 1):
        square += coeffs[j, 0] * coeffs[n - j, 0]
    return params[0] * coeffs[n, 0] + params[1] * square


@numba.njit(cache=True)
def _scalar_taylor(t0, u, params, coeffs, work):
    c = params[2]
    N = coeffs.shape[0] - 1
    coeffs[0, 0] = u[0]
    if c == 0.0:
        for n in range(N):
            coeffs[n + 1, 0] = _g_coeff(coeffs, params, n) / (n + 1)
        return
    # (t0 + s)^2 u' = (t0 + s)^2 G + c (u - t0 - s), coefficient n in s:
    # t0^2 (n+1) u_{n+1} + 2 t0 n u_n + (n-1) u_{n-1}
    #     = t0^2 G_n + 2 t0 G_{n-1} + G_{n-2} + c (u_n - t0 [n=0] - [n=1])
    if t0 == 0.0:  # singular point: the formal series, u_n from the order-n equation
        for n in range(1, N + 1):
            coeffs[n, 0] = ((n - 1) * coeffs[n - 1, 0] - _g_coeff(coeffs, params, n - 2)) / c
            if n == 1:
                coeffs[n, 0] += 1.0
        return
    for n in range(N):
        acc = (t0 * t0 * _g_coeff(coeffs, params, n) + 2.0 * t0 * _g_coeff(coeffs, params, n - 1)
               + _g_coeff(coeffs, params, n - 2) + c * coeffs[n, 0] - 2.0 * t0 * n * coeffs[n, 0])
        if n >= 1:
            acc -= (n - 1) * coeffs[n - 1, 0]
        if n == 0:
            acc -= c * t0
        if n == 1:
            acc -= c
        coeffs[n + 1, 0] = acc / (t0 * t0 * (n + 1))


class Quadratic(Problem):
    """u' = a u + b u^2 + c (u - t)/t^2 with u(0) = u0; subclasses set the coefficients."""

    rhs = staticmethod(_scalar_rhs)
    taylor = staticmethod(_scalar_taylor)
    coefficients = (0.0, 0.0, 0.0)
    start = 1.0

    def initial_state(self):
        return [self.start]

    def kernel_params(self):
        return np.array(self.coefficients)


class Decay(Quadratic):
    """u' = -u; default_dt = 20 makes the first trial step the whole span."""

    name = "decay"
    default_dt = 20.0
    coefficients = (-1.0, 0.0, 0.0)


class Riccati(Quadratic):
    """u' = u^2: u = 1/(1 - t) blows up at t = 1; the Borel transform is e^xi, whose [4/5]
    Pade approximant has a real positive pole."""

    name = "riccati"
    default_dt = 0.1
    coefficients = (0.0, 1.0, 0.0)


class EulerSeries(Quadratic):
    """t^2 u' = u - t, u(0) = 0: the Taylor series at 0 is sum n! t^(n+1), whose Borel
    transform is 1/(1 - xi), a pole on the positive real axis (the Stokes line)."""

    name = "euler-series"
    autonomous = False
    default_dt = 0.2
    coefficients = (0.0, 0.0, 1.0)
    start = 0.0


def harmonic(**settings):
    return registry.problem_class("harmonic")(**settings)


# ---------------------------------------------------------------- parameters
def test_parameters_and_default_degrees():
    assert BorelPadeLaplace().degrees == (4, 5)  # the paper's [4/5] at N = 10
    assert BorelPadeLaplace(order=4).degrees == (1, 2)
    assert BorelPadeLaplace(order=14).degrees == (6, 7)
    assert BorelPadeLaplace(pade_den=3).degrees == (6, 3)
    with pytest.raises(InputError, match="pade_num=6, pade_den=5"):
        BorelPadeLaplace(pade_num=6, pade_den=5)
    with pytest.raises(InputError, match="eps_res"):
        BorelPadeLaplace(eps_res=-1.0)

    class NoSeries(Problem):
        rhs = staticmethod(_scalar_rhs)

        def initial_state(self):
            return [1.0]

    with pytest.raises(InputError, match="needs taylor"):
        BorelPadeLaplace().integrate(NoSeries(), 1.0)


# ---------------------------------------------------------------- accuracy
def test_harmonic_accuracy_and_even_start():
    p = harmonic()
    traj = BorelPadeLaplace(eps_res=1e-8).integrate(p, 20.0)
    assert traj.status == "ok"
    err = np.max(np.abs(traj.u - p.exact(traj.t)))
    assert err < 1e-6
    # at t0 = 0 the Borel transforms of cos and -sin are odd and even: degenerate [4/5]
    assert traj.counters["pade_degenerate"] >= 1
    assert traj.counters["residual_evals"] >= traj.steps
    # a tighter residual gives a smaller error
    coarse = BorelPadeLaplace(eps_res=1e-4).integrate(p, 20.0)
    assert np.max(np.abs(coarse.u - p.exact(coarse.t))) > 3 * err


def test_residual_bound_holds_at_every_accepted_step():
    p = Riccati()
    eps = 1e-6
    traj = BorelPadeLaplace(eps_res=eps).integrate(p, 0.9)
    assert traj.status == "ok"
    np.testing.assert_allclose(traj.u[:, 0], 1.0 / (1.0 - traj.t), rtol=1e-5)


# ---------------------------------------------------------------- hard cases
@pytest.mark.parametrize("fallback", ["none", "taylor"])
def test_borel_pole_on_positive_axis(fallback):
    """Euler series: B = 1/(1 - xi) exactly. The robust Pade finds the pole (a degenerate
    [0/1]). The paper's algorithm lets the residual judge the spoilt sum and shortens the
    step; the Taylor variant replaces that component's sum once the pole is within reach.
    Both must give a solution of the ODE."""
    p = EulerSeries()
    traj = BorelPadeLaplace(eps_res=1e-6, fallback=fallback).integrate(p, 1.0)
    assert traj.status == "ok"
    assert traj.counters["pade_degenerate"] >= 1
    if fallback == "taylor":
        assert traj.counters["fallbacks"] >= 1
        assert traj.extra["fallback_fraction"] == traj.counters["fallbacks"] / traj.steps > 0
    else:
        assert traj.counters["fallbacks"] == 0 and traj.extra["fallback_fraction"] == 0.0
    from scipy.integrate import solve_ivp

    # the first step from the singular point: the series is the only definition of u there
    t1, u1 = traj.t[1], traj.u[1, 0]
    taylor_sum = sum(math.factorial(n) * t1 ** (n + 1) for n in range(10))
    assert abs(u1 - taylor_sum) < 1e-6 * max(1.0, abs(taylor_sum)) or t1 * 66.53 < 1.0
    # later steps: the ODE amplifies errors like exp(-1/t) (x 1e6 from t = 0.06 to 1), so
    # check each step's local error against an accurate solve from its start
    for i in range(1, traj.t.size - 1):
        ref = solve_ivp(lambda t, u: (u - t) / t**2, (traj.t[i], traj.t[i + 1]), [traj.u[i, 0]],
                        rtol=1e-12, atol=1e-14)
        assert abs(ref.y[0, -1] - traj.u[i + 1, 0]) < 1e-6 * (traj.t[i + 1] - traj.t[i])


def test_riccati_pole_of_pade_of_exp():
    """u' = u^2: the Borel transform e^xi has a [4/5] Pade approximant with a positive
    real pole; the run to near the blow-up stays accurate and never accepts garbage."""
    p = Riccati()
    traj = BorelPadeLaplace(eps_res=1e-6).integrate(p, 0.99)
    assert traj.status == "ok"
    np.testing.assert_allclose(traj.u[:, 0], 1.0 / (1.0 - traj.t), rtol=1e-4)


def test_even_function_rank_deficient_toeplitz_block():
    """The harmonic oscillator at (1, 0): cos and -sin, odd and even Borel transforms."""
    p = harmonic()
    traj = BorelPadeLaplace(eps_res=1e-6, max_dt=0.5).integrate(p, 1.0)
    assert traj.status == "ok"
    assert traj.counters["pade_degenerate"] >= 1
    assert np.max(np.abs(traj.u - p.exact(traj.t))) < 1e-5


def test_equilibrium_takes_max_dt():
    p = harmonic(q0=0.0, p0=0.0)
    traj = BorelPadeLaplace(max_dt=0.5).integrate(p, 10.0)
    assert traj.status == "ok"
    assert traj.max_dt == 0.5
    assert traj.steps <= 21  # the first proposal (the problem's dt), then max_dt throughout
    assert np.all(traj.u == 0.0)
    assert traj.counters["residual_evals"] == traj.steps  # one residual per step, r = 0


def test_quadrature_failure_on_a_too_long_step():
    """u' = -u, first proposal t = 20 in one step: the 20-node sum cannot hold there; the
    step must be shortened and the end value right, never accepted wrong."""
    p = Decay()
    eps = 1e-8
    traj = BorelPadeLaplace(eps_res=eps, max_dt=20.0).integrate(p, 20.0)
    assert traj.status == "ok"
    assert traj.steps > 1 and traj.t[1] < 20.0
    np.testing.assert_allclose(traj.u[:, 0], np.exp(-traj.t), rtol=0, atol=1e-7)
    assert abs(traj.u[-1, 0] - math.exp(-20.0)) < 1e-8


def test_growing_state_never_crashes():
    """duffing-1 (amplitude ~ e^(t/3), |F| ~ 1e9 at t = 25): ok with I bounded, or a status.
    The steps shrink with the growing frequency (the cost grows like e^(2t/3))."""
    p = registry.problem_class("duffing-1")()
    traj = BorelPadeLaplace(eps_res=1e-2).integrate(p, 25.0)
    assert traj.status in ("ok", "diverged", "failed")
    assert traj.status == "ok" and traj.min_dt < 1e-5
    assert np.all(np.isfinite(traj.u[:-1]))
    I = p.first_integral(traj.t, traj.u)
    ok = np.isfinite(I)
    assert np.max(np.abs(I[ok] - I[0]) / abs(I[0])) < 0.05


def test_blow_up_is_a_status_and_nothing_non_finite_is_accepted():
    traj = BorelPadeLaplace(eps_res=1e-6).integrate(Riccati(), 2.0)
    assert traj.status in ("diverged", "failed")
    assert traj.t[-1] < 1.0 + 1e-6
    assert np.all(np.isfinite(traj.u))


# ---------------------------------------------------------------- the paper's figures
def test_toda_reproduces_the_papers_bpl_figure():
    """docs/paper.md, the paper's BPL on toda over t_f = 5000: E_mean 3.010e-4 at mean step 0.0983
    (RK4sym at dt = 0.1: 2.261e-3). The faithful algorithm (no fallback) at eps_res = 3e-4
    lands on the paper's figure within 30 %: measured 2.99e-4 at mean step 0.0981."""
    row = run_cell(Cell("toda", "bpl", {}, {"eps_res": 3e-4}, 5000.0), reference=False)
    assert row["status"] == "ok"
    assert row["fallback_fraction"] == 0.0
    assert abs(row["mean_dt"] / 0.0983 - 1) < 0.05
    assert abs(row["H.mean"] / 3.010e-4 - 1) < 0.3


def test_taylor_fallback_is_another_scheme_on_toda():
    """The opt-in variant: about a third of the toda steps are Taylor steps, and its
    energy error at the same mean step is several times below the paper's."""
    row = run_cell(Cell("toda", "bpl", {}, {"eps_res": 3e-4, "fallback": "taylor"}, 5000.0),
                   reference=False)
    assert row["status"] == "ok"
    assert 0.2 < row["fallback_fraction"] < 0.5
    assert 0.09 < row["mean_dt"] < 0.12
    assert row["H.mean"] < 3.010e-4 / 3


# ---------------------------------------------------------------- linear stability
def test_amplification_on_the_imaginary_axis(monkeypatch):
    """One step on a rotation: exact to the tolerance for small y = omega h, amplifying
    past an onset that grows with the series order (measured: 0.72, 1.74, 2.34 for
    N = 4, 10, 14 at 1 % growth)."""
    from longtime.measure.stability import amplification, amplification_onset

    # amplification builds (and numba compiles, seconds each) a new step closure at every
    # call: build each order's once here, the calls below ask for orders 10 and 4 twice
    build, built = BorelPadeLaplace.make_try_step, {}

    def make_try_step(self, problem):
        key = (type(self), repr(sorted(self.settings.items())), type(problem), repr(sorted(problem.settings.items())))
        if key not in built:
            built[key] = build(self, problem)
        return built[key]

    monkeypatch.setattr(BorelPadeLaplace, "make_try_step", make_try_step)

    small = amplification([0.05, 0.1, 0.2], order=10)
    assert np.all(np.abs(small - 1.0) < 1e-9)
    onsets = [amplification_onset(n) for n in (4, 10, 14)]
    assert 0.5 < onsets[0] < 1.0 and 1.4 < onsets[1] < 2.2 and 2.0 < onsets[2] < 3.0
    assert amplification([2 * onsets[0]], order=4)[0] > 1.05


# ---------------------------------------------------------------- bpl-exp
def test_interaction_coefficients_remove_the_linear_flow():
    """For u = exp(L s) u0 (no nonlinear part) v = exp(-L s) u is constant: v_k = 0, k >= 1."""
    from longtime.integrators.bpl_exp import _interaction_coefficients

    rng = np.random.default_rng(1)
    lin = np.array([0.0, 3.0, -0.2, 40.0])  # (Re, Im) of two diagonal entries of L
    u0 = rng.standard_normal(4)
    N = 10
    coeffs = np.zeros((N + 1, 4))
    z0 = u0[0::2] + 1j * u0[1::2]
    lam = lin[0::2] + 1j * lin[1::2]
    for k in range(N + 1):
        zk = lam ** k / math.factorial(k) * z0
        coeffs[k, 0::2], coeffs[k, 1::2] = zk.real, zk.imag
    _interaction_coefficients(coeffs, lin)
    np.testing.assert_allclose(coeffs[0], u0, rtol=0, atol=1e-15)
    # rounding: the cancelled terms are up to 40^k / k! (about 3e15 at k = 10... times eps)
    scale = np.array([max(abs(lam) ** k / math.factorial(k)) for k in range(N + 1)])
    assert np.all(np.abs(coeffs[1:]).max(axis=1) < 1e-14 * np.maximum(1.0, scale[1:]) * 10)


@pytest.mark.slow
def test_bpl_exp_on_kdv_steps_past_bpls_cap():
    """KdV d = 128, one period: pure bpl's step is held near 3.7 / omega_max whatever
    eps_res; with the rotation exact, bpl-exp steps several times longer at the same
    eps_res and still meets it."""
    tf = registry.problem_class("kdv").default_t_final
    rows = {s: run_cell(Cell("kdv", s, {}, {"eps_res": 1e-3}, tf)) for s in ("bpl", "bpl-exp")}
    assert all(r["status"] == "ok" for r in rows.values())
    assert rows["bpl-exp"]["mean_dt"] > 4 * rows["bpl"]["mean_dt"]
    assert rows["bpl"]["mean_dt"] < 5.0 / 428.4
    assert rows["bpl-exp"]["final_error"] < 1e-4
    assert rows["bpl-exp"]["fallback_fraction"] == 0.0


def test_bpl_exp_needs_a_linear_part():
    from longtime.integrators.bpl_exp import BorelPadeLaplaceExp

    reason = BorelPadeLaplaceExp().incompatibility(registry.problem_class("toda")())
    assert reason and "linear_part" in reason
