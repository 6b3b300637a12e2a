"""Robust Pade approximation via the SVD (Gonnet, Guttel, Trefethen, SIAM Review 55, 2013).

Written by hand: numpy and scipy have no robust Pade (``scipy.interpolate.pade`` is the
naive linear solve, which returns spurious pole-zero pairs (Froissart doublets) or fails
outright when the Toeplitz block is rank-deficient, e.g. for an even function or an
exactly rational input). This is the algorithm of chebfun's ``padeapprox``:

1. if c_0..c_m are negligible (below tol * ||c||), r = 0;
2. diagonal hopping: while the n x (n+1) Toeplitz block C (rows m+1..m+n) has numerical
   rank rho < n (singular values above tol * ||c||_2), set m <- m - (n - rho), n <- rho;
3. b = null vector of C, recomputed by a QR factorisation of (C D)^T with the reweighting
   D = diag(|b| + sqrt(eps)), which keeps exact zeros of b zero;
4. a = the first m+1 rows of the Toeplitz matrix times b;
5. trim leading zeros of b (and a), trailing zeros of b (below tol) and of a (below
   tol * ||c||), then normalise b_0 = 1.

The kernels are compiled and work in caller-provided scratch, because the Borel-Pade-Laplace
integrator calls them once per component and step: a small one-sided Jacobi SVD and a
Householder QR (the blocks are at most a few rows; LAPACK through numba costs several
microseconds per call on them, mostly in copies and allocation, which is the whole step
budget).
"""
from __future__ import annotations

import math

import numba
import numpy as np

DEFAULT_TOL = 1e-14
_EPS = np.finfo(float).eps
_SQRT_EPS = math.sqrt(_EPS)


def scratch_size(m: int, n: int) -> int:
    """Length of the float64 scratch ``robust_pade`` needs for degrees (m, n)."""
    k = n + 1
    return 3 * k * k + 4 * k


@numba.njit(cache=True)
def _jacobi_singular_values(A, rows, cols, d):
    """Singular values of A[:rows, :cols] (destroyed) into d[:cols], by one-sided (Hestenes)
    Jacobi: plane rotations of column pairs until all columns are orthogonal; the column
    norms are then the singular values (cols - rows of them zero when cols > rows).
    The squared norms are updated through each rotation and recomputed every sweep."""
    frob = 0.0
    for j in range(cols):
        for r in range(rows):
            frob += A[r, j] * A[r, j]
    # a column this small is numerically zero: rotating it against the others only
    # shuffles round-off and never converges
    negligible = _EPS * _EPS * frob
    for sweep in range(60):
        for j in range(cols):
            s = 0.0
            for r in range(rows):
                s += A[r, j] * A[r, j]
            d[j] = s
        rotated = False
        for i in range(cols - 1):
            for j in range(i + 1, cols):
                alpha = d[i]
                beta = d[j]
                if alpha <= negligible or beta <= negligible:
                    continue
                gamma = 0.0
                for r in range(rows):
                    gamma += A[r, i] * A[r, j]
                if abs(gamma) <= _EPS * math.sqrt(alpha * beta):
                    continue
                rotated = True
                zeta = (beta - alpha) / (2.0 * gamma)
                t = (1.0 if zeta >= 0.0 else -1.0) / (abs(zeta) + math.sqrt(1.0 + zeta * zeta))
                cs = 1.0 / math.sqrt(1.0 + t * t)
                sn = cs * t
                for r in range(rows):
                    x = A[r, i]
                    y = A[r, j]
                    A[r, i] = cs * x - sn * y
                    A[r, j] = sn * x + cs * y
                d[i] = alpha - t * gamma
                d[j] = beta + t * gamma
        if not rotated:
            break
    for j in range(cols):
        d[j] = math.sqrt(max(d[j], 0.0))


@numba.njit(cache=True)
def _fill_block(c, m, n, C):
    """C[i, j] = c[m + 1 + i - j] (zero for a negative index): rows m+1..m+n of the
    (m+n+1) x (n+1) Toeplitz matrix of the coefficients."""
    for i in range(n):
        for j in range(n + 1):
            k = m + 1 + i - j
            C[i, j] = c[k] if k >= 0 else 0.0


