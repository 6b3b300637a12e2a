"""longtime.testing: each assertion passes on Forest-Ruth's splitting defined in memory and
fails, with what was measured, what was expected and the points used, on a copy whose
coefficient is perturbed by 1e-4 (still consistent: the middle step takes up the rest);
benchmark_cell's extra_info carries the accuracy of the timed cell."""
import re

import pytest

from longtime import InputError
from longtime.integrators import Splitting, compose
from longtime.testing import (
    assert_bounded,
    assert_growth,
    assert_no_regression,
    assert_order,
    benchmark_cell,
)

G = 1.0 / (2.0 - 2.0 ** (1.0 / 3.0))


class MemForestRuth(Splitting):
    """Forest-Ruth, defined here: no entry point, no install."""
    order = 4
    kicks, drifts = compose([G, 1.0 - 2.0 * G, G])


class MemForestRuthOff(Splitting):
    """The same with its coefficient G perturbed by 1e-4: order 2, a larger energy error."""
    order = 4
    kicks, drifts = compose([G + 1e-4, 1.0 - 2.0 * (G + 1e-4), G + 1e-4])


DTS = [0.02, 0.01, 0.005, 0.0025]


def test_assert_order_passes_on_forest_ruth_and_names_the_measured_order_when_perturbed():
    found = assert_order(MemForestRuth, "kepler", 4, dts=DTS)
    assert abs(found.value - 4) < 0.05 and len(found.points) == 4  # measured 3.997 +- 0.007
    with pytest.raises(AssertionError) as info:
        assert_order(MemForestRuthOff, "kepler", 4, dts=DTS)
    msg = str(info.value)
    # the h^2 term of the broken order-4 condition overtakes h^4 within the sweep: the local
    # slopes fall from 3.65 to 2.49, so no order is determined (a fit through them, 2.80, would be
    # an artefact of the crossover), and the message lists the slopes
    slopes = [float(x) for x in re.search(r"order undetermined \(pre-asymptotic: local slopes ([\d., ]+) \(dt",
                                          msg).group(1).split(", ")]
    assert len(slopes) == 3 and slopes[0] > 3.5 and slopes[-1] < 2.7 and slopes == sorted(slopes, reverse=True)
    assert "expected order 4 +- 0.1" in msg and "dt=0.0025" in msg and "points used (l2_error_state)" in msg


def test_assert_bounded_and_its_failure_message():
    # Forest-Ruth on kepler at dt = 0.0025 to t = 60: H.max 3.9e-9; perturbed 3.4e-8
    res = assert_bounded(MemForestRuth, "kepler", "H", 1e-8, t_final=60, dt=0.0025)
    assert res.row["H.max"] < 1e-8 and res.row["H.growth_class"] == "bounded"
    with pytest.raises(AssertionError, match=r"max relative error of H \d\.\d+e-0\d, expected at most 1\.000e-08"):
        assert_bounded(MemForestRuthOff, "kepler", "H", 1e-8, t_final=60, dt=0.0025)


def test_assert_growth_tells_bounded_from_linear():
    assert_growth("verlet", "kepler", "H", "bounded", t_final=2000, dt=0.01)
    with pytest.raises(AssertionError, match=r"error of H grows as t\^.*class 'linear'; expected 'bounded'"):
        assert_growth("rk4", "kepler", "H", ["bounded"], t_final=2000, dt=0.01)


def test_assert_no_regression_flags_a_less_accurate_run(tmp_path):
    from longtime import sweep
    from longtime.core import registry

    db = str(tmp_path / "s.sqlite")
    for _ in range(2):
        sweep("kepler", MemForestRuth, dt=[0.01, 0.005], executor="serial", store=db, repeats=1)
    assert_no_regression(db, 1, 2, timing=False)  # the same scheme: bitwise the same errors
    # the perturbed copy under the same name (a later commit of the scheme): its errors grow
    MemForestRuthOff.name = ""
    registry.register(MemForestRuthOff, MemForestRuth.name)
    try:
        sweep("kepler", MemForestRuth.name, dt=[0.01, 0.005], executor="serial", store=db, repeats=1)
    finally:
        registry.register(MemForestRuth)
    with pytest.raises(AssertionError) as info:
        assert_no_regression(db, 1, 3, timing=False)
    msg = str(info.value)
    # dt = 0.005: l2_error 5.5e-6 -> 1.4e-5 (x2.6); the order of the sweep changes too
    assert "run 3 against run 1" in msg and "dt=0.005" in msg and "l2_error x" in msg


def test_a_class_that_breaks_the_contract_is_an_input_error_with_one_line():
    with pytest.raises(InputError) as info:
        class Inconsistent(Splitting):  # noqa: F841
            order = 2
            kicks, drifts = compose([0.5, 0.6])
    assert "sum to 1.1, not 1" in str(info.value) and "\n" not in str(info.value)


def test_benchmark_cell_puts_accuracy_into_extra_info(benchmark):
    row = benchmark_cell(benchmark, "kepler", MemForestRuth, dt=0.01)
    info = benchmark.extra_info
    assert info["l2_error"] == row["l2_error"] and 1e-5 < info["l2_error"] < 1e-3  # measured 8.8e-5
    assert info["H.growth_class"] == "bounded" and info["integrator"] == "mem-forest-ruth"
