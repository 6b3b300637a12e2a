"""The parameter searches (longtime.execution.search) and `longtime match` on a plugin scheme whose
accuracy parameter is called ``rtol``: found from its declared role, swept and matched."""
import json
import math

from _rtol_scheme import NAME as RTOL
from _rtol_scheme import register

from longtime.commands.cli import main
from longtime.execution.search import CLOSE_ENOUGH, accuracy_parameter


def test_accuracy_parameter_from_roles(monkeypatch):
    register(monkeypatch)
    assert accuracy_parameter(RTOL) == "rtol"
    assert accuracy_parameter("bpl") == "eps_res"
    assert accuracy_parameter("rk45") == "tol"
    assert accuracy_parameter("rk4") == "dt"


def test_plugin_rtol_sweeps_from_the_command_line(monkeypatch, capsys):
    register(monkeypatch)
    code = main(["run", "--executor", "serial", "-p", "harmonic", "-i", RTOL, "--set", "rtol=1e-4,1e-8",
                 "--t-final", "20", "--format", "json", "--no-store", "--repeats", "1", "--min-time", "0"])
    rows = json.loads(capsys.readouterr().out)
    assert code == 0 and [json.loads(r["settings"]) for r in rows] == [{"rtol": 1e-4}, {"rtol": 1e-8}]
    assert [json.loads(r["parameters"])["rtol"] for r in rows] == [1e-4, 1e-8]
    assert all(r["tol"] is None for r in rows)  # rtol is not the row field tol
    loose, tight = rows
    assert tight["l2_error"] < loose["l2_error"] / 100  # the tolerance acts: 10^4 tighter
    assert tight["steps"] > loose["steps"]


def test_plugin_rtol_is_matched(monkeypatch, capsys):
    register(monkeypatch)
    target = 1e-7
    code = main(["match", "-p", "harmonic", "-i", RTOL, "--target", str(target), "--t-final", "20",
                 "--repeat", "1", "--max-evals", "10", "--format", "json", "--no-store", "-q"])
    (row,) = json.loads(capsys.readouterr().out)
    assert code == 0 and row["status"] == "ok"
    assert row["match_parameter"] == "rtol"
    assert json.loads(row["parameters"])["rtol"] == row["match_value"]
    assert abs(math.log(row["final_error"] / target)) <= CLOSE_ENOUGH, (row["final_error"], row["match_note"])
