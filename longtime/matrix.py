"""Running many cells: executors and the loop that stores each row as it finishes.

An executor is a function ``(cells, options) -> iterator of (cell, row)`` yielding rows as
they complete, in any order. ``serial`` runs in this process; ``process`` (the default)
on a pool of local worker processes, each keeping its compiled kernels across cells.
Rows are written to the store one transaction each, so an interruption loses nothing
already measured.
"""
from __future__ import annotations

import multiprocessing
import os
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass
from typing import Callable, Iterator

from .cells import DEFAULT_MAX_SAMPLES, Cell, run_cell
from .params import InputError, check_choice
from .store import Store


@dataclass
class ExecOptions:
    jobs: int = 0  # 0: one per core
    max_samples: int = DEFAULT_MAX_SAMPLES
    cell_timeout: float | None = None
    scheduler: str | None = None  # Dask scheduler address

    def workers(self) -> int:
        return self.jobs if self.jobs > 0 else max(1, os.cpu_count() or 1)


Executor = Callable[[list[Cell], ExecOptions], Iterator[tuple[Cell, dict]]]


def serial(cells: list[Cell], options: ExecOptions) -> Iterator[tuple[Cell, dict]]:
    for cell in cells:
        yield cell, run_cell(cell, options.max_samples)


def _order_for_reuse(cells: list[Cell]) -> list[Cell]:
    """Cells of one pair next to each other, so a worker reuses its compiled kernel."""
    return sorted(cells, key=lambda c: (c.problem, c.integrator))


def process_pool(cells: list[Cell], options: ExecOptions) -> Iterator[tuple[Cell, dict]]:
    # spawn: a fork after heyoka's or numba's threads have started can deadlock
    ctx = multiprocessing.get_context("spawn")
    runnable = [c for c in cells if not c.skip_reason]
    for cell in cells:
        if cell.skip_reason:
            yield cell, run_cell(cell)
    if not runnable:
        return
    workers = min(options.workers(), len(runnable))
    if workers == 1:
        yield from serial(runnable, options)
        return
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx)
    try:
        futures = {pool.submit(run_cell, c, options.max_samples): c for c in _order_for_reuse(runnable)}
        pending = set(futures)
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for fut in done:
                cell = futures[fut]
                try:
                    row = fut.result()
                except Exception as exc:  # the worker died (segfault, out of memory)
                    from .cells import base_row

                    row = base_row(cell)
                    row.update(status="failed", message=f"worker process failed: {exc!r}")
                yield cell, row
    finally:
        pool.shutdown(wait=False, cancel_futures=True)


EXECUTORS: dict[str, Executor] = {"serial": serial, "process": process_pool}


def get_executor(name: str) -> Executor:
    check_choice("executor", name, EXECUTORS)
    return EXECUTORS[name]


def run_matrix(cells: list[Cell], store: Store | None, run_id: int | None, executor: str = "process",
               options: ExecOptions | None = None, progress: bool = False) -> list[dict]:
    """Run the cells, storing each row as it completes; returns the rows in cell order."""
    options = options or ExecOptions()
    if options.max_samples < 2:
        raise InputError(f"max_samples={options.max_samples} is not valid: must be >= 2")
    run = get_executor(executor)
    rows: dict[str, dict] = {}
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(cells), unit="cell", dynamic_ncols=True)
    try:
        for cell, row in run(cells, options):
            rows[cell.key] = row
            if store is not None and run_id is not None:
                store.add_row(run_id, cell, row)
            if bar is not None:
                bar.set_postfix_str(f"{cell.problem} x {cell.integrator}: {row['status']}", refresh=False)
                bar.update()
    finally:
        if bar is not None:
            bar.close()
    return [rows[c.key] for c in cells if c.key in rows]
