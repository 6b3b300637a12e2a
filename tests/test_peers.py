"""The library peers: scipy's solve_ivp family, SUNDIALS' CVODE (scikit-sundae) and diffrax,
checked against heyoka's reference on kepler, with their compile and per-call overhead apart
from the timing, and skipped with the extra to install where their library is missing."""
import sys
from pathlib import Path

import numpy as np
import pytest

from longtime.core import registry
from longtime.core.params import InputError
from longtime.execution.cells import expand
from longtime.integrators import peer_common
from longtime.measure import reference

SCIPY = ["dop853", "scipy-rk23", "scipy-rk45", "scipy-radau", "scipy-bdf", "scipy-lsoda"]
CVODE = ["cvode-adams", "cvode-bdf"]
DIFFRAX = ["diffrax-tsit5", "diffrax-dopri5", "diffrax-dopri8", "diffrax-kvaerno5", "diffrax-reversible-heun"]
has_sundials = peer_common.installed("sksundae")
has_diffrax = peer_common.installed("jax", "diffrax")
needs_sundials = pytest.mark.skipif(not has_sundials, reason='needs pip install "longtime[sundials]"')
needs_diffrax = pytest.mark.skipif(not has_diffrax, reason='needs pip install "longtime[diffrax]"')
TOL = 1e-8
# kepler's pericentre passage (e = 0.6), where the steps are shortest: over a whole period the
# global error of every 5th-order pair, our rk45 included, is 100 to 900 times the tolerance
SPAN = 1.0


def test_the_peers_are_registered_by_library():
    found = registry.integrators()
    for names, library in ((SCIPY, "scipy"), (CVODE, "sundials"), (DIFFRAX + ["diffrax-semi-implicit-euler"],
                                                                      "diffrax")):
        for name in names:
            assert found[name].library == library and found[name].kind == "external", name
    assert found["rk45"].library == "longtime" and found["heyoka"].library == "heyoka"


def test_longtime_list_shows_the_six_scipy_methods(capsys):
    import json

    from longtime.commands.cli import main

    assert main(["list", "--format", "json"]) == 0
    listed = {s["name"]: s for s in json.loads(capsys.readouterr().out)["integrators"]}
    assert set(SCIPY) <= set(listed) and all(listed[n]["kind"] == "external" for n in SCIPY)
    # the other peers are listed too; without their extras their rows are skipped (below)
    assert set(CVODE + DIFFRAX) <= set(listed) and listed["diffrax-tsit5"]["requires"] == ["jax_rhs"]


@pytest.fixture(scope="module")
def kepler():
    return registry.problem_class("kepler")()


@pytest.fixture(scope="module")
def heyoka_kepler(kepler):
    """heyoka's states on kepler at the given times."""
    def at(times):
        return reference.propagate(kepler, np.asarray(times), "double")[0]
    return at


def _error_against_heyoka(name, kepler, heyoka_kepler, t_final=SPAN):
    traj = registry.integrator_class(name)(tol=TOL).integrate(kepler, t_final, max_samples=2001)
    assert traj.status == "ok", traj.message
    ref = heyoka_kepler(traj.t)
    return np.max(np.linalg.norm(traj.u - ref, axis=1) / np.linalg.norm(ref, axis=1)), traj


@pytest.mark.parametrize("name", SCIPY)
def test_scipy_against_heyoka_on_kepler(name, kepler, heyoka_kepler):
    error, traj = _error_against_heyoka(name, kepler, heyoka_kepler)
    assert error < 100 * TOL, f"{name}: {error:.3g}"
    assert traj.steps > 5 and traj.counters["rhs_evals"] >= traj.steps
    overhead = traj.extra["peer_overhead_s"]
    # the library's own cost of a step on u' = 0: positive, and less than a step with the work
    assert 0 < overhead < 50 * traj.cpu_s / traj.steps


def test_dop853_counts_hairers_steps_and_its_rejections(kepler, heyoka_kepler):
    error, traj = _error_against_heyoka("dop853", kepler, heyoka_kepler, t_final=10.0)
    assert error < 1e-6, error  # tol 1e-8 over one and a half periods at e = 0.6
    c = traj.counters
    assert c["rejected"] > 0  # the pericentre passages reject steps, and they are counted
    # Hairer's NFCN: 11 stages a step tried, one more (the next step's first) after an accepted
    # one, the first step's first stage and the initial step's guess
    assert c["rhs_evals"] == 12 * traj.steps + 11 * c["rejected"] + 2, c
    assert c["rhs_evals"] >= 12 * traj.steps


