"""Linear stability measured from the schemes' own steps."""
import json
import math

import numpy as np
import pytest

from longtime.commands import cli
from longtime.measure import stability


def test_rk4_amplification_factor_is_its_taylor_polynomial():
    re, im = np.array([-2.5, -1.0, 0.3]), np.array([0.0, 0.7, 2.0])
    growth = stability.region("rk4", re, im)
    for k, y in enumerate(im):
        for j, x in enumerate(re):
            z = complex(x, y)
            assert growth[k, j] == pytest.approx(abs(1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24), rel=1e-12)


@pytest.mark.parametrize("scheme, y", [("euler", 0.0), ("rk4", 2.82), ("verlet", 2.0)])
def test_imaginary_axis_intervals(scheme, y):
    # rk4: 2 sqrt 2 = 2.828 (to the 0.01 grid); verlet: |trace| <= 2 up to omega h = 2; euler: none
    result = stability.imaginary_interval(scheme)
    assert result["bounded"] and result["y"] == pytest.approx(y, abs=1e-9)


def test_verlet_growth_is_the_spectral_radius_not_the_norm():
    # one Verlet step is not a rotation (its matrix is not normal) but repeats without growth
    growth = stability.imaginary_growth("verlet", [0.5, 1.5, 2.5])
    assert growth[:2] == pytest.approx([1.0, 1.0], abs=1e-12)
    y = 2.5  # past the interval: eigenvalues of trace 2 - y^2
    t = 2 - y * y
    assert growth[2] == pytest.approx((abs(t) + math.sqrt(t * t - 4)) / 2, rel=1e-12)


def test_list_shows_the_measured_interval(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("LONGTIME_CACHE_DIR", str(tmp_path))
    assert stability.interval_texts({"rk4": None}) == {}  # nothing cached, nothing measured
    assert stability.interval_texts({"rk4": None}, compute=True) == {"rk4": "[0, 2.82]"}
    assert cli.main(["list", "--format", "json"]) == 0  # without --stability: what is cached
    found = {i["name"]: i["imaginary_interval"] for i in json.loads(capsys.readouterr().out)["integrators"]}
    assert found["rk4"][""]["y"] == pytest.approx(2.82) and found["rk4"][""]["bounded"]
    assert "external" in found["dop853"][""]["error"]  # no step kernel: said, not measured
    assert found["gauss6"] == {}  # not measured yet


def test_plot_kind_stability(tmp_path):
    from longtime.plot import draw

    paths = draw("stability", tmp_path, schemes=["euler", "rk4", "verlet"], formats=("svg",))
    text = paths[0].read_text()
    assert paths[0].name == "stability.svg" and "verlet: [0, 2]" in text and "rk4: [0, 2.82]" in text
    assert "verlet: no region (verlet needs separable" in text  # said, not left blank


def test_the_test_equation_is_a_diagnostic_not_part_of_the_default_matrix():
    from longtime.core import registry

    assert "linear-test" in registry.problems()
    assert "linear-test" not in registry.default_problems()
    assert {"toda", "kepler", "kdv"} <= set(registry.default_problems())


def test_cached_texts_leave_only_what_a_page_would_have_to_measure(tmp_path, monkeypatch):
    from longtime.measure.stability import cached_texts, interval_texts

    monkeypatch.setenv("LONGTIME_CACHE_DIR", str(tmp_path))
    wanted = {"rk4": None, "taylor-adaptive": [8, 12]}  # taylor-adaptive: never measurable, nothing to do
    texts, missing = cached_texts(wanted)
    assert missing == {"rk4": None} and texts["taylor-adaptive"].startswith("not measured: taylor-adaptive chooses")
    assert interval_texts({"rk4": None}, compute=True)["rk4"].startswith("[0, 2.82")
    texts, missing = cached_texts(wanted)
    assert missing == {} and texts["rk4"].startswith("[0, 2.82")


@pytest.mark.parametrize("name", ["rk4", "gauss4", "rk45", "bpl"])
def test_one_step_runs_the_loop_a_run_compiled(name):
    """The interval is measured through the very loop the scheme's runs use, called with a
    run's argument types: after a run on the harmonic oscillator one_step takes the same
    compiled loop and adds no signature to it (a cold main job loads, not compiles, it)."""
    from longtime.core import registry
    from longtime.core.kernel_cache import PAIRS
    from longtime.problems.harmonic import Harmonic

    problem = Harmonic()
    run = registry.integrator_class(name)()
    run.integrate(problem, 1.0, max_samples=3)
    loop = PAIRS[run][id(problem)][1]
    signatures = list(loop.signatures)
    measured = stability._scheme(name)
    step = stability.one_step(measured, problem)
    u = np.array([1.0, 0.0])
    assert step(u, problem.params, 0.5)
    assert abs(math.hypot(*u) - 1.0) < 1e-2  # one step of a rotation keeps |u| near 1
    assert PAIRS[measured][id(problem)][1] is loop
    assert list(loop.signatures) == signatures


def test_a_scheme_without_a_step_kernel_is_named_in_plain_words():
    with pytest.raises(stability.Unmeasurable, match="heyoka is an external integrator: no step kernel"):
        stability._scheme("heyoka")


@pytest.mark.parametrize("scheme", ["gauss4", "midpoint"])
def test_implicit_methods_are_stable_on_the_axis_and_their_solver_is_not(scheme):
    # the method: |R(iy)| = 1 for every y (A-stable); the fixed-point iteration: converges
    # only while h |lambda| ||A|| stays below about 1, so its step fails at a finite y
    result = stability.imaginary_interval(scheme)
    assert not result["linear"]["bounded"] and result["linear"]["y"] == pytest.approx(stability.Y_MAX)
    assert result["solver_y"] is not None and 0.5 < result["solver_y"] < 4.0
    assert result["bounded"] and result["y"] == pytest.approx(result["solver_y"])  # the step stops at the solver
    A, b = stability.implicit_tableau(scheme)
    assert abs(stability.stability_function(A, b, 3j)) == pytest.approx(1.0, abs=1e-14)
    text = stability.format_interval(result)
    assert text.startswith("linear stability (|R(iy)| <= 1 from R(z)) [0, >= 12]; fixed-point solver converges to y = ")
    assert stability.linear_interval("rk4") is None and "linear" not in stability.imaginary_interval("rk4")
