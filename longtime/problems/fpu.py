"""Fermi-Pasta-Ulam-Tsingou with stiff springs (Hairer, Lubich, Wanner, Geometric Numerical
Integration, section I.5): 2m unit masses in a chain with fixed ends, joined alternately by
soft cubic springs and stiff linear springs of frequency omega.

In the chain's coordinates (q_0 = q_{2m+1} = 0)

    H = sum_i (p_{2i-1}^2 + p_{2i}^2)/2 + omega^2/4 sum_i (q_{2i} - q_{2i-1})^2
        + sum_{i=0..m} (q_{2i+1} - q_{2i})^4.

The state is in HLW's rotated variables (I.5.2): x_{0,i} = (q_{2i} + q_{2i-1})/sqrt 2 (the
mean position of stiff spring i), x_{1,i} = (q_{2i} - q_{2i-1})/sqrt 2 (its elongation), and
y the same of p; u = (x_{0,1..m}, x_{1,1..m}, y_{0,1..m}, y_{1,1..m}). Then

    H = |y|^2/2 + omega^2/2 sum_i x_{1,i}^2 + 1/4 sum_{k=0..m} d_k^4,
    d_k = x_{0,k+1} - x_{1,k+1} - x_{0,k} - x_{1,k}   (x_{.,0} = x_{.,m+1} = 0),

separable with unit masses. The stiff springs' oscillatory energies
I_j = (y_{1,j}^2 + omega^2 x_{1,j}^2)/2 exchange energy slowly; their sum I = I_1 + ... + I_m
stays within O(1/omega) of its initial value along the exact solution.
"""
from __future__ import annotations

import numba
import numpy as np

from longtime.core.params import Param
from longtime.core.problem import Problem, separable_rhs


@numba.njit(cache=True, inline="always")
def _add_grad_U(q, out):
    """out = dU/dq of the soft springs' U = sum_k d_k^4 / 4 (d_k as in the module)."""
    m = q.size // 2
    d3_prev = (q[0] - q[m]) ** 3  # d_0 = x_{0,1} - x_{1,1}
    for i in range(m):
        d = -q[i] - q[m + i]  # d_{i+1} = x_{0,i+2} - x_{1,i+2} - x_{0,i+1} - x_{1,i+1}
        if i + 1 < m:
            d += q[i + 1] - q[m + i + 1]
        d3 = d * d * d
        out[i] = d3_prev - d3
        out[m + i] = -d3_prev - d3
        d3_prev = d3


@numba.njit(cache=True)
def _grad_U(q, params, out):
    _add_grad_U(q, out)


@numba.njit(cache=True)
def _grad_V(q, params, out):
    _add_grad_U(q, out)
    m = q.size // 2
    w2 = params[0] * params[0]
    for i in range(m, 2 * m):
        out[i] += w2 * q[i]


@numba.njit(cache=True)
def _grad_T(p, params, out):
    for i in range(p.size):
        out[i] = p[i]


@numba.njit(cache=True)
def _frequencies(params, out):
    m = out.size // 2
    for i in range(m):
        out[i] = 0.0
        out[m + i] = params[0]


def _jax_rhs(t, u, params):
    """The rhs in jax.numpy (the diffrax peers): the soft springs' d_k padded with the fixed ends."""
    import jax.numpy as jnp

    n = u.size // 2
    m = n // 2
    x0 = jnp.pad(u[:m], 1)
    x1 = jnp.pad(u[m:n], 1)
    d3 = (x0[1:] - x1[1:] - x0[:-1] - x1[:-1]) ** 3  # d_0 .. d_m
    grad_v = jnp.concatenate([d3[:-1] - d3[1:], -d3[:-1] - d3[1:] + params[0] * params[0] * u[m:n]])
    return jnp.concatenate([u[n:], -grad_v])


