"""The docs site (mkdocs.yml: docs/ and the docstrings) builds with no warning, its command
reference has a section for every command the parser registers, and each API page renders
the public names of its module."""
import argparse
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
pytest.importorskip("mkdocs")
pytest.importorskip("mkdocstrings_handlers.python")


def _commands(parser, prefix="longtime"):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield f"{prefix} {name}"
                yield from _commands(sub, f"{prefix} {name}")


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    out = tmp_path_factory.mktemp("site")
    res = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(out)],
                         cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    warnings = [line for line in (res.stdout + res.stderr).splitlines() if "WARNING" in line]
    assert warnings == []
    return out


def test_every_command_has_a_section(site):
    from longtime.commands.cli import build_parser

    page = (site / "commands" / "index.html").read_text()
    commands = list(_commands(build_parser()))
    assert {"longtime run", "longtime matrix", "longtime cache info", "longtime asv-init"} <= set(commands)
    for command in commands:
        assert re.search(rf'<h\d id="[^"]+"><code>{command}</code>', page), command
        # the section shows the parser's own usage line
        assert f"usage: {command}" in page, command


@pytest.mark.parametrize("page, names", [
    ("reference/api", ["longtime.api.solve", "longtime.api.sweep", "longtime.api.convergence",
                       "longtime.api.work_precision", "longtime.api.recommend", "longtime.api.card"]),
    ("reference/testing", ["longtime.testing.assert_order", "longtime.testing.assert_bounded",
                           "longtime.testing.assert_growth", "longtime.testing.assert_no_regression",
                           "longtime.testing.assert_symplectic", "longtime.testing.assert_reversible",
                           "longtime.testing.benchmark_cell"]),
    ("reference/asvbench", ["longtime.asvbench.benchmarks"]),
    ("reference/plot", ["longtime.plot.work_precision", "longtime.plot.drift"]),
    ("reference/bases", ["longtime.core.problem.Problem", "longtime.core.integrator.Integrator",
                         "longtime.core.params.Param", "longtime.core.params.InputError"]),
])
def test_api_pages_render_the_public_names(site, page, names):
    html = (site / page / "index.html").read_text()
    for name in names:
        assert f'id="{name}"' in html, name


def test_every_docs_page_is_in_the_site(site):
    pages = [p.relative_to(ROOT / "docs") for p in (ROOT / "docs").rglob("*.md")]
    for page in pages:
        folder = "" if page.name == "README.md" else page.with_suffix("").as_posix()
        assert (site / folder / "index.html").exists(), page
