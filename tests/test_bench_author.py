"""The scheme author's repository that benchmarks/bench_author_repo.py builds: its versions
change what they claim (and nothing else), and its reading of `asv compare` and of the
flags finds each wrong or missing flag."""
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import bench_author_repo as bench  # noqa: E402

TABLE = """
| Change   | Before [adf3744d]    | After [9c1e0b7a]    |   Ratio | Benchmark (Parameter)                                                              |
|----------|----------------------|---------------------|---------|------------------------------------------------------------------------------------|
| +        | 6.31±0.2ms           | 8.52±0.3ms          |    1.35 | bench_longtime.Integration.time_integrate('harmonic', 'author-rk4', 'dt=0.01')     |
|          | 7.10±0.4ms           | 7.33±0.5ms          |   ~1.03 | bench_longtime.Integration.time_integrate('harmonic', 'verlet', 'dt=0.01')         |
| +        | 4.4M                 | 5.9M                |    1.34 | bench_longtime.Cost.track_instructions('harmonic', 'author-rk4', 'dt=0.01')        |
| -        | 2.84e-06             | 4.81e-08            |    0.02 | bench_longtime.Accuracy.track_l2_error('duffing-2', 'author-rk4', 'dt=0.01')       |
|          | n/a                  | n/a                 |     n/a | bench_longtime.Accuracy.track_growth_class('duffing-2', 'verlet', 'dt=0.01')       |
"""  # noqa: E501 (asv compare's table, verbatim)


def test_asv_compare_table_is_read_per_cell():
    marks = bench.read_compare(TABLE)
    assert marks[("harmonic", "author-rk4")] == {"time_integrate": "+", "time_integrate ratio": "1.35",
                                                 "track_instructions": "+", "track_instructions ratio": "1.34"}
    assert marks[("harmonic", "verlet")] == {"time_integrate ratio": "~1.03"}  # not significant: no mark
    assert marks[("duffing-2", "author-rk4")] == {"track_l2_error": "-", "track_l2_error ratio": "0.02"}
    assert "track_growth_class" not in marks[("duffing-2", "verlet")]


def test_flags_are_checked_both_ways():
    expect = bench.expected_asv("author-rk4", bench.LESS_ACCURATE)
    accuracy = set(bench.ACCURACY_NAMES)
    assert bench.check({"track_l2_error": "+", "track_drift": "+"}, expect, "track_l2_error", accuracy) == []
    assert bench.check({}, expect, "track_l2_error", accuracy) == ["track_l2_error + missing"]
    # a drift flag only follows the l2 flag in its direction; a time flag is never optional
    assert bench.check({"track_l2_error": "+", "track_drift": "-"}, expect, "track_l2_error", accuracy)
    assert bench.check({"track_l2_error": "+", "time_integrate": "+"}, expect, "track_l2_error", accuracy)
    slower = bench.expected_asv("author-rk4", bench.SLOWER)
    assert bench.check({**slower, "track_drift": "+"}, slower, "track_l2_error", accuracy)
    assert bench.expected_asv("verlet", bench.SLOWER) == {} and bench.expected_history("author-rk4", 2, True) == {}
    # track_cpu_ratio is a benchmark, not a flag's ratio: a false flag on it is found, its ratio is not a flag
    assert bench.check({"track_cpu_ratio": "+", "track_cpu_ratio ratio": "1.2"}, {}, "track_l2_error", accuracy) \
        == ["track_cpu_ratio + not expected"]
    assert bench.check({"track_cpu_ratio ratio": "1.01"}, {}, "track_l2_error", accuracy) == []


@pytest.mark.slow
def test_versions_change_only_what_they_claim(tmp_path):
    """Commits 1 to 3 compute the same states bit for bit (a refactoring, then repeated work
    into scratch); commit 4 loses accuracy beyond compare's x2 on both problems; commit 3
    evaluates the right-hand side about 1 + REPEAT times as often."""
    import importlib.util

    from longtime.core import registry
    from longtime.core.timing import Timing

    classes = []
    for k, (_, text) in enumerate(bench.VERSIONS, 1):
        path = tmp_path / f"author_scheme_v{k}.py"
        path.write_text(text)
        spec = importlib.util.spec_from_file_location(path.stem, path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        classes.append(module.AuthorRK4)
    for name in bench.PROBLEMS:
        problem = registry.problem_class(name)()
        t_final = problem.t0 + 2000 * bench.DT
        finals = [cls(dt=bench.DT).integrate(problem, t_final, timing=Timing(repeats=1)).u[-1] for cls in classes]
        assert np.array_equal(finals[0], finals[1]) and np.array_equal(finals[1], finals[2])
        exact = problem.exact(np.array([t_final]))[0]
        err = [np.linalg.norm(f - exact) for f in finals]
        assert err[3] > 2 * err[2], (name, err)
