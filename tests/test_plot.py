"""`longtime plot`: the kinds registry, the files written, bad input."""
from __future__ import annotations

import pytest

from longtime.commands.cli import main
from longtime.core import registry
from longtime.core.params import InputError
from longtime.plot import PLOT_KINDS, draw, kind_function
from longtime.reporting.figures.work_precision import work_precision


def _png_ok(path):
    from matplotlib.image import imread

    img = imread(path)
    assert img.shape[0] > 200 and img.shape[1] > 300
    assert img[..., :3].std() > 0.01  # not a blank canvas


def test_every_registered_kind_loads():
    for kind in PLOT_KINDS:
        assert callable(kind_function(kind)), kind


def test_work_precision_one_figure_per_problem(tmp_path):
    rows = [{"problem": p, "integrator": s, "status": "ok", "cpu_s": c, "H.max": e, "l2_error": 10 * e}
            for p in ("toda", "kepler") for s in ("rk4", "verlet")
            for c, e in ((1e-3, 1e-2), (2e-3, 1e-3), (4e-3, 1e-4))]
    rows.append({"problem": "toda", "integrator": "euler", "status": "diverged", "cpu_s": 1.0, "H.max": None})
    paths = work_precision(tmp_path / "wp", rows=rows)
    assert sorted(p.name for p in paths) == ["wp-kepler.png", "wp-kepler.svg", "wp-toda.png", "wp-toda.svg"]
    _png_ok(tmp_path / "wp-toda.png")
    with pytest.raises(InputError, match="no ok rows"):
        work_precision(tmp_path / "wp", rows=rows, schemes=["euler"])


def test_work_precision_from_the_store_through_the_cli(tmp_path, capsys):
    db = str(tmp_path / "s.sqlite")
    assert main(["run", "-p", "harmonic", "-i", "rk4,verlet", "--dt", "0.2,0.1", "--t-final", "20",
                 "--db", db]) == 0
    assert main(["plot", "work-precision", "--db", db, "--out", str(tmp_path / "figs")]) == 0
    out = capsys.readouterr().out
    assert "work-precision-harmonic.png" in out
    _png_ok(tmp_path / "figs" / "work-precision-harmonic.png")


def test_drift_and_eigenvalue_figures(tmp_path):
    paths = draw("drift", tmp_path, problems=["toda"], schemes=["rk4", "rk4sym"], dt=0.1, t_final=100.0)
    assert [p.suffix for p in paths] == [".png", ".svg"] and all(p.stat().st_size > 0 for p in paths)
    _png_ok(paths[0])
    paths = draw("toda-eigenvalues", tmp_path, schemes=["rk4"], t_final=50.0, formats=("png",))
    assert [p.name for p in paths] == ["toda-eigenvalues.png"]


def test_duffing_phase_short(tmp_path):
    if "duffing-forced" not in registry.problems():
        with pytest.raises(InputError, match="not available"):
            draw("duffing-phase", tmp_path)
        return
    paths = draw("duffing-phase", tmp_path, t_final=60.0, dt=0.02, formats=("png",))
    _png_ok(paths[0])


def test_bad_input(tmp_path, capsys):
    with pytest.raises(SystemExit):
        main(["plot", "no-such-kind"])
    assert main(["plot", "work-precision", "--db", str(tmp_path / "empty.sqlite")]) == 2
    assert "no such file (nothing was created)" in capsys.readouterr().err  # read-only: no empty store
    assert not (tmp_path / "empty.sqlite").exists()
    assert main(["plot", "drift", "--format", "gif", "-p", "harmonic", "--t-final", "1",
                 "--out", str(tmp_path)]) == 2
