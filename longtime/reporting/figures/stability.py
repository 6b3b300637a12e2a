"""The ``stability`` kind of ``longtime plot``: stability regions measured from each
scheme's own step (``longtime.measure.stability``).

Left: the region |R(z)| <= 1 in the complex plane z = lambda h, one step of the scheme on
the test problem ``linear-test``; right: |R(iy)| on the imaginary axis (the rotation), whose
interval [0, Y] caps the step on oscillatory problems. Series schemes (``order`` is a
parameter) are drawn at each N given by ``--set order=4,8,...`` (default: N = 10), as the
fixed-order sum. A scheme that cannot step the test problem (it needs a separable
Hamiltonian, constraints, a linear part) has only the axis panel or a note. Where a step is
not linear (BPL), the region takes the worst of ``phases`` (12) starting phases, the axis
curve the worst of ``stability.PHASES`` (48). A step that fails (an implicit solve that
does not converge) counts as unstable: the region's edge is then where the solve fails.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

import numpy as np

from longtime.core.params import InputError

DEFAULT_SCHEMES = ("euler", "rk4", "verlet", "gauss4", "rk45", "bpl")
RE = (-6.0, 2.0)
IM = (0.0, 6.0)  # R(conj z) = conj R(z) for a real scheme: the lower half is the mirror


def _orders(scheme: str, settings: dict[str, Any] | None) -> list[int | None]:
    from longtime.core import registry

    if "order" not in registry.integrator_class(scheme).parameters:
        return [None]
    text = str((settings or {}).get("order", "10"))
    try:
        return [int(x) for x in text.replace(";", ",").split(",") if x.strip()]
    except ValueError:
        raise InputError(f"--set order={text!r}: expected comma-separated integers N") from None


def stability_regions(out: str | Path = "stability", formats: Sequence[str] = ("png", "svg"),
                      schemes: Sequence[str] | None = None, problem_settings: dict[str, Any] | None = None,
                      resolution: int = 81, phases: int = 12) -> list[Path]:
    """Draw the regions and the imaginary-axis growth of ``schemes`` (default: euler, rk4,
    verlet, gauss4, rk45, bpl); ``problem_settings`` carries ``order`` (N of series schemes)."""
    from longtime.core import registry
    from longtime.measure.stability import (
        Unmeasurable,
        format_interval,
        imaginary_growth,
        imaginary_interval,
        region,
    )
    from longtime.reporting.figures import plain_ticks, pyplot, save

    plt = pyplot()

    schemes = list(schemes or DEFAULT_SCHEMES)
    registry.check_names("integrator", schemes) if hasattr(registry, "check_names") else None
    from longtime.reporting.figures.style import styles

    colours = {s: st["color"] for s, st in styles(schemes).items()}  # no two schemes of the figure alike
    xs = np.linspace(*RE, int(resolution * (RE[1] - RE[0]) / (IM[1] - IM[0]) / 2) * 2 + 1)
    ys = np.linspace(*IM, resolution)
    axis = np.linspace(0.01, 8.0, 800)
    fig, (left, right) = plt.subplots(1, 2, figsize=(12.5, 4.8), gridspec_kw={"width_ratios": [1.25, 1]})
    notes = []
    ls_cycle = ("-", "--", ":", "-.")
    for scheme in schemes:
        colour = colours[scheme]
        for k, order in enumerate(_orders(scheme, problem_settings)):
            label = scheme + ("" if order is None else f" N={order}")
            ls = ls_cycle[k % len(ls_cycle)]
            try:
                g = region(scheme, xs, ys, order, phases=phases)
                full = np.vstack([g[::-1], g[1:]])  # mirror to the lower half plane
                im_full = np.concatenate([-ys[::-1], ys[1:]])
                left.contour(xs, im_full, np.where(np.isfinite(full), full, 1e3), levels=[1.0],
                             colors=[colour], linestyles=[ls], linewidths=1.4)
            except Unmeasurable as exc:
                notes.append(f"{label}: no region ({exc})")
            try:
                growth = imaginary_growth(scheme, axis, order)
                interval = format_interval(imaginary_interval(scheme, order))
                right.semilogy(axis, np.where(np.isfinite(growth), growth, np.nan),
                               color=colour, ls=ls, lw=1.1, label=f"{label}: {interval}")
            except Unmeasurable as exc:
                notes.append(f"{label}: {exc}")
    left.axhline(0, color="0.5", lw=0.6)
    left.axvline(0, color="0.5", lw=0.6)
    left.set_xlim(*RE)
    left.set_ylim(-IM[1], IM[1])
    left.set_aspect("equal")
    left.set_xlabel("Re z (z = lambda h)")
    left.set_ylabel("Im z")
    left.set_title("|R(z)| = 1, one step on u' = lambda u (stable inside; colours as on the right)",
                   fontsize=10)
    left.grid(True, alpha=0.3)
    right.axhline(1.0, color="k", lw=0.7)
    right.set_ylim(0.5, 2.0)
    right.set_xlabel("y (= omega h)")
    right.set_ylabel("|R(iy)| (growth of a mode per step)")
    right.set_title("imaginary axis: stable while |R(iy)| <= 1 (legend: that interval of y)", fontsize=10)
    right.grid(True, which="both", alpha=0.3)
    right.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0), frameon=False)
    if notes:
        fig.text(0.01, -0.02, "\n".join(notes), fontsize=7, va="top")
    plain_ticks(fig)
    fig.tight_layout()
    return save(fig, out, formats)