def test_dop853_failures_are_failed_rows_with_hairers_reason(monkeypatch, kepler):
    from longtime.integrators.scipy_ivp import DOP853

    monkeypatch.setattr(DOP853, "NSTEPS", 50)
    traj = DOP853(tol=1e-10).integrate(kepler, 10.0)
    assert traj.status == "failed" and "larger nsteps is needed" in traj.message
    assert 0 < traj.steps <= 50 and traj.t[-1] < 10.0
    monkeypatch.undo()

    import numba

    @numba.njit
    def nan_past_one(t, u, params, out):  # kepler's rhs, NaN from t = 1 on
        r3 = (u[0] * u[0] + u[1] * u[1]) ** 1.5
        out[0], out[1], out[2], out[3] = u[2], u[3], -u[0] / r3, -u[1] / r3
        if t > 1.0:
            out[:] = np.nan

    problem = registry.problem_class("kepler")()
    problem.rhs = nan_past_one
    traj = DOP853(tol=1e-8).integrate(problem, 10.0)
    assert traj.status == "failed" and "step size becomes too small" in traj.message
    assert 0.9 < traj.t[-1] <= 1.0 and np.all(np.isfinite(traj.u))

    @numba.njit
    def raises_past_one(t, u, params, out):
        if t > 1.0:
            raise ZeroDivisionError("at the centre")
        out[0], out[1], out[2], out[3] = u[2], u[3], -u[0], -u[1]

    problem.rhs = raises_past_one
    traj = DOP853(tol=1e-8).integrate(problem, 10.0)  # scipy's dop853 alone would never return
    assert traj.status == "failed" and "the rhs raised ZeroDivisionError('at the centre')" in traj.message
    assert 0.9 < traj.t[-1] <= 1.0


@needs_sundials
@pytest.mark.parametrize("name", CVODE)
def test_cvode_against_heyoka_on_kepler(name, kepler, heyoka_kepler):
    error, traj = _error_against_heyoka(name, kepler, heyoka_kepler)
    assert error < 100 * TOL, f"{name}: {error:.3g}"
    assert traj.steps > 5 and 0 < traj.extra["peer_overhead_s"]


@needs_diffrax
@pytest.mark.parametrize("name", [n if n == "diffrax-tsit5" else pytest.param(n, marks=pytest.mark.slow)
                                  for n in DIFFRAX])  # each compiles jax code first: slow
def test_diffrax_against_heyoka_on_kepler(name, kepler, heyoka_kepler):
    error, traj = _error_against_heyoka(name, kepler, heyoka_kepler)
    assert error < 100 * TOL, f"{name}: {error:.3g}"
    assert traj.steps > 5 and 0 < traj.extra["peer_overhead_s"]


@needs_diffrax
def test_diffrax_semi_implicit_euler_is_symplectic_euler(kepler):
    # the same steps as our symplectic Euler B (q first from p_n, then p from q_{n+1}) at the
    # same dt: the same final state up to the order in which the sums round
    dt = 1e-3
    ours = registry.integrator_class("symplectic-euler-b")(dt=dt).integrate(kepler, 1.0, max_samples=11)
    theirs = registry.integrator_class("diffrax-semi-implicit-euler")(dt=dt).integrate(kepler, 1.0, max_samples=11)
    assert theirs.status == "ok" and theirs.steps == 1000
    assert np.max(np.abs(theirs.u[-1] - ours.u[-1])) < 1e-10


@needs_diffrax
def test_diffrax_compile_time_is_reported_apart_from_cpu_s():
    from longtime.integrators import diffrax_ode

    jax = diffrax_ode._jax()
    problem = registry.problem_class("henon-heiles")()
    scheme = registry.integrator_class("diffrax-tsit5")(tol=1e-7)
    diffrax_ode._COMPILED.clear()
    jax.config.update("jax_enable_compilation_cache", False)  # a true compile, not a load
    try:
        first = scheme.integrate(problem, 10.0)  # compiles
    finally:
        jax.config.update("jax_enable_compilation_cache", True)
    again = scheme.integrate(problem, 10.0)  # reuses the compiled solve
    compile_s = first.extra["compile_s"]
    assert compile_s > 0.05  # XLA compiles a diffeqsolve in about a second
    assert first.cpu_s < compile_s / 5, (first.cpu_s, compile_s)
    # the run that compiled costs what the run that did not costs: the compile is not in it
    assert first.cpu_s < 3 * again.cpu_s + 0.01, (first.cpu_s, again.cpu_s)
    assert again.extra["compile_s"] == compile_s and np.array_equal(first.u, again.u)


@needs_diffrax
@pytest.mark.parametrize("name", sorted(n for n, c in registry.problems().items() if c.jax_rhs is not None))
def test_jax_rhs_is_the_rhs(name):
    import jax

    jax.config.update("jax_enable_x64", True)
    problem = registry.problem_class(name)()
    rng = np.random.default_rng(5)
    for u in (problem.u0, problem.u0 * (1 + 0.1 * rng.standard_normal(problem.dim))):
        out = np.empty(problem.dim)
        problem.rhs(0.7, u, problem.params, out)
        given = np.asarray(problem.jax_rhs(0.7, jax.numpy.asarray(u), jax.numpy.asarray(problem.params)))
        assert np.allclose(given, out, rtol=1e-12, atol=1e-12 * np.max(np.abs(out))), name


