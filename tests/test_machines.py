"""Results from several machines: two stores written as two machines (two CPU models, two
calibrations, the same instruction counts) merged with ``longtime merge`` keep each run's
machine, and compare, report, history and the page show them side by side."""
import json

import pytest

from longtime.commands import cli
from longtime.core.timing import Timing
from longtime.execution.cells import expand, run_cell
from longtime.execution.store import Store

# the two "machines": the second's clock half as fast (its reference workload twice as long),
# and its kernels a third slower again (its calibrated time x1.5)
MACHINES = {"a": ({"node": "laptop", "cpu_model": "Intel Xeon (haswell)", "cpus": 4, "machine": "x86_64"}, 0.003),
            "b": ({"node": "ci-runner", "cpu_model": "AMD EPYC (znver4)", "cpus": 2, "machine": "x86_64"}, 0.006)}
COUNTS = {"rk4": 2_025_773, "gauss4": 17_740_771}
TARGET = {"instructions_tool": "callgrind 3.19.0 (x86-64-v3 kernels)", "instructions_target": "x86-64-v3",
          "instructions_versions": {"python": "3.11.7", "numba": "0.68.1", "llvmlite": "0.50.0", "numpy": "2.4.6"}}


@pytest.fixture(scope="module")
def stores(tmp_path_factory):
    """Two stores of one run each (run id 1 in both: a collision), as two machines wrote them."""
    folder = tmp_path_factory.mktemp("machines")
    cells = expand(["toda"], ["rk4", "gauss4"], t_final=10.0)
    rows = [(c, run_cell(c, timing=Timing(repeats=1))) for c in cells]
    paths = {}
    for side, (machine, calibration) in MACHINES.items():
        store = Store(folder / f"{side}.sqlite")
        run_id = store.begin_run(f"run on {machine['node']}", cells)
        store.set_machine(run_id, {**machine, "platform": "Linux"})
        store.add_calibrations(run_id, [{"t": 1.0, "pid": 1, "phase": "before", "steps": 400_000, "cpu_s": calibration,
                                         "cpu_s_median": calibration, "cpu_s_max": 1.01 * calibration,
                                         "cpu_s_samples": [calibration, 1.01 * calibration]}])
        for cell, row in rows:
            cpu_s = 1e-3 * (3 if side == "b" else 1) * (8 if cell.integrator == "gauss4" else 1)
            store.add_row(run_id, cell, {**row, "cpu_s": cpu_s, "cpu_s_calibrated": cpu_s / calibration,
                                         "instructions": COUNTS[cell.integrator], **TARGET,
                                         "instructions_skipped": None})
        store.finish_run(run_id, "done")
        paths[side] = folder / f"{side}.sqlite"
    return paths


@pytest.fixture(scope="module")
def merged(stores, tmp_path_factory):
    into = tmp_path_factory.mktemp("merged") / "c.sqlite"
    assert cli.main(["merge", str(stores["a"]), str(stores["b"]), "--into", str(into)]) == 0
    return into


def test_merge_keeps_each_run_and_its_machine(stores, merged, capsys):
    store = Store(merged, readonly=True)
    runs = store.runs()
    assert [r["id"] for r in runs] == [1, 2]  # b's run 1 collided: remapped to 2
    machines = [json.loads(r["machine"]) for r in runs]
    assert [m["cpu_model"] for m in machines] == ["Intel Xeon (haswell)", "AMD EPYC (znver4)"]
    assert machines[1]["merged_from"] == {"store": str(stores["b"]), "run": 1}
    assert [p["cpu_s"] for p in store.calibrations(2)] == [0.006]
    assert len(store.rows(1)) == len(store.rows(2)) == 2
    # merging the same stores again copies nothing
    capsys.readouterr()
    assert cli.main(["merge", str(stores["a"]), str(stores["b"]), "--into", str(merged), "--format", "json"]) == 0
    assert [m["id"] for m in json.loads(capsys.readouterr().out)] == [None, None]
    assert len(Store(merged, readonly=True).runs()) == 2


def test_merge_refuses_its_own_target(stores, capsys):
    assert cli.main(["merge", str(stores["a"]), "--into", str(stores["a"])]) == 2
    assert "both a source and --into" in capsys.readouterr().err


def test_compare_shows_the_cross_machine_table(merged, capsys):
    cli.main(["compare", "1", "2", "--db", str(merged)])
    out = capsys.readouterr().out
    assert "runs A and B ran on different machines" in out
    assert "M1: Intel Xeon (haswell), 4 cores (laptop); calibration 3 ms" in out
    assert "M2: AMD EPYC (znver4), 2 cores (ci-runner); calibration 6 ms" in out
    line = next(ln for ln in out.splitlines() if ln.strip().startswith("toda rk4"))
    # the same count on both machines; the calibrated times (0.001 / 0.003 and 0.003 / 0.006)
    # and each machine's own CPU time
    words = line.split()[4:]  # after the cell's name, dt and t_final
    assert words[:3] == ["2.026e+06", "2.026e+06", "x1.00000"]
    assert words[3:5] == ["0.3333", "0.5"] and words[5:] == ["0.001", "s", "0.003", "s"]
    assert "CPU seconds: do not compare across machines" in out
    result = cli.main(["compare", "1", "2", "--db", str(merged), "--format", "json"])
    assert result == 0
    table = json.loads(capsys.readouterr().out)["cross_machine"]
    assert [c["instructions_agree"]["ratio"] for c in table["cells"]] == [1.0, 1.0]


def test_counts_of_another_target_are_not_compared(stores, tmp_path, capsys):
    store = Store(stores["b"], readonly=True)
    from longtime.reporting import machines
    from longtime.reporting.compare_cells import cell_key
    from longtime.reporting.compare_text import label

    rows = Store(stores["a"], readonly=True).rows() + [{**r, "run_id": 9, "instructions_target": "znver4",
                                                        "instructions_tool": "callgrind 3.19.0 (znver4 kernels)"}
                                                       for r in store.rows()]
    runs = Store(stores["a"], readonly=True).runs() + [{**r, "id": 9} for r in store.runs()]
    table = machines.cross_machine(rows, runs, lambda i: [], cell_key, label)
    why = {c["instructions_agree"]["why"] for c in table["cells"]}
    assert why == {"counted for another target, Valgrind or versions"}


def test_report_history_and_page_show_the_machines(merged, tmp_path, capsys):
    from longtime.reporting.page import write_html

    assert cli.main(["report", "--db", str(merged), "--run", "all"]) == 0
    out = capsys.readouterr().out
    assert "results from several machines:" in out and "M2: AMD EPYC (znver4)" in out
    assert cli.main(["history", "--db", str(merged)]) == 0
    out = capsys.readouterr().out
    assert "results from several machines:" in out
    assert "STEP time" not in out  # the two machines' times are never one series
    store = Store(merged, readonly=True)
    page = write_html(tmp_path / "page", store.rows(), store, jobs=1)
    html = page.read_text()
    assert "Results from several machines" in html and "Which figures compare across machines" in html
    assert "M1 instructions" in html and "AMD EPYC (znver4)" in html
