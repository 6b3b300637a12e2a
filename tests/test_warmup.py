"""`longtime warmup`: one compilation per distinct kernel, into the disk cache a later process loads."""
import os
import subprocess
import sys

from longtime.commands.warmup import distinct_kernels
from longtime.execution.cells import expand


def test_cells_that_differ_only_in_run_time_values_share_one_kernel():
    cells = expand(["toda"], ["rk4", "bpl", "taylor"], sweeps={"dt": [0.1, 0.05], "eps_res": [1e-3, 1e-4],
                                                               "order": [6, 8]})
    kernels = distinct_kernels(cells)
    pairs = sorted((c.integrator, c.integrator_settings.get("order")) for c in kernels)
    # rk4: the dt values share its loop; bpl and taylor close over N: one kernel per order
    assert pairs == [("bpl", 6), ("bpl", 8), ("rk4", None), ("taylor", 6), ("taylor", 8)]


def test_warmup_fills_the_cache_that_a_later_process_loads(tmp_path):
    env = {**os.environ, "LONGTIME_CACHE_DIR": str(tmp_path / "cache"), "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    env.pop("LONGTIME_NO_KERNEL_CACHE", None)
    done = subprocess.run([sys.executable, "-m", "longtime.commands.cli", "warmup", "-p", "harmonic",
                           "-i", "rk4,verlet", "--jobs", "1"], env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert "warmed 2 kernels" in done.stderr
    kernels = list((tmp_path / "cache" / "kernels").glob("longtime_kernel_*.py"))
    assert len(kernels) >= 2  # each loop and the step it closes over
    # a later process loads those kernels: numba compiles nothing of them (its compile events)
    probe = ("from numba.core import event; from longtime.core import registry; "
             "p = registry.problem_class('harmonic')(); s = registry.integrator_class('verlet')()\n"
             "with event.install_recorder('numba:compile') as rec: s.integrate(p, 0.1, max_samples=16)\n"
             "print(sum(e.is_start and 'longtime_kernel_' in getattr(e.data.get('dispatcher'), "
             "'py_func', print).__module__ for _, e in rec.buffer))")
    loaded = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, timeout=600)
    assert loaded.returncode == 0, loaded.stderr
    assert loaded.stdout.strip() == "0"
