"""What a scheme author passes in is checked before any cell runs, with the command line's
rule and wording (longtime.core.params): an InputError naming the argument, what it got and
what is allowed; what a scheme returns is checked before it is measured (a row that is not
ok); a script without a main guard runs its sweep serially, without a traceback."""
import math
import os
import subprocess
import sys
import textwrap

import numba
import numpy as np
import pytest

import longtime
from longtime import InputError, Integrator, Param, Problem, Trajectory
from longtime.testing import assert_order


@pytest.mark.parametrize("call, words", [
    (lambda: longtime.sweep("kepler", "verlet", dt=["0.1"]), ["dt='0.1' is not valid", "float > 0"]),
    (lambda: longtime.sweep("kepler", "verlet", dt=True), ["dt=True is not valid"]),
    (lambda: longtime.sweep("kepler", "verlet", dt=0.1, jobs=-3), ["jobs=-3 is not valid", "integer >= 0"]),
    (lambda: longtime.sweep("kepler", "verlet", dt=0.1, max_samples=2.5), ["max_samples=2.5", "integer >= 2"]),
    (lambda: longtime.solve("kepler", "verlet", dt=0.1, max_samples=2.5), ["max_samples=2.5", "integer >= 2"]),
    (lambda: longtime.sweep("kepler", "verlet", dt=[]), ["dt=[] is not valid", "non-empty list"]),
    (lambda: longtime.sweep([], "verlet", dt=0.1), ["problems=[] is not valid"]),
    (lambda: longtime.sweep("kepler", [], dt=0.1), ["schemes=[] is not valid"]),
    (lambda: longtime.sweep("kepler", "verlet", dt=0.1, time_limit=float("nan")), ["time_limit=nan", "finite"]),
    (lambda: longtime.sweep("kepler", "verlet", dt=0.1, time_limit=-5), ["time_limit=-5", ">= 0"]),
    (lambda: longtime.sweep("kepler", "verlet", dt=0.1, time_limit="10"), ["time_limit='10'", "finite number"]),
    (lambda: longtime.solve("kepler", "verlet", dt=0.1, t_final="2"), ["t_final='2' is not valid", "finite number"]),
    (lambda: longtime.solve("kepler", "verlet", dt=0.1, memory_limit=-1), ["memory_limit=-1"]),
    (lambda: longtime.solve("kepler", "verlet", dt=0.1, repeats=0), ["repeats=0", "integer >= 1"]),
    (lambda: longtime.sweep("kepler", "verlet", dt=0.1, executor="threads"), ["executor 'threads'", "serial"]),
    (lambda: longtime.convergence([{"a": 1}]), ["convergence: rows[0] is not a row of longtime.sweep",
                                                "lacks problem, integrator, status"]),
    (lambda: longtime.convergence("kepler"), ["convergence: rows=str is not valid"]),
    (lambda: assert_order("verlet", "kepler", float("nan")), ["order=nan is not valid", "> 0"]),
    (lambda: assert_order("verlet", "kepler", "2"), ["order='2' is not valid"]),
    (lambda: longtime.sweep("kepler", "verlet", dt=0.1, progress="yes"), ["progress='yes' is not valid"]),
    (lambda: longtime.main_job(progress=None), ["progress=None is not valid"]),
], ids=lambda x: "" if callable(x) else x[0][:30])
def test_bad_arguments_are_input_errors_naming_them(call, words):
    with pytest.raises(InputError) as info:
        call()
    for w in words:
        assert w in str(info.value)


def test_unknown_keyword_has_api_wording_every_parameter_and_a_did_you_mean():
    with pytest.raises(InputError) as info:
        longtime.sweep("kepler", "verlet", dtt=[0.1, 0.05])
    msg = str(info.value)
    assert msg.startswith("sweep: keyword dtt: unknown parameter (did you mean dt?)")
    assert "their parameters: compensated, dt, e" in msg and "--set" not in msg
    with pytest.raises(InputError, match=r"^solve: keyword ee: unknown parameter \(did you mean e\?\)"):
        longtime.solve("kepler", "verlet", dt=0.1, ee=0.5)


# ------------------------------------------------------------------ problems of a plugin
@numba.njit
def _rhs2(t, u, params, out):  # a 2-dimensional oscillator: writes out[0], out[1] only
    out[0] = u[1]
    out[1] = -u[0]


