"""Order conditions of schemes given by coefficients, and their residuals.

Runge-Kutta tableaus (A, b): the rooted-tree conditions of Butcher, b . Phi(t) = 1/gamma(t)
for every rooted tree t of order <= p (1, 1, 2, 4, 9, 20, 48, 115 trees of orders 1..8),
generated here by attaching a leaf to every node of the trees one order lower.

Splittings (kicks b_i, drifts a_i; a composition of Verlet steps is one, its kicks and
drifts from ``compose``): the step is the product of exponentials e^{b_1 h B} e^{a_1 h A}
... e^{b_s h B} e^{a_s h A} (A the drift's vector field, B the kick's). Its logarithm, the
modified vector field, is computed by the Baker-Campbell-Hausdorff series in the free
associative algebra on A and B, truncated at degree p; the scheme has order p exactly when
log = h (A + B) up to degree p. The conditions of order d are the coefficients of the Lyndon
words of length d in log - h (A + B) (a Lie polynomial is zero exactly when these are:
the Lyndon words index a basis of the free Lie algebra, the bracket of a word being its
standard bracketing, [A,[A,B]] for AAB): 2 of order 1 (sum a = 1, sum b = 1), 1 of order 2,
2 of order 3, 3 of order 4, 6 of order 5, 9 of order 6. This covers symmetric and
non-symmetric splittings and compositions alike, to any order (MAX_DEGREE).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

# a condition holds when its residual is below this (coefficients are printed to 15-20
# digits; sums of a few hundred products of O(1) numbers keep ~1e-13)
TOL = 1e-10
# the highest order whose conditions are computed (2^d words of degree d)
MAX_DEGREE = 10


@dataclass(frozen=True)
class Condition:
    order: int
    name: str
    residual: float

    @property
    def satisfied(self) -> bool:
        return abs(self.residual) <= TOL


# ------------------------------------------------------------------ rooted trees (Runge-Kutta)
def _canon(children) -> tuple:
    return tuple(sorted(children))


def _grow(tree: tuple):
    """Every tree one node larger: a leaf attached to each node of ``tree``."""
    yield _canon(tree + ((),))
    for i, child in enumerate(tree):
        for g in _grow(child):
            yield _canon(tree[:i] + (g,) + tree[i + 1:])


def trees(order: int) -> list[tuple]:
    """The rooted trees of ``order`` nodes, a tree as the sorted tuple of its subtrees."""
    level = {()}
    for _ in range(order - 1):
        level = {g for t in level for g in _grow(t)}
    return sorted(level, key=lambda t: (_depth(t), t))


def _depth(t: tuple) -> int:
    return 1 + max((_depth(c) for c in t), default=0)


def tree_order(t: tuple) -> int:
    return 1 + sum(tree_order(c) for c in t)


def density(t: tuple) -> int:
    """gamma(t): the tree's order times its subtrees' densities."""
    return tree_order(t) * math.prod(density(c) for c in t)


def tree_name(t: tuple) -> str:
    """Bracket notation: a leaf is t, [t, t] a root with two leaves."""
    return "t" if not t else "[" + ",".join(tree_name(c) for c in t) + "]"


def _stage_expr(t: tuple) -> str:
    leaves = sum(1 for c in t if not c)
    parts = ([("c" if leaves == 1 else f"c^{leaves}")] if leaves else [])
    for c in t:
        if c:
            inner = _stage_expr(c)
            parts.append("A" + (inner if inner.startswith("A") or " " not in inner else f"({inner})"))
    return " ".join(parts) if parts else "1"


def tree_condition(t: tuple) -> str:
    """The condition as a formula: sum b c^2 = 1/3, sum b A c = 1/6, ..."""
    expr = _stage_expr(t)
    return f"sum b{'' if expr == '1' else ' ' + expr} = {Fraction(1, density(t))}"


def _weight(t: tuple, A: np.ndarray) -> np.ndarray:
    """The stage vector of t: the product over its subtrees s of A . weight(s)."""
    out = np.ones(A.shape[0])
    for c in t:
        out = out * (A @ _weight(c, A))
    return out


def tableau_conditions(A, b, order: int) -> list[Condition]:
    """The residuals b . Phi(t) - 1/gamma(t) of every rooted tree of order 1..``order``."""
    A, b = np.asarray(A, dtype=float), np.asarray(b, dtype=float)
    order = min(int(order), 8)
    out = []
    for p in range(1, order + 1):
        for t in trees(p):
            out.append(Condition(p, f"{tree_name(t)}: {tree_condition(t)}",
                                 float(b @ _weight(t, A) - 1.0 / density(t))))
    return out


# ------------------------------------------------------------------ BCH (splittings)
# an element of the free associative algebra on A (0) and B (1), truncated at degree N: a
# list of arrays, entry d holding the coefficients of the 2^d words of length d (the word
# read as a binary number), so that the product of the degree-i and degree-j parts is their
# outer product, flattened
def _zero(n: int) -> list[np.ndarray]:
    return [np.zeros(2 ** d) for d in range(n + 1)]


def _mul(x, y, n: int) -> list[np.ndarray]:
    z = _zero(n)
    for i in range(n + 1):
        for j in range(n + 1 - i):
            if x[i].any() and y[j].any():
                z[i + j] += np.outer(x[i], y[j]).ravel()
    return z


def _exp_letter(letter: int, coef: float, n: int) -> list[np.ndarray]:
    z = _zero(n)
    for d in range(n + 1):
        z[d][0 if letter == 0 else 2 ** d - 1] = coef ** d / math.factorial(d)
    return z


def _log(x, n: int) -> list[np.ndarray]:
    """log(x) for x = 1 + (terms of degree >= 1), by the series of log(1 + X)."""
    X = [np.zeros(1)] + [v.copy() for v in x[1:]]
    out, power = _zero(n), _zero(n)
    power[0][0] = 1.0
    for k in range(1, n + 1):
        power = _mul(power, X, n)
        for d in range(n + 1):
            out[d] += (-1) ** (k + 1) / k * power[d]
    return out


def lyndon_words(length: int) -> list[str]:
    """The Lyndon words of ``length`` on A < B (smaller than each proper rotation)."""
    out = []
    for k in range(2 ** length):
        w = format(k, f"0{length}b").replace("0", "A").replace("1", "B")
        if all(w < w[i:] + w[:i] for i in range(1, length)):
            out.append(w)
    return out


def bracket(word: str) -> str:
    """The standard bracketing of a Lyndon word: w = u v with v its longest proper Lyndon
    suffix, [bracket(u), bracket(v)]."""
    if len(word) == 1:
        return word
    for i in range(1, len(word)):
        v = word[i:]
        if all(v < v[j:] + v[:j] for j in range(1, len(v))):
            return f"[{bracket(word[:i])},{bracket(v)}]"
    raise ValueError(word)  # a Lyndon word of length >= 2 always splits


def splitting_conditions(kicks, drifts, order: int) -> list[Condition]:
    """The coefficients of the Lyndon words of lengths 1..``order`` in the logarithm of the
    splitting's step minus h (A + B): each is 0 for a scheme of that order."""
    n = min(int(order), MAX_DEGREE)
    prod = _zero(n)
    prod[0][0] = 1.0
    for b, a in zip(np.asarray(kicks, dtype=float), np.asarray(drifts, dtype=float)):
        if b != 0.0:
            prod = _mul(prod, _exp_letter(1, b, n), n)
        if a != 0.0:
            prod = _mul(prod, _exp_letter(0, a, n), n)
    log = _log(prod, n)
    log[1] = log[1] - 1.0  # minus A + B
    out = []
    for d in range(1, n + 1):
        for w in lyndon_words(d):
            index = int(w.replace("A", "0").replace("B", "1"), 2)
            name = {"A": "sum of drifts = 1", "B": "sum of kicks = 1"}.get(w, f"{bracket(w)} (word {w})")
            out.append(Condition(d, name, float(log[d][index])))
    return out


