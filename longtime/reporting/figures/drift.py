"""``drift`` (an invariant's relative error, or a diagnostic's change, against t) and ``toda-eigenvalues`` (the Lax
eigenvalues against t): every curve integrated in the call."""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from longtime.core.params import InputError
from longtime.core.status import Status
from longtime.reporting.figures import plain_ticks, pyplot, run, save


def drift(out: Path, formats: Sequence[str] = ("png", "svg"), problems: list[str] | None = None,
          schemes: list[str] | None = None, dt: float | None = None, t_final: float | None = None,
          problem_settings: dict | None = None, invariant: str | None = None) -> list[Path]:
    """e_I(t) = |I(t) - I(0)| / |I(0)| (absolute where I(0) = 0) of the invariant ``invariant``
    (default: H, else the problem's first) against t for each scheme (default: the paper's
    Toda run, RK4 and RK4sym at dt = 0.1 to t = 5000), one panel per problem; a diagnostic's
    name draws its change the same way."""
    from longtime.core import registry
    from longtime.measure.metrics import relative_error
    from longtime.reporting.figures.style import styles

    problems = problems or ["toda"]
    schemes = schemes or ["rk4", "rk4sym"]
    colours = {s: st["color"] for s, st in styles(schemes).items()}  # no two schemes of the figure alike
    plt = pyplot()
    fig, axes = plt.subplots(len(problems), 1, figsize=(8, 3.8 * len(problems)), squeeze=False)
    for ax, name in zip(axes[:, 0], problems):
        drawn = invariant
        for i, scheme in enumerate(schemes):
            problem, traj = run(name, scheme, dt, t_final, problem_settings)
            found = problem.invariants(traj.t, traj.u)
            watched = problem.diagnostics(traj.t, traj.u)
            drawn = drawn or ("H" if "H" in found else next(iter(found), None))
            values = found.get(drawn) if drawn in found else watched.get(drawn)
            if values is None:
                known = ", ".join([*found, *watched]) or "none"
                raise InputError(f"--invariant {drawn}: problem '{name}' has no invariant or diagnostic of that "
                                 f"name (it has: {known})")
            err = relative_error(values)
            ok = err > 0
            step = dt if dt is not None else problem.default_dt
            has_dt = "dt" in registry.integrator_class(scheme).parameters
            label = scheme + (f" (dt={step:g})" if step and has_dt else "")
            if traj.status != Status.OK:
                label += f" [{traj.status} at t={traj.t_reached:.4g}]"
            # the first scheme on top: oscillating curves of later ones must not hide it
            ax.semilogy(traj.t[ok], err[ok], lw=0.6, label=label, color=colours[scheme], zorder=len(schemes) - i,
                        alpha=0.9 if i == 0 else 0.6)
        what = "relative error" if drawn not in watched else "relative change"
        ax.set_xlabel("t")
        ax.set_ylabel(f"{what} of {drawn}")
        ax.set_title(f"{problem.describe()}: {'drift' if drawn not in watched else 'change'} of {drawn}")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    plain_ticks(fig)
    fig.tight_layout()
    return save(fig, out, formats)


def toda_eigenvalues(out: Path, formats: Sequence[str] = ("png", "svg"), schemes: list[str] | None = None,
                     dt: float | None = None, t_final: float | None = None,
                     problem_settings: dict | None = None) -> list[Path]:
    """Eigenvalues of the Toda Lax matrix against t, one panel per scheme (default: RK4 and
    RK4sym, dt = 0.1, t = 5000); dashed: their initial values (exact invariants)."""
    schemes = schemes or ["rk4", "rk4sym"]
    plt = pyplot()
    fig, axes = plt.subplots(len(schemes), 1, figsize=(8, 3.4 * len(schemes)), squeeze=False, sharex=True)
    for ax, scheme in zip(axes[:, 0], schemes):
        problem, traj = run("toda", scheme, dt, t_final, problem_settings, max_samples=10_001)
        eig0 = problem.lax_eigenvalues(np.array([problem.t0]), problem.u0[None, :])[0]
        eig = problem.lax_eigenvalues(traj.t, traj.u)
        for k in range(eig.shape[1]):
            ax.plot(traj.t, eig[:, k], lw=0.7, color=f"C{k}", label=f"eig{k + 1}")
            ax.axhline(eig0[k], color=f"C{k}", ls="--", lw=0.6)
        step = dt if dt is not None else problem.default_dt
        ax.set_title(f"{scheme}, dt={step:g}: Lax eigenvalues (dashed: initial)")
        ax.set_ylabel("eigenvalue")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8, loc="upper right")
    axes[-1, 0].set_xlabel("t")
    plain_ticks(fig)
    fig.tight_layout()
    return save(fig, out, formats)
