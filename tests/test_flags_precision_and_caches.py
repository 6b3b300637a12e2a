"""Every flag reaches every scheme that declares it, every machine output format keeps full
precision, and every cache is verified before it is trusted. The scheme tests go over the
registry, so a new scheme that ignores a parameter it declares fails here without anyone
listing it."""
import csv
import io
import json
import math
import os
import sqlite3
import struct
import subprocess
import sys

import numpy as np
import pytest

from longtime import FixedStepIntegrator
from longtime.commands.cli import main
from longtime.core import registry
from longtime.core.roles import ROW_PARAMETERS
from longtime.core.timing import Timing
from longtime.core.trajectory import same_run
from longtime.execution import cells as cells_module
from longtime.execution.cells import Cell, run_cell

# tiny problems, first compatible one wins (constraints: the pendulum; a linear part: kdv;
# the Lorentz force: the charged particle)
PROBLEMS = (("harmonic", {}), ("kepler", {}), ("double-pendulum", {}), ("kdv", {"d": 16}),
            ("charged-particle", {}))
T_FINAL = {"harmonic": 2.3, "kepler": 2.3, "double-pendulum": 0.3, "kdv": 0.3, "charged-particle": 2.3}
SCHEMES = sorted(registry.integrators())
# a value of each built-in parameter that must change a short run; a parameter of a new
# scheme not listed here gets a generic probe (_probe)
PROBES = {"dt": 0.5, "tol": 1e-3, "eps_res": 1e-10, "order": 4, "atol": 1e-2, "max_iter": 1,
          "compensated": True, "stop": "brouwer", "high_accuracy": True, "nodes": 8, "pade_num": 2,
          "pade_den": 2, "pade_tol": 0.5, "max_dt": 0.01, "fallback": "taylor"}


# the libraries whose every run compiles first (JAX: tens of seconds a run): their schemes are
# in the slow run only (tests/test_peers.py runs one of them by default)
COMPILING_LIBRARIES = {"diffrax"}


def _representatives(schemes: list[str]) -> set[str]:
    """A scheme of each implementation (the first of each module), but those of
    COMPILING_LIBRARIES: the default run checks the flags on these; the slow run on every
    scheme of the registry."""
    first: dict[str, str] = {}
    for s in schemes:
        icls = registry.integrator_class(s)
        if icls.library not in COMPILING_LIBRARIES:
            first.setdefault(icls.__module__, s)
    return set(first.values())


REPRESENTATIVE = _representatives(SCHEMES)


def each_scheme(cases, scheme_of=lambda case: case):
    """``cases`` as pytest params: those of a representative scheme in the default run, the
    others marked slow."""
    return [pytest.param(*(c if isinstance(c, tuple) else (c,)),
                         marks=() if scheme_of(c) in REPRESENTATIVE else pytest.mark.slow) for c in cases]


def problem_for(scheme: str) -> tuple[str, dict]:
    icls = registry.integrator_class(scheme)
    for name, settings in PROBLEMS:
        if icls().incompatibility(registry.problem_class(name)(**settings)) is None:
            return name, settings
    pytest.skip(f"{scheme}: no tiny problem it can treat")


def _probe(scheme: str, key: str, problem: str):
    spec = registry.integrator_class(scheme).parameters[key]
    if key == "dt":
        return 0.5 * registry.problem_class(problem).default_dt
    if key == "controller":
        return next(c for c in spec.choices if c != spec.default)
    if key in PROBES:
        return PROBES[key]
    if spec.kind is bool:
        return not spec.default
    if spec.choices:
        return next(c for c in spec.choices if c != spec.default)
    if spec.kind is int:
        return (spec.default or 2) + 1
    return (spec.default or 1.0) * 0.5


