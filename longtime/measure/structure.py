"""The structure of a scheme's step map, measured from the map itself on a canonical problem.

One step Phi_h of the scheme's own compiled step (``stability.one_step``: the loop its runs
use, from a fresh start; error control off for an adaptive scheme; an implicit scheme's
stage iteration with its own stopping rule, by default at round-off, so the measured loop is
the one the matrix's cells on that problem compiled already) is measured from the state u0
of the first ``CANONICAL`` problem the scheme can step, with the step ``STEP``:

- **Symplecticity defect** ||M^T J M - J||_2, M = dPhi_h/du0, J = [[0, I], [-I, 0]] for
  u = (q, p). The numba kernels are real, so M is taken by central differences (no complex
  step): column j is (Phi(u0 + d e_j) - Phi(u0 - d e_j)) / 2d at d = ``FD_STEP`` max(1, |u0_j|)
  at 2d and 4d; M = (4 M_d - M_2d) / 3 (Richardson's extrapolation: truncation O(d^4)). The
  stated error ``symplecticity_error`` bounds the defect's error by 2 ||M|| E + E^2, with E
  = ||M - M'||_F / 15 (M' the same extrapolation from 2d and 4d, whose O(d^4) error is 16
  times M's) plus 1.5 ``PHI_ULPS`` eps max|Phi| / d (round-off of the differences). A symplectic map has
  a defect within its error; ``SAFETY`` times the error is the tolerance of
  ``longtime.testing.assert_symplectic``.
- **Reversibility defect** |Phi_{-h}(Phi_h(u0)) - u0|_inf / max(1, |u0|_inf): a step of h,
  then one of -h (time symmetry). Its round-off is ``REVERSIBLE_ULPS`` eps (ulps of the
  state's largest component); a symmetric scheme's defect stays within it.
- **Invariants kept to round-off**: each invariant of the problem over ``INVARIANT_STEPS``
  steps of STEP; kept when its largest relative change stays at most ``KEPT``, a bound
  well above the round-off of that many steps (~1e-15) and well below the truncation error
  of any scheme of order up to 10 at STEP (>~1e-9).
"""
from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from longtime.core.cache import discard, write_atomic

EPS = float(np.finfo(float).eps)
CANONICAL = ("kepler", "henon-heiles", "harmonic")
STEP = 0.05
FD_STEP = 1e-4
PHI_ULPS = 16.0
SAFETY = 10.0
REVERSIBLE_ULPS = 64.0
INVARIANT_STEPS = 100
KEPT = 1e-12


@dataclass
class Structure:
    """What ``measure`` found for one scheme: the canonical problem and step, the
    symplecticity defect with its stated error, the reversibility defect with its
    round-off bound, the invariants kept to round-off (``kept``) with every invariant's
    largest relative change over INVARIANT_STEPS steps (``changes``), and ``reason`` (why
    nothing was measured; then every number is None)."""

    scheme: str
    problem: str | None = None
    h: float | None = None
    symplecticity_defect: float | None = None
    symplecticity_error: float | None = None
    reversibility_defect: float | None = None
    reversibility_bound: float | None = None
    changes: dict[str, float] = field(default_factory=dict)
    kept: list[str] = field(default_factory=list)
    reason: str | None = None

    @property
    def symplectic(self) -> bool | None:
        """The defect within SAFETY times its stated error (None: not measured)."""
        if self.symplecticity_defect is None:
            return None
        return bool(self.symplecticity_defect <= SAFETY * self.symplecticity_error)

    @property
    def reversible(self) -> bool | None:
        """The defect within its round-off (None: not measured; an adaptive scheme's loop
        steps forward only)."""
        if self.reversibility_defect is None:
            return None
        return bool(self.reversibility_defect <= self.reversibility_bound)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self) | {"symplectic": self.symplectic, "reversible": self.reversible}

    def __str__(self) -> str:
        if self.reason is not None:
            return f"{self.scheme}: structure not measured ({self.reason})"
        return (f"{self.scheme} on {self.problem}, one step h = {self.h:g}: symplecticity defect "
                f"{self.symplecticity_defect:.2e} (error <= {self.symplecticity_error:.1e}: "
                f"{'symplectic' if self.symplectic else 'not symplectic'}); {reversibility_text(self)}; "
                f"kept to round-off: {', '.join(self.kept) or 'none'}")


