"""Round-off, measured: Brouwer's law (error ~ t^0.5) or a linear drift, per configuration.

Where a scheme conserves an invariant exactly in exact arithmetic (the energy of
``harmonic`` under the implicit midpoint rule and Gauss methods, a quadratic invariant of
a linear problem; the angular momentum of ``kepler`` under Gauss methods and under
splitting methods, whose kicks are central and drifts free), all that invariant's error
is round-off. Each configuration (scheme x settings: plain, ``compensated=true``, and for
implicit schemes also ``stop=brouwer``) runs ``steps`` steps of dt = 0.01 once from the
problem's initial state (alpha of that run, ``longtime.measure.growth``) and as an ensemble of K
runs from initial states perturbed by a seeded relative 1e-12 (rng(seed, member) normal
factors): the RMS over the members of the invariant's error at each sample time, and the
alpha of that RMS. The ensemble's members run as tasks on a process pool (``jobs``) or on
a Dask cluster (``scheduler``); the RMS is formed when all are in. Beside them: heyoka's
Taylor integrator (tol = machine epsilon, high_accuracy) over the same span, sampled at
the same log- and evenly spaced times.

Nothing is tuned: the table reports what each configuration does.
"""
from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from longtime.core import cli_args, jsontext
from longtime.core.params import InputError
from longtime.core.status import Status
from longtime.execution.sizes import MAX_STEPS
from longtime.measure.growth import growth_fields

PERTURBATION = 1e-12
DT = 0.01
MAX_SAMPLES = 20_001


@dataclass(frozen=True)
class Config:
    problem: str
    invariant: str
    scheme: str
    settings: dict[str, Any] = field(default_factory=dict)

    @property
    def label(self) -> str:
        return ", ".join(f"{k}={v}" for k, v in sorted(self.settings.items())) or "plain"


def configurations() -> list[Config]:
    """The pairs whose invariant is conserved exactly in exact arithmetic, each plain, with
    compensated summation, and (implicit schemes) with the Brouwer stopping rule as well."""
    implicit = {"stop": "brouwer", "compensated": True}
    out = []
    for problem, invariant, schemes in (("harmonic", "H", ("midpoint", "gauss4")),
                                        ("kepler", "L", ("gauss4", "verlet"))):
        for scheme in schemes:
            variants = [{}, {"compensated": True}]
            if scheme in ("midpoint", "gauss4", "gauss6"):
                variants.append(implicit)
            out += [Config(problem, invariant, scheme, v) for v in variants]
    return out


def run_member(config: Config, steps: int, member: int, seed: int) -> dict[str, Any]:
    """One run of ``config``: member -1 from the problem's initial state, member k >= 0 from
    it perturbed by rng([seed, k]). Returns the sample times, the invariant's relative
    error there, and the cost."""
    from longtime.execution.cells import Cell, build
    from longtime.measure.metrics import relative_error

    problem, scheme = build(Cell(config.problem, config.scheme, {}, {"dt": DT, **config.settings}))
    if member >= 0:
        rng = np.random.default_rng([seed, member])
        problem.u0 = problem.u0 * (1.0 + PERTURBATION * rng.standard_normal(problem.dim))
    traj = scheme.integrate(problem, problem.t0 + steps * DT, max_samples=MAX_SAMPLES)
    err = relative_error(problem.invariants(traj.t, traj.u)[config.invariant])
    return {"t": traj.t, "err": err, "cpu_s": traj.cpu_s, "status": traj.status, "steps": traj.steps,
            "nl_iters": traj.counters.get("nl_iters", 0)}


def _run_task(index: int, config: Config, steps: int, member: int, seed: int) -> dict[str, Any]:
    return run_member(config, steps, member, seed)