def run(monkeypatch, scheme, settings, t_final=None, max_samples=100_001, timing=None, time_limit=None):
    """run_cell on the scheme's tiny problem (no reference), and the trajectory behind the row."""
    problem, psettings = problem_for(scheme)
    seen = {}
    evaluate = cells_module.metrics.evaluate

    def spy(problem_, traj, *args, **kwargs):
        seen["traj"] = traj
        return evaluate(problem_, traj, *args, **kwargs)

    monkeypatch.setattr(cells_module.metrics, "evaluate", spy)
    cell = Cell(problem, scheme, psettings, settings, T_FINAL[problem] if t_final is None else t_final)
    row = run_cell(cell, max_samples, reference=False, timing=timing or Timing(repeats=1, min_time=0),
                   time_limit=time_limit)
    monkeypatch.undo()
    assert row["status"] != "failed" or "traj" in seen, row["message"]
    return row, seen.get("traj")


PARAMETERS = [(s, k) for s in SCHEMES for k in registry.integrator_class(s).parameters]


@pytest.mark.parametrize("scheme,key", each_scheme(PARAMETERS, lambda c: c[0]), ids=[f"{s}-{k}" for s, k in PARAMETERS])
def test_every_declared_parameter_reaches_the_run(monkeypatch, scheme, key):
    """The row records the value (its field for a swept one, and ``parameters``) and the run
    changes with it: a scheme that declares a parameter and ignores it fails here."""
    problem, _ = problem_for(scheme)
    value = _probe(scheme, key, problem)
    base_row, base = run(monkeypatch, scheme, {})
    row, traj = run(monkeypatch, scheme, {key: value})
    assert json.loads(row["parameters"])[key] == value
    if key in ROW_PARAMETERS:
        assert row[key] == value
    assert not same_run(base, traj), f"{scheme}: {key}={value!r} gave the run of the default"


@pytest.mark.parametrize("scheme", each_scheme(SCHEMES))
def test_t_final_and_repeats_reach_every_scheme(monkeypatch, scheme):
    """--t-final (not a multiple of any step) is where every run ends; --repeats N with a long
    --min-time gives N timed runs; the row records every parameter actually used (a fixed
    step scheme's default dt too)."""
    row, traj = run(monkeypatch, scheme, {}, timing=Timing(repeats=2, min_time=60))
    problem, _ = problem_for(scheme)
    assert row["status"] == "ok", row["message"]
    assert row["t_final"] == row["t_reached"] == T_FINAL[problem]
    assert row["repeats"] == 2
    used = json.loads(row["parameters"])
    assert set(registry.integrator_class(scheme).parameters) <= set(used)
    if issubclass(registry.integrator_class(scheme), FixedStepIntegrator):
        assert used["dt"] == row["dt"] == registry.problem_class(problem).default_dt


@pytest.mark.parametrize("scheme", each_scheme(SCHEMES))
def test_max_samples_bounds_the_samples_of_every_scheme(monkeypatch, scheme):
    problem, _ = problem_for(scheme)
    icls = registry.integrator_class(scheme)
    small = {k: v for k, v in (("dt", 0.25 * registry.problem_class(problem).default_dt), ("tol", 1e-10),
                               ("eps_res", 1e-10)) if k in icls.parameters}
    row, _ = run(monkeypatch, scheme, small, t_final=20 * T_FINAL[problem], max_samples=5)
    assert row["steps"] > 10 and row["samples"] <= 5, (row["steps"], row["samples"])


# ------------------------------------------------------------------ the flags on the command line
def cli_rows(capsys, *argv):
    code = main(["run", "--no-store", "--format", "json", "--repeats", "1", *argv])
    out = capsys.readouterr()
    rows = json.loads(out.out)
    assert code == (1 if any(r["status"] == "failed" for r in rows) else 0), out.err
    return rows


def _flag_cases():
    out = []
    for flag in ROW_PARAMETERS:
        for s in SCHEMES:
            if flag in registry.integrator_class(s).parameters:
                out.append((flag, s))
    return out


