"""The problem contract (the whole plugin contract, as a checklist: docs/plugins.md).

A problem models only what its scene needs and says so by what it provides. Every
capability is an attribute that is ``None`` on this base class; a subclass provides it by
defining it. ``Problem.capabilities`` reads them off, and a scheme's ``requires`` is
matched against that set.

Compiled functions (numba ``njit``) take the state and a float64 ``params`` array and
write into ``out``; they never allocate. They are attached as ``staticmethod``s so that
schemes can close compiled loops over them.

    rhs(t, u, params, out)              u' = f(t, u)                    (required)
    grad_T(p, params, out)              dT/dp       } separable H = T(p) + V(q),
    grad_V(q, params, out)              dV/dq       } u = (q, p), q = u[:n], p = u[n:]
    jac(t, u, params, out)              df/du, out of shape (dim, dim)   ("jacobian")
    taylor(t0, u, params, coeffs, work) ("taylor") normalised Taylor coefficients of the
                                        solution through (t0, u): coeffs[k] = u^(k)(t0)/k!
                                        for k = 0..N, N = coeffs.shape[0] - 1 (row 0 = u);
                                        work: scratch of shape taylor_work_shape(N)
    frequencies(params, out)            ("oscillatory", with grad_U) H = |p|^2/2 +
    grad_U(q, params, out)              |Omega q|^2/2 + U(q): out = diag(Omega), shape (n,),
                                        and dU/dq (the slow force's negative), shape (n,)
    field_B(x, params, out)             ("lorentz", with field_E) a charged particle (unit
    field_E(x, params, out)             charge and mass) in space: u = (x, v), x, v in
                                        R^(3N), x_k'' = v_k x B(x_k) + E(x_k); out = B(x_k),
                                        E(x_k) at one position x_k, shape (3,) each

Python-level capabilities (vectorised over samples; ``U`` has shape (n, dim)):

    invariants(t, U) -> {name: (n,) or (n, k) array}     conserved quantities
    violations(t, U) -> {name: (n,) array}              non-negative residuals (constraints)
    diagnostics(t, U) -> {name: (n,) or (n, k) array}   quantities watched, not conserved
                                                        (FPU's mode energies): recorded and
                                                        drawn, never classed as a drift
    exact(t) -> U                                       exact solution at the times t,
                                                        through the state u0 as rounded
    exact_rtol                                          the relative accuracy of ``exact``
                                                        where it is not machine-level; None:
                                                        checked against heyoka in long
                                                        double (longtime.measure.reference)
    pde_solution(t) -> U                                the solution of the PDE that the
                                                        problem discretises, at the times t
                                                        (kdv's soliton): not the reference,
                                                        which is the system's own solution;
                                                        rows give its distance from it
                                                        (``discretisation_error``)
    blocks() -> {name: component indices}              the state's blocks, each measured
                                                        against its own motion (default:
                                                        each component its own block)
    heyoka_system() -> (vars, rhs expressions)          for the heyoka reference
    jax_rhs(t, u, params) -> u'                         ("jax_rhs") the rhs in jax.numpy (a
                                                        staticmethod that imports jax when
                                                        called), for the diffrax peers
    constraints, linear_part, nonlinear                 see the constrained and
                                                        exponential schemes

The ``constraints`` capability (holonomic constraints phi(q) = 0, state u = (q, p) with
n = dim/2 coordinates and p = M v; example: longtime/problems/double_pendulum.py) is an
object whose compiled functions are

    n_constraints                       m (0 < m < n)
    phi(q, params, out)                 out[a] = phi_a(q), shape (m,)
    grad_phi(q, params, out)            out[a, i] = d phi_a/d q_i, shape (m, n): rows of G
    mass(params, out)                   constant diagonal mass matrix, out[i] = M_ii, (n,)
    grad_U(q, params, out)              gradient of the potential, shape (n,)

and ``rhs`` stays the index-1 ODE (multipliers from phi'' = 0) for unconstrained schemes.
"""
from __future__ import annotations

