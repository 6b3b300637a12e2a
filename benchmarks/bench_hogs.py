"""Identical code beside CPU hogs and beside memory-bandwidth hogs: does `longtime compare`
stay quiet, and do the instruction counts agree? And is a 1.3x slower scheme flagged on
time beside a hog?

A small matrix (kepler x {rk4, rk45, gauss4}, toda x {rk4, rk4sym, gauss4} at t_final 500,
harmonic x verlet, and a plugin scheme ``author-rk4`` on harmonic at dt 0.01, t_final
1000: classical RK4 from benchmarks/bench_author_repo.py) is run with ``--cost
instructions`` (the default 3 timing processes) four times into one store, each run in a
fresh process:

1. quiet (nothing of this script running beside it);
2. beside two CPU hogs (``while 1: pass``);
3. beside two memory-bandwidth hogs (numpy copy loops over 64 MiB arrays);
4. beside one CPU hog, with ``author-rk4`` made 1.3x slower (its stages repeated into
   scratch 0.35 times a step on average: results unchanged bit for bit).

Then ``longtime compare`` 1 -> 2 and 1 -> 3 must find 0 regressions and every cell's
instruction count must agree within 0.1 %; ``longtime compare`` 1 -> 4 must flag
``author-rk4`` slower (on time: the verdict's time part, not only its instructions) and
nothing else. Exit 1 otherwise.

    python benchmarks/bench_hogs.py                  # about 10 minutes
    python benchmarks/bench_hogs.py --db /tmp/hogs.sqlite
    python benchmarks/bench_hogs.py --db /tmp/hogs.sqlite --judge 1,2,3,4   # judge again

docs/performance.md ("Hogs, identical code and a slower plugin") has the results.
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
GROUPS = [("kepler", ["rk4", "rk45", "gauss4"], 500.0, {}), ("toda", ["rk4", "rk4sym", "gauss4"], 500.0, {}),
          ("harmonic", ["verlet"], None, {}), ("harmonic", ["author-rk4"], 1000.0, {"dt": 0.01})]
CPU_HOG = "while 1: pass"
MEMORY_HOG = ("import numpy as np; a = np.ones(8 << 20); b = np.empty_like(a)\n"
              "while True: np.copyto(b, a); np.copyto(a, b)")
PHASES = [("quiet", None, 0, 0.0), ("2 CPU hogs", CPU_HOG, 2, 0.0), ("2 memory hogs", MEMORY_HOG, 2, 0.0),
          ("author-rk4 1.3x slower, 1 CPU hog", CPU_HOG, 1, None)]
COUNT_TOLERANCE = 1e-3


def run_phase(db: str, name: str, repeat: float) -> None:
    """One run of the matrix into ``db`` (in this fresh process), author-rk4 at ``repeat``."""
    import cloudpickle

    sys.path.insert(0, str(HERE))
    from bench_author_repo import version

    from longtime.api import cells_for, run_cells
    from longtime.core import registry
    from longtime.execution.matrix import ExecOptions

    folder = Path(tempfile.mkdtemp(prefix="author-rk4-"))
    path = folder / "author_scheme.py"
    path.write_text(version(repeat, "6.0", True))
    spec = importlib.util.spec_from_file_location("author_scheme", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules["author_scheme"] = module
    spec.loader.exec_module(module)
    cloudpickle.register_pickle_by_value(module)  # the timing processes receive the class itself
    registry.register(module.AuthorRK4)
    cells = [c for p, schemes, tf, sets in GROUPS for c in cells_for([p], schemes, tf, sets)]
    rows, run_id = run_cells(cells, store=db, command=f"bench_hogs: {name}", executor="process",
                             options=ExecOptions(cost="instructions"))
    bad = [r for r in rows if r.get("status") != "ok" or not isinstance(r.get("instructions"), int)]
    for r in bad:
        print(f"{r['problem']} {r['integrator']}: {r.get('status')} "
              f"{r.get('message') or r.get('instructions_skipped')}",
              file=sys.stderr)
    print(json.dumps({"run_id": run_id, "bad": len(bad)}))


def compare(db: str, a: int, b: int) -> dict:
    done = subprocess.run([sys.executable, "-m", "longtime", "compare", "--db", db, str(a), str(b), "--all",
                           "--format", "json"], capture_output=True, text=True)
    if done.returncode not in (0, 1):
        raise SystemExit(f"compare {a} {b}: {done.stderr.strip()}")
    return json.loads(done.stdout)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--db", default=None, help="the store (default: a new one in a temporary folder)")
    parser.add_argument("--judge", default=None, metavar="A,B,C,D",
                        help="measure nothing: judge these four run ids of --db (runs 1 to 4 above)")
    parser.add_argument("--phase", default=None, help=argparse.SUPPRESS)
    parser.add_argument("--repeat", type=float, default=0.0, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.phase:
        run_phase(args.db, args.phase, args.repeat)
        return 0
    sys.path.insert(0, str(HERE))
    from bench_author_repo import REPEAT

    db = args.db or str(Path(tempfile.mkdtemp(prefix="hogs-")) / "hogs.sqlite")
    runs = [int(x) for x in args.judge.split(",")] if args.judge else []
    for name, hog, n, repeat in [] if args.judge else PHASES:
        hogs = [subprocess.Popen([sys.executable, "-c", hog]) for _ in range(n)]
        try:
            if hogs:
                time.sleep(1.0)
            t0 = time.time()
            done = subprocess.run([sys.executable, __file__, "--db", db, "--phase", name,
                                   "--repeat", str(REPEAT if repeat is None else repeat)],
                                  capture_output=True, text=True)
        finally:
            for h in hogs:
                h.kill()
                h.wait()
        if done.returncode != 0:
            raise SystemExit(f"phase {name}: {done.stderr[-3000:]}")
        out = json.loads(done.stdout.strip().splitlines()[-1])
        runs.append(out["run_id"])
        print(f"run {out['run_id']}: {name} ({time.time() - t0:.0f} s, {out['bad']} cells not ok or not counted)")
        if out["bad"]:
            print(done.stderr[-3000:])
            return 1
    bad = 0
    print(f"{'cell':26s} {'quiet cpu_s':>11s} " + " ".join(f"{n[:14]:>26s}" for n, *_ in PHASES[1:]))
    results = [compare(db, runs[0], r) for r in runs[1:]]
    for k, res in enumerate(results, 1):
        expect_slow = PHASES[k][3] is None
        for c in res["cells"]:
            regressions = c["regressions"]
            author = c["integrator"] == "author-rk4"
            if expect_slow and author:
                timed = c.get("time_verdict") == "slower"
                if not timed or not any("instructions" in x for x in regressions):
                    print(f"  {PHASES[k][0]}: {c['problem']} {c['integrator']} not flagged slower on time and "
                          f"instructions: {c.get('time_verdict')}, {regressions}")
                    bad += 1
            elif regressions:
                print(f"  {PHASES[k][0]}: {c['problem']} {c['integrator']} REGRESSED: {regressions}")
                bad += 1
            ia, ib = c.get("instructions_a"), c.get("instructions_b")
            if not (expect_slow and author) and (not ia or not ib or abs(ib / ia - 1) > COUNT_TOLERANCE):
                print(f"  {PHASES[k][0]}: {c['problem']} {c['integrator']} instructions {ia} -> {ib}")
                bad += 1
    by_cell = {}
    for k, res in enumerate(results):
        for c in res["cells"]:
            key = f"{c['problem']} {c['integrator']}"
            entry = by_cell.setdefault(key, {"cpu_a": c.get("cpu_a")})
            ia, ib = c.get("instructions_a"), c.get("instructions_b")
            count = f"{ib / ia - 1:+.1e}" if ia and ib else "-"
            entry[k] = f"t x{c.get('time_ratio') or float('nan'):.2f} {c.get('time_verdict') or '-':>6s} n {count}"
    for key, entry in by_cell.items():
        cpu = entry.get("cpu_a")
        print(f"{key:26s} {(f'{1e3 * cpu:.3f} ms' if cpu else '-'):>11s} "
              + " ".join(f"{entry.get(k, '-'):>26s}" for k in range(len(results))))
    for k, res in enumerate(results, 1):
        print(f"compare {runs[0]} {runs[k]} ({PHASES[k][0]}): {res['regressed']} regressed; machine: "
              f"{json.dumps(res.get('machine'))[:200]}")
    print(f"{bad} wrong; store {db}")
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
