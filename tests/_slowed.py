"""Test helper: a plugin scheme whose code is made slower or less accurate on purpose, as a
scheme author's commit might, for `longtime compare` and `longtime history`.

``source(repeat, bias)`` is the text of a module defining ``SlowedRK4`` (registered as
``slowed-rk4``): classical RK4 that repeats its four stages into scratch ``repeat`` times a
step on average (the cell takes longer, by less than ``repeat``: the driver's own work per
step is not repeated; its results are unchanged bit for bit) and adds
``bias * h**5`` to the first component each step (an error of order h^4 over a run, like
RK4's own: ``bias`` costs accuracy). The constants are
in the module's text, so each version is other code (another kernel), not another setting:
the cells keep their identity across versions.
"""
import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

TEMPLATE = '''"""RK4 repeating its stages {repeat} times a step on average and biased by {bias} h^5 a step
(a test plugin)."""
import numba

from longtime import FixedStepIntegrator
from longtime.core.drivers import OK, RHS_EVALS

REPEAT = {repeat!r}
BIAS = {bias!r}


class SlowedRK4(FixedStepIntegrator):
    name = "slowed-rk4"
    summary = "classical RK4 with its stages repeated REPEAT times a step on average (test plugin)"
    order = 4

    def work_shape(self, problem):
        return (8, problem.dim)  # k1..k4, a stage, the increment, its repeat, a step counter

    def make_step(self, problem):
        rhs = problem.rhs
        extra, bias = REPEAT, BIAS

        @numba.njit
        def increment(t, u, h, params, work, out):
            k1, k2, k3, k4, y = work[0], work[1], work[2], work[3], work[4]
            rhs(t, u, params, k1)
            for i in range(u.size):
                y[i] = u[i] + 0.5 * h * k1[i]
            rhs(t + 0.5 * h, y, params, k2)
            for i in range(u.size):
                y[i] = u[i] + 0.5 * h * k2[i]
            rhs(t + 0.5 * h, y, params, k3)
            for i in range(u.size):
                y[i] = u[i] + h * k3[i]
            rhs(t + h, y, params, k4)
            for i in range(u.size):
                out[i] = h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])

        @numba.njit
        def step(t, u, h, params, work, counters, first):
            if first:  # the work array is not zeroed between runs: the step counter starts here
                work[7, 0] = 0.0
            increment(t, u, h, params, work, work[5])
            n = work[7, 0]
            for _ in range(int((n + 1.0) * extra) - int(n * extra)):  # the repeated work, into scratch
                increment(t, u, h, params, work, work[6])
            work[7, 0] = n + 1.0
            for i in range(u.size):
                u[i] += work[5, i]
            u[0] += bias * h ** 5
            counters[RHS_EVALS] += 4
            return OK

        return step
'''


def source(repeat: float = 0.0, bias: float = 0.0) -> str:
    return TEMPLATE.format(repeat=float(repeat), bias=float(bias))


def load(path: Path, tag: str):
    """The SlowedRK4 class of the module file ``path`` (imported under a name of its own,
    pickled by value: the timing processes of a run receive the class itself)."""
    import cloudpickle

    name = f"_slowed_rk4_{tag}"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    cloudpickle.register_pickle_by_value(module)
    return module.SlowedRK4


def _git(repo: Path, *args: str) -> str:
    return subprocess.run(["git", *args], cwd=repo, check=True, capture_output=True, text=True).stdout.strip()


def measure_commits(repo: str, db: str) -> None:
    """Five commits of the scheme in the git repository ``repo``, each measured into the
    store ``db`` as its own run: commits 1 and 2 plain RK4, commit 3 its stages repeated 1.2
    times a step, commits 4 and 5 also a bias of 32 h^5 a step. Each stored run times the
    cell in three processes (``--processes 3``) and names no commit: the store finds the
    author's commit from the module's repository. Prints the commit hashes (JSON) on stdout."""
    import contextlib
    import io

    from longtime.commands import cli
    from longtime.core import registry

    repo_path = Path(repo)
    versions = [(0.0, 0.0), (0.0, 0.0), (1.2, 0.0), (1.2, 32.0), (1.2, 32.0)]
    commits = []
    for k, (repeat, bias) in enumerate(versions, 1):
        module = repo_path / "slowed_rk4.py"
        module.write_text(source(repeat, bias) + f"# commit {k}\n")
        _git(repo_path, "add", "-A")
        _git(repo_path, "commit", "-q", "-m", f"commit {k}")
        commits.append(_git(repo_path, "rev-parse", "HEAD"))
        os.environ.pop("LONGTIME_GIT_COMMIT", None)
        registry.register(load(module, str(k)))
        # the minimum of many repeats, in this process and two fresh ones (the plugin is registered
        # for the session: the timing processes receive it)
        argv = ["run", "-p", "harmonic", "-i", "slowed-rk4", "--dt", "0.01", "--t-final", "1000", "--format", "json",
                "--repeats", "48", "--executor", "serial"]
        with contextlib.redirect_stdout(io.StringIO()):
            # the first runs of new code are slower (its kernel loaded, memory touched): unstored
            assert cli.main([*argv, "--min-time", "1", "--no-store", "--processes", "1"]) == 0
            assert cli.main([*argv, "--min-time", "1.5", "--db", db, "--processes", "3"]) == 0
    print(json.dumps(commits))
