"""The free rigid body: Euler's equations for the angular momentum m in the body frame
(Hairer, Lubich, Wanner, Geometric Numerical Integration, IV.1 and VII.5),

    m' = m x (I^-1 m),   i.e.   m1' = (1/I3 - 1/I2) m2 m3,
                                m2' = (1/I1 - 1/I3) m3 m1,
                                m3' = (1/I2 - 1/I1) m1 m2,

a Lie-Poisson system. Invariants: the Casimir C = |m|^2 and the energy
H = (m1^2/I1 + m2^2/I2 + m3^2/I3)/2. HLW's example: I1 = 2, I2 = 1, I3 = 2/3,
m0 = (cos 1.1, 0, sin 1.1).

Exact solution in Jacobi elliptic functions (``rigid_body_orbit``): with a_i = 1/I_i sorted
increasingly (a1 <= a2 <= a3), G^2 = |m|^2 and E = 2H, a body with E > a2 G^2 turns about
axis 3 and

    m1 = A cn(tau), m2 = B sn(tau), m3 = s3 D dn(tau),   tau = lambda t + tau0,
    A^2 = (a3 G^2 - E)/(a3 - a1),   B^2 = (a3 G^2 - E)/(a3 - a2),   D^2 = (E - a1 G^2)/(a3 - a1),
    k^2 = (a2 - a1)(a3 G^2 - E) / ((a3 - a2)(E - a1 G^2)),
    lambda = -s3 sqrt((a3 - a2)(E - a1 G^2)),   s3 = sign m3(0),

and tau0 = F(atan2(m2(0)/B, m1(0)/A) | k^2) (incomplete elliptic integral of the first kind).
E < a2 G^2 (about axis 1) is the same case for the axes reversed and a_i -> -a_i.
"""
from __future__ import annotations

import numba
import numpy as np

from longtime.core.params import Param
from longtime.core.problem import Problem, whole_state


@numba.njit(cache=True)
def _rhs(t, u, params, out):
    a1, a2, a3 = params[0], params[1], params[2]  # inverse moments of inertia
    out[0] = (a3 - a2) * u[1] * u[2]
    out[1] = (a1 - a3) * u[2] * u[0]
    out[2] = (a2 - a1) * u[0] * u[1]


@numba.njit(cache=True)
def _jac(t, u, params, out):
    a1, a2, a3 = params[0], params[1], params[2]
    out[0, 0], out[0, 1], out[0, 2] = 0.0, (a3 - a2) * u[2], (a3 - a2) * u[1]
    out[1, 0], out[1, 1], out[1, 2] = (a1 - a3) * u[2], 0.0, (a1 - a3) * u[0]
    out[2, 0], out[2, 1], out[2, 2] = (a2 - a1) * u[1], (a2 - a1) * u[0], 0.0


