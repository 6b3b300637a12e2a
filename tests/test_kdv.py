"""KdV (Fourier-Galerkin) and ETDRK4: the compiled transform, the soliton's shape and speed,
the invariants, the series recurrence and ETDRK4's order and coefficients."""
from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.fft

from longtime.core.params import InputError
from longtime.integrators.etdrk4 import E2, ETDRK4, F1, F2, F3, LAM, META, E, Q, _phi_coefficients
from longtime.problems import kdv as K
from longtime.problems.kdv import SOLITON_PERIOD, KdV


def galerkin_rhs(problem, u):
    """u' from the equation in Fourier modes, with u^2 on a fine grid (numpy, scipy.fft)."""
    C = problem.to_coefficients(u)[0]
    M, cut = problem.modes, problem.cutoff
    Ck = np.where(np.arange(M + 1) <= cut, C, 0)
    n = 8192
    v = scipy.fft.irfft(Ck * n, n=n)
    S = scipy.fft.rfft(v * v)[: M + 1] / n
    S[cut + 1:] = 0
    w = 2 * np.pi / K.PERIOD_X
    m = np.arange(M + 1)
    dC = 1j * (-K.C0 * w * m + K.BETA * w**3 * m**3) * C - 0.5 * K.ALPHA * 1j * w * m * S
    return problem.from_coefficients(dC)[0]


@pytest.mark.parametrize("d,dealias", [(6, "3/2"), (32, "3/2"), (128, "3/2"), (32, "2/3")])
def test_rhs_matches_spectral_formula(d, dealias):
    p = KdV(d=d, dealias=dealias)
    rng = np.random.default_rng(d)
    u = p.u0 + 0.1 * rng.standard_normal(p.dim) / (1 + np.arange(p.dim))
    u[1] = 0.0  # Im of mode 0: a real field
    out = np.empty(p.dim)
    p.rhs(0.0, u, p.params, out)
    ref = galerkin_rhs(p, u)
    assert np.max(np.abs(out - ref)) < 1e-13 * np.max(np.abs(ref))
    # rhs = L u + N(u)
    lam, nl = np.empty(p.dim), np.empty(p.dim)
    p.linear_part(p.params, lam)
    p.nonlinear(0.0, u, p.params, nl)
    z = (lam[0::2] + 1j * lam[1::2]) * (u[0::2] + 1j * u[1::2])
    lin = np.empty(p.dim)
    lin[0::2], lin[1::2] = z.real, z.imag
    assert np.max(np.abs(lin + nl - out)) < 1e-13 * np.max(np.abs(out))


def test_constants_and_stiffness():
    assert abs(SOLITON_PERIOD - 14.98627) < 1e-5
    p = KdV(d=128)
    assert p.dim == 130 and p.grid >= 3 * 64 + 1
    lam = np.empty(p.dim)
    p.linear_part(p.params, lam)
    assert np.all(lam[0::2] == 0)
    assert 420 < np.max(np.abs(lam)) < 480  # max |c0 w m - beta w^3 m^3| = 428 (docs/problems.md 5)
    with pytest.raises(InputError, match="d=7"):
        KdV(d=7)


def test_soliton_shape():
    p = KdV(d=128)
    n = 512
    x = K.PERIOD_X * np.arange(n) / n
    x = np.where(x >= K.PERIOD_X / 2, x - K.PERIOD_X, x)
    values = p.values(p.u0[None], n)[0]
    soliton = K.AMPLITUDE / np.cosh(K.KAPPA * x) ** 2
    assert np.max(np.abs(values - soliton)) < 1e-6  # the periodic prolongation: about 3e-7
    assert abs(values.max() - K.AMPLITUDE) < 1e-6
    # the state is orthonormal: its norm is the L2 norm in x
    l2 = math.sqrt(K.PERIOD_X * np.mean(values**2))
    assert abs(np.linalg.norm(p.u0) - l2) < 1e-12 * l2


def test_soliton_speed_and_pde_solution():
    """ETDRK4 over half a period: the computed soliton moves at c = c0 (1 + h/(2 delta))."""
    p = KdV(d=128)
    tf = SOLITON_PERIOD / 2
    traj = ETDRK4(dt=tf / 200).integrate(p, tf, max_samples=11)
    assert traj.status == "ok"
    exact = p.pde_solution(traj.t)
    err = np.linalg.norm(traj.u - exact, axis=1) / np.linalg.norm(exact, axis=1)
    assert err.max() < 1e-6
    # speed from the phase of mode 1, which rotates as exp(-i w c t)
    z1 = traj.u[:, 2] + 1j * traj.u[:, 3]
    phase = np.unwrap(np.angle(z1))
    speed = -np.polyfit(traj.t, phase, 1)[0] / (2 * np.pi / K.PERIOD_X)
    assert abs(speed - K.SPEED) < 1e-6 * K.SPEED
    # the peak is half a period away after half a period: exact soliton state at T is u0
    assert np.max(np.abs(p.pde_solution([SOLITON_PERIOD])[0] - p.u0)) < 1e-13


