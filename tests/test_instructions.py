"""``--cost instructions``: the integration's instructions counted under Valgrind.

Each Valgrind process costs about a minute of CPU (numba imported under it), so the cells
of these tests share one process (the ``counted`` fixture), and one more process counts a
cell again beside a CPU-bound process. Without Valgrind on the machine they are skipped,
except the test that the missing Valgrind is one line naming its Debian package."""
import os
import shutil
import subprocess
import sys
from pathlib import Path

import _slowed
import pytest

from longtime.core import registry
from longtime.core.timing import Timing
from longtime.execution.cells import expand, run_cell
from longtime.reporting.compare import compare
from longtime.reporting.compare_cells import INSTRUCTION_FACTOR

# CI installs Valgrind and sets LONGTIME_REQUIRE_VALGRIND: there these tests fail instead of skipping
needs_valgrind = pytest.mark.skipif(shutil.which("valgrind") is None
                                    and not os.environ.get("LONGTIME_REQUIRE_VALGRIND"),
                                    reason="valgrind is not installed (Debian package valgrind)")

# kepler rk4 over T and 2T: the count doubles with the steps; harmonic with the plain scheme
# and with one that repeats its stages every 20th step (5 % more work a step, as an
# author's commit might add); an adaptive scheme; schemes whose integration is not isolated
T = 50.0


def _schemes(folder: Path) -> tuple[str, str]:
    """Two plugin schemes in modules of their own: the plain one and the one doing 5 % more."""
    names = []
    for name, repeat in (("instr-plain", 0.0), ("instr-heavier", 0.05)):
        module = name.replace("-", "_")
        text = _slowed.source(repeat).replace('name = "slowed-rk4"', f'name = "{name}"')
        (folder / f"{module}.py").write_text(text)
        names.append(name)
    sys.path.insert(0, str(folder))
    import instr_heavier
    import instr_plain

    registry.register(instr_plain.SlowedRK4, "instr-plain")
    registry.register(instr_heavier.SlowedRK4, "instr-heavier")
    return names[0], names[1]


def _rows(cells):
    return [(c, run_cell(c, timing=Timing(repeats=1))) for c in cells]


@pytest.fixture(scope="module")
def counted(tmp_path_factory):
    from longtime.execution.valgrind import instruction_fields

    plain, heavier = _schemes(tmp_path_factory.mktemp("schemes"))
    cells = (expand(["kepler"], ["rk4"], t_final=[T, 2 * T]) + expand(["kepler"], ["rk45", "heyoka"], t_final=T)
             + expand(["harmonic"], [plain, heavier], sweeps={"dt": [0.01]}, t_final=100.0))
    pairs = _rows(cells)
    fields = instruction_fields(pairs, 100_001, 600.0)
    return {(c.integrator, c.t_final): {**row, **fields[c.key]} for c, row in pairs}


@pytest.mark.slow
@needs_valgrind
def test_count_covers_the_integration_only(counted):
    short, long = counted[("rk4", T)], counted[("rk4", 2 * T)]
    assert long["steps"] == 2 * short["steps"]
    # twice the steps, twice the instructions: imports, compilation and the reference (a
    # fixed cost of millions of instructions) are not in the count
    assert long["instructions"] / short["instructions"] == pytest.approx(2.0, rel=0.02)
    assert short["instructions_per_step"] == pytest.approx(short["instructions"] / short["steps"])
    assert short["instructions_skipped"] is None and short["instructions_tool"].startswith("callgrind")
    adaptive = counted[("rk45", T)]
    assert adaptive["instructions"] > adaptive["steps"] * 100  # counted over its chunks of samples
    external = counted[("heyoka", T)]
    assert external["instructions"] is None and "cannot be counted apart" in external["instructions_skipped"]


@pytest.mark.slow
@needs_valgrind
def test_five_percent_more_work_a_step_is_flagged(counted):
    plain, heavier = counted[("instr-plain", 100.0)], counted[("instr-heavier", 100.0)]
    ratio = heavier["instructions"] / plain["instructions"]
    assert 1.02 < ratio < 1.06
    # compare of the author's two commits (the same cell: her scheme before and after)
    before, after = dict(plain), {**heavier, "integrator": plain["integrator"]}
    result = compare([before], [after])
    cell = result["cells"][0]
    assert cell["instruction_verdict"] == "more" and result["regressed"] == 1
    assert any(r.startswith("instructions x") for r in cell["regressions"])
    # identical counts: nothing to say
    same = compare([before], [dict(before)])
    assert same["cells"][0]["instruction_verdict"] == "within" and same["regressed"] == 0
    assert INSTRUCTION_FACTOR < ratio


