"""longtime compare: an injected slowdown and an injected accuracy loss make it exit 1."""
import json
import sqlite3

import pytest

from longtime import cli
from longtime.compare import compare, slower_p


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    db = tmp_path_factory.mktemp("compare") / "runs.sqlite"
    assert cli.main(["run", "-p", "harmonic", "-i", "rk4", "--dt", "0.1,0.05", "--t-final", "2000",
                     "--repeats", "7", "--min-time", "0.02", "--db", str(db), "--format", "json"]) == 0
    return db


def _inject(db, edit) -> int:
    """Copy run 1 into a new run, each row passed through ``edit(i, row)``; return its id."""
    con = sqlite3.connect(db)
    with con:
        cur = con.execute("INSERT INTO runs (started, status, command) VALUES ('now', 'done', 'injected')")
        run_b = cur.lastrowid
        for i, (key, problem, integrator, status, text) in enumerate(con.execute(
                "SELECT cell_key, problem, integrator, status, row FROM rows WHERE run_id = 1 ORDER BY id").fetchall()):
            con.execute("INSERT INTO rows (run_id, cell_key, problem, integrator, status, row, created) "
                        "VALUES (?, ?, ?, ?, ?, ?, 'now')",
                        (run_b, key, problem, integrator, status, json.dumps(edit(i, json.loads(text)))))
    con.close()
    return run_b


def test_same_run_has_no_regression(store, capsys, tmp_path):
    assert cli.main(["compare", "1", "1", "--db", str(store)]) == 0
    assert "2 common cells" in capsys.readouterr().out
    other = tmp_path / "other.sqlite"  # the same run in a second store
    with sqlite3.connect(store) as src, sqlite3.connect(other) as dst:
        src.backup(dst)
    assert cli.main(["compare", "1", "1", "--db", str(store), "--db-b", str(other)]) == 0
    assert "2 common cells (0 only in A, 0 only in B): 0 regressed" in capsys.readouterr().out


def test_injected_slowdown_and_accuracy_loss_exit_1(store, capsys):
    def edit(i, row):
        assert len(row["cpu_s_samples"]) >= 3  # the repeats the rank test needs
        if i == 0:  # 1.5x slower, every repeat
            row["cpu_s_samples"] = [1.5 * c for c in row["cpu_s_samples"]]
            row["cpu_s"] = min(row["cpu_s_samples"])
        else:  # ten times less accurate
            row["l2_error"] *= 10
        return row

    run_b = _inject(store, edit)
    assert cli.main(["compare", "1", str(run_b), "--db", str(store), "--format", "json"]) == 1
    result = json.loads(capsys.readouterr().out)
    by_dt = {c["dt"]: c for c in result["cells"]}
    slow, worse = by_dt[0.1], by_dt[0.05]
    assert slow["cpu_ratio"] == pytest.approx(1.5)
    assert slow["p_slower"] <= 0.05 and any(r.startswith("cpu x1.5") for r in slow["regressions"])
    assert [r for r in worse["regressions"] if r.startswith("l2_error x10")]
    assert not [r for r in worse["regressions"] if r.startswith("cpu")]
    # a generous factor lets the slowdown pass, not the accuracy loss
    assert cli.main(["compare", "1", str(run_b), "--db", str(store), "--factor", "2"]) == 1
    text = capsys.readouterr().out
    assert "1 regressed" in text and "l2_error x10" in text and "cpu x1.5 (p=" not in text


def test_rank_test_and_round_off_floor():
    assert slower_p([1.0, 1.1, 1.2], [2.0, 2.1, 2.2]) == pytest.approx(0.05)  # 3 vs 3: the smallest p
    assert slower_p([1.0, 2.0, 1.5], [1.1, 1.9, 1.4]) > 0.3
    a = {"problem": "p", "integrator": "s", "status": "ok", "cpu_s": 1.0, "H.max": 1e-16, "l2_error": 1e-6}
    b = {**a, "H.max": 9e-16, "l2_error": 1.5e-6, "status": "diverged"}
    cell = compare([a], [b])["cells"][0]
    assert cell["errors"]["H.max"]["ratio"] == pytest.approx(9.0)
    assert cell["regressions"] == ["status ok -> diverged"]  # H.max at round-off, l2 within x2
