"""Compiled kernels are never stale: a kernel is keyed by the fingerprint of everything it
runs and closes over, in the process (``_LOOPS``) and on disk (the generated module's name)."""
import collections
import json
import os
import subprocess
import sys
import textwrap

import numba
import numpy as np
import pytest
from _plugins import install_plugin, longtime

from longtime import FixedStepIntegrator
from longtime.commands.cli import main
from longtime.core import drivers
from longtime.problems.toda import Toda


class AddIndex(FixedStepIntegrator):
    """u_i += h (i + 1) for i < n, with n = problem.dim captured by the compiled step."""

    name = "add-index"

    def make_step(self, problem):
        n = problem.dim

        @numba.njit
        def step(t, u, h, params, work, counters, first):
            for i in range(n):
                u[i] += h * (i + 1)
            return drivers.OK

        return step


Scale = collections.namedtuple("Scale", "factor")


class AddScaled(AddIndex):
    """The same over a namedtuple, which has no fingerprint: its kernel is never shared."""

    name = "add-scaled"

    def make_step(self, problem):
        n, scale = problem.dim, Scale(2.0)

        @numba.njit
        def step(t, u, h, params, work, counters, first):
            for i in range(n):
                u[i] += h * scale.factor
            return drivers.OK

        return step


def _private_cache(tmp_path, env):
    """``env`` with longtime's cache in tmp_path, shared by the test's processes: kernels are
    compiled afresh there (numba's cache of longtime's own functions, keyed by their files,
    is the session's)."""
    return {**env, "LONGTIME_CACHE_DIR": str(tmp_path / "lt")}


def _loop(scheme, problem):
    return scheme.compiled_loop(problem)


def test_a_step_that_captures_the_dimension_never_runs_another_dimension():
    for d in (3, 4, 3):
        problem = Toda(d=d)
        traj = AddIndex(dt=0.25).integrate(problem, 1.0)
        assert traj.status == "ok"
        np.testing.assert_allclose(traj.u[-1], problem.u0 + np.arange(1, 2 * d + 1), rtol=0, atol=1e-12)
    assert _loop(AddIndex(), Toda(d=3)) is not _loop(AddIndex(), Toda(d=4))
    assert _loop(AddIndex(), Toda(d=3)) is _loop(AddIndex(dt=0.5), Toda(d=3))  # equal settings share


def test_a_kernel_without_fingerprint_is_never_shared():
    scheme, d3, d4 = AddScaled(dt=0.25), Toda(d=3), Toda(d=4)
    assert _loop(scheme, d3) is _loop(scheme, d3)  # reused by the same scheme on the same problem
    assert _loop(scheme, d3) is not _loop(scheme, d4)
    assert _loop(scheme, d3) is not _loop(AddScaled(), d3)
    for problem in (d3, d4):
        traj = scheme.integrate(problem, 1.0)
        np.testing.assert_allclose(traj.u[-1], problem.u0 + 2.0, rtol=0, atol=1e-12)


SCHEMES = {"rk4": {"dt": 0.1}, "verlet": {"dt": 0.1}, "rk4sym": {"dt": 0.1}, "taylor": {"dt": 0.1}, "bpl": {}}
TODA_PROBE = textwrap.dedent(f'''
    import json, sys
    from longtime.core import registry
    out = {{}}
    for d in map(int, sys.argv[1:]):
        problem = registry.problem_class("toda")(d=d)
        for name, settings in {SCHEMES!r}.items():
            traj = registry.integrator_class(name)(**settings).integrate(problem, 10.0)
            out[f"{{d}} {{name}}"] = [traj.status, traj.counters, traj.u[-1].tobytes().hex()]
    print(json.dumps(out))
''')


@pytest.mark.slow
def test_toda_d3_then_d4_in_one_process_matches_fresh_processes_bitwise(tmp_path):
    env = _private_cache(tmp_path, os.environ)

    def run(*ds):
        res = subprocess.run([sys.executable, "-c", TODA_PROBE, *map(str, ds)], env=env, capture_output=True,
                             text=True, timeout=900)
        assert res.returncode == 0, res.stderr
        return json.loads(res.stdout)

    both = run(3, 4)  # first: compiles every kernel, d = 4 after d = 3 in one process
    assert {k: v[0] for k, v in both.items()} == {f"{d} {s}": "ok" for d in (3, 4) for s in SCHEMES}
    assert both == {**run(3), **run(4)}


