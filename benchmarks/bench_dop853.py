"""The ``dop853`` peer on Hairer's code (``scipy.integrate.ode('dop853')``, the scheme) against
the same method stepped by ``solve_ivp`` (scipy's Python port, ``OdeSolver.step`` in a Python
loop): steps, rejected steps, the error against the problem's reference (``l2_error``, as a
row reports it) and CPU per step, on several problems at their default t_final and three
tolerances.

The two runs of each cell are interleaved (ode, solve_ivp, ode, ...; the minimum CPU of
REPEATS each) in one process, so that a loaded machine slows both alike; the ratio
``new/old CPU per step`` below 1 means Hairer's code is cheaper a step.

    python benchmarks/bench_dop853.py
    python benchmarks/bench_dop853.py -p kepler,toda --tol 1e-9
"""
from __future__ import annotations

import argparse
import time

from longtime.core import registry
from longtime.integrators.scipy_ivp import ScipyIVP
from longtime.measure.metrics import evaluate
from longtime.measure.reference import reference_states

PROBLEMS = "kepler,toda,fpu,pythagorean-three-body,outer-solar-system"
TOLS = "1e-6,1e-9,1e-12"
REPEATS = 2
LIMIT_S = 120.0  # wall seconds a run may take before it stops as a timeout


class SolveIvpDOP853(ScipyIVP):
    """DOP853 stepped by solve_ivp's Python loop (the scheme's former call)."""

    name = "solve-ivp-dop853"
    method = "DOP853"
    order = 8


def run(integrator, problem, t_final: float) -> dict:
    """One cell: the minimum CPU of REPEATS runs, its steps, rejected steps and l2_error."""
    best = None
    for _ in range(REPEATS):
        traj = integrator.integrate(problem, t_final, max_samples=2001, deadline=time.monotonic() + LIMIT_S)
        if best is None or traj.cpu_s < best.cpu_s:
            best = traj
    row = evaluate(problem, best, reference_states(problem, best.t)) if best.status == "ok" else {}
    rejected = best.counters.get("rejected", 0)
    if not rejected and integrator.name != "dop853":  # solve_ivp counts rhs calls, 12 a step tried
        rejected = max(0, round((best.counters["rhs_evals"] - 2) / 12) - best.steps)
    return {"status": best.status, "steps": best.steps, "rejected": rejected, "error": row.get("l2_error"),
            "cpu_step": best.cpu_s / max(best.steps, 1)}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-p", default=PROBLEMS, help="problems, comma-separated")
    parser.add_argument("--tol", default=TOLS, help="tolerances, comma-separated")
    args = parser.parse_args(argv)
    print("| problem | t_final | tol | steps new (old) | rejected new (old) | l2_error new | l2_error old "
          "| CPU/step new s | CPU/step old s | new/old CPU per step |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    new_cls = registry.integrator_class("dop853")
    for name in args.p.split(","):
        problem = registry.problem_class(name)()
        t_final = problem.default_t_final
        for tol in (float(x) for x in args.tol.split(",")):
            new, old = run(new_cls(tol=tol), problem, t_final), run(SolveIvpDOP853(tol=tol), problem, t_final)
            err = ["-" if r["error"] is None else f"{r['error']:.3g}" for r in (new, old)]
            status = "".join(f" ({r['status']})" for r in (new, old) if r["status"] != "ok")
            print(f"| {name} | {t_final:.4g} | {tol:g} | {new['steps']} ({old['steps']}){status} "
                  f"| {new['rejected']} ({old['rejected']}) | {err[0]} | {err[1]} | {new['cpu_step']:.3g} "
                  f"| {old['cpu_step']:.3g} | {new['cpu_step'] / old['cpu_step']:.3f} |", flush=True)


if __name__ == "__main__":
    main()
