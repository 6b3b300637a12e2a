"""Gravitational N-body problems, H = sum |p_k|^2/(2 m_k) - sum_{k<l} G m_k m_l / |q_k - q_l|.

State u = (q_1..q_N, p_1..p_N), each q_k, p_k in R^s (s = 2 or 3). The compiled functions
read s, G and the masses from ``params = (s, G, m_1..m_N, 1/m_1..1/m_N)``.
Invariants: H, the angular momentum L (a scalar in the plane, a vector in space) and the
linear momentum P.
"""
from __future__ import annotations

import functools
import math

import numba
import numpy as np

from longtime.core.params import Param
from longtime.core.problem import Problem, qp_blocks
from longtime.numerics.series import power_coeff, product, square


def _kernels(s: int):
    """rhs, grad_T, grad_V for bodies in R^s, with s a compile-time constant (strides and
    branches fold away: this is the hot loop of every n-body run)."""

    @numba.njit(inline="always")
    def add_forces(q, n, params, out, offset, sign):
        # out[offset + i] += sign * dV/dq_i for positions q[0:n*s]; dx once per pair, one
        # sqrt. rhs indexes the full state directly: views cost reference counting.
        G = params[1]
        for k in range(n):
            for l in range(k + 1, n):
                x0 = q[k * s] - q[l * s]
                x1 = q[k * s + 1] - q[l * s + 1]
                x2 = q[k * s + 2] - q[l * s + 2] if s == 3 else 0.0
                r2 = x0 * x0 + x1 * x1 + x2 * x2
                f = sign * G * params[2 + k] * params[2 + l] / (r2 * math.sqrt(r2))
                out[offset + k * s] += f * x0
                out[offset + k * s + 1] += f * x1
                out[offset + l * s] -= f * x0
                out[offset + l * s + 1] -= f * x1
                if s == 3:
                    out[offset + k * s + 2] += f * x2
                    out[offset + l * s + 2] -= f * x2

    @numba.njit(inline="always")
    def velocities(p, n, params, out, p_offset):
        for b in range(n):
            inverse_mass = params[2 + n + b]
            for c in range(b * s, b * s + s):
                out[c] = p[p_offset + c] * inverse_mass

    @numba.njit
    def grad_V(q, params, out):
        for i in range(q.size):
            out[i] = 0.0
        add_forces(q, q.size // s, params, out, 0, 1.0)

    @numba.njit
    def grad_T(p, params, out):
        velocities(p, p.size // s, params, out, 0)

    @numba.njit
    def rhs(t, u, params, out):
        h = u.size // 2
        velocities(u, h // s, params, out, h)
        for i in range(h, 2 * h):
            out[i] = 0.0
        add_forces(u, h // s, params, out, h, -1.0)

    return rhs, grad_T, grad_V


_PLANAR = _kernels(2)
_SPATIAL = _kernels(3)


@numba.njit(cache=True)
def _taylor(t0, u, params, coeffs, work):
    # for each pair k < l, rows of work hold the series of q_k - q_l (s rows), of
    # r_kl^2 and of r_kl^-3 = (r_kl^2)^(-3/2); p_k' = -sum_l G m_k m_l (q_k - q_l) r_kl^-3
    s = int(params[0])
    G = params[1]
    h = u.size // 2
    nb = h // s
    for i in range(u.size):
        coeffs[0, i] = u[i]
    for n in range(coeffs.shape[0] - 1):
        for i in range(h, 2 * h):
            coeffs[n + 1, i] = 0.0
        row = 0
        for k in range(nb):
            for l in range(k + 1, nb):
                r2 = 0.0
                for c in range(s):
                    work[row + c, n] = coeffs[n, k * s + c] - coeffs[n, l * s + c]
                    r2 += square(work[row + c], n)
                work[row + s, n] = r2
                work[row + s + 1, n] = power_coeff(work[row + s], work[row + s + 1], -1.5, n)
                f = G * params[2 + k] * params[2 + l]
                for c in range(s):
                    g = f * product(work[row + c], work[row + s + 1], n)
                    coeffs[n + 1, h + k * s + c] -= g
                    coeffs[n + 1, h + l * s + c] += g
                row += s + 2
        for i in range(h):
            coeffs[n + 1, i] = coeffs[n, h + i] / (params[2 + i // s] * (n + 1))
            coeffs[n + 1, h + i] /= n + 1


class NBody(Problem):
    """Base of the gravitational problems: subclasses give masses, s, G and the state."""

    space_dim: int = 2
    G: float = 1.0
    check_class = "many-body"

    rhs, grad_T, grad_V = (staticmethod(f) for f in _PLANAR)
    taylor = staticmethod(_taylor)

    def taylor_work_shape(self, order):
        n = self.masses().size
        return (max(1, n * (n - 1) // 2) * (self.space_dim + 2), order + 1)

    def masses(self) -> np.ndarray:
        raise NotImplementedError

    def body_names(self) -> list[str]:
        return [f"body {k + 1}" for k in range(self.masses().size)]

    def blocks(self):
        """Each body's position and its momentum (its momentum m v is 1e-5 of its position
        for Jupiter in AU and solar masses: in one norm it would not count)."""
        return qp_blocks(self.body_names(), self.space_dim)

    def kernel_params(self):
        if self.space_dim not in (2, 3):
            raise ValueError(f"space_dim={self.space_dim}: the n-body kernels take 2 or 3")
        m = self.masses()
        return np.r_[self.space_dim, self.G, m, 1.0 / m]

    def inverse_masses(self):
        return np.repeat(1.0 / self.masses(), self.space_dim)

    def split_state(self, U):
        m = self.masses()
        n, s = m.size, self.space_dim
        q = U[:, : n * s].reshape(-1, n, s)
        p = U[:, n * s :].reshape(-1, n, s)
        return m, q, p

    def invariants(self, t, U):
        m, q, p = self.split_state(U)
        kinetic = np.sum(np.sum(p**2, axis=2) / (2 * m), axis=1)
        potential = np.zeros(U.shape[0])
        # each body's positions contiguous, each distance an einsum: faster than strided
        # columns through np.linalg.norm, and than all pairs at once through fancy indexing
        # (docs/performance.md)
        qs = [np.ascontiguousarray(q[:, k]) for k in range(m.size)]
        for k in range(m.size):
            for l in range(k + 1, m.size):
                d = qs[k] - qs[l]
                potential -= self.G * m[k] * m[l] / np.sqrt(np.einsum("ij,ij->i", d, d))
        if self.space_dim == 2:
            L = np.sum(q[:, :, 0] * p[:, :, 1] - q[:, :, 1] * p[:, :, 0], axis=1)
        else:
            L = np.sum(np.cross(q, p), axis=1)
        return {"H": kinetic + potential, "L": L, "P": np.sum(p, axis=1)}

    def heyoka_system(self):
        import heyoka as hy

        m = self.masses()
        n, s = m.size, self.space_dim
        q = hy.make_vars(*[f"q{k}_{c}" for k in range(n) for c in range(s)])
        p = hy.make_vars(*[f"p{k}_{c}" for k in range(n) for c in range(s)])
        dq = [p[i] / float(m[i // s]) for i in range(n * s)]
        dp = [0.0 * q[0] for _ in range(n * s)]
        for k in range(n):
            for l in range(k + 1, n):
                d = [q[k * s + c] - q[l * s + c] for c in range(s)]
                r3 = hy.sum([x * x for x in d]) ** 1.5
                f = self.G * float(m[k] * m[l])
                for c in range(s):
                    dp[k * s + c] = dp[k * s + c] - f * d[c] / r3
                    dp[l * s + c] = dp[l * s + c] + f * d[c] / r3
        return list(q) + list(p), dq + dp


# Chenciner-Montgomery figure-eight (Simo's digits), m = 1, G = 1
_Q1 = np.array([0.97000436, -0.24308753])
_V3 = np.array([-0.93240737, -0.86473146])
FIGURE_EIGHT_PERIOD = 6.32591398


def figure_eight_state() -> np.ndarray:
    q = np.r_[_Q1, -_Q1, 0.0, 0.0]
    v = np.r_[-_V3 / 2, -_V3 / 2, _V3]
    return np.r_[q, v]


class FigureEight(NBody):
    name = "figure-eight"
    summary = "three-body figure-eight choreography (planar, m = G = 1)"
    period = FIGURE_EIGHT_PERIOD
    default_t_final = 2200 * FIGURE_EIGHT_PERIOD
    default_dt = 0.002 * FIGURE_EIGHT_PERIOD  # the paper prints 0.02 T (docs/paper.md)
    sweep_dt = (0.004 * FIGURE_EIGHT_PERIOD, 0.002 * FIGURE_EIGHT_PERIOD)
    sweep_t_final = 20 * FIGURE_EIGHT_PERIOD
    long_t_final = 2200 * FIGURE_EIGHT_PERIOD  # the paper's, for the schemes that can afford it

    def masses(self):
        return np.ones(3)

    def initial_state(self):
        return figure_eight_state()


class FigureEightPerturbed(FigureEight):
    """Body 3 takes the state it has at t = T/shift on the exact figure-eight. Measured from
    the reference (docs/problems.md): for shift >= 33 (the default 80 among them) the three
    bodies stay bound and separate like a regular orbit (no exponential separation over
    t = 1e4); for shift <= 32 the choreography breaks up, and the bound pair's encounters
    with the third body are chaotic (``chaotic_settings``: shift = 10)."""

    name = "figure-eight-perturbed"
    summary = ("figure-eight with the middle body shifted along its orbit (hard; regular at the default "
               "shift, chaotic break-up for shift <= 32)")
    chaotic = True
    chaotic_settings = {"shift": 10.0}
    parameters = {"shift": Param(80.0, "body 3 moved to t = T/shift on the orbit",
                                 float, positive=True, role="physical")}
    default_t_final = 200 * FIGURE_EIGHT_PERIOD
    sweep_t_final = 20 * FIGURE_EIGHT_PERIOD
    long_t_final = 2200 * FIGURE_EIGHT_PERIOD  # the paper's, for the schemes that can afford it

    def initial_state(self):
        u = figure_eight_state()
        shifted = _figure_eight_at(self.period / self.settings["shift"])
        u[4:6], u[10:12] = shifted[4:6], shifted[10:12]
        return u


@functools.lru_cache(maxsize=16)
def _figure_eight_at(t: float) -> np.ndarray:
    """The figure-eight's state at time t, by heyoka as the reference integrates it (double,
    high accuracy, the reference's code mode): the same numbers as its reference states.
    Kept per process (read-only): every cell of the perturbed problem builds it again."""
    from longtime.core import heyoka_build

    base = FigureEight()
    ta = heyoka_build.taylor_adaptive(base, base.u0.astype(np.float64), None, high_accuracy=True,
                                      fp_type=np.float64, time=np.float64(base.t0),
                                      compact_mode=heyoka_build.compact_mode(base, np.float64, reference=True))
    state = np.array(np.asarray(ta.propagate_grid(np.array([base.t0, t], dtype=np.float64))[-1], dtype=float)[-1])
    state.flags.writeable = False
    return state


# Hairer, Lubich, Wanner, Geometric Numerical Integration, section I.2.4: the Sun (with the
# inner planets' mass) and the five outer planets on 5 September 1994; AU, days, solar masses.
_OSS_G = 2.95912208286e-4
_OSS_MASSES = np.array([1.00000597682, 0.000954786104043, 0.000285583733151,
                        0.0000437273164546, 0.0000517759138449, 1 / 1.3e8])
_OSS_Q = np.array([[0.0, 0.0, 0.0],
                   [-3.5023653, -3.8169847, -1.5507963],
                   [9.0755314, -3.0458353, -1.6483708],
                   [8.3101420, -16.2901086, -7.2521278],
                   [11.4707666, -25.7294829, -10.8169456],
                   [-15.5387357, -25.2225594, -3.1902382]])
_OSS_V = np.array([[0.0, 0.0, 0.0],
                   [0.00565429, -0.00412490, -0.00190589],
                   [0.00168318, 0.00483525, 0.00192462],
                   [0.00354178, 0.00137102, 0.00055029],
                   [0.00288930, 0.00114527, 0.00039677],
                   [0.00276725, -0.00170702, -0.00136504]])


class OuterSolarSystem(NBody):
    name = "outer-solar-system"
    summary = "Sun and the five outer planets (Hairer-Lubich-Wanner's data; days, AU)"
    space_dim = 3
    G = _OSS_G
    rhs, grad_T, grad_V = (staticmethod(f) for f in _SPATIAL)
    default_t_final = 200_000.0
    default_dt = 10.0
    sweep_dt = (200.0, 100.0)
    sweep_t_final = 100_000.0
    long_t_final = 1_000_000.0  # days: over 10^3 Jupiter years, for the schemes that can afford it

    def masses(self):
        return _OSS_MASSES

    def body_names(self):
        return ["Sun", "Jupiter", "Saturn", "Uranus", "Neptune", "Pluto"]

    def initial_state(self):
        return np.r_[_OSS_Q.ravel(), (_OSS_MASSES[:, None] * _OSS_V).ravel()]
