"""Test session setup: private cache and store, nothing written to the working folder."""
import os

import pytest


@pytest.fixture(scope="session", autouse=True)
def _private_state(tmp_path_factory):
    root = tmp_path_factory.mktemp("longtime-state")
    os.environ.setdefault("LONGTIME_CACHE_DIR", str(root / "cache"))
    os.environ["LONGTIME_DB"] = str(root / "default.sqlite")
    os.environ.setdefault("MPLBACKEND", "Agg")
    # one timing process per cell unless a test asks for more (each process is an interpreter start)
    os.environ.setdefault("LONGTIME_PROCESSES", "1")
    yield


# The slow tests: fault injection in subprocesses, Valgrind, Dask clusters, fresh interpreters,
# ensembles and long integrations. The default run (README's test command) leaves them out;
# `python -m pytest -m slow` runs them, and CI runs both.
SLOW_MODULES = {
    "test_faults.py", "test_faults_limits.py", "test_faults_store.py", "test_faults_disk.py",
    "test_faults_dask_signals.py", "test_faults_cpu.py", "test_dask.py", "test_dask_workers.py",
    "test_instructions.py", "test_isolation.py", "test_kernel_cache.py", "test_compile_once.py",
    "test_history.py", "test_processes.py", "test_chaos.py",
}
SLOW_TESTS = {
    "test_horizon.py::test_verlet_breakdown_time_grows_exponentially_in_one_over_dt",
    "test_duffing.py::test_a_run_past_the_growing_bound_is_diverged_and_an_o1_error_is_flagged",
    "test_store.py::test_killed_matrix_keeps_finished_cells",
    "test_audit.py::test_corrupt_kernel_module_and_bytecode_are_discarded_and_rebuilt",
    "test_plugins.py::test_plugin_joins_the_matrix",
    "test_card.py::test_card_command_and_its_bad_input",
    "test_examples.py::test_a_plugin_that_breaks_the_contract_is_listed_broken_with_one_line",
    "test_examples.py::test_example_plugin_lists_and_runs",
    "test_report_html.py::test_main_job_page_takes_the_figures_its_workers_drew",
    "test_fpu.py::test_oscillatory_energy_over_5000",
    "test_bpl.py::test_bpl_exp_on_kdv_steps_past_bpls_cap",
    "test_api_input.py::test_a_script_without_main_guard_runs_its_sweep",
    "test_bench_author.py::test_versions_change_only_what_they_claim",
    "test_asvbench.py::test_speed_tracks_a_ratio_per_cell_from_fresh_processes",
}


def pytest_collection_modifyitems(config, items):
    for item in items:
        module = item.nodeid.split("::")[0].rsplit("/", 1)[-1]
        name = f"{module}::{item.originalname}"
        if module in SLOW_MODULES or name in SLOW_TESTS:
            item.add_marker(pytest.mark.slow)