@numba.njit
def _rhs_oob(t, u, params, out):  # writes past its output
    for i in range(u.size + 1):
        out[i] = -u[i % u.size]


@numba.njit
def _rhs_nan(t, u, params, out):
    out[0] = u[1]
    out[1] = -math.sqrt(u[0])  # NaN once q < 0


class Osc(Problem):
    name = "input-osc"
    summary = "q' = p, p' = -q"
    parameters = {"n": Param(2, "size of the state", int, positive=True)}
    default_t_final = 10.0
    default_dt = 0.1
    rhs = staticmethod(_rhs2)

    def initial_state(self):
        return np.r_[1.0, np.zeros(self.settings["n"] - 1)]

    def invariants(self, t, U):
        return {"H": 0.5 * (U[:, 0] ** 2 + U[:, 1] ** 2)}


class BadExact(Osc):
    name = "input-bad-exact"

    def exact(self, t):
        return np.cos(np.asarray(t) - self.t0)[:, None]  # (n, 1) for a 2-dimensional state


class TransposedExact(Osc):
    name = "input-transposed-exact"

    def exact(self, t):
        s = np.asarray(t) - self.t0
        return np.vstack([np.cos(s), -np.sin(s)])  # (2, n) instead of (n, 2)


class WrongExact(Osc):
    name = "input-wrong-exact"

    def exact(self, t):
        s = np.asarray(t) - self.t0
        return np.column_stack([np.sin(s), np.cos(s)])  # the right shape, not the initial state


class BadInvariant(Osc):
    name = "input-bad-invariant"

    def invariants(self, t, U):
        return {"H": np.ones((len(t), 2, 2))}


class NoHorizon(Osc):
    name = "input-no-horizon"
    default_t_final = None


class Oob(Osc):
    name = "input-oob"
    rhs = staticmethod(_rhs_oob)


class Sqrt(Osc):
    name = "input-sqrt"
    rhs = staticmethod(_rhs_nan)


def test_a_state_of_the_wrong_size_is_found_before_any_cell_runs():
    with pytest.raises(InputError, match=r"problem input-osc: its rhs returns NaN \(or leaves unwritten\) "
                                         r"components \[2\] of 3"):
        longtime.sweep(Osc(n=3), "rk4", dt=0.1, executor="serial")
    assert longtime.solve(Osc, "rk4", dt=0.1).status == "ok"


def test_shapes_of_exact_and_invariants():
    with pytest.raises(InputError, match=r"problem input-bad-exact: exact\(t\) for 3 times returned shape \(3, 1\); "
                                         r"expected \(3, 2\)"):
        longtime.solve(BadExact, "rk4", dt=0.1)
    with pytest.raises(InputError, match=r"invariants\(t, U\)\['H'\] for 2 samples returned shape \(2, 2, 2\)"):
        longtime.solve(BadInvariant, "rk4", dt=0.1)


def test_a_transposed_exact_is_told_from_wrong_values():
    with pytest.raises(InputError, match=r"problem input-transposed-exact: exact\(t\) for 3 times returned shape "
                                         r"\(2, 3\): transposed; expected \(3, 2\)"):
        longtime.solve(TransposedExact, "rk4", dt=0.1)
    with pytest.raises(InputError,
                       match=r"problem input-wrong-exact: exact\(t0\) = .* is not the initial state") as info:
        longtime.solve(WrongExact, "rk4", dt=0.1)
    assert "transposed" not in str(info.value)


def test_a_problem_without_default_t_final_needs_t_final():
    with pytest.raises(InputError, match="t_final=None is not valid: problem input-no-horizon has no default_t_final"):
        longtime.solve(NoHorizon, "rk4", dt=0.1)
    assert longtime.solve(NoHorizon, "rk4", dt=0.1, t_final=1).status == "ok"


def test_an_out_of_range_write_names_the_plugin():
    with pytest.raises(InputError, match=r"problem input-oob: its rhs indexes outside its arrays .*boundscheck"):
        longtime.solve(Oob, "rk4", dt=0.1)


def test_a_rhs_that_returns_nan_is_named():
    r = longtime.solve(Sqrt, "rk4", dt=0.1)
    assert r.status == "diverged"
    assert "the rhs of input-sqrt returns NaN near t=" in r.row["message"]


