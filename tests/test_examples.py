"""The example plugin (examples/plugin, the one README.md and docs/plugins.md point to) is
complete: pip installs it, `longtime list` shows its problem and schemes (none broken) and
`longtime run` runs them with the accuracy their orders promise."""
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from _plugins import longtime

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "plugin"
NAMES = ("example-heun", "example-midpoint", "example-forest-ruth")


@pytest.fixture(scope="module")
def example_env(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("example")
    src, site = tmp / "src", tmp / "site"
    shutil.copytree(EXAMPLE, src)  # pip builds in place: keep the tree clean
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--target", str(site),
                    str(src)], check=True, capture_output=True)
    path = os.pathsep.join(filter(None, [str(site), os.environ.get("PYTHONPATH")]))
    return {**os.environ, "PYTHONPATH": path}


def test_readme_points_to_the_example():
    readme = (ROOT / "README.md").read_text()
    assert "examples/plugin" in readme and "docs/plugins.md" in readme
    # the entry points the plugin contract shows are the example's own
    contract = (ROOT / "docs" / "plugins.md").read_text()
    toml = (EXAMPLE / "pyproject.toml").read_text()
    block = contract.split("```toml\n", 1)[1].split("```", 1)[0]
    assert block.strip() and block.strip() in toml


@pytest.mark.slow
def test_example_plugin_lists_and_runs(example_env):
    res = longtime(example_env, "list", "--format", "json")
    assert res.returncode == 0, res.stderr
    listed = json.loads(res.stdout)
    assert listed["broken"] == []
    problems = {p["name"]: p for p in listed["problems"]}
    assert {"rhs", "separable", "invariants"} <= set(problems["example-pendulum"]["capabilities"])
    schemes = {i["name"]: i for i in listed["integrators"]}
    assert set(NAMES) <= set(schemes)
    assert schemes["example-forest-ruth"]["symplectic"] and schemes["example-forest-ruth"]["order"] == 4

    res = longtime(example_env, "run", "-p", "example-pendulum", "-i", ",".join(NAMES), "--dt", "0.05,0.025",
                   "--t-final", "100", "--repeats", "1", "--no-store", "--format", "json")
    assert res.returncode == 0, res.stderr
    rows = {(r["integrator"], r["dt"]): r for r in json.loads(res.stdout)}
    assert all(r["status"] == "ok" for r in rows.values())
    drift = {k: r["H.max"] for k, r in rows.items()}
    # order 4 symplectic: bounded energy error, 16x smaller at half the step (measured 16.0)
    assert drift[("example-forest-ruth", 0.05)] < 1e-5
    assert 12 < drift[("example-forest-ruth", 0.05)] / drift[("example-forest-ruth", 0.025)] < 20
    # order 2, not symplectic: energy drifts, about 8x less at half the step (measured 8.0, 7.1)
    for name in ("example-heun", "example-midpoint"):
        assert drift[(name, 0.05)] > 1e-3
        assert 5 < drift[(name, 0.05)] / drift[(name, 0.025)] < 10
    assert rows[("example-midpoint", 0.05)]["rhs_evals"] == 2 * rows[("example-midpoint", 0.05)]["steps"]


# one module each: a class that fails its definition check fails its whole module's import
FORGOT_NJIT = '''
from longtime import Problem


def plain_rhs(t, u, params, out):  # forgot @numba.njit
    out[0] = -u[0]


class Forgot(Problem):
    rhs = staticmethod(plain_rhs)

    def initial_state(self):
        return [1.0]
'''
NO_KICKS = '''
from longtime.integrators import Splitting


class NoKicks(Splitting):
    summary = "forgot its coefficients"
'''


@pytest.mark.slow
def test_a_plugin_that_breaks_the_contract_is_listed_broken_with_one_line(tmp_path):
    from _plugins import install_plugin

    env, _ = install_plugin(tmp_path, "longtime-broken-example",
                            {"problems": {"forgot-njit": "forgot_njit:Forgot"},
                             "integrators": {"no-kicks": "no_kicks:NoKicks"}},
                            {"forgot_njit.py": FORGOT_NJIT, "no_kicks.py": NO_KICKS})
    res = longtime(env, "list", "--format", "json")
    assert res.returncode == 0, res.stderr
    broken = {b["name"]: b["error"] for b in json.loads(res.stdout)["broken"]}
    assert "rhs = plain_rhs is not compiled: decorate it with @numba.njit" in broken["forgot-njit"]
    assert "does not set kicks, which its family Splitting declares" in broken["no-kicks"] or \
        "does not set drifts, which its family Splitting declares" in broken["no-kicks"]
    assert all("\n" not in e for e in broken.values())
    res = longtime(env, "run", "-p", "forgot-njit", "-i", "rk4", "--no-store")
    assert res.returncode == 2 and "broken plugin" in res.stderr and "@numba.njit" in res.stderr