@pytest.mark.slow
@needs_valgrind
def test_counts_agree_beside_a_cpu_bound_process(counted):
    from longtime.execution.valgrind import instruction_fields

    hog = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        pairs = _rows(expand(["kepler"], ["rk4"], t_final=T))
        again = instruction_fields(pairs, 100_001, 600.0)[pairs[0][0].key]
    finally:
        hog.kill()
        hog.wait()
    first = counted[("rk4", T)]["instructions"]
    assert abs(again["instructions"] / first - 1) < 1e-3


@pytest.mark.slow
@needs_valgrind
def test_a_count_does_not_depend_on_the_cells_counted_with_it():
    """kepler x verlet and x rk4 (100 steps: the smallest counts, where the dispatch of the
    call weighs most) counted in two batches, in the opposite order: each cell's two counts
    agree within COUNT_NOISE (the warm-up, the interpreter's and the allocators' state that
    the cell before leaves are not in the count)."""
    from longtime.execution.valgrind import instruction_fields
    from longtime.measure.instructions import COUNT_NOISE

    counts = []
    for order in (["rk4", "verlet"], ["verlet", "rk4"]):
        pairs = _rows(expand(["kepler"], order, t_final=10.0, sets={"dt": 0.1}))
        fields = instruction_fields(pairs, 100_001, 600.0)
        counts.append({c.integrator: fields[c.key]["instructions"] for c, _ in pairs})
    for scheme in ("rk4", "verlet"):
        first, second = counts[0][scheme], counts[1][scheme]
        assert abs(second - first) <= COUNT_NOISE, (scheme, first, second)


@pytest.mark.slow
def test_missing_valgrind_is_one_line(tmp_path):
    env = {**os.environ, "PATH": str(tmp_path)}  # no valgrind (nor anything else) on PATH
    res = subprocess.run([sys.executable, "-m", "longtime.commands.cli", "run", "-p", "kepler", "-i", "rk4",
                          "--t-final", "1", "--cost", "instructions", "--no-store"],
                         capture_output=True, text=True, env=env, timeout=300)
    assert res.returncode == 2 and res.stdout == ""
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "valgrind" in lines[0] and "Debian package" in lines[0]


def test_a_cell_too_long_to_count_is_skipped_with_the_reason(monkeypatch):
    from longtime.execution import valgrind
    from longtime.measure import instructions

    monkeypatch.setattr(instructions, "require", lambda: "/no/valgrind/needed")  # nothing is counted here
    cells = expand(["kepler"], ["rk4"], t_final=T)
    row = {"status": "ok", "wall_s": 30.0, "cpu_s": 30.0, "steps": 5000}
    fields = valgrind.instruction_fields([(cells[0], row)], 100_001, 600.0)[cells[0].key]
    assert fields["instructions"] is None and fields["instructions_per_step"] is None
    assert "too long to count under Valgrind" in fields["instructions_skipped"]
    failed = valgrind.instruction_fields([(cells[0], {"status": "diverged"})], 100_001, 600.0)[cells[0].key]
    assert failed["instructions"] is None and "diverged" in failed["instructions_skipped"]


def test_history_marks_a_step_in_the_count_and_none_in_its_noise(tmp_path):
    from longtime.execution.store import Store
    from longtime.reporting.history import history, render

    store = Store(tmp_path / "s.sqlite")
    cell = expand(["kepler"], ["rk4"], t_final=T)[0]
    # counts as identical code gives them (a few instructions apart), then 5 % more a step
    for count in (1_000_000, 1_000_003, 999_998, 1_050_000, 1_050_001):
        run_id = store.begin_run("run", [cell])
        store.add_row(run_id, cell, {"problem": "kepler", "integrator": "rk4", "status": "ok", "t_final": T,
                                     "dt": None, "settings": "", "cpu_s": 1e-3, "cpu_s_calibrated": 0.3,
                                     "instructions": count, "instructions_per_step": count / 5000,
                                     "instructions_tool": "callgrind 3.19.0", "instructions_skipped": None})
        store.finish_run(run_id, "done")
    found = history(store)
    steps = [s for s in found[0]["steps"] if s["field"] == "instructions"]
    assert len(steps) == 1 and steps[0]["kind"] == "more instructions" and steps[0]["run_id"] == 4
    assert steps[0]["ratio"] == pytest.approx(1.05, rel=1e-3)
    assert "STEP instructions x1.05" in render(found)


