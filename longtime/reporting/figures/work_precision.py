"""``work-precision``: error against CPU seconds per problem, from the store's rows."""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

from longtime.core.fmt import positive
from longtime.core.params import InputError, check_choice
from longtime.core.status import Status
from longtime.reporting.figures import pyplot, save

DRIFT_METRICS = ("H.max", "H.mean")


def _store_rows(db, run) -> list[dict]:
    from longtime.execution.store import Store

    store = Store(db, readonly=True)  # a figure writes nothing into the store
    if run in (None, "", "latest"):
        run_id = store.latest_run()
        if run_id is None:
            raise InputError(f"no runs in {store.path}: run `longtime matrix` first")
        return store.rows(run_id)
    if str(run) == "all":
        return store.rows()
    try:
        return store.rows(int(run))
    except ValueError:
        raise InputError(f"--run {run!r} is not valid: expected a run id, 'latest' or 'all'") from None


def curves(ax, rows: list[dict], field: str, style: dict[str, dict[str, str]]) -> None:
    """One curve per scheme of ``rows`` (ok rows of one problem): ``field`` against CPU
    seconds, log-log, a colour and a marker per scheme (``style``: figures.style.styles)."""
    from longtime.reporting.figures.style import family

    for scheme in sorted({r["integrator"] for r in rows}):
        # the point is the minimum cpu_s of the repeated runs; the bar reaches the
        # slowest repeat (rows of a store without repeated timing have no bar)
        pts = sorted((r["cpu_s"], r[field], r.get("cpu_s_max") or r["cpu_s"]) for r in rows
                     if r["integrator"] == scheme and positive(r.get(field)))
        if pts:
            x, y, x_max = zip(*pts)
            color = style[scheme]["color"]
            ax.loglog(x, y, marker=style[scheme]["marker"], ms=5, lw=1.2, color=color,
                      label=f"{scheme} ({family(scheme)})")
            ax.hlines(y, x, x_max, color=color, lw=2.5, alpha=0.45)


def work_precision(out: Path, formats: Sequence[str] = ("png", "svg"), rows: list[dict] | None = None,
                   db=None, run=None, problems: list[str] | None = None, schemes: list[str] | None = None,
                   metric: str = "H.max") -> list[Path]:
    """Per problem: invariant drift (``metric``) and L2 error against CPU seconds, log-log,
    one curve per scheme (its points: the swept dt / tol / eps_res / N), from stored rows."""
    check_choice("metric", metric, DRIFT_METRICS)
    rows = _store_rows(db, run) if rows is None else rows
    rows = [r for r in rows if r.get("status") == Status.OK and positive(r.get("cpu_s"))]
    if problems:
        rows = [r for r in rows if r["problem"] in problems]
    if schemes:
        rows = [r for r in rows if r["integrator"] in schemes]
    if not rows:
        raise InputError("work-precision: no ok rows with a CPU time to draw (run `longtime matrix` first, "
                         "or check --run, -p and -i)")
    plt = pyplot()
    written = []
    for problem in sorted({r["problem"] for r in rows}):
        mine = [r for r in rows if r["problem"] == problem]
        panels = [(metric, f"{metric} (relative energy error)"), ("l2_error", "relative L2 error")]
        panels = [p for p in panels if any(positive(r.get(p[0])) for r in mine)]
        if not panels:
            continue
        fig, axes = plt.subplots(1, len(panels), figsize=(6.2 * len(panels), 4.6), squeeze=False)
        from longtime.reporting.figures.style import styles

        style = styles(sorted({r["integrator"] for r in mine}))  # a colour and a marker per scheme, none alike
        for ax, (field, label) in zip(axes[0], panels):
            curves(ax, mine, field, style)
            ax.set_xlabel("CPU seconds (integration: minimum of repeats, bar to the maximum)")
            ax.set_ylabel(label)
            ax.grid(True, which="both", alpha=0.3)
        # outside the axes: a legend inside covers data once there are many schemes
        axes[0][-1].legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0), frameon=False)
        fig.suptitle(f"{problem}: error against cost")
        written += save(fig, Path(out).with_name(f"{Path(out).name}-{problem}"), formats)
    if not written:
        raise InputError("work-precision: no row has a drift or an L2 error to draw")
    return written
