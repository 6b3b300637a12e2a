"""``longtime plot KIND``: the suite's figures, saved as PNG and SVG (matplotlib, Agg).

Kinds are a registry, ``PLOT_KINDS``: name -> "module:function", imported only when drawn,
so a module adds a kind with one line. A kind function takes keyword arguments and
returns the paths it wrote; ``longtime plot`` passes it only the options below that its
signature accepts (and that were given, except ``out`` and ``formats``, always given):

    out: Path               file stem to write (<--out>/<kind>; suffixes are added)
    formats: tuple[str]     ("png", "svg") by default
    problems, schemes       -p / -i lists
    dt, t_final             --dt (first value), --t-final
    problem_settings        --set key=value of the problem's parameters
    db, run, metric         the store, the run id ("all": every run), the drift metric

Every curve a kind draws from integration is computed in that call; work-precision
draws the rows of the store (the measurements of a `longtime matrix` or `run`).
"""
from __future__ import annotations

import argparse
import importlib
import inspect
import math
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

import numpy as np

from .params import InputError, check_choice

PLOT_KINDS: dict[str, str] = {
    "work-precision": "longtime.plot:work_precision",
    "drift": "longtime.plot:drift",
    "toda-eigenvalues": "longtime.plot:toda_eigenvalues",
    "duffing-phase": "longtime.plot:duffing_phase",
    "pendulum-region": "longtime.figures.pendulum:pendulum_region",
}

FORMATS = ("png", "svg", "pdf")
DRIFT_METRICS = ("H.max", "H.mean")
# the forcing amplitudes of the paper's Duffing phase portraits (SPEC.md 1.4)
DUFFING_C = (0.20, 0.28, 0.29, 0.37, 0.50, 0.65)


def kind_function(kind: str) -> Callable[..., list[Path]]:
    check_choice("plot kind", kind, PLOT_KINDS)
    module, _, name = PLOT_KINDS[kind].partition(":")
    try:
        return getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError) as exc:
        raise InputError(f"plot kind '{kind}' is not available: {PLOT_KINDS[kind]} failed to load ({exc})") from None


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save(fig, out: str | Path, formats: Sequence[str] = ("png", "svg")) -> list[Path]:
    """Write ``fig`` as out.<format> for each format; close it; return the paths."""
    bad = [f for f in formats if f not in FORMATS]
    if bad:
        raise InputError(f"formats: {', '.join(bad)} not valid: expected {', '.join(FORMATS)}")
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    paths = []
    for fmt in formats:
        path = out.with_name(f"{out.name}.{fmt}")
        fig.savefig(path, dpi=130, bbox_inches="tight")
        paths.append(path)
    _pyplot().close(fig)
    return paths


def _positive(x) -> bool:
    return x is not None and isinstance(x, (int, float)) and math.isfinite(x) and x > 0


def _store_rows(db, run) -> list[dict]:
    from .store import Store

    store = Store(db)
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


def work_precision(out: Path, formats: Sequence[str] = ("png", "svg"), rows: list[dict] | None = None,
                   db=None, run=None, problems: list[str] | None = None, schemes: list[str] | None = None,
                   metric: str = "H.max") -> list[Path]:
    """Per problem: invariant drift (``metric``) and L2 error against CPU seconds, log-log,
    one curve per scheme (its points: the swept dt / tol / eps_res / N), from stored rows."""
    check_choice("metric", metric, DRIFT_METRICS)
    rows = _store_rows(db, run) if rows is None else rows
    rows = [r for r in rows if r.get("status") == "ok" and _positive(r.get("cpu_s"))]
    if problems:
        rows = [r for r in rows if r["problem"] in problems]
    if schemes:
        rows = [r for r in rows if r["integrator"] in schemes]
    if not rows:
        raise InputError("work-precision: no ok rows with a CPU time to draw (run `longtime matrix` first, "
                         "or check --run, -p and -i)")
    plt = _pyplot()
    written = []
    for problem in sorted({r["problem"] for r in rows}):
        mine = [r for r in rows if r["problem"] == problem]
        panels = [(metric, f"{metric} (relative energy error)"), ("l2_error", "relative L2 error")]
        panels = [p for p in panels if any(_positive(r.get(p[0])) for r in mine)]
        if not panels:
            continue
        fig, axes = plt.subplots(1, len(panels), figsize=(6.2 * len(panels), 4.6), squeeze=False)
        for ax, (field, label) in zip(axes[0], panels):
            for i, scheme in enumerate(sorted({r["integrator"] for r in mine})):
                # the point is the minimum cpu_s of the repeated runs; the bar reaches the
                # slowest repeat (rows stored before repeated timing have no bar)
                pts = sorted((r["cpu_s"], r[field], r.get("cpu_s_max") or r["cpu_s"]) for r in mine
                             if r["integrator"] == scheme and _positive(r.get(field)))
                if pts:
                    x, y, x_max = zip(*pts)
                    color = f"C{i % 10}"
                    ax.loglog(x, y, marker="o", ms=4, lw=1.2, label=scheme, color=color,
                              ls="-" if i < 10 else "--")
                    ax.hlines(y, x, x_max, color=color, lw=2.5, alpha=0.45)
            ax.set_xlabel("CPU seconds (integration: minimum of repeats, bar to the maximum)")
            ax.set_ylabel(label)
            ax.grid(True, which="both", alpha=0.3)
        axes[0][0].legend(fontsize=8, ncol=2)
        fig.suptitle(f"{problem}: error against cost")
        written += save(fig, Path(out).with_name(f"{Path(out).name}-{problem}"), formats)
    if not written:
        raise InputError("work-precision: no row has a drift or an L2 error to draw")
    return written


