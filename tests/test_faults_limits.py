"""Fault injection, continued: hard time and memory limits of a cell, stdout that carries only
the contract, bad input refused up front, names that are identifiers. Each test's docstring
says the fault it guards against. Plugins are pip-installed as tests/_plugins.py describes."""
import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from _permissions import unprivileged
from _plugins import HEUN_SOURCE, install_plugin, longtime

from longtime.commands.cli import main

PLUGINS = '''
import os
import time

import numba
import numpy as np

from longtime.integrators.explicit_rk import ExplicitRungeKutta
from longtime.problems.harmonic import Harmonic


''' + HEUN_SOURCE + '''

def _entered():
    with open(os.environ["SPIN_FILE"] + ".step", "a") as f:
        f.write(f"{os.getpid()}\\n")


@numba.njit
def _spin(t, u, h, params, work, counters, first):
    with numba.objmode():
        _entered()  # the step has started: from here on it runs compiled, for ever
    x = 1.0
    while x > 0.0:  # never ends: compiled code that never returns to Python
        x = x * 1.0000001 + 1.0
        u[0] = x
    return 0


class Spin(_Heun):
    summary = "a compiled step that never returns"

    def make_step(self, problem):
        with open(os.environ["SPIN_FILE"], "a") as f:
            f.write(f"{os.getpid()}\\n")
        return _spin


class Sleep(_Heun):
    summary = "a plugin's Python that never returns"

    def _integrate(self, *args, **kwargs):
        while True:
            time.sleep(0.05)


@numba.njit
def _talk(t, u, h, params, work, counters, first):
    print("numba print from a step")
    return 0


class Talk(_Heun):
    summary = "prints from Python, to fd 1, and from a compiled step"

    def make_step(self, problem):
        return _talk

    def _integrate(self, *args, **kwargs):
        print("python print from a plugin")
        os.write(1, b"fd 1 write, as compiled printf does\\n")
        return super()._integrate(*args, **kwargs)


class Hog(_Heun):
    summary = "allocates 3 GiB"

    def _integrate(self, *args, **kwargs):
        block = np.ones(3 * 2**30 // 8)
        return block.sum()


class Named(_Heun):
    summary = "a scheme whose entry-point name breaks the rule"


class DollarInvariant(Harmonic):
    name = "plug-dollar-invariant"
    summary = "harmonic oscillator whose invariant is named in mathtext"

    def invariants(self, t, U):
        return {"$\\\\alpha$": next(iter(super().invariants(t, U).values()))}
'''

ENTRY_POINTS = {
    "problems": {"plug-dollar-invariant": "longtime_limits:DollarInvariant"},
    "integrators": {"plug-spin": "longtime_limits:Spin", "plug-sleep": "longtime_limits:Sleep",
                    "plug-talk": "longtime_limits:Talk", "plug-hog": "longtime_limits:Hog"},
}
# names pyproject.toml's validation refuses, written into the installed metadata as a
# hand-made or older package could have them
BAD_NAMES = ("../../../../tmp/x", "a<b", "a=b")


@pytest.fixture(scope="module")
def env(tmp_path_factory):
    environment, site = install_plugin(tmp_path_factory.mktemp("limits"), "longtime-limits", ENTRY_POINTS,
                                       {"longtime_limits.py": PLUGINS})
    (points,) = site.glob("*.dist-info/entry_points.txt")
    text = points.read_text().replace("[longtime.integrators]\n", "[longtime.integrators]\n" + "".join(
        f"{name} = longtime_limits:Named\n" for name in BAD_NAMES))
    points.write_text(text)
    return environment


def _spin_env(env, tmp_path):
    return {**env, "SPIN_FILE": str(tmp_path / "spin.txt"), "LONGTIME_DB": str(tmp_path / "spin.sqlite")}


# --- hard time limit -------------------------------------------------------------------------

@pytest.mark.slow
@pytest.mark.parametrize("scheme", ["plug-spin", "plug-sleep"])
def test_a_stuck_cell_of_run_ends_as_a_timeout_row(env, tmp_path, scheme):
    """A compiled step that spins (or a plugin's Python that never returns) ends as a timeout row of
    `longtime run`, not a hang: --time-limit holds inside a chunk, not only between chunks."""
    from longtime.execution.limits import hard_limit

    start = time.monotonic()
    res = subprocess.run([sys.executable, "-m", "longtime.commands.cli", "run", "-p", "harmonic",
                          "-i", f"{scheme},verlet", "--dt", "0.1", "--t-final", "1",
                          "--time-limit", "1", "--no-store", "--format", "json"],
                         env=_spin_env(env, tmp_path), capture_output=True, text=True, timeout=120)
    elapsed = time.monotonic() - start
    rows = {r["integrator"]: r for r in json.loads(res.stdout)}
    assert rows[scheme]["status"] == "timeout", rows[scheme]
    assert "hard time limit" in rows[scheme]["message"]
    assert rows["verlet"]["status"] == "ok"
    assert elapsed > hard_limit(1.0)  # the limit is what ended it


