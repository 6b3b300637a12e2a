"""Where file permissions hold: root ignores the permission bits, so a test of a read-only
folder or file runs its command in a user namespace without a mapping when it runs as root."""
import os
import shutil
import subprocess


def unprivileged() -> list[str] | None:
    """A command prefix under which file permissions hold: [] for a user that is not root;
    as root, ``unshare --user`` (a user namespace without a mapping, so no override of the
    permission bits); None when that is not possible."""
    if os.geteuid() != 0:
        return []
    if shutil.which("unshare") and subprocess.run(["unshare", "--user", "true"], capture_output=True).returncode == 0:
        return ["unshare", "--user"]
    return None
