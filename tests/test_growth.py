"""Growth laws: the fit on synthetic errors whose law is known, the rule that classes only
what the data support, and the known laws of kepler and the harmonic oscillator."""
from __future__ import annotations

import json

import numpy as np
import pytest

from longtime.commands.cli import main
from longtime.measure.growth import classify, fit_power_law, growth_fields


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
    from longtime.measure.growth import growth_fields

    t = np.linspace(0.0, 1e4, 100_001)
    fields = growth_fields("H", t, 1e-9 * t**0.123456789, 0.0)
    assert abs(fields["H.growth"] - 0.123456789) < 1e-9  # not rounded: formats round, rows do not
    low, high = fields["H.growth_ci"]
    assert low <= fields["H.growth"] <= high and high - low < 1e-9


def _cli_rows(capsys, tmp_path, *args):
    code = main(["run", *args, "--format", "json", "--repeats", "1", "--db", str(tmp_path / "s.sqlite")])
    out = capsys.readouterr().out
    assert code == 0
    return {r["integrator"]: r for r in json.loads(out)}


@pytest.mark.parametrize("t_final", [200, 600])
def test_kepler_rk4_early_is_pre_asymptotic_never_sqrt(capsys, tmp_path, t_final):
    """rk4's energy error on kepler (e = 0.6, dt 0.01) drifts linearly, but up to t = 600 its
    log-log slope still rises (0.26, 0.51, 0.75 over the last windows at t = 200): the
    whole fit's 0.51 and 0.72 would read as Brouwer's sqrt, 10^7 times above round-off."""
    rows = _cli_rows(capsys, tmp_path, "-p", "kepler", "-i", "rk4", "--dt", "0.01", "--t-final", str(t_final))
    rk4 = rows["rk4"]
    assert rk4["H.growth_class"] == "undetermined", rk4["H.growth_reason"]
    assert rk4["H.growth_reason"].startswith("pre-asymptotic: slopes ")
    slopes = rk4["H.growth_windows"]
    assert len(slopes) == 3 and slopes == sorted(slopes) and slopes[-1] - slopes[0] > 0.3
    low, high = rk4["H.growth_ci"]
    assert low <= min(slopes) and high >= max(slopes)  # the interval spans the windows
    assert rk4["L.growth_class"] == "linear"  # the angular momentum's drift is linear already


def test_known_laws_of_the_harmonic_oscillator(capsys, tmp_path):
    """rk4: H and the error linear; gauss4 (conserves H exactly in exact arithmetic) and
    heyoka at machine tolerance: Brouwer's random walk of round-off."""
    rows = _cli_rows(capsys, tmp_path, "-p", "harmonic", "-i", "rk4,gauss4,heyoka", "--dt", "0.01",
                     "--t-final", "1000")
    assert rows["rk4"]["H.growth_class"] == "linear" and rows["rk4"]["error.growth_class"] == "linear"
    for scheme in ("gauss4", "heyoka"):
        r = rows[scheme]
        assert r["H.growth_class"] == "sqrt", (scheme, r["H.growth"], r["H.growth_reason"])
        assert r["H.growth_reason"].startswith("round-off: ")
        assert r["H.max"] < 10 * 2.2e-16 * r["steps"] ** 0.5


def test_kepler_rk4_error_grows_quadratically(capsys, tmp_path):
    """Its energy error drifts linearly, so the frequency does and the phase error grows like
    t^2 (t = 2000: the error reaches 0.5 only at t = 7800)."""
    rk4 = _cli_rows(capsys, tmp_path, "-p", "kepler", "-i", "rk4", "--dt", "0.01", "--t-final", "2000")["rk4"]
    assert rk4["error.growth_class"] == "quadratic", rk4["error.growth_reason"]
    assert rk4["H.growth_class"] == "linear"


def test_sqrt_needs_an_error_round_off_can_explain():
    t = np.linspace(0.0, 1e4, 100_001)
    walk = 1e-15 * np.sqrt(t) * (1.0 + 0.1 * np.sin(t))  # 1.1e-13 at the end
    small = growth_fields("H", t, walk, 0.0, steps=100_000)
    assert small["H.growth_class"] == "sqrt" and small["H.growth_reason"].startswith("round-off: ")
    large = growth_fields("H", t, 1e7 * walk, 0.0, steps=100_000)  # 1e-6: no rounding walks that far
    assert large["H.growth"] == pytest.approx(0.5, abs=0.05)
    assert large["H.growth_class"] == "undetermined" and large["H.growth_reason"].startswith("not round-off: ")
    assert growth_fields("H", t, 1e7 * walk, 0.0)["H.growth_class"] == "sqrt"  # no step count: not checked


def test_a_curved_error_is_undetermined_with_a_wide_interval():
    """A bounded oscillation of 1e-6 under a linear drift: the log-log slope rises towards 1
    through the run, and the whole fit's alpha is no law of the run."""
    t = np.linspace(0.0, 1e4, 200_001)
    err = 1e-6 * np.abs(np.sin(t)) + 1e-8 * t
    fields = growth_fields("H", t, err, 0.0, steps=200_000)
    assert fields["H.growth_class"] == "undetermined"
    assert fields["H.growth_reason"].startswith("pre-asymptotic: slopes")
    low, high = fields["H.growth_ci"]
    assert high - low > 0.2 and low <= min(fields["H.growth_windows"]) and high >= max(fields["H.growth_windows"])
    later = growth_fields("H", t, 1e-6 * np.abs(np.sin(t)) + 1e-9 * t, 0.0, steps=200_000)
    assert later["H.growth_class"] == "undetermined"  # slopes 0.25, 0.50, 0.75: not a random walk at 1e-5
    short = growth_fields("H", t[:30], err[:30], 0.0)  # 0.05 .. 1.45: under 1.5 decades
    assert short["H.growth_class"] == "undetermined" and short["H.growth_reason"].startswith("too short")