def study(steps: int = 10**7, ensemble: int = 8, seed: int = 1, jobs: int = 0, scheduler: str | None = None,
          configs: list[Config] | None = None, heyoka: bool = True, progress: bool = True) -> list[dict]:
    """One row per configuration (and one per problem for heyoka): alpha of the single run
    and of the ensemble's RMS error, with their classes, the final errors and the CPU."""
    if steps < 100:
        raise InputError(f"steps={steps} is not valid: expected an integer >= 100")
    if ensemble < 0:
        raise InputError(f"ensemble={ensemble} is not valid: expected an integer >= 0")
    configs = configs or configurations()
    # a task: (config index, config, steps, member, seed); member -1 is the unperturbed run
    tasks = [(i, c, steps, m, seed) for i, c in enumerate(configs) for m in range(-1, ensemble)]
    results: list[dict[int, dict]] = [{} for _ in configs]
    from longtime.execution.pool import run_tasks

    for n, ((i, _, _, member, _), result) in enumerate(run_tasks(_run_task, tasks, jobs, scheduler), 1):
        results[i][member] = result
        if progress:
            print(f"roundoff: {n}/{len(tasks)} runs done", file=sys.stderr, end="\r", flush=True)
    if progress:
        print(file=sys.stderr)
    rows = []
    for i, config in enumerate(configs):
        single = results[i][-1]
        t0 = float(single["t"][0])
        row = {"problem": config.problem, "invariant": config.invariant, "scheme": config.scheme,
               "settings": config.label, "steps": single["steps"], "status": single["status"],
               "t_final": float(single["t"][-1]), "cpu_s": single["cpu_s"],
               "nl_iters_per_step": single["nl_iters"] / max(1, single["steps"])}
        fit = growth_fields("e", single["t"], single["err"], t0, steps=single["steps"])
        row.update(alpha=fit["e.growth"], alpha_ci=fit["e.growth_ci"], law=fit["e.growth_class"],
                   error_max=float(np.max(single["err"])))
        members = [results[i][m] for m in range(ensemble)]
        row["ensemble"] = ensemble
        if members:
            if any(not np.array_equal(m["t"], single["t"]) for m in members):
                raise RuntimeError("ensemble members sampled at different times")  # same dt, same steps
            rms = np.sqrt(np.mean([m["err"] ** 2 for m in members], axis=0))
            fit = growth_fields("rms", single["t"], rms, t0, steps=single["steps"])
            row.update(rms_alpha=fit["rms.growth"], rms_alpha_ci=fit["rms.growth_ci"],
                       rms_law=fit["rms.growth_class"], rms_final=float(rms[-1]),
                       ensemble_cpu_s=float(sum(m["cpu_s"] for m in members)))
        rows.append(row)
    if heyoka:
        for problem_name, invariant in dict.fromkeys((c.problem, c.invariant) for c in configs):
            first = [c.problem for c in configs].index(problem_name)
            rows.append(heyoka_row(problem_name, invariant, results[first][-1]["t"]))
    return rows


def heyoka_row(problem_name: str, invariant: str, times: np.ndarray) -> dict[str, Any]:
    """heyoka at machine tolerance with high_accuracy (the references' integrator) over the
    schemes' span, sampled at their times; a row like the schemes' (no ensemble)."""
    from longtime.core import registry
    from longtime.measure.metrics import relative_error
    from longtime.measure.reference_runs import ReferenceUnavailable, propagate

    problem = registry.problem_class(problem_name)()
    row: dict[str, Any] = {"problem": problem_name, "invariant": invariant, "scheme": "heyoka",
                           "settings": "tol=eps, high_accuracy", "t_final": float(times[-1]), "ensemble": 0}
    try:
        import heyoka  # noqa: F401
    except ImportError:
        row.update(status=Status.SKIPPED, message="heyoka is not installed")
        return row
    c0 = time.process_time()
    try:
        states, stopped = propagate(problem, np.asarray(times, dtype=float), "double", budget_s=600.0)
    except ReferenceUnavailable as exc:
        row.update(status=Status.FAILED, message=str(exc))
        return row
    row["cpu_s"] = time.process_time() - c0
    t = times[:len(states)]
    err = relative_error(problem.invariants(t, states)[invariant])
    fit = growth_fields("e", t, err, float(times[0]))
    row.update(status=Status.OK if stopped is None else Status.TIMEOUT, alpha=fit["e.growth"],
               alpha_ci=fit["e.growth_ci"], law=fit["e.growth_class"], error_max=float(np.max(err)))
    return row


