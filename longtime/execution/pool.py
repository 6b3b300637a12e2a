"""Worker processes: how many a ``--jobs`` value means, and the pool of them every command
that fans work out uses (the matrix, warmup, the round-off study, the results page)."""
from __future__ import annotations

import os
from typing import Any, Callable, Iterator


def workers(jobs: int, tasks: int | None = None) -> int:
    """The worker processes for ``--jobs``: ``jobs`` when > 0, else one per core; never more
    than ``tasks`` (when given), and at least one."""
    n = jobs if jobs > 0 else (os.cpu_count() or 1)
    return max(1, n if tasks is None else min(n, tasks))


def worker_pool(workers: int, spec=None):
    """``workers`` worker processes (``longtime.execution.resident.ResidentPool``): each a fresh
    interpreter (``python -m longtime.execution.child``, never a fork: a fork after numba's or
    heyoka's threads, or a Dask client's, have started can deadlock) that lives from task to
    task; ``submit(fn, *args)`` as a process pool's, and a task that crashes its worker
    (``CallFailed``) costs that worker only."""
    from longtime.execution.resident import ResidentPool

    return ResidentPool(workers, spec)


def guard_resource_tracker() -> None:
    """Keep multiprocessing's resource tracker (the process that cleans up the semaphores of
    the processes multiprocessing starts: a local Dask cluster's workers) quiet when it was
    killed: the one started in its place never saw what the dead one tracked, and would print
    a KeyError traceback for each name this process then unregisters. Those names are not
    sent to it, and its start is said in one line. Where the tracker is not the one this
    knows (another Python), nothing changes."""
    import sys
    import warnings
    from multiprocessing import resource_tracker as rt

    tracker = getattr(rt, "_resource_tracker", None)
    if tracker is None or not hasattr(tracker, "_pid") or getattr(tracker, "_longtime_guarded", False):
        return
    owners: dict[tuple[str, str], Any] = {}  # (name, type) -> the tracker process it was registered with
    ensure, register, unregister = tracker.ensure_running, tracker.register, tracker.unregister

    def ensure_running() -> None:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            ensure()
        if caught:
            print("warning: multiprocessing's resource tracker process had ended (killed?); a new one runs",
                  file=sys.stderr)

    def registered(name: str, rtype: str) -> None:
        ensure_running()
        register(name, rtype)
        owners[(name, rtype)] = tracker._pid

    def unregistered(name: str, rtype: str) -> None:
        ensure_running()
        if owners.pop((name, rtype), tracker._pid) == tracker._pid:  # else a dead tracker's: unknown here
            unregister(name, rtype)

    tracker.ensure_running = rt.ensure_running = ensure_running
    tracker.register = rt.register = registered
    tracker.unregister = rt.unregister = unregistered
    tracker._longtime_guarded = True


def unguarded_main() -> str | None:
    """Why a local Dask cluster cannot start here, or None when it can: a worker that
    multiprocessing spawns runs the main module again, and a script that calls longtime
    outside ``if __name__ == "__main__":`` would then call it again in every worker
    (multiprocessing's "bootstrapping phase" RuntimeError). Found from the stack: the main
    module's top level is running, at a statement that is not that guard. A notebook,
    ``python -c`` and the REPL have no file to run again; a worker bootstrapping a script
    says so."""
    import ast
    import sys

    main = sys.modules.get("__main__")
    path = getattr(main, "__file__", None)
    if getattr(main, "__name__", None) == "__mp_main__":
        return f"{path} is being run again by a worker process as it starts"
    if not path or not str(path).endswith(".py"):
        return None
    frame = sys._getframe(1)
    while frame is not None and not (frame.f_globals is vars(main) and frame.f_code.co_name == "<module>"):
        frame = frame.f_back
    if frame is None:  # the script's top level has finished (a callback, a thread)
        return None
    try:
        with open(path, encoding="utf-8") as f:
            tree = ast.parse(f.read())
    except (OSError, SyntaxError, ValueError):
        return None
    line = frame.f_lineno
    stmt = next((s for s in tree.body if s.lineno <= line <= (s.end_lineno or s.lineno)), None)
    if stmt is None or _is_main_guard(stmt):
        return None
    return (f"{path} calls it outside `if __name__ == \"__main__\":` (line {line}), and each worker "
            f"process would run the script again")


def _is_main_guard(stmt) -> bool:
    import ast

    if not isinstance(stmt, ast.If) or not isinstance(stmt.test, ast.Compare) or len(stmt.test.ops) != 1:
        return False
    sides = [stmt.test.left, stmt.test.comparators[0]]
    names = [s.id for s in sides if isinstance(s, ast.Name)]
    consts = [s.value for s in sides if isinstance(s, ast.Constant)]
    return isinstance(stmt.test.ops[0], ast.Eq) and names == ["__name__"] and consts == ["__main__"]

def run_tasks(fn: Callable, tasks: list[tuple], jobs: int, scheduler: str | None = None) -> Iterator[tuple[tuple, Any]]:
    """Yield (task, fn(*task)) as the tasks finish: on the Dask cluster at ``scheduler``, else
    on a ``worker_pool`` of ``workers(jobs)`` processes (in this process when that is one).
    The studies that fan out independent runs (round-off, the breakdown horizon) use it."""
    if scheduler:
        try:
            from distributed import Client, as_completed
        except ImportError:
            from longtime.core.params import InputError

            raise InputError("--scheduler needs dask.distributed: pip install 'longtime[dask]'") from None
        client = Client(scheduler)
        try:
            futures = {client.submit(fn, *task, pure=False): task for task in tasks}
            for fut in as_completed(futures):
                yield futures[fut], fut.result()
        finally:
            client.close()
        return
    from concurrent.futures import as_completed as finished

    n = workers(jobs, len(tasks))
    if n == 1:
        for task in tasks:
            yield task, fn(*task)
        return
    with worker_pool(n) as pool:
        futures = {pool.submit(fn, *task): task for task in tasks}
        for fut in finished(futures):
            yield futures[fut], fut.result()


class Queued:
    """Tasks that their owners hand out (an owner's ``task()``: (function, its arguments,
    where its result goes), or None when it has no more), all queued at once on the workers
    of ``pool`` (a ``worker_pool``) beside the caller's own jobs; ``finish`` waits for them
    and gives each result to its owner. A task that fails, or whose worker dies, is only not
    done: its owner does that work later itself."""

    def __init__(self, pool) -> None:
        self.pool = pool
        self.pending: list[tuple[Any, Callable[[Any], None]]] = []

    def take(self, owner) -> None:
        """Queue every task ``owner`` has now."""
        while (task := owner.task()) is not None:
            fn, args, done = task
            self.pending.append((self.pool.submit(fn, *args), done))

    def finish(self) -> None:
        for future, done in self.pending:
            try:
                result = future.result()
            except Exception:  # not done here: its owner does it
                continue
            done(result)
        self.pending = []