@numba.njit(cache=True)
def _numerical_rank(c, m, n, ts, C, norms):
    """Number of singular values of the n x (n+1) block above ts."""
    _fill_block(c, m, n, C)
    _jacobi_singular_values(C, n, n + 1, norms)
    smallest = 0
    for j in range(n + 1):
        if norms[j] < norms[smallest]:
            smallest = j
    rank = 0
    for j in range(n + 1):  # the n largest of the n+1 column norms are the singular values
        if j != smallest and norms[j] > ts:
            rank += 1
    return rank


@numba.njit(cache=True)
def _householder_null(M, rows, cols, H, betas, q):
    """Last column of the full Q of M[:rows, :cols] (rows = cols + 1) by Householder QR:
    the unit vector orthogonal to the columns of M. H and betas store the reflectors."""
    for j in range(cols):
        norm = 0.0
        for r in range(j, rows):
            norm += M[r, j] * M[r, j]
        norm = math.sqrt(norm)
        for r in range(rows):
            H[r, j] = 0.0
        if norm == 0.0:
            betas[j] = 0.0
            continue
        alpha = -norm if M[j, j] >= 0.0 else norm
        for r in range(j, rows):
            H[r, j] = M[r, j]
        H[j, j] -= alpha
        vv = 0.0
        for r in range(j, rows):
            vv += H[r, j] * H[r, j]
        betas[j] = 2.0 / vv if vv > 0.0 else 0.0
        for k in range(j, cols):
            s = 0.0
            for r in range(j, rows):
                s += H[r, j] * M[r, k]
            s *= betas[j]
            for r in range(j, rows):
                M[r, k] -= s * H[r, j]
    for r in range(rows):
        q[r] = 0.0
    q[rows - 1] = 1.0
    for j in range(cols - 1, -1, -1):  # Q e_last = H_0 H_1 ... H_{cols-1} e_last
        s = 0.0
        for r in range(j, rows):
            s += H[r, j] * q[r]
        s *= betas[j]
        for r in range(j, rows):
            q[r] -= s * H[r, j]


@numba.njit(cache=True)
def _inverse_frobenius(R, n, x):
    """||R^-1||_F of the upper triangle of R[:n, :n] (inf when singular); x: n scratch."""
    for i in range(n):
        if R[i, i] == 0.0:
            return np.inf
    total = 0.0
    for k in range(n):  # column k of R^-1 by back substitution; its entries below k are 0
        for i in range(k, -1, -1):
            acc = 1.0 if i == k else 0.0
            for j in range(i + 1, k + 1):
                acc -= R[i, j] * x[j]
            x[i] = acc / R[i, i]
            total += x[i] * x[i]
    return math.sqrt(total)