@pytest.fixture(scope="module")
def one_calibration():
    """A calibration taken once: the flag tests' runs are calibrated with it (a copy at the
    time asked) instead of timing the reference workload again in each."""
    from longtime.execution import calibration

    return calibration.measure("batch")


@pytest.mark.parametrize("flag,scheme", each_scheme(_flag_cases(), lambda c: c[1]),
                         ids=[f"{f}-{s}" for f, s in _flag_cases()])
def test_sweep_flags_reach_the_row_from_the_command_line(capsys, monkeypatch, one_calibration, flag, scheme):
    """The flag, given on the command line (cells run in this process: --executor serial),
    is the row's value and its parameter."""
    import time

    from longtime.execution import calibration

    monkeypatch.setattr(calibration, "measure", lambda phase="batch", **_: {**one_calibration, "t": time.time(),
                                                                            "phase": phase})
    problem, psettings = problem_for(scheme)
    value = _probe(scheme, flag, problem)
    sets = [a for k, v in psettings.items() for a in ("--set", f"{k}={v}")]
    rows = cli_rows(capsys, "-p", problem, "-i", scheme, f"--{flag.replace('_', '-')}", str(value),
                    "--t-final", str(T_FINAL[problem]), "--executor", "serial", *sets)
    assert len(rows) == 1 and rows[0][flag] == value
    assert json.loads(rows[0]["parameters"])[flag] == value


def test_min_time_and_repeats_from_the_command_line(capsys):
    argv = ["-p", "harmonic", "-i", "verlet", "--t-final", "1"]
    assert cli_rows(capsys, *argv)[0]["repeats"] == 1
    rows = json.loads(_cli(capsys, "run", "--no-store", "--format", "json", "--repeats", "5", "--min-time", "0",
                           *argv)[1])
    assert rows[0]["repeats"] == Timing.MIN_RUNS


def _cli(capsys, *argv):
    try:
        code = main(list(argv))
    except SystemExit as exc:  # argparse's own input errors
        code = exc.code
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.mark.parametrize("argv,words", [
    # a flag and --set giving one parameter: refused, neither wins silently
    (["-i", "rk4", "--dt", "0.2", "--set", "dt=0.1"], ["--dt and --set dt= both give dt"]),
    # --jobs with the serial executor is refused, not ignored; a negative --jobs is refused
    (["-i", "rk4", "--jobs", "2", "--executor", "serial"], ["--jobs 2", "serial"]),
    (["-i", "rk4", "--jobs", "-2", "--executor", "process"], ["--jobs", ">= 0"]),
    (["-i", "rk4", "--repeats", "0"], ["--repeats", ">= 1"]),
    (["-i", "rk4", "--min-time", "-1"], ["--min-time", ">= 0"]),
    (["-i", "rk4", "--max-samples", "1"], ["--max-samples", ">= 2"]),
    # a flag no selected scheme takes names the schemes it applies to
    (["-i", "heyoka", "--order", "5"], ["--order", "applies to", "bpl", "taylor"]),
])
def test_a_flag_that_would_be_ignored_is_an_input_error(capsys, argv, words):
    code, out, err = _cli(capsys, "run", "-p", "harmonic", "--t-final", "1", "--no-store", *argv)
    assert code == 2 and not out.strip()
    for w in words:
        assert w in err
    assert "Traceback" not in err


# ------------------------------------------------------------------ full precision in every format
def _floats_equal(a, b) -> bool:
    """Bitwise equality of two numbers (a NaN matches a NaN of the same bits)."""
    return struct.pack("<d", float(a)) == struct.pack("<d", float(b))


def _compare(stored: dict, shown: dict, parse=lambda v: v):
    """Every float of the stored row is the same float in the output (bitwise); a count
    stays the integer it was."""
    checked = 0
    for key, value in stored.items():
        if key == "run_id":
            continue
        got = parse(shown[key])
        if isinstance(value, bool) or value is None or isinstance(value, str):
            continue
        if isinstance(value, float):
            assert _floats_equal(got, value), (key, value, got)
            checked += 1
        elif isinstance(value, int):
            assert got == value and float(got).is_integer(), (key, value, got)
        elif isinstance(value, (list, dict)):
            assert (json.loads(got) if isinstance(got, str) else got) == value, key
    assert checked > 10


