"""Whether ``longtime recommend``'s answers hold at their horizon: ten questions (problem,
target error, horizon) on problems the verdict was not tuned on, each answer's setting run
to the horizon again and measured against a reference checked to that horizon.

    python benchmarks/bench_answers.py [--db STORE] [--budget 30] [--rivals 2] [-q N,..]

Without ``--db`` it first builds its own store, ``longtime matrix --quick -p PROBLEMS
--checks 0 --no-ensemble`` (the questions' problems x the quick schemes over their
default sweep), in a temporary folder. For each question it asks ``longtime.recommend``
twice: with ``--budget 0`` (the answer predicted from the stored runs' laws and cost
models alone) and with ``--budget`` (default 30 wall seconds for the runs that measure
an answer at T, the answer a user gets). It runs each named setting to T in this
process (``run_cell``: its own reference check to T, the suite's heyoka or exact
reference, not the stored row's), timed by a warm-up and ``--repeats`` runs (the CPU
figure is their minimum), and up to ``--rivals`` stored settings of other schemes that
could beat the answer by 1.5 in CPU (their error over their own run keeps the target,
their predicted CPU at T is under the answer's measured CPU / 1.5, cheapest first).
Where the answer is a refusal, it runs the stored setting of least error to T and says
what it measures.

A line: the question | the answer (what recommend states: its figures measured at T, or
predicted) | the --budget 0 answer with its predicted error and CPU at T (and, where it
names another setting, that setting measured at T), and its measured / predicted CPU |
the answer's setting measured at T: max_error (the largest error of any block over
[0, T]) and CPU | held: the error kept within the target and no rival 1.5 times cheaper
keeps it (with the CPU within CHECK_COST_FACTOR of the stated one); for a refusal,
whether the best stored setting indeed misses the target or its reference cannot be
trusted to T. The table in docs/performance.md ("Answers at their horizon") is its
output.
"""
from __future__ import annotations

import argparse
import math
import os
import subprocess
import sys
import tempfile
import time

# (problem, target error, horizon, what it asks)
QUESTIONS = [
    ("harmonic", 1e-4, 2e4, "100 x the stored runs"),
    ("harmonic", 1e-6, 1e5, "500 x the stored runs: past every reach"),
    ("duffing-2", 1e-6, 200, "within the stored runs"),
    ("duffing-2", 1e-10, 1e4, "50 x the stored runs"),
    ("henon-heiles", 1e-6, 1e3, "regular orbit, twice most stored runs"),
    ("henon-heiles", 1e-8, 1e4, "regular orbit, 20 x most stored runs"),
    ("linear-test", 1e-10, 200, "10 x the stored runs"),
    ("lennard-jones", 1e-6, 0.005, "chaotic many-body, within the stored runs"),
    ("lennard-jones", 1e-4, 0.2, "chaotic many-body, past its predictability horizon"),
    ("double-pendulum", 1e-6, 40.0, "chaotic, past its predictability horizon"),
]
MATRIX = ["matrix", "--quick", "--checks", "0", "--no-ensemble", "--no-html", "--no-progress", "--no-report"]


def _fmt(x: float | None, unit: str = "") -> str:
    return "-" if x is None or not math.isfinite(x) else f"{x:.2g}{unit}"


def _cpu(x: float | None) -> str:
    return "-" if x is None or not math.isfinite(x) else f"{x:.3g} s"


def _short(text: str, most: int = 200) -> str:
    """``text`` cut after its last clause ('; ') within ``most`` characters."""
    if len(text) <= most:
        return text
    cut = text.rfind("; ", 0, most)
    return (text[:cut] if cut > 0 else text[:most]) + " ..."


def _run(s, horizon: float, repeats: int, ref_s: float) -> dict:
    """The row of ``s``'s setting run to ``horizon`` against a reference checked to it."""
    from longtime.core.timing import Timing
    from longtime.execution.cells import cell_of_row, run_cell

    return run_cell(cell_of_row(s.row, t_final=horizon), timing=Timing(repeats=repeats, min_time=0.0, min_runs=repeats),
                    time_limit=600.0, reference_budget_s=ref_s)


