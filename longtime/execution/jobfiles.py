"""The files of a worker's folder, named in one place, and how they are written.

A child process's folder (``longtime.execution.child``) holds its job (``JOB``), the
session beside it (``SESSION``, ``SYS_PATH``), its stderr (``STDERR``), its mark
(``MARK``), its result (``RESULT``) and its records (``RECORDS``); a ``call`` job's function
and arguments (``CALL``) and what it returned or raised (``OUTCOME``), both pickled. A
resident child's folder, where batches run (``longtime.execution.batches``), also holds
the marker of the cell it is in (``running-PID``: the cell, as JSON), each finished row
(``row-KEY.json``: the cell and its row, KEY a digest of the cell's key) and the marker of a
cell whose worker the watchdog killed (``killed-PID``, ``longtime.execution.limits``).

Every one of these files but the appended records is written with ``write`` or
``write_json``: whole or not at all (``longtime.core.files.write_atomic``), so no reader
sees half a file, and a writer killed mid-write leaves only a hidden temporary file.
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Any

from longtime.core.files import write_atomic

JOB = "job.json"
SESSION = "session.pkl"
SYS_PATH = "sys_path.json"
STDERR = "stderr.txt"
MARK = "current"
RESULT = "result.json"
RECORDS = "records.jsonl"
CALL = "call.pkl"
OUTCOME = "outcome.pkl"
RUNNING = "running-"
ROW = "row-"
KILLED = "killed-"
# what one job leaves in the folder besides the job itself (``clear``); the hidden temporary
# files of a writer killed mid-write among them
LEFTOVERS = (RESULT, RECORDS, MARK, CALL, OUTCOME, f"{ROW}*", f"{RUNNING}*", f"{KILLED}*", ".*.tmp")


def write(path: str | os.PathLike, data: str | bytes) -> None:
    """``data`` (text or bytes) to ``path``, whole or not at all."""
    write_atomic(path, data)


def write_json(path: str | os.PathLike, data: Any) -> None:
    """``data`` as JSON to ``path``, whole or not at all."""
    write_atomic(path, json.dumps(data))


def key_digest(text: str) -> str:
    return hashlib.sha1(text.encode()).hexdigest()


def running_marker(folder: str | os.PathLike, pid: int | None = None) -> Path:
    """The marker of the cell worker ``pid`` (this process: None) is in."""
    return Path(folder, f"{RUNNING}{pid if pid is not None else os.getpid()}")


def marker_pid(marker: Path) -> int:
    """The worker's process id in a ``running-PID`` or ``killed-PID`` marker's name."""
    return int(marker.name.split("-", 1)[1])


def killed_marker(marker: Path) -> Path:
    """What the watchdog renames a ``running-PID`` marker to when it kills its worker."""
    return marker.with_name(f"{KILLED}{marker_pid(marker)}")


def running_markers(folder: str | os.PathLike) -> list[Path]:
    """The markers of the cells workers are in."""
    return list(Path(folder).glob(f"{RUNNING}*"))


def running_cells(folder: str | os.PathLike) -> list[dict[str, Any]]:
    """The cells (as dicts) whose markers are in ``folder``: those running when it is read."""
    return [json.loads(p.read_text()) for p in running_markers(folder)]


def row_file(folder: str | os.PathLike, key: str) -> Path:
    """The file of the finished row of the cell whose key is ``key``."""
    return Path(folder, f"{ROW}{key_digest(key)}.json")


def write_row(folder: str | os.PathLike, key: str, cell: dict[str, Any], row: dict[str, Any]) -> None:
    """A finished row, with its cell (as a dict), into ``folder``."""
    write_json(row_file(folder, key), {"cell": cell, "row": row})


def finished_rows(folder: str | os.PathLike) -> list[tuple[dict[str, Any], dict[str, Any]]]:
    """(cell as a dict, row) of each finished row in ``folder``, in the order of their files."""
    out = []
    for path in sorted(Path(folder).glob(f"{ROW}*.json")):
        data = json.loads(path.read_text())
        out.append((data["cell"], data["row"]))
    return out


def clear(folder: str | os.PathLike) -> None:
    """Remove what the last job left in ``folder`` (``LEFTOVERS``); the job file stays."""
    for pattern in LEFTOVERS:
        for path in Path(folder).glob(pattern):
            path.unlink(missing_ok=True)
