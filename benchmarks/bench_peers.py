"""Our kernels against the library peers on equal methods (the equal-method table), and each
peer against a direct call of its library (the direct-call table).

- Dormand-Prince 5(4): our ``rk45`` kernel against ``scipy-rk45`` (solve_ivp's RK45) and
  ``diffrax-dopri5``, the same tableau at equal tolerance, on kepler and henon-heiles;
- our implicit schemes (``gauss4``, ``gauss6``, ``midpoint``; fixed step) against SUNDIALS'
  CVODE (``cvode-bdf``, ``cvode-adams``; tolerance) and scipy's ``scipy-radau`` on the stiff
  problems: kdv and fpu (stiff springs, omega = 50).

(The suite has no DOP853 kernel of its own: ``dop853`` is Hairer's code through scipy, measured against
solve_ivp's DOP853 by bench_dop853.py, and diffrax's Dopri8 is
another 8(7) pair, so there is no equal-method row for it.)

Each scheme runs a ladder of tolerances (or steps), timed as the matrix times a cell
(``Timing``: repeats, the minimum), with its error against the problem's reference (the
relative L2 error over the samples, ``l2_error``). For each pair it prints the ratio of our
CPU to the peer's per step (at the middle tolerance, or our middle step), and at equal
error (both cost curves interpolated log-log at the geometric middle of the errors both
reach), with the error it is taken at. A ratio below 1: ours is cheaper. Both run the same
horizon, each peer at its best call (CVODE in one ``solve`` at the sample times, scipy's
step loop, diffrax under ``jax.jit``).

The direct-call table runs each peer's row and the same library called directly, as its
users call it (``direct``: ``solve_ivp``, scikit-sundae's ``CVODE.solve`` at 10,001 output
times, diffrax's jitted ``diffeqsolve``), on the same problem, tolerance and horizon, and
prints both errors at the final time (against heyoka) and both CPU times (the minimum of
REPEATS after a warm-up call; diffrax's compile excluded from both): the row's error should
be the direct call's (within x2) and its CPU within x1.3 of it.

    python benchmarks/bench_peers.py                # the full ladders (a few minutes)
    python benchmarks/bench_peers.py --size small   # short horizons, three rungs each
    python benchmarks/bench_peers.py --table direct # the direct-call table alone
"""
from __future__ import annotations

import argparse
import math
import time

import numpy as np

from longtime.core import registry
from longtime.core.timing import Timing
from longtime.integrators.peer_common import SAMPLES  # the rows' output times, a direct call's too
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
     [("cvode-bdf", "tol", (1e-4, 1e-6, 1e-8, 1e-10)), ("cvode-adams", "tol", (1e-4, 1e-6, 1e-8, 1e-10))]),
]
# the direct-call table: (problem, its settings, t_final by size, tolerance, peers); kepler at
# e = 0.9 over 20 orbits at tol 1e-8 is the case whose errors docs/schemes.md states
DIRECT = [("kepler", {"e": 0.9}, {"small": 4 * math.pi, "full": 40 * math.pi}, 1e-8,
           ["scipy-rk45", "scipy-lsoda", "scipy-radau", "cvode-adams", "cvode-bdf", "diffrax-tsit5"]),
          ("toda", {}, {"small": 50.0, "full": 500.0}, 1e-10,
           ["scipy-rk45", "cvode-adams", "cvode-bdf", "diffrax-tsit5"])]
REPEATS = 3
SCIPY_METHODS = {"scipy-rk23": "RK23", "scipy-rk45": "RK45", "scipy-radau": "Radau",
                 "scipy-bdf": "BDF", "scipy-lsoda": "LSODA"}