# ------------------------------------------------------------------ a plugin's own step kernel
class OobStep(longtime.FixedStepIntegrator):
    name = "input-oob-step"
    summary = "Euler that writes past the state"
    order = 1

    def work_shape(self, problem):
        return (1, problem.dim)

    def make_step(self, problem):
        rhs = problem.rhs

        @numba.njit
        def step(t, u, h, params, work, counters, first):
            rhs(t, u, params, work[0])
            for m in range(u.size + 1):
                u[m] += h * work[0, m]
            return 0

        return step


def test_a_step_that_writes_past_its_array_is_a_failed_row_naming_the_scheme():
    r = longtime.solve("harmonic", OobStep, dt=0.1, t_final=1)
    assert r.status == "failed"
    assert r.row["message"].startswith("scheme input-oob-step: its step indexes outside its arrays")


# ------------------------------------------------------------------ an external scheme's samples
class Liar(Integrator):
    name = "input-liar"
    summary = "returns the exact solution, as told to break it"
    kind = "external"
    order = 2
    parameters = {"lie": Param("none", "how", str, choices=("none", "half", "nan", "backwards", "cpu", "shape"))}

    def _integrate(self, problem, t_final, max_samples):
        lie = self.settings["lie"]
        t = np.linspace(problem.t0, t_final / 2 if lie == "half" else t_final, 11)
        u = problem.exact(t)
        if lie == "nan":
            u = np.full_like(u, np.nan)
        if lie == "backwards":
            t[5], t[6] = t[6], t[5]
        if lie == "shape":
            u = u[:, :1]
        return Trajectory("ok", "", t, u, float("nan") if lie == "cpu" else 0.01, 0.01,
                          counters={"steps": 10, "rhs_evals": 10})


@pytest.mark.parametrize("lie, words", [
    ("half", "says ok but its samples end at t=10, before t_final=20"),
    ("nan", "says ok but its state is not finite from t=0 on"),
    ("backwards", "sample times that do not increase: t[5]=12"),
    ("cpu", "returned cpu_s=nan: a time must be finite"),
    ("shape", "returned samples of shapes t (11,), u (11, 1); expected t (n,) and u (n, 2)"),
])
def test_an_external_scheme_is_not_believed_whatever_it_returns(lie, words):
    r = longtime.solve("harmonic", Liar(lie=lie), t_final=20)
    assert r.status == "failed" and words in r.row["message"], r.row["message"]
    assert longtime.solve("harmonic", Liar, t_final=20).status == "ok"
    with pytest.raises(AssertionError, match="status failed"):
        longtime.testing.assert_bounded(Liar(lie="half"), "harmonic", "H", 1.0, t_final=20)


# ------------------------------------------------------------------ memory, scripts
def test_solve_and_sweep_take_the_memory_limit(tmp_path):
    script = tmp_path / "hog.py"
    script.write_text(textwrap.dedent('''
        import resource
        import numpy as np
        import longtime
        from longtime import Integrator, Trajectory

        class Hog(Integrator):
            name = "input-hog"
            summary = "asks for 4 GiB"
            kind = "external"

            def _integrate(self, problem, t_final, max_samples):
                np.empty(2**29)  # 4 GiB, never touched
                t = np.array([problem.t0, t_final])
                return Trajectory("ok", "", t, problem.exact(t), 0.0, 0.0, counters={"steps": 1})

        if __name__ == "__main__":
            before = resource.getrlimit(resource.RLIMIT_DATA)
            r = longtime.solve("harmonic", Hog, t_final=1, memory_limit=2)
            print(r.status, "|", r.row["message"])
            assert resource.getrlimit(resource.RLIMIT_DATA) == before  # the session keeps its own limit
            rows = longtime.sweep("harmonic", Hog, t_final=1, memory_limit=2, executor="serial")
            print(rows["status"][0], "|", rows["message"][0])
            rows = longtime.sweep("harmonic", Hog, t_final=1, memory_limit="10%", jobs=1)
            print(rows["status"][0], "|", rows["message"][0])
    '''))
    res = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert res.returncode == 0, res.stderr[-3000:]
    lines = res.stdout.splitlines()
    assert len(lines) == 3 and all(line.startswith("failed | memory limit: the cell may use") for line in lines), lines


