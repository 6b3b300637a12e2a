"""Periodic Toda lattice, H = sum_k p_k^2/2 + exp(q_k - q_{k+1}), q_{d+1} = q_1.

Invariants: H and the eigenvalues of the periodic tridiagonal Lax matrix with diagonal
-p_k and off-diagonals exp((q_k - q_{k+1})/2) (docs/paper.md: the paper's extra 1/2 factors
are a misprint; this scaling gives its eigenvalues -5.2439, 1.3125, 3.9314).
"""
from __future__ import annotations

import math

import numba
import numpy as np

from longtime.core.params import Param
from longtime.core.problem import Problem, qp_blocks
from longtime.numerics.series import exp_coeff


@numba.njit(cache=True, inline="always")
def _add_forces(x, d, out, offset, sign):
    """out[offset + k] = sign * dV/dq_k for positions x[0:d]; dV/dq_k = e_k - e_{k-1} with
    e_k = exp(q_k - q_{k+1}): one exp per spring, no modulo. Shared by grad_V and rhs, which
    index the full state directly (array views cost reference counting in the hot loop)."""
    wrap = math.exp(x[d - 1] - x[0])
    previous = wrap
    for k in range(d - 1):
        e = math.exp(x[k] - x[k + 1])
        out[offset + k] = sign * (e - previous)
        previous = e
    out[offset + d - 1] = sign * (wrap - previous)


@numba.njit(cache=True)
def _grad_V(q, params, out):
    _add_forces(q, q.size, out, 0, 1.0)


@numba.njit(cache=True)
def _rhs(t, u, params, out):
    d = u.size // 2
    for k in range(d):
        out[k] = u[d + k]
    _add_forces(u, d, out, d, -1.0)


@numba.njit(cache=True)
def _grad_T(p, params, out):
    for k in range(p.size):
        out[k] = p[k]


@numba.njit(cache=True)
def _taylor(t0, u, params, coeffs, work):
    # q_k' = p_k, p_k' = e_{k-1} - e_k with e_k = exp(q_k - q_{k+1}): work[k] holds the
    # series of q_k - q_{k+1}, work[d + k] that of its exponential
    d = u.size // 2
    for i in range(2 * d):
        coeffs[0, i] = u[i]
    for n in range(coeffs.shape[0] - 1):
        for k in range(d):
            work[k, n] = coeffs[n, k] - coeffs[n, (k + 1) % d]
            work[d + k, n] = exp_coeff(work[k], work[d + k], n)
        for k in range(d):
            coeffs[n + 1, k] = coeffs[n, d + k] / (n + 1)
            coeffs[n + 1, d + k] = (work[d + (k - 1) % d, n] - work[d + k, n]) / (n + 1)


# bytes of Lax matrices built at once by Toda.lax_eigenvalues
LAX_CHUNK_BYTES = 64 * 2**20


def _jax_rhs(t, u, params):
    """The rhs in jax.numpy (the diffrax peers): dV/dq_k = e_k - e_{k-1}, e_k = exp(q_k - q_{k+1})."""
    import jax.numpy as jnp

    d = u.size // 2
    q, p = u[:d], u[d:]
    e = jnp.exp(q - jnp.roll(q, -1))
    return jnp.concatenate([p, jnp.roll(e, 1) - e])


class Toda(Problem):
    name = "toda"
    summary = "periodic Toda lattice (integrable; H and Lax eigenvalues conserved)"
    check_class = "many-body"
    # an upper bound, so that a typo (d=1e9) is an input error, not 16 GB allocated while expanding
    parameters = {"d": Param(3, "number of particles (>= 3)", int, minimum=3, maximum=10**6, role="physical")}
    default_t_final = 5000.0
    default_dt = 0.1
    sweep_dt = (0.1, 0.05, 0.025)
    sweep_t_final = 500.0
    long_t_final = 5000.0  # the paper's, for the schemes that can afford it

    rhs = staticmethod(_rhs)
    jax_rhs = staticmethod(_jax_rhs)
    grad_T = staticmethod(_grad_T)
    grad_V = staticmethod(_grad_V)
    taylor = staticmethod(_taylor)

    def taylor_work_shape(self, order):
        return (2 * self.settings["d"], order + 1)

    def blocks(self):
        return qp_blocks([str(k + 1) for k in range(self.settings["d"])], 1)

    def initial_state(self):
        d = self.settings["d"]
        if d == 3:  # the paper's state, H0 = 22.338751647595720
            return [0.0, 2.0, 3.0, 0.5, -1.5, 1.0]
        # any other size: at rest but for a momentum wave of zero total momentum
        k = np.arange(d)
        return np.r_[np.zeros(d), np.cos(2 * np.pi * k / d)]

    def inverse_masses(self):
        return np.ones(self.dim // 2)

    def hamiltonian(self, t, U):
        d = self.settings["d"]
        q, p = U[:, :d], U[:, d:]
        return 0.5 * np.sum(p**2, axis=1) + np.sum(np.exp(q - np.roll(q, -1, axis=1)), axis=1)

    def lax_eigenvalues(self, t, U):
        """Eigenvalues of the Lax matrix at each sample, (n, d). The matrices are built and
        solved a chunk of samples at a time (about LAX_CHUNK_BYTES of matrices), so memory
        stays bounded whatever the number of samples (all at once, d = 80 and 62500 samples
        would hold 3.2 GB of matrices)."""
        d = self.settings["d"]
        n = U.shape[0]
        eig = np.full((n, d), np.nan)
        per = max(1, LAX_CHUNK_BYTES // (8 * d * d))
        k = np.arange(d)
        for a in range(0, n, per):
            q, p = U[a:a + per, :d], U[a:a + per, d:]
            b = np.exp(0.5 * (q - np.roll(q, -1, axis=1)))
            L = np.zeros((q.shape[0], d, d))
            L[:, k, k] = -p
            L[:, k, (k + 1) % d] = b
            L[:, (k + 1) % d, k] = b
            # a blown-up state (entries near overflow) has no meaningful spectrum: NaN, not an error
            sane = np.all(np.abs(L) < 1e100, axis=(1, 2))
            if sane.any():
                eig[a:a + q.shape[0]][sane] = np.linalg.eigvalsh(L[sane])
        return eig

    def metrics_bytes(self, samples):
        d = self.settings["d"]
        chunk = min(samples, max(1, LAX_CHUNK_BYTES // (8 * d * d))) * 8 * d * d
        # the generic metrics, the eigenvalues and their relative errors (2 x n x d), and a chunk
        # of matrices three times over (L, the sane ones, LAPACK's copy)
        return super().metrics_bytes(samples) + 2 * samples * d * 8 + 3 * chunk

    def invariants(self, t, U):
        out = {"H": self.hamiltonian(t, U)}
        eig = self.lax_eigenvalues(t, U)
        for i in range(eig.shape[1]):
            out[f"eig{i + 1}"] = eig[:, i]
        return out

    def heyoka_system(self):
        import heyoka as hy

        d = self.settings["d"]
        q = hy.make_vars(*[f"q{k}" for k in range(d)])
        p = hy.make_vars(*[f"p{k}" for k in range(d)])
        springs = [hy.exp(q[k] - q[(k + 1) % d]) for k in range(d)]
        dp = [springs[k - 1] - springs[k] for k in range(d)]
        return list(q) + list(p), list(p) + dp
