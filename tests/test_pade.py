"""Robust Pade (longtime.numerics.pade) against closed forms, degree reduction and the SVD kernel."""
from __future__ import annotations

import math

import numpy as np
import pytest

from longtime.core.params import InputError
from longtime.numerics.pade import (
    _jacobi_singular_values,
    pade,
    rational_and_derivative,
    robust_pade,
    scratch_size,
)


def exp_pade(m, n):
    """Closed form of the [m/n] Pade approximant of exp."""
    f = math.factorial
    p = [f(m + n - j) * f(m) / (f(m + n) * f(j) * f(m - j)) for j in range(m + 1)]
    q = [(-1) ** j * f(m + n - j) * f(n) / (f(m + n) * f(j) * f(n - j)) for j in range(n + 1)]
    return np.array(p), np.array(q)


@pytest.mark.parametrize("m,n", [(1, 1), (2, 2), (4, 5), (5, 4), (3, 6), (6, 6)])
def test_exp_against_closed_form(m, n):
    c = [1.0 / math.factorial(k) for k in range(m + n + 1)]
    a, b = pade(c, m, n)
    p, q = exp_pade(m, n)
    assert a.size == m + 1 and b.size == n + 1
    np.testing.assert_allclose(a, p, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(b, q, rtol=1e-10, atol=1e-14)


def test_log1p_against_known_approximants():
    c = [0.0] + [(-1) ** (k + 1) / k for k in range(1, 12)]
    a, b = pade(c, 1, 1)  # x / (1 + x/2)
    np.testing.assert_allclose(a, [0.0, 1.0], atol=1e-15)
    np.testing.assert_allclose(b, [1.0, 0.5], atol=1e-15)
    a, b = pade(c, 2, 2)  # (x + x^2/2) / (1 + x + x^2/6)
    np.testing.assert_allclose(a, [0.0, 1.0, 0.5], atol=1e-14)
    np.testing.assert_allclose(b, [1.0, 1.0, 1.0 / 6.0], atol=1e-14)
    x = 0.7
    approx = np.polyval(a[::-1], x) / np.polyval(b[::-1], x)
    assert abs(approx - math.log1p(x)) < 2e-3


def test_degree_reduction_on_exactly_rational_input():
    # 1/(1+x): every [m/n] with m >= 0, n >= 1 is exactly [0/1]
    a, b = pade([(-1.0) ** k for k in range(10)], 4, 5)
    np.testing.assert_allclose(a, [1.0], atol=1e-14)
    np.testing.assert_allclose(b, [1.0, 1.0], atol=1e-14)
    # (1 + 2x) / (1 - x/3 + x^2/5): a [1/2] seen through [4/5]
    num, den = np.array([1.0, 2.0]), np.array([1.0, -1.0 / 3.0, 0.2])
    c = np.zeros(10)
    for k in range(10):  # series of num/den by the recurrence den * c = num
        c[k] = (num[k] if k < 2 else 0.0) - sum(den[j] * c[k - j] for j in range(1, min(k, 2) + 1))
    work = np.zeros(scratch_size(4, 5))
    a, b = np.zeros(5), np.zeros(6)
    mu, nu, reduced = robust_pade(c, 4, 5, 1e-14, a, b, work)
    assert (mu, nu, reduced) == (1, 2, True)
    np.testing.assert_allclose(a[:2], num, rtol=1e-12)
    np.testing.assert_allclose(b[:3], den, rtol=1e-12)


def test_even_functions():
    work = np.zeros(scratch_size(4, 5))
    a, b = np.zeros(5), np.zeros(6)
    # 1/(1 + x^2): the [4/5] Toeplitz block is rank-deficient; hopping lands on [0/2]
    c = np.array([0.0 if k % 2 else (-1.0) ** (k // 2) for k in range(10)])
    assert robust_pade(c, 4, 5, 1e-14, a, b, work) == (0, 2, True)
    np.testing.assert_allclose(a[:1], [1.0], atol=1e-14)
    np.testing.assert_allclose(b[:3], [1.0, 0.0, 1.0], atol=1e-14)
    # cos: the block has full rank, its null vector ends in a zero: trimmed to [4/4]
    c = [0.0 if k % 2 else (-1) ** (k // 2) / math.factorial(k) for k in range(10)]
    mu, nu, hopped = robust_pade(np.array(c), 4, 5, 1e-14, a, b, work)
    assert (mu, nu, hopped) == (4, 4, False)
    np.testing.assert_allclose(a[[0, 2, 4]], [1.0, -115.0 / 252.0, 313.0 / 15120.0], rtol=1e-12)
    np.testing.assert_allclose(b[[0, 2, 4]], [1.0, 11.0 / 252.0, 13.0 / 15120.0], rtol=1e-12)
    assert np.all(np.abs(a[[1, 3]]) < 1e-15) and np.all(np.abs(b[[1, 3]]) < 1e-15)  # zeros kept


def test_noisy_series_has_no_spurious_high_degree():
    rng = np.random.default_rng(7)
    c = np.array([1.0 / math.factorial(k) for k in range(21)]) + 1e-15 * rng.standard_normal(21)
    a, b = pade(c, 10, 10)
    assert b.size - 1 < 10  # degrees reduced: no Froissart doublets fitted to the noise
    x = 0.5
    assert abs(np.polyval(a[::-1], x) / np.polyval(b[::-1], x) - math.exp(x)) < 1e-12


def test_zero_series_and_input_errors():
    a, b = pade(np.zeros(10), 4, 5)
    np.testing.assert_array_equal(a, [0.0])
    np.testing.assert_array_equal(b, [1.0])
    with pytest.raises(InputError, match="degrees"):
        pade([1.0, 2.0], -1, 2)
    with pytest.raises(InputError, match="finite"):
        pade([1.0, np.nan], 1, 1)


def test_jacobi_singular_values_match_lapack():
    rng = np.random.default_rng(3)
    for rows, cols in [(5, 6), (3, 4), (6, 6)]:
        A = rng.standard_normal((rows, cols))
        A[:, 1] = A[:, 0] * 1e-9 + A[:, 2]  # a nearly dependent column
        d = np.zeros(cols)
        _jacobi_singular_values(A.copy(), rows, cols, d)
        expected = np.linalg.svd(A, compute_uv=False)
        np.testing.assert_allclose(np.sort(d)[::-1][:min(rows, cols)], expected, rtol=1e-10, atol=1e-14)


def test_rational_and_derivative():
    a, b = np.array([1.0, 2.0, 0.0]), np.array([1.0, -0.5])
    r, dr = rational_and_derivative(a, 1, b, 1, 0.3)
    assert r == pytest.approx((1 + 0.6) / (1 - 0.15), rel=1e-15)
    assert dr == pytest.approx((2 * 0.85 + 0.5 * 1.6) / 0.85**2, rel=1e-14)