import json
from abc import ABC, abstractmethod
from typing import Any, Callable, ClassVar

import numba
import numpy as np

from longtime.core.contract import CAPABILITIES, check_problem_definition
from longtime.core.params import Param, check_state, resolve
from longtime.core.status import BLOWUP as BLOWUP_MESSAGE  # noqa: F401 (its home; read from here too)


def separable_rhs(grad_T: Callable, grad_V: Callable) -> Callable:
    """Compiled rhs of a separable Hamiltonian: u = (q, p), u' = (grad T(p), -grad V(q))."""

    @numba.njit
    def rhs(t, u, params, out):
        n = u.size // 2
        grad_T(u[n:], params, out[:n])
        grad_V(u[:n], params, out[n:])
        for i in range(n, 2 * n):
            out[i] = -out[i]

    return rhs


def qp_blocks(objects: list[str], space_dim: int) -> dict[str, list[int]]:
    """The blocks (``Problem.blocks``) of a state u = (q, p) that holds, in the order of
    ``objects``, each object's ``space_dim`` coordinates in q and as many momenta in p: its
    position "q NAME" and its momentum "p NAME" for each object."""
    n = len(objects)
    out = {}
    for k, name in enumerate(objects):
        out[f"q {name}"] = list(range(k * space_dim, (k + 1) * space_dim))
        out[f"p {name}"] = list(range((n + k) * space_dim, (n + k + 1) * space_dim))
    return out


def whole_state(problem: "Problem") -> dict[str, list[int]]:
    """One block, the whole state (``Problem.blocks`` of a field or a single vector quantity)."""
    return {"u": list(range(problem.dim))}


