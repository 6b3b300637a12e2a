"""Temporary folders of longtime's processes (a pool's row files, an isolated cell's files,
a local Dask cluster's scratch space).

Each folder is named after the process that makes it, ``longtime-KIND-PID-XXXXXXXX`` in the
temp folder. Its maker removes it on every exit it sees (an error, Ctrl-C, SIGTERM, SIGHUP:
``finally`` blocks); a process killed outright (SIGKILL, a power cut) cannot, so the first
folder a later process makes also removes the folders whose process is gone.
"""
from __future__ import annotations

import os
import re
import shutil
import sys
import tempfile
from pathlib import Path
from typing import NoReturn

from longtime.core.cache import no_space

KINDS = ("pool", "cell", "valgrind", "timing", "dask")
# a cell process's exit code when a write found no space (sysexits' EX_TEMPFAIL: try again later)
NO_SPACE_EXIT = 75


class DiskFull(RuntimeError):
    """A write that the run needs (a temp file, a row file, the store) found no space left:
    a fault of the machine, not a property of the cell, so no row is stored for it; the run
    is marked ``interrupted`` and ``longtime matrix --resume`` completes it once there is
    space again (as a lost Dask scheduler is)."""


def disk_full(exc: BaseException, what: str) -> DiskFull:
    """The DiskFull of ``exc`` (a write that found no space) while doing ``what``."""
    if isinstance(exc, DiskFull):
        return exc
    where = f" ({exc.filename})" if isinstance(exc, OSError) and exc.filename else ""
    return DiskFull(f"no space left on the disk while {what}{where}: "
                    f"{getattr(exc, 'strerror', None) or exc}")


def out_of_space(exc: BaseException) -> bool:
    """Whether ``exc`` is the disk's fault, not the cell's: a DiskFull, or a write that found
    no space."""
    return isinstance(exc, DiskFull) or no_space(exc)


def exit_out_of_space(exc: BaseException, what: str) -> NoReturn:
    """A child process's end on ``exc`` (``out_of_space``) while doing ``what``: the reason
    on stderr, exit NO_SPACE_EXIT, from which its parent raises DiskFull."""
    print(disk_full(exc, what), file=sys.stderr)
    sys.stderr.flush()
    os._exit(NO_SPACE_EXIT)


_NAME = re.compile(rf"longtime-(?:{'|'.join(KINDS)})-(\d+)-[^/]+")
_swept = False


def make(kind: str) -> Path:
    """A new folder of this process (``kind``: one of KINDS); the process's first call also
    sweeps the folders of processes that are gone."""
    global _swept
    if kind not in KINDS:
        raise ValueError(f"temp folder kind {kind!r}: expected one of {', '.join(KINDS)}")
    if not _swept:
        _swept = True
        sweep()
    return Path(tempfile.mkdtemp(prefix=f"longtime-{kind}-{os.getpid()}-"))


def alive(pid: int) -> bool:
    """Whether process ``pid`` exists on this machine and is not a zombie."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return True


def sweep(root: str | os.PathLike | None = None) -> list[Path]:
    """Remove the folders in ``root`` (default: the temp folder) whose process is gone;
    returns them. Folders of other users or of live processes are left alone."""
    removed = []
    try:
        entries = list(Path(root or tempfile.gettempdir()).iterdir())
    except OSError:
        return removed
    for path in entries:
        found = _NAME.fullmatch(path.name)
        if not found or int(found[1]) == os.getpid() or alive(int(found[1])):
            continue
        try:
            if path.is_dir() and not path.is_symlink() and path.stat().st_uid == os.getuid():
                shutil.rmtree(path, ignore_errors=True)
                removed.append(path)
        except OSError:
            continue
    return removed
