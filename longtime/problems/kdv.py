"""Korteweg-de Vries, Fourier-Galerkin in space (docs/problems.md 5).

    u_t + c0 u_x + beta u_xxx + (alpha/2) (u^2)_x = 0,   x periodic of period X = 24 pi,

with modes |m| <= M, d = 2M (d = 128: 2M + 1 = 129 real unknowns), w = 2 pi / X:

    d/dt u_m = i omega_m u_m - (alpha/2) i w m (u^2)_m,   omega_m = -c0 w m + beta w^3 m^3.

State representation: packed, scaled complex Fourier coefficients. With
u(x) = sum_m uh_m e^{i m w x}, the state holds s_m = sigma_m uh_m for m = 0..M as (Re, Im)
pairs: u = [Re s_0, Im s_0, Re s_1, Im s_1, ..., Re s_M, Im s_M] (dim = 2M + 2; Im s_0 is
identically 0 for a real field, so there are 2M + 1 real unknowns as in the paper), with
sigma_0 = sqrt(X), sigma_m = sqrt(2X): the basis is orthonormal in L2(0, X), so the
Euclidean norm of the state is the L2 norm of u(x), and the harness's relative errors
(``final_error``) are relative L2 errors in x. In this basis the linear part is diagonal
(a rotation of each pair), which exponential schemes need, and every other scheme sees an
ordinary real ODE.

Aliasing of u^2 (parameter ``dealias``): "3/2" (default) evaluates u^2 on a padded grid of
n >= 3M + 1 points, so the projection of u^2 onto |m| <= M is exact: a true Galerkin
scheme, which conserves mass, momentum and H. "2/3" is the classical truncation: the
nonlinear term sees only the modes |m| <= 2M/3 of u and keeps only those of u^2 (alias-free
too; the top third of the modes then evolves linearly).

FFT inside compiled code: the rhs is called inside the shared compiled loops, where
scipy.fft is out of reach of plain numba; rocket-fft registers pocketfft's transforms for
numba, and its low-level ``r2c`` / ``c2r`` write into arrays we pass. The grid has the
smallest fast length n >= 3K + 1 (any factors 2, 3, 5: d need not be a power of two).
``params`` holds constants only; the rhs allocates its two grid buffers per call (the rhs
contract has no work array), ``taylor`` keeps its grid rows in ``work``.
``python benchmarks/bench_kdv_rhs.py`` times the rhs against a hand-written radix-2 FFT.

Capabilities beyond ``rhs``:
  ``pde_solution`` the soliton u0(x - c t), c = c0 (1 + h/(2 delta)), projected on the modes:
                   the PDE's solution, not the Galerkin system's (the periodic prolongation
                   of the soliton and the truncation to |m| <= M differ from the system's
                   solution by about 2.5e-7 at d = 128). The reference is the system's own
                   solution (longtime.measure.reference, the integrating factor); the row's
                   ``discretisation_error`` is the soliton's distance from it.
  ``linear_part``  compiled ``linear_part(params, out)``: the diagonal of L in the complex
                   view of the state (z_k = u[2k] + i u[2k+1]), written as (Re, Im) pairs
                   into ``out`` (length dim): here (0, omega_k).
  ``nonlinear``    compiled ``nonlinear(t, u, params, out)``: N(u) with rhs = L u + N(u).
  ``taylor``       the series recurrence (docs/problems.md 5, corrected sign):
                   u_{k+1} = [i omega u_k - (alpha/2) i w m sum_{j<=k} (u_j u_{k-j})_m] / (k+1),
                   the products in physical space (one inverse FFT per order, one forward
                   FFT of the Cauchy sum per order).
Invariants: ``mass`` (integral of u), ``momentum`` (integral of u^2, the squared L2 norm) and
``H``, the Hamiltonian integral of (c0 u^2/2 + alpha u^3/6 - beta u_x^2/2), with
u_t = -d/dx (dH/du).
"""
from __future__ import annotations

import math

import numba
import numpy as np

from longtime.core.drivers import copy_into
from longtime.core.params import InputError, Param
from longtime.core.problem import Problem, whole_state