def _fmt(x: Any, digits: int = 3) -> str:
    if x is None:
        return "-"
    if isinstance(x, float):
        return f"{x:.{digits}g}"
    if isinstance(x, list):
        return "[" + ", ".join(_fmt(v) for v in x) + "]"
    return str(x)


def markdown(rows: list[dict]) -> str:
    head = ["problem", "invariant", "scheme", "settings", "alpha (95 % CI)", "law", "max error",
            "ensemble RMS alpha (CI)", "RMS law", "RMS at t_f", "CPU s (one run)"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        lines.append("| " + " | ".join([
            r["problem"], r["invariant"], r["scheme"], r.get("settings", ""),
            f"{_fmt(r.get('alpha'))} {_fmt(r.get('alpha_ci'))}" if r.get("alpha") is not None else r.get("status", "-"),
            _fmt(r.get("law")), _fmt(r.get("error_max")),
            f"{_fmt(r.get('rms_alpha'))} {_fmt(r.get('rms_alpha_ci'))}" if r.get("rms_alpha") is not None else "-",
            _fmt(r.get("rms_law")), _fmt(r.get("rms_final")), _fmt(r.get("cpu_s"))]) + " |")
    return "\n".join(lines)


def explain(rows: list[dict], steps: int, ensemble: int, seed: int) -> str:
    """The text around the table: what was run and which configurations reach Brouwer."""
    sqrt = [f"{r['scheme']} ({r['settings']}) on {r['problem']}" for r in rows
            if r.get("scheme") != "heyoka" and (r.get("rms_law") or r.get("law")) == "sqrt"]
    linear = [f"{r['scheme']} ({r['settings']}) on {r['problem']}" for r in rows
              if r.get("scheme") != "heyoka"
              and (r.get("rms_law") or r.get("law")) in ("linear", "quadratic", "faster")]
    return "\n".join([
        f"{steps:.3g} steps of dt = {DT} per run; ensemble of {ensemble} initial states perturbed by a relative "
        f"{PERTURBATION:g} (seed {seed}); alpha of e ~ C t^alpha fitted on the running maximum over the last "
        "two decades (longtime.measure.growth); `law` classifies alpha (sqrt: 0.25 to 0.75, Brouwer's law is 0.5; "
        "undetermined where the data support no class: docs/metrics.md).",
        "",
        "- Brouwer's law (RMS, or the single run without an ensemble): " + ("; ".join(sqrt) or "none") + ".",
        "- Linear or faster drift: " + ("; ".join(linear) or "none") + ".",
        "- Why (the mechanism, from Hairer, McLachlan and Razakarivony 2008; the table is what this run "
        "measured): an implicit scheme whose stage iteration stops on a tolerance (`stop=round-off`, the "
        "default: increment below half an ulp of the state's scale, or stalled) leaves an iteration error "
        "of one sign in every step, which adds up linearly; `stop=brouwer` iterates until the increment "
        "is 0 or stops decreasing. Compensated "
        "summation (`compensated=true`) removes the rounding of u + increment, the largest round-off of a "
        "step; alone, on an implicit scheme, it can leave the tolerance stop's bias as the largest error "
        "(linear, but smaller). What remains with both (the rounding of the stage values and of the increment "
        "itself) is not compensated here; a configuration that still drifts with both presumably drifts from "
        "that (this study does not isolate it).",
        "- Errors of a few ulps are quantised (multiples of 2^-52 relative), which makes alpha noisy on short "
        "runs; the ensemble's RMS is the steadier figure.",
    ])


def spread(args) -> int:
    """``--spread FIELD``: the round-off spread of one figure of a chaotic run."""
    from longtime.execution.cells import Cell, build
    from longtime.measure.ensemble import field_spread

    if not (args.problem and args.integrator and args.t_final):
        raise InputError("--spread needs -p PROBLEM, -i SCHEME and --t-final T (and --dt for a fixed step)")
    settings = {"dt": args.dt} if args.dt is not None else {}
    problem, scheme = build(Cell(args.problem, args.integrator, {}, settings))
    step = args.dt or problem.default_dt
    if step and not (args.t_final - problem.t0) / step <= MAX_STEPS:
        raise InputError(f"--t-final {args.t_final:g} with the step {step:g}: about "
                         f"{(args.t_final - problem.t0) / step:.3g} steps a run, over the limit of {MAX_STEPS:.0e}")
    if args.ensemble < 2:
        raise InputError(f"--ensemble {args.ensemble}: --spread needs an integer >= 2")
    out = field_spread(problem, scheme, args.t_final, args.spread, args.ensemble, args.size, args.seed)
    out.update(problem=args.problem, scheme=args.integrator, dt=args.dt, t_final=args.t_final)
    if args.format == "json":
        print(jsontext.dumps(out))
    else:
        print(f"{args.problem} x {args.integrator} (dt {args.dt}, t_final {args.t_final:g}): {args.spread} = "
              f"{out['value']:.6g} from the initial state; {out['min']:.6g} .. {out['max']:.6g} over "
              f"{args.ensemble} initial states perturbed by a relative {args.size:g} (seed {args.seed})")
    return 0


def cmd_roundoff(args) -> int:
    if args.spread:
        return spread(args)

    if args.scheduler:  # an address where no Dask scheduler answers: one line before any member runs
        from longtime.execution.dask_executor import check_scheduler

        check_scheduler(args.scheduler)
    rows = study(steps=int(args.steps), ensemble=args.ensemble, seed=args.seed, jobs=args.jobs,
                 scheduler=args.scheduler, heyoka=not args.no_heyoka)
    if args.format == "json":
        print(jsontext.dumps(rows))
    else:
        print(markdown(rows))
        print()
        print(explain(rows, int(args.steps), args.ensemble, args.seed))
    return 0


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("roundoff", help="round-off study: Brouwer's law or linear drift per scheme and setting",
                              description=__doc__.splitlines()[0])
    p.add_argument("--steps", type=cli_args.bounded("--steps", 1, MAX_STEPS), default=1e7,
                   help="steps per run (dt = 0.01; default 1e7)")
    p.add_argument("--ensemble", type=cli_args.members("--ensemble", 0), default=8, metavar="K",
                   help="perturbed members per configuration")
    p.add_argument("--seed", type=cli_args.seed(), default=1, metavar="S", help="seed of the perturbations")
    p.add_argument("--jobs", type=cli_args.jobs, default=0, help="worker processes (default: one per core)")
    p.add_argument("--scheduler", type=cli_args.scheduler, default=None, metavar="ADDRESS",
                   help="run the members on this Dask cluster")
    p.add_argument("--no-heyoka", action="store_true", help="leave out heyoka's row")
    p.add_argument("--format", choices=["markdown", "json"], default="markdown")
    g = p.add_argument_group("the round-off spread of one figure of a chaotic run (--spread)")
    g.add_argument("--spread", metavar="FIELD", default=None,
                   help="a row field measured without a reference (I.max, H.max): its value over --ensemble "
                        "initial states perturbed by --size")
    g.add_argument("-p", "--problem", default=None, metavar="PROBLEM")
    g.add_argument("-i", "--integrator", default=None, metavar="SCHEME")
    g.add_argument("--dt", type=cli_args.positive_number("--dt"), default=None)
    g.add_argument("--t-final", type=cli_args.positive_number("--t-final"), default=None, metavar="T")
    g.add_argument("--size", type=cli_args.bounded("--size", cli_args.MIN_SIZE, 1.0), default=1e-14,
                   help="relative perturbation (default 1e-14)")
    p.set_defaults(func=cmd_roundoff)


def section(quick: bool, jobs: int = 0) -> str:
    """The reproduction report's round-off section (``longtime reproduce``)."""
    steps, ensemble, seed = (10**6, 4, 1) if quick else (10**7, 8, 1)
    rows = study(steps=steps, ensemble=ensemble, seed=seed, jobs=jobs, progress=False)
    command = f"longtime roundoff --steps {steps:.0e} --ensemble {ensemble} --seed {seed}"
    return "\n".join([
        f"Made by `{command}`" + (" (**quick**: 10^6 steps, 4 members; the full report runs 10^7 and 8)"
                                  if quick else "") + ".", "", markdown(rows), "",
        explain(rows, steps, ensemble, seed)])
