"""Borel-Pade-Laplace (BPL): an adaptive series integrator with a residual-controlled step.

One step from (t0, u) (docs/schemes.md, ``bpl``):

1. Taylor coefficients u_0..u_N from the problem's recurrence (``taylor``);
2. per component, the Borel transform B(xi) = sum_{n<N} u_{n+1} xi^n / n!;
3. its robust [m/n] Pade approximant P (``longtime.numerics.pade``: SVD degree reduction, reweighted
   QR, zero trimming), computed in the scaled variable z = xi / lam, lam a power of two that
   balances the first and last nonzero coefficients (the SVD tolerance is relative, so the
   rank decisions should not depend on the time unit);
4. the Laplace sum S(t) = u_0 + t sum_k w_k P(t s_k) over Gauss-Laguerre nodes s_k and
   weights w_k (numpy's laggauss), and S'(t) = sum_k w_k [P(t s_k) + t s_k P'(t s_k)];
5. the residual r(t) = ||S'(t) - F(S(t), t0 + t)||_2; the step is the largest t (found to
   within 5 %) with r(t) <= eps_res, searched below the proposed step by log-log secant
   and bisection on the same approximants; the next proposal extrapolates r ~ t^N.

That is the whole of the paper's algorithm (``fallback="none"``, the default): an
approximant with a pole within reach of the nodes, or a non-finite sum, is not replaced;
the residual test sees the spoilt sum and the step shrinks. A step is never accepted on a
non-finite value: a non-finite residual or state counts as a failed trial t (that is the
residual test, not an extra safeguard). Where eps_res is below the rounding level of the
residual itself (64 eps ||F(S)||, e.g. once a growing state makes |F| ~ 1e12), a step
accepts that level instead of shrinking to underflow.

``fallback="taylor"`` is a named variant, not the paper's (counted in ``fallbacks``, per
accepted step, and reported as ``fallback_fraction`` = fallbacks / steps in every row):
when a component's Pade approximant cannot be trusted at the trial t, that component uses
its truncated Taylor sum sum_n u_n t^n instead, which is exactly what the quadrature
returns for the polynomial B itself (K nodes integrate degree <= 2K-1 exactly). Untrusted
means: non-finite Pade coefficients; a non-finite Laplace sum; or a pole on the positive
real axis within reach of the quadrature. Descartes' rule of signs on the denominator says
whether a positive pole can exist at all; if so, a sign change of the denominator between
consecutive nodes t s_k brackets one, and it is within reach when the terms w_k |P(t s_k)|
of the sum on either side of it exceed eps_res (a pole beyond the nodes that carry weight,
e.g. at s = 60 where w ~ 1e-25, moves the sum by far less than the tolerance). The residual
then judges the mixed sum like any other. On toda (eps_res 1e-3 to 1e-4) a third of the
steps of this variant are Taylor steps, and its energy error at a given mean step is far
below the paper's: it is another scheme, which is why it is opt-in.

A degenerate approximant (exact degrees below [m/n]: a rank-deficient Toeplitz block,
where the robust Pade lowers the degrees, or trimmed zero coefficients, as for an even
function; not the zero series of a component at rest) is not a fallback; such steps
count in ``pade_degenerate``.

The family: ``bpl_exp`` (``bpl-exp``) runs the same Pade, Laplace sum and step search on
the integrating-factor variables of u' = L u + N(u). The steps differ only in three
compiled hooks (``series``, ``to_state``, ``field``, see ``make_try_step``).
"""
from __future__ import annotations

import math

import numba
import numpy as np

from longtime.core.drivers import EXTRA1, EXTRA2, FALLBACKS, RHS_EVALS
from longtime.core.params import InputError, Param
from longtime.core.stepping import AdaptiveIntegrator
from longtime.numerics.pade import DEFAULT_TOL, polynomial_and_derivative, robust_pade, scratch_size
from longtime.numerics.series import header_view

