"""`longtime reproduce`: the report's tables beside the paper's, sections that degrade to
"not available", and the CLI. The full --quick report runs in CI (`longtime reproduce --quick`)."""
from __future__ import annotations

import re

import pytest

from longtime.commands import reproduce as rep
from longtime.commands import reproduce_sections
from longtime.commands.cli import main
from longtime.core import registry


def _row(report: str, first_cells: str) -> list[str]:
    for line in report.splitlines():
        if line.startswith(f"| {first_cells} |"):
            return [c.strip() for c in line.strip("|").split("|")]
    raise AssertionError(f"no row starting with {first_cells!r}")


def test_toda_section_beside_the_paper(tmp_path, monkeypatch):
    # BPL rows need a search: the table's other rows are the subject here
    monkeypatch.setattr(reproduce_sections, "PAPER_TODA_BPL", {})
    path, failed = rep.reproduce(tmp_path, quick=True, figures=False, executor="serial", sections=["toda"])
    text = path.read_text()
    assert failed == []
    assert "**quick**" in text and "t_f = 500" in text
    # RK4sym's energy error does not grow: its E_mean at t_f = 500 is the paper's (t_f = 5000)
    cells = _row(text, "rk4sym | dt = 0.1")
    ours, paper, ratio = float(cells[2]), float(cells[3]), float(cells[4])
    assert paper == pytest.approx(2.261e-3)
    assert ratio == pytest.approx(ours / paper, rel=1e-2)
    assert abs(ratio - 1) < 0.05
    cells = _row(text, "rk4 | dt = 0.1")
    assert float(cells[3]) == pytest.approx(0.379, rel=1e-3) and cells[7] == "107.4"
    assert re.search(r"Energy error of rk4sym at dt = 0.1: .* no growth", text)
    assert re.search(r"Energy error of rk4 at dt = 0.1: .* grows", text)


def test_missing_plugins_make_a_section_not_available(tmp_path, monkeypatch):
    found = registry.problems()
    found.pop("double-pendulum", None)
    monkeypatch.setattr(registry, "problems", lambda: dict(found))
    path, failed = rep.reproduce(tmp_path, quick=True, figures=False, executor="serial", sections=["pendulum"])
    assert failed == []
    assert "Not available: needs problem 'double-pendulum'" in path.read_text()


def test_a_failing_section_is_reported_and_the_others_go_on(tmp_path, monkeypatch):
    def broken(ctx):
        raise RuntimeError("deliberate")

    monkeypatch.setattr(rep, "SECTIONS", [("Broken", broken), ("Fine", lambda ctx: "all fine")])
    path, failed = rep.reproduce(tmp_path, quick=True, figures=False, executor="serial")
    text = path.read_text()
    assert failed == ["Broken"] and "deliberate" in text and "all fine" in text


def test_cli_rejects_an_unknown_section(capsys):
    assert main(["reproduce", "--section", "nope", "--no-store"]) == 2
    assert "--section" in capsys.readouterr().err
