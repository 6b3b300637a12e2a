"""``longtime match``: schemes compared at matched accuracy, and how their cost scales.

For each scheme, the parameter that sets its accuracy (``eps_res`` for BPL, ``tol`` for
adaptive schemes, ``dt`` for fixed-step ones) is searched, by bracketing in decades and
then bisection on its logarithm, for an error at t_final near ``--target`` (default 1e-5;
the error is ``final_error``, for KdV the relative L2 norm in x at t = T, since its state
is orthonormal Fourier coefficients). The evaluated point nearest the target (in log) is
then re-timed ``--repeat`` times (minimum CPU kept, the machine being shared). Every
evaluation goes through ``longtime.cells.run_cell`` and into the store (``match_role``:
search, matched or scaling). The paper's figures (SPEC.md 4, KdV d = 128) are printed
beside ours; they are the paper's measurements on its own machine and code, quoted, never
used in a computation.

``--scaling`` then runs each scheme at its matched parameter for every ``--sizes`` value of
the problem's ``d`` (KdV: 64, 128, 256, 512), and BPL at every series order ``--orders``
(4..14), and reports the CPU growth from d = 128 to d = 512 with a figure (PNG and SVG).
Fixed parameters, not re-matched per size: the growth then measures the cost of the size
alone (the stiffness grows as d^3, so explicit schemes' steps shrink with it).
"""
from __future__ import annotations

import argparse
import json
import math
import shlex
import sys
from pathlib import Path
from typing import Any

from . import registry
from .cells import Cell, expand, run_cell
from .params import InputError
from .store import Store, default_path

# SPEC.md section 4: KdV, d = 128, one period (CPU s, mean step, L2 error), the paper's code
PAPER_KDV = {
    "bpl": (1.74, 0.153, 9.76e-6),
    "etdrk4": (1660.0, 6.41e-4, 1.10e-5),
    "adaptive-rk4": (59.8, 1.88e-3, 1.69e-5),
    "rk4": (59.8, 1.88e-3, 1.69e-5),
}
PAPER_GROWTH_128_512 = {"bpl": 51.0, "etdrk4": 381.0}  # % CPU growth from d = 128 to 512
# the paper has one BPL; its variants are shown against it
PAPER_ROW = {"bpl-exp": "bpl"}
DEFAULT_SCHEMES = ["bpl", "bpl-exp", "etdrk4", "rk45", "adaptive-rk4"]
ACCURACY_PARAMETERS = ("eps_res", "tol", "dt")
BOUNDS = {"eps_res": (1e-14, 1.0), "tol": (1e-14, 1e-1)}
MAX_FIXED_STEPS = 2_000_000  # smallest dt tried: the span over this many steps
CLOSE_ENOUGH = math.log(1.2)  # stop the search within 20 % of the target
MATCH_SAMPLES = 2001  # states kept per run: the metrics need the final state, not every step


def accuracy_parameter(scheme: str) -> str:
    cls = registry.integrator_class(scheme)
    for name in ACCURACY_PARAMETERS:
        if name in cls.parameters:
            return name
    raise InputError(f"scheme '{scheme}' has none of the parameters {', '.join(ACCURACY_PARAMETERS)}: "
                     "nothing to match")


def _error(row: dict, metric: str) -> float:
    value = row.get(metric)
    return float(value) if row.get("status") == "ok" and value is not None else math.inf


