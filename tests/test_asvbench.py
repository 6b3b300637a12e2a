"""longtime.asvbench builds asv's parametrized classes for a selection (a time of the
integration, tracks of l2_error, drift and growth with units) and `longtime asv-init`
writes a plugin repository's asv.conf.json and benchmarks/ that asv can load."""
import json
import math
import re
import subprocess
import sys
from pathlib import Path

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
    assert integration.params == [["kepler", "linear-test"], ["verlet", "asv-verlet-copy", "rk4"],
                                  ["dt=0.02", "dt=0.01"]]
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


class _FakeRun:
    """What time_cells reads of an integration: its status, times and digest."""

    def __init__(self, cpu_s):
        self.status, self.message, self.cpu_s, self.wall_s = "ok", None, cpu_s, cpu_s
        self.extra = {"samples_digest": "same"}


def _fake_cells(monkeypatch, runs, log):
    """Cells whose integration is a fake: the n-th run of cell k logs ("cell", k) and
    reports runs[k][n] (or, for a callable, what it returns) as its CPU seconds."""
    from longtime.execution import processes

    class Integrator:
        def __init__(self, k):
            self.k, self.n = k, 0

        def integrate(self, problem, t_final, **kw):
            log.append(("cell", self.k))
            times = runs[self.k]
            self.n += 1
            return _FakeRun(times() if callable(times) else times[self.n - 1])

    class Problem:
        default_t_final = 1.0

    made = iter(range(len(runs)))
    monkeypatch.setattr(processes, "build", lambda cell: (Problem(), Integrator(next(made))))
    return [processes.Cell("harmonic", "verlet", {}, {"dt": 0.1}, 1.0) for _ in runs]


def test_paired_timing_alternates_cell_and_reference_and_takes_the_ratio_of_minima(monkeypatch):
    from longtime.core.timing import Timing
    from longtime.execution import processes

    log = []
    refs = iter([1.0, 0.75, 1.0, 9.0, 9.0, 9.0])

    def reference():
        log.append(("reference",))
        return next(refs)

    # cell 0: pairs (3, 1), (1.5, 0.75), (3, 1): the pairs' ratios are 3, 2, 3 (median 3),
    # the minima 1.5 and 0.75 (ratio 2)
    cells = _fake_cells(monkeypatch, [[3.0, 1.5, 3.0]], log)
    monkeypatch.setattr(processes, "SPREAD_S", 0.0)
    (record,) = processes.time_cells(cells, 1000, Timing(repeats=3, min_time=0, min_runs=3), reference=reference)
    assert log == [("cell", 0), ("reference",)] * 3  # each run of the cell followed by one of the reference
    assert record["cpu_s_samples"] == [3.0, 1.5, 3.0] and record["reference_s_samples"] == [1.0, 0.75, 1.0]
    assert record["cpu_ratio"] == 2.0
    # two cells in rounds: each run paired with the reference run right after it
    log.clear()
    refs = iter([1.0, 2.0, 1.0, 2.0])
    cells = _fake_cells(monkeypatch, [[1.0, 1.0], [4.0, 4.0]], log)
    a, b = processes.time_cells(cells, 1000, Timing(repeats=2, min_time=0, min_runs=2), reference=reference)
    assert log == [("cell", 0), ("reference",), ("cell", 1), ("reference",)] * 2
    assert a["reference_s_samples"] == [1.0, 1.0] and b["reference_s_samples"] == [2.0, 2.0]
    assert (a["cpu_ratio"], b["cpu_ratio"]) == (1.0, 2.0)
    # no reference: no pairs and no ratio (the timing processes of longtime run)
    log.clear()
    cells = _fake_cells(monkeypatch, [[1.0, 1.0]], log)
    (plain,) = processes.time_cells(cells, 1000, Timing(repeats=2, min_time=0, min_runs=2))
    assert log == [("cell", 0)] * 2 and "cpu_ratio" not in plain and "reference_s_samples" not in plain


def test_paired_ratio_is_the_ratio_of_minima_not_the_median_of_pair_ratios():
    from longtime.execution.processes import paired_ratio

    # a slow moment doubles two of the cell's runs and not the reference beside them
    assert paired_ratio([2.0, 4.0, 4.1], [1.0, 1.0, 1.02]) == 2.0
    assert paired_ratio([4.0, 2.0], [1.1, 1.0]) == 2.0
    for cell, ref in (([], [1.0]), ([1.0], []), ([1.0], [0.0]), ([0.0], [1.0])):
        assert math.isnan(paired_ratio(cell, ref))


def test_twice_the_reference_work_has_a_ratio_of_about_two(monkeypatch):
    """A cell that runs the reference workload twice, timed against it in pairs: about
    2 (the same instructions in registers; loose bounds: the machine may be loaded)."""
    import time

    from longtime.core.timing import Timing
    from longtime.execution import calibration, processes

    calibration.reference_workload(10, 0.01)

    def twice():
        c0 = time.process_time()
        calibration.reference_workload(2 * calibration.STEPS, 0.01)
        return time.process_time() - c0

    cells = _fake_cells(monkeypatch, [twice], [])
    monkeypatch.setattr(processes, "SPREAD_S", 0.5)
    (record,) = processes.time_cells(cells, 1000, Timing(repeats=5, min_time=0, min_runs=5),
                                     reference=calibration.reference_seconds)
    assert len(record["cpu_s_samples"]) == len(record["reference_s_samples"]) >= 5
    assert 1.6 < record["cpu_ratio"] < 2.5, record


@pytest.mark.slow
def test_speed_tracks_a_ratio_per_cell_from_fresh_processes(monkeypatch):
    from longtime.execution import processes

    monkeypatch.setattr(processes, "DEFAULT_PROCESSES", 2)
    classes = benchmarks(["kepler", "linear-test"], ["verlet", "rk4"], dt=0.01, t_final=20)
    assert set(classes) == {"Integration", "Accuracy", "Cost", "Speed"}
    speed = classes["Speed"]
    assert speed.track_cpu_ratio.unit == "x reference"
    bench = speed()
    ratios = bench.setup_cache()
    assert "linear-test|verlet|dt=0.01" not in ratios  # a pair that cannot run: n/a in asv
    with pytest.raises(NotImplementedError):
        bench.setup(ratios, "linear-test", "verlet", "dt=0.01")
    for key in ("kepler|verlet|dt=0.01", "kepler|rk4|dt=0.01"):
        found = ratios[key]
        assert len(found["processes"]) == 2 and found["cpu_ratio"] == min(found["processes"]) > 0
    bench.setup(ratios, "kepler", "rk4", "dt=0.01")
    # rk4 evaluates the force four times a step, Verlet once: more time against the same reference
    assert bench.track_cpu_ratio(ratios, "kepler", "rk4", "dt=0.01") > bench.track_cpu_ratio(
        ratios, "kepler", "verlet", "dt=0.01")


def test_the_example_plugins_suite_is_what_asv_init_writes_for_it():
    """examples/plugin/benchmarks/bench_longtime.py is the template's output for its cells:
    a change of the template shows here until the example is written again."""
    from longtime.commands.asv_init import BENCH_TEMPLATE

    schemes = ["example-forest-ruth", "example-heun", "example-midpoint"]
    expected = BENCH_TEMPLATE.format(what=f"{', '.join(schemes)} on kepler", problems=["kepler"], schemes=schemes,
                                     settings={"dt": [0.01]}, t_final=None)
    example = Path(__file__).resolve().parents[1] / "examples" / "plugin" / "benchmarks" / "bench_longtime.py"
    assert example.read_text() == expected
