"""The Python API (longtime.api, docs/api.md): solve gives the row `longtime run --format json`
prints, with the samples, invariants and reference; sweep runs in-memory classes on the
serial and process executors; convergence fits the order and names what it left out;
contract breaks and impossible pairs are one-line InputErrors."""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

import longtime
from longtime import InputError
from longtime.core import registry
from longtime.integrators import Splitting, compose

G = 1.0 / (2.0 - 2.0 ** (1.0 / 3.0))


class ApiForestRuth(Splitting):
    order = 4
    kicks, drifts = compose([G, 1.0 - 2.0 * G, G])


# timing fields differ from run to run; everything else is the same computation
TIMING = ("cpu_s", "wall_s", "cpu_s_median", "cpu_s_max", "wall_s_median", "wall_s_max", "cpu_s_samples", "repeats",
          "cpu_s_calibrated", "calibration_cpu_s", "calibration_t", "cpu_s_processes", "cpu_s_process_spread")


def test_solve_row_is_the_cli_json_row():
    res = subprocess.run([sys.executable, "-m", "longtime.commands.cli", "run", "-p", "kepler", "-i", "verlet",
                          "--dt", "0.01", "--t-final", "30", "--set", "e=0.5", "--repeats", "1", "--no-store",
                          "--format", "json"],
                         capture_output=True, text=True, timeout=300, env=os.environ)
    assert res.returncode == 0, res.stderr
    cli = json.loads(res.stdout)[0]
    result = longtime.solve("kepler", "verlet", t_final=30, dt=0.01, e=0.5, repeats=1)
    row = json.loads(json.dumps(result.row))  # as JSON carries it
    assert set(row) == set(cli)
    assert cli["settings"] == row["settings"] == '{"e": 0.5}'  # --set e=0.5 is the number, as in Python
    assert {k: v for k, v in row.items() if k not in TIMING} == {k: v for k, v in cli.items() if k not in TIMING}
    assert row["status"] == "ok" and row["l2_error"] > 0


def test_solve_result_holds_samples_invariants_and_the_trusted_reference():
    result = longtime.solve("kepler", ApiForestRuth(dt=0.01), t_final=20, repeats=1)
    assert result.row["integrator"] == "api-forest-ruth" and result.row["dt"] == 0.01
    assert result.t.shape[0] == result.u.shape[0] and result.u.shape[1] == 4
    H = result.invariants["H"]
    assert np.max(np.abs(H - H[0]) / abs(H[0])) == pytest.approx(result.row["H.max"], rel=1e-12)
    ref = result.reference
    assert ref is not None and ref.shape == (len(result.t), 4)  # kepler's exact solution: trusted everywhere
    err = np.linalg.norm(result.u - ref, axis=1).max()
    assert 1e-8 < err < 1e-3  # an order-4 scheme at dt = 0.01 follows the orbit (measured 2e-5)


def test_solve_on_a_pair_that_cannot_run_names_the_missing_capability():
    with pytest.raises(InputError, match="needs separable, which linear-test does not provide"):
        longtime.solve("linear-test", ApiForestRuth)
    with pytest.raises(InputError, match="did you mean"):
        longtime.solve("keplr", "verlet")
    with pytest.raises(InputError, match="solve runs one cell"):
        longtime.solve("kepler", "verlet", dt=[0.1, 0.05])


def test_an_incomplete_class_is_refused_with_the_plugin_reason():
    class NoCoefficients(Splitting):
        order = 2

    with pytest.raises(InputError) as info:
        longtime.solve("kepler", NoCoefficients)
    assert "does not set kicks, which its family Splitting declares" in str(info.value)
    assert "\n" not in str(info.value)
    with pytest.raises(InputError, match="is taken by"):
        class Verlet2(Splitting):
            name = "verlet"
            order = 2
            kicks, drifts = compose([1.0])
        registry.register(Verlet2)