def test_invariants_conserved_by_galerkin():
    from longtime.integrators.explicit_rk import RK4

    p = KdV(d=32)
    rng = np.random.default_rng(3)
    u0 = p.u0 + 0.02 * rng.standard_normal(p.dim) / (1 + np.arange(p.dim))
    u0[1] = 0.0
    p.u0 = u0  # a non-soliton state: every mode exchanges energy
    traj = RK4(dt=2e-3).integrate(p, 2.0, max_samples=101)
    inv = p.invariants(traj.t, traj.u)
    assert set(inv) == {"mass", "momentum", "H"}
    for name, values in inv.items():
        drift = np.max(np.abs(values - values[0])) / abs(values[0])
        assert drift < 1e-9, (name, drift)
    # and H changes if the dispersion term is dropped from it (it is not a trivial constant)
    U = traj.u
    C = p.to_coefficients(U)
    ux2 = np.sum((p.wavenumbers * np.abs(C * p.sigma)) ** 2, axis=1)
    assert np.ptp(ux2) > 1e3 * np.ptp(inv["H"])


def test_taylor_recurrence():
    from scipy.integrate import solve_ivp

    p = KdV(d=32)
    order = 6
    coeffs = np.full((order + 1, p.dim), np.nan)
    work = np.full(p.taylor_work_shape(order), np.nan)
    p.taylor(0.0, p.u0.copy(), p.params, coeffs, work)
    f = np.empty(p.dim)
    p.rhs(0.0, p.u0, p.params, f)
    assert np.max(np.abs(coeffs[1] - f)) < 1e-14
    # second coefficient: (1/2) J f by central differences
    eps = 1e-5
    fp, fm = np.empty(p.dim), np.empty(p.dim)
    p.rhs(0.0, p.u0 + eps * f, p.params, fp)
    p.rhs(0.0, p.u0 - eps * f, p.params, fm)
    assert np.max(np.abs(coeffs[2] - (fp - fm) / (4 * eps))) < 1e-8

    def fun(t, y):
        out = np.empty_like(y)
        p.rhs(t, y, p.params, out)
        return out

    hs = np.array([0.4, 0.2, 0.1])
    errs = []
    for h in hs:
        ref = solve_ivp(fun, (0, h), p.u0, method="DOP853", rtol=1e-13, atol=1e-15).y[:, -1]
        series = sum(coeffs[k] * h**k for k in range(order + 1))
        errs.append(np.linalg.norm(series - ref))
    slope = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert abs(slope - (order + 1)) < 0.5, (errs, slope)


def test_etdrk4_contour_coefficients():
    h = 0.3
    lam = np.array([0.0, 0.0, 0.0, 2.5, -4.0, 0.0, 1e-9, 3e-9])
    work = np.zeros((META + 1, lam.size))
    work[LAM] = lam
    _phi_coefficients(h, work)
    # L = 0: the RK4 weights
    assert np.allclose(work[[Q, F1, F2, F3], 0], [h / 2, h / 6, h / 6, h / 6], rtol=1e-14, atol=0)
    assert np.all(work[[E, E2, Q, F1, F2, F3], 1] == 0)
    # against the direct formulas where they do not cancel
    for k in (1, 2):
        z = h * complex(lam[2 * k], lam[2 * k + 1])
        direct = {Q: h * (np.exp(z / 2) - 1) / z,
                  F1: h * (-4 - z + np.exp(z) * (4 - 3 * z + z * z)) / z**3,
                  F2: h * (2 + z + np.exp(z) * (z - 2)) / z**3,
                  F3: h * (-4 - 3 * z - z * z + np.exp(z) * (4 - z)) / z**3,
                  E: np.exp(z), E2: np.exp(z / 2)}
        for row, value in direct.items():
            got = complex(work[row, 2 * k], work[row, 2 * k + 1])
            assert abs(got - value) < 1e-13 * max(1.0, abs(value)), (row, k, got, value)
    # tiny |z| (1e-9): the direct formulas lose everything here; the contour gives the limits
    # up to O(z)
    assert abs(work[F1, 6] - h / 6) < 1e-9 and abs(work[Q, 6] - h / 2) < 1e-9


def test_etdrk4_order_four():
    p = KdV(d=32)
    tf = SOLITON_PERIOD / 2
    ref = ETDRK4(dt=tf / 2000).integrate(p, tf, max_samples=2).u[-1]
    dts = tf / np.array([20, 40, 80, 160])
    errs = [np.linalg.norm(ETDRK4(dt=dt).integrate(p, tf, max_samples=2).u[-1] - ref) for dt in dts]
    slope = np.polyfit(np.log(dts), np.log(errs), 1)[0]
    assert abs(slope - 4) < 0.3, (errs, slope)


def test_etdrk4_skips_problems_without_linear_part():
    from longtime.problems.harmonic import Harmonic

    reason = ETDRK4().incompatibility(Harmonic())
    assert reason and "linear_part" in reason


def test_matcher_finds_the_target_step(capsys):
    """`longtime match` machinery: the bisection lands near the target error."""
    from longtime.commands.matched import Matcher, match_table
    from longtime.execution.cells import Cell

    matcher = Matcher(None, None, "final_error", 1e-3, repeat=1, max_evals=14, verbose=False)
    row = matcher.match(Cell("kdv", "etdrk4", {"d": 32}, {}, SOLITON_PERIOD))
    assert row["status"] == "ok" and row["match_parameter"] == "dt"
    assert abs(math.log(row["final_error"] / 1e-3)) < math.log(1.25), row["final_error"]
    text = match_table([row], "kdv", {"d": 32}, "final_error", 1e-3)
    assert "etdrk4" in text and "dt=" in text