class Matcher:
    def __init__(self, store: Store | None, run_id: int | None, metric: str, target: float,
                 repeat: int, max_evals: int, verbose: bool = True):
        self.store, self.run_id = store, run_id
        self.metric, self.target = metric, target
        self.repeat, self.max_evals, self.verbose = repeat, max_evals, verbose

    def evaluate(self, cell: Cell, role: str) -> dict:
        row = run_cell(cell, max_samples=MATCH_SAMPLES)
        row["match_role"], row["match_target"] = role, self.target
        if self.store is not None:
            self.store.add_row(self.run_id, cell, row)
        if self.verbose:
            print(f"  {cell.integrator:14s} {cell.problem_settings} {cell.integrator_settings}: "
                  f"{row['status']} {self.metric}={row.get(self.metric)} cpu={row.get('cpu_s')}",
                  file=sys.stderr)
        return row

    def timed(self, cell: Cell, first: dict, role: str) -> dict:
        """The best CPU of ``repeat`` runs (a run longer than 5 s is not repeated)."""
        best = first
        for _ in range(self.repeat - 1):
            if best.get("status") != "ok" or (best.get("cpu_s") or 0.0) > 5.0:
                break
            row = run_cell(cell, max_samples=MATCH_SAMPLES)
            if row.get("status") == "ok" and row["cpu_s"] < best["cpu_s"]:
                best = row
        best = {**best, "match_role": role, "match_target": self.target, "cpu_runs": self.repeat}
        if self.store is not None:
            self.store.add_row(self.run_id, cell, best)
        return best

    def match(self, base: Cell) -> dict:
        """Search the scheme's accuracy parameter for an error near the target."""
        if base.skip_reason:
            return run_cell(base)  # a skipped row, with the reason as its message
        name = accuracy_parameter(base.integrator)
        problem = registry.problem_class(base.problem)(**base.problem_settings)
        span = base.t_final - problem.t0
        if name == "dt":
            start = problem.default_dt
            low, high = span / MAX_FIXED_STEPS, span / 4
        else:
            start = registry.integrator_class(base.integrator).parameters[name].default
            low, high = BOUNDS[name]
        start = min(max(start, low), high)
        tried: dict[float, dict] = {}

        def run(value: float) -> float:
            cell = Cell(base.problem, base.integrator, dict(base.problem_settings),
                        {**base.integrator_settings, name: value}, base.t_final)
            tried[value] = (cell, self.evaluate(cell, "search"))
            return _error(tried[value][1], self.metric)

        # bracket in decades: ok (error <= target) below, too large above
        value, err = start, run(start)
        ok = value if err <= self.target else None
        bad = value if err > self.target else None
        while len(tried) < self.max_evals:
            if ok is None:
                value = value / 10
                if value < low:
                    break
                if run(value) <= self.target:
                    ok = value
                else:
                    bad = value
            elif bad is None:
                value = value * 10
                if value > high:
                    break
                if run(value) > self.target:
                    bad = value
                else:
                    ok = value
            else:
                break
        # bisection on log(value) while the nearest error is not close enough
        while ok is not None and bad is not None and len(tried) < self.max_evals:
            nearest = min(abs(math.log(_error(r, self.metric) / self.target)) if _error(r, self.metric) > 0
                          else math.inf for _, r in tried.values())
            if nearest <= CLOSE_ENOUGH or bad / ok < 1.01:
                break
            mid = math.sqrt(ok * bad)
            if run(mid) <= self.target:
                ok = mid
            else:
                bad = mid

        def distance(item):
            e = _error(item[1][1], self.metric)
            return abs(math.log(e / self.target)) if 0 < e < math.inf else math.inf

        value, (cell, row) = min(tried.items(), key=distance)
        searched = {v: r.get("mean_dt") for v, (_, r) in sorted(tried.items()) if r.get("status") == "ok"}
        note = ""
        if ok is None:
            note = f"error above the target down to {name}={min(tried):.3g}"
        elif bad is None:
            note = f"error below the target up to {name}={max(tried):.3g}"
        elif distance((value, (cell, row))) > CLOSE_ENOUGH:
            # the error jumps across the target (e.g. from the error floor to a stability
            # limit): the cheapest setting that meets the target is the fair point
            value = max(v for v, (_, r) in tried.items() if _error(r, self.metric) <= self.target)
            cell, row = tried[value]
            above = min(v for v in tried if v > value)
            note = (f"no {name} gives an error near the target: {name}={above:.4g} gives "
                    f"{_error(tried[above][1], self.metric):.3g} ({tried[above][1]['status']}); "
                    f"the largest {name} below the target is shown")
        row = self.timed(cell, row, "matched")
        row.update(match_parameter=name, match_value=value, match_note=note, match_evals=len(tried),
                   match_mean_steps=searched)
        return row


# ---------------------------------------------------------------- output


def _shown(row: dict, metric: str):
    """The error of a finished run (none for a failed or diverged one)."""
    return row.get(metric) if row.get("status") == "ok" else None


def _fmt(x, spec: str) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        width = "".join(ch for ch in spec.split(".")[0] if ch.isdigit())
        return "-".rjust(int(width or 0))
    return format(x, spec)


