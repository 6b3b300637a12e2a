"""Every file the suite writes for a reader (the results page, figures, asv files, reports and
JSON exports) is written whole or not at all: into a temporary file beside it, then renamed
over it (``os.replace``, atomic within a folder). A reader never sees half a file; a failed
write (a full disk, a read-only folder) keeps the previous file and raises ``NotWritten``
(one line); a symbolic link at the path is replaced itself, never written through, so the
file it points to (perhaps outside the folder) is left as it is."""
from __future__ import annotations

import os
import secrets
from pathlib import Path


class NotWritten(OSError):
    """A file that could not be written whole; the previous one (if any) is kept."""

    def __str__(self) -> str:
        return f"cannot write {self.filename}: {self.strerror}; nothing was replaced"


def write_atomic(path: str | os.PathLike, data: str | bytes, encoding: str = "utf-8") -> Path:
    """Write ``data`` (text in ``encoding``, or bytes) to ``path`` whole, replacing the file
    or link there at once; returns the path. Raises ``NotWritten`` (an OSError, with the
    errno of the failed step) and leaves no temporary file."""
    path = Path(path)
    payload = data.encode(encoding) if isinstance(data, str) else bytes(data)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp")
    try:
        # O_EXCL: a name planted in the folder (a link) is never followed; mode 0o666 minus the umask
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        try:
            view = memoryview(payload)
            while view:
                view = view[os.write(fd, view):]
        finally:
            os.close(fd)
        os.replace(tmp, path)
    except OSError as exc:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise NotWritten(exc.errno, exc.strerror or str(exc), str(path)) from exc
    return path
