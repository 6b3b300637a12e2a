"""Planar double pendulum in Cartesian coordinates with two rigid rods (docs/problems.md 3).

Positions q = (x1, y1, x2, y2) of the two masses (pivot at the origin, y up); the rods
are the holonomic constraints

    phi_1 = |q1|^2 - l1^2 = 0,    phi_2 = |q2 - q1|^2 - l2^2 = 0,

the mass matrix is M = diag(m1, m1, m2, m2) and the potential U = g (m1 y1 + m2 y2).

State layout, shared by every scheme: u = (q, p) = (x1, y1, x2, y2, p_x1, p_y1, p_x2, p_y2)
with p = M v (for the Dirac schemes p_{n+1} = M v_n, the discrete Legendre transform).
The constrained schemes (dirac-1, dirac-2, dirac-midpoint, rattle) read the ``constraints``
capability; the unconstrained schemes integrate the index-1 ODE ``rhs``

    q' = M^{-1} p,   p' = -grad U + G^T lambda,
    (G M^{-1} G^T) lambda = G M^{-1} grad U - d2phi[v, v]      (v = M^{-1} p),

whose multipliers come from the acceleration-level constraints phi'' = 0. The ODE keeps
phi only up to the drift of its integrator (phi'' = 0 is neutrally stable): that drift is
what the naive baselines show.

Energy: H = |p1|^2/(2 m1) + |p2|^2/(2 m2) + U - U_min, measured from the stable rest
state U_min = -g (m1 l1 + m2 (l1 + l2)) (both masses hanging down). With the pivot as
the zero of U the default release (both rods horizontal, at rest) has H0 = 0, which would
turn the relative energy error into an absolute one; from the rest state, H0 is the
largest energy the pendulum can release (29.43 at the defaults), so ``H.max`` etc. are
relative to a physical scale. Violations: ``constraint`` = max_a |phi_a(q)| and
``velocity_constraint`` = max_a |(G v)_a| (the hidden constraint d phi / dt = 0).

The ``constraints`` contract (the capability "constraints"): an object with

    n_constraints                      m, the number of holonomic constraints
    phi(q, params, out)                out[a] = phi_a(q), shape (m,)
    grad_phi(q, params, out)           out[a, i] = d phi_a / d q_i, shape (m, n)  (rows of G)
    mass(params, out)                  the constant diagonal mass matrix, out[i] = M_ii, (n,)
    grad_U(q, params, out)             dU/dq, shape (n,)

with n = dim / 2 coordinates and the state u = (q, p), p = M v. All are compiled
(numba) and write into ``out``. The problem also offers ``project(u)`` (the nearest
consistent state) and ``angles(U)`` (theta1, theta2 from the downward vertical, for plots).

Reference: ``heyoka_system`` gives heyoka the same index-1 ODE; tests/test_constrained.py
checks it against heyoka on the angle (Lagrangian) formulation mapped to Cartesian.
"""
from __future__ import annotations

import math

import numba
import numpy as np

from longtime.core.params import InputError, Param
from longtime.core.problem import Problem, qp_blocks

# kernel params: (m1, m2, l1, l2, g)


@numba.njit(cache=True)
def _phi(q, params, out):
    l1, l2 = params[2], params[3]
    dx, dy = q[2] - q[0], q[3] - q[1]
    out[0] = q[0] * q[0] + q[1] * q[1] - l1 * l1
    out[1] = dx * dx + dy * dy - l2 * l2


@numba.njit(cache=True)
def _grad_phi(q, params, out):
    dx, dy = q[2] - q[0], q[3] - q[1]
    out[0, 0] = 2.0 * q[0]
    out[0, 1] = 2.0 * q[1]
    out[0, 2] = 0.0
    out[0, 3] = 0.0
    out[1, 0] = -2.0 * dx
    out[1, 1] = -2.0 * dy
    out[1, 2] = 2.0 * dx
    out[1, 3] = 2.0 * dy


@numba.njit(cache=True)
def _mass(params, out):
    out[0] = params[0]
    out[1] = params[0]
    out[2] = params[1]
    out[3] = params[1]


@numba.njit(cache=True)
def _grad_U(q, params, out):
    out[0] = 0.0
    out[1] = params[0] * params[4]
    out[2] = 0.0
    out[3] = params[1] * params[4]