def test_a_problem_without_jax_rhs_is_skipped_for_diffrax():
    (cell,) = expand(["kdv"], ["diffrax-tsit5"], sets={"tol": 1e-6}, t_final=1.0)
    assert cell.skip_reason == "diffrax-tsit5 needs jax_rhs, which kdv does not provide"


@pytest.mark.parametrize("names, hidden, extra", [
    (CVODE, ["sksundae"], "sundials"),
    (DIFFRAX, ["diffrax"], "diffrax"),
    (DIFFRAX, ["jax"], "diffrax"),
])
def test_without_the_extra_the_rows_are_skipped_naming_it(monkeypatch, names, hidden, extra):
    for module in list(sys.modules):
        if module.split(".")[0] in hidden:
            monkeypatch.delitem(sys.modules, module)
    for module in hidden:
        monkeypatch.setitem(sys.modules, module, None)  # import raises ImportError
    cells = expand(["kepler"], names, sets={"tol": 1e-6}, t_final=1.0)
    assert [c.skip_reason for c in cells] == [
        f'{n} needs the package {"scikit-sundae" if extra == "sundials" else "diffrax"}: '
        f'pip install "longtime[{extra}]"' for n in names]
    with pytest.raises(InputError, match=rf'longtime\[{extra}\]'):
        registry.integrator_class(names[0])(tol=1e-6).integrate(registry.problem_class("kepler")(), 1.0)


def test_the_peers_default_sweep_crosses_the_targets_and_is_budgeted():
    from longtime.execution import budget

    for name in SCIPY[1:] + CVODE + DIFFRAX:
        cls = registry.integrator_class(name)
        # the table's 1e-6 and the report's 1e-10 at T need tolerances down to about 1e-13
        assert min(cls.sweep["tol"]) <= 1e-13 and max(cls.sweep["tol"]) >= 1e-7
        assert cls.cell_budget_s < budget.CELL_BUDGET_S
    assert registry.integrator_class("dop853").cell_budget_s is None  # the matrix's per-cell budget applies to it
    assert budget.cell_budget("scipy-radau") == registry.integrator_class("scipy-radau").cell_budget_s
    assert budget.cell_budget("rk4") == budget.CELL_BUDGET_S


def test_a_peer_over_its_budget_runs_fewer_settings_never_a_shorter_horizon():
    from longtime.execution import budget

    full = expand(["toda", "outer-solar-system", "fpu"], ["scipy-rk23", "scipy-rk45", "cvode-adams", "dop853"],
                  default_sweep=True)
    cells, moves = budget.fit(full)
    ran = [c for c in cells if not c.skip_reason]
    mains = {p: registry.problem_class(p).sweep_t_final for p in ("toda", "outer-solar-system", "fpu")}
    assert ran and all(c.t_final == mains[c.problem] for c in ran)  # the horizon every scheme runs
    # every pair keeps at least its cheapest setting, the loosest tolerance
    pairs = {(c.problem, c.integrator) for c in full if not c.skip_reason}
    assert pairs == {(c.problem, c.integrator) for c in ran}
    assert moves and all("left out" in m.setting for m in moves)
    for m in moves:  # what was left out is estimated over the budget, and the cells kept say so
        kept = [c for c in ran if (c.problem, c.integrator) == (m.problem, m.integrator)]
        assert all(budget.NOTE in c.note and m.setting in c.note for c in kept)
    for pair in pairs:
        tols = [c.integrator_settings["tol"] for c in ran if (c.problem, c.integrator) == pair]
        assert max(registry.integrator_class(pair[1]).sweep["tol"]) in tols
    # fpu x scipy-rk23 is estimated at tens of seconds a run to t = 1000 even at its loosest
    # tolerance, past a cell's budget: that one setting runs the horizon under a time limit
    slow = [c for c in ran if c.time_limit == budget.SLOW_LIMIT_S]
    assert [(c.problem, c.integrator, c.integrator_settings) for c in slow if c.integrator == "scipy-rk23"] == [
        ("fpu", "scipy-rk23", {"tol": 1e-7})]
    assert all(budget.TOO_SLOW in c.note and "too slow" in c.limit_reason for c in slow)
    assert all(budget.run_seconds(c) > budget.CELL_BUDGET_S for c in slow)
    # every other cell of a library peer runs under the peers' own limit
    peers = {"scipy-rk23", "scipy-rk45", "cvode-adams"}
    assert all(c.time_limit == budget.PEER_LIMIT_S for c in ran if c.integrator in peers and c not in slow)
    assert all(c.time_limit is None for c in ran if c.integrator not in peers)


