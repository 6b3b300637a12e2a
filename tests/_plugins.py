"""Test helper: pip-install a plugin package and run the CLI in processes that see it.

The package is installed with ``pip install --target`` into a temporary folder that the
child processes get on PYTHONPATH: discovery goes through its installed entry-point
metadata exactly as for a site-packages install, without touching the test environment.
"""
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

PYPROJECT = """\
[build-system]
requires = ["setuptools>=61"]
build-backend = "setuptools.build_meta"

[project]
name = "{name}"
version = "0.1"
{entry_points}
[tool.setuptools]
py-modules = {modules}
"""


def install_plugin(root: Path, name: str, entry_points: dict[str, dict[str, str]],
                   modules: dict[str, str]) -> tuple[dict[str, str], Path]:
    """Build the distribution ``name`` of the top-level ``modules`` (file name -> source)
    that declares ``entry_points`` ({"problems" or "integrators": {name: "module:Class"}})
    in root/src, install it into root/site; returns the environment of a process that sees
    it and the site folder (where its installed modules can be edited)."""
    src, site = root / "src", root / "site"
    src.mkdir(parents=True)
    groups = "".join(f'\n[project.entry-points."longtime.{group}"]\n'
                     + "".join(f'{key} = "{target}"\n' for key, target in points.items())
                     for group, points in entry_points.items())
    py_modules = [Path(m).stem for m in modules]
    (src / "pyproject.toml").write_text(PYPROJECT.format(name=name, entry_points=groups,
                                                         modules=json.dumps(py_modules)))
    for module, text in modules.items():
        (src / module).write_text(textwrap.dedent(text))
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps",
                    "--target", str(site), str(src)], check=True, capture_output=True)
    assert list(site.glob("*.dist-info/entry_points.txt"))
    path = os.pathsep.join(filter(None, [str(site), os.environ.get("PYTHONPATH")]))
    return {**os.environ, "PYTHONPATH": path}, site


def longtime(env, *args):
    return subprocess.run([sys.executable, "-m", "longtime.commands.cli", *args], env=env, capture_output=True,
                          text=True, timeout=600)


# Heun's method as a plugin module defines it (needs numpy as np and ExplicitRungeKutta):
# the base of the misbehaving test schemes
HEUN_SOURCE = '''
class _Heun(ExplicitRungeKutta):
    summary = "Heun's method (order 2)"
    order = 2
    A = np.array([[0.0, 0.0], [1.0, 0.0]])
    b = np.array([0.5, 0.5])
    c = np.array([0.0, 1.0])
'''