@numba.njit(cache=True)
def _rhs(t, u, params, out):
    # the index-1 ODE, written out for two constraints (a 2x2 solve by Cramer's rule)
    m1, m2, g = params[0], params[1], params[4]
    w1, w2 = 1.0 / m1, 1.0 / m2
    x1, y1 = u[0], u[1]
    dx, dy = u[2] - u[0], u[3] - u[1]
    vx1, vy1 = u[4] * w1, u[5] * w1
    vx2, vy2 = u[6] * w2, u[7] * w2
    dvx, dvy = vx2 - vx1, vy2 - vy1
    # applied forces f = -grad U, accelerations without constraint a = M^{-1} f
    ay1, ay2 = -g, -g
    # (G M^{-1} G^T) lambda = -(G a + d2phi[v, v]), rows of G = grad phi
    a00 = 4.0 * w1 * (x1 * x1 + y1 * y1)
    a01 = -4.0 * w1 * (x1 * dx + y1 * dy)
    a11 = 4.0 * (w1 + w2) * (dx * dx + dy * dy)
    b0 = -(2.0 * y1 * ay1 + 2.0 * (vx1 * vx1 + vy1 * vy1))
    b1 = -(2.0 * dy * (ay2 - ay1) + 2.0 * (dvx * dvx + dvy * dvy))
    det = a00 * a11 - a01 * a01
    lam0 = (b0 * a11 - a01 * b1) / det
    lam1 = (a00 * b1 - a01 * b0) / det
    out[0] = vx1
    out[1] = vy1
    out[2] = vx2
    out[3] = vy2
    out[4] = 2.0 * (lam0 * x1 - lam1 * dx)
    out[5] = -m1 * g + 2.0 * (lam0 * y1 - lam1 * dy)
    out[6] = 2.0 * lam1 * dx
    out[7] = -m2 * g + 2.0 * lam1 * dy


class PendulumConstraints:
    """The ``constraints`` capability of the double pendulum (contract: module docstring)."""

    n_constraints = 2
    phi = staticmethod(_phi)
    grad_phi = staticmethod(_grad_phi)
    mass = staticmethod(_mass)
    grad_U = staticmethod(_grad_U)