def test_a_peer_too_slow_for_the_default_matrix_is_a_timeout_row_which_library_shows():
    import dataclasses

    from longtime.execution import budget
    from longtime.execution.cells import run_cell
    from longtime.reporting.libraries import _cell

    cells, _ = budget.fit(expand(["fpu"], ["scipy-rk23"], default_sweep=True))
    assert len(cells) == 1 and cells[0].time_limit == budget.SLOW_LIMIT_S and cells[0].t_final == 1000.0
    # the same cell under a shorter limit of its own (the test's time): a measured timeout row
    # at the full horizon, saying how far it got and that the budget's limit stopped it
    row = run_cell(dataclasses.replace(cells[0], time_limit=0.5), reference=False)
    assert row["status"] == "timeout" and row["t_final"] == 1000.0 and 0.0 < row["t_reached"] < 1000.0
    assert "0.5 s: the default matrix's time limit" in row["message"] and budget.TOO_SLOW in row["message"]
    text, cpu = _cell([row], 1000.0, 1e-6, None)
    assert cpu is None and text.startswith("too slow: scipy-rk23 tol=1e-07 ran ") and " of 1000" in text
    # on a loaded machine the wall seconds the limit counts are said beside the CPU seconds
    text, _ = _cell([{**row, "cpu_s": 2.5, "wall_s": 15.0}], 1000.0, 1e-6, None)
    assert "ran 2.5 s CPU in 15 s wall for t=" in text


def test_a_pace_projects_the_end_from_the_cpu_seconds_per_unit_of_t(monkeypatch):
    clock = [100.0]
    monkeypatch.setattr(peer_common.time, "process_time", lambda: clock[0])
    pace = peer_common.Pace(20.0, 10.0, 1010.0)
    clock[0] += 0.9  # before its first CPU second a run is never judged, however slow
    assert not pace.beyond(10.001) and pace.projected is None
    clock[0] += 0.1  # 1 s for 50 of 1000: 20 s to t_end, not past the bound
    assert not pace.beyond(60.0) and pace.projected == pytest.approx(20.0) and not pace.stopped
    clock[0] += 1.0  # 2 s for 80 of 1000: 25 s
    assert pace.beyond(90.0) and pace.stopped and pace.projected == pytest.approx(25.0)
    assert pace.message(90.0, 2.0).startswith("stopped on its pace: t=90 of 1010 reached in 2 s CPU")
    assert "about 25 s CPU, past 20 s" in pace.message(90.0, 2.0)
    clock[0] += 1.0  # no progress at all: an end never reached
    assert pace.beyond(10.0) and pace.projected == float("inf")
    early = peer_common.Pace(20.0, 10.0, 1010.0, after_s=0.25)  # judged from a quarter second
    clock[0] += 0.25  # 0.25 s for 10 of 1000: 25 s
    assert early.beyond(20.0) and early.projected == pytest.approx(25.0)
    assert "no progress past t0, which puts t_final beyond any CPU time, past 20 s" in pace.message(10.0, 4.0)
    # its row keeps no infinite projection: pace_cpu_s is null, the message says why
    problem = registry.problem_class("harmonic")()
    traj = peer_common.trajectory(problem, "scipy", np.array([0.0, 1e-9]), np.tile(problem.u0, (2, 1)), 4.0, 4.0,
                                  {}, 100, timed_out=True, pace=pace)
    assert traj.status == "timeout" and traj.message.startswith("stopped on its pace:")
    assert traj.extra["pace_cpu_s"] is None


def test_a_too_slow_peer_stops_on_its_pace_and_which_library_says_where_its_pace_put_its_end():
    import dataclasses

    from longtime.core.status import PACED, bounded
    from longtime.execution import budget
    from longtime.execution.cells import run_cell
    from longtime.integrators.peer_common import PACE_AFTER_S
    from longtime.reporting.libraries import _cell

    cells, _ = budget.fit(expand(["fpu"], ["scipy-rk23"], default_sweep=True))
    assert cells[0].pace == budget.PACE_FACTOR and cells[0].time_limit == budget.SLOW_LIMIT_S
    # a pace bound of 0.1 x a 60 s limit: RK23's pace at tol=1e-7 puts t = 1000 at tens of CPU
    # seconds, so the run stops at its first look past PACE_AFTER_S, long before the wall limit
    row = run_cell(dataclasses.replace(cells[0], time_limit=60.0, pace=0.1), reference=False)
    assert row["status"] == "timeout" and row["message"].startswith(PACED) and not bounded(row)
    assert row["cpu_s"] >= PACE_AFTER_S and row["pace_cpu_s"] > 6.0 and 0.0 < row["t_reached"] < 1000.0
    assert "past 6 s (0.1 x the cell's time limit of 60 s for a setting estimated too slow)" in row["message"]
    assert abs(row["pace_cpu_s"] / (row["cpu_s"] * 1000.0 / row["t_reached"]) - 1.0) < 0.05
    text, cpu = _cell([row], 1000.0, 1e-6, None)
    assert cpu is None and text.startswith("too slow: scipy-rk23 tol=1e-07 ran ")
    assert " of 1000 (about " in text and " s to T at its pace)" in text
    # a run whose pace keeps its end within the bound runs to it
    short = run_cell(dataclasses.replace(cells[0], t_final=20.0, time_limit=60.0, pace=0.1), reference=False)
    assert short["status"] == "ok" and short.get("pace_cpu_s") is None


