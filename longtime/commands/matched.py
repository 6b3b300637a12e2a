"""``longtime match``: schemes compared at matched accuracy, and how their cost scales.

For each scheme, the parameter that sets its accuracy (its declared ``accuracy`` parameter:
``eps_res`` for BPL, ``tol`` for adaptive schemes, a plugin's own; else its step ``dt``) is
searched, by bracketing in decades and
then bisection on its logarithm, for an error at t_final near ``--target`` (default 1e-5;
the error is ``final_error``, for KdV the relative L2 norm in x at t = T, since its state
is orthonormal Fourier coefficients). The evaluated point nearest the target (in log) is
then re-timed ``--repeat`` times (minimum CPU kept, the machine being shared). Every
evaluation goes through ``longtime.execution.cells.run_cell`` and into the store (``match_role``:
search, matched or scaling); the search is ``longtime.execution.search.Matcher``. The paper's
figures (``longtime.reporting.paper``, docs/paper.md; KdV d = 128) are printed
beside ours; they are the paper's measurements on its own machine and code, quoted, never
used in a computation.

``--scaling`` then runs each scheme at its matched parameter for every ``--sizes`` value of
the problem's ``d`` (KdV: 64, 128, 256, 512), and BPL at every series order ``--orders``
(4..14), and reports the CPU growth from d = 128 to d = 512 with a figure (PNG and SVG).
Fixed parameters, not re-matched per size: the growth then measures the cost of the size
alone (the stiffness grows as d^3, so explicit schemes' steps shrink with it).
"""
from __future__ import annotations

import math
from pathlib import Path

from longtime.core import cli_args, jsontext, registry
from longtime.core.fmt import column
from longtime.core.params import InputError
from longtime.core.status import Status
from longtime.execution.cells import Cell, build, expand
from longtime.execution.lifecycle import command_line, recorded_run
from longtime.execution.search import Matcher, accuracy_parameter  # noqa: F401  (the search lives in longtime.execution.search)
from longtime.execution.store import Store, default_path
from longtime.reporting.figures.scaling import scaling_figure
from longtime.reporting.paper import KDV_GROWTH_128_512, KDV_ROW, kdv_row

DEFAULT_SCHEMES = ["bpl", "bpl-exp", "etdrk4", "rk45", "adaptive-rk4"]


# ---------------------------------------------------------------- output


def _shown(row: dict, metric: str):
    """The error of a finished run (none for a failed or diverged one)."""
    return row.get(metric) if row.get("status") == Status.OK else None


def match_table(rows: list[dict], problem: str, settings: dict, metric: str, target: float) -> str:
    paper = problem == "kdv" and settings.get("d") == 128
    head = (f"{'scheme':14s} {'parameter':>18s} {'mean step':>10s} {metric:>11s} {'CPU s':>9s} "
            f"{'steps':>8s} {'rhs evals':>9s} | {'paper CPU':>9s} {'mean step':>9s} {'L2 error':>9s} "
            f"{'paper/ours':>10s}")
    lines = [f"== {problem} {settings or ''}: matched accuracy, target {metric} = {target:g} ==", head,
             "-" * len(head)]
    for r in rows:
        p = kdv_row(r["integrator"]) if paper else None
        param = (f"{r['match_parameter']}={r['match_value']:.3g}" if r.get("match_parameter") else "-")
        ratio = (p[0] / r["cpu_s"]) if p and r.get("cpu_s") else None
        lines.append(
            f"{r['integrator']:14s} {param:>18s} {column(r.get('mean_dt'), '10.3e')} "
            f"{column(_shown(r, metric), '11.3e')} {column(r.get('cpu_s'), '9.4f')} {column(r.get('steps'), '8d')} "
            f"{column(r.get('rhs_evals'), '9d')} | "
            + (f"{p[0]:9.4g} {p[1]:9.3g} {p[2]:9.3g} {column(ratio, '10.3g')}" if p
               else f"{'-':>9s} " * 3 + f"{'-':>10s}"))
        if r["status"] != Status.OK:
            lines.append(f"    {r['status']}: {r.get('message')}")
        if r.get("match_note"):
            lines.append(f"    note: {r['match_note']}")
        if r.get("fallback_fraction"):
            lines.append(f"    fallback_fraction {r['fallback_fraction']:.3f}: that share of the steps "
                         "took a component's Taylor sum (the fallback variant)")
    if paper:
        lines.append("paper: its own code and machine (docs/paper.md); CPU = best of the repeats, "
                     "measured in this run; paper/ours = paper CPU over ours"
                     + "".join(f"; {v} is shown against the paper's {k}" for v, k in KDV_ROW.items()
                               if any(r["integrator"] == v for r in rows)))
    return "\n".join(lines)