SPRING = '''
import numba
import numpy as np

from longtime import Problem


@numba.njit(cache=True)
def _spring_rhs(t, u, params, out):
    out[0] = u[1]
    out[1] = -4.0 * u[0]


class Spring(Problem):
    """q'' = -k q, k written in the rhs (and in exact: an edit changes both)."""
    default_t_final = 3.0
    default_dt = 0.01
    rhs = staticmethod(_spring_rhs)

    def initial_state(self):
        return [1.0, 0.0]

    def exact(self, t):
        w = np.sqrt(4.0)
        t = np.asarray(t, dtype=float)
        return np.stack([np.cos(w * t), -w * np.sin(w * t)], axis=1)
'''


@pytest.mark.slow
def test_an_edited_plugin_rhs_runs_the_new_code(tmp_path):
    plugin_env, site = install_plugin(tmp_path / "plugin", "longtime-spring",
                                      {"problems": {"spring": "longtime_spring:Spring"}},
                                      {"longtime_spring.py": SPRING})
    env = _private_cache(tmp_path, plugin_env)
    kernels, source = tmp_path / "lt" / "kernels", site / "longtime_spring.py"

    def final_error():
        res = longtime(env, "run", "-p", "spring", "-i", "rk4", "--format", "json", "--no-store")
        assert res.returncode == 0, res.stderr
        (row,) = json.loads(res.stdout)
        assert row["status"] == "ok"
        return row["final_error"]

    assert final_error() < 1e-6
    # k = 4 -> 16 changes the file's size, 16 -> 25 does not
    for old_k, new_k in (("4.0", "16.0"), ("16.0", "25.0")):
        modules = set(kernels.glob("longtime_kernel_*.py"))
        stat = source.stat()
        source.write_text(source.read_text().replace(old_k, new_k))
        # a later mtime whatever the clock's resolution: Python's .pyc and numba's own
        # cache of the rhs check the source's mtime (and size)
        os.utime(source, (stat.st_atime, stat.st_mtime + 10))
        # the old kernel would integrate the old k against the new exact solution: error ~ 1
        assert final_error() < 1e-6
        assert set(kernels.glob("longtime_kernel_*.py")) - modules  # a new kernel module


@pytest.mark.slow
def test_cache_info_and_clear(tmp_path, monkeypatch, capsys):
    # a private numba cache too: clear removes its entries of generated kernels
    env = {**_private_cache(tmp_path, os.environ), "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    res = longtime(env, "run", "-p", "harmonic", "-i", "rk4", "--t-final", "1", "--no-store")
    assert res.returncode == 0, res.stderr
    # the run checked harmonic's exact solution against heyoka: one cached check already
    refs = tmp_path / "lt" / "reference"
    refs.mkdir(exist_ok=True)
    ref_files = [f for f in refs.rglob("*") if f.is_file()]
    ref_bytes = sum(f.stat().st_size for f in ref_files)
    (refs / "toda-x.npy").write_bytes(b"\0" * 100)
    for name in ("NUMBA_CACHE_DIR", "LONGTIME_CACHE_DIR"):
        monkeypatch.setenv(name, env[name])

    def cache(*args):
        assert main(["cache", *args]) == 0
        return capsys.readouterr().out

    def info():
        return {f["folder"]: f for f in json.loads(cache("info", "--format", "json"))["folders"]}

    before = info()
    assert set(before) == {"kernels", "reference", "numba"}
    assert before["kernels"]["files"] >= 2 and before["reference"] == {
        "folder": "reference", "path": str(refs), "files": len(ref_files) + 1, "bytes": ref_bytes + 100}
    assert list((tmp_path / "numba").rglob("longtime_kernel_*"))
    assert "reference" in cache("info")

    n = len(ref_files) + 1
    assert f"removed {n} file{'' if n == 1 else 's'}" in cache("clear", "--references")
    assert info()["reference"]["files"] == 0
    assert info()["kernels"]["files"] == before["kernels"]["files"]

    out = cache("clear")
    assert str(tmp_path / "lt" / "kernels") in out and "numba" in out
    after = info()
    assert after["kernels"]["files"] == after["reference"]["files"] == 0
    assert not list((tmp_path / "numba").rglob("longtime_kernel_*"))
    assert after["numba"]["files"] > 0  # numba's cache of longtime's own functions stays
