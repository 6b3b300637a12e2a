"""One structurally bad stored row (garbage JSON, {}, a list, null, status
null, order "four") is skipped, with its id and the reason, by report, compare, report --html
and history; it never costs the store."""
import json
import sqlite3

import pytest

from longtime.commands.cli import main

BAD = {
    "garbage": "{not json",
    "empty": "{}",
    "list": "[1, 2]",
    "null": "null",
    "status-null": None,  # the good row with status null
    "order-four": None,   # the good row with order "four"
}


@pytest.fixture(scope="module")
def good_store(tmp_path_factory):
    db = tmp_path_factory.mktemp("rows") / "s.sqlite"
    argv = ["matrix", "-p", "harmonic", "-i", "rk4,verlet", "--dt", "0.1,0.05", "--t-final", "2", "--db", str(db),
            "--executor", "serial", "--no-progress", "--no-html", "--no-report", "--repeats", "1", "--min-time", "0"]
    assert main(argv) == 0
    assert main(argv) == 0  # two runs: compare and history have two sides
    return db.read_bytes()


def _spoil(path, kind):
    with sqlite3.connect(path) as con:
        row_id, text = con.execute("SELECT id, row FROM rows WHERE run_id = 2 ORDER BY id LIMIT 1").fetchone()
        row = json.loads(text)
        new = BAD[kind]
        if kind == "status-null":
            new = json.dumps({**row, "status": None})
        elif kind == "order-four":
            new = json.dumps({**row, "order": "four"})
        con.execute("UPDATE rows SET row = ? WHERE id = ?", (new, row_id))
    return row_id


@pytest.mark.parametrize("kind", list(BAD))
def test_one_bad_row_is_skipped_by_report_compare_html_and_history(kind, good_store, tmp_path, capsys):
    db = tmp_path / "s.sqlite"
    db.write_bytes(good_store)
    row_id = _spoil(db, kind)
    commands = [
        ["report", "--db", str(db), "--run", "2"],
        ["report", "--db", str(db), "--run", "all", "--format", "json"],
        ["report", "--db", str(db), "--run", "2", "--html", str(tmp_path / "page")],
        # the two runs' times are of tiny cells, one repeat each: no time factor judges them here
        ["compare", "1", "2", "--db", str(db), "--factor", "1e6", "--cell-factor", "1e6"],
        ["history", "--db", str(db), "-p", "harmonic"],
    ]
    for argv in commands:
        capsys.readouterr()
        code = main(argv)
        out, err = capsys.readouterr()
        assert code == 0, (argv, err)
        assert f"row {row_id} (run 2) skipped" in err, (argv, err)
        assert "Traceback" not in err
    assert (tmp_path / "page" / "index.html").exists()
    # the other rows are all there
    main(["report", "--db", str(db), "--run", "all", "--format", "json"])
    assert len(json.loads(capsys.readouterr().out)) == 7
