"""Kepler two-body problem in relative coordinates, H = |p|^2/2 - 1/|q| (mu = 1, a = 1).

Starts at pericentre (1 - e, 0) with p = (0, sqrt((1+e)/(1-e))): period 2 pi. Invariants:
H, angular momentum L and the Runge-Lenz vector A. Exact solution via Kepler's equation, on
the orbit of the rounded initial state (``kepler_orbit``).
"""
from __future__ import annotations

import math

import numba
import numpy as np

from longtime.core.params import Param
from longtime.core.problem import Problem, qp_blocks, separable_rhs
from longtime.numerics.series import power_coeff, product, square


@numba.njit(cache=True)
def _grad_V(q, params, out):
    r2 = q[0] * q[0] + q[1] * q[1]
    inv_r3 = 1.0 / (r2 * math.sqrt(r2))
    out[0] = q[0] * inv_r3
    out[1] = q[1] * inv_r3


@numba.njit(cache=True)
def _grad_T(p, params, out):
    out[0] = p[0]
    out[1] = p[1]


@numba.njit(cache=True)
def _taylor(t0, u, params, coeffs, work):
    # x'' = -x r^-3: work[0] is the series of r^2 = x^2 + y^2, work[1] that of r^-3 = (r^2)^(-3/2)
    for i in range(4):
        coeffs[0, i] = u[i]
    for n in range(coeffs.shape[0] - 1):
        work[0, n] = square(coeffs[:, 0], n) + square(coeffs[:, 1], n)
        work[1, n] = power_coeff(work[0], work[1], -1.5, n)
        coeffs[n + 1, 0] = coeffs[n, 2] / (n + 1)
        coeffs[n + 1, 1] = coeffs[n, 3] / (n + 1)
        coeffs[n + 1, 2] = -product(coeffs[:, 0], work[1], n) / (n + 1)
        coeffs[n + 1, 3] = -product(coeffs[:, 1], work[1], n) / (n + 1)


_TWO_PI = 8 * np.arctan(np.longdouble(1))


def solve_kepler(M: np.ndarray, e) -> np.ndarray:
    """Eccentric anomaly E in [0, 2 pi] with E - e sin E = M (mod 2 pi), by Newton's method
    to round-off in the precision of M (float64 or long double)."""
    M = np.asarray(M)
    M = np.remainder(M, _TWO_PI.astype(M.dtype))
    E = np.where(e > 0.8, np.pi, M.astype(np.float64))  # from pi Newton converges for any e < 1
    if M.dtype != np.float64:  # long double is slow: solve in double, then polish
        E = _newton(M.astype(np.float64), float(e), E).astype(M.dtype)
    return _newton(M, e, E)


def _newton(M: np.ndarray, e, E: np.ndarray) -> np.ndarray:
    # the residual's terms are below 2 pi + 1: 16 eps is its round-off, where the step is
    # noise (up to 100x larger at e = 0.99 near pericentre, so the step is no test)
    tol = 16 * np.finfo(M.dtype).eps
    for _ in range(60):
        residual = E - e * np.sin(E) - M
        E = E - residual / (1 - e * np.cos(E))
        if np.max(np.abs(residual), initial=0) <= tol:
            break
    return E


def kepler_orbit(u0: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """States (len(tau), 4) at times tau after u0 = (x, y, px, py) on its Kepler orbit
    (mu = 1), in float64. The elements come from u0 itself and everything is evaluated in
    long double: the orbit is the one through the rounded state, not the one the formula's
    parameters describe (at e = 0.99 the rounded state's period is 1.5e-14 shorter than
    2 pi: 1e-9 relative at pericentre after 16 orbits)."""
    x, y, px, py = np.asarray(u0, dtype=np.longdouble)
    r = np.hypot(x, y)
    a = -1 / ((px * px + py * py) - 2 / r)  # semi-major axis, from the energy
    L = x * py - y * px
    ax, ay = py * L - x / r, -px * L - y / r  # Runge-Lenz vector: e towards the pericentre
    e = np.hypot(ax, ay)
    cw, sw = np.cos(np.arctan2(ay, ax)), np.sin(np.arctan2(ay, ax))
    b = a * np.sqrt(1 - e * e) * np.sign(L)  # negative for a clockwise orbit
    # u0 in the orbit's frame (pericentre on +x): x = a (cos E - e), y = b sin E
    E0 = np.arctan2((cw * y - sw * x) / b, (cw * x + sw * y) / a + e)
    n = a**-1.5  # mean motion
    E = solve_kepler(E0 - e * np.sin(E0) + n * np.asarray(tau, dtype=np.longdouble), e)
    c, s = np.cos(E), np.sin(E)
    rate = n / (1 - e * c)  # dE/dt
    xf, yf, vxf, vyf = a * (c - e), b * s, -a * s * rate, b * c * rate
    return np.stack([cw * xf - sw * yf, sw * xf + cw * yf,
                     cw * vxf - sw * vyf, sw * vxf + cw * vyf], axis=1).astype(float)


def _jax_rhs(t, u, params):
    """The rhs in jax.numpy (the diffrax peers)."""
    import jax.numpy as jnp

    q, p = u[:2], u[2:]
    r2 = q[0] * q[0] + q[1] * q[1]
    return jnp.concatenate([p, -q / (r2 * jnp.sqrt(r2))])


class Kepler(Problem):
    name = "kepler"
    summary = "Kepler orbit of eccentricity e (e = 0.9 is the hard case), exact solution"
    parameters = {"e": Param(0.6, "eccentricity, 0 <= e < 1", float, minimum=0.0, maximum=0.99, role="physical")}
    period = 2 * np.pi  # the semi-major axis is 1 at every e
    default_t_final = 20 * np.pi
    default_dt = 0.01
    sweep_dt = (0.02, 0.01, 0.005)
    sweep_t_final = 40 * np.pi
    long_t_final = 2000 * np.pi  # 10^3 periods, for the schemes that can afford it

    rhs = staticmethod(separable_rhs(_grad_T, _grad_V))
    jax_rhs = staticmethod(_jax_rhs)
    grad_T = staticmethod(_grad_T)
    grad_V = staticmethod(_grad_V)
    taylor = staticmethod(_taylor)

    def taylor_work_shape(self, order):
        return (2, order + 1)

    def blocks(self):
        return qp_blocks(["planet"], 2)

    def initial_state(self):
        e = self.settings["e"]
        return [1 - e, 0.0, 0.0, math.sqrt((1 + e) / (1 - e))]

    def inverse_masses(self):
        return np.ones(self.dim // 2)

    def invariants(self, t, U):
        x, y, px, py = U.T
        r = np.hypot(x, y)
        L = x * py - y * px
        return {
            "H": 0.5 * (px**2 + py**2) - 1 / r,
            "L": L,
            "A": np.stack([py * L - x / r, -px * L - y / r], axis=1),
        }

    def exact(self, t):
        return kepler_orbit(self.u0, np.asarray(t, dtype=float) - self.t0)

    def heyoka_system(self):
        import heyoka as hy

        x, y, px, py = hy.make_vars("x", "y", "px", "py")
        r3 = (x * x + y * y) ** 1.5
        return [x, y, px, py], [px, py, -x / r3, -y / r3]