@numba.njit(cache=True)
def robust_pade(c, m, n, tol, a, b, scratch):
    """Robust [m/n] Pade approximant of the series sum_k c[k] x^k (uses c[0..m+n]).

    Writes the numerator into a[0..mu] and the denominator into b[0..nu] (b[0] = 1) and
    returns (mu, nu, hopped): the exact degrees (mu = -1 for the zero function) and
    whether the degrees were reduced because the Toeplitz block was rank-deficient
    (degrees can also drop by trimming zero coefficients, e.g. for an even function).
    ``scratch`` has at least ``scratch_size(m, n)`` entries; a and b at least m+1, n+1.
    """
    L = m + n + 1
    norm2 = 0.0
    norm_inf = 0.0
    for k in range(L):
        norm2 += c[k] * c[k]
        norm_inf = max(norm_inf, abs(c[k]))
    norm2 = math.sqrt(norm2)
    ts = tol * norm2
    head = 0.0
    for k in range(m + 1):
        head = max(head, abs(c[k]))
    if head <= tol * norm_inf:  # r = 0 (also the all-zero series)
        a[0] = 0.0
        b[0] = 1.0
        return -1, 0, False
    k1 = n + 1
    C = scratch[0:k1 * k1].reshape((k1, k1))
    M = scratch[k1 * k1:2 * k1 * k1].reshape((k1, k1))
    H = scratch[2 * k1 * k1:3 * k1 * k1].reshape((k1, k1))
    o = 3 * k1 * k1
    norms = scratch[o:o + k1]
    null = scratch[o + k1:o + 2 * k1]
    betas = scratch[o + 2 * k1:o + 3 * k1]
    q = scratch[o + 3 * k1:o + 4 * k1]
    n0 = n
    while n > 0:  # diagonal hopping across a square block of the Pade table
        # the null vector of C (the right singular vector of its zero singular value) is
        # the last column of the full Q of C^T = Q R
        for i in range(n):
            for j in range(n + 1):
                k = m + 1 + i - j
                M[j, i] = c[k] if k >= 0 else 0.0
        _householder_null(M, n + 1, n, H, betas, null)
        # shortcut, the same decision: sigma_min(C) = sigma_min(R) >= 1/||R^-1||_F, so
        # when that bound clears ts the rank is n without the SVD
        if _inverse_frobenius(M, n, norms) * ts < 1.0:
            break
        rank = _numerical_rank(c, m, n, ts, C, norms)
        if rank == n:
            break
        m = max(m - (n - rank), 0)
        n = rank
    hopped = n < n0
    if n == 0:
        for k in range(m + 1):
            a[k] = c[k]
        b[0] = 1.0
        nu = 0
    else:
        # reweighted QR of (C D)^T: its last Q column is the null vector of C D
        for i in range(n):
            for j in range(n + 1):
                k = m + 1 + i - j
                M[j, i] = (c[k] if k >= 0 else 0.0) * (abs(null[j]) + _SQRT_EPS)
        _householder_null(M, n + 1, n, H, betas, q)
        s = 0.0
        for j in range(n + 1):
            q[j] *= abs(null[j]) + _SQRT_EPS
            s += q[j] * q[j]
        s = math.sqrt(s)
        for j in range(n + 1):
            q[j] /= s
        for i in range(m + 1):  # a = Z[0:m+1, 0:n+1] b
            acc = 0.0
            for j in range(min(i, n) + 1):
                acc += c[i - j] * q[j]
            a[i] = acc
        lead = 0  # leading zeros of b: a common factor x^lead of a and b
        while lead < n and abs(q[lead]) <= tol:
            lead += 1
        last = n
        while last > lead and abs(q[last]) <= tol:
            last -= 1
        for j in range(lead, last + 1):
            b[j - lead] = q[j]
        nu = last - lead
        for i in range(lead, m + 1):
            a[i - lead] = a[i]
        m = m - lead
    mu = m
    while mu >= 0 and not abs(a[mu]) > ts:  # trailing zeros of a
        mu -= 1
    b0 = b[0]
    for i in range(mu + 1):
        a[i] /= b0
    for j in range(nu + 1):
        b[j] /= b0
    if mu < 0:
        a[0] = 0.0
    return mu, nu, hopped


@numba.njit(cache=True, inline="always")
def polynomial_and_derivative(c, degree, x):
    """(c(x), c'(x)) of sum_i c[i] x^i by Horner, for a polynomial of the given degree (-1: zero)."""
    value = 0.0
    slope = 0.0
    for i in range(degree, -1, -1):
        slope = slope * x + value
        value = value * x + c[i]
    return value, slope


@numba.njit(cache=True, inline="always")
def rational_and_derivative(a, mu, b, nu, x):
    """(r(x), r'(x)) of r = a/b by Horner, with a of degree mu (-1: zero) and b of degree nu."""
    p, dp = polynomial_and_derivative(a, mu, x)
    q, dq = polynomial_and_derivative(b, nu, x)
    r = p / q
    return r, (dp - r * dq) / q


def pade(coefficients, m: int, n: int, tol: float = DEFAULT_TOL):
    """Python entry point: (a, b) with r(x) = sum a_i x^i / sum b_j x^j, b[0] = 1.

    ``coefficients`` are c_0, c_1, ... (zero-padded to m+n+1 terms if shorter).
    """
    from longtime.core.params import InputError

    if int(m) != m or m < 0 or int(n) != n or n < 0:
        raise InputError(f"Pade degrees m={m!r}, n={n!r} are not valid: expected integers >= 0")
    if not tol >= 0:
        raise InputError(f"tol={tol!r} is not valid: expected a float >= 0")
    m, n = int(m), int(n)
    c = np.zeros(m + n + 1)
    given = np.asarray(coefficients, dtype=np.float64).ravel()[: m + n + 1]
    if not np.all(np.isfinite(given)):
        raise InputError("coefficients are not valid: must be finite")
    c[: given.size] = given
    a, b = np.zeros(m + 1), np.zeros(n + 1)
    mu, nu, _ = robust_pade(c, m, n, float(tol), a, b, np.zeros(scratch_size(m, n)))
    return a[: mu + 1].copy() if mu >= 0 else np.zeros(1), b[: nu + 1].copy()