def reversibility_text(s: Any) -> str:
    """The reversibility part of a Structure (or its dict)."""
    get = s.get if isinstance(s, dict) else lambda k: getattr(s, k)
    if get("reversibility_defect") is None:
        return "reversibility not measured (an adaptive scheme's loop steps forward only)"
    ok = get("reversibility_defect") <= get("reversibility_bound")
    return (f"reversibility defect {get('reversibility_defect'):.2e} (round-off {get('reversibility_bound'):.1e}: "
            f"{'reversible' if ok else 'not reversible'})")


def _instance(scheme: Any):
    """The scheme as an instance to measure: its own settings (an implicit scheme's stopping
    rule included), error control off."""
    from longtime.core import registry, roles
    from longtime.core.integrator import Integrator
    from longtime.measure.stability import OFF

    if isinstance(scheme, str):
        cls, given = registry.integrator_class(scheme), {}
    elif isinstance(scheme, type) and issubclass(scheme, Integrator):
        cls, given = scheme, {}
    else:
        cls, given = type(scheme), {k: v for k, v in scheme.settings.items() if v is not None}
    # a series order chosen from the tolerance (taylor-adaptive) is kept at the default
    # tolerance's: error control off must not change the map's order
    chosen = cls(**given).settings
    given.update({k: chosen[k] for k in roles.with_role([cls], "order") if chosen.get(k) is not None})
    settings = {**given, **{k: OFF for k in roles.with_role([cls], "accuracy")}}
    settings.pop("dt", None)
    return cls(**settings)


def _problem(instance):
    from longtime.core import registry

    reasons = []
    for name in CANONICAL:
        problem = registry.problem_class(name)()
        why = instance.incompatibility(problem)
        if why is None:
            return problem, None
        reasons.append(why)
    return None, "; ".join(reasons)


def _jacobian(step, u0: np.ndarray, params: np.ndarray, h: float, d: float) -> tuple[np.ndarray, float]:
    """(central-difference Jacobian of the step at relative step d, max |Phi| seen)."""
    n = u0.size
    M = np.empty((n, n))
    top = 0.0
    for j in range(n):
        dj = d * max(1.0, abs(u0[j]))
        plus, minus = u0.copy(), u0.copy()
        plus[j] += dj
        minus[j] -= dj
        dj = (plus[j] - minus[j]) / 2  # the step as represented
        step(plus, params, h)
        step(minus, params, h)
        M[:, j] = (plus - minus) / (2 * dj)
        top = max(top, float(np.max(np.abs(plus))), float(np.max(np.abs(minus))))
    return M, top


def _change(before: Any, after: Any) -> float:
    a, b = np.asarray(before, float), np.asarray(after, float)
    scale = float(np.linalg.norm(a))
    diff = float(np.linalg.norm(b - a))
    return diff / scale if scale > 0 else diff


def measure(scheme: Any, *, h: float = STEP, problem: Any = None) -> Structure:
    """The structure of ``scheme`` (a registered name, a class or an instance) on the
    canonical problem (or ``problem``, a Problem instance) at step ``h``."""
    from longtime.measure.stability import Unmeasurable, one_step

    try:
        instance = _instance(scheme)
    except Exception as exc:  # a scheme that cannot be built with error control off
        return Structure(getattr(scheme, "name", str(scheme)), reason=f"cannot build it to measure: {exc}")
    name = instance.name
    if problem is None:
        problem, why = _problem(instance)
        if problem is None:
            return Structure(name, reason=why)
    if problem.dim % 2 or problem.capabilities() & {"constraints"}:
        return Structure(name, problem.name, reason=f"{problem.name} is not a canonical Hamiltonian system")
    path = _cache_file(instance, problem, h)
    cached = _read(path) if path is not None else None
    if cached is not None:
        return cached
    try:
        step = one_step(instance, problem)
    except Unmeasurable as exc:
        return Structure(name, problem.name, reason=str(exc))
    found = _measure(name, instance, problem, step, h)
    if path is not None:
        write_atomic(path, json.dumps(asdict(found)).encode())
    return found


