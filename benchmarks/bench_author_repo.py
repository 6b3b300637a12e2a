"""A scheme author's repository of five commits, measured by the commands she runs, beside a
CPU hog: do asv (the suite `longtime asv-init` writes) and `longtime history` mark the
slowdown and the accuracy loss at the right commits, for every cell, and nothing elsewhere?

The script builds, in a temporary folder, a git repository holding a plugin scheme
(``author-rk4``, classical RK4, registered by an entry point in its pyproject.toml) and a
virtualenv that sees this machine's packages and the longtime this script runs with, and
the plugin installed editable (``pip install -e``; pip's build isolation takes setuptools
from the package index or pip's cache). Its commits:

1. baseline RK4;
2. a refactoring that changes nothing (a helper for the stages, other names: the same
   arithmetic, bit for bit);
3. 1.3x slower: the stages repeated into scratch ``REPEAT`` times a step on average
   (results unchanged bit for bit);
4. a digit of accuracy lost: the weights' denominator 6 mistyped as ``MISTYPED_SIX``
   (every step scaled by 1 + 5e-9; the same instructions);
5. ``git revert`` of 4 and 3: the code of commit 2.

At each commit, with one CPU hog (``python -c 'while 1: pass'``) running throughout, the
author runs ``asv run --python=same --set-commit-hash <commit>`` (asv's ``existing``
environment: the checkout is the installed code) and ``longtime run`` into one store
(``--history-cost instructions`` adds ``--cost instructions``: a Valgrind process more a
commit; asv's suite counts the instructions in any case). Then ``asv compare`` between
successive commits (asv's
default factor 1.1 and its significance test) and ``longtime history`` over the store say
what changed. Per commit and cell, the script prints what each flagged and exits 1 where a
flag of a benchmark the suite says to judge by is wrong or missing: slower / more
instructions at 3 and faster / fewer at 5 only (asv's track_cpu_ratio and
track_instructions; time_integrate and track_cpu_s, the time in seconds, are printed and
counted on the last line, which counts each one's right verdicts, but do not set the exit
status);
less accurate (l2_error) at 4 and more accurate at 5 only (other error fields may follow
l2_error there, never elsewhere); nothing for verlet, longtime's own scheme in the same
suite; every asv result and every stored run names the author's commit.

    python benchmarks/bench_author_repo.py                 # 4 cells, about 15 minutes
    python benchmarks/bench_author_repo.py --keep /tmp/author-repo
    python benchmarks/bench_author_repo.py --hogs 0        # on a quiet machine
    python benchmarks/bench_author_repo.py --judge /tmp/author-repo   # judge it again

docs/performance.md ("An author's repository, measured") has the results.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PROBLEMS = ["harmonic", "duffing-2"]
SCHEMES = ["author-rk4", "verlet"]
DT = 0.01
T_FINAL = 1000.0
# the stages repeated this often a step on average make each cell about 1.3x slower;
# the weights' denominator 6 mistyped as this scales each step by 1 + 5e-9, which costs
# about 0.8 (duffing-2) and 1.8 (harmonic) digits of l2_error and no instruction
REPEAT = 0.35
MISTYPED_SIX = "5.99999997"

HEAD = '''"""Classical RK4 (a scheme author's plugin)."""
import numba

from longtime import FixedStepIntegrator
from longtime.core.drivers import OK, RHS_EVALS

'''

BODY = '''

class AuthorRK4(FixedStepIntegrator):
    name = "author-rk4"
    summary = "classical RK4 (an author's plugin)"
    order = 4

    def work_shape(self, problem):
        return (8, problem.dim)  # k1..k4, a stage, the increment, scratch, a step counter

    def make_step(self, problem):
        rhs = problem.rhs
        extra = REPEAT

        @numba.njit
        def increment(t, u, h, params, work, out):
            k1, k2, k3, k4, y = work[0], work[1], work[2], work[3], work[4]
            rhs(t, u, params, k1)
{stages}
            for i in range(u.size):
                out[i] = h / {six} * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])

        @numba.njit
        def step(t, u, h, params, work, counters, first):
            increment(t, u, h, params, work, work[5])
            if extra > 0.0:  # a constant of the compiled kernel: no branch when 0
                if first:
                    work[7, 0] = 0.0
                n = work[7, 0]
                for _ in range(int((n + 1.0) * extra) - int(n * extra)):
                    increment(t, u, h, params, work, work[6])
                work[7, 0] = n + 1.0
            for i in range(u.size):
                u[i] += work[5, i]
            counters[RHS_EVALS] += 4
            return OK

        return step
