"""The region swept by the double pendulum up to several times, schemes side by side.

docs/problems.md, section 3 (the paper's plots of the region swept up to T = 10, 50, 100, Dirac-2 against
explicit Euler): one row per scheme, one column per time T; each panel shows the rods at
evenly spaced instants of [0, T] (light strokes: the swept region) and the paths of the
two bobs, with the circles of radius l1 and l1 + l2 for scale; ``space="angles"`` plots
(theta1, theta2) instead. A scheme that leaves the constraint manifold shows as bobs
leaving those circles. Every trajectory is computed by the scheme in this call.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Iterable, Sequence

import numpy as np

from longtime.core.params import InputError
from longtime.core.status import Status
from longtime.reporting.figures import check_formats, pyplot, run, save

DEFAULT_SCHEMES = ("dirac-2", "euler")
DEFAULT_TIMES = (10.0, 50.0, 100.0)
RODS_PER_PANEL = 1500  # instants drawn as rods: enough to fill the swept region
PATH_POINTS = 20_000  # points kept per bob path


def pendulum_region(schemes: Sequence[str] | None = None, dt: float | None = None,
                    times: Iterable[float] | None = None, t_final: float | None = None,
                    out: str | Path = "pendulum-region", problem_settings: dict[str, Any] | None = None,
                    space: str = "plane", formats: Sequence[str] = ("png", "svg")) -> list[Path]:
    """Draw the figure; write ``out``.png and ``out``.svg; return the paths written.

    The kind ``pendulum-region`` of ``longtime plot`` (longtime/plot.py passes schemes, dt,
    t_final, problem_settings, out, formats). schemes: registered scheme names, each run
    once to max(times) at step dt (default dirac-2 and euler at dt = 1e-4); times: the
    final times of the columns (default 10, 50, 100; with only t_final: t_final/10,
    t_final/2, t_final); problem_settings: double-pendulum parameters; space: "plane" or
    "angles".
    """
    from matplotlib.collections import LineCollection

    plt = pyplot()

    schemes = list(DEFAULT_SCHEMES) if not schemes else [schemes] if isinstance(schemes, str) else list(schemes)
    dt = 1e-4 if dt is None else float(dt)
    if times is None:
        times = DEFAULT_TIMES if t_final is None else (t_final / 10, t_final / 2, t_final)
    times = sorted({float(t) for t in times})
    if not dt > 0:
        raise InputError(f"dt={dt!r} is not valid: expected a time step > 0")
    if not times or times[0] <= 0:
        raise InputError(f"times={times!r} is not valid: expected final times > 0")
    if space not in ("plane", "angles"):
        raise InputError(f"space={space!r} is not valid: expected one of plane, angles")
    check_formats(formats)  # checked first: a bad format costs no integration
    runs = {}
    for name in schemes:
        problem, runs[name] = run("double-pendulum", name, dt, times[-1], problem_settings,
                                  max_samples=400_001)
    l1, l2 = problem.settings["l1"], problem.settings["l2"]

    fig, axes = plt.subplots(len(schemes), len(times), figsize=(3.4 * len(times), 3.4 * len(schemes)),
                             squeeze=False, constrained_layout=True)
    reach = l1 + l2
    for r, name in enumerate(schemes):
        traj = runs[name]
        for c, T in enumerate(times):
            ax = axes[r, c]
            keep = traj.t <= T * (1 + 1e-12)
            t, U = traj.t[keep], traj.u[keep]
            status = "" if traj.status == Status.OK or traj.t[-1] >= T else f" ({traj.status} at t={traj.t[-1]:.3g})"
            ax.set_title(f"{name}, T = {T:g}{status}", fontsize=10)
            if space == "angles":
                th1, th2 = problem.angles(U)
                step = max(1, t.size // PATH_POINTS)
                ax.plot(th1[::step], th2[::step], lw=0.3, color="C0", rasterized=True)
                ax.set_xlabel(r"$\theta_1$", parse_math=True)
                ax.set_ylabel(r"$\theta_2$", parse_math=True)
                continue
            step = max(1, t.size // RODS_PER_PANEL)
            x1, y1, x2, y2 = (U[::step, k] for k in range(4))
            rods = np.stack([np.stack([np.zeros_like(x1), np.zeros_like(y1)], 1),
                             np.stack([x1, y1], 1), np.stack([x2, y2], 1)], axis=1)
            ax.add_collection(LineCollection(rods, colors="0.6", linewidths=0.3, alpha=0.25,
                                             rasterized=True))
            step = max(1, t.size // PATH_POINTS)
            ax.plot(U[::step, 0], U[::step, 1], lw=0.4, color="C0", label="bob 1", rasterized=True)
            ax.plot(U[::step, 2], U[::step, 3], lw=0.4, color="C3", label="bob 2", rasterized=True)
            circle = np.linspace(0, 2 * np.pi, 400)
            for radius in (l1, reach):
                ax.plot(radius * np.cos(circle), radius * np.sin(circle), lw=0.6, ls="--", color="k",
                        zorder=0.5)
            bound = 1.15 * max(reach, float(np.max(np.hypot(U[:, 2], U[:, 3]))))
            ax.set_xlim(-bound, bound)
            ax.set_ylim(-bound, bound)
            ax.set_aspect("equal")
            ax.set_xticks([])
            ax.set_yticks([])
            if r == 0 and c == 0:
                ax.legend(loc="upper right", fontsize=7)
    changed = {k: v for k, v in problem.settings.items() if v != type(problem).parameters[k].default}
    extra = "".join(f", {k} = {v:g}" for k, v in changed.items())
    fig.suptitle(f"double pendulum: region swept, dt = {dt:g}{extra}", fontsize=10)
    return save(fig, out, formats)