def _measured(row: dict, horizon: float) -> tuple[float | None, float | None, str]:
    """The error the row keeps up to ``horizon``, its CPU, and why there is no error."""
    from longtime.core.fmt import positive

    cpu = row.get("cpu_s") if positive(row.get("cpu_s")) else None
    if row.get("status") != "ok":
        return None, cpu, f"{row.get('status')}"
    reach = row.get("error_horizon")
    if not positive(row.get("max_error")):
        return None, cpu, "no error"
    if not (positive(reach) and reach >= horizon * (1 - 1e-9)):
        return None, cpu, f"reference trusted to t = {reach:.3g} only" if positive(reach) else "no reference"
    return float(row["max_error"]), cpu, "lost" if row.get("solution_lost") else ""


def _question(db: str, rows: list, problem: str, target: float, horizon: float, what: str, args,
              ref_s: float, commands: list[str]) -> str:
    """The table's line of one question; the commands it ran are appended to ``commands``."""
    from longtime import api
    from longtime.execution.answers import candidates
    from longtime.predict.checks import CHECK_COST_FACTOR
    from longtime.predict.decision import run_command
    from longtime.predict.settings import measure, settings

    q = f"{problem}, {target:g} up to {horizon:g} ({what})"
    ask = f"longtime recommend -p {problem} --error {target:g} --horizon {horizon:g} --db STORE"
    predicted = api.recommend(problem, target, horizon, db=db, budget=0)
    rec = api.recommend(problem, target, horizon, db=db, budget=args.budget)
    commands.append(f"{ask} --budget 0")
    commands.append(f"{ask} --budget {args.budget:g}")
    mine = [r for r in rows if r.get("problem") == problem]
    m = measure(mine)
    cands = settings(mine, m) if m else []
    best = rec.decision.best if rec.answered else None
    guess = predicted.decision.best if predicted.answered else None
    if best is None:
        reason = rec.lines[0].split(": ", 2)[-1] if rec.lines else ""
        reason = _short(reason)
        finest = min(cands, key=lambda s: s.error, default=None)
        if finest is None:
            return f"| {q} | refused: {reason} | - | - | - |"
        err, cpu, why = _measured(_run(finest, horizon, 1, ref_s), horizon)
        commands.append(" ".join(run_command(finest, horizon)))
        misses = err is None or err > target or why == "lost"
        seen = f"{finest.text}: " + (f"{_fmt(err)} ({why})" if why and err is not None else
                                     _fmt(err) if err is not None else why)
        return (f"| {q} | refused: {reason} | - | {seen}, {_cpu(cpu)} | "
                f"{'yes (the finest stored setting misses it)' if misses else 'no: it keeps the target'} |")
    err, cpu, why = _measured(_run(best, horizon, args.repeats, ref_s), horizon)
    commands.append(" ".join(run_command(best, horizon)))
    keeps = err is not None and err <= target and why != "lost"
    # the answer --budget 0 gives, from the stored runs' laws alone, against its run to T
    g_err = g_cpu = None
    g_why = ""
    if guess is None:
        p_text = "no answer: " + (_short(predicted.lines[0].split(": ", 2)[-1]) if predicted.lines else "")
    else:
        p_err, p_cpu = guess.error_at(horizon), guess.cpu_at(horizon)
        p_text = f"{guess.text}: {_fmt(p_err)}, {_cpu(p_cpu)}"
        g_err, g_cpu, g_why = (err, cpu, why) if guess.text == best.text else \
            _measured(_run(guess, horizon, args.repeats, ref_s), horizon)
        if guess.text != best.text:
            commands.append(" ".join(run_command(guess, horizon)))
            p_text += f" (measured {_fmt(g_err)}, {_cpu(g_cpu)})" if g_err is not None else f" ({g_why})"
        if g_cpu and p_cpu > 0:
            p_text += f"; CPU measured/predicted {g_cpu / p_cpu:.2g}"
    beaten = ""
    if keeps and cpu is not None:
        rivals = [s for s in candidates(cands, target, horizon) if s.scheme != best.scheme] + \
                 [s for s in cands if s.scheme != best.scheme and s.error <= target]
        seen, tried = set(), 0
        for s in sorted(rivals, key=lambda s: s.cpu_at(horizon)):
            if s.text in seen or not s.cpu_at(horizon) < cpu / 1.5 or tried >= args.rivals:
                continue
            seen.add(s.text)
            tried += 1
            r_err, r_cpu, r_why = _measured(_run(s, horizon, args.repeats, ref_s), horizon)
            commands.append(" ".join(run_command(s, horizon)))
            if r_err is not None and r_err <= target and not r_why and r_cpu is not None and r_cpu < cpu / 1.5:
                beaten = f"{s.text} keeps it ({r_err:.2g}) for {r_cpu:.3g} s"
                break
    stated_cpu = rec.measured_cpu_s if rec.basis == "measured at T" else best.cpu_at(horizon)
    held = ("yes" if keeps and not beaten else
            f"no: {beaten}" if beaten else f"no: {why or f'misses {target:g}'}")
    if keeps and not beaten and cpu and stated_cpu and max(cpu / stated_cpu, stated_cpu / cpu) > CHECK_COST_FACTOR:
        held = f"error yes, CPU off x{max(cpu / stated_cpu, stated_cpu / cpu):.2g}"
    if guess is not None and guess.text != best.text and keeps and cpu and g_cpu:
        kept = g_err is not None and g_err <= target and not g_why
        held += (f"; the --budget 0 answer costs x{g_cpu / cpu:.2g} the CPU" if kept
                 else "; the --budget 0 answer misses it")
    answer = best.text + (f" (measured at T by recommend: {_fmt(rec.measured_error)}, {_cpu(rec.measured_cpu_s)})"
                          if rec.basis == "measured at T" else
                          f" (predicted: {_fmt(best.error_at(horizon))}, {_cpu(best.cpu_at(horizon))})")
    measured = f"{_fmt(err)}, {_cpu(cpu)}" if err is not None else f"{why}, {_cpu(cpu)}"
    return f"| {q} | {answer} | {p_text} | {measured} | {held} |"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--db", default=None, help="a store with rows of the questions' problems (default: build one)")
    ap.add_argument("--budget", type=float, default=30.0, help="recommend's --budget, wall seconds a question")
    ap.add_argument("--repeats", type=int, default=3, help="timed runs of each setting after its warm-up")
    ap.add_argument("--rivals", type=int, default=2, help="rivals run per answer")
    ap.add_argument("-q", "--questions", default="", help="only these questions (1-based, comma-separated)")
    args = ap.parse_args(argv)
    os.environ.setdefault("LONGTIME_REFERENCE_SECONDS", "60")
    ref_s = float(os.environ["LONGTIME_REFERENCE_SECONDS"])
    picked = [QUESTIONS[int(k) - 1] for k in args.questions.split(",")] if args.questions else QUESTIONS

    started = time.perf_counter()
    db = args.db
    if db is None:
        db = os.path.join(tempfile.mkdtemp(prefix="bench-answers-"), "store.sqlite")
        problems = ",".join(dict.fromkeys(q[0] for q in picked))
        cmd = [sys.executable, "-m", "longtime", *MATRIX, "-p", problems, "--db", db]
        print("store: " + " ".join(["longtime", *cmd[3:]]), file=sys.stderr, flush=True)
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    built = time.perf_counter() - started

    from longtime.execution.store import Store

    rows = Store(db, readonly=True).rows()
    print("| question | answer | predicted at T | measured at T | held |")
    print("|---|---|---|---|---|")
    commands = []
    for problem, target, horizon, what in picked:
        print(_question(db, rows, problem, target, horizon, what, args, ref_s, commands), flush=True)
    print(f"\nstore built in {built:.0f} s; total {time.perf_counter() - started:.0f} s wall", file=sys.stderr)
    print("\ncommands:")
    for c in commands:
        print("    " + c)
    return 0


if __name__ == "__main__":
    sys.exit(main())