# header of the flat work array: sizes and offsets, read by the compiled step
(_N, _M, _NDEN, _K, _DIM, _TOL, _EPS_RES, _TW0, _TW1, _TW2, _TW3, _O_COEF, _O_TW, _O_INVFACT,
 _O_NODES, _O_WEIGHTS, _O_CBUF, _O_A, _O_B, _O_MU, _O_NU, _O_LAM, _O_FLAG, _O_SCR, _O_S, _O_SD,
 _O_F, _O_BEST, _O_LIN, _HEADER) = range(30)

_SEARCH_EVALS = 12  # residual evaluations allowed in one step's search below the proposal
_SEARCH_REL = 0.05  # the search stops when the bracket [ok, too large] is this narrow
_GROW_MAX = 4.0  # largest growth of the proposal from one step to the next
_ROUNDING = 64 * np.finfo(float).eps  # rounding level of S' - F(S), relative to |F|
FALLBACKS_ALLOWED = ("none", "taylor")

# component flags: how far its Pade approximant can be trusted (_PADE_CHECK_POLES: only
# with the Taylor fallback, whose pole test it arms)
_PADE_OK, _PADE_CHECK_POLES, _PADE_BAD = 0, 1, 2


@numba.njit(cache=True)
def _balance_scale(c, L):
    """Power of two lam with |c_f| ~ |c_l| lam^(l-f), f/l the first/last nonzero index."""
    first, last = -1, -1
    for k in range(L):
        if c[k] != 0.0:
            if first < 0:
                first = k
            last = k
    if first < 0 or last == first:
        return 1.0
    e = (math.log2(abs(c[first])) - math.log2(abs(c[last]))) / (last - first)
    e = min(max(round(e), -60.0), 60.0)
    return 2.0 ** e


@numba.njit(cache=True)
def _prepare_pade(coeffs, work, counters, check_poles):
    """Robust Pade approximants of every component's Borel transform (once per step).
    A component with non-finite coefficients is flagged bad (its sum would be non-finite);
    ``check_poles`` (the Taylor fallback only) flags the approximants that may have a
    positive real pole (Descartes' rule on the denominator)."""
    N, m, n, dim = int(work[_N]), int(work[_M]), int(work[_NDEN]), int(work[_DIM])
    tol = work[_TOL]
    L = m + n + 1
    invfact = work[int(work[_O_INVFACT]):]
    cbuf = work[int(work[_O_CBUF]):int(work[_O_CBUF]) + N]
    scr = work[int(work[_O_SCR]):]
    o_a, o_b = int(work[_O_A]), int(work[_O_B])
    o_mu, o_nu, o_lam, o_flag = int(work[_O_MU]), int(work[_O_NU]), int(work[_O_LAM]), int(work[_O_FLAG])
    degenerate = False
    for i in range(dim):
        for k in range(L):
            cbuf[k] = coeffs[k + 1, i] * invfact[k]
        lam = _balance_scale(cbuf, L)
        scale = 1.0
        for k in range(L):
            cbuf[k] *= scale
            scale *= lam
        a = work[o_a + i * (m + 1):o_a + (i + 1) * (m + 1)]
        b = work[o_b + i * (n + 1):o_b + (i + 1) * (n + 1)]
        finite = True
        for k in range(L):
            if not math.isfinite(cbuf[k]):
                finite = False
        flag = _PADE_BAD
        mu, nu = -1, 0
        if finite:
            mu, nu, hopped = robust_pade(cbuf, m, n, tol, a, b, scr)
            # a zero series (an equilibrium component) is exact, not degenerate
            degenerate = degenerate or (mu >= 0 and (mu < m or nu < n))
            flag = _PADE_OK
            changes = 0
            previous = 1.0  # b[0] = 1
            for j in range(nu + 1):
                if not math.isfinite(b[j]):
                    flag = _PADE_BAD
                elif b[j] != 0.0:
                    if (b[j] > 0.0) != (previous > 0.0):
                        changes += 1
                    previous = b[j]
            for j in range(mu + 1):
                if not math.isfinite(a[j]):
                    flag = _PADE_BAD
            if check_poles and flag == _PADE_OK and changes > 0:
                flag = _PADE_CHECK_POLES  # Descartes: a positive real pole may exist
        work[o_mu + i] = mu
        work[o_nu + i] = nu
        work[o_lam + i] = lam
        work[o_flag + i] = flag
    if degenerate:
        counters[EXTRA2] += 1