@pytest.mark.slow
def test_benchmark_cell_puts_the_count_in_extra_info(monkeypatch):
    from longtime.execution import valgrind
    from longtime.testing import benchmark_cell

    seen = []

    def fields(pairs, max_samples, time_limit):  # the count itself is the tests' above
        pairs = list(pairs)
        seen.extend(row["steps"] for _, row in pairs)
        return {c.key: {"instructions": 1234, "instructions_per_step": 1234 / row["steps"],
                        "instructions_tool": "callgrind", "instructions_skipped": None} for c, row in pairs}

    monkeypatch.setattr(valgrind, "instruction_fields", fields)

    class Benchmark:  # pytest-benchmark's fixture, as benchmark_cell uses it
        extra_info: dict = {}

        def __call__(self, fn, *args):
            return fn(*args)

    bench = Benchmark()
    row = benchmark_cell(bench, "kepler", "verlet", t_final=1, dt=0.01, cost="instructions")
    assert seen == [100] and bench.extra_info["instructions"] == 1234 == row["instructions"]
    assert bench.extra_info["instructions_per_step"] == pytest.approx(12.34)
    plain = Benchmark()
    plain.extra_info = {}
    benchmark_cell(plain, "kepler", "verlet", t_final=1, dt=0.01)
    assert "instructions" not in plain.extra_info  # time only by default


def test_the_page_draws_work_precision_against_instructions():
    from longtime.reporting.figures.results import problem_figures
    from longtime.reporting.figures.style import styles

    rows = [{"problem": "kepler", "integrator": "rk4", "status": "ok", "dt": dt, "t_final": T, "settings": "",
             "cpu_s": 1e-3 * 0.01 / dt, "l2_error": dt ** 4, "steps": round(T / dt)} for dt in (0.01, 0.005)]
    figs = problem_figures(rows, styles(["rk4"]), drift=False)
    assert figs["work_precision"] is not None and figs["work_precision_instructions"] is None  # time only
    for r in rows:
        r.update(instructions=1300 * r["steps"], instructions_per_step=1300.0)
    figs = problem_figures(rows, styles(["rk4"]), drift=False)
    assert "instructions of the integration" in figs["work_precision_instructions"]


def test_a_count_change_within_the_counts_noise_is_no_change(tmp_path):
    """Counts of identical code differ by up to COUNT_NOISE instructions a call: on a cell so
    small that this passes --instruction-factor, compare and history judge it within."""
    from longtime.execution.store import Store
    from longtime.measure.instructions import COUNT_NOISE
    from longtime.reporting.history import history

    row = {"problem": "harmonic", "integrator": "verlet", "status": "ok", "t_final": 1.0, "dt": 0.1, "settings": "",
           "cpu_s": 1e-3, "instructions": 5_000, "instructions_tool": "callgrind 3.19.0"}
    noisy = {**row, "instructions": 5_000 + COUNT_NOISE - 1}  # beyond x1.01, within the noise
    cell = compare([row], [noisy])["cells"][0]
    assert cell["instruction_verdict"] == "within" and cell["instruction_threshold"] == pytest.approx(1.02)
    assert compare([row], [{**row, "instructions": 5_400}])["cells"][0]["instruction_verdict"] == "more"
    big = {**row, "instructions": 1_000_000}
    assert compare([big], [{**big, "instructions": 1_010_100}])["cells"][0]["instruction_verdict"] == "more"
    store = Store(tmp_path / "s.sqlite")
    cell = expand(["harmonic"], ["verlet"], t_final=1.0, sets={"dt": 0.1})[0]
    for count in (5_000, 5_000 + COUNT_NOISE - 1, 5_000, 5_400, 5_401):
        run_id = store.begin_run("run", [cell])
        store.add_row(run_id, cell, {**row, "instructions_per_step": count / 10, "instructions": count})
        store.finish_run(run_id, "done")
    steps = [s for s in history(store)[0]["steps"] if s["field"] == "instructions"]
    assert [s["run_id"] for s in steps] == [4]


def test_compare_judges_counts_of_one_tool_only():
    row = {"problem": "kepler", "integrator": "rk4", "status": "ok", "t_final": T, "dt": 0.01, "settings": "",
           "cpu_s": 1e-3, "instructions": 1_000_000, "instructions_per_step": 200.0,
           "instructions_tool": "callgrind 3.19.0 (znver3 kernels)"}
    other = {**row, "instructions": 1_100_000, "instructions_tool": "callgrind 3.19.0 (haswell kernels)"}
    result = compare([row], [other])
    assert result["cells"][0]["instruction_verdict"] == "other tool" and result["regressed"] == 0
    fewer = compare([row], [{**row, "instructions": 900_000}])
    assert fewer["cells"][0]["instruction_verdict"] == "fewer" and fewer["improved"] == 1
    timed_only = compare([row], [{k: v for k, v in row.items() if not k.startswith("instructions")}])
    assert timed_only["cells"][0]["instruction_verdict"] is None
