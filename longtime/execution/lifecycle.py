"""A recorded run's life in the store: begun with its planned cells, then finished as done
(the body returned), interrupted (it raised: Ctrl-C, a crash; `longtime matrix --resume`
completes it) or, when the body rejected its input before storing a row, discarded (there
is nothing to resume). Every command that stores rows (run, matrix, match, reproduce)
records its run here, under the command line it was given."""
from __future__ import annotations

import shlex
from contextlib import contextmanager
from typing import Iterable, Iterator

from longtime.core.params import InputError


def command_line(args) -> str:
    """The command a run records: the arguments given to ``longtime`` (``cli.main``'s argv,
    the subcommand first), e.g. "run -p toda -i rk4 --dt 0.1"."""
    return shlex.join(args.argv)


@contextmanager
def recorded_run(store, command: str, cells: Iterable = (), run_id: int | None = None) -> Iterator[int | None]:
    """The run of the ``with`` body in ``store`` (None: nothing is recorded, the body gets
    None): begun here with ``command`` and ``cells``, or ``run_id``, a run resumed. It
    finishes as done or interrupted; an InputError (input rejected as the body starts, e.g.
    an executor's setting) discards a run begun here that stored no row, and leaves a
    resumed one interrupted."""
    if store is None:
        yield None
        return
    begun = run_id is None
    if begun:
        run_id = store.begin_run(command, cells)
    status = "interrupted"
    try:
        yield run_id
        status = "done"
    except InputError:
        status = "rejected"
        raise
    finally:
        if status == "rejected" and begun:
            store.discard_run(run_id)  # kept (as interrupted, below) if it stored a row
        store.finish_run(run_id, "interrupted" if status == "rejected" else status)