@pytest.fixture(scope="module")
def stored(tmp_path_factory):
    """A store with rows whose floats need all 17 digits (1/3 steps, irrational errors)."""
    db = tmp_path_factory.mktemp("formats") / "formats.sqlite"
    code = main(["run", "-p", "harmonic", "-i", "rk4,rk45,verlet", "--dt", str(1 / 3), "--tol", "1e-7",
                 "--t-final", "7", "--repeats", "1", "--db", str(db), "--format", "csv"])
    assert code == 0
    with sqlite3.connect(db) as con:
        rows = [json.loads(r[0]) for r in con.execute("SELECT row FROM rows ORDER BY id")]
    return db, rows


def test_report_json_keeps_every_float_bitwise(stored, capsys):
    """`report --format json` keeps every float bitwise (not pandas' 10 digits: cpu_s 0.3333333333) and
    writes counts as integers, not floats."""
    db, rows = stored
    code, out, _ = _cli(capsys, "report", "--db", str(db), "--format", "json")
    assert code == 0
    shown = json.loads(out)
    assert len(shown) == len(rows)
    for s, r in zip(rows, shown):
        _compare(s, r)


def _csv_value(text):
    if text == "":
        return None
    try:
        return int(text)
    except ValueError:
        try:
            return float(text)
        except ValueError:
            return text


def test_report_csv_keeps_every_float_bitwise(stored, capsys):
    db, rows = stored
    code, out, _ = _cli(capsys, "report", "--db", str(db), "--format", "csv")
    assert code == 0
    shown = list(csv.DictReader(io.StringIO(out)))
    assert len(shown) == len(rows)
    for s, r in zip(rows, shown):
        _compare(s, r, _csv_value)


@pytest.mark.parametrize("fmt", ["json", "csv"])
def test_run_output_is_the_stored_row_bitwise(capsys, tmp_path, fmt):
    db = tmp_path / "run.sqlite"
    code, out, _ = _cli(capsys, "run", "-p", "kepler", "-i", "rk45,gauss4", "--tol", "1e-6", "--dt", "0.0123",
                        "--t-final", "3", "--repeats", "1", "--db", str(db), "--format", fmt)
    assert code == 0
    shown = json.loads(out) if fmt == "json" else list(csv.DictReader(io.StringIO(out)))
    with sqlite3.connect(db) as con:
        rows = [json.loads(r[0]) for r in con.execute("SELECT row FROM rows ORDER BY id")]
    for s, r in zip(rows, shown):
        _compare(s, r, (lambda v: v) if fmt == "json" else _csv_value)


def test_report_parquet_keeps_every_float_bitwise(stored, capsys, tmp_path):
    pd = pytest.importorskip("pandas")
    pytest.importorskip("pyarrow")
    db, rows = stored
    out = tmp_path / "rows.parquet"
    code, _, _ = _cli(capsys, "report", "--db", str(db), "--format", "parquet", "--out", str(out))
    assert code == 0
    shown = pd.read_parquet(out).to_dict("records")

    def value(v):
        return None if v is None or (isinstance(v, float) and math.isnan(v)) else v

    for s, r in zip(rows, shown):
        _compare({k: v for k, v in s.items() if not (isinstance(v, int) and not isinstance(v, bool))}, r, value)
        for k, v in s.items():  # a count is the same number (parquet may type a column with nulls as float)
            if isinstance(v, int) and not isinstance(v, bool):
                assert r[k] == v, k