def direct(scheme: str, problem, tol: float, t_final: float):
    """A call of ``scheme``'s library as its users make it, on ``problem`` from t0 to t_final at
    rtol = atol = ``tol``: a function of no arguments returning the state at t_final, after one
    untimed call (the library's first call, and diffrax's compile)."""
    import numba

    rhs, jac, params = problem.rhs, problem.jac, problem.params

    @numba.njit
    def f(t, y, p):
        out = np.empty_like(y)
        rhs(t, y, p, out)
        return out

    if scheme in SCIPY_METHODS:
        from scipy.integrate import solve_ivp

        options = {}
        if scheme in ("scipy-radau", "scipy-bdf", "scipy-lsoda") and jac is not None:
            @numba.njit
            def jf(t, y, p):
                out = np.zeros((y.size, y.size))
                jac(t, y, p, out)
                return out
            options["jac"] = lambda t, y: jf(t, y, params)

        def call():
            sol = solve_ivp(lambda t, y: f(t, y, params), (problem.t0, t_final), problem.u0,
                            method=SCIPY_METHODS[scheme], rtol=tol, atol=tol, **options)
            return sol.y[:, -1]
    elif scheme.startswith("cvode-"):
        from sksundae.cvode import CVODE

        @numba.njit
        def rhsfn(t, y, yp, userdata):
            rhs(t, y, userdata[0], yp)

        options = {}
        if scheme == "cvode-bdf" and jac is not None:
            @numba.njit
            def jacfn(t, y, yp, JJ, userdata):
                jac(t, y, userdata[0], JJ)
            options["jacfn"] = jacfn
        solver = CVODE(rhsfn, userdata=(params,), method="Adams" if scheme == "cvode-adams" else "BDF", rtol=tol,
                       atol=tol, max_num_steps=2**31 - 1, **options)
        grid = np.linspace(problem.t0, t_final, SAMPLES)

        def call():
            return solver.solve(grid, problem.u0.copy()).y[-1]
    elif scheme.startswith("diffrax-"):
        import diffrax
        import jax

        jax.config.update("jax_enable_x64", True)
        solver = {"diffrax-tsit5": diffrax.Tsit5, "diffrax-dopri5": diffrax.Dopri5,
                  "diffrax-dopri8": diffrax.Dopri8}[scheme]()
        grid = np.linspace(problem.t0, t_final, SAMPLES)

        @jax.jit
        def solve(u0, p):
            sol = diffrax.diffeqsolve(diffrax.ODETerm(lambda t, y, a: problem.jax_rhs(t, y, a)), solver, problem.t0,
                                      t_final, None, u0, args=p, saveat=diffrax.SaveAt(ts=grid), max_steps=2**31 - 1,
                                      stepsize_controller=diffrax.PIDController(rtol=tol, atol=tol))
            return sol.ys

        def call():
            return np.asarray(solve(np.asarray(problem.u0), np.asarray(params)).block_until_ready())[-1]
    else:
        raise ValueError(f"{scheme}: no direct call")
    call()
    return call


def direct_row(scheme: str, problem, tol: float, t_final: float) -> dict:
    """The suite's row and the direct call of ``scheme`` on ``problem``: their errors at t_final
    against heyoka (relative) and their CPU seconds (each the minimum of REPEATS)."""
    from longtime.measure import reference

    truth = reference.propagate(problem, np.array([problem.t0, t_final]), "double")[0][-1]

    def error(u):
        return float(np.linalg.norm(u - truth) / np.linalg.norm(truth))

    # the matrix's samples: CVODE's first step depends on its first output time
    traj = registry.integrator_class(scheme)(tol=tol).integrate(problem, t_final, max_samples=SAMPLES,
                                                                timing=Timing(repeats=REPEATS, min_runs=REPEATS))
    call = direct(scheme, problem, tol, t_final)
    cpus = []
    for _ in range(REPEATS):
        c0 = time.process_time()
        end = call()
        cpus.append(time.process_time() - c0)
    return {"scheme": scheme, "status": traj.status, "row_error": error(traj.u[-1]), "direct_error": error(end),
            "row_cpu": traj.cpu_s, "direct_cpu": min(cpus)}


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
    parser.add_argument("--table", choices=("both", "equal", "direct"), default="both")
    args = parser.parse_args(argv)
    if args.table != "direct":
        equal_method_table(args)
    if args.table != "equal":
        direct_call_table(args)


def equal_method_table(args) -> None:
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
    print()


def direct_call_table(args) -> None:
    print("| problem | t_final | tol | peer | row error at t_final | direct error | row CPU s | direct CPU s "
          "| row/direct CPU |")
    print("|---|---|---|---|---|---|---|---|---|")
    for pname, psets, horizons, tol, schemes in DIRECT:
        problem = registry.problem_class(pname)(**psets)
        t_final = horizons[args.size]
        for scheme in schemes:
            reason = registry.integrator_class(scheme)().incompatibility(problem)
            if reason:
                print(f"| {pname} | {t_final:.4g} | {tol:g} | {scheme} | skipped: {reason} | | | | |")
                continue
            r = direct_row(scheme, problem, tol, t_final)
            label = pname + "".join(f" {k}={v:g}" for k, v in psets.items())
            print(f"| {label} | {t_final:.4g} | {tol:g} | {scheme} | {r['row_error']:.2g} | {r['direct_error']:.2g} "
                  f"| {r['row_cpu']:.3g} | {r['direct_cpu']:.3g} | {r['row_cpu'] / r['direct_cpu']:.2f} |")


if __name__ == "__main__":
    main()
