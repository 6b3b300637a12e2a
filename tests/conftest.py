"""Test session setup: private cache and store, nothing written to the working folder.

The slow tests (fault injection in subprocesses, Valgrind, Dask clusters, fresh interpreters,
ensembles and long integrations) carry ``@pytest.mark.slow`` where they are (or
``pytestmark`` in a module whose every test is slow). The default run (README's test
command) leaves them out; `python -m pytest -m slow` runs them, and CI runs both. At the end
of a session, a test not marked slow that took over ``SLOW_UNMARKED_S`` seconds is named in
the terminal summary. README's test command runs the default tests on every core
(pytest-xdist's ``-n auto``); the slow run stays serial."""
import os

import pytest

SLOW_UNMARKED_S = 30.0  # a test not marked slow over this many seconds is listed at the end
MARKED_SLOW = pytest.StashKey[set]()  # the node ids of the tests marked slow in this session


@pytest.fixture(scope="session", autouse=True)
def _private_state(tmp_path_factory):
    root = tmp_path_factory.mktemp("longtime-state")
    os.environ.setdefault("LONGTIME_CACHE_DIR", str(root / "cache"))
    os.environ["LONGTIME_DB"] = str(root / "default.sqlite")
    os.environ.setdefault("MPLBACKEND", "Agg")
    # one timing process per cell unless a test asks for more (each process is an interpreter start)
    os.environ.setdefault("LONGTIME_PROCESSES", "1")
    yield


def slow_unmarked(reports, marked_slow) -> list[tuple[str, float]]:
    """(node id, seconds) of each test whose setup, call and teardown together took over
    SLOW_UNMARKED_S seconds and that is not in ``marked_slow``, the slowest first."""
    took: dict[str, float] = {}
    for report in reports:
        took[report.nodeid] = took.get(report.nodeid, 0.0) + report.duration
    return sorted(((node, s) for node, s in took.items() if s > SLOW_UNMARKED_S and node not in marked_slow),
                  key=lambda item: -item[1])


@pytest.hookimpl(tryfirst=True)
def pytest_configure(config):
    """Under pytest-xdist (README's ``-n auto``) the benchmark cases run once, untimed:
    timings taken beside other workers measure the load. Said here, before pytest-benchmark
    warns of it; CI times them in a run of their own (.ci/run)."""
    if config.pluginmanager.hasplugin("benchmark") and (
            os.environ.get("PYTEST_XDIST_WORKER") or config.getoption("numprocesses", None)):
        config.option.benchmark_disable = True


def pytest_collection_modifyitems(config, items):
    config.stash[MARKED_SLOW] = {item.nodeid for item in items if item.get_closest_marker("slow")}


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    reports = [r for key in ("passed", "failed", "error", "skipped", "") for r in terminalreporter.stats.get(key, [])
               if hasattr(r, "duration") and hasattr(r, "nodeid")]
    found = slow_unmarked(reports, config.stash.get(MARKED_SLOW, set()))
    if found:
        terminalreporter.write_sep("-", f"tests not marked slow that took over {SLOW_UNMARKED_S:g} s")
        for node, seconds in found:
            terminalreporter.write_line(f"{seconds:.1f} s  {node}  (mark it @pytest.mark.slow)")
