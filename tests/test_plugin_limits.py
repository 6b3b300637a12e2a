"""Calls into a plugin before any cell (the contract check of its problem) run under a cell's
limits: invariants that never return stop at the hard time limit; invariants that raise give
one error naming the problem."""
import time

import numba
import numpy as np
import pytest

import longtime
from longtime import InputError
from longtime.core import registry
from longtime.execution import limits
from longtime.integrators.explicit_rk import RK4
from longtime.problems.harmonic import Harmonic


class SpinningInvariants(Harmonic):
    name = "faulty-spinning-invariants"

    def invariants(self, t, U):
        while True:
            pass


class RaisingInvariants(Harmonic):
    name = "faulty-raising-invariants"

    def invariants(self, t, U):
        return {"H": 1.0 / 0.0}


def test_invariants_that_never_return_stop_at_the_hard_limit(monkeypatch):
    monkeypatch.setattr(limits, "GRACE_S", 1.0)
    registry.register(SpinningInvariants)
    started = time.monotonic()
    with pytest.raises(InputError) as info:
        longtime.sweep("faulty-spinning-invariants", "verlet", dt=0.1, time_limit=2, executor="serial")
    took = time.monotonic() - started
    assert took < 2 + 1 + 0.2 + 10, took  # the hard limit (2 s + 1 s + 10 %) and the start-up
    message = str(info.value)
    assert "problem faulty-spinning-invariants" in message and "did not return within 3.2 s" in message


def test_invariants_that_raise_are_one_error_naming_the_problem():
    registry.register(RaisingInvariants)
    with pytest.raises(InputError) as info:
        longtime.sweep("faulty-raising-invariants", "verlet", dt=0.1, executor="serial")
    message = str(info.value)
    assert "problem faulty-raising-invariants" in message and "ZeroDivisionError" in message
    assert "\n" not in message


def test_a_limited_call_returns_its_result_and_raises_its_exception():
    assert limits.call_limited(sum, [1, 2, 3], time_limit=5) == 6
    with pytest.raises(KeyError):
        limits.call_limited({}.__getitem__, "x", time_limit=5)
    with pytest.raises(MemoryError):
        limits.call_limited(np.ones, 2**33, time_limit=30, memory_limit=2**28)


@numba.njit
def _spin_step(t, u, h, params, work, counters, first):
    x = 1.0
    while x > 0.0:  # compiled code that never returns to Python
        x = x * 1.0000001 + 1.0
        u[0] = x
    return 0


class SpinningStep(RK4):
    name = "faulty-spinning-step"
    summary = "a compiled step that never returns"

    def make_step(self, problem):
        return _spin_step


def test_an_ensemble_whose_step_spins_stops_at_the_hard_limit(monkeypatch):
    from longtime.commands import ensemble as ensemble_command

    monkeypatch.setattr(limits, "GRACE_S", 1.0)
    registry.register(SpinningStep)
    started = time.monotonic()
    rows = ensemble_command.study(["henon-heiles"], ["faulty-spinning-step"], dt=0.1, t_final=5.0, members=2,
                                  time_limit=1.0)
    assert time.monotonic() - started < 1 + 1 + 0.1 + 15
    (row,) = rows
    assert row["status"] == "timeout" and "did not return within 2.1 s" in row["message"]


def test_a_horizon_member_whose_step_spins_stops_at_the_hard_limit_and_is_named(monkeypatch):
    from longtime.commands import horizon

    monkeypatch.setattr(limits, "GRACE_S", 1.0)
    registry.register(SpinningStep)
    started = time.monotonic()
    with pytest.raises(RuntimeError, match=r"faulty-spinning-step at dt=0.9, y0=.*did not return within 2.1 s"):
        horizon.study(schemes=["faulty-spinning-step"], dts=[0.9, 0.8], members=2, t_final=50.0, jobs=1,
                      progress=False, time_limit=1.0)
    assert time.monotonic() - started < 1 + 1 + 0.1 + 15


def test_the_card_of_a_scheme_whose_step_spins_stops_at_the_hard_limit(monkeypatch, tmp_path, capsys):
    from longtime.commands.cli import main

    monkeypatch.setattr(limits, "GRACE_S", 1.0)
    registry.register(SpinningStep)
    started = time.monotonic()
    code = main(["card", "faulty-spinning-step", "--time-limit", "1", "--db", str(tmp_path / "none.sqlite")])
    assert time.monotonic() - started < 1 + 1 + 0.1 + 15
    assert code == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "the card of faulty-spinning-step" in err[0] and "did not return within 2.1 s" in err[0]


SPIN_ENSEMBLE = """
import sys
sys.path.insert(0, {tests!r})
from test_plugin_limits import SpinningStep
from longtime.core import registry
from longtime.commands.cli import main
registry.register(SpinningStep)
sys.exit(main(["ensemble", "-p", "henon-heiles", "-i", "faulty-spinning-step", "--dt", "0.1", "--t-final", "5",
               "--members", "2"]))
"""


def test_sigterm_ends_an_ensemble_whose_step_spins_and_leaves_no_child():
    import os
    import signal
    import subprocess
    import sys

    from _procs import alive, descendants

    tests = os.path.dirname(os.path.abspath(__file__))
    proc = subprocess.Popen([sys.executable, "-c", SPIN_ENSEMBLE.format(tests=tests)], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 60
        while not descendants(proc.pid):  # the forked child that runs the ensemble
            assert proc.poll() is None, proc.stderr.read().decode()
            assert time.monotonic() < deadline, "the ensemble did not start a child"
            time.sleep(0.05)
        time.sleep(1.0)
        children = list(descendants(proc.pid))
        proc.send_signal(signal.SIGTERM)
        code = proc.wait(timeout=20)
    finally:
        proc.kill()
        proc.wait()
    assert code == 128 + signal.SIGTERM
    time.sleep(0.5)
    assert not [p for p in children if alive(p)]
