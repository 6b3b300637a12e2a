"""What a run measured on, recorded with it in the store: package versions, the machine and
the code (longtime.execution.provenance)."""
from __future__ import annotations

import functools
import os
import platform
import sys
from typing import Any, Iterable

from longtime.execution.cells import Cell


def environment(cells: Iterable[Cell] = ()) -> dict[str, Any]:
    """What a run measured on: package versions, the machine, and the code: ``versions``'
    ``longtime_git`` (longtime's own commit and dirty flag) and ``code`` (the commit and dirty
    flag of each repository that holds a problem or scheme of ``cells`` other than
    longtime's: longtime.execution.provenance). ``git_commit`` is the commit of the code
    measured: $LONGTIME_GIT_COMMIT where the caller names it, else the one repository of the
    code under test, else longtime's own."""
    from importlib.metadata import PackageNotFoundError, version

    from longtime.execution import provenance

    versions: dict[str, Any] = {"python": sys.version.split()[0]}
    for pkg in ("longtime", "numpy", "scipy", "numba", "llvmlite", "heyoka", "pandas", "rebound"):
        try:
            versions[pkg] = version(pkg)
        except PackageNotFoundError:
            versions[pkg] = None
    machine = this_machine()
    own = provenance.longtime_state()
    code = provenance.of_cells(cells)
    versions["longtime_git"] = {"commit": own["commit"], "dirty": own["dirty"]}
    versions["code"] = code
    committed = [c["commit"] for c in code if c.get("commit")]
    commit = os.environ.get("LONGTIME_GIT_COMMIT") or (committed[0] if len(committed) == 1 else None) or own["commit"]
    return {"versions": versions, "machine": machine, "git_commit": commit}


def this_machine() -> dict[str, Any]:
    """The machine this process runs on, as a run records it: platform, architecture,
    processor, core count, host name and CPU model."""
    return {"platform": platform.platform(), "machine": platform.machine(),
            "processor": platform.processor(), "cpus": os.cpu_count(), "node": platform.node(),
            "cpu_model": cpu_model()}


def machine_key(machine: dict[str, Any]) -> tuple:
    """What tells one machine from another: its host name, CPU model and core count."""
    return (machine.get("node"), machine.get("cpu_model") or machine.get("processor"), machine.get("cpus"))


@functools.cache
def cpu_model() -> str | None:
    """The CPU's model name (/proc/cpuinfo's ``model name``, else platform.processor()), or None."""
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                key, _, value = line.partition(":")
                if key.strip() in ("model name", "Model") and value.strip():
                    return value.strip()
    except OSError:
        pass
    return platform.processor() or None
