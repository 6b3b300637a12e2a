"""pytest-benchmark: the integration of one cell timed, its accuracy in extra_info
(``pytest --benchmark-json=bench.json`` keeps both)."""
from longtime_example.schemes import ForestRuth

from longtime.testing import benchmark_cell


def test_forest_ruth_on_kepler(benchmark):
    row = benchmark_cell(benchmark, "kepler", ForestRuth, dt=0.01)
    assert benchmark.extra_info["l2_error"] == row["l2_error"] < 1e-3  # measured 8.8e-5
