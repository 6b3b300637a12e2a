"""Growth laws: the fit on synthetic errors whose law is known, and kepler's known classes."""
from __future__ import annotations

import json

import numpy as np
import pytest

from longtime.cli import main
from longtime.growth import classify, fit_power_law, growth_fields


@pytest.mark.parametrize("alpha, expected", [(0.0, "bounded"), (0.5, "sqrt"), (1.0, "linear"),
                                             (2.0, "quadratic"), (3.0, "faster")])
def test_fit_recovers_a_power_law_under_an_oscillation(alpha, expected):
    t = np.linspace(0.0, 1e4, 200_001)
    # an oscillating error whose envelope grows like t^alpha, plus a bounded floor
    err = 1e-14 * (1.0 + t**alpha) * (1.0 + np.sin(t) ** 2)
    fields = growth_fields("H", t, err, 0.0)
    assert fields["H.growth"] == pytest.approx(alpha, abs=0.1)  # the running max lags a fast envelope
    low, high = fields["H.growth_ci"]
    assert low <= fields["H.growth"] <= high
    assert fields["H.growth_class"] == expected and fields["H.saturated_t"] is None


def test_saturation_diverged_and_zero():
    t = np.linspace(0.0, 100.0, 1001)
    fields = growth_fields("error", t, 1e-3 * t**2, 0.0)  # reaches 0.5 at t = sqrt(500)
    assert fields["error.growth_class"] == "saturated"
    assert fields["error.saturated_t"] == pytest.approx(22.4, abs=0.1)
    assert fields["error.growth"] == pytest.approx(2.0, abs=0.05)  # fitted before saturation
    assert growth_fields("H", t, 1e-12 * t, 0.0, diverged=True)["H.growth_class"] == "diverged"
    zero = growth_fields("L", t, np.zeros_like(t), 0.0)
    assert zero["L.growth"] == 0.0 and zero["L.growth_class"] == "bounded"
    assert fit_power_law(np.array([1.0, 2.0]), np.array([1.0, 2.0])) is None
    assert [classify(a) for a in (0.2, 0.3, 0.8, 1.6, 2.6)] == ["bounded", "sqrt", "linear", "quadratic",
                                                                  "faster"]


def test_kepler_classes_from_the_command_line(capsys, tmp_path):
    """The issue's known cases: kepler e = 0.6, dt = 0.01, t_f = 2e4."""
    code = main(["run", "-p", "kepler", "-i", "verlet,gauss4,rk4,euler", "--dt", "0.01",
                 "--t-final", "20000", "--format", "json", "--repeats", "1", "--db", str(tmp_path / "s.sqlite")])
    out = capsys.readouterr().out
    assert code == 0
    rows = {r["integrator"]: r for r in json.loads(out)}
    assert rows["verlet"]["H.growth_class"] == "bounded" and abs(rows["verlet"]["H.growth"]) < 0.1
    assert rows["gauss4"]["H.growth_class"] == "bounded" and abs(rows["gauss4"]["H.growth"]) < 0.1
    assert rows["rk4"]["H.growth_class"] == "linear" and rows["rk4"]["H.growth"] == pytest.approx(1.0, abs=0.05)
    assert rows["gauss4"]["error.growth_class"] == "linear"  # phase drift
    assert rows["gauss4"]["error.growth"] == pytest.approx(1.0, abs=0.05)
    assert rows["euler"]["H.growth_class"] == "saturated" and rows["euler"]["H.saturated_t"] < 100
    assert rows["euler"]["error.growth_class"] == "saturated"


def test_growth_fields_keep_full_precision():
    from longtime.growth import growth_fields

    t = np.linspace(0.0, 1e4, 100_001)
    fields = growth_fields("H", t, 1e-9 * t**0.123456789, 0.0)
    assert abs(fields["H.growth"] - 0.123456789) < 1e-9  # not rounded: formats round, rows do not
    low, high = fields["H.growth_ci"]
    assert low <= fields["H.growth"] <= high and high - low < 1e-9
