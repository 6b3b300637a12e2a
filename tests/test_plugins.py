"""A third-party plugin package, pip-installed, joins the matrix through entry points
(installed as tests/_plugins.py describes)."""
import json
import sqlite3

import pytest
from _plugins import install_plugin, longtime

PLUGIN = '''
import numba
import numpy as np

from longtime import Problem
from longtime.integrators.explicit_rk import ExplicitRungeKutta


@numba.njit(cache=True)
def _pendulum_rhs(t, u, params, out):
    out[0] = u[1]
    out[1] = -np.sin(u[0]) - params[0] * u[1]


class DampedPendulum(Problem):
    """Provides only rhs: schemes that need a separable H must be skipped."""
    summary = "damped pendulum from a plugin"
    default_t_final = 10.0
    default_dt = 0.05
    sweep_dt = (0.05,)
    rhs = staticmethod(_pendulum_rhs)

    def initial_state(self):
        return [1.0, 0.0]

    def kernel_params(self):
        return np.array([0.1])


class Heun(ExplicitRungeKutta):
    summary = "Heun's method from a plugin (order 2)"
    order = 2
    A = np.array([[0.0, 0.0], [1.0, 0.0]])
    b = np.array([0.5, 0.5])
    c = np.array([0.0, 1.0])


class Exploding(Heun):
    summary = "raises inside integrate"

    def _integrate(self, problem, t_final, max_samples):
        raise RuntimeError("plugin bug")
'''


@pytest.fixture(scope="module")
def plugin_env(tmp_path_factory):
    entry_points = {
        "problems": {"plug-pendulum": "longtime_testplugin:DampedPendulum"},
        "integrators": {"plug-heun": "longtime_testplugin:Heun", "plug-exploding": "longtime_testplugin:Exploding",
                        "plug-broken": "longtime_testplugin_broken:Anything"},
    }
    env, _ = install_plugin(tmp_path_factory.mktemp("plugin"), "longtime-testplugin", entry_points, {
        "longtime_testplugin.py": PLUGIN,
        "longtime_testplugin_broken.py": "raise RuntimeError('this plugin is broken on purpose')\n"})
    return env


def test_plugin_is_listed_and_broken_plugin_reported(plugin_env):
    res = longtime(plugin_env, "list", "--format", "json")
    assert res.returncode == 0, res.stderr
    data = json.loads(res.stdout)
    assert "plug-pendulum" in {p["name"] for p in data["problems"]}
    assert {"plug-heun", "plug-exploding"} <= {i["name"] for i in data["integrators"]}
    broken = {b["name"]: b for b in data["broken"]}
    assert "this plugin is broken on purpose" in broken["plug-broken"]["error"]
    assert "rk4" in {i["name"] for i in data["integrators"]}  # the rest go on


@pytest.mark.slow
def test_plugin_joins_the_matrix(plugin_env, tmp_path):
    db = tmp_path / "plugin.sqlite"
    res = longtime(plugin_env, "matrix", "-p", "plug-pendulum,harmonic", "-i", "plug-heun,plug-exploding,rk4,verlet",
                   "--executor", "serial", "--db", str(db), "--no-progress", "--t-final", "5")
    assert res.returncode == 0, res.stderr
    assert "plug-broken" in res.stderr and "failed to load" in res.stderr
    with sqlite3.connect(db) as con:
        rows = [json.loads(r[0]) for r in con.execute("SELECT row FROM rows")]
    by_pair = {(r["problem"], r["integrator"], r["dt"]): r for r in rows}
    status = {(p, i): r["status"] for (p, i, _), r in by_pair.items()}
    assert status[("plug-pendulum", "plug-heun")] == "ok"
    assert status[("plug-pendulum", "rk4")] == "ok"
    assert status[("harmonic", "plug-heun")] == "ok"
    assert status[("plug-pendulum", "verlet")] == "skipped"
    assert status[("harmonic", "plug-exploding")] == "failed"
    exploded = next(r for r in rows if r["integrator"] == "plug-exploding")
    assert "plugin bug" in exploded["message"]
    skipped = next(r for r in rows if r["status"] == "skipped")
    assert "separable" in skipped["message"]
    # the plugin's Heun is second order on the harmonic oscillator
    heun = sorted((r["dt"], r["final_error"]) for r in rows
                  if r["problem"] == "harmonic" and r["integrator"] == "plug-heun")
    assert len(heun) == 3 and heun[0][1] < heun[1][1] < heun[2][1]


def test_asking_for_a_broken_plugin_is_an_error(plugin_env):
    res = longtime(plugin_env, "run", "-p", "harmonic", "-i", "plug-broken", "--no-store")
    assert res.returncode == 2
    assert "broken plugin" in res.stderr and "broken on purpose" in res.stderr