def test_a_peer_too_slow_whose_run_cannot_be_stopped_is_skipped_with_the_estimate():
    from longtime.execution import budget
    from longtime.execution.cells import base_row
    from longtime.reporting.libraries import _cell

    cells, _ = budget.fit(expand(["fpu"], ["diffrax-reversible-heun"], default_sweep=True))
    assert not registry.integrator_class("diffrax-reversible-heun").stops_at_deadline
    if not has_diffrax:
        return
    assert len(cells) == 3 and all(c.skip_reason.startswith(budget.TOO_SLOW) for c in cells)
    rows = [{**base_row(c), "status": "skipped", "message": c.skip_reason} for c in cells]
    text, cpu = _cell(rows, 1000.0, 1e-6, None)
    assert cpu is None and text.startswith("too slow: about ") and "estimated for t_final 1000" in text


def test_every_peer_row_of_a_default_matrix_slice_runs_the_full_horizon():
    from longtime.commands.cli import build_parser
    from longtime.commands.matrix import matrix_cells
    from longtime.core.timing import Timing
    from longtime.execution.cells import run_cell

    schemes = ["dop853", "scipy-rk45"] + (["cvode-adams"] if has_sundials else [])
    cells, _ = matrix_cells(build_parser().parse_args(["matrix", "-p", "linear-test", "-i", ",".join(schemes)]))
    pcls = registry.problem_class("linear-test")
    horizon = pcls.sweep_t_final or pcls.default_t_final
    assert {c.integrator for c in cells} == set(schemes) and all(not c.skip_reason for c in cells)
    for cell in cells:
        row = run_cell(cell, reference=False, timing=Timing(repeats=1))
        assert row["status"] == "ok", (cell, row["message"])
        assert row["t_final"] == horizon and row["t_reached"] == pytest.approx(horizon, rel=1e-12), cell


@needs_sundials
def test_cvode_takes_a_problem_with_many_params():
    # kdv's params are an array of many values: scikit-sundae gets them in a 1-tuple
    problem = registry.problem_class("kdv")(d=32)
    assert problem.params.size > 1
    traj = registry.integrator_class("cvode-bdf")(tol=1e-6).integrate(problem, 0.05)
    assert traj.status == "ok" and traj.steps >= 2, traj.message


