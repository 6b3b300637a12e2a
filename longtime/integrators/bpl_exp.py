"""bpl-exp: Borel-Pade-Laplace on the nonlinear part, the linear part solved exactly.

A named variant of ``bpl`` (not the paper's algorithm) for u' = L u + N(t, u) with L
diagonal (the ``linear_part`` capability, as for etdrk4: the diagonal of L in the complex
view of the state, (Re, Im) pairs). One step from (t0, u0) sums the integrating-factor
variable v(s) = exp(-L s) u(t0 + s), which solves v' = exp(-L s) N(t0 + s, exp(L s) v),
v(0) = u0, with bpl's machinery (``bpl.make_try_step``: robust Pade of the Borel transform,
Gauss-Laguerre Laplace sum, residual-controlled step search, the same ``fallback``
setting), and maps the sum back: U(s) = exp(L s) V(s).

Why: on KdV, pure bpl's step is capped near 3 / max|omega| whatever eps_res, because its
amplification on the imaginary axis exceeds 1 past omega h of about 2.9 (N = 10) and the
top modes (omega = 428 at d = 128) are pumped up (``longtime.measure.stability.amplification``
measures it through the compiled step). Here the stiff rotation exp(L s) is exact and the
series sees only the slow nonlinear dynamics.

Taylor coefficients of v: the Cauchy product of the series of exp(-L s), whose
coefficients are (-L)^j / j!, with the problem's own series of u (``taylor``):
v_k = sum_{j<=k} (-L)^j / j! u_{k-j}. This is exact (v = exp(-L s) u along the true
solution), so no new capability is needed. The linear parts of the u_k cancel in the sum;
the rounding error that leaves in v_k is about eps |u_m| (2 |omega_m|)^k / k! per mode,
largest on the top modes, where |u_m| is at round-off already (KdV's soliton).

Residual: that of the original equation at the reconstructed state,
U' - L U - N(U) = exp(L s) V'(s) - N(t0 + s, U(s)) (the L U terms cancel exactly and are
not formed), so eps_res means the same as in bpl and the two schemes are compared at one
tolerance. For a skew L (KdV: pure rotations) exp(L s) is unitary and this is also the
residual of the transformed equation; for a dissipative L the transformed residual would
weigh the decayed stiff modes by exp(-L s), far above what they contribute to u.
"""
from __future__ import annotations

import math

import numba

from longtime.core.contract import pairs_incompatibility
from longtime.integrators.bpl import _O_LIN, BorelPadeLaplace


@numba.njit(cache=True)
def _interaction_coefficients(coeffs, lin):
    """In place: the Taylor coefficients u_k of u become those of v = exp(-L s) u,
    v_k = sum_{j<=k} (-L)^j / j! u_{k-j}, L = diag(lin) as complex (Re, Im) pairs.
    From the top order down, since v_k reads only u_0..u_k."""
    N = coeffs.shape[0] - 1
    for k in range(N, 0, -1):
        for i in range(0, coeffs.shape[1], 2):
            lr, li = -lin[i], -lin[i + 1]  # -L
            cr, ci = 1.0, 0.0  # (-L)^j / j!
            vr, vi = coeffs[k, i], coeffs[k, i + 1]
            for j in range(1, k + 1):
                cr, ci = (cr * lr - ci * li) / j, (cr * li + ci * lr) / j
                ur, ui = coeffs[k - j, i], coeffs[k - j, i + 1]
                vr += cr * ur - ci * ui
                vi += cr * ui + ci * ur
            coeffs[k, i], coeffs[k, i + 1] = vr, vi


@numba.njit(cache=True)
def _rotate_back(t, S, Sd, work):
    """``to_state`` of bpl-exp: U = exp(L t) V into S, and exp(L t) V' (= U' - L U) into Sd."""
    o = int(work[_O_LIN])
    for i in range(0, S.size, 2):
        g = math.exp(work[o + i] * t)
        er, ei = g * math.cos(work[o + i + 1] * t), g * math.sin(work[o + i + 1] * t)
        vr, vi = S[i], S[i + 1]
        S[i], S[i + 1] = er * vr - ei * vi, er * vi + ei * vr
        vr, vi = Sd[i], Sd[i + 1]
        Sd[i], Sd[i + 1] = er * vr - ei * vi, er * vi + ei * vr


class BorelPadeLaplaceExp(BorelPadeLaplace):
    name = "bpl-exp"
    summary = ("BPL variant: integrating factor exp(L t) for the diagonal linear part, "
               "Borel-Pade-Laplace for the rest; step by the residual of u' = L u + N(u)")
    requires = frozenset({"taylor", "linear_part"})

    def incompatibility(self, problem):
        return super().incompatibility(problem) or pairs_incompatibility(self.name, problem)

    def _linear_size(self, problem):
        return problem.dim

    def prepare_work(self, problem, work):
        super().prepare_work(problem, work)
        o = int(work[_O_LIN])
        problem.linear_part(problem.params, work[o:o + problem.dim])

    def _series(self, problem):
        taylor_series = super()._series(problem)

        @numba.njit
        def series(t, u, params, coeffs, work):
            taylor_series(t, u, params, coeffs, work)
            o = int(work[_O_LIN])
            _interaction_coefficients(coeffs, work[o:o + u.size])

        return series

    def _to_state(self, problem):
        return _rotate_back

    def _field(self, problem):
        return problem.nonlinear
