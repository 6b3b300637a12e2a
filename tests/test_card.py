"""A card for every scheme: from the Python API, the command line and the results page."""
import json
import subprocess
import sys

import pytest

import longtime
from longtime.integrators import Splitting, compose
from longtime.reporting.card import card_text, cards_html

G = 1 / (2 - 2 ** (1 / 3))


class CardForestRuth(Splitting):
    """Forest-Ruth, defined in memory as a scheme author would."""
    name = "card-forest-ruth"
    summary = "Forest-Ruth, in memory"
    order = 4
    kicks, drifts = compose([G, 1 - 2 * G, G])


@pytest.fixture(scope="module")
def rows():
    return longtime.sweep(["kepler", "harmonic"], [CardForestRuth, "rk4"], dt=[0.02, 0.01, 0.005, 0.0025], t_final=10,
                          executor="serial", repeats=1, min_time=0.0)


def test_an_in_memory_scheme_gets_its_card(rows):
    c = longtime.card(CardForestRuth, rows)
    assert c["scheme"] == "card-forest-ruth" and c["declared_order"] == 4 and c["declared_symplectic"]
    s = c["structure"]
    assert s["problem"] == "kepler" and s["symplectic"] and s["reversible"] and "L" in s["kept"]
    assert s["symplecticity_defect"] < s["symplecticity_error"] < 1e-8
    by = {p["problem"]: p for p in c["problems"]}
    assert set(by) == {"harmonic", "kepler"}
    (kepler,) = by["kepler"]["orders"]
    assert abs(kepler["observed"] - 4) < 0.1 and not kepler["flag"]
    assert by["kepler"]["rhs_evals_per_step"] == pytest.approx(3.0, abs=0.01)  # three forces a step (FSAL)
    assert by["kepler"]["instructions_per_step"] is None
    assert by["kepler"]["growth"]["H"]["class"] and by["kepler"]["pareto"]
    assert c["stability_interval"].startswith("[0, ")
    text = card_text(c)
    assert "instructions per step not measured" in text and "symplecticity defect" in text
    # the Pareto front ranks by the largest error over the run (the verdict's "keeps E up to T")
    assert "== kepler:" in text and "Pareto front: (max_error)" in text
    json.dumps(c)  # the JSON of `longtime card --format json`


def test_rk4s_card_measures_it_not_symplectic(rows):
    c = longtime.card("rk4", rows, stability=False)
    s = c["structure"]
    assert not s["symplectic"] and not s["reversible"] and s["kept"] == [] and s["symplecticity_defect"] > 1e-6
    assert c["stability_interval"] == "not measured"


def test_cards_html_folds_one_card_per_scheme(rows):
    from longtime.api import records

    page = cards_html(records(rows), structure=False)
    assert page.count('<details class="card"') == 2 and 'id="card-card-forest-ruth"' in page and 'id="card-rk4"' in page
    assert page.startswith('<section id="scheme-cards">') and "<summary>" in page


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "longtime", "card", *args], capture_output=True, text=True)


@pytest.mark.slow
def test_card_command_and_its_bad_input(tmp_path):
    db = tmp_path / "s.sqlite"
    longtime.sweep("harmonic", "verlet", dt=[0.2, 0.1, 0.05], t_final=20, executor="serial", repeats=1, store=str(db))
    out = _cli("verlet", "--db", str(db), "--format", "json")
    assert out.returncode == 0, out.stderr
    c = json.loads(out.stdout)
    assert c["scheme"] == "verlet" and c["problems"][0]["problem"] == "harmonic"
    assert abs(c["problems"][0]["orders"][0]["observed"] - 2) < 0.05 and c["rows_from"].startswith("every run of")
    table = _cli("verlet", "--db", str(db))
    assert table.returncode == 0 and table.stdout.startswith("verlet: ")
    assert "== harmonic: 3 of 3 cells ok ==" in table.stdout
    assert _cli("verlet", "--db", str(db), "--format", "markdown").stdout.startswith("### verlet")
    for bad, says in ((("nope", "--db", str(db)), "unknown integrator 'nope'"),
                      (("verlet", "--db", str(db), "--run", "9"), "run 9 is not in"),
                      (("verlet", "--db", str(db), "--run", "x"), "--run 'x': expected a run id")):
        got = _cli(*bad)
        assert got.returncode == 2 and says in got.stderr and got.stdout == "" and len(got.stderr.splitlines()) == 1


@pytest.mark.slow
def test_card_reads_every_run_says_does_not_apply_and_hints_a_command_that_runs(tmp_path):
    db = tmp_path / "runs.sqlite"
    longtime.sweep("harmonic", "verlet", dt=[0.2, 0.1], t_final=10, executor="serial", repeats=1, store=str(db))
    longtime.sweep("linear-test", ["verlet", "rk4"], dt=[0.1], t_final=1, executor="serial", repeats=1, store=str(db))
    table = _cli("verlet", "--db", str(db))
    assert table.returncode == 0, table.stderr
    # every run by default (recommend's rows): run 1's harmonic rows, though run 2 is the latest
    assert "== harmonic: 2 of 2 cells ok ==" in table.stdout
    # the problems it does not apply to in one line; --full: each on its own
    assert any(line.startswith("  does not apply: verlet needs") and "(linear-test)" in line
               for line in table.stdout.splitlines()), table.stdout
    assert "== linear-test: does not apply (verlet needs" in _cli("verlet", "--db", str(db), "--full").stdout
    assert "linear-test: 0 of" not in table.stdout and table.stdout.count("Pareto front") == 1
    narrowed = _cli("verlet", "--db", str(db), "--run", "2", "--format", "json")
    assert [p["problem"] for p in json.loads(narrowed.stdout)["problems"]] == ["linear-test"]
    assert json.loads(narrowed.stdout)["rows_from"].startswith("run 2 of")
    # the hint's flags come from the scheme's declared parameters: bpl's accuracy is eps_res, not a step
    from longtime.reporting.card import run_hint

    assert "--dt" not in run_hint("bpl") and "--eps-res" in run_hint("bpl")
    assert "--dt" in run_hint("verlet") and "--tol" in run_hint("rk45")
    hint = run_hint("verlet").split()
    assert hint[:2] == ["longtime", "run"]
    ran = subprocess.run([sys.executable, "-m", "longtime", *hint[1:], "--t-final", "1", "--db",
                          str(tmp_path / "hint.sqlite")], capture_output=True, text=True)
    assert ran.returncode == 0, ran.stderr
    empty = _cli("bpl", "--db", str(tmp_path / "hint.sqlite"))
    assert empty.returncode == 0 and "no stored rows of bpl" in empty.stdout and "--eps-res" in empty.stdout