@pytest.mark.parametrize("fmt", ["table", "markdown"])
def test_human_formats_round_but_never_show_a_tiny_value_as_zero(fmt):
    from longtime.reporting.report import render

    rows = [{"problem": "p", "integrator": "a", "status": "ok", "message": "", "dt": 0.1, "cpu_s": 1.5e-6,
             "H.max": 3e-17, "l2_error": 1e-300, "steps": 12345678901},
            {"problem": "p", "integrator": "b", "status": "failed", "message": "x"}]
    text = render(rows, fmt)
    assert "3.000e-17" in text and "1.000e-300" in text and "1.500e-06" in text
    assert "12345678901" in text  # a count is not rounded, even beside a null (not 1.235e+10)
    line = next(line for line in text.splitlines() if " a " in f" {line} " or "| a " in line)
    assert " 0 " not in line and " 0.0 " not in line and "| 0 |" not in line


# ------------------------------------------------------------------ caches, verified before trusted
def test_stability_cache_that_is_corrupt_is_discarded_and_rebuilt(tmp_path, monkeypatch):
    """A corrupt stability file is discarded and rebuilt: a truncated one does not crash `longtime
    list` (JSONDecodeError), nor one of the wrong shape format_interval (KeyError)."""
    from longtime.measure import stability

    monkeypatch.setenv("LONGTIME_CACHE_DIR", str(tmp_path))
    result = {"y": 2.0, "bounded": True, "why": "|R| = 1.1 at y = 2.01", "y_1pct": 2.5}
    calls = []
    monkeypatch.setattr(stability, "imaginary_interval", lambda name, order=None: calls.append(name) or result)
    assert stability.intervals("rk4") == {"": result}
    path = next((tmp_path / "stability").iterdir())
    assert json.loads(path.read_text()) == result
    for bad in (b'{"y": 2.0, "boun', b"\xff\xfe", b'{"y": 2.0}', b"[]"):
        path.write_bytes(bad)
        with pytest.warns(UserWarning, match=f"discarding the unreadable stability cache file {path}"):
            assert stability.intervals("rk4", compute=False) == {}  # not believed, not a crash
        assert not path.exists()
        path.write_bytes(bad)
        with pytest.warns(UserWarning, match="discarding the unreadable stability cache file"):
            assert stability.intervals("rk4") == {"": result}  # rebuilt
        assert json.loads(path.read_text()) == result
    assert len(calls) == 5


def test_reference_cache_file_with_flipped_bits_is_not_believed(tmp_path, monkeypatch):
    """A states file whose data bytes are damaged (right shape, finite values) is not used as the
    reference: every file is checked against the checksum written with it, not only for being
    readable."""
    from longtime.measure import reference

    monkeypatch.setenv("LONGTIME_CACHE_DIR", str(tmp_path))
    path = tmp_path / "states.npy"
    states = np.linspace(0.0, 1.0, 64).reshape(32, 2)
    reference.save_cached(path, states)
    assert np.array_equal(reference.load_cached(path, lambda: np.load(path)), states)
    data = bytearray(path.read_bytes())
    data[-100] ^= 0x01  # in the last state: a finite value, a little off
    path.write_bytes(bytes(data))
    assert np.isfinite(np.load(path)).all()
    with pytest.warns(UserWarning, match=f"discarding the unreadable reference cache file {path}"):
        assert reference.load_cached(path, lambda: np.load(path)) is None
    assert not path.exists()
    np.save(path, states)  # a file without a checksum (another writer, an older version)
    with pytest.warns(UserWarning, match="no checksum"):
        assert reference.load_cached(path, lambda: np.load(path)) is None


def test_reference_cache_key_covers_the_equations(monkeypatch, tmp_path):
    """The reference's key covers the equations, not only the problem's name, settings and initial
    state: an edited right-hand side (a coefficient in heyoka_system) does not reuse the old
    reference."""
    pytest.importorskip("heyoka")
    from longtime.measure import reference

    monkeypatch.setenv("LONGTIME_CACHE_DIR", str(tmp_path))
    problem = registry.problem_class("harmonic")()
    before = reference.cache_path(problem, "states", "double")
    system = problem.heyoka_system

    def edited():
        variables, rhs = system()
        return variables, [rhs[0], 1.0000000000000002 * rhs[1]]

    monkeypatch.setattr(problem, "heyoka_system", edited)
    assert reference.cache_path(problem, "states", "double") != before


