"""longtime compare: an injected slowdown and an injected accuracy loss make it exit 1; a slower
machine, a batch's change of speed between processes and too-short cells do not."""
import json
import sqlite3

import pytest

from longtime.commands import cli
from longtime.reporting.compare import compare, order_changes
from longtime.reporting.compare_cells import slower_p
from longtime.reporting.compare_text import render


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    db = tmp_path_factory.mktemp("compare") / "runs.sqlite"
    assert cli.main(["run", "-p", "harmonic", "-i", "rk4", "--dt", "0.1,0.05", "--t-final", "4000",
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
        assert row["cpu_s_calibrated"] == pytest.approx(row["cpu_s"] / row["calibration_cpu_s"])
        if i == 0:  # 2.5x slower code: raw and calibrated time alike
            row["cpu_s_samples"] = [2.5 * c for c in row["cpu_s_samples"]]
            row["cpu_s"] = min(row["cpu_s_samples"])
            row["cpu_s_calibrated"] *= 2.5
        else:  # ten times less accurate
            row["l2_error"] *= 10
        return row

    run_b = _inject(store, edit)
    assert cli.main(["compare", "1", str(run_b), "--db", str(store), "--format", "json"]) == 1
    result = json.loads(capsys.readouterr().out)
    by_dt = {c["dt"]: c for c in result["cells"]}
    slow, worse = by_dt[0.1], by_dt[0.05]
    assert slow["cpu_ratio"] == pytest.approx(2.5) and slow["time_ratio"] == pytest.approx(2.5)
    assert slow["time_basis"] == "calibrated" and slow["time_verdict"] == "slower"
    assert any(r.startswith("time x2.5 (calibrated") for r in slow["regressions"])
    assert [r for r in worse["regressions"] if r.startswith("l2_error x10")]
    assert worse["time_verdict"] == "within" and worse["error_verdict"] == "less accurate"
    assert result["counts"]["time"]["slower"] == 1 and result["counts"]["accuracy"]["less accurate"] == 1
    # a generous cell factor lets the slowdown pass, not the accuracy loss
    assert cli.main(["compare", "1", str(run_b), "--db", str(store), "--cell-factor", "3"]) == 1
    text = capsys.readouterr().out
    assert "1 regressed" in text and "l2_error x10" in text and "time x2.5" not in text


def test_a_slower_machine_is_not_a_regression_of_calibrated_times(store, capsys):
    def edit(i, row):  # the machine 2.5x slower: cells and the reference workload alike
        row["cpu_s"] *= 2.5
        row["calibration_cpu_s"] *= 2.5
        return row

    run_b = _inject(store, edit)
    assert cli.main(["compare", "1", str(run_b), "--db", str(store)]) == 0
    assert "0 regressed" in capsys.readouterr().out
    assert cli.main(["compare", "1", str(run_b), "--db", str(store), "--raw-time", "--format", "json"]) == 1
    result = json.loads(capsys.readouterr().out)
    assert result["time_basis"] == "raw" and result["counts"]["time"]["slower"] == 2


def _rows(times: dict[tuple[str, str], float], error: float = 1e-6, cpu: float = 0.01,
          dts: tuple[float, ...] = (0.1, 0.05)) -> list[dict]:
    """Synthetic ok rows, a cell per dt per problem x scheme, calibrated time scaled per pair."""
    return [{"problem": p, "integrator": s, "status": "ok", "dt": dt, "t_final": 10.0, "settings": "",
             "cpu_s": cpu * f, "cpu_s_calibrated": 5 * f * dt, "l2_error": error * (dt / 0.1) ** 4}
            for (p, s), f in times.items() for dt in dts]


PAIRS = [(p, s) for p in ("harmonic", "toda", "kepler") for s in ("rk4", "verlet")]


def test_a_scheme_slower_on_every_problem_is_flagged_a_batch_flip_is_not():
    a = _rows({k: 1.0 for k in PAIRS})
    slowed = compare(a, _rows({k: 1.3 if k[1] == "rk4" else 1.0 for k in PAIRS}))
    assert slowed["schemes"]["rk4"]["verdict"] == "slower" and slowed["schemes"]["verlet"]["verdict"] == "within"
    assert slowed["regressed"] == 6 and {c["integrator"] for c in slowed["cells"] if c["regressions"]} == {"rk4"}
    # identical code: one batch (a problem x scheme in one process) took another speed
    flipped = compare(a, _rows({k: 1.8 if k == ("toda", "rk4") else 1.0 for k in PAIRS}))
    assert flipped["regressed"] == 0 and flipped["counts"]["time"]["within"] == 12
    # too few problems for a scheme's verdict: only the cell factor judges
    two = [k for k in PAIRS if k[0] != "kepler"]
    few = compare(_rows({k: 1.0 for k in two}), _rows({k: 1.3 if k[1] == "rk4" else 1.0 for k in two}))
    assert few["schemes"]["rk4"]["verdict"] is None and few["regressed"] == 0


def test_too_short_cells_get_no_verdict():
    result = compare(_rows({("harmonic", "rk4"): 1.0}, cpu=1e-5), _rows({("harmonic", "rk4"): 3.0}, cpu=1e-5))
    assert {c["time_verdict"] for c in result["cells"]} == {"too short"} and result["regressed"] == 0
    assert "2 too short to time (< 20 us)" in render(result)


def test_counts_once_under_each_heading_and_orders_and_machine():
    dts = (0.1, 0.05, 0.025)  # three steps a sweep: an order needs three points
    a = _rows({k: 1.0 for k in PAIRS}, dts=dts)
    b = _rows({k: 2.5 if k == ("toda", "rk4") else 1.0 for k in PAIRS}, dts=dts)
    for r in b:
        if r["problem"] == "toda" and r["integrator"] == "rk4":
            r["l2_error"] /= 10  # slower and more accurate
        if r["problem"] == "kepler" and r["integrator"] == "verlet":
            r["l2_error"] = 1e-6 * (r["dt"] / 0.1) ** 2  # second order: less accurate at dt 0.05 and 0.025
    cals = ([{"t": 0.0, "cpu_s": 3e-3, "cpu_s_max": 3.1e-3}], [{"t": 9.0, "cpu_s": 3.6e-3, "cpu_s_max": 3.7e-3}])
    result = compare(a, b, calibrations=cals)
    counts = result["counts"]
    assert counts["time"] == {"slower": 3, "faster": 0, "within": 15, "too short": 0, "not comparable": 0,
                              "not compared": 0}
    assert counts["accuracy"]["more accurate"] == 3 and counts["accuracy"]["less accurate"] == 2
    assert result["regressed"] == 5 and result["improved"] == 3
    assert sum(counts["time"].values()) == sum(counts["accuracy"].values()) == len(result["cells"])
    orders = {(o["problem"], o["integrator"]): o for o in order_changes(a, b)}
    assert orders[("kepler", "verlet")]["order_changed"]
    assert orders[("kepler", "verlet")]["observed_order_b"] == pytest.approx(2.0)
    assert not orders[("toda", "rk4")]["order_changed"]
    assert result["machine"]["differed"] and result["machine"]["ratio"] == pytest.approx(1.2)
    text = render(result)
    assert "its speed differed" in text and "kepler verlet (3 cells)" in text and "CHANGED" in text


def test_matrix_baseline_exits_1_on_a_regression(tmp_path, capsys):
    db = tmp_path / "base.sqlite"
    argv = ["matrix", "-p", "harmonic", "-i", "verlet", "--dt", "0.1,0.05", "--t-final", "20", "--executor",
            "serial", "--no-html", "--no-progress", "--db", str(db)]
    assert cli.main(argv) == 0
    assert "calibration: reference workload" in capsys.readouterr().out
    assert cli.main([*argv, "--baseline", "1"]) == 0  # identical code: no regression
    assert "== compared with run 1" in capsys.readouterr().out
    run = _inject(db, lambda i, row: {**row, "l2_error": row["l2_error"] / 10})  # a more accurate baseline
    assert cli.main([*argv, "--baseline", str(run)]) == 1
    assert "l2_error x10" in capsys.readouterr().out
    assert cli.main([*argv, "--baseline", "99"]) == 2
    assert "run 99 is not in" in capsys.readouterr().err


def test_rank_test_and_round_off_floor():
    assert slower_p([1.0, 1.1, 1.2], [2.0, 2.1, 2.2]) == pytest.approx(0.05)  # 3 vs 3: the smallest p
    assert slower_p([1.0, 2.0, 1.5], [1.1, 1.9, 1.4]) > 0.3
    a = {"problem": "p", "integrator": "s", "status": "ok", "cpu_s": 1.0, "H.max": 1e-16, "l2_error": 1e-6}
    b = {**a, "H.max": 9e-16, "l2_error": 1.5e-6, "status": "diverged"}
    cell = compare([a], [b])["cells"][0]
    assert cell["errors"]["H.max"]["ratio"] == pytest.approx(9.0)
    assert cell["regressions"] == ["status ok -> diverged"]  # H.max at round-off, l2 within x2


def test_same_instructions_hold_the_time_verdict_to_the_cell_factor():
    """Identical code (the same instruction count) slowed x1.57 by a neighbour's load is
    not slower; x2.1 is; more instructions with x1.3 is slower on both counts."""
    from longtime.reporting.compare_cells import compare_rows

    def row(cpu, spread, count):
        return {"problem": "toda", "integrator": "gauss4", "status": "ok", "cpu_s": cpu, "t_final": 500.0,
                "cpu_s_process_spread": spread, "instructions": count, "instructions_tool": "callgrind 3.19"}

    c = compare_rows(row(1.0, 1.1, 1_000_000), row(1.57, 1.2, 1_000_040))
    assert c["instruction_verdict"] == "within" and c["time_verdict"] == "within" and not c["regressions"]
    assert c["time_threshold"] == 2.0
    c = compare_rows(row(1.0, 1.1, 1_000_000), row(2.1, 1.2, 1_000_040))
    assert c["time_verdict"] == "slower" and "instructions within" in c["regressions"][0]
    c = compare_rows(row(1.0, 1.1, 1_000_000), row(1.3, 1.1, 1_300_000))
    assert c["time_verdict"] == "slower" and c["instruction_verdict"] == "more" and len(c["regressions"]) == 2
    # without counts, the spread between processes and --factor judge the time
    a, b = row(1.0, 1.1, None), row(1.3, 1.1, None)
    assert compare_rows(a, b)["time_verdict"] == "slower"


def test_a_cell_with_more_instructions_is_judged_against_the_unchanged_cells():
    """Run B ran on a machine 0.9x as loaded: the cells of unchanged code took 0.9 of their
    time. A cell with 25 % more instructions at x1.18 (x1.31 against them) is slower; the
    same cell at x1.05 (x1.17) is not, and without three unchanged cells nothing is judged again."""
    from longtime.reporting.compare import compare

    def rows(ratio, plugin_ratio, plugin_count, n=4):
        a, b = [], []
        for i in range(n):
            base = {"problem": "toda", "integrator": f"s{i}", "status": "ok", "t_final": 500.0,
                    "cpu_s_process_spread": 1.05, "instructions_tool": "callgrind"}
            a.append({**base, "cpu_s": 1e-2, "instructions": 10**7})
            b.append({**base, "cpu_s": 1e-2 * ratio, "instructions": 10**7})
        base = {"problem": "harmonic", "integrator": "plugin", "status": "ok", "t_final": 1000.0,
                "cpu_s_process_spread": 1.1, "instructions_tool": "callgrind"}
        a.append({**base, "cpu_s": 6e-3, "instructions": 4 * 10**7})
        b.append({**base, "cpu_s": 6e-3 * plugin_ratio, "instructions": plugin_count})
        return a, b

    cells = {c["integrator"]: c for c in compare(*rows(0.9, 1.18, 5 * 10**7))["cells"]}
    assert cells["plugin"]["time_verdict"] == "slower"
    assert abs(cells["plugin"]["time_ratio_against_unchanged"] - 1.18 / 0.9) < 1e-9
    assert all(cells[f"s{i}"]["time_verdict"] == "within" for i in range(4))
    assert compare(*rows(0.9, 1.05, 5 * 10**7))["cells"][-1]["time_verdict"] == "within"
    assert compare(*rows(0.9, 1.18, 5 * 10**7, n=2))["cells"][-1]["time_verdict"] == "within"
    # the same instructions: no second judgement, whatever the others did
    assert compare(*rows(0.7, 1.18, 4 * 10**7))["cells"][-1]["time_verdict"] == "within"