@numba.njit(cache=True)
def _laplace_sum(t, u, coeffs, work, S, Sd, taylor_fallback):
    """S(t), S'(t) per component into S, Sd; returns True when some component fell back.
    Without ``taylor_fallback`` (the paper's algorithm) every sum is evaluated as it is, a
    bad approximant's as NaN (the value of a non-finite sum): the residual judges it."""
    N, m, n, K, dim = int(work[_N]), int(work[_M]), int(work[_NDEN]), int(work[_K]), int(work[_DIM])
    nodes = work[int(work[_O_NODES]):int(work[_O_NODES]) + K]
    weights = work[int(work[_O_WEIGHTS]):int(work[_O_WEIGHTS]) + K]
    o_a, o_b = int(work[_O_A]), int(work[_O_B])
    o_mu, o_nu, o_lam, o_flag = int(work[_O_MU]), int(work[_O_NU]), int(work[_O_LAM]), int(work[_O_FLAG])
    eps_res = work[_EPS_RES]
    fell_back = False
    for i in range(dim):
        flag = int(work[o_flag + i])
        usable = flag != _PADE_BAD
        if usable:
            mu, nu, lam = int(work[o_mu + i]), int(work[o_nu + i]), work[o_lam + i]
            a = work[o_a + i * (m + 1):o_a + (i + 1) * (m + 1)]
            b = work[o_b + i * (n + 1):o_b + (i + 1) * (n + 1)]
            s_acc = 0.0
            d_acc = 0.0
            positive = True  # sign of the denominator, b(0) = 1
            previous_term = 0.0
            for k in range(K):
                x = t * nodes[k]
                z = x / lam
                p, dp = polynomial_and_derivative(a, mu, z)
                q, dq = polynomial_and_derivative(b, nu, z)  # q's sign: the pole check below
                r = p / q
                if flag == _PADE_CHECK_POLES:
                    # a sign change of the denominator brackets a real pole; it is within
                    # reach when the terms of the sum on either side of it matter
                    term = weights[k] * abs(r)
                    if (q > 0.0) != positive:
                        if not term + previous_term <= eps_res:
                            usable = False
                            break
                        positive = q > 0.0
                    previous_term = term
                dr = (dp - r * dq) / (q * lam)  # dP/dxi
                s_acc += weights[k] * r
                d_acc += weights[k] * (r + x * dr)
            if not taylor_fallback or (usable and math.isfinite(s_acc) and math.isfinite(d_acc)):
                S[i] = u[i] + t * s_acc
                Sd[i] = d_acc
                continue
        elif not taylor_fallback:
            S[i] = Sd[i] = np.nan
            continue
        # the fallback variant: the truncated Taylor sum and its derivative
        fell_back = True
        S[i], Sd[i] = polynomial_and_derivative(coeffs[:, i], N, t)
    return fell_back


# -- the robust Pade, compiled once for every problem's kernel
# Called directly, _prepare_pade (and the robust Pade, SVD and rank decisions under it) is
# linked into each problem's kernel, and LLVM optimises and emits its code again every time
# (most of a bpl kernel's first compile: docs/performance.md). Instead it
# is compiled once as a C callback (a numba cfunc, disk-cached like the rest) and a kernel
# calls it by symbol name, an ExternalFunction that the JIT resolves when the kernel is
# compiled or loaded from the cache; ``_link_shared_code`` registers the symbol ahead of any
# kernel is built. The same machine code runs, once per step, and rounds the same (rows are
# bitwise those of the linked version). The Laplace sum, called at every trial of the step
# search and cheap to compile, stays linked, where LLVM optimises it with the residual.
_F64P, _INTP, _VOIDP = numba.types.CPointer(numba.types.float64), numba.types.intp, numba.types.voidptr
_PREPARE_SYMBOL = "longtime_bpl_prepare_pade_v1"
_PREPARE_SIG = numba.types.void(_F64P, _INTP, _INTP, _F64P, _INTP, numba.types.CPointer(numba.types.int64),
                                _INTP, _INTP)
