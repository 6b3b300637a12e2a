"""Numeric arguments are bounded and checked before any work (one line, exit 2); JSON output
holds null, never NaN or Infinity, for a stored non-finite value."""
import json
import sqlite3

import pytest

from longtime.commands.cli import main
from longtime.core import jsontext
from longtime.core.params import InputError
from longtime.execution.processes import check_processes, max_processes


@pytest.mark.parametrize("argv, words", [
    (["run", "-p", "harmonic", "-i", "verlet", "--dt", "0.1", "--processes", "100000"], "--processes"),
    (["run", "-p", "harmonic", "-i", "verlet", "--dt", "0.1", "--t-final", "1e300", "--allow-large"],
     "more than a run can count"),
    (["horizon", "--dt", "0.5,nan"], "--dt takes finite numbers"),
    (["horizon", "--members", "1000000000"], "--members takes an integer from 2 to 10000"),
    (["horizon", "--dt", "0.5,0.4", "--t-final", "1e300"], "over the limit"),
    (["roundoff", "--ensemble", "1000000000"], "--ensemble takes an integer from 0 to 10000"),
    (["roundoff", "--seed", "-1"], "--seed takes an integer from 0"),
    (["roundoff", "--steps", "1e300"], "--steps takes a number from 1 to"),
    (["roundoff", "--scheduler", "not an address"], "--scheduler"),
    (["ensemble", "-p", "henon-heiles", "-i", "verlet", "--window", "1e-300"],
     "--window takes a number from 1e-06 to 1"),
    (["ensemble", "-p", "henon-heiles", "-i", "verlet", "--seed", "-1"], "--seed takes an integer from 0"),
    (["ensemble", "-p", "henon-heiles", "-i", "verlet", "--size", "1e-300"], "--size takes a number"),
    (["ensemble", "-p", "henon-heiles", "-i", "verlet", "--members", "1000000000"], "--members"),
    (["ensemble", "-p", "henon-heiles", "-i", "verlet", "--t-final", "1e308"], "over the limit"),
    (["ensemble", "-p", "henon-heiles", "-i", "verlet", "--dt", "1e-300", "--t-final", "10"], "over the limit"),
    (["roundoff", "--spread", "H.max", "-p", "henon-heiles", "-i", "verlet", "--dt", "1e-300", "--t-final", "10"],
     "over the limit"),
], ids=lambda x: " ".join(x[:4]) if isinstance(x, list) else None)
def test_out_of_bounds_arguments_are_one_line_exit_2(argv, words, capsys, tmp_path):
    with pytest.raises(SystemExit) as info:
        code = main([*argv, *(["--db", str(tmp_path / "x.sqlite")] if argv[0] == "run" else [])])
        raise SystemExit(code)
    assert info.value.code == 2
    err = capsys.readouterr().err.strip()
    assert words in err and "Traceback" not in err
    assert not (tmp_path / "x.sqlite").exists()


def test_processes_have_an_upper_bound_in_the_api_and_the_environment(monkeypatch):
    assert check_processes(max_processes()) == max_processes()
    for value in (max_processes() + 1, 10**20, "1e20"):
        with pytest.raises(InputError, match="expected an integer from 1 to"):
            check_processes(value, "processes")


def test_json_output_is_strict_with_null_for_non_finite_values():
    text = jsontext.dumps({"a": float("nan"), "b": [1.0, float("inf"), {"c": -float("inf")}], "d": 2.5})
    assert json.loads(text) == {"a": None, "b": [1.0, None, {"c": None}], "d": 2.5}
    assert "NaN" not in text and "Infinity" not in text


def test_report_and_card_print_null_for_a_stored_nan(tmp_path, capsys):
    db = tmp_path / "n.sqlite"
    assert main(["run", "-p", "harmonic", "-i", "verlet", "--dt", "0.1", "--t-final", "1", "--db", str(db)]) == 0
    with sqlite3.connect(db) as con:
        (text,) = con.execute("SELECT row FROM rows").fetchone()
        row = json.loads(text)
        row["l2_error"] = float("nan")
        row["final_error"] = float("inf")
        con.execute("UPDATE rows SET row = ?", (json.dumps(row),))
    capsys.readouterr()
    assert main(["report", "--format", "json", "--db", str(db)]) == 0
    out = capsys.readouterr().out
    assert "NaN" not in out and "Infinity" not in out
    (printed,) = json.loads(out)
    assert printed["l2_error"] is None and printed["final_error"] is None
    assert main(["card", "verlet", "--format", "json", "--db", str(db)]) == 0
    out = capsys.readouterr().out
    assert "NaN" not in out and "Infinity" not in out
    json.loads(out)
