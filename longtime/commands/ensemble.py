"""``longtime ensemble``: a chaotic problem's statistical accuracy past its predictability
horizon, per scheme (longtime.measure.ensemble), beside the Lyapunov time
(longtime.measure.lyapunov) that says where that horizon lies."""
from __future__ import annotations

from typing import Any

from longtime.core import cli_args, jsontext
from longtime.core.params import InputError, check_time_span
from longtime.core.progress import Progress
from longtime.core.status import Status
from longtime.execution.cells import DEFAULT_TIME_LIMIT
from longtime.execution.limits import PastLimit, call_limited, default_memory_limit
from longtime.execution.sizes import MAX_STEPS, check_step
from longtime.measure import ensemble


def study(problems: list[str], schemes: list[str], dt: float | None = None, t_final: float | None = None,
          members: int = ensemble.DEFAULT_MEMBERS, size: float = ensemble.DEFAULT_SIZE, seed: int = 1,
          window: float = ensemble.DEFAULT_WINDOW, time_limit: float | None = DEFAULT_TIME_LIMIT,
          memory_limit: int | None = default_memory_limit()) -> list[dict[str, Any]]:
    """One row per problem x scheme that the scheme can treat; each ensemble (its members
    together) runs under ``time_limit`` and ``memory_limit`` as a cell does (limits.call_limited):
    past them its row is ``timeout`` or ``failed``."""
    from longtime.core import registry
    from longtime.core.stepping import FixedStepIntegrator
    from longtime.execution.cells import Cell, build
    from longtime.measure import lyapunov

    if not 2 <= members <= cli_args.MAX_MEMBERS:
        raise InputError(f"--members {members}: expected an integer from 2 to {cli_args.MAX_MEMBERS}")
    if not cli_args.MIN_SIZE <= size < 1:
        raise InputError(f"--size {size:g}: expected a relative perturbation from {cli_args.MIN_SIZE:g} to 1")
    if not 1e-6 <= window <= 1:
        raise InputError(f"--window {window:g}: expected a share of the span from 1e-6 to 1")
    for p in problems:
        if not registry.problem_class(p).chaotic:
            raise InputError(f"-p {p}: not a chaotic problem (ensembles are for problems that declare "
                             f"`chaotic`: {', '.join(n for n, c in registry.problems().items() if c.chaotic)})")
    for s in schemes:
        registry.integrator_class(s)
    for p in problems:  # every member's length, before any member runs
        pcls = registry.problem_class(p)
        tf = pcls.default_t_final if t_final is None else t_final
        step = dt if dt is not None else pcls.default_dt
        check_time_span(pcls.t0, tf, f"problem {p}")
        for s in schemes:  # a fixed step larger than the span, as run refuses it
            check_step(p, s, {} if dt is None else {"dt": dt}, tf)
        if step and not (tf - pcls.t0) / step <= MAX_STEPS:
            raise InputError(f"-p {p}: t_final {tf:g} with the step {step:g} is about {(tf - pcls.t0) / step:.3g} "
                             f"steps a member, over the limit of {MAX_STEPS:.0e}")
    rows = []
    for p in problems:
        for s in schemes:
            problem, scheme = build(Cell(p, s))
            reason = scheme.incompatibility(problem)
            row: dict[str, Any] = {"problem": p, "integrator": s}
            if reason:
                rows.append({**row, "status": Status.SKIPPED, "message": reason})
                continue
            if dt is not None and isinstance(scheme, FixedStepIntegrator):
                problem, scheme = build(Cell(p, s, {}, {"dt": dt}))
            tf = problem.default_t_final if t_final is None else t_final
            row.update(dt=scheme.dt_for(problem) if isinstance(scheme, FixedStepIntegrator) else None, t_final=tf)
            try:
                row.update(call_limited(ensemble.measure, problem, scheme, tf, members, size, seed, window,
                                        time_limit=time_limit, memory_limit=memory_limit))
            except PastLimit as exc:
                rows.append({**row, "status": Status.TIMEOUT, "message": f"the ensemble stopped: {exc}"})
                continue
            except MemoryError as exc:
                rows.append({**row, "status": Status.FAILED, "message": f"the ensemble ran out of memory: {exc}"})
                continue
            found = lyapunov.measure(problem)
            row["lyapunov_time"] = found["lyapunov_time"]
            row["span_lyapunov"] = (tf - problem.t0) / found["lyapunov_time"] if found["lyapunov_time"] else None
            row["verdict"] = ensemble.verdict(row)
            row["status"] = Status.OK if row["ensemble.distance"] is not None else Status.FAILED
            rows.append(row)
    return rows


def _g(x) -> str:
    return "-" if x is None else (f"{x:.3g}" if isinstance(x, float) else str(x))