_prepare_pade_external = numba.types.ExternalFunction(
    _PREPARE_SYMBOL, numba.types.void(_VOIDP, _INTP, _INTP, _VOIDP, _INTP, _VOIDP, _INTP, _INTP))
_linked: list[object] = []  # the registered cfunc (kept alive: the kernels call its address)


def _prepare_pade_c(p_coeffs, rows, dim, p_work, n_work, p_counters, n_counters, check_poles):
    _prepare_pade(numba.carray(p_coeffs, (rows, dim)), numba.carray(p_work, n_work),
                  numba.carray(p_counters, n_counters), check_poles != 0)


def _link_shared_code() -> None:
    """Compile (or load) the cfunc and register its symbol, once per process."""
    if not _linked:
        import llvmlite.binding as llvm

        compiled = numba.cfunc(_PREPARE_SIG, cache=True)(_prepare_pade_c)
        llvm.add_symbol(_PREPARE_SYMBOL, compiled.address)
        _linked.append(compiled)


@numba.njit(cache=True)
def _prepare_pade_shared(coeffs, work, counters, check_poles):
    """_prepare_pade through its cfunc (coeffs, work and counters are contiguous)."""
    _prepare_pade_external(coeffs.ctypes, coeffs.shape[0], coeffs.shape[1], work.ctypes, work.size,
                           counters.ctypes, counters.size, 1 if check_poles else 0)


@numba.njit(cache=True)
def _identity_map(t, S, Sd, work):
    """``to_state`` of bpl: the Laplace sum is the state."""