class Problem(ABC):
    """Base class of every problem: the contract a new problem implements.

    A problem is a subclass registered under the entry-point group ``longtime.problems``
    (docs/plugins.md is the whole contract as a checklist; ``longtime.core.contract`` checks
    it when the class is defined, so a class that breaks it fails at import).

    A subclass must provide:

    - ``initial_state()``: the state u0 at ``t0``, a finite float64 vector (its size is
      ``dim``);
    - ``rhs(t, u, params, out)``: u' = f(t, u), a numba-compiled function attached as a
      ``staticmethod`` that writes into ``out`` and never allocates.

    It may provide:

    - the capabilities of the module docstring (``grad_T`` and ``grad_V``, ``jac``,
      ``taylor``, ``frequencies`` and ``grad_U``, ``field_B`` and ``field_E``,
      ``constraints``, ``jax_rhs``, ``heyoka_system``, ``exact``, ...): each is ``None`` here
      and provided by defining it; ``capabilities()`` reads them off, and a scheme's
      ``requires`` is matched against that set;
    - ``invariants``, ``violations`` and ``diagnostics``: quantities over the samples,
      vectorised (``U`` of shape (n, dim));
    - ``parameters``: ``{name: Param}``, the settings it takes (``self.settings`` holds them
      resolved), and ``setup()`` and ``kernel_params()`` to derive the float64 ``params``
      array the compiled functions receive;
    - ``blocks()``: the state's blocks, each measured against its own motion (default: each
      component; ``qp_blocks`` for bodies' positions and momenta, ``whole_state``);
    - the class attributes below: ``name`` and ``summary``, ``t0``, ``default_t_final`` and
      ``default_dt``, the default matrix's sweep, ``chaotic``, ``autonomous`` and the
      divergence bound (``blowup_factor``, or ``size_bound`` for a solution that grows).
    """

    name: ClassVar[str] = ""  # the registry sets it from the entry point when empty
    summary: ClassVar[str] = ""
    parameters: ClassVar[dict[str, Param]] = {}
    t0: ClassVar[float] = 0.0
    default_t_final: ClassVar[float] = 10.0
    default_dt: ClassVar[float] = 0.01
    # the default matrix sweep: time steps and final time
    sweep_dt: ClassVar[tuple[float, ...]] = ()
    sweep_t_final: ClassVar[float | None] = None
    # tolerances (tol, eps_res) of the default sweep below this are not run: their errors
    # would all read the reference's own accuracy (its floor), so they measure only cost
    sweep_min_tolerance: ClassVar[float | None] = None
    # the final time of one paper-scale cell per scheme that can afford it (its ``long_runs``)
    long_t_final: ClassVar[float | None] = None
    # False for a diagnostic problem (the linear test equation): `longtime matrix` and
    # `longtime warmup` run it only when it is named with -p
    in_default_matrix: ClassVar[bool] = True
    # a problem whose motion can be chaotic: its rows carry the Lyapunov time measured from
    # the reference (longtime.measure.lyapunov, over ``lyapunov_span``, default the default
    # final time) and each row's predictability horizon in Lyapunov times
    chaotic: ClassVar[bool] = False
    lyapunov_span: ClassVar[float | None] = None
    # for a ``chaotic`` problem whose default state is measured regular (no exponential
    # separation over ``lyapunov_span``): settings (``--set`` names to values) from which its
    # motion is measured chaotic; docs/problems.md gives the exponent, its interval and the
    # command. None: the default state itself is measured chaotic
    chaotic_settings: ClassVar[dict[str, Any] | None] = None
    # the class of question the main job's checks cover this problem as, where it is one whose
    # answers go wrong in a way of its own (longtime.execution.checks.CHECK_KINDS): "unstable
    # orbit", "close encounters", "discretised PDE", "many-body"; None: by its runs
    check_class: ClassVar[str | None] = None
    autonomous: ClassVar[bool] = True
    # |u|_1 above blowup_factor * max(1, |u0|_inf), or a non-finite component, is a
    # divergence (the 1-norm: a branch-free sum in the compiled drivers, which every
    # scheme shares through ``first_blowup``). A problem whose true solution grows gives
    # ``size_bound`` instead: the bound then follows it (see there).
    blowup_factor: ClassVar[float] = 1e10
    # the compiled drivers' constant bound when the bound follows ``size_bound``: only an
    # overflow stops the loop; the recorded samples are judged against the growing bound
    OVERFLOW_BOUND: ClassVar[float] = 1e250

    rhs: ClassVar[Callable | None] = None
    grad_T: ClassVar[Callable | None] = None
    grad_V: ClassVar[Callable | None] = None
    jac: ClassVar[Callable | None] = None
    exact: ClassVar[Callable | None] = None
    exact_rtol: ClassVar[float | None] = None
    pde_solution: ClassVar[Callable | None] = None
    heyoka_system: ClassVar[Callable | None] = None
    taylor: ClassVar[Callable | None] = None
    constraints: ClassVar[Any] = None
    linear_part: ClassVar[Any] = None
    nonlinear: ClassVar[Any] = None
    frequencies: ClassVar[Callable | None] = None
    grad_U: ClassVar[Callable | None] = None
    field_B: ClassVar[Callable | None] = None
    field_E: ClassVar[Callable | None] = None
    jax_rhs: ClassVar[Callable | None] = None

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        check_problem_definition(cls)  # a plugin that breaks the contract fails at import

    def __init__(self, **settings: Any) -> None:
        self.settings = resolve(self.parameters, settings, owner=f"problem '{self.name}'")
        self.setup()
        u0 = np.array(self.initial_state(), dtype=np.float64)
        check_state(f"initial state of problem '{self.name}'", u0)
        self.u0 = u0
        self.params = np.ascontiguousarray(self.kernel_params(), dtype=np.float64)

    def setup(self) -> None:
        """Derive whatever the settings imply (called before ``initial_state``)."""

    @abstractmethod
    def initial_state(self) -> np.ndarray: ...

    def kernel_params(self) -> np.ndarray:
        """Constants passed to the compiled functions as a float64 array."""
        return np.zeros(1)

    def inverse_masses(self) -> np.ndarray | None:
        """diag(M^-1) when T(p) = p.M^-1 p / 2 with M diagonal (None: T is general).

        An optional fast path: splitting schemes then drift q += a h M^-1 p without calling
        grad_T. grad_T must still be provided (it defines the "separable" capability).
        """
        return None

    def taylor_work_shape(self, order: int) -> tuple[int, ...]:
        """Scratch array shape for ``taylor`` at series order N (auxiliary series)."""
        return (1, self.dim)

    def invariants(self, t: np.ndarray, U: np.ndarray) -> dict[str, np.ndarray]:
        """Conserved quantities at the samples: {name: (n,) or (n, k)}."""
        return {}

    def violations(self, t: np.ndarray, U: np.ndarray) -> dict[str, np.ndarray]:
        """Residuals that should stay zero (constraints): {name: (n,)}."""
        return {}

    def diagnostics(self, t: np.ndarray, U: np.ndarray) -> dict[str, np.ndarray]:
        """Quantities worth watching that the exact flow does not conserve (energies that
        modes exchange by design): {name: (n,) or (n, k)}. Each row records how far each
        moved from its initial value and its curve; none is classed as a drift."""
        return {}

    def blocks(self) -> dict[str, list[int]]:
        """The state's blocks, {name: component indices}: the parts whose errors are measured
        each against its own motion (longtime.measure.metrics), so that a part that moves
        little beside the rest (a planet beside the outer solar system's 53 AU, a body's
        momentum m v beside its position) cannot hide its loss in the whole state's norm. A
        block is one quantity of one object in one unit (a body's position, its momentum; a
        field), so that no block's norm adds different units. Every component is in exactly
        one block. Default: each component its own block."""
        return {f"u[{i}]": [i] for i in range(self.dim)}

    def metrics_bytes(self, samples: int) -> int:
        """Peak bytes the metrics of ``samples`` recorded states allocate beside the samples
        (the reference's states, differences and norms, the invariants' values): the up-front
        size check (longtime.execution.sizes.check_size) counts them. A problem whose
        invariants allocate more per sample (toda's Lax matrices) says so here."""
        return 4 * samples * self.dim * 8

    @property
    def dim(self) -> int:
        return int(self.u0.size)

    def size_bound(self, t: np.ndarray) -> np.ndarray | None:
        """Optional, for a problem whose true solution grows: an upper bound on the 1-norm of
        the true state at the times ``t`` (from a first integral, say). A state above
        ``blowup_factor`` times it (at least 1) has diverged. None (the default): the bound is
        constant, ``blowup``."""
        return None

    @property
    def grows(self) -> bool:
        return type(self).size_bound is not Problem.size_bound

    @property
    def blowup(self) -> float:
        """The constant bound of the compiled drivers."""
        if self.grows:
            return self.OVERFLOW_BOUND
        return self.blowup_factor * max(1.0, float(np.max(np.abs(self.u0))))

    def first_blowup(self, U: np.ndarray, t: np.ndarray | None = None) -> int | None:
        """Index of the first state of U (n, dim) that blew up, or None: a non-finite one, or
        a 1-norm above ``blowup`` (as drivers.is_blown_up judges it) or, with the times ``t``
        of a problem that ``grows``, above blowup_factor * max(1, size_bound(t))."""
        bound = self.blowup
        if t is not None and self.grows:
            bound = np.minimum(bound, self.blowup_factor * np.maximum(1.0, self.size_bound(np.asarray(t, dtype=float))))
        bad = ~(np.sum(np.abs(U), axis=1) <= bound)
        return int(np.argmax(bad)) if bad.any() else None

    @classmethod
    def capabilities(cls) -> frozenset[str]:
        caps = {"rhs"}
        for cap, attrs in CAPABILITIES.items():
            if all(getattr(cls, a, None) is not None for a in attrs):
                caps.add(cap)
        if cls.invariants is not Problem.invariants:
            caps.add("invariants")
        if cls.autonomous:
            caps.add("autonomous")
        return frozenset(caps)

    def identity(self) -> str:
        """Canonical text of what defines the trajectory (for caches)."""
        return json.dumps({"problem": self.name, "settings": self.settings}, sort_keys=True)

    def describe(self) -> str:
        return f"{self.name}({', '.join(f'{k}={v}' for k, v in self.settings.items())})"