def match_table(rows: list[dict], problem: str, settings: dict, metric: str, target: float) -> str:
    paper = PAPER_KDV if problem == "kdv" and settings.get("d") == 128 else {}
    head = (f"{'scheme':14s} {'parameter':>18s} {'mean step':>10s} {metric:>11s} {'CPU s':>9s} "
            f"{'steps':>8s} {'rhs evals':>9s} | {'paper CPU':>9s} {'mean step':>9s} {'L2 error':>9s} "
            f"{'paper/ours':>10s}")
    lines = [f"== {problem} {settings or ''}: matched accuracy, target {metric} = {target:g} ==", head,
             "-" * len(head)]
    for r in rows:
        p = paper.get(PAPER_ROW.get(r["integrator"], r["integrator"]))
        param = (f"{r['match_parameter']}={r['match_value']:.3g}" if r.get("match_parameter") else "-")
        ratio = (p[0] / r["cpu_s"]) if p and r.get("cpu_s") else None
        lines.append(
            f"{r['integrator']:14s} {param:>18s} {_fmt(r.get('mean_dt'), '10.3e')} "
            f"{_fmt(_shown(r, metric), '11.3e')} {_fmt(r.get('cpu_s'), '9.4f')} {_fmt(r.get('steps'), '8d')} "
            f"{_fmt(r.get('rhs_evals'), '9d')} | "
            + (f"{p[0]:9.4g} {p[1]:9.3g} {p[2]:9.3g} {_fmt(ratio, '10.3g')}" if p else f"{'-':>9s} " * 3 + f"{'-':>10s}"))
        if r["status"] != "ok":
            lines.append(f"    {r['status']}: {r.get('message')}")
        if r.get("match_note"):
            lines.append(f"    note: {r['match_note']}")
        if r.get("fallback_fraction"):
            lines.append(f"    fallback_fraction {r['fallback_fraction']:.3f}: that share of the steps "
                         "took a component's Taylor sum (the fallback variant)")
    if paper:
        lines.append("paper: its own code and machine (SPEC.md 4); CPU = best of the repeats, "
                     "measured in this run; paper/ours = paper CPU over ours"
                     + "".join(f"; {v} is shown against the paper's {k}" for v, k in PAPER_ROW.items()
                               if any(r["integrator"] == v for r in rows)))
    return "\n".join(lines)


def step_cap_lines(problem: str, psettings: dict, bases: list[Cell], rows: list[dict]) -> list[str]:
    """Why pure bpl's step is capped on a problem with a stiff linear part, measured: the
    largest frequency omega_max of the linear part, omega_max x bpl's mean step, the mean
    steps over the eps_res searched, and where one bpl step starts to amplify a rotation
    (``bpl.amplification_onset``). Empty when there is no bpl row or no linear part."""
    import numpy as np

    from .integrators.bpl import AMPLIFICATION_GROWTH, amplification_onset

    pcls = registry.problem_class(problem)
    by = {c.integrator: (c, r) for c, r in zip(bases, rows) if r.get("status") == "ok" and r.get("mean_dt")}
    if "bpl" not in by or pcls.linear_part is None:
        return []
    p = pcls(**psettings)
    lin = np.zeros(p.dim)
    p.linear_part(p.params, lin)
    omega_max = float(np.max(np.abs(lin[1::2])))
    cell, row = by["bpl"]
    order = cell.integrator_settings.get("order", registry.integrator_class("bpl").parameters["order"].default)
    onset = amplification_onset(int(order))
    h = row["mean_dt"]
    lines = [f"why bpl's step is capped on {problem} (measured): the linear part's largest frequency is "
             f"omega_max = {omega_max:.4g}; one bpl step (N = {order}) amplifies some rotation exp(i y) by "
             f"more than {100 * AMPLIFICATION_GROWTH:g} % from y = omega h = {onset:g} on "
             f"(bpl.amplification_onset); bpl's mean step {h:.3g} puts the top modes at y = {omega_max * h:.3g}: "
             "the residual test holds the step where their growth stays small, and that, not eps_res, "
             "sets the step"]
    steps = row.get("match_mean_steps") or {}
    if len(steps) > 1:
        lines.append(f"    bpl mean step over the search: {min(steps.values()):.3g} to {max(steps.values()):.3g} "
                     f"for eps_res from {min(steps):.3g} to {max(steps):.3g}")
    if "bpl-exp" in by:
        he = by["bpl-exp"][1]["mean_dt"]
        lines.append(f"    bpl-exp (the linear part exact, BPL on the rest): mean step {he:.3g} = "
                     f"{he / h:.3g} x bpl's, omega_max h = {omega_max * he:.3g}")
    return lines


