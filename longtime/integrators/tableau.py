"""Consistency checks of Butcher tableaus, run when a tableau class is defined.

A tableau family (explicit, implicit, embedded Runge-Kutta) calls ``check_tableau`` from
``__init_subclass__``: a class whose coefficients do not fit together raises
``TableauError`` at import, so its plugin is reported as broken by ``longtime list`` (with
this message) instead of running a kernel that reads past its arrays.
"""
from __future__ import annotations

import numba
import numpy as np

from longtime.core.contract import ContractError
from longtime.core.drivers import compensated_add

TOL = 1e-12  # coefficient sums are exact up to a few roundings of O(1) numbers


class TableauError(ContractError):
    """A Butcher tableau whose arrays are inconsistent."""


def _vector(owner: str, name: str, value) -> np.ndarray:
    x = np.asarray(value, dtype=float)
    if x.ndim != 1 or x.size == 0:
        raise TableauError(f"{owner}: {name} must be a non-empty 1-D array, got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise TableauError(f"{owner}: {name} has non-finite entries")
    return x


def check_tableau(owner: str, A, b, c, *, explicit: bool, e=None, fsal: bool = False) -> None:
    """Raise TableauError unless (A, b, c[, e]) is a consistent s-stage tableau: A is s x s,
    b and c have s entries, sum(b) = 1, the row sums of A equal c, A is strictly lower
    triangular when ``explicit``; an error-weight vector ``e`` (b minus the embedded
    weights) has s entries summing to 0; ``fsal`` needs A's last row = b and c_s = 1."""
    b, c = _vector(owner, "b (weights)", b), _vector(owner, "c (nodes)", c)
    A = np.asarray(A, dtype=float)
    s = b.size
    if A.shape != (s, s) or c.size != s:
        raise TableauError(f"{owner}: inconsistent shapes: A {A.shape}, b ({b.size},), c ({c.size},); "
                           f"an s-stage tableau needs A (s, s), b (s,), c (s,)")
    if not np.all(np.isfinite(A)):
        raise TableauError(f"{owner}: A has non-finite entries")
    if abs(b.sum() - 1.0) > TOL:
        raise TableauError(f"{owner}: weights b sum to {float(b.sum())!r}, not 1 (the scheme would "
                           f"not be consistent)")
    rows = A.sum(axis=1)
    bad = np.flatnonzero(np.abs(rows - c) > TOL * np.maximum(1.0, np.abs(c)))
    if bad.size:
        i = int(bad[0])
        raise TableauError(f"{owner}: row {i} of A sums to {float(rows[i])!r} but c[{i}] = {float(c[i])!r} "
                           f"(row sums of A must equal c)")
    if explicit and np.any(np.triu(A) != 0.0):
        i, j = (int(k[0]) for k in np.nonzero(np.triu(A)))
        raise TableauError(f"{owner}: A[{i}, {j}] = {float(A[i, j])!r} but an explicit tableau needs A "
                           f"strictly lower triangular")
    if e is not None:
        e = _vector(owner, "e (error weights)", e)
        if e.size != s:
            raise TableauError(f"{owner}: e has {e.size} entries for {s} stages")
        if abs(e.sum()) > TOL:
            raise TableauError(f"{owner}: error weights e sum to {float(e.sum())!r}, not 0 (e = b - b_hat "
                               f"of two consistent weight vectors)")
    if fsal and (c[-1] != 1.0 or np.any(np.abs(A[-1] - b) > TOL)):
        raise TableauError(f"{owner}: fsal needs the last stage at c = 1 with A's last row equal to b")


def checked_on_definition(cls, *, explicit: bool, error_weights: bool = False) -> None:
    """Check ``cls``'s tableau if it defines one (a family's abstract base does not)."""
    if not all(hasattr(cls, k) for k in ("A", "b", "c")):
        return
    check_tableau(f"{cls.__module__}.{cls.__qualname__}", cls.A, cls.b, cls.c, explicit=explicit,
                  e=cls.e if error_weights else None, fsal=bool(getattr(cls, "fsal", False)))


@numba.njit(cache=True, inline="always")
def add_weighted_slopes(u, h, b, work, compensated, comp):
    """The last line of every Runge-Kutta step: u += h sum_i b_i k_i, the slopes k_i in the
    rows of ``work``, rounded once per step with Kahan's summation (``comp``) when the
    scheme's ``compensated`` setting asks for it."""
    for m in range(u.size):
        acc = 0.0
        for i in range(b.size):
            acc += b[i] * work[i, m]
        if compensated:
            compensated_add(u, m, h * acc, comp, m)
        else:
            u[m] += h * acc