def make_try_step(series, to_state, field, taylor_fallback):
    """The compiled try_step of the BPL family, from three compiled hooks:

    series(t, u, params, coeffs, work)   Taylor coefficients of the summed variable
    to_state(t, S, Sd, work)             the Laplace sum (S, S') at local time t -> the
                                         state and the part of u' that ``field`` must match
    field(t, u, params, out)             what S' must equal (bpl: the rhs)

    The robust Pade, the Laplace sum and the residual-controlled step search are shared.
    ``taylor_fallback`` is a constant of the closure, so each setting gets its own kernel;
    N is read from the work array's header, so every N shares one.
    """
    _link_shared_code()

    @numba.njit
    def residual(t0, t, u, coeffs, params, work, counters):
        dim = u.size
        o_s, o_sd, o_f = int(work[_O_S]), int(work[_O_SD]), int(work[_O_F])
        S, Sd, F = work[o_s:o_s + dim], work[o_sd:o_sd + dim], work[o_f:o_f + dim]
        fell_back = _laplace_sum(t, u, coeffs, work, S, Sd, taylor_fallback)
        to_state(t, S, Sd, work)
        field(t0 + t, S, params, F)
        counters[RHS_EVALS] += 1
        counters[EXTRA1] += 1
        r = 0.0
        f2 = 0.0
        for i in range(dim):
            r += (Sd[i] - F[i]) ** 2
            f2 += F[i] * F[i]
            if not math.isfinite(S[i]):
                r = np.inf
        # relative to the attainable tolerance: eps_res, or the rounding level of
        # S' - F(S) where |F| is so large that eps_res is below it
        r = math.sqrt(r) / max(work[_EPS_RES], _ROUNDING * math.sqrt(f2))
        return (r if math.isfinite(r) else np.inf), fell_back

    @numba.njit
    def try_step(t, u, h, params, work, counters, u_new):
        dim = u.size
        eps = 1.0  # residuals come relative to the attainable tolerance
        N, oc = int(work[_N]), int(work[_O_COEF])
        coeffs = work[oc:oc + (N + 1) * dim].reshape((N + 1, dim))
        series(t, u, params, coeffs, work)
        _prepare_pade_shared(coeffs, work, counters, taylor_fallback)
        o_s, o_best = int(work[_O_S]), int(work[_O_BEST])
        S, best = work[o_s:o_s + dim], work[o_best:o_best + dim]

        r, fell_back = residual(t, h, u, coeffs, params, work, counters)
        if r <= eps:  # the proposal holds: take it, propose more next time
            for i in range(dim):  # element loops: a slice copy compiles a slow shape check
                u_new[i] = S[i]
            if fell_back:
                counters[FALLBACKS] += 1
            grow = _GROW_MAX if r == 0.0 else min(_GROW_MAX, max(1.0, (eps / r) ** (1.0 / N)))
            return 1, h, (np.inf if r == 0.0 else h * grow)
        # search below h: lo holds (r <= eps), hi does not
        lo, r_lo, hi, r_hi = 0.0, 0.0, h, r
        best_fell_back = False
        for it in range(_SEARCH_EVALS):
            if lo > 0.0 and hi - lo <= _SEARCH_REL * hi:
                break
            if lo > 0.0 and r_lo > 0.0 and math.isfinite(r_hi):
                p = max(math.log(r_hi / r_lo) / math.log(hi / lo), 1.0)
                trial = lo * (eps / r_lo) ** (1.0 / p)
            elif lo == 0.0 and math.isfinite(r_hi):
                trial = hi * (eps / r_hi) ** (1.0 / N)
            else:
                trial = 0.5 * (lo + hi)
            # keep the trial strictly inside the bracket, away from its ends
            trial = min(max(trial, lo + 0.1 * (hi - lo)), hi - 0.1 * (hi - lo))
            if lo == 0.0:
                trial = min(trial, 0.9 * hi)
            r, fell_back = residual(t, trial, u, coeffs, params, work, counters)
            if r <= eps:
                lo, r_lo, best_fell_back = trial, r, fell_back
                for i in range(dim):
                    best[i] = S[i]
            else:
                hi, r_hi = trial, r
        if lo == 0.0:  # nothing below h held: retry from scratch with a smaller step
            return 0, 0.0, 0.25 * hi
        for i in range(dim):
            if not math.isfinite(best[i]):
                return 0, 0.0, 0.5 * lo
        for i in range(dim):
            u_new[i] = best[i]
        if best_fell_back:
            counters[FALLBACKS] += 1
        return 1, lo, lo

    return try_step