'''
INLINE = """            for i in range(u.size):
                y[i] = u[i] + 0.5 * h * k1[i]
            rhs(t + 0.5 * h, y, params, k2)
            for i in range(u.size):
                y[i] = u[i] + 0.5 * h * k2[i]
            rhs(t + 0.5 * h, y, params, k3)
            for i in range(u.size):
                y[i] = u[i] + h * k3[i]
            rhs(t + h, y, params, k4)"""
HELPER = """            stage_state(u, 0.5 * h, k1, y)
            rhs(t + 0.5 * h, y, params, k2)
            stage_state(u, 0.5 * h, k2, y)
            rhs(t + 0.5 * h, y, params, k3)
            stage_state(u, h, k3, y)
            rhs(t + h, y, params, k4)"""
CONSTANTS = '''REPEAT = {repeat!r}  # the stages computed again into scratch, times a step on average
'''
# The refactoring: a helper for a stage's state; the same floating-point operations in the
# same order (the helper is inlined by the compiler).
HELPER_FN = '''

@numba.njit
def stage_state(u, c, k, y):
    for i in range(u.size):
        y[i] = u[i] + c * k[i]
'''


def version(repeat: float, six: str, refactored: bool) -> str:
    """The module's text: stages repeated ``repeat`` times a step, the weights' denominator
    written as ``six``, the stage states through a helper if ``refactored``."""
    return (HEAD + CONSTANTS.format(repeat=float(repeat)) + (HELPER_FN if refactored else "")
            + BODY.replace("{stages}", HELPER if refactored else INLINE).replace("{six}", six))


PYPROJECT = '''[build-system]
requires = ["setuptools>=61"]
build-backend = "setuptools.build_meta"

[project]
name = "author-scheme"
version = "0.1"
dependencies = ["longtime"]

[project.entry-points."longtime.integrators"]
author-rk4 = "author_scheme:AuthorRK4"