def scaling_tables(scaling: dict[str, dict[int, dict]], orders: dict[int, dict], metric: str,
                   base_size: int = 128, top_size: int = 512) -> str:
    lines = ["== scaling with the size d (each scheme at its matched parameter) =="]
    sizes = sorted({d for per in scaling.values() for d in per})
    head = f"{'scheme':14s} " + " ".join(f"{'d=' + str(d) + ' CPU s':>14s}" for d in sizes) + \
        f" {'growth ' + str(base_size) + '->' + str(top_size):>16s} {'paper':>7s}"
    lines += [head, "-" * len(head)]
    for scheme, per in scaling.items():
        cells = []
        for d in sizes:
            r = per.get(d)
            cells.append(f"{_fmt(r.get('cpu_s') if r and r['status'] == 'ok' else None, '14.4f')}")
        g = growth(per, base_size, top_size)
        paper = PAPER_GROWTH_128_512.get(scheme)
        lines.append(f"{scheme:14s} " + " ".join(cells) + f" {_fmt(g, '+15.0f')}%"
                     + (f" {paper:+6.0f}%" if paper is not None else f" {'-':>7s}"))
    lines.append("")
    lines.append(f"{'scheme':14s} {'d':>5s} {'mean step':>10s} {metric:>11s} {'steps':>8s} {'rhs evals':>10s}")
    for scheme, per in scaling.items():
        for d in sizes:
            r = per.get(d)
            if r:
                lines.append(f"{scheme:14s} {d:5d} {_fmt(r.get('mean_dt'), '10.3e')} "
                             f"{_fmt(_shown(r, metric), '11.3e')} {_fmt(r.get('steps'), '8d')} "
                             f"{_fmt(r.get('rhs_evals'), '10d')}  {r['status'] if r['status'] != 'ok' else ''}")
    if orders:
        lines += ["", "== bpl: series order N (matched eps_res, base size) ==",
                  f"{'N':>4s} {'CPU s':>9s} {'mean step':>10s} {metric:>11s} {'steps':>8s}"]
        for n, r in sorted(orders.items()):
            lines.append(f"{n:4d} {_fmt(r.get('cpu_s'), '9.4f')} {_fmt(r.get('mean_dt'), '10.3e')} "
                         f"{_fmt(_shown(r, metric), '11.3e')} {_fmt(r.get('steps'), '8d')}  "
                         f"{r['status'] if r['status'] != 'ok' else ''}")
    return "\n".join(lines)


def growth(per: dict[int, dict], base: int, top: int) -> float | None:
    a, b = per.get(base), per.get(top)
    if not a or not b or a["status"] != "ok" or b["status"] != "ok" or not a.get("cpu_s"):
        return None
    return 100.0 * (b["cpu_s"] / a["cpu_s"] - 1.0)


def scaling_figure(scaling, orders, problem: str, out_dir: Path, metric: str = "final_error") -> list[Path]:
    import matplotlib
    import numpy as np

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = 2 if orders else 1
    fig, axes = plt.subplots(1, panels, figsize=(5.5 * panels, 4.2), squeeze=False)
    ax = axes[0, 0]
    for scheme, per in scaling.items():
        pts = sorted((d, r["cpu_s"]) for d, r in per.items() if r["status"] == "ok" and r.get("cpu_s"))
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
        ok = sorted((n, r) for n, r in orders.items() if r["status"] == "ok" and r.get("cpu_s"))
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
    fig.tight_layout()
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = [out_dir / f"{problem}-scaling.{ext}" for ext in ("png", "svg")]
    for p in paths:
        fig.savefig(p, dpi=120)
    plt.close(fig)
    return paths


# ---------------------------------------------------------------- command


def _names(text: str) -> list[str]:
    return [x.strip() for x in text.split(",") if x.strip()]


