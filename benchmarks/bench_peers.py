"""Our kernels against the library peers on equal methods: the equal-method table.

- Dormand-Prince 5(4): our ``rk45`` kernel against ``scipy-rk45`` (solve_ivp's RK45) and
  ``diffrax-dopri5``, the same tableau at equal tolerance, on kepler and henon-heiles;
- our implicit schemes (``gauss4``, ``gauss6``, ``midpoint``; fixed step) against SUNDIALS'
  CVODE (``cvode-bdf``, ``cvode-adams``; tolerance) and scipy's ``scipy-radau`` on the stiff
  problems: kdv and fpu (stiff springs, omega = 50).

(The suite has no DOP853 kernel of its own: ``dop853`` is scipy's, and diffrax's Dopri8 is
another 8(7) pair, so there is no equal-method row for it.)

Each scheme runs a ladder of tolerances (or steps), timed as the matrix times a cell
(``Timing``: repeats, the minimum), with its error against the problem's reference (the
relative L2 error over the samples, ``l2_error``). For each pair it prints the ratio of our
CPU to the peer's per step (at the middle tolerance, or our middle step), and at equal
error (both cost curves interpolated log-log at the geometric middle of the errors both
reach), with the error it is taken at. A ratio below 1: ours is cheaper.

    python benchmarks/bench_peers.py                # the full ladders (a few minutes)
    python benchmarks/bench_peers.py --size small   # short horizons, three rungs each
"""
from __future__ import annotations

import argparse
import math

from longtime.core import registry
from longtime.core.timing import Timing
from longtime.measure.metrics import evaluate
from longtime.measure.reference import reference_states

# (problem, problem settings, t_final by size, ours and its ladder, peers and their ladder)
TOLS = (1e-5, 1e-7, 1e-9, 1e-11)
PAIRS = [
    ("kepler", {}, {"small": 20.0, "full": 200.0}, ("rk45", "tol", TOLS),
     [("scipy-rk45", "tol", TOLS), ("diffrax-dopri5", "tol", TOLS)]),
    ("henon-heiles", {}, {"small": 50.0, "full": 500.0}, ("rk45", "tol", TOLS),
     [("scipy-rk45", "tol", TOLS), ("diffrax-dopri5", "tol", TOLS)]),
    ("kdv", {}, {"small": 0.5, "full": 5.0}, ("gauss4", "dt", (4e-3, 2e-3, 1e-3, 5e-4)),
     [("cvode-bdf", "tol", (1e-4, 1e-6, 1e-8, 1e-10)), ("scipy-radau", "tol", (1e-4, 1e-6, 1e-8))]),
    ("fpu", {}, {"small": 10.0, "full": 100.0}, ("gauss4", "dt", (2e-2, 1e-2, 5e-3, 2.5e-3)),
     [("cvode-bdf", "tol", (1e-4, 1e-6, 1e-8, 1e-10)), ("cvode-adams", "tol", (1e-4, 1e-6, 1e-8, 1e-10))]),
    ("fpu", {}, {"small": 10.0, "full": 100.0}, ("gauss6", "dt", (4e-2, 2e-2, 1e-2, 5e-3)),
     [("cvode-bdf", "tol", (1e-4, 1e-6, 1e-8, 1e-10))]),
]


def ladder(problem, scheme: str, setting: str, values, t_final: float, rungs: int) -> list[dict]:
    """One row per rung: the setting, CPU s, steps and error (skipped schemes: none)."""
    cls = registry.integrator_class(scheme)
    rows = []
    for value in values[:rungs]:
        integrator = cls(**{setting: value})
        if integrator.incompatibility(problem):
            return []
        integrator.integrate(problem, problem.t0 + (t_final - problem.t0) / 100, max_samples=16)  # compile
        traj = integrator.integrate(problem, t_final, max_samples=2001, timing=Timing())
        if traj.status != "ok":
            continue
        row = evaluate(problem, traj, reference_states(problem, traj.t))
        rows.append({"value": value, "cpu_s": traj.cpu_s, "steps": traj.steps, "error": row.get("l2_error"),
                     "overhead": traj.extra.get("peer_overhead_s")})
    return [r for r in rows if r["error"] and r["error"] > 0]


def at_error(rows: list[dict], error: float) -> float | None:
    """CPU s at ``error``, interpolated log-log along the ladder (None outside it)."""
    pts = sorted((math.log(r["error"]), math.log(r["cpu_s"])) for r in rows)
    for (e0, c0), (e1, c1) in zip(pts, pts[1:]):
        if e0 <= math.log(error) <= e1 and e1 > e0:
            return math.exp(c0 + (c1 - c0) * (math.log(error) - e0) / (e1 - e0))
    return None


def compare(ours: list[dict], peer: list[dict]) -> tuple[float | None, float | None, float | None]:
    """(ratio per step, ratio at equal error, that error)."""
    if not ours or not peer:
        return None, None, None
    mid_o, mid_p = ours[len(ours) // 2], peer[len(peer) // 2]
    per_step = (mid_o["cpu_s"] / mid_o["steps"]) / (mid_p["cpu_s"] / mid_p["steps"])
    lo = max(min(r["error"] for r in ours), min(r["error"] for r in peer))
    hi = min(max(r["error"] for r in ours), max(r["error"] for r in peer))
    if lo > hi:
        return per_step, None, None
    error = math.sqrt(lo * hi)
    a, b = at_error(ours, error), at_error(peer, error)
    return per_step, (a / b if a and b else None), error


def fmt(x: float | None, spec: str = ".3g") -> str:
    return "-" if x is None else format(x, spec)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", choices=("small", "full"), default="full")
    args = parser.parse_args(argv)
    rungs = 3 if args.size == "small" else 4
    print("| problem | t_final | ours | peer | ours/peer per step | ours/peer at equal error | at error "
          "| peer overhead s/step |")
    print("|---|---|---|---|---|---|---|---|")
    for pname, psets, horizons, (mine, msetting, mvalues), peers in PAIRS:
        problem = registry.problem_class(pname)(**psets)
        t_final = horizons[args.size]
        ours = ladder(problem, mine, msetting, mvalues, t_final, rungs)
        for peer, psetting, pvalues in peers:
            theirs = ladder(problem, peer, psetting, pvalues, t_final, rungs)
            if not theirs:
                reason = registry.integrator_class(peer)().incompatibility(problem) or "no ok run"
                print(f"| {pname} | {t_final:g} | {mine} | {peer} | skipped: {reason} | | | |")
                continue
            per_step, equal, error = compare(ours, theirs)
            overhead = theirs[len(theirs) // 2]["overhead"]
            print(f"| {pname} | {t_final:g} | {mine} | {peer} | {fmt(per_step)} | {fmt(equal)} | {fmt(error, '.2g')} "
                  f"| {fmt(overhead, '.2g')} |")


if __name__ == "__main__":
    main()
