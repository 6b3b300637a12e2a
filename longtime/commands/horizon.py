"""``longtime horizon``: the paper's exponentially long times, measured.

The experiment: Henon-Heiles just below its escape energy 1/6 (energy 1/6 - gap). The exact
orbit is bounded for ever (its energy is conserved and the level set below 1/6 is closed);
a numerical orbit escapes (and then runs off to infinity: a diverged run) only once the
energy it conserves has drifted past the saddles. Each scheme runs an ensemble of members
(initial y0 spread evenly over [-0.25, 0.35], x = 0, py = 0, px from the energy) at each
step dt up to t_final; a member's breakdown is its escape, or with ``--threshold`` the first
time its relative energy error reaches that (longtime.measure.horizon). T*(dt) is the inverse
breakdown rate over the ensemble, and
ln T* is fitted against 1/dt (the exponential law of backward error analysis) and ln dt (a
power law). The members run as tasks on a process pool, as the round-off study's do.
"""
from __future__ import annotations

import math
import sys
from typing import Any

import numpy as np

from longtime.core import cli_args, jsontext
from longtime.core.params import InputError
from longtime.core.status import Status
from longtime.execution.cells import DEFAULT_TIME_LIMIT
from longtime.execution.sizes import MAX_STEPS
from longtime.measure.horizon import estimate, fit_law, judge, local_slopes, verdict_text

PROBLEM = "henon-heiles"
ESCAPE_ENERGY = 1.0 / 6.0
DEFAULT_GAP = 0.02
DEFAULT_SCHEMES = ("verlet", "euler")
# 1/dt from 1.11 to 1.67: wide enough that steps outside the range where verlet escapes
# within t_final bound its T* from below (a narrower span, 1.11 to 1.33, cannot tell an
# exponential law from a power law dt^-11.5)
DEFAULT_DTS = (0.9, 0.85, 0.8, 0.75, 0.7, 0.65, 0.6)
DEFAULT_MEMBERS = 24
DEFAULT_T_FINAL = 5e6
Y0_RANGE = (-0.25, 0.35)
MAX_SAMPLES = 4001


def member_states(members: int) -> list[float]:
    """The members' initial y0 (evenly spread; each is valid for every energy in (0.1, 1/6))."""
    return [float(y) for y in np.linspace(*Y0_RANGE, members)]


def run_member(scheme: str, dt: float, energy: float, y0: float, t_final: float,
               threshold: float | None, time_limit: float | None = DEFAULT_TIME_LIMIT) -> tuple[float | None, float]:
    """One member: (its breakdown time, or None if it held to t_final; its largest |H - H0|
    before it). Its run is a cell's: under ``time_limit`` and the memory limit of a cell
    (limits.call_limited), a member past them an error that names it."""
    from longtime.execution.cells import Cell, integrate_cell
    from longtime.execution.limits import PastLimit, call_limited, default_memory_limit
    from longtime.measure.horizon import breakdown_time
    from longtime.measure.metrics import relative_error

    cell = Cell(PROBLEM, scheme, {"energy": energy, "y0": y0}, {"dt": dt}, t_final)
    try:
        problem, traj = call_limited(integrate_cell, cell, MAX_SAMPLES, time_limit=time_limit,
                                     memory_limit=default_memory_limit())
    except PastLimit as exc:
        raise RuntimeError(f"{scheme} at dt={dt}, y0={y0}: {exc} (--time-limit)") from None
    if traj.status == Status.FAILED:
        raise RuntimeError(f"{scheme} at dt={dt}, y0={y0}: {traj.message}")
    escaped = traj.t_reached if traj.status == Status.DIVERGED else None
    t, u = traj.t, traj.u
    finite = np.all(np.isfinite(u), axis=1)
    H = problem.invariants(t[finite], u[finite])["H"]
    err = relative_error(H)
    when = breakdown_time(t[finite], err, threshold, escaped)
    before = t[finite] <= (when if when is not None else np.inf)
    return when, float(np.max(np.abs(H[before] - H[0]))) if np.any(before) else 0.0