class DoublePendulum(Problem):
    name = "double-pendulum"
    summary = "Cartesian double pendulum, two rod constraints (index-1 ODE for unconstrained schemes)"
    chaotic = True
    lyapunov_span = 100.0
    parameters = {
        "m1": Param(1.0, "mass of the first bob", float, positive=True, role="physical"),
        "m2": Param(1.0, "mass of the second bob", float, positive=True, role="physical"),
        "l1": Param(1.0, "length of the first rod", float, positive=True, role="physical"),
        "l2": Param(1.0, "length of the second rod", float, positive=True, role="physical"),
        "g": Param(9.81, "gravity", float, minimum=0.0, role="physical"),
        "theta1": Param(math.pi / 2, "initial angle of rod 1 from the downward vertical (rad)", float, role="physical"),
        "theta2": Param(math.pi / 2, "initial angle of rod 2 from the downward vertical (rad)", float, role="physical"),
        "omega1": Param(0.0, "initial angular velocity of rod 1 (rad/s)", float, role="physical"),
        "omega2": Param(0.0, "initial angular velocity of rod 2 (rad/s)", float, role="physical"),
    }
    # cheap defaults for the matrix: the paper's run (dt 1e-4 to T 100) is `longtime run`'s
    default_t_final = 10.0
    default_dt = 1e-3
    sweep_dt = (4e-3, 2e-3, 1e-3)
    sweep_t_final = 10.0
    # the paper's runs: (schemes, dt, t_final)
    paper_runs = ((("dirac-2", "euler"), 1e-4, 100.0),)

    rhs = staticmethod(_rhs)
    constraints = PendulumConstraints

    def blocks(self):
        return qp_blocks(["bob 1", "bob 2"], 2)  # each bob's position and momentum

    def initial_state(self):
        s = self.settings
        l1, l2, m1, m2 = s["l1"], s["l2"], s["m1"], s["m2"]
        t1, t2, w1, w2 = s["theta1"], s["theta2"], s["omega1"], s["omega2"]
        x1, y1 = l1 * math.sin(t1), -l1 * math.cos(t1)
        x2, y2 = x1 + l2 * math.sin(t2), y1 - l2 * math.cos(t2)
        vx1, vy1 = l1 * w1 * math.cos(t1), l1 * w1 * math.sin(t1)
        vx2, vy2 = vx1 + l2 * w2 * math.cos(t2), vy1 + l2 * w2 * math.sin(t2)
        return [x1, y1, x2, y2, m1 * vx1, m1 * vy1, m2 * vx2, m2 * vy2]

    def kernel_params(self):
        s = self.settings
        return np.array([s["m1"], s["m2"], s["l1"], s["l2"], s["g"]])

    # ---- Python-level views (vectorised over samples U of shape (k, 8)) ----

    def _split(self, U):
        U = np.atleast_2d(np.asarray(U, dtype=float))
        m1, m2 = self.settings["m1"], self.settings["m2"]
        q = U[:, :4]
        v = U[:, 4:] / np.array([m1, m1, m2, m2])
        return q, v

    def energy(self, U):
        s = self.settings
        q, v = self._split(U)
        m1, m2, g = s["m1"], s["m2"], s["g"]
        kinetic = 0.5 * (m1 * (v[:, 0] ** 2 + v[:, 1] ** 2) + m2 * (v[:, 2] ** 2 + v[:, 3] ** 2))
        u_rest = -g * (m1 * s["l1"] + m2 * (s["l1"] + s["l2"]))
        return kinetic + g * (m1 * q[:, 1] + m2 * q[:, 3]) - u_rest

    def constraint_values(self, U):
        """(phi_1, phi_2) and (G v)_1, (G v)_2 at the samples, each of shape (k, 2)."""
        s = self.settings
        q, v = self._split(U)
        dx, dy = q[:, 2] - q[:, 0], q[:, 3] - q[:, 1]
        dvx, dvy = v[:, 2] - v[:, 0], v[:, 3] - v[:, 1]
        phi = np.stack([q[:, 0] ** 2 + q[:, 1] ** 2 - s["l1"] ** 2, dx**2 + dy**2 - s["l2"] ** 2], axis=1)
        gv = 2 * np.stack([q[:, 0] * v[:, 0] + q[:, 1] * v[:, 1], dx * dvx + dy * dvy], axis=1)
        return phi, gv

    def invariants(self, t, U):
        return {"H": self.energy(U)}

    def violations(self, t, U):
        phi, gv = self.constraint_values(U)
        return {"constraint": np.max(np.abs(phi), axis=1),
                "velocity_constraint": np.max(np.abs(gv), axis=1)}

    def angles(self, U):
        """theta1, theta2 (from the downward vertical, unwrapped along the samples)."""
        q, _ = self._split(U)
        t1 = np.arctan2(q[:, 0], -q[:, 1])
        t2 = np.arctan2(q[:, 2] - q[:, 0], -(q[:, 3] - q[:, 1]))
        return np.unwrap(t1), np.unwrap(t2)

    def project(self, u):
        """The consistent state nearest to ``u``: each rod rescaled to its length along its
        current direction, then the velocity projected M-orthogonally onto ker G(q)."""
        u = np.array(u, dtype=float)
        if u.shape != (8,) or not np.all(np.isfinite(u)):
            raise InputError(f"state must be 8 finite numbers (x1, y1, x2, y2, p...), got {u!r}")
        s = self.settings
        q1, r = u[:2], u[2:4] - u[:2]
        n1, n2 = np.linalg.norm(q1), np.linalg.norm(r)
        if n1 == 0 or n2 == 0:
            raise InputError("state: a rod has zero length, its direction (and the projection) is undefined")
        q1 = q1 * (s["l1"] / n1)
        q2 = q1 + r * (s["l2"] / n2)
        q = np.r_[q1, q2]
        minv = 1 / np.array([s["m1"], s["m1"], s["m2"], s["m2"]])
        G = np.zeros((2, 4))
        _grad_phi(q, self.params, G)
        w = minv * u[4:]
        lam = np.linalg.solve((G * minv) @ G.T, G @ w)
        v = w - minv * (G.T @ lam)
        return np.r_[q, v / minv]

    def heyoka_system(self):
        """heyoka expressions of the same index-1 ODE as ``rhs`` (Cramer's rule for lambda)."""
        import heyoka as hy

        s = self.settings
        m1, m2, g = s["m1"], s["m2"], s["g"]
        w1, w2 = 1.0 / m1, 1.0 / m2
        x1, y1, x2, y2, px1, py1, px2, py2 = hy.make_vars("x1", "y1", "x2", "y2", "px1", "py1", "px2", "py2")
        dx, dy = x2 - x1, y2 - y1
        vx1, vy1, vx2, vy2 = px1 * w1, py1 * w1, px2 * w2, py2 * w2
        dvx, dvy = vx2 - vx1, vy2 - vy1
        a00 = 4.0 * w1 * (x1 * x1 + y1 * y1)
        a01 = -4.0 * w1 * (x1 * dx + y1 * dy)
        a11 = 4.0 * (w1 + w2) * (dx * dx + dy * dy)
        b0 = 2.0 * g * y1 - 2.0 * (vx1 * vx1 + vy1 * vy1)
        b1 = -2.0 * (dvx * dvx + dvy * dvy)
        det = a00 * a11 - a01 * a01
        lam0 = (b0 * a11 - a01 * b1) / det
        lam1 = (a00 * b1 - a01 * b0) / det
        rhs = [vx1, vy1, vx2, vy2,
               2.0 * (lam0 * x1 - lam1 * dx), -m1 * g + 2.0 * (lam0 * y1 - lam1 * dy),
               2.0 * lam1 * dx, -m2 * g + 2.0 * lam1 * dy]
        return [x1, y1, x2, y2, px1, py1, px2, py2], rhs