[tool.setuptools]
py-modules = ["author_scheme"]
'''

# commit 1 .. 5: (message, module text); commit 5 is `git revert` of 4 and 3
VERSIONS = [("baseline RK4", version(0, "6.0", False)),
            ("refactor: a helper for the stage states", version(0, "6.0", True)),
            ("slower: the stages repeated", version(REPEAT, "6.0", True)),
            ("less accurate: a weight's denominator mistyped", version(REPEAT, MISTYPED_SIX, True))]
SLOWER, LESS_ACCURATE, REVERT = 3, 4, 5
HOG = "while 1: pass"
TIME_NAMES = ("time_integrate", "track_cpu_s", "track_cpu_ratio", "track_instructions")
# a flag's ratio is kept beside it under its name + RATIO (a suffix no benchmark name has)
RATIO = " ratio"
# the time in seconds: shown and counted, not judged (the suite judges speed by the ratio)
SECONDS_NAMES = ("time_integrate", "track_cpu_s")
ACCURACY_NAMES = ("track_l2_error", "track_drift", "track_growth_class")


def sh(cmd: list[str], cwd: Path | None = None, env: dict | None = None, check: bool = True) -> str:
    done = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True)
    if check and done.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({done.returncode}):\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}")
    return done.stdout


def make_env(tmp: Path) -> tuple[Path, dict]:
    """A virtualenv over this machine's packages that sees the longtime this script runs
    with (its site folder added by a .pth line); the environment the author's commands run in."""
    import site
    import sysconfig

    venv = tmp / "venv"
    base = Path(sys.base_prefix) / "bin" / "python3"
    sh([str(base), "-m", "venv", "--system-site-packages", str(venv)])
    py = venv / "bin" / "python"
    target = Path(sh([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"]).strip())
    here = sysconfig.get_paths()["purelib"]
    if Path(here) != target and here not in site.getsitepackages()[1:]:
        (target / "zz_longtime_under_test.pth").write_text(f"import site; site.addsitedir({here!r})\n")
    env = {**os.environ, "PATH": f"{venv / 'bin'}{os.pathsep}{os.environ.get('PATH', '')}",
           "LONGTIME_CACHE_DIR": os.environ.get("LONGTIME_CACHE_DIR", str(tmp / "cache"))}
    env.pop("LONGTIME_GIT_COMMIT", None)  # the author's commit comes from her repository
    env.pop("PYTHONPATH", None)
    env.pop("VIRTUAL_ENV", None)
    found = sh([str(py), "-c", "import longtime, os; print(os.path.dirname(longtime.__file__))"], env=env).strip()
    if Path(found).resolve() != (ROOT / "longtime").resolve():
        raise SystemExit(f"the author's environment imports longtime from {found}, not {ROOT / 'longtime'}")
    return py, env


def commit(repo: Path, message: str) -> str:
    sh(["git", "add", "-A"], repo)
    sh(["git", "commit", "-q", "-m", message], repo)
    return sh(["git", "rev-parse", "HEAD"], repo).strip()


def build_repo(repo: Path, py: Path, env: dict) -> None:
    repo.mkdir()
    sh(["git", "init", "-q"], repo)
    sh(["git", "config", "user.email", "author@example.org"], repo)
    sh(["git", "config", "user.name", "author"], repo)
    (repo / "pyproject.toml").write_text(PYPROJECT)
    (repo / ".gitignore").write_text(".asv/\n*.egg-info/\n__pycache__/\nbuild/\n")
    (repo / "author_scheme.py").write_text(VERSIONS[0][1])
    sh([str(py), "-m", "pip", "install", "-q", "--no-deps", "-e", str(repo)], env=env)  # as she installs it
    sh([str(py), "-m", "longtime", "asv-init", str(repo), "-p", ",".join(PROBLEMS), "-i", ",".join(SCHEMES),
        "--dt", str(DT), "--t-final", str(T_FINAL)], env=env)


def measure(repo: Path, py: Path, env: dict, db: Path, sha: str, log, cost: str) -> None:
    """The author's commands at the checked-out commit: asv, then longtime run."""
    t0 = time.time()
    out = sh([str(py), "-m", "asv", "run", "--python=same", "--set-commit-hash", sha, "--machine", "author",
              "--show-stderr"], repo, env, check=False)
    log.write(f"$ asv run --set-commit-hash {sha}\n{out}")
    t1 = time.time()
    out = sh([str(py), "-m", "longtime", "run", "-p", ",".join(PROBLEMS), "-i", ",".join(SCHEMES), "--dt", str(DT),
              "--t-final", str(T_FINAL), "--cost", cost, "--db", str(db), "--format", "csv"], repo, env)
    log.write(f"$ longtime run ({sha[:10]})\n{out}")
    print(f"  measured {sha[:10]}: asv {t1 - t0:.0f} s, longtime run {time.time() - t1:.0f} s", file=sys.stderr)


BENCH = re.compile(r"bench_longtime\.(\w+)\.(\w+)\('([^']*)', '([^']*)', '([^']*)'\)")


def asv_marks(repo: Path, py: Path, env: dict, before: str, after: str, log) -> dict[tuple, dict[str, str]]:
    """What `asv compare before after` marked (``read_compare``)."""
    out = sh([str(py), "-m", "asv", "compare", "--machine", "author", before, after], repo, env)
    log.write(f"$ asv compare {before[:8]} {after[:8]}\n{out}")
    return read_compare(out)


def read_compare(out: str) -> dict[tuple, dict[str, str]]:
    """{(problem, scheme): {benchmark: '+' worse or '-' better, benchmark + RATIO: its ratio}}
    of the table `asv compare` prints (one benchmark a row: change, before, after, ratio,
    name)."""
    marks: dict[tuple, dict[str, str]] = {}
    for line in out.splitlines():
        cells = [x.strip() for x in line.strip().strip("|").split("|")]
        m = BENCH.fullmatch(cells[-1]) if len(cells) == 5 else None
        if m:
            mark, ratio = cells[0], cells[3]
            _, bench, problem, scheme, _ = m.groups()
            entry = marks.setdefault((problem, scheme), {})
            entry[bench + RATIO] = ratio
            if mark in ("+", "-"):
                entry[bench] = mark
    return marks


def check(found: dict[str, str], expect: dict[str, str], anchor: str, accuracy: set[str]) -> list[str]:
    """Wrong flags: each expected one missing, each other one present. An accuracy field
    (``accuracy``) may follow the expected flag of ``anchor`` (l2_error) in the same direction."""
    wrong = [f"{k} {v} missing" for k, v in expect.items() if found.get(k) != v]
    wrong += [f"{k} {v} not expected" for k, v in found.items() if k not in expect and not k.endswith(RATIO)
              and not (k in accuracy and expect.get(anchor) == v)]
    return wrong


def expected_asv(scheme: str, k: int) -> dict[str, str]:
    if scheme != "author-rk4":
        return {}
    return {SLOWER: {"time_integrate": "+", "track_cpu_s": "+", "track_cpu_ratio": "+", "track_instructions": "+"},
            LESS_ACCURATE: {"track_l2_error": "+"},
            REVERT: {"time_integrate": "-", "track_cpu_s": "-", "track_cpu_ratio": "-", "track_instructions": "-",
                     "track_l2_error": "-"}}.get(k, {})


def expected_history(scheme: str, k: int, counted: bool) -> dict[str, str]:
    if scheme != "author-rk4":
        return {}
    more, fewer = (({"instructions": "more instructions"}, {"instructions": "fewer instructions"}) if counted
                   else ({}, {}))
    return {SLOWER: {"cpu_s_calibrated": "slower", **more},
            LESS_ACCURATE: {"l2_error": "less accurate"},
            REVERT: {"cpu_s_calibrated": "faster", "l2_error": "more accurate", **fewer}}.get(k, {})


def tune() -> int:
    """Time and error ratios of the versions in this process (to choose REPEAT and MISTYPED_SIX)."""
    import importlib.util

    import cloudpickle

    from longtime.api import cells_for
    from longtime.core import registry
    from longtime.core.timing import Timing
    from longtime.execution.cells import run_cell

    tmp = Path(tempfile.mkdtemp())
    rows = {}
    for k, (_, text) in enumerate(VERSIONS, 1):
        path = tmp / f"author_scheme_{k}.py"
        path.write_text(text)
        spec = importlib.util.spec_from_file_location(path.stem, path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[path.stem] = module
        spec.loader.exec_module(module)
        cloudpickle.register_pickle_by_value(module)
        registry.register(module.AuthorRK4)
        for p in PROBLEMS:
            (cell,) = cells_for([p], ["author-rk4"], T_FINAL, {"dt": DT})
            rows[k, p] = run_cell(cell, timing=Timing(repeats=15, min_time=0.5))
    for p in PROBLEMS:
        base = rows[2, p]
        for k in range(1, 5):
            r = rows[k, p]
            print(f"{p:10s} commit {k}: cpu_s {r['cpu_s'] * 1e3:8.3f} ms (x{r['cpu_s'] / base['cpu_s']:.2f}) "
                  f"l2_error {r['l2_error']:.3e} (x{r['l2_error'] / base['l2_error']:.2f})")
    shutil.rmtree(tmp)
    return 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hogs", type=int, default=1, help="CPU hogs running throughout (default 1)")
    parser.add_argument("--keep", default=None, metavar="DIR", help="build in DIR (kept) instead of a temp folder")
    parser.add_argument("--history-cost", choices=["time", "instructions"], default="time",
                        help="longtime run's --cost at each commit (instructions: a Valgrind process more a "
                             "commit; asv counts them in any case)")
    parser.add_argument("--judge", default=None, metavar="DIR",
                        help="measure nothing: judge the repository and store that --keep DIR left")
    parser.add_argument("--tune", action="store_true", help="only time the versions in this process")
    args = parser.parse_args()
    if args.tune:
        return tune()
    tmp = Path(args.keep or args.judge or tempfile.mkdtemp(prefix="author-repo-"))
    tmp.mkdir(parents=True, exist_ok=True)
    repo, db = tmp / "repo", tmp / "history.sqlite"
    log = open(tmp / ("judged.log" if args.judge else "commands.log"), "w")
    hogs = [subprocess.Popen([sys.executable, "-c", HOG]) for _ in range(0 if args.judge else args.hogs)]
    try:
        if args.judge:
            py, env = tmp / "venv" / "bin" / "python", {**os.environ, "PATH": f"{tmp / 'venv' / 'bin'}{os.pathsep}"
                                                                            f"{os.environ.get('PATH', '')}"}
            # the measured commits: those asv has results of (the revert's first half has none)
            measured = {p.name[:8] for p in (repo / ".asv" / "results" / "author").glob("*.json")}
            commits = [c for c in sh(["git", "rev-list", "--reverse", "HEAD"], repo).split() if c[:8] in measured]
        else:
            py, env = make_env(tmp)
            build_repo(repo, py, env)
            sh([str(py), "-m", "asv", "machine", "--yes", "--machine", "author"], repo, env)
            commits = []
            for k in range(1, 6):
                if k <= len(VERSIONS):
                    (repo / "author_scheme.py").write_text(VERSIONS[k - 1][1])
                    commits.append(commit(repo, f"commit {k}: {VERSIONS[k - 1][0]}"))
                else:
                    sh(["git", "revert", "--no-edit", "HEAD", "HEAD~1"], repo)
                    commits.append(sh(["git", "rev-parse", "HEAD"], repo).strip())
                print(f"commit {k} {commits[-1][:10]}", file=sys.stderr)
                measure(repo, py, env, db, commits[-1], log, args.history_cost)
        history = json.loads(sh([str(py), "-m", "longtime", "history", "--db", str(db), "--format", "json"], repo, env))
        log.write("$ longtime history\n" + sh([str(py), "-m", "longtime", "history", "--db", str(db)], repo, env))
        asv = {k: asv_marks(repo, py, env, commits[k - 2], commits[k - 1], log) for k in range(2, 6)}
    finally:
        for h in hogs:
            h.kill()
            h.wait()
        log.close()
    bad = 0
    results = sorted(p.name for p in (repo / ".asv" / "results" / "author").glob("*.json") if p.name != "machine.json")
    for k, sha in enumerate(commits, 1):
        if not any(name.startswith(sha[:8]) for name in results):
            print(f"commit {k}: no asv result names {sha[:8]}")
            bad += 1
    print(f"{'commit':8s} {'cell':22s} {'asv compare (vs the commit before)':58s} history")
    tally: dict[str, list[bool]] = {}  # per asv time benchmark: each judgement right or not
    for cell in history:
        c = cell["cell"]
        problem, scheme = c["problem"], c["integrator"]
        runs = cell["runs"]
        for p, sha in zip(runs, commits):
            code = [x for x in p.get("code") or []]
            if scheme == "author-rk4" and not (len(code) == 1 and code[0].get("commit") == sha
                                               and code[0].get("dirty") is False):
                print(f"  {problem} {scheme}: run {p['run_id']} names {code}, not {sha}")
                bad += 1
        if len(runs) != 5:
            print(f"  {problem} {scheme}: {len(runs)} runs, not 5")
            bad += 1
            continue
        steps: dict[int, dict[str, str]] = {}
        for s in cell["steps"]:
            k = next(i for i, p in enumerate(runs, 1) if p["run_id"] == s["run_id"])
            steps.setdefault(k, {})[s["field"]] = s["kind"]
            steps[k][s["field"] + RATIO] = f"{s['ratio']:.3g}"
        for k in range(2, 6):
            a = asv[k].get((problem, scheme), {})
            h = steps.get(k, {})
            judged = {b: v for b, v in a.items() if b.removesuffix(RATIO) not in SECONDS_NAMES}
            expect = {b: v for b, v in expected_asv(scheme, k).items() if b not in SECONDS_NAMES}
            wrong = check(judged, expect, "track_l2_error", set(ACCURACY_NAMES))
            hist_expect = expected_history(scheme, k, any(isinstance(p.get("instructions"), int) for p in runs))
            wrong += check(h, hist_expect, "l2_error", {f for f in h if f not in ("cpu_s_calibrated", "instructions")})
            shown_a = " ".join(f"{b}{a[b]}x{a.get(b + RATIO)}" for b in (*TIME_NAMES, *ACCURACY_NAMES) if b in a) or "-"
            shown_h = " ".join(f"{f}:{v}x{h.get(f + RATIO)}" for f, v in h.items() if not f.endswith(RATIO)) or "-"
            ratios = " ".join(f"{b.split('_', 1)[1][:5]}x{a.get(b + RATIO)}" for b in TIME_NAMES)
            print(f"{k:<8d} {problem + ' ' + scheme:22s} {shown_a:58s} {shown_h}   [asv {ratios}]"
                  + (f"  WRONG: {'; '.join(wrong)}" if wrong else ""))
            bad += bool(wrong)
            for b in TIME_NAMES:
                tally.setdefault(b, []).append(a.get(b) == expected_asv(scheme, k).get(b))
    print("asv time verdicts right: " + ", ".join(f"{b} {sum(v)}/{len(v)}" for b, v in tally.items()))
    print(f"{bad} wrong; commands and their output in {tmp / 'commands.log'}")
    if not (args.keep or args.judge) and not bad:
        shutil.rmtree(tmp, ignore_errors=True)
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