def test_sweep_runs_an_in_memory_class_on_the_process_pool_and_convergence_fits_it():
    rows = longtime.sweep("kepler", [ApiForestRuth, "verlet"], dt=[0.01, 0.005, 0.0025], executor="process",
                          jobs=2, repeats=1)
    assert len(rows) == 6 and set(rows["status"]) == {"ok"}
    orders = longtime.convergence(rows)
    by = {o.scheme: o for o in orders}
    assert abs(by["api-forest-ruth"].value - 4) < 0.1 and by["api-forest-ruth"].declared == 4
    assert abs(by["verlet"].value - 2) < 0.1 and by["verlet"].interval[0] < by["verlet"].value
    assert "observed order" in str(by["verlet"])
    table = longtime.work_precision(rows)
    assert list(table["problem"].unique()) == ["kepler"] and table["target"].is_monotonic_decreasing


def test_convergence_names_why_a_scheme_has_no_order():
    rows = longtime.sweep("kepler", "euler", dt=[0.02, 0.01], t_final=30, executor="serial", repeats=1)
    order = longtime.convergence(rows)
    assert order.value is None and order.reason.startswith("every point above 0.1")
    assert len(order.dropped) == 2 and all(why == "above 0.1" for _, _, why in order.dropped)
    from longtime.api import records as as_records
    from longtime.reporting.report import summary

    records = as_records(rows)
    assert "left out of the order table: euler (every point above 0.1)" in summary(records)
    from longtime.reporting.compare import compare
    from longtime.reporting.compare_text import render
    from longtime.reporting.page import build_page

    text = render(compare(records, records))
    assert "left out of A's order table: kepler euler (every point above 0.1)" in text
    page = build_page(records, [], drift=False, jobs=1)
    assert "Left out of the order table:" in page and "<li>euler: every point above 0.1</li>" in page


def test_a_plugin_splitting_is_of_the_splitting_family_with_a_look_of_its_own():
    from longtime.reporting.figures.style import family, styles

    longtime.solve("kepler", ApiForestRuth, t_final=1, repeats=1)  # registers it
    assert family("api-forest-ruth") == family("verlet") == "splitting"
    s = styles(["api-forest-ruth", "verlet", "rk4"])
    looks = {(v["color"], v["marker"]) for v in s.values()}
    assert len(looks) == 3  # a plugin's scheme is told from the built-in ones


def test_plot_helpers_return_axes():
    import matplotlib

    matplotlib.use("Agg")
    from longtime import plot

    rows = longtime.sweep("kepler", ["verlet", "rk4"], dt=[0.02, 0.01], t_final=10, executor="serial", repeats=1)
    ax = plot.work_precision(rows)
    assert {t.get_text() for t in ax.get_legend().get_texts()} >= {"verlet (splitting)", "rk4 (explicit_rk)"}
    result = longtime.solve("kepler", "rk4", t_final=10, dt=0.01, repeats=1)
    ax = plot.drift(result)
    y = ax.get_lines()[0].get_ydata()
    assert np.nanmax(y) == pytest.approx(result.row["H.max"], rel=1e-12)
    ax = plot.drift(rows)  # from the rows' stored drift envelopes
    assert len(ax.get_lines()) == 4


def test_an_in_memory_class_runs_isolated():
    rows = longtime.sweep("kepler", ApiForestRuth, dt=[0.02, 0.01], t_final=10, executor="isolated", jobs=2,
                          repeats=1)
    assert list(rows["status"]) == ["ok", "ok"] and (rows["l2_error"] > 0).all()


def test_an_in_memory_class_on_dask_is_refused_before_any_cell_with_what_to_do():
    pytest.importorskip("distributed")
    with pytest.raises(InputError, match=r"api-forest-ruth: defined in this process.*install it as a plugin"):
        longtime.sweep("kepler", [ApiForestRuth, "verlet"], dt=[0.02], t_final=10, executor="dask", jobs=1,
                       repeats=1)