class FPU(Problem):
    name = "fpu"
    summary = "Fermi-Pasta-Ulam-Tsingou with stiff springs (HLW I.5): oscillatory energy I near-conserved"
    check_class = "many-body"
    chaotic = True
    lyapunov_span = 2000.0
    parameters = {
        "m": Param(3, "number of stiff springs (2m masses)", int, minimum=1, maximum=10**4, role="physical"),
        "omega": Param(50.0, "frequency of the stiff springs", float, positive=True, role="physical"),
        "oscillatory_energy": Param(True, "measure I = I1 + ... + Im as the invariant I (a near-invariant: "
                                          "the exact solution keeps it to O(1/omega))", bool),
    }
    default_t_final = 200.0
    default_dt = 0.005
    # h omega = 1.5, 1.0, 0.5, 0.25, 0.1 at omega = 50, over 8000 fast periods: I's
    # conservation shows. No longer paper-scale cell: the motion is chaotic, so a reference
    # check to a later time runs heyoka in real128 as well
    sweep_dt = (0.03, 0.02, 0.01, 0.005, 0.002)
    sweep_t_final = 1000.0

    rhs = staticmethod(separable_rhs(_grad_T, _grad_V))
    jax_rhs = staticmethod(_jax_rhs)
    grad_T = staticmethod(_grad_T)
    grad_V = staticmethod(_grad_V)
    frequencies = staticmethod(_frequencies)
    grad_U = staticmethod(_grad_U)

    def blocks(self):
        """Each stiff spring's two masses: their positions (x_{0,i}, x_{1,i}, a rotation of
        q_{2i-1}, q_{2i}) and their momenta (y_{0,i}, y_{1,i})."""
        m = self.settings["m"]
        out = {}
        for i in range(m):
            out[f"q spring {i + 1}"] = [i, m + i]
            out[f"p spring {i + 1}"] = [2 * m + i, 3 * m + i]
        return out

    def initial_state(self):
        # HLW I.5.1: x_{0,1} = 1, y_{0,1} = 1, x_{1,1} = 1/omega, y_{1,1} = 1, the rest 0
        m, w = self.settings["m"], self.settings["omega"]
        u = np.zeros(4 * m)
        u[0], u[m], u[2 * m], u[3 * m] = 1.0, 1.0 / w, 1.0, 1.0
        return u

    def kernel_params(self):
        return np.array([self.settings["omega"]])

    def inverse_masses(self):
        return np.ones(self.dim // 2)

    def _parts(self, U):
        m = self.settings["m"]
        return U[:, :m], U[:, m:2 * m], U[:, 2 * m:3 * m], U[:, 3 * m:]

    def oscillatory_energies(self, U: np.ndarray) -> np.ndarray:
        """I_j = (y_{1,j}^2 + omega^2 x_{1,j}^2)/2, shape (n, m)."""
        w = self.settings["omega"]
        _, x1, _, y1 = self._parts(U)
        return 0.5 * (y1**2 + w**2 * x1**2)

    def hamiltonian(self, U: np.ndarray) -> np.ndarray:
        x0, x1, y0, y1 = self._parts(U)
        n = U.shape[0]
        zero = np.zeros((n, 1))
        a = np.hstack([x0, zero]) - np.hstack([x1, zero])  # x_{0,k+1} - x_{1,k+1}, k = 0..m
        b = np.hstack([zero, x0]) + np.hstack([zero, x1])  # x_{0,k} + x_{1,k}
        d = a - b
        w = self.settings["omega"]
        return (0.5 * np.sum(y0**2 + y1**2, axis=1) + 0.5 * w**2 * np.sum(x1**2, axis=1)
                + 0.25 * np.sum(d**4, axis=1))

    def invariants(self, t, U):
        out = {"H": self.hamiltonian(U)}
        if self.settings["oscillatory_energy"]:
            out["I"] = np.sum(self.oscillatory_energies(U), axis=1)
        return out

    def diagnostics(self, t, U):
        energies = self.oscillatory_energies(U)
        out = {f"I{j + 1}": energies[:, j] for j in range(energies.shape[1])}
        out["I"] = np.sum(energies, axis=1)
        return out

    def heyoka_system(self):
        import heyoka as hy

        m, w = self.settings["m"], self.settings["omega"]
        x0 = hy.make_vars(*[f"x0_{i}" for i in range(m)])
        x1 = hy.make_vars(*[f"x1_{i}" for i in range(m)])
        y0 = hy.make_vars(*[f"y0_{i}" for i in range(m)])
        y1 = hy.make_vars(*[f"y1_{i}" for i in range(m)])
        if m == 1:
            x0, x1, y0, y1 = [x0], [x1], [y0], [y1]
        # d_k for k = 0..m, then -dV/dx as in _add_grad_U
        d = []
        for k in range(m + 1):
            terms = []
            if k < m:
                terms += [x0[k] - x1[k]]
            if k > 0:
                terms += [-x0[k - 1] - x1[k - 1]]
            d.append(hy.sum(terms) if len(terms) > 1 else terms[0])
        d3 = [dk * dk * dk for dk in d]
        dy0 = [d3[i + 1] - d3[i] for i in range(m)]
        dy1 = [d3[i] + d3[i + 1] - w * w * x1[i] for i in range(m)]
        return list(x0) + list(x1) + list(y0) + list(y1), list(y0) + list(y1) + dy0 + dy1
