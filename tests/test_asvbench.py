"""longtime.asvbench builds asv's parametrized classes for a selection (a time of the
integration, tracks of l2_error, drift and growth with units) and `longtime asv-init`
writes a plugin repository's asv.conf.json and benchmarks/ that asv can load."""
import json
import math
import re
import subprocess
import sys

import pytest

from longtime.asvbench import benchmarks
from longtime.integrators import Splitting, compose


class AsvVerletCopy(Splitting):
    order = 2
    kicks, drifts = compose([1.0])


def test_benchmarks_time_and_track_every_cell():
    classes = benchmarks(["kepler", "linear-test"], ["verlet", AsvVerletCopy, "rk4"], dt=[0.02, 0.01], t_final=10)
    integration, accuracy = classes["Integration"], classes["Accuracy"]
    assert integration.__name__ == "Integration" and accuracy.__name__ == "Accuracy"
    assert integration.params == [["kepler", "linear-test"], ["verlet", "asv-verlet-copy", "rk4"], ["dt=0.02", "dt=0.01"]]
    assert accuracy.track_l2_error.unit == accuracy.track_drift.unit == "relative error"
    assert accuracy.track_growth_class.unit.startswith("growth class")
    assert not hasattr(accuracy, "track_growth")  # an exponent near 0: its ratio judges nothing
    assert classes["Cost"].track_instructions.unit == "instructions"
    # asv times CPU seconds of the process, as longtime does: the wall clock counts a neighbour's turns
    import time

    assert integration.timer is time.process_time and integration.processes >= 2

    bench = integration()
    bench.setup("kepler", "asv-verlet-copy", "dt=0.01")
    assert bench.integrator.settings["dt"] == 0.01 and bench.t_final == 10
    bench.time_integrate("kepler", "asv-verlet-copy", "dt=0.01")
    # the minimum over runs spread in time, of the same integration: CPU seconds, the
    # runs' own (at least the per-process repeats, each a bitwise copy of the first)
    from longtime.execution import processes

    processes.SPREAD_S, spread = 0.0, processes.SPREAD_S
    try:
        cpu = bench.track_cpu_s("kepler", "asv-verlet-copy", "dt=0.01")
    finally:
        processes.SPREAD_S = spread
    assert integration.track_cpu_s.unit == "seconds" and 0 < cpu < 10
    with pytest.raises(NotImplementedError, match="needs separable"):  # asv skips the pair
        bench.setup("linear-test", "verlet", "dt=0.01")

    acc = accuracy()
    rows = acc.setup_cache()
    assert "linear-test|verlet|dt=0.01" not in rows and "linear-test|rk4|dt=0.01" in rows
    args = ("kepler", "asv-verlet-copy", "dt=0.01")
    acc.setup(rows, *args)
    # the copy is Verlet: the same numbers as the built-in
    assert acc.track_l2_error(rows, *args) == acc.track_l2_error(rows, "kepler", "verlet", "dt=0.01") > 0
    assert acc.track_drift(rows, *args) == rows["kepler|verlet|dt=0.01"]["H.max"] > 0
    growth_class = rows["kepler|asv-verlet-copy|dt=0.01"]["H.growth_class"]  # undetermined over t = 10
    assert math.isnan(acc.track_growth_class(rows, *args)) == (growth_class == "undetermined")
    halved = acc.track_l2_error(rows, "kepler", "verlet", "dt=0.02") / acc.track_l2_error(rows, *args)
    assert 3 < halved < 5  # order 2
    with pytest.raises(NotImplementedError):
        acc.setup(rows, "linear-test", "verlet", "dt=0.01")
    assert math.isnan(acc.track_l2_error(rows, "linear-test", "rk4", "dt=0.01")) or \
        acc.track_l2_error(rows, "linear-test", "rk4", "dt=0.01") > 0


def test_asv_init_writes_a_loadable_suite(tmp_path):
    (tmp_path / "pyproject.toml").write_text(
        '[project]\nname = "my-schemes"\n[project.entry-points."longtime.integrators"]\n'
        'my-scheme = "my_schemes:MyScheme"\n')
    res = subprocess.run([sys.executable, "-m", "longtime.commands.cli", "asv-init", str(tmp_path), "-p", "kepler",
                          "-i", "verlet", "--dt", "0.01,0.005"], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    conf = json.loads("\n".join(l for l in (tmp_path / "asv.conf.json").read_text().splitlines()
                                if not l.lstrip().startswith("//")))
    assert conf["project"] == "my-schemes" and conf["benchmark_dir"] == "benchmarks"
    module = (tmp_path / "benchmarks" / "bench_longtime.py").read_text()
    assert "SCHEMES = ['verlet']" in module and "'dt': [0.01, 0.005]" in module
    probe = ("import runpy; g = runpy.run_path('benchmarks/bench_longtime.py'); "
             "print(g['Integration'].params, g['Accuracy'].track_l2_error.unit)")
    res = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert "[['kepler'], ['verlet'], ['dt=0.01', 'dt=0.005']] relative error" in res.stdout
    # without -p the declared names are taken, and a problem is still needed
    res = subprocess.run([sys.executable, "-m", "longtime.commands.cli", "asv-init", str(tmp_path), "--force"],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 2 and re.search(r"declares problems none, schemes \['my-scheme'\]", res.stderr)


def test_instructions_without_valgrind_are_skipped_saying_why(monkeypatch, tmp_path):
    monkeypatch.setenv("PATH", str(tmp_path))  # no valgrind on PATH
    cost = benchmarks(["kepler"], ["verlet"], dt=0.01, t_final=1)["Cost"]
    bench = cost()
    counts = bench.setup_cache()
    with pytest.raises(NotImplementedError, match="Debian package 'valgrind'"):  # asv shows n/a
        bench.setup(counts, "kepler", "verlet", "dt=0.01")


def test_growth_class_ranks_are_ratios_asv_can_judge():
    from longtime.asvbench import GROWTH_RANKS
    from longtime.measure.growth import CLASSES

    acc = benchmarks(["kepler"], ["verlet"], dt=0.01, t_final=1000)["Accuracy"]()
    rows = acc.setup_cache()
    assert rows["kepler|verlet|dt=0.01"]["H.growth_class"] == "bounded"  # an exponent of about 1e-7
    assert acc.track_growth_class(rows, "kepler", "verlet", "dt=0.01") == 1.0

    # every class a run can end in has a rank, worse is larger; undetermined has none (n/a)
    assert set(GROWTH_RANKS) == set(CLASSES) - {"undetermined"}
    order = ["bounded", "sqrt", "linear", "quadratic", "faster", "saturated", "diverged"]
    assert [GROWTH_RANKS[c] for c in order] == sorted(GROWTH_RANKS.values())
    assert GROWTH_RANKS["linear"] / GROWTH_RANKS["bounded"] > 1.05  # a change of class is a step asv marks
