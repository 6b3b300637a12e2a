"""Compiled loops are rewritten as cacheable modules: same numbers, loaded from disk next time."""
import os
import subprocess
import sys
import textwrap

import numpy as np

from longtime.core import drivers, jitcache, registry

PROBE = textwrap.dedent('''
    from longtime.core import registry
    from longtime.core.kernel_cache import LOOPS
    p = registry.problem_class("toda")()
    traj = registry.integrator_class("rk4sym")(dt=0.1).integrate(p, 5.0)
    (loop,) = LOOPS.values()
    print(sum(loop.stats.cache_hits.values()), traj.u[-1][0].hex())
''')


def test_generated_kernel_gives_the_same_numbers_as_the_closure():
    problem = registry.problem_class("toda")()
    scheme = registry.integrator_class("rk4sym")(dt=0.1)
    closure = drivers.fixed_step_loop(scheme.make_step(problem))
    frozen = jitcache.cacheable(closure)
    assert frozen is not closure and frozen.py_func.__module__.startswith("longtime_kernel_")
    results = []
    for loop in (closure, frozen):
        u = problem.u0.copy()
        out_t, out_u = np.zeros(12), np.zeros((12, 6))
        out_t[0], out_u[0] = 0.0, u
        status, n, _, _ = loop(u, 0.0, 1.0, 0.1, 0, 10, 10, drivers.sample_steps(10, 11), 0, 1,
                               problem.params, np.zeros(scheme.work_shape(problem)), out_t, out_u,
                               drivers.new_counters(), 1e10)
        assert status == drivers.OK and n == 11
        results.append(out_u[:n])
    assert np.array_equal(results[0], results[1])


def test_unfreezable_closure_is_returned_unchanged():
    import numba

    class Opaque:  # an arbitrary object cannot become a module global
        scale = 2.0

    def closure_over(obj):
        scale = obj

        @numba.njit
        def g(x):
            return x if scale is None else x

        return g

    g = closure_over(Opaque())
    assert jitcache.cacheable(g) is g


def test_second_process_loads_the_kernel_from_disk(tmp_path):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba"), "LONGTIME_CACHE_DIR": str(tmp_path / "lt")}
    runs = [subprocess.run([sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, timeout=300)
            for _ in range(2)]
    for r in runs:
        assert r.returncode == 0, r.stderr
    (hits1, x1), (hits2, x2) = (r.stdout.split() for r in runs)
    assert x1 == x2
    assert hits1 == "0" and hits2 != "0"
    assert list((tmp_path / "lt" / "kernels").glob("longtime_kernel_*.py"))


def test_source_that_no_longer_matches_the_code_is_not_frozen(tmp_path, monkeypatch):
    """A kernel module edited after import must not be frozen from the new text."""
    import importlib.util

    path = tmp_path / "edited_kernels.py"
    path.write_text(textwrap.dedent('''
        import numba

        def make(c):
            @numba.njit
            def kernel(x):
                return x * c
            return kernel
    '''))
    spec = importlib.util.spec_from_file_location("edited_kernels", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules["edited_kernels"] = module
    spec.loader.exec_module(module)
    kernel = module.make(3.0)
    # the file changes under the running process: same line numbers, other code
    path.write_text(path.read_text().replace("return x * c", "return x + c + 1.0"))
    try:
        assert jitcache.cacheable(kernel) is kernel
        assert kernel(2.0) == 6.0
    finally:
        sys.modules.pop("edited_kernels")


def test_fingerprint_covers_callees_and_captured_values(tmp_path):
    """The kernel's own code is unchanged; its callee's code, or a captured number, is not."""
    import importlib.util

    path = tmp_path / "fingerprinted.py"
    prints = []
    for coefficient in ("2.0", "3.0", "2.0"):
        path.write_text(textwrap.dedent(f'''
            import numba

            @numba.njit
            def helper(x):
                return x * {coefficient}

            def make(n):
                @numba.njit
                def kernel(x):
                    return helper(x) + n
                return kernel
        '''))
        spec = importlib.util.spec_from_file_location("fingerprinted", path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        prints.append([jitcache.fingerprint(module.make(n)) for n in (1, 2, 1)])
    assert prints[0] == prints[2] and prints[0][0] == prints[0][2]  # a function of the code alone
    assert prints[0][0] != prints[1][0]  # the callee changed
    assert prints[0][0] != prints[0][1]  # the captured n changed