def _about_axis3(a: np.ndarray, m0: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The case a1 <= a2 < a3, E >= a2 G^2 of the module's formulas: states (len(t), 3)."""
    from scipy.special import ellipj, ellipkinc

    a1, a2, a3 = a
    G2 = float(np.dot(m0, m0))
    E = float(np.dot(a, m0 * m0))
    top, bottom = a3 * G2 - E, E - a1 * G2
    if top <= 0.0 or bottom <= 0.0:  # a steady rotation (m on a principal axis, or a
        return np.tile(m0, (t.size, 1))  # symmetric body about its plane of equal moments)
    A, B, D = np.sqrt(top / (a3 - a1)), np.sqrt(top / (a3 - a2)), np.sqrt(bottom / (a3 - a1))
    k2 = min((a2 - a1) * top / ((a3 - a2) * bottom), 1.0)
    s3 = 1.0 if m0[2] >= 0 else -1.0
    lam = -s3 * np.sqrt((a3 - a2) * bottom)
    tau0 = ellipkinc(np.arctan2(m0[1] / B, m0[0] / A), k2)
    sn, cn, dn, _ = ellipj(lam * t + tau0, k2)
    return np.stack([A * cn, B * sn, s3 * D * dn], axis=1)


def rigid_body_orbit(inertia, m0, t) -> np.ndarray:
    """m(t), shape (len(t), 3), of the free rigid body with moments ``inertia`` from ``m0``
    at t = 0 (the module's formulas; axes sorted by 1/I_i, permuted back afterwards)."""
    a = 1.0 / np.asarray(inertia, dtype=float)
    m0 = np.asarray(m0, dtype=float)
    t = np.asarray(t, dtype=float)
    order = np.argsort(a, kind="stable")
    # an odd permutation of the axes reverses m x (a m): run time backwards then
    odd = int(np.round(np.linalg.det(np.eye(3)[order]))) < 0
    a_s, m_s, sign = a[order], m0[order], (-1.0 if odd else 1.0)
    G2, E = float(np.dot(m_s, m_s)), float(np.dot(a_s, m_s * m_s))
    if np.ptp(a_s) == 0.0 or G2 == 0.0:  # a sphere, or at rest: m is constant
        return np.tile(m0, (t.size, 1))
    if E < a_s[1] * G2:  # about axis 1: axes reversed (odd) and a -> -a (time reversed): t kept
        states = _about_axis3(-a_s[::-1], m_s[::-1], t * sign)[:, ::-1]
    else:
        states = _about_axis3(a_s, m_s, t * sign)
    out = np.empty_like(states)
    out[:, order] = states
    return out


def _jax_rhs(t, u, params):
    """The rhs in jax.numpy (the diffrax peers)."""
    import jax.numpy as jnp

    a1, a2, a3 = params[0], params[1], params[2]
    return jnp.stack([(a3 - a2) * u[1] * u[2], (a1 - a3) * u[2] * u[0], (a2 - a1) * u[0] * u[1]])


class RigidBody(Problem):
    name = "rigid-body"
    summary = "free rigid body (Euler's equations, HLW IV.1): Casimir |m|^2 and energy, exact solution"
    parameters = {
        "I1": Param(2.0, "moment of inertia about axis 1", float, positive=True, role="physical"),
        "I2": Param(1.0, "moment of inertia about axis 2", float, positive=True, role="physical"),
        "I3": Param(2.0 / 3.0, "moment of inertia about axis 3", float, positive=True, role="physical"),
        "angle": Param(1.1, "m0 = (cos angle, 0, sin angle)", float, role="physical"),
    }
    default_t_final = 100.0
    default_dt = 0.05
    sweep_dt = (0.1, 0.05, 0.025)
    sweep_t_final = 1000.0
    long_t_final = 10_000.0  # about 10^3 periods of the tumbling

    rhs = staticmethod(_rhs)
    jax_rhs = staticmethod(_jax_rhs)
    jac = staticmethod(_jac)

    def blocks(self):
        return whole_state(self)  # one angular momentum vector

    def initial_state(self):
        angle = self.settings["angle"]
        return [np.cos(angle), 0.0, np.sin(angle)]

    def inertia(self) -> np.ndarray:
        return np.array([self.settings["I1"], self.settings["I2"], self.settings["I3"]])

    def kernel_params(self):
        return 1.0 / self.inertia()

    def invariants(self, t, U):
        return {"C": np.sum(U**2, axis=1), "H": 0.5 * np.sum(U**2 / self.inertia(), axis=1)}

    def exact(self, t):
        return rigid_body_orbit(self.inertia(), self.u0, np.asarray(t, dtype=float) - self.t0)

    def heyoka_system(self):
        import heyoka as hy

        m1, m2, m3 = hy.make_vars("m1", "m2", "m3")
        a1, a2, a3 = (float(x) for x in self.kernel_params())
        return [m1, m2, m3], [(a3 - a2) * m2 * m3, (a1 - a3) * m3 * m1, (a2 - a1) * m1 * m2]
