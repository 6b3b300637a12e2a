"""Importing longtime and loading every plugin compiles nothing (numba compiles lazily)."""
import os
import subprocess
import sys
import textwrap

PROBE = textwrap.dedent('''
    import sys
    from numba.core.registry import CPUDispatcher
    from longtime.core import registry
    problems, schemes = registry.problems(), registry.integrators()
    assert not registry.broken(), registry.broken()
    dispatchers = [v for name, mod in list(sys.modules.items()) if name.startswith("longtime")
                   for v in vars(mod).values() if isinstance(v, CPUDispatcher)]
    compiled = [d.py_func.__qualname__ for d in dispatchers if d.signatures]
    print(len(problems), len(schemes), len(dispatchers), compiled)
''')


def test_import_and_plugin_discovery_compile_nothing(tmp_path):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    res = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, timeout=300, env=env)
    assert res.returncode == 0, res.stderr
    n_problems, n_schemes, n_dispatchers, compiled = res.stdout.split(maxsplit=3)
    assert int(n_problems) >= 12 and int(n_schemes) >= 21
    assert int(n_dispatchers) > 20  # the probe does see the kernels
    assert compiled.strip() == "[]"


def test_plugin_discovery_leaves_kdvs_fft_until_a_kdv_is_made():
    # every problem's module is imported to register it: kdv's FFT (rocket-fft, scipy.fft)
    # is imported with the first KdV, and its kernels then find it
    probe = textwrap.dedent('''
        import sys
        from longtime.core import registry
        registry.problem_class("kepler")
        print(sorted(m for m in ("rocket_fft", "scipy.fft") if m in sys.modules))
        registry.problem_class("kdv")(d=8)
        print(sorted(m for m in ("rocket_fft", "scipy.fft") if m in sys.modules))
    ''')
    res = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert res.stdout.split("\n")[:2] == ["[]", "['rocket_fft', 'scipy.fft']"]
