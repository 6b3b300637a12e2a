"""``duffing-phase``: phase portraits of the forced Duffing oscillator, one panel per
forcing amplitude (the paper's six, ``longtime.reporting.paper.DUFFING_C``)."""
from __future__ import annotations

import math
from pathlib import Path
from typing import Iterable, Sequence

from longtime.core.params import InputError
from longtime.core.status import Status
from longtime.reporting.figures import plain_ticks, pyplot, run, save
from longtime.reporting.paper import DUFFING_C


def duffing_phase(out: Path, formats: Sequence[str] = ("png", "svg"), schemes: list[str] | None = None,
                  dt: float | None = None, t_final: float | None = None,
                  problem_settings: dict | None = None, c_values: Iterable[float] = DUFFING_C,
                  t_start: float = 40.0) -> list[Path]:
    """Phase portraits (u, u') of the forced Duffing oscillator over t in [40, 1000], one panel
    per forcing amplitude c (the paper's six values), integrated by ``schemes[0]`` (rk4)."""
    from longtime.core import registry

    if "duffing-forced" not in registry.problems():
        raise InputError("plot kind 'duffing-phase' is not available: problem 'duffing-forced' is not registered")
    scheme = (schemes or ["rk4"])[0]
    c_values = list(c_values)
    cols = 3
    rows_n = math.ceil(len(c_values) / cols)
    plt = pyplot()
    fig, axes = plt.subplots(rows_n, cols, figsize=(4.2 * cols, 3.8 * rows_n), squeeze=False)
    for ax in axes.flat[len(c_values):]:
        ax.set_visible(False)
    for ax, c in zip(axes.flat, c_values):
        tf = t_final if t_final is not None else 1000.0
        _, traj = run("duffing-forced", scheme, dt, tf, {**(problem_settings or {}), "c": c}, max_samples=200_001)
        keep = traj.t >= min(t_start, 0.5 * tf)
        ax.plot(traj.u[keep, 0], traj.u[keep, 1], lw=0.25, color="C0", rasterized=True)
        status = "" if traj.status == Status.OK else f" [{traj.status}]"
        ax.set_title(f"c = {c:g}{status}")
        ax.set_xlabel("u")
        ax.set_ylabel("u'")
    step = dt if dt is not None else registry.problem_class("duffing-forced").default_dt
    fig.suptitle(f"forced Duffing: phase portraits over t in [{t_start:g}, {tf:g}] ({scheme}, dt={step:g})")
    plain_ticks(fig)
    fig.tight_layout()
    return save(fig, out, formats)