def _ints(text: str) -> list[int]:
    try:
        return [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated integers, got {text!r}") from None


def _key_value(text: str) -> tuple[str, str]:
    if "=" not in text:
        raise argparse.ArgumentTypeError(f"--set takes key=value, got {text!r}")
    key, value = text.split("=", 1)
    return key.strip(), value.strip()


def _orders_arg(text: str) -> list[int]:
    if ".." in text:
        a, b = text.split("..", 1)
        return list(range(int(a), int(b) + 1))
    return _ints(text)


def cmd_match(args) -> int:
    if args.target <= 0 or not math.isfinite(args.target):
        raise InputError(f"--target={args.target} is not valid: must be > 0")
    if args.repeat < 1:
        raise InputError(f"--repeat={args.repeat} is not valid: must be >= 1")
    if len(args.problem) != 1:
        raise InputError(f"-p/--problem takes one problem, got {', '.join(args.problem)}")
    problem = args.problem[0]
    sets = dict(args.set)
    for scheme in args.integrator:
        accuracy_parameter(scheme)
    bases = expand([problem], args.integrator, t_final=args.t_final, sets=sets)
    pcls = registry.problem_class(problem)
    if args.scaling and "d" not in pcls.parameters:
        raise InputError(f"--scaling varies the parameter d, which problem '{problem}' does not have")
    store = None if args.no_store else Store(args.db)
    run_id = store.begin_run("match " + shlex.join(sys.argv[2:] if sys.argv[1:2] == ["match"] else sys.argv[1:]),
                             bases) if store else None
    matcher = Matcher(store, run_id, args.metric, args.target, args.repeat, args.max_evals,
                      verbose=not args.quiet)
    status = "interrupted"
    out_rows: list[dict] = []
    try:
        matched = [matcher.match(c) for c in bases]
        base_settings = bases[0].problem_settings if bases else {}
        psettings = pcls(**base_settings).settings  # parsed values (--set gives strings)
        out_rows += matched
        text = [match_table(matched, problem, psettings, args.metric, args.target)]
        cap = step_cap_lines(problem, psettings, bases, matched)
        if cap:
            text[0] += "\n\n" + "\n".join(cap)
        if args.scaling:
            scaling: dict[str, dict[int, dict]] = {}
            orders: dict[int, dict] = {}
            for cell, row in zip(bases, matched):
                if cell.skip_reason or row.get("match_parameter") is None:
                    continue
                per = scaling.setdefault(cell.integrator, {})
                settings = {**cell.integrator_settings, row["match_parameter"]: row["match_value"]}
                for d in args.sizes:
                    c = Cell(problem, cell.integrator, {**cell.problem_settings, "d": d}, settings, cell.t_final)
                    r = matcher.timed(c, matcher.evaluate(c, "scaling"), "scaling")
                    r["d"] = d
                    per[d] = r
                    out_rows.append(r)
                if cell.integrator == "bpl" and args.orders:
                    for n in args.orders:
                        c = Cell(problem, "bpl", dict(cell.problem_settings), {**settings, "order": n},
                                 cell.t_final)
                        r = matcher.timed(c, matcher.evaluate(c, "scaling"), "scaling")
                        orders[n] = r
                        out_rows.append(r)
            text.append(scaling_tables(scaling, orders, args.metric))
            if not args.no_figure:
                paths = scaling_figure(scaling, orders, problem, Path(args.out), args.metric)
                text.append("figures: " + ", ".join(map(str, paths)))
        status = "done"
    finally:
        if store:
            store.finish_run(run_id, status)
    if args.format == "json":
        print(json.dumps(out_rows, indent=1, default=str))
    else:
        print("\n\n".join(text))
    return 0


def add_parser(subparsers) -> None:
    p = subparsers.add_parser(
        "match", help="schemes at matched accuracy (e.g. KdV: the paper's table) and their scaling",
        description=__doc__.split("\n\n")[1])
    p.add_argument("-p", "--problem", type=_names, default=["kdv"], metavar="PROBLEM",
                   help="one problem with a reference (default: kdv)")
    p.add_argument("-i", "--integrator", type=_names, default=DEFAULT_SCHEMES,
                   metavar="SCHEME[,..]", help=f"schemes (default: {','.join(DEFAULT_SCHEMES)})")
    p.add_argument("--target", type=float, default=1e-5, help="error to match (default 1e-5)")
    p.add_argument("--metric", choices=["final_error", "l2_error"], default="final_error",
                   help="final_error: relative error at t_final (KdV: relative L2 in x); "
                        "l2_error: over all samples")
    p.add_argument("--t-final", type=float, default=None, help="final time (default: the problem's)")
    p.add_argument("--set", type=_key_value, action="append", default=[], metavar="KEY=VALUE",
                   help="other parameters of the problem or schemes, e.g. d=128 (repeatable)")
    p.add_argument("--repeat", type=int, default=3, help="timing runs of each matched point (best kept)")
    p.add_argument("--max-evals", type=int, default=14, help="search runs allowed per scheme")
    p.add_argument("--scaling", action="store_true", help="also run the sizes and the BPL orders")
    p.add_argument("--sizes", type=_ints, default=[64, 128, 256, 512], help="values of d for --scaling")
    p.add_argument("--orders", type=_orders_arg, default=list(range(4, 15)),
                   help="BPL series orders for --scaling (e.g. 4..14 or 4,6,8)")
    p.add_argument("--out", default="figures", help="folder of the scaling figure (PNG and SVG)")
    p.add_argument("--no-figure", action="store_true")
    p.add_argument("--format", choices=["table", "json"], default="table")
    p.add_argument("--db", default=None, help=f"SQLite store (default: $LONGTIME_DB or {default_path()})")
    p.add_argument("--no-store", action="store_true", help="do not store the rows")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress lines on stderr")
    p.set_defaults(func=cmd_match)