def study(schemes=DEFAULT_SCHEMES, dts=DEFAULT_DTS, members: int = DEFAULT_MEMBERS, t_final: float = DEFAULT_T_FINAL,
          gap: float = DEFAULT_GAP, threshold: float | None = None, jobs: int = 0,
          progress: bool = True, time_limit: float | None = DEFAULT_TIME_LIMIT) -> dict[str, Any]:
    """Every scheme's T*(dt) and the two fits, as one JSON-ready dict; each member's run under
    ``time_limit`` seconds (None: none) as a cell's."""
    from longtime.core import registry
    from longtime.execution.pool import run_tasks

    for s in schemes:
        registry.integrator_class(s)  # an unknown name fails before anything runs
    if not 0 < gap < 0.06:
        raise InputError(f"--gap {gap:g}: expected 0 < gap < 0.06 (the energy 1/6 - gap keeps the orbits' "
                         "initial states valid)")
    if not 2 <= members <= cli_args.MAX_MEMBERS:
        raise InputError(f"--members {members}: expected an integer from 2 to {cli_args.MAX_MEMBERS}")
    if len(set(dts)) < 2 or not all(0 < d < math.inf for d in dts):
        raise InputError("--dt: expected at least 2 distinct positive finite steps")
    if not max(dts) < t_final < math.inf:
        raise InputError(f"--t-final {t_final:g}: expected a finite time more than the largest step")
    if not t_final / min(dts) <= MAX_STEPS:
        raise InputError(f"--t-final {t_final:g} with --dt {min(dts):g}: about {t_final / min(dts):.3g} steps a "
                         f"member, over the limit of {MAX_STEPS:.0e}")
    energy = ESCAPE_ENERGY - gap
    tasks = [(s, float(dt), energy, y0, float(t_final), threshold, time_limit)
             for s in schemes for dt in sorted(set(dts), reverse=True) for y0 in member_states(members)]
    found: dict[tuple, tuple[float | None, float]] = {}
    for n, (task, result) in enumerate(run_tasks(run_member, tasks, jobs), 1):
        found[task] = result
        if progress:
            print(f"horizon: {n}/{len(tasks)} runs done", file=sys.stderr, end="\r", flush=True)
    if progress:
        print(file=sys.stderr)
    out: dict[str, Any] = {"problem": PROBLEM, "energy": energy, "gap": gap, "threshold": threshold,
                           "members": members, "t_final": float(t_final), "schemes": {}}
    for s in schemes:
        points = []
        for dt in sorted(set(dts), reverse=True):
            results = [found[(s, float(dt), energy, y0, float(t_final), threshold, time_limit)]
                       for y0 in member_states(members)]
            points.append(estimate(dt, [r[0] for r in results], float(t_final), swings=[r[1] for r in results]))
        exp_fit, power_fit = fit_law(points, "exponential"), fit_law(points, "power")
        held = [p.held_swing for p in points if p.held_swing is not None]
        # an escape is the breakdown only without a threshold; then the held orbits' swing decides
        judged = judge(exp_fit, power_fit, max(held) if held and threshold is None else None, gap)
        slopes = local_slopes(points)
        out["schemes"][s] = {"points": [p.as_dict() for p in points], "exponential": exp_fit, "power": power_fit,
                             "judged": judged, "local_slopes": slopes,
                             "verdict": verdict_text(s, exp_fit, power_fit, judged, slopes)}
    return out


def _g(x: float | None) -> str:
    return "-" if x is None else f"{x:.3g}"


def markdown(result: dict[str, Any]) -> str:
    cause = "escape" + (f" or a relative energy error >= {result['threshold']:.3g}" if result["threshold"] else "")
    lines = [f"Henon-Heiles at energy 1/6 - {result['gap']:g} = {result['energy']:.6g}; breakdown: {cause}; "
             f"{result['members']} members to t = {result['t_final']:g} each.", "",
             "| scheme | dt | 1/dt | broke down | T* | T* 95 % | median breakdown | held orbits' max abs(H - H0) |",
             "|---|---|---|---|---|---|---|---|"]
    for s, r in result["schemes"].items():
        for p in r["points"]:
            lo, hi = p["t_star_ci"]
            t_star = _g(p["t_star"]) if p["t_star"] is not None else f"> {lo:.3g}"
            lines.append(f"| {s} | {p['dt']:g} | {1 / p['dt']:.3g} | {p['events']}/{p['members']} | {t_star} | "
                         f"{_g(lo)} .. {_g(hi)} | {_g(p['median_t'])} | {_g(p.get('held_swing'))} |")
    lines.append("")
    lines += [f"- {r['verdict']}" for r in result["schemes"].values()]
    return "\n".join(lines)