def _integrate(problem, scheme: str, dt: float | None, t_final: float, max_samples: int = 20_001):
    from . import registry

    icls = registry.integrator_class(scheme)
    settings = {"dt": dt} if dt is not None and "dt" in icls.parameters else {}
    integrator = icls(**settings)
    reason = integrator.incompatibility(problem)
    if reason:
        raise InputError(reason)
    return integrator.integrate(problem, t_final, max_samples=max_samples)


def _problem(name: str, settings: dict | None):
    from . import registry

    cls = registry.problem_class(name)
    return cls(**{k: v for k, v in (settings or {}).items() if k in cls.parameters})


def drift(out: Path, formats: Sequence[str] = ("png", "svg"), problems: list[str] | None = None,
          schemes: list[str] | None = None, dt: float | None = None, t_final: float | None = None,
          problem_settings: dict | None = None, invariant: str = "H") -> list[Path]:
    """e_H(t) = |H(t) - H(0)| / |H(0)| against t for each scheme (default: the paper's Toda
    run, RK4 and RK4sym at dt = 0.1 to t = 5000), one panel per problem."""
    from .metrics import relative_error

    problems = problems or ["toda"]
    schemes = schemes or ["rk4", "rk4sym"]
    plt = _pyplot()
    fig, axes = plt.subplots(len(problems), 1, figsize=(8, 3.8 * len(problems)), squeeze=False)
    for ax, name in zip(axes[:, 0], problems):
        problem = _problem(name, problem_settings)
        tf = t_final if t_final is not None else problem.default_t_final
        for i, scheme in enumerate(schemes):
            traj = _integrate(problem, scheme, dt, tf)
            values = problem.invariants(traj.t, traj.u).get(invariant)
            if values is None:
                raise InputError(f"problem '{name}' has no invariant '{invariant}'")
            err = relative_error(values)
            ok = err > 0
            step = dt if dt is not None else getattr(problem, "default_dt", None)
            label = scheme + (f" (dt={step:g})" if step and "dt" in _parameters(scheme) else "")
            if traj.status != "ok":
                label += f" [{traj.status} at t={traj.t_reached:.4g}]"
            # the first scheme on top: oscillating curves of later ones must not hide it
            ax.semilogy(traj.t[ok], err[ok], lw=0.6, label=label, color=f"C{i}", zorder=len(schemes) - i,
                        alpha=0.9 if i == 0 else 0.6)
        ax.set_xlabel("t")
        ax.set_ylabel(f"relative error of {invariant}")
        ax.set_title(f"{problem.describe()}: drift of {invariant}")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    return save(fig, out, formats)


def _parameters(scheme: str) -> dict:
    from . import registry

    return registry.integrator_class(scheme).parameters


def toda_eigenvalues(out: Path, formats: Sequence[str] = ("png", "svg"), schemes: list[str] | None = None,
                     dt: float | None = None, t_final: float | None = None,
                     problem_settings: dict | None = None) -> list[Path]:
    """Eigenvalues of the Toda Lax matrix against t, one panel per scheme (default: RK4 and
    RK4sym, dt = 0.1, t = 5000); dashed: their initial values (exact invariants)."""
    schemes = schemes or ["rk4", "rk4sym"]
    problem = _problem("toda", problem_settings)
    tf = t_final if t_final is not None else problem.default_t_final
    plt = _pyplot()
    fig, axes = plt.subplots(len(schemes), 1, figsize=(8, 3.4 * len(schemes)), squeeze=False, sharex=True)
    eig0 = problem.lax_eigenvalues(np.array([problem.t0]), problem.u0[None, :])[0]
    for ax, scheme in zip(axes[:, 0], schemes):
        traj = _integrate(problem, scheme, dt, tf, max_samples=10_001)
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
    fig.tight_layout()
    return save(fig, out, formats)