class BorelPadeLaplace(AdaptiveIntegrator):
    name = "bpl"
    summary = ("Borel-Pade-Laplace: Taylor series, robust Pade of its Borel transform, "
               "Gauss-Laguerre Laplace sum; step by the ODE residual")
    requires = frozenset({"taylor"})
    order = None  # the series order N is a parameter
    parameters = {
        "order": Param(10, "series order N (Taylor coefficients u_0..u_N)", int, minimum=2, maximum=60,
                       role="order"),
        "pade_num": Param(None, "Pade numerator degree (default (N-1)//2)", int, minimum=0),
        "pade_den": Param(None, "Pade denominator degree (default N-1-pade_num)", int, minimum=0),
        "nodes": Param(20, "Gauss-Laguerre nodes of the Laplace sum", int, minimum=1, maximum=100),
        "eps_res": Param(1e-6, "residual tolerance ||S' - F(S)||_2 per step", float, positive=True,
                         role="accuracy", search=(1e-14, 1.0)),
        "pade_tol": Param(DEFAULT_TOL, "relative SVD tolerance of the robust Pade", float, minimum=0.0),
        "max_dt": Param(None, "largest step (default: the whole span)", float, positive=True),
        "fallback": Param("none", "untrusted Pade: none (the paper's algorithm: the residual judges "
                          "it) or taylor (a variant: that component takes its Taylor sum)", str,
                          choices=FALLBACKS_ALLOWED),
    }
    sweep = {"eps_res": (1e-4, 1e-6, 1e-8, 1e-10)}
    extra_counters = ("residual_evals", "pade_degenerate")

    def __init__(self, **settings):
        super().__init__(**settings)
        s = self.settings
        N = s["order"]
        m = s["pade_num"] if s["pade_num"] is not None else (
            (N - 1) // 2 if s["pade_den"] is None else N - 1 - s["pade_den"])
        n = s["pade_den"] if s["pade_den"] is not None else N - 1 - m
        if m < 0 or n < 0 or m + n + 1 > N:
            raise InputError(
                f"integrator '{self.name}': pade_num={m}, pade_den={n} are not valid for order={N}: "
                f"the [m/n] Pade approximant of the Borel transform needs m + n + 1 <= order "
                f"(its N coefficients u_1..u_N), m >= 0, n >= 0")
        self.degrees = (m, n)

    def _layout(self, problem):
        N, (m, n), K, dim = self.settings["order"], self.degrees, self.settings["nodes"], problem.dim
        tw_shape = tuple(int(x) for x in problem.taylor_work_shape(N))
        sizes = [
            ("coef", (N + 1) * dim), ("tw", int(np.prod(tw_shape))), ("invfact", N + 1),
            ("nodes", K), ("weights", K), ("cbuf", N + 1), ("a", dim * (m + 1)),
            ("b", dim * (n + 1)), ("mu", dim), ("nu", dim), ("lam", dim), ("flag", dim),
            ("scr", scratch_size(m, n)), ("S", dim), ("Sd", dim), ("F", dim), ("best", dim),
            ("lin", self._linear_size(problem)),
        ]
        offsets, o = {}, _HEADER
        for key, size in sizes:
            offsets[key] = o
            o += max(size, 1)
        return tw_shape, offsets, o

    def _linear_size(self, problem):
        """Length of the work slot of the linear part (bpl-exp); bpl has none."""
        return 0

    def work_shape(self, problem):
        return (self._layout(problem)[2],)

    def prepare_work(self, problem, work):
        N, (m, n), K = self.settings["order"], self.degrees, self.settings["nodes"]
        tw_shape, off, _ = self._layout(problem)
        work[[_N, _M, _NDEN, _K, _DIM]] = N, m, n, K, problem.dim
        work[_TOL], work[_EPS_RES] = self.settings["pade_tol"], self.settings["eps_res"]
        for i, s in enumerate(tw_shape):
            work[_TW0 + i] = s
        for i, key in enumerate(("coef", "tw", "invfact", "nodes", "weights", "cbuf", "a", "b", "mu",
                                 "nu", "lam", "flag", "scr", "S", "Sd", "F", "best", "lin")):
            work[_O_COEF + i] = off[key]
        work[off["invfact"]:off["invfact"] + N + 1] = [1.0 / math.factorial(k) for k in range(N + 1)]
        s, w = np.polynomial.laguerre.laggauss(K)
        work[off["nodes"]:off["nodes"] + K] = s
        work[off["weights"]:off["weights"] + K] = w

    def initial_step(self, problem, t_final):
        return min(float(problem.default_dt), self.max_step(problem, t_final))

    # -- the three hooks of the family (see make_try_step)
    def _series(self, problem):
        taylor = problem.taylor
        taylor_work = header_view(len(problem.taylor_work_shape(self.settings["order"])), _O_TW, _TW0)

        @numba.njit
        def series(t, u, params, coeffs, work):
            taylor(t, u, params, coeffs, taylor_work(work))

        return series

    def _to_state(self, problem):
        return _identity_map

    def _field(self, problem):
        return problem.rhs

    def make_try_step(self, problem):
        return make_try_step(self._series(problem), self._to_state(problem), self._field(problem),
                             self.settings["fallback"] == "taylor")

    def _integrate(self, problem, t_final, max_samples):
        traj = super()._integrate(problem, t_final, max_samples)
        # measured, for every variant: the share of accepted steps that used a Taylor sum
        steps = traj.steps
        traj.extra["fallback_fraction"] = traj.counters["fallbacks"] / steps if steps else None
        return traj