def cmd_horizon(args) -> int:
    result = study(schemes=args.integrator or DEFAULT_SCHEMES, dts=args.dt or DEFAULT_DTS, members=args.members,
                   t_final=args.t_final, gap=args.gap, threshold=args.threshold, jobs=args.jobs,
                   time_limit=args.time_limit or None)
    if args.format == "json":
        print(jsontext.dumps(result, default=float))
    else:
        print(markdown(result))
    return 0


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("horizon", help="the breakdown time T*(dt) of symplectic and other schemes: "
                                               "is it exponentially long in 1/dt?",
                              description=__doc__.splitlines()[0])
    p.add_argument("-i", "--integrator", type=cli_args.names, default=None, metavar="SCHEME[,..]",
                   help=f"schemes (default: {','.join(DEFAULT_SCHEMES)})")
    p.add_argument("--dt", type=cli_args.floats("--dt"), default=None, metavar="X[,..]",
                   help=f"steps (default: {','.join(f'{d:g}' for d in DEFAULT_DTS)})")
    p.add_argument("--members", type=cli_args.members("--members", 2), default=DEFAULT_MEMBERS, metavar="K",
                   help="runs per scheme and step")
    p.add_argument("--t-final", type=cli_args.positive_number("--t-final"), default=DEFAULT_T_FINAL, metavar="T",
                   help=f"how long each member runs (default {DEFAULT_T_FINAL:g})")
    p.add_argument("--gap", type=cli_args.positive_number("--gap"), default=DEFAULT_GAP,
                   help="the energy's distance below the escape "
                        f"energy 1/6 (default {DEFAULT_GAP:g})")
    p.add_argument("--threshold", type=cli_args.positive_number("--threshold"), default=None,
                   help="a relative energy error that also counts as a breakdown (default: escapes only)")
    p.add_argument("--jobs", type=cli_args.jobs, default=0, help="worker processes (default: one per core)")
    p.add_argument("--time-limit", type=cli_args.seconds("--time-limit", allow_zero=True),
                   default=DEFAULT_TIME_LIMIT, metavar="S",
                   help=f"each member's limit in seconds, as a cell's (default {DEFAULT_TIME_LIMIT:g}; 0: none)")
    p.add_argument("--format", choices=["markdown", "json"], default="markdown")
    p.set_defaults(func=cmd_horizon)


def section(quick: bool, jobs: int = 0) -> str:
    """The reproduction report's section on the paper's exponentially long times."""
    if quick:
        schemes, dts, members, t_final = ("verlet",), (0.9, 0.875, 0.85, 0.825), 8, 2e5
    else:
        schemes, dts, members, t_final = DEFAULT_SCHEMES, DEFAULT_DTS, DEFAULT_MEMBERS, DEFAULT_T_FINAL
    result = study(schemes=schemes, dts=dts, members=members, t_final=t_final, jobs=jobs, progress=False)
    command = (f"longtime horizon -i {','.join(schemes)} --dt {','.join(f'{d:g}' for d in dts)} "
               f"--members {members} --t-final {t_final:g}")
    return "\n".join([
        f"Made by `{command}`" + (" (**quick**: 4 steps, 8 members to t = 2e5; the full report runs the "
                                  "default 7 steps, 24 members to 5e6, and explicit Euler beside)" if quick else "")
        + ". The paper: a symplectic scheme keeps its energy error O(dt^r) for times up to about "
          "e^(gamma/dt) (docs/metrics.md, \"Exponentially long times\").", "", markdown(result)])
