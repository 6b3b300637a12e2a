"""The ``longtime`` command's entry point: Ctrl-C at any moment, the first second of imports
included, ends the command with one line and exit 130, never a traceback.

It imports nothing heavy itself (``import longtime`` loads no numpy or numba), so it runs
before the command's modules load; ``longtime.commands.guard`` handles Ctrl-C once the
command runs.
"""
from __future__ import annotations

import signal
import sys


def main() -> int:
    from longtime.core import threads

    threads.limit_this_process()  # before numpy loads: the cells run here (checks, serial) as in a worker
    try:
        from longtime.commands.cli import main as cli_main

        return cli_main()
    except KeyboardInterrupt:  # before the command ran (imports, parsing): nothing to clean up
        try:
            print("longtime: interrupted by SIGINT", file=sys.stderr)
        except (OSError, KeyboardInterrupt):
            pass
        return 128 + signal.SIGINT


if __name__ == "__main__":
    sys.exit(main())