def _longtime_run(env, *argv):
    return subprocess.run([sys.executable, "-m", "longtime.commands.cli", "run", *argv], env=env,
                          capture_output=True, text=True, timeout=300)


@pytest.mark.slow
def test_corrupt_kernel_module_and_bytecode_are_discarded_and_rebuilt(tmp_path):
    """A generated kernel module with bytes that are not UTF-8, and a damaged .pyc of it ('bad marshal
    data'), are discarded and rebuilt, not a failed row ('UnicodeDecodeError') on every rerun naming
    no file."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env.update(NUMBA_CACHE_DIR=str(tmp_path / "numba"), LONGTIME_CACHE_DIR=str(tmp_path / "lt"))
    argv = ["-p", "harmonic", "-i", "verlet", "--dt", "0.1", "--t-final", "1", "--no-store", "--format",
            "json", "--repeats", "1"]
    first = _longtime_run(env, *argv)
    assert first.returncode == 0, first.stderr
    kernels = tmp_path / "lt" / "kernels"
    modules = sorted(kernels.glob("longtime_kernel_*.py"))
    assert modules
    for m in modules:
        m.write_bytes(m.read_bytes() + b"\xff\xfe")
    again = _longtime_run(env, *argv)
    assert again.returncode == 0 and json.loads(again.stdout)[0]["status"] == "ok", again.stdout + again.stderr
    assert f"discarding the unreadable kernel cache file {modules[0]}" in again.stderr
    pycs = sorted(kernels.rglob("*.pyc"))
    assert pycs
    for p in pycs:
        p.write_bytes(p.read_bytes()[:16] + b"\x00garbage")
    third = _longtime_run(env, *argv)
    assert third.returncode == 0 and json.loads(third.stdout)[0]["status"] == "ok", third.stdout + third.stderr
    assert "discarding the unreadable kernel bytecode cache file" in third.stderr


CALLER = """
import numba
from callee import value

@numba.njit(cache=True)
def caller():
    return value()

print(caller())
"""


def test_numba_cache_of_a_function_whose_callee_changed_is_not_used(tmp_path):
    """numba keys a cached function by its own bytecode and its own file: a callee edited in
    another file leaves numba's key of the caller unchanged, so its stale code would run. The cache
    guard adds the fingerprint of everything the function reaches to the key."""
    (tmp_path / "caller.py").write_text("import longtime.core.jitcache\n" + CALLER)
    callee = tmp_path / "callee.py"
    path = os.pathsep.join(p for p in (str(tmp_path), os.environ.get("PYTHONPATH")) if p)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba"), "PYTHONPATH": path}

    def run_caller():
        res = subprocess.run([sys.executable, str(tmp_path / "caller.py")], env=env, capture_output=True,
                             text=True, timeout=120)
        assert res.returncode == 0, res.stderr
        return res.stdout.strip()

    callee.write_text("import numba\n\n@numba.njit\ndef value():\n    return 1\n")
    assert run_caller() == "1"
    callee.write_text("import numba\n\n@numba.njit\ndef value():\n    return 2\n")
    assert run_caller() == "2"
    assert run_caller() == "2"  # and the new entry is cached, and used
    assert len(list((tmp_path / "numba").rglob("*.nbc"))) >= 2


@pytest.mark.parametrize("command", ["run", "matrix", "roundoff", "warmup", "reproduce"])
def test_negative_jobs_is_an_input_error_on_every_command(command, capsys):
    # roundoff, warmup and reproduce took any integer: -2 silently meant one per core
    with pytest.raises(SystemExit) as exit_:
        main([command, "--jobs", "-2"])
    assert exit_.value.code == 2
    assert "--jobs takes an integer >= 0" in capsys.readouterr().err