@pytest.mark.slow
def test_a_spinning_cell_of_the_default_matrix_ends_as_a_timeout_row(env, tmp_path):
    db = tmp_path / "m.sqlite"
    res = longtime(_spin_env(env, tmp_path), "matrix", "-p", "harmonic", "-i", "plug-spin,verlet,euler",
                   "--dt", "0.1", "--t-final", "1", "--time-limit", "1", "--jobs", "2", "--db", str(db),
                   "--no-progress", "--no-report")
    assert res.returncode == 0, res.stderr
    import sqlite3

    with sqlite3.connect(db) as con:
        rows = {json.loads(r[0])["integrator"]: json.loads(r[0]) for r in con.execute("SELECT row FROM rows")}
        status = con.execute("SELECT status FROM runs").fetchone()[0]
    assert rows["plug-spin"]["status"] == "timeout" and "killed" in rows["plug-spin"]["message"]
    assert rows["verlet"]["status"] == "ok" and rows["euler"]["status"] == "ok"
    assert status == "done"


@pytest.mark.slow
def test_ctrl_c_ends_a_run_stuck_in_a_compiled_step(env, tmp_path):
    """SIGINT ends a `run` whose cell spins in compiled code."""
    spin = _spin_env(env, tmp_path)
    proc = subprocess.Popen([sys.executable, "-m", "longtime.commands.cli", "run", "-p", "harmonic", "-i", "plug-spin",
                             "--dt", "0.1", "--t-final", "1"], env=spin, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 120
    while time.time() < deadline and not (tmp_path / "spin.txt.step").exists():
        time.sleep(0.1)
    worker = int((tmp_path / "spin.txt.step").read_text().split()[0])
    time.sleep(0.5)  # inside the step
    os.kill(proc.pid, signal.SIGINT)
    start = time.monotonic()
    _, err = proc.communicate(timeout=30)
    assert time.monotonic() - start < 10  # a hang would take the 30 s (it ends in well under a second)
    assert proc.returncode == 130, err
    time.sleep(0.5)
    assert not os.path.exists(f"/proc/{worker}") or open(f"/proc/{worker}/stat").read().split()[2] == "Z"


def test_toda_invariants_are_bounded_in_memory():
    """Toda's invariants are computed in chunks of samples, not from every sample's Lax matrix at once
    (d = 80, 62500 samples: 3.2 GB, 5.9 GB with eigvalsh's copy); the eigenvalues are the same,
    bitwise."""
    from longtime.core.registry import problem_class
    from longtime.problems import toda

    problem = problem_class("toda")(d=6)
    rng = np.random.default_rng(1)
    U = problem.u0 + 0.1 * rng.standard_normal((50, problem.dim))
    whole = problem.lax_eigenvalues(None, U)
    saved = toda.LAX_CHUNK_BYTES
    try:
        toda.LAX_CHUNK_BYTES = 8 * 6 * 6 * 7  # 7 samples a chunk
        assert np.array_equal(problem.lax_eigenvalues(None, U), whole)
    finally:
        toda.LAX_CHUNK_BYTES = saved
    big = problem_class("toda")(d=80)
    assert big.metrics_bytes(62_500) < 2**30


def test_the_estimate_counts_the_metrics_and_the_memory_limit(capsys):
    """A cell whose samples and metrics pass the cell's memory limit is refused up front."""
    argv = ["run", "-p", "toda", "-i", "rk4", "--dt", "0.01", "--t-final", "1000", "--set", "d=80", "--no-store"]
    assert main([*argv, "--memory-limit", "0.05"]) == 2
    err = capsys.readouterr().err
    assert "--memory-limit" in err and "metrics" in err and "Traceback" not in err
    from longtime.execution.cells import check_size, expand

    check_size(expand(["toda"], ["rk4"], sweeps={"dt": [0.01]}, t_final=1000.0, sets={"d": 80}),
               memory_limit=2**30)  # fits in 1 GiB: the eigenvalues go in chunks


@pytest.mark.slow
def test_toda_d5000_ends_within_its_limit(tmp_path):
    """The issue's command ran for minutes at 9.1 GB; SIGINT did not end it."""
    from longtime.execution.limits import hard_limit

    start = time.monotonic()
    res = subprocess.run([sys.executable, "-m", "longtime.commands.cli", "run", "--no-store", "-p", "toda", "-i", "rk4",
                          "--dt", "0.1", "--t-final", "2", "--set", "d=5000", "--time-limit", "1",
                          "--format", "json"], capture_output=True, text=True, timeout=300)
    elapsed = time.monotonic() - start
    if res.returncode == 2:  # refused up front: also a promise kept
        assert "Traceback" not in res.stderr and len(res.stderr.strip().splitlines()) == 1
        return
    (row,) = json.loads(res.stdout)
    assert row["status"] == "timeout", row
    assert elapsed < hard_limit(1.0) + 60  # startup and the worker's start on a busy machine


# --- memory limit ----------------------------------------------------------------------------

@pytest.mark.slow
def test_a_cell_past_the_memory_limit_fails_alone(env):
    """A cell past the memory limit fails alone: a plugin's cell cannot invite the OOM killer."""
    res = longtime(env, "run", "-p", "harmonic", "-i", "plug-hog,verlet", "--dt", "0.1", "--t-final", "1",
                   "--memory-limit", "1", "--no-store", "--format", "json")
    assert res.returncode == 1, res.stderr
    rows = {r["integrator"]: r for r in json.loads(res.stdout)}
    assert rows["plug-hog"]["status"] == "failed"
    assert rows["plug-hog"]["message"].startswith("memory limit"), rows["plug-hog"]["message"]
    assert rows["verlet"]["status"] == "ok"


def test_help_states_the_limits(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["run", "--help"])
    out = capsys.readouterr().out
    assert exc.value.code == 0 and "--memory-limit" in out and "(default 50%;" in out and "10 % of it" in out


@pytest.mark.parametrize("value", ["-1", "abc", "150%", "inf"])
def test_bad_memory_limit_is_an_input_error(value, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["run", "-p", "harmonic", "-i", "verlet", "--memory-limit", value, "--no-store"])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and "--memory-limit takes GiB" in err


# --- stdout carries only the contract --------------------------------------------------------

@pytest.mark.slow
@pytest.mark.parametrize("extra", [[], ["--time-limit", "0"]])
def test_plugin_output_does_not_corrupt_json(env, extra):
    """A scheme's print (Python, numba, or to fd 1) stays out of the JSON on stdout, both in a worker
    process (default) and in this process (no time limit)."""
    res = longtime(env, "run", "-p", "harmonic", "-i", "plug-talk", "--dt", "0.5", "--t-final", "1",
                   "--no-store", "--format", "json", "--repeats", "1", *extra)
    (row,) = json.loads(res.stdout)
    assert row["integrator"] == "plug-talk"
    for text in ("python print from a plugin", "fd 1 write", "numba print from a step"):
        assert text in res.stderr, res.stderr


# --- bad input refused up front --------------------------------------------------------------

def test_a_fixed_step_larger_than_the_span_is_refused(capsys, tmp_path):
    """A fixed step larger than the span is refused, not a row saying dt 5 for one step of 1."""
    db = tmp_path / "s.sqlite"
    assert main(["run", "-p", "kepler", "-i", "verlet", "--dt", "5", "--t-final", "1", "--db", str(db)]) == 2
    err = capsys.readouterr().err
    assert "--dt 5" in err and "span" in err and len(err.strip().splitlines()) == 1
    assert not db.exists()


def test_one_computation_under_several_labels_is_one_point_of_an_order_fit():
    """dt 1, 5 and 10 over a span of 1 (one step each, the same computation) are one point."""
    from longtime.measure.orders import observed_orders

    base = {"status": "ok", "problem": "harmonic", "integrator": "rk4", "t_final": 1.0, "settings": "",
            "run_id": 1, "order": None, "tol": None, "eps_res": None}
    rows = [{**base, "dt": dt, "steps": round(1 / dt), "mean_dt": dt, "l2_error": 0.08 * dt**4} for dt in (0.25, 0.5)]
    rows += [{**base, "dt": dt, "steps": 1, "mean_dt": 1.0, "l2_error": 0.08} for dt in (1.0, 5.0, 10.0)]
    (fit,) = observed_orders(rows)
    assert [x for x, _ in fit["order_points"]] == [0.25, 0.5, 1.0]
    assert fit["observed_order"] == pytest.approx(4.0)


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["file", "read-only", "under-file"])
def test_an_unusable_cache_folder_is_refused_up_front(tmp_path, kind):
    """An unusable cache folder is refused up front, not in every cell on its own (PermissionError,
    NotADirectoryError)."""
    cache = tmp_path / "cache"
    prefix = []
    if kind == "file":
        cache.write_text("x")
    elif kind == "under-file":
        (tmp_path / "f").write_text("x")
        cache = tmp_path / "f" / "cache"
    else:
        prefix = unprivileged()
        if prefix is None:
            pytest.skip("root without user namespaces: permissions do not hold")
        cache.mkdir()
        os.chmod(cache, 0o555)
    try:
        res = subprocess.run([*prefix, sys.executable, "-m", "longtime.commands.cli", "run", "-p", "harmonic",
                              "-i", "verlet", "--dt", "0.1", "--t-final", "1", "--no-store"],
                             env={**os.environ, "LONGTIME_CACHE_DIR": str(cache)}, capture_output=True, text=True,
                             timeout=120)
    finally:
        if cache.is_dir():
            os.chmod(cache, 0o755)
    assert res.returncode == 2, res.stderr
    assert "cache folder" in res.stderr and "Traceback" not in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1


