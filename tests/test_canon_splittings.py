"""The published splittings: Blanes-Moan S6, Suzuki's fractal composition, McLachlan's p8s15,
Kahan-Li p8s17.

Their coefficients are checked against the order conditions through the flows they compose
(on non-commuting matrices), their orders observed on kepler through longtime.measure.orders, and
their imaginary-axis intervals measured by longtime.measure.stability against the spectral radius of
the composed rotation step.
"""
import numpy as np
import pytest
from scipy.linalg import expm

from longtime.core import registry
from longtime.core.timing import Timing
from longtime.execution.cells import Cell, run_cell
from longtime.measure import stability
from longtime.measure.orders import observed_orders

# scheme, order, force evaluations per step, kepler steps per unit of time 2 (asymptotic range)
CANON = [
    ("blanes-moan-s6", 4, 6, (25, 50, 100, 200)),
    ("suzuki4", 4, 5, (25, 50, 100, 200)),
    ("mclachlan-8", 8, 15, (20, 28, 40, 56)),
    ("kahan-li-8", 8, 17, (20, 28, 40, 56)),
]
IDS = [c[0] for c in CANON]


def composed_flow(cls, h, A, B):
    """The splitting's step on y' = (A + B) y: each pair kicks (B) then drifts (A)."""
    M = np.eye(A.shape[0])
    for k, d in zip(cls.kicks, cls.drifts):
        M = expm(d * h * A) @ expm(k * h * B) @ M
    return M


@pytest.mark.parametrize("scheme, order, forces, _", CANON, ids=IDS)
def test_coefficients_meet_the_order_conditions(scheme, order, forces, _):
    # the local error of a method of order p on generic non-commuting A, B is O(h^(p+1));
    # a coefficient wrong in its 4th digit drops the slope to 3 (or 5 for order 8)
    cls = registry.integrator_class(scheme)
    assert cls.order == order
    rng = np.random.default_rng(1)
    A, B = rng.standard_normal((6, 6)) / 2, rng.standard_normal((6, 6)) / 2
    hs = np.array([0.4, 0.2, 0.1]) if order == 8 else np.array([0.2, 0.1, 0.05])
    errors = [np.linalg.norm(composed_flow(cls, h, A, B) - expm(h * (A + B))) for h in hs]
    slopes = np.diff(np.log(errors)) / np.diff(np.log(hs))
    assert np.all(np.abs(slopes - (order + 1)) < 0.1), slopes


def test_symmetric_compositions_are_palindromes_summing_to_one():
    from longtime.integrators.splitting import KAHAN_LI_8, MCLACHLAN_8, SUZUKI_P

    assert 2 * sum(MCLACHLAN_8[:7]) + MCLACHLAN_8[7] == pytest.approx(1.0, abs=1e-15)
    assert 2 * sum(KAHAN_LI_8[:8]) + KAHAN_LI_8[8] == pytest.approx(1.0, abs=1e-15)
    assert KAHAN_LI_8[0] == 0.13020248308889008087881763  # HLW's gamma_1 of p8s17
    assert SUZUKI_P == pytest.approx(0.41449077179437573714, abs=1e-15)
    for scheme in IDS:
        cls = registry.integrator_class(scheme)
        # kick then drift per pair: the adjoint reverses the sequence of flows
        flows = [x for k, d in zip(cls.kicks, cls.drifts) for x in (("B", k), ("A", d)) if x[1] != 0]
        assert [f for f, _ in flows] == [f for f, _ in flows[::-1]]
        assert np.allclose([c for _, c in flows], [c for _, c in flows[::-1]], rtol=0, atol=1e-15)


@pytest.mark.parametrize("scheme, order, forces, steps", CANON, ids=IDS)
def test_observed_order_on_kepler(scheme, order, forces, steps):
    rows = []
    for n in steps:
        row = run_cell(Cell("kepler", scheme, {"e": 0.5}, {"dt": 2.0 / n}, 2.0), max_samples=201,
                       timing=Timing(repeats=1))
        assert row["status"] == "ok", row["message"]
        assert abs(row["rhs_evals"] - forces * n) <= 1  # a force per stage (+1: first same as last)
        rows.append({**row, "run_id": 1})
    fit = observed_orders(rows)[0]
    assert len(fit["order_points"]) >= 3
    assert abs(fit["observed_order"] - order) < 0.2 and not fit["order_flag"], fit


def rotation_interval(cls, y_max=12.0, y_step=0.01):
    """The largest y (to the grid) with the composed step on q' = p, p' = -q of size y
    repeating without growth on all of [0, y]: spectral radius of its 2x2 matrix."""
    for y in np.arange(y_step, y_max + y_step / 2, y_step):
        M = np.eye(2)
        for k, d in zip(cls.kicks, cls.drifts):
            M = np.array([[1.0, d * y], [0.0, 1.0]]) @ np.array([[1.0, 0.0], [-k * y, 1.0]]) @ M
        if max(abs(np.linalg.eigvals(M))) > 1 + stability.TOL:
            return round(y - y_step, 6)
    return None


@pytest.mark.parametrize("scheme, order, forces, _", CANON, ids=IDS)
def test_stability_interval_is_measured_and_plausible(scheme, order, forces, _, tmp_path, monkeypatch):
    monkeypatch.setenv("LONGTIME_CACHE_DIR", str(tmp_path))
    text = stability.interval_texts({scheme: None}, compute=True)[scheme]  # what `list --stability` shows
    found = stability.intervals(scheme, compute=False)[""]
    assert found["bounded"] and text == f"[0, {found['y']:.3g}]"
    assert found["y"] == pytest.approx(rotation_interval(registry.integrator_class(scheme)), abs=1e-9)
    # beyond Verlet's 2, below the 2 s that s force evaluations allow at most
    assert 2.0 < found["y"] < 2 * forces


def test_kahan_li_8_is_p8s17_and_its_old_rows_are_named():
    # 17 Verlet steps: 17 drifts, 18 kicks merged to 17 + the last; the notice names mclachlan-8
    cls = registry.integrator_class("kahan-li-8")
    assert np.count_nonzero(cls.drifts) == 17
    assert np.count_nonzero(registry.integrator_class("mclachlan-8").drifts) == 15
    assert "mclachlan-8" in cls.notice and "p8s15" in cls.notice


def test_list_shows_the_notice(capsys):
    from longtime.commands.cli import main

    assert main(["list"]) == 0
    lines = capsys.readouterr().out.splitlines()
    at = next(i for i, line in enumerate(lines) if line.split()[:1] == ["kahan-li-8"])
    assert lines[at + 2].split()[:1] == ["notice:"] and "mclachlan-8" in lines[at + 2]


def test_run_says_the_notice_on_stderr_only(capsys):
    import json

    from longtime.commands.cli import main

    code = main(["run", "--no-store", "--format", "json", "--repeats", "1", "-p", "kepler", "-i", "kahan-li-8,verlet",
                 "--t-final", "0.5"])
    out = capsys.readouterr()
    assert code == 0
    assert [r["integrator"] for r in json.loads(out.out)] == ["kahan-li-8", "verlet"]  # stdout: the rows only
    assert out.err.count("notice: kahan-li-8:") == 1 and "mclachlan-8" in out.err