def step_cap_lines(problem: str, bases: list[Cell], rows: list[dict]) -> list[str]:
    """Why pure bpl's step is capped on a problem with a stiff linear part, measured: the
    largest frequency omega_max of the linear part, omega_max x bpl's mean step, the mean
    steps over the eps_res searched, and where one bpl step starts to amplify a rotation
    (``stability.amplification_onset``). Empty when there is no bpl row or no linear part."""
    import numpy as np

    from longtime.measure.stability import AMPLIFICATION_GROWTH, amplification_onset

    by = {c.integrator: (c, r) for c, r in zip(bases, rows) if r.get("status") == Status.OK and r.get("mean_dt")}
    if "bpl" not in by or registry.problem_class(problem).linear_part is None:
        return []
    cell, row = by["bpl"]
    p, bpl = build(cell)
    lin = np.zeros(p.dim)
    p.linear_part(p.params, lin)
    omega_max = float(np.max(np.abs(lin[1::2])))
    order = bpl.settings["order"]
    onset = amplification_onset(int(order))
    h = row["mean_dt"]
    lines = [f"why bpl's step is capped on {problem} (measured): the linear part's largest frequency is "
             f"omega_max = {omega_max:.4g}; one bpl step (N = {order}) amplifies some rotation exp(i y) by "
             f"more than {100 * AMPLIFICATION_GROWTH:g} % from y = omega h = {onset:g} on "
             f"(stability.amplification_onset); bpl's mean step {h:.3g} puts the top modes at y = {omega_max * h:.3g}: "
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
            cells.append(f"{column(r.get('cpu_s') if r and r['status'] == Status.OK else None, '14.4f')}")
        g = growth(per, base_size, top_size)
        paper = KDV_GROWTH_128_512.get(scheme)
        lines.append(f"{scheme:14s} " + " ".join(cells) + f" {column(g, '+15.0f')}%"
                     + (f" {paper:+6.0f}%" if paper is not None else f" {'-':>7s}"))
    lines.append("")
    lines.append(f"{'scheme':14s} {'d':>5s} {'mean step':>10s} {metric:>11s} {'steps':>8s} {'rhs evals':>10s}")
    for scheme, per in scaling.items():
        for d in sizes:
            r = per.get(d)
            if r:
                lines.append(f"{scheme:14s} {d:5d} {column(r.get('mean_dt'), '10.3e')} "
                             f"{column(_shown(r, metric), '11.3e')} {column(r.get('steps'), '8d')} "
                             f"{column(r.get('rhs_evals'), '10d')}  {r['status'] if r['status'] != Status.OK else ''}")
    if orders:
        lines += ["", "== bpl: series order N (matched eps_res, base size) ==",
                  f"{'N':>4s} {'CPU s':>9s} {'mean step':>10s} {metric:>11s} {'steps':>8s}"]
        for n, r in sorted(orders.items()):
            lines.append(f"{n:4d} {column(r.get('cpu_s'), '9.4f')} {column(r.get('mean_dt'), '10.3e')} "
                         f"{column(_shown(r, metric), '11.3e')} {column(r.get('steps'), '8d')}  "
                         f"{r['status'] if r['status'] != Status.OK else ''}")
    return "\n".join(lines)


def growth(per: dict[int, dict], base: int, top: int) -> float | None:
    a, b = per.get(base), per.get(top)
    if not a or not b or a["status"] != Status.OK or b["status"] != Status.OK or not a.get("cpu_s"):
        return None
    return 100.0 * (b["cpu_s"] / a["cpu_s"] - 1.0)


# ---------------------------------------------------------------- command


def cmd_match(args) -> int:
    if args.target <= 0 or not math.isfinite(args.target):
        raise InputError(f"--target={args.target} is not valid: must be > 0")
    if args.repeat < 1:
        raise InputError(f"--repeat={args.repeat} is not valid: must be >= 1")
    if len(args.problem) != 1:
        raise InputError(f"-p/--problem takes one problem, got {', '.join(args.problem)}")
    problem = args.problem[0]
    sets = cli_args.single_settings(args.set)
    for scheme in args.integrator:
        accuracy_parameter(scheme)
    bases = expand([problem], args.integrator, t_final=args.t_final, sets=sets)
    pcls = registry.problem_class(problem)
    if args.scaling and "d" not in pcls.parameters:
        raise InputError(f"--scaling varies the parameter d, which problem '{problem}' does not have")
    store = None if args.no_store else Store(args.db)
    out_rows: list[dict] = []
    with recorded_run(store, command_line(args), bases) as run_id:
        matcher = Matcher(store, run_id, args.metric, args.target, args.repeat, args.max_evals,
                          verbose=not args.quiet)
        matched = [matcher.match(c) for c in bases]
        # parsed values (--set gives strings)
        psettings = build(bases[0])[0].settings if bases else pcls().settings
        out_rows += matched
        text = [match_table(matched, problem, psettings, args.metric, args.target)]
        cap = step_cap_lines(problem, bases, matched)
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
    if args.format == "json":
        print(jsontext.dumps(out_rows, default=str))
    else:
        print("\n\n".join(text))
    return 0


def add_parser(subparsers) -> None:
    p = subparsers.add_parser(
        "match", help="schemes at matched accuracy (e.g. KdV: the paper's table) and their scaling",
        description=__doc__.split("\n\n")[1])
    p.add_argument("-p", "--problem", type=cli_args.names, default=["kdv"], metavar="PROBLEM",
                   help="one problem with a reference (default: kdv)")
    p.add_argument("-i", "--integrator", type=cli_args.names, default=DEFAULT_SCHEMES,
                   metavar="SCHEME[,..]", help=f"schemes (default: {','.join(DEFAULT_SCHEMES)})")
    p.add_argument("--target", type=float, default=1e-5, help="error to match (default 1e-5)")
    p.add_argument("--metric", choices=["final_error", "l2_error"], default="final_error",
                   help="final_error: relative error at t_final (KdV: relative L2 in x); "
                        "l2_error: over all samples")
    p.add_argument("--t-final", type=float, default=None, help="final time (default: the problem's)")
    p.add_argument("--set", type=cli_args.key_value, action="append", default=[], metavar="KEY=VALUE",
                   help="other parameters of the problem or schemes, e.g. d=128 (repeatable)")
    p.add_argument("--repeat", type=int, default=3, help="timing runs of each matched point (best kept)")
    p.add_argument("--max-evals", type=int, default=14, help="search runs allowed per scheme")
    p.add_argument("--scaling", action="store_true", help="also run the sizes and the BPL orders")
    p.add_argument("--sizes", type=cli_args.ints("--sizes"), default=[64, 128, 256, 512],
                   help="values of d for --scaling")
    p.add_argument("--orders", type=cli_args.ints("--orders"), default=list(range(4, 15)),
                   help="BPL series orders for --scaling (e.g. 4..14 or 4,6,8)")
    p.add_argument("--out", default="figures", type=cli_args.out_folder("--out"),
                   help="folder of the scaling figure (PNG and SVG)")
    p.add_argument("--no-figure", action="store_true")
    p.add_argument("--format", choices=["table", "json"], default="table")
    p.add_argument("--db", default=None, help=f"SQLite store (default: $LONGTIME_DB or {default_path()})")
    p.add_argument("--no-store", action="store_true", help="do not store the rows")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress lines on stderr")
    p.set_defaults(func=cmd_match)