@pytest.mark.slow
def test_a_stored_order_that_is_not_a_number_does_not_break_the_report(tmp_path, capsys):
    import sqlite3

    db = tmp_path / "o.sqlite"
    assert main(["run", "-p", "harmonic", "-i", "taylor", "--order", "4", "--dt", "0.1", "--t-final", "1",
                 "--db", str(db)]) == 0
    with sqlite3.connect(db) as con:
        for rowid, text in list(con.execute("SELECT rowid, row FROM rows")):
            con.execute("UPDATE rows SET row = ? WHERE rowid = ?", (json.dumps({**json.loads(text), "order": "x<"}),
                                                                      rowid))
    capsys.readouterr()
    assert main(["report", "--db", str(db), "--html", str(tmp_path / "page")]) == 0
    assert (tmp_path / "page" / "index.html").exists()


# --- names are identifiers -------------------------------------------------------------------

@pytest.mark.slow
def test_names_that_break_the_rule_are_broken_plugins(env):
    """Names that break the rule make broken plugins: a scheme registered as ../../../../tmp/x is not
    loaded (its name builds cache file names), and 'a=b' is refused, not an AttributeError."""
    from longtime.core.contract import NAME_RULE

    res = longtime(env, "list", "--format", "json")
    assert res.returncode == 0, res.stderr
    data = json.loads(res.stdout)
    broken = {b["name"]: b["error"] for b in data["broken"]}
    for name in ("../../../../tmp/x", "a<b", "a"):
        assert name in broken and NAME_RULE in broken[name], broken
    assert "AttributeError" not in json.dumps(data["broken"])
    loaded = {i["name"] for i in data["integrators"]}
    assert not loaded & {"../../../../tmp/x", "a<b", "a", "a=b"}