def duffing_phase(out: Path, formats: Sequence[str] = ("png", "svg"), schemes: list[str] | None = None,
                  dt: float | None = None, t_final: float | None = None,
                  problem_settings: dict | None = None, c_values: Iterable[float] = DUFFING_C,
                  t_start: float = 40.0) -> list[Path]:
    """Phase portraits (u, u') of the forced Duffing oscillator over t in [40, 1000], one panel
    per forcing amplitude c (the paper's six values), integrated by ``schemes[0]`` (rk4)."""
    from . import registry

    if "duffing-forced" not in registry.problems():
        raise InputError("plot kind 'duffing-phase' is not available: problem 'duffing-forced' is not registered")
    scheme = (schemes or ["rk4"])[0]
    c_values = list(c_values)
    cols = 3
    rows_n = math.ceil(len(c_values) / cols)
    plt = _pyplot()
    fig, axes = plt.subplots(rows_n, cols, figsize=(4.2 * cols, 3.8 * rows_n), squeeze=False)
    for ax in axes.flat[len(c_values):]:
        ax.set_visible(False)
    for ax, c in zip(axes.flat, c_values):
        problem = _problem("duffing-forced", {**(problem_settings or {}), "c": c})
        tf = t_final if t_final is not None else 1000.0
        traj = _integrate(problem, scheme, dt, tf, max_samples=200_001)
        keep = traj.t >= min(t_start, 0.5 * tf)
        ax.plot(traj.u[keep, 0], traj.u[keep, 1], lw=0.25, color="C0", rasterized=True)
        status = "" if traj.status == "ok" else f" [{traj.status}]"
        ax.set_title(f"c = {c:g}{status}")
        ax.set_xlabel("u")
        ax.set_ylabel("u'")
    step = dt if dt is not None else registry.problem_class("duffing-forced").default_dt
    fig.suptitle(f"forced Duffing: phase portraits over t in [{t_start:g}, {tf:g}] ({scheme}, dt={step:g})")
    fig.tight_layout()
    return save(fig, out, formats)


def draw(kind: str, out_dir: str | Path = "figures", **options: Any) -> list[Path]:
    """Draw one kind into ``out_dir``; options as in the module docstring (None: not given)."""
    fn = kind_function(kind)
    accepted = inspect.signature(fn).parameters
    takes_all = any(p.kind is inspect.Parameter.VAR_KEYWORD for p in accepted.values())
    given = {k: v for k, v in options.items() if v is not None and (takes_all or k in accepted)}
    given.setdefault("formats", ("png", "svg"))
    return [Path(p) for p in fn(out=Path(out_dir) / kind, **given)]


def _names(text: str) -> list[str]:
    return [x.strip() for x in text.split(",") if x.strip()]


def _key_value(text: str) -> tuple[str, Any]:
    if "=" not in text:
        raise argparse.ArgumentTypeError(f"--set takes key=value, got {text!r}")
    key, value = text.split("=", 1)
    return key.strip(), value.strip()


def cmd_plot(args) -> int:
    settings: dict[str, Any] = dict(args.set)
    paths = draw(args.kind, args.out, problems=args.problem, schemes=args.integrator, dt=args.dt,
                 t_final=args.t_final, problem_settings=settings or None, db=args.db, run=args.run,
                 metric=args.metric, formats=tuple(args.format))
    for p in paths:
        print(p)
    return 0


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("plot", help="figures: work-precision, drift, Toda eigenvalues, Duffing phase, ...",
                              description=__doc__.splitlines()[0])
    p.add_argument("kind", choices=sorted(PLOT_KINDS), help="what to draw")
    p.add_argument("--out", default="figures", help="folder for the files (default: figures)")
    p.add_argument("-p", "--problem", type=_names, default=None, metavar="PROBLEM[,..]")
    p.add_argument("-i", "--integrator", type=_names, default=None, metavar="SCHEME[,..]")
    p.add_argument("--dt", type=float, default=None, help="time step of the integrations")
    p.add_argument("--t-final", type=float, default=None, metavar="T")
    p.add_argument("--set", type=_key_value, action="append", default=[], metavar="KEY=VALUE",
                   help="a problem parameter (repeatable)")
    p.add_argument("--db", default=None, help="store to read (work-precision)")
    p.add_argument("--run", default=None, help="run id, 'latest' (default) or 'all' (work-precision)")
    p.add_argument("--metric", choices=DRIFT_METRICS, default=None, help="drift metric of work-precision")
    p.add_argument("--format", type=_names, default=["png", "svg"], metavar="FMT[,..]",
                   help="png, svg, pdf (default: png,svg)")
    p.set_defaults(func=cmd_plot)
