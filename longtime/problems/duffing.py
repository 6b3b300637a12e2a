"""Duffing oscillators u'' + r u' + a u + b u^3 = c cos(w t), state (u, u') (docs/problems.md 4).

- ``duffing-1``: a = 2/9, b = 1, r = -1, c = 0. Not conservative (negative damping: the
  amplitude grows), but it has the time-dependent first integral
  I = exp(-4t/3) (u'^2 - (2/3) u u' + u^2/9 + u^4/2).
- ``duffing-2``: a = b = 1, r = c = 0. Hamiltonian and separable, H = u'^2/2 + u^2/2 + u^4/4;
  from u(0) = A, u'(0) = 0 the exact solution is u = A cn(omega t | m) with
  omega^2 = 1 + A^2, m = A^2 / (2 (1 + A^2)) (A = 1: cn(sqrt(2) t | 1/4)).
- ``duffing-forced``: a = -1, b = 1, r = 0.3, w = 1.2, forcing amplitude c (the paper's set
  0.20, 0.28, 0.29, 0.37, 0.50, 0.65; c = 0.50 is chaotic). Non-autonomous.

All three share one set of compiled kernels over params = (a, b, r, c, w).
"""
from __future__ import annotations

import math

import numba
import numpy as np

from longtime.core.params import Param
from longtime.core.problem import Problem, qp_blocks
from longtime.numerics.series import cos_wt_coeff, product, square

_A, _B, _R, _C, _W = range(5)


@numba.njit(cache=True)
def _rhs(t, u, params, out):
    x, v = u[0], u[1]
    out[0] = v
    out[1] = -params[_R] * v - params[_A] * x - params[_B] * x * x * x
    if params[_C] != 0.0:
        out[1] += params[_C] * math.cos(params[_W] * t)


@numba.njit(cache=True)
def _jac(t, u, params, out):
    out[0, 0] = 0.0
    out[0, 1] = 1.0
    out[1, 0] = -params[_A] - 3.0 * params[_B] * u[0] * u[0]
    out[1, 1] = -params[_R]


@numba.njit(cache=True)
def _grad_T(p, params, out):
    out[0] = p[0]


@numba.njit(cache=True)
def _grad_V(q, params, out):
    out[0] = params[_A] * q[0] + params[_B] * q[0] * q[0] * q[0]


@numba.njit(cache=True)
def _taylor(t0, u, params, coeffs, work):
    # u' = v, v' = -r v - a u - b u^3 + c cos(w t): work[0] is the series of u^2, work[1] of u^3
    a, b, r, c, w = params[_A], params[_B], params[_R], params[_C], params[_W]
    cos0, sin0 = math.cos(w * t0), math.sin(w * t0)
    coeffs[0, 0], coeffs[0, 1] = u[0], u[1]
    w_pow_over_fact = 1.0  # w^n / n!
    for n in range(coeffs.shape[0] - 1):
        work[0, n] = square(coeffs[:, 0], n)
        work[1, n] = product(work[0], coeffs[:, 0], n)
        f = -r * coeffs[n, 1] - a * coeffs[n, 0] - b * work[1, n]
        if c != 0.0:
            f += c * cos_wt_coeff(cos0, sin0, w_pow_over_fact, n)
            w_pow_over_fact *= w / (n + 1)
        coeffs[n + 1, 0] = coeffs[n, 1] / (n + 1)
        coeffs[n + 1, 1] = f / (n + 1)


def _jax_rhs(t, u, params):
    """The rhs in jax.numpy (the diffrax peers)."""
    import jax.numpy as jnp

    x, v = u[0], u[1]
    force = params[_C] * jnp.cos(params[_W] * t)
    return jnp.stack([v, -params[_R] * v - params[_A] * x - params[_B] * x * x * x + force])


class _Duffing(Problem):
    """Shared kernels; subclasses fix (a, b, r, c, w) through ``coefficients``."""

    rhs = staticmethod(_rhs)
    jax_rhs = staticmethod(_jax_rhs)
    jac = staticmethod(_jac)
    taylor = staticmethod(_taylor)

    def coefficients(self) -> tuple[float, float, float, float, float]:
        """(a, b, r, c, w)."""
        raise NotImplementedError

    def blocks(self):
        return qp_blocks(["oscillator"], 1)

    def initial_state(self):
        return [1.0, 0.0]

    def kernel_params(self):
        return np.array(self.coefficients(), dtype=float)

    def taylor_work_shape(self, order):
        return (2, order + 1)

    def heyoka_system(self):
        import heyoka as hy

        a, b, r, c, w = self.coefficients()
        x, v = hy.make_vars("u", "v")
        dv = -r * v - a * x - b * x * x * x
        if c != 0.0:
            dv = dv + c * hy.cos(w * hy.time)
        return [x, v], [v, dv]