def _cache_file(instance, problem, h: float):
    """$LONGTIME_CACHE_DIR/structure/NAME-KEY.json, KEY a digest of the compiled step (its
    code and everything it closes over), the settings, the problem's state and the
    constants; None where the step has no fingerprint (it is then measured every time)."""
    from longtime.core.cache import cache_dir, digest
    from longtime.core.jitcache import fingerprint

    try:
        build = instance.make_step if hasattr(instance, "make_step") else instance.make_try_step
        code = fingerprint(build(problem))
    except Exception:
        return None
    key = digest(instance.name, repr(sorted(instance.settings.items())), code, problem.name,
                 repr(np.asarray(problem.u0).tolist()), repr(problem.params.tolist()),
                 repr((h, FD_STEP, PHI_ULPS, REVERSIBLE_ULPS, INVARIANT_STEPS, KEPT, 1)))
    return cache_dir("structure") / f"{instance.name}-{key}.json"


def _read(path) -> Structure | None:
    try:
        return Structure(**json.loads(path.read_bytes()))
    except FileNotFoundError:
        return None
    except (OSError, ValueError, TypeError) as exc:  # a truncated or foreign file: measured again
        discard(path, "structure", exc)
        return None


def _measure(name: str, instance, problem, step, h: float) -> Structure:
    from longtime.core.stepping import FixedStepIntegrator

    params, u0 = problem.params, np.array(problem.u0, dtype=float)
    n = u0.size // 2
    J = np.block([[np.zeros((n, n)), np.eye(n)], [-np.eye(n), np.zeros((n, n))]])

    u1 = u0.copy()
    if not step(u1, params, h) or not np.all(np.isfinite(u1)):
        return Structure(name, problem.name, h, reason=f"one step of h = {h:g} failed on {problem.name}")
    (M1, top1), (M2, top2), (M4, top4) = (_jacobian(step, u0, params, h, k * FD_STEP) for k in (1, 2, 4))
    M, M_coarse = (4 * M1 - M2) / 3, (4 * M2 - M4) / 3
    E = float(np.linalg.norm(M - M_coarse)) / 15 + 1.5 * PHI_ULPS * EPS * max(top1, top2, top4, 1.0) / FD_STEP
    defect = float(np.linalg.norm(M.T @ J @ M - J, 2))
    error = 2 * float(np.linalg.norm(M, 2)) * E + E * E

    reversibility, bound = None, None
    if isinstance(instance, FixedStepIntegrator):  # an adaptive loop steps forward only
        back = u1.copy()
        step(back, params, -h)
        scale = max(1.0, float(np.max(np.abs(u0))), float(np.max(np.abs(u1))))
        reversibility, bound = float(np.max(np.abs(back - u0))) / scale, REVERSIBLE_ULPS * EPS

    u, states = u0.copy(), [u0.copy()]
    for _ in range(INVARIANT_STEPS):
        if not step(u, params, h):
            break
        states.append(u.copy())
    U = np.array(states)
    t = problem.t0 + h * np.arange(len(states))
    changes = {}
    for key, values in problem.invariants(t, U).items():
        values = np.asarray(values, float)
        changes[key] = max(_change(values[0], values[k]) for k in range(1, len(values)))
    kept = [k for k, c in changes.items() if c <= KEPT]
    return Structure(name, problem.name, h, defect, error, reversibility, bound, changes, kept)
