"""Which code a run measured: the git commit, and whether the working tree was dirty, of the
repository that holds each problem and scheme under test, beside longtime's own.

A scheme author's plugin (an entry point, or a class registered from Python) lives in her
repository, not in longtime's: the module that defines the class is found
(``inspect.getsourcefile``), the folders above it are walked up to one holding ``.git``,
and ``git rev-parse HEAD`` and ``git status --porcelain`` say its commit and whether it
had changes not committed. A class without a file (defined in an interactive session)
has no repository: its entry says so. ``$LONGTIME_GIT_COMMIT`` still names the run's
commit where the caller knows better (a CI checkout without ``.git``).
"""
from __future__ import annotations

import inspect
import subprocess
import sys
from pathlib import Path
from typing import Any, Iterable

from longtime.core.version import __version__

GIT_TIMEOUT_S = 5.0
# longtime's own package folder: its problems and schemes are not the code under test
PACKAGE = Path(__file__).resolve().parents[1]


def repository(path: str | Path) -> Path | None:
    """The folder at or above ``path`` that holds ``.git`` (a folder, or a worktree's file)."""
    here = Path(path).resolve()
    for folder in (here, *here.parents) if here.is_dir() else here.parents:
        if (folder / ".git").exists():
            return folder
    return None


def git_state(repo: Path) -> dict[str, Any]:
    """``commit`` (HEAD, None without one) and ``dirty`` (uncommitted changes, tracked or not;
    None when git cannot tell) of the repository ``repo``."""
    def git(*args: str) -> str | None:
        try:
            done = subprocess.run(["git", *args], cwd=repo, capture_output=True, text=True, timeout=GIT_TIMEOUT_S)
        except (OSError, subprocess.SubprocessError):
            return None
        return done.stdout if done.returncode == 0 else None

    head = git("rev-parse", "HEAD")
    status = git("status", "--porcelain")
    return {"repository": str(repo), "commit": head.strip() or None if head is not None else None,
            "dirty": None if status is None else bool(status.strip())}


def source_file(cls: type) -> str | None:
    """The file of the module that defines ``cls`` (None for a class without one)."""
    try:
        return inspect.getsourcefile(cls)
    except (TypeError, OSError):
        module = sys.modules.get(getattr(cls, "__module__", ""), None)
        return getattr(module, "__file__", None)


def longtime_state() -> dict[str, Any]:
    """longtime's own version, and its commit and dirty flag where it runs from a checkout."""
    state: dict[str, Any] = {"version": __version__, "commit": None, "dirty": None}
    repo = repository(PACKAGE)
    if repo is not None:
        state.update({k: v for k, v in git_state(repo).items() if k != "repository"})
    return state


def code_under_test(classes: Iterable[type]) -> list[dict[str, Any]]:
    """Per repository holding some of ``classes`` (problems and schemes): ``repository``,
    ``commit``, ``dirty`` and ``modules`` (the classes' modules in it); a class without a
    file or outside any repository gives an entry with ``repository`` None and why."""
    by_repo: dict[str | None, dict[str, Any]] = {}
    for cls in classes:
        path = source_file(cls)
        if path and Path(path).resolve().is_relative_to(PACKAGE):
            continue  # longtime's own problems and schemes: longtime's version and commit say it
        repo = repository(path) if path else None
        key = str(repo) if repo else None
        if key not in by_repo:
            by_repo[key] = git_state(repo) if repo else {
                "repository": None, "commit": None, "dirty": None,
                "reason": "defined without a file (an interactive session)" if not path
                else f"{path} is in no git repository"}
            by_repo[key]["modules"] = []
        module = getattr(cls, "__module__", "?")
        if module not in by_repo[key]["modules"]:
            by_repo[key]["modules"].append(module)
    return list(by_repo.values())


def of_cells(cells: Iterable[Any]) -> list[dict[str, Any]]:
    """``code_under_test`` of the problems and schemes that ``cells`` name (unknown names: none)."""
    from longtime.core import registry

    classes: dict[int, type] = {}
    for cell in cells:
        for kind, name in (("problem", cell.problem), ("integrator", cell.integrator)):
            try:
                cls = registry.problem_class(name) if kind == "problem" else registry.integrator_class(name)
            except Exception:
                continue
            classes[id(cls)] = cls
    return code_under_test(classes.values())


def run_code(run: dict[str, Any]) -> list[dict[str, Any]]:
    """The code under test a stored run recorded (its ``versions``' ``code``; none before)."""
    import json

    try:
        versions = json.loads(run.get("versions") or "{}")
    except ValueError:
        return []
    code = versions.get("code") if isinstance(versions, dict) else None
    return code if isinstance(code, list) else []


def text(code: list[dict[str, Any]]) -> str:
    """'abc1234567+dirty (/path/to/repo: my_scheme)' per repository, or 'longtime's own'."""
    if not code:
        return "longtime's own problems and schemes"
    parts = []
    for c in code:
        if c.get("repository") is None:
            parts.append(f"{', '.join(c.get('modules', []))}: no commit ({c.get('reason')})")
        else:
            mark = "+dirty" if c.get("dirty") else ""
            parts.append(f"{(c.get('commit') or 'no commit')[:10]}{mark} ({c['repository']}: "
                         f"{', '.join(c.get('modules', []))})")
    return "; ".join(parts)