class Duffing1(_Duffing):
    name = "duffing-1"
    summary = "Duffing with negative damping (a=2/9, b=1, r=-1): growing amplitude, first integral I"
    default_t_final = 30.0
    default_dt = 4e-4  # the paper's RK4 step
    sweep_dt = (4e-3, 2e-3, 1e-3)
    sweep_t_final = 10.0
    # the true solution grows like exp(2t/3): its 1-norm passes 1e10 near t = 36, so a bound
    # on the initial size would call an accurate run diverged; the bound follows size_bound

    def size_bound(self, t):
        """From the first integral: I e^{4t/3} = (v - u/3)^2 + u^4/2 with I = I(0), so
        |u| <= (2I)^{1/4} e^{t/3} and |v| <= sqrt(I) e^{2t/3} + |u|/3."""
        i0 = float(self.first_integral(np.array([self.t0]), self.u0[None, :])[0])
        t = np.asarray(t, dtype=float)
        u_max = (2.0 * i0) ** 0.25 * np.exp(t / 3.0)
        return u_max + np.sqrt(i0) * np.exp(2.0 * t / 3.0) + u_max / 3.0

    def coefficients(self):
        return (2.0 / 9.0, 1.0, -1.0, 0.0, 0.0)

    def first_integral(self, t, U):
        u, v = U[:, 0], U[:, 1]
        t = np.asarray(t, dtype=float)
        return np.exp(-4.0 * t / 3.0) * (v * v - (2.0 / 3.0) * u * v + u * u / 9.0 + 0.5 * u**4)

    def invariants(self, t, U):
        return {"I": self.first_integral(t, U)}


class Duffing2(_Duffing):
    name = "duffing-2"
    summary = "conservative Duffing u'' + u + u^3 = 0 (separable H, exact cn solution)"
    parameters = {"amplitude": Param(1.0, "initial displacement u(0) (u'(0) = 0)",
                                     float, positive=True, role="physical")}
    default_t_final = 1000.0
    default_dt = 0.1  # the paper's RK4 step
    sweep_dt = (0.1, 0.05, 0.025)
    sweep_t_final = 200.0

    grad_T = staticmethod(_grad_T)
    grad_V = staticmethod(_grad_V)

    def coefficients(self):
        return (1.0, 1.0, 0.0, 0.0, 0.0)

    def initial_state(self):
        return [self.settings["amplitude"], 0.0]

    def hamiltonian(self, t, U):
        u, v = U[:, 0], U[:, 1]
        return 0.5 * v * v + 0.5 * u * u + 0.25 * u**4

    def invariants(self, t, U):
        return {"H": self.hamiltonian(t, U)}

    def exact(self, t):
        from scipy.special import ellipj, ellipk

        amp = self.settings["amplitude"]
        omega = math.sqrt(1.0 + amp * amp)
        m = amp * amp / (2.0 * (1.0 + amp * amp))
        # reduced modulo the period 4K(m): ellipj loses accuracy as its argument grows
        # (1e-12 by omega t = 1400, 1e-14 after the reduction)
        x = np.remainder(omega * (np.asarray(t, dtype=float) - self.t0), 4.0 * ellipk(m))
        sn, cn, dn, _ = ellipj(x, m)
        # d/dt cn(omega t) = -omega sn dn
        return np.stack([amp * cn, -amp * omega * sn * dn], axis=1)


class DuffingForced(_Duffing):
    name = "duffing-forced"
    summary = "forced damped Duffing (a=-1, b=1, r=0.3, w=1.2), forcing amplitude c (0.5: chaotic)"
    chaotic = True
    parameters = {"c": Param(0.5, "forcing amplitude (paper: 0.20, 0.28, 0.29, 0.37, 0.50, 0.65)",
                             float, role="physical")}
    autonomous = False
    default_t_final = 1000.0
    default_dt = 0.01
    sweep_dt = (0.04, 0.02, 0.01)
    sweep_t_final = 100.0

    def coefficients(self):
        return (-1.0, 1.0, 0.3, self.settings["c"], 1.2)