@pytest.mark.slow
def test_one_method_of_each_library_runs_ok_on_the_issue_problems(tmp_path):
    import json
    import subprocess

    schemes = ["scipy-rk45", "scipy-radau"] + (["cvode-bdf"] if has_sundials else []) + \
        (["diffrax-tsit5"] if has_diffrax else [])
    # the matrix pairs every scheme with every problem (`run` refuses a pair that does not
    # apply; the matrix stores it `skipped`, with the reason)
    db = tmp_path / "db.sqlite"
    out = subprocess.run([sys.executable, "-m", "longtime", "matrix", "-p", "kepler,toda,henon-heiles,kdv",
                          "-i", ",".join(schemes), "--tol", "1e-6", "--t-final", "0.5", "--db", str(db),
                          "--no-html", "--no-report", "--checks", "0", "--no-ensemble", "--processes", "1",
                          "--no-progress"], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    report = subprocess.run([sys.executable, "-m", "longtime", "report", "--db", str(db), "--format", "json"],
                            capture_output=True, text=True, timeout=120)
    rows = {(r["problem"], r["integrator"]): r for r in json.loads(report.stdout)}
    for (problem, scheme), row in rows.items():
        expected = "skipped" if scheme.startswith("diffrax") and problem == "kdv" else "ok"
        assert row["status"] == expected, (problem, scheme, row["message"])
        if expected == "ok":
            # kdv over t = 0.5 moves little: its error relative to that motion is the larger one
            bound = 0.1 if problem == "kdv" else 1e-3
            assert row["peer_overhead_s"] > 0 and row["l2_error"] < bound, (problem, scheme, row["l2_error"])
    assert len(rows) == 4 * len(schemes)


def _direct_call_case(name):
    marks = [pytest.mark.skipif(not has_sundials, reason='needs pip install "longtime[sundials]"')] \
        if name.startswith("cvode") else []
    if name.startswith("diffrax"):  # two compiles of jax code (the row's and the direct call's): slow
        marks = [pytest.mark.skipif(not has_diffrax, reason='needs pip install "longtime[diffrax]"'), pytest.mark.slow]
    return pytest.param(name, marks=marks)


@pytest.mark.parametrize("name", [_direct_call_case(n) for n in
                                  ("scipy-rk45", "scipy-lsoda", "scipy-radau", "cvode-adams", "cvode-bdf",
                                   "diffrax-tsit5")])
def test_a_peer_gives_what_a_direct_call_of_its_library_gives(name, kepler, heyoka_kepler):
    # the same problem, tolerance and horizon through the library called as its users call it
    # (benchmarks/bench_peers.py's ``direct``; it also compares the CPU, which a test cannot)
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository's benchmarks/
    from benchmarks.bench_peers import SAMPLES, direct

    t_final = 4 * np.pi  # two orbits of kepler, through two pericentre passages
    traj = registry.integrator_class(name)(tol=TOL).integrate(kepler, t_final, max_samples=SAMPLES)
    assert traj.status == "ok" and traj.t[-1] == pytest.approx(t_final), traj.message
    truth = heyoka_kepler(np.array([0.0, t_final]))[-1]
    row = np.linalg.norm(traj.u[-1] - truth) / np.linalg.norm(truth)
    mine = np.linalg.norm(direct(name, kepler, TOL, t_final)() - truth) / np.linalg.norm(truth)
    assert 0.5 <= row / mine <= 2.0, f"{name}: the row's error {row:.3g}, a direct call's {mine:.3g}"


def test_a_peer_s_tolerances_given_on_the_command_line_are_never_left_out():
    from longtime.execution.main_job import Selection, plan
    from longtime.execution.matrix import ExecOptions

    cells, moves = plan(Selection(problems=("fpu",), schemes=("scipy-rk23",), sweeps={"tol": (1e-7, 1e-13)}),
                        ExecOptions())
    assert sorted(c.integrator_settings["tol"] for c in cells) == [1e-13, 1e-7] and not moves



def _nan_harmonic():
    """harmonic whose right-hand side turns NaN at t = 1 (compiled and in jax.numpy)."""
    import numba

    from longtime.problems.harmonic import Harmonic

    @numba.njit
    def nan_rhs(t, u, params, out):
        out[0] = u[1]
        out[1] = -u[0] if t < 1.0 else np.nan

    def nan_jax_rhs(t, u, params):
        import jax.numpy as jnp

        return jnp.where(t < 1.0, Harmonic.jax_rhs(t, u, params), jnp.nan)

    class NanHarmonic(Harmonic):
        name = "nan-harmonic"
        rhs = staticmethod(nan_rhs)
        jax_rhs = staticmethod(nan_jax_rhs)
        grad_T = grad_V = taylor = None

    return NanHarmonic


@needs_sundials
@pytest.mark.parametrize("name", CVODE)
def test_a_right_hand_side_that_turns_nan_fails_cvode_at_its_smallest_step(name):
    """A NaN right-hand side past t = 1: CVODE's step stops at its smallest step (a share of
    the span) with CVODE's own failure, a failed row at t = 1, not a step shrinking without end."""
    import longtime

    row = longtime.sweep(_nan_harmonic(), [name], t_final=10.0, executor="serial", tol=1e-8).iloc[0]
    assert row["status"] == "failed" and "min step size" in row["message"]
    assert row["t_reached"] == pytest.approx(1.0, abs=1e-6)


@needs_diffrax
@pytest.mark.slow  # diffrax compiles its solve (JAX)
def test_a_right_hand_side_that_turns_nan_fails_diffrax_at_its_smallest_step():
    """The same NaN past t = 1 through diffrax: its PID controller's smallest step (a share of
    the span) ends the solve there, a failed row, not MAX_STEPS rejected steps."""
    import longtime

    row = longtime.sweep(_nan_harmonic(), ["diffrax-tsit5"], t_final=10.0, executor="serial", tol=1e-8).iloc[0]
    assert row["status"] == "failed" and "did not succeed" in row["message"]
    assert row["t_reached"] == pytest.approx(1.0, abs=0.01)


def _chain(problem, settings, t_final):
    """The chained cells (``Cell.bound``) of ``settings`` [(scheme, tol)] at ``t_final``."""
    from longtime.execution.cells import Cell
    from longtime.predict.need import FACTOR

    return [Cell(problem, s, {}, {"tol": tol}, t_final, bound=FACTOR) for s, tol in settings]


def test_the_main_jobs_peers_run_as_chains_cheapest_first_and_the_budget_says_so():
    from longtime.execution import budget
    from longtime.execution.batches import batches_by_pair
    from longtime.predict.need import FACTOR

    full = expand(["kepler"], ["dop853", "scipy-rk23", "scipy-rk45", "rk4"], default_sweep=True)
    plain, plain_moves = budget.fit(full)
    assert all(c.bound is None for c in plain) and not any(m.kind == budget.CHAINED for m in plain_moves)
    cells, moves = budget.fit(full, chained=True)
    peers = [c for c in cells if c.integrator != "rk4"]
    assert peers and all(c.bound == FACTOR for c in peers) and all(c.bound is None for c in cells if c not in peers)
    assert [m.integrator for m in moves if m.kind == budget.CHAINED] == ["scipy"]
    assert "1 (problem, library) chain(s) of peers run cheapest first" in budget.summary(moves)
    (chain,) = [b for b in batches_by_pair(cells) if b[0].bound]  # one worker runs scipy's settings on kepler
    assert sorted(map(id, chain)) == sorted(map(id, peers))
    cost = [budget.run_seconds(c) for c in chain]
    assert cost == sorted(cost) and {c.integrator for c in chain} == {"dop853", "scipy-rk23", "scipy-rk45"}


@pytest.mark.slow  # two runs with kepler's reference, and scipy's first imports
@pytest.mark.parametrize("on_pace", [True, False])
def test_a_chain_stops_a_later_setting_at_factor_times_the_cpu_of_one_that_keeps_the_target(on_pace, monkeypatch):
    from longtime.core.status import BOUNDED, bounded
    from longtime.core.timing import Timing
    from longtime.execution import limits
    from longtime.execution.batches import run_batch
    from longtime.execution.cells import RunSpec
    from longtime.predict.need import FACTOR

    if not on_pace:  # a pace never past the bound: the run goes on to the bound itself
        monkeypatch.setattr(limits, "CHAIN_PACE", 1e9)
    # dop853 at 1e-12 keeps 1e-6 on kepler; RK23 at 1e-10 takes tens of times its steps
    keeper, later = run_batch(_chain("kepler", [("dop853", 1e-12), ("scipy-rk23", 1e-10)], 20.0),
                              RunSpec(timing=Timing(repeats=1)))
    assert keeper["status"] == "ok" and keeper["max_error"] <= 1e-6, keeper["message"]
    assert later["status"] == "timeout" and bounded(later) and later["message"].startswith(BOUNDED)
    assert 0.0 < later["t_reached"] < 20.0 and f"t={later['t_reached']:.6g} of 20 reached" in later["message"]
    assert (f"x2 the CPU of scipy dop853 tol=1e-12 ({keeper['cpu_s']:.3g} s), which keeps 1e-06: it cannot be "
            f"scipy's cheapest") in later["message"]
    if not on_pace:
        assert later["cpu_s"] >= FACTOR * keeper["cpu_s"]  # its own CPU seconds reached the bound
        return
    # judged on its pace once it spent the keeper's CPU seconds: its end projected past 4 x the bound
    assert keeper["cpu_s"] <= later["cpu_s"] < FACTOR * keeper["cpu_s"]
    assert later["pace_cpu_s"] > limits.CHAIN_PACE * FACTOR * keeper["cpu_s"]
    assert (f"(on its pace: t={later['t_reached']:.6g} of 20 reached in {later['cpu_s']:.3g} s CPU, which puts "
            f"t_final at about {later['pace_cpu_s']:.3g} s CPU") in later["message"]
    assert later["message"].endswith("4 x the bound)") or "4 x the bound); " in later["message"]


def test_a_chains_pace_is_judged_from_the_keepers_cpu_against_four_times_its_bound():
    import dataclasses

    from longtime.execution import limits

    (cell,) = _chain("kepler", [("scipy-rk45", 1e-10)], 20.0)
    assert limits.pace_bounds(cell) == (None, None, False)  # no keeper yet: no pace
    bounded = dataclasses.replace(cell, cpu_bound=0.5)  # x2 a keeper's 0.25 s
    assert limits.pace_bounds(bounded) == (2.0, 0.25, True)
    slow = dataclasses.replace(cell, pace=4.0, time_limit=5.0)  # a setting estimated too slow
    assert limits.pace_bounds(slow) == (20.0, None, False)
    assert limits.pace_bounds(dataclasses.replace(slow, cpu_bound=0.5)) == (2.0, 0.25, True)  # the tighter
    assert limits.pace_bounds(dataclasses.replace(slow, cpu_bound=10.0)) == (20.0, None, False)


@pytest.mark.parametrize("scheme", ["dop853", "scipy-rk45"])
def test_a_scipy_run_stops_where_its_own_cpu_seconds_reach_its_bound(scheme):
    from longtime.core import registry

    # Hairer's code (a callback per step) and solve_ivp's loop both look at the run's CPU seconds
    problem = registry.problem_class("fpu")()
    integrator = registry.integrator_class(scheme)(tol=1e-10)
    assert integrator.stops_at_cpu_bound
    traj = integrator.integrate(problem, 1000.0, cpu_bound=0.05)
    assert traj.status == "timeout" and traj.cpu_s >= 0.05
    assert problem.t0 < traj.t[-1] < 1000.0


def test_a_row_whose_cpu_did_not_reach_the_bound_is_never_called_stopped():
    import dataclasses

    from longtime.core.status import bounded
    from longtime.execution.cells import run_cell

    # the wall-clock limit stops it long before its (huge) CPU bound: a time limit's timeout
    (cell,) = _chain("fpu", [("scipy-rk23", 1e-10)], 1000.0)
    cell = dataclasses.replace(cell, cpu_bound=1e9, bound_reason="x2 the CPU of nothing", time_limit=0.2)
    row = run_cell(cell, reference=False)
    assert row["status"] == "timeout" and row["cpu_s"] < 1e9 and not bounded(row)
    assert "time limit" in row["message"] and "x2 the CPU of nothing" not in row["message"]


def test_a_chain_whose_first_cells_miss_the_target_runs_every_setting_unbounded():
    from longtime.execution.batches import Chains
    from longtime.execution.cells import base_row

    first, second, third = _chain("kepler", [("dop853", 1e-3), ("dop853", 1e-6), ("scipy-rk45", 1e-10)], 20.0)
    chains = Chains()
    for cell, err in ((first, 1e-2), (second, 2e-6)):  # neither keeps 1e-6
        assert chains.bounded(cell) is cell
        chains.saw(cell, {**base_row(cell), "status": "ok", "cpu_s": 0.01, "max_error": err, "solution_lost": False})
    assert chains.bounded(third) is third and third.cpu_bound is None
    # a kept error with the solution lost, or a timeout, is no keeper either
    chains.saw(second, {**base_row(second), "status": "ok", "cpu_s": 0.01, "max_error": 1e-7, "solution_lost": True})
    chains.saw(second, {**base_row(second), "status": "timeout", "cpu_s": 0.01, "max_error": 1e-7})
    assert chains.bounded(third) is third
    # one that keeps it bounds the later ones, in its chain only (another t_final is another chain)
    chains.saw(second, {**base_row(second), "status": "ok", "cpu_s": 0.25, "max_error": 1e-7, "solution_lost": False})
    assert chains.bounded(third).cpu_bound == 0.5
    assert "x2 the CPU of scipy dop853 tol=1e-06 (0.25 s), which keeps" in chains.bounded(third).bound_reason
    # a cheaper keeper lowers the bound; a scheme named after its library is not named twice
    chains.saw(third, {**base_row(third), "status": "ok", "cpu_s": 0.1, "max_error": 1e-7, "solution_lost": False})
    assert chains.bounded(first).cpu_bound == 0.2
    assert "the CPU of scipy-rk45 tol=1e-10 (0.1 s)" in chains.bounded(first).bound_reason
    (other,) = _chain("kepler", [("scipy-rk45", 1e-10)], 40.0)
    assert chains.bounded(other) is other


def test_which_library_reads_a_row_stopped_at_its_bound_as_no_entry_and_no_failure():
    from longtime.core.status import BOUNDED, Status, bounded
    from longtime.reporting.libraries import library_table
    from longtime.reporting.report import STOPPED, not_ok

    def row(scheme, cpu, err, status="ok", message="", tol=1e-9):
        return {"problem": "kepler", "integrator": scheme, "status": status, "t_final": 10.0, "cpu_s": cpu,
                "max_error": err, "solution_lost": False, "tol": tol, "wall_s": cpu, "id": 1, "t_reached": 10.0,
                "message": message}

    stopped = row("scipy-rk23", 0.4, 1e-3, Status.TIMEOUT, f"{BOUNDED} x2 the CPU of scipy dop853 tol=1e-09 "
                                                          f"(0.2 s), which keeps 1e-06: it cannot be scipy's cheapest")
    stopped["t_reached"] = 4.0
    slow = row("scipy-radau", 5.0, 1e-3, Status.TIMEOUT, "stopped at t=1: past the cell's time limit")
    rows = [row("dop853", 0.2, 1e-7), stopped, row("rk4", 0.1, 1e-8)]
    header, (kepler,) = library_table(rows)
    assert dict(zip(header, kepler))["scipy"] == "dop853 tol=1e-09: 0.2 s (1e-07) x2"
    assert bounded(stopped) and not bounded(slow)
    # a time limit's timeout beside it is still said too slow where nothing keeps the target
    header, (kepler,) = library_table([row("dop853", 0.2, 1e-3), stopped, slow])
    assert "too slow: scipy-radau" in dict(zip(header, kepler))["scipy"]
    folded = not_ok(rows + [slow])
    assert folded[STOPPED] == ["scipy-rk23 (1 of 1)"] and folded["timeout"] == ["scipy-radau (1 of 1)"]
