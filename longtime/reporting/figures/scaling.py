"""The scaling figure of ``longtime match --scaling``: CPU seconds against the size d at
each scheme's matched parameter, and BPL's cost (and error) against its series order N."""
from __future__ import annotations

from pathlib import Path

from longtime.core.status import Status
from longtime.reporting.figures import plain_ticks, pyplot, save


def scaling_figure(scaling, orders, problem: str, out_dir: Path, metric: str = "final_error") -> list[Path]:
    import numpy as np

    plt = pyplot()
    panels = 2 if orders else 1
    fig, axes = plt.subplots(1, panels, figsize=(5.5 * panels, 4.2), squeeze=False)
    ax = axes[0, 0]
    for scheme, per in scaling.items():
        pts = sorted((d, r["cpu_s"]) for d, r in per.items() if r["status"] == Status.OK and r.get("cpu_s"))
        if pts:
            ax.loglog(*zip(*pts), "o-", label=scheme)
    sizes = sorted({d for per in scaling.values() for d in per})
    if sizes:
        from matplotlib.ticker import NullFormatter

        ax.set_xticks(sizes, [str(d) for d in sizes])
        ax.xaxis.set_minor_formatter(NullFormatter())
    ax.set_xlabel("d (Fourier modes)")
    ax.set_ylabel("CPU s (integration)")
    ax.set_title(f"{problem}: cost against size, matched parameters")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    if orders:
        ax = axes[0, 1]
        ok = sorted((n, r) for n, r in orders.items() if r["status"] == Status.OK and r.get("cpu_s"))
        if ok:
            ax.semilogy([n for n, _ in ok], [r["cpu_s"] for _, r in ok], "o-", color="C0", label="CPU s")
            err_ax = ax.twinx()
            err_ax.semilogy([n for n, _ in ok], [r.get(metric) or np.nan for _, r in ok], "s--",
                            color="C3", label=metric)
            err_ax.set_ylabel(metric, color="C3")
        ax.set_xlabel("series order N")
        ax.set_ylabel("CPU s", color="C0")
        ax.set_title("bpl at the matched eps_res: cost (and error) against N")
        ax.grid(True, which="both", alpha=0.3)
    plain_ticks(fig)
    fig.tight_layout()
    return save(fig, Path(out_dir) / f"{problem}-scaling")