def test_every_builtin_name_follows_the_rule():
    from longtime.core import registry
    from longtime.core.contract import name_error

    for kind, found in (("problem", registry.problems()), ("scheme", registry.integrators())):
        for name, cls in found.items():
            assert name_error(kind, name) is None
            for key in cls.parameters:
                assert name_error("parameter", key) is None
    toda = registry.problem_class("toda")()
    for name in toda.invariants(np.zeros(2), np.array([toda.u0, toda.u0])):
        assert name_error("invariant", name) is None


@pytest.mark.slow
def test_an_invariant_name_that_breaks_the_rule_fails_its_cell(env):
    res = longtime(env, "run", "-p", "plug-dollar-invariant", "-i", "verlet", "--dt", "0.1", "--t-final", "1",
                   "--no-store", "--format", "json")
    (row,) = json.loads(res.stdout)
    assert row["status"] == "failed" and "invariant name" in row["message"]


def test_figure_text_is_not_mathtext():
    r"""A label '$\alpha$' is drawn as typed, not as the Greek letter."""
    from longtime.reporting.figures import pyplot

    plt = pyplot()
    fig, ax = plt.subplots()
    title = ax.set_title(r"$\alpha$ scheme")
    fig.canvas.draw()
    assert title._preprocess_math(title.get_text()) == (r"$\alpha$ scheme", False)
    plt.close(fig)
