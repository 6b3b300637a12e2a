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