# constants (docs/problems.md 5): depth delta, gravity g, soliton amplitude h, period X
DEPTH, GRAVITY, AMPLITUDE, PERIOD_X = 2.0, 10.0, 0.5, 24.0 * math.pi
C0 = math.sqrt(GRAVITY * DEPTH)
ALPHA = 1.5 * math.sqrt(GRAVITY / DEPTH)
BETA = DEPTH**2 * C0 / 6.0
KAPPA = math.sqrt(3.0 * AMPLITUDE / (4.0 * DEPTH**3))
SPEED = C0 * (1.0 + AMPLITUDE / (2.0 * DEPTH))
SOLITON_PERIOD = PERIOD_X / SPEED  # T = 14.98627...

# layout of params: constants only (the problem contract: params never change)
P_C0, P_BETA, P_ALPHA, P_W, P_M, P_N, P_K, P_X, P_S0, P_S1 = range(10)
_AXES = np.zeros(1, dtype=np.int64)  # the transforms run along axis 0


# ---------------------------------------------------------------- compiled FFT kernels
# rocket-fft's low-level r2c / c2r (pocketfft inside) write into arrays we pass, at any
# length n (not only powers of two). They are imported with the first KdV made (``_load_fft``),
# not with the module: the registry imports every problem's module, and rocket-fft with
# scipy.fft would be most of that import's time for every command, kdv run or not. The
# kernels read them as globals when numba compiles them, which needs a KdV's params first.
c2r = r2c = None


def _load_fft() -> None:
    global c2r, r2c
    if c2r is None:
        from rocket_fft.lowlevel import c2r as _c2r
        from rocket_fft.lowlevel import r2c as _r2c

        c2r, r2c = _c2r, _r2c


@numba.njit(cache=True)
def _to_physical(u, params, spec, grid):
    """Values of u(x) on the grid x_j = j X / n (n = grid.size) from the state, keeping the
    modes |m| <= K; ``spec`` (n/2 + 1 complex) is scratch."""
    K = int(params[P_K])
    spec[0] = complex(u[0] / params[P_S0], 0.0)  # a real field: Im of mode 0 is 0
    s1 = params[P_S1]
    for m in range(1, K + 1):
        spec[m] = complex(u[2 * m] / s1, u[2 * m + 1] / s1)
    for m in range(K + 1, spec.size):
        spec[m] = 0.0
    c2r(spec, grid, _AXES, False, 1.0, 1)


@numba.njit(cache=True)
def _nonlinear_from_physical(grid, params, spec, out, factor):
    """out = factor * N for the grid values y (of u^2 or of a Cauchy sum):
    N_m = sigma_m (-(alpha/2) i w m) (1/n) sum_j y_j e^{-i m w x_j}, |m| <= K; the modes
    K < m <= M get 0."""
    n = grid.size
    K, M = int(params[P_K]), int(params[P_M])
    r2c(grid, spec, _AXES, True, 1.0 / n, 1)
    half_alpha_w = 0.5 * params[P_ALPHA] * params[P_W]
    out[0] = 0.0  # m = 0: the factor m vanishes
    out[1] = 0.0
    for m in range(1, K + 1):
        g = factor * params[P_S1] * half_alpha_w * m
        out[2 * m] = g * spec[m].imag  # -(i g) (yr + i yi)
        out[2 * m + 1] = -g * spec[m].real
    for m in range(K + 1, M + 1):
        out[2 * m] = 0.0
        out[2 * m + 1] = 0.0