@pytest.mark.slow
def test_a_script_without_main_guard_runs_its_sweep(tmp_path):
    """The process executor's workers never run the script again: an unguarded script runs
    its sweep on them once, and nothing is said; a local Dask cluster's spawned workers would
    run it again, so there the cells run serially, said in one line."""
    script = tmp_path / "noguard.py"
    script.write_text(textwrap.dedent('''
        import longtime
        from longtime.integrators import Splitting, compose

        class ScriptVerlet(Splitting):
            order = 2
            kicks, drifts = compose([1.0])

        rows = longtime.sweep("harmonic", ["rk4", ScriptVerlet], dt=[0.1, 0.05], t_final=5, jobs=2)
        print("rows", len(rows), sorted(set(rows["status"])))
    '''))
    env = {**os.environ, "MPLBACKEND": "Agg"}
    res = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=600, cwd=tmp_path,
                         env=env)
    assert res.returncode == 0, res.stderr[-3000:]
    assert res.stdout.strip() == "rows 4 ['ok']"  # once: no worker ran the script again
    assert "Traceback" not in res.stderr and "serially" not in res.stderr, res.stderr[-3000:]
    script.write_text(script.read_text().replace("jobs=2)", "jobs=2, executor='dask')"))
    res = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=600, cwd=tmp_path,
                         env=env)
    assert res.returncode == 0, res.stderr[-3000:]
    assert res.stdout.strip() == "rows 4 ['ok']"
    assert "Traceback" not in res.stderr and "bootstrapping" not in res.stderr
    said = [line for line in res.stderr.splitlines() if line.startswith("longtime.sweep: running the cells serially")]
    # line 9: the dedented script opens with a blank line
    assert len(said) == 1 and "outside `if __name__ == \"__main__\":` (line 9)" in said[0]


class OobAdaptive(longtime.AdaptiveIntegrator):
    name = "input-oob-adaptive"
    summary = "Euler at a fixed h, as an adaptive scheme, that writes past its output"
    order = 1

    def make_try_step(self, problem):
        rhs = problem.rhs

        @numba.njit
        def try_step(t, u, h, params, work, counters, u_new):
            rhs(t, u, params, work[0])
            for m in range(u.size + 1):
                u_new[m] = u[m] + h * work[0, m]
            return 0, h, h

        return try_step


def test_an_adaptive_try_step_that_writes_past_its_array_is_a_failed_row_naming_the_scheme():
    r = longtime.solve("harmonic", OobAdaptive, t_final=1)
    assert r.status == "failed"
    assert r.row["message"].startswith("scheme input-oob-adaptive: its try_step indexes outside its arrays")


def test_schemes_all_is_every_scheme_that_applies():
    """``schemes="all"``: every registered scheme on the problems it can treat, a pair it
    cannot treat left out (not a skipped row); a swept keyword reaches the schemes that take it."""
    from longtime.api import cells_for
    from longtime.core import registry

    cells = cells_for(["kepler"], "all", t_final=1.0)
    names = {c.integrator for c in cells}
    assert not any(c.skip_reason for c in cells)
    assert {"verlet", "rk4", "gauss4", "heyoka"} <= names and "boris" not in names  # boris needs lorentz
    assert names <= set(registry.integrators())
    swept = cells_for(["harmonic"], "all", t_final=1.0, settings={"dt": [0.1, 0.05]})
    assert {c.integrator_settings.get("dt") for c in swept if c.integrator == "verlet"} == {0.1, 0.05}


def test_sweep_shows_its_progress_on_stderr_unless_told_not_to(capsys):
    """A sweep from Python says on stderr what it runs, as `longtime run` does (lines where
    stderr is no terminal); ``progress=False`` says nothing; stdout stays empty."""
    small = dict(executor="serial", dt=[0.02, 0.01], t_final=2.0, processes=1)
    assert len(longtime.sweep("kepler", "verlet", **small)) == 2
    out = capsys.readouterr()
    assert "longtime: cells: started, 0 of 2 cells" in out.err and "cells: done (2 cells" in out.err
    assert out.out == ""
    assert len(longtime.sweep("kepler", "verlet", progress=False, **small)) == 2
    assert capsys.readouterr().err == ""
