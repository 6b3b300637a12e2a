"""A kernel compiles once per machine, not once per process: what a Python loop calls (scipy's
DOP853 calls the problem's rhs) comes from the disk cache like the compiled loops do. A
closure rhs (nbody's, the separable problems') compiled afresh in every worker cost up to
0.75 s each, 1.8 s per process in the main job."""
import json
import os
import subprocess
import sys

import numpy as np

from longtime import heyoka_build, registry

_CHILD = r"""
import json, sys
from numba.core import event
from longtime import registry
compiled = []

class Listener(event.Listener):
    def on_start(self, ev):
        pass

    def on_end(self, ev):
        compiled.append(ev.data["dispatcher"].py_func.__qualname__)

event.register("numba:compile", Listener())
for name in sys.argv[1:]:
    problem = registry.problem_class(name)()
    traj = registry.integrator_class("dop853")(tol=1e-6).integrate(problem, problem.t0 + 1.0, max_samples=8)
    assert traj.status == "ok", traj.message
print(json.dumps(compiled))
"""


def test_dop853_rhs_comes_from_the_disk_cache(tmp_path):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba"), LONGTIME_CACHE_DIR=str(tmp_path / "lt"))
    problems = ["figure-eight", "kepler"]  # a closure rhs (nbody) and a separable one

    def compiled():
        out = subprocess.run([sys.executable, "-c", _CHILD, *problems], env=env, capture_output=True,
                             text=True, check=True)
        return json.loads(out.stdout.strip().splitlines()[-1])

    first = compiled()
    assert "rhs" in first  # the cold process compiles the problems' rhs
    assert compiled() == []  # a second process finds everything in the cache


def test_the_reference_switches_to_compact_mode_sooner_than_the_scheme():
    solar = registry.problem_class("outer-solar-system")()
    assert 24 < solar.dim <= heyoka_build.COMPACT_ABOVE
    assert heyoka_build.compact_mode(solar, np.float64, reference=True)
    assert not heyoka_build.compact_mode(solar, np.float64)  # the timed scheme keeps straight-line code
    small = registry.problem_class("figure-eight")()
    assert not heyoka_build.compact_mode(small, np.float64, reference=True)