@numba.njit(cache=True)
def _nonlinear(t, u, params, out):
    """N(u) = -(alpha/2) (u^2)_x in the state's basis."""
    n = int(params[P_N])
    # the rhs contract has no work array and params are constants: the two grid buffers
    # are allocated per call (small beside the FFTs of the rhs)
    grid = np.empty(n)
    spec = np.empty(n // 2 + 1, dtype=np.complex128)
    _to_physical(u, params, spec, grid)
    for j in range(n):
        grid[j] *= grid[j]
    _nonlinear_from_physical(grid, params, spec, out, 1.0)


@numba.njit(cache=True)
def _linear_part(params, out):
    """Diagonal of L in the complex view of the state, as (Re, Im) pairs: (0, omega_m)."""
    c0w, bw3 = params[P_C0] * params[P_W], params[P_BETA] * params[P_W] ** 3
    for m in range(int(params[P_M]) + 1):
        out[2 * m] = 0.0
        out[2 * m + 1] = -c0w * m + bw3 * m * m * m


@numba.njit(cache=True)
def _add_linear(u, params, out, factor):
    """out += factor * L u, L a rotation of each pair by omega_m."""
    c0w, bw3 = params[P_C0] * params[P_W], params[P_BETA] * params[P_W] ** 3
    for m in range(int(params[P_M]) + 1):
        om = factor * (-c0w * m + bw3 * m * m * m)
        a, b = u[2 * m], u[2 * m + 1]
        out[2 * m] -= om * b
        out[2 * m + 1] += om * a


@numba.njit(cache=True)
def _rhs(t, u, params, out):
    _nonlinear(t, u, params, out)
    _add_linear(u, params, out, 1.0)


@numba.njit(cache=True)
def _taylor(t0, u, params, coeffs, work):
    """Normalised Taylor coefficients: rows 0..N-1 of ``work`` keep the grid values of
    coefficients 0..N-1, row N the Cauchy sum of order k (docs/problems.md, KdV)."""
    order = coeffs.shape[0] - 1
    n = int(params[P_N])
    spec = np.empty(n // 2 + 1, dtype=np.complex128)  # once per call, not per order
    copy_into(coeffs[0], u)  # not a slice assignment: drivers.copy_into says why
    acc = work[order]
    for k in range(order):
        _to_physical(coeffs[k], params, spec, work[k])
        # grid values of sum_{j=0..k} u_j u_{k-j}, by symmetry
        for i in range(n):
            s = 0.0
            for j in range((k + 1) // 2):
                s += work[j, i] * work[k - j, i]
            s *= 2.0
            if k % 2 == 0:
                s += work[k // 2, i] * work[k // 2, i]
            acc[i] = s
        inv = 1.0 / (k + 1)
        _nonlinear_from_physical(acc, params, spec, coeffs[k + 1], inv)
        _add_linear(coeffs[k], params, coeffs[k + 1], inv)


# ---------------------------------------------------------------- the problem


def _grid_size(modes: int, dealias: str) -> int:
    """The smallest fast FFT length on which the kept product modes are alias-free."""
    import scipy.fft

    cutoff = modes if dealias == "3/2" else (2 * modes) // 3
    return scipy.fft.next_fast_len(max(3 * cutoff + 1, 2 * modes + 1, 8), real=True)


class KdV(Problem):
    name = "kdv"
    summary = "Korteweg-de Vries soliton, Fourier-Galerkin (stiff), the system's own reference"
    check_class = "discretised PDE"
    parameters = {
        # bounded so that a typo (d=1e8) is an input error, not minutes of setup and gigabytes
        "d": Param(128, "number of Fourier modes d = 2M (2M + 1 real unknowns), even", int, minimum=4,
                   maximum=2**20, role="physical"),
        "dealias": Param("3/2", "aliasing of u^2: 3/2 padding (exact Galerkin) or the 2/3 rule",
                         str, choices=("3/2", "2/3"), role="option"),
    }
    default_t_final = SOLITON_PERIOD
    # explicit schemes are stability-limited: max |omega_m| = 428 at d = 128 (|c0 w M| subtracted from
    # |beta w^3 M^3|; adding them gives about 476); RK4 needs dt < 6.6e-3.
    # The matrix sweep stays at d = 128 over half a period: every scheme's cells stay short.
    default_dt = 1e-3
    sweep_dt = (2e-3, 1e-3)
    sweep_t_final = SOLITON_PERIOD / 2
    long_t_final = 10 * SOLITON_PERIOD  # 10 periods, for the schemes that can afford it

    rhs = staticmethod(_rhs)
    taylor = staticmethod(_taylor)
    linear_part = staticmethod(_linear_part)
    nonlinear = staticmethod(_nonlinear)

    def setup(self):
        d = self.settings["d"]
        if d % 2:
            raise InputError(f"problem 'kdv': d={d} is not valid: must be even (d = 2M modes)")
        _load_fft()
        self.modes = d // 2
        self.grid = _grid_size(self.modes, self.settings["dealias"])
        self.cutoff = self.modes if self.settings["dealias"] == "3/2" else (2 * self.modes) // 3
        M = self.modes
        self.sigma = np.full(M + 1, math.sqrt(2 * PERIOD_X))
        self.sigma[0] = math.sqrt(PERIOD_X)
        self.wavenumbers = 2 * np.pi / PERIOD_X * np.arange(M + 1)

    # -- kernel data
    def kernel_params(self):
        params = np.zeros(10)
        params[[P_C0, P_BETA, P_ALPHA, P_W, P_M, P_N, P_K, P_X, P_S0, P_S1]] = (
            C0, BETA, ALPHA, 2 * np.pi / PERIOD_X, self.modes, self.grid, self.cutoff, PERIOD_X,
            self.sigma[0], math.sqrt(2 * PERIOD_X))
        return params

    def taylor_work_shape(self, order):
        return (order + 1, self.grid)

    # -- conversions (Python level, scipy.fft)
    def to_coefficients(self, U):
        """Complex Fourier coefficients uh_m, m = 0..M, of states U (n, dim)."""
        U = np.atleast_2d(U)
        return (U[:, 0::2] + 1j * U[:, 1::2]) / self.sigma

    def from_coefficients(self, C):
        C = np.atleast_2d(C) * self.sigma
        U = np.empty((C.shape[0], 2 * C.shape[1]))
        U[:, 0::2], U[:, 1::2] = C.real, C.imag
        return U

    def values(self, U, n_points=None):
        """u(x_j) at x_j = j X / n_points, for states U (n, dim)."""
        import scipy.fft

        n_points = n_points or 2 * self.modes + 1
        C = self.to_coefficients(U)
        return scipy.fft.irfft(C * n_points, n=n_points, axis=1)

    def soliton_coefficients(self):
        """Fourier coefficients of the (periodically prolonged) soliton u0, |m| <= M."""
        import scipy.fft

        n_fine = max(4096, 1 << (8 * self.modes).bit_length())
        x = PERIOD_X * np.arange(n_fine) / n_fine
        x = np.where(x >= PERIOD_X / 2, x - PERIOD_X, x)
        u0 = AMPLITUDE / np.cosh(KAPPA * x) ** 2
        return scipy.fft.rfft(u0)[: self.modes + 1] / n_fine

    def blocks(self):
        return whole_state(self)  # one field: its modes are not objects of their own

    def initial_state(self):
        return self.from_coefficients(self.soliton_coefficients())[0]

    def pde_solution(self, t):
        """The PDE's solution at the times ``t``: the soliton translated by c t, projected on
        the modes (states, shape (len(t), dim))."""
        t = np.asarray(t, dtype=float).reshape(-1) - self.t0
        C = self.soliton_coefficients()[None, :] * np.exp(-1j * np.outer(SPEED * t, self.wavenumbers))
        return self.from_coefficients(C)

    def invariants(self, t, U):
        C = self.to_coefficients(U)
        momentum = np.sum(U**2, axis=1)  # orthonormal basis: the integral of u^2
        ux2 = np.sum((self.wavenumbers * np.abs(C * self.sigma)) ** 2, axis=1)
        # u^3 has modes up to 3M: its mean is exact on any grid of more than 3M points; the
        # next fast FFT length is taken (3M+2 itself may have a large prime factor)
        import scipy.fft

        n3 = scipy.fft.next_fast_len(3 * self.modes + 2, real=True)
        chunk = max(1, 2_000_000 // n3)  # bounded memory for long sample sets
        cube = np.concatenate([PERIOD_X * np.mean(self.values(U[i:i + chunk], n3) ** 3, axis=1)
                               for i in range(0, U.shape[0], chunk)])
        H = 0.5 * C0 * momentum + ALPHA / 6.0 * cube - 0.5 * BETA * ux2
        return {"mass": PERIOD_X * C[:, 0].real, "momentum": momentum, "H": H}
