"""A kernel compiles once per machine, not once per process: what a Python loop calls (scipy's
DOP853 calls the problem's rhs) comes from the disk cache like the compiled loops do. A
closure rhs (nbody's, the separable problems') compiled afresh in every worker cost up to
0.75 s each, 1.8 s per process in the main job."""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from longtime.core import heyoka_build, registry

_CHILD = r"""
import json, sys
from numba.core import event
from longtime.core import registry
compiled = []

class Listener(event.Listener):
    def on_start(self, ev):
        pass

    def on_end(self, ev):
        compiled.append(ev.data["dispatcher"].py_func.__qualname__)

event.register("numba:compile", Listener())
scheme = sys.argv[1]
for name in sys.argv[2:]:
    problem = registry.problem_class(name)()
    traj = registry.integrator_class(scheme)().integrate(problem, problem.t0 + 1.0, max_samples=8)
    assert traj.status == "ok", traj.message
print(json.dumps([compiled, traj.u[-1].tolist()]))
"""


def _two_processes(tmp_path, scheme, *problems):
    """(compiled, final state) of a cold process and of a second one on the same caches."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba"), LONGTIME_CACHE_DIR=str(tmp_path / "lt"))

    def run():
        out = subprocess.run([sys.executable, "-c", _CHILD, scheme, *problems], env=env, capture_output=True,
                             text=True, check=True)
        return json.loads(out.stdout.strip().splitlines()[-1])

    return run(), run()


@pytest.mark.slow
def test_dop853_rhs_comes_from_the_disk_cache(tmp_path):
    # a closure rhs (nbody) and a separable one
    (compiled, _), (again, _) = _two_processes(tmp_path, "dop853", "figure-eight", "kepler")
    assert "rhs" in compiled  # the cold process compiles the problems' rhs
    assert again == []  # a second process finds everything in the cache


@pytest.mark.slow
def test_bpl_kernels_call_the_pade_compiled_once(tmp_path):
    """bpl's robust Pade is a cfunc the kernels call by symbol: a kernel loaded from the cache
    in a new process finds it (registered before any kernel loads) and runs bitwise alike."""
    from longtime.core.jitcache import _names_used
    from longtime.integrators import bpl

    called = _names_used(bpl.make_try_step.__code__)  # the names its nested kernels read
    assert "_prepare_pade_shared" in called and "_prepare_pade" not in called  # not linked in
    (compiled, first), (again, second) = _two_processes(tmp_path, "bpl", "harmonic", "kepler")
    assert "try_step" in compiled and "_prepare_pade" in compiled  # the Pade itself compiled once
    assert again == []
    assert first == second


def test_the_reference_switches_to_compact_mode_sooner_than_the_scheme():
    solar = registry.problem_class("outer-solar-system")()
    assert 24 < solar.dim <= heyoka_build.COMPACT_ABOVE
    assert heyoka_build.compact_mode(solar, np.float64, reference=True)
    assert not heyoka_build.compact_mode(solar, np.float64)  # the timed scheme keeps straight-line code
    small = registry.problem_class("figure-eight")()
    assert not heyoka_build.compact_mode(small, np.float64, reference=True)


def _batches(pairs):
    from longtime.execution.cells import Cell

    return [[Cell(problem, scheme, {}, {}, None)] for problem, scheme in pairs]


def test_no_two_running_batches_share_code_that_is_not_compiled_yet():
    from longtime.execution.matrix import CompileOnce, shared_code

    batches = _batches([("kdv", "rk4"), ("kdv", "rk4sym"), ("toda", "rk4"), ("harmonic", "verlet"),
                        ("toda", "bpl"), ("kepler", "bpl-exp")])
    assert "longtime.problems.kdv" in shared_code(batches[0])
    assert "longtime.integrators.bpl" in shared_code(batches[5])  # bpl-exp inherits bpl's Pade
    assert not any(m.startswith("longtime.core.") for b in batches for m in shared_code(b))  # the base classes'
    order = CompileOnce(batches)
    first, second = order.take(), order.take()
    assert (first[0].problem, second[0].problem) == ("kdv", "harmonic")  # not kdv twice, not rk4 twice
    third = order.take()
    assert (third[0].problem, third[0].integrator) == ("toda", "bpl")
    fourth = order.take()  # all the rest share kdv, explicit RK or bpl with a running batch: never idle
    assert (fourth[0].problem, fourth[0].integrator) == ("kdv", "rk4sym")
    for batch in (first, second, third):
        order.finished(batch)
    assert [order.take()[0].integrator for _ in range(2)] == ["rk4", "bpl-exp"]  # compiled now: in order
    assert not order


def test_idle_workers_take_extra_work_only_once_every_batch_is_handed_out():
    """The results page's figures run on the pool's workers, but never beside a batch that
    waits for a worker (they would take time from timed cells); work made ready by the
    caller's last rows is still picked up; a failing task only loses its own result."""
    import threading
    from concurrent.futures import ThreadPoolExecutor

    from longtime.execution.matrix import scheduled

    batches = _batches([("toda", "rk4"), ("kepler", "verlet"), ("harmonic", "euler"), ("duffing-1", "rk45")])
    log, results, seen = [], {}, []
    lock = threading.Lock()

    def run(batch):
        with lock:
            log.append(("batch", batch[0].problem))
        return batch[0].problem

    def extra(name):
        with lock:
            log.append(("extra", name))
        if name == "bad":
            raise RuntimeError("a figure that fails")
        return name.upper()

    tasks = ["early"]  # ready from the start, yet it waits for every batch to be handed out

    def idle_work():
        if not tasks:
            return None
        name = tasks.pop(0)
        return extra, (name,), lambda out: results.__setitem__(name, out)

    with ThreadPoolExecutor(2) as pool:
        for batch, fut in scheduled(pool, 2, batches, lambda batch: pool.submit(run, batch), idle_work=idle_work):
            seen.append(fut.result())
            if len(seen) == len(batches):  # ready once the caller has the last rows, nothing running
                tasks.extend(["a", "bad", "b"])
    first_extra = next(i for i, (kind, _) in enumerate(log) if kind == "extra")
    assert [k for k, _ in log[:first_extra]] == ["batch"] * len(batches)  # every batch handed out first
    assert sorted(seen) == sorted(b[0].problem for b in batches)  # the caller sees the batches only
    assert results == {"early": "EARLY", "a": "A", "b": "B"}  # 'bad' lost its own result, nothing else
