"""Compiled building blocks of Taylor-series recurrences (automatic differentiation).

A series is a 1-D array of normalised coefficients a[k] = a^(k)(t0)/k!. Each function
returns (or writes) coefficient k of a derived series from coefficients 0..k of its inputs
and 0..k-1 of itself, so that a problem's ``taylor`` builds all its series order by order:
with the solution known up to order k, every auxiliary series gets its order-k coefficient,
then u[k+1] = f_k / (k+1). Nothing allocates; the auxiliary series live in the scratch
array the problem asks for with ``taylor_work_shape``.

Written by hand: these are the textbook recurrences (Moore; Jorba and Zou 2005, section 3),
a few lines each, and no maintained library offers them as compiled kernels over arrays.
"""
from __future__ import annotations

import math

import numba

from longtime.core.params import InputError


@numba.njit(cache=True, inline="always")
def product(a, b, k):
    """Coefficient k of a*b: the Cauchy product sum_{j=0..k} a[j] b[k-j]."""
    acc = 0.0
    for j in range(k + 1):
        acc += a[j] * b[k - j]
    return acc


@numba.njit(cache=True, inline="always")
def square(a, k):
    """Coefficient k of a*a, by symmetry with about half the products."""
    acc = 0.0
    for j in range((k + 1) // 2):
        acc += a[j] * a[k - j]
    acc *= 2.0
    if k % 2 == 0:
        acc += a[k // 2] * a[k // 2]
    return acc


@numba.njit(cache=True, inline="always")
def exp_coeff(a, e, k):
    """Coefficient k of e = exp(a), from e' = a' e: e_k = (1/k) sum_{j=1..k} j a_j e_{k-j}."""
    if k == 0:
        return math.exp(a[0])
    acc = 0.0
    for j in range(1, k + 1):
        acc += j * a[j] * e[k - j]
    return acc / k


@numba.njit(cache=True, inline="always")
def power_coeff(a, p, alpha, k):
    """Coefficient k of p = a^alpha (a[0] > 0), from a p' = alpha a' p:
    p_k = (1/(k a_0)) sum_{j=0..k-1} (alpha (k-j) - j) a_{k-j} p_j."""
    if k == 0:
        return a[0] ** alpha
    acc = 0.0
    for j in range(k):
        acc += (alpha * (k - j) - j) * a[k - j] * p[j]
    return acc / (k * a[0])


@numba.njit(cache=True, inline="always")
def sqrt_coeff(a, s, k):
    """Coefficient k of s = sqrt(a), from s*s = a: s_k = (a_k - sum_{j=1..k-1} s_j s_{k-j}) / (2 s_0)."""
    if k == 0:
        return math.sqrt(a[0])
    acc = 0.0
    for j in range(1, k):
        acc += s[j] * s[k - j]
    return (a[k] - acc) / (2.0 * s[0])


@numba.njit(cache=True, inline="always")
def divide_coeff(a, b, q, k):
    """Coefficient k of q = a/b, from q b = a: q_k = (a_k - sum_{j=0..k-1} q_j b_{k-j}) / b_0."""
    acc = a[k]
    for j in range(k):
        acc -= q[j] * b[k - j]
    return acc / b[0]


@numba.njit(cache=True, inline="always")
def cos_wt_coeff(cos_wt0, sin_wt0, w_pow_over_fact, k):
    """Coefficient k of cos(w (t0 + s)) in s: w^k/k! cos(w t0 + k pi/2), given w^k/k!."""
    r = k % 4
    if r == 0:
        return w_pow_over_fact * cos_wt0
    if r == 1:
        return -w_pow_over_fact * sin_wt0
    if r == 2:
        return -w_pow_over_fact * cos_wt0
    return w_pow_over_fact * sin_wt0


@numba.njit(cache=True, inline="always")
def horner(coeffs, h, out):
    """out = sum_k coeffs[k] h^k (the truncated series at step h), row by row."""
    n = coeffs.shape[0] - 1
    for i in range(coeffs.shape[1]):
        acc = coeffs[n, i]
        for k in range(n - 1, -1, -1):
            acc = acc * h + coeffs[k, i]
        out[i] = acc


def header_view(ndim: int, offset_slot: int, shape_slot: int):
    """Compiled ``view(work)``: the block of a flat work array that starts at
    work[offset_slot] with the shape work[shape_slot:shape_slot + ndim] (1 to 4 dimensions),
    as a scheme's ``prepare_work`` wrote them. The sizes are read at run time, not closed
    over, so one compiled kernel serves every series order N: compiled per N, a tolerance
    sweep of taylor-adaptive (N follows tol) cost a compile per tolerance."""
    if ndim == 1:
        @numba.njit(inline="always")
        def view(work):
            o = int(work[offset_slot])
            return work[o:o + int(work[shape_slot])]
    elif ndim == 2:
        @numba.njit(inline="always")
        def view(work):
            o, s0, s1 = int(work[offset_slot]), int(work[shape_slot]), int(work[shape_slot + 1])
            return work[o:o + s0 * s1].reshape((s0, s1))
    elif ndim == 3:
        @numba.njit(inline="always")
        def view(work):
            o, s0 = int(work[offset_slot]), int(work[shape_slot])
            s1, s2 = int(work[shape_slot + 1]), int(work[shape_slot + 2])
            return work[o:o + s0 * s1 * s2].reshape((s0, s1, s2))
    elif ndim == 4:
        @numba.njit(inline="always")
        def view(work):
            o, s0, s1 = int(work[offset_slot]), int(work[shape_slot]), int(work[shape_slot + 1])
            s2, s3 = int(work[shape_slot + 2]), int(work[shape_slot + 3])
            return work[o:o + s0 * s1 * s2 * s3].reshape((s0, s1, s2, s3))
    else:
        raise InputError(f"taylor_work_shape of {ndim} dimensions is not supported (1 to 4)")
    return view
