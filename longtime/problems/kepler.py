"""Kepler two-body problem in relative coordinates, H = |p|^2/2 - 1/|q| (mu = 1, a = 1).

Starts at pericentre (1 - e, 0) with p = (0, sqrt((1+e)/(1-e))): period 2 pi. Invariants:
H, angular momentum L and the Runge-Lenz vector A. Exact solution via Kepler's equation.
"""
from __future__ import annotations

import math

import numba
import numpy as np

from ..params import Param
from ..problem import Problem, separable_rhs
from ..series import power_coeff, product, square


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


def solve_kepler(M: np.ndarray, e: float) -> np.ndarray:
    """Eccentric anomaly E with E - e sin E = M, by Newton's method to round-off."""
    M = np.remainder(M, 2 * np.pi)
    E = np.where(e > 0.8, np.pi, M)
    for _ in range(50):
        step = (E - e * np.sin(E) - M) / (1 - e * np.cos(E))
        E = E - step
        if np.max(np.abs(step)) < 1e-15:
            break
    return E


class Kepler(Problem):
    name = "kepler"
    summary = "Kepler orbit of eccentricity e (e = 0.9 is the hard case), exact solution"
    parameters = {"e": Param(0.6, "eccentricity, 0 <= e < 1", float, minimum=0.0, maximum=0.99)}
    default_t_final = 20 * np.pi
    default_dt = 0.01
    sweep_dt = (0.02, 0.01, 0.005)
    sweep_t_final = 40 * np.pi

    rhs = staticmethod(separable_rhs(_grad_T, _grad_V))
    grad_T = staticmethod(_grad_T)
    grad_V = staticmethod(_grad_V)
    taylor = staticmethod(_taylor)

    def taylor_work_shape(self, order):
        return (2, order + 1)

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
        e = self.settings["e"]
        E = solve_kepler(np.asarray(t, dtype=float) - self.t0, e)
        c, s = np.cos(E), np.sin(E)
        w = math.sqrt(1 - e * e)
        den = 1 - e * c
        return np.stack([c - e, w * s, -s / den, w * c / den], axis=1)

    def heyoka_system(self):
        import heyoka as hy

        x, y, px, py = hy.make_vars("x", "y", "px", "py")
        r3 = (x * x + y * y) ** 1.5
        return [x, y, px, py], [px, py, -x / r3, -y / r3]