# ------------------------------------------------------------------ the report
def describe(conditions: list[Condition], what: str) -> str:
    """The residuals, order by order, and the first condition not satisfied."""
    if not conditions:
        return ""
    first = next((c for c in conditions if not c.satisfied), None)
    top = max(c.order for c in conditions)
    orders = []
    for p in range(1, top + 1):
        here = [c for c in conditions if c.order == p]
        orders.append(f"order {p}: " + ", ".join(f"{c.name} {c.residual:+.2e}" for c in here))
    head = f"order conditions of {what} up to order {top} (residuals; |r| <= {TOL:g} holds): "
    verdict = (f"first not satisfied: order {first.order}, {first.name}, residual {first.residual:+.3e}"
               if first else "all satisfied")
    return head + "; ".join(orders) + "; " + verdict


def scheme_conditions(cls, order: int) -> tuple[list[Condition], str] | None:
    """The order conditions of a scheme class that carries coefficients (a tableau A, b; a
    splitting's kicks and drifts) and what they are; None for any other scheme."""
    if order is None or not (order >= 1):
        return None
    if hasattr(cls, "kicks") and hasattr(cls, "drifts"):
        return (splitting_conditions(cls.kicks, cls.drifts, order),
                "the splitting (Lyndon-word coefficients of log(step) - h(A+B), A drift, B kick)")
    if hasattr(cls, "A") and hasattr(cls, "b"):
        return (tableau_conditions(cls.A, cls.b, order),
                f"the Runge-Kutta tableau (rooted trees{', up to order 8' if order > 8 else ''})")
    return None