def markdown(rows: list[dict[str, Any]]) -> str:
    head = ["problem", "scheme", "dt", "t_final", "Lyapunov times", "observable", "members", "W1 / std",
            "ensembles' own spread", "verdict"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        if r.get("status") == Status.SKIPPED:
            lines.append(f"| {r['problem']} | {r['integrator']} | skipped: {r['message']} |" + " |" * (len(head) - 3))
            continue
        lines.append("| " + " | ".join([r["problem"], r["integrator"], _g(r.get("dt")), _g(r.get("t_final")),
                                        _g(r.get("span_lyapunov")), _g(r.get("ensemble.observable")),
                                        _g(r.get("ensemble.members")), _g(r.get("ensemble.distance")),
                                        _g(r.get("ensemble.floor")), r.get("verdict", "")]) + " |")
    return "\n".join(lines)


def cmd_ensemble(args) -> int:
    if args.dt is not None and len(args.dt) != 1:
        raise InputError("--dt: give one step")
    if args.t_final is not None and len(args.t_final) != 1:
        raise InputError("--t-final: give one final time")
    with Progress().phase("ensemble", detail=f"{args.members} members a scheme, heyoka's beside them",
                          announce=False):
        rows = study(args.problem, args.integrator, dt=args.dt[0] if args.dt else None,
                     t_final=args.t_final[0] if args.t_final else None, members=args.members, size=args.size,
                     seed=args.seed, window=args.window, time_limit=args.time_limit or None)
    print(jsontext.dumps(rows) if args.format == "json" else markdown(rows))
    return 0


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("ensemble", help="a chaotic problem's statistical accuracy: the distance between "
                                                "the distributions a scheme's and heyoka's ensembles visit",
                              description=__doc__.splitlines()[0])
    p.add_argument("-p", "--problem", type=cli_args.names, required=True, metavar="PROBLEM[,..]")
    p.add_argument("-i", "--integrator", type=cli_args.names, required=True, metavar="SCHEME[,..]")
    p.add_argument("--dt", type=cli_args.floats("--dt"), default=None, metavar="X",
                   help="the step of fixed-step schemes")
    p.add_argument("--t-final", type=cli_args.floats("--t-final"), default=None, metavar="T")
    p.add_argument("--members", type=cli_args.members("--members", 2), default=ensemble.DEFAULT_MEMBERS, metavar="K")
    p.add_argument("--size", type=cli_args.bounded("--size", cli_args.MIN_SIZE, 1.0), default=ensemble.DEFAULT_SIZE,
                   help="relative size of the perturbations")
    p.add_argument("--seed", type=cli_args.seed(), default=1)
    p.add_argument("--window", type=cli_args.share("--window"), default=ensemble.DEFAULT_WINDOW,
                   help="the last share of the span the distributions are taken over")
    p.add_argument("--time-limit", type=cli_args.seconds("--time-limit", allow_zero=True),
                   default=DEFAULT_TIME_LIMIT, metavar="SECONDS",
                   help=f"seconds one ensemble (its members together) may take, as a cell's limit "
                        f"(default {DEFAULT_TIME_LIMIT:g}; 0: no limit)")
    p.add_argument("--format", choices=["markdown", "json"], default="markdown")
    p.set_defaults(func=cmd_ensemble)


def section(quick: bool) -> str:
    """The reproduction report's section on chaos: Lyapunov times and ensembles past the
    predictability horizon, on the chaotic problems of the paper and the canon."""
    cases = [("double-pendulum", ["rk4", "euler"], 0.001, 100.0),
             ("henon-heiles", ["verlet", "rk4"], 0.05, 1000.0),
             ("figure-eight-perturbed", ["verlet", "rk4"], None, None)]
    members = 6 if quick else 16
    parts = []
    for problem, schemes, dt, t_final in cases:
        rows = study([problem], schemes, dt=dt, t_final=t_final, members=members)
        parts += [f"`longtime ensemble -p {problem} -i {','.join(schemes)}"
                  + (f" --dt {dt:g}" if dt else "") + (f" --t-final {t_final:g}" if t_final else "")
                  + f" --members {members}`", "", markdown(rows), ""]
    return "\n".join([
        "Past a few Lyapunov times a pointwise error is O(1) for every scheme; what can still be right is the "
        "distribution the orbit visits. W1 / std: the Wasserstein distance between the scheme's and heyoka's "
        "ensembles (last half of the run), in units of heyoka's standard deviation; beside it, the same distance "
        "between two heyoka ensembles of other seeds (docs/metrics.md, \"Chaos\"). \"Lyapunov times\" is the "
        "span in Lyapunov times where a Lyapunov time is determined (\"-\": no sign of chaos on the measured span)."
        + (" (**quick**: 6 members a scheme.)" if quick else ""), "", *parts])
