"""Every invariant drawn, diagnostics beside the invariants: what each row keeps, the page
and `longtime plot drift --invariant`."""
from __future__ import annotations

import json

import numpy as np
import pytest

from longtime.commands.cli import main
from longtime.core import registry
from longtime.reporting.figures.results import drift_svg
from longtime.reporting.figures.style import styles
from longtime.reporting.page import build_page


def _rows(capsys, tmp_path, *args):
    # in this process: the monkeypatched problem is not seen by a worker process
    code = main(["run", *args, "--format", "json", "--repeats", "1", "--executor", "serial",
                 "--db", str(tmp_path / "s.sqlite")])
    out = capsys.readouterr().out
    assert code == 0
    return json.loads(out)


@pytest.fixture
def watched_harmonic(monkeypatch):
    """harmonic with two diagnostics: q^2 (1 at t = 0, swings to 0) and the kinetic energy
    p^2 / 2 (0 at t = 0: its change is absolute, up to H = 1/2)."""
    def diagnostics(self, t, U):
        return {"q2": U[:, 0] ** 2, "K": 0.5 * U[:, 1] ** 2}

    monkeypatch.setattr(registry.problem_class("harmonic"), "diagnostics", diagnostics)


def test_diagnostics_are_recorded_drawn_and_never_classed(watched_harmonic, capsys, tmp_path):
    (row,) = _rows(capsys, tmp_path, "-p", "harmonic", "-i", "verlet", "--dt", "0.01", "--t-final", "100")
    assert row["diag.q2.max"] == pytest.approx(1.0, abs=1e-3)  # q swings through 0
    assert row["diag.K.max"] == pytest.approx(0.5, abs=1e-3)  # absolute: K starts at 0
    assert 0 <= row["diag.q2.final"] <= row["diag.q2.max"]
    assert [c["diagnostic"] for c in row["diag_curves"]] == ["q2", "K"]
    assert max(row["diag_curves"][1]["error"]) == pytest.approx(row["diag.K.max"], rel=1e-5)
    # watched, never classed: no growth law of a diagnostic, and the invariant keeps its own
    assert not [k for k in row if "growth" in k and ("q2" in k or "K." in k)]
    assert row["H.growth_class"] == "bounded" and [c["invariant"] for c in row["drift_curves"]] == ["H"]
    page = build_page([row], [], stability=False)
    # the winner map, work-precision, drift and diagnostics
    assert "<summary>Diagnostics against time</summary>" in page and page.count('<figure class="plot">') == 4
    diag = page[page.index("Diagnostics against time"):]
    assert ">q2<" in diag and ">K<" in diag  # one panel each, titled by name (SVG text)


def test_rows_without_diagnostics_draw_none(capsys, tmp_path):
    (row,) = _rows(capsys, tmp_path, "-p", "harmonic", "-i", "verlet", "--dt", "0.01", "--t-final", "10")
    assert row["diag_curves"] is None and not [k for k in row if k.startswith("diag.")]
    assert "Diagnostics against time" not in build_page([row], [], stability=False)


def _curve(name, slope, key="invariant"):
    t = np.logspace(-2, 4, 60)
    return {key: name, "t": t.tolist(), "error": (1e-12 * t**slope).tolist()}


def test_the_drift_figure_draws_every_invariant_and_reads_old_rows():
    """outer-solar-system keeps H, L and P: one panel each. A row stored when rows kept only
    the first invariant's curve (``drift_curve``) still draws, that one alone."""
    base = {"problem": "outer-solar-system", "status": "ok", "cpu_s": 1.0, "dt": 100.0, "t_final": 2e4}
    curves = [_curve("H", 1.0), _curve("L", 0.5), _curve("P", 0.0)]
    new = {**base, "integrator": "rk4", "drift_curve": curves[0], "drift_curves": curves}
    old = {**base, "integrator": "verlet", "drift_curve": _curve("H", 0.0)}
    figure, notes = drift_svg([new, old], styles(["rk4", "verlet"]))
    assert not notes
    for name in ("H", "L", "P"):
        assert f">{name}<" in figure  # a panel titled by each invariant
    assert "rk4 dt=100" in figure and "verlet dt=100" in figure


def test_plot_drift_draws_the_invariant_named(tmp_path, capsys):
    assert main(["plot", "drift", "-p", "kepler", "-i", "verlet", "--dt", "0.05", "--t-final", "50",
                 "--invariant", "L", "--format", "svg", "--out", str(tmp_path)]) == 0
    svg = (tmp_path / "drift.svg").read_text()
    assert "drift of L" in svg and "relative error of L" in svg
    capsys.readouterr()
    assert main(["plot", "drift", "-p", "kepler", "-i", "verlet", "--t-final", "5", "--invariant", "X",
                 "--format", "svg", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "--invariant X" in err and "H, L, A" in err and len(err.strip().splitlines()) == 1
