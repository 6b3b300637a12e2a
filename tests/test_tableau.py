"""Butcher tableaus are checked when their class is defined; a broken one is a broken plugin."""
import json
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from longtime.integrators.embedded_rk import DormandPrince45, EmbeddedRungeKutta
from longtime.integrators.explicit_rk import RK4, ExplicitRungeKutta
from longtime.integrators.implicit_rk import Gauss6, ImplicitRungeKutta, RK4Sym
from longtime.integrators.tableau import TableauError, check_tableau

HEUN = dict(A=[[0.0, 0.0], [1.0, 0.0]], b=[0.5, 0.5], c=[0.0, 1.0])


@pytest.mark.parametrize("cls", [RK4, RK4Sym, Gauss6, DormandPrince45])
def test_built_in_tableaus_pass(cls):
    explicit = issubclass(cls, (ExplicitRungeKutta, EmbeddedRungeKutta))
    check_tableau(cls.__name__, cls.A, cls.b, cls.c, explicit=explicit, e=getattr(cls, "e", None),
                  fsal=getattr(cls, "fsal", False))


@pytest.mark.parametrize("change, explicit, reason", [
    (dict(b=[0.25, 0.5, 0.25]), True, "inconsistent shapes"),      # three weights, two stages
    (dict(b=[0.5, 0.6]), True, "sum to"),                         # weights do not sum to 1
    (dict(c=[0.0, 0.5]), True, "row 1 of A sums to 1.0"),         # c is not A's row sums
    (dict(A=[[0.5, 0.0], [0.5, 0.5]], c=[0.5, 1.0]), True, "strictly lower triangular"),
    (dict(A=[[0.0, 0.0], [np.nan, 0.0]]), True, "non-finite"),
    (dict(A=[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]), False, "inconsistent shapes"),
])
def test_inconsistent_tableaus_are_refused(change, explicit, reason):
    t = {**HEUN, **change}
    with pytest.raises(TableauError, match=reason):
        check_tableau("Heun", t["A"], t["b"], t["c"], explicit=explicit)


def test_error_weights_and_fsal():
    dp = DormandPrince45
    with pytest.raises(TableauError, match="error weights e sum to"):
        check_tableau("dp", dp.A, dp.b, dp.c, explicit=True, e=dp.e + 1e-3)
    check_tableau("dp", dp.A, dp.b, dp.c, explicit=True, e=dp.e, fsal=True)  # DP5(4) is FSAL
    with pytest.raises(TableauError, match="fsal"):
        check_tableau("rk4", RK4.A, RK4.b, RK4.c, explicit=True, fsal=True)  # RK4 is not


def test_a_broken_subclass_fails_when_defined():
    with pytest.raises(TableauError, match="inconsistent shapes"):
        class ThreeWeights(ExplicitRungeKutta):  # noqa: F841
            A = np.array([[0.0, 0.0], [1.0, 0.0]])
            b = np.array([0.25, 0.5, 0.25])
            c = np.array([0.0, 1.0])
    with pytest.raises(TableauError, match="row 0 of A sums to"):
        class WrongNodes(ImplicitRungeKutta):  # noqa: F841
            A = np.array([[0.5]])
            b = np.array([1.0])
            c = np.array([0.0])


PLUGIN = '''
import numpy as np
from longtime.integrators.explicit_rk import ExplicitRungeKutta


class ThreeWeights(ExplicitRungeKutta):
    summary = "three weights against two stages"
    order = 2
    A = np.array([[0.0, 0.0], [1.0, 0.0]])
    b = np.array([0.25, 0.5, 0.25])
    c = np.array([0.0, 1.0])
'''


def test_broken_tableau_plugin_is_reported_by_list(tmp_path):
    """An installed plugin (dist-info with entry points on sys.path) with a broken tableau is
    listed as broken with the reason, and asking for it is an input error (exit 2)."""
    (tmp_path / "bad_tableau.py").write_text(PLUGIN)
    info = tmp_path / "bad_tableau-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: bad-tableau\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text("[longtime.integrators]\nthree-weights = bad_tableau:ThreeWeights\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), os.environ.get("PYTHONPATH", "")])}
    out = subprocess.run([sys.executable, "-m", "longtime.commands.cli", "list", "--format", "json"],
                         capture_output=True, text=True, env=env, check=True).stdout
    broken = {b["name"]: b for b in json.loads(out)["broken"]}
    assert "three-weights" in broken
    assert "inconsistent shapes" in broken["three-weights"]["error"]
    assert "three-weights" not in [i["name"] for i in json.loads(out)["integrators"]]
    run = subprocess.run([sys.executable, "-m", "longtime.commands.cli", "run", "-p", "harmonic", "-i", "three-weights",
                          "--no-store"], capture_output=True, text=True, env=env)
    assert run.returncode == 2
    assert "broken plugin" in run.stderr and "inconsistent shapes" in run.stderr, textwrap.shorten(run.stderr, 300)
